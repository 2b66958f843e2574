//! The Newton system of an island, kept in its block structure: one dense block per object
//! (its own Hessian plus the diagonal part of its contacts) and a coupling block only for
//! each pair of objects with samples in contact. It is solved by conjugate gradients
//! preconditioned with each object's own block (block Jacobi, one Cholesky factor per
//! object), so the cost grows with the number of objects and contacts instead of the cube
//! of the island's size, as the dense factorization did (docs/performance.md). Block Jacobi
//! alone needs more iterations the longer the chains of stiff contacts are: it moves a load
//! one object further each iteration. A coarse level over each object's affine motions (12
//! per object, one small dense system for the island) solves those collective motions
//! directly, in the balancing form that keeps the preconditioner symmetric and exact on the
//! coarse space.

use super::coarse::{column, Coarse, CoarseBasis};
use crate::sim::newton::{dot, RestSolve};
use faer::linalg::matmul::matmul;
use faer::linalg::solvers::{Llt, Solve};
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::sync::Arc;

/// Relative residual |H d - g| / |g| at which the conjugate gradients stop. 1e-8: the
/// direction then differs from the exact Newton step by far less than the minimiser's own
/// tolerance (1e-6 of the diagonal by default), and it stays well above the round-off of the
/// block products (~1e-13 relative); the test against the dense solve checks the agreement.
pub const CG_TOLERANCE: f64 = 1e-8;

/// Most conjugate-gradient iterations per solve, a multiple of the number of objects: block
/// Jacobi converges in a number of iterations that grows with the length of the contact
/// chains, not with the unknowns per object; the cap only guards against a breakdown.
pub const CG_ITERATIONS_PER_OBJECT: usize = 60;

/// A symmetric block matrix over the stacked coordinates of an island: dense diagonal blocks
/// (n_a x n_a) and the upper coupling blocks H_ab (n_a x n_b, a < b) of the pairs that have
/// any; H_ba = H_ab^T is implied.
#[derive(Debug, Clone)]
pub struct BlockHessian {
    offsets: Vec<usize>,
    diag: Vec<Mat<f64>>,
    coupling: BTreeMap<(usize, usize), Mat<f64>>,
}

impl BlockHessian {
    /// From the diagonal blocks (square, in the order of the stacked coordinates) and no
    /// coupling.
    pub fn new(diag: Vec<Mat<f64>>) -> BlockHessian {
        let mut offsets = Vec::with_capacity(diag.len() + 1);
        let mut at = 0;
        for d in &diag {
            assert_eq!(d.nrows(), d.ncols(), "diagonal blocks are square");
            offsets.push(at);
            at += d.nrows();
        }
        offsets.push(at);
        BlockHessian {
            offsets,
            diag,
            coupling: BTreeMap::new(),
        }
    }

    /// Zero blocks of the given sizes.
    pub fn zeros(sizes: &[usize]) -> BlockHessian {
        BlockHessian::new(sizes.iter().map(|&n| Mat::zeros(n, n)).collect())
    }

    /// Total size of the stacked coordinates.
    pub fn dim(&self) -> usize {
        self.offsets[self.offsets.len() - 1]
    }

    /// Number of blocks (objects).
    pub fn blocks(&self) -> usize {
        self.diag.len()
    }

    /// Number of coupling blocks (object pairs in contact).
    pub fn couplings(&self) -> usize {
        self.coupling.len()
    }

