//! OFF (Object File Format) triangle meshes, ASCII (read and written by hand): the format of
//! CGAL's and Princeton's shape sets.
//!
//! Reading:
//! - An optional header line `OFF`; `COFF`, `NOFF`, `STOFF` and their combinations in
//!   Geomview's order (`[ST][C][N]OFF`, case-sensitive) are accepted and say which extra
//!   per-vertex values follow `x y z` (normals 3, colour 1 to 4, texture coordinates 2); those
//!   are checked to be numbers and ignored. Without such a prefix a vertex line must hold
//!   exactly three numbers. `4OFF`, `nOFF` and `OFF BINARY` are refused with a message saying
//!   so. The counts may follow the keyword on the header line (`OFF 8 6 0`).
//! - `#` starts a comment anywhere on a line; blank and comment-only lines are skipped. A UTF-8
//!   byte order mark and CRLF line ends are accepted.
//! - The counts line `nv nf ne` (three non-negative integers; `ne` is ignored), then `nv`
//!   vertex lines and `nf` face lines, one element per line (an element split over lines is
//!   refused, so every error names the line of its element).
//! - A face line is `n i0 ... i(n-1)` with 0-based indices, optionally followed by up to four
//!   colour values (a colour index or RGB(A)), which are ignored. Faces with more than three
//!   vertices are fan-triangulated from their first vertex (exact for planar polygons, see
//!   [`crate::io::obj`]); bit-identical vertices are welded as by the other readers.
//! - **Trailing content is refused**: anything but blank or comment lines after the declared
//!   faces is an error naming its line, because it means the counts line is wrong and some of
//!   the geometry would be silently dropped.
//! - Declared counts are never trusted for allocation: storage grows with what the file holds.
//!
//! Every error is a [`GeometryError::Parse`] naming the file and `OFF line N` (or, at the end
//! of the file, how many elements were found of how many declared); never a panic or a NaN.
//!
//! Writing: [`write_off`] writes `OFF`, the counts, vertices with round-trip precision and
//! triangles.

use super::file::{create, finish, io_error, mesh_from_file_data, parse_error, read_nonempty};
use crate::geometry::{GeometryError, ShapeOptions, TriMesh};
use crate::Point3;
use std::io::Write;
use std::path::Path;

/// Most colour values accepted after a face's indices (a colour index, RGB or RGBA).
const MAX_FACE_COLOUR: usize = 4;

/// Read an OFF file into a validated mesh (vertices V x 3, metres).
///
/// # Errors
/// [`GeometryError::Io`] if the file cannot be read; [`GeometryError::Parse`] (with the line
/// number) for an empty or non-text file, a missing, garbled or unsupported header or counts
/// line, fewer vertices or faces than declared, malformed or non-finite coordinates, a face
/// with fewer than 3 vertices or an index out of range, content after the declared faces, or
/// no faces; the [`TriMesh::new`] errors (`NotWatertight`, `Misoriented`, `Degenerate`) with
/// the path.
pub fn read_off(path: &Path, opts: &ShapeOptions) -> Result<TriMesh, GeometryError> {
    let (vertices, triangles) = read_off_raw(path)?;
    mesh_from_file_data(path, vertices, triangles, opts)
}

/// Read an OFF file's vertices (V x 3, metres, file order, unreferenced ones kept) and
/// fan-triangulated faces (F x 3, zero-based) without welding or mesh validation. Errors as
/// [`read_off`] minus the mesh checks.
pub fn read_off_raw(path: &Path) -> Result<(Vec<Point3>, Vec<[u32; 3]>), GeometryError> {
    parse_off_raw(path, &read_nonempty(path)?)
}

