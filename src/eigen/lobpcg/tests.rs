//! LOBPCG against the dense oracle and analytic spectra.

use super::*;
use crate::eigen::dense::DenseSolver;
use crate::eigen::testing;
use crate::eigen::EigenStatus;
use crate::progress::Silent;
use crate::sparse::{self, SparseMatrix};
use faer::Mat;

fn request(nev: usize, tol: f64) -> EigenRequest {
    EigenRequest {
        nev,
        tol,
        max_iter: 500,
    }
}

/// sin of the largest principal angle, in the M-inner product, between span(a) and span(b),
/// both M-orthonormal with a.ncols() <= b.ncols(): the M-norm of the part of a outside span(b).
fn sin_largest_angle(m: SparseMatrixRef<'_>, a: &Mat<f64>, b: &Mat<f64>) -> f64 {
    let mut mb = Mat::zeros(b.nrows(), b.ncols());
    sparse::sym_mul_block(m, b.as_ref(), mb.as_mut());
    let coef = mb.transpose() * a;
    let e = a - b * &coef;
    let mut me = Mat::zeros(e.nrows(), e.ncols());
    sparse::sym_mul_block(m, e.as_ref(), me.as_mut());
    let g = e.transpose() * &me;
    let ev = g.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    ev.iter().fold(0.0f64, |x, &v| x.max(v)).max(0.0).sqrt()
}

/// Groups of indices of (nearly) equal eigenvalues: consecutive values within `rel` of each
/// other relative to the larger.
fn clusters(values: &[f64], rel: f64) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..=values.len() {
        if i == values.len()
            || (values[i] - values[i - 1]).abs() > rel * values[i].abs().max(1e-300)
        {
            out.push(start..i);
            start = i;
        }
    }
    out
}

/// Compare a LOBPCG solution with the dense one (which must hold extra pairs beyond the cut so
/// that a cluster split by the cut is complete in it): eigenvalues to `val_tol` relative,
/// each LOBPCG cluster inside the dense eigenspace of its cluster to `angle_tol`.
fn compare_with_dense(
    m: SparseMatrixRef<'_>,
    lob: &EigenSolution,
    dense: &EigenSolution,
    val_tol: f64,
    angle_tol: f64,
) {
    let nev = lob.values.len();
    assert_eq!(lob.values[0], 0.0);
    for j in 1..nev {
        let (a, b) = (lob.values[j], dense.values[j]);
        assert!(
            (a - b).abs() <= val_tol * b.abs(),
            "value {j}: lobpcg {a:.15e} dense {b:.15e}"
        );
    }
    for group in clusters(&dense.values, 1e-9) {
        if group.start >= nev {
            break;
        }
        let lob_cols = group.start..group.end.min(nev);
        let a = lob
            .vectors
            .as_ref()
            .subcols(lob_cols.start, lob_cols.len())
            .to_owned();
        let b = dense
            .vectors
            .as_ref()
            .subcols(group.start, group.len())
            .to_owned();
        let s = sin_largest_angle(m, &a, &b);
        assert!(
            s < angle_tol,
            "cluster {group:?}: sin(largest angle) = {s:.3e}"
        );
    }
}

fn assert_solution_quality(sol: &EigenSolution, tol: f64) {
    assert!(
        sol.info.max_relative_residual <= tol,
        "max residual {:.3e}",
        sol.info.max_relative_residual
    );
    assert!(
        sol.info.orthonormality_error <= 1e-10,
        "orthonormality {:.3e}",
        sol.info.orthonormality_error
    );
    assert!(
        sol.values.windows(2).all(|w| w[0] <= w[1]),
        "values not ascending"
    );
    assert_eq!(sol.values[0], 0.0);
}

#[test]
fn lobpcg_matches_dense_with_random_diagonal_mass() {
    // Wide-stencil Laplacian (radius 2: 33 entries per row) and an SPD kernel mass with a
    // random diagonal perturbation (seeded), K = 8 x 7 x 6 = 336, no analytic spectrum.
    let n = [8, 7, 6];
    let h = testing::grid_laplacian(n, 2.0);
    let m = testing::perturb_diagonal(
        (testing::kernel_mass(n, 2.0, 0.05, 0.3, 7)).as_ref(),
        0.5,
        11,
    );
    let nev = 17;
    let tol = 1e-10;
    let lob = Lobpcg::default()
        .solve_converged(h.as_ref(), m.as_ref(), &request(nev, tol), &Silent)
        .unwrap();
    let dense = DenseSolver
        .solve_converged(h.as_ref(), m.as_ref(), &request(nev + 8, tol), &Silent)
        .unwrap();
    // Residual 1e-10 * ||H|| (~30) and gaps >= ~1e-2 give eigenvalue errors ~ (3e-9)^2 / 1e-2
    // ~ 1e-15: 1e-8 relative is loose. Angles ~ residual * ||H|| / gap ~ 3e-7 worst case.
    assert_solution_quality(&lob, tol);
    compare_with_dense(m.as_ref(), &lob, &dense, 1e-8, 1e-6);
    assert_eq!(lob.info.solver, "lobpcg");
    assert!(lob.info.iterations > 0 && lob.info.matvecs > 0);
    // K = 336 has little fill: Auto takes the exact factorization.
    assert!(
        lob.info
            .notes
            .iter()
            .any(|n| n.starts_with("preconditioner: sparse Cholesky")),
        "{:?}",
        lob.info.notes
    );
}

