//! 3D Gaussian splats in and out (issue #16, part 1): a 3DGS PLY round-trips with every
//! property (extras and `f_rest` included) equal to float32 rounding; a deformed frame's
//! covariances are F Sigma F^T (to 1e-6 relative after float32 output) and stay positive
//! definite; SH colour turns with the material; the deformation gradient matches finite
//! differences of the map; bad files name the file, the element and the property and leave
//! nothing written.

use crate::common::no_cache;
use freeform::io::splat::{
    read_splats, read_splats_with_report, write_splats, write_splats_moved, MovedSplats, PlyType,
    Splats,
};
use freeform::linalg3::{mul, quat_to_matrix, sym_eig3, transpose, Mat3};
use freeform::progress::Silent;
use freeform::random::SplitMix64;
use freeform::scene::{
    run, FrameObserver, FrameWriter, ObjectSpec, OutputSettings, RunSettings, Scene, SceneBuilder,
    World,
};
use freeform::sim::gaussian::{covariance, deform_splats, sh_basis};
use std::path::{Path, PathBuf};

/// Deterministic numbers in [-1, 1) from the library's generator (these tests moved to it
/// from their own linear congruential one: other synthetic splats, the same checks).
fn signed(rng: &mut SplitMix64) -> f64 {
    rng.uniform(-1.0, 1.0)
}

/// The properties of the synthetic file, in order: the 3DGS layout with SH degree 3, then an
/// `int` and a `double` extra.
fn header_names() -> Vec<(String, &'static str)> {
    let mut p: Vec<(String, &'static str)> = Vec::new();
    for n in [
        "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
    ] {
        p.push((n.into(), "float"));
    }
    for k in 0..45 {
        p.push((format!("f_rest_{k}"), "float"));
    }
    for n in [
        "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
    ] {
        p.push((n.into(), "float"));
    }
    p.push(("segment".into(), "int"));
    p.push(("confidence".into(), "double"));
    p
}

/// One row of values per splat (as f64; floats already float32), in header order: a grid of
/// 12^3 splats 0.05 m apart in a 0.55 m cube, random unit quaternions, log-scales near -3.5.
fn synthetic_rows(n_side: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = SplitMix64::new(seed);
    let f32r = |v: f64| v as f32 as f64;
    let mut rows = Vec::new();
    for i in 0..n_side {
        for j in 0..n_side {
            for k in 0..n_side {
                let mut r = vec![
                    f32r(i as f64 * 0.05 + 0.01 * signed(&mut rng)),
                    f32r(j as f64 * 0.05 + 0.01 * signed(&mut rng)),
                    f32r(k as f64 * 0.05 + 0.01 * signed(&mut rng)),
                    0.0,
                    0.0,
                    0.0,
                ];
                for _ in 0..48 {
                    r.push(f32r(signed(&mut rng)));
                }
                r.push(f32r(3.0 * signed(&mut rng)));
                for _ in 0..3 {
                    r.push(f32r(-3.5 + 0.8 * signed(&mut rng)));
                }
                let q = [
                    signed(&mut rng),
                    signed(&mut rng),
                    signed(&mut rng),
                    signed(&mut rng),
                ];
                let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                r.extend(q.iter().map(|v| f32r(v / n)));
                r.push(((i * 7 + j * 3 + k) % 11) as f64 - 5.0);
                r.push(signed(&mut rng) * 1e-3 + 0.5);
                rows.push(r);
            }
        }
    }
    rows
}

/// Write rows as a binary little-endian splat PLY with the header of [`header_names`].
fn write_rows(path: &Path, rows: &[Vec<f64>], names: &[(String, &str)]) {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\n",
        rows.len()
    );
    for (n, t) in names {
        out.push_str(&format!("property {t} {n}\n"));
    }
    out.push_str("end_header\n");
    let mut bytes = out.into_bytes();
    for r in rows {
        for (v, (_, t)) in r.iter().zip(names) {
            match *t {
                "float" => bytes.extend_from_slice(&(*v as f32).to_le_bytes()),
                "int" => bytes.extend_from_slice(&(*v as i32).to_le_bytes()),
                "double" => bytes.extend_from_slice(&v.to_le_bytes()),
                _ => unreachable!(),
            }
        }
    }
    std::fs::write(path, bytes).unwrap();
}

