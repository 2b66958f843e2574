//! PLY meshes and point clouds, ASCII and binary (read with `ply-rs-bw`, written by hand).
//!
//! Reading:
//! - The `vertex` element must have scalar `x`, `y`, `z` properties (any numeric type); every
//!   other vertex property is skipped without being stored, so 3D Gaussian splat files
//!   (`x, y, z, nx, ny, nz, f_dc_*, f_rest_*, opacity, scale_*, rot_*`) cost 32 bytes per
//!   splat while reading.
//! - A non-empty `face` element (list property `vertex_indices` or `vertex_index`) makes the
//!   file a mesh; faces with more than three vertices are fan-triangulated from their first
//!   vertex (exact for planar polygons, see [`crate::io::obj`]); bit-identical vertices are
//!   welded. Without faces (or with `element face 0`) the file is a point cloud.
//! - Errors name the element and index; truncated payloads, wrong counts, non-finite
//!   coordinates and out-of-range indices are all reported, never panicking. In an ASCII
//!   payload a value that is not a finite number of its property's type (`nan`, `inf`, a word,
//!   `1e39` for a `float`) is reported with its line, element, property and text, e.g.
//!   `PLY line 11: vertex 1 has a non-finite coordinate x = 'nan'; remove or fix that vertex`;
//!   a binary NaN or Inf coordinate names the vertex, the axis and the value.
//!
//! Writing: [`write_ply_points`] (binary little endian, `float` properties) and
//! [`write_ply_points_with`] / [`write_ply_mesh`] with explicit [`PlyWriteOptions`].

use super::file::{create, finish, first_non_finite, io_error, mesh_from_file_data, parse_error};
use crate::geometry::{GeometryError, PointCloud, Shape, ShapeOptions};
use crate::Point3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    ElementDef, Encoding, Header, Payload, Property, PropertyAccess, PropertyAccessResult,
    PropertyType, ScalarType,
};
use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;

/// Names accepted for the face index list.
const FACE_LISTS: [&str; 2] = ["vertex_indices", "vertex_index"];

/// What a PLY file holds, before validation as a [`Shape`].
#[derive(Debug, Clone, PartialEq)]
pub struct PlyData {
    /// Vertex positions, V x 3, metres (finite).
    pub points: Vec<Point3>,
    /// Fan-triangulated faces (F x 3, zero-based, in range); `None` if the file has no faces.
    pub triangles: Option<Vec<[u32; 3]>>,
}

/// Read a PLY file as a [`Shape`]: [`Shape::Mesh`] if it has faces, else
/// [`Shape::PointCloud`].
///
/// # Errors
/// [`GeometryError::Io`] if the file cannot be opened; [`GeometryError::Parse`] for an empty or
/// malformed file (bad header, truncated payload, wrong counts), missing `x`/`y`/`z`, non-finite
/// coordinates, bad faces; the [`crate::geometry::TriMesh::new`] or [`PointCloud::new`] errors
/// with the path.
pub fn read_ply(path: &Path, opts: &ShapeOptions) -> Result<Shape, GeometryError> {
    shape_from_data(path, read_ply_data(path)?, opts)
}

/// Parse PLY content already in memory as a [`Shape`], exactly as [`read_ply`] parses a
/// file; `name` only labels the errors (e.g. the file or URL the bytes came from).
///
/// # Errors
/// As [`read_ply`], minus the file-system errors.
pub fn parse_ply_bytes(
    name: &Path,
    bytes: &[u8],
    opts: &ShapeOptions,
) -> Result<Shape, GeometryError> {
    if bytes.is_empty() {
        return Err(parse_error(name, "empty file"));
    }
    let data = read_ply_data_from(name, &mut std::io::Cursor::new(bytes))?;
    shape_from_data(name, data, opts)
}

fn shape_from_data(
    path: &Path,
    data: PlyData,
    opts: &ShapeOptions,
) -> Result<Shape, GeometryError> {
    match data.triangles {
        Some(triangles) => Ok(Shape::Mesh(mesh_from_file_data(
            path,
            data.points,
            triangles,
            opts,
        )?)),
        None => Ok(Shape::PointCloud(
            PointCloud::new(data.points).map_err(|e| e.with_path(path))?,
        )),
    }
}

/// Read only the vertex positions of a PLY file (faces, if any, are parsed and ignored) as a
/// point cloud: the way to load splat centres or scanned points.
///
/// # Errors
/// As [`read_ply`]; `Degenerate` if there are no vertices.
pub fn read_ply_points(path: &Path) -> Result<PointCloud, GeometryError> {
    let data = read_ply_data(path)?;
    PointCloud::new(data.points).map_err(|e| e.with_path(path))
}