#[test]
fn lobpcg_q1_fem_matches_analytic_and_dense() {
    // Consistent Q1 mass, box 9 x 8 x 7 nodes (K = 504), spacing 0.1: analytic eigenvalues.
    let n = [9, 8, 7];
    let hsp = 0.1;
    let (h, m) = testing::q1_fem(n, hsp);
    let nev = 21;
    let tol = 1e-10;
    let lob = Lobpcg::default()
        .solve_converged(h.as_ref(), m.as_ref(), &request(nev, tol), &Silent)
        .unwrap();
    assert_solution_quality(&lob, tol);
    let exact = testing::q1_fem_eigenvalues(n, hsp, nev);
    for j in 1..nev {
        // Eigenvalue error ~ residual^2 * ||H||^2 / gap: far below 1e-9 relative.
        assert!(
            (lob.values[j] - exact[j]).abs() <= 1e-9 * exact[j],
            "{j}: {} vs {}",
            lob.values[j],
            exact[j]
        );
    }
    let dense = DenseSolver
        .solve_converged(h.as_ref(), m.as_ref(), &request(nev + 8, tol), &Silent)
        .unwrap();
    compare_with_dense(m.as_ref(), &lob, &dense, 1e-8, 1e-6);
}

#[test]
fn lobpcg_cube_multiplicities_are_complete() {
    // 7-point Laplacian on a 7^3 cube, identity mass: eigenvalue multiplicities 1, 3, 3, 1, 3,
    // 6, ... The cut nev = 6 falls inside the 3-fold cluster (values 4..6 hold copies 1..3 of
    // it) and nev = 12 inside the 6-fold one. Every returned value must equal the dense one at
    // the same index (no copy skipped) and the returned vectors of a split cluster must lie in
    // its full eigenspace.
    let n = [7, 7, 7];
    let h = testing::grid_laplacian(n, 1.0);
    let m = testing::identity(343);
    let exact = testing::grid_laplacian_eigenvalues(n, 40);
    let dense = DenseSolver
        .solve_converged(h.as_ref(), m.as_ref(), &request(40, 1e-10), &Silent)
        .unwrap();
    let groups = clusters(&exact, 1e-9);
    let sizes: Vec<usize> = groups.iter().map(|g| g.len()).collect();
    assert_eq!(&sizes[..6], &[1, 3, 3, 1, 3, 6]);
    for nev in [5, 6, 8, 12, 17] {
        let tol = 1e-10;
        let lob = Lobpcg::default()
            .solve_converged(h.as_ref(), m.as_ref(), &request(nev, tol), &Silent)
            .unwrap();
        assert_solution_quality(&lob, tol);
        for j in 0..nev {
            // Analytic values; residual 1e-10 * 12 gives errors ~1e-18 relative to gaps 0.1.
            assert!(
                (lob.values[j] - exact[j]).abs() <= 1e-9 * exact[j].max(1.0),
                "nev {nev} value {j}"
            );
        }
        // Same multiplicities as the analytic spectrum, truncated at the cut.
        let got: Vec<usize> = clusters(&lob.values, 1e-9)
            .iter()
            .map(|g| g.len())
            .collect();
        let want: Vec<usize> = clusters(&exact[..nev], 1e-9)
            .iter()
            .map(|g| g.len())
            .collect();
        assert_eq!(got, want, "nev {nev}");
        compare_with_dense(m.as_ref(), &lob, &dense, 1e-8, 1e-6);
        if exact[nev] - exact[nev - 1] < 1e-9 {
            assert!(
                lob.info
                    .notes
                    .iter()
                    .any(|n| n.contains("splits a cluster")),
                "nev {nev}: no split note"
            );
        }
    }
}

