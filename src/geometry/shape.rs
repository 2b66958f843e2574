//! The shape the pipeline samples: a primitive, a triangle mesh, a point cloud or the filled
//! voxels of an image.

use super::{Aabb, PointCloud, TriMesh, VoxelImage};
use crate::Point3;
use rayon::prelude::*;
use std::sync::Arc;

/// A shape to simulate.
#[derive(Debug, Clone)]
pub enum Shape {
    /// The box `[0, LX] x [0, LY] x [0, LZ]`, corner at the origin; `size` = [LX, LY, LZ],
    /// metres, all positive.
    Box {
        /// Edge lengths, metres.
        size: [f64; 3],
    },
    /// The ball of `radius` (metres, positive) centred at the origin.
    Sphere {
        /// Radius, metres.
        radius: f64,
    },
    /// A validated, outward-oriented triangle mesh (inside = winding number >= 0.5).
    Mesh(TriMesh),
    /// A point cloud (no inside test; the points are the material).
    PointCloud(PointCloud),
    /// The filled voxels of an image (label != 0 or modulus > 0); shared, since the same image
    /// usually also gives the materials.
    Image(Arc<VoxelImage>),
}

impl Shape {
    /// Short name of the shape kind for reports: "box", "sphere", "mesh", "point cloud" or
    /// "image".
    pub fn kind(&self) -> &'static str {
        match self {
            Shape::Box { .. } => "box",
            Shape::Sphere { .. } => "sphere",
            Shape::Mesh(_) => "mesh",
            Shape::PointCloud(_) => "point cloud",
            Shape::Image(_) => "image",
        }
    }

    /// Axis-aligned bounding box, metres (tight for all kinds).
    pub fn bounding_box(&self) -> Aabb {
        match self {
            Shape::Box { size } => Aabb {
                min: [0.0; 3],
                max: *size,
            },
            Shape::Sphere { radius: r } => Aabb {
                min: [-r; 3],
                max: [*r; 3],
            },
            Shape::Mesh(m) => m.bounding_box(),
            Shape::PointCloud(c) => c.bounding_box(),
            Shape::Image(i) => i.bounding_box(),
        }
    }

    /// Enclosed volume, m^3: exact for primitives and images (filled voxels times the voxel
    /// volume), the divergence-theorem volume for closed meshes; `None` for open meshes and
    /// point clouds.
    pub fn volume(&self) -> Option<f64> {
        match self {
            Shape::Box { size } => Some(size[0] * size[1] * size[2]),
            Shape::Sphere { radius: r } => Some(4.0 / 3.0 * std::f64::consts::PI * r * r * r),
            Shape::Mesh(m) => m.volume(),
            Shape::PointCloud(_) => None,
            Shape::Image(i) => Some(i.volume()),
        }
    }

    /// Whether the shape has an inside test ([`Shape::contains`] returns `Some`): true for
    /// primitives, meshes and images, false for point clouds.
    pub fn is_solid(&self) -> bool {
        !matches!(self, Shape::PointCloud(_))
    }

    /// Inside test for `points` (N x 3, metres), rayon-parallel; `None` for point clouds,
    /// which have no inside.
    ///
    /// Primitives use closed sets (points on the boundary are inside); meshes use the
    /// generalized winding number >= 0.5 (points exactly on the surface may go either way);
    /// images the filled voxel nearest each point ([`VoxelImage::voxel_at`]).
    /// Points with a NaN coordinate are outside.
    pub fn contains(&self, points: &[Point3]) -> Option<Vec<bool>> {
        match self {
            Shape::Box { size } => Some(
                points
                    .par_iter()
                    .map(|p| (0..3).all(|a| p[a] >= 0.0 && p[a] <= size[a]))
                    .collect(),
            ),
            Shape::Sphere { radius: r } => Some(
                points
                    .par_iter()
                    .map(|p| p[0] * p[0] + p[1] * p[1] + p[2] * p[2] <= r * r)
                    .collect(),
            ),
            Shape::Mesh(m) => Some(m.contains(points)),
            Shape::PointCloud(_) => None,
            Shape::Image(i) => Some(i.contains(points)),
        }
    }

    /// Points to draw or deform for output, N x 3 metres: the mesh vertices for meshes, the
    /// input points for point clouds, `None` for primitives and images.
    pub fn render_points(&self) -> Option<&[Point3]> {
        match self {
            Shape::Mesh(m) => Some(m.vertices()),
            Shape::PointCloud(c) => Some(c.points()),
            Shape::Box { .. } | Shape::Sphere { .. } | Shape::Image(_) => None,
        }
    }
}
