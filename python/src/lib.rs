//! Python bindings of freeform: `freeform._native`, re-exported by the `freeform` package
//! (python/freeform/__init__.py). Guide: docs/python.md.

mod basis;
mod convert;
mod eigen;
mod errors;
mod fem;
mod gradient;
mod progress;
mod sampling;
mod usd;
mod world;

use pyo3::prelude::*;

/// The compiled part of the `freeform` package.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<basis::PyBasis>()?;
    m.add_class::<world::PyScene>()?;
    m.add_class::<world::PyWorld>()?;
    m.add_class::<gradient::PyRecording>()?;
    m.add_function(wrap_pyfunction!(fem::beam_reference, m)?)?;
    m.add_function(wrap_pyfunction!(gradient::map_points, m)?)?;
    m.add_function(wrap_pyfunction!(gradient::positions_adjoint, m)?)?;
    m.add_function(wrap_pyfunction!(sampling::sample, m)?)?;
    m.add_function(wrap_pyfunction!(eigen::eigsh, m)?)?;
    m.add_function(wrap_pyfunction!(usd::read_usd_kaolin, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