#[test]
fn lobpcg_is_deterministic() {
    let n = [6, 6, 5];
    let h = testing::grid_laplacian(n, 1.8);
    let m = testing::kernel_mass(n, 1.8, 0.05, 0.5, 3);
    let req = request(9, 1e-9);
    let a = Lobpcg::default()
        .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
        .unwrap();
    let b = Lobpcg::default()
        .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
        .unwrap();
    // Bit-identical: compare the f64 bit patterns.
    let bits = |s: &EigenSolution| -> Vec<u64> {
        s.values
            .iter()
            .map(|v| v.to_bits())
            .chain(
                (0..s.vectors.ncols())
                    .flat_map(|j| (0..s.vectors.nrows()).map(move |i| (i, j)))
                    .map(|(i, j)| s.vectors[(i, j)].to_bits()),
            )
            .collect()
    };
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a.info.iterations, b.info.iterations);
    // A different seed converges to the same values (to the tolerance) with other bits.
    let other = Lobpcg::new(LobpcgOptions {
        seed: 99,
        ..LobpcgOptions::default()
    })
    .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
    .unwrap();
    for (x, y) in a.values.iter().zip(&other.values) {
        assert!((x - y).abs() <= 1e-9 * y.abs());
    }
}

#[test]
fn lobpcg_not_converged_keeps_partial_result() {
    let n = [8, 8, 8];
    let h = testing::grid_laplacian(n, 1.0);
    let m = testing::identity(512);
    let req = EigenRequest {
        nev: 10,
        tol: 1e-12,
        max_iter: 2,
    };
    let opts = LobpcgOptions {
        preconditioner: PreconditionerKind::Jacobi,
        ..LobpcgOptions::default()
    };
    // Not converged is a status on the result, with the result in hand.
    let partial = Lobpcg::new(opts)
        .solve(h.as_ref(), m.as_ref(), &req, &Silent)
        .unwrap();
    assert!(!partial.converged());
    match partial.info.status {
        EigenStatus::NotConverged {
            iterations,
            converged,
            nev,
            max_residual,
            ..
        } => {
            assert_eq!(iterations, 2);
            assert_eq!(nev, 10);
            assert!(converged < 10);
            assert_eq!(partial.values.len(), 10);
            assert_eq!(
                (partial.vectors.nrows(), partial.vectors.ncols()),
                (512, 10)
            );
            assert_eq!(partial.info.residuals.len(), 10);
            assert!(max_residual > 1e-12 && max_residual == partial.info.max_relative_residual);
            // The partial vectors are still M-orthonormal and the constant mode is exact.
            assert!(partial.info.orthonormality_error < 1e-10);
            assert_eq!(partial.values[0], 0.0);
            assert!(partial.info.residuals[0] < 1e-14);
        }
        ref other => panic!("expected NotConverged, got {other:?}"),
    }
    // Where a converged result is required, the status becomes the error, with the same
    // figures and the result as `partial`.
    let values = partial.values.clone();
    match partial.into_converged() {
        Err(
            ref e @ EigenError::NotConverged {
                iterations,
                converged,
                nev,
                ref partial,
                ..
            },
        ) => {
            assert_eq!((iterations, nev), (2, 10));
            assert!(converged < 10);
            assert_eq!(partial.values, values);
            assert!(
                e.to_string().starts_with(&format!(
                    "eigensolver did not converge in 2 iterations: {converged}/10 pairs below \
                     tol 1.0e-12 (max relative residual "
                )),
                "{e}"
            );
        }
        other => panic!("expected NotConverged, got {other:?}"),
    }
    assert!(matches!(
        Lobpcg::new(LobpcgOptions {
            preconditioner: PreconditionerKind::Jacobi,
            ..LobpcgOptions::default()
        })
        .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent),
        Err(EigenError::NotConverged { .. })
    ));
}

