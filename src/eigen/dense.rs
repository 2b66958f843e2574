//! Dense reference solver: densify, Cholesky M = L L^T, eigendecomposition of
//! C = L^-1 H L^-T, back-solve x = L^-T z.
//!
//! faer has no dense generalized symmetric-definite eigensolver, so the standard reduction is
//! done by hand (residual ~5e-13 at K = 300 per the crate notes). The constant mode is deflated
//! exactly, as in LOBPCG: with z0 = L^T y0 (unit norm, y0 = 1/sqrt(1^T M 1)) the matrix
//! decomposed is P C P - z0 z0^T with P = I - z0 z0^T, so z0 is an exact eigenvector (value -1,
//! hence first) and every other eigenvector is orthogonal to it to working precision; the first
//! pair is then returned as (0, y0) exactly. O(K^3) time, ~5 K^2 doubles of memory: K is
//! limited to [`DENSE_MAX_K`].

use super::{
    check_solution, constant_mode, validate_problem, EigenError, EigenInfo, EigenRequest,
    EigenSolution, Eigensolver,
};
use crate::progress::Progress;
use crate::sparse::{self, SparseMatrixRef};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Mat, Par, Side};

/// Largest K the dense solver accepts: at K = 6000 it holds ~5 dense K x K matrices
/// (1.4 GB) and the eigendecomposition takes on the order of a minute on 2 cores.
pub const DENSE_MAX_K: usize = 6000;

/// Dense reference eigensolver (name "dense"). Exact up to round-off; the oracle of the
/// LOBPCG tests. Refuses K > [`DENSE_MAX_K`] with [`EigenError::TooLarge`].
#[derive(Debug, Clone, Copy, Default)]
pub struct DenseSolver;

