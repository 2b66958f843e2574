//! SLEPc backend (feature `slepc`): eigenvalues against the analytic Q1 spectrum and against our
//! dense solver, every preset, options pass-through, PETSc errors and non-convergence.
//! Run: `cargo test --features slepc --test slepc`.
#![cfg(feature = "slepc")]

use freeform::eigen::dense::DenseSolver;
use freeform::eigen::slepc::{SlepcOptions, SlepcPreset, SlepcSolver};
use freeform::eigen::testing::{q1_fem, q1_fem_eigenvalues};
use freeform::eigen::{EigenError, EigenRequest, EigenStatus, Eigensolver, SlepcLobpcgStop};
use freeform::options::Front; // advice as the command line prints it (flags)
use freeform::progress::Silent;

/// Q1 Neumann problem, 9 x 8 x 7 nodes (K = 504), 8 pairs: distinct sizes keep the wanted
/// eigenvalues apart except for the exact multiplicities of the analytic formula.
const N: [usize; 3] = [9, 8, 7];
const H: f64 = 0.1;

fn request(tol: f64) -> EigenRequest {
    EigenRequest {
        nev: 8,
        tol,
        max_iter: 2000,
    }
}

/// Largest relative eigenvalue difference over the non-zero eigenvalues, and the absolute
/// difference of the zero one relative to the first non-zero.
fn max_rel_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b[1];
    a.iter()
        .zip(b)
        .enumerate()
        .map(|(i, (x, y))| {
            if i == 0 {
                (x - y).abs() / scale
            } else {
                (x - y).abs() / y.abs()
            }
        })
        .fold(0.0, f64::max)
}

#[test]
fn every_preset_matches_the_analytic_spectrum_and_the_dense_solver() {
    let (h, m) = q1_fem(N, H);
    let exact = q1_fem_eigenvalues(N, H, 8);
    let dense = DenseSolver
        .solve_converged(h.as_ref(), m.as_ref(), &request(1e-10), &Silent)
        .unwrap();
    // The dense solver is exact to round-off (~1e-13 relative here), so it checks the
    // analytic formula as much as it checks SLEPc.
    assert!(max_rel_diff(&dense.values, &exact) < 1e-10);
    for preset in [
        SlepcPreset::KsSinvert,
        SlepcPreset::LobpcgGamg,
        SlepcPreset::LobpcgHypre,
    ] {
        let solver = SlepcSolver::new(SlepcOptions {
            preset,
            ..SlepcOptions::default()
        });
        let sol = solver
            .solve_converged(h.as_ref(), m.as_ref(), &request(1e-10), &Silent)
            .unwrap();
        // Residual tolerance 1e-10 (relative to ||H|| + |lambda| ||M||) bounds the eigenvalue
        // error by ~ residual^2 / gap ~ 1e-20 relative for shift-and-invert and by ~ residual
        // x ||H|| / lambda ~ 1e-10 x lambda_max / lambda_1 ~ 1e-8 for an iterative method
        // whose residual just meets the tolerance; 1e-8 is the agreement target.
        let diff = max_rel_diff(&sol.values, &dense.values);
        assert!(
            diff < 1e-8,
            "{}: eigenvalues differ from dense by {diff:e}: {:?} vs {:?}",
            preset.name(),
            sol.values,
            dense.values
        );
        // Recomputed by check_solution, not SLEPc's numbers.
        assert!(sol.info.max_relative_residual <= 10.0 * 1e-10);
        assert!(sol.info.orthonormality_error < 1e-8, "{:?}", sol.info);
        assert!(sol.info.solver.starts_with("slepc:"));
    }
}

