//! The RGB image and its atomic PNG output.

use crate::{Error, Result};
use std::path::Path;

/// An 8-bit RGB image, rows top to bottom, `rgb.len() == 3 * width * height`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Pixels, row-major from the top-left, 3 bytes each.
    pub rgb: Vec<u8>,
}

/// A rectangle of pixels: left, top, width, height.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
}

impl Image {
    /// A `width x height` image filled with `colour`.
    pub fn new(width: u32, height: u32, colour: [u8; 3]) -> Image {
        let n = width as usize * height as usize;
        Image {
            width,
            height,
            rgb: colour.iter().copied().cycle().take(3 * n).collect(),
        }
    }

    /// The whole image as a rectangle.
    pub fn rect(&self) -> Rect {
        Rect {
            x: 0,
            y: 0,
            width: self.width,
            height: self.height,
        }
    }

    /// The colour at column `x`, row `y` (panics outside the image).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Set the colour at column `x`, row `y` (ignored outside the image).
    pub fn set(&mut self, x: u32, y: u32, colour: [u8; 3]) {
        if x < self.width && y < self.height {
            let i = 3 * (y as usize * self.width as usize + x as usize);
            self.rgb[i..i + 3].copy_from_slice(&colour);
        }
    }

    /// Fill `rect` (clipped to the image) with `colour`.
    pub fn fill_rect(&mut self, rect: Rect, colour: [u8; 3]) {
        for y in rect.y..(rect.y + rect.height).min(self.height) {
            for x in rect.x..(rect.x + rect.width).min(self.width) {
                self.set(x, y, colour);
            }
        }
    }

    /// Write the image as an 8-bit RGB PNG to `path`, atomically.
    pub fn write_png(&self, path: &Path) -> Result<()> {
        write_png_rgb(path, self.width, self.height, &self.rgb)
    }
}

/// Write `rgb` (`3 * width * height` bytes, rows from the top) as an 8-bit RGB PNG to
/// `path`, atomically (a temporary file renamed into place).
pub fn write_png_rgb(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    if rgb.len() != 3 * width as usize * height as usize {
        return Err(Error::LengthMismatch {
            what: "RGB image bytes",
            expected: 3 * width as usize * height as usize,
            got: rgb.len(),
        });
    }
    crate::io::write_atomically(path, |tmp| {
        let io = |e: std::io::Error| Error::Io {
            path: tmp.to_path_buf(),
            source: e,
        };
        let png_err = |e: png::EncodingError| io(std::io::Error::other(e.to_string()));
        let file = std::io::BufWriter::new(std::fs::File::create(tmp).map_err(io)?);
        let mut enc = png::Encoder::new(file, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        // Balanced: High made the files no smaller (the 51 frames of examples/drop.toml:
        // 4.52 MB either way; they go into the repository and the docs) at over twice the
        // render time (docs/pictures.md, "Cost").
        enc.set_compression(png::Compression::Balanced);
        let mut w = enc.write_header().map_err(png_err)?;
        w.write_image_data(rgb).map_err(png_err)?;
        w.finish().map_err(png_err)
    })
}
