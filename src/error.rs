//! The library's error type. Each stage has a small, precise error enum of its own; [`Error`]
//! wraps them so callers of the whole pipeline match on one type.

use std::path::PathBuf;

pub use crate::eigen::EigenError;
pub use crate::fem::FemError;
pub use crate::geometry::GeometryError;

/// Result alias used across the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in the freeform pipeline.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading or parsing a shape, mesh or point file failed, or the shape is unusable.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// The eigensolver failed (see the inner error; it may carry partial results).
    #[error(transparent)]
    Eigen(#[from] EigenError),
    /// The FEM reference failed: mesh file, mesh validity, Newton, or trajectory shapes.
    #[error(transparent)]
    Fem(#[from] FemError),
    /// A user parameter is out of its valid range.
    #[error("invalid {name} = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name as the user sees it (CLI flag or field name).
        name: &'static str,
        /// The offending value, formatted.
        value: String,
        /// What is wrong and what to do about it.
        reason: String,
    },
    /// Input arrays contain NaN or infinite values.
    #[error("{what} has a non-finite value (NaN or Inf) at index {index}; clean the input")]
    NonFinite {
        /// Which input (e.g. "integration points").
        what: &'static str,
        /// First offending row.
        index: usize,
    },
    /// Input arrays disagree in length.
    #[error("{what}: expected {expected} entries, got {got}")]
    LengthMismatch {
        /// Which input.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// Some points are not covered by enough kernels for a well-conditioned moment matrix.
    #[error(
        "{count} point(s) are not covered by enough kernels (worst at index {index}, \
         position [{:.6e}, {:.6e}, {:.6e}], {covering} covering kernel(s), reciprocal condition \
         number {rcond:.3e} < {min_rcond:.1e}); increase the support factor (--support), the \
         number of kernels, or check for isolated points", position[0], position[1], position[2]
    )]
    Coverage {
        /// Number of points whose moment matrix failed the check.
        count: usize,
        /// Index of the worst point.
        index: usize,
        /// Position of the worst point, metres.
        position: [f64; 3],
        /// Kernels covering the worst point.
        covering: usize,
        /// Reciprocal condition number of its moment matrix (0 when singular).
        rcond: f64,
        /// The threshold that was applied.
        min_rcond: f64,
    },
    /// File input/output failed.
    #[error("{path}: {source}")]
    Io {
        /// File involved.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// A scene description is malformed or inconsistent.
    #[error("scene: {message}")]
    Scene {
        /// What is wrong, with the line and column for parse errors.
        message: String,
    },
    /// Setting up one object of a scene failed: the object's index and name around the
    /// stage's own error (match on `source` for, e.g., a [`Error::Coverage`] of object 2).
    #[error("scene: object '{name}': {source}")]
    Object {
        /// Index of the object in the scene (`[[object]]` order, from 0).
        index: usize,
        /// The object's name.
        name: String,
        /// What went wrong.
        source: Box<Error>,
    },
    /// A basis file is malformed or from an incompatible version.
    #[error("{path}: not a valid freeform basis file: {reason}")]
    BasisFile {
        /// File involved.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// An array of a basis file decompresses to more bytes than it can legitimately hold (a
    /// damaged archive or a "zip bomb"); see [`crate::io::basis`] for the limits.
    #[error(
        "{path}: array `{array}` of the basis file is larger than its limit of {limit} bytes \
         (the archive declares {declared} bytes); the file is damaged or not a freeform basis"
    )]
    BasisArrayTooLarge {
        /// File involved.
        path: PathBuf,
        /// The array (zip entry without `.npy`), e.g. `coefficients`.
        array: &'static str,
        /// The limit that was exceeded: `.npy` header allowance plus the most data the array
        /// can hold, bytes.
        limit: u64,
        /// The uncompressed size the archive declares for the entry, bytes (a damaged or
        /// hostile archive may understate it).
        declared: u64,
    },
    /// `--strict` (or `strict: true` in the settings) was asked for and a monitor raised a
    /// warning: poor conditioning, a non-converged solve, a failed line search.
    #[error("strict mode: {} warning(s), the first: {}", warnings.len(), warnings.first().map(String::as_str).unwrap_or("-"))]
    Strict {
        /// Every warning raised up to the point where the run stopped.
        warnings: Vec<String>,
    },
}

impl Error {
    /// Shorthand for [`Error::InvalidParameter`].
    pub fn param(
        name: &'static str,
        value: impl std::fmt::Display,
        reason: impl Into<String>,
    ) -> Self {
        Error::InvalidParameter {
            name,
            value: value.to_string(),
            reason: reason.into(),
        }
    }
}

/// `Err(Error::Strict)` when `strict` is set and `warnings` is not empty.
pub fn check_strict(strict: bool, warnings: &[String]) -> Result<()> {
    if strict && !warnings.is_empty() {
        return Err(Error::Strict {
            warnings: warnings.to_vec(),
        });
    }
    Ok(())
}

/// Check that every coordinate of `points` is finite.
pub fn check_finite_points(what: &'static str, points: &[[f64; 3]]) -> Result<()> {
    match points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        Some(index) => Err(Error::NonFinite { what, index }),
        None => Ok(()),
    }
}
