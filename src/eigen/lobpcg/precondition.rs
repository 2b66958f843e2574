//! The LOBPCG preconditioner T ~ (H + sigma M)^-1: built once, applied to the residual block
//! every iteration without allocating.
//!
//! - Cholesky: one sparse Cholesky factorization of H + sigma M (faer supernodal/simplicial,
//!   AMD ordering), applied by two triangular solves on all columns at once.
//! - IC(0): zero-fill incomplete Cholesky of H + sigma M ([`super::incomplete_cholesky`]),
//!   the shallow-fill option when the exact factor is too large.
//! - Jacobi: diag(H + sigma M)^-1.
//! - Identity: no preconditioning.
//! - User: a caller's [`crate::eigen::Preconditioner`], applied through a copy of the
//!   residual columns and checked for shape, error and finite output.
//!
//! Fallbacks (recorded in the notes): a failed Cholesky is retried with sigma x 100, then
//! replaced by Jacobi; an IC(0) breakdown is retried with growing diagonal shifts, then
//! replaced by Jacobi; `Auto` over its fill budget uses IC(0).

use super::incomplete_cholesky::{Breakdown, IncompleteCholesky};
use super::options::{LobpcgOptions, PreconditionerKind};
use super::workspace::{Block, ROW_CHUNK};
use crate::eigen::{self, EigenError};
use crate::sparse::{self, SparseMatrixRef};
use crate::triangle::UpperRef;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::{Conj, Par, Side};
use rayon::prelude::*;
use std::time::Instant;

/// A built preconditioner.
pub(super) enum Preconditioner<'a> {
    Cholesky(Box<Factor>),
    Incomplete(Box<IncompleteCholesky<'a>>),
    Jacobi { inv_diag: Vec<f64> },
    Identity,
    User(&'a dyn eigen::Preconditioner),
}

impl Preconditioner<'_> {
    /// The same preconditioner holding no borrow of H and M (an IC(0) factor copies the
    /// column indices it shares with them); `None` for a caller's, which is borrowed by nature.
    pub fn into_owned(self) -> Option<Preconditioner<'static>> {
        Some(match self {
            Self::Cholesky(factor) => Preconditioner::Cholesky(factor),
            Self::Incomplete(ic) => Preconditioner::Incomplete(Box::new(ic.into_owned())),
            Self::Jacobi { inv_diag } => Preconditioner::Jacobi { inv_diag },
            Self::Identity => Preconditioner::Identity,
            Self::User(_) => return None,
        })
    }
}

/// A sparse Cholesky factor with its solve workspace.
pub(super) struct Factor {
    symbolic: SymbolicCholesky<u32>,
    values: Vec<f64>,
    /// One solve scratch per group of columns ([`Preconditioner::apply`]).
    mems: Vec<MemBuffer>,
}

impl std::fmt::Debug for Preconditioner<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Cholesky(factor) => write!(f, "Cholesky({} factor entries)", factor.values.len()),
            Self::Incomplete(ic) => write!(f, "IC(0)({} factor entries)", ic.entries()),
            Self::Jacobi { .. } => write!(f, "Jacobi"),
            Self::Identity => write!(f, "Identity"),
            Self::User(_) => write!(f, "caller's preconditioner"),
        }
    }
}

/// Diagnostics of the preconditioner setup.
#[derive(Debug, Clone, Default)]
pub(super) struct SetupReport {
    /// The shift sigma used (0 for Identity).
    pub sigma: f64,
    /// Stored entries of the factor in use (0 if none).
    pub factor_entries: usize,
    /// Entries the exact Cholesky factor would have, when its symbolic analysis was run.
    pub exact_entries: Option<usize>,
    /// Seconds spent in the symbolic and numeric factorization.
    pub symbolic_seconds: f64,
    pub numeric_seconds: f64,
    /// Human-readable notes (kind, shift, fill, fallbacks).
    pub notes: Vec<String>,
}

