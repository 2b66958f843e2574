//! Generalized symmetric eigensolvers for H_w c = lambda M c (H_w PSD with the constant vector
//! as null space, M SPD), behind one trait.
//!
//! - [`lobpcg::Lobpcg`]: native sparse LOBPCG (the default).
//! - `slepc::SlepcSolver` (feature `slepc`): SLEPc through PETSc, optionally under MPI.
//! - [`dense::DenseSolver`]: dense reference (Cholesky of M, standard eigenproblem), for K up to a
//!   few thousand; tests use it as the oracle.
//!
//! Every solver returns eigenpairs in ascending order, the constant mode first, with
//! M-orthonormal vectors (c^T M c = I), and diagnostics recomputed independently of the
//! solver's own bookkeeping ([`check_solution`]). Whether the solve converged is a status on
//! the result ([`EigenInfo::status`]), not an error (see [`EigenError`]).

pub mod compare;
pub mod dense;
pub mod lobpcg;
pub mod operator;
pub mod operator_problem;
pub mod q1_operator;
pub mod rows;
#[cfg(feature = "slepc")]
pub mod slepc;
mod slepc_options;
#[cfg(feature = "slepc")]
mod slepc_pencil;
#[cfg(feature = "slepc")]
mod slepc_rows;
#[cfg(feature = "slepc")]
mod slepc_shell;
#[cfg(feature = "slepc")]
mod slepc_status;
mod solver;
pub mod testing;

pub use operator::{
    apply_checked, apply_preconditioner_checked, probe_symmetry, FnOperator, LinearOperator,
    OperatorError, Preconditioner,
};
pub use operator_problem::OperatorProblem;
pub use rows::{block_range, RowPencil};
pub use slepc_options::{SlepcOptions, SlepcPreset};
pub use solver::Eigensolver;

use crate::options;
use crate::sparse::{self, SparseMatrixRef};
use faer::Mat;

/// What the caller asks of an eigensolver.
#[derive(Debug, Clone, PartialEq)]
pub struct EigenRequest {
    /// Number of eigenpairs wanted, including the constant mode (m + 1).
    pub nev: usize,
    /// Relative residual tolerance: ||H x - lambda M x|| / ((||H|| + |lambda| ||M||) ||x||).
    pub tol: f64,
    /// Iteration cap (LOBPCG outer iterations).
    pub max_iter: usize,
}

impl Default for EigenRequest {
    fn default() -> Self {
        // tol 1e-8: eigenvalues converge quadratically in the residual, so ~1e-14 relative
        // eigenvalue accuracy; far below the discretization error of the modes themselves.
        Self {
            nev: 17,
            tol: 1e-8,
            max_iter: 1000,
        }
    }
}

/// Diagnostics that come back with a solution. Deserializing (a report stored in basis
/// metadata) takes the default for a missing field.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct EigenInfo {
    /// Solver name ("lobpcg", "dense").
    pub solver: String,
    /// Outer iterations performed (0 for the dense solver).
    pub iterations: usize,
    /// Restarts (LOBPCG: iterations that dropped the P block for conditioning).
    pub restarts: usize,
    /// Eigenpairs locked (converged and frozen) at exit.
    pub locked: usize,
    /// Sparse matrix-block products with H and M performed.
    pub matvecs: usize,
    /// Per-pair relative residuals, recomputed from H, M and the returned vectors.
    pub residuals: Vec<f64>,
    /// Largest entry of `residuals`.
    pub max_relative_residual: f64,
    /// max |c^T M c - I|, recomputed.
    pub orthonormality_error: f64,
    /// Free-form notes (preconditioner used, shift, fallbacks taken).
    pub notes: Vec<String>,
    /// Converged, or how the solver stopped short (with the figures of the error
    /// [`EigenSolution::into_converged`] makes of it). Left out of the JSON when converged.
    #[serde(skip_serializing_if = "EigenStatus::is_converged")]
    pub status: EigenStatus,
}

