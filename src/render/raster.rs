//! The z-buffered rasterizer: triangles (flat or smooth Lambert + ambient shading) and
//! points as shaded discs (sphere impostors), optionally coloured by a scalar per vertex;
//! then splats, alpha-blended over them ([`super::splat`]).

use super::camera::Camera;
use super::colormap::NAN_COLOUR;
use super::image::{Image, Rect};
use super::splat::Gaussians;
use super::target::{unit, Scalars, Target};
use crate::linalg3::{cross, dot, sub};
use crate::{Error, Point3, Result};

/// Something to draw.
#[derive(Debug, Clone, Copy)]
pub enum Item<'a> {
    /// A triangle mesh: positions (N x 3, metres), triangles (indices into positions),
    /// optional scalar per position, colour when there are no scalars.
    Triangles {
        /// Vertex positions, N x 3, metres.
        positions: &'a [Point3],
        /// Triangles, indices into `positions`.
        triangles: &'a [[u32; 3]],
        /// A value per vertex (N), coloured through [`DrawOptions::scalars`].
        scalars: Option<&'a [f64]>,
        /// Colour without scalars.
        colour: [u8; 3],
    },
    /// Points drawn as shaded discs of `radius` (metres) at each position.
    Points {
        /// Centres, N x 3, metres.
        positions: &'a [Point3],
        /// Disc radius, metres (see [`disc_radius_from_spacing`]).
        radius: f64,
        /// A value per point (N), coloured through [`DrawOptions::scalars`].
        scalars: Option<&'a [f64]>,
        /// Colour without scalars.
        colour: [u8; 3],
    },
    /// 3D Gaussians drawn as projected ellipses and alpha-blended back to front after every
    /// other item ([`Gaussians`]; docs/pictures.md).
    Splats {
        /// The Gaussians (centres, covariances, colours, opacities).
        gaussians: &'a Gaussians,
        /// A value per Gaussian (N), coloured through [`DrawOptions::scalars`] (then shaded
        /// by the splat's shortest axis) instead of the Gaussians' own colours.
        scalars: Option<&'a [f64]>,
    },
}

/// A checkered ground square perpendicular to a coordinate axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ground {
    /// The axis it is perpendicular to (0 = x, 1 = y, 2 = z).
    pub axis: usize,
    /// Its coordinate along `axis`, metres.
    pub height: f64,
    /// Its extent along the two other axes (in increasing axis order), [min, max] each, metres.
    pub extent: [[f64; 2]; 2],
    /// Checker tile edge, metres.
    pub tile: f64,
}

/// Shading and colouring settings. Defaults: a light from the upper left behind the camera,
/// 35 % ambient so faces turned away stay readable.
#[derive(Debug, Clone, Copy, PartialEq)]
#[must_use]
pub struct DrawOptions {
    /// Ambient fraction of the colour, 0..1. Default 0.35.
    pub ambient: f64,
    /// Light direction in the camera frame (right, up, towards the viewer); normalized when
    /// used. Default [-0.35, 0.5, 1.0].
    pub light: [f64; 3],
    /// Scalar colouring of items that carry scalars (None: items use their colour).
    pub scalars: Option<Scalars>,
    /// An optional ground square (drawn first, so objects hide it).
    pub ground: Option<Ground>,
    /// Triangles shaded by interpolated vertex normals (true, default) or by face normals.
    pub smooth: bool,
    /// Variance added to both screen axes of every splat, px^2. Default 0.3 (the 3DGS
    /// rasterizer's low-pass filter): a splat smaller than a pixel still covers about one.
    pub splat_low_pass: f64,
}

impl Default for DrawOptions {
    fn default() -> Self {
        DrawOptions {
            ambient: 0.35,
            light: [-0.35, 0.5, 1.0],
            scalars: None,
            ground: None,
            smooth: true,
            splat_low_pass: 0.3,
        }
    }
}