/// Assembled H and M as the preconditioner reads them: both triangles, or upper triangles of
/// one pattern (`crate::triangle`).
#[derive(Clone, Copy)]
pub(super) enum Pencil<'a> {
    Full(SparseMatrixRef<'a>, SparseMatrixRef<'a>),
    Upper(UpperRef<'a>, UpperRef<'a>),
}

impl<'a> Pencil<'a> {
    /// The diagonals of H and M.
    fn diagonals(&self) -> (Vec<f64>, Vec<f64>) {
        match self {
            Pencil::Full(h, m) => (sparse::diagonal(*h), sparse::diagonal(*m)),
            Pencil::Upper(h, m) => (h.diagonal(), m.diagonal()),
        }
    }

    /// K.
    fn dim(&self) -> usize {
        match self {
            Pencil::Full(h, _) => h.nrows(),
            Pencil::Upper(h, _) => h.dim(),
        }
    }

    /// Entries of the lower triangle of A = H + sigma M at least (the larger of H's and M's).
    fn lower_entries(&self) -> usize {
        match self {
            Pencil::Full(h, m) => (h.val().len().max(m.val().len()) + h.nrows()) / 2,
            Pencil::Upper(h, _) => h.val().len(),
        }
    }

    /// IC(0) of H + sigma M with Manteuffel's shift alpha.
    fn factor_incomplete(
        &self,
        sigma: f64,
        alpha: f64,
    ) -> Result<IncompleteCholesky<'a>, Breakdown> {
        match *self {
            Pencil::Full(h, m) => IncompleteCholesky::factor(h, m, sigma, alpha),
            Pencil::Upper(h, m) => IncompleteCholesky::factor_upper(h, m, sigma, alpha),
        }
    }
}

/// The shift sigma of H + sigma M from the options: `shift_factor * tr(H) / tr(M)`.
#[cfg(test)]
pub(super) fn shift(h: SparseMatrixRef<'_>, m: SparseMatrixRef<'_>, opts: &LobpcgOptions) -> f64 {
    shift_of(&Pencil::Full(h, m), opts)
}

/// [`shift`] for either storage (the traces are the same sums).
fn shift_of(pencil: &Pencil<'_>, opts: &LobpcgOptions) -> f64 {
    let (dh, dm) = pencil.diagonals();
    let trace = |d: &[f64]| -> f64 { d.iter().sum() };
    opts.shift_factor * (trace(&dh) / trace(&dm))
}

/// Build the preconditioner for block products of up to `max_cols` columns.
pub(super) fn build<'a>(
    h: SparseMatrixRef<'a>,
    m: SparseMatrixRef<'a>,
    opts: &LobpcgOptions,
    max_cols: usize,
    par: Par,
) -> Result<(Preconditioner<'a>, SetupReport), EigenError> {
    build_pencil(Pencil::Full(h, m), opts, max_cols, par)
}

