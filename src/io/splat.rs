//! 3D Gaussian splat PLY files (the layout of the 3DGS reference code): one `vertex` element
//! with `x, y, z`, `f_dc_0..2`, `f_rest_*` (0, 9, 24 or 45: SH degree 0 to 3), `opacity`,
//! `scale_0..2` (natural log of the standard deviations), `rot_0..3` (quaternion, w first)
//! and any other properties (`nx, ny, nz` and extras), which are kept in file order with
//! their types and written back unchanged.
//!
//! Reading ([`read_splats`]): ASCII and binary (either endianness); the header is parsed by
//! `ply-rs-bw`, the payload here. A missing required property, a list property, a zero or
//! non-finite quaternion, a non-finite or out-of-range log-scale or any other non-finite 3DGS
//! value is an error naming the file, the element, the vertex and the property. Non-unit
//! quaternions are normalized (the reference renderer normalizes them too) and counted
//! ([`SplatReadReport`]). Writing ([`write_splats`], [`write_splats_moved`]): binary little
//! endian in the layout read, atomically (a failed write leaves no file).

use super::file::{io_error, parse_error};
use crate::geometry::GeometryError;
use crate::Point3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, Encoding, PropertyType, ScalarType};
use rayon::prelude::*;
use std::fs::File;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;

/// Quaternions whose norm differs from 1 by more than this are counted as normalized (float32
/// files of unit quaternions are within a few 1e-7).
const UNIT_TOLERANCE: f64 = 1e-5;

/// Largest |log-scale| accepted: exp(2 s) must stay a normal f64 with room for the
/// deformation's stretch (exp(600) ~ 1e260). Real splats have |s| < 20.
pub const MAX_LOG_SCALE: f64 = 300.0;

/// Scalar type of a PLY property.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlyType {
    /// `char`, i8.
    Char,
    /// `uchar`, u8.
    UChar,
    /// `short`, i16.
    Short,
    /// `ushort`, u16.
    UShort,
    /// `int`, i32.
    Int,
    /// `uint`, u32.
    UInt,
    /// `float`, f32.
    Float,
    /// `double`, f64.
    Double,
}

impl PlyType {
    fn from_scalar(t: &ScalarType) -> PlyType {
        match t {
            ScalarType::Char => PlyType::Char,
            ScalarType::UChar => PlyType::UChar,
            ScalarType::Short => PlyType::Short,
            ScalarType::UShort => PlyType::UShort,
            ScalarType::Int => PlyType::Int,
            ScalarType::UInt => PlyType::UInt,
            ScalarType::Float => PlyType::Float,
            ScalarType::Double => PlyType::Double,
        }
    }

    /// Size in bytes.
    pub fn size(self) -> usize {
        match self {
            PlyType::Char | PlyType::UChar => 1,
            PlyType::Short | PlyType::UShort => 2,
            PlyType::Int | PlyType::UInt | PlyType::Float => 4,
            PlyType::Double => 8,
        }
    }

