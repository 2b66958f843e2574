//! Linear operators for the eigensolvers: H and M given as "apply to a block of vectors"
//! rather than as assembled matrices (PETSc's `MatShell`). An assembled [`SparseMatrix`] is one
//! implementation; a caller's own operator (an element-by-element FEM stiffness, a GPU
//! operator, a callback from C or Python) is another.
//!
//! The contract: the operator is square and symmetric (`x^T A y = y^T A x`), applied to blocks
//! of `b` vectors at once. Under MPI each rank owns a contiguous range of rows
//! ([`LinearOperator::local_rows`]) and applies the operator to its local rows only (the
//! operator exchanges whatever halo it needs itself); in one process the range is all rows.

use crate::sparse::{self, SparseMatrix};
use faer::{MatMut, MatRef};
use std::ops::Range;

/// Why applying an operator failed: a caller's callback reported an error (or raised, from
/// Python), or returned an output that cannot be used. The solver stops with it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct OperatorError {
    /// What went wrong, in the caller's words where the caller gave them.
    pub message: String,
}

impl OperatorError {
    /// An error with this message.
    pub fn new(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
        }
    }
}

/// A square symmetric linear operator on R^K, applied to blocks of vectors.
///
/// `Sync`: the native solver may call [`LinearOperator::apply`] from any one thread (never
/// from several at once for one operator; an implementation may parallelize inside).
pub trait LinearOperator: Sync {
    /// Global size K (rows and columns).
    fn dim(&self) -> usize;

    /// The rows this process owns, as PETSc's local sizes give them: a contiguous range of
    /// `0..dim()`. Default: all rows (one process). Under MPI the ranges of all ranks must
    /// tile `0..dim()` in rank order (the solver checks).
    fn local_rows(&self) -> Range<usize> {
        0..self.dim()
    }

    /// `out = A x` on this process's rows: `x` and `out` are `local_rows().len() x b` (any
    /// strides; the native solver passes row-major blocks). `out` is fully overwritten.
    ///
    /// # Errors
    /// [`OperatorError`] when the operator cannot be applied (a failing callback).
    fn apply(&self, x: MatRef<'_, f64>, out: MatMut<'_, f64>) -> Result<(), OperatorError>;

    /// The diagonal of A on this process's rows, if it is cheap to give (used for the
    /// spectral scale tr(H)/tr(M) and for Jacobi preconditioning). Default: unknown.
    fn diagonal(&self) -> Option<Vec<f64>> {
        None
    }

    /// The assembled matrix behind this operator, if there is one: lets a solver build a
    /// factorization preconditioner (IC(0), Cholesky) or hand the matrix to a backend as is.
    /// Default: none (matrix-free).
    fn assembled(&self) -> Option<&SparseMatrix> {
        None
    }
}

impl LinearOperator for SparseMatrix {
    fn dim(&self) -> usize {
        self.nrows()
    }

    fn apply(&self, x: MatRef<'_, f64>, out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        check_block_shapes(self.nrows(), &x, &out)?;
        sparse::sym_mul_block(self, x, out);
        Ok(())
    }

    fn diagonal(&self) -> Option<Vec<f64>> {
        Some(sparse::diagonal(self))
    }

    fn assembled(&self) -> Option<&SparseMatrix> {
        Some(self)
    }
}

/// A preconditioner for the eigensolver: `z ~ (H + sigma M)^{-1} r` for a block of residuals.
/// Applied to blocks `local_rows x b`; symmetric positive definite by contract.
pub trait Preconditioner: Sync {
    /// `z = T r` (both `local_rows x b`; `z` fully overwritten).
    ///
    /// # Errors
    /// [`OperatorError`] when it cannot be applied.
    fn apply(&self, r: MatRef<'_, f64>, z: MatMut<'_, f64>) -> Result<(), OperatorError>;
}

/// An error unless `x` and `out` are both `rows x b` for one `b`: a caller's operator that
/// receives or returns the wrong shape is refused with the shapes in the message.
///
/// # Errors
/// [`OperatorError`] naming both shapes.
pub fn check_block_shapes(
    rows: usize,
    x: &MatRef<'_, f64>,
    out: &MatMut<'_, f64>,
) -> Result<(), OperatorError> {
    if x.nrows() != rows || out.nrows() != rows || x.ncols() != out.ncols() {
        return Err(OperatorError::new(format!(
            "operator of {rows} rows applied to a {} x {} block with a {} x {} output",
            x.nrows(),
            x.ncols(),
            out.nrows(),
            out.ncols()
        )));
    }
    Ok(())
}
