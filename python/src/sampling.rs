//! `freeform.sample`: integration points of a shape as NumPy arrays (the "points from a
//! mesh" step of a Kaolin-style workflow).

use crate::basis::run_released;
use crate::convert::{array1, points_array};
use crate::errors::invalid;
use freeform::geometry::ShapeOptions;
use freeform::options::Front;
use freeform::precompute::sample_shape;
use freeform::precompute::sampling::{CloudVolumeOptions, Resolution};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;

/// Points (N x 3) and volumes (N) as NumPy arrays.
type PointsAndVolumes<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

/// Points inside a shape and their volumes: ``(points (N, 3) metres, volumes (N,) m^3)``.
/// A regular grid inside primitives and watertight meshes (``points``: about how many;
/// ``spacing``: the grid step, metres; default 20,000 points), a point cloud's own points
/// (downsampled to ``points``) with voxel-fill volumes.
#[pyfunction]
#[pyo3(signature = (shape, *, points = None, spacing = None, allow_open_mesh = false))]
pub fn sample<'py>(
    py: Python<'py>,
    shape: &str,
    points: Option<i128>,
    spacing: Option<f64>,
    allow_open_mesh: bool,
) -> PyResult<PointsAndVolumes<'py>> {
    let points = points
        .map(|n| crate::convert::count(py, n, "points", freeform::precompute::MAX_POINTS))
        .transpose()?;
    let resolution = match (points, spacing) {
        (Some(_), Some(_)) => {
            return Err(invalid(
                py,
                "give either points (a count) or spacing (metres), not both",
            ))
        }
        (Some(n), None) => Resolution::Count(n),
        (None, Some(h)) => Resolution::Spacing(h),
        (None, None) => Resolution::Count(20_000),
    };
    let ip = run_released(py, Front::Python, false, |_| {
        let s = freeform::io::read_shape(
            shape,
            &ShapeOptions {
                allow_open_mesh,
                ..ShapeOptions::default()
            },
        )?;
        sample_shape(&s, resolution, &CloudVolumeOptions::default())
    })?;
    Ok((points_array(py, &ip.points), array1(py, ip.volumes)))
}