    /// The header name (`float`, `uchar`, ...).
    pub fn name(self) -> &'static str {
        match self {
            PlyType::Char => "char",
            PlyType::UChar => "uchar",
            PlyType::Short => "short",
            PlyType::UShort => "ushort",
            PlyType::Int => "int",
            PlyType::UInt => "uint",
            PlyType::Float => "float",
            PlyType::Double => "double",
        }
    }

    fn decode(self, b: &[u8], big: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                f64::from(if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                })
            }};
        }
        match self {
            PlyType::Char => num!(i8, 1),
            PlyType::UChar => num!(u8, 1),
            PlyType::Short => num!(i16, 2),
            PlyType::UShort => num!(u16, 2),
            PlyType::Int => num!(i32, 4),
            PlyType::UInt => num!(u32, 4),
            PlyType::Float => num!(f32, 4),
            PlyType::Double => num!(f64, 8),
        }
    }

    /// Little-endian bytes of `v` in this type (integers saturate; values read from a file
    /// convert back exactly).
    fn encode(self, v: f64, out: &mut Vec<u8>) {
        match self {
            PlyType::Char => out.extend_from_slice(&(v as i8).to_le_bytes()),
            PlyType::UChar => out.extend_from_slice(&(v as u8).to_le_bytes()),
            PlyType::Short => out.extend_from_slice(&(v as i16).to_le_bytes()),
            PlyType::UShort => out.extend_from_slice(&(v as u16).to_le_bytes()),
            PlyType::Int => out.extend_from_slice(&(v as i32).to_le_bytes()),
            PlyType::UInt => out.extend_from_slice(&(v as u32).to_le_bytes()),
            PlyType::Float => out.extend_from_slice(&(v as f32).to_le_bytes()),
            PlyType::Double => out.extend_from_slice(&v.to_le_bytes()),
        }
    }

    /// An ASCII token as a value of this type (floats rounded to the type), or None.
    fn parse(self, token: &str) -> Option<f64> {
        match self {
            PlyType::Float => token.parse::<f32>().ok().map(f64::from),
            PlyType::Double => token.parse::<f64>().ok(),
            _ => {
                let v = token.parse::<i64>().ok()?;
                let (lo, hi) = match self {
                    PlyType::Char => (i8::MIN as i64, i8::MAX as i64),
                    PlyType::UChar => (0, u8::MAX as i64),
                    PlyType::Short => (i16::MIN as i64, i16::MAX as i64),
                    PlyType::UShort => (0, u16::MAX as i64),
                    PlyType::Int => (i32::MIN as i64, i32::MAX as i64),
                    _ => (0, u32::MAX as i64),
                };
                (lo..=hi).contains(&v).then_some(v as f64)
            }
        }
    }
}

/// A vertex property that is not one of the 3DGS properties, kept as read.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraProperty {
    /// Property name.
    pub name: String,
    /// Its type in the file.
    pub ty: PlyType,
    /// One value per splat (exact for every PLY type).
    pub values: Vec<f64>,
}

/// Where a property's values live in [`Splats`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Slot {
    Mean(usize),
    Dc(usize),
    Rest(usize),
    Opacity,
    Scale(usize),
    Rot(usize),
    Extra(usize),
}

/// A set of 3D Gaussian splats with the layout of the file they came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Splats {
    /// Centres, N x 3, metres.
    pub means: Vec<Point3>,
    /// Natural log of the standard deviations along the splat's axes, N x 3.
    pub log_scales: Vec<[f64; 3]>,
    /// Unit quaternions (w, x, y, z) of the axes, N.
    pub rotations: Vec<[f64; 4]>,
    /// Opacity before the sigmoid (as stored), N.
    pub opacities: Vec<f64>,
    /// Degree-0 SH coefficients (`f_dc_0..2`, one per colour channel), N x 3.
    pub sh_dc: Vec<[f64; 3]>,
    /// Higher SH coefficients `f_rest_*`, N x 3 K (K = (degree + 1)^2 - 1), per splat in file
    /// index order: channel-major, `f_rest_{c K + k}` is SH index k + 1 of channel c.
    pub sh_rest: Vec<f64>,
    /// SH degree, 0 to 3.
    pub sh_degree: usize,
    /// Every other vertex property, in file order.
    pub extras: Vec<ExtraProperty>,
    /// Norm of each quaternion as stored (3DGS training leaves them unnormalized; renderers
    /// normalize): written quaternions are scaled back by it, so a file round-trips.
    rotation_norms: Vec<f64>,
    layout: Vec<(String, PlyType, Slot)>,
}

/// What [`read_splats_with_report`] noticed besides errors.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SplatReadReport {
    /// Quaternions whose norm differed from 1 by more than 1e-5 (normalized).
    pub normalized_rotations: usize,
    /// The largest |norm - 1| seen.
    pub max_norm_error: f64,
}

impl SplatReadReport {
    /// A note for `path` if quaternions were not unit (they are used normalized and written
    /// back with their stored norm; 3DGS training files routinely hold such quaternions).
    pub fn warning(&self, path: &Path) -> Option<String> {
        (self.normalized_rotations > 0).then(|| {
            format!(
                "{}: {} splat quaternion(s) rot_0..rot_3 of element `vertex` were not unit \
                 (largest |norm - 1| = {:.3e}) and were normalized",
                path.display(),
                self.normalized_rotations,
                self.max_norm_error
            )
        })
    }
}