/// The real problem: H_w and M of RKPM kernels on a box (K = 300, graded spectrum with
/// lambda_max / lambda_1 ~ 1e3, a null vector), where a wrong convergence test shows up.
#[test]
fn rkpm_matrices_agree_with_the_dense_solver() {
    use freeform::eigen::compare::{max_eigenvalue_rel_diff, max_subspace_angle};
    use freeform::geometry::ShapeOptions;
    use freeform::io::read_shape;
    use freeform::precompute::{BasisOptions, Problem};
    let shape = read_shape("box:2,1,1", &ShapeOptions::default()).unwrap();
    let opts = BasisOptions {
        kernels: 300,
        modes: 8,
        ..BasisOptions::default()
    };
    let p = Problem::from_shape(&shape, &opts, &Silent).unwrap();
    let (h, m) = (p.matrices().hessian(), p.matrices().mass());
    let req = EigenRequest {
        nev: 9,
        tol: 1e-10,
        max_iter: 2000,
    };
    let dense = DenseSolver.solve_converged(h, m, &req, &Silent).unwrap();
    for preset in [SlepcPreset::KsSinvert, SlepcPreset::LobpcgGamg] {
        let sol = SlepcSolver::new(SlepcOptions {
            preset,
            ..SlepcOptions::default()
        })
        .solve_converged(h, m, &req, &Silent)
        .unwrap_or_else(|e| panic!("{}: {e}", preset.name()));
        // The targets: 1e-8 relative for eigenvalues, 1e-6 rad for eigenspaces. With
        // residuals <= 1e-10 the angle bound is residual x ||H|| / gap ~ 1e-10 x 1e3 / 1e-1.
        let diff = max_eigenvalue_rel_diff(&sol.values, &dense.values);
        let angle = max_subspace_angle(
            m,
            &sol.values,
            &sol.vectors,
            &dense.values,
            &dense.vectors,
            1e-6,
        )
        .unwrap();
        assert!(diff < 1e-8, "{}: eigenvalue diff {diff:e}", preset.name());
        assert!(angle < 1e-6, "{}: subspace angle {angle:e}", preset.name());
    }
}

#[test]
fn petsc_options_override_the_preset() {
    let (h, m) = q1_fem(N, H);
    let solver = SlepcSolver::new(
        SlepcOptions::parse(
            "-eps_type lobpcg -eps_smallest_real -st_type precond -st_pc_type jacobi",
        )
        .unwrap(),
    );
    let sol = solver
        .solve_converged(h.as_ref(), m.as_ref(), &request(1e-9), &Silent)
        .unwrap();
    let note = sol.info.notes.join("; ");
    assert!(
        note.contains("eps lobpcg") && note.contains("pc jacobi"),
        "{note}"
    );
    let exact = q1_fem_eigenvalues(N, H, 8);
    assert!(max_rel_diff(&sol.values, &exact) < 1e-7);
    // The options were removed after the solve: the next default solve is the preset's again.
    let sol = SlepcSolver::default()
        .solve_converged(h.as_ref(), m.as_ref(), &request(1e-9), &Silent)
        .unwrap();
    assert!(
        sol.info.notes[0].contains("eps lobpcg") && sol.info.notes[0].contains("pc gamg"),
        "{:?}",
        sol.info.notes
    );
}

#[test]
fn options_for_objects_made_at_setup_reach_them() {
    // The multigrid levels' smoothers are created inside EPSSolve (at PCSetUp) and read the
    // options database then: an option for them must still be there. A bogus smoother type
    // proves it was read (it was silently dropped while options were cleared before the solve).
    let (h, m) = q1_fem(N, H);
    let solver = SlepcSolver::new(
        SlepcOptions::parse("lobpcg-gamg:-st_mg_levels_ksp_type bogus_smoother").unwrap(),
    );
    let err = solver
        .solve(h.as_ref(), m.as_ref(), &request(1e-9), &Silent)
        .unwrap_err();
    assert!(err.to_string().contains("bogus_smoother"), "{err}");
    // And they are gone after the solve: the same preset without them solves.
    let sol = SlepcSolver::new(SlepcOptions::parse("lobpcg-gamg").unwrap())
        .solve_converged(h.as_ref(), m.as_ref(), &request(1e-9), &Silent)
        .unwrap();
    assert!(sol.converged());
}

#[test]
fn a_petsc_error_carries_petscs_message() {
    let (h, m) = q1_fem(N, H);
    let solver = SlepcSolver::new(SlepcOptions::parse("-eps_type no_such_solver").unwrap());
    let err = solver
        .solve(h.as_ref(), m.as_ref(), &request(1e-9), &Silent)
        .unwrap_err();
    match &err {
        EigenError::Backend { message, .. } => {
            assert!(message.contains("no_such_solver"), "{message}")
        }
        other => panic!("expected a PETSc error, got {other}"),
    }
}