/// Draw `items` into `viewport` of `image` as seen by `camera`, with a fresh depth buffer
/// (pixels outside the viewport are untouched; the background is whatever is there).
/// The ground, triangles and discs are z-buffered; then the splats of every
/// [`Item::Splats`] together are blended back to front over them. Triangles, points or splats
/// behind the eye are skipped. Errors: a triangle index past its positions, or scalars (or
/// splat fields) whose length differs from the positions'.
pub fn draw(
    image: &mut Image,
    viewport: Rect,
    camera: &Camera,
    items: &[Item],
    options: &DrawOptions,
) -> Result<()> {
    let view = Rect {
        x: viewport.x.min(image.width),
        y: viewport.y.min(image.height),
        width: viewport.width.min(image.width.saturating_sub(viewport.x)),
        height: viewport.height.min(image.height.saturating_sub(viewport.y)),
    };
    let l = unit(options.light);
    let light =
        [0, 1, 2].map(|k| l[0] * camera.right[k] + l[1] * camera.up[k] - l[2] * camera.forward[k]);
    let mut t = Target {
        near: vec![f64::NEG_INFINITY; view.width as usize * view.height as usize],
        image,
        view,
        camera,
        light,
        ambient: options.ambient.clamp(0.0, 1.0),
    };
    for item in items {
        let (n, scalars) = match item {
            Item::Triangles {
                positions,
                triangles,
                scalars,
                ..
            } => {
                crate::io::check_triangle_indices(positions.len(), triangles)?;
                (positions.len(), scalars)
            }
            Item::Points {
                positions, scalars, ..
            } => (positions.len(), scalars),
            Item::Splats { gaussians, scalars } => {
                let n = gaussians
                    .check()
                    .map_err(|(what, got)| Error::LengthMismatch {
                        what,
                        expected: gaussians.len(),
                        got,
                    })?;
                (n, scalars)
            }
        };
        if let Some(s) = scalars {
            if s.len() != n {
                return Err(Error::LengthMismatch {
                    what: "render scalars",
                    expected: n,
                    got: s.len(),
                });
            }
        }
    }
    if let Some(g) = &options.ground {
        draw_ground(&mut t, g);
    }
    for item in items {
        match *item {
            Item::Triangles {
                positions,
                triangles,
                scalars,
                colour,
            } => draw_triangles(
                &mut t,
                positions,
                triangles,
                scalars,
                colour,
                options.scalars,
                options.smooth,
            ),
            Item::Points {
                positions,
                radius,
                scalars,
                colour,
            } => draw_points(&mut t, positions, radius, scalars, colour, options.scalars),
            Item::Splats { .. } => {}
        }
    }
    let splats: Vec<(&Gaussians, Option<&[f64]>)> = items
        .iter()
        .filter_map(|item| match *item {
            Item::Splats { gaussians, scalars } => Some((gaussians, scalars)),
            _ => None,
        })
        .collect();
    if !splats.is_empty() {
        super::splat::composite(&mut t, &splats, options.scalars, options.splat_low_pass);
    }
    Ok(())
}

/// A colour per vertex: the scalar's through the map, or `colour`.
fn vertex_colour(
    scalars: Option<&[f64]>,
    map: Option<Scalars>,
    colour: [u8; 3],
) -> impl Fn(f64) -> [u8; 3] {
    let on = scalars.is_some();
    move |v: f64| match (on, map) {
        (true, Some(s)) => s.map.map(v, s.range),
        (true, None) => colour,
        (false, _) => colour,
    }
}

/// Rasterize one triangle with screen vertices `s` (column, row, depth) and call `fragment`
/// with the pixel and the perspective-correct barycentric weights of each covered pixel
/// centre (all three edge functions >= 0 for either winding).
fn raster_triangle(
    t: &mut Target,
    s: [(f64, f64, f64); 3],
    mut fragment: impl FnMut(&mut Target, u32, u32, f64, [f64; 3]),
) {
    let area = (s[1].0 - s[0].0) * (s[2].1 - s[0].1) - (s[2].0 - s[0].0) * (s[1].1 - s[0].1);
    if area.abs() < 1e-12 || !area.is_finite() {
        return;
    }
    let (w, h) = (t.view.width as f64, t.view.height as f64);
    let xmin = s.iter().map(|p| p.0).fold(f64::INFINITY, f64::min).max(0.0);
    let xmax = s
        .iter()
        .map(|p| p.0)
        .fold(f64::NEG_INFINITY, f64::max)
        .min(w);
    let ymin = s.iter().map(|p| p.1).fold(f64::INFINITY, f64::min).max(0.0);
    let ymax = s
        .iter()
        .map(|p| p.1)
        .fold(f64::NEG_INFINITY, f64::max)
        .min(h);
    if xmin >= xmax || ymin >= ymax {
        return;
    }
    let perspective = t.camera.is_perspective();
    let inv_depth = s.map(|p| 1.0 / p.2);
    let keys = s.map(|p| t.key(p.2));
    for py in (ymin - 0.5).floor().max(0.0) as u32
        ..((ymax - 0.5).ceil().max(0.0) as u32 + 1).min(t.view.height)
    {
        let cy = py as f64 + 0.5;
        for px in (xmin - 0.5).floor().max(0.0) as u32
            ..((xmax - 0.5).ceil().max(0.0) as u32 + 1).min(t.view.width)
        {
            let cx = px as f64 + 0.5;
            let e = |a: (f64, f64, f64), b: (f64, f64, f64)| {
                ((b.0 - a.0) * (cy - a.1) - (cx - a.0) * (b.1 - a.1)) / area
            };
            let l = [e(s[1], s[2]), e(s[2], s[0]), e(s[0], s[1])];
            if l.iter().any(|&v| v < 0.0) {
                continue;
            }
            let key = l[0] * keys[0] + l[1] * keys[1] + l[2] * keys[2];
            let b = if perspective {
                let q = [
                    l[0] * inv_depth[0],
                    l[1] * inv_depth[1],
                    l[2] * inv_depth[2],
                ];
                let sum = q[0] + q[1] + q[2];
                [q[0] / sum, q[1] / sum, q[2] / sum]
            } else {
                l
            };
            fragment(t, px, py, key, b);
        }
    }
}

