//! Weighted moments of the deformation map over a point set, and the block products that
//! apply them to z.
//!
//! Every point position is x = X + B z with B = I_3 (x) b^T, b[4 j + a] = W_j(X) Xh_a, so a
//! weighted sum of |x - target|^2 over fixed points is a quadratic in z whose coefficients
//! are the moments sum c b b^T, sum c b Xh^T and sum c Xh Xh^T, computed once.

use crate::precompute::skinning::SkinningWeights;
use crate::sim::elastic::Layout;
use crate::Point3;
use faer::prelude::ReborrowMut;
use faer::{Accum, Mat, MatMut, MatRef, Par};

/// Weighted moments of the map b over a point set.
#[derive(Debug, Clone)]
pub struct Moments {
    /// sum c b b^T, 4 (m + 1) square.
    pub bb: Mat<f64>,
    /// sum c b Xh^T, 4 (m + 1) x 4.
    pub bx: Mat<f64>,
    /// sum c Xh Xh^T, 4 x 4.
    pub xx: [[f64; 4]; 4],
    /// sum c b, 4 (m + 1).
    pub b: Vec<f64>,
    /// sum c.
    pub total: f64,
}

/// Rows of b for `points` (row i = b(X_i), 4 (m + 1) entries), each scaled by `scale[i]`.
fn b_rows(points: &[Point3], w: &SkinningWeights, idx: &[usize], scale: &[f64]) -> Mat<f64> {
    let nh = w.modes;
    Mat::from_fn(idx.len(), 4 * nh, |p, col| {
        let i = idx[p];
        let (j, a) = (col / 4, col % 4);
        let xa = if a == 3 { 1.0 } else { points[i][a] };
        scale[p] * w.values[i * nh + j] * xa
    })
}

impl Moments {
    /// Moments over the points `idx` of `points` with non-negative weights `coef` (one per
    /// index); `w` holds the skinning weights of all `points`.
    pub fn new(points: &[Point3], w: &SkinningWeights, idx: &[usize], coef: &[f64]) -> Moments {
        let n4 = 4 * w.modes;
        let mut bb = Mat::<f64>::zeros(n4, n4);
        let mut bx = Mat::<f64>::zeros(n4, 4);
        let mut xx = [[0.0; 4]; 4];
        let mut b = vec![0.0; n4];
        // Blocks of rows keep the dense scratch small for millions of points.
        for (ids, cs) in idx.chunks(4096).zip(coef.chunks(4096)) {
            let sq: Vec<f64> = cs.iter().map(|c| c.max(0.0).sqrt()).collect();
            let rows = b_rows(points, w, ids, &sq);
            faer::linalg::matmul::matmul(
                bb.as_mut(),
                Accum::Add,
                rows.transpose(),
                rows.as_ref(),
                1.0,
                Par::rayon(0),
            );
            let xh = Mat::from_fn(ids.len(), 4, |p, a| {
                sq[p] * if a == 3 { 1.0 } else { points[ids[p]][a] }
            });
            faer::linalg::matmul::matmul(
                bx.as_mut(),
                Accum::Add,
                rows.transpose(),
                xh.as_ref(),
                1.0,
                Par::Seq,
            );
            for (p, (&i, &c)) in ids.iter().zip(cs).enumerate() {
                let x = points[i];
                let h = [x[0], x[1], x[2], 1.0];
                for a in 0..4 {
                    for q in 0..4 {
                        xx[a][q] += c * h[a] * h[q];
                    }
                }
                for (col, bc) in b.iter_mut().enumerate() {
                    *bc += sq[p] * rows[(p, col)];
                }
            }
        }
        // Exact symmetry.
        for i in 0..n4 {
            for j in 0..i {
                let v = 0.5 * (bb[(i, j)] + bb[(j, i)]);
                bb[(i, j)] = v;
                bb[(j, i)] = v;
            }
        }
        Moments {
            bb,
            bx,
            xx,
            b,
            total: coef.iter().sum(),
        }
    }
}

/// y += A x for the n4 x n4 matrix A applied to each row block of z.
pub fn add_block_product(layout: Layout, a: &Mat<f64>, scale: f64, z: &[f64], y: &mut [f64]) {
    let n4 = layout.row_len();
    for r in 0..3 {
        let zr = &z[r * n4..(r + 1) * n4];
        let yr = &mut y[r * n4..(r + 1) * n4];
        for (j, zj) in zr.iter().enumerate() {
            if *zj != 0.0 {
                let col = a.col(j);
                for (i, yi) in yr.iter_mut().enumerate() {
                    *yi += scale * col[i] * zj;
                }
            }
        }
    }
}

/// Add sum_p (b_p b_p^T) (x) H_p to `target` (3 n4 x 3 n4, the layout of z): its block (r, s)
/// (n4 x n4) gains B^T diag(H_p[r][s]) B, one matrix product per block, with B = `rows`
/// (P x n4, row p = b_p) and H_p = `blocks[p]` (3 x 3). Blocks zero for every p are skipped.
pub fn add_outer_blocks(
    mut target: MatMut<'_, f64>,
    rows: MatRef<'_, f64>,
    blocks: &[crate::linalg3::Mat3],
) {
    let n4 = rows.ncols();
    for r in 0..3 {
        for s in 0..3 {
            if blocks.iter().all(|m| m[r][s] == 0.0) {
                continue;
            }
            let scaled = Mat::from_fn(rows.nrows(), n4, |p, k| blocks[p][r][s] * rows[(p, k)]);
            faer::linalg::matmul::matmul(
                target.rb_mut().submatrix_mut(r * n4, s * n4, n4, n4),
                Accum::Add,
                rows.transpose(),
                scaled.as_ref(),
                1.0,
                Par::Seq,
            );
        }
    }
}

/// Add `scale` x A to each diagonal block of the 12 (m + 1) square matrix `h`.
pub fn add_block_diagonal(layout: Layout, a: &Mat<f64>, scale: f64, h: &mut Mat<f64>) {
    let n4 = layout.row_len();
    for r in 0..3 {
        for j in 0..n4 {
            for i in 0..n4 {
                h[(r * n4 + i, r * n4 + j)] += scale * a[(i, j)];
            }
        }
    }
}