    /// The block (a, b), a <= b, to add into (a coupling block is created zero on first
    /// use).
    pub fn block_mut(&mut self, a: usize, b: usize) -> MatMut<'_, f64> {
        assert!(a <= b, "only the upper blocks are stored");
        if a == b {
            return self.diag[a].as_mut();
        }
        let (na, nb) = (self.diag[a].nrows(), self.diag[b].nrows());
        self.coupling
            .entry((a, b))
            .or_insert_with(|| Mat::zeros(na, nb))
            .as_mut()
    }

    /// Add the whole matrix into the dense `h` (dim x dim).
    pub fn add_to_dense(&self, h: &mut Mat<f64>) {
        for (a, d) in self.diag.iter().enumerate() {
            let o = self.offsets[a];
            let mut dst = h.as_mut().submatrix_mut(o, o, d.nrows(), d.ncols());
            dst += d.as_ref();
        }
        for (&(a, b), c) in &self.coupling {
            let (oa, ob) = (self.offsets[a], self.offsets[b]);
            let mut dst = h.as_mut().submatrix_mut(oa, ob, c.nrows(), c.ncols());
            dst += c.as_ref();
            let mut dst = h.as_mut().submatrix_mut(ob, oa, c.ncols(), c.nrows());
            dst += c.transpose();
        }
    }

    /// The dense matrix.
    pub fn to_dense(&self) -> Mat<f64> {
        let n = self.dim();
        let mut h = Mat::zeros(n, n);
        self.add_to_dense(&mut h);
        h
    }

    /// y = H x (written block by block straight into y: no allocation, as CG calls it
    /// every iteration).
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        let o = &self.offsets;
        let col = |v, a: usize| column(v, o[a], o[a + 1]);
        let mut add = |a: usize, m: MatRef<'_, f64>, b: usize| {
            let out =
                MatMut::from_column_major_slice_mut(&mut y[o[a]..o[a + 1]], o[a + 1] - o[a], 1);
            matmul(out, Accum::Add, m, col(x, b), 1.0, Par::Seq);
        };
        for (a, d) in self.diag.iter().enumerate() {
            add(a, d.as_ref(), a);
        }
        for (&(a, b), c) in &self.coupling {
            add(a, c.as_ref(), b);
            add(b, c.transpose(), a);
        }
    }

    /// Factor each diagonal block (in parallel; each factor on its own, so the result does
    /// not depend on the thread count) for the block-Jacobi preconditioner, and, when
    /// `coarse` holds a basis per block and there are at least two blocks, the island's
    /// system restricted to those bases for the coarse correction ([`BlockSolve`]). None: a
    /// block or the coarse system is not positive definite (then neither is H).
    pub fn into_solver(self, coarse: Option<&Arc<CoarseBasis>>) -> Option<BlockSolve> {
        let factors: Vec<Option<Llt<f64>>> = self
            .diag
            .par_iter()
            .map(|d| d.llt(Side::Lower).ok())
            .collect();
        let factors = factors.into_iter().collect::<Option<Vec<_>>>()?;
        let coarse = match coarse {
            Some(basis) if self.blocks() > 1 => {
                Some(Coarse::new(&self.diag, &self.coupling, basis)?)
            }
            _ => None,
        };
        Some(BlockSolve {
            h: self,
            factors,
            coarse,
        })
    }
}

/// H^-1 g for a [`BlockHessian`] H by block-Jacobi preconditioned conjugate gradients.
pub struct BlockSolve {
    h: BlockHessian,
    factors: Vec<Llt<f64>>,
    coarse: Option<Coarse>,
}

/// What one [`BlockSolve::solve_with_info`] did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CgInfo {
    /// Iterations taken.
    pub iterations: usize,
    /// Final |H d - g| / |g|.
    pub relative_residual: f64,
    /// Whether the solve stopped at a direction of zero or negative curvature (H is not
    /// positive definite).
    pub negative_curvature: bool,
}

/// The preconditioner's work vectors, allocated once per solve: the residual after the coarse
/// correction (n) and the two coarse solutions.
struct Scratch {
    r1: Vec<f64>,
    w1: Mat<f64>,
    w2: Mat<f64>,
}

impl BlockSolve {
    /// The matrix.
    pub fn matrix(&self) -> &BlockHessian {
        &self.h
    }

    /// The matrix back, for another solver.
    pub fn into_matrix(self) -> BlockHessian {
        self.h
    }

