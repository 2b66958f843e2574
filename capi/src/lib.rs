//! The C API of freeform: build a skinning basis from arrays, read eigenvalues and
//! coefficients, evaluate weights and gradients, free; and the live simulation of a scene
//! file ([`world`]: open, step, read positions and state, move boundary targets and
//! colliders, free). Header: `ffi/include/freeform.h`; guide: `docs/c-api.md`.
//!
//! Conventions: every function returns an `int` status (0 = `FF_OK`, see [`Status`]); on
//! failure [`ff_last_error`] returns the message (per thread, valid until the next failing
//! call on that thread). No Rust panic crosses the boundary: a panic becomes
//! `FF_ERR_PANIC`. Arrays are row-major `double`; sizes are `size_t`.
#![warn(missing_docs)]
// The exported functions take raw pointers by design; each checks them for NULL and
// documents the lengths it reads or writes.
#![allow(clippy::missing_safety_doc)]

use freeform::material::MaterialField;
use freeform::options::Front;
use freeform::precompute::rkpm::KernelType;
use freeform::precompute::sampling::IntegrationPoints;
use freeform::precompute::skinning::Basis;
use freeform::precompute::{BasisOptions, Problem, SolverConfig};
use freeform::progress::Silent;
use std::cell::RefCell;
use std::ffi::{c_char, c_int, CString};

pub mod eigen;
pub mod gradient;
pub mod world;
pub use eigen::*;
pub use gradient::*;
pub use world::*;

/// Status codes (the `FF_*` constants of the header).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// Success.
    Ok = 0,
    /// A required pointer was NULL.
    NullPointer = 1,
    /// A parameter or array is invalid (sizes, ranges, NaN).
    InvalidArgument = 2,
    /// Points not covered by enough kernels (increase support or kernels).
    Coverage = 3,
    /// The eigensolver failed or did not converge.
    Eigensolver = 4,
    /// An output buffer is too small.
    BufferTooSmall = 5,
    /// Internal error (a panic was caught); please report it.
    Panic = 6,
    /// A file could not be read (a scene file, or a shape file it names).
    Io = 7,
    /// Strict mode: a warning (a step that did not converge, an inversion, a Newton Hessian
    /// fallback, a poorly conditioned basis) stopped the simulation.
    Strict = 8,
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_error(msg: &str) {
    let c = CString::new(msg.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = c);
}

fn fail(status: Status, msg: &str) -> c_int {
    set_error(msg);
    status as c_int
}

/// Run `f`, turning a panic into `FF_ERR_PANIC` with its message.
pub(crate) fn guard(f: impl FnOnce() -> Result<(), (Status, String)>) -> c_int {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(Ok(())) => Status::Ok as c_int,
        Ok(Err((s, m))) => fail(s, &m),
        Err(p) => {
            let msg = p
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| p.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            fail(Status::Panic, &format!("internal error: {msg}"))
        }
    }
}

/// A library error of the basis and eigensolver calls as a status and a message that names
/// options by the fields of `ff_options`.
pub(crate) fn lib_error(e: &freeform::Error) -> (Status, String) {
    (status_of(e), Front::C.render(e))
}

/// The status of a library error, from its kind ([`freeform::Error::kind`]).
pub(crate) fn status_of(e: &freeform::Error) -> Status {
    use freeform::ErrorKind;
    match e.kind() {
        ErrorKind::Coverage => Status::Coverage,
        ErrorKind::NotConverged | ErrorKind::BadOperator => Status::Eigensolver,
        ErrorKind::Io => Status::Io,
        ErrorKind::Strict => Status::Strict,
        _ => Status::InvalidArgument,
    }
}

/// The message of the last failure on this thread ("" if none). Owned by the library; valid
/// until the next failing call on this thread.
#[no_mangle]
pub extern "C" fn ff_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// Options of [`ff_basis_build`] (C struct `ff_options`); fill with [`ff_options_default`].
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct FfOptions {
    /// Number of kernels K (default 1000).
    pub kernels: usize,
    /// Non-constant modes m; m + 1 are computed (default 16).
    pub modes: usize,
    /// Kernel window: 0 cubic B-spline (default), 1 quartic, 2 Gaussian.
    pub kernel: c_int,
    /// Support radius factor (default 2.0: see docs/guide.md).
    pub support_factor: f64,
    /// The n-th nearest other centre in the support rule.
    pub support_neighbor: usize,
    /// Eigen residual tolerance (default 1e-8).
    pub tol: f64,
    /// Eigensolver iteration cap (default 1000).
    pub max_iter: usize,
    /// 0 native LOBPCG (default), 1 dense (K up to a few thousand).
    pub solver: c_int,
}

