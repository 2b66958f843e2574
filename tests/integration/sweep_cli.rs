//! `freeform sweep`: CSV rows and columns, valid PNG plots, consistent Pareto flags, and bad
//! input giving a clear error (non-zero exit, no panic, no outputs). Tiny settings: a linear
//! FEM reference at 1 cube per metre and 20 frames.

use crate::common;
use common::freeform;
use std::path::Path;
use std::process::Output;

const PNG_MAGIC: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

fn tiny<'a>(out: &'a str, cache: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut v = vec![
        "sweep",
        "bend",
        "--fem-resolution",
        "1",
        "--fem-order",
        "linear",
        "--frames",
        "20",
        "--out",
        out,
        "--cache",
        cache,
    ];
    v.extend_from_slice(extra);
    v
}

/// Run a tiny sweep with `extra` arguments in a fresh directory and check it succeeded:
/// the directory (kept alive), the output folder, the process output.
fn run_tiny(extra: &[&str]) -> (tempfile::TempDir, std::path::PathBuf, Output) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let cache = dir.path().join("fem");
    let o = freeform(&tiny(out.to_str().unwrap(), cache.to_str().unwrap(), extra));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    (dir, out, o)
}

/// Whether `p` is dominated by any row of `all` (cost, error), both minimized.
fn dominated(p: [f64; 2], all: &[[f64; 2]]) -> bool {
    all.iter()
        .any(|q| q[0] <= p[0] && q[1] <= p[1] && (q[0] < p[0] || q[1] < p[1]))
}

#[test]
fn sweep_writes_csv_plots_and_consistent_pareto_flags() {
    let (_dir, out, o) = run_tiny(&[
        "--modes",
        "2,4",
        "--kernels",
        "100,200",
        "--points",
        "5000,8000",
        "--cubature",
        "500,300",
        "--hessian",
        "lbfgs,fixed",
        "--base-modes",
        "4",
        "--base-kernels",
        "100",
        "--json",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    // One progress line per run: 4 grid runs + 1 points + 1 cubature + 1 Hessian variation.
    assert_eq!(
        stderr.lines().filter(|l| l.starts_with('[')).count(),
        7,
        "{stderr}"
    );

    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let expect = [
        "test",
        "axis",
        "modes",
        "kernels",
        "points",
        "cubature",
        "hessian",
        "density_boundaries",
        "frames",
        "normalized_mse",
        "max_error",
        "normalized_mse_first_half",
        "max_error_first_half",
        "precompute_s",
        "basis_s",
        "reduced_step_ms_mean",
        "reduced_nonconverged_steps",
        "fem_step_ms_mean",
        "fem_nodes",
        "pareto_precompute",
        "pareto_step",
    ];
    assert_eq!(header, expect);
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 7);
    for r in &rows {
        assert_eq!(r.len(), header.len(), "{r:?}");
        assert_eq!(r[col("test")], "bend");
        assert_eq!(r[col("frames")], "20");
    }
    let axes: Vec<&str> = rows.iter().map(|r| r[col("axis")]).collect();
    assert_eq!(
        axes,
        ["grid", "grid", "grid", "grid", "points", "cubature", "hessian"]
    );
    let num = |r: &Vec<&str>, c: &str| -> f64 { r[col(c)].parse().unwrap() };
    let variations = &rows[4..];
    for r in variations {
        assert_eq!((r[col("modes")], r[col("kernels")]), ("4", "100"));
    }
    // Point counts are those of the grid that fits the box, near the target.
    let n = num(&variations[0], "points");
    assert!((7000.0..9000.0).contains(&n), "{n}");
    assert!(num(&rows[2], "points") < 6000.0);
    assert_eq!(variations[1][col("cubature")], "300");
    assert_eq!(variations[2][col("hessian")], "fixed");
    for r in &rows {
        let mse = num(r, "normalized_mse");
        assert!(mse.is_finite() && mse > 0.0, "{r:?}");
        assert!(num(r, "precompute_s") >= num(r, "basis_s"));
    }

    // The Pareto flags match the definition, and each front is non-empty.
    for (cost, flag) in [
        ("precompute_s", "pareto_precompute"),
        ("reduced_step_ms_mean", "pareto_step"),
    ] {
        let pts: Vec<[f64; 2]> = rows
            .iter()
            .map(|r| [num(r, cost), num(r, "normalized_mse")])
            .collect();
        let mut on = 0;
        for (r, p) in rows.iter().zip(&pts) {
            let f: bool = r[col(flag)].parse().unwrap();
            assert_eq!(f, !dominated(*p, &pts), "{flag} of {r:?}");
            on += usize::from(f);
        }
        assert!(on >= 1);
        // The most accurate run is always on the front.
        let best = (0..pts.len())
            .min_by(|&a, &b| {
                pts[a][1]
                    .total_cmp(&pts[b][1])
                    .then(pts[a][0].total_cmp(&pts[b][0]))
            })
            .unwrap();
        assert_eq!(rows[best][col(flag)], "true");
    }

    for png in [
        "error_vs_precompute.png",
        "error_vs_step.png",
        "error_vs_kernels.png",
    ] {
        let bytes = std::fs::read(out.join(png)).unwrap();
        assert!(bytes.len() > 5000, "{png} is only {} bytes", bytes.len());
        assert_eq!(bytes[..8], PNG_MAGIC, "{png}");
    }
    let j: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("sweep.json")).unwrap()).unwrap();
    assert_eq!(j["rows"].as_array().unwrap().len(), 7);
    assert_eq!(
        j["bases_built"], 5,
        "the cubature and Hessian variations reuse a basis"
    );
    let stdout: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is JSON");
    assert_eq!(stdout["test"], "bend");
    // No temporary files are left behind.
    let names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.ends_with(".tmp")), "{names:?}");
}