/// Read a PLY file's positions and faces without building a shape.
///
/// # Errors
/// As [`read_ply`] minus the shape validation.
pub fn read_ply_data(path: &Path) -> Result<PlyData, GeometryError> {
    let file = File::open(path).map_err(|e| io_error(path, e))?;
    let meta = file.metadata().map_err(|e| io_error(path, e))?;
    if meta.is_dir() {
        let e = std::io::Error::new(std::io::ErrorKind::InvalidInput, "is a directory");
        return Err(io_error(path, e));
    }
    if meta.len() == 0 {
        return Err(parse_error(path, "empty file"));
    }
    read_ply_data_from(path, &mut BufReader::new(file))
}

/// Parse PLY content from `reader` (positions and faces, no shape validation); `path` only
/// labels the errors.
///
/// # Errors
/// As [`read_ply_data`], minus the file-system errors.
pub fn read_ply_data_from(
    path: &Path,
    reader: &mut impl BufRead,
) -> Result<PlyData, GeometryError> {
    let parser = Parser::<Record>::new();
    let mut reader = Reader::new(reader);
    let header = parser
        .read_header(&mut reader)
        .map_err(|e| parse_error(path, format!("PLY: {e}")))?;
    // ASCII payloads are read line by line here (each line parsed by ply-rs-bw) so that a
    // value the grammar rejects (`nan`, `inf`, a word) is reported by line, element and
    // token instead of as the grammar's expected-token dump.
    let payload = match header.encoding {
        Encoding::Ascii => read_ascii_payload(path, &parser, &mut reader, &header)?,
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => parser
            .read_payload(&mut reader, &header)
            .map_err(|e| parse_error(path, format!("PLY: {e}")))?,
    };

    let vdef = header
        .elements
        .get("vertex")
        .ok_or_else(|| parse_error(path, "PLY has no `vertex` element"))?;
    for name in ["x", "y", "z"] {
        match vdef.properties.get(name).map(|p| &p.data_type) {
            Some(PropertyType::Scalar(_)) => {}
            Some(PropertyType::List(..)) => {
                return Err(parse_error(
                    path,
                    format!("PLY vertex property `{name}` is a list"),
                ))
            }
            None => {
                return Err(parse_error(
                    path,
                    format!("PLY vertex element has no `{name}` property"),
                ))
            }
        }
    }
    let records = payload.get("vertex").map(Vec::as_slice).unwrap_or(&[]);
    let points: Vec<Point3> = records.iter().map(|r| r.xyz).collect();
    // ASCII vertices were checked with their line numbers; this catches binary NaN and Inf.
    if let Some(i) = first_non_finite(&points) {
        let (axis, value) = ["x", "y", "z"]
            .into_iter()
            .zip(points[i])
            .find(|(_, v)| !v.is_finite())
            .unwrap_or(("x", points[i][0]));
        return Err(parse_error(
            path,
            format!(
                "PLY vertex {i} has a non-finite coordinate {axis} = {value}; remove or fix \
                 that vertex"
            ),
        ));
    }

    let faces = match header.elements.get("face") {
        Some(fdef) if fdef.count > 0 => {
            if !FACE_LISTS.iter().any(|n| fdef.properties.contains_key(*n)) {
                return Err(parse_error(
                    path,
                    "PLY face element has no `vertex_indices` (or `vertex_index`) list",
                ));
            }
            payload.get("face").map(Vec::as_slice).unwrap_or(&[])
        }
        _ => &[],
    };
    let triangles = if faces.is_empty() {
        None
    } else {
        Some(triangulate(path, faces, points.len())?)
    };
    Ok(PlyData { points, triangles })
}

/// Most elements reserved up front for one ASCII element list: the header's count is not trusted
/// (`element vertex 1000000000000000` in a small file must fail at the end of the file, not in
/// the allocator); beyond this the vector grows as lines are actually read. 65,536 records of
/// 48 bytes are 3 MB, small next to the text that fills them.
const MAX_ASCII_PREALLOCATION: usize = 1 << 16;

