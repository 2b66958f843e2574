//! Offscreen software rendering to an RGB image: pictures of meshes and point sets without
//! ParaView (`freeform render`, `freeform modes --png`, docs/pictures.md).
//!
//! One job: rasterize. A [`Camera`] fitted to bounds ([`CameraOptions`]: direction, up, field
//! of view or orthographic, zoom), a z-buffered triangle rasterizer with Lambert + ambient
//! shading ([`draw`]), points as shaded discs with depth, 3D Gaussians as projected ellipses
//! alpha-blended back to front ([`Gaussians`], EWA splatting), scalars through a [`ColorMap`]
//! with a colour bar ([`draw_colorbar`]), text in the embedded DejaVu Sans
//! ([`draw_text`]) and atomic PNG output ([`Image::write_png`]). One picture is drawn
//! sequentially and deterministically: the same input gives the same pixels (`freeform
//! render` draws several frames at once, each on its own thread).

mod camera;
mod colormap;
mod image;
mod raster;
mod splat;
mod target;
mod text;

pub use camera::{Camera, CameraOptions, Projection};
pub use colormap::{draw_colorbar, ColorMap};
pub use image::{write_png_rgb, Image, Rect};
pub use raster::{disc_radius_from_spacing, draw, DrawOptions, Ground, Item};
pub use splat::{sigmoid, Gaussians, SH_C0};
pub use target::Scalars;
pub use text::{draw_text, register_font, FONT_FAMILY};
