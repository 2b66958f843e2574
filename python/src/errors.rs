//! The library's errors as Python exceptions (classes defined in `freeform/_errors.py`).

use freeform::eigen::EigenError;
use freeform::error::{FemError, GeometryError};
use freeform::Error;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// The Python class for a library error.
fn class_name(e: &Error) -> &'static str {
    match e {
        Error::Object { source, .. } | Error::Collider { source, .. } => class_name(source),
        Error::Coverage { .. } => "CoverageError",
        Error::Io { .. } | Error::BasisFile { .. } | Error::BasisArrayTooLarge { .. } => {
            "FreeformIOError"
        }
        Error::Geometry(GeometryError::Io { .. }) | Error::Fem(FemError::Io { .. }) => {
            "FreeformIOError"
        }
        Error::Eigen(
            EigenError::InvalidRequest(_)
            | EigenError::TooLarge { .. }
            | EigenError::Operator { .. }
            | EigenError::NonFinite(_)
            | EigenError::NotPositiveDefinite { .. },
        ) => "InvalidInputError",
        Error::Eigen(_) => "NotConvergedError",
        Error::Fem(FemError::NotConverged { .. } | FemError::LineSearch { .. }) => {
            "NotConvergedError"
        }
        Error::Strict { .. } => "StrictModeError",
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

/// A library error as the matching `freeform` exception with the library's message.
pub fn to_py(py: Python<'_>, e: &Error) -> PyErr {
    raise(py, class_name(e), e.to_string())
}

/// An invalid-input exception (a bad argument caught in the binding itself).
pub fn invalid(py: Python<'_>, message: impl Into<String>) -> PyErr {
    raise(py, "InvalidInputError", message.into())
}
