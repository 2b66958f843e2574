//! The splat compositor through `render::draw`: footprints against the projected covariance,
//! back-to-front order with the z-buffered geometry, scalar colouring and field checks.

use freeform::geometry::Aabb;
use freeform::io::splat::Splats;
use freeform::render::{
    draw, Camera, CameraOptions, DrawOptions, Gaussians, Image, Item, Projection, SH_C0,
};
use freeform::Point3;

/// 3DGS caps a splat's alpha at 0.99 (a splat never hides all that is behind it); the
/// expected pixels below are computed from the paper's rule, not read from the renderer.
const MAX_ALPHA: f64 = 0.99;

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
        // EWA: the screen covariance is J Sigma J^T plus the default low-pass 0.3 px^2 on its
        // diagonal.
        let sigma = &g.covariances[0];
        let jsj = |r: usize, c: usize| -> f64 {
            (0..3)
                .map(|k| (0..3).map(|l| j[r][k] * sigma[k][l] * j[c][l]).sum::<f64>())
                .sum()
        };
        let (a0, b0, c0) = (jsj(0, 0) + 0.3, jsj(0, 1), jsj(1, 1) + 0.3);
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
    use freeform::render::{ColorMap, Scalars};
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
