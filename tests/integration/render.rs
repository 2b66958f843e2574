//! `freeform render` and `freeform modes --png` end to end, and the renderer's identities
//! through the public API (src/render/ has the pixel-level unit tests).

use crate::common::freeform;
use freeform::geometry::Aabb;
use freeform::render::{draw, Camera, CameraOptions, DrawOptions, Image, Item, Projection};
use std::path::Path;

/// Width and height of a PNG file, and that its pixels decode.
fn png_size(path: &Path) -> (u32, u32) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    (info.width, info.height)
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// A 4-step run of a small box writing 3 frames (0, 2, 4) into `dir/frames`.
fn tiny_run(dir: &Path) -> std::path::PathBuf {
    let scene = dir.join("s.toml");
    std::fs::write(
        &scene,
        "[simulation]\ndt = 0.01\nsteps = 4\ngravity = [0.0, -9.81, 0.0]\n\
         [solver]\ncubature = 300\n[output]\nevery = 2\nformats = [\"vtk\"]\n\
         [[object]]\nname = \"bar\"\nshape = \"box:1,0.2,0.2\"\n\
         basis = { kernels = 40, modes = 4, points = 2000 }\n",
    )
    .unwrap();
    let out = dir.join("frames");
    let o = freeform(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    out
}

#[test]
fn render_writes_one_png_per_selected_frame_with_the_asked_size() {
    let dir = tempfile::tempdir().unwrap();
    let frames = tiny_run(dir.path());
    let f = frames.to_str().unwrap();
    // Every frame, default colouring (|displacement| with a colour bar), into DIR/png.
    let o = freeform(&["render", f, "--size", "160x120"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut pngs: Vec<_> = std::fs::read_dir(frames.join("png"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    pngs.sort();
    assert_eq!(
        pngs,
        ["frame_000000.png", "frame_000001.png", "frame_000002.png"]
    );
    for p in &pngs {
        assert_eq!(png_size(&frames.join("png").join(p)), (160, 120));
    }
    // Every second frame, no colour, another view, the ground, into --out.
    let out = dir.path().join("pics");
    let o = freeform(&[
        "render",
        f,
        "--every",
        "2",
        "--color",
        "none",
        "--out",
        out.to_str().unwrap(),
        "--azimuth",
        "-60",
        "--elevation",
        "45",
        "--ortho",
        "--ground",
        "0",
        "--object",
        "bar",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("frames 2 of 3"));
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 2);
    assert_eq!(png_size(&out.join("frame_000002.png")), (800, 600));
    // The same input gives the same picture.
    let again = dir.path().join("again");
    let o = freeform(&[
        "render",
        f,
        "--every",
        "2",
        "--color",
        "none",
        "--out",
        again.to_str().unwrap(),
        "--azimuth",
        "-60",
        "--elevation",
        "45",
        "--ortho",
        "--ground",
        "0",
        "--object",
        "bar",
    ]);
    assert!(o.status.success());
    assert_eq!(
        std::fs::read(out.join("frame_000002.png")).unwrap(),
        std::fs::read(again.join("frame_000002.png")).unwrap()
    );
}

/// A sphere shell of `n` flat splats (radius 0.2 m, centre 0.5 m up), the upper half red and
/// the lower half blue, written as a 3DGS PLY.
fn write_splat_ball(path: &Path, n: usize) {
    use freeform::io::splat::{write_splats, Splats};
    use freeform::linalg3::matrix_to_quat;
    let c0 = 0.282_094_791_773_878_14;
    let (mut means, mut scales, mut rots, mut dc) = (vec![], vec![], vec![], vec![]);
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..n {
        let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - y * y).sqrt();
        let phi = golden * i as f64;
        let normal = [r * phi.cos(), y, r * phi.sin()];
        let east = [-phi.sin(), 0.0, phi.cos()];
        let north = [-y * phi.cos(), r, -y * phi.sin()];
        // Columns north, east, normal: a proper rotation with the thin axis along the normal.
        let m = [0, 1, 2].map(|k| [north[k], east[k], normal[k]]);
        means.push([0.2 * normal[0], 0.5 + 0.2 * normal[1], 0.2 * normal[2]]);
        scales.push([0.02f64.ln(), 0.02f64.ln(), 0.003f64.ln()]);
        rots.push(matrix_to_quat(&m));
        let colour: [f64; 3] = if y > 0.0 {
            [0.9, 0.1, 0.1]
        } else {
            [0.1, 0.1, 0.9]
        };
        dc.push(colour.map(|c| (c - 0.5) / c0));
    }
    let s = Splats::new(means, scales, rots, vec![5.0; n], dc, vec![], 0).unwrap();
    write_splats(path, &s).unwrap();
}

#[test]
fn render_draws_splat_objects_as_ellipses_from_their_ply_frames() {
    let dir = tempfile::tempdir().unwrap();
    write_splat_ball(&dir.path().join("ball.ply"), 400);
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        "[simulation]\ndt = 0.01\nsteps = 4\ngravity = [0.0, -9.81, 0.0]\n\
         [solver]\ncubature = 200\n[output]\nevery = 2\nformats = [\"vtk\", \"ply\"]\n\
         [[object]]\nname = \"ball\"\nshape = \"ball.ply\"\n\
         basis = { kernels = 40, modes = 4 }\n",
    )
    .unwrap();
    let frames = dir.path().join("frames");
    let o = freeform(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        frames.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(frames.join("ball").join("ball_000004.ply").is_file());
    let f = frames.to_str().unwrap();
    // Default: a splat object in its own colours, no colour bar.
    let o = freeform(&[
        "render",
        f,
        "--size",
        "200x150",
        "--azimuth",
        "0",
        "--elevation",
        "0",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("ball (splats as ellipses)"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let png = frames.join("png").join("frame_000002.png");
    assert_eq!(png_size(&png), (200, 150));
    // Red above, blue below: the SH colours, not an object colour.
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut buf).unwrap();
    let px = |x: usize, y: usize| {
        let i = 3 * (y * 200 + x);
        [buf[i], buf[i + 1], buf[i + 2]]
    };
    let (top, bottom) = (px(100, 55), px(100, 95));
    assert!(top[0] > 150 && top[2] < 80, "top {top:?}");
    assert!(bottom[2] > 150 && bottom[0] < 80, "bottom {bottom:?}");
    // By displacement (from the .vtp) with a colour bar; --color splat as the default.
    for colour in ["displacement", "splat", "none"] {
        let out = dir.path().join(colour);
        let o = freeform(&[
            "render",
            f,
            "--color",
            colour,
            "--size",
            "240x160",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{colour}: {}", stderr(&o));
        assert_eq!(std::fs::read_dir(&out).unwrap().count(), 3);
        assert_eq!(png_size(&out.join("frame_000001.png")), (240, 160));
    }
    assert_eq!(
        std::fs::read(dir.path().join("splat").join("frame_000002.png")).unwrap(),
        std::fs::read(dir.path().join("none").join("frame_000002.png")).unwrap()
    );
}

#[test]
fn render_rejects_bad_input_with_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nowhere");
    let o = freeform(&["render", missing.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("nowhere") && stderr(&o).contains("no such directory"),
        "{}",
        stderr(&o)
    );
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let o = freeform(&["render", empty.to_str().unwrap()]);
    assert!(stderr(&o).contains("no .pvd files"), "{}", stderr(&o));

    let frames = tiny_run(dir.path());
    let f = frames.to_str().unwrap();
    let o = freeform(&["render", f, "--object", "ball"]);
    assert!(
        !o.status.success() && stderr(&o).contains("objects: bar"),
        "{}",
        stderr(&o)
    );
    let o = freeform(&["render", f, "--color", "stress"]);
    assert!(
        stderr(&o).contains("no point array `stress`") && stderr(&o).contains("displacement"),
        "{}",
        stderr(&o)
    );
    for (flag, value) in [
        ("--size", "800"),
        ("--size", "0x10"),
        ("--every", "0"),
        ("--elevation", "90"),
        ("--fov", "0"),
        ("--zoom", "-1"),
        ("--radius", "0"),
    ] {
        let o = freeform(&["render", f, flag, value]);
        assert!(
            !o.status.success() && stderr(&o).contains(flag),
            "{flag} {value}: {}",
            stderr(&o)
        );
    }
    // A truncated frame: the error names the file; no picture is written for it.
    let vtp = frames.join("bar").join("bar_000002.vtp");
    let bytes = std::fs::read(&vtp).unwrap();
    std::fs::write(&vtp, &bytes[..bytes.len() / 2]).unwrap();
    let o = freeform(&["render", f]);
    assert!(
        !o.status.success() && stderr(&o).contains("bar_000002.vtp"),
        "{}",
        stderr(&o)
    );
    std::fs::remove_file(&vtp).unwrap();
    let o = freeform(&["render", f]);
    assert!(
        !o.status.success() && stderr(&o).contains("bar_000002.vtp"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn modes_png_draws_a_grid_of_the_first_modes() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("modes.png");
    // `freeform modes` on a small box with m modes and 120 x 100 tiles, plus `extra` flags.
    let draw = |modes: &str, out: &std::path::Path, extra: &[&str]| {
        let mut args = vec![
            "modes",
            "box:1,0.3,0.3",
            "--modes",
            modes,
            "--out",
            out.to_str().unwrap(),
            "--png",
            png.to_str().unwrap(),
            "--png-tile",
            "120x100",
        ];
        args.extend_from_slice(extra);
        let o = freeform(&args);
        assert!(o.status.success(), "{}", stderr(&o));
    };
    draw(
        "5",
        &dir.path().join("b.npz"),
        &["--kernels", "40", "--points", "2000"],
    );
    // min(6, 5) modes: 3 per row, 2 rows, a 28-pixel footer.
    assert_eq!(png_size(&png), (360, 228));
    // With a kernel density the picture gets one more tile, the kernels by support radius;
    // the density is in the basis metadata.
    let npz = dir.path().join("d.npz");
    let region = ["--density-region", "sphere:0.2,0.15,0.15,0.2@2"];
    draw(
        "3",
        &npz,
        &["--kernels", "60", "--points", "3000", region[0], region[1]],
    );
    // 3 modes and the density tile: two rows (one row without it).
    assert_eq!(png_size(&png), (360, 228));
    let back = freeform::io::basis::load(&npz).unwrap();
    let options = back.metadata.options.expect("typed options");
    assert_eq!(options.density.regions.len(), 1);
    assert_eq!(options.density.regions[0].factor, 2.0);
    let o = freeform(&[
        "modes",
        "box:1,0.3,0.3",
        "--density-region",
        "sphere:0.2,0.15,0.15,0.2@0",
    ]);
    assert!(
        !o.status.success() && stderr(&o).contains("density region"),
        "{}",
        stderr(&o)
    );
    let o = freeform(&[
        "modes",
        "box:1,0.3,0.3",
        "--png",
        png.to_str().unwrap(),
        "--png-tile",
        "9x9",
    ]);
    assert!(
        !o.status.success() && stderr(&o).contains("--png-tile"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn a_fitted_camera_keeps_every_point_of_the_bounds_inside_the_image() {
    // Points spread through skewed bounds, every projection and several views.
    let b = Aabb {
        min: [-3.0, 0.5, 10.0],
        max: [2.0, 0.7, 14.0],
    };
    let pts: Vec<[f64; 3]> = (0..2000u64)
        .map(|i| {
            let t = [
                (i * 7919) % 1000,
                (i * 104_729) % 1000,
                (i * 1_299_709) % 1000,
            ]
            .map(|v| v as f64 / 999.0);
            [0, 1, 2].map(|k| b.min[k] + t[k] * (b.max[k] - b.min[k]))
        })
        .collect();
    for projection in [
        Projection::Orthographic,
        Projection::Perspective { fov_deg: 25.0 },
        Projection::Perspective { fov_deg: 120.0 },
    ] {
        for az in [-170.0, -30.0, 0.0, 45.0, 90.0] {
            for el in [-60.0, 0.0, 30.0, 85.0] {
                let cam = Camera::fit(
                    &b,
                    &CameraOptions {
                        azimuth_deg: az,
                        elevation_deg: el,
                        projection,
                        ..Default::default()
                    },
                );
                for (w, h) in [(640.0, 480.0), (100.0, 400.0)] {
                    for &p in &pts {
                        let (x, y, _) = cam.project(p, w, h).unwrap();
                        assert!(
                            x > 0.0 && x < w && y > 0.0 && y < h,
                            "{p:?} -> ({x}, {y}) in {w}x{h}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn a_cube_seen_face_on_orthographically_fills_its_square() {
    // A unit cube seen along -z: its front face covers the square the corners project to.
    let v: Vec<[f64; 3]> = (0..8)
        .map(|i| [0, 1, 2].map(|k| (i >> k & 1) as f64))
        .collect();
    let t: Vec<[u32; 3]> = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    let b = Aabb {
        min: [0.0; 3],
        max: [1.0; 3],
    };
    let cam = Camera::fit(
        &b,
        &CameraOptions {
            azimuth_deg: 0.0,
            elevation_deg: 0.0,
            projection: Projection::Orthographic,
            ..Default::default()
        },
    );
    let mut img = Image::new(200, 200, [255; 3]);
    let rect = img.rect();
    let item = Item::Triangles {
        positions: &v,
        triangles: &t,
        scalars: None,
        colour: [0, 100, 200],
    };
    // Flat shading: each face is one colour (smooth shading blends the corner normals).
    let flat = DrawOptions {
        smooth: false,
        ..Default::default()
    };
    draw(&mut img, rect, &cam, &[item], &flat).unwrap();
    let (x0, y0, _) = cam.project([0.0, 1.0, 1.0], 200.0, 200.0).unwrap();
    let (x1, y1, _) = cam.project([1.0, 0.0, 1.0], 200.0, 200.0).unwrap();
    let mut first = None;
    for y in 0..200 {
        for x in 0..200 {
            let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
            let inside = cx > x0 + 1e-9 && cx < x1 - 1e-9 && cy > y0 + 1e-9 && cy < y1 - 1e-9;
            let outside = cx < x0 - 1e-9 || cx > x1 + 1e-9 || cy < y0 - 1e-9 || cy > y1 + 1e-9;
            let c = img.pixel(x, y);
            if inside {
                // One flat face: one colour.
                assert_eq!(c, *first.get_or_insert(c), "pixel {x},{y}");
            } else if outside {
                assert_eq!(c, [255; 3], "pixel {x},{y}");
            }
        }
    }
}