/// Read an ASCII payload element by element, one line per element, in header order.
fn read_ascii_payload(
    path: &Path,
    parser: &Parser<Record>,
    reader: &mut Reader<impl BufRead>,
    header: &Header,
) -> Result<Payload<Record>, GeometryError> {
    // The reader stands on the first payload line (1-based) after the header.
    let mut line_no = reader.line();
    let mut payload = Payload::with_capacity(header.elements.len());
    let mut line = String::new();
    for (name, def) in &header.elements {
        let mut records = Vec::with_capacity(def.count.min(MAX_ASCII_PREALLOCATION));
        for i in 0..def.count {
            line.clear();
            let read = reader
                .get_mut()
                .read_line(&mut line)
                .map_err(|e| parse_error(path, format!("PLY line {line_no}: {e}")))?;
            if read == 0 {
                return Err(parse_error(
                    path,
                    format!(
                        "PLY line {line_no}: unexpected end of file in element `{name}` \
                         (expected {}, got {i})",
                        def.count
                    ),
                ));
            }
            let record = match parser.read_ascii_element(&line, def) {
                Ok(r) => r,
                Err(e) => return Err(ascii_element_error(path, line_no, def, i, &line, &e)),
            };
            if name == "vertex" && !record.xyz.iter().all(|c| c.is_finite()) {
                // A number too large for its type (`1e39` as `float`) parses to infinity.
                let e = "a coordinate is not finite";
                return Err(ascii_element_error(path, line_no, def, i, &line, &e));
            }
            records.push(record);
            line_no += 1;
        }
        payload.insert(name.clone(), records);
    }
    Ok(payload)
}

/// A short error for ASCII element `index` on line `line_no` that failed to parse (`cause`):
/// the property and token at fault where one can be found, else the parser's first line.
fn ascii_element_error(
    path: &Path,
    line_no: usize,
    def: &ElementDef,
    index: usize,
    line: &str,
    cause: &dyn std::fmt::Display,
) -> GeometryError {
    let element = &def.name;
    let reason = match find_bad_token(line, def) {
        TokenCheck::Bad {
            property,
            token,
            problem,
        } => {
            let what = if element == "vertex" && ["x", "y", "z"].contains(&property) {
                "coordinate"
            } else {
                "value"
            };
            format!(
                "{element} {index} has a {problem} {what} {property} = '{token}'; remove or fix \
                 that {element}"
            )
        }
        TokenCheck::Missing { property } => format!(
            "{element} {index} ends before its property {property}; give every {element} all \
             {} properties",
            def.properties.len()
        ),
        TokenCheck::Fine => {
            let cause = cause.to_string();
            let first = cause.lines().next().unwrap_or_default().trim();
            format!("cannot read {element} {index}: {first}")
        }
    };
    parse_error(path, format!("PLY line {line_no}: {reason}"))
}

/// The first token of an ASCII element line that its property's type cannot hold.
#[derive(Debug, PartialEq)]
enum TokenCheck<'a> {
    /// `token` (for `property`) is `problem` ("non-finite", "non-numeric", "non-integer").
    Bad {
        property: &'a str,
        token: &'a str,
        problem: &'static str,
    },
    /// The line ends before `property`.
    Missing { property: &'a str },
    /// Every property has a valid token.
    Fine,
}

/// Walk the tokens of `line` along the properties of `def` (a list consumes its count, then that
/// many items) and report the first one its type cannot hold.
fn find_bad_token<'a>(line: &'a str, def: &'a ElementDef) -> TokenCheck<'a> {
    let mut tokens = line.split_ascii_whitespace();
    // The next token of `property` if type `t` can hold it, else what is wrong with it.
    let mut next = |property: &'a str, t: &ScalarType| -> Result<&'a str, TokenCheck<'a>> {
        let token = tokens.next().ok_or(TokenCheck::Missing { property })?;
        match token_problem(token, t) {
            None => Ok(token),
            Some(problem) => Err(TokenCheck::Bad {
                property,
                token,
                problem,
            }),
        }
    };
    for (property, p) in &def.properties {
        let property = property.as_str();
        let (count, item_type) = match &p.data_type {
            PropertyType::Scalar(t) => (1, t),
            PropertyType::List(count_type, item) => {
                let token = match next(property, count_type) {
                    Ok(token) => token,
                    Err(check) => return check,
                };
                // A count that is no usize (negative) leaves the grammar's error to speak.
                match token.parse::<usize>() {
                    Ok(n) => (n, item),
                    Err(_) => return TokenCheck::Fine,
                }
            }
        };
        for _ in 0..count {
            if let Err(check) = next(property, item_type) {
                return check;
            }
        }
    }
    TokenCheck::Fine
}