/// [`build`] for either storage of H and M.
pub(super) fn build_pencil<'a>(
    pencil: Pencil<'a>,
    opts: &LobpcgOptions,
    max_cols: usize,
    par: Par,
) -> Result<(Preconditioner<'a>, SetupReport), EigenError> {
    let mut report = SetupReport {
        sigma: shift_of(&pencil, opts),
        ..SetupReport::default()
    };
    if !(report.sigma.is_finite() && report.sigma > 0.0) {
        return Err(EigenError::NotPositiveDefinite {
            what: "H + sigma M",
            detail: format!(
                "shift sigma = {:e} from tr(H)/tr(M) is not positive",
                report.sigma
            ),
        });
    }
    let kind = opts.preconditioner;
    if kind == PreconditionerKind::Identity {
        report.sigma = 0.0;
        report.notes.push("preconditioner: none (identity)".into());
        return Ok((Preconditioner::Identity, report));
    }
    let mut try_incomplete = kind == PreconditionerKind::IncompleteCholesky;
    let mut early_incomplete = None;
    if matches!(
        kind,
        PreconditionerKind::Cholesky | PreconditionerKind::Auto
    ) {
        let budget = if kind == PreconditionerKind::Auto {
            Budget {
                entries: opts.max_factor_entries,
                fill_ratio: opts.max_fill_ratio,
            }
        } else {
            Budget {
                entries: usize::MAX,
                fill_ratio: f64::INFINITY,
            }
        };
        for attempt in 0..2 {
            let outcome = if attempt == 0 && kind == PreconditionerKind::Auto {
                // Both sequential: IC(0) of the same pencil is factored on the other thread
                // while the exact factor is analysed, ready for when the analysis rejects it.
                let sigma = report.sigma;
                let (exact, ic) = rayon::join(
                    || cholesky(pencil, sigma, budget, max_cols, par, &mut report),
                    || {
                        let mut ic_report = SetupReport {
                            sigma,
                            ..SetupReport::default()
                        };
                        (incomplete(pencil, sigma, &mut ic_report), ic_report)
                    },
                );
                early_incomplete = Some(ic);
                exact
            } else {
                cholesky(pencil, report.sigma, budget, max_cols, par, &mut report)
            };
            match outcome {
                Ok(pre) => return Ok((pre, report)),
                Err(CholeskyFailure::OverBudget {
                    entries,
                    ratio,
                    analysed: false,
                }) => {
                    report.notes.push(format!(
                        "preconditioner: the Cholesky factor of H + sigma M would hold at least \
                         {entries} entries ({ratio}x the lower triangle, the least fill seen), \
                         over the Auto limit of {} entries; using IC(0) without the symbolic \
                         analysis",
                        budget.entries
                    ));
                    try_incomplete = true;
                    break;
                }
                Err(CholeskyFailure::OverBudget { entries, ratio, .. }) => {
                    report.notes.push(format!(
                        "preconditioner: the Cholesky factor of H + sigma M would hold {entries} entries, \
                         {ratio:.1}x the lower triangle (Auto limits: {} entries, {}x; symbolic analysis \
                         {:.2} s); using IC(0) instead",
                        budget.entries, budget.fill_ratio, report.symbolic_seconds
                    ));
                    try_incomplete = true;
                    break;
                }
                Err(CholeskyFailure::Failed(why)) => {
                    if attempt == 0 {
                        report.notes.push(format!(
                            "preconditioner: Cholesky of H + sigma M failed with sigma = {:.3e} ({why}); \
                             retrying with sigma x 100",
                            report.sigma
                        ));
                        report.sigma *= 100.0;
                    } else {
                        report.notes.push(format!(
                            "preconditioner: Cholesky failed again with sigma = {:.3e} ({why}); falling \
                             back to Jacobi",
                            report.sigma
                        ));
                    }
                }
            }
        }
    }
    if try_incomplete {
        let ic = match early_incomplete {
            // Factored beside the analysis with the shift still in use.
            Some((ic, ic_report)) if ic_report.sigma == report.sigma => {
                if ic.is_some() {
                    report.numeric_seconds = ic_report.numeric_seconds;
                    report.factor_entries = ic_report.factor_entries;
                }
                report.notes.extend(ic_report.notes);
                ic
            }
            _ => incomplete(pencil, report.sigma, &mut report),
        };
        if let Some(ic) = ic {
            return Ok((Preconditioner::Incomplete(Box::new(ic)), report));
        }
    }
    let (dh, dm) = pencil.diagonals();
    let inv_diag = jacobi_from_diagonals(&dh, &dm, report.sigma)?;
    report.notes.push(format!(
        "preconditioner: Jacobi, diag(H + sigma M)^-1, sigma = {:.3e}",
        report.sigma
    ));
    Ok((Preconditioner::Jacobi { inv_diag }, report))
}

