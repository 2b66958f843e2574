//! The deformation map of a reduced state away from the integration points:
//! x(X) = X + sum_j W_j(X) Z_j [X; 1] (the handles Z_j are 3 x 4 blocks of z, stored relative
//! to the identity; [`Layout::index`]) and its gradient
//! F(X) = I + sum_j (W_j(X) Z_j[:, 0..3] + (Z_j [X; 1]) grad W_j(X)^T)
//! at any points whose skinning weights and gradients are known (render points, splat centres).

use crate::linalg3::Mat3;
use crate::precompute::skinning::SkinningWeights;
use crate::sim::elastic::Layout;
use crate::Point3;
use rayon::prelude::*;

/// Deformation gradients F(X_i), dimensionless, of the map of state `z` (12 (m + 1)) at rest
/// points `rest` (N x 3, metres) with skinning weights and gradients `w` (N points,
/// `w.modes == layout.handles`). Row-major 3 x 3: `f[r][c] = d x_r / d X_c`. The same formula
/// as the elastic term's F at its cubature points.
pub fn deformation_gradients(
    layout: Layout,
    z: &[f64],
    rest: &[Point3],
    w: &SkinningWeights,
) -> Vec<Mat3> {
    let nh = layout.handles;
    rest.par_iter()
        .enumerate()
        .map(|(i, x)| {
            let mut f = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
            for j in 0..nh {
                let wj = w.values[i * nh + j];
                let g = w.gradients[i * nh + j];
                for (r, fr) in f.iter_mut().enumerate() {
                    let o = layout.index(r, j, 0);
                    let zz = &z[o..o + 4];
                    let y = zz[0] * x[0] + zz[1] * x[1] + zz[2] * x[2] + zz[3];
                    fr[0] += g[0] * y + wj * zz[0];
                    fr[1] += g[1] * y + wj * zz[1];
                    fr[2] += g[2] * y + wj * zz[2];
                }
            }
            f
        })
        .collect()
}

/// B(X) z = sum_j w_j Z_j [X; 1] for one point: the displacement, metres, of rest position
/// `x` (metres) with skinning weights `w` (m + 1) under the state (or state change) `z`
/// (three rows of `row_len` = 4 (m + 1) entries, [`Layout::row_len`]).
pub fn skinned_offset(x: Point3, w: &[f64], z: &[f64], row_len: usize) -> Point3 {
    std::array::from_fn(|r| {
        let row = &z[r * row_len..(r + 1) * row_len];
        w.iter()
            .zip(row.chunks_exact(4))
            .map(|(wj, zj)| wj * (zj[0] * x[0] + zj[1] * x[1] + zj[2] * x[2] + zj[3]))
            .sum()
    })
}

/// x(X) = X + B(X) z for one point ([`skinned_offset`]), metres.
pub fn skinned_position(x: Point3, w: &[f64], z: &[f64], row_len: usize) -> Point3 {
    let d = skinned_offset(x, w, z, row_len);
    [x[0] + d[0], x[1] + d[1], x[2] + d[2]]
}

/// x(X_i) = X_i + sum_j W_j(X_i) Z_j [X_i; 1], metres, for rest points `rest` (N x 3,
/// metres) with skinning weights `w` (N points) under state `z` (12 (m + 1)): the deformed
/// render points and splat centres. Each coordinate accumulates from X_i handle by handle
/// (the frames' bits depend on that order; [`skinned_position`] sums the offset first).
pub fn map_points(layout: Layout, z: &[f64], rest: &[Point3], w: &SkinningWeights) -> Vec<Point3> {
    let nh = layout.handles;
    rest.par_iter()
        .enumerate()
        .map(|(i, x)| {
            let mut y = *x;
            for j in 0..nh {
                let wj = w.values[i * nh + j];
                for (r, yr) in y.iter_mut().enumerate() {
                    let o = layout.index(r, j, 0);
                    *yr += wj * (z[o] * x[0] + z[o + 1] * x[1] + z[o + 2] * x[2] + z[o + 3]);
                }
            }
            y
        })
        .collect()
}