/// Fill `out` with the defaults.
#[no_mangle]
pub unsafe extern "C" fn ff_options_default(out: *mut FfOptions) -> c_int {
    if out.is_null() {
        return fail(Status::NullPointer, "ff_options_default: out is NULL");
    }
    let d = BasisOptions::default();
    // SAFETY: checked non-NULL; the caller provides a writable ff_options.
    unsafe {
        *out = FfOptions {
            kernels: d.kernels,
            modes: d.modes,
            kernel: 0,
            support_factor: d.support.factor,
            support_neighbor: d.support.neighbor,
            tol: d.tol,
            max_iter: d.max_iter,
            solver: 0,
        }
    };
    Status::Ok as c_int
}

/// An opaque basis (C type `ff_basis`).
pub struct FfBasis {
    basis: Basis,
}

/// A slice from a C array, checking NULL (an empty array may be NULL).
pub(crate) unsafe fn slice<'a>(
    p: *const f64,
    len: usize,
    what: &str,
) -> Result<&'a [f64], (Status, String)> {
    if len == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err((Status::NullPointer, format!("{what} is NULL")));
    }
    // SAFETY: the caller promises `len` readable doubles at `p` (documented per function).
    Ok(unsafe { std::slice::from_raw_parts(p, len) })
}

/// Build a basis from `n` integration points: `points` (n x 3, metres), `volumes` (n, m^3),
/// per-point `youngs` (Pa), `poisson` and `density` (kg/m^3) arrays of length n. On success
/// `*out` owns a basis to release with [`ff_basis_free`].
#[no_mangle]
pub unsafe extern "C" fn ff_basis_build(
    points: *const f64,
    volumes: *const f64,
    youngs: *const f64,
    poisson: *const f64,
    density: *const f64,
    n: usize,
    options: *const FfOptions,
    out: *mut *mut FfBasis,
) -> c_int {
    guard(|| {
        if out.is_null() || options.is_null() {
            return Err((
                Status::NullPointer,
                "ff_basis_build: out or options is NULL".into(),
            ));
        }
        // SAFETY: checked non-NULL above.
        unsafe { *out = std::ptr::null_mut() };
        let o = unsafe { *options };
        let len3 = n
            .checked_mul(3)
            .ok_or((Status::InvalidArgument, format!("n = {n} is too large")))?;
        let p = unsafe { slice(points, len3, "points")? };
        let pts: Vec<[f64; 3]> = p.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let vol = unsafe { slice(volumes, n, "volumes")? }.to_vec();
        let e = unsafe { slice(youngs, n, "youngs")? }.to_vec();
        let nu = unsafe { slice(poisson, n, "poisson")? }.to_vec();
        let rho = unsafe { slice(density, n, "density")? }.to_vec();
        // The code is the kernel's place in `KernelType::ALL` (0 cubic, 1 quartic, 2 Gaussian).
        let kernel = usize::try_from(o.kernel)
            .ok()
            .and_then(|k| KernelType::ALL.get(k).copied())
            .ok_or_else(|| {
                let last = KernelType::ALL.len() - 1;
                let codes: Vec<String> = (0..last).map(|k| k.to_string()).collect();
                (
                    Status::InvalidArgument,
                    format!("kernel = {}: use {} or {last}", o.kernel, codes.join(", ")),
                )
            })?;
        let solver = match o.solver {
            0 => SolverConfig::lobpcg(),
            1 => SolverConfig::Dense,
            s => return Err((Status::InvalidArgument, format!("solver = {s}: use 0 or 1"))),
        };
        let mut opts = BasisOptions {
            kernels: o.kernels,
            modes: o.modes,
            kernel,
            tol: o.tol,
            max_iter: o.max_iter,
            solver,
            ..BasisOptions::default()
        };
        opts.support.factor = o.support_factor;
        opts.support.neighbor = o.support_neighbor;
        let material = MaterialField::from_arrays(e, nu, rho).map_err(|e| lib_error(&e))?;
        let run = Problem::from_points(
            IntegrationPoints {
                points: pts,
                volumes: vol,
            },
            material,
            &opts,
            &Silent,
        )
        .and_then(|problem| problem.solve(&Silent))
        .map_err(|e| lib_error(&e))?;
        let b = Box::new(FfBasis { basis: run.basis });
        // SAFETY: checked non-NULL above.
        unsafe { *out = Box::into_raw(b) };
        Ok(())
    })
}