/// Every property of splat `i` by name (f64).
fn values(s: &Splats, i: usize) -> Vec<(String, f64)> {
    let per = s.rest_per_splat();
    let mut out = Vec::new();
    for (name, _) in s.properties() {
        let v = match name {
            "x" => s.means[i][0],
            "y" => s.means[i][1],
            "z" => s.means[i][2],
            "opacity" => s.opacities[i],
            n if n.starts_with("f_dc_") => s.sh_dc[i][n[5..].parse::<usize>().unwrap()],
            n if n.starts_with("f_rest_") => s.sh_rest[i * per + n[7..].parse::<usize>().unwrap()],
            n if n.starts_with("scale_") => s.log_scales[i][n[6..].parse::<usize>().unwrap()],
            n if n.starts_with("rot_") => s.rotations[i][n[4..].parse::<usize>().unwrap()],
            n => s.extras.iter().find(|e| e.name == n).unwrap().values[i],
        };
        out.push((name.to_string(), v));
    }
    out
}

/// Equal to float32 rounding: within 1 ulp of float32 (plus 1e-7 absolute, for values that
/// round through 0).
fn f32_equal(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1.2e-7 * a.abs().max(b.abs()) + 1e-7
}

/// A scene with one splat object read from `file` (in `dir`), no gravity, frames in PLY.
fn splat_scene(file: &str, rotate_sh: bool) -> Scene {
    SceneBuilder::new(0.01, 1)
        .cache(no_cache())
        .output(OutputSettings {
            every: 1,
            formats: vec![freeform::scene::Format::Ply],
            rotate_splat_sh: rotate_sh,
            ..OutputSettings::default()
        })
        .object(
            ObjectSpec::new("splats", file)
                .unwrap()
                .kernels(80)
                .modes(4),
        )
        .build()
        .unwrap()
}

fn settings(dir: &Path) -> RunSettings {
    RunSettings {
        base_dir: dir.to_path_buf(),
        out: Some(dir.join("out")),
        strict: false,
    }
}

fn relative(a: &Mat3, b: &Mat3) -> f64 {
    let mut d = 0.0f64;
    let mut n = 0.0f64;
    for r in 0..3 {
        for c in 0..3 {
            d = d.max((a[r][c] - b[r][c]).abs());
            n = n.max(b[r][c].abs());
        }
    }
    d / n
}

#[test]
fn a_splat_file_round_trips_with_every_property() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.ply");
    let names = header_names();
    let rows = synthetic_rows(5, 1);
    write_rows(&input, &rows, &names);
    let (s, report) = read_splats_with_report(&input).unwrap();
    assert_eq!(report.normalized_rotations, 0);
    assert_eq!(s.sh_degree, 3);
    assert_eq!(s.len(), rows.len());
    let types: Vec<(String, PlyType)> = s.properties().map(|(n, t)| (n.into(), t)).collect();
    assert_eq!(types.len(), names.len());
    assert_eq!(types[62], ("segment".to_string(), PlyType::Int));
    assert_eq!(types[63], ("confidence".to_string(), PlyType::Double));
    for (i, row) in rows.iter().enumerate() {
        let got = values(&s, i);
        for ((name, v), ((want_name, _), want)) in got.iter().zip(names.iter().zip(row)) {
            assert_eq!(name, want_name);
            assert!(f32_equal(*v, *want), "splat {i} {name}: {v} vs {want}");
        }
    }
    // A plain copy keeps every property (quaternions renormalized, so to float32 rounding).
    let copy = dir.path().join("copy.ply");
    write_splats(&copy, &s).unwrap();
    let again = read_splats(&copy).unwrap();
    assert_eq!(again.extras, s.extras);
    assert_eq!(again.sh_rest, s.sh_rest);
    assert_eq!(again.means, s.means);
    for (i, row) in rows.iter().enumerate() {
        for ((name, v), want) in values(&again, i).iter().zip(row) {
            assert!(f32_equal(*v, *want), "copy splat {i} {name}: {v} vs {want}");
        }
    }
    // The rest frame through the deformation (F = I) equals the input to float32 rounding.
    let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let f = vec![id; s.len()];
    let d = deform_splats(&f, &s.log_scales, &s.rotations, &s.sh_rest, 3, true);
    let rest = dir.path().join("rest.ply");
    let moved = MovedSplats {
        means: s.means.clone(),
        log_scales: d.log_scales,
        rotations: d.rotations,
        sh_rest: d.sh_rest,
    };
    write_splats_moved(&rest, &s, &moved).unwrap();
    let back = read_splats(&rest).unwrap();
    for (i, row) in rows.iter().enumerate() {
        for ((name, v), want) in values(&back, i).iter().zip(row) {
            assert!(f32_equal(*v, *want), "rest splat {i} {name}: {v} vs {want}");
        }
    }
}

