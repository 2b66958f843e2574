//! STL triangle meshes, ASCII and binary (read with `stl_io`, written by hand or `stl_io`).
//!
//! STL stores a triangle soup with single-precision coordinates; the reader welds vertices with
//! bit-identical coordinates (`-0.0` = `0.0`) so shared edges are recognized, drops triangles
//! that collapse to a repeated vertex, and builds a validated [`TriMesh`].
//!
//! Format detection does not trust the `solid` keyword (many binary exporters write it into the
//! 80-byte header): a file whose size is exactly `84 + 50 n` with `n` the triangle count at
//! byte 80 is binary; otherwise a file starting with `solid` is ASCII; anything else is read as
//! binary and rejected with the size mismatch.

use super::file::{create, finish, io_error, mesh_from_file_data, parse_error, read_nonempty};
use crate::geometry::{GeometryError, ShapeOptions, TriMesh};
use crate::Point3;
use std::io::{Cursor, Write};
use std::path::Path;

/// Encoding of an STL file written by [`write_stl`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StlFormat {
    /// `solid ... facet normal ... endsolid` text.
    Ascii,
    /// 80-byte header, u32 triangle count, 50 bytes per triangle (little endian).
    Binary,
}

/// Read an ASCII or binary STL file into a validated mesh (vertices V x 3, metres).
///
/// # Errors
/// [`GeometryError::Io`] if the file cannot be read; [`GeometryError::Parse`] for an empty,
/// truncated or malformed file, a non-finite coordinate, or no triangles; the [`TriMesh::new`]
/// errors (`NotWatertight`, `Misoriented`, `Degenerate`) with the path.
pub fn read_stl(path: &Path, opts: &ShapeOptions) -> Result<TriMesh, GeometryError> {
    let (vertices, triangles) = read_stl_soup(path)?;
    mesh_from_file_data(path, vertices, triangles, opts)
}

/// Read an STL file as an unwelded triangle soup: vertices (3F x 3, metres, `[3t, 3t+1, 3t+2]`
/// are triangle t) and the trivial triangles. Errors as [`read_stl`] minus mesh validation.
pub fn read_stl_soup(path: &Path) -> Result<(Vec<Point3>, Vec<[u32; 3]>), GeometryError> {
    let bytes = read_nonempty(path)?;
    soup_from_bytes(path, bytes)
}

/// Parse STL content already in memory into a validated mesh, exactly as [`read_stl`] parses
/// a file; `name` only labels the errors.
///
/// # Errors
/// As [`read_stl`], minus the file-system errors.
pub fn parse_stl_bytes(
    name: &Path,
    bytes: &[u8],
    opts: &ShapeOptions,
) -> Result<TriMesh, GeometryError> {
    if bytes.is_empty() {
        return Err(parse_error(name, "empty file"));
    }
    let (vertices, triangles) = soup_from_bytes(name, bytes.to_vec())?;
    mesh_from_file_data(name, vertices, triangles, opts)
}

/// [`read_stl_soup`] on bytes in memory (non-empty; `path` labels the errors).
fn soup_from_bytes(
    path: &Path,
    bytes: Vec<u8>,
) -> Result<(Vec<Point3>, Vec<[u32; 3]>), GeometryError> {
    let data = classify(path, bytes)?;
    let mut cursor = Cursor::new(data.as_slice());
    let reader = stl_io::create_stl_reader(&mut cursor)
        .map_err(|e| parse_error(path, format!("not a valid STL file: {e}")))?;
    let mut vertices = Vec::new();
    for (t, tri) in reader.enumerate() {
        let tri = tri.map_err(|e| {
            parse_error(
                path,
                format!("STL triangle {t}: {e} (file truncated or malformed?)"),
            )
        })?;
        for v in tri.vertices {
            let p = v.0.map(f64::from);
            if !p.iter().all(|c| c.is_finite()) {
                return Err(parse_error(
                    path,
                    format!("STL triangle {t} has a non-finite coordinate {p:?}"),
                ));
            }
            vertices.push(p);
        }
    }
    if vertices.is_empty() {
        return Err(parse_error(path, "the STL file has no triangles"));
    }
    let nt = (vertices.len() / 3) as u32;
    if vertices.len() / 3 > u32::MAX as usize {
        return Err(parse_error(path, "too many triangles for 32-bit indices"));
    }
    let triangles = (0..nt).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
    Ok((vertices, triangles))
}

