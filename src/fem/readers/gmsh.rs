//! Gmsh `.msh` files, format version 4.1, ASCII.
//!
//! Sections `$MeshFormat` (must say `4.1 0 <size>`), `$Nodes` and `$Elements` are read; every
//! other section (`$Entities`, `$PhysicalNames`, ...) is skipped up to its `$End...` marker.
//! Elements of type 4 (4-node tet) and 11 (10-node tet; corners kept) become tets; other
//! element types (points, lines, triangles, ...) are skipped. Version 2.2 or 4.0 files, and
//! binary files, are refused with a line-numbered error saying how to re-export
//! (`gmsh -3 -format msh41 file.geo`, or `Mesh.MshFileVersion = 4.1;` with
//! `Mesh.Binary = 0;`).

use super::tokens::{compact, read_text, NodeIds, Tokens};
use crate::fem::{FemError, TetMesh};
use std::path::Path;

/// Nodes per element for Gmsh element types 1..=19, 0 for unknown.
fn nodes_per_element(kind: i64) -> usize {
    const N: [usize; 20] = [
        0, 2, 3, 4, 4, 8, 6, 5, 3, 6, 9, 10, 27, 18, 14, 1, 8, 20, 15, 13,
    ];
    usize::try_from(kind)
        .ok()
        .and_then(|k| N.get(k).copied())
        .unwrap_or(0)
}

/// Read a Gmsh 4.1 ASCII file.
///
/// # Errors
/// [`FemError::Io`], [`FemError::Parse`] (with line), [`FemError::Mesh`].
pub fn read(path: &Path) -> Result<TetMesh, FemError> {
    parse(&read_text(path)?, path)
}

/// Parse Gmsh 4.1 ASCII text; `path` only labels errors.
///
/// # Errors
/// As [`read`], without I/O.
pub fn parse(text: &str, path: &Path) -> Result<TetMesh, FemError> {
    let mut t = Tokens::new(text, path, None);
    let mut format_seen = false;
    let mut ids: Vec<i64> = Vec::new();
    let mut nodes = Vec::new();
    let mut raw_tets: Vec<[i64; 4]> = Vec::new();
    let mut tet_lines: Vec<usize> = Vec::new();
    while !t.at_end() {
        let section = t.next("a section")?;
        match section {
            "$MeshFormat" => {
                let version = t.next("the format version")?;
                if version != "4.1" {
                    return Err(t.error(format!(
                        "Gmsh format version {version}: only 4.1 is supported; re-export with \
                         `gmsh -3 -format msh41` (or Mesh.MshFileVersion = 4.1)"
                    )));
                }
                let file_type = t.usize("the file type")?;
                if file_type != 0 {
                    return Err(t.error(
                        "binary Gmsh file: only ASCII is supported; re-export with Mesh.Binary = 0",
                    ));
                }
                t.usize("the data size")?;
                expect(&mut t, "$EndMeshFormat")?;
                format_seen = true;
            }
            "$Nodes" => {
                if !format_seen {
                    return Err(t.error("$Nodes before $MeshFormat"));
                }
                let blocks = t.usize("the number of node blocks")?;
                let total = t.usize("the number of nodes")?;
                t.usize("the minimum node tag")?;
                t.usize("the maximum node tag")?;
                ids.reserve(total);
                nodes.reserve(total);
                for _ in 0..blocks {
                    let dim = t.usize("the entity dimension")?;
                    t.i64("the entity tag")?;
                    let parametric = t.usize("the parametric flag")?;
                    let count = t.usize("the number of nodes in the block")?;
                    for _ in 0..count {
                        ids.push(t.i64("a node tag")?);
                    }
                    for _ in 0..count {
                        nodes.push(t.point("a node coordinate")?);
                        if parametric == 1 {
                            t.skip(dim.min(3), "parametric coordinates")?;
                        }
                    }
                }
                if nodes.len() != total {
                    return Err(t.error(format!(
                        "the $Nodes header announces {total} nodes, the blocks hold {}",
                        nodes.len()
                    )));
                }
                expect(&mut t, "$EndNodes")?;
            }
            "$Elements" => {
                if !format_seen {
                    return Err(t.error("$Elements before $MeshFormat"));
                }
                let blocks = t.usize("the number of element blocks")?;
                t.usize("the number of elements")?;
                t.usize("the minimum element tag")?;
                t.usize("the maximum element tag")?;
                for _ in 0..blocks {
                    t.usize("the entity dimension")?;
                    t.i64("the entity tag")?;
                    let kind = t.i64("the element type")?;
                    let per = nodes_per_element(kind);
                    if per == 0 {
                        return Err(t.error(format!("unknown Gmsh element type {kind}")));
                    }
                    let count = t.usize("the number of elements in the block")?;
                    for _ in 0..count {
                        t.i64("an element tag")?;
                        if kind == 4 || kind == 11 {
                            let mut tet = [0i64; 4];
                            for slot in &mut tet {
                                *slot = t.i64("a node tag")?;
                            }
                            tet_lines.push(line_of(&t));
                            raw_tets.push(tet);
                            t.skip(per - 4, "higher-order nodes")?;
                        } else {
                            t.skip(per, "element nodes")?;
                        }
                    }
                }
                expect(&mut t, "$EndElements")?;
            }
            s if s.starts_with('$') && !s.starts_with("$End") => {
                let end = format!("$End{}", &s[1..]);
                loop {
                    if t.next(&end)? == end {
                        break;
                    }
                }
            }
            other => return Err(t.error(format!("expected a $Section marker, found '{other}'"))),
        }
    }
    if !format_seen {
        return Err(t.error("no $MeshFormat section: not a Gmsh file"));
    }
    let map = NodeIds::new(&ids);
    let mut tets = Vec::with_capacity(raw_tets.len());
    for (raw, line) in raw_tets.iter().zip(tet_lines) {
        let mut tet = [0u32; 4];
        for (slot, &id) in tet.iter_mut().zip(raw) {
            *slot = map.get(id, nodes.len()).ok_or_else(|| FemError::Parse {
                path: path.to_path_buf(),
                line,
                reason: format!("tet refers to node tag {id}, which $Nodes does not define"),
            })?;
        }
        tets.push(tet);
    }
    compact(nodes, tets)
}

fn expect(t: &mut Tokens<'_>, marker: &str) -> Result<(), FemError> {
    let got = t.next(marker)?;
    if got == marker {
        Ok(())
    } else {
        Err(t.error(format!("expected {marker}, found '{got}' (counts in the section header and its data disagree?)")))
    }
}

fn line_of(t: &Tokens<'_>) -> usize {
    match t.error("") {
        FemError::Parse { line, .. } => line,
        _ => 0,
    }
}
