//! freeform's own bindings to PETSc 3.18 and SLEPc 3.18 (bindgen over Debian's headers) and a
//! small safe layer on top of them.
//!
//! Everything is behind the `petsc` feature: without it this crate is empty and needs nothing
//! installed, so the default workspace build and `cargo test --workspace` work without PETSc.
//!
//! The safe layer ([`Session`], [`Mat`], [`Vector`], [`Eps`], [`Ksp`]):
//! - every PETSc call's error code becomes a [`PetscError`] carrying PETSc's own message (a
//!   recording error handler replaces PETSc's printing one);
//! - PETSc objects are RAII handles destroyed on drop, tied to the [`Session`] they were made in;
//! - a [`Session`] is a lock over the process-wide PETSc state: PETSc is not thread-safe, so
//!   every use goes through one (tests running on several threads queue up);
//! - PETSc is initialized once per process ([`initialize`] with command-line style options, or
//!   lazily by [`session`]) with `-no_signal_handler`, and finalized once ([`finalize`], or at
//!   process exit after a lazy initialization).
//!
//! Debian's build: `PetscInt` is 32-bit, `PetscScalar` = `PetscReal` = `f64`.
#![warn(missing_docs)]

#[cfg(feature = "petsc")]
mod safe;
#[cfg(feature = "petsc")]
pub use safe::*;
#[cfg(feature = "petsc")]
mod shell;
#[cfg(feature = "petsc")]
pub use shell::{callback_allreduce_sum, ShellApply, ShellFailure};

/// Raw bindgen output (PETSc, SLEPc and the MPI functions they need). Unsafe to use directly;
/// prefer the safe layer.
#[cfg(feature = "petsc")]
#[allow(
    non_upper_case_globals,
    non_camel_case_types,
    non_snake_case,
    dead_code,
    missing_docs,
    clippy::all
)]
pub mod sys {
    include!(concat!(env!("OUT_DIR"), "/bindings.rs"));
}