/// A cap set too low for SLEPc's LOBPCG: the message says so and advises raising it first.
#[test]
fn non_convergence_returns_the_partial_result() {
    let (h, m) = q1_fem(N, H);
    let solver = SlepcSolver::new(SlepcOptions {
        preset: SlepcPreset::LobpcgGamg,
        ..SlepcOptions::default()
    });
    let req = EigenRequest {
        nev: 8,
        tol: 1e-12,
        max_iter: 2,
    };
    // Not converged is a status on the result, with the partial result in hand.
    let partial = solver
        .solve(h.as_ref(), m.as_ref(), &req, &Silent)
        .unwrap_or_else(|e| panic!("expected SLEPc's LOBPCG iteration cap, got {e}"));
    match partial.info.status {
        EigenStatus::SlepcLobpcgNotConverged {
            stop: SlepcLobpcgStop::IterationCap,
            converged,
            ..
        } => {
            assert!(converged < 8);
            assert_eq!(partial.info.residuals.len(), partial.values.len());
        }
        EigenStatus::Converged => panic!(
            "2 iterations cannot converge 8 pairs to 1e-12: {:?}",
            partial.info
        ),
        ref other => panic!("expected SLEPc's LOBPCG iteration cap, got {other:?}"),
    }
    // Its error, where a converged result is required, says so and advises raising the cap.
    let text = Front::Flags.render(&partial.into_converged().unwrap_err());
    assert!(
        text.starts_with("SLEPc's LOBPCG stopped at its iteration cap (2 iterations)")
            && text.contains("raise --max-iter (2 now, default 1000)"),
        "{text}"
    );
}

#[test]
fn petsc_reads_our_binary_export_exactly() {
    use freeform::eigen::slepc::petsc_binary_difference;
    use freeform::io::matrix_market::write_petsc_binary;
    let (h, m) = q1_fem(N, H);
    let dir = tempfile::tempdir().unwrap();
    for (name, a) in [("h.petsc", &h), ("m.petsc", &m)] {
        let path = dir.path().join(name);
        write_petsc_binary(&path, a.as_ref()).unwrap();
        // Same entries, same summation order per row: PETSc's product equals ours exactly.
        assert_eq!(petsc_binary_difference(&path, a.as_ref()).unwrap(), 0.0);
    }
    // A different matrix is detected (M is not H).
    let diff = petsc_binary_difference(&dir.path().join("m.petsc"), h.as_ref()).unwrap();
    assert!(diff > 0.1, "{diff}");
    // A file that is not a PETSc matrix is a PETSc error with its message, not a crash.
    let junk = dir.path().join("junk.petsc");
    std::fs::write(&junk, b"not a petsc file at all").unwrap();
    match petsc_binary_difference(&junk, h.as_ref()) {
        Err(EigenError::Backend { message, .. }) => assert!(
            message.contains("MatLoad") || message.contains("PetscViewer"),
            "{message}"
        ),
        other => panic!("expected a PETSc error, got {:?}", other.map(|_| ())),
    }
}

