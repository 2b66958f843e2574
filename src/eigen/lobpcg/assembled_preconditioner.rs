//! The native preconditioner T ~ (H + sigma M)^-1 (exact Cholesky, IC(0) or Jacobi, chosen as
//! [`LobpcgOptions::preconditioner`] chooses) built from assembled matrices and handed out as
//! a [`crate::eigen::Preconditioner`]: a caller who applies H and M matrix-free can still
//! precondition with a factor of assembled copies (or of a simpler operator), and the cost of
//! the operator interface can be measured against the direct path with the same factor.

use super::options::LobpcgOptions;
use super::precondition::{self, Preconditioner};
use super::workspace::Block;
use crate::eigen::{self, validate_problem, EigenError, EigenRequest, OperatorError};
use crate::sparse::SparseMatrixRef;
use faer::{MatMut, MatRef, Par};
use std::sync::Mutex;

/// A built native preconditioner behind the [`crate::eigen::Preconditioner`] trait. Applying
/// it copies the residual block into its own row-major workspace (K x w), solves there and
/// copies the result out; calls from several threads are serialized.
pub struct AssembledPreconditioner {
    inner: Mutex<Workspace>,
    rows: usize,
    max_cols: usize,
    notes: Vec<String>,
}

struct Workspace {
    pre: Preconditioner<'static>,
    block: Block,
    tmp: Block,
}

impl AssembledPreconditioner {
    /// Build T for H, M (both K x K, validated as [`crate::eigen::Eigensolver::solve`] does)
    /// with `options`, sized for the LOBPCG block that `request` leads to (nev - 1 wanted plus
    /// the guard vectors).
    ///
    /// # Errors
    /// As the native solver's preconditioner setup: invalid problems, a non-positive shift
    /// or diagonal.
    pub fn build(
        h: SparseMatrixRef<'_>,
        m: SparseMatrixRef<'_>,
        options: &LobpcgOptions,
        request: &EigenRequest,
    ) -> Result<Self, EigenError> {
        validate_problem(h, m, request)?;
        let k = h.nrows();
        let nwant = request.nev - 1;
        let max_cols = (nwant + options.guard_for(nwant)).min(k - 1).max(1);
        let (pre, report) = precondition::build(h, m, options, max_cols, Par::rayon(0))?;
        // It outlives the matrices it was built from.
        let pre = pre.into_owned().ok_or_else(|| {
            EigenError::InvalidRequest("a built preconditioner cannot be the caller's".into())
        })?;
        Ok(Self {
            inner: Mutex::new(Workspace {
                pre,
                block: Block::new(k, max_cols),
                tmp: Block::new(k, max_cols),
            }),
            rows: k,
            max_cols,
            notes: report.notes,
        })
    }

    /// What the setup chose and measured (kind, shift, fill, fallbacks), as in a solve's notes.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The widest block it applies to at once.
    pub fn max_cols(&self) -> usize {
        self.max_cols
    }
}

impl eigen::Preconditioner for AssembledPreconditioner {
    fn apply(&self, r: MatRef<'_, f64>, mut z: MatMut<'_, f64>) -> Result<(), OperatorError> {
        eigen::operator::check_block_shapes(self.rows, &r, &z)?;
        let w = r.ncols();
        if w > self.max_cols {
            return Err(OperatorError::new(format!(
                "preconditioner built for blocks of at most {} columns applied to {w}",
                self.max_cols
            )));
        }
        let mut guard = self
            .inner
            .lock()
            .map_err(|_| OperatorError::new("preconditioner poisoned by an earlier panic"))?;
        let Workspace { pre, block, tmp } = &mut *guard;
        block.cols_mut(0, w).copy_from(r);
        pre.apply(block, 0, w, tmp)
            .map_err(|e| OperatorError::new(e.to_string()))?;
        z.copy_from(block.cols(0, w));
        Ok(())
    }
}
