//! The coarse level of an island's preconditioner ([`super::system::BlockSolve`]): a few
//! whole-body motions per object (their affine motions), the island's Newton matrix H
//! restricted to them (E = P^T H P, one small dense system), and the products with H P that
//! the balancing form Q + (I - Q H) B (I - H Q), Q = P E^-1 P^T, needs at every
//! conjugate-gradient iteration. Block Jacobi (B) alone moves a load along a chain of stiff
//! contacts one object per iteration; the coarse level solves the chain's collective motion
//! at once.

use faer::linalg::matmul::matmul;
use faer::linalg::solvers::{Llt, Solve};
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};
use std::collections::BTreeMap;
use std::sync::Arc;

/// Entries lo..hi of `v` as a column.
pub(super) fn column(v: &[f64], lo: usize, hi: usize) -> MatRef<'_, f64> {
    MatRef::from_column_major_slice(&v[lo..hi], hi - lo, 1)
}

/// A coarse basis of one block as its non-zero entries, column by column: (row, value).
/// The objects' affine motions have one entry per handle in each of their 12 columns, so the
/// products with it cost 1/12 of dense ones.
type SparseColumns = Vec<Vec<(usize, f64)>>;

fn sparse_columns(p: &Mat<f64>) -> SparseColumns {
    (0..p.ncols())
        .map(|k| {
            (0..p.nrows())
                .filter(|&i| p[(i, k)] != 0.0)
                .map(|i| (i, p[(i, k)]))
                .collect()
        })
        .collect()
}

/// m P for a block m (n_a x n_b) and a sparse basis P (n_b x c).
fn times_sparse(m: MatRef<'_, f64>, p: &SparseColumns) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(m.nrows(), p.len());
    for (k, col) in p.iter().enumerate() {
        for &(i, w) in col {
            for r in 0..m.nrows() {
                out[(r, k)] += w * m[(r, i)];
            }
        }
    }
    out
}

/// The coarse space of an island: per object a basis P_a of its whole-body motions, kept as
/// its non-zeros, with each object's first coarse unknown. Built once per island step and
/// shared by the preconditioners of its Newton systems.
pub struct CoarseBasis {
    blocks: Vec<SparseColumns>,
    /// Rows of each block's basis (the object's unknowns).
    rows: Vec<usize>,
    offsets: Vec<usize>,
}

impl CoarseBasis {
    /// From one basis per object (n_a x c_a, full column rank).
    pub fn new(basis: &[Mat<f64>]) -> CoarseBasis {
        let mut offsets = Vec::with_capacity(basis.len() + 1);
        let mut at = 0;
        for p in basis {
            offsets.push(at);
            at += p.ncols();
        }
        offsets.push(at);
        CoarseBasis {
            blocks: basis.iter().map(sparse_columns).collect(),
            rows: basis.iter().map(|p| p.nrows()).collect(),
            offsets,
        }
    }
}

/// The coarse level of the preconditioner: the island's coarse basis, the products H P by
/// block pairs, and the Cholesky factor of E = P^T H P (sum_a c_a square, dense).
pub struct Coarse {
    basis: Arc<CoarseBasis>,
    /// (a, b, H_ab P_b): row block a, coarse block b; every stored block of H both ways.
    hp: Vec<(usize, usize, Mat<f64>)>,
    factor: Llt<f64>,
}

impl Coarse {
    /// H P and P^T H P from the diagonal blocks `diag` and the upper coupling blocks
    /// `coupling` of a block matrix H ([`super::system::BlockHessian`]) and the coarse basis
    /// (one block per diagonal block, as many rows); None when E is not positive definite.
    pub fn new(
        diag: &[Mat<f64>],
        coupling: &BTreeMap<(usize, usize), Mat<f64>>,
        coarse: &Arc<CoarseBasis>,
    ) -> Option<Coarse> {
        let (basis, offsets) = (&coarse.blocks, &coarse.offsets);
        assert_eq!(basis.len(), diag.len(), "one coarse basis per block");
        for (&rows, d) in coarse.rows.iter().zip(diag) {
            assert_eq!(rows, d.nrows(), "a coarse basis spans its block's unknowns");
        }
        let at = offsets[offsets.len() - 1];
        let mut hp = Vec::with_capacity(diag.len() + 2 * coupling.len());
        for (a, d) in diag.iter().enumerate() {
            hp.push((a, a, times_sparse(d.as_ref(), &basis[a])));
        }
        for (&(a, b), c) in coupling {
            hp.push((a, b, times_sparse(c.as_ref(), &basis[b])));
            hp.push((b, a, times_sparse(c.transpose(), &basis[a])));
        }
        // E = P^T (H P), block (a, b) from the stored H_ab P_b.
        let mut e = Mat::<f64>::zeros(at, at);
        for (a, b, m) in &hp {
            for (k, col) in basis[*a].iter().enumerate() {
                for l in 0..m.ncols() {
                    let v: f64 = col.iter().map(|&(i, w)| w * m[(i, l)]).sum();
                    e[(offsets[*a] + k, offsets[*b] + l)] += v;
                }
            }
        }
        let factor = e.llt(Side::Lower).ok()?;
        Some(Coarse {
            basis: Arc::clone(coarse),
            hp,
            factor,
        })
    }

    /// y = E^-1 P^T v (`transpose_hp`: E^-1 (H P)^T v instead), with the fine offsets `o`;
    /// `y` is the coarse vector (sum_a c_a x 1), overwritten.
    pub fn solve_restricted(&self, o: &[usize], v: &[f64], transpose_hp: bool, y: &mut Mat<f64>) {
        let offsets = &self.basis.offsets;
        if transpose_hp {
            y.fill(0.0);
            for (a, b, m) in &self.hp {
                let dst = y.as_mut().submatrix_mut(offsets[*b], 0, m.ncols(), 1);
                matmul(
                    dst,
                    Accum::Add,
                    m.transpose(),
                    column(v, o[*a], o[*a + 1]),
                    1.0,
                    Par::Seq,
                );
            }
        } else {
            for (a, p) in self.basis.blocks.iter().enumerate() {
                for (k, col) in p.iter().enumerate() {
                    y[(offsets[a] + k, 0)] = col.iter().map(|&(i, w)| w * v[o[a] + i]).sum();
                }
            }
        }
        self.factor.solve_in_place(y.as_mut());
    }

    /// A coarse vector for [`Coarse::solve_restricted`].
    pub fn coarse_vector(&self) -> Mat<f64> {
        Mat::zeros(self.basis.offsets[self.basis.offsets.len() - 1], 1)
    }

    /// out += s P w (`hp`: s H P w instead) for the coarse vector w.
    pub fn prolong(&self, o: &[usize], w: &Mat<f64>, s: f64, hp: bool, out: &mut [f64]) {
        let offsets = &self.basis.offsets;
        if hp {
            for (a, b, m) in &self.hp {
                let n = o[*a + 1] - o[*a];
                let dst = MatMut::from_column_major_slice_mut(&mut out[o[*a]..o[*a + 1]], n, 1);
                let wb = w.as_ref().submatrix(offsets[*b], 0, m.ncols(), 1);
                matmul(dst, Accum::Add, m.as_ref(), wb, s, Par::Seq);
            }
        } else {
            for (a, p) in self.basis.blocks.iter().enumerate() {
                for (k, col) in p.iter().enumerate() {
                    let wk = s * w[(offsets[a] + k, 0)];
                    for &(i, v) in col {
                        out[o[a] + i] += v * wk;
                    }
                }
            }
        }
    }
}
