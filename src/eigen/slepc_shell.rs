//! SLEPc over operators (feature `slepc`): H and M become PETSc shell matrices whose product
//! calls the caller's [`LinearOperator`] on this rank's rows, and the preconditioner a shell
//! PC (the caller's [`crate::eigen::Preconditioner`], else Jacobi from the operators'
//! diagonals, else none). The solver is SLEPc's LOBPCG with ST `precond` and the
//! `EPS_CONV_NORM` test (shift-and-invert would need a factorization of a matrix that does not
//! exist); `SlepcOptions::petsc_options` still apply on top.
//!
//! Under `mpirun` every rank passes its own operators: each owns the rows
//! [`LinearOperator::local_rows`] says, the ranges must tile 0..K in rank order (checked on
//! every rank from one all-reduce, so all ranks refuse together), and the operator applies to
//! its local rows (exchanging whatever halo it needs itself). The 1-norms of the residual test
//! are estimated collectively (Hager-Higham on the distributed vectors), and the residuals and
//! M-orthonormality are recomputed through the operators, each rank on its rows, summed.

use super::slepc_status::{backend, convergence_status, ScopedOptions, SolveStatus};
use super::{
    apply_checked, apply_preconditioner_checked, relative_residual, validate_request, EigenError,
    EigenInfo, EigenRequest, EigenSolution, LinearOperator, OperatorProblem, SlepcOptions,
};
use faer::{Mat, MatMut, MatRef};
use freeform_ffi as petsc;
use std::ops::Range;

/// Collective sums and maxima over the ranks of one communicator.
struct Reduce<'a> {
    session: &'a petsc::Session,
    comm: petsc::Comm,
    rank: usize,
    size: usize,
}

impl Reduce<'_> {
    fn sum(&self, values: &mut [f64]) -> Result<(), EigenError> {
        self.session
            .allreduce_sum(self.comm, values)
            .map_err(backend)
    }
    fn max(&self, values: &mut [f64]) -> Result<(), EigenError> {
        self.session
            .allreduce_max(self.comm, values)
            .map_err(backend)
    }
}

/// `A x` on this rank's rows, through the checks of [`apply_checked`].
fn apply_local(
    op: &dyn LinearOperator,
    which: &'static str,
    x: &[f64],
) -> Result<Vec<f64>, EigenError> {
    let mut y = vec![0.0; x.len()];
    apply_checked(
        op,
        which,
        MatRef::from_column_major_slice(x, x.len(), 1),
        MatMut::from_column_major_slice_mut(&mut y, x.len(), 1),
    )?;
    Ok(y)
}

/// Every rank's row range, from one all-reduce; an error (the same on every rank) unless the
/// ranges of H and M agree and tile 0..k in rank order.
fn check_tiling(
    reduce: &Reduce<'_>,
    rank: usize,
    size: usize,
    k: usize,
    h: Range<usize>,
    m: Range<usize>,
) -> Result<(), EigenError> {
    let mut table = vec![0.0; 4 * size];
    table[4 * rank..4 * rank + 4].copy_from_slice(&[
        h.start as f64,
        h.end as f64,
        m.start as f64,
        m.end as f64,
    ]);
    reduce.sum(&mut table)?;
    let ranges: Vec<[usize; 4]> = table
        .chunks(4)
        .map(|c| [c[0] as usize, c[1] as usize, c[2] as usize, c[3] as usize])
        .collect();
    let mut next = 0;
    for (r, [hs, he, ms, me]) in ranges.iter().copied().enumerate() {
        if (hs, he) != (ms, me) {
            return Err(EigenError::InvalidRequest(format!(
                "rank {r}: H owns rows {hs}..{he} but M owns {ms}..{me}; both must own the same rows"
            )));
        }
        if hs != next || he < hs || he > k {
            let list: Vec<String> = ranges
                .iter()
                .enumerate()
                .map(|(r, c)| format!("rank {r}: {}..{}", c[0], c[1]))
                .collect();
            return Err(EigenError::InvalidRequest(format!(
                "the operators' row ranges do not tile 0..{k} in rank order ({})",
                list.join(", ")
            )));
        }
        next = he;
    }
    if next != k {
        return Err(EigenError::InvalidRequest(format!(
            "the operators' row ranges do not tile 0..{k}: together they cover 0..{next}"
        )));
    }
    Ok(())
}

