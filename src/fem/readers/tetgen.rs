//! TetGen `.node` / `.ele` files.
//!
//! `.node`: a header `<#points> <dimension = 3> <#attributes> <#boundary markers (0|1)>`,
//! then one line per point `<number> <x> <y> <z> [attributes...] [marker]`. `.ele`: a header
//! `<#tets> <nodes per tet (4|10)> <#attributes>`, then `<number> <n1> ... <nk> [attributes]`.
//! Point numbers start at 0 or 1 (the first point decides); `#` starts a comment.

use super::tokens::{compact, read_text, NodeIds, Tokens};
use crate::fem::{FemError, TetMesh};
use std::path::Path;

/// Read the pair `node_path`, `ele_path`.
///
/// # Errors
/// [`FemError::Io`], [`FemError::Parse`] (with file and line), [`FemError::Mesh`].
pub fn read(node_path: &Path, ele_path: &Path) -> Result<TetMesh, FemError> {
    parse(
        &read_text(node_path)?,
        node_path,
        &read_text(ele_path)?,
        ele_path,
    )
}

/// Parse `.node` and `.ele` text; the paths only label errors.
///
/// # Errors
/// As [`read`], without I/O.
pub fn parse(
    node: &str,
    node_path: &Path,
    ele: &str,
    ele_path: &Path,
) -> Result<TetMesh, FemError> {
    let mut t = Tokens::new(node, node_path, Some('#'));
    let count = t.usize("the number of points")?;
    let dim = t.usize("the dimension")?;
    if dim != 3 {
        return Err(t.error(format!("dimension {dim}: only 3D meshes are supported")));
    }
    let attrs = t.usize("the number of point attributes")?;
    let markers = t.usize("the number of boundary markers")?;
    if markers > 1 {
        return Err(t.error(format!("{markers} boundary markers: TetGen allows 0 or 1")));
    }
    let mut ids = Vec::with_capacity(count);
    let mut nodes = Vec::with_capacity(count);
    for _ in 0..count {
        ids.push(t.i64("a point number")?);
        nodes.push(t.point("a point coordinate")?);
        t.skip(attrs + markers, "point attributes and marker")?;
    }
    let ids = NodeIds::new(&ids);

    let mut t = Tokens::new(ele, ele_path, Some('#'));
    let ntets = t.usize("the number of tetrahedra")?;
    let per = t.usize("the number of nodes per tetrahedron")?;
    if per != 4 && per != 10 {
        return Err(t.error(format!("{per} nodes per tetrahedron: expected 4 or 10")));
    }
    let attrs = t.usize("the number of tetrahedron attributes")?;
    let mut tets = Vec::with_capacity(ntets);
    for _ in 0..ntets {
        t.i64("a tetrahedron number")?;
        let mut tet = [0u32; 4];
        for (k, slot) in tet.iter_mut().enumerate() {
            let id = t.i64("a node number")?;
            *slot = ids.get(id, count).ok_or_else(|| {
                t.error(format!(
                    "corner {k} refers to point {id}, which the .node file does not define"
                ))
            })?;
        }
        t.skip(per - 4 + attrs, "higher-order nodes and attributes")?;
        tets.push(tet);
    }
    compact(nodes, tets)
}
