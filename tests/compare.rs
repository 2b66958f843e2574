//! `freeform compare`, `freeform export` and `freeform modes --from-matrices` (default build:
//! native LOBPCG against the dense oracle; the SLEPc variants are in tests/slepc_cli.rs).

use std::process::{Command, Output};

fn freeform(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_freeform"))
        .args(args)
        .output()
        .expect("run freeform")
}

fn json(o: &Output) -> serde_json::Value {
    assert!(
        o.status.success(),
        "exit {:?}: {}",
        o.status,
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).expect("stdout is JSON")
}

const SMALL: [&str; 7] = [
    "box:2,1,1",
    "--kernels",
    "150",
    "--modes",
    "6",
    "--points",
    "8000",
];

#[test]
fn compare_native_against_dense_reports_every_key() {
    let mut args = vec!["compare"];
    args.extend(SMALL);
    args.extend(["--dense", "--json"]);
    let r = json(&freeform(&args));
    let solvers = r["solvers"].as_array().expect("solvers array");
    // Without SLEPc (default build) the list is native + dense; with it, the default SLEPc
    // set is the default preset (lobpcg-gamg) and the direct one (ks-sinvert).
    let expected = if cfg!(feature = "slepc") { 4 } else { 2 };
    assert_eq!(solvers.len(), expected, "{solvers:?}");
    assert_eq!(r["max_iter"], 1000);
    for s in solvers {
        for key in [
            "solver",
            "time_s",
            "iterations",
            "max_relative_residual",
            "orthonormality_error",
        ] {
            assert!(!s[key].is_null(), "missing {key} in {s}");
        }
        assert!(s["max_relative_residual"].as_f64().unwrap() <= 1e-8 * 10.0);
    }
    assert_eq!(solvers[0]["solver"], "lobpcg");
    assert!(solvers.iter().any(|s| s["solver"] == "dense"));
    // The agreement targets. LOBPCG stops at residual 1e-8 relative to ||H||; the
    // eigenvalue error is then ~ residual^2 x ||H|| / lambda (1e-13 here) and the angle
    // ~ residual x ||H|| / gap (1e-7 here); both far below the targets.
    let diff = r["max_eigenvalue_rel_diff"].as_f64().unwrap();
    let angle = r["max_subspace_angle"].as_f64().unwrap();
    assert!(diff < 1e-8, "eigenvalue diff {diff}");
    assert!(angle < 1e-6, "subspace angle {angle}");
    // The comparison is not vacuous: the dense entry has its own (non-identical) figures.
    let dense = solvers.iter().find(|s| s["solver"] == "dense").unwrap();
    assert!(dense["eigenvalue_rel_diff"].as_f64().unwrap() > 0.0);
}

#[test]
fn export_then_solve_from_matrices_reproduces_the_modes() {
    let dir = tempfile::tempdir().unwrap();
    let mats = dir.path().join("mats");
    let mut args = vec!["export"];
    args.extend(SMALL);
    args.extend(["--json", "--out", mats.to_str().unwrap()]);
    let e = json(&freeform(&args));
    for f in ["hessian.mtx", "mass.mtx", "hessian.petsc", "mass.petsc"] {
        assert!(mats.join(f).is_file(), "{f} missing: {e}");
    }
    // The same problem through `modes` directly and through the exported files: the files are
    // written with 17 digits, so the matrices (and the deterministic LOBPCG) are identical.
    let basis = dir.path().join("b.npz");
    let mut args = vec!["modes"];
    args.extend(SMALL);
    args.extend(["--json", "--out", basis.to_str().unwrap()]);
    let direct = json(&freeform(&args));
    let vecs = dir.path().join("v.mtx");
    let from = json(&freeform(&[
        "modes",
        "--from-matrices",
        mats.to_str().unwrap(),
        "--modes",
        "6",
        "--json",
        "--out",
        vecs.to_str().unwrap(),
    ]));
    assert_eq!(from["kernels"], 150);
    let a = direct["eigenvalues"].as_array().unwrap();
    let b = from["eigenvalues"].as_array().unwrap();
    assert_eq!(a.len(), 7);
    for (x, y) in a.iter().zip(b) {
        let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
        assert!((x - y).abs() <= 1e-12 * y.abs().max(1.0), "{x} vs {y}");
    }
    let text = std::fs::read_to_string(&vecs).unwrap();
    assert!(text.starts_with("%%MatrixMarket matrix array real general"));
    assert!(text.contains("\n150 7\n"));
}

#[test]
fn bad_matrix_directory_and_missing_slepc_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("hessian.mtx"), "not a matrix\n").unwrap();
    let o = freeform(&["modes", "--from-matrices", dir.path().to_str().unwrap()]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("hessian.mtx") && err.contains("MatrixMarket"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    if cfg!(not(feature = "slepc")) {
        let mut args = vec!["modes"];
        args.extend(SMALL);
        args.extend(["--solver", "slepc"]);
        let o = freeform(&args);
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("--features slepc"), "{err}");
    }
}
