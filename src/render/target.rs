//! What every drawn item writes into: the viewport's depth buffer with its shading state
//! ([`Target`]) and how scalars become colours ([`Scalars`]). The rasterizer and the splat
//! compositor both draw into a `Target`; neither needs the other for it.

use super::camera::Camera;
use super::colormap::ColorMap;
use super::image::{Image, Rect};
use crate::linalg3::{dot, normalize};

/// How scalars become colours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scalars {
    /// The colour map.
    pub map: ColorMap,
    /// The values at the map's ends, [min, max].
    pub range: [f64; 2],
}

/// `a` scaled to unit length, or `a` itself when it is zero (a degenerate normal shades as
/// ambient only).
pub(super) fn unit(a: [f64; 3]) -> [f64; 3] {
    normalize(a).unwrap_or(a)
}

/// The viewport's depth buffer and the shading state shared by all items.
pub(super) struct Target<'a> {
    pub(super) image: &'a mut Image,
    pub(super) view: Rect,
    pub(super) camera: &'a Camera,
    /// Nearness per viewport pixel: 1 / depth (perspective) or -depth (orthographic), both
    /// affine in screen space; larger is nearer.
    pub(super) near: Vec<f64>,
    /// The light direction in world space, unit length.
    pub(super) light: [f64; 3],
    /// The ambient share of the brightness, 0..1.
    pub(super) ambient: f64,
}

impl Target<'_> {
    /// The nearness of `depth` (larger is nearer), as stored in `near`.
    pub(super) fn key(&self, depth: f64) -> f64 {
        if self.camera.is_perspective() {
            1.0 / depth
        } else {
            -depth
        }
    }

    /// Lambert + ambient of `colour` for a world normal (turned towards the viewer).
    pub(super) fn shade(&self, colour: [u8; 3], normal: [f64; 3]) -> [u8; 3] {
        let f = self.lambert(normal).clamp(0.0, 1.0);
        // c f lies in [0, 255]: adding 1/2 and truncating is `round` (half away from zero)
        // without its call, which was a tenth of the render time.
        colour.map(|c| (c as f64 * f + 0.5) as u8)
    }

    /// The brightness factor (ambient + Lambert, 0..1) of a world normal, either side lit.
    pub(super) fn lambert(&self, normal: [f64; 3]) -> f64 {
        let mut n = unit(normal);
        if dot(&n, &self.camera.forward) > 0.0 {
            n = [-n[0], -n[1], -n[2]];
        }
        let lambert = dot(&n, &self.light).max(0.0);
        self.ambient + (1.0 - self.ambient) * lambert
    }

    /// Whether something at nearness `key` could still show at viewport pixel (x, y): a
    /// cheap test before a pixel's exact depth is computed.
    pub(super) fn may_show(&self, x: u32, y: u32, key: f64) -> bool {
        key > self.near[y as usize * self.view.width as usize + x as usize]
    }

    /// Write `colour` at viewport pixel (x, y) if `key` is nearer than what is there.
    pub(super) fn plot(&mut self, x: u32, y: u32, key: f64, colour: impl FnOnce(&Self) -> [u8; 3]) {
        let i = y as usize * self.view.width as usize + x as usize;
        if key > self.near[i] {
            self.near[i] = key;
            let c = colour(self);
            self.image.set(self.view.x + x, self.view.y + y, c);
        }
    }
}
