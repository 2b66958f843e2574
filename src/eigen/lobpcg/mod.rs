//! Native sparse LOBPCG for H c = lambda M c (H PSD with the constant null vector, M SPD).
//!
//! Follows Knyazev (2001) with the robustness measures of Duersch, Shao, Yang & Gu, "A robust
//! and efficient implementation of LOBPCG" (SISC 2018):
//! - the known null vector is deflated: the iteration runs in the M-orthogonal complement of
//!   y0 = 1 / sqrt(1^T M 1), which is returned as the first pair with eigenvalue exactly 0;
//! - SVQB M-orthonormalization with drop tolerances (`orthogonalize.rs`);
//! - soft locking: converged columns stay in the Rayleigh-Ritz basis but get no new
//!   directions;
//! - restart without P when the Gram matrix of the basis is ill-conditioned
//!   (`rayleigh_ritz.rs`);
//! - periodic explicit recomputation of H X and M X, and an explicit check before stopping;
//! - guard vectors beyond the wanted pairs (so a multiple eigenvalue at the cut is complete);
//! - a preconditioner T ~ (H + sigma M)^-1 (`precondition.rs`): exact sparse Cholesky when its
//!   fill is small, zero-fill incomplete Cholesky otherwise ([`PreconditionerKind::Auto`]).
//!
//! Workspaces are allocated once; the inner loop does not allocate. Deterministic: the start
//! block comes from a fixed-seed splitmix64 generator, the sparse kernels sum each row in
//! stored order, the tall dense products split rows into fixed chunks summed in order, and the
//! IC(0) solves give every column the same operations whatever the grouping; the output is
//! bit-identical for the same input, whatever the thread count (tested with 1, 2, 3 threads;
//! the supernodal Cholesky is faer's and is only claimed deterministic per thread count).
//!
//! Measured (2 cores shared with other jobs, nev = 33, tol 1e-8, default options):
//!
//! | problem | K | nnz/row | preconditioner | iterations | time |
//! |---|---|---|---|---|---|
//! | grid, radius-3 stencil | 10,648 | 105 | IC(0) (Auto) | 16 | 1.8 s |
//! | same | 10,648 | 105 | Cholesky (17.3M entries, 0.6 s) | 14 | 3.3 s |
//! | same | 10,648 | 105 | Jacobi | 37 | 3.4 s |
//! | grid, radius-3 stencil | 97,336 | 114 | IC(0) (Auto) | 26 | 30 s |
//! | same | 97,336 | 114 | Cholesky (591M entries, 4.7 GB, 127 s numeric) | 14 | 252 s |
//! | same | 97,336 | 114 | Jacobi | 83 | 61 s |
//! | RKPM beam 5x1x1 | 50,000 | 244 | IC(0) (Auto) | 21 | 19-34 s |
//! | same | 50,000 | 244 | Cholesky (152M entries, 15 s numeric) | 15 | 56 s |
//! | RKPM beam 5x1x1 | 100,000 | 251 | IC(0) (Auto) | 24 | 85 s |
//!
//! The grid rows come from the ignored test `tests::measure_lobpcg`; the RKPM rows from the
//! stage API (sampling, FPS, shape functions, assembly) with the default support factor
//! (cond(M) ~ 6e2). With wider supports (factor 3-4, cond(M) 1e6-1e7) IC(0) degrades (89-255
//! iterations) while the exact factor stays at 15-16: `Auto` then keeps the exact factor when
//! it fits, and switches to it after [`LobpcgOptions::escalate_after`] slow IC(0) iterations.

mod assembled_preconditioner;
mod driver;
mod incomplete_cholesky;
mod iterate;
mod operators;
mod orthogonalize;
mod precondition;
mod rayleigh_ritz;
mod workspace;

pub use assembled_preconditioner::AssembledPreconditioner;

use super::operator_problem::{validate_operators, OperatorProblem};
use super::{validate_problem, EigenError, EigenRequest, EigenSolution, Eigensolver};
use crate::progress::Progress;
use crate::sparse::SparseMatrix;

