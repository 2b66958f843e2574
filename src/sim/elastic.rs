//! The elastic energy of the reduced model, sum_c v_c Psi(F_c(z)), on the cubature points,
//! with its gradient and (PSD-projected) Hessian in z.
//!
//! Layout of z (see [`Layout`]): handle j has an affine matrix Z_j (3 x 4); row r of all the
//! Z_j forms the block z_r of length 4 (m + 1), z = [z_0; z_1; z_2]. With Xh = [X; 1],
//! x_r(X) = X_r + b(X) . z_r with b[4 j + a] = W_j(X) Xh_a, and
//! F_rc = delta_rc + a_c . z_r with a_c[4 j + a] = dW_j/dX_c Xh_a + W_j delta_ac.
//! So row r of F depends on z_r only. The per-point products use that structure directly
//! (about 30 (m + 1) flops per point for F, the same for the gradient) instead of forming
//! 9 x 12(m + 1) blocks; the Hessian is assembled per 3 x 3 block pair (r, s) by dense
//! matrix products over chunks of points (see [`ElasticTerm::hessian`] for why the energy's
//! structure does not reduce that work).

use crate::elasticity::{hessian, hessian_psd, Mat9};
use crate::linalg3::Mat3;
use crate::precompute::skinning::SkinningWeights;
use crate::sim::cubature::Cubature;
use crate::sim::lanes::{BlockState, LaneData, Partial, LANES};
use crate::simd::multiversion;
use crate::{Error, Point3, Result};
use faer::linalg::matmul::triangular::BlockStructure;
use faer::{Accum, Mat, Par};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Points per work unit. Fixed (not derived from the thread count), so sums are formed in
/// the same order on any machine: results are bit-identical across thread counts.
const CHUNK: usize = 256;

/// Points per dense product in the Hessian assembly: large enough for efficient matrix
/// products (the inner dimension is 3 x HESSIAN_CHUNK), small enough to split over threads.
const HESSIAN_CHUNK: usize = 1024;

/// Points per dense product within a chunk (the T buffer then stays in cache).
const HESSIAN_SUB: usize = 128;

/// Index arithmetic for the reduced coordinates z (12 (m + 1) entries).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// Number of handles m + 1 (the constant mode included).
    pub handles: usize,
}

impl Layout {
    /// Length of one row block z_r: 4 (m + 1).
    pub fn row_len(&self) -> usize {
        4 * self.handles
    }
    /// Number of reduced degrees of freedom 12 (m + 1).
    pub fn dofs(&self) -> usize {
        12 * self.handles
    }
    /// Position of `Z_j[r][a]` (a = 3 is the translation column) in z.
    pub fn index(&self, r: usize, j: usize, a: usize) -> usize {
        r * self.row_len() + 4 * j + a
    }
}

/// How the elastic Hessian is made positive semi-definite.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Projection {
    /// The exact Hessian (may be indefinite away from the rest state).
    None,
    /// Each point's 9 x 9 Hessian projected to PSD (analytic eigensystem).
    PerPoint,
}

/// The elastic term on the cubature points.
#[derive(Debug, Clone)]
pub struct ElasticTerm {
    layout: Layout,
    points: Vec<Point3>,
    volumes: Vec<f64>,
    lambda: Vec<f64>,
    mu: Vec<f64>,
    /// W_j at point c: `w[c * handles + j]`.
    w: Vec<f64>,
    /// grad W_j at point c.
    gw: Vec<[f64; 3]>,
    /// The same data in SIMD-friendly blocks for the energy and gradient.
    lanes: LaneData,
    /// The constant vectors a_c for the Hessian, built on first use
    /// ([`ElasticTerm::rest_vectors`]).
    rest_vectors: std::sync::OnceLock<Vec<f64>>,
    /// The same in single precision, for [`Precision::Single`].
    rest_vectors_single: std::sync::OnceLock<Vec<f32>>,
}

/// The elastic term's exact Hessian at one state, as an operator ([`ElasticTerm::hessian_at`]).
pub struct ElasticHessian<'a> {
    term: &'a ElasticTerm,
    /// F and cof F at every cubature point, per block of lanes.
    f: Vec<BlockState>,
}

