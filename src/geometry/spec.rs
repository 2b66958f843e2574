//! Parsing of shape specs: `box:LX,LY,LZ`, `sphere:R`, or a path to a shape file. Parsing reads
//! no file: [`crate::io::read_shape`] reads the files a spec names.

use super::{GeometryError, Shape};
use std::path::{Path, PathBuf};

/// A parsed shape spec: a primitive, or a shape file for [`crate::io`] to read
/// ([`crate::io::read_shape_spec`]).
#[derive(Debug, Clone, PartialEq)]
pub enum ShapeSpec {
    /// `box:LX,LY,LZ`: the box `[0, LX] x [0, LY] x [0, LZ]`, edge lengths in metres.
    Box {
        /// Edge lengths, metres, all positive.
        size: [f64; 3],
    },
    /// `sphere:R`: the ball of radius R (metres) centred at the origin.
    Sphere {
        /// Radius, metres, positive.
        radius: f64,
    },
    /// A path to a shape file of a supported format (by its extension, case-insensitive).
    File {
        /// The path as given (surrounding whitespace removed).
        path: PathBuf,
        /// The format its extension names.
        format: ShapeFileFormat,
    },
    /// A path to a voxel image (`.nii`, `.nii.gz` or `.npy`) whose filled voxels are the shape
    /// ([`crate::io::image`]); a `.npy` has no spacing, so only a scene's `[object.image]`
    /// table (which gives it) can use one.
    Image {
        /// The path as given (surrounding whitespace removed).
        path: PathBuf,
    },
    /// A prim of a USD stage (`.usd`, `.usda`, `.usdc` or `.usdz`): `scene.usda:/World/Table`
    /// names the prim, `scene.usda:/World/Table@12` also the time code to read a time-sampled
    /// prim at; a bare `scene.usda` takes the stage's only mesh or points prim
    /// ([`crate::io::usd`]).
    Usd {
        /// The stage file as given (surrounding whitespace removed).
        path: PathBuf,
        /// The prim path (absolute, as written after the `:`); None: the stage's only mesh or
        /// points prim.
        prim: Option<String>,
        /// The time code to read at (after `@`); None: the prim's default value.
        time: Option<f64>,
    },
}

/// The shape file formats a spec may name, by extension (case-insensitive).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShapeFileFormat {
    /// `.obj`: a Wavefront OBJ triangle mesh ([`crate::io::obj`]).
    Obj,
    /// `.stl`: an ASCII or binary STL triangle mesh ([`crate::io::stl`]).
    Stl,
    /// `.off`: an ASCII OFF (Object File Format) polygon mesh ([`crate::io::off`]).
    Off,
    /// `.ply`: a PLY mesh (non-empty `face` element) or point cloud, Gaussian splat files
    /// included ([`crate::io::ply`]).
    Ply,
}

impl ShapeSpec {
    /// Parse a shape spec without reading any file: `box:LX,LY,LZ` or `sphere:R` (positive
    /// finite numbers, metres; prefix case-insensitive), or a path to a `.obj`, `.stl`, `.off`,
    /// `.ply`, `.nii`, `.nii.gz` or `.npy` file (extension case-insensitive).
    ///
    /// # Errors
    /// [`GeometryError::BadPrimitive`] for missing, extra, non-numeric, non-finite, zero or
    /// negative sizes; [`GeometryError::UnknownSpec`] for anything else that is not a
    /// supported file name.
    pub fn parse(spec: &str) -> Result<ShapeSpec, GeometryError> {
        let trimmed = spec.trim();
        let lower = trimmed.to_ascii_lowercase();
        if let Some(rest) = strip_prefix_ci(trimmed, "box:") {
            let v = numbers(spec, rest, 3, "box:LX,LY,LZ (three edge lengths, metres)")?;
            return Ok(ShapeSpec::Box {
                size: [v[0], v[1], v[2]],
            });
        }
        if let Some(rest) = strip_prefix_ci(trimmed, "sphere:") {
            let v = numbers(spec, rest, 1, "sphere:R (radius, metres)")?;
            return Ok(ShapeSpec::Sphere { radius: v[0] });
        }
        if lower == "box" || lower == "sphere" {
            return Err(bad(
                spec,
                format!("missing sizes: write {lower}:{}", usage(&lower)),
            ));
        }
        if let Some(usd) = parse_usd(spec, trimmed)? {
            return Ok(usd);
        }
        let path = Path::new(trimmed);
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let format = match ext.as_deref() {
            Some("obj") => ShapeFileFormat::Obj,
            Some("stl") => ShapeFileFormat::Stl,
            Some("off") => ShapeFileFormat::Off,
            Some("ply") => ShapeFileFormat::Ply,
            Some("nii" | "npy") => {
                return Ok(ShapeSpec::Image {
                    path: path.to_path_buf(),
                })
            }
            Some("gz") if lower.ends_with(".nii.gz") => {
                return Ok(ShapeSpec::Image {
                    path: path.to_path_buf(),
                })
            }
            _ => return Err(GeometryError::UnknownSpec(spec.to_string())),
        };
        Ok(ShapeSpec::File {
            path: path.to_path_buf(),
            format,
        })
    }