/// SLEPc's LOBPCG loses B-orthogonality and LAPACK's sygvd rejects the projected pencil. The
/// smallest case found with the `lobpcg-gamg` preset: K = 80 (SLEPc needs K >= 5 x the block
/// size 16) and 19 pairs, i.e. more pairs than one block holds (scanned K = 80..3000, m = 8..32;
/// it breaks down here and at K = 100 with m >= 24, K = 2800 and 3000 with m = 32, but not at
/// K = 90 or with m <= 15; scanned with [`OLD_BLOCK`], the configuration the preset had then;
/// the preset itself now refuses K this small, `refuse_lobpcg_too_small`). The advice in the message is checked too: the direct SLEPc configuration and the
/// native LOBPCG solve the same problem and agree with the dense solver.
#[test]
fn lobpcg_breakdown_is_a_typed_error_with_advice() {
    use freeform::eigen::compare::max_eigenvalue_rel_diff;
    use freeform::eigen::lobpcg::Lobpcg;
    let (hw, mass) = box_pencil(80);
    let (h, m) = (&hw, &mass);
    let req = EigenRequest {
        nev: 19,
        tol: 1e-8,
        max_iter: 1000,
    };
    let lobpcg = SlepcSolver::new(SlepcOptions::parse(OLD_BLOCK).unwrap());
    match lobpcg.solve(h.as_ref(), m.as_ref(), &req, &Silent) {
        Err(
            ref e @ EigenError::SlepcLobpcgBreakdown {
                ref routine,
                info,
                k,
                nev,
                block_size,
                ref message,
            },
        ) => {
            assert_eq!(routine, "sygvd", "{message}");
            // info > projected size (at most 3 x block size): a leading minor of the projected
            // M is not positive definite, i.e. B-orthogonality was lost.
            assert!(info > 3 * 16, "{message}");
            assert_eq!((k, nev, block_size), (80, 19, Some(16)));
            let text = Front::Flags.render(&e);
            // One block of 19 would need K >= 95 (SLEPc's limit): not advised here.
            assert!(
                text.contains("SLEPc's LOBPCG broke down")
                    && text.contains("--slepc ks-sinvert")
                    && text.contains("--solver lobpcg")
                    && !text.contains("blocksize"),
                "{text}"
            );
        }
        Err(other) => panic!("expected the LOBPCG breakdown, got {other}"),
        Ok(sol) => panic!("SLEPc's LOBPCG no longer breaks down here: {:?}", sol.info),
    }
    // PETSc is usable afterwards, and both advised solvers solve the same problem.
    let dense = DenseSolver
        .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
        .unwrap();
    let ks = SlepcSolver::new(SlepcOptions::parse("ks-sinvert").unwrap())
        .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
        .unwrap();
    let native = Lobpcg::default()
        .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
        .unwrap();
    for (name, sol) in [("ks-sinvert", &ks), ("native lobpcg", &native)] {
        let diff = max_eigenvalue_rel_diff(&sol.values, &dense.values);
        assert!(diff < 1e-8, "{name} vs dense: {diff:e}");
    }
}

/// H_w and M of `freeform modes box:5,1,1 --kernels K` (default options), the problem the
/// SLEPc LOBPCG failures below were found on.
fn box_pencil(
    kernels: usize,
) -> (
    freeform::sparse::SparseMatrix,
    freeform::sparse::SparseMatrix,
) {
    use freeform::geometry::ShapeOptions;
    use freeform::io::read_shape;
    use freeform::precompute::{BasisOptions, Problem};
    let shape = read_shape("box:5,1,1", &ShapeOptions::default()).unwrap();
    let opts = BasisOptions {
        kernels,
        ..BasisOptions::default()
    };
    let a = Problem::from_shape(&shape, &opts, &Silent)
        .unwrap()
        .into_matrices();
    a.into_pair()
}

/// ||H x - lambda M x||_2 / ((||H||_1 + |lambda| ||M||_1) ||x||_2) of column `j`, with plain
/// loops over the CSC arrays of the (symmetric, fully stored) matrices: independent of
/// `eigen::check_solution`, which decided convergence.
fn plain_residual(
    h: freeform::sparse::SparseMatrixRef<'_>,
    m: freeform::sparse::SparseMatrixRef<'_>,
    lambda: f64,
    x: &[f64],
) -> f64 {
    let k = x.len();
    let apply = |a: freeform::sparse::SparseMatrixRef<'_>| {
        let mut y = vec![0.0; k];
        let mut norm1 = 0.0f64;
        for (j, &xj) in x.iter().enumerate() {
            let range = a.symbolic().col_range(j);
            let mut col = 0.0;
            for (&i, &v) in a.symbolic().row_idx()[range.clone()]
                .iter()
                .zip(&a.val()[range])
            {
                y[i as usize] += v * xj;
                col += v.abs();
            }
            norm1 = norm1.max(col);
        }
        (y, norm1)
    };
    let ((hx, nh), (mx, nm)) = (apply(h), apply(m));
    let r: f64 = hx
        .iter()
        .zip(&mx)
        .map(|(a, b)| (a - lambda * b).powi(2))
        .sum::<f64>()
        .sqrt();
    let xn = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    r / ((nh + lambda.abs() * nm) * xn)
}