impl ElasticHessian<'_> {
    /// H v, 12 (m + 1): about one elastic gradient's work (F's change along v, the stress
    /// change dP/dF : dF and its transpose map).
    pub fn product(&self, v: &[f64]) -> Vec<f64> {
        let lanes = &self.term.lanes;
        let nb = lanes.blocks();
        let per = CHUNK / LANES;
        let dofs = self.term.layout.dofs();
        let parts: Vec<Vec<f64>> = (0..nb.div_ceil(per))
            .into_par_iter()
            .map(|k| {
                let mut out = vec![0.0; dofs];
                let range = k * per..((k + 1) * per).min(nb);
                lanes.hessian_product(range, &self.f, v, &mut out);
                out
            })
            .collect();
        // Sum in chunk order: deterministic for any thread count.
        let mut out = vec![0.0; dofs];
        for p in &parts {
            out.iter_mut().zip(p).for_each(|(a, b)| *a += b);
        }
        out
    }
}

/// Per-call statistics of an energy evaluation.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ElasticStats {
    /// Smallest det F over the cubature points (<= 0 means inverted points).
    pub min_det: f64,
    /// Number of cubature points with det F <= 0.
    pub inverted: usize,
}

impl ElasticTerm {
    /// The term for `cubature` points with their skinning weights `weights` (same order).
    pub fn new(cubature: &Cubature, weights: &SkinningWeights) -> Result<Self> {
        if weights.points() != cubature.len() {
            return Err(Error::LengthMismatch {
                what: "skinning weights (cubature points)",
                expected: cubature.len(),
                got: weights.points(),
            });
        }
        Ok(Self {
            layout: Layout {
                handles: weights.modes,
            },
            points: cubature.points.clone(),
            volumes: cubature.volumes.clone(),
            lambda: cubature.lambda.clone(),
            mu: cubature.mu.clone(),
            lanes: LaneData::new(
                &cubature.points,
                &cubature.volumes,
                &cubature.lambda,
                &cubature.mu,
                &weights.values,
                &weights.gradients,
                weights.modes,
            ),
            w: weights.values.clone(),
            gw: weights.gradients.clone(),
            rest_vectors: std::sync::OnceLock::new(),
            rest_vectors_single: std::sync::OnceLock::new(),
        })
    }

    /// The layout of z.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Number of cubature points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True without cubature points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Deformation gradient F at cubature point `c` for coordinates `z`.
    #[inline]
    pub fn deformation_gradient(&self, c: usize, z: &[f64]) -> Mat3 {
        let mut f = self.deformation_change(c, z);
        for (r, row) in f.iter_mut().enumerate() {
            row[r] += 1.0;
        }
        f
    }

    /// The change of F at cubature point `c` along `z` (F is affine in z: F(z) - I, formed
    /// without the identity so that a small z keeps its relative precision).
    #[inline]
    pub fn deformation_change(&self, c: usize, z: &[f64]) -> Mat3 {
        let nh = self.layout.handles;
        let n4 = self.layout.row_len();
        let x = self.points[c];
        let mut f = [[0.0; 3]; 3];
        for j in 0..nh {
            let wj = self.w[c * nh + j];
            let g = self.gw[c * nh + j];
            for (r, fr) in f.iter_mut().enumerate() {
                let zz = &z[r * n4 + 4 * j..r * n4 + 4 * j + 4];
                let y = zz[0] * x[0] + zz[1] * x[1] + zz[2] * x[2] + zz[3];
                fr[0] += g[0] * y + wj * zz[0];
                fr[1] += g[1] * y + wj * zz[1];
                fr[2] += g[2] * y + wj * zz[2];
            }
        }
        f
    }

    /// Elastic energy sum_c v_c Psi(F_c), J, and inversion statistics.
    pub fn energy(&self, z: &[f64]) -> (f64, ElasticStats) {
        self.evaluate(z, None)
    }

    /// Energy (J) and its gradient dE/dz, written to `grad` (length 12 (m + 1)).
    pub fn energy_gradient(&self, z: &[f64], grad: &mut [f64]) -> (f64, ElasticStats) {
        self.evaluate(z, Some(grad))
    }

