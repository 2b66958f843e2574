//! Wavefront OBJ triangle meshes (read with `tobj`, written by hand).
//!
//! Reading:
//! - Only `v` and `f` matter for the shape; `vt`, `vn`, groups, objects and materials are
//!   accepted and ignored (material libraries are never opened). `l` and `p` elements are
//!   ignored.
//! - **Polygons** with more than three vertices are triangulated as a fan from their first
//!   vertex. For planar polygons the fan's solid angles sum to the polygon's exactly (convex or
//!   not), so the winding number is right; only non-planar polygons get an arbitrary split.
//! - All objects and groups form one mesh; vertices with bit-identical coordinates are welded.
//!   Vertices are numbered in order of first use by a face (`tobj`'s numbering); vertices no
//!   face uses are dropped.
//! - Before `tobj` sees the file it is checked line by line: vertex lines need three finite
//!   numbers; face lines need at least three vertices whose indices (1-based, or negative =
//!   relative) refer to vertices, texture coordinates and normals already defined. Errors name
//!   the line. This also keeps hostile indices away from `tobj`'s index arithmetic.
//! - Coordinates pass through `tobj`'s single-precision `Float` (its `use_f64` feature is
//!   off in this build), so they are rounded to f32.

use super::file::{
    create, finish, first_non_finite, io_error, mesh_from_file_data, parse_error, read_nonempty,
};
use crate::geometry::{GeometryError, ShapeOptions, TriMesh};
use crate::Point3;
use std::io::{Cursor, Write};
use std::path::Path;

/// Read an OBJ file into a validated mesh (vertices V x 3, metres).
///
/// # Errors
/// [`GeometryError::Io`] if the file cannot be read; [`GeometryError::Parse`] (with the line
/// number where known) for an empty or non-text file, malformed vertex or face lines, indices
/// out of range, non-finite coordinates, or no faces; the [`TriMesh::new`] errors
/// (`NotWatertight`, `Misoriented`, `Degenerate`) with the path.
pub fn read_obj(path: &Path, opts: &ShapeOptions) -> Result<TriMesh, GeometryError> {
    let (vertices, triangles) = read_obj_raw(path)?;
    mesh_from_file_data(path, vertices, triangles, opts)
}

/// Read an OBJ file's vertices (V x 3, metres) and fan-triangulated faces (F x 3, zero-based)
/// without welding or mesh validation. Errors as [`read_obj`] minus the mesh checks.
pub fn read_obj_raw(path: &Path) -> Result<(Vec<Point3>, Vec<[u32; 3]>), GeometryError> {
    parse_obj_raw(path, &read_nonempty(path)?)
}

/// Parse OBJ content already in memory into a validated mesh, exactly as [`read_obj`] parses
/// a file; `name` only labels the errors.
///
/// # Errors
/// As [`read_obj`], minus the file-system errors.
pub fn parse_obj_bytes(
    name: &Path,
    bytes: &[u8],
    opts: &ShapeOptions,
) -> Result<TriMesh, GeometryError> {
    let (vertices, triangles) = parse_obj_raw(name, bytes)?;
    mesh_from_file_data(name, vertices, triangles, opts)
}

