//! Eigensolvers compared on one problem: each [`SolverConfig`] solves the same H_w and M; the
//! report holds its wall and CPU time, iterations, residuals, and its eigenvalue differences
//! and subspace angles against a reference solver (what `freeform compare` prints).

use super::problem::Problem;
use super::solver::SolverConfig;
use crate::eigen::compare::{max_eigenvalue_rel_diff, max_subspace_angle};
use crate::eigen::{EigenError, EigenRequest, EigenSolution, Eigensolver};
use crate::progress::Progress;
use crate::report::{process_cpu_seconds, Stopwatch};
use crate::sparse::SparseMatrixRef;
use crate::{Error, Result};
use serde::Serialize;

/// One solver's figures in a [`SolverComparison`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SolverResult {
    /// The solver's own label (`EigenInfo::solver`, e.g. "slepc:ks-sinvert"), or its short
    /// name when it returned no solution.
    pub solver: String,
    /// Wall-clock seconds of the solve.
    pub time_s: f64,
    /// CPU seconds of this process during the solve (all threads; user + system): less
    /// sensitive than `time_s` to other processes sharing the cores. 0 where unknown.
    pub cpu_s: f64,
    /// Outer iterations (0 without a solution).
    pub iterations: usize,
    /// Largest recomputed relative residual (+inf without a solution).
    pub max_relative_residual: f64,
    /// max |c^T M c - I|, recomputed (+inf without a solution).
    pub orthonormality_error: f64,
    /// Eigenvalues, ascending, Pa/m^2 (empty without a solution).
    pub eigenvalues: Vec<f64>,
    /// Largest relative eigenvalue difference against the reference
    /// ([`max_eigenvalue_rel_diff`]); +inf when the numbers of pairs differ.
    pub eigenvalue_rel_diff: f64,
    /// Largest principal angle against the reference's eigenspaces, radians
    /// ([`max_subspace_angle`]); +inf when the numbers of pairs differ.
    pub subspace_angle: f64,
    /// The solver's notes.
    pub notes: Vec<String>,
    /// Set when the solver failed or did not converge; the figures above are then from its
    /// partial result, or 0 / +inf / empty without one.
    pub error: Option<String>,
}

/// Every solver's figures on one pencil, against a reference: the first solver that succeeded.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SolverComparison {
    /// The reference's label (empty when every solver failed).
    pub reference: String,
    /// The iteration cap every solver was given (`EigenRequest::max_iter`; a SLEPc
    /// configuration's own `-eps_max_it` overrides it for that solver): a solver that reaches
    /// it reports "not converged" in its entry.
    pub max_iter: usize,
    /// One entry per solver, in the order given.
    pub solvers: Vec<SolverResult>,
    /// Largest `eigenvalue_rel_diff` over the solvers that succeeded.
    pub max_eigenvalue_rel_diff: f64,
    /// Largest `subspace_angle` over the solvers that succeeded, radians.
    pub max_subspace_angle: f64,
}

impl SolverComparison {
    /// Whether any solver failed or did not converge.
    pub fn any_failed(&self) -> bool {
        self.solvers.iter().any(|s| s.error.is_some())
    }
}

/// A [`SolverComparison`] on a [`Problem`], with the problem's sizes: the JSON of
/// `freeform compare --json` without its `shape`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProblemComparison {
    /// Kernels K.
    pub kernels: usize,
    /// Integration points N.
    pub points: usize,
    /// Non-constant modes m (m + 1 pairs are computed).
    pub modes: usize,
    /// Relative residual tolerance every solver was given.
    pub tol: f64,
    /// Non-zeros of H_w.
    pub nnz_hessian: usize,
    /// Seconds spent building H_w and M (once, shared by every solver).
    pub matrices_s: f64,
    /// The solvers' figures.
    #[serde(flatten)]
    pub comparison: SolverComparison,
}