/// Every way out that a SLEPc LOBPCG failure message advises solves the problem: the direct
/// SLEPc configuration, the native LOBPCG, and the SLEPc options given, all against the dense
/// solver (`nev` pairs, or the first `fewer` with the preset alone).
fn advised_solvers_agree_with_dense(
    h: freeform::sparse::SparseMatrixRef<'_>,
    m: freeform::sparse::SparseMatrixRef<'_>,
    req: &EigenRequest,
    slepc_lobpcg_options: &[&str],
    fewer: usize,
) {
    use freeform::eigen::compare::max_eigenvalue_rel_diff;
    use freeform::eigen::lobpcg::Lobpcg;
    let dense = DenseSolver
        .solve_converged(h.as_ref(), m.as_ref(), req, &Silent)
        .unwrap();
    let mut solvers: Vec<(String, Box<dyn Eigensolver>, usize)> = vec![
        (
            "ks-sinvert".into(),
            Box::new(SlepcSolver::new(SlepcOptions::parse("ks-sinvert").unwrap())),
            req.nev,
        ),
        ("native lobpcg".into(), Box::new(Lobpcg::default()), req.nev),
        (
            format!("{OLD_BLOCK}, {fewer} pairs"),
            Box::new(SlepcSolver::new(SlepcOptions::parse(OLD_BLOCK).unwrap())),
            fewer,
        ),
    ];
    for spec in slepc_lobpcg_options {
        solvers.push((
            spec.to_string(),
            Box::new(SlepcSolver::new(SlepcOptions::parse(spec).unwrap())),
            req.nev,
        ));
    }
    for (name, solver, nev) in solvers {
        let req = EigenRequest { nev, ..req.clone() };
        let sol = solver
            .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let diff = max_eigenvalue_rel_diff(&sol.values, &dense.values[..nev]);
        assert!(diff < 1e-8, "{name} vs dense: {diff:e}");
    }
}

/// The `lobpcg-gamg` preset with SLEPc's own default block size, min(16, nev), which the preset
/// now replaces by one block for all pairs (or refuses, on a pencil too small for one), and
/// GAMG's own level smoothers (Chebyshev + Jacobi; the preset now uses Richardson + SOR), and
/// GAMG's squared graph on the first level (the preset now turns it off): the failures below
/// (a false convergence, the iteration cap, SLEPc's breakdown stop) are SLEPc's with that
/// configuration, and their reports are what these tests check.
const OLD_BLOCK: &str = "lobpcg-gamg:-eps_lobpcg_blocksize 16 -st_mg_levels_ksp_type chebyshev \
                         -st_mg_levels_pc_type jacobi -st_pc_gamg_square_graph 1";

/// SLEPc's LOBPCG reports every pair converged but one is far off. Smallest case found with
/// the `lobpcg-gamg` preset where one block with guard vectors fits (K >= 5 x 18): K = 120,
/// m = 15 (16 pairs, SLEPc's default block of 16 already holds them all; scanned K = 80..150,
/// m = 8..32: also K = 80 m = 16, K = 90 m = 28, K = 100 m = 22, K = 130 and 145 m = 15..24;
/// never with m <= 14). The message names the pair, and its residual is confirmed here without
/// `check_solution`; its eigenvalue is not the dense one. Every advised way out is checked.
#[test]
fn slepc_lobpcg_false_convergence_names_the_pair_and_the_ways_out() {
    let (h, m) = box_pencil(120);
    let req = EigenRequest {
        nev: 16,
        tol: 1e-8,
        max_iter: 1000,
    };
    let dense = DenseSolver
        .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
        .unwrap();
    let lobpcg = SlepcSolver::new(SlepcOptions::parse(OLD_BLOCK).unwrap());
    let partial = lobpcg
        .solve(h.as_ref(), m.as_ref(), &req, &Silent)
        .unwrap_or_else(|e| panic!("expected SlepcLobpcgNotConverged, got {e}"));
    let EigenStatus::SlepcLobpcgNotConverged {
        stop,
        reported,
        converged,
        block_size,
        ..
    } = partial.info.status
    else {
        panic!(
            "SLEPc's LOBPCG no longer fails here: {:?}",
            partial.info.status
        )
    };
    let text = Front::Flags.render(&partial.clone().into_converged().unwrap_err());
    let SlepcLobpcgStop::ClaimedConverged {
        pair,
        lambda,
        residual,
        above,
    } = stop
    else {
        panic!("expected a claimed convergence, got {stop:?}: {text}")
    };
    assert!(reported >= 16, "SLEPc reported {reported}: {text}");
    assert_eq!((converged, above, block_size), (15, 1, Some(16)), "{text}");
    assert_eq!(lambda, partial.values[pair]);
    let x: Vec<f64> = (0..h.nrows()).map(|i| partial.vectors[(i, pair)]).collect();
    let plain = plain_residual(h.as_ref(), m.as_ref(), lambda, &x);
    assert!(
        residual > 1e-3 && (plain - residual).abs() < 1e-6 * residual,
        "residual {residual:e}, recomputed {plain:e}"
    );
    // Wrong pair, not a loose tolerance: no dense eigenvalue is within 1e-6 of it.
    let nearest = dense
        .values
        .iter()
        .map(|d| (d - lambda).abs() / d.abs().max(dense.values[1]))
        .fold(f64::INFINITY, f64::min);
    assert!(nearest > 1e-6, "lambda {lambda:e} is a dense eigenvalue");
    for needle in [
        "SLEPc's LOBPCG reported convergence",
        &format!("finds pair {pair} of 0..15"),
        "> 1.0e-7 (10 x tol 1.0e-8; 1 pair(s) above it)",
        "--slepc ks-sinvert",
        "--solver lobpcg",
        "--petsc-options \"-eps_lobpcg_blocksize 18\"",
        "or ask for fewer modes",
    ] {
        assert!(text.contains(needle), "{needle:?} missing in: {text}");
    }
    assert!(!text.contains("raise --tol"), "{text}");
    // A block of exactly 16 (the default) is what failed.
    advised_solvers_agree_with_dense(
        h.as_ref(),
        m.as_ref(),
        &req,
        &["lobpcg-gamg:-eps_lobpcg_blocksize 18"],
        15,
    );
}

