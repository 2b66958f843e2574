//! A generalized eigenproblem given by operators ([`OperatorProblem`]) and what a solver needs
//! to know about it without an assembled matrix: validation, the 1-norms (estimated), the
//! spectral scale tr(H)/tr(M), the constant mode and the independent residual check.

use crate::eigen::operator::{apply_checked, probe_symmetry, LinearOperator, Preconditioner};
use crate::eigen::{
    compensated_sum, fill_residual_report, EigenError, EigenInfo, EigenRequest, SplitMix64,
};
use faer::Mat;

/// H c = lambda M c with H and M as operators (`dim() x dim()`, symmetric by contract; H PSD
/// with the constant vector in its null space, M SPD), and optionally the caller's
/// preconditioner T ~ (H + sigma M)^-1.
#[derive(Clone, Copy)]
pub struct OperatorProblem<'a> {
    /// The stiffness-like operator H.
    pub h: &'a dyn LinearOperator,
    /// The mass-like operator M.
    pub m: &'a dyn LinearOperator,
    /// The caller's preconditioner; `None`: the solver builds its own (from the assembled
    /// matrices when both operators have them, else Jacobi from their diagonals, else none).
    pub preconditioner: Option<&'a dyn Preconditioner>,
    /// Probe both operators for symmetry before solving ([`probe_symmetry`]: two applications
    /// each). Default off: symmetry is the caller's contract.
    pub probe_symmetry: bool,
}

impl<'a> OperatorProblem<'a> {
    /// The problem H c = lambda M c, no preconditioner, no symmetry probe.
    pub fn new(h: &'a dyn LinearOperator, m: &'a dyn LinearOperator) -> Self {
        Self {
            h,
            m,
            preconditioner: None,
            probe_symmetry: false,
        }
    }

    /// The same problem with the caller's preconditioner.
    pub fn with_preconditioner(mut self, preconditioner: &'a dyn Preconditioner) -> Self {
        self.preconditioner = Some(preconditioner);
        self
    }

    /// The same problem with the symmetry probe on or off.
    pub fn with_symmetry_probe(mut self, probe: bool) -> Self {
        self.probe_symmetry = probe;
        self
    }
}

/// Check an operator problem and a request before solving in one process: H and M the same
/// size K, each owning all rows (a distributed operator needs a distributed solver), the
/// request as [`crate::eigen::validate_problem`] accepts it, and the symmetry probe when asked.
///
/// # Errors
/// [`EigenError::InvalidRequest`] naming what is wrong; the probe's errors.
pub fn validate_operators(
    problem: &OperatorProblem<'_>,
    request: &EigenRequest,
) -> Result<(), EigenError> {
    let k = problem.h.dim();
    if problem.m.dim() != k {
        return Err(EigenError::InvalidRequest(format!(
            "H is {k} x {k} and M is {0} x {0}; both must be K x K",
            problem.m.dim()
        )));
    }
    for (name, op) in [("H", problem.h), ("M", problem.m)] {
        let rows = op.local_rows();
        if rows != (0..k) {
            return Err(EigenError::InvalidRequest(format!(
                "operator {name} owns rows {}..{} of {k}: this solver runs in one process and \
                 needs every row (0..{k}); a distributed operator goes to the SLEPc solver",
                rows.start, rows.end
            )));
        }
    }
    crate::eigen::validate_request(k, request)?;
    if problem.probe_symmetry {
        probe_symmetry(problem.h, "H", 0x5eed_0001)?;
        probe_symmetry(problem.m, "M", 0x5eed_0002)?;
    }
    Ok(())
}

/// An estimate of ||A||_1 from products with A only (Hager 1984, with Higham's 1988 extra
/// alternating-sign test vector, as LAPACK's `dlacon`): a lower bound, usually exact, and
/// within a small factor otherwise. A is symmetric, so A^T products are A products. Costs at
/// most 11 applications to one vector.
///
/// # Errors
/// The operator's errors ([`apply_checked`]).
pub fn estimate_norm_1(op: &dyn LinearOperator, which: &'static str) -> Result<f64, EigenError> {
    let k = op.dim();
    if k == 0 {
        return Ok(0.0);
    }
    let mut x = Mat::<f64>::from_fn(k, 1, |_, _| 1.0 / k as f64);
    let mut y = Mat::<f64>::zeros(k, 1);
    let mut estimate = 0.0f64;
    let mut last_j = usize::MAX;
    for round in 0..5 {
        apply_checked(op, which, x.as_ref(), y.as_mut())?;
        let norm = compensated_sum((0..k).map(|i| y[(i, 0)].abs()));
        if round > 0 && norm <= estimate {
            break;
        }
        estimate = norm;
        let signs = Mat::<f64>::from_fn(k, 1, |i, _| if y[(i, 0)] < 0.0 { -1.0 } else { 1.0 });
        apply_checked(op, which, signs.as_ref(), y.as_mut())?;
        let (j, zmax) = (0..k)
            .map(|i| (i, y[(i, 0)].abs()))
            .fold((0, -1.0), |best, c| if c.1 > best.1 { c } else { best });
        let zx = compensated_sum((0..k).map(|i| y[(i, 0)] * x[(i, 0)]));
        if (round > 0 && zmax <= zx) || j == last_j {
            break;
        }
        last_j = j;
        x.fill(0.0);
        x[(j, 0)] = 1.0;
    }
    let alt = Mat::<f64>::from_fn(k, 1, |i, _| {
        let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
        sign * (1.0 + i as f64 / (k.max(2) - 1) as f64)
    });
    apply_checked(op, which, alt.as_ref(), y.as_mut())?;
    let alt_estimate = 2.0 * compensated_sum((0..k).map(|i| y[(i, 0)].abs())) / (3.0 * k as f64);
    Ok(estimate.max(alt_estimate))
}