/// Solve H x = lambda M x (H, M: K x K, symmetric) for `request` with each of `solvers`, in
/// order, and compare each result with the reference (the first solver that succeeded).
/// Clusters of eigenvalues closer than `cluster_gap` (relative) are compared as one subspace.
/// A solver that fails or does not converge is reported in its entry, not as an error.
///
/// # Errors
/// [`Error::InvalidParameter`] (`solvers`) for an empty list; a configuration that cannot be
/// built ([`SolverConfig::build`]), before any solve; a failed subspace-angle computation.
pub fn compare_solvers(
    h: SparseMatrixRef<'_>,
    m: SparseMatrixRef<'_>,
    request: &EigenRequest,
    solvers: &[SolverConfig],
    cluster_gap: f64,
    progress: &dyn Progress,
) -> Result<SolverComparison> {
    if solvers.is_empty() {
        return Err(Error::param("solvers", "[]", "no solver to compare"));
    }
    let built = solvers
        .iter()
        .map(SolverConfig::build)
        .collect::<Result<Vec<_>>>()?;
    let mut results: Vec<(SolverResult, Option<EigenSolution>)> = built
        .iter()
        .map(|solver| run_one(solver.as_ref(), h, m, request, progress))
        .collect();
    // Reference: the first solver that succeeded.
    let reference = results
        .iter()
        .position(|(e, s)| e.error.is_none() && s.is_some());
    let (mut max_diff, mut max_angle) = (0.0f64, 0.0f64);
    if let Some(r) = reference {
        let (ref_vals, ref_vecs) = {
            let s = results[r]
                .1
                .as_ref()
                .ok_or_else(|| EigenError::InvalidRequest("reference solution missing".into()))?;
            (s.values.clone(), s.vectors.clone())
        };
        for (entry, solution) in results.iter_mut() {
            let Some(s) = solution else {
                continue;
            };
            if s.values.len() != ref_vals.len() {
                entry.eigenvalue_rel_diff = f64::INFINITY;
                entry.subspace_angle = f64::INFINITY;
            } else {
                entry.eigenvalue_rel_diff = max_eigenvalue_rel_diff(&s.values, &ref_vals);
                entry.subspace_angle = max_subspace_angle(
                    m,
                    &s.values,
                    &s.vectors,
                    &ref_vals,
                    &ref_vecs,
                    cluster_gap,
                )?;
            }
            if entry.error.is_none() {
                max_diff = max_diff.max(entry.eigenvalue_rel_diff);
                max_angle = max_angle.max(entry.subspace_angle);
            }
        }
    }
    Ok(SolverComparison {
        reference: reference.map_or(String::new(), |r| results[r].0.solver.clone()),
        max_iter: request.max_iter,
        solvers: results.into_iter().map(|(e, _)| e).collect(),
        max_eigenvalue_rel_diff: max_diff,
        max_subspace_angle: max_angle,
    })
}

/// One solve, timed, as an entry (differences still 0) and its solution if any.
fn run_one(
    solver: &dyn Eigensolver,
    h: SparseMatrixRef<'_>,
    m: SparseMatrixRef<'_>,
    request: &EigenRequest,
    progress: &dyn Progress,
) -> (SolverResult, Option<EigenSolution>) {
    let clock = Stopwatch::start();
    let cpu0 = process_cpu_seconds();
    let outcome = solver.solve(h, m, request, progress);
    let time_s = clock.elapsed();
    let cpu_s = match (cpu0, process_cpu_seconds()) {
        (Some(a), Some(b)) => b - a,
        _ => 0.0,
    };
    let (solution, error) = match outcome {
        Ok(s) if s.converged() => (Some(s), None),
        Ok(s) => {
            let msg = format!(
                "not converged (max relative residual {:.2e})",
                s.info.max_relative_residual
            );
            (Some(s), Some(msg))
        }
        Err(e) => (None, Some(e.to_string())),
    };
    let entry = SolverResult {
        solver: solution
            .as_ref()
            .map(|s| s.info.solver.clone())
            .filter(|s| !s.is_empty())
            .unwrap_or_else(|| solver.name().to_string()),
        time_s,
        cpu_s,
        iterations: solution.as_ref().map_or(0, |s| s.info.iterations),
        max_relative_residual: solution
            .as_ref()
            .map_or(f64::INFINITY, |s| s.info.max_relative_residual),
        orthonormality_error: solution
            .as_ref()
            .map_or(f64::INFINITY, |s| s.info.orthonormality_error),
        eigenvalues: solution.as_ref().map_or(Vec::new(), |s| s.values.clone()),
        eigenvalue_rel_diff: 0.0,
        subspace_angle: 0.0,
        notes: solution
            .as_ref()
            .map_or(Vec::new(), |s| s.info.notes.clone()),
        error,
    };
    (entry, solution)
}

