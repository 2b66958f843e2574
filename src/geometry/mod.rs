//! Shapes that can be sampled: primitives, watertight triangle meshes (OBJ, STL, OFF, PLY) and
//! point clouds (PLY, including 3D Gaussian splat files).
//!
//! A shape answers three questions for the sampling stage: its bounding box, its volume (when
//! it has a well-defined one) and, for solids, whether points are inside.
//!
//! - [`Shape`] is what the pipeline consumes; [`ShapeSpec::parse`] parses a spec
//!   (`box:LX,LY,LZ`, `sphere:R`, or a file path) without reading files, and
//!   [`crate::io::read_shape`] turns a spec into a shape (reading the file it names).
//! - [`TriMesh`] is a validated, outward-oriented triangle mesh whose inside test is the
//!   generalized winding number, evaluated hierarchically by a [`WindingTree`].
//! - [`PointCloud`] is a validated set of points (no inside test).
//! - [`VoxelImage`] is a label or Young's-modulus image; its filled voxels can be the shape.
//! - [`generate`] builds simple meshes (box, icosphere) for tests and examples.

mod axis;
pub mod generate;
mod mesh;
mod occupied;
mod pointcloud;
mod shape;
mod spec;
mod topology;
mod voxels;
pub mod winding;

pub use axis::UpAxis;
pub use mesh::TriMesh;
pub use occupied::{OccupancyGrid, ISO_LEVEL};
pub use pointcloud::PointCloud;
pub use shape::Shape;
pub use spec::{ShapeFileFormat, ShapeSpec};
pub use topology::{boundary_edges, weld_exact, EdgeReport};
pub use voxels::{VoxelImage, VoxelValues, MAX_VOXELS};
pub use winding::{WindingParams, WindingTree};

pub use crate::error::GeometryError;
use crate::Point3;

/// Axis-aligned bounding box, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Point3,
    /// Maximum corner.
    pub max: Point3,
}

impl Aabb {
    /// The smallest box containing all `points` (N x 3, metres); `None` when `points` is
    /// empty. Non-finite coordinates are not filtered: validate the points first.
    pub fn from_points(points: &[Point3]) -> Option<Aabb> {
        let first = points.first()?;
        let mut b = Aabb {
            min: *first,
            max: *first,
        };
        for p in points {
            for (a, &c) in p.iter().enumerate() {
                b.min[a] = b.min[a].min(c);
                b.max[a] = b.max[a].max(c);
            }
        }
        Some(b)
    }

    /// Edge lengths `max - min` per axis, metres.
    pub fn size(&self) -> [f64; 3] {
        [0, 1, 2].map(|a| self.max[a] - self.min[a])
    }

    /// Centre `(min + max) / 2`, metres.
    pub fn center(&self) -> Point3 {
        [0, 1, 2].map(|a| 0.5 * (self.min[a] + self.max[a]))
    }

    /// Length of the diagonal, metres.
    pub fn diagonal(&self) -> f64 {
        let s = self.size();
        (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt()
    }

    /// Whether `p` (metres) lies in the closed box.
    pub fn contains(&self, p: &Point3) -> bool {
        (0..3).all(|a| p[a] >= self.min[a] && p[a] <= self.max[a])
    }
}

/// Options that change how a shape is read.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ShapeOptions {
    /// Accept a triangle mesh with boundary edges (holes), non-manifold edges or inconsistently
    /// oriented neighbouring triangles; inside is then decided by the generalized winding
    /// number >= 0.5 (see [`TriMesh`]). Off by default: such a mesh is an error.
    pub allow_open_mesh: bool,
    /// The up axis of the frame a USD input is read into (a stage with the other `upAxis` is
    /// turned by 90 degrees about x). Default Y; a scene sets it from its gravity
    /// ([`UpAxis::from_gravity`]). Other formats have no up axis and ignore it.
    pub up_axis: UpAxis,
}

/// Path label used in errors about meshes that did not come from a file.
pub(crate) const IN_MEMORY: &str = "<in-memory mesh>";
