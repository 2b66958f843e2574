//! Shell objects over Rust closures: a matrix applied by a closure (`MATSHELL` with
//! `MATOP_MULT`) and a preconditioner applied by a closure (`PCSHELL`), PETSc's way of taking
//! an operator it does not store.
//!
//! The closure sees this rank's local entries of x and writes this rank's local entries of
//! y = A x (both of the local size). Its error, or a panic inside it, never crosses into C:
//! the callback returns `PETSC_ERR_USER` to PETSc, which unwinds its own stack with an error
//! code, and the message is kept in a [`ShellFailure`] the caller reads after the failed call.
//! The closure's box is freed when PETSc destroys the object (the last reference: the
//! matrix held by an `EPS`, the PC inside it).

use crate::safe::{check, petsc_int, Comm, Eps, Mat, Result, Session};
use crate::sys;
use std::cell::RefCell;
use std::ffi::c_void;
use std::marker::PhantomData;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::rc::Rc;

/// `y = A x` on this rank's entries (`x`, `y` both of the local size); `Err` with a message
/// stops PETSc's current call.
pub type ShellApply<'c> = Box<dyn Fn(&[f64], &mut [f64]) -> std::result::Result<(), String> + 'c>;

/// Where a shell callback leaves the message of its first failure (its error, or a panic's
/// payload). Shared between the callback and the caller; read it after a PETSc call fails.
#[derive(Debug, Clone, Default)]
pub struct ShellFailure(Rc<RefCell<Option<String>>>);

impl ShellFailure {
    /// The first recorded failure message, if any, removing it.
    pub fn take(&self) -> Option<String> {
        self.0.borrow_mut().take()
    }

    fn record(&self, message: String) {
        let mut slot = self.0.borrow_mut();
        if slot.is_none() {
            *slot = Some(message);
        }
    }
}

struct Context<'c> {
    apply: ShellApply<'c>,
    failure: ShellFailure,
    /// What `MatNorm` answers (any norm type), when known.
    norm: Option<f64>,
}

/// Run the closure on the vectors' local arrays, turning errors and panics into
/// `PETSC_ERR_USER` with the message recorded.
///
/// # Safety
/// `ctx` is a live `Context` made by this module; `x`, `y` are valid PETSc vectors.
unsafe fn run(ctx: *const Context<'_>, x: sys::Vec, y: sys::Vec) -> sys::PetscErrorCode {
    let ctx = unsafe { &*ctx };
    let mut n: sys::PetscInt = 0;
    let mut xp: *const f64 = std::ptr::null();
    let mut yp: *mut f64 = std::ptr::null_mut();
    // SAFETY: valid vectors; arrays restored below on every path.
    let code = unsafe { sys::VecGetLocalSize(x, &mut n) };
    if code != 0 {
        return code;
    }
    let code = unsafe { sys::VecGetArrayRead(x, &mut xp) };
    if code != 0 {
        return code;
    }
    let code = unsafe { sys::VecGetArray(y, &mut yp) };
    if code != 0 {
        unsafe { sys::VecRestoreArrayRead(x, &mut xp) };
        return code;
    }
    let len = n.max(0) as usize;
    let outcome = {
        // SAFETY: PETSc gives `len` contiguous local values for each (x and y are distinct).
        let (xs, ys) = if len == 0 {
            (&[][..], &mut [][..])
        } else {
            unsafe {
                (
                    std::slice::from_raw_parts(xp, len),
                    std::slice::from_raw_parts_mut(yp, len),
                )
            }
        };
        catch_unwind(AssertUnwindSafe(|| (ctx.apply)(xs, ys)))
    };
    let restore_y = unsafe { sys::VecRestoreArray(y, &mut yp) };
    let restore_x = unsafe { sys::VecRestoreArrayRead(x, &mut xp) };
    match outcome {
        Ok(Ok(())) => {
            if restore_y != 0 {
                restore_y
            } else {
                restore_x
            }
        }
        Ok(Err(message)) => {
            ctx.failure.record(message);
            sys::PETSC_ERR_USER as sys::PetscErrorCode
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic".into());
            ctx.failure.record(format!("the callback panicked: {what}"));
            sys::PETSC_ERR_USER as sys::PetscErrorCode
        }
    }
}

