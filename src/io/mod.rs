//! File formats: shape inputs (OBJ, STL, OFF, PLY meshes and point clouds), 3D Gaussian splat PLY
//! files ([`splat`]), USD stages ([`usd`]), the basis file (.npz)
//! and matrix exchange (MatrixMarket, PETSc binary).
//!
//! [`read_shape`] is the entry for shapes: it parses a spec ([`crate::geometry::ShapeSpec`]) and
//! reads the file it names with the reader of its format.

pub mod basis;
mod file;
pub mod image;
pub mod matrix_market;
pub mod obj;
pub mod off;
pub mod ply;
mod shape;
pub mod splat;
pub mod stl;
pub mod usd;
pub mod vtk;

pub(crate) use file::check_triangle_indices;
pub use file::write_atomically;
pub use shape::{read_shape, read_shape_spec};
