//! What the SLEPc paths share (feature `slepc`): how `EPSSolve` ended ([`SolveStatus`]), the
//! verdict on SLEPc's pairs ([`convergence_status`]), PETSc errors as [`EigenError`], and the
//! option names of a `--petsc-options` string.

use super::{EigenError, EigenRequest, EigenSolution, EigenStatus, SlepcLobpcgStop};
use freeform_ffi as petsc;

/// How `EPSSolve` ended, beside the pairs: what [`convergence_status`] needs to word a
/// failure.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SolveStatus {
    /// EPS type in use ("krylovschur", "lobpcg", ...).
    pub eps_type: String,
    /// SLEPc's iteration count.
    pub iterations: usize,
    /// Pairs SLEPc reported converged (`EPSGetConverged`; may exceed nev).
    pub converged: usize,
    /// SLEPc's `EPSConvergedReason` (> 0 converged; -1 iteration cap, -2 breakdown).
    pub reason: i32,
    /// LOBPCG block size in use (LOBPCG only).
    pub block_size: Option<usize>,
}

pub(super) fn backend(e: petsc::PetscError) -> EigenError {
    EigenError::Backend {
        library: "PETSc/SLEPc",
        message: e.to_string(),
    }
}

/// PETSc options put into the global database for one solve and cleared again when this is
/// dropped, after the solve: objects PETSc creates while setting up (the levels of a multigrid
/// preconditioner, say) read the database then, so clearing the options right after
/// `EPSSetFromOptions` would silently drop every option for them.
pub(super) struct ScopedOptions<'s> {
    session: &'s petsc::Session,
    names: Vec<String>,
}

impl<'s> ScopedOptions<'s> {
    /// Insert `options` (e.g. `"-eps_type lobpcg -st_pc_type gamg"`).
    pub(super) fn insert(
        session: &'s petsc::Session,
        options: &str,
    ) -> Result<Self, petsc::PetscError> {
        let scoped = Self {
            session,
            names: option_names(options)
                .into_iter()
                .map(String::from)
                .collect(),
        };
        session.options_insert(options)?;
        Ok(scoped)
    }

    /// Whether an option of this name (or starting with it) was given.
    pub(super) fn has_prefix(&self, prefix: &str) -> bool {
        self.names.iter().any(|n| n.starts_with(prefix))
    }
}

impl Drop for ScopedOptions<'_> {
    fn drop(&mut self) {
        for name in &self.names {
            // Clearing an option that is not set is not an error in PETSc.
            let _ = self.session.options_clear(name);
        }
    }
}

/// Option names (`-eps_type`) in an options string: tokens starting with `-` and a letter.
pub(super) fn option_names(options: &str) -> Vec<&str> {
    options
        .split_whitespace()
        .filter(|t| {
            let mut c = t.chars();
            c.next() == Some('-') && c.next().is_some_and(|c| c.is_ascii_alphabetic())
        })
        .collect()
}

/// Judge SLEPc's pairs (`solution`, with freeform's recomputed residuals in `solution.info`):
/// converged when `request.nev` of them came back and each residual is at most
/// [`RESIDUAL_SLACK`] x tol. Otherwise, with SLEPc's LOBPCG,
/// [`EigenStatus::SlepcLobpcgNotConverged`] naming what happened (SLEPc reported `nev` pairs
/// converged but some are not, the worst one named; it stopped at its iteration cap; or it
/// stopped for another reason, `status.reason`); with any other EPS type,
/// [`EigenStatus::NotConverged`]. [`EigenSolution::into_converged`] turns either into its
/// error.
pub fn convergence_status(
    k: usize,
    request: &EigenRequest,
    status: &SolveStatus,
    solution: &EigenSolution,
) -> EigenStatus {
    let limit = super::SLEPC_RESIDUAL_SLACK * request.tol;
    let residuals = &solution.info.residuals;
    let good = residuals.iter().filter(|&&r| r <= limit).count();
    let complete = solution.values.len() >= request.nev;
    if complete && good >= request.nev {
        return EigenStatus::Converged;
    }
    if status.eps_type != "lobpcg" {
        return EigenStatus::NotConverged {
            iterations: status.iterations,
            converged: good,
            nev: request.nev,
            tol: request.tol,
            // Pairs SLEPc did not converge are not available at all: their residual is unknown.
            max_residual: if complete {
                solution.info.max_relative_residual
            } else {
                f64::INFINITY
            },
        };
    }
    let stop =
        if complete {
            // The worst pair; NaN residuals are +inf after check_solution.
            let (pair, residual) = residuals.iter().copied().enumerate().fold(
                (0, f64::NEG_INFINITY),
                |best, (j, r)| {
                    if r > best.1 {
                        (j, r)
                    } else {
                        best
                    }
                },
            );
            SlepcLobpcgStop::ClaimedConverged {
                pair,
                lambda: solution.values[pair],
                residual,
                above: residuals.len() - good,
            }
        } else if status.reason == -1 {
            SlepcLobpcgStop::IterationCap
        } else {
            SlepcLobpcgStop::Stopped {
                reason: status.reason,
            }
        };
    EigenStatus::SlepcLobpcgNotConverged {
        stop,
        iterations: status.iterations,
        reported: status.converged,
        converged: good,
        nev: request.nev,
        tol: request.tol,
        max_iter: request.max_iter,
        k,
        block_size: status.block_size,
    }
}