/// Release a basis (NULL is ignored).
#[no_mangle]
pub unsafe extern "C" fn ff_basis_free(basis: *mut FfBasis) {
    if !basis.is_null() {
        // SAFETY: made by Box::into_raw in ff_basis_build, freed once by contract.
        drop(unsafe { Box::from_raw(basis) });
    }
}

unsafe fn basis_ref<'a>(b: *const FfBasis) -> Result<&'a Basis, (Status, String)> {
    if b.is_null() {
        return Err((Status::NullPointer, "basis is NULL".into()));
    }
    // SAFETY: a live basis from ff_basis_build.
    Ok(unsafe { &(*b).basis })
}

/// Number of kernels K of the basis (0 for NULL).
#[no_mangle]
pub unsafe extern "C" fn ff_basis_kernels(basis: *const FfBasis) -> usize {
    unsafe { basis_ref(basis) }.map_or(0, |b| b.kernels.len())
}

/// Number of modes m + 1 (the constant mode included; 0 for NULL).
#[no_mangle]
pub unsafe extern "C" fn ff_basis_modes(basis: *const FfBasis) -> usize {
    unsafe { basis_ref(basis) }.map_or(0, |b| b.modes())
}

pub(crate) fn out_slice<'a>(
    p: *mut f64,
    len: usize,
    need: usize,
    what: &str,
) -> Result<&'a mut [f64], (Status, String)> {
    if need == 0 {
        return Ok(&mut []);
    }
    if p.is_null() {
        return Err((Status::NullPointer, format!("{what} is NULL")));
    }
    if len < need {
        return Err((
            Status::BufferTooSmall,
            format!("{what} holds {len} doubles; {need} needed"),
        ));
    }
    // SAFETY: the caller provides `len >= need` writable doubles at `p`.
    Ok(unsafe { std::slice::from_raw_parts_mut(p, need) })
}

/// Copy the m + 1 eigenvalues (Pa/m^2, ascending, the first ~0) into `out` (capacity `len`).
#[no_mangle]
pub unsafe extern "C" fn ff_basis_eigenvalues(
    basis: *const FfBasis,
    out: *mut f64,
    len: usize,
) -> c_int {
    guard(|| {
        let b = unsafe { basis_ref(basis)? };
        out_slice(out, len, b.eigenvalues.len(), "out")?.copy_from_slice(&b.eigenvalues);
        Ok(())
    })
}

/// Copy the coefficients c (K x (m + 1), row-major: `out[k * (m + 1) + j]`, M-orthonormal)
/// into `out` (capacity `len`).
#[no_mangle]
pub unsafe extern "C" fn ff_basis_coefficients(
    basis: *const FfBasis,
    out: *mut f64,
    len: usize,
) -> c_int {
    guard(|| {
        let b = unsafe { basis_ref(basis)? };
        let (k, m) = (b.coefficients.nrows(), b.coefficients.ncols());
        let o = out_slice(out, len, k * m, "out")?;
        for i in 0..k {
            for j in 0..m {
                o[i * m + j] = b.coefficients[(i, j)];
            }
        }
        Ok(())
    })
}

/// Kernel centres (K x 3, metres) into `out` (capacity `len`).
#[no_mangle]
pub unsafe extern "C" fn ff_basis_centers(
    basis: *const FfBasis,
    out: *mut f64,
    len: usize,
) -> c_int {
    guard(|| {
        let b = unsafe { basis_ref(basis)? };
        let o = out_slice(out, len, 3 * b.kernels.len(), "out")?;
        for (dst, c) in o.chunks_exact_mut(3).zip(&b.kernels.centers) {
            dst.copy_from_slice(c);
        }
        Ok(())
    })
}