fn draw_triangles(
    t: &mut Target,
    positions: &[Point3],
    triangles: &[[u32; 3]],
    scalars: Option<&[f64]>,
    colour: [u8; 3],
    map: Option<Scalars>,
    smooth: bool,
) {
    let (w, h) = (t.view.width as f64, t.view.height as f64);
    let screen: Vec<Option<(f64, f64, f64)>> = positions
        .iter()
        .map(|&p| t.camera.project(p, w, h))
        .collect();
    // Area-weighted vertex normals (the raw cross products sum to that).
    let face_normal = |tri: &[u32; 3]| {
        let [a, b, c] = tri.map(|i| positions[i as usize]);
        cross(&sub(&b, &a), &sub(&c, &a))
    };
    let mut normals = vec![[0.0; 3]; if smooth { positions.len() } else { 0 }];
    if smooth {
        for tri in triangles {
            let f = face_normal(tri);
            for &i in tri {
                let n = &mut normals[i as usize];
                *n = [n[0] + f[0], n[1] + f[1], n[2] + f[2]];
            }
        }
    }
    let colour_of = vertex_colour(scalars, map, colour);
    for tri in triangles {
        let idx = tri.map(|i| i as usize);
        let (Some(a), Some(b), Some(c)) = (screen[idx[0]], screen[idx[1]], screen[idx[2]]) else {
            continue;
        };
        let flat = face_normal(tri);
        let vn = if smooth {
            idx.map(|i| {
                let n = normals[i];
                // A vertex whose normals cancel (a sharp fold) takes the face's.
                if dot(&n, &n) > 0.0 {
                    unit(n)
                } else {
                    unit(flat)
                }
            })
        } else {
            [unit(flat); 3]
        };
        let sv = idx.map(|i| scalars.map_or(0.0, |s| s[i]));
        raster_triangle(t, [a, b, c], |t, px, py, key, bary| {
            t.plot(px, py, key, |t| {
                let n =
                    [0, 1, 2].map(|k| bary[0] * vn[0][k] + bary[1] * vn[1][k] + bary[2] * vn[2][k]);
                let v = bary[0] * sv[0] + bary[1] * sv[1] + bary[2] * sv[2];
                let base = colour_of(v);
                if base == NAN_COLOUR && v.is_nan() {
                    return NAN_COLOUR;
                }
                t.shade(base, if dot(&n, &n) > 0.0 { n } else { flat })
            });
        });
    }
}

