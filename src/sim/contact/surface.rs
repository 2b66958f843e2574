//! The contact surface of a shape without one: point clouds (splats among them) and voxel
//! images get the surface of the volume they occupy ([`OccupancyGrid::surface`]), on which
//! their contact samples are spread like a mesh's.

use crate::geometry::{OccupancyGrid, Shape, TriMesh};
use crate::{Error, Result};

/// The derived surface's cell is at least the bounding-box diagonal over this (a grid of about
/// 74^3 cells for a cube): 3 cells per default contact sample spacing (1/25 of the diagonal).
pub const SURFACE_CELLS_PER_DIAGONAL: f64 = 128.0;

/// Empty cells around the occupied ones: the closing's radius plus two, so the grid's border
/// stays empty.
const PAD: usize = 3;

/// The surface a shape's contact samples are spread over when it has none of its own: for a
/// point cloud, the occupied volume of cells of the median nearest-neighbour distance (at
/// least 1/[`SURFACE_CELLS_PER_DIAGONAL`] of the diagonal), closed by one cell so gaps between
/// neighbouring points are bridged; for an image, of its filled voxels sampled at cells of
/// its smallest voxel edge (same bound). Enclosed cavities are filled in both. `None` for
/// boxes, spheres and meshes.
///
/// # Errors
/// [`Error::InvalidParameter`] (`shape`) when no closed surface is left: the cloud is too
/// sparse or thin for its cells, or the image has no filled voxel thick enough.
pub fn derived_surface(shape: &Shape) -> Result<Option<TriMesh>> {
    let floor = shape.bounding_box().diagonal() / SURFACE_CELLS_PER_DIAGONAL;
    let mut grid = match shape {
        Shape::Box { .. } | Shape::Sphere { .. } | Shape::Mesh(_) => return Ok(None),
        Shape::PointCloud(cloud) => {
            let points = cloud.points();
            let h = crate::precompute::sampling::median_nn_distance(points)?.max(floor);
            let mut grid = OccupancyGrid::from_points(points, h, PAD)?;
            grid.close(1);
            grid
        }
        Shape::Image(image) => {
            let h = image
                .spacing()
                .into_iter()
                .fold(f64::INFINITY, f64::min)
                .max(floor);
            OccupancyGrid::from_inside(&image.bounding_box(), h, PAD, |c| image.contains(c))?
        }
    };
    grid.fill_cavities();
    let mesh = grid.surface().map_err(|e| {
        Error::param(
            "shape",
            shape.kind(),
            format!(
                "object-object contact needs a surface, and none could be derived from the \
                 volume this {} occupies ({e}); give the object a mesh or primitive shape, or \
                 leave it out of the [contact] scene",
                shape.kind()
            ),
        )
    })?;
    Ok(Some(mesh))
}