/// Why `token` is not a value of type `t`, if it is not.
fn token_problem(token: &str, t: &ScalarType) -> Option<&'static str> {
    let finite = match t {
        ScalarType::Float => token.parse::<f32>().map(f32::is_finite),
        ScalarType::Double => token.parse::<f64>().map(f64::is_finite),
        _ => {
            return match token.parse::<i64>() {
                Ok(_) => None,
                Err(_) if token.parse::<f64>().is_ok() => Some("non-integer"),
                Err(_) => Some("non-numeric"),
            }
        }
    };
    match finite {
        Ok(true) => None,
        Ok(false) => Some("non-finite"),
        Err(_) => Some("non-numeric"),
    }
}

/// Fan-triangulate the face lists, checking sizes and index ranges.
fn triangulate(path: &Path, faces: &[Record], nv: usize) -> Result<Vec<[u32; 3]>, GeometryError> {
    let mut triangles = Vec::with_capacity(faces.len());
    for (f, rec) in faces.iter().enumerate() {
        let list = &rec.list;
        if list.len() < 3 {
            return Err(parse_error(
                path,
                format!("PLY face {f} has {} vertices, needs at least 3", list.len()),
            ));
        }
        if let Some(&i) = list.iter().find(|&&i| i < 0 || i as u64 >= nv as u64) {
            return Err(parse_error(
                path,
                format!("PLY face {f} refers to vertex {i}, but the file has {nv} vertices"),
            ));
        }
        for k in 1..list.len() - 1 {
            triangles.push([list[0], list[k], list[k + 1]].map(|i| i as u32));
        }
    }
    Ok(triangles)
}

/// One PLY element as read: only what we use is stored.
#[derive(Debug, Default)]
struct Record {
    /// `x`, `y`, `z` (vertex elements).
    xyz: Point3,
    /// `vertex_indices` / `vertex_index` (face elements).
    list: Vec<i64>,
}

impl PropertyAccess for Record {
    fn new() -> Self {
        Record::default()
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        let axis = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            n if FACE_LISTS.contains(&n) => {
                return match integer_list(property) {
                    Some(list) => {
                        self.list = list;
                        PropertyAccessResult::Set
                    }
                    None => PropertyAccessResult::UnsupportedType,
                };
            }
            _ => return PropertyAccessResult::Ignored,
        };
        match scalar(&property) {
            Some(v) => {
                self.xyz[axis] = v;
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::UnsupportedType,
        }
    }
}

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => f64::from(v),
        Property::UChar(v) => f64::from(v),
        Property::Short(v) => f64::from(v),
        Property::UShort(v) => f64::from(v),
        Property::Int(v) => f64::from(v),
        Property::UInt(v) => f64::from(v),
        Property::Float(v) => f64::from(v),
        Property::Double(v) => v,
        _ => return None,
    })
}

fn integer_list(p: Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
        Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
        Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
        Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
        Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
        Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
        _ => return None,
    })
}

/// PLY encodings [`write_ply_points_with`] and [`write_ply_mesh`] can produce.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyFormat {
    /// `format ascii 1.0`; numbers in shortest round-trip notation.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
}

/// Scalar type for the written coordinates and extra properties.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyScalar {
    /// 32-bit `float`: what splat viewers and most tools expect.
    Float,
    /// 64-bit `double`: lossless.
    Double,
}

/// How to write a PLY file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[must_use]
pub struct PlyWriteOptions {
    /// Encoding. Default binary little endian (compact, fast).
    pub format: PlyFormat,
    /// Scalar type of x, y, z and the extra properties. Default `float`, the type viewers of
    /// Gaussian splats and point clouds expect.
    pub scalar: PlyScalar,
}

impl Default for PlyWriteOptions {
    fn default() -> Self {
        PlyWriteOptions {
            format: PlyFormat::BinaryLittleEndian,
            scalar: PlyScalar::Float,
        }
    }
}

/// Write points (N x 3, metres) with optional extra per-point properties as a binary
/// little-endian PLY with `float` properties: `element vertex N`, `x y z`, then each extra
/// `(name, values)` in order (values: N entries, any unit). Same as [`write_ply_points_with`]
/// with default options.
///
/// # Errors
/// See [`write_ply_points_with`].
pub fn write_ply_points(
    path: &Path,
    points: &[Point3],
    extra: &[(&str, &[f64])],
) -> Result<(), GeometryError> {
    write_ply_points_with(path, points, extra, PlyWriteOptions::default())
}

