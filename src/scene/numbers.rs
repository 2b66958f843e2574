//! One check of every number a scene holds, whatever table it sits in: finite, and either 0
//! or within magnitudes that the simulator's products of inputs can represent. Field checks
//! (a positive modulus, a proper rotation) come after it, field by field; this one cannot
//! miss a field, because it walks the scene as serialized.

use crate::{Error, Result};
use toml::Value;

/// Fields where an infinite value means something: the bounds of a box region (a half-open
/// slab, docs/scenes.md).
fn infinity_allowed(path: &str) -> bool {
    let bare: String = path
        .split('[')
        .map(|part| part.split_once(']').map_or(part, |(_, rest)| rest))
        .collect();
    bare.ends_with("region.box.min") || bare.ends_with("region.box.max")
}

/// Check every float of `scene` (a scene serialized to TOML values): not NaN; infinite only
/// where [`infinity_allowed`]; otherwise 0 or of magnitude within
/// [`crate::error::MIN_MAGNITUDE`]..=[`crate::error::MAX_MAGNITUDE`] ([`crate::error::in_range`]).
///
/// # Errors
/// [`Error::Scene`] naming the first offending number by its path in the scene
/// (`object[0].boundary[1].motion.rotate.pivot[2]`) and its value.
pub fn check(scene: &Value) -> Result<()> {
    let mut path = String::new();
    walk(scene, &mut path)
}

fn walk(v: &Value, path: &mut String) -> Result<()> {
    match v {
        Value::Table(t) => {
            for (key, x) in t {
                let len = path.len();
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(key);
                walk(x, path)?;
                path.truncate(len);
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                let len = path.len();
                path.push_str(&format!("[{i}]"));
                walk(x, path)?;
                path.truncate(len);
            }
        }
        Value::Float(x) => check_float(*x, path)?,
        _ => {}
    }
    Ok(())
}

fn check_float(x: f64, path: &str) -> Result<()> {
    let why = if x.is_nan() {
        "is not a number"
    } else if x.is_infinite() {
        if infinity_allowed(path) {
            return Ok(());
        }
        "must be finite (only a box region's bounds may be infinite)"
    } else if !crate::error::in_range(x) {
        "is out of range: a scene's numbers are 0 or between 1e-100 and 1e100 in magnitude \
         (a typo or a unit mistake?)"
    } else {
        return Ok(());
    };
    Err(Error::Scene {
        message: format!("{path} = {} {why}", crate::error::readable_number(x)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(text: &str) -> Value {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn every_float_is_checked_by_its_path() {
        check(&scene(
            "a = 1.0\nb = [0.0, -2.5e-7]\n[c]\nd = [[1e100, -1e-100]]",
        ))
        .unwrap();
        for (text, path) in [
            ("a = nan", "a = NaN"),
            ("[c]\nd = [[1.0, inf]]", "c.d[0][1] = inf"),
            ("[[o]]\nx = 1.0\n[[o]]\nx = 1e300", "o[1].x = 1e300"),
            ("[[o]]\nx = -1e-300", "o[0].x = -1e-300"),
        ] {
            let e = check(&scene(text)).unwrap_err().to_string();
            assert!(e.contains(path), "{text}: {e}");
        }
    }

    #[test]
    fn only_box_region_bounds_may_be_infinite() {
        check(&scene(
            "[[r]]\nregion = { box = { min = [-inf, 0.0, 0.0], max = [inf, 1.0, 1.0] } }",
        ))
        .unwrap();
        let e = check(&scene("region = { sphere = { radius = inf } }")).unwrap_err();
        assert!(e.to_string().contains("region.sphere.radius = inf"), "{e}");
    }
}
