//! The library's error type. Each stage has a small, precise error enum of its own; [`Error`]
//! wraps them so callers of the whole pipeline match on one type.
//!
//! Every stage returns [`Error`], so this module sits below the stages: it defines the stage
//! error enums that carry only paths, text and numbers ([`GeometryError`], [`FemError`]; their
//! stages re-export them as `geometry::GeometryError` and `fem::FemError`). The one exception
//! is [`EigenError`], which keeps the eigensolver's partial result
//! ([`crate::eigen::EigenSolution`]) and so is defined in [`crate::eigen`]: `error` imports
//! `eigen`, and `eigen` (with the modules it imports) must never use [`Error`]
//! (`tests/integration/architecture.rs` checks that the module graph has no circles).

use std::path::PathBuf;

pub use crate::eigen::EigenError;
use crate::options::OptionName;
use crate::report::Warning;

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
    /// An option of the option table has a value it does not take (an unknown name of a
    /// choice); the option is named as the front end that prints the message names it
    /// ([`crate::options::Front`]).
    #[error("invalid {option} = {value}: {reason}")]
    InvalidOption {
        /// The option.
        option: &'static OptionName,
        /// The offending value, formatted.
        value: String,
        /// What is wrong and what to do about it.
        reason: String,
    },
    /// Two options that exclude each other were both given (integration points as a count
    /// and as a spacing).
    #[error("give either {first} or {second}, not both")]
    ConflictingOptions {
        /// The option given first in the option table.
        first: &'static OptionName,
        /// The one it excludes.
        second: &'static OptionName,
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
         number {rcond:.3e} < {min_rcond:.1e}); increase the support factor ({}), the number \
         of kernels, or check for isolated points",
        position[0], position[1], position[2], crate::options::SUPPORT_FACTOR
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
    /// A collider of a scene is unusable: its index (`[[collider]]` order, from 0) and name
    /// around the cause (a bad number, a mesh file that cannot be used).
    #[error("scene: collider {index}{}: {source}", name.as_ref().map(|n| format!(" '{n}'")).unwrap_or_default())]
    Collider {
        /// Index of the collider in the scene.
        index: usize,
        /// Its name, if it has one.
        name: Option<String>,
        /// What went wrong.
        source: Box<Error>,
    },
    /// A boundary condition of an object is unusable: its index (`[[object.boundary]]` order,
    /// from 0) around the cause (a bad region or motion).
    #[error("boundary {index}: {source}")]
    Boundary {
        /// Index of the boundary in its object.
        index: usize,
        /// What went wrong.
        source: Box<Error>,
    },
    /// A named material of a scene (`[materials.NAME]`) is invalid.
    #[error("scene: material '{name}': {source}")]
    NamedMaterial {
        /// The material's name.
        name: String,
        /// What is wrong with it.
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
    /// The precomputation would not fit in memory: refused before it starts
    /// ([`crate::precompute::memory`]).
    #[error(
        "the precomputation would need about {:.1} GB ({breakdown}) but {:.1} GB is available \
         ({limit_from}); {advice}",
        *estimate_bytes as f64 / 1e9,
        *available_bytes as f64 / 1e9
    )]
    OutOfMemory {
        /// Estimated peak resident memory, bytes.
        estimate_bytes: u64,
        /// Memory available to the run, bytes.
        available_bytes: u64,
        /// Where the available figure comes from (MemAvailable, or the limit set).
        limit_from: String,
        /// The estimate by part, formatted.
        breakdown: String,
        /// How to make the run smaller.
        advice: String,
    },
    /// Gradients cannot be taken of this run as asked (an unconverged or inverted step, a
    /// recording that no longer matches its object, a loss gradient of the wrong shape, a
    /// tape that would not fit in memory); the message says which and what to do.
    #[error("gradients: {0}")]
    Gradient(String),
    /// The caller's [`crate::progress::Progress::cancelled`] asked the work to stop.
    #[error("cancelled by the caller during {stage}")]
    Cancelled {
        /// The stage that was running (e.g. "shape functions", "eigen (lobpcg)").
        stage: String,
    },
    /// `--strict` (or `strict: true` in the settings) was asked for and a monitor raised a
    /// warning: poor conditioning, a non-converged solve, a failed line search.
    #[error("strict mode: {} warning(s), the first: {}", warnings.len(), warnings.first().map_or_else(|| "-".to_string(), ToString::to_string))]
    Strict {
        /// Every warning raised up to the point where the run stopped.
        warnings: Vec<Warning>,
    },
}