/// tr(H) / tr(M), the mean eigenvalue: exact from the diagonals when both operators give them,
/// otherwise Hutchinson's estimate with 8 fixed-seed Rademacher probes (the same probes for H
/// and M; the ratio is only used to scale a shift, where a factor of 2 does not matter).
///
/// # Errors
/// The operators' errors.
pub fn trace_ratio(h: &dyn LinearOperator, m: &dyn LinearOperator) -> Result<f64, EigenError> {
    if let (Some(dh), Some(dm)) = (h.diagonal(), m.diagonal()) {
        return Ok(compensated_sum(dh.into_iter()) / compensated_sum(dm.into_iter()));
    }
    const PROBES: usize = 8;
    let k = h.dim();
    let mut rng = SplitMix64::new(0x7ace);
    let z = Mat::<f64>::from_fn(
        k,
        PROBES,
        |_, _| {
            if rng.next_u64() & 1 == 0 {
                -1.0
            } else {
                1.0
            }
        },
    );
    let mut az = Mat::<f64>::zeros(k, PROBES);
    let mut quadratic = |op: &dyn LinearOperator, which| -> Result<f64, EigenError> {
        apply_checked(op, which, z.as_ref(), az.as_mut())?;
        Ok(compensated_sum(
            (0..PROBES)
                .flat_map(|j| (0..k).map(move |i| (i, j)))
                .map(|(i, j)| z[(i, j)] * az[(i, j)]),
        ))
    };
    let th = quadratic(h, "H")?;
    let tm = quadratic(m, "M")?;
    Ok(th / tm)
}

/// The M-normalized constant vector 1 / sqrt(1^T M 1) (length K) from one application of M.
///
/// # Errors
/// [`EigenError::NotPositiveDefinite`] if 1^T M 1 <= 0; the operator's errors.
pub fn constant_mode_of(m: &dyn LinearOperator) -> Result<Vec<f64>, EigenError> {
    let k = m.dim();
    let ones = Mat::<f64>::from_fn(k, 1, |_, _| 1.0);
    let mut m1 = Mat::<f64>::zeros(k, 1);
    apply_checked(m, "M", ones.as_ref(), m1.as_mut())?;
    let total = compensated_sum((0..k).map(|i| m1[(i, 0)]));
    if total.is_nan() || total <= 0.0 || !total.is_finite() {
        return Err(EigenError::NotPositiveDefinite {
            what: "M",
            detail: format!("1^T M 1 = {total:e} <= 0"),
        });
    }
    Ok(vec![1.0 / total.sqrt(); k])
}

/// [`crate::eigen::check_solution`] for operators: the same residuals and M-orthonormality
/// error, with the given 1-norms (exact or estimated) in the denominators.
///
/// # Errors
/// The operators' errors, or [`EigenError::InvalidRequest`] for mismatched shapes.
pub fn check_solution_operators(
    h: &dyn LinearOperator,
    m: &dyn LinearOperator,
    norms: (f64, f64),
    values: &[f64],
    vectors: &Mat<f64>,
    info: &mut EigenInfo,
) -> Result<(), EigenError> {
    let (k, nev) = (h.dim(), vectors.ncols());
    if vectors.nrows() != k || m.dim() != k || values.len() != nev {
        return Err(EigenError::InvalidRequest(format!(
            "check_solution: {} x {nev} vectors and {} values for K = {k}",
            vectors.nrows(),
            values.len()
        )));
    }
    let mut hx = Mat::<f64>::zeros(k, nev);
    let mut mx = Mat::<f64>::zeros(k, nev);
    apply_checked(h, "H", vectors.as_ref(), hx.as_mut())?;
    apply_checked(m, "M", vectors.as_ref(), mx.as_mut())?;
    fill_residual_report(values, vectors, &hx, &mx, norms, info);
    Ok(())
}