/// Parse OFF content already in memory into a validated mesh, exactly as [`read_off`] parses
/// a file; `name` only labels the errors.
///
/// # Errors
/// As [`read_off`], minus the file-system errors.
pub fn parse_off_bytes(
    name: &Path,
    bytes: &[u8],
    opts: &ShapeOptions,
) -> Result<TriMesh, GeometryError> {
    let (vertices, triangles) = parse_off_raw(name, bytes)?;
    mesh_from_file_data(name, vertices, triangles, opts)
}

/// Extra per-vertex values a header keyword announces: at least `min`, at most `max`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Extras {
    min: usize,
    max: usize,
}

/// The extras of a header keyword (`OFF`, `COFF`, `NOFF`, `STCNOFF`, ...; case-sensitive, as
/// `nOFF` and `NOFF` differ), `None` if the word is no OFF keyword at all, `Err` for a keyword
/// we recognise but do not read (`4OFF`, `nOFF`).
fn header_extras(word: &str) -> Option<Result<Extras, String>> {
    let mut rest = word.strip_suffix("OFF")?;
    let mut extras = Extras { min: 0, max: 0 };
    for (tag, min, max) in [("ST", 2, 2), ("C", 1, 4), ("N", 3, 3)] {
        if let Some(r) = rest.strip_prefix(tag) {
            rest = r;
            extras.min += min;
            extras.max += max;
        }
    }
    if rest.is_empty() {
        return Some(Ok(extras));
    }
    if rest.chars().all(|c| c == '4' || c == 'n') {
        return Some(Err(format!(
            "`{word}` (4D or n-dimensional OFF) is not supported; only 3D `OFF` (optionally \
             `[ST][C][N]OFF`) is read"
        )));
    }
    None
}

/// The content of a line without its comment, trimmed.
fn content(line: &str) -> &str {
    line.split('#').next().unwrap_or("").trim()
}

/// [`read_off_raw`] on bytes in memory (`path` labels the errors).
fn parse_off_raw(path: &Path, bytes: &[u8]) -> Result<(Vec<Point3>, Vec<[u32; 3]>), GeometryError> {
    if bytes.is_empty() {
        return Err(parse_error(path, "empty file"));
    }
    let text = std::str::from_utf8(bytes).map_err(|e| {
        parse_error(
            path,
            format!(
                "not a text OFF file (invalid UTF-8 at byte {}; binary OFF is not supported)",
                e.valid_up_to()
            ),
        )
    })?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    // Non-blank, comment-stripped lines with their 1-based numbers.
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, content(l)))
        .filter(|(_, l)| !l.is_empty());
    let err = |line: usize, msg: String| parse_error(path, format!("OFF line {line}: {msg}"));

    // Header (optional) and counts.
    let Some((first_no, first)) = lines.next() else {
        return Err(parse_error(
            path,
            "OFF: no header or counts line (the file holds only blank lines or comments)",
        ));
    };
    let mut words: Vec<&str> = first.split_whitespace().collect();
    let mut extras = Extras { min: 0, max: 0 };
    let mut counts_no = first_no;
    if words[0].parse::<u64>().is_err() {
        match header_extras(words[0]) {
            Some(Ok(e)) => extras = e,
            Some(Err(msg)) => return Err(err(first_no, msg)),
            None => {
                return Err(err(
                    first_no,
                    format!(
                        "missing or garbled header: expected `OFF` or the counts line \
                         `nv nf ne`, found `{}`",
                        truncate(first)
                    ),
                ))
            }
        }
        if words
            .get(1)
            .is_some_and(|w| w.eq_ignore_ascii_case("BINARY"))
        {
            return Err(err(first_no, "binary OFF is not supported".into()));
        }
        words.remove(0);
        if words.is_empty() {
            let Some((no, line)) = lines.next() else {
                return Err(err(
                    first_no,
                    "the file ends after the header: the counts line `nv nf ne` is missing".into(),
                ));
            };
            counts_no = no;
            words = line.split_whitespace().collect();
        }
    }
    let [nv, nf] = parse_counts(&words).map_err(|m| err(counts_no, m))?;
    if nv > u32::MAX as u64 {
        return Err(err(
            counts_no,
            format!("{nv} vertices is more than 32-bit indices can address"),
        ));
    }
    if nf == 0 {
        return Err(err(
            counts_no,
            format!(
                "no faces ({nv} vertices declared); an OFF shape needs faces (point clouds \
                 are read from .ply)"
            ),
        ));
    }
    let (nv, nf) = (nv as usize, nf as usize);

    // Grow with the file, not with the declared counts.
    let budget = text.len() / 2 + 1;
    let mut vertices: Vec<Point3> = Vec::with_capacity(nv.min(budget));
    while vertices.len() < nv {
        let Some((no, line)) = lines.next() else {
            return Err(parse_error(
                path,
                format!(
                    "OFF: the file ends after {} of the {nv} vertices the counts line (line \
                     {counts_no}) declares",
                    vertices.len()
                ),
            ));
        };
        vertices.push(parse_vertex(line, extras, vertices.len()).map_err(|m| err(no, m))?);
    }

    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(nf.min(budget));
    for f in 0..nf {
        let Some((no, line)) = lines.next() else {
            return Err(parse_error(
                path,
                format!(
                    "OFF: the file ends after {f} of the {nf} faces the counts line (line \
                     {counts_no}) declares"
                ),
            ));
        };
        push_face(line, f, nv, &mut triangles).map_err(|m| err(no, m))?;
    }
    if let Some((no, line)) = lines.next() {
        return Err(err(
            no,
            format!(
                "unexpected content `{}` after the {nv} vertices and {nf} faces the counts \
                 line (line {counts_no}) declares (is a count wrong?)",
                truncate(line)
            ),
        ));
    }
    Ok((vertices, triangles))
}