    /// The file a spec names; `None` for a primitive.
    pub fn path(&self) -> Option<&Path> {
        match self {
            ShapeSpec::File { path, .. }
            | ShapeSpec::Image { path }
            | ShapeSpec::Usd { path, .. } => Some(path),
            ShapeSpec::Box { .. } | ShapeSpec::Sphere { .. } => None,
        }
    }

    /// The spec with its file's path relative to `base` (an absolute path, and a primitive,
    /// unchanged): a scene's shapes are relative to the scene file.
    pub fn resolved(&self, base: &Path) -> ShapeSpec {
        match self {
            ShapeSpec::File { path, format } => ShapeSpec::File {
                path: base.join(path),
                format: *format,
            },
            ShapeSpec::Image { path } => ShapeSpec::Image {
                path: base.join(path),
            },
            ShapeSpec::Usd { path, prim, time } => ShapeSpec::Usd {
                path: base.join(path),
                prim: prim.clone(),
                time: *time,
            },
            primitive => primitive.clone(),
        }
    }

    /// The shape of a primitive spec; `None` for a file (read it with
    /// [`crate::io::read_shape_spec`]).
    pub fn primitive(&self) -> Option<Shape> {
        match *self {
            ShapeSpec::Box { size } => Some(Shape::Box { size }),
            ShapeSpec::Sphere { radius } => Some(Shape::Sphere { radius }),
            ShapeSpec::File { .. } | ShapeSpec::Image { .. } | ShapeSpec::Usd { .. } => None,
        }
    }
}

/// The USD file extensions, lower case, longest first (`.usd` is a prefix of the others).
const USD_EXTENSIONS: [&str; 4] = [".usda", ".usdc", ".usdz", ".usd"];

/// `FILE.usd[a|c|z]`, `FILE.usd[a|c|z]:/Prim/Path` or `FILE.usd[a|c|z]:/Prim/Path@TIME` as a
/// [`ShapeSpec::Usd`]; None when the spec names no USD file.
fn parse_usd(spec: &str, trimmed: &str) -> Result<Option<ShapeSpec>, GeometryError> {
    let lower = trimmed.to_ascii_lowercase();
    // The first USD extension followed by the end, ':' or '@' ends the file name.
    let found = USD_EXTENSIONS.iter().find_map(|ext| {
        lower.match_indices(ext).find_map(|(i, _)| {
            let end = i + ext.len();
            matches!(lower.as_bytes().get(end), None | Some(b':') | Some(b'@')).then_some(end)
        })
    });
    let Some(end) = found else {
        return Ok(None);
    };
    let path = PathBuf::from(&trimmed[..end]);
    let rest = &trimmed[end..];
    let (prim_part, time_part) = match rest.rfind('@') {
        Some(at) => (&rest[..at], Some(&rest[at + 1..])),
        None => (rest, None),
    };
    let usd_bad = |reason: String| GeometryError::BadPrimitive {
        spec: spec.to_string(),
        reason,
    };
    let prim = match prim_part.strip_prefix(':') {
        None if prim_part.is_empty() => None,
        None => {
            return Err(usd_bad(format!(
                "expected `:` before the prim path, got `{prim_part}`"
            )))
        }
        Some(p) if p.starts_with('/') && p.len() > 1 && !p.ends_with('/') => Some(p.to_string()),
        Some(p) => {
            return Err(usd_bad(format!(
                "`{p}` is not an absolute prim path; write FILE.usda:/World/Prim"
            )))
        }
    };
    let time = match time_part {
        None => None,
        Some(t) => match t.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Some(v),
            _ => {
                return Err(usd_bad(format!(
                    "`{t}` after `@` is not a finite time code; write FILE.usda:/World/Prim@12"
                )))
            }
        },
    };
    Ok(Some(ShapeSpec::Usd { path, prim, time }))
}

