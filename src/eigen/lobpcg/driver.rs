//! One LOBPCG solve from start to report, over operators: the constant mode, the norms, the
//! preconditioner (the caller's, or built from the assembled matrices, or Jacobi from the
//! operators' diagonals), the iteration with its escalation to the exact factor, and the
//! independent check of the result. Assembled matrices take the exact paths they always took
//! (exact 1-norms, the compensated sum of M's entries, the fused kernels), so a
//! `SparseMatrix` problem gives the same bits as before operators existed.

use super::iterate::{State, Stop};
use super::operators::{upper_pair, Operators};
use super::options::{LobpcgOptions, PreconditionerKind};
use super::precondition::{self, Pencil, Preconditioner, SetupReport};
use crate::eigen::operator_problem::{
    check_solution_operators, constant_mode_of, estimate_norm_1, OperatorProblem,
};
use crate::eigen::{
    check_solution, constant_mode, constant_mode_from_sum, EigenError, EigenInfo, EigenRequest,
    EigenSolution, EigenStatus,
};
use crate::progress::Progress;
use crate::sparse;
use faer::{Mat, Par};
use std::time::Instant;

/// Solve `problem` (already validated) for `request.nev` pairs.
pub(super) fn solve(
    opts: &LobpcgOptions,
    problem: &OperatorProblem<'_>,
    request: &EigenRequest,
    progress: &dyn Progress,
) -> Result<EigenSolution, EigenError> {
    opts.validate()?;
    let clock = Instant::now();
    let (h, m) = (problem.h, problem.m);
    let assembled = h.assembled().zip(m.assembled());
    let upper = upper_pair(h, m);
    // What a factorization preconditioner is built from, if anything.
    let pencil = match (assembled, upper) {
        (Some((ha, ma)), _) => Some(Pencil::Full(ha, ma)),
        (None, Some((hu, mu))) => Some(Pencil::Upper(hu, mu)),
        (None, None) => None,
    };
    if let Some((hu, mu)) = upper {
        for (name, a) in [("H", hu), ("M", mu)] {
            if let Some((i, j)) = a.first_non_finite() {
                return Err(EigenError::NonFinite(format!(
                    "{name}[{i}, {j}] is NaN or infinite (H and M stored as upper triangles)"
                )));
            }
        }
    }
    let k = h.dim();
    let nev = request.nev;
    let nwant = nev - 1;
    if let Some((i, d)) = m
        .diagonal()
        .unwrap_or_default()
        .iter()
        .enumerate()
        .find(|(_, &d)| d.is_nan() || d <= 0.0)
    {
        return Err(EigenError::NotPositiveDefinite {
            what: "M",
            detail: format!("diagonal entry M[{i}, {i}] = {d:e}"),
        });
    }
    let y0 = match (m.assembled(), upper) {
        (Some(a), _) => constant_mode(a)?,
        (None, Some((_, mu))) => constant_mode_from_sum(k, mu.sum_all())?,
        (None, None) => constant_mode_of(m)?,
    };
    let norms = match (assembled, upper) {
        (Some((ha, ma)), _) => (sparse::norm_1(ha), sparse::norm_1(ma)),
        (None, Some((hu, mu))) => (hu.norm_1(), mu.norm_1()),
        (None, None) => (estimate_norm_1(h, "H")?, estimate_norm_1(m, "M")?),
    };
    let check = |values: &[f64], vectors: &Mat<f64>, info: &mut EigenInfo| match assembled {
        Some((ha, ma)) => {
            check_solution(ha, ma, values, vectors, info);
            Ok(())
        }
        None => check_solution_operators(h, m, norms, values, vectors, info),
    };
    let mut info = EigenInfo {
        solver: "lobpcg".into(),
        ..EigenInfo::default()
    };
    let seconds_norms = clock.elapsed().as_secs_f64();
    if upper.is_some() {
        info.notes.push(
            "H and M stored as upper triangles of one pattern: products by the two-pass \
             upper-triangle kernel; exact 1-norms"
                .into(),
        );
    } else if assembled.is_none() {
        info.notes.push(format!(
            "matrix-free: H and M applied as operators; 1-norms estimated (||H||_1 ~ {:.3e}, \
             ||M||_1 ~ {:.3e}, Hager-Higham lower bounds) for the relative residuals",
            norms.0, norms.1
        ));
    }
    if nwant == 0 {
        let vectors = Mat::from_fn(k, 1, |i, _| y0[i]);
        let values = vec![0.0];
        info.locked = 1;
        check(&values, &vectors, &mut info)?;
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
    let clock = Instant::now();
    let built = match (problem.preconditioner, pencil) {
        (Some(user), _) => Ok((
            Preconditioner::User(user),
            SetupReport {
                notes: vec!["preconditioner: the caller's".into()],
                ..SetupReport::default()
            },
        )),
        (None, Some(pencil)) => precondition::build_pencil(pencil, opts, nx, par),
        (None, None) => precondition::build_matrix_free(h, m, opts),
    };
    let (mut pre, mut report) = match built {
        Ok(built) => built,
        Err(e) => {
            progress.finish();
            return Err(e);
        }
    };
    info.notes.extend(report.notes.iter().cloned());
    // The exact factor's analysis (or a rejected attempt) freed many small allocations.
    crate::report::release_freed_memory();
    let seconds_setup = clock.elapsed().as_secs_f64();
    let clock = Instant::now();
    info.notes.push(format!(
        "block: {nwant} wanted + {} guard = {nx} columns; constant mode deflated; seed {:#x}",
        nx - nwant,
        opts.seed
    ));

    let ops = Operators::new(h, m, norms.0, norms.1);
    let mut state = match State::new(ops, &y0, nwant, nx) {
        Ok(state) => state,
        Err(e) => {
            progress.finish();
            return Err(e);
        }
    };
    // Auto with IC(0) may switch to the exact factor after `escalate_after` iterations if
    // that factor fits in `max_factor_entries` (IC(0) degrades when M is ill-conditioned).
    let can_escalate = opts.preconditioner == PreconditionerKind::Auto
        && pencil.is_some()
        && matches!(pre, Preconditioner::Incomplete(_))
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
    if let (Stop::MaxIter, true, Some(pencil)) = (&stop, first_cap < request.max_iter, pencil) {
        let notes_before = report.notes.len();
        if let Some(exact) = precondition::escalate(pencil, opts, nx, par, &mut report) {
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
    let seconds_iterations = clock.elapsed().as_secs_f64();
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
        Stop::Operator(e) => return Err(e),
        Stop::Cancelled => {
            return Err(EigenError::Cancelled {
                iterations: counters.iterations,
            })
        }
        _ => {}
    }
    // H must be PSD: a clearly negative Ritz value (beyond the residual tolerance) proves
    // x^T H x < 0 for some x, and the "constant mode first" ordering would be violated.
    let norm_h = norms.0;
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
            "stopped: no new search direction survived the orthogonalization (stagnation)".into(),
        );
    }
    let mut values = Vec::with_capacity(nev);
    values.push(0.0);
    values.extend_from_slice(&state.theta[..nwant]);
    let vectors = state.vectors_with_constant(&y0);
    // The iteration's blocks and the factor are not needed for the check: their memory goes
    // back before it allocates the products (at K = 1,000,000 this end was the peak).
    drop(state);
    drop(pre);
    let clock = Instant::now();
    check(&values, &vectors, &mut info)?;
    info.notes.push(format!(
        "time outside the iterations: constant mode and norms {seconds_norms:.2} s, \
         preconditioner setup {seconds_setup:.2} s, final check {:.2} s; the iterations (with \
         any switch of preconditioner) {seconds_iterations:.2} s",
        clock.elapsed().as_secs_f64()
    ));
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