fn draw_points(
    t: &mut Target,
    positions: &[Point3],
    radius: f64,
    scalars: Option<&[f64]>,
    colour: [u8; 3],
    map: Option<Scalars>,
) {
    let (w, h) = (t.view.width as f64, t.view.height as f64);
    let short = w.min(h);
    let radius = if radius.is_finite() && radius > 0.0 {
        radius
    } else {
        0.0
    };
    let colour_of = vertex_colour(scalars, map, colour);
    let (right, up, fwd) = (t.camera.right, t.camera.up, t.camera.forward);
    // Nearest first: a farther disc's pixels then fail the depth test before they are shaded
    // (drawn in input order, most pixels were shaded several times). Ties keep input order,
    // so the picture does not depend on the sort.
    let mut order: Vec<(usize, f64, f64, f64)> = positions
        .iter()
        .enumerate()
        .filter_map(|(i, &p)| t.camera.project(p, w, h).map(|(cx, cy, d)| (i, cx, cy, d)))
        .collect();
    order.sort_by(|a, b| a.3.total_cmp(&b.3).then(a.0.cmp(&b.0)));
    for (i, cx, cy, depth) in order {
        // At least a pixel-wide dot, so sparse or far points stay visible.
        let rp = (radius * t.camera.pixels_per_metre(depth, short)).max(0.75);
        if cx + rp < 0.0 || cy + rp < 0.0 || cx - rp > w || cy - rp > h {
            continue;
        }
        let base = colour_of(scalars.map_or(0.0, |s| s[i]));
        // The disc's nearest point: a pixel already nearer than it is skipped before its
        // depth is computed (with discs nearest first, most pixels of later discs are).
        let front = if depth - radius > 0.0 || !t.camera.is_perspective() {
            t.key(depth - radius)
        } else {
            f64::INFINITY // the disc reaches the eye plane: test every pixel exactly
        };
        let x0 = (cx - rp).floor().max(0.0) as u32;
        let x1 = ((cx + rp).ceil().max(0.0) as u32).min(t.view.width);
        let y0 = (cy - rp).floor().max(0.0) as u32;
        let y1 = ((cy + rp).ceil().max(0.0) as u32).min(t.view.height);
        for py in y0..y1 {
            for px in x0..x1 {
                let u = (px as f64 + 0.5 - cx) / rp;
                let v = -(py as f64 + 0.5 - cy) / rp;
                let q = u * u + v * v;
                if q > 1.0 || !t.may_show(px, py, front) {
                    continue;
                }
                // The visible hemisphere of a ball of this radius: its depth and normal.
                let nz = (1.0 - q).sqrt();
                let key = t.key(depth - radius * nz);
                t.plot(px, py, key, |t| {
                    let n = [0, 1, 2].map(|k| u * right[k] + v * up[k] - nz * fwd[k]);
                    t.shade(base, n)
                });
            }
        }
    }
}

fn draw_ground(t: &mut Target, g: &Ground) {
    let axis = g.axis.min(2);
    let (a, b) = match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let corner = |ua: f64, ub: f64| {
        let mut p = [0.0; 3];
        p[axis] = g.height;
        p[a] = ua;
        p[b] = ub;
        p
    };
    let [ea, eb] = g.extent;
    let quad = [
        corner(ea[0], eb[0]),
        corner(ea[1], eb[0]),
        corner(ea[1], eb[1]),
        corner(ea[0], eb[1]),
    ];
    let mut normal = [0.0; 3];
    normal[axis] = 1.0;
    let tile = if g.tile > 0.0 && g.tile.is_finite() {
        g.tile
    } else {
        1.0
    };
    let (w, h) = (t.view.width as f64, t.view.height as f64);
    for tri in [[0, 1, 2], [0, 2, 3]] {
        let p = tri.map(|i| quad[i]);
        let (Some(s0), Some(s1), Some(s2)) = (
            t.camera.project(p[0], w, h),
            t.camera.project(p[1], w, h),
            t.camera.project(p[2], w, h),
        ) else {
            continue;
        };
        raster_triangle(t, [s0, s1, s2], |t, px, py, key, bary| {
            let at = |k: usize| bary[0] * p[0][k] + bary[1] * p[1][k] + bary[2] * p[2][k];
            let parity = ((at(a) / tile).floor() + (at(b) / tile).floor()).rem_euclid(2.0);
            let c = if parity < 0.5 {
                [214, 214, 214]
            } else {
                [188, 188, 188]
            };
            t.plot(px, py, key, |t| t.shade(c, normal));
        });
    }
}