#[test]
fn a_scene_writes_its_rest_frame_equal_to_the_input_and_a_sheared_frame_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let names = header_names();
    let rows = synthetic_rows(12, 2);
    write_rows(&dir.path().join("g.ply"), &rows, &names);
    let input = read_splats(&dir.path().join("g.ply")).unwrap();
    let scene = splat_scene("g.ply", true);
    let mut world = World::new(&scene, &settings(dir.path()), &Silent).unwrap();
    let out = dir.path().join("out");
    let mut writer = FrameWriter::new(&out, &scene.output.formats).unwrap();
    writer.frame(&world, 0).unwrap();
    let frame0 = read_splats(&out.join("splats/splats_000000.ply")).unwrap();
    for (i, row) in rows.iter().enumerate() {
        for ((name, v), want) in values(&frame0, i).iter().zip(row) {
            assert!(
                f32_equal(*v, *want),
                "frame 0 splat {i} {name}: {v} vs {want}"
            );
        }
    }

    // An exact affine map x = A X + b through the constant mode: W_0 is constant (RKPM
    // reproduces constants), so z_0 = [A - I, b] / W_0 moves every point affinely.
    let obj = world.object(0);
    let w0 = obj.basis().weights(&[[0.2, 0.2, 0.2]]).unwrap().values[0];
    let a = [[1.0, 0.6, 0.0], [0.0, 1.1, -0.3], [0.2, 0.0, 0.8]];
    let b = [0.1, -0.2, 0.05];
    let layout = obj.sim().layout();
    let mut z = vec![0.0; layout.dofs()];
    for r in 0..3 {
        for c in 0..3 {
            z[layout.index(r, 0, c)] = (a[r][c] - if r == c { 1.0 } else { 0.0 }) / w0;
        }
        z[layout.index(r, 0, 3)] = b[r] / w0;
    }
    let zdot = vec![0.0; z.len()];
    world.set_state(0, &z, &zdot).unwrap();
    writer.frame(&world, 1).unwrap();
    let frame1 = read_splats(&out.join("splats/splats_000001.ply")).unwrap();
    let mut worst = 0.0f64;
    for i in 0..input.len() {
        let x = input.means[i];
        for r in 0..3 {
            let want = a[r][0] * x[0] + a[r][1] * x[1] + a[r][2] * x[2] + b[r];
            assert!((frame1.means[i][r] - want).abs() < 1e-6, "mean {i}");
        }
        let sigma = covariance(&input.log_scales[i], &input.rotations[i]);
        let want = mul(&mul(&a, &sigma), &transpose(&a));
        let got = covariance(&frame1.log_scales[i], &frame1.rotations[i]);
        worst = worst.max(relative(&got, &want));
        // Everything else is copied.
        assert_eq!(frame1.opacities[i], input.opacities[i]);
        assert_eq!(frame1.sh_dc[i], input.sh_dc[i]);
    }
    assert!(
        worst < 1e-6,
        "sheared covariance relative error {worst:.2e}"
    );
    assert_eq!(frame1.extras, input.extras);
}