/// The fields a deformation changes, for [`write_splats_moved`]: N entries each.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MovedSplats {
    /// Centres, N x 3, metres.
    pub means: Vec<Point3>,
    /// Log-scales, N x 3.
    pub log_scales: Vec<[f64; 3]>,
    /// Unit quaternions (w, x, y, z), N.
    pub rotations: Vec<[f64; 4]>,
    /// `f_rest` coefficients (N x 3 K); None keeps the original ones.
    pub sh_rest: Option<Vec<f64>>,
}

const REQUIRED: [&str; 14] = [
    "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
    "rot_0", "rot_1", "rot_2", "rot_3",
];

/// Names that mark a vertex element as 3DGS splats.
const MARKERS: [&str; 4] = ["opacity", "scale_0", "rot_0", "f_dc_0"];

fn slot_of(name: &str) -> Option<Slot> {
    let idx = |prefix: &str, n: usize| {
        name.strip_prefix(prefix)
            .and_then(|s| s.parse::<usize>().ok())
            .filter(|&k| k < n && name == format!("{prefix}{k}"))
    };
    Some(match name {
        "x" => Slot::Mean(0),
        "y" => Slot::Mean(1),
        "z" => Slot::Mean(2),
        "opacity" => Slot::Opacity,
        _ => {
            if let Some(k) = idx("f_dc_", 3) {
                Slot::Dc(k)
            } else if let Some(k) = idx("f_rest_", usize::MAX) {
                Slot::Rest(k)
            } else if let Some(k) = idx("scale_", 3) {
                Slot::Scale(k)
            } else if let Some(k) = idx("rot_", 4) {
                Slot::Rot(k)
            } else {
                return None;
            }
        }
    })
}

/// The logistic function 1 / (1 + e^-x): a stored 3DGS opacity to 0..1.
pub fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

impl Splats {
    /// Splats in the standard 3DGS layout (`x y z nx ny nz f_dc_0..2 f_rest_* opacity
    /// scale_0..2 rot_0..3`, all `float`, normals zero): means (N x 3, metres), log-scales
    /// (N x 3), unit quaternions (N, w first), opacities (N), SH dc (N x 3) and rest (N x 3 K
    /// for degree 0..=3).
    ///
    /// # Errors
    /// [`GeometryError::InvalidInput`] for a degree above 3 or mismatched lengths.
    pub fn new(
        means: Vec<Point3>,
        log_scales: Vec<[f64; 3]>,
        rotations: Vec<[f64; 4]>,
        opacities: Vec<f64>,
        sh_dc: Vec<[f64; 3]>,
        sh_rest: Vec<f64>,
        sh_degree: usize,
    ) -> Result<Splats, GeometryError> {
        let n = means.len();
        if sh_degree > 3 {
            return Err(GeometryError::InvalidInput(format!(
                "splat SH degree {sh_degree} is above 3"
            )));
        }
        let per = rest_per_splat(sh_degree);
        for (what, len, want) in [
            ("log_scales", log_scales.len(), n),
            ("rotations", rotations.len(), n),
            ("opacities", opacities.len(), n),
            ("sh_dc", sh_dc.len(), n),
            ("sh_rest", sh_rest.len(), n * per),
        ] {
            if len != want {
                return Err(GeometryError::InvalidInput(format!(
                    "splat {what} has {len} values, expected {want}"
                )));
            }
        }
        let f = PlyType::Float;
        let mut layout: Vec<(String, PlyType, Slot)> = Vec::new();
        for (a, nm) in ["x", "y", "z"].iter().enumerate() {
            layout.push((nm.to_string(), f, Slot::Mean(a)));
        }
        let mut extras = Vec::new();
        for nm in ["nx", "ny", "nz"] {
            layout.push((nm.to_string(), f, Slot::Extra(extras.len())));
            extras.push(ExtraProperty {
                name: nm.to_string(),
                ty: f,
                values: vec![0.0; n],
            });
        }
        for c in 0..3 {
            layout.push((format!("f_dc_{c}"), f, Slot::Dc(c)));
        }
        for k in 0..per {
            layout.push((format!("f_rest_{k}"), f, Slot::Rest(k)));
        }
        layout.push(("opacity".into(), f, Slot::Opacity));
        for a in 0..3 {
            layout.push((format!("scale_{a}"), f, Slot::Scale(a)));
        }
        for a in 0..4 {
            layout.push((format!("rot_{a}"), f, Slot::Rot(a)));
        }
        Ok(Splats {
            rotation_norms: vec![1.0; n],
            means,
            log_scales,
            rotations,
            opacities,
            sh_dc,
            sh_rest,
            sh_degree,
            extras,
            layout,
        })
    }