    /// The reverse pass's material part at a step's end `z`: adds -v_c dP/dmu : G_c to
    /// `mu[c]` and -v_c dP/dlambda : G_c to `lambda[c]` for every cubature point c, where
    /// G_c is the deformation gradient's change along `adjoint` (F is affine in z) and
    /// P = mu F + ((lambda + mu)(J - 1) - mu) cof F is linear in (mu, lambda):
    /// dP/dmu = F + (J - 2) cof F, dP/dlambda = (J - 1) cof F. Returns the number of
    /// points with det F <= 0.
    pub fn add_material_adjoint(
        &self,
        z: &[f64],
        adjoint: &[f64],
        mu: &mut [f64],
        lambda: &mut [f64],
    ) -> usize {
        let parts: Vec<(f64, f64, bool)> = (0..self.len())
            .into_par_iter()
            .with_min_len(CHUNK)
            .map(|c| {
                let f = self.deformation_gradient(c, z);
                let g = self.deformation_change(c, adjoint);
                let j = crate::linalg3::det3(&f);
                let cof = crate::linalg3::cofactor3(&f);
                let (mut cof_g, mut f_g) = (0.0, 0.0);
                for r in 0..3 {
                    for k in 0..3 {
                        cof_g += cof[r][k] * g[r][k];
                        f_g += f[r][k] * g[r][k];
                    }
                }
                let v = self.volumes[c];
                let inverted = j.is_nan() || j <= 0.0;
                (
                    -v * (f_g + (j - 2.0) * cof_g),
                    -v * (j - 1.0) * cof_g,
                    inverted,
                )
            })
            .collect();
        let mut inverted = 0;
        for (c, (dm, dl, inv)) in parts.into_iter().enumerate() {
            mu[c] += dm;
            lambda[c] += dl;
            inverted += usize::from(inv);
        }
        inverted
    }