/// Write points (N x 3, metres) and extra per-point properties (`(name, N values)`) as a PLY
/// point set in the given format and scalar type.
///
/// # Errors
/// [`GeometryError::InvalidInput`] if an extra has the wrong length or a bad name (empty,
/// whitespace, `x`/`y`/`z` or duplicated); [`GeometryError::Io`] when writing fails.
pub fn write_ply_points_with(
    path: &Path,
    points: &[Point3],
    extra: &[(&str, &[f64])],
    opts: PlyWriteOptions,
) -> Result<(), GeometryError> {
    let mut names: Vec<&str> = vec!["x", "y", "z"];
    for (name, values) in extra {
        if name.is_empty() || name.chars().any(char::is_whitespace) || names.contains(name) {
            return Err(GeometryError::InvalidInput(format!(
                "PLY property name `{name}` is empty, contains whitespace, or is used twice"
            )));
        }
        if values.len() != points.len() {
            return Err(GeometryError::InvalidInput(format!(
                "PLY property `{name}` has {} values for {} points",
                values.len(),
                points.len()
            )));
        }
        names.push(name);
    }
    let mut w = create(path)?;
    let mut header = header_start(opts, points.len());
    let ty = scalar_name(opts.scalar);
    for n in &names {
        header.push_str(&format!("property {ty} {n}\n"));
    }
    header.push_str("end_header\n");
    let mut out = header.into_bytes();
    let mut row: Vec<f64> = Vec::with_capacity(names.len());
    for (i, p) in points.iter().enumerate() {
        row.clear();
        row.extend_from_slice(p);
        row.extend(extra.iter().map(|(_, v)| v[i]));
        push_row(&mut out, &row, opts);
        if out.len() > 1 << 20 {
            w.write_all(&out).map_err(|e| io_error(path, e))?;
            out.clear();
        }
    }
    w.write_all(&out).map_err(|e| io_error(path, e))?;
    finish(path, w)
}

/// Write a triangle mesh (vertices V x 3 metres, triangles F x 3 zero-based) as a PLY with
/// `element vertex` (x, y, z) and `element face` (`list uchar int vertex_indices`). Writes what
/// it is given (indices only range-checked), so tests can produce broken meshes on purpose.
///
/// # Errors
/// [`GeometryError::InvalidInput`] for an index out of range; [`GeometryError::Io`] when writing
/// fails.
pub fn write_ply_mesh(
    path: &Path,
    vertices: &[Point3],
    triangles: &[[u32; 3]],
    opts: PlyWriteOptions,
) -> Result<(), GeometryError> {
    super::file::check_triangle_indices(vertices.len(), triangles)?;
    let mut header = header_start(opts, vertices.len());
    let ty = scalar_name(opts.scalar);
    for n in ["x", "y", "z"] {
        header.push_str(&format!("property {ty} {n}\n"));
    }
    header.push_str(&format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        triangles.len()
    ));
    let mut out = header.into_bytes();
    for p in vertices {
        push_row(&mut out, p, opts);
    }
    for t in triangles {
        match opts.format {
            PlyFormat::Ascii => {
                out.extend_from_slice(format!("3 {} {} {}\n", t[0], t[1], t[2]).as_bytes())
            }
            PlyFormat::BinaryLittleEndian => {
                out.push(3);
                for &i in t {
                    out.extend_from_slice(&(i as i32).to_le_bytes());
                }
            }
        }
    }
    let mut w = create(path)?;
    w.write_all(&out).map_err(|e| io_error(path, e))?;
    finish(path, w)
}

fn header_start(opts: PlyWriteOptions, n: usize) -> String {
    let format = match opts.format {
        PlyFormat::Ascii => "ascii",
        PlyFormat::BinaryLittleEndian => "binary_little_endian",
    };
    format!("ply\nformat {format} 1.0\ncomment written by freeform\nelement vertex {n}\n")
}

fn scalar_name(s: PlyScalar) -> &'static str {
    match s {
        PlyScalar::Float => "float",
        PlyScalar::Double => "double",
    }
}

fn push_row(out: &mut Vec<u8>, row: &[f64], opts: PlyWriteOptions) {
    match (opts.format, opts.scalar) {
        (PlyFormat::Ascii, scalar) => {
            let text: Vec<String> = row
                .iter()
                .map(|&v| match scalar {
                    PlyScalar::Float => format!("{}", v as f32),
                    PlyScalar::Double => format!("{v}"),
                })
                .collect();
            out.extend_from_slice(text.join(" ").as_bytes());
            out.push(b'\n');
        }
        (PlyFormat::BinaryLittleEndian, PlyScalar::Float) => {
            for &v in row {
                out.extend_from_slice(&(v as f32).to_le_bytes());
            }
        }
        (PlyFormat::BinaryLittleEndian, PlyScalar::Double) => {
            for &v in row {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
}