    /// Add a property written after the others (N values of type `ty`).
    ///
    /// # Errors
    /// [`GeometryError::InvalidInput`] for a used or malformed name or a wrong length.
    pub fn with_extra(
        mut self,
        name: &str,
        ty: PlyType,
        values: Vec<f64>,
    ) -> Result<Splats, GeometryError> {
        if name.is_empty()
            || name.chars().any(char::is_whitespace)
            || self.layout.iter().any(|(n, ..)| n == name)
            || slot_of(name).is_some()
        {
            return Err(GeometryError::InvalidInput(format!(
                "splat property name `{name}` is empty, has whitespace, is a 3DGS name or is \
                 used twice"
            )));
        }
        if values.len() != self.len() {
            return Err(GeometryError::InvalidInput(format!(
                "splat property `{name}` has {} values for {} splats",
                values.len(),
                self.len()
            )));
        }
        self.layout
            .push((name.to_string(), ty, Slot::Extra(self.extras.len())));
        self.extras.push(ExtraProperty {
            name: name.to_string(),
            ty,
            values,
        });
        Ok(self)
    }

    /// Number of splats N.
    pub fn len(&self) -> usize {
        self.means.len()
    }

    /// True without splats.
    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// Vertex properties in file order: (name, type).
    pub fn properties(&self) -> impl Iterator<Item = (&str, PlyType)> {
        self.layout.iter().map(|(n, t, _)| (n.as_str(), *t))
    }

    /// `f_rest` values per splat, 3 K.
    pub fn rest_per_splat(&self) -> usize {
        rest_per_splat(self.sh_degree)
    }
}

fn rest_per_splat(degree: usize) -> usize {
    3 * ((degree + 1) * (degree + 1) - 1)
}

/// Whether the PLY file at `path` is a 3DGS splat file: its `vertex` element has one of the
/// properties `opacity`, `scale_0`, `rot_0`, `f_dc_0`. Reads the header only.
///
/// # Errors
/// [`GeometryError::Io`] if it cannot be opened; [`GeometryError::Parse`] for a bad header.
pub fn is_splat_ply(path: &Path) -> Result<bool, GeometryError> {
    let file = File::open(path).map_err(|e| io_error(path, e))?;
    let mut reader = Reader::new(BufReader::new(file));
    let header = Parser::<DefaultElement>::new()
        .read_header(&mut reader)
        .map_err(|e| parse_error(path, format!("PLY: {e}")))?;
    Ok(header
        .elements
        .get("vertex")
        .is_some_and(|v| MARKERS.iter().any(|m| v.properties.contains_key(*m))))
}

/// Read a 3DGS splat PLY. See [`read_splats_with_report`].
///
/// # Errors
/// As [`read_splats_with_report`].
pub fn read_splats(path: &Path) -> Result<Splats, GeometryError> {
    read_splats_with_report(path).map(|(s, _)| s)
}

/// Read a 3DGS splat PLY with what was normalized.
///
/// # Errors
/// [`GeometryError::Io`] if the file cannot be opened; [`GeometryError::Parse`] naming the file,
/// the element and the property for: a bad header, no `vertex` element, a non-empty element
/// besides `vertex`, a list property, a missing required property or `f_rest_*` set, a
/// truncated payload, a wrong ASCII token; naming also the vertex for a zero or non-finite
/// quaternion, a non-finite or out-of-range (|s| > [`MAX_LOG_SCALE`]) log-scale and any other
/// non-finite 3DGS value.
pub fn read_splats_with_report(path: &Path) -> Result<(Splats, SplatReadReport), GeometryError> {
    let file = File::open(path).map_err(|e| io_error(path, e))?;
    if file.metadata().map_err(|e| io_error(path, e))?.is_dir() {
        let e = std::io::Error::new(std::io::ErrorKind::InvalidInput, "is a directory");
        return Err(io_error(path, e));
    }
    read_splats_from(path, &mut BufReader::with_capacity(1 << 20, file))
}

