//! Readers for tetrahedral mesh files: TetGen `.node/.ele` ([`tetgen`]), Gmsh `.msh` v4.1
//! ASCII ([`gmsh`]) and MEDIT `.mesh` ([`medit`]). Every reader:
//! - reports malformed input as [`FemError::Parse`] with the 1-based line number;
//! - keeps the 4 corner nodes of quadratic (10-node) tets, and ignores non-tet elements;
//! - drops nodes that no tet uses (they carry no mass and no stiffness) and renumbers the
//!   rest in file order;
//! - orients every tet positively ([`TetMesh::new`]).

pub mod gmsh;
pub mod medit;
pub mod tetgen;
mod tokens;

use super::{FemError, TetMesh};
use std::path::Path;

/// Read a tet mesh, choosing the reader by extension: `.msh` (Gmsh), `.mesh` (MEDIT),
/// `.node` or `.ele` (TetGen; the other file of the pair is found next to it).
///
/// # Errors
/// [`FemError::Io`], [`FemError::Parse`], [`FemError::Mesh`]; an unknown extension is a
/// [`FemError::Parse`] at line 0.
pub fn read_tet_mesh(path: &Path) -> Result<TetMesh, FemError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        "msh" => gmsh::read(path),
        "mesh" => medit::read(path),
        "node" | "ele" => tetgen::read(&path.with_extension("node"), &path.with_extension("ele")),
        _ => Err(FemError::Parse {
            path: path.to_path_buf(),
            line: 0,
            reason: format!(
                "unknown tet mesh extension '.{ext}': expected .msh (Gmsh 4.1 ASCII), .mesh \
                 (MEDIT) or .node/.ele (TetGen)"
            ),
        }),
    }
}
