//! From a loss on positions to a loss on z: the deformation map x = X + B(X) z is linear in
//! z, so dL/dz = B^T dL/dx.

use crate::precompute::skinning::SkinningWeights;
use crate::sim::elastic::Layout;
use crate::{Error, Point3, Result};

/// dL/dz (12 (m + 1)) from dL/dx at points with rest positions `rest` (N x 3, metres) and
/// skinning weights `w` (values used), `dl_dx` N x 3 (the loss's unit per metre): the
/// transpose of [`crate::sim::deformation::map_points`]. Any point set the object maps
/// (integration points, render points, mesh vertices, splat centres) will do.
pub fn positions_adjoint(
    layout: Layout,
    rest: &[Point3],
    w: &SkinningWeights,
    dl_dx: &[Point3],
) -> Result<Vec<f64>> {
    if dl_dx.len() != rest.len() || w.points() != rest.len() {
        return Err(Error::Gradient(format!(
            "a loss gradient on positions needs one 3-vector per point: {} points, {} weight \
             rows, {} gradient rows",
            rest.len(),
            w.points(),
            dl_dx.len()
        )));
    }
    if w.modes != layout.handles {
        return Err(Error::Gradient(format!(
            "the weights have {} handles, the object {}",
            w.modes, layout.handles
        )));
    }
    if let Some(i) = dl_dx.iter().position(|g| g.iter().any(|v| !v.is_finite())) {
        return Err(Error::Gradient(format!(
            "the loss gradient at point {i} is not finite: {:?}",
            dl_dx[i]
        )));
    }
    let nh = layout.handles;
    let mut out = vec![0.0; layout.dofs()];
    for (i, (x, g)) in rest.iter().zip(dl_dx).enumerate() {
        let xh = [x[0], x[1], x[2], 1.0];
        for j in 0..nh {
            let wj = w.values[i * nh + j];
            for (r, gr) in g.iter().enumerate() {
                let o = layout.index(r, j, 0);
                for (a, xa) in xh.iter().enumerate() {
                    out[o + a] += wj * xa * gr;
                }
            }
        }
    }
    Ok(out)
}