    /// The exact Hessian at `z` (12 (m + 1)) as an operator: F and cof F at every cubature
    /// point, kept for its products ([`ElasticHessian::product`]).
    pub fn hessian_at(&self, z: &[f64]) -> ElasticHessian<'_> {
        ElasticHessian {
            term: self,
            f: self.lanes.deformation_gradient_blocks(z),
        }
    }

    /// H(z) v (12 (m + 1) each) without forming H ([`ElasticTerm::hessian_at`] for several
    /// products at one z).
    pub fn hessian_product(&self, z: &[f64], v: &[f64]) -> Vec<f64> {
        self.hessian_at(z).product(v)
    }

    fn evaluate(&self, z: &[f64], grad: Option<&mut [f64]>) -> (f64, ElasticStats) {
        let nb = self.lanes.blocks();
        let per = CHUNK / LANES;
        let with_grad = grad.is_some();
        let dofs = self.layout.dofs();
        let parts: Vec<(Partial, Vec<f64>)> = (0..nb.div_ceil(per))
            .into_par_iter()
            .map(|k| {
                let range = k * per..((k + 1) * per).min(nb);
                let mut g = if with_grad {
                    vec![0.0; dofs]
                } else {
                    Vec::new()
                };
                let part = self
                    .lanes
                    .eval(range, z, with_grad.then_some(g.as_mut_slice()));
                (part, g)
            })
            .collect();
        // Sum in chunk order: deterministic for any thread count.
        let mut e = 0.0;
        let mut st = ElasticStats {
            min_det: f64::INFINITY,
            inverted: 0,
        };
        if let Some(grad) = grad {
            grad.fill(0.0);
            for (_, g) in &parts {
                grad.iter_mut().zip(g).for_each(|(a, b)| *a += b);
            }
        }
        for (p, _) in &parts {
            e += p.energy;
            st.min_det = st.min_det.min(p.min_det);
            st.inverted += p.inverted;
        }
        if parts.is_empty() {
            st.min_det = 1.0;
        }
        (e, st)
    }

    /// The Hessian d2E/dz2, 12 (m + 1) square, with per-point Hessians optionally projected to
    /// PSD. Cost: 6 C (4 (m + 1))^2 flops per 3 x 3 block pair (r, s) for C cubature points,
    /// 4.5 pairs' worth (the three diagonal pairs are symmetric, only their upper halves are
    /// formed): 2.4 GFLOP at m = 32, C = 5000, in dense products.
    ///
    /// The energy's structure does not cut that work. The mu/2 |F|^2 part has the constant
    /// point Hessian mu I_9, but it only adds to the diagonal pairs (r, r), whose other terms
    /// (the rank-one volumetric (lambda + mu) g_r g_r^T, and the projection's corrections) vary,
    /// so those products stay. The volumetric part (lambda + mu) (g g^T + (J - gamma) d2J/dF2)
    /// couples each off-diagonal pair through the skew 3 x 3 matrix of a row of F, a full
    /// n4 x 3C x n4 product like the general case. And the PSD projection changes most points
    /// (at rest one eigenvalue of each twist pair is exactly 0 and rounding tips it either
    /// way; in a bent beam state 85% of the points had a negative one), so no fixed split
    /// survives it.
    pub fn hessian(&self, z: &[f64], projection: Projection) -> Mat<f64> {
        let all: Vec<usize> = (0..self.len()).collect();
        self.hessian_on(z, projection, &all, 1.0, Precision::Double)
    }

    /// An approximation of [`ElasticTerm::hessian`] from every `stride`-th cubature point,
    /// volumes scaled so the sampled volume equals the total: about `stride` times cheaper.
    /// The cubature points are in farthest-point order (or a regular grid), so the sample
    /// spreads over the whole object. Used as a quasi-Newton base, never as the Newton
    /// Hessian.
    /// `precision` chooses the arithmetic of the dense products ([`Precision`]).
    pub fn hessian_sampled(
        &self,
        z: &[f64],
        projection: Projection,
        stride: usize,
        precision: Precision,
    ) -> Mat<f64> {
        let idx: Vec<usize> = (0..self.len()).step_by(stride.max(1)).collect();
        let total: f64 = self.volumes.iter().sum();
        let part: f64 = idx.iter().map(|&c| self.volumes[c]).sum();
        let scale = if part > 0.0 { total / part } else { 1.0 };
        self.hessian_on(z, projection, &idx, scale, precision)
    }

    /// The Hessian from the cubature points `idx`, volumes multiplied by `scale`.
    ///
    /// Three phases: (1) the scaled per-point 9 x 9 Hessians (in parallel over points);
    /// (2) one task per (chunk of points, block pair (r, s)): T = A C^(rs) and the product
    /// T A^T (only the upper triangle for r = s), with A the constant vectors a_c
    /// ([`ElasticTerm::rest_vectors`]); the tasks are many and small, so two threads stay
    /// busy to the end; (3) the chunk results summed in chunk order (the same sums for any
    /// thread count) and mirrored.
    fn hessian_on(
        &self,
        z: &[f64],
        projection: Projection,
        idx: &[usize],
        scale: f64,
        precision: Precision,
    ) -> Mat<f64> {
        let n4 = self.layout.row_len();
        let h9: Vec<Mat9> = idx
            .par_iter()
            .with_min_len(64)
            .map(|&c| {
                let f = self.deformation_gradient(c, z);
                let (l, m) = (self.lambda[c], self.mu[c]);
                let mut h = match projection {
                    Projection::None => hessian(&f, l, m),
                    Projection::PerPoint => hessian_psd(&f, l, m),
                };
                let v = scale * self.volumes[c];
                h.iter_mut().flatten().for_each(|e| *e *= v);
                h
            })
            .collect();
        let n = self.layout.dofs();
        let mut out = Mat::<f64>::zeros(n, n);
        match precision {
            Precision::Double => {
                let products = self.block_products(self.rest_vectors(), &h9, idx);
                add_products(&products, n4, &mut out);
            }
            Precision::Single => {
                let products = self.block_products(self.rest_vectors_single(), &h9, idx);
                add_products(&products, n4, &mut out);
            }
        }
        // Mirror the upper triangle.
        for j in 0..n {
            for i in 0..j {
                out[(j, i)] = out[(i, j)];
            }
        }
        out
    }

    /// Phase 2 of [`ElasticTerm::hessian_on`]: (block pair index, product) per task, in
    /// chunk order. `a` holds the vectors a_c of all cubature points (or of `idx` only when
    /// `idx` is not all of them: then gathered here).
    fn block_products<T: Scalar>(
        &self,
        cached: &[T],
        h9: &[Mat9],
        idx: &[usize],
    ) -> Vec<(usize, Mat<T>)> {
        let n4 = self.layout.row_len();
        let all = idx.len() == self.len() && idx.iter().enumerate().all(|(i, &c)| i == c);
        let gathered: Vec<T>;
        let a: &[T] = if all {
            cached
        } else {
            gathered = idx
                .iter()
                .flat_map(|&c| &cached[3 * c * n4..3 * (c + 1) * n4])
                .copied()
                .collect();
            &gathered
        };
        let chunks = idx.len().div_ceil(HESSIAN_CHUNK);
        let tasks: Vec<(usize, usize)> = (0..chunks)
            .flat_map(|k| (0..BLOCKS.len()).map(move |b| (k, b)))
            .collect();
        tasks
            .par_iter()
            .map(|&(k, b)| {
                let points = k * HESSIAN_CHUNK..((k + 1) * HESSIAN_CHUNK).min(idx.len());
                let ak = &a[3 * points.start * n4..3 * points.end * n4];
                (b, block_product(ak, &h9[points], BLOCKS[b], n4))
            })
            .collect()
    }

    /// The vectors a_c of every cubature point, n4 x 3 C column-major (column 3 p + c is
    /// a_c of point p, with a_c[4 j + q] = dW_j/dX_c Xh_q + W_j delta_qc): constant, so
    /// built on the first Hessian and kept (12 (m + 1) C values, 16 MB for m = 32 and
    /// C = 5000).
    fn rest_vectors(&self) -> &[f64] {
        self.rest_vectors.get_or_init(|| self.build_rest_vectors())
    }

    /// [`ElasticTerm::rest_vectors`] rounded to single precision (half the memory again).
    fn rest_vectors_single(&self) -> &[f32] {
        self.rest_vectors_single
            .get_or_init(|| self.rest_vectors().iter().map(|&v| v as f32).collect())
    }

    fn build_rest_vectors(&self) -> Vec<f64> {
        let n4 = self.layout.row_len();
        let nh = self.layout.handles;
        let mut a = vec![0.0; 3 * n4 * self.len()];
        a.par_chunks_mut(3 * n4).enumerate().for_each(|(c, ap)| {
            let x = self.points[c];
            let xh = [x[0], x[1], x[2], 1.0];
            for (col, ac) in ap.chunks_exact_mut(n4).enumerate() {
                for j in 0..nh {
                    let wj = self.w[c * nh + j];
                    let g = self.gw[c * nh + j][col];
                    for (q, xq) in xh.iter().enumerate() {
                        ac[4 * j + q] = g * xq + if q == col { wj } else { 0.0 };
                    }
                }
            }
        });
        a
    }
}