/// What kind of failure an [`Error`] is: the one classification every front end maps from
/// (the C status codes, the Python exception classes, the CLI's messages), so the same error
/// is the same kind everywhere. Stable: variants are only added.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum ErrorKind {
    /// A parameter, array, shape, scene or request is invalid, or the run would not fit in
    /// memory: fix the input (the message says which and how).
    InvalidInput,
    /// A file could not be read or written, or is not a valid file of its kind (a damaged
    /// basis file).
    Io,
    /// Points are not covered by enough RKPM kernels.
    Coverage,
    /// An iterative solver (the eigensolver, the FEM reference's Newton) did not converge or
    /// broke down, or its backend library failed.
    NotConverged,
    /// The operators given to the eigensolver failed or are unusable: a caller's callback
    /// reported an error or returned NaN, or M is not positive definite.
    BadOperator,
    /// Strict mode stopped at a warning.
    Strict,
    /// The caller asked the work to stop.
    Cancelled,
}

impl Error {
    /// The kind of failure ([`ErrorKind`]); an object's or a collider's error is the kind of
    /// its cause.
    pub fn kind(&self) -> ErrorKind {
        match self {
            Error::Object { source, .. }
            | Error::Collider { source, .. }
            | Error::Boundary { source, .. }
            | Error::NamedMaterial { source, .. } => source.kind(),
            Error::Coverage { .. } => ErrorKind::Coverage,
            Error::Io { .. } | Error::BasisFile { .. } | Error::BasisArrayTooLarge { .. } => {
                ErrorKind::Io
            }
            Error::Geometry(GeometryError::Io { .. }) | Error::Fem(FemError::Io { .. }) => {
                ErrorKind::Io
            }
            Error::Fem(FemError::NotConverged { .. } | FemError::LineSearch { .. }) => {
                ErrorKind::NotConverged
            }
            Error::Eigen(e) => match e {
                EigenError::InvalidRequest(_)
                | EigenError::TooLarge { .. }
                | EigenError::SlepcUnavailable => ErrorKind::InvalidInput,
                EigenError::Operator { .. }
                | EigenError::NonFinite(_)
                | EigenError::NotPositiveDefinite { .. } => ErrorKind::BadOperator,
                EigenError::Cancelled { .. } => ErrorKind::Cancelled,
                _ => ErrorKind::NotConverged,
            },
            Error::Strict { .. } => ErrorKind::Strict,
            Error::Cancelled { .. } => ErrorKind::Cancelled,
            _ => ErrorKind::InvalidInput,
        }
    }

    /// Shorthand for [`Error::InvalidParameter`].
    pub fn param(
        name: &'static str,
        value: impl std::fmt::Display,
        reason: impl Into<String>,
    ) -> Self {
        Error::InvalidParameter {
            name,
            value: readable_value(value.to_string()),
            reason: reason.into(),
        }
    }
}

/// Largest magnitude of an input quantity (a scene's numbers, materials, coordinates,
/// volumes, poses): 1e100. The library multiplies up to three inputs (a stiffness times a
/// squared length, a density times a volume times an acceleration), so inputs within
/// [`MIN_MAGNITUDE`]..=1e100 keep every such product inside f64's range (1e-308..1e308);
/// anything beyond is a typo or a unit mistake.
pub const MAX_MAGNITUDE: f64 = 1e100;

/// Smallest magnitude of a non-zero input quantity: 1e-100 (see [`MAX_MAGNITUDE`]).
pub const MIN_MAGNITUDE: f64 = 1e-100;

/// Whether `x` is finite and either 0 or of magnitude within
/// [`MIN_MAGNITUDE`]..=[`MAX_MAGNITUDE`].
pub fn in_range(x: f64) -> bool {
    x == 0.0 || (MIN_MAGNITUDE..=MAX_MAGNITUDE).contains(&x.abs())
}

/// `x` as people read it: Rust's plain form in 1e-4..1e16, scientific notation beyond (Rust
/// prints 1e300 as 301 digits).
pub fn readable_number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e16).contains(&x.abs()) {
        x.to_string()
    } else {
        format!("{x:e}")
    }
}

/// A displayed value, with a number too long to read (more than 20 characters) rewritten by
/// [`readable_number`].
fn readable_value(text: String) -> String {
    match text.parse::<f64>() {
        Ok(x) if text.len() > 20 => readable_number(x),
        _ => text,
    }
}

