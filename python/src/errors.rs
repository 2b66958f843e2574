//! The library's errors as Python exceptions (classes defined in `freeform/_errors.py`).

use freeform::options::Front;
use freeform::{Error, ErrorKind};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// The Python class for a library error, from its kind ([`Error::kind`]).
fn class_name(e: &Error) -> &'static str {
    match e.kind() {
        ErrorKind::Coverage => "CoverageError",
        ErrorKind::Io => "FreeformIOError",
        ErrorKind::NotConverged => "NotConvergedError",
        ErrorKind::Strict => "StrictModeError",
        // A caller's operator that fails or returns unusable values is the caller's input.
        _ => "InvalidInputError",
    }
}

/// An exception of class `class` (a name in `freeform._errors`) with `message`.
pub fn raise(py: Python<'_>, class: &str, message: String) -> PyErr {
    let made = py
        .import("freeform._errors")
        .and_then(|m| m.getattr(class))
        .and_then(|cls| cls.call1((message.clone(),)));
    match made {
        Ok(exc) => PyErr::from_value(exc),
        // The package is broken (its _errors module missing): still say what went wrong.
        Err(_) => PyRuntimeError::new_err(message),
    }
}

/// A library error as the matching `freeform` exception, its message naming options as
/// `front` does.
pub fn to_py_in(py: Python<'_>, e: &Error, front: Front) -> PyErr {
    raise(py, class_name(e), front.render(e))
}

/// A library error of the `Basis` builders and `eigsh`: options named by their keywords.
pub fn to_py(py: Python<'_>, e: &Error) -> PyErr {
    to_py_in(py, e, Front::Python)
}

/// A library error of `Scene` and `World`: options named by their scene keys.
pub fn scene_to_py(py: Python<'_>, e: &Error) -> PyErr {
    to_py_in(py, e, Front::Scene)
}

/// An invalid-input exception (a bad argument caught in the binding itself).
pub fn invalid(py: Python<'_>, message: impl Into<String>) -> PyErr {
    raise(py, "InvalidInputError", message.into())
}
