//! MEDIT `.mesh` files (ASCII), as written by TetGen (`-g`), MMG, CGAL and Gmsh.
//!
//! Keywords, each followed by its data: `MeshVersionFormatted <v>`, `Dimension 3`,
//! `Vertices <n>` then n x (x y z ref), `Tetrahedra <n>` then n x (v1 v2 v3 v4 ref) with
//! 1-based vertex numbers, `End`. Other known element/attribute sections (`Edges`,
//! `Triangles`, `Quadrilaterals`, `Hexahedra`, `Prisms`, `Corners`, `Ridges`,
//! `Required*`, `Normals`, `NormalAtVertices`, `Tangents`, `TangentAtVertices`) are skipped;
//! an unknown keyword is an error (its entry width is unknown). `#` starts a comment.

use super::tokens::{compact, read_text, Tokens};
use crate::fem::{FemError, TetMesh};
use std::path::Path;

/// Read a MEDIT `.mesh` file.
///
/// # Errors
/// [`FemError::Io`], [`FemError::Parse`] (with line), [`FemError::Mesh`].
pub fn read(path: &Path) -> Result<TetMesh, FemError> {
    parse(&read_text(path)?, path)
}

/// Tokens per entry of the sections that are skipped.
fn skipped_width(keyword: &str) -> Option<usize> {
    Some(match keyword {
        "edges" => 3,
        "triangles" => 4,
        "quadrilaterals" => 5,
        "hexahedra" => 9,
        "prisms" => 7,
        "corners"
        | "ridges"
        | "requiredvertices"
        | "requirededges"
        | "requiredtriangles"
        | "requiredquadrilaterals"
        | "requiredtetrahedra" => 1,
        "normals" | "tangents" => 3,
        "normalatvertices" | "tangentatvertices" => 2,
        _ => return None,
    })
}

/// Parse MEDIT text; `path` only labels errors.
///
/// # Errors
/// As [`read`], without I/O.
pub fn parse(text: &str, path: &Path) -> Result<TetMesh, FemError> {
    let mut t = Tokens::new(text, path, Some('#'));
    let mut nodes = Vec::new();
    let mut tets = Vec::new();
    let mut ended = false;
    while let Some(word) = t.peek() {
        t.next("a keyword")?;
        let key = word.to_ascii_lowercase();
        match key.as_str() {
            "meshversionformatted" => {
                t.usize("the format version")?;
            }
            "dimension" => {
                let d = t.usize("the dimension")?;
                if d != 3 {
                    return Err(t.error(format!("dimension {d}: only 3D meshes are supported")));
                }
            }
            "vertices" => {
                let n = t.usize("the number of vertices")?;
                nodes.reserve(n);
                for _ in 0..n {
                    nodes.push(t.point("a vertex coordinate")?);
                    t.i64("a vertex reference")?;
                }
            }
            "tetrahedra" => {
                let n = t.usize("the number of tetrahedra")?;
                tets.reserve(n);
                for _ in 0..n {
                    let mut tet = [0u32; 4];
                    for slot in &mut tet {
                        let v = t.usize("a vertex number")?;
                        if v == 0 || v > nodes.len() {
                            return Err(t.error(format!(
                                "vertex number {v} out of range 1..={} (Vertices must come first)",
                                nodes.len()
                            )));
                        }
                        *slot = (v - 1) as u32;
                    }
                    t.i64("a tetrahedron reference")?;
                    tets.push(tet);
                }
            }
            "end" => {
                ended = true;
                break;
            }
            k => match skipped_width(k) {
                Some(w) => {
                    let n = t.usize("the number of entries")?;
                    t.skip(n * w, word)?;
                }
                None => return Err(t.error(format!("unknown MEDIT keyword '{word}'"))),
            },
        }
    }
    let _ = ended; // `End` is optional in practice.
    if tets.is_empty() {
        return Err(t.error("no Tetrahedra section: the file holds no volume mesh"));
    }
    compact(nodes, tets)
}