/// How a solve ended, asked of its result as PETSc/SLEPc ask `EPSGetConvergedReason`: every
/// requested pair met the tolerance, or the solver stopped short with the pairs it has. A solve
/// that has no usable pairs fails with an [`EigenError`] instead.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EigenStatus {
    /// Every requested pair met the tolerance.
    #[default]
    Converged,
    /// The iteration stopped before all pairs met the tolerance (iteration cap, stagnation,
    /// or an external solver's stop); [`EigenError::NotConverged`] as a status.
    NotConverged {
        /// Iterations performed.
        iterations: usize,
        /// Pairs that met the tolerance.
        converged: usize,
        /// Pairs requested.
        nev: usize,
        /// Tolerance.
        tol: f64,
        /// Largest residual at exit (+inf when pairs are missing: their residual is unknown).
        max_residual: f64,
    },
    /// SLEPc's LOBPCG ended without `nev` pairs that pass freeform's residual check;
    /// [`EigenError::SlepcLobpcgNotConverged`] as a status.
    SlepcLobpcgNotConverged {
        /// How SLEPc's run ended.
        stop: SlepcLobpcgStop,
        /// SLEPc's iteration count.
        iterations: usize,
        /// Pairs SLEPc reported converged (`EPSGetConverged`; may exceed `nev`).
        reported: usize,
        /// Pairs that pass freeform's residual check.
        converged: usize,
        /// Pairs requested (m + 1).
        nev: usize,
        /// Tolerance requested.
        tol: f64,
        /// Iteration cap requested.
        max_iter: usize,
        /// Problem size K.
        k: usize,
        /// LOBPCG block size in use, if SLEPc could report it.
        block_size: Option<usize>,
    },
}

impl EigenStatus {
    /// Whether every requested pair met the tolerance.
    pub fn is_converged(&self) -> bool {
        matches!(self, EigenStatus::Converged)
    }

    /// `(pairs that met the tolerance, pairs requested)` when not converged.
    pub fn converged_pairs(&self) -> Option<(usize, usize)> {
        match *self {
            EigenStatus::Converged => None,
            EigenStatus::NotConverged { converged, nev, .. }
            | EigenStatus::SlepcLobpcgNotConverged { converged, nev, .. } => Some((converged, nev)),
        }
    }
}

/// Eigenpairs, ascending.
#[derive(Debug, Clone)]
pub struct EigenSolution {
    /// Eigenvalues, ascending, length nev (first one ~0: the constant mode).
    pub values: Vec<f64>,
    /// Eigenvectors, K x nev, M-orthonormal; column j pairs with `values[j]`.
    pub vectors: Mat<f64>,
    /// Diagnostics, with the convergence status ([`EigenInfo::status`]).
    pub info: EigenInfo,
}

impl EigenSolution {
    /// Whether every requested pair met the tolerance ([`EigenInfo::status`]).
    pub fn converged(&self) -> bool {
        self.info.status.is_converged()
    }

    /// This solution when it converged; otherwise the error its status stands for
    /// ([`EigenError::NotConverged`] or [`EigenError::SlepcLobpcgNotConverged`], with the
    /// status's figures and this solution as `partial`). For callers that need a converged
    /// result.
    ///
    /// # Errors
    /// As above, when [`EigenSolution::converged`] is false.
    pub fn into_converged(self) -> Result<EigenSolution, EigenError> {
        match self.info.status.clone() {
            EigenStatus::Converged => Ok(self),
            EigenStatus::NotConverged {
                iterations,
                converged,
                nev,
                tol,
                max_residual,
            } => Err(EigenError::NotConverged {
                iterations,
                converged,
                nev,
                tol,
                max_residual,
                partial: Box::new(self),
            }),
            EigenStatus::SlepcLobpcgNotConverged {
                stop,
                iterations,
                reported,
                converged,
                nev,
                tol,
                max_iter,
                k,
                block_size,
            } => Err(EigenError::SlepcLobpcgNotConverged {
                stop,
                iterations,
                reported,
                converged,
                nev,
                tol,
                max_iter,
                k,
                block_size,
                partial: Box::new(self),
            }),
        }
    }
}

