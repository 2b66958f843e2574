//! `--strict` and the monitors: warnings become errors (exit code 1, no output passed off as
//! complete), and every report carries the same `monitors` keys.

use crate::common;
use common::freeform;
use std::path::Path;

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A 1 x 1 x 0.01 m plate with 400 kernels: the kernels across the thickness are nearly
/// coplanar, the smallest moment-matrix rcond is ~1e-5 (tests/integration/extremes.rs), below the
/// 1e-4 warning level but above the 1e-6 acceptance threshold.
const PLATE: [&str; 8] = [
    "modes",
    "box:1,1,0.01",
    "--kernels",
    "400",
    "--modes",
    "4",
    "--points",
    "40000",
];

#[test]
fn modes_warns_and_strict_refuses_to_write_the_basis() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plate.npz");
    let out_s = out.to_str().unwrap();
    let mut args = PLATE.to_vec();
    args.extend(["--json", "--out", out_s]);
    let ok = freeform(&args);
    assert!(ok.status.success(), "{}", text(&ok.stderr));
    let v: serde_json::Value = serde_json::from_slice(&ok.stdout).unwrap();
    let warnings = v["warnings"].as_array().unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("reciprocal condition number")),
        "{warnings:?}"
    );
    let m = &v["monitors"];
    let rcond = m["min_moment_rcond"].as_f64().unwrap();
    assert!(rcond > 1e-6 && rcond < 1e-4, "{m}");
    assert_eq!(m["eigen_restarts"], v["eigen"]["restarts"]);
    assert_eq!(m["eigen_locked"], v["eigen"]["locked"]);
    assert!(m["steps"].is_null(), "no simulation in modes: {m}");
    assert!(out.exists());
    std::fs::remove_file(&out).unwrap();

    args.push("--strict");
    let strict = freeform(&args);
    assert_eq!(strict.status.code(), Some(1));
    let err = text(&strict.stderr);
    assert!(
        err.contains("strict mode") && err.contains("reciprocal condition number"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists(), "strict mode must not write the basis");

    // A healthy basis passes --strict.
    let good = dir.path().join("good.npz");
    let r = freeform(&[
        "modes",
        "box:2,1,1",
        "--kernels",
        "100",
        "--modes",
        "4",
        "--points",
        "5000",
        "--strict",
        "--out",
        good.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    assert!(good.exists());
}

fn write_scene(dir: &Path, max_iter: usize, youngs: f64) -> std::path::PathBuf {
    // A bar falling under gravity, held at its left end, with a Newton cap of `max_iter`:
    // 1 iteration cannot reach the 1e-9 tolerance, so steps are reported as not converged.
    // The soft bar needs time to fall and crush. The free basis, whose crushed root inverts
    // cubature points (the monitors, not the basis, are under test here).
    let steps = if youngs < 1e4 { 50 } else { 5 };
    let scene = format!(
        r#"
[simulation]
dt = 0.01
steps = {steps}
gravity = [0.0, -9.81, 0.0]

[solver]
hessian = "newton"
tol = 1e-9
max_iter = {max_iter}
cubature = 500

[cache]
enabled = false

[[object]]
name = "bar"
shape = "box:1,0.2,0.2"
material = {{ youngs = {youngs:e}, poisson = 0.4, density = 1000.0 }}
basis = {{ kernels = 60, modes = 4, points = 3000, boundaries = "free" }}

[[object.boundary]]
region = {{ half_space = {{ point = [0.1, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] }} }}
motion = "fixed"
"#
    );
    let path = dir.join(format!("bar{max_iter}_{youngs:e}.toml"));
    std::fs::write(&path, scene).unwrap();
    path
}

#[test]
fn run_reports_monitors_and_strict_stops_at_the_first_failed_step() {
    let dir = tempfile::tempdir().unwrap();
    // Converging run: monitors count every step, no warnings, --strict passes.
    let scene = write_scene(dir.path(), 100, 1e5);
    let out = dir.path().join("ok");
    let r = freeform(&[
        "run",
        scene.to_str().unwrap(),
        "--json",
        "--strict",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let m = &v["objects"][0]["monitors"];
    assert_eq!(m["steps"], 5, "{m}");
    assert_eq!(m["newton_nonconverged_steps"], 0, "{m}");
    assert!(m["min_moment_rcond"].as_f64().unwrap() > 1e-4, "{m}");
    assert!(m["min_det"].as_f64().unwrap() > 0.9, "{m}");
    assert!(out.join("bar.pvd").exists());

    // Capped at one iteration: without --strict the run completes and reports 5 failures.
    let scene = write_scene(dir.path(), 1, 1e5);
    let r = freeform(&["run", scene.to_str().unwrap(), "--json"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(v["objects"][0]["monitors"]["newton_nonconverged_steps"], 5);
    assert_eq!(v["warnings"].as_array().unwrap().len(), 5);

    // With --strict it stops at step 1 with the reason.
    let out = dir.path().join("strict");
    let r = freeform(&[
        "run",
        scene.to_str().unwrap(),
        "--strict",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.status.code(), Some(1));
    let err = text(&r.stderr);
    assert!(
        err.contains("strict mode") && err.contains("step 1 did not converge"),
        "{err}"
    );
    // The frames written before the stop stay, and the collection lists exactly them (it is
    // written as frames land): the stopped run opens in ParaView.
    let pvd = std::fs::read_to_string(out.join("bar.pvd")).unwrap();
    let vtp = std::fs::read_dir(out.join("bar"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.path().extension().is_some_and(|x| x == "vtp"))
        })
        .count();
    assert_eq!(pvd.matches("<DataSet").count(), vtp, "{pvd}");

    // A bar of E = 1e3 Pa crushed by its own weight (rho g L / E ~ 10): inverted cubature
    // points are warned about once, and counted in min_det.
    let scene = write_scene(dir.path(), 100, 1e3);
    let r = freeform(&["run", scene.to_str().unwrap(), "--json"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let v: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let warnings = v["warnings"].as_array().unwrap();
    let inverted: Vec<_> = warnings
        .iter()
        .filter(|w| w.as_str().unwrap().contains("inverted"))
        .collect();
    assert_eq!(inverted.len(), 1, "{warnings:?}");
    assert!(v["objects"][0]["monitors"]["min_det"].as_f64().unwrap() <= 0.0);
}

/// A strict world stops for good at its first warning: later steps are refused with the same
/// warnings and move nothing, in the library itself (so C and Python behave alike).
#[test]
fn a_strict_world_refuses_every_step_after_it_stopped() {
    use freeform::scene::{RunSettings, Scene, World};
    let dir = tempfile::tempdir().unwrap();
    // One Newton iteration cannot reach 1e-9: step 1 warns, so strict mode stops there.
    let scene = Scene::load(&write_scene(dir.path(), 1, 1e5)).unwrap();
    let settings = RunSettings {
        strict: true,
        ..RunSettings::for_scene_file(dir.path().join("x.toml").as_path())
    };
    let mut world = World::new(&scene, &settings, &freeform::progress::Silent).unwrap();
    let first = world.step().unwrap_err();
    let freeform::Error::Strict { warnings } = &first else {
        panic!("expected a strict-mode stop, got {first}");
    };
    // The warning is typed: which object, which step, how far from converged.
    let freeform::report::Warning::NotConverged {
        object,
        step,
        iterations,
        ..
    } = &warnings[0]
    else {
        panic!("expected a step that did not converge, got {}", warnings[0]);
    };
    assert_eq!((object.as_str(), *step, *iterations), ("bar", 1, 1));
    assert_eq!(first.kind(), freeform::ErrorKind::Strict);
    assert!(world.stopped());
    let (time, z) = (world.time(), world.object(0).sim().z().to_vec());
    for _ in 0..2 {
        match world.step() {
            Err(freeform::Error::Strict { warnings: again }) => assert_eq!(&again, warnings),
            other => panic!("a stopped world stepped: {other:?}"),
        }
    }
    assert_eq!(world.time().to_bits(), time.to_bits());
    assert_eq!(world.object(0).sim().z(), z.as_slice());
    assert_eq!(world.object(0).sim().steps(), 1);
}
