//! File formats: shape inputs (OBJ, STL, PLY meshes and point clouds) and the basis file (.npz).

pub mod basis;
pub mod obj;
pub mod ply;
pub mod stl;
