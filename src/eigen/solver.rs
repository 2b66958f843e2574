//! The one trait every eigensolver implements: [`Eigensolver`], over assembled matrices
//! ([`Eigensolver::solve`]) and over operators ([`Eigensolver::solve_operators`]).

use crate::eigen::{EigenError, EigenRequest, EigenSolution, OperatorProblem};
use crate::progress::Progress;
use crate::sparse::SparseMatrixRef;

/// A generalized symmetric-definite eigensolver for the m + 1 smallest pairs.
pub trait Eigensolver {
    /// Short name used in reports ("lobpcg", "dense").
    fn name(&self) -> &'static str;
    /// Solve H x = lambda M x for the `request.nev` smallest pairs. H, M: K x K symmetric.
    /// A solve that stops before every pair meets the tolerance returns `Ok` with
    /// [`EigenInfo::status`] saying so (and possibly fewer than `nev` pairs, for an external
    /// solver); see [`EigenError`] for the rule.
    ///
    /// # Errors
    /// Failures without a usable result ([`EigenError`]).
    fn solve(
        &self,
        h: SparseMatrixRef<'_>,
        m: SparseMatrixRef<'_>,
        request: &EigenRequest,
        progress: &dyn Progress,
    ) -> Result<EigenSolution, EigenError>;

    /// [`Eigensolver::solve`], then [`EigenSolution::into_converged`]: a converged solution
    /// or an error (the not-converged ones carry the partial result).
    ///
    /// # Errors
    /// As [`Eigensolver::solve`], plus [`EigenError::NotConverged`] /
    /// [`EigenError::SlepcLobpcgNotConverged`] for a solve that stopped short.
    fn solve_converged(
        &self,
        h: SparseMatrixRef<'_>,
        m: SparseMatrixRef<'_>,
        request: &EigenRequest,
        progress: &dyn Progress,
    ) -> Result<EigenSolution, EigenError> {
        self.solve(h, m, request, progress)?.into_converged()
    }

    /// Whether [`Eigensolver::solve_operators`] works on operators that hold their matrix as an
    /// upper triangle ([`crate::eigen::LinearOperator::upper_triangle`]) at full speed: callers
    /// holding such storage give it as is to these and mirror it for the others. Default: no.
    fn solves_upper_triangles(&self) -> bool {
        false
    }

    /// Solve an eigenproblem given by operators ([`OperatorProblem`]): H and M applied to
    /// blocks of vectors, never assembled, with an optional caller's preconditioner. Same
    /// result contract as [`Eigensolver::solve`].
    ///
    /// The default accepts only operators backed by assembled matrices and no caller's
    /// preconditioner, and hands the matrices to [`Eigensolver::solve`]; solvers that work
    /// matrix-free (the native LOBPCG) override it.
    ///
    /// # Errors
    /// As [`Eigensolver::solve`], plus [`EigenError::Operator`] when an operator fails and
    /// [`EigenError::InvalidRequest`] when this solver cannot take the problem as given.
    fn solve_operators(
        &self,
        problem: &OperatorProblem<'_>,
        request: &EigenRequest,
        progress: &dyn Progress,
    ) -> Result<EigenSolution, EigenError> {
        match (
            problem.h.assembled(),
            problem.m.assembled(),
            problem.preconditioner,
        ) {
            (Some(h), Some(m), None) => self.solve(h, m, request, progress),
            _ => Err(EigenError::InvalidRequest(format!(
                "the {} solver needs assembled H and M and builds its own preconditioner; \
                 matrix-free operators and caller's preconditioners go to the native LOBPCG \
                 (eigen::lobpcg::Lobpcg)",
                self.name()
            ))),
        }
    }
}
