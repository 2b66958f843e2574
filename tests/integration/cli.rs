//! The `freeform` binary: the JSON report, and bad input giving a clear message, a non-zero
//! exit code, no panic and no output file.

use crate::common;
use common::freeform;
use std::path::Path;

#[test]
fn modes_json_report_has_every_key() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("b.npz");
    let o = freeform(&[
        "modes",
        "box:2,1,1",
        "--kernels",
        "200",
        "--modes",
        "6",
        "--points",
        "10000",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is JSON");
    for key in [
        "kernels",
        "points",
        "modes",
        "nnz_hessian",
        "nnz_mass",
        "solver",
        "eigenvalues",
        "max_relative_residual",
        "orthonormality_error",
        "reproducing_error",
        "timings_s",
        "peak_memory_bytes",
    ] {
        assert!(r.get(key).is_some(), "missing key {key}");
    }
    for key in [
        "sampling",
        "centers",
        "neighbors",
        "shape_functions",
        "assembly",
        "eigensolve",
        "total",
    ] {
        assert!(
            r["timings_s"][key].as_f64().is_some(),
            "missing timing {key}"
        );
    }
    assert_eq!(r["kernels"], 200);
    assert_eq!(r["modes"], 6);
    let ev = r["eigenvalues"].as_array().unwrap();
    assert_eq!(ev.len(), 7);
    assert!(
        ev.windows(2).all(|w| w[0].as_f64() <= w[1].as_f64()),
        "ascending"
    );
    assert!(r["reproducing_error"].as_f64().unwrap() < 1e-10);
    // Converged: no status key (it appears only when the solver stopped short).
    assert!(r["eigen"].get("status").is_none(), "{}", r["eigen"]);
    assert!(r["peak_memory_bytes"].as_u64().unwrap() > 0);
    // The estimate made before the run, and the memory it was checked against.
    let est = &r["memory_estimate"];
    assert_eq!(est["points"], 10_000);
    assert!(est["total_bytes"].as_u64().unwrap() > 0, "{est}");
    assert!(est["available_bytes"].as_u64().unwrap() > 0, "{est}");
    assert!(out.exists());
    let back = freeform::io::basis::load(&out).unwrap();
    assert_eq!(back.basis.modes(), 7);
    // The metadata reads back typed: the options that made the basis and the run's figures.
    let meta = &back.metadata;
    assert_eq!(meta.shape.as_deref(), Some("box:2,1,1"));
    let options = meta.options.as_ref().expect("typed options");
    assert_eq!((options.kernels, options.modes), (200, 6));
    assert_eq!(options.solver, freeform::precompute::SolverConfig::lobpcg());
    assert_eq!(back.raw_metadata["options"]["solver"], "lobpcg");
    assert_eq!(meta.points, r["points"].as_u64().map(|n| n as usize));
    assert_eq!(
        meta.max_relative_residual,
        r["max_relative_residual"].as_f64()
    );
    assert!(meta.extra.is_empty(), "{:?}", meta.extra);
}

fn assert_fails(args: &[&str], needle: &str, out: &Path) {
    let o = freeform(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{args:?} should fail");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    assert!(
        err.to_lowercase().contains(&needle.to_lowercase()),
        "{args:?}: expected `{needle}` in: {err}"
    );
    assert!(!out.exists(), "{args:?} left an output file behind");
}

#[test]
fn write_failures_name_the_target_and_keep_their_cause() {
    // A small basis written to `out`: exit code 1 and stderr expected.
    let modes_to = |out: &str| {
        let o = freeform(&[
            "modes",
            "box:1,1,1",
            "--kernels",
            "50",
            "--modes",
            "4",
            "--points",
            "2000",
            "--out",
            out,
        ]);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(1), "{err}");
        err
    };
    let dir = tempfile::tempdir().unwrap();
    // A missing directory: the error names the file asked for, not the temporary one
    // (temporary files are named `.b.npz.<pid>-<nanos>.tmp`).
    let target = dir.path().join("no/such/dir/b.npz");
    let err = modes_to(target.to_str().unwrap());
    assert!(
        err.contains(target.to_str().unwrap()) && !err.contains(".b.npz."),
        "{err}"
    );
    // A full disk: the cause stays ("No space left on device"), and nothing else is printed
    // (the zip writer's own drop used to add "ZipWriter drop failed: ..." to stderr).
    if Path::new("/dev/full").exists() {
        let err = modes_to("/dev/full");
        assert!(err.contains("No space left on device"), "{err}");
        assert!(
            !err.contains("ZipWriter") && !err.contains("panicked"),
            "{err}"
        );
    }
}

