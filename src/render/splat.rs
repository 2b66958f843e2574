//! 3D Gaussians (splats) drawn as projected ellipses (EWA splatting, as the 3DGS rasterizer
//! does): each covariance goes to the screen through the camera's Jacobian at its centre,
//! Sigma_2D = J Sigma J^T + a low-pass (0.3 px^2), every pixel within 3 sigma gets
//! alpha = min(0.99, opacity exp(-d^T Sigma_2D^-1 d / 2)), and the splats are alpha-blended
//! back to front by the view depth of their centres over what is drawn already (the
//! background, the ground, meshes and discs, which hide the splats behind them).

use super::camera::Camera;
use super::target::{Scalars, Target};
pub use crate::io::splat::sigmoid;
use crate::io::splat::Splats;
use crate::linalg3::{quat_to_matrix, sym_eig3, Mat3};
use crate::Point3;

/// The degree-0 SH basis constant of 3DGS: colour = 0.5 + SH_C0 f_dc.
pub const SH_C0: f64 = 0.282_094_791_773_878_14;

/// Alpha never exceeds this (3DGS: a splat never hides all that is behind it).
const MAX_ALPHA: f64 = 0.99;
/// Fragments below this alpha are skipped (3DGS: 1 / 255).
const MIN_ALPHA: f64 = 1.0 / 255.0;
/// The footprint's extent, in standard deviations of the screen Gaussian.
const CUTOFF_SIGMAS: f64 = 3.0;

/// A set of 3D Gaussians to draw ([`super::Item::Splats`]): N entries each.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Gaussians {
    /// Centres, N x 3, metres.
    pub means: Vec<Point3>,
    /// Covariances, N symmetric positive (semi-)definite 3 x 3, m^2.
    pub covariances: Vec<Mat3>,
    /// Colours, N x (red, green, blue) in 0..1.
    pub colours: Vec<[f64; 3]>,
    /// Opacities, N, 0..1 (after the sigmoid).
    pub opacities: Vec<f64>,
}

impl Gaussians {
    /// The Gaussians of 3DGS splats: Sigma = R diag(exp(2 s)) R^T, colour 0.5 + SH_C0 f_dc
    /// clamped to 0..1 (the view-independent part; higher SH degrees are not evaluated),
    /// opacity sigmoid(opacity).
    pub fn from_splats(s: &Splats) -> Gaussians {
        let covariances = s
            .log_scales
            .iter()
            .zip(&s.rotations)
            .map(|(ls, q)| {
                let r = quat_to_matrix(q);
                let var = ls.map(|v| (2.0 * v).exp());
                let mut c = [[0.0; 3]; 3];
                for (i, row) in c.iter_mut().enumerate() {
                    for (j, cij) in row.iter_mut().enumerate() {
                        *cij = (0..3).map(|k| r[i][k] * var[k] * r[j][k]).sum();
                    }
                }
                c
            })
            .collect();
        Gaussians {
            means: s.means.clone(),
            covariances,
            colours: s
                .sh_dc
                .iter()
                .map(|dc| dc.map(|c| (0.5 + SH_C0 * c).clamp(0.0, 1.0)))
                .collect(),
            opacities: s.opacities.iter().map(|&o| sigmoid(o)).collect(),
        }
    }

    /// Number of Gaussians N.
    pub fn len(&self) -> usize {
        self.means.len()
    }

    /// True without Gaussians.
    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// The length all fields share, or the first mismatch as (field, its length).
    pub(super) fn check(&self) -> std::result::Result<usize, (&'static str, usize)> {
        let n = self.means.len();
        for (what, len) in [
            ("splat covariances", self.covariances.len()),
            ("splat colours", self.colours.len()),
            ("splat opacities", self.opacities.len()),
        ] {
            if len != n {
                return Err((what, len));
            }
        }
        Ok(n)
    }
}

/// One splat on the screen.
struct Footprint {
    depth: f64,
    centre: [f64; 2],
    /// The inverse of Sigma_2D: (a, b, c) of [[a, b], [b, c]], 1 / px^2.
    conic: [f64; 3],
    /// Pixel range [x0, x1) x [y0, y1) of the 3-sigma box, clipped to the viewport.
    bbox: [u32; 4],
    colour: [f64; 3],
    opacity: f64,
}

/// The screen covariance J Sigma J^T (2 x 2 as (a, b, c)) plus `low_pass` on the diagonal.
fn screen_covariance(j: &[[f64; 3]; 2], sigma: &Mat3, low_pass: f64) -> [f64; 3] {
    let js = |r: usize| [0, 1, 2].map(|k| (0..3).map(|l| j[r][l] * sigma[l][k]).sum::<f64>());
    let (j0s, j1s) = (js(0), js(1));
    let d = |a: [f64; 3], r: usize| (0..3).map(|k| a[k] * j[r][k]).sum::<f64>();
    [d(j0s, 0) + low_pass, d(j0s, 1), d(j1s, 1) + low_pass]
}