/// SLEPc's LOBPCG converges the first block of 16 pairs and then stalls on the 17th until its
/// iteration cap (1000; 5000 stalls the same way, tol 1e-6 or 1e-4 converge fewer pairs). The
/// smallest case found: K = 125, m = 16 (also K = 150, m >= 22). About 5 s in release.
#[test]
fn slepc_lobpcg_iteration_cap_is_named_with_the_ways_out() {
    let (h, m) = box_pencil(125);
    let req = EigenRequest {
        nev: 17,
        tol: 1e-8,
        max_iter: 1000,
    };
    let lobpcg = SlepcSolver::new(SlepcOptions::parse(OLD_BLOCK).unwrap());
    let partial = lobpcg
        .solve(h.as_ref(), m.as_ref(), &req, &Silent)
        .unwrap_or_else(|e| panic!("expected the iteration cap, got {e}"));
    match partial.info.status {
        EigenStatus::SlepcLobpcgNotConverged {
            stop: SlepcLobpcgStop::IterationCap,
            iterations,
            converged,
            block_size,
            ..
        } => {
            let text = Front::Flags.render(&partial.clone().into_converged().unwrap_err());
            assert_eq!((converged, block_size), (16, Some(16)), "{text}");
            assert!(iterations >= 1000, "{text}");
            assert_eq!(partial.values.len(), 16);
            assert!(
                text.starts_with(
                    "SLEPc's LOBPCG stopped at its iteration cap (1000 iterations) with 16/17 \
                     pairs converged (tol 1.0e-8). Use SLEPc's direct configuration --slepc \
                     ks-sinvert"
                ) && text.contains("--solver lobpcg")
                    && text.contains("\"-eps_lobpcg_blocksize 19\"), or ask for fewer modes")
                    && !text.contains("--max-iter"),
                "{text}"
            );
        }
        EigenStatus::Converged => {
            panic!("SLEPc's LOBPCG no longer stalls here: {:?}", partial.info)
        }
        ref other => panic!("expected the iteration cap, got {other:?}"),
    }
    advised_solvers_agree_with_dense(
        h.as_ref(),
        m.as_ref(),
        &req,
        &["lobpcg-gamg:-eps_lobpcg_blocksize 19"],
        16,
    );
}

