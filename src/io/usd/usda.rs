//! The usda text of a [`UsdLayer`], written atomically. Floats are printed in their shortest
//! form that reads back to the same float32 (checked number by number: the usda parser reads
//! a double and rounds it to float, so a number whose double would round elsewhere is printed
//! with all the digits of its double instead), about 9 bytes a number where `openusd`'s
//! writer prints 17 digits; the time samples of large arrays are formatted on every thread
//! (docs/usd.md, "What it costs").

use super::layer::{Attribute, Prim, UsdLayer, UsdValue, WORLD};
use crate::Result;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// Push a non-finite number as usda spells it (`nan`, `inf`, `-inf`); false if `x` is finite.
fn push_special(s: &mut String, x: f64) -> bool {
    let word = match x {
        x if x.is_nan() => "nan",
        f64::INFINITY => "inf",
        f64::NEG_INFINITY => "-inf",
        _ => return false,
    };
    s.push_str(word);
    true
}

/// Whether a magnitude prints shorter with an exponent (usda reads both).
fn exponent_form(a: f64) -> bool {
    a != 0.0 && !(1e-4..1e16).contains(&a)
}

/// Push `x` (a float32) so that parsing it as a double and rounding to float gives `x`.
fn push_f32(s: &mut String, x: f32) {
    if push_special(s, f64::from(x)) {
        return;
    }
    let start = s.len();
    if exponent_form(f64::from(x.abs())) {
        let _ = write!(s, "{x:e}");
    } else {
        let _ = write!(s, "{x}");
    }
    let back = s[start..].parse::<f64>().map(|d| d as f32);
    if back.map(f32::to_bits) != Ok(x.to_bits()) {
        s.truncate(start);
        // The double of a float prints exactly in its shortest double form.
        push_f64(s, f64::from(x));
    }
}

/// Push a double in its shortest form that reads back exactly.
fn push_f64(s: &mut String, x: f64) {
    if push_special(s, x) {
        return;
    }
    if exponent_form(x.abs()) {
        let _ = write!(s, "{x:e}");
    } else {
        let _ = write!(s, "{x}");
    }
}

fn push_tuple(s: &mut String, v: &[f32]) {
    s.push('(');
    for (i, &x) in v.iter().enumerate() {
        if i > 0 {
            s.push_str(", ");
        }
        push_f32(s, x);
    }
    s.push(')');
}

/// A string literal with `"` and `\` escaped.
fn push_quoted(s: &mut String, text: &str) {
    s.push('"');
    for c in text.chars() {
        match c {
            '"' => s.push_str("\\\""),
            '\\' => s.push_str("\\\\"),
            '\n' => s.push_str("\\n"),
            '\r' => s.push_str("\\r"),
            '\t' => s.push_str("\\t"),
            c if c.is_control() => {
                let _ = write!(s, "\\x{:02x}", u32::from(c) & 0xff);
            }
            c => s.push(c),
        }
    }
    s.push('"');
}

/// The usda text of one value.
fn push_value(s: &mut String, v: &UsdValue) {
    fn list<T>(s: &mut String, items: &[T], mut each: impl FnMut(&mut String, &T)) {
        s.push('[');
        for (i, x) in items.iter().enumerate() {
            if i > 0 {
                s.push_str(", ");
            }
            each(s, x);
        }
        s.push(']');
    }
    match v {
        UsdValue::Int(i) => {
            let _ = write!(s, "{i}");
        }
        UsdValue::Float(x) => push_f32(s, *x),
        UsdValue::Double(x) => push_f64(s, *x),
        UsdValue::Token(t) => push_quoted(s, t),
        UsdValue::Tokens(t) => list(s, t, |s, t| push_quoted(s, t)),
        UsdValue::Ints(v) => list(s, v, |s, i| {
            let _ = write!(s, "{i}");
        }),
        UsdValue::Floats(v) => list(s, v, |s, &x| push_f32(s, x)),
        UsdValue::Float3s(v) => list(s, v, |s, p| push_tuple(s, p)),
        // usda writes quaternions real part first, as they are held.
        UsdValue::Quats(v) => list(s, v, |s, q| push_tuple(s, q)),
        UsdValue::Matrix4(m) => {
            s.push('(');
            for r in 0..4 {
                if r > 0 {
                    s.push_str(", ");
                }
                s.push('(');
                for c in 0..4 {
                    if c > 0 {
                        s.push_str(", ");
                    }
                    push_f64(s, m[4 * r + c]);
                }
                s.push(')');
            }
            s.push(')');
        }
    }
}

struct Emitter<W: Write> {
    out: W,
    /// Samples formatted at once (a bound on the text held in memory).
    batch: usize,
}

impl<W: Write> Emitter<W> {
    fn indent(depth: usize) -> String {
        "    ".repeat(depth)
    }