/// Eigensolver failures.
///
/// The rule (as in PETSc/SLEPc, where "converged?" is a reason asked of the solver): **not
/// converged is a status, failed is an error.** A solver that stops before every pair meets
/// the tolerance (iteration cap, stagnation, SLEPc's own stop) returns `Ok` with the pairs it
/// has, their recomputed residuals and [`EigenInfo::status`] saying how it stopped. An error
/// means there is no usable result: a bad request or input, an indefinite matrix, a breakdown,
/// a library failure. The two not-converged variants below carry the partial result; they are
/// made from a status by [`EigenSolution::into_converged`] where a converged result is required
/// ([`Eigensolver::solve_converged`], `precompute::Problem::solve`, `build_basis`), so those
/// calls fail as before with the same message.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EigenError {
    /// The request does not fit the problem (e.g. nev >= K - 1).
    #[error("eigen request invalid: {0}")]
    InvalidRequest(String),
    /// The caller's [`crate::progress::Progress::cancelled`] asked the iteration to stop.
    #[error("eigensolver cancelled by the caller after {iterations} iterations")]
    Cancelled {
        /// Iterations performed.
        iterations: usize,
    },
    /// The matrix is too large for this solver (dense solver on big K).
    #[error(
        "the {solver} solver refuses K = {k} (limit {limit}); use {}",
        options::SOLVER.with("lobpcg")
    )]
    TooLarge {
        /// Solver name.
        solver: &'static str,
        /// Problem size.
        k: usize,
        /// Largest K accepted.
        limit: usize,
    },
    /// M is not positive definite (or H + shift M for the preconditioner).
    #[error("{what} is not positive definite ({detail}); the kernels or integration points are degenerate")]
    NotPositiveDefinite {
        /// Which matrix.
        what: &'static str,
        /// Extra detail.
        detail: String,
    },
    /// The iteration stopped before all pairs met the tolerance; the partial result is kept.
    /// Made from [`EigenStatus::NotConverged`] by [`EigenSolution::into_converged`].
    #[error(
        "eigensolver did not converge in {iterations} iterations: {converged}/{nev} pairs below \
         tol {tol:.1e} (max relative residual {max_residual:.2e}); raise {} or the iteration cap",
        options::TOL
    )]
    NotConverged {
        /// Iterations performed.
        iterations: usize,
        /// Pairs that met the tolerance.
        converged: usize,
        /// Pairs requested.
        nev: usize,
        /// Tolerance.
        tol: f64,
        /// Largest residual at exit.
        max_residual: f64,
        /// What the solver had when it stopped.
        partial: Box<EigenSolution>,
    },
    /// A non-finite value appeared (NaN/Inf in the inputs or a breakdown).
    #[error("non-finite value in the eigensolver: {0}")]
    NonFinite(String),
    /// A caller's [`LinearOperator`] or [`Preconditioner`] reported an error when applied
    /// (a failing callback, a wrong block shape); `which` names it ("H", "M", "preconditioner").
    #[error("operator {which} failed: {message}")]
    Operator {
        /// Which operator failed.
        which: &'static str,
        /// The operator's message ([`OperatorError::message`]).
        message: String,
    },
    /// SLEPc's LOBPCG (`--slepc lobpcg-gamg`, `lobpcg-hypre`, or `-eps_type lobpcg`) broke
    /// down: its search basis [X, preconditioned residuals, directions] lost B-orthogonality
    /// (here B = M), so the projected Rayleigh-Ritz pencil is not definite and LAPACK's
    /// `?sygvd` refused it (`info` > projected size n: the leading minor of order info - n of
    /// the projected M is not positive definite). SLEPc has no recovery for this; no
    /// eigenpairs are available.
    #[error(
        "SLEPc's LOBPCG broke down: loss of B-orthogonality in the Rayleigh-Ritz step (LAPACK \
         {routine} info={info}; {nev} pairs, block size {}). Use SLEPc's direct configuration {} \
         (Krylov-Schur, shift-and-invert), or freeform's native LOBPCG ({}, the default); to \
         keep SLEPc's LOBPCG, {}",
        block_size.map_or_else(|| "unknown".to_string(), |b| b.to_string()),
        options::SLEPC.with("ks-sinvert"),
        options::SOLVER.with("lobpcg"),
        lobpcg_breakdown_advice(*k, *nev, *block_size)
    )]
    SlepcLobpcgBreakdown {
        /// The LAPACK routine SLEPc names (`"sygvd"`).
        routine: String,
        /// LAPACK's `info`.
        info: i64,
        /// Problem size K.
        k: usize,
        /// Pairs requested (m + 1).
        nev: usize,
        /// LOBPCG block size in use, if SLEPc could report it.
        block_size: Option<usize>,
        /// SLEPc's own message with its call chain.
        message: String,
    },
    /// SLEPc's LOBPCG (`--slepc lobpcg-gamg`, `lobpcg-hypre`, or `-eps_type lobpcg`) ended
    /// without `nev` pairs that pass freeform's own residual check (relative residual at most
    /// [`SLEPC_RESIDUAL_SLACK`] x tol, recomputed by [`check_solution`]): it reported pairs
    /// converged that are not, or stopped at its iteration cap or on a breakdown it detected.
    /// At the default iteration cap a larger tol or cap did not help (measured, docs/slepc.md);
    /// the message names what does. The partial result is kept. Other solvers' non-convergence is
    /// [`EigenError::NotConverged`]. Made from [`EigenStatus::SlepcLobpcgNotConverged`] by
    /// [`EigenSolution::into_converged`].
    #[error(
        "{}. Use SLEPc's direct configuration {} (Krylov-Schur, shift-and-invert), or \
         freeform's native LOBPCG ({}, the default); to keep SLEPc's LOBPCG, {}",
        slepc_lobpcg_stop_text(stop, *iterations, *reported, *converged, *nev, *tol),
        options::SLEPC.with("ks-sinvert"),
        options::SOLVER.with("lobpcg"),
        slepc_lobpcg_advice(stop, *k, *nev, *block_size, *max_iter)
    )]
    SlepcLobpcgNotConverged {
        /// How SLEPc's run ended.
        stop: SlepcLobpcgStop,
        /// SLEPc's iteration count.
        iterations: usize,
        /// Pairs SLEPc reported converged (`EPSGetConverged`; may exceed `nev`).
        reported: usize,
        /// Pairs that pass freeform's residual check.
        converged: usize,
        /// Pairs requested (m + 1).
        nev: usize,
        /// Tolerance requested.
        tol: f64,
        /// Iteration cap requested.
        max_iter: usize,
        /// Problem size K.
        k: usize,
        /// LOBPCG block size in use, if SLEPc could report it.
        block_size: Option<usize>,
        /// The pairs SLEPc returned, with freeform's residuals in `info`.
        partial: Box<EigenSolution>,
    },
    /// An external solver library (PETSc/SLEPc) failed; `message` is the library's own.
    #[error("{library} failed: {message}")]
    Backend {
        /// Library name.
        library: &'static str,
        /// The library's error message (with the call that failed).
        message: String,
    },
    /// Under MPI, other ranks failed in a stage of the run; their errors are their own (each
    /// rank prints its own). Every rank stops, so none is left waiting in a collective call.
    #[error(
        "MPI rank(s) {ranks:?} failed during {stage}; their own errors say why; every rank stops"
    )]
    OtherRanks {
        /// The stage that failed.
        stage: &'static str,
        /// The ranks that failed, ascending.
        ranks: Vec<usize>,
    },
    /// A SLEPc configuration was asked for in a build without the `slepc` feature.
    #[error(
        "this freeform was built without SLEPc: rebuild with `cargo build --release --features \
         slepc` (needs libslepc-real-dev, see docs/slepc.md)"
    )]
    SlepcUnavailable,
}