/// SLEPc's LOBPCG gives up on its own (EPS_DIVERGED_BREAKDOWN: orthogonalizing a new block
/// against the locked pairs failed) with 28 of 31 pairs: K = 90, m = 30 (also m = 32). One
/// block of 34 would need K >= 170, so it is not advised. On some VMs the same pencil breaks
/// down in the Rayleigh-Ritz step instead (the BLAS kernels decide which comes first).
#[test]
fn slepc_lobpcg_stop_on_its_own_breakdown_is_named_with_the_ways_out() {
    let (h, m) = box_pencil(90);
    let req = EigenRequest {
        nev: 31,
        tol: 1e-8,
        max_iter: 1000,
    };
    let lobpcg = SlepcSolver::new(SlepcOptions::parse(OLD_BLOCK).unwrap());
    let partial = match lobpcg.solve(h.as_ref(), m.as_ref(), &req, &Silent) {
        Ok(partial) => partial,
        // The other way SLEPc's LOBPCG breaks down on this pencil: its Rayleigh-Ritz pencil
        // loses definiteness first. Which of the two comes first depends on the machine's
        // BLAS kernels (OpenBLAS picks them by CPU: one VM of this machine type stops, another
        // breaks down in ?sygvd); both must name the ways out.
        Err(e @ EigenError::SlepcLobpcgBreakdown { .. }) => {
            let text = Front::Flags.render(&e);
            assert!(
                text.contains("--slepc ks-sinvert")
                    && text.contains("--solver lobpcg")
                    && text.ends_with("ask for fewer modes"),
                "{text}"
            );
            advised_solvers_agree_with_dense(h.as_ref(), m.as_ref(), &req, &[], 27);
            return;
        }
        Err(e) => panic!("expected SLEPc's breakdown stop, got {e}"),
    };
    match partial.info.status {
        EigenStatus::SlepcLobpcgNotConverged {
            stop: SlepcLobpcgStop::Stopped { reason: -2 },
            converged,
            ..
        } => {
            let text = Front::Flags.render(&partial.clone().into_converged().unwrap_err());
            assert_eq!(converged, 28, "{text}");
            assert!(
                text.contains("with 28/31 pairs converged (tol 1.0e-8): it reports a breakdown")
                    && text.contains("--slepc ks-sinvert")
                    && text.contains("--solver lobpcg")
                    && text.ends_with("to keep SLEPc's LOBPCG, ask for fewer modes"),
                "{text}"
            );
        }
        EigenStatus::Converged => {
            panic!("SLEPc's LOBPCG no longer stops here: {:?}", partial.info)
        }
        ref other => panic!("expected SLEPc's breakdown stop, got {other:?}"),
    }
    advised_solvers_agree_with_dense(h.as_ref(), m.as_ref(), &req, &[], 27);
}

