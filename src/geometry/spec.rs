//! Parsing of shape specs: `box:LX,LY,LZ`, `sphere:R`, or a file path.

use super::{GeometryError, Shape, ShapeOptions};
use std::path::Path;

pub(super) fn parse(spec: &str, opts: &ShapeOptions) -> Result<Shape, GeometryError> {
    let trimmed = spec.trim();
    let lower = trimmed.to_ascii_lowercase();
    if let Some(rest) = strip_prefix_ci(trimmed, "box:") {
        let v = numbers(spec, rest, 3, "box:LX,LY,LZ (three edge lengths, metres)")?;
        return Ok(Shape::Box {
            size: [v[0], v[1], v[2]],
        });
    }
    if let Some(rest) = strip_prefix_ci(trimmed, "sphere:") {
        let v = numbers(spec, rest, 1, "sphere:R (radius, metres)")?;
        return Ok(Shape::Sphere { radius: v[0] });
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
    match ext.as_deref() {
        Some("obj") => Ok(Shape::Mesh(crate::io::obj::read_obj(path, opts)?)),
        Some("stl") => Ok(Shape::Mesh(crate::io::stl::read_stl(path, opts)?)),
        Some("ply") => crate::io::ply::read_ply(path, opts),
        _ => Err(GeometryError::UnknownSpec(spec.to_string())),
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
        match parse(spec, &ShapeOptions::default()) {
            Err(GeometryError::BadPrimitive { reason, .. }) => reason,
            other => panic!("{spec}: expected BadPrimitive, got {other:?}"),
        }
    }

    #[test]
    fn primitives_parse() {
        let o = ShapeOptions::default();
        assert!(
            matches!(parse("box:1,2,3.5", &o), Ok(Shape::Box { size }) if size == [1.0, 2.0, 3.5])
        );
        assert!(
            matches!(parse(" BOX: 1 , 2 ,3 ", &o), Ok(Shape::Box { size }) if size == [1.0, 2.0, 3.0])
        );
        assert!(matches!(parse("sphere:0.25", &o), Ok(Shape::Sphere { radius }) if radius == 0.25));
        assert!(matches!(parse("Sphere:1e-3", &o), Ok(Shape::Sphere { radius }) if radius == 1e-3));
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
            match parse(spec, &ShapeOptions::default()) {
                Err(GeometryError::UnknownSpec(s)) => assert_eq!(s, spec),
                other => panic!("{spec}: {other:?}"),
            }
        }
    }
}