/// [`read_splats_with_report`] from any reader; `path` labels the errors.
///
/// # Errors
/// As [`read_splats_with_report`] minus the file-system errors.
pub fn read_splats_from(
    path: &Path,
    input: &mut impl BufRead,
) -> Result<(Splats, SplatReadReport), GeometryError> {
    let err = |reason: String| parse_error(path, reason);
    let mut reader = Reader::new(input);
    let header = Parser::<DefaultElement>::new()
        .read_header(&mut reader)
        .map_err(|e| err(format!("PLY: {e}")))?;
    let vdef = header
        .elements
        .get("vertex")
        .ok_or_else(|| err("splat PLY has no `vertex` element".into()))?;
    for (name, def) in &header.elements {
        if name != "vertex" && def.count > 0 {
            return Err(err(format!(
                "splat PLY has a non-empty element `{name}` besides `vertex`; a 3DGS file has \
                 only `vertex`"
            )));
        }
    }
    // Layout and required properties.
    let mut layout = Vec::with_capacity(vdef.properties.len());
    let mut extras = Vec::new();
    let mut rest_seen = Vec::new();
    for (name, p) in &vdef.properties {
        let ty = match &p.data_type {
            PropertyType::Scalar(t) => PlyType::from_scalar(t),
            PropertyType::List(..) => {
                return Err(err(format!(
                    "splat PLY element `vertex` property `{name}` is a list; 3DGS properties \
                     are scalars"
                )))
            }
        };
        let slot = match slot_of(name) {
            Some(s) => s,
            None => {
                extras.push(ExtraProperty {
                    name: name.clone(),
                    ty,
                    values: Vec::new(),
                });
                Slot::Extra(extras.len() - 1)
            }
        };
        if let Slot::Rest(k) = slot {
            rest_seen.push(k);
        }
        layout.push((name.clone(), ty, slot));
    }
    for name in REQUIRED {
        if !vdef.properties.contains_key(name) {
            return Err(err(format!(
                "splat PLY element `vertex` has no property `{name}` (a 3DGS file needs x, y, \
                 z, f_dc_0..2, opacity, scale_0..2, rot_0..3)"
            )));
        }
    }
    let nrest = rest_seen.len();
    let degree = match nrest {
        0 => 0,
        9 => 1,
        24 => 2,
        45 => 3,
        _ => {
            return Err(err(format!(
                "splat PLY element `vertex` has {nrest} `f_rest_*` properties; 3DGS files have \
                 0, 9, 24 or 45 (SH degree 0 to 3)"
            )))
        }
    };
    rest_seen.sort_unstable();
    if let Some(k) = (0..nrest).find(|&k| rest_seen[k] != k) {
        return Err(err(format!(
            "splat PLY element `vertex` has no property `f_rest_{k}` (f_rest_0..f_rest_{} are \
             needed for SH degree {degree})",
            nrest - 1
        )));
    }

    let count = vdef.count;
    let reserve = count.min(1 << 20);
    let mut s = Splats {
        rotation_norms: Vec::with_capacity(reserve),
        means: Vec::with_capacity(reserve),
        log_scales: Vec::with_capacity(reserve),
        rotations: Vec::with_capacity(reserve),
        opacities: Vec::with_capacity(reserve),
        sh_dc: Vec::with_capacity(reserve),
        sh_rest: Vec::with_capacity(reserve * nrest),
        sh_degree: degree,
        extras,
        layout,
    };
    let nprop = s.layout.len();
    let mut row = vec![0.0; nprop];
    let push = |s: &mut Splats, row: &[f64]| {
        let mut mean = [0.0; 3];
        let mut scale = [0.0; 3];
        let mut rot = [0.0; 4];
        let mut dc = [0.0; 3];
        let mut opacity = 0.0;
        let base = s.sh_rest.len();
        s.sh_rest.resize(base + nrest, 0.0);
        for (k, &v) in row.iter().enumerate() {
            match s.layout[k].2 {
                Slot::Mean(a) => mean[a] = v,
                Slot::Dc(a) => dc[a] = v,
                Slot::Rest(r) => s.sh_rest[base + r] = v,
                Slot::Opacity => opacity = v,
                Slot::Scale(a) => scale[a] = v,
                Slot::Rot(a) => rot[a] = v,
                Slot::Extra(e) => s.extras[e].values.push(v),
            }
        }
        s.means.push(mean);
        s.log_scales.push(scale);
        s.rotations.push(rot);
        s.sh_dc.push(dc);
        s.opacities.push(opacity);
    };
    match header.encoding {
        Encoding::Ascii => {
            let mut line = String::new();
            let types: Vec<PlyType> = s.layout.iter().map(|l| l.1).collect();
            for i in 0..count {
                line.clear();
                let read = reader
                    .get_mut()
                    .read_line(&mut line)
                    .map_err(|e| io_error(path, e))?;
                if read == 0 {
                    return Err(err(format!(
                        "splat PLY ends in element `vertex` after {i} of {count} vertices"
                    )));
                }
                let mut tokens = line.split_ascii_whitespace();
                for k in 0..nprop {
                    let name = &s.layout[k].0;
                    let token = tokens.next().ok_or_else(|| {
                        err(format!(
                            "splat PLY element `vertex` {i} ends before property `{name}`"
                        ))
                    })?;
                    row[k] = types[k].parse(token).ok_or_else(|| {
                        err(format!(
                            "splat PLY element `vertex` {i} property `{name}` = '{token}' is \
                             not a {}",
                            types[k].name()
                        ))
                    })?;
                }
                if tokens.next().is_some() {
                    return Err(err(format!(
                        "splat PLY element `vertex` {i} has more than {nprop} values"
                    )));
                }
                push(&mut s, &row);
            }
        }
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
            let big = header.encoding == Encoding::BinaryBigEndian;
            let stride: usize = s.layout.iter().map(|l| l.1.size()).sum();
            let types: Vec<(PlyType, usize)> = {
                let mut off = 0;
                s.layout
                    .iter()
                    .map(|l| {
                        let o = off;
                        off += l.1.size();
                        (l.1, o)
                    })
                    .collect()
            };
            const CHUNK: usize = 1 << 14;
            let mut buf = vec![0u8; stride * CHUNK.min(count.max(1))];
            let mut done = 0;
            while done < count {
                let n = CHUNK.min(count - done);
                let bytes = &mut buf[..n * stride];
                reader.get_mut().read_exact(bytes).map_err(|e| {
                    if e.kind() == std::io::ErrorKind::UnexpectedEof {
                        err(format!(
                            "splat PLY is truncated in element `vertex` (header says {count} \
                             vertices of {stride} bytes; fewer than {} are present)",
                            done + n
                        ))
                    } else {
                        io_error(path, e)
                    }
                })?;
                for rec in bytes.chunks_exact(stride) {
                    for (k, &(t, o)) in types.iter().enumerate() {
                        row[k] = t.decode(&rec[o..], big);
                    }
                    push(&mut s, &row);
                }
                done += n;
            }
        }
    }
    let report = validate(path, &mut s)?;
    Ok((s, report))
}

