//! LOBPCG against the dense oracle and analytic spectra.

use super::*;
use crate::eigen::dense::DenseSolver;
use crate::eigen::testing;
use crate::progress::Silent;

fn request(nev: usize, tol: f64) -> EigenRequest {
    EigenRequest {
        nev,
        tol,
        max_iter: 500,
    }
}

/// sin of the largest principal angle, in the M-inner product, between span(a) and span(b),
/// both M-orthonormal with a.ncols() <= b.ncols(): the M-norm of the part of a outside span(b).
fn sin_largest_angle(m: &SparseMatrix, a: &Mat<f64>, b: &Mat<f64>) -> f64 {
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
    m: &SparseMatrix,
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
    let m = testing::perturb_diagonal(&testing::kernel_mass(n, 2.0, 0.05, 0.3, 7), 0.5, 11);
    let nev = 17;
    let tol = 1e-10;
    let lob = Lobpcg::default()
        .solve(&h, &m, &request(nev, tol), &Silent)
        .unwrap();
    let dense = DenseSolver
        .solve(&h, &m, &request(nev + 8, tol), &Silent)
        .unwrap();
    // Residual 1e-10 * ||H|| (~30) and gaps >= ~1e-2 give eigenvalue errors ~ (3e-9)^2 / 1e-2
    // ~ 1e-15: 1e-8 relative is loose. Angles ~ residual * ||H|| / gap ~ 3e-7 worst case.
    assert_solution_quality(&lob, tol);
    compare_with_dense(&m, &lob, &dense, 1e-8, 1e-6);
    assert_eq!(lob.info.solver, "lobpcg");
    assert!(lob.info.iterations > 0 && lob.info.matvecs > 0);
    assert!(lob.info.notes.iter().any(|n| n.contains("Cholesky")));
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
        .solve(&h, &m, &request(nev, tol), &Silent)
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
        .solve(&h, &m, &request(nev + 8, tol), &Silent)
        .unwrap();
    compare_with_dense(&m, &lob, &dense, 1e-8, 1e-6);
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
        .solve(&h, &m, &request(40, 1e-10), &Silent)
        .unwrap();
    let groups = clusters(&exact, 1e-9);
    let sizes: Vec<usize> = groups.iter().map(|g| g.len()).collect();
    assert_eq!(&sizes[..6], &[1, 3, 3, 1, 3, 6]);
    for nev in [5, 6, 8, 12, 17] {
        let tol = 1e-10;
        let lob = Lobpcg::default()
            .solve(&h, &m, &request(nev, tol), &Silent)
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
        compare_with_dense(&m, &lob, &dense, 1e-8, 1e-6);
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
    let a = Lobpcg::default().solve(&h, &m, &req, &Silent).unwrap();
    let b = Lobpcg::default().solve(&h, &m, &req, &Silent).unwrap();
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
    .solve(&h, &m, &req, &Silent)
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
    match Lobpcg::new(opts).solve(&h, &m, &req, &Silent) {
        Err(EigenError::NotConverged {
            iterations,
            converged,
            nev,
            partial,
            max_residual,
            ..
        }) => {
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
        other => panic!("expected NotConverged, got {other:?}"),
    }
}

#[test]
fn lobpcg_rejects_invalid_input() {
    let n = [4, 4, 4];
    let h = testing::grid_laplacian(n, 1.0);
    let m = testing::identity(64);
    let solver = Lobpcg::default();
    // nev = K - 1 too large; K - 2 is the largest accepted.
    assert!(matches!(
        solver.solve(&h, &m, &request(63, 1e-8), &Silent),
        Err(EigenError::InvalidRequest(_))
    ));
    assert!(matches!(
        solver.solve(&h, &m, &request(0, 1e-8), &Silent),
        Err(EigenError::InvalidRequest(_))
    ));
    assert!(matches!(
        solver.solve(&h, &m, &request(4, 0.0), &Silent),
        Err(EigenError::InvalidRequest(_))
    ));
    let mut nan = h.clone();
    nan.val_mut()[3] = f64::NAN;
    assert!(matches!(
        solver.solve(&nan, &m, &request(4, 1e-8), &Silent),
        Err(EigenError::NonFinite(_))
    ));
    let mut inf = m.clone();
    inf.val_mut()[3] = f64::INFINITY;
    assert!(matches!(
        solver.solve(&h, &inf, &request(4, 1e-8), &Silent),
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
        .map(|&(i, j, v)| faer::sparse::Triplet::new(i, j, v))
        .collect();
    let asym = faer::sparse::SparseColMat::try_new_from_triplets(4, 4, &trip).unwrap();
    assert!(matches!(
        solver.solve(&asym, &testing::identity(4), &request(1, 1e-8), &Silent),
        Err(EigenError::InvalidRequest(_))
    ));
    // M with a negative diagonal entry.
    let mut neg = m.clone();
    neg.val_mut()[5] = -1.0;
    assert!(matches!(
        solver.solve(&h, &neg, &request(4, 1e-8), &Silent),
        Err(EigenError::NotPositiveDefinite { what: "M", .. })
    ));
    // Shape mismatch.
    assert!(matches!(
        solver.solve(&h, &testing::identity(63), &request(4, 1e-8), &Silent),
        Err(EigenError::InvalidRequest(_))
    ));
}

#[test]
fn lobpcg_nev_one_is_the_constant_mode() {
    let (h, m) = testing::q1_fem([4, 4, 4], 0.5);
    let sol = Lobpcg::default()
        .solve(&h, &m, &request(1, 1e-8), &Silent)
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
        let sol = Lobpcg::new(opts).solve(&h, &m, &req, &Silent).unwrap();
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