/// The last part of [`EigenError::SlepcLobpcgBreakdown`]'s message: SLEPc's LOBPCG breaks down
/// when it works through the pairs in several blocks (block size min(16, nev) by default,
/// converged blocks hard-locked); one block holding every pair avoids that (measured: K =
/// 3000, 33 pairs, block size 16 breaks down, 33 solves in 7 s). SLEPc requires K >= 5 x the
/// block size, so that advice is only given when K allows it.
fn lobpcg_breakdown_advice(k: usize, nev: usize, block_size: Option<usize>) -> String {
    if block_size.is_some_and(|b| b >= nev) || k < 5 * nev {
        "ask for fewer modes".to_string()
    } else {
        format!(
            "solve all pairs in one block ({}) or ask for fewer modes",
            options::PETSC_OPTIONS.with(format!("-eps_lobpcg_blocksize {nev}"))
        )
    }
}

/// Slack between SLEPc's own convergence decision and freeform's recomputed residual: both use
/// the same definition (EPS_CONV_NORM with infinity norms, which equal our 1-norms for
/// symmetric matrices), but SLEPc may test a residual it updated by recurrence rather than
/// recomputed, so a pair SLEPc returns is accepted when its relative residual is at most this
/// x tol.
pub const SLEPC_RESIDUAL_SLACK: f64 = 10.0;