/// At most 40 characters of `s`, for messages.
fn truncate(s: &str) -> String {
    match s.char_indices().nth(40) {
        Some((i, _)) => format!("{}...", &s[..i]),
        None => s.to_string(),
    }
}

/// `nv nf ne` as `[nv, nf]`.
fn parse_counts(words: &[&str]) -> Result<[u64; 2], String> {
    if words.len() != 3 {
        return Err(format!(
            "the counts line must be `nv nf ne` (three non-negative integers), found {} \
             value(s) `{}`",
            words.len(),
            truncate(&words.join(" "))
        ));
    }
    let mut n = [0u64; 3];
    for (k, w) in words.iter().enumerate() {
        n[k] = w.parse().map_err(|_| {
            format!(
                "count `{w}` in `nv nf ne` is not a non-negative integer; is the header \
                 garbled?"
            )
        })?;
    }
    Ok([n[0], n[1]])
}

/// One vertex line: `x y z` then the extras the header announced.
fn parse_vertex(line: &str, extras: Extras, index: usize) -> Result<Point3, String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let (min, max) = (3 + extras.min, 3 + extras.max);
    if words.len() < min || words.len() > max {
        let want = if min == max {
            format!("{min}")
        } else {
            format!("{min} to {max}")
        };
        let hint = if extras.max == 0 && words.len() > 3 {
            " (extra per-vertex values need a `COFF`, `NOFF` or `STOFF` header)"
        } else {
            ""
        };
        return Err(format!(
            "vertex {index} has {} values, expected {want}{hint}",
            words.len()
        ));
    }
    let mut p = [0.0; 3];
    for (k, w) in words.iter().enumerate() {
        let x: f64 = w
            .parse()
            .map_err(|_| format!("vertex {index}: `{w}` is not a number"))?;
        if k < 3 {
            if !x.is_finite() {
                return Err(format!(
                    "vertex {index} has a non-finite coordinate {} = `{w}`",
                    ["x", "y", "z"][k]
                ));
            }
            p[k] = x;
        }
    }
    Ok(p)
}