#[test]
fn sh_colour_turns_with_a_rotation_and_can_be_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let rows = synthetic_rows(12, 3);
    write_rows(&dir.path().join("g.ply"), &rows, &header_names());
    let input = read_splats(&dir.path().join("g.ply")).unwrap();
    for rotate in [true, false] {
        let scene = splat_scene("g.ply", rotate);
        let mut world = World::new(&scene, &settings(dir.path()), &Silent).unwrap();
        let obj = world.object(0);
        let w0 = obj.basis().weights(&[[0.2, 0.2, 0.2]]).unwrap().values[0];
        let rot = quat_to_matrix(&[0.8, 0.2, -0.4, 0.4]);
        let layout = obj.sim().layout();
        let mut z = vec![0.0; layout.dofs()];
        for r in 0..3 {
            for c in 0..3 {
                z[layout.index(r, 0, c)] = (rot[r][c] - if r == c { 1.0 } else { 0.0 }) / w0;
            }
        }
        world.set_state(0, &z, &vec![0.0; z.len()]).unwrap();
        let out = dir.path().join(format!("out{rotate}"));
        let mut writer = FrameWriter::new(&out, &scene.output.formats)
            .unwrap()
            .rotate_splat_sh(rotate);
        writer.frame(&world, 1).unwrap();
        let frame = read_splats(&out.join("splats/splats_000001.ply")).unwrap();
        if !rotate {
            assert_eq!(frame.sh_rest, input.sh_rest);
            continue;
        }
        // Colour seen from d now = colour seen from R^T d before, per degree and channel.
        let d = [0.48, -0.6, 0.64];
        let rt = transpose(&rot);
        let back = [0, 1, 2].map(|r| rt[r][0] * d[0] + rt[r][1] * d[1] + rt[r][2] * d[2]);
        let eval = |c: &[f64], l: usize, dir: &[f64; 3]| {
            let mut y = [0.0; 7];
            sh_basis(l, dir, &mut y[..2 * l + 1]);
            y.iter().zip(c).map(|(a, b)| a * b).sum::<f64>()
        };
        for i in 0..input.len() {
            for ch in 0..3 {
                for l in 1..=3 {
                    let off = i * 45 + ch * 15 + l * l - 1;
                    let n = 2 * l + 1;
                    let got = eval(&frame.sh_rest[off..off + n], l, &d);
                    let want = eval(&input.sh_rest[off..off + n], l, &back);
                    assert!(
                        (got - want).abs() < 1e-5,
                        "splat {i} l {l}: {got} vs {want}"
                    );
                }
            }
        }
    }
}

#[test]
fn covariances_stay_positive_definite_under_large_random_affine_maps() {
    let dir = tempfile::tempdir().unwrap();
    let rows = synthetic_rows(6, 4);
    let path = dir.path().join("g.ply");
    write_rows(&path, &rows, &header_names());
    let s = read_splats(&path).unwrap();
    let mut rng = SplitMix64::new(9);
    let f: Vec<Mat3> = (0..s.len())
        .map(|i| {
            let mut m = [[0.0; 3]; 3];
            for row in m.iter_mut() {
                for v in row.iter_mut() {
                    *v = 5.0 * signed(&mut rng);
                }
            }
            if i % 7 == 0 {
                m[2] = [0.0; 3]; // flattened
            }
            m
        })
        .collect();
    let d = deform_splats(&f, &s.log_scales, &s.rotations, &s.sh_rest, 3, true);
    assert!(d.clamped >= s.len() / 7);
    let out = dir.path().join("affine.ply");
    let moved = MovedSplats {
        means: s.means.clone(),
        log_scales: d.log_scales,
        rotations: d.rotations,
        sh_rest: d.sh_rest,
    };
    write_splats_moved(&out, &s, &moved).unwrap();
    let back = read_splats(&out).unwrap();
    for (i, fi) in f.iter().enumerate() {
        let c = covariance(&back.log_scales[i], &back.rotations[i]);
        let (lam, _) = sym_eig3(&c);
        assert!(lam.iter().all(|&l| l > 0.0), "splat {i}: {lam:?}");
        if i % 7 != 0 {
            let sigma = covariance(&s.log_scales[i], &s.rotations[i]);
            let want = mul(&mul(fi, &sigma), &transpose(fi));
            assert!(relative(&c, &want) < 1e-6, "splat {i}");
        }
    }
}

