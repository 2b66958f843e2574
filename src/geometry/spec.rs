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
            ShapeSpec::File { path, .. } | ShapeSpec::Image { path } => Some(path),
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
            primitive => primitive.clone(),
        }
    }

    /// The shape of a primitive spec; `None` for a file (read it with
    /// [`crate::io::read_shape_spec`]).
    pub fn primitive(&self) -> Option<Shape> {
        match *self {
            ShapeSpec::Box { size } => Some(Shape::Box { size }),
            ShapeSpec::Sphere { radius } => Some(Shape::Sphere { radius }),
            ShapeSpec::File { .. } | ShapeSpec::Image { .. } => None,
        }
    }
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
}
