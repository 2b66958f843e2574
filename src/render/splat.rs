//! 3D Gaussians (splats) drawn as projected ellipses (EWA splatting, as the 3DGS rasterizer
//! does): each covariance goes to the screen through the camera's Jacobian at its centre,
//! Sigma_2D = J Sigma J^T + a low-pass (0.3 px^2), every pixel within 3 sigma gets
//! alpha = min(0.99, opacity exp(-d^T Sigma_2D^-1 d / 2)), and the splats are alpha-blended
//! back to front by the view depth of their centres over what is drawn already (the
//! background, the ground, meshes and discs, which hide the splats behind them).

use super::camera::Camera;
use super::raster::{Scalars, Target};
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

/// The logistic function 1 / (1 + e^-x): a stored 3DGS opacity to 0..1.
pub fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
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
pub(super) fn screen_covariance(j: &[[f64; 3]; 2], sigma: &Mat3, low_pass: f64) -> [f64; 3] {
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

#[cfg(test)]
mod tests {
    use super::super::camera::{CameraOptions, Projection};
    use super::super::image::Image;
    use super::super::raster::{draw, DrawOptions, Item};
    use super::*;
    use crate::geometry::Aabb;

    fn camera(projection: Projection, azimuth_deg: f64, elevation_deg: f64) -> Camera {
        Camera::fit(
            &Aabb {
                min: [-0.5; 3],
                max: [0.5; 3],
            },
            &CameraOptions {
                azimuth_deg,
                elevation_deg,
                projection,
                margin: 0.0,
                ..Default::default()
            },
        )
    }

    /// A test splat: centre, log-scales, rotation (w first), stored opacity, colour.
    type Spec = (Point3, [f64; 3], [f64; 4], f64, [f64; 3]);

    /// One splat per entry.
    fn splats(list: &[Spec]) -> Gaussians {
        let s = Splats::new(
            list.iter().map(|l| l.0).collect(),
            list.iter().map(|l| l.1).collect(),
            list.iter().map(|l| l.2).collect(),
            list.iter().map(|l| l.3).collect(),
            list.iter()
                .map(|l| l.4.map(|c| (c - 0.5) / SH_C0))
                .collect(),
            vec![],
            0,
        )
        .unwrap();
        Gaussians::from_splats(&s)
    }

    fn render(cam: &Camera, size: u32, items: &[Item]) -> Image {
        let mut img = Image::new(size, size, [0; 3]);
        let rect = img.rect();
        draw(&mut img, rect, cam, items, &DrawOptions::default()).unwrap();
        img
    }

    #[test]
    fn an_isotropic_gaussian_facing_the_camera_draws_a_circle_of_its_half_height_radius() {
        let cam = camera(Projection::Orthographic, 0.0, 0.0);
        let sigma: f64 = 0.1;
        let g = splats(&[(
            [0.0; 3],
            [sigma.ln(); 3],
            [1.0, 0.0, 0.0, 0.0],
            12.0,
            [1.0; 3],
        )]);
        assert!((g.colours[0][0] - 1.0).abs() < 1e-12 && g.opacities[0] > 0.9999);
        let size = 120;
        let img = render(
            &cam,
            size,
            &[Item::Splats {
                gaussians: &g,
                scalars: None,
            }],
        );
        // Alpha = 0.99 exp(-d^2 / (2 s^2)) with s^2 = (sigma in pixels)^2 + the 0.3 px^2
        // low-pass: above half its peak within d < s sqrt(2 ln 2).
        let sp = sigma * cam.pixels_per_metre(1.0, size as f64);
        let r = ((sp * sp + 0.3) * 2.0 * std::f64::consts::LN_2).sqrt();
        assert!(r > 5.0, "{r}");
        let (cx, cy, _) = cam.project([0.0; 3], size as f64, size as f64).unwrap();
        let half = (0.5 * MAX_ALPHA * 255.0).round() as u8;
        let mut above = 0;
        for y in 0..size {
            for x in 0..size {
                let d = ((x as f64 + 0.5 - cx).powi(2) + (y as f64 + 0.5 - cy).powi(2)).sqrt();
                let p = img.pixel(x, y);
                assert!(p[0] == p[1] && p[1] == p[2]);
                if d < r - 0.05 {
                    assert!(p[0] >= half, "{x},{y} at {d} px (r {r}): {p:?}");
                    above += 1;
                } else if d > r + 0.05 {
                    assert!(p[0] <= half, "{x},{y} at {d} px (r {r}): {p:?}");
                }
                // Nothing beyond 3 sigma.
                if d > 3.0 * (sp * sp + 0.3).sqrt() + 1.0 {
                    assert_eq!(p, [0; 3]);
                }
            }
        }
        let area = std::f64::consts::PI * r * r;
        assert!(
            (above as f64 - area).abs() < 2.0 * std::f64::consts::PI * r,
            "{above} vs {area}"
        );
    }

    #[test]
    fn an_elongated_gaussian_draws_the_ellipse_of_its_projected_covariance() {
        for projection in [
            Projection::Orthographic,
            Projection::Perspective { fov_deg: 40.0 },
        ] {
            let cam = camera(projection, 35.0, 25.0);
            // Long along a direction turned 30 degrees about z, thin along another.
            let (h, a) = (0.5 * 30f64.to_radians(), 0.5 * 50f64.to_radians());
            let q = [
                h.cos() * a.cos(),
                h.cos() * a.sin(),
                h.sin() * a.sin(),
                h.sin() * a.cos(),
            ];
            let centre = [0.1, -0.05, 0.08];
            let g = splats(&[(
                centre,
                [0.12f64.ln(), 0.025f64.ln(), 0.05f64.ln()],
                q,
                2.2,
                [1.0; 3],
            )]);
            let size = 200u32;
            let img = render(
                &cam,
                size,
                &[Item::Splats {
                    gaussians: &g,
                    scalars: None,
                }],
            );
            let s = size as f64;
            let j = cam.jacobian(centre, s, s).unwrap();
            let [a0, b0, c0] = screen_covariance(&j, &g.covariances[0], 0.3);
            // Second moments of the drawn alpha (white on black: value = 255 alpha).
            let (mut m0, mut mx, mut my) = (0.0, 0.0, 0.0);
            let mut pix = Vec::new();
            for y in 0..size {
                for x in 0..size {
                    let w = img.pixel(x, y)[0] as f64 / 255.0;
                    if w > 0.0 {
                        let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                        m0 += w;
                        mx += w * px;
                        my += w * py;
                        pix.push((w, px, py));
                    }
                }
            }
            let (mx, my) = (mx / m0, my / m0);
            let (cx, cy, _) = cam.project(centre, s, s).unwrap();
            assert!((mx - cx).abs() < 0.2 && (my - cy).abs() < 0.2);
            let (mut sa, mut sb, mut sc) = (0.0, 0.0, 0.0);
            for (w, px, py) in pix {
                sa += w * (px - mx) * (px - mx);
                sb += w * (px - mx) * (py - my);
                sc += w * (py - my) * (py - my);
            }
            let (sa, sb, sc) = (sa / m0, sb / m0, sc / m0);
            // A 2D Gaussian cut at 3 sigma keeps (1 - 5.5 e^-4.5) / (1 - e^-4.5) of its
            // second moment.
            let cut = (1.0 - 5.5 * (-4.5f64).exp()) / (1.0 - (-4.5f64).exp());
            let eig = |a: f64, b: f64, c: f64| {
                let m = 0.5 * (a + c);
                let d = (0.25 * (a - c) * (a - c) + b * b).sqrt();
                let angle = 0.5 * (2.0 * b).atan2(a - c);
                (m + d, m - d, angle)
            };
            let (l1, l2, t) = eig(a0 * cut, b0 * cut, c0 * cut);
            let (m1, m2, u) = eig(sa, sb, sc);
            assert!(l1 > 2.0 * l2 && l2 > 4.0, "{l1} {l2}: not a clear ellipse");
            assert!((m1 / l1 - 1.0).abs() < 0.1, "{projection:?}: {m1} vs {l1}");
            assert!((m2 / l2 - 1.0).abs() < 0.1, "{projection:?}: {m2} vs {l2}");
            let dt = (u - t).abs() % std::f64::consts::PI;
            assert!(
                dt.min(std::f64::consts::PI - dt) < 2f64.to_radians(),
                "{u} vs {t}"
            );
        }
    }

    #[test]
    fn a_nearer_opaque_splat_hides_a_farther_one_in_either_order_and_geometry_hides_both() {
        for projection in [
            Projection::Orthographic,
            Projection::Perspective { fov_deg: 30.0 },
        ] {
            let cam = camera(projection, 0.0, 0.0);
            // The eye is on +z: z = 0.2 is nearer than z = -0.2. The far one is larger.
            let near = (
                [0.0, 0.0, 0.2],
                [0.05f64.ln(); 3],
                [1.0, 0.0, 0.0, 0.0],
                12.0,
                [1.0, 0.0, 0.0],
            );
            let far = (
                [0.0, 0.0, -0.2],
                [0.15f64.ln(); 3],
                [1.0, 0.0, 0.0, 0.0],
                12.0,
                [0.0, 0.0, 1.0],
            );
            let mut pictures = Vec::new();
            for list in [[near, far], [far, near]] {
                let g = splats(&list);
                let img = render(
                    &cam,
                    100,
                    &[Item::Splats {
                        gaussians: &g,
                        scalars: None,
                    }],
                );
                let c = img.pixel(50, 50);
                // Blue only through the 1 - alpha (> 0.01 off the near one's centre) it leaves.
                assert!(c[0] >= 235 && c[2] <= 15, "{projection:?} centre {c:?}");
                let (x, y, _) = cam.project([0.15, 0.0, -0.2], 100.0, 100.0).unwrap();
                let c = img.pixel(x as u32, y as u32);
                assert!(c[2] > 100 && c[0] < 20, "{projection:?} far only {c:?}");
                pictures.push(img);
            }
            assert_eq!(pictures[0], pictures[1]);
            // An opaque triangle between them hides the far splat, not the near one.
            let g = splats(&[far, near]);
            let tri = [[-0.45, -0.45, 0.0], [0.45, -0.45, 0.0], [0.0, 0.45, 0.0]];
            let img = render(
                &cam,
                100,
                &[
                    Item::Splats {
                        gaussians: &g,
                        scalars: None,
                    },
                    Item::Triangles {
                        positions: &tri,
                        triangles: &[[0, 1, 2]],
                        scalars: None,
                        colour: [0, 200, 0],
                    },
                ],
            );
            assert!(img.pixel(50, 50)[0] >= 235);
            let (x, y, _) = cam.project([0.22, -0.2, -0.2], 100.0, 100.0).unwrap();
            let c = img.pixel(x as u32, y as u32);
            assert!(c[1] > 50 && c[2] == 0, "{c:?}");
        }
    }

    #[test]
    fn scalars_colour_the_splats_and_mismatched_fields_are_errors() {
        use super::super::colormap::ColorMap;
        use super::super::raster::Scalars;
        let cam = camera(Projection::Orthographic, 0.0, 0.0);
        let g = splats(&[(
            [0.0; 3],
            [0.08f64.ln(); 3],
            [1.0, 0.0, 0.0, 0.0],
            12.0,
            [1.0; 3],
        )]);
        let mut img = Image::new(64, 64, [0; 3]);
        let rect = img.rect();
        let opts = DrawOptions {
            ambient: 1.0,
            scalars: Some(Scalars {
                map: ColorMap::Viridis,
                range: [0.0, 1.0],
            }),
            ..Default::default()
        };
        let item = Item::Splats {
            gaussians: &g,
            scalars: Some(&[1.0]),
        };
        draw(&mut img, rect, &cam, &[item], &opts).unwrap();
        // Pixel (32, 32)'s centre is half a pixel off the splat's along both axes.
        let sp = 0.08 * cam.pixels_per_metre(1.0, 64.0);
        let alpha = (g.opacities[0] * (-0.5 * 0.5 / (sp * sp + 0.3)).exp()).min(MAX_ALPHA);
        let want = ColorMap::Viridis
            .at(1.0)
            .map(|v| (v as f64 * alpha).round() as u8);
        let got = img.pixel(32, 32);
        for k in 0..3 {
            assert!(
                (got[k] as i32 - want[k] as i32).abs() <= 1,
                "{got:?} vs {want:?}"
            );
        }
        let bad = Item::Splats {
            gaussians: &g,
            scalars: Some(&[1.0, 2.0]),
        };
        assert!(draw(&mut img, rect, &cam, &[bad], &opts).is_err());
        let mut short = g.clone();
        short.opacities.clear();
        let bad = Item::Splats {
            gaussians: &short,
            scalars: None,
        };
        assert!(draw(&mut img, rect, &cam, &[bad], &opts).is_err());
    }
}