#[test]
fn lobpcg_rejects_invalid_input() {
    let n = [4, 4, 4];
    let h = testing::grid_laplacian(n, 1.0);
    let m = testing::identity(64);
    let solver = Lobpcg::default();
    // nev = K - 1 too large; K - 2 is the largest accepted.
    assert!(matches!(
        solver.solve(h.as_ref(), m.as_ref(), &request(63, 1e-8), &Silent),
        Err(EigenError::InvalidRequest(_))
    ));
    assert!(matches!(
        solver.solve(h.as_ref(), m.as_ref(), &request(0, 1e-8), &Silent),
        Err(EigenError::InvalidRequest(_))
    ));
    assert!(matches!(
        solver.solve(h.as_ref(), m.as_ref(), &request(4, 0.0), &Silent),
        Err(EigenError::InvalidRequest(_))
    ));
    let mut nan = h.clone();
    nan.val_mut()[3] = f64::NAN;
    assert!(matches!(
        solver.solve(nan.as_ref(), m.as_ref(), &request(4, 1e-8), &Silent),
        Err(EigenError::NonFinite(_))
    ));
    let mut inf = m.clone();
    inf.val_mut()[3] = f64::INFINITY;
    assert!(matches!(
        solver.solve(h.as_ref(), inf.as_ref(), &request(4, 1e-8), &Silent),
        Err(EigenError::NonFinite(_))
    ));
    // Asymmetric H.
    let t = [
        (0usize, 1usize, -1.0),
        (1, 0, -0.5),
        (0, 0, 1.0),
        (1, 1, 0.5),
        (2, 2, 0.0),
        (3, 3, 0.0),
    ];
    let trip: Vec<_> = t
        .iter()
        .map(|&(i, j, v)| faer::sparse::Triplet::new(i as u32, j as u32, v))
        .collect();
    let asym = faer::sparse::SparseColMat::try_new_from_triplets(4, 4, &trip).unwrap();
    assert!(matches!(
        solver.solve(
            asym.as_ref(),
            (testing::identity(4)).as_ref(),
            &request(1, 1e-8),
            &Silent
        ),
        Err(EigenError::InvalidRequest(_))
    ));
    // M with a negative diagonal entry.
    let mut neg = m.clone();
    neg.val_mut()[5] = -1.0;
    assert!(matches!(
        solver.solve(h.as_ref(), neg.as_ref(), &request(4, 1e-8), &Silent),
        Err(EigenError::NotPositiveDefinite { what: "M", .. })
    ));
    // M with a positive diagonal but indefinite: I + 0.5 A (A the 7-point adjacency, whose
    // eigenvalues reach -6 on a bipartite grid, so M has eigenvalues down to about -2).
    let mut indef = h.clone();
    for j in 0..indef.ncols() {
        let range = indef.symbolic().col_range(j);
        let rows: Vec<usize> = indef.symbolic().row_idx()[range.clone()]
            .iter()
            .map(|&i| i as usize)
            .collect();
        for (p, i) in range.zip(rows) {
            indef.val_mut()[p] = if i == j { 1.0 } else { 0.5 };
        }
    }
    let err = solver
        .solve(h.as_ref(), indef.as_ref(), &request(4, 1e-8), &Silent)
        .unwrap_err();
    assert!(
        matches!(err, EigenError::NotPositiveDefinite { what: "M", .. }),
        "{err}"
    );
    // Shape mismatch.
    assert!(matches!(
        solver.solve(
            h.as_ref(),
            (testing::identity(63)).as_ref(),
            &request(4, 1e-8),
            &Silent
        ),
        Err(EigenError::InvalidRequest(_))
    ));
}

#[test]
fn lobpcg_nev_one_is_the_constant_mode() {
    let (h, m) = testing::q1_fem([4, 4, 4], 0.5);
    let sol = Lobpcg::default()
        .solve_converged(h.as_ref(), m.as_ref(), &request(1, 1e-8), &Silent)
        .unwrap();
    assert_eq!(sol.values, vec![0.0]);
    assert!(sol.info.max_relative_residual < 1e-14);
    assert!(sol.info.orthonormality_error < 1e-14);
}

#[test]
fn lobpcg_every_preconditioner_converges() {
    // Same answer with Cholesky, Jacobi and no preconditioner (more iterations for the
    // weaker ones), on a problem small enough for the unpreconditioned case.
    let n = [6, 5, 5];
    let h = testing::grid_laplacian(n, 1.5);
    let m = testing::kernel_mass(n, 1.5, 0.1, 0.3, 5);
    let req = EigenRequest {
        nev: 8,
        tol: 1e-9,
        max_iter: 2000,
    };
    let mut iterations = Vec::new();
    let mut reference: Option<Vec<f64>> = None;
    for kind in [
        PreconditionerKind::Cholesky,
        PreconditionerKind::Jacobi,
        PreconditionerKind::Identity,
    ] {
        let opts = LobpcgOptions {
            preconditioner: kind,
            ..LobpcgOptions::default()
        };
        let sol = Lobpcg::new(opts)
            .solve_converged(h.as_ref(), m.as_ref(), &req, &Silent)
            .unwrap();
        assert_solution_quality(&sol, 1e-9);
        iterations.push(sol.info.iterations);
        match &reference {
            None => reference = Some(sol.values.clone()),
            Some(r) => {
                for (a, b) in sol.values.iter().zip(r) {
                    assert!((a - b).abs() <= 1e-9 * b.abs());
                }
            }
        }
    }
    // The exact factorization needs the fewest iterations.
    assert!(
        iterations[0] < iterations[1] && iterations[0] < iterations[2],
        "{iterations:?}"
    );
}