/// `Err(Error::Cancelled)` when `progress` asks to stop; `stage` names the work that was
/// running.
pub fn check_cancelled(progress: &dyn crate::progress::Progress, stage: &str) -> Result<()> {
    if progress.cancelled() {
        return Err(Error::Cancelled {
            stage: stage.to_string(),
        });
    }
    Ok(())
}

/// `Err(Error::Strict)` when `strict` is set and `warnings` is not empty.
pub fn check_strict(strict: bool, warnings: &[Warning]) -> Result<()> {
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

/// Geometry errors: reading files and unusable shapes (the geometry and shape-file stages' error,
/// also named [`crate::geometry::GeometryError`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GeometryError {
    /// The shape spec is neither a primitive nor a supported file.
    #[error(
        "unknown shape `{0}`: use box:LX,LY,LZ, sphere:R, or a path to a .obj, .stl, .off, .ply, \
         .nii or .nii.gz file"
    )]
    UnknownSpec(String),
    /// A primitive spec has bad numbers.
    #[error("bad shape `{spec}`: {reason}")]
    BadPrimitive {
        /// The spec as given.
        spec: String,
        /// What is wrong.
        reason: String,
    },
    /// The file could not be opened or read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The file content is malformed.
    #[error("{path}: {reason}")]
    Parse {
        /// File.
        path: PathBuf,
        /// What is wrong (with a line or element number where known).
        reason: String,
    },
    /// A USD stage that does not open, or a prim or attribute of it that cannot be read as
    /// asked (`<file>: <prim path>[.<attribute>]: <reason>`).
    #[error(
        "{path}: {prim}{}: {reason}",
        attribute.as_deref().map(|a| format!(".{a}")).unwrap_or_default()
    )]
    Usd {
        /// The stage file.
        path: PathBuf,
        /// The prim path (`/` for the stage itself).
        prim: String,
        /// The attribute, where one is at fault.
        attribute: Option<String>,
        /// What is wrong and what to do.
        reason: String,
    },
    /// The mesh is not closed.
    #[error(
        "{path}: mesh is not watertight ({boundary_edges} boundary edges, {nonmanifold_edges} \
         non-manifold edges); repair it, or pass {} to decide inside by winding number",
        crate::options::ALLOW_OPEN_MESH
    )]
    NotWatertight {
        /// File (`<in-memory mesh>` for meshes built with
        /// [`TriMesh::new`](crate::geometry::TriMesh::new)).
        path: PathBuf,
        /// Edges used by exactly one triangle.
        boundary_edges: usize,
        /// Edges used by more than two triangles.
        nonmanifold_edges: usize,
    },
    /// Two triangles that share an edge traverse it in the same direction, so the mesh has no
    /// consistent inside and outside.
    #[error(
        "{path}: mesh orientation is inconsistent ({misoriented_edges} edges are traversed in the \
         same direction by both of their triangles); fix the face winding, or pass {} to use \
         the winding number anyway",
        crate::options::ALLOW_OPEN_MESH
    )]
    Misoriented {
        /// File (`<in-memory mesh>` for meshes built with
        /// [`TriMesh::new`](crate::geometry::TriMesh::new)).
        path: PathBuf,
        /// Manifold edges whose two triangles disagree on orientation.
        misoriented_edges: usize,
    },
    /// The shape encloses no volume or has no points.
    #[error("{0}")]
    Degenerate(String),
    /// A voxel image's spacing is zero, negative, not finite or out of range (1e-100..1e100
    /// m), or its origin is not finite or out of range.
    #[error(
        "voxel spacing {spacing:?} m and origin {origin:?} m: the spacing must be > 0 and \
         between 1e-100 and 1e100 m on every axis and the origin finite, at most 1e100 m \
         (check the file's pixdim / sform and its units, or give spacing and origin in the \
         scene's [object.image] table)"
    )]
    ImageSpacing {
        /// Voxel edge per axis, metres, as found.
        spacing: [f64; 3],
        /// Centre of voxel [0, 0, 0], metres, as found.
        origin: [f64; 3],
    },
    /// A voxel of a modulus image holds NaN, an infinity, a negative value or one above
    /// 1e100 Pa (where the matrices overflow).
    #[error(
        "voxel {voxel:?} has Young's modulus {} Pa: moduli must be finite, >= 0 and at most \
         1e100 Pa (0 marks empty voxels); fix the image (are its units Pa?)",
        readable_number(*.value)
    )]
    ImageVoxel {
        /// The voxel's [i, j, k] (0-based).
        voxel: [usize; 3],
        /// Its value.
        value: f64,
    },
    /// A voxel image is unusable (no voxels, no filled voxel, wrong dimensionality or length,
    /// too large, unsupported orientation or data type).
    #[error("voxel image: {0}")]
    BadImage(String),
    /// A filled voxel holds a label the label map does not name.
    #[error(
        "voxel image label {label} (first at voxel {voxel:?}) has no material: add it to the \
         object's image.labels (label = \"material name\")"
    )]
    UnknownLabel {
        /// The label.
        label: i64,
        /// The first voxel holding it, [i, j, k] (0-based).
        voxel: [usize; 3],
    },
    /// An integration point inside the object (a mesh or primitive whose materials come from
    /// an image) falls outside the image or in an empty voxel, so it has no material.
    #[error(
        "material gap: integration point {point} at {position:?} m {where_}; extend the image \
         to cover the shape, map label 0 in image.labels, or set image.gaps = \"material\" to \
         give such points the object's material"
    )]
    MaterialGap {
        /// Index of the first such point.
        point: usize,
        /// Its position, metres.
        position: [f64; 3],
        /// Where it fell ("is outside the image" or "falls in empty voxel [i, j, k]").
        where_: String,
    },
    /// A collider mesh has a triangle of (near-)zero area, whose normal is undefined.
    #[error(
        "{path}: triangle {triangle} (0-based, in the file's triangle order) has zero area \
         (collinear or coincident corners); {count} of the {total} triangles are degenerate: \
         remove them from the collider mesh"
    )]
    DegenerateTriangle {
        /// File.
        path: PathBuf,
        /// The first degenerate triangle.
        triangle: usize,
        /// Degenerate triangles in all.
        count: usize,
        /// Triangles in the file.
        total: usize,
    },
    /// A solid collider mesh is not closed and consistently oriented.
    #[error(
        "{path}: a solid collider mesh must be closed and consistently oriented, and this one \
         has {boundary_edges} boundary, {nonmanifold_edges} non-manifold and \
         {misoriented_edges} misoriented edges; repair it, or use it as a one-sided surface \
         (sided = \"outside\")"
    )]
    ColliderNotClosed {
        /// File.
        path: PathBuf,
        /// Edges used by one triangle.
        boundary_edges: usize,
        /// Edges used by more than two triangles.
        nonmanifold_edges: usize,
        /// Edges whose two triangles disagree on orientation.
        misoriented_edges: usize,
    },
    /// A one-sided collider surface has no consistent free side.
    #[error(
        "{path}: a one-sided collider surface needs manifold, consistently oriented triangles \
         (its normals say which side is free), and this one has {nonmanifold_edges} \
         non-manifold and {misoriented_edges} misoriented edges"
    )]
    ColliderSurface {
        /// File.
        path: PathBuf,
        /// Edges used by more than two triangles.
        nonmanifold_edges: usize,
        /// Edges whose two triangles disagree on orientation.
        misoriented_edges: usize,
    },
    /// An argument to a geometry function (e.g. a writer) is inconsistent.
    #[error("invalid input: {0}")]
    InvalidInput(String),
}