#[test]
fn an_aware_basis_through_slepc_equals_the_native_one() {
    use freeform::geometry::ShapeOptions;
    use freeform::io::read_shape;
    use freeform::material::Region;
    use freeform::precompute::{build_basis, BasisOptions, SolverConfig};
    // The grounded restricted pencil (precompute::boundary_modes) goes to SLEPc unchanged.
    let shape = read_shape("box:2,0.5,0.5", &ShapeOptions::default()).unwrap();
    let regions = vec![
        Region::HalfSpace {
            point: [0.5, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
        },
        Region::HalfSpace {
            point: [1.5, 0.0, 0.0],
            normal: [1.0, 0.0, 0.0],
        },
    ];
    let opts = |solver| BasisOptions {
        kernels: 200,
        modes: 6,
        boundary_regions: regions.clone(),
        solver,
        ..BasisOptions::default()
    };
    let native = build_basis(&shape, &opts(SolverConfig::lobpcg()), &Silent).unwrap();
    let slepc = build_basis(
        &shape,
        &opts(SolverConfig::slepc("ks-sinvert", "").unwrap()),
        &Silent,
    )
    .unwrap();
    assert_eq!(slepc.basis.modes(), 7);
    // Lifts do not depend on the eigensolver (one sparse solve on the same H_w; 1e-12 allows
    // for a different summation order); eigenvalues at tol 1e-8 agree to ~1e-12 relative
    // (they converge with the squared residual): 1e-8 is loose.
    let (a, b) = (&slepc.basis.coefficients, &native.basis.coefficients);
    for j in 0..2 {
        for i in 0..a.nrows() {
            assert!(
                (a[(i, j)] - b[(i, j)]).abs() < 1e-12,
                "lift {j}, kernel {i}"
            );
        }
    }
    let diff = max_rel_diff(&slepc.basis.eigenvalues, &native.basis.eigenvalues);
    assert!(diff < 1e-8, "eigenvalue diff {diff:e}");
}

/// Matrix-free through SLEPc: the element-loop Q1 operators on shell matrices give the
/// closed-form eigenvalues, with Jacobi from their diagonals and with the caller's
/// preconditioner; a failing operator and a failing preconditioner stop the solve with their
/// own message; row ranges that do not tile are refused.
#[test]
fn shell_matrices_solve_the_matrix_free_q1_laplacian() {
    use faer::{MatMut, MatRef};
    use freeform::eigen::q1_operator::{Q1Operator, Q1Part};
    use freeform::eigen::{FnOperator, LinearOperator, OperatorError, OperatorProblem};
    let hq = Q1Operator::new(N, H, Q1Part::Stiffness).unwrap();
    let mq = Q1Operator::new(N, H, Q1Part::Mass).unwrap();
    let exact = q1_fem_eigenvalues(N, H, 8);
    let solver = SlepcSolver::default();
    let jacobi = solver
        .solve_operators(&OperatorProblem::new(&hq, &mq), &request(1e-9), &Silent)
        .unwrap()
        .into_converged()
        .unwrap();
    // Residuals <= 1e-9 bound the eigenvalue errors far below 1e-8 (the bar).
    assert!(
        max_rel_diff(&jacobi.values, &exact) < 1e-8,
        "{:?}",
        jacobi.values
    );
    assert!(jacobi
        .info
        .notes
        .iter()
        .any(|n| n.contains("Jacobi from the operators")));
    // The caller's preconditioner: diag(H)^-1 from the assembled copy, as a closure.
    let (ha, _) = q1_fem(N, H);
    let inv: Vec<f64> = freeform::sparse::diagonal(ha.as_ref())
        .iter()
        .map(|d| 1.0 / d)
        .collect();
    let pre = |r: MatRef<'_, f64>, mut z: MatMut<'_, f64>| -> Result<(), OperatorError> {
        for j in 0..r.ncols() {
            for i in 0..r.nrows() {
                z[(i, j)] = r[(i, j)] * inv[i];
            }
        }
        Ok(())
    };
    let hn = hq.clone().without_diagonal();
    let mn = mq.clone().without_diagonal();
    let with_pre = OperatorProblem::new(&hn, &mn).with_preconditioner(&pre);
    let caller = solver
        .solve_operators(&with_pre, &request(1e-9), &Silent)
        .unwrap()
        .into_converged()
        .unwrap();
    assert!(max_rel_diff(&caller.values, &exact) < 1e-8);
    assert!(caller.info.notes.iter().any(|n| n.contains("the caller's")));
    // Failures inside SLEPc come back with the operator's own words.
    let k = hq.dim();
    let failing = FnOperator::new(k, |_: MatRef<'_, f64>, _: MatMut<'_, f64>| {
        Err(OperatorError::new("device lost"))
    });
    match solver.solve_operators(
        &OperatorProblem::new(&hq, &failing),
        &request(1e-9),
        &Silent,
    ) {
        Err(EigenError::Operator {
            which: "M",
            message,
        }) => {
            assert!(message.contains("device lost"), "{message}")
        }
        other => panic!("{other:?}"),
    }
    let bad_pre = |_: MatRef<'_, f64>, _: MatMut<'_, f64>| -> Result<(), OperatorError> {
        Err(OperatorError::new("no factor"))
    };
    let problem = OperatorProblem::new(&hn, &mn).with_preconditioner(&bad_pre);
    match solver.solve_operators(&problem, &request(1e-9), &Silent) {
        Err(EigenError::Operator {
            which: "preconditioner",
            message,
        }) => assert!(message.contains("no factor"), "{message}"),
        other => panic!("{other:?}"),
    }
    // One rank claiming only half the rows: the ranges do not tile 0..K.
    struct Half(Q1Operator);
    impl LinearOperator for Half {
        fn dim(&self) -> usize {
            self.0.dim()
        }
        fn local_rows(&self) -> std::ops::Range<usize> {
            0..self.0.dim() / 2
        }
        fn apply(&self, x: MatRef<'_, f64>, y: MatMut<'_, f64>) -> Result<(), OperatorError> {
            self.0.apply(x, y)
        }
    }
    let (hh, mh) = (Half(hq.clone()), Half(mq.clone()));
    match solver.solve_operators(&OperatorProblem::new(&hh, &mh), &request(1e-9), &Silent) {
        Err(EigenError::InvalidRequest(msg)) => assert!(msg.contains("do not tile"), "{msg}"),
        other => panic!("{other:?}"),
    }
}