    /// z = M^-1 r with M^-1 the block-Jacobi inverse B; with a coarse level, the balancing
    /// form z = Q r + (I - Q H) B (I - H Q) r, Q = P E^-1 P^T (symmetric positive definite;
    /// exact on the coarse space), its products with H through the stored H P.
    fn precondition(&self, r: &[f64], z: &mut [f64], scratch: &mut Scratch) {
        let o = &self.h.offsets;
        let Some(c) = &self.coarse else {
            self.block_jacobi(r, z);
            return;
        };
        let Scratch { r1, w1, w2 } = scratch;
        c.solve_restricted(o, r, false, w1);
        r1.copy_from_slice(r);
        c.prolong(o, w1, -1.0, true, r1);
        self.block_jacobi(r1, z);
        c.solve_restricted(o, z, true, w2);
        c.prolong(o, w1, 1.0, false, z);
        c.prolong(o, w2, -1.0, false, z);
    }

    fn block_jacobi(&self, r: &[f64], z: &mut [f64]) {
        let o = &self.h.offsets;
        z.copy_from_slice(r);
        for (a, f) in self.factors.iter().enumerate() {
            let n = o[a + 1] - o[a];
            f.solve_in_place(MatMut::from_column_major_slice_mut(
                &mut z[o[a]..o[a + 1]],
                n,
                1,
            ));
        }
    }

    /// d with H d = g to the relative residual [`CG_TOLERANCE`] (or the best iterate after
    /// the iteration cap; every iterate from 0 is a descent direction for -d, as the
    /// conjugate gradients minimise the quadratic model over growing subspaces).
    pub fn solve_with_info(&self, g: &[f64]) -> (Vec<f64>, CgInfo) {
        self.solve_to(g, CG_TOLERANCE)
    }

    /// [`BlockSolve::solve_with_info`] to the relative residual `tolerance` (the reverse
    /// pass asks for a tighter one than Newton).
    pub fn solve_to(&self, g: &[f64], tolerance: f64) -> (Vec<f64>, CgInfo) {
        let n = g.len();
        let mut x = vec![0.0; n];
        let gnorm = dot(g, g).sqrt();
        let mut info = CgInfo::default();
        if gnorm == 0.0 || !gnorm.is_finite() {
            return (x, info);
        }
        let mut r = g.to_vec();
        let mut z = vec![0.0; n];
        let mut scratch = Scratch {
            r1: vec![0.0; if self.coarse.is_some() { n } else { 0 }],
            w1: self
                .coarse
                .as_ref()
                .map_or(Mat::zeros(0, 1), Coarse::coarse_vector),
            w2: self
                .coarse
                .as_ref()
                .map_or(Mat::zeros(0, 1), Coarse::coarse_vector),
        };
        self.precondition(&r, &mut z, &mut scratch);
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        let mut hp = vec![0.0; n];
        let cap = CG_ITERATIONS_PER_OBJECT * self.h.blocks().max(1);
        info.relative_residual = 1.0;
        while info.iterations < cap {
            self.h.mul(&p, &mut hp);
            let php = dot(&p, &hp);
            // Zero or negative curvature (or NaN) along p: stop with the iterate so far.
            if php.is_nan() || php <= 0.0 {
                info.negative_curvature = true;
                break;
            }
            let alpha = rz / php;
            for i in 0..n {
                x[i] += alpha * p[i];
                r[i] -= alpha * hp[i];
            }
            info.iterations += 1;
            info.relative_residual = dot(&r, &r).sqrt() / gnorm;
            if info.relative_residual <= tolerance {
                break;
            }
            self.precondition(&r, &mut z, &mut scratch);
            let rz_next = dot(&r, &z);
            let beta = rz_next / rz;
            rz = rz_next;
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
        }
        (x, info)
    }
}

