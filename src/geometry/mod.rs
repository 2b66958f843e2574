//! Shapes that can be sampled: primitives, watertight triangle meshes (OBJ, STL, PLY) and point
//! clouds (PLY, including 3D Gaussian splat files).
//!
//! A shape answers three questions for the sampling stage: its bounding box, its volume (when
//! it has a well-defined one) and, for solids, whether points are inside.

use crate::Point3;
use std::path::PathBuf;

/// Axis-aligned bounding box, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Point3,
    /// Maximum corner.
    pub max: Point3,
}

/// Options that change how a shape is read.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ShapeOptions {
    /// Accept a triangle mesh with boundary edges (holes); inside is then decided by the
    /// generalized winding number >= 0.5. Off by default: an open mesh is an error.
    pub allow_open_mesh: bool,
}

/// Geometry errors: reading files and unusable shapes.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GeometryError {
    /// The shape spec is neither a primitive nor a supported file.
    #[error(
        "unknown shape `{0}`: use box:LX,LY,LZ, sphere:R, or a path to a .obj, .stl or .ply file"
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
    /// The mesh is not closed.
    #[error(
        "{path}: mesh is not watertight ({boundary_edges} boundary edges, {nonmanifold_edges} \
         non-manifold edges); repair it, or pass --allow-open-mesh to decide inside by winding number"
    )]
    NotWatertight {
        /// File.
        path: PathBuf,
        /// Edges used by exactly one triangle.
        boundary_edges: usize,
        /// Edges used by more than two triangles.
        nonmanifold_edges: usize,
    },
    /// The shape encloses no volume or has no points.
    #[error("{0}")]
    Degenerate(String),
}