#[test]
fn lobpcg_restarts_and_recomputes_still_converge() {
    // restart_tol = 1 makes every Rayleigh-Ritz step with a P block restart without it, and
    // recompute_every = 1 recomputes H X, M X, H P, M P every iteration: the same answer.
    let n = [7, 6, 5];
    let h = testing::grid_laplacian(n, 1.5);
    let m = testing::kernel_mass(n, 1.5, 0.05, 0.5, 8);
    let tol = 1e-10;
    let opts = LobpcgOptions {
        restart_tol: 1.0,
        recompute_every: 1,
        ..LobpcgOptions::default()
    };
    let lob = Lobpcg::new(opts)
        .solve_converged(h.as_ref(), m.as_ref(), &request(9, tol), &Silent)
        .unwrap();
    assert_solution_quality(&lob, tol);
    assert!(lob.info.restarts > 0 && lob.info.restarts <= lob.info.iterations);
    let reference = Lobpcg::default()
        .solve_converged(h.as_ref(), m.as_ref(), &request(9, tol), &Silent)
        .unwrap();
    for (a, b) in lob.values.iter().zip(&reference.values) {
        // Both to residual 1e-10: eigenvalues agree far below 1e-9 relative.
        assert!((a - b).abs() <= 1e-9 * b.abs());
    }
}

#[test]
fn lobpcg_largest_request_fills_the_space() {
    // nev = K - 2 (the largest accepted): the block is clipped to the K - 1 dimensional
    // complement of the constant, every new direction is dropped, and the explicit check
    // confirms the exact Rayleigh-Ritz answer.
    let n = [3, 3, 3];
    let h = testing::grid_laplacian(n, 1.0);
    let m = testing::identity(27);
    let tol = 1e-10;
    let lob = Lobpcg::default()
        .solve_converged(h.as_ref(), m.as_ref(), &request(25, tol), &Silent)
        .unwrap();
    assert_solution_quality(&lob, tol);
    let exact = testing::grid_laplacian_eigenvalues(n, 25);
    for (a, b) in lob.values.iter().zip(&exact) {
        assert!((a - b).abs() <= 1e-12 * b.max(1.0), "{a} vs {b}");
    }
}

#[test]
fn auto_skips_the_symbolic_analysis_when_the_factor_cannot_fit() {
    // An entry budget below twice the lower triangle: no factor can fit (the least fill seen
    // is 2.8x), so Auto goes to IC(0) without analysing, never escalates, and still converges
    // to the dense reference's pairs.
    let n = [6, 6, 6];
    let h = testing::grid_laplacian(n, 2.0);
    let m = testing::kernel_mass(n, 2.0, 0.05, 0.5, 12);
    let lower = (h.compute_nnz() + h.nrows()) / 2;
    let tol = 1e-10;
    let opts = LobpcgOptions {
        max_factor_entries: lower,
        escalate_after: Some(2),
        ..LobpcgOptions::default()
    };
    let sol = Lobpcg::new(opts)
        .solve_converged(h.as_ref(), m.as_ref(), &request(9, tol), &Silent)
        .unwrap();
    assert_solution_quality(&sol, tol);
    let notes = &sol.info.notes;
    assert!(
        notes
            .iter()
            .any(|n| n.contains("using IC(0) without the symbolic analysis")),
        "{notes:?}"
    );
    assert!(
        !notes
            .iter()
            .any(|n| n.contains("switched to the exact Cholesky")),
        "{notes:?}"
    );
    let reference = DenseSolver
        .solve_converged(h.as_ref(), m.as_ref(), &request(12, tol), &Silent)
        .unwrap();
    compare_with_dense(m.as_ref(), &sol, &reference, 1e-8, 1e-6);
}

#[test]
fn auto_switches_from_ic0_to_cholesky_when_slow() {
    // max_fill_ratio = 0 forces Auto onto IC(0); after 2 iterations it must switch to the
    // exact factor (which fits in max_factor_entries) and converge to the same pairs.
    let n = [6, 6, 6];
    let h = testing::grid_laplacian(n, 2.0);
    let m = testing::kernel_mass(n, 2.0, 0.05, 0.5, 12);
    let tol = 1e-10;
    let opts = LobpcgOptions {
        max_fill_ratio: 0.0,
        escalate_after: Some(2),
        ..LobpcgOptions::default()
    };
    let sol = Lobpcg::new(opts)
        .solve_converged(h.as_ref(), m.as_ref(), &request(9, tol), &Silent)
        .unwrap();
    assert_solution_quality(&sol, tol);
    assert!(
        sol.info
            .notes
            .iter()
            .any(|n| n.contains("using IC(0) instead")),
        "{:?}",
        sol.info.notes
    );
    assert!(
        sol.info
            .notes
            .iter()
            .any(|n| n.contains("switched to the exact Cholesky")),
        "{:?}",
        sol.info.notes
    );
    assert!(sol
        .info
        .notes
        .iter()
        .any(|n| n.starts_with("preconditioner: sparse Cholesky")));
    let reference = DenseSolver
        .solve_converged(h.as_ref(), m.as_ref(), &request(12, tol), &Silent)
        .unwrap();
    compare_with_dense(m.as_ref(), &sol, &reference, 1e-8, 1e-6);
}