/// Skinning weights W_j at `nq` query points (`queries`, nq x 3, metres): `weights[i * (m + 1)
/// + j]` (capacity `weights_len`), and if `gradients` is not NULL, grad W_j at
/// `gradients[(i * (m + 1) + j) * 3 + d]` (capacity `gradients_len`).
#[no_mangle]
pub unsafe extern "C" fn ff_basis_weights(
    basis: *const FfBasis,
    queries: *const f64,
    nq: usize,
    weights: *mut f64,
    weights_len: usize,
    gradients: *mut f64,
    gradients_len: usize,
) -> c_int {
    guard(|| {
        let b = unsafe { basis_ref(basis)? };
        let len3 = nq
            .checked_mul(3)
            .ok_or((Status::InvalidArgument, format!("nq = {nq} is too large")))?;
        let q = unsafe { slice(queries, len3, "queries")? };
        let pts: Vec<[f64; 3]> = q.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let m = b.modes();
        let w = out_slice(weights, weights_len, nq * m, "weights")?;
        let sw = b.weights(&pts).map_err(|e| lib_error(&e))?;
        w.copy_from_slice(&sw.values);
        if !gradients.is_null() {
            let g = out_slice(gradients, gradients_len, 3 * nq * m, "gradients")?;
            for (dst, v) in g.chunks_exact_mut(3).zip(&sw.gradients) {
                dst.copy_from_slice(v);
            }
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use freeform::precompute::{BasisChoices, OptionTable, Value};

    /// `ff_options` has one field per row of the option table with a C name, in the table's
    /// order (the header's struct and this crate's `FfOptions` alike), and
    /// `ff_options_default` fills in the table's defaults.
    #[test]
    fn ff_options_are_the_option_tables() {
        let header = include_str!("../../ffi/include/freeform.h");
        let start = header.find("typedef struct ff_options {").unwrap();
        let end = start + header[start..].find("} ff_options;").unwrap();
        let fields: Vec<&str> = header[start..end]
            .lines()
            .skip(1)
            .filter_map(|l| l.split(';').next()?.split_whitespace().last())
            .collect();
        let names: Vec<&str> = freeform::options::ALL.iter().filter_map(|o| o.c).collect();
        assert_eq!(fields, names);
        let mut o = std::mem::MaybeUninit::<FfOptions>::uninit();
        assert_eq!(unsafe { ff_options_default(o.as_mut_ptr()) }, 0);
        let o = unsafe { o.assume_init() };
        let table = OptionTable::basis();
        let d = BasisChoices::default();
        for name in names {
            let row = table
                .find(freeform::options::Front::C, name)
                .unwrap_or_else(|| panic!("no row for the C field {name}"));
            let ours = match name {
                "kernels" => Value::Count(o.kernels),
                "modes" => Value::Count(o.modes),
                "kernel" => Value::Text(KernelType::ALL[o.kernel as usize].name().to_string()),
                "support_factor" => Value::Number(o.support_factor),
                "support_neighbor" => Value::Count(o.support_neighbor),
                "tol" => Value::Number(o.tol),
                "max_iter" => Value::Count(o.max_iter),
                "solver" => Value::Text(["lobpcg", "dense"][o.solver as usize].to_string()),
                other => panic!("FfOptions has no field {other}"),
            };
            assert_eq!(Some(ours), (row.default)(&d), "{name}");
        }
    }

    #[test]
    fn errors_are_codes_with_messages() {
        let mut o = FfOptions {
            kernels: 0,
            modes: 0,
            kernel: 0,
            support_factor: 0.0,
            support_neighbor: 0,
            tol: 0.0,
            max_iter: 0,
            solver: 0,
        };
        assert_eq!(unsafe { ff_options_default(&mut o) }, 0);
        let mut out: *mut FfBasis = std::ptr::null_mut();
        let code = unsafe {
            ff_basis_build(
                std::ptr::null(),
                std::ptr::null(),
                std::ptr::null(),
                std::ptr::null(),
                std::ptr::null(),
                5,
                &o,
                &mut out,
            )
        };
        assert_eq!(code, Status::NullPointer as c_int);
        let msg = unsafe { std::ffi::CStr::from_ptr(ff_last_error()) };
        assert!(msg.to_str().unwrap().contains("points is NULL"));
        assert!(out.is_null());
        let mut ev = [0.0; 2];
        assert_eq!(
            unsafe { ff_basis_eigenvalues(std::ptr::null(), ev.as_mut_ptr(), 2) },
            Status::NullPointer as c_int
        );
    }
}