/// How SLEPc's LOBPCG ended when [`EigenError::SlepcLobpcgNotConverged`] is returned.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SlepcLobpcgStop {
    /// SLEPc reported at least `nev` pairs converged, but freeform's recomputed residual of
    /// some returned pairs is above [`SLEPC_RESIDUAL_SLACK`] x tol.
    ClaimedConverged {
        /// The worst such pair (0-based in ascending order; 0 is the constant mode).
        pair: usize,
        /// Its eigenvalue (Pa/m^2).
        lambda: f64,
        /// Its recomputed relative residual.
        residual: f64,
        /// How many returned pairs are above the limit.
        above: usize,
    },
    /// SLEPc stopped at its iteration cap (`EPS_DIVERGED_ITS`) with fewer than `nev` pairs.
    IterationCap,
    /// SLEPc stopped with fewer than `nev` pairs for another reason: `EPSConvergedReason`
    /// (-2 `EPS_DIVERGED_BREAKDOWN`: an orthogonalization in LOBPCG failed).
    Stopped {
        /// SLEPc's `EPSConvergedReason`.
        reason: i32,
    },
}

/// The first sentence of [`EigenError::SlepcLobpcgNotConverged`]'s message: what happened.
fn slepc_lobpcg_stop_text(
    stop: &SlepcLobpcgStop,
    iterations: usize,
    reported: usize,
    converged: usize,
    nev: usize,
    tol: f64,
) -> String {
    match *stop {
        SlepcLobpcgStop::ClaimedConverged {
            pair,
            lambda,
            residual,
            above,
        } => format!(
            "SLEPc's LOBPCG reported convergence ({reported} pairs after {iterations} \
             iterations), but freeform's own residual check finds pair {pair} of 0..{} (lambda \
             {lambda:.4e}) at relative residual {residual:.2e} > {:.1e} ({} x tol {tol:.1e}; \
             {above} pair(s) above it)",
            nev.saturating_sub(1),
            SLEPC_RESIDUAL_SLACK * tol,
            SLEPC_RESIDUAL_SLACK,
        ),
        SlepcLobpcgStop::IterationCap => format!(
            "SLEPc's LOBPCG stopped at its iteration cap ({iterations} iterations) with \
             {converged}/{nev} pairs converged (tol {tol:.1e})"
        ),
        SlepcLobpcgStop::Stopped { reason } => format!(
            "SLEPc's LOBPCG stopped after {iterations} iterations with {converged}/{nev} pairs \
             converged (tol {tol:.1e}): {}",
            if reason == -2 {
                "it reports a breakdown (EPS_DIVERGED_BREAKDOWN: an orthogonalization failed)"
                    .to_string()
            } else {
                format!("EPSConvergedReason {reason}")
            }
        ),
    }
}

/// SLEPc's LOBPCG guard vectors for block size `b` (SLEPc 3.18, default restart 0.9):
/// min(floor(0.1 b + 0.45), b - 1), none for b = 1. Pairs are hard-locked, and the next ones
/// searched in a new block, once b - guard of them have converged.
pub fn slepc_lobpcg_guard(b: usize) -> usize {
    if b <= 1 {
        0
    } else {
        ((0.1 * b as f64 + 0.45).floor() as usize).min(b - 1)
    }
}

/// The smallest SLEPc LOBPCG block size b that holds `nev` pairs and SLEPc's guard vectors
/// (b - guard >= nev, guard from [`slepc_lobpcg_guard`]), so that no block is hard-locked
/// before all pairs have converged: 18 for 16 pairs, 19 for 17, 37 for 33.
pub fn slepc_lobpcg_single_block(nev: usize) -> usize {
    (nev.max(1)..)
        .find(|&b| b - slepc_lobpcg_guard(b) >= nev)
        .unwrap_or(nev)
}