impl RestSolve for BlockSolve {
    fn solve(&self, rhs: &[f64]) -> Vec<f64> {
        self.solve_with_info(rhs).0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random SPD island of three blocks (3, 4 and 2 unknowns) coupled 0-1 and 1-2 (the
    /// library's generator, `seed`): the block matrix, the same matrix dense, and a random
    /// right-hand side.
    fn random_island(seed: u64) -> (BlockHessian, Mat<f64>, Vec<f64>) {
        let sizes = [3, 4, 2];
        let mut rng = crate::random::SplitMix64::new(seed);
        let mut rnd = move || rng.uniform(-0.5, 0.5);
        let n: usize = sizes.iter().sum();
        // H = A A^T + I restricted to the block pattern: build A with the same pattern.
        let a = Mat::from_fn(n, n, |_, _| rnd());
        let mut dense = Mat::<f64>::identity(n, n);
        matmul(
            dense.as_mut(),
            Accum::Add,
            a.as_ref(),
            a.transpose(),
            1.0,
            Par::Seq,
        );
        // Zero the (0, 2) coupling: it is not stored.
        for i in 0..3 {
            for j in 7..9 {
                dense[(i, j)] = 0.0;
                dense[(j, i)] = 0.0;
            }
        }
        // Keep it SPD after removing the coupling: add a diagonal shift.
        for i in 0..n {
            dense[(i, i)] += 10.0;
        }
        let off = [0, 3, 7, 9];
        let mut h = BlockHessian::zeros(&sizes);
        for (a, b) in [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2)] {
            let mut blk = h.block_mut(a, b);
            for i in 0..sizes[a] {
                for j in 0..sizes[b] {
                    blk[(i, j)] = dense[(off[a] + i, off[b] + j)];
                }
            }
        }
        let g: Vec<f64> = (0..n).map(|_| rnd()).collect();
        (h, dense, g)
    }

    /// Max |d - H^-1 g| against the dense Cholesky solve, relative to |H^-1 g|.
    fn error_against_dense(dense: &Mat<f64>, g: &[f64], d: &[f64]) -> f64 {
        let n = g.len();
        let reference = dense.llt(Side::Lower).unwrap();
        let rhs = Mat::from_fn(n, 1, |i, _| g[i]);
        let exact = Solve::solve(&reference, rhs.as_ref());
        let norm: f64 = (0..n).map(|i| exact[(i, 0)].powi(2)).sum::<f64>().sqrt();
        (0..n)
            .map(|i| (d[i] - exact[(i, 0)]).abs())
            .fold(0.0, f64::max)
            / norm
    }

    /// The block products equal the dense ones, and the block-Jacobi conjugate-gradient solve
    /// equals the dense Cholesky solve to the CG tolerance times the condition number.
    #[test]
    fn block_solve_matches_the_dense_cholesky_solve() {
        let (h, dense, g) = random_island(12345);
        let n = g.len();
        assert_eq!(h.couplings(), 2);
        let back = h.to_dense();
        for i in 0..n {
            for j in 0..n {
                assert_eq!(back[(i, j)], dense[(i, j)]);
            }
        }
        let mut y = vec![0.0; n];
        h.mul(&g, &mut y);
        for i in 0..n {
            let e: f64 = (0..n).map(|j| dense[(i, j)] * g[j]).sum();
            // Sums of 9 products of O(10) numbers: round-off ~1e-14.
            assert!((y[i] - e).abs() < 1e-12, "{} vs {e}", y[i]);
        }
        let (d, info) = h.into_solver(None).unwrap().solve_with_info(&g);
        assert!(info.relative_residual <= CG_TOLERANCE, "{info:?}");
        // Relative error <= condition number x relative residual; the shifted matrix has a
        // condition number below 10 here (eigenvalues in [10, ~50]).
        assert!(error_against_dense(&dense, &g, &d) <= 10.0 * CG_TOLERANCE);
    }

    /// With a coarse level of random bases (two columns per block) the solve meets the same
    /// bound; with bases that span every unknown, the balancing preconditioner is H^-1
    /// itself (Q = H^-1, I - Q H = 0), so one iteration solves the system.
    #[test]
    fn two_level_solve_matches_the_dense_solve_and_is_exact_on_a_full_coarse_space() {
        let (h, dense, g) = random_island(777);
        let mut rng = crate::random::SplitMix64::new(99);
        let sizes = [3, 4, 2];
        let random: Vec<Mat<f64>> = sizes
            .iter()
            .map(|&n| Mat::from_fn(n, 2, |_, _| rng.uniform(-1.0, 1.0)))
            .collect();
        let (d, info) = h
            .clone()
            .into_solver(Some(&Arc::new(CoarseBasis::new(&random))))
            .unwrap()
            .solve_with_info(&g);
        assert!(info.relative_residual <= CG_TOLERANCE, "{info:?}");
        assert!(error_against_dense(&dense, &g, &d) <= 10.0 * CG_TOLERANCE);

        let full: Vec<Mat<f64>> = sizes.iter().map(|&n| Mat::identity(n, n)).collect();
        let (d, info) = h
            .into_solver(Some(&Arc::new(CoarseBasis::new(&full))))
            .unwrap()
            .solve_with_info(&g);
        assert_eq!(info.iterations, 1, "{info:?}");
        // One application of the exact inverse: round-off of a 9 x 9 solve, condition < 10.
        assert!(error_against_dense(&dense, &g, &d) <= 1e-12);
    }

    /// A chain of eight objects, each two unknowns joined by a spring (1e3) and grounded
    /// softly (1), the objects joined end to end by stiffer springs (1e4), a load at one end:
    /// block Jacobi passes the load along the chain one object per iteration; the coarse
    /// level over each object's translation (1, 1) solves the chain's collective motion, so
    /// the two-level solve needs at most half the iterations (a property of this matrix).
    #[test]
    fn the_coarse_level_cuts_the_iterations_on_a_stiff_chain() {
        let objects = 8;
        let (soft, body, stiff) = (1.0, 1e3, 1e4);
        let mut h = BlockHessian::zeros(&vec![2; objects]);
        for a in 0..objects {
            // Inside an object: its two unknowns joined by a unit spring, grounded softly.
            let mut d = h.block_mut(a, a);
            d[(0, 0)] += body + soft;
            d[(1, 1)] += body + soft;
            d[(0, 1)] -= body;
            d[(1, 0)] -= body;
        }
        for a in 0..objects - 1 {
            // The stiff contact: unknown 1 of object a to unknown 0 of object a + 1.
            h.block_mut(a, a)[(1, 1)] += stiff;
            h.block_mut(a + 1, a + 1)[(0, 0)] += stiff;
            h.block_mut(a, a + 1)[(1, 0)] -= stiff;
        }
        let dense = h.to_dense();
        let mut g = vec![0.0; 2 * objects];
        g[0] = 1.0;
        let (d1, jacobi) = h.clone().into_solver(None).unwrap().solve_with_info(&g);
        let rigid: Vec<Mat<f64>> = (0..objects)
            .map(|_| Mat::from_fn(2, 1, |_, _| 1.0))
            .collect();
        let (d2, two_level) = h
            .into_solver(Some(&Arc::new(CoarseBasis::new(&rigid))))
            .unwrap()
            .solve_with_info(&g);
        for (d, info) in [(&d1, jacobi), (&d2, two_level)] {
            assert!(info.relative_residual <= CG_TOLERANCE, "{info:?}");
            // The condition number is ~1e4 / soft contrast: the error bound scales with it.
            assert!(error_against_dense(&dense, &g, d) <= 1e5 * CG_TOLERANCE);
        }
        // Measured: 16 and 5 (CG in exact arithmetic stops by 16, the dimension).
        assert!(
            2 * two_level.iterations <= jacobi.iterations,
            "{jacobi:?} {two_level:?}"
        );
    }
}