/// Which preconditioner LOBPCG applies to the residuals.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PreconditionerKind {
    /// Sparse Cholesky of H + sigma M when its factor is small, otherwise
    /// [`PreconditionerKind::IncompleteCholesky`]. "Small": at most
    /// [`LobpcgOptions::max_factor_entries`] entries and at most
    /// [`LobpcgOptions::max_fill_ratio`] times the entries of the lower triangle of
    /// H + sigma M, both known from the symbolic analysis before any numeric work.
    Auto,
    /// Sparse Cholesky of H + sigma M (AMD ordering), whatever its size.
    Cholesky,
    /// Zero-fill incomplete Cholesky IC(0) of H + sigma M: as many entries as the lower
    /// triangle of H + sigma M, sequential triangular solves. On breakdown the diagonal is
    /// raised (alpha = 1e-3 ... 1 times diag), then Jacobi is used.
    IncompleteCholesky,
    /// diag(H + sigma M)^-1.
    Jacobi,
    /// No preconditioner.
    Identity,
}

/// `Option<usize>` serialized as a number with 0 for `None` (TOML has no null).
mod zero_is_never {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &Option<usize>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(v.unwrap_or(0) as u64)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<usize>, D::Error> {
        let n = usize::deserialize(d)?;
        Ok((n > 0).then_some(n))
    }
}

/// LOBPCG settings. Every field has a documented default ([`LobpcgOptions::default`]); in
/// serialized form (scene files, basis metadata) a missing field takes its default.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LobpcgOptions {
    /// Guard vectors: extra block columns beyond the nev - 1 wanted non-constant pairs.
    /// `None`: `max(8, ceil((nev - 1) / 4))`. Convergence of pair j goes like
    /// lambda_j / lambda_{block + 1}, so guards speed up the last wanted pairs, and at least
    /// 5 are needed for a 6-fold eigenvalue (cubes) at the cut to fit entirely in the block.
    pub guard: Option<usize>,
    /// Preconditioner. Default [`PreconditionerKind::Auto`].
    pub preconditioner: PreconditionerKind,
    /// Shift rule: sigma = `shift_factor` * tr(H) / tr(M). tr(H)/tr(M) is the mean
    /// eigenvalue, a cheap scale of the spectrum. Default 1e-4 (well below the first non-zero
    /// eigenvalue for K up to ~1e5, where lambda_1 / mean ~ 1e-3; a shift below lambda_1
    /// makes T close to the ideal shift-invert operator on the wanted end while keeping
    /// H + sigma M safely positive definite: condition number ~ 1e4 * (lambda_max / mean)).
    pub shift_factor: f64,
    /// Budget for [`PreconditionerKind::Auto`]: most entries allowed in the Cholesky factor.
    /// Default 2^27 = 134M entries (1.07 GB).
    pub max_factor_entries: usize,
    /// Second budget for [`PreconditionerKind::Auto`]: most fill allowed, as factor entries over
    /// entries of the lower triangle of H + sigma M. Default 8. Measured (nev = 33): the exact
    /// factor and IC(0) need about the same iterations (14-16 vs 16-21), an exact solve costs
    /// ~fill/2 times an IC(0) solve, so above ~8x IC(0) wins: RKPM beam K = 4,000 (fill 5.5x)
    /// Cholesky 1.6 s vs IC(0) 1.9 s; K = 10,000 (8.9x) 5.6 s vs 5.7 s; K = 50,000 (24.8x)
    /// 56 s vs 34 s; 3D grid K = 10,648 (31x) 3.2 s vs 2.1 s.
    pub max_fill_ratio: f64,
    /// For [`PreconditionerKind::Auto`] runs that chose IC(0): after this many iterations
    /// without convergence, switch to the exact Cholesky if its factor holds at most
    /// `max_factor_entries` entries (ignoring `max_fill_ratio`). Default `Some(60)`: IC(0)
    /// converges in 16-26 iterations on well-conditioned problems but degrades when M is
    /// ill-conditioned (RKPM beam, K = 2,000, support factor 4, cond(M) = 7.8e6: IC(0) 255
    /// iterations, 34 s; exact Cholesky 15 iterations, 1.8 s). `None` never switches; in
    /// serialized form (scene files, metadata) `None` is written and read as 0, since TOML has
    /// no null and a missing key means the default.
    #[serde(with = "zero_is_never")]
    pub escalate_after: Option<usize>,
    /// Recompute H X, M X, H P, M P explicitly every this many iterations (the implicit
    /// updates accumulate round-off). Default 10.
    pub recompute_every: usize,
    /// Restart (drop P) when min/max eigenvalue of the basis M-Gram matrix falls below this.
    /// Default 1e-10 (the basis is M-orthonormalized, so this only triggers on real loss of
    /// orthogonality between P and the rest).
    pub restart_tol: f64,
    /// Drop a new direction when the projection against [X | P] leaves less than this fraction
    /// of its M-norm (what remains would be mostly round-off). Default 1e-10.
    pub ortho_drop: f64,
    /// SVQB drop tolerance: eigenvalues of the scaled Gram matrix below this times the largest
    /// are dropped (directions that cannot be resolved from the Gram matrix). Default 1e-14.
    pub svqb_drop: f64,
    /// Seed of the start block. Default 0x5eed.
    pub seed: u64,
}

