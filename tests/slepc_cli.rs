//! The `freeform` binary with SLEPc (feature `slepc`): `compare` across backends, and MPI runs
//! (`mpirun -n 1` vs `-n 2`). Needs `mpirun` (OpenMPI) on PATH.
//! Run: `cargo test --features slepc --test slepc_cli`.
#![cfg(feature = "slepc")]

use std::process::{Command, Output};

fn json(o: &Output) -> serde_json::Value {
    assert!(
        o.status.success(),
        "exit {:?}: {}\n{}",
        o.status,
        String::from_utf8_lossy(&o.stderr),
        String::from_utf8_lossy(&o.stdout)
    );
    serde_json::from_slice(&o.stdout).expect("stdout is one JSON document")
}

/// `mpirun -n ranks freeform args...`, with the settings docs/slepc.md gives for a 2-core
/// machine run as root.
fn mpirun(ranks: usize, args: &[&str]) -> Output {
    Command::new("mpirun")
        .args(["-n", &ranks.to_string(), "--oversubscribe"])
        .arg(env!("CARGO_BIN_EXE_freeform"))
        .args(args)
        .env("OMP_NUM_THREADS", "1")
        // Waiting ranks yield the core instead of busy-polling (2 cores shared with others).
        .env("OMPI_MCA_mpi_yield_when_idle", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .output()
        .expect("run mpirun (install openmpi-bin / libslepc-real-dev)")
}

#[test]
fn compare_native_slepc_and_dense() {
    let o = Command::new(env!("CARGO_BIN_EXE_freeform"))
        .args([
            "compare",
            "box:2,1,1",
            "--kernels",
            "300",
            "--modes",
            "8",
            "--slepc",
            "ks-sinvert,lobpcg-gamg",
            "--slepc",
            "-eps_type lobpcg -st_type precond -st_pc_type hypre -eps_smallest_real",
            "--dense",
            "--json",
        ])
        .output()
        .unwrap();
    let r = json(&o);
    let names: Vec<&str> = r["solvers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["solver"].as_str().unwrap())
        .collect();
    assert_eq!(names[0], "lobpcg");
    assert!(names.contains(&"slepc:ks-sinvert"), "{names:?}");
    assert!(names.contains(&"slepc:lobpcg-gamg"), "{names:?}");
    assert!(
        names.iter().any(|n| n.contains("-st_pc_type hypre")),
        "{names:?}"
    );
    assert!(names.contains(&"dense"), "{names:?}");
    // The targets (tol 1e-8 for every solver): eigenvalues 1e-8 relative,
    // eigenspaces 1e-6 rad, across all of them.
    let diff = r["max_eigenvalue_rel_diff"].as_f64().unwrap();
    let angle = r["max_subspace_angle"].as_f64().unwrap();
    assert!(diff < 1e-8, "{diff}");
    assert!(angle < 1e-6, "{angle}");
}

/// Eigenvalues of `freeform modes --solver slepc --json` under mpirun (`extra` flags added).
fn mpi_eigenvalues(
    ranks: usize,
    extra: &[&str],
    dir: &std::path::Path,
) -> (Vec<f64>, serde_json::Value) {
    let out = dir.join(format!("basis{ranks}{}.npz", extra.len()));
    let mut args = vec![
        "modes",
        "box:2,1,1",
        "--kernels",
        "400",
        "--modes",
        "8",
        "--solver",
        "slepc",
        "--tol",
        "1e-10",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let r = json(&mpirun(ranks, &args));
    assert!(out.is_file(), "rank 0 writes the basis");
    let ev = r["eigenvalues"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    (ev, r)
}

#[test]
fn one_and_two_mpi_ranks_agree() {
    let dir = tempfile::tempdir().unwrap();
    // One rank: the ordinary pipeline. Two ranks: distributed assembly (each rank only its
    // kernels' rows) and a distributed solve.
    let (one, r1) = mpi_eigenvalues(1, &[], dir.path());
    let (two, r2) = mpi_eigenvalues(2, &[], dir.path());
    assert_eq!(one.len(), 9);
    assert_eq!(two.len(), 9);
    // Same matrices on 1 and 2 ranks; only the solver's parallel reductions and the
    // distributed factorization change round-off (~1e-14). The constant mode's eigenvalue
    // (~0) is compared relative to the first non-zero one.
    for (i, (a, b)) in one.iter().zip(&two).enumerate() {
        let scale = if i == 0 { one[1] } else { a.abs() };
        assert!((a - b).abs() <= 1e-10 * scale, "pair {i}: {a} vs {b}");
    }
    for r in [&r1, &r2] {
        assert!(r["max_relative_residual"].as_f64().unwrap() < 1e-9, "{r}");
        assert!(r["orthonormality_error"].as_f64().unwrap() < 1e-8, "{r}");
    }
    let notes = r2["eigen"]["notes"].to_string();
    assert!(notes.contains("2 MPI rank(s)"), "{notes}");
    assert!(notes.contains("distributed assembly: 2 rank(s)"), "{notes}");
    // Per-rank figures of the distributed run: every rank's peak memory (a process of this
    // size holds at least a few MB, at most the machine), rows and points, stage minima.
    let peaks = r2["peak_memory_bytes_per_rank"]
        .as_array()
        .expect("per-rank peaks");
    assert_eq!(peaks.len(), 2, "{r2}");
    for p in peaks {
        let bytes = p.as_u64().unwrap();
        assert!(bytes > 1 << 20 && bytes < 1 << 40, "{bytes}");
    }
    let d = &r2["distributed"];
    let rows: Vec<u64> = d["rows_per_rank"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert_eq!(rows.iter().sum::<u64>() as usize, 400, "{d}");
    assert!(
        d["timings_min"]["total"].as_f64().unwrap() <= r2["timings_s"]["total"].as_f64().unwrap(),
        "{d}"
    );
    assert!(r1.get("peak_memory_bytes_per_rank").is_none());
}

#[test]
fn distributed_assembly_on_one_rank_is_the_same_problem() {
    // The distributed path on one rank assembles the same entries, summed over the same
    // points in the same order, as the ordinary pipeline: identical matrices, identical
    // solver, so identical eigenvalues (to the last bits the JSON printing keeps).
    let dir = tempfile::tempdir().unwrap();
    let (plain, _) = mpi_eigenvalues(1, &[], dir.path());
    let (dist, r) = mpi_eigenvalues(1, &["--distributed"], dir.path());
    assert_eq!(plain, dist);
    assert!(r["eigen"]["notes"]
        .to_string()
        .contains("distributed assembly: 1 rank(s)"));
}

/// A SLEPc run names SLEPc and its whole configuration (preset and `--petsc-options`) in the
/// basis metadata, in the string form `SolverConfig` parses back, and in its report.
#[test]
fn slepc_basis_metadata_names_the_solver_that_ran() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("basis.npz");
    let o = Command::new(env!("CARGO_BIN_EXE_freeform"))
        .args(["modes", "box:2,1,1", "--kernels", "200", "--modes", "4"])
        .args(["--solver", "slepc", "--slepc", "ks-sinvert"])
        .args(["--petsc-options", "-eps_ncv 24", "--json", "--out"])
        .arg(&out)
        .env("OMP_NUM_THREADS", "1")
        .output()
        .unwrap();
    let r = json(&o);
    assert_eq!(r["solver"], "slepc");
    assert_eq!(r["eigen"]["solver"], "slepc:ks-sinvert -eps_ncv 24");
    let loaded = freeform::io::basis::load(&out).unwrap();
    assert_eq!(
        loaded.raw_metadata["options"]["solver"],
        "slepc:ks-sinvert:-eps_ncv 24"
    );
    let options = loaded.metadata.options.expect("typed options");
    assert_eq!(
        options.solver,
        freeform::precompute::SolverConfig::slepc("ks-sinvert", "-eps_ncv 24").unwrap()
    );
}

/// The options that give `lobpcg-gamg` its earlier configuration: SLEPc's own block size,
/// GAMG's own level smoothers and its squared first-level graph.
const OLD_LOBPCG_GAMG_OPTIONS: &str = "-eps_lobpcg_blocksize 16 -st_mg_levels_ksp_type chebyshev \
     -st_mg_levels_pc_type jacobi -st_pc_gamg_square_graph 1";

/// `freeform modes box:5,1,1 --kernels K --modes M --solver slepc --slepc lobpcg-gamg` with
/// `OLD_LOBPCG_GAMG_OPTIONS` (the preset as it was when these failures
/// were found; the preset now refuses K this small) into a
/// temporary directory, for runs that must fail: the whole stderr and its one `error:` line,
/// after checking the exit status 1, that there is exactly one error line, no PETSc output,
/// and no basis file written.
fn failing_slepc_lobpcg(kernels: &str, modes: &str) -> (String, String) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("basis.npz");
    let o = Command::new(env!("CARGO_BIN_EXE_freeform"))
        .args(["modes", "box:5,1,1", "--kernels", kernels, "--modes", modes])
        .args([
            "--solver",
            "slepc",
            "--slepc",
            "lobpcg-gamg",
            "--petsc-options",
        ])
        .arg(OLD_LOBPCG_GAMG_OPTIONS)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    let error: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(error.len(), 1, "{stderr}");
    assert!(!stderr.contains("PETSC ERROR"), "{stderr}");
    assert!(!out.exists());
    let line = error[0].to_string();
    (stderr, line)
}

/// What a user sees when SLEPc's LOBPCG breaks down (see tests/slepc.rs for the size): one
/// line on stderr naming the breakdown and the ways out, exit status 1, no abort and no PETSc
/// output.
#[test]
fn lobpcg_breakdown_is_reported_not_aborted() {
    let (stderr, line) = failing_slepc_lobpcg("80", "18");
    assert!(
        line.starts_with("error: SLEPc's LOBPCG broke down: loss of B-orthogonality")
            && line.contains("LAPACK sygvd info=")
            && line.contains("--slepc ks-sinvert")
            && line.contains("--solver lobpcg"),
        "{stderr}"
    );
}

/// What a user sees when SLEPc's LOBPCG reports convergence but one pair is far off (smallest
/// case found: K = 80, m = 16; see tests/slepc.rs): one line naming the pair, its residual and
/// the ways out, not "raise --tol or the iteration cap"; exit status 1, no basis written.
#[test]
fn slepc_lobpcg_false_convergence_is_reported_with_advice() {
    let (stderr, line) = failing_slepc_lobpcg("80", "16");
    assert!(
        line.starts_with("error: SLEPc's LOBPCG reported convergence (")
            && line.contains("but freeform's own residual check finds pair ")
            && line.contains("> 1.0e-7 (10 x tol 1.0e-8; 1 pair(s) above it)")
            && line.contains("--slepc ks-sinvert")
            && line.contains("--solver lobpcg")
            // One block of 19 would need K >= 95.
            && line.ends_with("to keep SLEPc's LOBPCG, ask for fewer modes")
            && !line.contains("raise --tol"),
        "{stderr}"
    );
}

#[test]
fn distributed_runs_on_1_2_and_4_ranks_equal_the_native_basis() {
    // The bar: eigenvalues across P = 1, 2, 4 equal to 1e-8 relative, eigenspaces to
    // 1e-6 rad, here against the native one-process basis of the same kernels (the
    // distributed kernels and rows are the one-process ones bit for bit; only the solvers
    // differ). tol 1e-10 leaves the solvers' own errors (~tol x condition) far below both bars.
    use freeform::eigen::compare::{max_eigenvalue_rel_diff, max_subspace_angle};
    let dir = tempfile::tempdir().unwrap();
    let common = [
        "box:2,1,1",
        "--kernels",
        "600",
        "--modes",
        "8",
        "--tol",
        "1e-10",
        "--json",
    ];
    let native_out = dir.path().join("native.npz");
    let native = Command::new(env!("CARGO_BIN_EXE_freeform"))
        .arg("modes")
        .args(common)
        .args(["--out", native_out.to_str().unwrap()])
        .output()
        .unwrap();
    json(&native);
    let reference = freeform::io::basis::load(&native_out).unwrap().basis;
    // M of the same problem, for the M-inner-product angles.
    let shape = freeform::io::read_shape("box:2,1,1", &Default::default()).unwrap();
    let opts = freeform::precompute::BasisOptions {
        kernels: 600,
        modes: 8,
        ..Default::default()
    };
    let problem =
        freeform::precompute::Problem::from_shape(&shape, &opts, &freeform::progress::Silent)
            .unwrap();
    let mass = problem.matrices().mass();
    for ranks in [1, 2, 4] {
        let out = dir.path().join(format!("p{ranks}.npz"));
        let mut args = vec!["modes"];
        args.extend(common);
        args.extend(["--solver", "slepc", "--distributed", "--threads", "1"]);
        args.extend(["--out", out.to_str().unwrap()]);
        let r = json(&mpirun(ranks, &args));
        assert_eq!(r["distributed"]["ranks"], ranks, "{r}");
        let got = freeform::io::basis::load(&out).unwrap().basis;
        assert_eq!(
            got.kernels.centers, reference.kernels.centers,
            "P = {ranks}"
        );
        assert_eq!(got.kernels.radii, reference.kernels.radii, "P = {ranks}");
        // The constant mode's eigenvalue is ~0: compare the others relatively.
        let diff = max_eigenvalue_rel_diff(&reference.eigenvalues[1..], &got.eigenvalues[1..]);
        assert!(diff < 1e-8, "P = {ranks}: eigenvalues differ by {diff:e}");
        let angle = max_subspace_angle(
            mass.as_ref(),
            &reference.eigenvalues,
            &reference.coefficients,
            &got.eigenvalues,
            &got.coefficients,
            1e-6,
        )
        .unwrap();
        assert!(angle < 1e-6, "P = {ranks}: eigenspaces {angle:e} rad apart");
    }
}

/// Refusals under `mpirun` come from every rank, before any collective could hang, and write
/// nothing: more ranks than kernels, and a memory share too small for the per-rank estimate
/// (`FREEFORM_MEMORY_LIMIT`, checked by every rank before anything is allocated).
#[test]
fn distributed_refusals_come_from_every_rank_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("basis.npz");
    let out_arg = out.to_str().unwrap();
    let common = ["modes", "box:2,1,1", "--modes", "2", "--solver", "slepc"];
    // (ranks, kernels, FREEFORM_MEMORY_LIMIT, what every rank says); 10 kernels is the least
    // any run accepts.
    let cases = [
        (11, "10", None, "fewer kernels than the 11 MPI ranks"),
        (3, "2000", Some("0.001"), "FREEFORM_MEMORY_LIMIT"),
    ];
    for (ranks, kernels, limit, expected) in cases {
        let mut args = common.to_vec();
        args.extend(["--kernels", kernels, "--distributed", "--threads", "1"]);
        args.extend(["--out", out_arg]);
        let mut cmd = Command::new("mpirun");
        // mpirun would kill the other ranks as soon as one exits non-zero; they are let finish
        // here so that each rank's own error can be counted.
        cmd.args(["-n", &ranks.to_string(), "--oversubscribe"])
            .args(["--mca", "orte_abort_on_non_zero_status", "0"])
            .arg(env!("CARGO_BIN_EXE_freeform"))
            .args(&args)
            .env("OMP_NUM_THREADS", "1")
            .env("OMPI_MCA_mpi_yield_when_idle", "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
        if let Some(gb) = limit {
            cmd.env(freeform::precompute::memory::MEMORY_LIMIT_ENV, gb);
        }
        let o = cmd.output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        // (mpirun's own exit status is 0 with that setting.) Each rank prints its own error (lines may interleave: the message is counted).
        assert_eq!(stderr.matches(expected).count(), ranks, "{stderr}");
        assert!(!stderr.contains("PETSC ERROR"), "{stderr}");
        assert!(!out.exists(), "{expected}: a basis was written");
    }
}