/// Hager-Higham estimate of ||A||_1 on distributed vectors (see
/// [`super::operator_problem::estimate_norm_1`]; the same algorithm with the sums, the
/// maximum and the argmax taken over all ranks).
fn estimate_norm_1(
    reduce: &Reduce<'_>,
    op: &dyn LinearOperator,
    which: &'static str,
    rows: Range<usize>,
    k: usize,
) -> Result<f64, EigenError> {
    let n = rows.len();
    let sum = |v: f64| -> Result<f64, EigenError> {
        let mut a = [v];
        reduce.sum(&mut a)?;
        Ok(a[0])
    };
    let mut x = vec![1.0 / k as f64; n];
    let (mut estimate, mut last_j) = (0.0f64, usize::MAX);
    for round in 0..5 {
        let y = apply_local(op, which, &x)?;
        let norm = sum(y.iter().map(|v| v.abs()).sum())?;
        if round > 0 && norm <= estimate {
            break;
        }
        estimate = norm;
        let signs: Vec<f64> = y
            .iter()
            .map(|&v| if v < 0.0 { -1.0 } else { 1.0 })
            .collect();
        let z = apply_local(op, which, &signs)?;
        let local_max = z.iter().map(|v| v.abs()).fold(-1.0, f64::max);
        let mut global = [local_max];
        reduce.max(&mut global)?;
        // The smallest global index attaining the maximum: max of -index.
        let candidate = z
            .iter()
            .position(|v| v.abs() == global[0])
            .map_or(f64::NEG_INFINITY, |i| -((rows.start + i) as f64));
        let mut pick = [candidate];
        reduce.max(&mut pick)?;
        let j = (-pick[0]) as usize;
        let zx = sum(z.iter().zip(&x).map(|(a, b)| a * b).sum())?;
        if (round > 0 && global[0] <= zx) || j == last_j {
            break;
        }
        last_j = j;
        x.fill(0.0);
        if rows.contains(&j) {
            x[j - rows.start] = 1.0;
        }
    }
    let alt: Vec<f64> = rows
        .clone()
        .map(|i| {
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            sign * (1.0 + i as f64 / (k.max(2) - 1) as f64)
        })
        .collect();
    let y = apply_local(op, which, &alt)?;
    let alt_estimate = 2.0 * sum(y.iter().map(|v| v.abs()).sum())? / (3.0 * k as f64);
    Ok(estimate.max(alt_estimate))
}

/// The shell-matrix callback for `op`: `y = A x` on this rank's rows, checked; a failure on
/// any rank fails the product on every rank ([`fail_together`]).
fn shell_apply<'c>(
    op: &'c dyn LinearOperator,
    which: &'static str,
    reduce: &'c Reduce<'c>,
) -> petsc::ShellApply<'c> {
    Box::new(move |x: &[f64], y: &mut [f64]| {
        let n = x.len();
        let local = apply_checked(
            op,
            which,
            MatRef::from_column_major_slice(x, n, 1),
            MatMut::from_column_major_slice_mut(y, n, 1),
        )
        .map_err(|e| e.to_string());
        fail_together(reduce, which, local)
    })
}

/// Under MPI, a product that fails on one rank only would leave the others waiting in SLEPc's
/// next collective call: every application ends with one all-reduce of a failure flag, and
/// the ranks whose own part succeeded fail too, naming the ranks that did not. (A callback
/// must still make its own collective calls, e.g. its halo exchange, on every rank alike.)
fn fail_together(
    reduce: &Reduce<'_>,
    which: &'static str,
    local: Result<(), String>,
) -> Result<(), String> {
    if reduce.size < 2 {
        return local;
    }
    let mut failed = vec![0.0; reduce.size];
    failed[reduce.rank] = f64::from(u8::from(local.is_err()));
    reduce.sum(&mut failed).map_err(|e| e.to_string())?;
    let ranks: Vec<usize> = (0..reduce.size).filter(|&r| failed[r] > 0.0).collect();
    match local {
        Err(e) => Err(e),
        Ok(()) if !ranks.is_empty() => Err(format!(
            "{which} failed on MPI rank(s) {ranks:?} (their errors say why); every rank stops"
        )),
        Ok(()) => Ok(()),
    }
}