fn usage(kind: &str) -> &'static str {
    if kind == "box" {
        "LX,LY,LZ"
    } else {
        "R"
    }
}

fn strip_prefix_ci<'a>(s: &'a str, prefix: &str) -> Option<&'a str> {
    let head = s.get(..prefix.len())?;
    head.eq_ignore_ascii_case(prefix)
        .then(|| &s[prefix.len()..])
}

fn bad(spec: &str, reason: String) -> GeometryError {
    GeometryError::BadPrimitive {
        spec: spec.to_string(),
        reason,
    }
}

/// Smallest primitive size accepted, metres: below it volumes and grid spacings underflow
/// towards f64's limits.
const MIN_SIZE: f64 = 1e-9;
/// Largest primitive size accepted, metres (a million km); beyond it volumes overflow.
const MAX_SIZE: f64 = 1e9;

/// Parse exactly `n` comma-separated positive finite numbers in [`MIN_SIZE`, `MAX_SIZE`].
fn numbers(spec: &str, list: &str, n: usize, form: &str) -> Result<Vec<f64>, GeometryError> {
    if list.trim().is_empty() {
        return Err(bad(spec, format!("no numbers given; expected {form}")));
    }
    let parts: Vec<&str> = list.split(',').map(str::trim).collect();
    if parts.len() != n {
        let what = if parts.len() < n {
            "too few"
        } else {
            "too many"
        };
        return Err(bad(
            spec,
            format!(
                "{what} numbers: expected {n}, got {}; write {form}",
                parts.len()
            ),
        ));
    }
    parts
        .iter()
        .map(|s| {
            if s.is_empty() {
                return Err(bad(spec, format!("empty number; expected {form}")));
            }
            let v: f64 = s
                .parse()
                .map_err(|_| bad(spec, format!("`{s}` is not a number; expected {form}")))?;
            if !v.is_finite() {
                Err(bad(
                    spec,
                    format!("`{s}` is not finite; sizes must be finite"),
                ))
            } else if v <= 0.0 {
                Err(bad(
                    spec,
                    format!("`{s}` is not positive; sizes must be > 0"),
                ))
            } else if !(MIN_SIZE..=MAX_SIZE).contains(&v) {
                Err(bad(
                    spec,
                    format!(
                        "`{s}` is out of range; sizes are metres between {MIN_SIZE:e} and \
                         {MAX_SIZE:e} (rescale the shape)"
                    ),
                ))
            } else {
                Ok(v)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reason(spec: &str) -> String {
        match ShapeSpec::parse(spec) {
            Err(GeometryError::BadPrimitive { reason, .. }) => reason,
            other => panic!("{spec}: expected BadPrimitive, got {other:?}"),
        }
    }

    #[test]
    fn primitives_parse() {
        let parse = ShapeSpec::parse;
        assert!(
            matches!(parse("box:1,2,3.5"), Ok(ShapeSpec::Box { size }) if size == [1.0, 2.0, 3.5])
        );
        assert!(
            matches!(parse(" BOX: 1 , 2 ,3 "), Ok(ShapeSpec::Box { size }) if size == [1.0, 2.0, 3.0])
        );
        assert!(matches!(parse("sphere:0.25"), Ok(ShapeSpec::Sphere { radius }) if radius == 0.25));
        assert!(matches!(parse("Sphere:1e-3"), Ok(ShapeSpec::Sphere { radius }) if radius == 1e-3));
        assert!(matches!(
            parse("box:1,2,3.5").unwrap().primitive(),
            Some(Shape::Box { size }) if size == [1.0, 2.0, 3.5]
        ));
    }

    #[test]
    fn primitive_errors_say_what_is_wrong() {
        assert!(reason("box:1,2").contains("too few numbers: expected 3, got 2"));
        assert!(reason("box:1,2,3,4").contains("too many numbers: expected 3, got 4"));
        assert!(reason("box:").contains("no numbers given"));
        assert!(reason("box:1,,3").contains("empty number"));
        assert!(reason("box:1,-2,3").contains("`-2` is not positive"));
        assert!(reason("box:0,1,1").contains("`0` is not positive"));
        assert!(reason("box:1e300,1,1").contains("`1e300` is out of range"));
        assert!(reason("sphere:1e-300").contains("`1e-300` is out of range"));
        assert!(reason("sphere:nan").contains("`nan` is not finite"));
        assert!(reason("sphere:inf").contains("`inf` is not finite"));
        assert!(reason("sphere:abc").contains("`abc` is not a number"));
        assert!(reason("sphere:1,2").contains("too many numbers: expected 1, got 2"));
        assert!(reason("sphere").contains("missing sizes: write sphere:R"));
        assert!(reason("box").contains("missing sizes: write box:LX,LY,LZ"));
    }

    #[test]
    fn unknown_specs() {
        for spec in ["cube:1", "shape.txt", "noextension", "", "model.obj.bak"] {
            match ShapeSpec::parse(spec) {
                Err(GeometryError::UnknownSpec(s)) => assert_eq!(s, spec),
                other => panic!("{spec}: {other:?}"),
            }
        }
    }

    #[test]
    fn file_specs_name_their_format_without_reading() {
        assert_eq!(
            ShapeSpec::parse(" /no/such/dir/Model.PLY ").unwrap(),
            ShapeSpec::File {
                path: PathBuf::from("/no/such/dir/Model.PLY"),
                format: ShapeFileFormat::Ply,
            }
        );
        let spec = ShapeSpec::parse("a.obj").unwrap();
        assert!(matches!(
            spec,
            ShapeSpec::File {
                format: ShapeFileFormat::Obj,
                ..
            }
        ));
        assert!(spec.primitive().is_none());
    }

    #[test]
    fn usd_specs_name_file_prim_and_time() {
        let usd = |p: &str, prim: Option<&str>, time: Option<f64>| ShapeSpec::Usd {
            path: PathBuf::from(p),
            prim: prim.map(str::to_string),
            time,
        };
        let parse = |s: &str| ShapeSpec::parse(s).unwrap();
        assert_eq!(parse("scene.usda"), usd("scene.usda", None, None));
        assert_eq!(
            parse(" dir/Scene.USDZ:/World/Table "),
            usd("dir/Scene.USDZ", Some("/World/Table"), None)
        );
        assert_eq!(
            parse("a.usd:/World/ball@40"),
            usd("a.usd", Some("/World/ball"), Some(40.0))
        );
        assert_eq!(parse("a.usdc@-2.5"), usd("a.usdc", None, Some(-2.5)));
        // A directory named like a stage is not the file.
        assert_eq!(
            parse("x.usd.d/b.usda:/W"),
            usd("x.usd.d/b.usda", Some("/W"), None)
        );
        assert!(reason("a.usda:World").contains("not an absolute prim path"));
        assert!(reason("a.usda:/World/").contains("not an absolute prim path"));
        assert!(reason("a.usda:/World@x").contains("not a finite time code"));
        assert!(reason("a.usda:/World@inf").contains("not a finite time code"));
    }
}