#[test]
fn deformation_gradient_matches_finite_differences_of_the_map() {
    let dir = tempfile::tempdir().unwrap();
    write_rows(
        &dir.path().join("g.ply"),
        &synthetic_rows(12, 5),
        &header_names(),
    );
    let scene = splat_scene("g.ply", true);
    let mut world = World::new(&scene, &settings(dir.path()), &Silent).unwrap();
    let obj = world.object(0);
    let layout = obj.sim().layout();
    let mut rng = SplitMix64::new(17);
    let z: Vec<f64> = (0..layout.dofs())
        .map(|_| 0.05 * signed(&mut rng))
        .collect();
    world.set_state(0, &z, &vec![0.0; z.len()]).unwrap();
    let obj = world.object(0);
    let points: Vec<[f64; 3]> = (0..20)
        .map(|_| {
            [
                0.275 + 0.2 * signed(&mut rng),
                0.275 + 0.2 * signed(&mut rng),
                0.275 + 0.2 * signed(&mut rng),
            ]
        })
        .collect();
    let w = obj.basis().weights(&points).unwrap();
    let f = freeform::sim::deformation::deformation_gradients(layout, &z, &points, &w);
    let h = 1e-5;
    for (i, p) in points.iter().enumerate() {
        for c in 0..3 {
            let (mut a, mut b) = (*p, *p);
            a[c] += h;
            b[c] -= h;
            let wab = obj.basis().weights(&[a, b]).unwrap();
            let x = freeform::sim::deformation::map_points(layout, &z, &[a, b], &wab);
            for r in 0..3 {
                let fd = (x[0][r] - x[1][r]) / (2.0 * h);
                assert!(
                    (fd - f[i][r][c]).abs() < 1e-6 * (1.0 + f[i][r][c].abs()),
                    "point {i} F[{r}][{c}] = {} vs {fd}",
                    f[i][r][c]
                );
            }
        }
    }
}

/// The synthetic file with one change: a property removed, or a value replaced.
fn bad_file(
    dir: &Path,
    name: &str,
    edit: impl Fn(&mut Vec<(String, &'static str)>, &mut Vec<Vec<f64>>),
) -> PathBuf {
    let mut names = header_names();
    let mut rows = synthetic_rows(3, 6);
    edit(&mut names, &mut rows);
    let path = dir.join(name);
    write_rows(&path, &rows, &names);
    path
}

#[test]
fn bad_splat_files_name_file_element_and_property_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let rot2 = header_names()
        .iter()
        .position(|(n, _)| n == "rot_2")
        .unwrap();
    let scale1 = header_names()
        .iter()
        .position(|(n, _)| n == "scale_1")
        .unwrap();
    let rot0 = header_names()
        .iter()
        .position(|(n, _)| n == "rot_0")
        .unwrap();
    let cases: Vec<(PathBuf, Vec<&str>)> = vec![
        (
            bad_file(dir.path(), "missing.ply", |names, rows| {
                names.remove(rot2);
                for r in rows.iter_mut() {
                    r.remove(rot2);
                }
            }),
            vec!["missing.ply", "`vertex`", "`rot_2`"],
        ),
        (
            bad_file(dir.path(), "zero_quat.ply", |_, rows| {
                for k in 0..4 {
                    rows[4][rot0 + k] = 0.0;
                }
            }),
            vec!["zero_quat.ply", "`vertex` 4", "rot_0..rot_3", "zero"],
        ),
        (
            bad_file(dir.path(), "nan_scale.ply", |_, rows| {
                rows[7][scale1] = f64::NAN
            }),
            vec!["nan_scale.ply", "`vertex` 7", "`scale_1`", "not finite"],
        ),
        (
            bad_file(dir.path(), "rest_gap.ply", |names, rows| {
                names.remove(9 + 17);
                for r in rows.iter_mut() {
                    r.remove(9 + 17);
                }
            }),
            vec!["rest_gap.ply", "`vertex`", "f_rest"],
        ),
    ];
    for (path, needles) in &cases {
        let e = read_splats(path).unwrap_err().to_string();
        for n in needles {
            assert!(e.contains(n), "{}: `{e}` lacks `{n}`", path.display());
        }
        // A scene with this file fails at setup and writes no frame.
        let name = path.file_name().unwrap().to_str().unwrap();
        let out = dir.path().join(format!("out_{name}"));
        let scene = splat_scene(name, true);
        let r = run(
            &scene,
            &RunSettings {
                base_dir: dir.path().to_path_buf(),
                out: Some(out.clone()),
                strict: false,
            },
            &Silent,
        );
        let msg = r.unwrap_err().to_string();
        assert!(msg.contains(name), "{msg}");
        assert!(!out.exists() || std::fs::read_dir(&out).unwrap().next().is_none());
    }
    // A moved set of the wrong length is refused before anything is written.
    let good = bad_file(dir.path(), "good.ply", |_, _| {});
    let s = read_splats(&good).unwrap();
    let target = dir.path().join("frame.ply");
    let moved = MovedSplats {
        means: s.means[1..].to_vec(),
        log_scales: s.log_scales.clone(),
        rotations: s.rotations.clone(),
        sh_rest: None,
    };
    assert!(write_splats_moved(&target, &s, &moved).is_err());
    assert!(!target.exists());
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty());
}
