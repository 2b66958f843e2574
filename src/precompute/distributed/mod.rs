//! The precomputation across the ranks of `mpirun`, with memory per rank falling as 1/P: no
//! rank holds all integration points, the K x K matrices or all eigenvectors.
//!
//! ```text
//! partition  each rank samples its block of the points (grid rows counted, then sampled)
//! fps        exact farthest point sampling across the parts: the one-process kernels
//! rows       each rank's block of kernels: the points in their supports, its rows of H_w, M
//! pipeline   (feature slepc) the rows to PETSc, SLEPc, checks on distributed vectors,
//!            the m + 1 eigenvectors gathered on rank 0 only
//! ```
//!
//! Every stage but the solve runs on any [`Collective`]: MPI's ([`MpiWorld`], feature
//! `slepc`), or ranks on threads of one process ([`run_ranks`]), with which the tests check
//! that the kernels and rows are the one-process ones bit for bit for any P.

pub mod collective;
pub mod fps;
pub mod partition;
pub mod rows;

pub use collective::{agree, arg_max, run_ranks, Collective};
pub use fps::place_kernels_parts;
pub use partition::{sample_part, PointPart};
pub use rows::{assemble_own_rows, OwnRows};
#[cfg(feature = "slepc")]
mod mpi;
#[cfg(feature = "slepc")]
mod pipeline;

#[cfg(feature = "slepc")]
pub use mpi::MpiWorld;
#[cfg(feature = "slepc")]
pub use pipeline::{build_basis_mpi, DistributedReport, DistributedRun, StagePeaks};