/// The preconditioner for operators without assembled matrices: Jacobi from their diagonals
/// (`Auto`, `Jacobi`) when both give one, otherwise none (`Auto`, `Identity`). The shift is
/// `shift_factor * tr(H) / tr(M)` as for matrices, the traces estimated when the diagonals
/// are unknown.
///
/// # Errors
/// [`EigenError::InvalidRequest`] for a factorization kind (there is no matrix to factor) or
/// for `Jacobi` without both diagonals; [`EigenError::NotPositiveDefinite`] for a
/// non-positive diagonal of H + sigma M.
pub(super) fn build_matrix_free(
    h: &dyn eigen::LinearOperator,
    m: &dyn eigen::LinearOperator,
    opts: &LobpcgOptions,
) -> Result<(Preconditioner<'static>, SetupReport), EigenError> {
    let kind = opts.preconditioner;
    let mut report = SetupReport::default();
    if matches!(
        kind,
        PreconditionerKind::Cholesky | PreconditionerKind::IncompleteCholesky
    ) {
        return Err(EigenError::InvalidRequest(format!(
            "preconditioner {kind:?} factors H + sigma M, but H and M are matrix-free \
             operators: pass your own preconditioner (OperatorProblem::with_preconditioner), \
             or choose auto, jacobi or identity"
        )));
    }
    let diagonals = h.diagonal().zip(m.diagonal());
    match (kind, diagonals) {
        (PreconditionerKind::Identity, _) => {
            report.notes.push("preconditioner: none (identity)".into());
            Ok((Preconditioner::Identity, report))
        }
        (PreconditionerKind::Auto, None) => {
            report.notes.push(
                "preconditioner: none; the operators give no diagonal to build Jacobi from \
                 and no preconditioner was passed (expect many more iterations)"
                    .into(),
            );
            Ok((Preconditioner::Identity, report))
        }
        (_, Some((dh, dm))) => {
            report.sigma = opts.shift_factor * eigen::operator_problem::trace_ratio(h, m)?;
            if !(report.sigma.is_finite() && report.sigma > 0.0) {
                return Err(EigenError::NotPositiveDefinite {
                    what: "H + sigma M",
                    detail: format!(
                        "shift sigma = {:e} from tr(H)/tr(M) is not positive",
                        report.sigma
                    ),
                });
            }
            let inv_diag = jacobi_from_diagonals(&dh, &dm, report.sigma)?;
            report.notes.push(format!(
                "preconditioner: Jacobi from the operators' diagonals, diag(H + sigma M)^-1, \
                 sigma = {:.3e}",
                report.sigma
            ));
            Ok((Preconditioner::Jacobi { inv_diag }, report))
        }
        (_, None) => Err(EigenError::InvalidRequest(
            "preconditioner Jacobi needs the diagonals of H and M, and an operator gives none \
             (LinearOperator::diagonal): give them, or choose auto or identity"
                .into(),
        )),
    }
}

/// The exact Cholesky preconditioner with the shift already in `report`, for an `Auto` run
/// that chose IC(0) and then converged too slowly; `None` (with a note) if the factor does
/// not fit in `max_factor_entries` or fails.
pub(super) fn escalate(
    pencil: Pencil<'_>,
    opts: &LobpcgOptions,
    max_cols: usize,
    par: Par,
    report: &mut SetupReport,
) -> Option<Preconditioner<'static>> {
    let budget = Budget {
        entries: opts.max_factor_entries,
        fill_ratio: f64::INFINITY,
    };
    match cholesky(pencil, report.sigma, budget, max_cols, par, report) {
        Ok(pre) => Some(pre),
        Err(CholeskyFailure::OverBudget { entries, .. }) => {
            report.notes.push(format!(
                "preconditioner: not switching to Cholesky: {entries} entries > max_factor_entries"
            ));
            None
        }
        Err(CholeskyFailure::Failed(why)) => {
            report.notes.push(format!(
                "preconditioner: switch to Cholesky failed ({why}); keeping IC(0)"
            ));
            None
        }
    }
}

