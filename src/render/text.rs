//! Text in the embedded DejaVu Sans (assets/fonts), drawn by plotters' bitmap backend with
//! ab_glyph: no system fonts needed.

use super::image::Image;
use crate::{Error, Result};
use plotters::prelude::*;

/// The font family name the embedded font is registered under with plotters.
pub const FONT_FAMILY: &str = "sans-serif";
/// DejaVu Sans (Bitstream Vera license, assets/fonts/DejaVuSans.LICENSE).
static FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Register the embedded font with plotters as [`FONT_FAMILY`] (once per process).
pub fn register_font() -> Result<&'static str> {
    static ONCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *ONCE.get_or_init(|| {
        plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, FONT_BYTES).is_ok()
    });
    if ok {
        Ok(FONT_FAMILY)
    } else {
        Err(Error::param(
            "font",
            "DejaVuSans.ttf",
            "the embedded font could not be loaded".to_string(),
        ))
    }
}

/// Draw `text` with its top-left corner at column `x`, row `y`, `size` pixels high, in
/// `colour`; clipped to the image.
pub fn draw_text(
    image: &mut Image,
    x: i32,
    y: i32,
    size: f64,
    colour: [u8; 3],
    text: &str,
) -> Result<()> {
    register_font()?;
    let (w, h) = (image.width, image.height);
    let root = BitMapBackend::with_buffer(&mut image.rgb, (w, h)).into_drawing_area();
    let rgb = RGBColor(colour[0], colour[1], colour[2]);
    let style = TextStyle::from((FONT_FAMILY, size).into_font()).color(&rgb);
    let err = |e: String| Error::param("text", text, e);
    root.draw_text(text, &style, (x, y))
        .map_err(|e| err(e.to_string()))?;
    root.present().map_err(|e| err(e.to_string()))
}