#[test]
fn lobpcg_incomplete_cholesky_matches_dense() {
    // IC(0) on a wide stencil (radius 2.5: 81 entries per row) with a non-trivial mass.
    let n = [8, 8, 7];
    let h = testing::grid_laplacian(n, 2.5);
    let m = testing::kernel_mass(n, 2.5, 0.05, 0.4, 21);
    let tol = 1e-10;
    let opts = LobpcgOptions {
        preconditioner: PreconditionerKind::IncompleteCholesky,
        ..LobpcgOptions::default()
    };
    let lob = Lobpcg::new(opts)
        .solve_converged(h.as_ref(), m.as_ref(), &request(13, tol), &Silent)
        .unwrap();
    assert_solution_quality(&lob, tol);
    assert!(
        lob.info.notes.iter().any(|n| n.contains("IC(0)")),
        "{:?}",
        lob.info.notes
    );
    let dense = DenseSolver
        .solve_converged(h.as_ref(), m.as_ref(), &request(21, tol), &Silent)
        .unwrap();
    // Same tolerances and reasoning as the Cholesky comparison above.
    compare_with_dense(m.as_ref(), &lob, &dense, 1e-8, 1e-6);
}

#[test]
fn lobpcg_same_bits_for_any_thread_count() {
    // Every kernel splits work by fixed row chunks, the IC(0) solves by columns (which does
    // not change any column's arithmetic) and the Cholesky solves by groups of columns whose
    // width depends on the block only (16 modes and 8 guards: two groups), so 1, 2 and 3
    // threads agree bit for bit.
    let n = [7, 6, 6];
    let h = testing::grid_laplacian(n, 2.0);
    let m = testing::kernel_mass(n, 2.0, 0.05, 0.5, 4);
    for (preconditioner, modes) in [
        (PreconditionerKind::IncompleteCholesky, 9),
        (PreconditionerKind::Cholesky, 16),
    ] {
        let opts = LobpcgOptions {
            preconditioner,
            ..LobpcgOptions::default()
        };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                Lobpcg::new(opts.clone())
                    .solve_converged(h.as_ref(), m.as_ref(), &request(modes, 1e-9), &Silent)
                    .unwrap()
            })
        };
        let bits = |s: &EigenSolution| -> Vec<u64> {
            let mut out: Vec<u64> = s.values.iter().map(|v| v.to_bits()).collect();
            for j in 0..s.vectors.ncols() {
                out.extend((0..s.vectors.nrows()).map(|i| s.vectors[(i, j)].to_bits()));
            }
            out
        };
        let one = bits(&run(1));
        assert_eq!(one, bits(&run(2)), "{preconditioner:?}");
        assert_eq!(one, bits(&run(3)), "{preconditioner:?}");
    }
}

/// A 7-point grid Laplacian minus 5 (e_i - e_j)(e_i - e_j)^T on an interior edge: still zero
/// row sums and a positive diagonal, but x = e_i - e_j gives x^T H x = 14 - 20 < 0.
fn indefinite_laplacian(n: [usize; 3]) -> SparseMatrix {
    let h = testing::grid_laplacian(n, 1.0);
    let (i, j) = (n[0] * (n[1] + 1) + 1, n[0] * (n[1] + 1) + 2);
    let mut t = Vec::new();
    for c in 0..h.ncols() {
        let range = h.symbolic().col_range(c);
        for (&r, &v) in h.symbolic().row_idx()[range.clone()]
            .iter()
            .zip(&h.val()[range])
        {
            t.push(faer::sparse::Triplet::new(r, c as u32, v));
        }
    }
    for (r, c, v) in [(i, i, -5.0), (j, j, -5.0), (i, j, 5.0), (j, i, 5.0)] {
        t.push(faer::sparse::Triplet::new(r as u32, c as u32, v));
    }
    faer::sparse::SparseColMat::try_new_from_triplets(h.nrows(), h.ncols(), &t).unwrap()
}