/// [`read_obj_raw`] on bytes in memory (`path` labels the errors).
fn parse_obj_raw(path: &Path, bytes: &[u8]) -> Result<(Vec<Point3>, Vec<[u32; 3]>), GeometryError> {
    if bytes.is_empty() {
        return Err(parse_error(path, "empty file"));
    }
    let text = std::str::from_utf8(bytes).map_err(|e| {
        parse_error(
            path,
            format!(
                "not a text OBJ file (invalid UTF-8 at byte {})",
                e.valid_up_to()
            ),
        )
    })?;
    // A UTF-8 byte order mark would hide the first line's keyword from both parsers.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let counts = precheck(path, text)?;
    if counts.faces == 0 {
        return Err(parse_error(
            path,
            format!(
                "no faces ({} vertices); an OBJ shape needs `f` lines (point clouds are read \
                 from .ply)",
                counts.positions
            ),
        ));
    }
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _materials) =
        tobj::load_obj_buf(&mut Cursor::new(text.as_bytes()), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| parse_error(path, format!("OBJ: {e}")))?;
    let mut vertices: Vec<Point3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    for model in &models {
        let mesh = &model.mesh;
        let base = vertices.len();
        vertices.extend(mesh.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        for t in mesh.indices.chunks_exact(3) {
            let t = [t[0], t[1], t[2]].map(|i| i as usize + base);
            if t.iter()
                .any(|&i| i >= vertices.len() || i > u32::MAX as usize)
            {
                return Err(parse_error(
                    path,
                    "OBJ: face index out of range after loading",
                ));
            }
            triangles.push(t.map(|i| i as u32));
        }
    }
    if let Some(i) = first_non_finite(&vertices) {
        return Err(parse_error(
            path,
            format!(
                "vertex {} has a non-finite coordinate {:?} (beyond single precision?)",
                i + 1,
                vertices[i]
            ),
        ));
    }
    Ok(with_every_vertex(
        counts.all_positions,
        &vertices,
        triangles,
    ))
}

/// The file's vertices in file order, unreferenced ones included (the loader keeps only those
/// faces use), with the faces re-pointed at them. Each loaded vertex is matched to a file
/// vertex with the same coordinates bit for bit (both parse the same text), the first not yet
/// matched, so duplicated positions keep their own indices where the file has them.
fn with_every_vertex(
    all: Vec<Point3>,
    loaded: &[Point3],
    mut triangles: Vec<[u32; 3]>,
) -> (Vec<Point3>, Vec<[u32; 3]>) {
    use std::collections::HashMap;
    if all.len() == loaded.len() && all == loaded {
        return (all, triangles);
    }
    let key = |p: &Point3| p.map(f64::to_bits);
    let mut by_position: HashMap<[u64; 3], Vec<u32>> = HashMap::with_capacity(all.len());
    for (i, p) in all.iter().enumerate().rev() {
        by_position.entry(key(p)).or_default().push(i as u32);
    }
    let mut first: HashMap<[u64; 3], u32> = HashMap::new();
    let mut remap = Vec::with_capacity(loaded.len());
    for p in loaded {
        let k = key(p);
        let index = match by_position.get_mut(&k).and_then(Vec::pop) {
            Some(i) => {
                first.entry(k).or_insert(i);
                i
            }
            // Every copy is taken (a vertex loaded twice, e.g. in two groups): reuse one.
            None => match first.get(&k) {
                Some(&i) => i,
                // Not in the file's `v` lines: keep the loaded vertex (cannot happen when
                // both parse the same text; kept rather than dropped).
                None => return (loaded.to_vec(), triangles),
            },
        };
        remap.push(index);
    }
    for t in &mut triangles {
        *t = t.map(|i| remap[i as usize]);
    }
    (all, triangles)
}

/// What [`precheck`] counted.
struct Counts {
    positions: usize,
    faces: usize,
    /// Every `v` line's position, in file order (referenced by a face or not).
    all_positions: Vec<Point3>,
}