/// A disc radius for points `positions` (N x 3, metres): 0.6 x the median distance to the
/// nearest other point over at most 2000 evenly strided points (so neighbouring discs just
/// overlap); 1 % of the bounding-box diagonal for fewer than two distinct points.
pub fn disc_radius_from_spacing(positions: &[Point3]) -> f64 {
    use kiddo::{ImmutableKdTree, SquaredEuclidean};
    let fallback = crate::geometry::Aabb::from_points(positions).map_or(0.01, |b| {
        let s = b.size();
        let d = dot(&s, &s).sqrt();
        if d > 0.0 {
            0.01 * d
        } else {
            0.01
        }
    });
    if positions.len() < 2 {
        return fallback;
    }
    let Ok(tree) = ImmutableKdTree::<f64, 3>::new_from_slice(positions) else {
        return fallback;
    };
    let stride = (positions.len() / 2000).max(1);
    let two = std::num::NonZero::new(2).expect("2 > 0");
    let mut d: Vec<f64> = positions
        .iter()
        .step_by(stride)
        .filter_map(|p| {
            tree.query(p)
                .nearest_n::<SquaredEuclidean<f64>>(two)
                .execute()
                .last()
                .map(|r| r.distance.sqrt())
        })
        .filter(|&d| d > 0.0 && d.is_finite())
        .collect();
    if d.is_empty() {
        return fallback;
    }
    d.sort_by(f64::total_cmp);
    0.6 * d[d.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::super::camera::{CameraOptions, Projection};
    use super::super::colormap::ColorMap;
    use super::*;
    use crate::geometry::Aabb;

    const BG: [u8; 3] = [255, 255, 255];

    fn ortho_camera() -> Camera {
        // Looking down -z (azimuth 0, elevation 0: the eye on +z), x right, y up; the unit
        // cube's circumscribed sphere (radius sqrt(3)/2) spans the shorter side.
        Camera::fit(
            &Aabb {
                min: [-0.5; 3],
                max: [0.5; 3],
            },
            &CameraOptions {
                azimuth_deg: 0.0,
                elevation_deg: 0.0,
                projection: Projection::Orthographic,
                margin: 0.0,
                ..Default::default()
            },
        )
    }

    #[test]
    fn a_facing_triangle_covers_the_pixels_whose_centres_its_projection_covers() {
        let cam = ortho_camera();
        let mut img = Image::new(100, 100, BG);
        let rect = img.rect();
        let pos = [[-0.4, -0.3, 0.0], [0.4, -0.3, 0.0], [0.0, 0.45, 0.0]];
        draw(
            &mut img,
            rect,
            &cam,
            &[Item::Triangles {
                positions: &pos,
                triangles: &[[0, 1, 2]],
                scalars: None,
                colour: [200, 0, 0],
            }],
            &DrawOptions::default(),
        )
        .unwrap();
        let s = pos.map(|p| cam.project(p, 100.0, 100.0).unwrap());
        // Signed distance (pixels) of a pixel centre inside the projected triangle.
        let inside = |x: f64, y: f64| {
            let mut d = f64::INFINITY;
            for k in 0..3 {
                let (a, b) = (s[k], s[(k + 1) % 3]);
                let (ex, ey) = (b.0 - a.0, b.1 - a.1);
                let len = (ex * ex + ey * ey).sqrt();
                // The projection is clockwise on screen (y down); inside is to the right.
                d = d.min(-(ex * (y - a.1) - (x - a.0) * ey) / len);
            }
            d
        };
        let (mut covered, mut edge) = (0, 0);
        for y in 0..100 {
            for x in 0..100 {
                let d = inside(x as f64 + 0.5, y as f64 + 0.5);
                let drawn = img.pixel(x, y) != BG;
                if d > 1e-9 {
                    assert!(drawn, "pixel {x},{y} inside by {d} is not drawn");
                } else if d < -1e-9 {
                    assert!(!drawn, "pixel {x},{y} outside by {d} is drawn");
                } else {
                    edge += 1;
                }
                covered += drawn as usize;
            }
        }
        // The count is the projected area up to the pixels along the edges.
        let area = 0.5
            * ((s[1].0 - s[0].0) * (s[2].1 - s[0].1) - (s[2].0 - s[0].0) * (s[1].1 - s[0].1)).abs();
        let perimeter: f64 = (0..3)
            .map(|k| {
                ((s[(k + 1) % 3].0 - s[k].0).powi(2) + (s[(k + 1) % 3].1 - s[k].1).powi(2)).sqrt()
            })
            .sum();
        assert!(
            (covered as f64 - area).abs() <= perimeter + edge as f64,
            "{covered} vs {area}"
        );
        // Facing the light-ish camera: lit above ambient, the same colour everywhere.
        let c = img.pixel(50, 50);
        assert!(c[0] > (200.0 * 0.35) as u8 && c[1] == 0 && c[2] == 0);
    }

    #[test]
    fn a_near_triangle_hides_a_far_one_in_either_order() {
        for perspective in [false, true] {
            let mut cam = ortho_camera();
            if perspective {
                cam = Camera::fit(
                    &Aabb {
                        min: [-0.5; 3],
                        max: [0.5; 3],
                    },
                    &CameraOptions {
                        azimuth_deg: 0.0,
                        elevation_deg: 0.0,
                        ..Default::default()
                    },
                );
            }
            let near = [[-0.3, -0.3, 0.2], [0.3, -0.3, 0.2], [0.0, 0.3, 0.2]];
            let far = [[-0.4, -0.4, -0.2], [0.4, -0.4, -0.2], [0.0, 0.4, -0.2]];
            let tri = |p: &'static [Point3; 3], c| Item::Triangles {
                positions: p,
                triangles: &[[0, 1, 2]],
                scalars: None,
                colour: c,
            };
            let (near, far): (&'static [Point3; 3], &'static [Point3; 3]) =
                (Box::leak(Box::new(near)), Box::leak(Box::new(far)));
            for order in [
                [tri(near, [0, 200, 0]), tri(far, [0, 0, 200])],
                [tri(far, [0, 0, 200]), tri(near, [0, 200, 0])],
            ] {
                let mut img = Image::new(64, 64, BG);
                let rect = img.rect();
                draw(&mut img, rect, &cam, &order, &DrawOptions::default()).unwrap();
                let centre = img.pixel(32, 32);
                assert!(centre[1] > 0 && centre[2] == 0, "{centre:?}");
                // Where only the far one is: blue.
                let (x, y, _) = cam.project([0.0, -0.38, -0.2], 64.0, 64.0).unwrap();
                let c = img.pixel(x as u32, y as u32 - 1);
                assert!(c[2] > 0 && c[1] == 0, "{c:?}");
            }
        }
    }

    #[test]
    fn discs_scale_with_radius_and_scalars_pick_the_map_ends() {
        let cam = ortho_camera();
        let mut img = Image::new(100, 100, BG);
        let rect = img.rect();
        let pos = [[-0.25, 0.0, 0.0], [0.25, 0.0, 0.0]];
        let opts = DrawOptions {
            ambient: 1.0,
            scalars: Some(Scalars {
                map: ColorMap::Viridis,
                range: [1.0, 2.0],
            }),
            ..Default::default()
        };
        draw(
            &mut img,
            rect,
            &cam,
            &[Item::Points {
                positions: &pos,
                radius: 0.1,
                scalars: Some(&[1.0, 2.0]),
                colour: [0; 3],
            }],
            &opts,
        )
        .unwrap();
        let (x0, y0, _) = cam.project(pos[0], 100.0, 100.0).unwrap();
        let (x1, _, _) = cam.project(pos[1], 100.0, 100.0).unwrap();
        // Full ambient: the exact map colours at the centres.
        assert_eq!(img.pixel(x0 as u32, y0 as u32), ColorMap::Viridis.at(0.0));
        assert_eq!(img.pixel(x1 as u32, y0 as u32), ColorMap::Viridis.at(1.0));
        // The disc's pixel count is close to pi r^2 (r in pixels).
        let rp = 0.1 * cam.pixels_per_metre(1.0, 100.0);
        let count = img.rgb.chunks(3).filter(|c| *c != BG).count() as f64 / 2.0;
        let area = std::f64::consts::PI * rp * rp;
        assert!(
            (count - area).abs() < 2.0 * std::f64::consts::PI * rp + 1.0,
            "{count} vs {area}"
        );
        // Bad input is an error.
        let e = draw(
            &mut img,
            rect,
            &cam,
            &[Item::Points {
                positions: &pos,
                radius: 0.1,
                scalars: Some(&[1.0]),
                colour: [0; 3],
            }],
            &opts,
        );
        assert!(e.is_err());
    }

    #[test]
    fn spacing_radius_is_a_fraction_of_the_grid_step() {
        let pts: Vec<Point3> = (0..1000)
            .map(|i| {
                [
                    (i % 10) as f64 * 0.1,
                    (i / 10 % 10) as f64 * 0.1,
                    (i / 100) as f64 * 0.1,
                ]
            })
            .collect();
        assert!((disc_radius_from_spacing(&pts) - 0.06).abs() < 1e-9);
    }
}