#[test]
fn preconditioner_fallbacks_are_recorded() {
    let n = [5, 5, 5];
    let h = indefinite_laplacian(n);
    let m = testing::identity(125);
    // Cholesky fails (H + sigma M is indefinite), is retried with sigma x 100, then Jacobi.
    let opts = LobpcgOptions {
        preconditioner: PreconditionerKind::Cholesky,
        ..LobpcgOptions::default()
    };
    let (pre, report) =
        precondition::build(h.as_ref(), m.as_ref(), &opts, 8, faer::Par::Seq).unwrap();
    assert!(
        matches!(pre, precondition::Preconditioner::Jacobi { .. }),
        "{pre:?}"
    );
    assert!(
        report
            .notes
            .iter()
            .any(|n| n.contains("retrying with sigma x 100")),
        "{:?}",
        report.notes
    );
    assert!(report
        .notes
        .iter()
        .any(|n| n.contains("falling back to Jacobi")));
    assert_eq!(
        report.sigma,
        100.0 * precondition::shift(h.as_ref(), m.as_ref(), &opts)
    );
    // IC(0) breaks down for every diagonal shift (the 2 x 2 block [2 4; 4 2] stays
    // indefinite even with alpha = 1), then Jacobi.
    let opts = LobpcgOptions {
        preconditioner: PreconditionerKind::IncompleteCholesky,
        ..LobpcgOptions::default()
    };
    let (pre, report) =
        precondition::build(h.as_ref(), m.as_ref(), &opts, 8, faer::Par::Seq).unwrap();
    assert!(matches!(pre, precondition::Preconditioner::Jacobi { .. }));
    assert_eq!(
        report
            .notes
            .iter()
            .filter(|n| n.contains("IC(0) broke down"))
            .count(),
        5
    );
    // The solve itself then finds the negative eigenvalue and reports that H is not PSD.
    let err = Lobpcg::default()
        .solve(h.as_ref(), m.as_ref(), &request(4, 1e-8), &Silent)
        .unwrap_err();
    assert!(
        matches!(err, EigenError::NotPositiveDefinite { what: "H", .. }),
        "{err}"
    );
}

/// Measurement harness (not a unit test): LOBPCG on a wide-stencil grid Laplacian with a
/// kernel mass. Environment: N (grid side, default 22), R (stencil radius, default 3),
/// NEV (default 33), TOL (default 1e-8), PRE (auto|cholesky|jacobi|identity), GUARD, SHIFT
/// (shift_factor). Run with
/// `cargo test --release --lib measure_lobpcg -- --ignored --nocapture`.
#[test]
#[ignore]
fn measure_lobpcg() {
    fn env<T: std::str::FromStr>(name: &str, default: T) -> T {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    }
    let n: usize = env("N", 22);
    let r: f64 = env("R", 3.0);
    let dims = [n, n, n];
    let t = std::time::Instant::now();
    let h = testing::grid_laplacian(dims, r);
    let m = testing::kernel_mass(dims, r, 0.05, 0.5, 1);
    let k = h.nrows();
    eprintln!(
        "K = {k}, nnz/row = {:.1}, build {:.2} s",
        h.val().len() as f64 / k as f64,
        t.elapsed().as_secs_f64()
    );
    let pre = match std::env::var("PRE").as_deref() {
        Ok("cholesky") => PreconditionerKind::Cholesky,
        Ok("jacobi") => PreconditionerKind::Jacobi,
        Ok("ic0") => PreconditionerKind::IncompleteCholesky,
        Ok("identity") => PreconditionerKind::Identity,
        _ => PreconditionerKind::Auto,
    };
    let defaults = LobpcgOptions::default();
    let opts = LobpcgOptions {
        preconditioner: pre,
        guard: std::env::var("GUARD").ok().and_then(|v| v.parse().ok()),
        shift_factor: env("SHIFT", defaults.shift_factor),
        ..defaults
    };
    let req = EigenRequest {
        nev: env("NEV", 33),
        tol: env("TOL", 1e-8),
        max_iter: env("MAXIT", 1000),
    };
    let t = std::time::Instant::now();
    let result = Lobpcg::new(opts).solve(h.as_ref(), m.as_ref(), &req, &Silent);
    let secs = t.elapsed().as_secs_f64();
    let sol = result.unwrap_or_else(|e| panic!("{e}"));
    if !sol.converged() {
        eprintln!("NOT CONVERGED");
    }
    eprintln!(
        "time {secs:.2} s, iterations {}, restarts {}, matvecs {}, max residual {:.2e}, orthonormality {:.2e}",
        sol.info.iterations, sol.info.restarts, sol.info.matvecs, sol.info.max_relative_residual, sol.info.orthonormality_error
    );
    eprintln!(
        "values[1..4] {:?} last {:e}",
        &sol.values[1..4],
        sol.values[sol.values.len() - 1]
    );
    {
        let v = &sol.vectors;
        let mut mv = Mat::zeros(v.nrows(), v.ncols());
        sparse::sym_mul_block(m.as_ref(), v.as_ref(), mv.as_mut());
        let g = v.transpose() * &mv;
        let nev = v.ncols();
        let (mut e0, mut e1) = (0.0f64, 0.0f64);
        for j in 0..nev {
            for i in 0..nev {
                let e = (g[(i, j)] - if i == j { 1.0 } else { 0.0 }).abs();
                if i == 0 || j == 0 {
                    e0 = e0.max(e)
                } else {
                    e1 = e1.max(e)
                }
            }
        }
        eprintln!("orthonormality: constant-mode row/col {e0:.2e}, the rest {e1:.2e}");
        let ones = Mat::from_fn(v.nrows(), 1, |_, _| 1.0);
        let mut m1 = Mat::zeros(v.nrows(), 1);
        sparse::sym_mul_block(m.as_ref(), ones.as_ref(), m1.as_mut());
        let c = m1.transpose() * v;
        let c2 = ones.transpose() * &mv;
        eprintln!(
            "(M1)^T x: {:.2e} {:.2e}; 1^T (M x): {:.2e} {:.2e}; y0 {:.3e}",
            c[(0, 1)],
            c[(0, 5)],
            c2[(0, 1)],
            c2[(0, 5)],
            v[(0, 0)]
        );
    }
    for note in &sol.info.notes {
        eprintln!("note: {note}");
    }
}