/// Validate vertex and face lines (see the module docs) and count them.
fn precheck(path: &Path, text: &str) -> Result<Counts, GeometryError> {
    let (mut nv, mut nvt, mut nvn, mut nf) = (0usize, 0usize, 0usize, 0usize);
    let mut all_positions = Vec::new();
    for (line_no, line) in text.lines().enumerate() {
        let line_no = line_no + 1;
        let err = |msg: String| parse_error(path, format!("line {line_no}: {msg}"));
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let xyz: Vec<&str> = words.by_ref().take(3).collect();
                if xyz.len() < 3 {
                    return Err(err(format!(
                        "vertex needs 3 coordinates, got {}",
                        xyz.len()
                    )));
                }
                let mut p = [0.0; 3];
                for (d, w) in xyz.into_iter().enumerate() {
                    match w.parse::<f64>() {
                        Ok(x) if x.is_finite() => p[d] = x,
                        Ok(_) => return Err(err(format!("non-finite vertex coordinate `{w}`"))),
                        Err(_) => return Err(err(format!("`{w}` is not a number"))),
                    }
                }
                all_positions.push(p);
                nv += 1;
            }
            Some("vt") => nvt += 1,
            Some("vn") => nvn += 1,
            Some(kind @ ("f" | "l")) => {
                let refs: Vec<&str> = words.collect();
                if kind == "f" {
                    if refs.len() < 3 {
                        return Err(err(format!(
                            "face has {} vertices, needs at least 3",
                            refs.len()
                        )));
                    }
                    nf += 1;
                }
                for r in refs {
                    check_ref(r, [nv, nvt, nvn]).map_err(err)?;
                }
            }
            _ => {}
        }
    }
    Ok(Counts {
        positions: nv,
        faces: nf,
        all_positions,
    })
}

/// Check one `v`, `v/vt`, `v//vn` or `v/vt/vn` face reference against the counts so far.
fn check_ref(r: &str, counts: [usize; 3]) -> Result<(), String> {
    let parts: Vec<&str> = r.split('/').collect();
    if parts.len() > 3 || parts[0].is_empty() {
        return Err(format!("bad face vertex `{r}`"));
    }
    const WHAT: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    for (k, p) in parts.iter().enumerate() {
        if p.is_empty() {
            continue;
        }
        let i: i64 = p.parse().map_err(|_| format!("bad face vertex `{r}`"))?;
        let n = counts[k] as i64;
        let ok = (1..=n).contains(&i) || (-n..=-1).contains(&i);
        if !ok {
            return Err(format!(
                "face refers to {} {i}, but only {n} are defined before this line",
                WHAT[k]
            ));
        }
    }
    Ok(())
}

/// Write `vertices` (V x 3, metres) and `triangles` (F x 3, zero-based) as an OBJ file with
/// `v` and 1-based `f` lines. Coordinates use Rust's shortest round-trip formatting, so
/// reading them back as f64 is exact. Writes what it is given (indices are only range-checked),
/// so tests can produce broken meshes on purpose.
///
/// # Errors
/// [`GeometryError::InvalidInput`] for an index out of range; [`GeometryError::Io`] when writing
/// fails.
pub fn write_obj(
    path: &Path,
    vertices: &[Point3],
    triangles: &[[u32; 3]],
) -> Result<(), GeometryError> {
    super::file::check_triangle_indices(vertices.len(), triangles)?;
    let mut w = create(path)?;
    let mut write = |s: String| w.write_all(s.as_bytes()).map_err(|e| io_error(path, e));
    write(format!(
        "# freeform: {} vertices, {} triangles\n",
        vertices.len(),
        triangles.len()
    ))?;
    for p in vertices {
        write(format!("v {} {} {}\n", p[0], p[1], p[2]))?;
    }
    for t in triangles {
        write(format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1))?;
    }
    finish(path, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_vertex_is_kept_in_file_order_with_faces_re_pointed() {
        // Vertex 2 is unreferenced, vertex 5 duplicates vertex 1's position, and vertex 1 is
        // used by two groups (the loader returns it twice).
        let text = "v 0 0 0\nv 9 9 9\nv 1 0 0\nv 0 1 0\nv 0 0 0\n\
                    g a\nf 1 3 4\ng b\nf 5 4 3\nf 1 4 3\n";
        let (v, t) = parse_obj_raw(Path::new("mem.obj"), text.as_bytes()).unwrap();
        assert_eq!(v.len(), 5);
        assert_eq!(v[1], [9.0, 9.0, 9.0]);
        // Each face points at vertices with its corners' positions.
        let want = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]],
            [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]],
        ];
        assert_eq!(t.len(), 3);
        for (tri, w) in t.iter().zip(want) {
            assert_eq!(tri.map(|i| v[i as usize]), w);
        }
        assert!(t.iter().flatten().all(|&i| i != 1));
    }
}