#[test]
fn sweep_runs_the_grid_once_per_density_and_measures_the_rise_with_k() {
    let (_dir, out, _) = run_tiny(&[
        "--modes",
        "2",
        "--kernels",
        "100,200",
        "--density-boundaries",
        "1,2",
        "--base-modes",
        "2",
        "--base-kernels",
        "100",
        "--json",
    ]);
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    // The grid once per factor, the base point (on the grid) not again.
    let grid: Vec<(&str, &str, &str)> = rows
        .iter()
        .map(|r| {
            (
                r[col("axis")],
                r[col("kernels")],
                r[col("density_boundaries")],
            )
        })
        .collect();
    assert_eq!(
        grid,
        [
            ("grid", "100", "1"),
            ("grid", "200", "1"),
            ("grid", "100", "2"),
            ("grid", "200", "2")
        ]
    );
    // A refined basis is another basis: its error differs from the uniform one's.
    let mse: Vec<f64> = rows
        .iter()
        .map(|r| r[col("normalized_mse")].parse().unwrap())
        .collect();
    assert_ne!(mse[0], mse[2]);
    // One curve per density, its rise the ratio of the two points, as the CSV has them.
    let j: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("sweep.json")).unwrap()).unwrap();
    let curves = j["curves"].as_array().unwrap();
    assert_eq!(curves.len(), 2);
    for (c, pair) in curves.iter().zip([[mse[0], mse[1]], [mse[2], mse[3]]]) {
        assert_eq!(c["kernels"], serde_json::json!([100, 200]));
        assert_eq!(c["normalized_mse"], serde_json::json!(pair));
        assert_eq!(c["worst_rise"].as_f64().unwrap(), pair[1] / pair[0]);
        assert_eq!(c["worst_rise_at"], 200);
    }
    assert_eq!(curves[1]["density"]["boundaries"], 2.0);
    let bytes = std::fs::read(out.join("error_vs_kernels.png")).unwrap();
    assert_eq!(bytes[..8], PNG_MAGIC);
}

fn assert_clean_failure(o: &Output, out: &Path, needle: &str) {
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert_ne!(o.status.code(), Some(101), "panicked: {stderr}");
    assert!(stderr.contains(needle), "expected {needle:?} in {stderr}");
    assert!(!out.join("sweep.csv").exists());
}

#[test]
fn sweep_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let cache = dir.path().join("fem");
    let (o, c) = (out.to_str().unwrap(), cache.to_str().unwrap());
    let cases: [(&[&str], &str); 7] = [
        (&["--modes", "4,32", "--kernels", "30"], "m = 32, K = 30"),
        (&["--kernels", ""], "kernels"),
        (&["--hessian", "lbfgs,bogus"], "bogus"),
        (&["--points", "auto,lots"], "lots"),
        (
            &["--cubature", "0", "--kernels", "100", "--modes", "2"],
            "cubature",
        ),
        (
            &["--spacing=-0.1", "--kernels", "100", "--modes", "2"],
            "spacing",
        ),
        (
            &[
                "--density-boundaries",
                "1,0",
                "--kernels",
                "100",
                "--modes",
                "2",
            ],
            "density boundaries",
        ),
    ];
    for (extra, needle) in cases {
        let args = tiny(o, c, extra);
        assert_clean_failure(&freeform(&args), &out, needle);
    }
}