/// IC(0) of H + sigma M, with Manteuffel's diagonal shift alpha = 0, 1e-3, 1e-2, 1e-1, 1 on
/// breakdown; `None` (with a note) if every attempt breaks down.
fn incomplete<'a>(
    pencil: Pencil<'a>,
    sigma: f64,
    report: &mut SetupReport,
) -> Option<IncompleteCholesky<'a>> {
    incomplete_with(sigma, report, |alpha| {
        pencil.factor_incomplete(sigma, alpha)
    })
}

/// [`incomplete`] with the factorization of one diagonal shift alpha given by `factor`.
fn incomplete_with<'a>(
    sigma: f64,
    report: &mut SetupReport,
    factor: impl Fn(f64) -> Result<IncompleteCholesky<'a>, Breakdown>,
) -> Option<IncompleteCholesky<'a>> {
    let t0 = Instant::now();
    for alpha in [0.0, 1e-3, 1e-2, 1e-1, 1.0] {
        match factor(alpha) {
            Ok(ic) => {
                report.numeric_seconds = t0.elapsed().as_secs_f64();
                report.factor_entries = ic.entries();
                report.notes.push(format!(
                    "preconditioner: IC(0) of H + sigma M (sigma = {sigma:.3e}, diagonal shift alpha = {alpha:e}): \
                     {} factor entries, {:.2} s",
                    ic.entries(),
                    report.numeric_seconds
                ));
                return Some(ic);
            }
            Err(Breakdown { row }) => {
                report.notes.push(format!(
                    "preconditioner: IC(0) broke down at row {row} with diagonal shift alpha = {alpha:e}"
                ));
            }
        }
    }
    report.notes.push(
        "preconditioner: IC(0) failed for every diagonal shift; falling back to Jacobi".into(),
    );
    None
}

/// Limits on the exact factor for `Auto`.
#[derive(Debug, Clone, Copy)]
struct Budget {
    entries: usize,
    fill_ratio: f64,
}

enum CholeskyFailure {
    /// The factor would be over the budget: `entries` from the symbolic analysis, or, when
    /// `analysed` is false, a lower bound (the analysis was skipped, see [`MIN_FILL`]).
    OverBudget {
        entries: usize,
        ratio: f64,
        analysed: bool,
    },
    Failed(String),
}

/// Fill below which no pencil here has been seen (factor entries over the entries of the lower
/// triangle): 2.8x at K = 1,000 on the beam, growing with K. When even this fill would put the
/// factor over the entry budget, the symbolic analysis is skipped: at K = 1,000,000 it took
/// 117 s only to find 19.4 billion entries.
const MIN_FILL: f64 = 2.0;

/// Most columns of one sequential Cholesky solve in [`Preconditioner::apply`]: a 40-column
/// block (32 modes and 8 guards) is two groups, one per core here. Narrower groups were
/// slower per column (4 columns: 1.4x the preconditioner's time at K = 6,000), and each
/// column's arithmetic depends on its group's width, so the width is fixed, not the thread
/// count's.
const SOLVE_GROUP: usize = 20;