/// Check values and normalize quaternions.
fn validate(path: &Path, s: &mut Splats) -> Result<SplatReadReport, GeometryError> {
    let bad = |i: usize, prop: &str, v: String, why: &str| {
        parse_error(
            path,
            format!("splat PLY element `vertex` {i} property `{prop}` = {v} {why}"),
        )
    };
    let finite = |i: usize, prop: String, v: f64| {
        if v.is_finite() {
            Ok(())
        } else {
            Err(bad(i, &prop, v.to_string(), "is not finite"))
        }
    };
    let per = s.rest_per_splat();
    let mut report = SplatReadReport::default();
    for i in 0..s.len() {
        for a in 0..3 {
            finite(i, ["x", "y", "z"][a].to_string(), s.means[i][a])?;
            finite(i, format!("f_dc_{a}"), s.sh_dc[i][a])?;
            let v = s.log_scales[i][a];
            if !v.is_finite() {
                return Err(bad(
                    i,
                    &format!("scale_{a}"),
                    v.to_string(),
                    "is not finite",
                ));
            }
            if v.abs() > MAX_LOG_SCALE {
                return Err(bad(
                    i,
                    &format!("scale_{a}"),
                    v.to_string(),
                    &format!("is out of range (a log-scale beyond +-{MAX_LOG_SCALE})"),
                ));
            }
        }
        finite(i, "opacity".into(), s.opacities[i])?;
        for (k, &v) in s.sh_rest[i * per..(i + 1) * per].iter().enumerate() {
            finite(i, format!("f_rest_{k}"), v)?;
        }
        let q = s.rotations[i];
        let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(n.is_finite() && n > 0.0) {
            return Err(bad(
                i,
                "rot_0..rot_3",
                format!("({}, {}, {}, {})", q[0], q[1], q[2], q[3]),
                "is a zero or non-finite quaternion",
            ));
        }
        let e = (n - 1.0).abs();
        if e > UNIT_TOLERANCE {
            report.normalized_rotations += 1;
            report.max_norm_error = report.max_norm_error.max(e);
        }
        s.rotations[i] = q.map(|v| v / n);
        s.rotation_norms.push(n);
    }
    Ok(report)
}