/// The last part of [`EigenError::SlepcLobpcgNotConverged`]'s message. One block with room
/// for all pairs and the guard vectors fixed every case measured (docs/slepc.md; a block of
/// exactly `nev` did not where it was already the default); SLEPc requires K >= 5 x the block
/// size, so it is only advised when K allows it and the block in use is smaller. A cap below
/// the default (1000) is worth raising first.
fn slepc_lobpcg_advice(
    stop: &SlepcLobpcgStop,
    k: usize,
    nev: usize,
    block_size: Option<usize>,
    max_iter: usize,
) -> String {
    let single = slepc_lobpcg_single_block(nev);
    let mut ways = Vec::new();
    let default_cap = EigenRequest::default().max_iter;
    if *stop == SlepcLobpcgStop::IterationCap && max_iter < default_cap {
        ways.push(format!(
            "raise {} ({max_iter} now, default {default_cap})",
            options::MAX_ITER
        ));
    }
    if k >= 5 * single && block_size.is_none_or(|b| b < single) {
        ways.push(format!(
            "solve all pairs in one block with room for SLEPc's guard vectors ({})",
            options::PETSC_OPTIONS.with(format!("-eps_lobpcg_blocksize {single}"))
        ));
    }
    ways.push("ask for fewer modes".to_string());
    let last = ways.pop().unwrap_or_default();
    if ways.is_empty() {
        last
    } else {
        format!("{}, or {last}", ways.join(", "))
    }
}

/// Parameters for faer's dense self-adjoint eigendecomposition that force the tridiagonal QR
/// algorithm. faer 0.24's default switches to divide and conquer at n >= 128, which we measured
/// to lose accuracy on graded spectra (the normal case here: a zero eigenvalue next to
/// lambda_max ~ 1e10): residual / ||A|| of 2.7e-8 (n = 600) to 1.5e-3 (n = 1200, spread 1e16),
/// against 3e-14 to 1.4e-13 with the QR algorithm, at 1.5-2x the time.
pub(crate) fn accurate_evd_params() -> faer::Spec<faer::linalg::evd::SelfAdjointEvdParams, f64> {
    let mut params = <faer::linalg::evd::SelfAdjointEvdParams as faer::Auto<f64>>::auto();
    params.recursion_threshold = usize::MAX;
    faer::Spec::new(params)
}

/// Recompute per-pair relative residuals and the M-orthonormality error of `vectors`
/// (K x nev) independently of any solver, and store them into `info`.
///
/// - `info.residuals[j] = ||H x_j - lambda_j M x_j||_2 / ((||H||_1 + |lambda_j| ||M||_1)
///   ||x_j||_2)`, with the exact 1-norms of [`crate::sparse::norm_1`] (an upper bound of the
///   2-norms, within a factor ~2 for Laplacian- and mass-like matrices). A zero denominator
///   gives 0 for a zero residual and +inf otherwise; NaN becomes +inf.
/// - `info.max_relative_residual`: the largest of them (0 for no pairs).
/// - `info.orthonormality_error = max_ij |(X^T M X - I)_ij|`.
///
/// H and M are only read; costs two sparse block products and one K x nev x nev product.
///
/// # Panics
/// If the shapes do not match (`vectors.nrows() != K` or `values.len() != vectors.ncols()`),
/// a caller bug.
pub fn check_solution(
    h: SparseMatrixRef<'_>,
    m: SparseMatrixRef<'_>,
    values: &[f64],
    vectors: &Mat<f64>,
    info: &mut EigenInfo,
) {
    let k = h.nrows();
    let nev = vectors.ncols();
    assert!(
        vectors.nrows() == k && m.nrows() == k && values.len() == nev,
        "check_solution: shape mismatch"
    );
    let norms = (sparse::norm_1(h), sparse::norm_1(m));
    // Row-major copies for the fused row-major kernel (one pass over the shared pattern, a
    // contiguous row of X per entry); each product row is summed in stored order as the
    // column-major kernel sums it, so the figures are the same bits.
    let x: Vec<f64> = (0..k)
        .flat_map(|i| (0..nev).map(move |j| vectors[(i, j)]))
        .collect();
    let (mut hx_rows, mut mx_rows) = (vec![0.0; k * nev], vec![0.0; k * nev]);
    sparse::sym_mul_pair_row_major(h, m, &x, nev, &mut hx_rows, &mut mx_rows, nev, nev);
    drop(x);
    let hx = Mat::from_fn(k, nev, |i, j| hx_rows[i * nev + j]);
    drop(hx_rows);
    let mx = Mat::from_fn(k, nev, |i, j| mx_rows[i * nev + j]);
    drop(mx_rows);
    fill_residual_report(values, vectors, &hx, &mx, norms, info);
}