/// Add the block-pair products (in the order given) into the upper triangle of `out`.
fn add_products<T: Scalar>(products: &[(usize, Mat<T>)], n4: usize, out: &mut Mat<f64>) {
    for (b, prod) in products {
        let (r, s) = BLOCKS[*b];
        for q in 0..n4 {
            // Diagonal pairs: only the upper triangle (p <= q) was computed.
            let rows = if r == s { q + 1 } else { n4 };
            for p in 0..rows {
                out[(r * n4 + p, s * n4 + q)] += prod[(p, q)].into();
            }
        }
    }
}

/// Arithmetic of the Hessian's dense products (the per-point 9 x 9 Hessians and the final
/// sums are always double).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Precision {
    /// f64 products: the Hessian to rounding (what an object stepping alone by Newton
    /// factorizes; an island's Newton follows `contact.hessian_precision`).
    #[default]
    Double,
    /// f32 products, about twice as fast: entries carry relative errors of ~1e-6 of their
    /// size. Enough for a quasi-Newton base matrix, which only needs to be a good SPD
    /// model (a base that fails to factorize is rebuilt in double), and for an island's
    /// Newton model (the same iterations, docs/performance.md).
    Single,
}

/// The element types of the dense products.
trait Scalar: faer::traits::ComplexField + Copy + Into<f64> + Send + Sync + 'static {
    fn from_f64(v: f64) -> Self;
    /// td = c0 a0 + c1 a1 + c2 a2 (see [`combine3_f64`]).
    fn combine3(td: &mut [Self], a: &[Self], c: [Self; 3]);
}

