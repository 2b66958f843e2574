//! Scalar colour maps and the colour bar.

use super::image::{Image, Rect};
use super::text::draw_text;
use crate::Result;

/// A map from a scalar in a range to a colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColorMap {
    /// Perceptually uniform, dark purple (min) to yellow (max): matplotlib's viridis, by
    /// linear interpolation between 11 of its samples. For magnitudes (|displacement|).
    Viridis,
    /// Blue (min) through light grey (mid) to red (max), Moreland's cool-warm: for signed
    /// values with the range symmetric about 0 (a mode's weight).
    CoolWarm,
}

const VIRIDIS: [[u8; 3]; 11] = [
    [68, 1, 84],
    [72, 36, 117],
    [65, 68, 135],
    [53, 95, 141],
    [42, 120, 142],
    [33, 145, 140],
    [34, 168, 132],
    [68, 191, 112],
    [122, 209, 81],
    [189, 223, 38],
    [253, 231, 37],
];

const COOLWARM: [[u8; 3]; 5] = [
    [59, 76, 192],
    [141, 176, 254],
    [221, 221, 221],
    [244, 154, 123],
    [180, 4, 38],
];

/// Colour of values that are not finite.
pub(crate) const NAN_COLOUR: [u8; 3] = [128, 128, 128];

impl ColorMap {
    fn table(self) -> &'static [[u8; 3]] {
        match self {
            ColorMap::Viridis => &VIRIDIS,
            ColorMap::CoolWarm => &COOLWARM,
        }
    }

    /// The colour at `t` in [0, 1] (clamped; NaN gives grey).
    pub fn at(self, t: f64) -> [u8; 3] {
        if t.is_nan() {
            return NAN_COLOUR;
        }
        let table = self.table();
        let s = t.clamp(0.0, 1.0) * (table.len() - 1) as f64;
        let i = (s.floor() as usize).min(table.len() - 2);
        let f = s - i as f64;
        let (a, b) = (table[i], table[i + 1]);
        [0, 1, 2].map(|k| (a[k] as f64 + f * (b[k] as f64 - a[k] as f64)).round() as u8)
    }

    /// The colour of `value` in `range` = [min, max] (min at 0, max at 1; a zero-width range
    /// maps everything to the middle).
    pub fn map(self, value: f64, range: [f64; 2]) -> [u8; 3] {
        let w = range[1] - range[0];
        let t = if w > 0.0 && w.is_finite() {
            (value - range[0]) / w
        } else if value.is_finite() {
            0.5
        } else {
            f64::NAN
        };
        self.at(t)
    }
}

/// Draw a vertical colour bar for `map` over `range` in `rect` (max at the top), with the two
/// end values to its right and `label` above it (text in the embedded font, black).
pub fn draw_colorbar(
    image: &mut Image,
    rect: Rect,
    map: ColorMap,
    range: [f64; 2],
    label: &str,
) -> Result<()> {
    let bar_w = (rect.width / 4).clamp(6, 24);
    let top = rect.y + 22;
    let h = rect.height.saturating_sub(30).max(2);
    for row in 0..h {
        let t = 1.0 - row as f64 / (h - 1) as f64;
        let c = map.at(t);
        for col in 0..bar_w {
            image.set(rect.x + col, top + row, c);
        }
    }
    let black = [0, 0, 0];
    for col in 0..bar_w {
        image.set(rect.x + col, top, black);
        image.set(rect.x + col, top + h - 1, black);
    }
    for row in 0..h {
        image.set(rect.x, top + row, black);
        image.set(rect.x + bar_w - 1, top + row, black);
    }
    let x = (rect.x + bar_w + 4) as i32;
    draw_text(image, rect.x as i32, rect.y as i32, 13.0, black, label)?;
    draw_text(image, x, top as i32, 13.0, black, &number(range[1]))?;
    draw_text(
        image,
        x,
        (top + h) as i32 - 14,
        13.0,
        black,
        &number(range[0]),
    )?;
    Ok(())
}

/// A colour-bar number: 3 significant digits, exponent form outside [1e-2, 1e4).
fn number(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-2..1e4).contains(&v.abs()) {
        let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{v:.2e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_of_the_maps_are_their_table_ends() {
        assert_eq!(ColorMap::Viridis.map(-3.0, [-3.0, 5.0]), VIRIDIS[0]);
        assert_eq!(ColorMap::Viridis.map(5.0, [-3.0, 5.0]), VIRIDIS[10]);
        assert_eq!(ColorMap::Viridis.map(9.0, [-3.0, 5.0]), VIRIDIS[10]);
        assert_eq!(ColorMap::CoolWarm.map(-1.0, [-1.0, 1.0]), COOLWARM[0]);
        assert_eq!(ColorMap::CoolWarm.map(0.0, [-1.0, 1.0]), COOLWARM[2]);
        assert_eq!(ColorMap::CoolWarm.map(1.0, [-1.0, 1.0]), COOLWARM[4]);
        assert_eq!(ColorMap::Viridis.map(f64::NAN, [0.0, 1.0]), NAN_COLOUR);
        assert_eq!(ColorMap::Viridis.map(2.0, [2.0, 2.0]), VIRIDIS[5]);
        assert_eq!(number(0.012345), "0.0123");
        assert_eq!(number(123.4), "123");
        assert_eq!(number(-2.5e-5), "-2.50e-5");
    }
}