/// Solve `problem` with SLEPc's LOBPCG on shell matrices (every rank calls this with its own
/// operators). Eigenvectors are gathered onto every rank (K x nev).
///
/// # Errors
/// [`EigenError::InvalidRequest`] for sizes, requests or row ranges that do not fit;
/// [`EigenError::Operator`] / [`EigenError::NonFinite`] when an operator or the
/// preconditioner fails inside SLEPc; [`EigenError::Backend`] for other PETSc failures.
pub(super) fn solve(
    problem: &OperatorProblem<'_>,
    request: &EigenRequest,
    options: &SlepcOptions,
) -> Result<EigenSolution, EigenError> {
    let (h, m) = (problem.h, problem.m);
    let k = h.dim();
    if m.dim() != k {
        return Err(EigenError::InvalidRequest(format!(
            "H is {k} x {k} and M is {0} x {0}; both must be K x K",
            m.dim()
        )));
    }
    validate_request(k, request)?;
    let session = petsc::session().map_err(backend)?;
    let world = session.world();
    let rank = session.rank(world).map_err(backend)?;
    let size = session.size(world).map_err(backend)?;
    let reduce = Reduce {
        session: &session,
        comm: world,
        rank,
        size,
    };
    let rows = h.local_rows();
    check_tiling(&reduce, rank, size, k, rows.clone(), m.local_rows())?;
    let norm_h = estimate_norm_1(&reduce, h, "H", rows.clone(), k)?;
    let norm_m = estimate_norm_1(&reduce, m, "M", rows.clone(), k)?;
    let n = rows.len();
    // Jacobi of H + sigma M from the diagonals, when there is no caller's preconditioner.
    let jacobi = match (problem.preconditioner, h.diagonal().zip(m.diagonal())) {
        (None, Some((dh, dm))) => {
            let mut traces = [dh.iter().sum::<f64>(), dm.iter().sum::<f64>()];
            reduce.sum(&mut traces)?;
            let sigma = 1e-4 * traces[0] / traces[1];
            let inv: Vec<f64> = dh
                .iter()
                .zip(&dm)
                .map(|(a, b)| 1.0 / (a + sigma * b))
                .collect();
            let mut bad = [if inv.iter().all(|v| v.is_finite() && *v > 0.0) {
                0.0
            } else {
                1.0
            }];
            reduce.max(&mut bad)?;
            (bad[0] == 0.0).then_some(inv)
        }
        _ => None,
    };
    let shell = |op, which, norm| {
        // SAFETY: the EPS is declared after the shells and dropped before them (reverse order
        // of declaration), and all of them before this function returns, while the operators
        // live.
        unsafe {
            petsc::Mat::shell(
                &session,
                world,
                n,
                k,
                Some(norm),
                shell_apply(op, which, &reduce),
            )
        }
        .map_err(backend)
    };
    let (hm, h_failure) = shell(h, "H", norm_h)?;
    let (mm, m_failure) = shell(m, "M", norm_m)?;
    let mut eps = petsc::Eps::new(&session, world).map_err(backend)?;
    eps.set_operators(&hm, &mm).map_err(backend)?;
    eps.set_problem_type(petsc::ProblemType::Ghep)
        .map_err(backend)?;
    eps.set_dimensions(request.nev).map_err(backend)?;
    eps.set_tolerances(request.tol, request.max_iter)
        .map_err(backend)?;
    eps.set_convergence_test(petsc::Convergence::Norm)
        .map_err(backend)?;
    eps.set_type("lobpcg").map_err(backend)?;
    eps.set_which(petsc::Which::SmallestReal).map_err(backend)?;
    eps.set_spectral_transform(Some("precond"), Some("preonly"), Some("none"), None)
        .map_err(backend)?;
    let pc_failure = match (problem.preconditioner, &jacobi) {
        (Some(user), _) => {
            let reduce = &reduce;
            let apply: petsc::ShellApply<'_> = Box::new(move |x: &[f64], y: &mut [f64]| {
                let n = x.len();
                let local = apply_preconditioner_checked(
                    user,
                    MatRef::from_column_major_slice(x, n, 1),
                    MatMut::from_column_major_slice_mut(y, n, 1),
                )
                .map_err(|e| e.to_string());
                fail_together(reduce, "preconditioner", local)
            });
            // SAFETY: as for the shells above.
            Some(unsafe { eps.set_shell_preconditioner(apply) }.map_err(backend)?)
        }
        (None, Some(inv)) => {
            let apply: petsc::ShellApply<'_> = Box::new(move |x: &[f64], y: &mut [f64]| {
                for ((yi, xi), d) in y.iter_mut().zip(x).zip(inv) {
                    *yi = xi * d;
                }
                Ok(())
            });
            // SAFETY: as for the shells above.
            Some(unsafe { eps.set_shell_preconditioner(apply) }.map_err(backend)?)
        }
        (None, None) => None,
    };
    // In the database until the solve is over (objects made at setup read it then).
    let scoped = ScopedOptions::insert(&session, &options.petsc_options).map_err(backend)?;
    eps.set_from_options().map_err(backend)?;
    let solved = eps.solve();
    drop(scoped);
    if let Err(e) = solved {
        for (which, failure) in [
            ("H", Some(&h_failure)),
            ("M", Some(&m_failure)),
            ("preconditioner", pc_failure.as_ref()),
        ] {
            if let Some(message) = failure.and_then(|f| f.take()) {
                return Err(EigenError::Operator { which, message });
            }
        }
        return Err(backend(e));
    }
    let converged = eps.converged().map_err(backend)?;
    let status = SolveStatus {
        eps_type: "lobpcg".into(),
        iterations: eps.iterations().map_err(backend)?,
        converged,
        reason: eps.converged_reason().map_err(backend)?,
        block_size: eps.lobpcg_block_size().ok().filter(|&b| b > 0),
    };
    let mut x = hm.create_vector().map_err(backend)?;
    let mut pairs: Vec<(f64, Vec<f64>, Vec<f64>)> = Vec::new();
    for i in 0..converged.min(request.nev) {
        let lambda = eps.eigenpair(i, &mut x).map_err(backend)?;
        pairs.push((
            lambda,
            x.local_values().map_err(backend)?,
            x.gather_all().map_err(backend)?,
        ));
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let [eps_type, st_type, ksp_type, pc_type, _] = eps.describe().map_err(backend)?;
    let nev = pairs.len();
    let mut info = EigenInfo {
        solver: "slepc:matrix-free".into(),
        iterations: status.iterations,
        locked: converged,
        notes: vec![
            format!(
                "slepc: matrix-free, eps {eps_type}, st {st_type}, ksp {ksp_type}, pc {pc_type} ({}), {size} MPI rank(s), {converged} converged",
                match (problem.preconditioner, &jacobi) {
                    (Some(_), _) => "the caller's preconditioner",
                    (None, Some(_)) => "Jacobi from the operators' diagonals",
                    (None, None) => "no preconditioner",
                }
            ),
            format!(
                "matrix-free: 1-norms estimated (||H||_1 ~ {norm_h:.3e}, ||M||_1 ~ {norm_m:.3e}, Hager-Higham lower bounds) for the relative residuals"
            ),
        ],
        ..EigenInfo::default()
    };
    if !options.petsc_options.is_empty() {
        info.notes
            .push(format!("slepc: options {}", options.petsc_options));
    }
    // Residuals and M-orthonormality through the operators, each rank on its rows.
    let local = Mat::<f64>::from_fn(n, nev, |i, j| pairs[j].1[i]);
    let mut hx = Mat::<f64>::zeros(n, nev);
    let mut mx = Mat::<f64>::zeros(n, nev);
    apply_checked(h, "H", local.as_ref(), hx.as_mut())?;
    apply_checked(m, "M", local.as_ref(), mx.as_mut())?;
    let mut sums = vec![0.0; 2 * nev + nev * nev];
    for j in 0..nev {
        let lambda = pairs[j].0;
        for i in 0..n {
            let r = hx[(i, j)] - lambda * mx[(i, j)];
            sums[j] += r * r;
            sums[nev + j] += local[(i, j)] * local[(i, j)];
        }
        for a in 0..nev {
            sums[2 * nev + a * nev + j] = (0..n).map(|i| local[(i, a)] * mx[(i, j)]).sum();
        }
    }
    reduce.sum(&mut sums)?;
    info.residuals = (0..nev)
        .map(|j| {
            relative_residual(
                sums[j].sqrt(),
                pairs[j].0,
                norm_h,
                norm_m,
                sums[nev + j].sqrt(),
            )
        })
        .collect();
    info.max_relative_residual = info.residuals.iter().copied().fold(0.0, f64::max);
    info.orthonormality_error = (0..nev * nev)
        .map(|e| {
            let (a, j) = (e / nev, e % nev);
            let d = (sums[2 * nev + e] - if a == j { 1.0 } else { 0.0 }).abs();
            if d.is_nan() {
                f64::INFINITY
            } else {
                d
            }
        })
        .fold(0.0, f64::max);
    let vectors = Mat::<f64>::from_fn(k, nev, |i, j| pairs[j].2[i]);
    let mut solution = EigenSolution {
        values: pairs.iter().map(|p| p.0).collect(),
        vectors,
        info,
    };
    solution.info.status = convergence_status(k, request, &status, &solution);
    Ok(solution)
}