/// The residuals and M-orthonormality error of [`check_solution`] from the products
/// `hx = H X`, `mx = M X` (both K x nev) and the 1-norms `(||H||_1, ||M||_1)`.
pub(crate) fn fill_residual_report(
    values: &[f64],
    vectors: &Mat<f64>,
    hx: &Mat<f64>,
    mx: &Mat<f64>,
    (norm_h, norm_m): (f64, f64),
    info: &mut EigenInfo,
) {
    let (k, nev) = (vectors.nrows(), vectors.ncols());
    info.residuals = (0..nev)
        .map(|j| {
            let lambda = values[j];
            let r: Vec<f64> = (0..k).map(|i| hx[(i, j)] - lambda * mx[(i, j)]).collect();
            let x: Vec<f64> = (0..k).map(|i| vectors[(i, j)]).collect();
            relative_residual(sparse::norm2(&r), lambda, norm_h, norm_m, sparse::norm2(&x))
        })
        .collect();
    info.max_relative_residual = info.residuals.iter().copied().fold(0.0, f64::max);
    let mut gram = Mat::<f64>::zeros(nev, nev);
    faer::linalg::matmul::matmul(
        gram.as_mut(),
        faer::Accum::Replace,
        vectors.transpose(),
        mx.as_ref(),
        1.0,
        // Sequential: faer's parallel split of a K-long inner dimension was ~10x slower here.
        faer::Par::Seq,
    );
    let mut err = 0.0f64;
    for j in 0..nev {
        for i in 0..nev {
            let e = (gram[(i, j)] - if i == j { 1.0 } else { 0.0 }).abs();
            err = if e.is_nan() {
                f64::INFINITY
            } else {
                err.max(e)
            };
        }
    }
    info.orthonormality_error = err;
}

/// The relative residual of one pair, as defined on [`EigenRequest::tol`]:
/// `r_norm / ((norm_h + |lambda| norm_m) x_norm)`; 0/0 is 0, x/0 is +inf, NaN is +inf.
pub fn relative_residual(r_norm: f64, lambda: f64, norm_h: f64, norm_m: f64, x_norm: f64) -> f64 {
    let denom = (norm_h + lambda.abs() * norm_m) * x_norm;
    let rel = if r_norm == 0.0 {
        0.0
    } else if denom > 0.0 {
        r_norm / denom
    } else {
        f64::INFINITY
    };
    if rel.is_nan() {
        f64::INFINITY
    } else {
        rel
    }
}