fn cholesky(
    pencil: Pencil<'_>,
    sigma: f64,
    budget: Budget,
    max_cols: usize,
    par: Par,
    report: &mut SetupReport,
) -> Result<Preconditioner<'static>, CholeskyFailure> {
    // A = H + sigma M has the union of the two patterns, so at least as many entries as
    // either: a bound known before A is formed (4 GB at K = 1,000,000).
    let least = (pencil.lower_entries() as f64 * MIN_FILL) as usize;
    if least > budget.entries {
        return Err(CholeskyFailure::OverBudget {
            entries: least,
            ratio: MIN_FILL,
            analysed: false,
        });
    }
    // With one pattern for H and M (the assembled pencil) the analysis reads H's, and A is
    // formed only for a factor within budget; otherwise A's pattern is the union. An upper
    // triangle is analysed and factored as faer's `Side::Upper`.
    let (union, side) = match pencil {
        Pencil::Full(h, m) => {
            let same = sparse::same_pattern(h, m);
            if !same && h.val().len() + m.val().len() > sparse::MAX_ENTRIES {
                return Err(CholeskyFailure::Failed(
                    "the union of the patterns of H and M may exceed a SparseMatrix's u32 range"
                        .into(),
                ));
            }
            (
                (!same).then(|| sparse::add_scaled(1.0, h, sigma, m)),
                Side::Lower,
            )
        }
        Pencil::Upper(..) => (None, Side::Upper),
    };
    let pattern = match (&union, pencil) {
        (Some(u), _) => u.as_ref().symbolic(),
        (None, Pencil::Full(h, _)) => h.symbolic(),
        (None, Pencil::Upper(h, _)) => h.pattern().symbolic(),
    };
    let k = pencil.dim();
    let lower = match side {
        Side::Lower => (pattern.row_idx().len() + k) / 2,
        Side::Upper => pattern.row_idx().len(),
    };
    let t0 = Instant::now();
    let symbolic =
        factorize_symbolic_cholesky(pattern, side, SymmetricOrdering::Amd, Default::default())
            .map_err(|e| CholeskyFailure::Failed(format!("symbolic analysis: {e:?}")))?;
    report.symbolic_seconds = t0.elapsed().as_secs_f64();
    let entries = symbolic.len_val();
    report.factor_entries = entries;
    report.exact_entries = Some(entries);
    let ratio = entries as f64 / lower.max(1) as f64;
    if entries > budget.entries || ratio > budget.fill_ratio {
        return Err(CholeskyFailure::OverBudget {
            entries,
            ratio,
            analysed: true,
        });
    }
    // A's values on the pattern analysed.
    let upper_values: Vec<f64>;
    let formed;
    let a = match (union, pencil) {
        (Some(a), _) => {
            formed = a;
            formed.as_ref()
        }
        (None, Pencil::Full(h, m)) => {
            formed = sparse::add_scaled(1.0, h, sigma, m);
            formed.as_ref()
        }
        (None, Pencil::Upper(h, m)) => {
            upper_values = h
                .val()
                .iter()
                .zip(m.val())
                .map(|(&a, &b)| 1.0 * a + sigma * b)
                .collect();
            SparseMatrixRef::new(h.pattern().symbolic(), &upper_values)
        }
    };
    let mut values = Vec::new();
    values
        .try_reserve_exact(entries)
        .map_err(|_| CholeskyFailure::Failed(format!("out of memory for {entries} entries")))?;
    values.resize(entries, 0.0);
    let t1 = Instant::now();
    {
        let req = symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default());
        let mut mem = MemBuffer::try_new(req)
            .map_err(|_| CholeskyFailure::Failed("out of memory for scratch".into()))?;
        symbolic
            .factorize_numeric_llt(
                &mut values,
                a,
                side,
                Default::default(),
                par,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .map_err(|e| CholeskyFailure::Failed(format!("numeric factorization: {e:?}")))?;
    }
    report.numeric_seconds = t1.elapsed().as_secs_f64();
    if !values.iter().all(|v| v.is_finite()) {
        return Err(CholeskyFailure::Failed("non-finite factor entries".into()));
    }
    // The solves run sequentially on groups of at most SOLVE_GROUP columns
    // ([`Preconditioner::apply`]), each with its own scratch.
    let groups = max_cols.max(1).div_ceil(SOLVE_GROUP);
    let group_cols = max_cols.clamp(1, SOLVE_GROUP);
    let mems = (0..groups)
        .map(|_| {
            MemBuffer::try_new(symbolic.solve_in_place_scratch::<f64>(group_cols, Par::Seq))
                .map_err(|_| CholeskyFailure::Failed("out of memory for solve scratch".into()))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let kind = match symbolic.raw() {
        SymbolicCholeskyRaw::Simplicial(_) => "simplicial",
        SymbolicCholeskyRaw::Supernodal(_) => "supernodal",
    };
    report.notes.push(format!(
        "preconditioner: sparse Cholesky of H + sigma M (sigma = {sigma:.3e}, AMD, {kind}): {entries} factor \
         entries ({:.1}x the {} stored entries of the lower triangle of A, {:.2} GB), symbolic {:.2} s, numeric {:.2} s",
        entries as f64 / lower.max(1) as f64,
        lower,
        entries as f64 * 8e-9,
        report.symbolic_seconds,
        report.numeric_seconds
    ));
    Ok(Preconditioner::Cholesky(Box::new(Factor {
        symbolic,
        values,
        mems,
    })))
}

/// diag(H + sigma M)^-1 from the two diagonals (both length K).
pub(super) fn jacobi_from_diagonals(
    dh: &[f64],
    dm: &[f64],
    sigma: f64,
) -> Result<Vec<f64>, EigenError> {
    dh.iter()
        .zip(dm)
        .enumerate()
        .map(|(i, (&a, &b))| {
            let d = a + sigma * b;
            if d > 0.0 && d.is_finite() {
                Ok(1.0 / d)
            } else {
                Err(EigenError::NotPositiveDefinite {
                    what: "H + sigma M",
                    detail: format!("diagonal entry {i} is {d:e} (H_ii = {a:e}, M_ii = {b:e})"),
                })
            }
        })
        .collect()
}

impl Preconditioner<'_> {
    /// Replace columns `c0..c0 + w` of `s` by T applied to them (`tmp` has at least `w`
    /// columns).
    ///
    /// # Errors
    /// Only a caller's preconditioner fails: its error, a wrong shape, a non-finite output.
    pub fn apply(
        &mut self,
        s: &mut Block,
        c0: usize,
        w: usize,
        tmp: &mut Block,
    ) -> Result<(), EigenError> {
        if w == 0 {
            return Ok(());
        }
        match self {
            Self::Cholesky(factor) => {
                // Groups of at most SOLVE_GROUP columns, solved sequentially side by side:
                // faer's parallel supernodal solve was slower than its sequential one at
                // every size measured (docs/performance.md). The groups depend on w only,
                // so the result does not depend on the thread count.
                let Factor {
                    symbolic,
                    values,
                    mems,
                } = &mut **factor;
                let llt = LltRef::new(symbolic, values);
                let width = w.div_ceil(w.div_ceil(SOLVE_GROUP));
                let mut rest = s.cols_mut(c0, w);
                let mut parts = Vec::with_capacity(mems.len());
                while rest.ncols() > width {
                    let (head, tail) = rest.split_at_col_mut(width);
                    parts.push(head);
                    rest = tail;
                }
                parts.push(rest);
                // w <= max_cols, so the groups are at most the scratches built for them.
                debug_assert!(parts.len() <= mems.len());
                parts
                    .into_par_iter()
                    .zip(mems.par_iter_mut())
                    .for_each(|(cols, mem)| {
                        llt.solve_in_place_with_conj(Conj::No, cols, Par::Seq, MemStack::new(mem));
                    });
            }
            Self::Incomplete(ic) => ic.solve_in_place(s, c0, w, tmp),
            Self::Jacobi { inv_diag } => {
                let ld = s.ld;
                s.data
                    .par_chunks_mut(ld * ROW_CHUNK)
                    .zip(inv_diag.par_chunks(ROW_CHUNK))
                    .for_each(|(d, inv)| {
                        for (row, &f) in d.chunks_mut(ld).zip(inv) {
                            row[c0..c0 + w].iter_mut().for_each(|v| *v *= f);
                        }
                    });
            }
            Self::Identity => {}
            Self::User(user) => {
                let ld = tmp.ld;
                for (dst, src) in tmp.data.chunks_mut(ld).zip(s.data.chunks(s.ld)) {
                    dst[..w].copy_from_slice(&src[c0..c0 + w]);
                }
                eigen::operator::apply_preconditioner_checked(
                    *user,
                    tmp.cols(0, w),
                    s.cols_mut(c0, w),
                )?;
            }
        }
        Ok(())
    }
}
