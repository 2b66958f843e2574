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

use super::shape::{
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
    Ok((vertices, triangles))
}

/// What [`precheck`] counted.
struct Counts {
    positions: usize,
    faces: usize,
}

/// Validate vertex and face lines (see the module docs) and count them.
fn precheck(path: &Path, text: &str) -> Result<Counts, GeometryError> {
    let (mut nv, mut nvt, mut nvn, mut nf) = (0usize, 0usize, 0usize, 0usize);
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
                for w in xyz {
                    match w.parse::<f64>() {
                        Ok(x) if x.is_finite() => {}
                        Ok(_) => return Err(err(format!("non-finite vertex coordinate `{w}`"))),
                        Err(_) => return Err(err(format!("`{w}` is not a number"))),
                    }
                }
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
    super::check_triangle_indices(vertices.len(), triangles)?;
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