    fn attribute(&mut self, a: &Attribute, depth: usize) -> std::io::Result<()> {
        let pad = Self::indent(depth);
        let decl = format!(
            "{pad}{}{} {}",
            if a.uniform { "uniform " } else { "" },
            a.type_name,
            a.name
        );
        let mut head = decl.clone();
        let mut meta = Vec::new();
        if let Some(n) = a.element_size {
            meta.push(format!("elementSize = {n}"));
        }
        if let Some(i) = a.interpolation {
            meta.push(format!("interpolation = \"{i}\""));
        }
        if let Some(v) = &a.default {
            head.push_str(" = ");
            push_value(&mut head, v);
        }
        if !meta.is_empty() {
            head.push_str(" (\n");
            for m in &meta {
                let _ = writeln!(head, "{pad}    {m}");
            }
            head.push_str(&pad);
            head.push(')');
        }
        if a.default.is_some() || !meta.is_empty() || a.samples.is_empty() {
            head.push('\n');
            self.out.write_all(head.as_bytes())?;
        }
        if a.samples.is_empty() {
            return Ok(());
        }
        self.out
            .write_all(format!("{decl}.timeSamples = {{\n").as_bytes())?;
        for chunk in a.samples.chunks(self.batch) {
            let texts: Vec<String> = chunk
                .par_iter()
                .map(|(t, v)| {
                    let mut s = String::with_capacity(16 * v.len() + 32);
                    s.push_str(&pad);
                    s.push_str("    ");
                    push_f64(&mut s, *t);
                    s.push_str(": ");
                    push_value(&mut s, v);
                    s.push_str(",\n");
                    s
                })
                .collect();
            for t in texts {
                self.out.write_all(t.as_bytes())?;
            }
        }
        self.out.write_all(format!("{pad}}}\n").as_bytes())
    }

    fn prim(&mut self, layer: &UsdLayer, p: &Prim, depth: usize) -> std::io::Result<()> {
        let pad = Self::indent(depth);
        let name = p.path.rsplit('/').next().unwrap_or_default();
        let mut head = format!("{pad}def {} \"{name}\"", p.type_name);
        if !p.api_schemas.is_empty() {
            let mut list = String::new();
            push_value(&mut list, &UsdValue::Tokens(p.api_schemas.clone()));
            let _ = write!(head, " (\n{pad}    prepend apiSchemas = {list}\n{pad})");
        }
        let _ = write!(head, "\n{pad}{{\n");
        self.out.write_all(head.as_bytes())?;
        for a in &p.attributes {
            self.attribute(a, depth + 1)?;
        }
        for (i, child) in p.children.iter().enumerate() {
            if i > 0 || !p.attributes.is_empty() {
                self.out.write_all(b"\n")?;
            }
            if let Some(c) = layer.prim_at(&format!("{}/{child}", p.path)) {
                self.prim(layer, c, depth + 1)?;
            }
        }
        self.out.write_all(format!("{pad}}}\n").as_bytes())
    }

    fn layer(&mut self, layer: &UsdLayer) -> std::io::Result<()> {
        let m = &layer.metadata;
        let mut s = String::from("#usda 1.0\n(\n    defaultPrim = \"World\"\n");
        if !m.documentation.is_empty() {
            s.push_str("    doc = ");
            push_quoted(&mut s, &m.documentation);
            s.push('\n');
        }
        s.push_str("    metersPerUnit = ");
        push_f64(&mut s, m.meters_per_unit);
        let _ = write!(s, "\n    upAxis = \"{}\"\n", m.up_axis.token());
        if let Some(t) = m.time_codes_per_second {
            for key in ["timeCodesPerSecond", "framesPerSecond"] {
                let _ = write!(s, "    {key} = ");
                push_f64(&mut s, t);
                s.push('\n');
            }
        }
        if let Some((a, b)) = m.time_range {
            s.push_str("    startTimeCode = ");
            push_f64(&mut s, a);
            s.push_str("\n    endTimeCode = ");
            push_f64(&mut s, b);
            s.push('\n');
        }
        s.push_str(")\n\n");
        self.out.write_all(s.as_bytes())?;
        if let Some(world) = layer.prim_at(WORLD) {
            self.prim(layer, world, 0)?;
        }
        Ok(())
    }
}

/// Write `layer` as usda to `path`, atomically (a failed write leaves no file).
///
/// # Errors
/// [`crate::Error::Io`] when the file cannot be written.
pub fn write_usda(layer: &UsdLayer, path: &Path) -> Result<()> {
    super::super::write_atomically(path, |tmp| {
        let io = |source| crate::Error::Io {
            path: tmp.to_path_buf(),
            source,
        };
        let file = std::fs::File::create(tmp).map_err(io)?;
        let mut e = Emitter {
            out: std::io::BufWriter::with_capacity(1 << 20, file),
            batch: 4 * rayon::current_num_threads(),
        };
        e.layer(layer).map_err(io)?;
        e.out.flush().map_err(io)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every float pattern of a wide sample reads back through a double exactly.
    #[test]
    fn floats_read_back_to_the_same_bits_through_a_double() {
        let mut rng = crate::random::SplitMix64::new(11);
        let mut s = String::new();
        for k in 0..200_000u32 {
            let bits = if k < 1000 {
                // Near 1, powers of two and subnormals: where short forms are likeliest.
                [0x3f80_0000 + k, 0x0000_0001 + k, 0x7f7f_ffff - k][k as usize % 3]
            } else {
                (rng.next_u64() >> 32) as u32 & 0x7fff_ffff
            };
            let x = f32::from_bits(bits);
            if !x.is_finite() {
                continue;
            }
            s.clear();
            push_f32(&mut s, x);
            let back = s.parse::<f64>().unwrap() as f32;
            assert_eq!(back.to_bits(), x.to_bits(), "{x:e} printed as {s}");
        }
        for (x, text) in [
            (0.1, "0.1"),
            (1e-7, "1e-7"),
            (-2.5e20, "-2.5e20"),
            (0.0, "0"),
            (f32::NAN, "nan"),
            (f32::NEG_INFINITY, "-inf"),
        ] {
            s.clear();
            push_f32(&mut s, x);
            assert_eq!(s, text);
        }
        s.clear();
        push_quoted(&mut s, "a\"b\\c\r\u{1}");
        assert_eq!(s, r#""a\"b\\c\r\x01""#);
    }
}