/// One face line `n i0 ... i(n-1) [colour]`, fan-triangulated onto `triangles`.
fn push_face(line: &str, f: usize, nv: usize, triangles: &mut Vec<[u32; 3]>) -> Result<(), String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let n: usize = words[0].parse().map_err(|_| {
        format!(
            "face {f}: vertex count `{}` is not a non-negative integer",
            words[0]
        )
    })?;
    if n < 3 {
        return Err(format!("face {f} has {n} vertices, needs at least 3"));
    }
    let listed = words.len() - 1;
    if listed < n {
        return Err(format!(
            "face {f} declares {n} vertices but lists {listed} values"
        ));
    }
    if listed - n > MAX_FACE_COLOUR {
        return Err(format!(
            "face {f} has {} values after its {n} indices; at most {MAX_FACE_COLOUR} colour \
             values may follow (is the vertex count wrong?)",
            listed - n
        ));
    }
    for w in &words[1 + n..] {
        w.parse::<f64>()
            .map_err(|_| format!("face {f}: colour value `{w}` is not a number"))?;
    }
    let mut idx = Vec::with_capacity(n);
    for w in &words[1..=n] {
        let i: i64 = w
            .parse()
            .map_err(|_| format!("face {f}: vertex index `{w}` is not an integer"))?;
        if i < 0 || i as u64 >= nv as u64 {
            return Err(format!(
                "face {f} refers to vertex {i}, but the file has {nv} vertices (indices are \
                 0-based)"
            ));
        }
        idx.push(i as u32);
    }
    for k in 1..n - 1 {
        triangles.push([idx[0], idx[k], idx[k + 1]]);
    }
    Ok(())
}