impl GeometryError {
    /// Attach a file path to errors raised while building a shape from that file's content
    /// (`NotWatertight`, `Misoriented`, `Degenerate`); other variants are returned unchanged.
    pub fn with_path(self, path: &std::path::Path) -> GeometryError {
        match self {
            GeometryError::NotWatertight {
                boundary_edges,
                nonmanifold_edges,
                ..
            } => GeometryError::NotWatertight {
                path: path.to_path_buf(),
                boundary_edges,
                nonmanifold_edges,
            },
            GeometryError::Misoriented {
                misoriented_edges, ..
            } => GeometryError::Misoriented {
                path: path.to_path_buf(),
                misoriented_edges,
            },
            GeometryError::Degenerate(msg) => {
                GeometryError::Degenerate(format!("{}: {msg}", path.display()))
            }
            other => other,
        }
    }
}

/// Errors of the FEM stage: mesh files, mesh validity, the Newton solver, trajectories (also
/// named [`crate::fem::FemError`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FemError {
    /// A mesh file could not be parsed; `line` is 1-based (0 when the file ended early).
    #[error("{path}:{line}: {reason}")]
    Parse {
        /// File involved.
        path: PathBuf,
        /// 1-based line number of the offending token (0: unexpected end of file).
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// File involved.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The tetrahedral mesh is unusable (empty, bad index, non-finite or flat element).
    #[error("invalid tetrahedral mesh: {0}")]
    Mesh(String),
    /// Newton did not reach the tolerance within the iteration cap. The solver state holds
    /// the last iterate, so a caller may inspect it or continue.
    #[error(
        "Newton did not converge in step {step}: {iterations} iterations, last step \
         max |dx| = {step_norm:.3e} m (tolerance {tolerance:.3e} m), gradient max norm \
         {gradient_norm:.3e} N; reduce the time step or raise max_newton_iterations (FEM \
         references halve a failing step up to 4 times before they report this)"
    )]
    NotConverged {
        /// 0-based step index.
        step: usize,
        /// Iterations done.
        iterations: usize,
        /// Largest nodal update of the last iteration, metres.
        step_norm: f64,
        /// The absolute tolerance it was compared to, metres.
        tolerance: f64,
        /// Largest nodal gradient (force residual) at the last iterate, N.
        gradient_norm: f64,
    },
    /// The line search found no decrease of the incremental potential along the Newton
    /// direction (the direction is not a descent direction, or round-off dominates).
    #[error("line search failed in step {step}, iteration {iteration}: {detail}")]
    LineSearch {
        /// 0-based step index.
        step: usize,
        /// 0-based Newton iteration.
        iteration: usize,
        /// Energies and step sizes tried.
        detail: String,
    },
    /// A NaN or infinity appeared in the state, energy or gradient.
    #[error("non-finite {what} in step {step}, iteration {iteration}")]
    NonFinite {
        /// What became non-finite.
        what: &'static str,
        /// 0-based step index.
        step: usize,
        /// 0-based Newton iteration.
        iteration: usize,
    },
    /// The sparse Cholesky factorization failed (the system is not positive definite, e.g.
    /// a static solve with too few held nodes).
    #[error("sparse Cholesky failed: {0}")]
    Factorization(String),
    /// The external tet mesher (TetGen) is missing, failed, or produced no tetrahedra: its
    /// own message and what to do.
    #[error("TetGen: {0}")]
    Mesher(String),
    /// Trajectories handed to the error metric do not fit together.
    #[error("trajectory {what}: {detail}")]
    Trajectory {
        /// Which input ("reference", "candidate", "rest").
        what: &'static str,
        /// Shape, NaN or emptiness problem, with frame and node indices.
        detail: String,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_and_tiny_values_print_in_scientific_notation() {
        let e = Error::param("dt", 1e300, "too large");
        assert_eq!(
            e.to_string(),
            Error::param("dt", "1e300", "too large").to_string()
        );
        assert!(e.to_string().len() < 60, "{e}");
        assert_eq!(readable_number(1e-300), "1e-300");
        assert_eq!(readable_number(0.25), "0.25");
        assert_eq!(readable_number(-3e20), "-3e20");
        // Text that is no number, or short, stays as it is.
        let e = Error::param("name", "x".repeat(30), "bad");
        assert!(e.to_string().contains(&"x".repeat(30)), "{e}");
    }

    /// The kinds the bindings map from: a file error is an IO error wherever it arises, an
    /// object's error is its cause's kind, and eigensolver failures split by whose fault.
    #[test]
    fn errors_have_one_kind_for_every_front_end() {
        let basis_file = Error::BasisFile {
            path: "b.npz".into(),
            reason: "truncated".into(),
        };
        assert_eq!(basis_file.kind(), ErrorKind::Io);
        let wrapped = Error::Object {
            index: 2,
            name: "ball".into(),
            source: Box::new(Error::Coverage {
                count: 1,
                index: 0,
                position: [0.0; 3],
                covering: 2,
                rcond: 0.0,
                min_rcond: 1e-12,
            }),
        };
        assert_eq!(wrapped.kind(), ErrorKind::Coverage);
        let callback = Error::Eigen(EigenError::Operator {
            which: "H",
            message: "device lost".into(),
        });
        assert_eq!(callback.kind(), ErrorKind::BadOperator);
        let request = Error::Eigen(EigenError::InvalidRequest("nev".into()));
        assert_eq!(request.kind(), ErrorKind::InvalidInput);
        assert_eq!(Error::param("dt", -1, "x").kind(), ErrorKind::InvalidInput);
        let strict = Error::Strict {
            warnings: vec![Warning::monitor("w")],
        };
        assert_eq!(strict.kind(), ErrorKind::Strict);
    }
}