/// Decide ASCII or binary and return bytes that `stl_io` reads the right way: a binary header
/// that starts with `solid` is blanked (so `stl_io` does not take it for ASCII), and an ASCII
/// first line that is just `solid` gets the trailing space `stl_io` expects.
fn classify(path: &Path, mut bytes: Vec<u8>) -> Result<Vec<u8>, GeometryError> {
    let len = bytes.len() as u64;
    let declared = (len >= 84).then(|| {
        u64::from(u32::from_le_bytes([
            bytes[80], bytes[81], bytes[82], bytes[83],
        ]))
    });
    let binary_size = declared.map(|n| 84 + 50 * n);
    let text_start = bytes
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(0);
    let starts_solid = bytes[text_start..].starts_with(b"solid");

    // A text file whose size happens to match a binary triangle count stays ASCII.
    let all_text = starts_solid && bytes.iter().all(|b| b.is_ascii());
    if binary_size == Some(len) && !all_text {
        if bytes.starts_with(b"solid") {
            bytes[..5].fill(0);
        }
        return Ok(bytes);
    }
    if starts_solid {
        let rest = &bytes[text_start + 5..];
        let mut fixed = b"solid ".to_vec();
        fixed.extend_from_slice(rest);
        return Ok(fixed);
    }
    match (declared, binary_size) {
        (Some(n), Some(size)) if size > len => {
            let looks_text = bytes[..84]
                .iter()
                .all(|b| b.is_ascii_graphic() || b.is_ascii_whitespace());
            if looks_text {
                Err(parse_error(
                    path,
                    "neither ASCII STL (does not start with `solid`) nor binary STL",
                ))
            } else {
                Err(parse_error(
                    path,
                    format!(
                        "truncated binary STL: the header declares {n} triangles ({size} bytes), \
                         the file has {len} bytes"
                    ),
                ))
            }
        }
        (Some(n), Some(size)) => Err(parse_error(
            path,
            format!(
                "binary STL size mismatch: the header declares {n} triangles ({size} bytes), \
                 the file has {len} bytes (trailing data)"
            ),
        )),
        _ => Err(parse_error(
            path,
            format!(
                "not an STL file: {len} bytes, too short for a binary STL (at least 84) and no \
                 `solid` keyword"
            ),
        )),
    }
}

/// Write triangles (F x 3 indices into `vertices`, V x 3, metres) as an STL file. Coordinates
/// are stored in single precision; facet normals are the unit normals `(b-a) x (c-a)` (zero for
/// degenerate triangles). Writes what it is given (no validation beyond index range), so tests
/// can produce broken meshes on purpose.
///
/// # Errors
/// [`GeometryError::InvalidInput`] for an index out of range; [`GeometryError::Io`] when writing
/// fails.
pub fn write_stl(
    path: &Path,
    vertices: &[Point3],
    triangles: &[[u32; 3]],
    format: StlFormat,
) -> Result<(), GeometryError> {
    super::file::check_triangle_indices(vertices.len(), triangles)?;
    let tris = triangles.iter().map(|t| {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        let n = crate::geometry::winding::unit_normal(&a, &b, &c);
        stl_io::Triangle {
            normal: stl_io::Normal::new(n.map(|x| x as f32)),
            vertices: [a, b, c].map(|p| stl_io::Vertex::new(p.map(|x| x as f32))),
        }
    });
    let mut w = create(path)?;
    match format {
        StlFormat::Binary => {
            stl_io::write_stl(&mut w, tris).map_err(|e| io_error(path, e))?;
        }
        StlFormat::Ascii => {
            let mut text = String::from("solid freeform\n");
            for t in tris {
                let [nx, ny, nz] = t.normal.0;
                text.push_str(&format!(
                    "  facet normal {nx:e} {ny:e} {nz:e}\n    outer loop\n"
                ));
                for v in t.vertices {
                    let [x, y, z] = v.0;
                    text.push_str(&format!("      vertex {x:e} {y:e} {z:e}\n"));
                }
                text.push_str("    endloop\n  endfacet\n");
            }
            text.push_str("endsolid freeform\n");
            w.write_all(text.as_bytes())
                .map_err(|e| io_error(path, e))?;
        }
    }
    finish(path, w)
}