/// Lambert + ambient factor for a Gaussian coloured by a scalar: lit by its shortest axis
/// (the normal of a flat splat), blended towards a viewer-facing normal as it gets round.
fn shade_factor(t: &Target, sigma: &Mat3) -> f64 {
    let (w, v) = sym_eig3(sigma);
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| w[a].total_cmp(&w[b]));
    let normal = [v[0][order[0]], v[1][order[0]], v[2][order[0]]];
    let flat = 1.0
        - (w[order[0]].max(0.0) / w[order[1]].max(1e-300))
            .sqrt()
            .min(1.0);
    let facing = t.lambert(t.camera.forward);
    flat * t.lambert(normal) + (1.0 - flat) * facing
}

/// Composite every Gaussian of `sets` (each with optional scalars, coloured through `map`)
/// into the target's viewport, back to front by the view depth of the centres (ties in input
/// order), each fragment only where it is nearer than the opaque geometry drawn already.
pub(super) fn composite(
    t: &mut Target,
    sets: &[(&Gaussians, Option<&[f64]>)],
    map: Option<Scalars>,
    low_pass: f64,
) {
    let (w, h) = (t.view.width as f64, t.view.height as f64);
    let low_pass = if low_pass.is_finite() {
        low_pass.max(0.0)
    } else {
        0.0
    };
    let camera: &Camera = t.camera;
    let mut splats: Vec<Footprint> = Vec::new();
    for &(g, scalars) in sets {
        for i in 0..g.len() {
            let opacity = g.opacities[i].clamp(0.0, 1.0);
            if opacity.is_nan() || opacity < MIN_ALPHA {
                continue;
            }
            let p = g.means[i];
            let (Some((cx, cy, depth)), Some(j)) =
                (camera.project(p, w, h), camera.jacobian(p, w, h))
            else {
                continue;
            };
            let [a, b, c] = screen_covariance(&j, &g.covariances[i], low_pass);
            let det = a * c - b * b;
            if !(det > 0.0 && det.is_finite() && a > 0.0 && c > 0.0) {
                continue;
            }
            let (hx, hy) = (CUTOFF_SIGMAS * a.sqrt(), CUTOFF_SIGMAS * c.sqrt());
            if cx + hx < 0.0 || cy + hy < 0.0 || cx - hx > w || cy - hy > h {
                continue;
            }
            let clip = |v: f64, hi: u32| (v.max(0.0) as u32).min(hi);
            let bbox = [
                clip((cx - hx - 0.5).floor(), t.view.width),
                clip((cx + hx - 0.5).ceil() + 1.0, t.view.width),
                clip((cy - hy - 0.5).floor(), t.view.height),
                clip((cy + hy - 0.5).ceil() + 1.0, t.view.height),
            ];
            let colour = match (scalars, map) {
                (Some(s), Some(m)) => {
                    let base = m.map.map(s[i], m.range);
                    let f = if s[i].is_nan() {
                        1.0
                    } else {
                        shade_factor(t, &g.covariances[i])
                    };
                    base.map(|v| (v as f64 / 255.0 * f).clamp(0.0, 1.0))
                }
                _ => g.colours[i].map(|v| if v.is_nan() { 0.5 } else { v.clamp(0.0, 1.0) }),
            };
            splats.push(Footprint {
                depth,
                centre: [cx, cy],
                conic: [c / det, -b / det, a / det],
                bbox,
                colour,
                opacity,
            });
        }
    }
    // Back to front; a stable sort keeps the input order among equal depths.
    splats.sort_by(|a, b| b.depth.total_cmp(&a.depth));
    let vw = t.view.width as usize;
    let mut buffer: Vec<[f64; 3]> = (0..t.view.height)
        .flat_map(|y| (0..t.view.width).map(move |x| (x, y)))
        .map(|(x, y)| {
            t.image
                .pixel(t.view.x + x, t.view.y + y)
                .map(|v| v as f64 / 255.0)
        })
        .collect();
    let mut touched = vec![false; buffer.len()];
    for s in &splats {
        let key = t.key(s.depth);
        let [a, b, c] = s.conic;
        for py in s.bbox[2]..s.bbox[3] {
            let dy = py as f64 + 0.5 - s.centre[1];
            for px in s.bbox[0]..s.bbox[1] {
                let dx = px as f64 + 0.5 - s.centre[0];
                let q = a * dx * dx + 2.0 * b * dx * dy + c * dy * dy;
                if q > CUTOFF_SIGMAS * CUTOFF_SIGMAS {
                    continue;
                }
                let alpha = (s.opacity * (-0.5 * q).exp()).min(MAX_ALPHA);
                let i = py as usize * vw + px as usize;
                if alpha < MIN_ALPHA || key <= t.near[i] {
                    continue;
                }
                let dst = &mut buffer[i];
                for k in 0..3 {
                    dst[k] = alpha * s.colour[k] + (1.0 - alpha) * dst[k];
                }
                touched[i] = true;
            }
        }
    }
    for (i, rgb) in buffer.iter().enumerate() {
        if touched[i] {
            let (x, y) = ((i % vw) as u32, (i / vw) as u32);
            let c = rgb.map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8);
            t.image.set(t.view.x + x, t.view.y + y, c);
        }
    }
}