/// Check a problem and a request before solving; shared by every solver.
///
/// Accepted: H and M square, same size K; `1 <= nev <= K - 2` (that is, m = nev - 1 <= K - 3
/// non-constant modes: the non-constant pairs live in the (K - 1)-dimensional M-orthogonal
/// complement of the constant vector, and at least one of its eigenpairs must stay outside the
/// returned set so the cut between the last returned eigenvalue and the next one is defined);
/// `tol` finite and > 0; all stored entries finite; both matrices symmetric to within 1e-10 of
/// their 1-norm (assembly round-off is ~1e-16 of it; the product kernels rely on symmetry).
///
/// # Errors
/// [`EigenError::InvalidRequest`] for shapes, `nev`, `tol` or asymmetry;
/// [`EigenError::NonFinite`] for a NaN or infinite entry.
pub fn validate_problem(
    h: SparseMatrixRef<'_>,
    m: SparseMatrixRef<'_>,
    request: &EigenRequest,
) -> Result<(), EigenError> {
    let k = h.nrows();
    if h.ncols() != k || m.nrows() != k || m.ncols() != k {
        return Err(EigenError::InvalidRequest(format!(
            "H is {} x {} and M is {} x {}; both must be K x K",
            h.nrows(),
            h.ncols(),
            m.nrows(),
            m.ncols()
        )));
    }
    validate_request(k, request)?;
    for (name, a) in [("H", h), ("M", m)] {
        if let Some((i, j)) = sparse::first_non_finite(a) {
            return Err(EigenError::NonFinite(format!(
                "{name}[{i}, {j}] = {}",
                entry(a, i, j)
            )));
        }
        let defect = sparse::symmetry_defect(a);
        let scale = sparse::norm_1(a);
        if defect > 1e-10 * scale {
            return Err(EigenError::InvalidRequest(format!(
                "{name} is not symmetric: max |a_ij - a_ji| = {defect:.3e} (||{name}||_1 = {scale:.3e})"
            )));
        }
    }
    Ok(())
}

/// The request checks of [`validate_problem`] for a problem of size K: `1 <= nev <= K - 2`,
/// `tol` finite and > 0.
///
/// # Errors
/// [`EigenError::InvalidRequest`] saying which.
pub fn validate_request(k: usize, request: &EigenRequest) -> Result<(), EigenError> {
    if request.nev == 0 || request.nev.saturating_add(2) > k {
        return Err(EigenError::InvalidRequest(format!(
            "nev = {} pairs (m = nev - 1 modes plus the constant one) requested for K = {k}: need \
             1 <= nev <= K - 2 (m <= K - 3)",
            request.nev
        )));
    }
    if !(request.tol > 0.0 && request.tol < 1.0) {
        return Err(EigenError::InvalidRequest(format!(
            "tol = {:e} must lie in (0, 1): a relative residual of 1 or more holds for any \
             vector (e.g. 1e-8)",
            request.tol
        )));
    }
    if request.max_iter == 0 {
        return Err(EigenError::InvalidRequest(
            "max_iter = 0: need at least one iteration (e.g. 1000)".into(),
        ));
    }
    Ok(())
}

/// Value stored at (i, j) (sum of duplicates; 0 if absent). Diagnostic use only.
fn entry(a: SparseMatrixRef<'_>, i: usize, j: usize) -> f64 {
    let range = a.symbolic().col_range(j);
    a.symbolic().row_idx()[range.clone()]
        .iter()
        .zip(&a.val()[range])
        .filter(|(&r, _)| r as usize == i)
        .map(|(_, &v)| v)
        .sum()
}

/// The M-normalized constant vector y0 = 1 / sqrt(1^T M 1) (length K), the exact null vector
/// of H that every solver returns as the first pair with eigenvalue 0.
///
/// # Errors
/// [`EigenError::NotPositiveDefinite`] if 1^T M 1 <= 0 (M cannot be SPD then).
pub fn constant_mode(m: SparseMatrixRef<'_>) -> Result<Vec<f64>, EigenError> {
    let k = m.nrows();
    // Compensated sum: a plain running sum of ~1e7 entries loses ~1e-10 relative, which
    // would show up directly as y0^T M y0 - 1.
    constant_mode_from_sum(k, compensated_sum(m.val().iter().copied()))
}

/// [`constant_mode`] from `total` = 1^T M 1 (however M is stored), length `k`.
///
/// # Errors
/// [`EigenError::NotPositiveDefinite`] if `total` <= 0 or is not finite.
pub fn constant_mode_from_sum(k: usize, total: f64) -> Result<Vec<f64>, EigenError> {
    if total.is_nan() || total <= 0.0 || !total.is_finite() {
        return Err(EigenError::NotPositiveDefinite {
            what: "M",
            detail: format!("1^T M 1 = {total:e} <= 0"),
        });
    }
    Ok(vec![1.0 / total.sqrt(); k])
}

/// Neumaier's compensated sum ([`crate::sparse::compensated_sum`]).
pub use crate::sparse::compensated_sum;

/// The library's pseudo-random generator ([`crate::random`]), for start vectors and synthetic
/// test data.
pub use crate::random::SplitMix64;
