//! Linear operators for the eigensolvers: H and M given as "apply to a block of vectors"
//! rather than as assembled matrices (PETSc's `MatShell`). An assembled [`SparseMatrix`] is one
//! implementation; a caller's own operator (an element-by-element FEM stiffness, a GPU
//! operator, a callback from C or Python) is another.
//!
//! The contract: the operator is square and symmetric (`x^T A y = y^T A x`), applied to blocks
//! of `b` vectors at once. Under MPI each rank owns a contiguous range of rows
//! ([`LinearOperator::local_rows`]) and applies the operator to its local rows only (the
//! operator exchanges whatever halo it needs itself); in one process the range is all rows.

use crate::eigen::{EigenError, SplitMix64};
use crate::sparse::{self, SparseMatrix, SparseMatrixRef};
use crate::triangle::UpperRef;
use faer::{Mat, MatMut, MatRef};
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
    fn assembled(&self) -> Option<SparseMatrixRef<'_>> {
        None
    }

    /// The assembled matrix behind this operator stored as its upper triangle only (half the
    /// memory; `crate::triangle`), if that is how it is held: the native solver then applies
    /// it with the upper-triangle kernels and factors IC(0) from it. Default: none.
    fn upper_triangle(&self) -> Option<UpperRef<'_>> {
        None
    }
}

/// A symmetric matrix stored as its upper triangle is an operator (matrix-free to every
/// solver but the native LOBPCG, which reads [`LinearOperator::upper_triangle`]).
impl LinearOperator for UpperRef<'_> {
    fn dim(&self) -> usize {
        UpperRef::dim(self)
    }

    fn apply(&self, x: MatRef<'_, f64>, mut out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        check_block_shapes(self.dim(), &x, &out)?;
        // The kernel takes row-major blocks: copy in and out (this generic path is not the
        // native solver's, which applies the kernel to its own row-major blocks).
        let (k, b) = (x.nrows(), x.ncols());
        let xr: Vec<f64> = (0..k)
            .flat_map(|i| (0..b).map(move |j| x[(i, j)]))
            .collect();
        let mut yr = vec![0.0; k * b];
        self.mul_row_major(&xr, b, &mut yr, b, b);
        for i in 0..k {
            for j in 0..b {
                out[(i, j)] = yr[i * b + j];
            }
        }
        Ok(())
    }

    fn diagonal(&self) -> Option<Vec<f64>> {
        Some(UpperRef::diagonal(self))
    }

    fn upper_triangle(&self) -> Option<UpperRef<'_>> {
        Some(*self)
    }
}

impl LinearOperator for SparseMatrixRef<'_> {
    fn dim(&self) -> usize {
        self.nrows()
    }

    fn apply(&self, x: MatRef<'_, f64>, out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        check_block_shapes(self.nrows(), &x, &out)?;
        sparse::sym_mul_block(*self, x, out);
        Ok(())
    }

    fn diagonal(&self) -> Option<Vec<f64>> {
        Some(sparse::diagonal(*self))
    }

    fn assembled(&self) -> Option<SparseMatrixRef<'_>> {
        Some(*self)
    }
}

impl LinearOperator for SparseMatrix {
    fn dim(&self) -> usize {
        self.nrows()
    }

    fn apply(&self, x: MatRef<'_, f64>, out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        self.as_ref().apply(x, out)
    }

    fn diagonal(&self) -> Option<Vec<f64>> {
        Some(sparse::diagonal(self.as_ref()))
    }

