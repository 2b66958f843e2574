//! The integration tests in one crate: one test binary to compile and link instead of one per
//! file. Each module is a former `tests/<name>.rs`; its tests are named `<name>::<test>`, so
//! `cargo test --test integration -- <name>::` runs one file's tests.
//!
//! Kept as crates of their own, because .ci/run builds and runs them again with
//! `--features slepc` and they are small (building this crate with the feature costs more):
//! `tests/compare.rs`, `tests/slepc.rs`, `tests/slepc_cli.rs`. `slepc.rs` and `slepc_cli.rs`
//! must not share a process either: `slepc.rs` initializes MPI in-process, which exports
//! PMIX_*/OMPI_* variables, and the `mpirun` that `slepc_cli.rs` starts inherits them and
//! exits 1.
//!
//! proptest keeps `properties.rs`'s regressions in `tests/proptest-regressions/properties.txt`
//! (its `SourceParallel` default, now that this directory has a `main.rs`).

mod common;

mod architecture;
mod assembly;
mod bad_inputs;
mod boundary_modes;
mod cli;
mod cloud_contact;
mod colliders;
mod contact;
mod eval_shapes;
mod extremes;
mod fem;
mod geometry;
mod gradient;
mod gradient_contact;
mod gradient_friction;
mod gradient_placement;
mod images;
mod matrix_free;
mod options;
mod pipeline;
mod properties;
mod render;
mod rkpm;
mod scene;
mod scene_numbers;
mod sim;
mod splat_render;
mod splats;
mod streaming;
mod strict;
mod sweep_cli;
mod tunnel;
mod usd;
mod world;