/// Write `splats` as a binary little-endian PLY in their layout (property order and types),
/// atomically.
///
/// # Errors
/// [`crate::Error::Io`] or a geometry I/O error when writing fails (no file is left).
pub fn write_splats(path: &Path, splats: &Splats) -> crate::Result<()> {
    write_impl(
        path,
        splats,
        &splats.means,
        &splats.log_scales,
        &splats.rotations,
        &splats.sh_rest,
    )
}

/// Write `base` with the fields a deformation changed (`moved`: means, log-scales, rotations
/// and optionally the `f_rest` coefficients), every other property copied; as
/// [`write_splats`].
///
/// # Errors
/// [`GeometryError::InvalidInput`] (as [`crate::Error`]) if a field of `moved` has the wrong
/// length; as [`write_splats`].
pub fn write_splats_moved(path: &Path, base: &Splats, moved: &MovedSplats) -> crate::Result<()> {
    let n = base.len();
    let rest = moved.sh_rest.as_deref().unwrap_or(&base.sh_rest);
    for (what, len, want) in [
        ("means", moved.means.len(), n),
        ("log_scales", moved.log_scales.len(), n),
        ("rotations", moved.rotations.len(), n),
        ("sh_rest", rest.len(), base.sh_rest.len()),
    ] {
        if len != want {
            return Err(GeometryError::InvalidInput(format!(
                "moved splat {what} has {len} values, expected {want}"
            ))
            .into());
        }
    }
    write_impl(
        path,
        base,
        &moved.means,
        &moved.log_scales,
        &moved.rotations,
        rest,
    )
}