/// Write `vertices` (V x 3, metres) and `triangles` (F x 3, zero-based) as an ASCII OFF file.
/// Coordinates use Rust's shortest round-trip formatting, so reading them back is exact.
/// Writes what it is given (indices are only range-checked), so tests can produce broken
/// meshes on purpose.
///
/// # Errors
/// [`GeometryError::InvalidInput`] for an index out of range; [`GeometryError::Io`] when writing
/// fails.
pub fn write_off(
    path: &Path,
    vertices: &[Point3],
    triangles: &[[u32; 3]],
) -> Result<(), GeometryError> {
    super::file::check_triangle_indices(vertices.len(), triangles)?;
    let mut w = create(path)?;
    let mut write = |s: String| w.write_all(s.as_bytes()).map_err(|e| io_error(path, e));
    write(format!(
        "OFF\n# freeform: {} vertices, {} triangles\n{} {} 0\n",
        vertices.len(),
        triangles.len(),
        vertices.len(),
        triangles.len()
    ))?;
    for p in vertices {
        write(format!("{} {} {}\n", p[0], p[1], p[2]))?;
    }
    for t in triangles {
        write(format!("3 {} {} {}\n", t[0], t[1], t[2]))?;
    }
    finish(path, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube as six quads, 0-based, outward.
    const CUBE: &str = "OFF\n# unit cube\n8 6 12\n\
        0 0 0\n1 0 0\n0 1 0\n1 1 0\n0 0 1\n1 0 1\n0 1 1\n1 1 1\n\
        4 0 2 3 1\n4 4 5 7 6\n4 0 1 5 4\n4 2 6 7 3\n4 0 4 6 2\n4 1 3 7 5\n";

    fn raw(text: &str) -> Result<(Vec<Point3>, Vec<[u32; 3]>), GeometryError> {
        parse_off_raw(Path::new("mem.off"), text.as_bytes())
    }

    /// The reason of a parse error (panics otherwise); it must name the file.
    fn reason(text: &str) -> String {
        match raw(text) {
            Err(e @ GeometryError::Parse { .. }) => {
                let s = e.to_string();
                assert!(s.starts_with("mem.off: "), "{s}");
                s
            }
            other => panic!("expected a parse error, got {other:?}"),
        }
    }

    #[test]
    fn cube_of_quads_is_fan_triangulated_and_closed() {
        let (v, t) = raw(CUBE).unwrap();
        assert_eq!(v.len(), 8);
        assert_eq!(t.len(), 12);
        // The first quad 0 2 3 1 becomes the fan (0 2 3), (0 3 1).
        assert_eq!(&t[..2], &[[0, 2, 3], [0, 3, 1]]);
        let m = parse_off_bytes(
            Path::new("mem.off"),
            CUBE.as_bytes(),
            &ShapeOptions::default(),
        )
        .unwrap();
        assert!(m.is_closed() && !m.was_flipped());
        assert_eq!(m.volume(), Some(1.0));
    }

    #[test]
    fn headerless_comments_colours_crlf_and_bom_are_read() {
        let text = "\u{feff}# no header\r\n\r\n  4 4 6 # counts\r\n0 0 0\r\n1 0 0\r\n0 1 0\r\n\
                    0 0 1\r\n3 0 2 1 255 0 0\r\n3 0 1 3 0.5 0.5 0.5 1\r\n3 0 3 2 7\r\n3 1 2 3\r\n\
                    # trailing comment\r\n\r\n";
        let (v, t) = raw(text).unwrap();
        assert_eq!(v.len(), 4);
        assert_eq!(t, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]);
        // Counts on the header line.
        let (v, t) = raw(&CUBE.replacen("OFF\n# unit cube\n8 6 12", "OFF 8 6 12", 1)).unwrap();
        assert_eq!((v.len(), t.len()), (8, 12));
    }

    #[test]
    fn header_variants_allow_their_extra_vertex_values_only() {
        let with = |header: &str, extra: &str| {
            let mut s = String::new();
            for (i, line) in CUBE.lines().enumerate() {
                match i {
                    0 => s.push_str(header),
                    3..=10 => {
                        s.push_str(line);
                        s.push_str(extra);
                    }
                    _ => s.push_str(line),
                }
                s.push('\n');
            }
            s
        };
        assert!(raw(&with("COFF", " 0.1 0.2 0.3 1")).is_ok());
        assert!(raw(&with("COFF", " 255 0 0")).is_ok());
        assert!(raw(&with("NOFF", " 0 0 1")).is_ok());
        assert!(raw(&with("STCNOFF", " 0 0 1 1 1 1 1 0.5 0.5")).is_ok());
        assert!(reason(&with("OFF", " 0.5")).contains(
            "OFF line 4: vertex 0 has 4 values, expected 3 (extra per-vertex values need"
        ));
        assert!(reason(&with("NOFF", "")).contains("vertex 0 has 3 values, expected 6"));
        assert!(reason(&with("NOFF", " 0 0 x")).contains("vertex 0: `x` is not a number"));
        assert!(reason(&with("4OFF", " 1")).contains("OFF line 1: `4OFF`"));
        assert!(reason(&with("nOFF", "")).contains("not supported"));
        assert!(reason(&with("OFF BINARY", "")).contains("binary OFF is not supported"));
    }

    #[test]
    fn missing_or_garbled_header_or_counts() {
        assert!(reason("").contains("empty file"));
        assert!(reason("# only a comment\n\n").contains("no header or counts line"));
        assert!(reason("PLY\n8 6 0\n")
            .contains("OFF line 1: missing or garbled header: expected `OFF` or the counts line"));
        assert!(reason("OFF\n").contains("OFF line 1: the file ends after the header"));
        assert!(reason("OFF\n8 6\n").contains("OFF line 2: the counts line must be `nv nf ne`"));
        assert!(reason("OFF\n8 six 0\n").contains("OFF line 2: count `six`"));
        assert!(reason("OFF\n8 -6 0\n").contains("count `-6`"));
        assert!(reason("OFF\n8 0 0\n").contains("OFF line 2: no faces (8 vertices declared)"));
        assert!(reason("OFF\n99999999999 1 0\n").contains("more than 32-bit indices"));
        match raw("OFF\n\u{ff}") {
            Err(GeometryError::Parse { .. }) => {}
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            parse_off_raw(Path::new("b.off"), &[0xff, 0xfe, 0, 1]),
            Err(GeometryError::Parse { reason, .. }) if reason.contains("not a text OFF file")
        ));
    }

    #[test]
    fn fewer_vertices_or_faces_than_declared() {
        let short_v = CUBE.replace("8 6 12", "9 6 12");
        // The ninth vertex line is the first face line: four values.
        assert!(reason(&short_v).contains("OFF line 12: vertex 8 has 5 values, expected 3"));
        let cut: String = CUBE.lines().take(7).map(|l| format!("{l}\n")).collect();
        assert!(reason(&cut)
            .contains("the file ends after 4 of the 8 vertices the counts line (line 3) declares"));
        let short_f = CUBE.replace("8 6 12", "8 7 12");
        assert!(reason(&short_f).contains("the file ends after 6 of the 7 faces"));
        // A huge declared count fails at the end of the file, not at allocation.
        let huge = CUBE.replace("8 6 12", "8 4000000000 12");
        assert!(reason(&huge).contains("after 6 of the 4000000000 faces"));
    }

    #[test]
    fn bad_faces() {
        let face = |line: &str| CUBE.replace("4 1 3 7 5", line);
        assert!(reason(&face("4 1 3 7 8"))
            .contains("OFF line 17: face 5 refers to vertex 8, but the file has 8 vertices"));
        assert!(reason(&face("4 1 -3 7 5")).contains("face 5 refers to vertex -3"));
        assert!(reason(&face("2 1 3")).contains("face 5 has 2 vertices, needs at least 3"));
        assert!(reason(&face("0")).contains("face 5 has 0 vertices"));
        assert!(reason(&face("4 1 3 7")).contains("face 5 declares 4 vertices but lists 3"));
        assert!(reason(&face("4 1 3 7 5 0 0 0 0 0")).contains("5 values after its 4 indices"));
        assert!(reason(&face("4 1 3 x 5")).contains("vertex index `x` is not an integer"));
        assert!(reason(&face("4 1 3 7 5 red")).contains("colour value `red`"));
        assert!(reason(&face("four 1 3 7 5")).contains("vertex count `four`"));
        assert!(reason(&face("4 1 3 7 99999999999999999999999")).contains("not an integer"));
    }

    #[test]
    fn non_finite_or_non_numeric_coordinates() {
        let vertex = |line: &str| CUBE.replace("1 1 1\n", &format!("{line}\n"));
        assert!(reason(&vertex("1 nan 1"))
            .contains("OFF line 11: vertex 7 has a non-finite coordinate y = `nan`"));
        assert!(reason(&vertex("1 1 inf")).contains("non-finite coordinate z = `inf`"));
        assert!(reason(&vertex("1e999 1 1")).contains("non-finite coordinate x = `1e999`"));
        assert!(reason(&vertex("1 one 1")).contains("OFF line 11: vertex 7: `one` is not a number"));
        assert!(reason(&vertex("1 1")).contains("vertex 7 has 2 values, expected 3"));
    }

    #[test]
    fn trailing_content_is_refused_but_comments_are_not() {
        assert!(raw(&format!("{CUBE}\n# done\n   \n")).is_ok());
        assert!(reason(&format!("{CUBE}3 0 1 2\n")).contains(
            "OFF line 18: unexpected content `3 0 1 2` after the 8 vertices and 6 faces"
        ));
    }

    #[test]
    fn write_then_read_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let (v, t) = crate::geometry::generate::icosphere(0.7, 1);
        let p = dir.path().join("ico.off");
        write_off(&p, &v, &t).unwrap();
        assert_eq!(read_off_raw(&p).unwrap(), (v, t));
    }
}
