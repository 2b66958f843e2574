//! A voxel tet mesher for watertight triangle meshes.
//!
//! The bounding box of the surface is covered by a grid of cubes of edge `spacing`, centred
//! on the box; a cube is kept when its centre is inside the surface (generalized winding
//! number >= 1/2, [`TriMesh::contains`]). Each kept cube is cut into the 6 Kuhn tets of
//! [`TetMesh::structured_box`], with shared corners merged, so the mesh is conforming.
//!
//! **Staircase boundary.** The meshed solid is the union of kept cubes, not the surface: its
//! boundary is axis-aligned steps that deviate from the true surface by up to
//! sqrt(3)/2 x spacing, and its volume differs by O(spacing x area). Refine `spacing` for a
//! better fit; [`VoxelMesh::volume_error`] reports the volume difference. Cubes touching only
//! along an edge or corner stay connected through that edge or corner node (a weak
//! connection); thin features narrower than one cube may vanish.

use super::{FemError, TetMesh};
use crate::geometry::TriMesh;
use std::collections::HashMap;

/// A voxel tet mesh and how it relates to the surface.
#[derive(Debug, Clone)]
pub struct VoxelMesh {
    /// The tet mesh (6 tets per kept cube).
    pub mesh: TetMesh,
    /// Cube edge length, metres.
    pub spacing: f64,
    /// Grid cells per axis.
    pub cells: [usize; 3],
    /// Cubes kept.
    pub voxels: usize,
    /// (mesh volume - surface volume) / surface volume (the staircase error).
    pub volume_error: f64,
}

/// Mesh the inside of `surface` with cubes of edge `spacing` (metres).
///
/// # Errors
/// [`FemError::Mesh`] when `spacing` is not positive and finite, the grid would exceed 2^31
/// cells, or no cube centre lies inside (spacing too coarse for the shape).
pub fn voxel_tet_mesh(surface: &TriMesh, spacing: f64) -> Result<VoxelMesh, FemError> {
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(FemError::Mesh(format!(
            "voxel spacing {spacing} must be > 0 metres"
        )));
    }
    let bb = surface.bounding_box();
    let size = bb.size();
    let cells = size.map(|s| ((s / spacing).ceil() as usize).max(1));
    let total = cells[0] as f64 * cells[1] as f64 * cells[2] as f64;
    if total > (1u64 << 31) as f64 {
        return Err(FemError::Mesh(format!(
            "voxel grid {cells:?} has {total:.3e} cells; increase the spacing"
        )));
    }
    // Grid centred on the box: it overhangs by at most one spacing in total per axis.
    let origin = [0, 1, 2].map(|a| bb.center()[a] - 0.5 * cells[a] as f64 * spacing);
    let [nx, ny, nz] = cells;
    let centres: Vec<_> = (0..nz)
        .flat_map(|k| (0..ny).flat_map(move |j| (0..nx).map(move |i| [i, j, k])))
        .map(|c| [0, 1, 2].map(|a| origin[a] + (c[a] as f64 + 0.5) * spacing))
        .collect();
    let inside = surface.contains(&centres);
    let mut node_of: HashMap<[usize; 3], u32> = HashMap::new();
    let mut nodes = Vec::new();
    let mut tets = Vec::new();
    let mut voxels = 0;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if !inside[i + nx * (j + ny * k)] {
                    continue;
                }
                voxels += 1;
                let mut corner = [0u32; 8];
                for (bits, slot) in corner.iter_mut().enumerate() {
                    let g = [i + (bits & 1), j + ((bits >> 1) & 1), k + ((bits >> 2) & 1)];
                    *slot = *node_of.entry(g).or_insert_with(|| {
                        nodes.push([0, 1, 2].map(|a| origin[a] + g[a] as f64 * spacing));
                        (nodes.len() - 1) as u32
                    });
                }
                super::tetmesh::push_kuhn_cell(&mut tets, |bits| corner[bits as usize]);
            }
        }
    }
    if voxels == 0 {
        return Err(FemError::Mesh(format!(
            "no voxel centre of spacing {spacing} m lies inside the surface; use a finer spacing"
        )));
    }
    let mesh = TetMesh::new(nodes, tets)?;
    let surface_volume = surface.volume().unwrap_or(f64::NAN);
    let volume_error = (mesh.volume() - surface_volume) / surface_volume;
    Ok(VoxelMesh {
        mesh,
        spacing,
        cells,
        voxels,
        volume_error,
    })
}