#[test]
fn bad_input_gives_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("b.npz");
    let o = out.to_str().unwrap();
    let missing = dir.path().join("missing.obj");
    let garbage = dir.path().join("garbage.stl");
    std::fs::write(&garbage, [0xffu8, 0x00, 0x13, 0x37, 0x42]).unwrap();
    let empty = dir.path().join("empty.ply");
    std::fs::write(&empty, b"").unwrap();
    let nan_ply = dir.path().join("nan.ply");
    std::fs::write(&nan_ply, "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\nnan 1 1\n").unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["modes", missing.to_str().unwrap()], "missing.obj"),
        (vec!["modes", "cylinder:1,2"], "unknown shape"),
        (vec!["modes", "box:1,0,1"], "box"),
        (vec!["modes", "box:1,-1,1"], "box"),
        (vec!["modes", "sphere:nan"], "sphere"),
        (vec!["modes", garbage.to_str().unwrap()], "garbage.stl"),
        (vec!["modes", empty.to_str().unwrap()], "empty.ply"),
        (vec!["modes", nan_ply.to_str().unwrap()], "nan.ply"),
        (
            vec!["modes", "box:1,1,1", "--kernels", "100", "--points", "50"],
            "points",
        ),
        (
            vec!["modes", "box:1,1,1", "--kernels", "100", "--modes", "99"],
            "modes",
        ),
        (vec!["modes", "box:1,1,1", "--youngs", "0"], "youngs"),
        (vec!["modes", "box:1,1,1", "--youngs", "-5e6"], "youngs"),
        (vec!["modes", "box:1,1,1", "--poisson", "0.5"], "poisson"),
        (vec!["modes", "box:1,1,1", "--poisson", "-1.2"], "poisson"),
        (vec!["modes", "box:1,1,1", "--density", "0"], "density"),
        (vec!["modes", "box:1,1,1", "--tol", "0"], "tol"),
        (
            vec![
                "modes",
                "box:1,1,1",
                "--kernels",
                "200",
                "--points",
                "8000",
                "--support",
                "0.3",
                "--support-neighbor",
                "1",
            ],
            "not covered",
        ),
        (vec!["modes", "box:1,1,1", "--spacing", "-0.1"], "spacing"),
        (vec!["modes", "box:1,1,1", "--spacing", "1e-9"], "spacing"),
        (
            vec!["modes", "box:1,1,1", "--kernel", "wendland"],
            "wendland",
        ),
    ];
    for (mut args, needle) in cases {
        args.extend(["--out", o]);
        assert_fails(&args, needle, &out);
    }
}

