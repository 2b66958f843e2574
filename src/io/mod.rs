//! File formats: shape inputs (OBJ, STL, PLY meshes and point clouds), the basis file (.npz)
//! and matrix exchange (MatrixMarket, PETSc binary).

pub mod basis;
pub mod matrix_market;
pub mod obj;
pub mod ply;
pub mod stl;

use crate::geometry::GeometryError;

/// Check that every triangle of a mesh about to be written refers to one of `vertex_count`
/// vertices (and fits the signed 32-bit indices some formats store).
pub(crate) fn check_triangle_indices(
    vertex_count: usize,
    triangles: &[[u32; 3]],
) -> Result<(), GeometryError> {
    match triangles.iter().enumerate().find(|(_, t)| {
        t.iter()
            .any(|&i| i as usize >= vertex_count || i > i32::MAX as u32)
    }) {
        Some((f, t)) => Err(GeometryError::InvalidInput(format!(
            "triangle {f} = {t:?} refers past the {vertex_count} vertices"
        ))),
        None => Ok(()),
    }
}
