//! The eigensolver over the caller's operators: `ff_eigen_solve_operators` takes H and M (and
//! optionally a preconditioner) as C callbacks with a context pointer, applied to blocks of
//! column-major vectors, and runs the native LOBPCG matrix-free.

use crate::{guard, Status};
use faer::{Mat, MatMut, MatRef};
use freeform::eigen::lobpcg::Lobpcg;
use freeform::eigen::{
    EigenRequest, Eigensolver, LinearOperator, OperatorError, OperatorProblem, Preconditioner,
};
use freeform::progress::Silent;
use std::cell::RefCell;
use std::ffi::{c_char, c_int, c_void, CStr};

/// `y = A x` for a block of `ncols` vectors of length `k`, both column-major (column j at
/// `x + j k`). Return 0 on success; anything else stops the solve (the message is the one
/// given to `ff_callback_error`, else the code).
pub type FfApply = Option<
    unsafe extern "C" fn(
        ctx: *mut c_void,
        x: *const f64,
        y: *mut f64,
        k: usize,
        ncols: usize,
    ) -> c_int,
>;

thread_local! {
    static CALLBACK_ERROR: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Set the message of the failure a callback is about to report (call it from inside the
/// callback, then return non-zero). NULL clears it.
#[no_mangle]
pub unsafe extern "C" fn ff_callback_error(message: *const c_char) {
    let text = if message.is_null() {
        None
    } else {
        // SAFETY: the caller passes a NUL-terminated string.
        Some(
            unsafe { CStr::from_ptr(message) }
                .to_string_lossy()
                .into_owned(),
        )
    };
    CALLBACK_ERROR.with(|e| *e.borrow_mut() = text);
}

/// A C callback as an operator or preconditioner.
struct Callback {
    k: usize,
    f: unsafe extern "C" fn(*mut c_void, *const f64, *mut f64, usize, usize) -> c_int,
    ctx: *mut c_void,
    diagonal: Option<Vec<f64>>,
    name: &'static str,
}

// SAFETY: the native solver calls an operator from the thread that called the solve, one call
// at a time (operator.rs's contract); the context pointer is only passed back to the caller.
unsafe impl Sync for Callback {}

impl Callback {
    /// Copy x into a contiguous column-major block, prefill y with NaN (so a callback that
    /// writes fewer than k x ncols values is caught as a non-finite output), call, copy out.
    fn call(&self, x: MatRef<'_, f64>, mut out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        let (k, b) = (self.k, x.ncols());
        let xin = Mat::<f64>::from_fn(k, b, |i, j| x[(i, j)]);
        let mut y = vec![f64::NAN; k * b];
        let xs: Vec<f64> = (0..b)
            .flat_map(|j| xin.col(j).iter().copied().collect::<Vec<_>>())
            .collect();
        CALLBACK_ERROR.with(|e| e.borrow_mut().take());
        // SAFETY: buffers of k x b doubles; the caller's function and context as given.
        let code = unsafe { (self.f)(self.ctx, xs.as_ptr(), y.as_mut_ptr(), k, b) };
        if code != 0 {
            let message = CALLBACK_ERROR
                .with(|e| e.borrow_mut().take())
                .unwrap_or_else(|| format!("the {} callback returned {code}", self.name));
            return Err(OperatorError::new(message));
        }
        for j in 0..b {
            for i in 0..k {
                out[(i, j)] = y[j * k + i];
            }
        }
        Ok(())
    }
}

impl LinearOperator for Callback {
    fn dim(&self) -> usize {
        self.k
    }
    fn apply(&self, x: MatRef<'_, f64>, out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        self.call(x, out)
    }
    fn diagonal(&self) -> Option<Vec<f64>> {
        self.diagonal.clone()
    }
}

impl Preconditioner for Callback {
    fn apply(&self, r: MatRef<'_, f64>, z: MatMut<'_, f64>) -> Result<(), OperatorError> {
        self.call(r, z)
    }
}

fn diagonal(ptr: *const f64, k: usize, name: &str) -> Result<Option<Vec<f64>>, (Status, String)> {
    if ptr.is_null() {
        return Ok(None);
    }
    // SAFETY: the caller passes k doubles (documented).
    let d = unsafe { std::slice::from_raw_parts(ptr, k) }.to_vec();
    if let Some(i) = d.iter().position(|v| !v.is_finite()) {
        return Err((
            Status::InvalidArgument,
            format!("{name}[{i}] = {} is not finite", d[i]),
        ));
    }
    Ok(Some(d))
}

/// The `nev` smallest eigenpairs of H x = lambda M x (H PSD with the constant vector in its
/// null space, M SPD, both K x K symmetric), by the native LOBPCG with H and M applied only
/// through the callbacks `h` and `m` (contexts `h_ctx`, `m_ctx`). Preconditioner: `pre` (may
/// be NULL; `pre_ctx` its context) applying T ~ (H + sigma M)^-1 to residual blocks; if NULL,
/// Jacobi when both diagonals `h_diag`, `m_diag` (K doubles each, may be NULL) are given, else
/// none. Writes `values` (nev, ascending, the first 0 for the constant mode) and `vectors`
/// (K x nev row-major, M-orthonormal); `iterations` (may be NULL) gets LOBPCG's count.
/// Callbacks are called from the calling thread, one at a time.
///
/// Errors: `FF_ERR_NULL_POINTER`; `FF_ERR_INVALID_ARGUMENT` (k, nev, tol, a non-finite
/// diagonal); `FF_ERR_EIGENSOLVER` (a callback failed, returned NaN, or wrote too little; M
/// not positive definite; not converged), with the message in `ff_last_error()`.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn ff_eigen_solve_operators(
    k: usize,
    nev: usize,
    tol: f64,
    max_iter: usize,
    h: FfApply,
    h_ctx: *mut c_void,
    m: FfApply,
    m_ctx: *mut c_void,
    pre: FfApply,
    pre_ctx: *mut c_void,
    h_diag: *const f64,
    m_diag: *const f64,
    values: *mut f64,
    vectors: *mut f64,
    iterations: *mut usize,
) -> c_int {
    guard(|| {
        let (Some(hf), Some(mf)) = (h, m) else {
            return Err((
                Status::NullPointer,
                "h and m callbacks must not be NULL".into(),
            ));
        };
        if values.is_null() || vectors.is_null() {
            return Err((
                Status::NullPointer,
                "values and vectors must not be NULL".into(),
            ));
        }
        let hop = Callback {
            k,
            f: hf,
            ctx: h_ctx,
            diagonal: diagonal(h_diag, k, "h_diag")?,
            name: "H",
        };
        let mop = Callback {
            k,
            f: mf,
            ctx: m_ctx,
            diagonal: diagonal(m_diag, k, "m_diag")?,
            name: "M",
        };
        let pop = pre.map(|f| Callback {
            k,
            f,
            ctx: pre_ctx,
            diagonal: None,
            name: "preconditioner",
        });
        let mut problem = OperatorProblem::new(&hop, &mop);
        if let Some(p) = &pop {
            problem = problem.with_preconditioner(p);
        }
        let request = EigenRequest { nev, tol, max_iter };
        let solution = Lobpcg::default()
            .solve_operators(&problem, &request, &Silent)
            .and_then(|s| s.into_converged())
            .map_err(|e| crate::lib_error(&freeform::Error::Eigen(e)))?;
        // SAFETY: the caller passes nev and k x nev doubles (documented).
        let vals = unsafe { std::slice::from_raw_parts_mut(values, nev) };
        vals.copy_from_slice(&solution.values);
        let vecs = unsafe { std::slice::from_raw_parts_mut(vectors, k * nev) };
        for i in 0..k {
            for j in 0..nev {
                vecs[i * nev + j] = solution.vectors[(i, j)];
            }
        }
        if !iterations.is_null() {
            unsafe { *iterations = solution.info.iterations };
        }
        Ok(())
    })
}
