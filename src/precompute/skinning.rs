//! Skinning eigenmodes as functions of space: W_j(X) = sum_k phi_k(X) c_kj and their
//! gradients, at any query points (integration points, mesh vertices, splat centres, FEM nodes).

use super::centers::morton_order;
use super::rkpm::{self, Kernels, ShapeFunctionOptions};
use crate::{Error, Point3, Result};
use faer::Mat;
use rayon::prelude::*;

/// A basis of skinning weight functions: kernels plus coefficients.
#[derive(Debug, Clone)]
pub struct Basis {
    /// The RKPM kernels the weights are built from.
    pub kernels: Kernels,
    /// Coefficients c, K x (m + 1); column 0 is the constant mode. M-orthonormal: c^T M c = I.
    pub coefficients: Mat<f64>,
    /// Eigenvalues of H_w c = lambda M c, m + 1, ascending (lambda_0 = 0), Pa / m^2
    /// (H_w is in Pa m, M in m^3).
    pub eigenvalues: Vec<f64>,
}

/// Weights and gradients at N query points for the m + 1 modes, row-major by point.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SkinningWeights {
    /// Number of modes (m + 1), the row length.
    pub modes: usize,
    /// W_j(X_i) at `values[i * modes + j]`, m^(-3/2) (the normalization c^T M c = I makes
    /// the integral of W_j^2 over the object equal 1).
    pub values: Vec<f64>,
    /// grad W_j(X_i) at `gradients[i * modes + j]`, m^(-5/2).
    pub gradients: Vec<[f64; 3]>,
}

impl SkinningWeights {
    /// Number of query points N.
    pub fn points(&self) -> usize {
        self.values.len().checked_div(self.modes).unwrap_or(0)
    }
    /// The m + 1 weights at point i.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.values[i * self.modes..(i + 1) * self.modes]
    }
    /// The m + 1 weight gradients at point i.
    pub fn gradient_row(&self, i: usize) -> &[[f64; 3]] {
        &self.gradients[i * self.modes..(i + 1) * self.modes]
    }
}

impl Basis {
    /// Number of modes m + 1 (the constant mode included).
    pub fn modes(&self) -> usize {
        self.coefficients.ncols()
    }

    /// W(X) and grad W(X) at `queries` (N x 3, metres). Every query point must be covered by
    /// kernels with a well-conditioned moment matrix (points inside or near the sampled object
    /// are); otherwise an [`Error::Coverage`] names the worst point.
    ///
    /// The shape functions are evaluated a chunk of (Morton-ordered) queries at a time and
    /// dropped, so memory beyond the N x (m + 1) result is one chunk's; each point's weights
    /// are the same as from one evaluation of all points.
    pub fn weights(&self, queries: &[Point3]) -> Result<SkinningWeights> {
        crate::error::check_finite_points("query points", queries)?;
        let opts = ShapeFunctionOptions::default();
        let modes = self.modes();
        let c = &self.coefficients;
        if c.nrows() != self.kernels.len() {
            return Err(Error::LengthMismatch {
                what: "basis coefficients (rows)",
                expected: self.kernels.len(),
                got: c.nrows(),
            });
        }
        let n = queries.len();
        let mut order: Vec<usize> = (0..n).collect();
        morton_order(queries, &mut order);
        let mut values = vec![0.0; n * modes];
        let mut gradients = vec![[0.0; 3]; n * modes];
        let mut stats = rkpm::ChunkedStats::default();
        let mut w = Vec::new();
        let mut g = Vec::new();
        for ids in order.chunks(rkpm::CHUNK_POINTS) {
            let pts: Vec<Point3> = ids.iter().map(|&i| queries[i]).collect();
            let (sf, st, _) = rkpm::evaluate_chunk(&self.kernels, &pts, &opts);
            stats.add(&sf, &st, |i| ids[i]);
            if stats.any_failed() {
                continue;
            }
            w.clear();
            w.resize(ids.len() * modes, 0.0);
            g.clear();
            g.resize(ids.len() * modes, [0.0; 3]);
            w.par_chunks_mut(modes.max(1))
                .zip(g.par_chunks_mut(modes.max(1)))
                .enumerate()
                .for_each(|(i, (w, g))| {
                    for e in sf.pattern.ptr[i]..sf.pattern.ptr[i + 1] {
                        let k = sf.pattern.kernels[e] as usize;
                        let (f, d) = (sf.phi[e], sf.grad[e]);
                        for j in 0..modes {
                            let ckj = c[(k, j)];
                            w[j] += f * ckj;
                            g[j][0] += d[0] * ckj;
                            g[j][1] += d[1] * ckj;
                            g[j][2] += d[2] * ckj;
                        }
                    }
                });
            for (r, &i) in ids.iter().enumerate() {
                let (src, dst) = (r * modes..(r + 1) * modes, i * modes..(i + 1) * modes);
                values[dst.clone()].copy_from_slice(&w[src.clone()]);
                gradients[dst].copy_from_slice(&g[src]);
            }
        }
        stats.coverage_error(|i| queries[i], opts.min_rcond)?;
        Ok(SkinningWeights {
            modes,
            values,
            gradients,
        })
    }
}