#[test]
fn run_writes_frames_and_a_json_summary_and_rejects_bad_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        "[simulation]\ndt = 0.01\nsteps = 4\ngravity = [0.0, -9.81, 0.0]\n\
         [solver]\ncubature = 300\n[output]\nevery = 2\nformats = [\"vtk\"]\n\
         [[object]]\nname = \"bar\"\nshape = \"box:1,0.2,0.2\"\n\
         basis = { kernels = 40, modes = 4, points = 2000 }\n\
         [[object.boundary]]\nregion = { half_space = { point = [0.1, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] } }\n",
    )
    .unwrap();
    let out = dir.path().join("frames");
    let o = freeform(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is JSON");
    assert_eq!(r["steps"], 4);
    assert_eq!(r["frames"], 3);
    let obj = &r["objects"][0];
    for key in [
        "step_ms_mean",
        "iterations_mean",
        "nonconverged_steps",
        "line_search_failures",
        "terms",
        "basis_cached",
    ] {
        assert!(!obj[key].is_null(), "missing {key}");
    }
    let steps = obj["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 4);
    for key in [
        "wall_ms",
        "iterations",
        "energy",
        "line_search_failed",
        "converged",
    ] {
        assert!(!steps[0][key].is_null(), "missing step key {key}");
    }
    assert!(out.join("bar.pvd").exists() && out.join("bar/bar_000004.vtp").exists());
    // The cache sits next to the scene; a second run uses it. --steps and --dt override the
    // scene's (the cache key holds neither: the basis is the same).
    let o = freeform(&[
        "run",
        scene.to_str().unwrap(),
        "--json",
        "--steps",
        "2",
        "--dt",
        "0.02",
    ]);
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["objects"][0]["basis_cached"], true);
    assert_eq!(r["steps"], 2);
    assert_eq!(r["objects"][0]["steps"].as_array().unwrap().len(), 2);
    for (flag, value, needle) in [
        ("--dt", "nan", "simulation.dt = NaN"),
        ("--dt=-0.01", "", "simulation.dt = -0.01"),
        ("--steps", "0", "simulation.steps must be at least 1"),
    ] {
        let mut args = vec!["run", scene.to_str().unwrap(), flag];
        if !value.is_empty() {
            args.push(value);
        }
        let o = freeform(&args);
        assert_eq!(o.status.code(), Some(1), "{flag} {value}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(needle), "{flag} {value}: {err}");
    }

    // A bad scene: exit 1, the line number, no frames.
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[simulation]\ndt = 0.01\nsteps = 4\nsubsteps = 2\n").unwrap();
    let out2 = dir.path().join("frames2");
    let o = freeform(&[
        "run",
        bad.to_str().unwrap(),
        "--out",
        out2.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("line 4") && err.contains("substeps"), "{err}");
    assert!(!out2.exists());
    let o = freeform(&["run", dir.path().join("missing.toml").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("missing.toml"));
}

#[test]
fn beam_reports_every_key_and_caches_the_fem_reference() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("fem");
    let args = [
        "beam",
        "bend",
        "--fem-resolution",
        "1",
        "--fem-order",
        "linear",
        "--kernels",
        "100",
        "--modes",
        "4",
        "--points",
        "5000",
        "--cubature",
        "500",
        "--json",
        "--cache",
        cache.to_str().unwrap(),
    ];
    let o = freeform(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is JSON");
    for key in [
        "test",
        "modes",
        "kernels",
        "cubature_points",
        "normalized_mse",
        "max_error",
        "precompute_s",
        "reduced_step_ms_mean",
        "fem_step_ms_mean",
        "fem_nodes",
        "fem_tets",
    ] {
        assert!(!r[key].is_null(), "missing {key}");
    }
    assert_eq!(r["fem_cached"], false);
    // The monitors count every reduced step and carry the basis conditioning.
    let m = &r["monitors"];
    assert_eq!(m["steps"], r["frames"], "{m}");
    assert_eq!(
        m["newton_nonconverged_steps"],
        r["reduced_nonconverged_steps"]
    );
    assert!(m["min_moment_rcond"].as_f64().unwrap() > 0.0, "{m}");
    assert!(r["warnings"].is_array());
    // 5 x 1 x 1 cubes, 6 tets each, 2 x 2 x 6 nodes.
    assert_eq!(r["fem_tets"], 30);
    assert_eq!(r["fem_nodes"], 24);
    let mse = r["normalized_mse"].as_f64().unwrap();
    assert!(mse.is_finite() && mse > 0.0);
    let o = freeform(&args);
    let r2: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r2["fem_cached"], true);
    assert_eq!(r2["normalized_mse"], r["normalized_mse"]);
    assert!(r.get("fit").is_none(), "no fit unless --fit: {r}");

    // --fit --frames: the basis fitting residual of the frames compared. The simulation's
    // frames are one choice of z in the same space, so the best fit is never worse.
    let fitted = [&args[..], &["--fit", "--frames", "50"]].concat();
    let o = freeform(&fitted);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r3: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let f = &r3["fit"];
    assert_eq!(r3["frames"], 50);
    assert_eq!(
        (&f["frames"], &f["nodes"], &f["columns"]),
        (&50.into(), &24.into(), &20.into())
    );
    let fit_mse = f["mean_squared_over_diagonal2"].as_f64().unwrap();
    let fit_abs = f["mean_abs_over_diagonal"].as_f64().unwrap();
    assert!(
        fit_mse >= 0.0 && fit_mse <= r3["normalized_mse"].as_f64().unwrap(),
        "{r3}"
    );
    assert!(fit_abs <= f["max_over_diagonal"].as_f64().unwrap(), "{f}");
    let text: Vec<&str> = fitted.iter().copied().filter(|a| *a != "--json").collect();
    let o = freeform(&text);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && out.contains("mean |r|^2/D^2"),
        "{out}"
    );
    let o = freeform(&[&args[..], &["--frames", "0"]].concat());
    assert_eq!(o.status.code(), Some(1));
}

#[test]
fn a_run_that_would_not_fit_is_refused_before_it_starts() {
    // An artificial limit of 10 MB: K = 2,000 with 100,000 points needs ~100 MB.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("b.npz");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_freeform"))
        .args([
            "modes",
            "box:2,1,1",
            "--kernels",
            "2000",
            "--points",
            "100000",
        ])
        .args(["--out", out.to_str().unwrap()])
        .env(freeform::precompute::memory::MEMORY_LIMIT_ENV, "0.01")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    for needle in [
        "GB",
        "0.0 GB is available",
        "FREEFORM_MEMORY_LIMIT=0.01",
        "fewer",
    ] {
        assert!(err.contains(needle), "missing {needle:?}: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists());
    // An unreadable limit is a clear error too.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_freeform"))
        .args([
            "modes",
            "box:2,1,1",
            "--kernels",
            "50",
            "--out",
            out.to_str().unwrap(),
        ])
        .env(freeform::precompute::memory::MEMORY_LIMIT_ENV, "lots")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("FREEFORM_MEMORY_LIMIT") && err.contains("GB"),
        "{err}"
    );
}
