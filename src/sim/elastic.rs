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
//! matrix products over chunks of points.

use crate::elasticity::{hessian, hessian_psd, Mat3};
use crate::sim::cubature::Cubature;
use crate::sim::lanes::{LaneData, Partial, LANES};
use crate::skinning::SkinningWeights;
use crate::{Error, Point3, Result};
use faer::{Accum, Mat, Par};
use rayon::prelude::*;

/// Points per work unit. Fixed (not derived from the thread count), so sums are formed in
/// the same order on any machine: results are bit-identical across thread counts.
const CHUNK: usize = 128;

/// Points per dense product in the Hessian assembly: large enough for efficient matrix
/// products (the inner dimension is 3 x HESSIAN_CHUNK), small enough to split over threads.
const HESSIAN_CHUNK: usize = 1024;

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
    /// Position of Z_j[r][a] (a = 3 is the translation column) in z.
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
        let nh = self.layout.handles;
        let n4 = self.layout.row_len();
        let x = self.points[c];
        let mut f = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
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
    /// PSD. Cost: O(C (4 (m + 1))^2) flops for C cubature points, in dense products.
    pub fn hessian(&self, z: &[f64], projection: Projection) -> Mat<f64> {
        let all: Vec<usize> = (0..self.len()).collect();
        self.hessian_on(z, projection, &all, 1.0)
    }

    /// An approximation of [`ElasticTerm::hessian`] from every `stride`-th cubature point,
    /// volumes scaled so the sampled volume equals the total: about `stride` times cheaper.
    /// The cubature points are in farthest-point order (or a regular grid), so the sample
    /// spreads over the whole object. Used as a quasi-Newton base, never as the Newton
    /// Hessian.
    pub fn hessian_sampled(&self, z: &[f64], projection: Projection, stride: usize) -> Mat<f64> {
        let idx: Vec<usize> = (0..self.len()).step_by(stride.max(1)).collect();
        let total: f64 = self.volumes.iter().sum();
        let part: f64 = idx.iter().map(|&c| self.volumes[c]).sum();
        let scale = if part > 0.0 { total / part } else { 1.0 };
        self.hessian_on(z, projection, &idx, scale)
    }

    /// The Hessian from the cubature points `idx`, volumes multiplied by `scale`.
    fn hessian_on(&self, z: &[f64], projection: Projection, idx: &[usize], scale: f64) -> Mat<f64> {
        let n4 = self.layout.row_len();
        let nh = self.layout.handles;
        let parts: Vec<[Mat<f64>; 6]> = idx
            .par_chunks(HESSIAN_CHUNK)
            .map(|range| {
                let cols = 3 * range.len();
                // A: the vectors a_c of each point (column 3 p + c), column-major in a plain
                // buffer so the T loop below runs over contiguous slices;
                // T^(rs): column 3 p + d = sum_c v H[3r + c][3s + d] a_(3p + c).
                let mut a = vec![0.0; n4 * cols];
                let mut h9 = Vec::with_capacity(range.len());
                for (p, &c) in range.iter().enumerate() {
                    let x = self.points[c];
                    let xh = [x[0], x[1], x[2], 1.0];
                    for col in 0..3 {
                        let ac = &mut a[(3 * p + col) * n4..(3 * p + col + 1) * n4];
                        for j in 0..nh {
                            let wj = self.w[c * nh + j];
                            let g = self.gw[c * nh + j][col];
                            for (q, xq) in xh.iter().enumerate() {
                                ac[4 * j + q] = g * xq + if q == col { wj } else { 0.0 };
                            }
                        }
                    }
                    let f = self.deformation_gradient(c, z);
                    let (l, m) = (self.lambda[c], self.mu[c]);
                    let h = match projection {
                        Projection::None => hessian(&f, l, m),
                        Projection::PerPoint => hessian_psd(&f, l, m),
                    };
                    h9.push((scale * self.volumes[c], h));
                }
                let a_ref = faer::MatRef::from_column_major_slice(&a, n4, cols);
                let mut blocks: [Mat<f64>; 6] = std::array::from_fn(|_| Mat::zeros(n4, n4));
                let mut t = vec![0.0; n4 * cols];
                for (b, (r, s)) in BLOCKS.iter().enumerate() {
                    for (p, (v, h)) in h9.iter().enumerate() {
                        let ap = &a[3 * p * n4..(3 * p + 3) * n4];
                        let (a0, rest) = ap.split_at(n4);
                        let (a1, a2) = rest.split_at(n4);
                        for d in 0..3 {
                            let c0 = v * h[3 * r][3 * s + d];
                            let c1 = v * h[3 * r + 1][3 * s + d];
                            let c2 = v * h[3 * r + 2][3 * s + d];
                            let td = &mut t[(3 * p + d) * n4..(3 * p + d + 1) * n4];
                            for i in 0..n4 {
                                td[i] = c0 * a0[i] + c1 * a1[i] + c2 * a2[i];
                            }
                        }
                    }
                    faer::linalg::matmul::matmul(
                        blocks[b].as_mut(),
                        Accum::Replace,
                        faer::MatRef::from_column_major_slice(&t, n4, cols),
                        a_ref.transpose(),
                        1.0,
                        Par::Seq,
                    );
                }
                blocks
            })
            .collect();
        let n = self.layout.dofs();
        let mut out = Mat::<f64>::zeros(n, n);
        for blocks in &parts {
            for (b, (r, s)) in BLOCKS.iter().enumerate() {
                for q in 0..n4 {
                    for p in 0..n4 {
                        out[(r * n4 + p, s * n4 + q)] += blocks[b][(p, q)];
                    }
                }
            }
        }
        // Mirror the upper block triangle; symmetrize the diagonal blocks exactly.
        for i in 0..n {
            for j in 0..i {
                let v = if i / n4 == j / n4 {
                    0.5 * (out[(i, j)] + out[(j, i)])
                } else {
                    out[(j, i)]
                };
                out[(i, j)] = v;
                out[(j, i)] = v;
            }
        }
        out
    }
}

/// The (r, s) block pairs with r <= s.
const BLOCKS: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