#[test]
fn upper_triangle_storage_matches_both_triangles() {
    // The same pencil stored as upper triangles gives the same bits: the two-pass kernel adds
    // each output row's terms in ascending column order starting from zero (the gather of
    // the row's lower part, then the scatters of later columns, the second pass last), the
    // order the both-triangle kernel uses; the IC(0) factor has the same values; the norms
    // are the same sums, and the constant mode's compensated sum of M's entries (taken in
    // another order) is correctly rounded either way.
    let n = [8, 7, 7];
    let h = testing::grid_laplacian(n, 2.0);
    let m = testing::kernel_mass(n, 2.0, 0.05, 0.4, 8);
    let upper = crate::triangle::UpperPencil::from_full(h.as_ref(), m.as_ref()).unwrap();
    let tol = 1e-10;
    let opts = LobpcgOptions {
        preconditioner: PreconditionerKind::IncompleteCholesky,
        ..LobpcgOptions::default()
    };
    let solver = Lobpcg::new(opts);
    let full = solver
        .solve_converged(h.as_ref(), m.as_ref(), &request(11, tol), &Silent)
        .unwrap();
    let (hu, mu) = (upper.first(), upper.second());
    let tri = solver
        .solve_operators(&OperatorProblem::new(&hu, &mu), &request(11, tol), &Silent)
        .unwrap()
        .into_converged()
        .unwrap();
    assert_solution_quality(&tri, tol);
    assert!(
        tri.info.notes.iter().any(|n| n.contains("upper triangles")),
        "{:?}",
        tri.info.notes
    );
    assert!(tri.info.notes.iter().any(|n| n.contains("IC(0)")));
    assert_eq!(tri.info.iterations, full.info.iterations);
    assert_eq!(tri.values, full.values);
    assert_eq!(tri.vectors, full.vectors);
    // The exact 1-norms are those of both-triangle storage.
    assert_eq!(hu.norm_1(), sparse::norm_1(h.as_ref()));
    assert_eq!(mu.norm_1(), sparse::norm_1(m.as_ref()));
    // The exact factor from the upper triangle (faer's `Side::Upper`), as `Auto` takes it at
    // this size: the same factor as from both triangles, up to the order of its sums.
    for kind in [PreconditionerKind::Cholesky, PreconditionerKind::Auto] {
        let solver = Lobpcg::new(LobpcgOptions {
            preconditioner: kind,
            ..LobpcgOptions::default()
        });
        let full = solver
            .solve_converged(h.as_ref(), m.as_ref(), &request(11, tol), &Silent)
            .unwrap();
        let tri = solver
            .solve_operators(&OperatorProblem::new(&hu, &mu), &request(11, tol), &Silent)
            .unwrap()
            .into_converged()
            .unwrap();
        assert!(tri.info.notes.iter().any(|n| n.contains("sparse Cholesky")));
        assert_solution_quality(&tri, tol);
        // A Ritz value's error is ~ the squared residual (1e-20 relative here): 1e-12
        // leaves room for rounding only.
        for (a, b) in full.values.iter().zip(&tri.values) {
            assert!((a - b).abs() <= 1e-12 * a.abs(), "{kind:?}: {a} vs {b}");
        }
    }
}
