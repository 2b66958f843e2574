//! The shape the pipeline samples: a primitive, a triangle mesh, a point cloud or the filled
//! voxels of an image.

use super::{Aabb, PointCloud, TriMesh, VoxelImage};
use crate::linalg3::{norm, sub};
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

    /// Points on the shape's boundary where its basis is evaluated beyond the integration
    /// points (N x 3, metres): a FEM reference's nodes, render points, contact samples. The
    /// integration points sit up to half a cell inside the boundary, so these see fewer
    /// kernels. For a box, a grid over its six faces (corners and edges included) with at most
    /// `spacing` (metres) between neighbours; for a sphere, a Fibonacci lattice of about one
    /// point per `spacing`^2 of surface; a mesh's vertices and a grid on each of its triangles
    /// (a FEM mesh of it adds nodes inside large faces); none for a point cloud (its
    /// integration points are its own points, or a subset of them: it has no surface of its
    /// own, and checking a million splat centres would cost more than the basis) or an image.
    /// At most [`MAX_SURFACE_PROBES`] (the spacing widens beyond that; a mesh keeps at least
    /// its vertices); an invalid spacing (not positive and finite) gives none.
    pub fn surface_probes(&self, spacing: f64) -> Vec<Point3> {
        if !(spacing > 0.0 && spacing.is_finite()) {
            return Vec::new();
        }
        match self {
            Shape::Box { size } => box_surface_grid(size, spacing),
            Shape::Sphere { radius } => sphere_lattice(*radius, spacing),
            Shape::Mesh(m) => mesh_surface_grid(m.vertices(), m.triangles(), spacing),
            Shape::PointCloud(_) | Shape::Image(_) => Vec::new(),
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

/// Most points [`Shape::surface_probes`] puts on a primitive's surface.
pub const MAX_SURFACE_PROBES: usize = 1 << 22;

/// The nodes of a grid over the box `[0, size]` that lie on its surface, at most `spacing`
/// apart along each axis (at least 2 nodes per axis, so the corners are always in).
fn box_surface_grid(size: &[f64; 3], spacing: f64) -> Vec<Point3> {
    let nodes = |h: f64| size.map(|l| ((l / h).ceil() as usize).clamp(1, 1 << 20) + 1);
    let surface = |n: [usize; 3]| {
        let all = n[0] * n[1] * n[2];
        all - n.map(|k| k - 2).iter().product::<usize>()
    };
    let mut h = spacing;
    while surface(nodes(h)) > MAX_SURFACE_PROBES {
        h *= 1.25;
    }
    let n = nodes(h);
    let at = |a: usize, i: usize| size[a] * i as f64 / (n[a] - 1) as f64;
    let mut out = Vec::with_capacity(surface(n));
    for i in 0..n[0] {
        let x_face = i == 0 || i == n[0] - 1;
        for j in 0..n[1] {
            let y_face = j == 0 || j == n[1] - 1;
            if x_face || y_face {
                out.extend((0..n[2]).map(|k| [at(0, i), at(1, j), at(2, k)]));
            } else {
                out.push([at(0, i), at(1, j), 0.0]);
                out.push([at(0, i), at(1, j), size[2]]);
            }
        }
    }
    out
}

/// A mesh's vertices, then on each triangle the points of its barycentric grid of n divisions
/// per edge (n = its longest edge / `spacing`, rounded up) other than its corners: at most
/// `spacing` apart along the edges and inside. An edge shared by two triangles gets its points
/// from both (the same points up to round-off).
fn mesh_surface_grid(vertices: &[Point3], triangles: &[[u32; 3]], spacing: f64) -> Vec<Point3> {
    let corner = |t: &[u32; 3]| t.map(|i| vertices[i as usize]);
    let longest = |v: &[Point3; 3]| {
        (0..3)
            .map(|e| norm(&sub(&v[e], &v[(e + 1) % 3])))
            .fold(0.0, f64::max)
    };
    let divisions = |v: &[Point3; 3], h: f64| ((longest(v) / h).ceil() as usize).clamp(1, 1 << 12);
    // Grid points other than the corners: (n + 1)(n + 2) / 2 - 3.
    let count = |h: f64| {
        triangles
            .iter()
            .map(|t| {
                let n = divisions(&corner(t), h);
                (n + 1) * (n + 2) / 2 - 3
            })
            .sum::<usize>()
            + vertices.len()
    };
    // At n = 1 a triangle adds no point, so the widening ends at the vertices at the latest.
    let (mut h, mut total) = (spacing, count(spacing));
    while total > MAX_SURFACE_PROBES.max(vertices.len()) && h.is_finite() {
        h *= 1.25;
        total = count(h);
    }
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(vertices);
    for t in triangles {
        let v = corner(t);
        let n = divisions(&v, h);
        for i in 0..=n {
            for j in 0..=n - i {
                if (i == 0 && j == 0) || i == n || j == n {
                    continue;
                }
                let (a, b) = (i as f64 / n as f64, j as f64 / n as f64);
                out.push(
                    [0, 1, 2].map(|c| v[0][c] + a * (v[1][c] - v[0][c]) + b * (v[2][c] - v[0][c])),
                );
            }
        }
    }
    out
}

/// About one point per `spacing`^2 on the sphere of `radius` centred at the origin (a
/// Fibonacci lattice: deterministic and nearly uniform), at least 12.
fn sphere_lattice(radius: f64, spacing: f64) -> Vec<Point3> {
    let area = 4.0 * std::f64::consts::PI * radius * radius;
    let n = ((area / (spacing * spacing)).ceil() as usize).clamp(12, MAX_SURFACE_PROBES);
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2 * i + 1) as f64 / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let t = golden * i as f64;
            [radius * r * t.cos(), radius * r * t.sin(), radius * z]
        })
        .collect()
}