    fn assembled(&self) -> Option<SparseMatrixRef<'_>> {
        Some(self.as_ref())
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

/// A closure `f(r, z)` (`z = T r`) is a preconditioner.
impl<F> Preconditioner for F
where
    F: Fn(MatRef<'_, f64>, MatMut<'_, f64>) -> Result<(), OperatorError> + Sync,
{
    fn apply(&self, r: MatRef<'_, f64>, z: MatMut<'_, f64>) -> Result<(), OperatorError> {
        self(r, z)
    }
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

/// A [`LinearOperator`] made of a closure `f(x, out)` (`out = A x` for a `dim x b` block),
/// with an optional diagonal: the simplest way to pass one's own matrix-free operator. The
/// closure must be symmetric in the sense of the trait ([`probe_symmetry`] checks it).
pub struct FnOperator<F> {
    dim: usize,
    f: F,
    diagonal: Option<Vec<f64>>,
}

impl<F> FnOperator<F>
where
    F: Fn(MatRef<'_, f64>, MatMut<'_, f64>) -> Result<(), OperatorError> + Sync,
{
    /// An operator of size `dim` x `dim` applied by `f`; diagonal unknown.
    pub fn new(dim: usize, f: F) -> Self {
        Self {
            dim,
            f,
            diagonal: None,
        }
    }

    /// The same operator with its diagonal (length `dim`) known.
    pub fn with_diagonal(mut self, diagonal: Vec<f64>) -> Self {
        self.diagonal = Some(diagonal);
        self
    }
}

impl<F> LinearOperator for FnOperator<F>
where
    F: Fn(MatRef<'_, f64>, MatMut<'_, f64>) -> Result<(), OperatorError> + Sync,
{
    fn dim(&self) -> usize {
        self.dim
    }

    fn apply(&self, x: MatRef<'_, f64>, out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        (self.f)(x, out)
    }

    fn diagonal(&self) -> Option<Vec<f64>> {
        self.diagonal.clone()
    }
}

/// `out = A x` through `op`, with the checks a solver needs on a caller's operator: shapes
/// (`x`, `out` both `local_rows().len() x b`), the operator's own error, and a finite output. `which` names
/// the operator in the error ("H", "M").
///
/// # Errors
/// [`EigenError::Operator`] for a shape mismatch or a failing operator;
/// [`EigenError::NonFinite`] for a NaN or infinite output entry (the first one found).
pub fn apply_checked(
    op: &dyn LinearOperator,
    which: &'static str,
    x: MatRef<'_, f64>,
    mut out: MatMut<'_, f64>,
) -> Result<(), EigenError> {
    let to_error = |e: OperatorError| EigenError::Operator {
        which,
        message: e.message,
    };
    check_block_shapes(op.local_rows().len(), &x, &out).map_err(to_error)?;
    op.apply(x, out.as_mut()).map_err(to_error)?;
    first_non_finite(out.as_ref(), which)
}

/// `z = T r` through a caller's preconditioner, with the checks of [`apply_checked`]: `z` the
/// shape of `r`, the preconditioner's own error, a finite output.
///
/// # Errors
/// [`EigenError::Operator`] (named "preconditioner") for a shape mismatch or a failing
/// preconditioner; [`EigenError::NonFinite`] for a NaN or infinite output entry.
pub fn apply_preconditioner_checked(
    pre: &dyn Preconditioner,
    r: MatRef<'_, f64>,
    mut z: MatMut<'_, f64>,
) -> Result<(), EigenError> {
    let to_error = |e: OperatorError| EigenError::Operator {
        which: "preconditioner",
        message: e.message,
    };
    check_block_shapes(r.nrows(), &r, &z).map_err(to_error)?;
    pre.apply(r, z.as_mut()).map_err(to_error)?;
    first_non_finite(z.as_ref(), "preconditioner")
}

/// An error for the first NaN or infinite entry of `out`, naming `which`.
fn first_non_finite(out: MatRef<'_, f64>, which: &str) -> Result<(), EigenError> {
    for j in 0..out.ncols() {
        for i in 0..out.nrows() {
            let v = out[(i, j)];
            if !v.is_finite() {
                return Err(EigenError::NonFinite(format!(
                    "operator {which} returned {v} at row {i}, column {j} of a {} x {} block",
                    out.nrows(),
                    out.ncols()
                )));
            }
        }
    }
    Ok(())
}

/// Random probe of symmetry: for two fixed-seed random vectors x, y (entries in [-1, 1)),
/// compares x^T A y with y^T A x. Accepted when they differ by at most
/// `1e-10 (||A y|| ||x|| + ||A x|| ||y||)`: a symmetric operator differs only by round-off
/// (~1e-16 relative per product, times the accumulation length), while an asymmetric part of
/// relative size e shows up at ~e with probability 1 over the random pair. One probe costs
/// two applications.
///
/// # Errors
/// [`EigenError::InvalidRequest`] naming `which` when the probe finds asymmetry; the errors of
/// [`apply_checked`].
pub fn probe_symmetry(
    op: &dyn LinearOperator,
    which: &'static str,
    seed: u64,
) -> Result<(), EigenError> {
    let k = op.dim();
    let mut rng = SplitMix64::new(seed);
    let mut xy = Mat::<f64>::zeros(k, 2);
    for j in 0..2 {
        for i in 0..k {
            xy[(i, j)] = 2.0 * rng.next_f64() - 1.0;
        }
    }
    let mut a_xy = Mat::<f64>::zeros(k, 2);
    apply_checked(op, which, xy.as_ref(), a_xy.as_mut())?;
    let dot = |a: usize, b: usize| (0..k).map(|i| xy[(i, a)] * a_xy[(i, b)]).sum::<f64>();
    let norm = |m: &Mat<f64>, c: usize| (0..k).map(|i| m[(i, c)] * m[(i, c)]).sum::<f64>().sqrt();
    let (x_ay, y_ax) = (dot(0, 1), dot(1, 0));
    let scale = norm(&a_xy, 1) * norm(&xy, 0) + norm(&a_xy, 0) * norm(&xy, 1);
    if (x_ay - y_ax).abs() > 1e-10 * scale {
        return Err(EigenError::InvalidRequest(format!(
            "operator {which} is not symmetric: x^T {which} y = {x_ay:.6e} but y^T {which} x = \
             {y_ax:.6e} for random x, y (seed {seed:#x})"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1D Neumann Laplacian applied matrix-free (tridiagonal [-1 2 -1], ends 1): symmetric.
    fn laplacian(x: MatRef<'_, f64>, mut out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        let n = x.nrows();
        check_block_shapes(n, &x, &out)?;
        for j in 0..x.ncols() {
            for i in 0..n {
                let mut v = 0.0;
                if i > 0 {
                    v += x[(i, j)] - x[(i - 1, j)];
                }
                if i + 1 < n {
                    v += x[(i, j)] - x[(i + 1, j)];
                }
                out[(i, j)] = v;
            }
        }
        Ok(())
    }

    fn block(k: usize) -> (Mat<f64>, Mat<f64>) {
        (
            Mat::from_fn(k, 2, |i, j| (i + 3 * j) as f64),
            Mat::zeros(k, 2),
        )
    }

    #[test]
    fn symmetric_closure_passes_probe_and_applies() {
        let op = FnOperator::new(50, laplacian);
        probe_symmetry(&op, "H", 7).expect("symmetric Laplacian");
        let (x, mut out) = block(50);
        apply_checked(&op, "H", x.as_ref(), out.as_mut()).expect("applies");
        // Row 10 of column 0: 2 * 10 - 9 - 11 = 0; end row 0: 0 - 1 = -1.
        assert_eq!(out[(10, 0)], 0.0);
        assert_eq!(out[(0, 0)], -1.0);
    }

    #[test]
    fn nan_output_is_non_finite_naming_the_operator() {
        let op = FnOperator::new(20, |x: MatRef<'_, f64>, mut out: MatMut<'_, f64>| {
            laplacian(x, out.as_mut())?;
            out[(3, 1)] = f64::NAN;
            Ok(())
        });
        let (x, mut out) = block(20);
        match apply_checked(&op, "M", x.as_ref(), out.as_mut()) {
            Err(EigenError::NonFinite(msg)) => {
                assert!(
                    msg.contains("operator M") && msg.contains("row 3, column 1"),
                    "{msg}"
                )
            }
            other => panic!("expected NonFinite, got {other:?}"),
        }
    }

    #[test]
    fn callback_error_becomes_operator_error() {
        let op = FnOperator::new(20, |_: MatRef<'_, f64>, _: MatMut<'_, f64>| {
            Err(OperatorError::new("GPU out of memory"))
        });
        let (x, mut out) = block(20);
        match apply_checked(&op, "H", x.as_ref(), out.as_mut()) {
            Err(EigenError::Operator { which, message }) => {
                assert_eq!((which, message.as_str()), ("H", "GPU out of memory"))
            }
            other => panic!("expected Operator, got {other:?}"),
        }
    }

    #[test]
    fn wrong_block_shape_is_refused() {
        // The operator claims 20 rows; a 19-row block must be refused before it is applied.
        let op = FnOperator::new(20, laplacian);
        let (x, mut out) = block(19);
        match apply_checked(&op, "H", x.as_ref(), out.as_mut()) {
            Err(EigenError::Operator {
                which: "H",
                message,
            }) => {
                assert!(
                    message.contains("20 rows") && message.contains("19 x 2"),
                    "{message}"
                )
            }
            other => panic!("expected Operator, got {other:?}"),
        }
    }

    #[test]
    fn non_symmetric_operator_is_caught_by_the_probe() {
        // The Laplacian plus a strictly lower-triangular perturbation of relative size 1e-3:
        // far above the probe's 1e-10 round-off allowance.
        let op = FnOperator::new(30, |x: MatRef<'_, f64>, mut out: MatMut<'_, f64>| {
            laplacian(x, out.as_mut())?;
            for j in 0..x.ncols() {
                for i in 1..x.nrows() {
                    out[(i, j)] += 1e-3 * x[(i - 1, j)];
                }
            }
            Ok(())
        });
        match probe_symmetry(&op, "H", 7) {
            Err(EigenError::InvalidRequest(msg)) => assert!(msg.contains("not symmetric"), "{msg}"),
            other => panic!("expected InvalidRequest, got {other:?}"),
        }
    }

    #[test]
    fn sparse_matrix_operator_matches_the_kernel() {
        let a = crate::eigen::testing::grid_laplacian([3, 2, 2], 1.5);
        probe_symmetry(&a, "H", 3).expect("assembled Laplacian is symmetric");
        assert!(a.assembled().is_some() && a.diagonal().is_some());
        // Through the trait, a block gives exactly the dense product (entries are multiples of 1/2,
        // times small integers: every partial sum is exact in f64, in any order).
        let k = a.nrows();
        let dense = crate::sparse::to_dense(a.as_ref());
        let x = faer::Mat::from_fn(k, 2, |i, j| (i as f64) - 3.0 * (j as f64));
        let mut y = faer::Mat::<f64>::zeros(k, 2);
        apply_checked(&a, "H", x.as_ref(), y.as_mut()).expect("assembled apply");
        for j in 0..2 {
            for i in 0..k {
                let want: f64 = (0..k).map(|l| dense[(i, l)] * x[(l, j)]).sum();
                assert_eq!(y[(i, j)], want, "entry ({i}, {j})");
            }
        }
    }
}