impl Default for LobpcgOptions {
    fn default() -> Self {
        Self {
            guard: None,
            preconditioner: PreconditionerKind::Auto,
            shift_factor: 1e-4,
            max_factor_entries: 1 << 27,
            max_fill_ratio: 8.0,
            escalate_after: Some(60),
            recompute_every: 10,
            restart_tol: 1e-10,
            ortho_drop: 1e-10,
            svqb_drop: 1e-14,
            seed: 0x5eed,
        }
    }
}

impl LobpcgOptions {
    /// Guard vectors for `nwant` wanted non-constant pairs.
    pub fn guard_for(&self, nwant: usize) -> usize {
        self.guard.unwrap_or_else(|| 8.max(nwant.div_ceil(4)))
    }
}

/// Native LOBPCG eigensolver (name "lobpcg").
#[derive(Debug, Clone, Default)]
pub struct Lobpcg {
    /// Settings.
    pub options: LobpcgOptions,
}

impl Lobpcg {
    /// A solver with the given settings.
    pub fn new(options: LobpcgOptions) -> Self {
        Self { options }
    }
}

impl Eigensolver for Lobpcg {
    fn name(&self) -> &'static str {
        "lobpcg"
    }

    fn solve(
        &self,
        h: &SparseMatrix,
        m: &SparseMatrix,
        request: &EigenRequest,
        progress: &dyn Progress,
    ) -> Result<EigenSolution, EigenError> {
        validate_problem(h, m, request)?;
        driver::solve(
            &self.options,
            &OperatorProblem::new(h, m),
            request,
            progress,
        )
    }

    /// Matrix-free LOBPCG: H and M are applied only through [`crate::eigen::LinearOperator`]
    /// (a `SparseMatrix` operator takes the assembled path, bit for bit). Preconditioner: the
    /// problem's own if given; else, with both operators assembled, the one
    /// [`LobpcgOptions::preconditioner`] builds; else Jacobi from the operators' diagonals
    /// (`Auto` or `Jacobi`, when both give one) or none (`Auto`, `Identity`). The relative
    /// residuals then use estimated 1-norms (see the solution's notes). One process only:
    /// operators must own all rows.
    fn solve_operators(
        &self,
        problem: &OperatorProblem<'_>,
        request: &EigenRequest,
        progress: &dyn Progress,
    ) -> Result<EigenSolution, EigenError> {
        if let (Some(h), Some(m)) = (problem.h.assembled(), problem.m.assembled()) {
            validate_problem(h, m, request)?;
        }
        validate_operators(problem, request)?;
        driver::solve(&self.options, problem, request, progress)
    }
}

#[cfg(test)]
mod tests;
