//! `freeform.beam_reference`: the beam benchmark's FEM reference (design.md section 3) as
//! arrays, computed once and cached, for comparisons and inverse problems in Python.

use crate::basis::run_released;
use crate::convert::{array2, points_array};
use crate::errors::invalid;
use freeform::fem::beam::{run_beam_reference, BeamTest, FemBeamConfig};
use freeform::options::Front;
use numpy::PyArrayMethods;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// The FEM reference of the beam test ``test`` ("bend" or "twist"): quadratic tets at 4
/// cubes per metre (the recommended reference; 3-8 minutes on 2 cores, then read from
/// ``cache_dir`` if given). Returns a dict: ``rest`` (N, 3) node positions, ``frames``
/// (steps, N, 3) node positions after each step (metres), ``youngs``, ``poisson``,
/// ``density``, ``dt``, ``steps``, ``size`` (3), ``gravity`` (3), ``held_length`` (nodes
/// with x <= it are held), ``twist_length``, ``twist_degrees``.
#[pyfunction]
#[pyo3(signature = (test = "bend", *, cache_dir = None, progress = false))]
pub fn beam_reference<'py>(
    py: Python<'py>,
    test: &str,
    cache_dir: Option<PathBuf>,
    progress: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let test: BeamTest = freeform::names::from_name(test)
        .ok_or_else(|| invalid(py, format!("test = {test:?}: give \"bend\" or \"twist\"")))?;
    let config = FemBeamConfig::reference(test);
    let reference = run_released(py, Front::Python, progress, |p| {
        run_beam_reference(&config, cache_dir.as_deref(), p)
    })?;
    let n = reference.rest.len();
    let frames: Vec<f64> = reference
        .frames
        .iter()
        .flatten()
        .flatten()
        .copied()
        .collect();
    let steps = reference.frames.len();
    let d = PyDict::new(py);
    d.set_item("rest", points_array(py, &reference.rest))?;
    d.set_item(
        "frames",
        array2(py, frames, steps * n, 3).reshape([steps, n, 3])?,
    )?;
    d.set_item("youngs", config.material.youngs)?;
    d.set_item("poisson", config.material.poisson)?;
    d.set_item("density", config.material.density)?;
    d.set_item("dt", config.solver.dt)?;
    d.set_item("steps", config.steps)?;
    d.set_item("size", config.size.to_vec())?;
    d.set_item("gravity", config.solver.gravity.to_vec())?;
    d.set_item("held_length", config.held_length)?;
    d.set_item("twist_length", config.twist_length)?;
    d.set_item("twist_degrees", config.twist_degrees)?;
    Ok(d)
}
