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

mod incomplete_cholesky;
mod iterate;
mod orthogonalize;
mod precondition;
mod rayleigh_ritz;
mod workspace;

use super::{
    check_solution, constant_mode, validate_problem, EigenError, EigenInfo, EigenRequest,
    EigenSolution, EigenStatus, Eigensolver,
};
use crate::progress::Progress;
use crate::sparse::{self, SparseMatrix};
use faer::{Mat, Par};
use iterate::{State, Stop};

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
        let opts = &self.options;
        let k = h.nrows();
        let nev = request.nev;
        let nwant = nev - 1;
        if let Some((i, d)) = sparse::diagonal(m)
            .iter()
            .enumerate()
            .find(|(_, &d)| d.is_nan() || d <= 0.0)
        {
            return Err(EigenError::NotPositiveDefinite {
                what: "M",
                detail: format!("diagonal entry M[{i}, {i}] = {d:e}"),
            });
        }
        let y0 = constant_mode(m)?;
        let mut info = EigenInfo {
            solver: "lobpcg".into(),
            ..EigenInfo::default()
        };
        if nwant == 0 {
            let vectors = Mat::from_fn(k, 1, |i, _| y0[i]);
            let values = vec![0.0];
            info.locked = 1;
            check_solution(h, m, &values, &vectors, &mut info);
            return Ok(EigenSolution {
                values,
                vectors,
                info,
            });
        }
        let guard = opts.guard_for(nwant);
        let nx = (nwant + guard).min(k - 1);
        let par = Par::rayon(0);
        progress.begin("eigen (lobpcg)", Some(request.max_iter as u64));
        let (mut pre, mut report) = match precondition::build(h, m, opts, nx, par) {
            Ok(built) => built,
            Err(e) => {
                progress.finish();
                return Err(e);
            }
        };
        info.notes.extend(report.notes.iter().cloned());
        info.notes.push(format!(
            "block: {nwant} wanted + {} guard = {nx} columns; constant mode deflated; seed {:#x}",
            nx - nwant,
            opts.seed
        ));

        let mut state = State::new(h, m, &y0, nwant, nx);
        // Auto with IC(0) may switch to the exact factor after `escalate_after` iterations if
        // that factor fits in `max_factor_entries` (IC(0) degrades when M is ill-conditioned).
        let can_escalate = opts.preconditioner == PreconditionerKind::Auto
            && matches!(pre, precondition::Preconditioner::Incomplete(_))
            && report
                .exact_entries
                .is_some_and(|e| e <= opts.max_factor_entries);
        let first_cap = match (can_escalate, opts.escalate_after) {
            (true, Some(after)) => after.min(request.max_iter),
            _ => request.max_iter,
        };
        let mut stop = match state.start(opts.seed, opts) {
            Ok(()) => state.run(request.tol, first_cap, opts, &mut pre, progress),
            Err(stop) => stop,
        };
        if matches!(stop, Stop::MaxIter) && first_cap < request.max_iter {
            let notes_before = report.notes.len();
            if let Some(exact) = precondition::escalate(h, m, opts, nx, par, &mut report) {
                pre = exact;
                info.notes.push(format!(
                    "preconditioner: IC(0) not converged after {first_cap} iterations; switched to the exact Cholesky"
                ));
            }
            info.notes
                .extend(report.notes[notes_before..].iter().cloned());
            stop = state.run(request.tol, request.max_iter, opts, &mut pre, progress);
        }
        progress.finish();
        // Make the returned vectors consistent with explicitly computed products.
        let stop = match stop {
            Stop::MaxIter | Stop::Stagnated => match state.finalize(opts) {
                Ok(()) => stop,
                Err(other) => other,
            },
            other => other,
        };
        let counters = &state.counters;
        info.iterations = counters.iterations;
        info.restarts = counters.restarts;
        info.matvecs = counters.matvecs;
        info.locked = 1 + state.residuals[..nwant]
            .iter()
            .filter(|&&r| r <= request.tol)
            .count();
        info.notes.push(format!(
            "time: preconditioner {:.2} s, sparse products {:.2} s, orthogonalization {:.2} s, \
             Rayleigh-Ritz and updates {:.2} s",
            counters.seconds_precondition,
            counters.seconds_spmm,
            counters.seconds_ortho,
            counters.seconds_rayleigh_ritz
        ));
        info.notes.push(format!(
            "explicit convergence checks: {}; final P width {}",
            counters.explicit_checks,
            state.p_width()
        ));
        if nx > nwant {
            let last = state.theta[nwant - 1];
            let next = state.theta[nwant];
            if (next - last).abs() <= 1e-8 * last.abs().max(f64::MIN_POSITIVE) {
                info.notes.push(format!(
                    "the cut splits a cluster: values[{}] = {last:.12e} and the first guard Ritz value {next:.12e} \
                     coincide; the returned vectors span part of a multiple eigenvalue's eigenspace",
                    nwant
                ));
            }
        }
        match stop {
            Stop::Indefinite(detail) => {
                return Err(EigenError::NotPositiveDefinite { what: "M", detail })
            }
            Stop::Breakdown(detail) => {
                return Err(EigenError::NonFinite(format!("LOBPCG breakdown: {detail}")))
            }
            Stop::Cancelled => {
                return Err(EigenError::Cancelled {
                    iterations: counters.iterations,
                })
            }
            _ => {}
        }
        // H must be PSD: a clearly negative Ritz value (beyond the residual tolerance) proves
        // x^T H x < 0 for some x, and the "constant mode first" ordering would be violated.
        let norm_h = sparse::norm_1(h);
        if state.theta[0] < -request.tol * norm_h {
            return Err(EigenError::NotPositiveDefinite {
                what: "H",
                detail: format!(
                    "Rayleigh quotient {:.3e} < 0 (||H||_1 = {norm_h:.3e}): H is not positive semidefinite",
                    state.theta[0]
                ),
            });
        }
        if matches!(stop, Stop::Stagnated) {
            info.notes.push(
                "stopped: no new search direction survived the orthogonalization (stagnation)"
                    .into(),
            );
        }
        let mut values = Vec::with_capacity(nev);
        values.push(0.0);
        values.extend_from_slice(&state.theta[..nwant]);
        let wanted = state.wanted_vectors();
        let vectors = Mat::from_fn(
            k,
            nev,
            |i, j| if j == 0 { y0[i] } else { wanted[(i, j - 1)] },
        );
        check_solution(h, m, &values, &vectors, &mut info);
        if info.residuals[0] > request.tol {
            info.notes.push(format!(
                "the constant vector is not in the null space of H to the tolerance: relative residual {:.3e}",
                info.residuals[0]
            ));
        }
        let converged = info.residuals.iter().filter(|&&r| r <= request.tol).count();
        if !(matches!(stop, Stop::Converged) && converged == nev) {
            info.status = EigenStatus::NotConverged {
                iterations: info.iterations,
                converged,
                nev,
                tol: request.tol,
                max_residual: info.max_relative_residual,
            };
        }
        Ok(EigenSolution {
            values,
            vectors,
            info,
        })
    }
}

#[cfg(test)]
mod tests;