fn write_impl(
    path: &Path,
    s: &Splats,
    means: &[Point3],
    log_scales: &[[f64; 3]],
    rotations: &[[f64; 4]],
    sh_rest: &[f64],
) -> crate::Result<()> {
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by freeform (3D Gaussian \
         splats)\nelement vertex {}\n",
        s.len()
    );
    for (name, ty, _) in &s.layout {
        header.push_str(&format!("property {} {name}\n", ty.name()));
    }
    header.push_str("end_header\n");
    let per = s.rest_per_splat();
    let stride: usize = s.layout.iter().map(|l| l.1.size()).sum();
    let encode = |range: std::ops::Range<usize>| {
        let mut out = Vec::with_capacity(range.len() * stride);
        for i in range {
            for (_, ty, slot) in &s.layout {
                let v = match *slot {
                    Slot::Mean(a) => means[i][a],
                    Slot::Dc(a) => s.sh_dc[i][a],
                    Slot::Rest(k) => sh_rest[i * per + k],
                    Slot::Opacity => s.opacities[i],
                    Slot::Scale(a) => log_scales[i][a],
                    Slot::Rot(a) => rotations[i][a] * s.rotation_norms[i],
                    Slot::Extra(e) => s.extras[e].values[i],
                };
                ty.encode(v, &mut out);
            }
        }
        out
    };
    super::file::write_atomically(path, |tmp| {
        let file = File::create(tmp).map_err(|e| io_error(tmp, e))?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, file);
        w.write_all(header.as_bytes())
            .map_err(|e| io_error(tmp, e))?;
        // Encoded in parallel blocks, written in order.
        const BLOCK: usize = 8192;
        const GROUP: usize = 32 * BLOCK;
        let n = s.len();
        let mut start = 0;
        while start < n {
            let end = (start + GROUP).min(n);
            let blocks: Vec<Vec<u8>> = (start..end)
                .step_by(BLOCK)
                .collect::<Vec<_>>()
                .into_par_iter()
                .map(|b| encode(b..(b + BLOCK).min(end)))
                .collect();
            for b in &blocks {
                w.write_all(b).map_err(|e| io_error(tmp, e))?;
            }
            start = end;
        }
        w.flush().map_err(|e| io_error(tmp, e))?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_parse_names_exactly() {
        assert_eq!(slot_of("f_rest_12"), Some(Slot::Rest(12)));
        assert_eq!(slot_of("f_rest_012"), None);
        assert_eq!(slot_of("scale_3"), None);
        assert_eq!(slot_of("rot_3"), Some(Slot::Rot(3)));
        assert_eq!(slot_of("nx"), None);
    }

    #[test]
    fn ascii_and_binary_read_the_same() {
        let head = |fmt: &str| {
            let mut h = format!("ply\nformat {fmt} 1.0\nelement vertex 2\n");
            for n in REQUIRED {
                h.push_str(&format!("property float {n}\n"));
            }
            h.push_str("property uchar label\nend_header\n");
            h
        };
        let rows = [
            [
                0.5f32, 1.0, -2.0, 0.1, 0.2, 0.3, -1.0, -3.0, -3.5, -4.0, 1.0, 0.0, 0.0, 0.0,
            ],
            [
                1.5, 0.0, 2.0, 0.0, 0.0, 0.0, 2.0, -2.0, -2.0, -2.0, 0.0, 0.0, 2.0, 0.0,
            ],
        ];
        let mut ascii = head("ascii").into_bytes();
        let mut bin = head("binary_little_endian").into_bytes();
        for (i, r) in rows.iter().enumerate() {
            let text: Vec<String> = r.iter().map(|v| v.to_string()).collect();
            ascii.extend_from_slice(format!("{} {}\n", text.join(" "), 7 + i).as_bytes());
            for v in r {
                bin.extend_from_slice(&v.to_le_bytes());
            }
            bin.push(7 + i as u8);
        }
        let p = Path::new("mem.ply");
        let (a, ra) = read_splats_from(p, &mut std::io::Cursor::new(ascii)).unwrap();
        let (b, _) = read_splats_from(p, &mut std::io::Cursor::new(bin)).unwrap();
        assert_eq!(a, b);
        assert_eq!(ra.normalized_rotations, 1);
        assert_eq!(a.rotations[1], [0.0, 0.0, 1.0, 0.0]);
        assert_eq!(a.extras[0].values, vec![7.0, 8.0]);
        assert_eq!(a.extras[0].ty, PlyType::UChar);
        assert_eq!(a.sh_degree, 0);
        // The non-unit quaternion (0, 0, 2, 0) is used normalized and written back as stored.
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("back.ply");
        write_splats(&out, &a).unwrap();
        let written = std::fs::read(&out).unwrap();
        let body = &written[written.len() - 2 * (14 * 4 + 1)..];
        let rot_of = |row: usize| -> Vec<f32> {
            let at = row * (14 * 4 + 1) + 10 * 4;
            (0..4)
                .map(|k| f32::from_le_bytes(body[at + 4 * k..at + 4 * k + 4].try_into().unwrap()))
                .collect()
        };
        assert_eq!(rot_of(1), vec![0.0, 0.0, 2.0, 0.0]);
        assert_eq!(rot_of(0), vec![1.0, 0.0, 0.0, 0.0]);
    }
}