impl Problem {
    /// Compare `solvers` on this problem's H_w and M at its request ([`Problem::request`]):
    /// [`compare_solvers`] with the problem's sizes. `matrices_s` is the problem's build time
    /// (`timings().total`). Every solver gets both triangles: a problem stored as the upper
    /// triangle mirrors it beside itself (build it with `MatrixStorage::Full` to hold one
    /// storage).
    ///
    /// # Errors
    /// As [`compare_solvers`].
    pub fn compare(
        &self,
        solvers: &[SolverConfig],
        cluster_gap: f64,
        progress: &dyn Progress,
    ) -> Result<ProblemComparison> {
        let (h, m) = (self.matrices().hessian(), self.matrices().mass());
        let comparison = compare_solvers(h, m, &self.request(), solvers, cluster_gap, progress)?;
        Ok(ProblemComparison {
            kernels: self.kernels().len(),
            points: self.points().len(),
            modes: self.options().modes,
            tol: self.options().tol,
            nnz_hessian: h.compute_nnz(),
            matrices_s: self.timings().total,
            comparison,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eigen::testing::{grid_laplacian, identity};
    use crate::progress::Silent;

    #[test]
    fn native_against_dense_and_a_failing_solver() {
        let h = grid_laplacian([6, 5, 4], 1.0);
        let m = identity(120);
        let request = EigenRequest {
            nev: 6,
            tol: 1e-9,
            max_iter: 1000,
        };
        let c = compare_solvers(
            h.as_ref(),
            m.as_ref(),
            &request,
            &[SolverConfig::lobpcg(), SolverConfig::Dense],
            1e-6,
            &Silent,
        )
        .unwrap();
        assert_eq!(c.reference, "lobpcg");
        assert_eq!(c.max_iter, 1000);
        assert_eq!(c.solvers.len(), 2);
        assert_eq!(c.solvers[1].solver, "dense");
        assert!(!c.any_failed());
        assert!(
            c.max_eigenvalue_rel_diff < 1e-12,
            "{}",
            c.max_eigenvalue_rel_diff
        );
        assert!(c.max_subspace_angle < 1e-6, "{}", c.max_subspace_angle);
        assert_eq!(c.solvers[0].eigenvalue_rel_diff, 0.0);

        // Two iterations cannot converge to 1e-14: reported in the solver's entry with its
        // partial result, not as an error, and not counted in the maxima.
        let tight = EigenRequest {
            nev: 6,
            tol: 1e-14,
            max_iter: 2,
        };
        let c = compare_solvers(
            h.as_ref(),
            m.as_ref(),
            &tight,
            &[SolverConfig::Dense, SolverConfig::lobpcg()],
            1e-6,
            &Silent,
        )
        .unwrap();
        assert_eq!(c.reference, "dense");
        let failed = &c.solvers[1];
        let error = failed
            .error
            .as_deref()
            .expect("2 iterations do not converge");
        assert!(
            error.starts_with("not converged (max relative residual "),
            "{error}"
        );
        assert_eq!(failed.iterations, 2);
        assert_eq!(failed.eigenvalues.len(), 6);
        assert!(failed.eigenvalue_rel_diff > 0.0);
        assert!(c.any_failed());
        // Only the reference counts: itself at round-off.
        let reference = &c.solvers[0];
        assert_eq!(c.max_eigenvalue_rel_diff, reference.eigenvalue_rel_diff);
        assert_eq!(c.max_subspace_angle, reference.subspace_angle);
        assert!(c.max_subspace_angle < 1e-12, "{}", c.max_subspace_angle);
        assert!(failed.subspace_angle > 1e-6, "{}", failed.subspace_angle);

        assert!(compare_solvers(h.as_ref(), m.as_ref(), &request, &[], 1e-6, &Silent).is_err());
    }
}