unsafe extern "C" fn mat_mult(a: sys::Mat, x: sys::Vec, y: sys::Vec) -> sys::PetscErrorCode {
    let mut ctx: *mut c_void = std::ptr::null_mut();
    // SAFETY: `a` is one of our shells; its context is our `Context`.
    let code = unsafe { sys::MatShellGetContext(a, (&mut ctx as *mut *mut c_void).cast()) };
    if code != 0 {
        return code;
    }
    unsafe { run(ctx as *const Context<'_>, x, y) }
}

unsafe extern "C" fn mat_norm(
    a: sys::Mat,
    _kind: sys::NormType,
    out: *mut sys::PetscReal,
) -> sys::PetscErrorCode {
    let mut ctx: *mut c_void = std::ptr::null_mut();
    // SAFETY: as in `mat_mult`; only registered when the context has a norm.
    let code = unsafe { sys::MatShellGetContext(a, (&mut ctx as *mut *mut c_void).cast()) };
    if code != 0 {
        return code;
    }
    let ctx = unsafe { &*(ctx as *const Context<'_>) };
    match ctx.norm {
        Some(v) => {
            unsafe { *out = v };
            0
        }
        None => sys::PETSC_ERR_USER as sys::PetscErrorCode,
    }
}

unsafe extern "C" fn free_context(ctx: *mut c_void) -> sys::PetscErrorCode {
    if !ctx.is_null() {
        // SAFETY: made by Box::into_raw in this module; PETSc calls this once.
        drop(unsafe { Box::from_raw(ctx as *mut Context<'_>) });
    }
    0
}

unsafe extern "C" fn pc_apply(pc: sys::PC, x: sys::Vec, y: sys::Vec) -> sys::PetscErrorCode {
    let mut ctx: *mut c_void = std::ptr::null_mut();
    // SAFETY: `pc` is one of our shells; its context is our `Context`.
    let code = unsafe { sys::PCShellGetContext(pc, (&mut ctx as *mut *mut c_void).cast()) };
    if code != 0 {
        return code;
    }
    unsafe { run(ctx as *const Context<'_>, x, y) }
}

unsafe extern "C" fn pc_destroy(pc: sys::PC) -> sys::PetscErrorCode {
    let mut ctx: *mut c_void = std::ptr::null_mut();
    // SAFETY: as in `pc_apply`.
    let code = unsafe { sys::PCShellGetContext(pc, (&mut ctx as *mut *mut c_void).cast()) };
    if code != 0 {
        return code;
    }
    unsafe { free_context(ctx) }
}

impl<'s> Mat<'s> {
    /// A square shell matrix of global size `global` on `comm`, this rank owning `local` rows
    /// (and the same columns), applied by `apply`. Collective on `comm`; the local sizes of all
    /// ranks must sum to `global` (PETSc checks). Returns the matrix and where its callback's
    /// failures are recorded. `norm`, when given, is what `MatNorm` answers for every norm
    /// type (SLEPc's `EPS_CONV_NORM` test asks for one; give ||A||_1, exact or estimated).
    ///
    /// # Safety
    /// PETSc keeps the closure until the matrix's last reference goes: every PETSc object that
    /// takes a reference to it (an `EPS` given it as an operator) must be destroyed before
    /// `'c` ends, as well as the returned `Mat`.
    ///
    /// # Errors
    /// PETSc's error; sizes beyond `PetscInt`.
    pub unsafe fn shell<'c>(
        _session: &'s Session,
        comm: Comm,
        local: usize,
        global: usize,
        norm: Option<f64>,
        apply: ShellApply<'c>,
    ) -> Result<(Self, ShellFailure)> {
        let (nl, ng) = (
            petsc_int("MatCreateShell", local)?,
            petsc_int("MatCreateShell", global)?,
        );
        let failure = ShellFailure::default();
        let ctx = Box::into_raw(Box::new(Context {
            apply,
            failure: failure.clone(),
            norm,
        })) as *mut c_void;
        let mut raw: sys::Mat = std::ptr::null_mut();
        // SAFETY: out-pointer on a valid communicator; the context is ours until the destroy
        // hook is registered, freed here if that fails.
        let created = check("MatCreateShell", unsafe {
            sys::MatCreateShell(comm.raw(), nl, nl, ng, ng, ctx, &mut raw)
        });
        if let Err(e) = created {
            unsafe { free_context(ctx) };
            return Err(e);
        }
        let mat = Mat {
            raw,
            _session: PhantomData,
        };
        if let Err(e) = check("MatShellSetContextDestroy", unsafe {
            sys::MatShellSetContextDestroy(raw, Some(free_context))
        }) {
            unsafe { free_context(ctx) };
            return Err(e);
        }
        // SAFETY: PETSc stores operations as `void (*)(void)` and calls them with the MATOP's
        // real signature, which `mat_mult` has.
        let mult: unsafe extern "C" fn() = unsafe {
            std::mem::transmute::<
                unsafe extern "C" fn(sys::Mat, sys::Vec, sys::Vec) -> sys::PetscErrorCode,
                unsafe extern "C" fn(),
            >(mat_mult)
        };
        check("MatShellSetOperation", unsafe {
            sys::MatShellSetOperation(raw, sys::MATOP_MULT, Some(mult))
        })?;
        if norm.is_some() {
            // SAFETY: as for MATOP_MULT, with MATOP_NORM's signature.
            let norm_op: unsafe extern "C" fn() = unsafe {
                std::mem::transmute::<
                    unsafe extern "C" fn(
                        sys::Mat,
                        sys::NormType,
                        *mut sys::PetscReal,
                    ) -> sys::PetscErrorCode,
                    unsafe extern "C" fn(),
                >(mat_norm)
            };
            check("MatShellSetOperation", unsafe {
                sys::MatShellSetOperation(raw, sys::MATOP_NORM, Some(norm_op))
            })?;
        }
        Ok((mat, failure))
    }
}

impl<'s> Eps<'s> {
    /// Precondition with `apply` (`y ~ (A - sigma B)^-1 x` on this rank's entries): the
    /// spectral transformation's KSP becomes `preonly` and its PC a `PCSHELL` calling the
    /// closure. Returns where the closure's failures are recorded.
    ///
    /// # Safety
    /// As [`Mat::shell`]: the EPS must be destroyed before `'c` ends.
    ///
    /// # Errors
    /// PETSc's error.
    pub unsafe fn set_shell_preconditioner<'c>(
        &mut self,
        apply: ShellApply<'c>,
    ) -> Result<ShellFailure> {
        let (_st, ksp, pc) = self.st_ksp_pc()?;
        let preonly = crate::safe::cstring("KSPSetType", "preonly")?;
        let shell = crate::safe::cstring("PCSetType", "shell")?;
        // SAFETY (all calls): sub-objects owned by the EPS, valid while it lives.
        check("KSPSetType", unsafe {
            sys::KSPSetType(ksp, preonly.as_ptr())
        })?;
        check("PCSetType", unsafe { sys::PCSetType(pc, shell.as_ptr()) })?;
        let failure = ShellFailure::default();
        let ctx = Box::into_raw(Box::new(Context {
            apply,
            failure: failure.clone(),
            norm: None,
        })) as *mut c_void;
        if let Err(e) = check("PCShellSetContext", unsafe {
            sys::PCShellSetContext(pc, ctx)
        }) {
            unsafe { free_context(ctx) };
            return Err(e);
        }
        if let Err(e) = check("PCShellSetDestroy", unsafe {
            sys::PCShellSetDestroy(pc, Some(pc_destroy))
        }) {
            unsafe { free_context(ctx) };
            return Err(e);
        }
        check("PCShellSetApply", unsafe {
            sys::PCShellSetApply(pc, Some(pc_apply))
        })?;
        Ok(failure)
    }
}

/// Element-wise sum of `values` over the ranks of `PETSC_COMM_WORLD`, for a shell callback
/// that needs its halo while PETSc is inside a solve (the solve holds the [`Session`], so the
/// session's own `allreduce_sum` cannot be reached). Collective: every rank's callback must
/// make the same calls in the same order. Call it only from a shell callback (the thread
/// that runs the solve).
///
/// # Errors
/// PETSc not initialized; MPI's error.
pub fn callback_allreduce_sum(values: &mut [f64]) -> Result<()> {
    let mut initialized: sys::PetscBool = 0;
    // SAFETY: a plain query of PETSc's state.
    check("PetscInitialized", unsafe {
        sys::PetscInitialized(&mut initialized)
    })?;
    if initialized == 0 {
        return Err(crate::safe::PetscError {
            code: -1,
            call: "callback_allreduce_sum",
            message: "PETSc is not initialized (call it only from a shell callback)".into(),
        });
    }
    let send = values.to_vec();
    // SAFETY: PETSc (hence MPI) is initialized; buffers of equal length; collective on the
    // world communicator, which PETSc set at initialization.
    let code = unsafe {
        sys::MPI_Allreduce(
            send.as_ptr().cast(),
            values.as_mut_ptr().cast(),
            std::ffi::c_int::try_from(values.len()).unwrap_or(std::ffi::c_int::MAX),
            std::ptr::addr_of_mut!(sys::ompi_mpi_double).cast(),
            std::ptr::addr_of_mut!(sys::ompi_mpi_op_sum).cast(),
            sys::PETSC_COMM_WORLD,
        )
    };
    if code == 0 {
        Ok(())
    } else {
        Err(crate::safe::PetscError {
            code,
            call: "MPI_Allreduce",
            message: format!("MPI error code {code}"),
        })
    }
}