impl Scalar for f64 {
    fn from_f64(v: f64) -> Self {
        v
    }
    fn combine3(td: &mut [Self], a: &[Self], c: [Self; 3]) {
        combine3_f64(td, a, c)
    }
}

impl Scalar for f32 {
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    fn combine3(td: &mut [Self], a: &[Self], c: [Self; 3]) {
        combine3_f32(td, a, c)
    }
}

/// sum_p A_p C_p^(rs) A_p^T over the points p of one chunk, n4 x n4 (upper triangle only
/// when r = s), with A_p the n4 x 3 columns of point p in `a` and C_p^(rs) the (r, s)
/// 3 x 3 block of point p's (volume-weighted) Hessian `h9[p]`.
fn block_product<T: Scalar>(a: &[T], h9: &[Mat9], (r, s): (usize, usize), n4: usize) -> Mat<T> {
    let structure = if r == s {
        BlockStructure::TriangularUpper
    } else {
        BlockStructure::Rectangular
    };
    let points = h9.len();
    let sub = HESSIAN_SUB.min(points).max(1);
    // T for `sub` points at a time, small enough to stay in cache.
    let mut t = vec![T::from_f64(0.0); n4 * 3 * sub];
    let mut out = Mat::<T>::zeros(n4, n4);
    for (k, first) in (0..points).step_by(sub).enumerate() {
        let last = (first + sub).min(points);
        let cols = 3 * (last - first);
        for (p, h) in h9[first..last].iter().enumerate() {
            let ap = &a[3 * (first + p) * n4..(3 * (first + p) + 3) * n4];
            for d in 0..3 {
                let c = [
                    h[3 * r][3 * s + d],
                    h[3 * r + 1][3 * s + d],
                    h[3 * r + 2][3 * s + d],
                ]
                .map(T::from_f64);
                T::combine3(&mut t[(3 * p + d) * n4..(3 * p + d + 1) * n4], ap, c);
            }
        }
        let am = faer::MatRef::from_column_major_slice(&a[3 * first * n4..3 * last * n4], n4, cols);
        let tm = faer::MatRef::from_column_major_slice(&t[..n4 * cols], n4, cols);
        // out += T A^T; for r = s the product is symmetric (C^(rr) is), so its upper half
        // is all we need.
        faer::linalg::matmul::triangular::matmul(
            out.as_mut(),
            structure,
            if k == 0 { Accum::Replace } else { Accum::Add },
            tm,
            BlockStructure::Rectangular,
            am.transpose(),
            BlockStructure::Rectangular,
            T::from_f64(1.0),
            Par::Seq,
        );
    }
    out
}

/// `fn $name(td, a, c)`: td = c0 a0 + c1 a1 + c2 a2 for element type `$t`, where `a` holds
/// a0, a1, a2 one after the other (each the length of `td`); multiversioned.
macro_rules! combine3 {
    ($name:ident, $t:ty) => {
        multiversion! {
            /// td = c0 a0 + c1 a1 + c2 a2 (a = [a0; a1; a2]).
            fn $name(td: &mut [$t], a: &[$t], c: [$t; 3]) {
                let n = td.len();
                let (a0, rest) = a.split_at(n);
                let (a1, a2) = rest.split_at(n);
                for (((t, x), y), w) in td.iter_mut().zip(a0).zip(a1).zip(&a2[..n]) {
                    *t = c[0] * x + c[1] * y + c[2] * w;
                }
            }
        }
    };
}
combine3!(combine3_f64, f64);
combine3!(combine3_f32, f32);

/// The (r, s) block pairs with r <= s.
const BLOCKS: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