impl Eigensolver for DenseSolver {
    fn name(&self) -> &'static str {
        "dense"
    }

    fn solve(
        &self,
        h: SparseMatrixRef<'_>,
        m: SparseMatrixRef<'_>,
        request: &EigenRequest,
        progress: &dyn Progress,
    ) -> Result<EigenSolution, EigenError> {
        let k = h.nrows();
        if k > DENSE_MAX_K {
            return Err(EigenError::TooLarge {
                solver: "dense",
                k,
                limit: DENSE_MAX_K,
            });
        }
        validate_problem(h, m, request)?;
        progress.begin("eigen (dense)", None);
        let nev = request.nev;
        let par = Par::rayon(0);
        let y0 = constant_mode(m)?;

        let md = sparse::to_dense(m);
        let llt = md
            .llt(Side::Lower)
            .map_err(|e| EigenError::NotPositiveDefinite {
                what: "M",
                detail: format!("dense Cholesky failed: {e:?}"),
            })?;
        let l = llt.L();
        // C = L^-1 H L^-T: Y = L^-1 H, then C = L^-1 Y^T (H symmetric).
        let mut y = sparse::to_dense(h);
        solve_lower_triangular_in_place(l, y.as_mut(), par);
        let mut c = y.transpose().to_owned();
        drop(y);
        solve_lower_triangular_in_place(l, c.as_mut(), par);
        // z0 = L^T y0, unit norm since y0^T M y0 = 1.
        let mut z0 = Mat::<f64>::zeros(k, 1);
        for i in 0..k {
            z0[(i, 0)] = y0[i];
        }
        let z0 = l.transpose() * &z0;
        let v = &c * &z0;
        let rayleigh = (z0.transpose() * &v)[(0, 0)];
        // C' = (C + C^T)/2 projected: P C P - z0 z0^T
        //    = C - v z0^T - z0 v^T + (z0^T v) z0 z0^T - z0 z0^T.
        let mut cp = Mat::<f64>::zeros(k, k);
        for j in 0..k {
            for i in 0..k {
                cp[(i, j)] =
                    0.5 * (c[(i, j)] + c[(j, i)]) - v[(i, 0)] * z0[(j, 0)] - z0[(i, 0)] * v[(j, 0)]
                        + (rayleigh - 1.0) * z0[(i, 0)] * z0[(j, 0)];
            }
        }
        drop(c);
        // faer's default switches to divide and conquer, which is inaccurate on our graded
        // spectra: force the QR algorithm (see `accurate_evd_params`).
        let mut u = Mat::<f64>::zeros(k, k);
        let mut s = Mat::<f64>::zeros(k, 1);
        {
            use faer::dyn_stack::{MemBuffer, MemStack};
            use faer::linalg::evd::{
                self_adjoint_evd, self_adjoint_evd_scratch, ComputeEigenvectors,
            };
            let params = super::accurate_evd_params();
            let mut mem = MemBuffer::new(self_adjoint_evd_scratch::<f64>(
                k,
                ComputeEigenvectors::Yes,
                par,
                params,
            ));
            self_adjoint_evd(
                cp.as_ref(),
                s.col_mut(0).as_diagonal_mut(),
                Some(u.as_mut()),
                par,
                MemStack::new(&mut mem),
                params,
            )
            .map_err(|e| {
                EigenError::NonFinite(format!("dense eigendecomposition did not converge: {e:?}"))
            })?;
        }
        let s = s.col(0);
        let u = u.as_ref();
        // Eigenvalues ascending; index 0 is the deflated constant mode (-1), the rest >= -eps.
        let mut values = Vec::with_capacity(nev);
        values.push(0.0);
        let mut vectors = Mat::<f64>::zeros(k, nev);
        for i in 0..k {
            vectors[(i, 0)] = y0[i];
        }
        let mut z = u.subcols(1, nev - 1).to_owned();
        // x = L^-T z.
        solve_upper_triangular_in_place(l.transpose(), z.as_mut(), par);
        for j in 1..nev {
            values.push(s[j]);
            vectors.col_mut(j).copy_from(z.col(j - 1));
        }
        let h_norm = sparse::norm_1(h);
        let mut info = EigenInfo {
            solver: "dense".into(),
            notes: vec![
                "dense: Cholesky of M, eigendecomposition of L^-1 H L^-T with the constant mode deflated".into(),
                format!(
                    "constant mode Rayleigh quotient y0^T H y0 = {rayleigh:.3e} (relative to ||H||_1: {:.3e})",
                    rayleigh / h_norm.max(f64::MIN_POSITIVE)
                ),
            ],
            ..EigenInfo::default()
        };
        if nev < k - 1 && (s[nev] - s[nev - 1]).abs() <= 1e-10 * s[nev].abs().max(h_norm * 1e-12) {
            info.notes.push(format!(
                "the cut splits a cluster: values[{}] = {:.12e} and the next eigenvalue {:.12e} coincide",
                nev - 1,
                s[nev - 1],
                s[nev]
            ));
        }
        check_solution(h, m, &values, &vectors, &mut info);
        progress.finish();
        Ok(EigenSolution {
            values,
            vectors,
            info,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::testing;
    use crate::progress::Silent;

    fn request(nev: usize) -> EigenRequest {
        EigenRequest {
            nev,
            ..EigenRequest::default()
        }
    }

    #[test]
    fn dense_matches_grid_laplacian_analytic() {
        // 7-point Laplacian on a 6 x 6 x 6 cube, identity mass: eigenvalues are sums of
        // 2 - 2cos(pi k / 6), with 3- and 6-fold multiplicities.
        let n = [6, 6, 6];
        let h = testing::grid_laplacian(n, 1.0);
        let m = testing::identity(216);
        let sol = DenseSolver
            .solve_converged(h.as_ref(), m.as_ref(), &request(40), &Silent)
            .unwrap();
        let exact = testing::grid_laplacian_eigenvalues(n, 40);
        for (a, b) in sol.values.iter().zip(&exact) {
            // Backward-stable dense eigensolver: absolute error ~ eps ||C|| ~ 1e-15 * 12.
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        assert_eq!(sol.values[0], 0.0);
        assert!(
            sol.info.max_relative_residual < 1e-13,
            "{}",
            sol.info.max_relative_residual
        );
        assert!(sol.info.orthonormality_error < 1e-12);
    }

    #[test]
    fn dense_matches_q1_fem_analytic_with_consistent_mass() {
        // Non-trivial M (consistent Q1 mass, cond ~ 27 ... 64): exercises the Cholesky
        // reduction. Box 5 x 4 x 6 nodes, h = 0.2.
        let n = [5, 4, 6];
        let (h, m) = testing::q1_fem(n, 0.2);
        let sol = DenseSolver
            .solve_converged(h.as_ref(), m.as_ref(), &request(30), &Silent)
            .unwrap();
        let exact = testing::q1_fem_eigenvalues(n, 0.2, 30);
        for (a, b) in sol.values.iter().zip(&exact) {
            // Relative 1e-11 of the largest eigenvalue ~ 1e3: round-off of the reduction
            // amplified by cond(M) ~ 1e2 stays below 1e-12 * ||C||.
            assert!((a - b).abs() < 1e-11 * 1e3, "{a} vs {b}");
        }
        assert!(sol.info.max_relative_residual < 1e-13);
        assert!(sol.info.orthonormality_error < 1e-12);
        // The first vector is the M-normalized constant.
        let y0 = 1.0 / crate::eigen::compensated_sum(m.val().iter().copied()).sqrt();
        assert!((0..m.nrows()).all(|i| sol.vectors[(i, 0)] == y0));
    }

    #[test]
    fn dense_errors() {
        let h = testing::grid_laplacian([3, 3, 3], 1.0);
        let m = testing::identity(27);
        // nev = K - 1 is one too many.
        assert!(matches!(
            DenseSolver.solve(h.as_ref(), m.as_ref(), &request(26), &Silent),
            Err(EigenError::InvalidRequest(_))
        ));
        assert!(DenseSolver
            .solve(h.as_ref(), m.as_ref(), &request(25), &Silent)
            .is_ok());
        // M indefinite: -I.
        let mut bad = m.clone();
        bad.val_mut().iter_mut().for_each(|v| *v = -*v);
        bad.val_mut()[0] = 100.0; // keep 1^T M 1 > 0 so the Cholesky is what fails
        assert!(matches!(
            DenseSolver.solve(h.as_ref(), bad.as_ref(), &request(4), &Silent),
            Err(EigenError::NotPositiveDefinite { what: "M", .. })
        ));
        let mut nan = h.clone();
        nan.val_mut()[5] = f64::NAN;
        assert!(matches!(
            DenseSolver.solve(nan.as_ref(), m.as_ref(), &request(4), &Silent),
            Err(EigenError::NonFinite(_))
        ));
        let big = testing::identity(DENSE_MAX_K + 1);
        assert!(matches!(
            DenseSolver.solve(big.as_ref(), big.as_ref(), &request(4), &Silent),
            Err(EigenError::TooLarge {
                limit: DENSE_MAX_K,
                ..
            })
        ));
    }
}
