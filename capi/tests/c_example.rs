//! Compiles `examples/basis.c` against the static library with the system C compiler, runs it,
//! and checks its output against the Rust library on the same input.

use freeform::material::MaterialField;
use freeform::precompute::sampling::IntegrationPoints;
use freeform::precompute::{BasisOptions, Problem};
use freeform::progress::Silent;

mod common;
use common::compile_and_run;

/// The same problem as examples/basis.c: 20 x 10 x 10 cell centres of a 2 x 1 x 1 box.
fn rust_eigenvalues() -> Vec<f64> {
    let h = 0.1;
    let mut points = Vec::new();
    for k in 0..10 {
        for j in 0..10 {
            for i in 0..20 {
                points.push([
                    (i as f64 + 0.5) * h,
                    (j as f64 + 0.5) * h,
                    (k as f64 + 0.5) * h,
                ]);
            }
        }
    }
    let n = points.len();
    let material =
        MaterialField::from_arrays(vec![5e6; n], vec![0.45; n], vec![1000.0; n]).unwrap();
    let opts = BasisOptions {
        kernels: 120,
        modes: 6,
        ..BasisOptions::default()
    };
    let ip = IntegrationPoints {
        points,
        volumes: vec![h * h * h; n],
    };
    Problem::from_points(ip, material, &opts, &Silent)
        .and_then(|p| p.solve(&Silent))
        .unwrap()
        .basis
        .eigenvalues
}

#[test]
fn c_example_compiles_runs_and_matches_the_rust_library() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = compile_and_run("basis", dir.path(), &[]);
    assert!(stdout.lines().last() == Some("OK"), "{stdout}");
    // The error paths printed their codes and messages.
    assert!(
        stdout.contains("bad options: code 2: invalid kernels"),
        "{stdout}"
    );
    assert!(stdout.contains("small buffer: code 5"), "{stdout}");
    // Eigenvalues through C (printed with 13 significant digits) equal the Rust library's.
    let line = stdout
        .lines()
        .find(|l| l.starts_with("eigenvalues"))
        .expect("eigenvalue line");
    let c: Vec<f64> = line
        .split_whitespace()
        .skip(1)
        .map(|v| v.parse().unwrap())
        .collect();
    let r = rust_eigenvalues();
    assert_eq!(c.len(), 7);
    assert_eq!(r.len(), 7);
    for (x, y) in c.iter().zip(&r) {
        assert!(
            (x - y).abs() <= 1e-11 * y.abs().max(1e-3 * r[1]),
            "{x} vs {y}"
        );
    }
}
