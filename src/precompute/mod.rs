//! The precomputation: from a shape (or your own points) to skinning eigenmodes.
//!
//! ```text
//! Shape --sampling--> integration points, volumes, materials
//!       --centers---> kernel centres (FPS, weighted by the kernel density; Morton order),
//!                     support radii
//!       --rkpm------> shape functions and gradients at the points
//!       --assembly--> sparse H_w and M (K x K)                  = Problem
//!       --eigen-----> m + 1 eigenpairs (LOBPCG | dense | SLEPc)
//!       --skinning--> Basis: weights W(X) anywhere in the shape  = BasisRun
//! ```
//!
//! [`build_basis`] runs it all; [`Problem`] splits it at the eigensolve (assemble once, solve
//! with the [`SolverConfig`] of the options or with any [`crate::eigen::Eigensolver`]; or
//! compare solvers on it, [`Problem::compare`], as `freeform compare` does); the stages are public
//! modules so a caller can enter the flow anywhere. `distributed` (feature `slepc`) runs the
//! same stages across MPI ranks.

pub mod assembly;
mod ball_max;
pub mod boundary_modes;
pub mod centers;
mod compare;
mod coverage;
pub mod density;
pub mod distributed;
pub mod image_material;
pub mod memory;
mod options;
mod problem;
mod quality;
mod resolution;
pub mod rkpm;
pub mod sampling;
pub mod skinning;
mod solver;
pub mod stream;
pub mod table;

pub use boundary_modes::BoundaryModes;
pub use compare::{compare_solvers, ProblemComparison, SolverComparison, SolverResult};
pub use density::{DensityBands, DensityRegion, KernelDensity};
pub use image_material::{GapPolicy, ImageMaterial};
pub use memory::MemoryEstimate;
pub use options::{default_points, BasisOptions, MatrixStorage, MAX_KERNELS, MAX_POINTS};
pub use problem::{build_basis, place_kernels, BasisRun, Problem};
pub use quality::{
    basis_monitors, check_quality, CoverageReport, ModesReport, SolveFacts, ORTHONORMALITY_WARNING,
    RCOND_WARNING, REPRODUCING_WARNING,
};
pub use sampling::{sample_shape, sample_with_material};
pub use solver::SolverConfig;
pub use table::{BasisChoices, BasisOption, OptionTable, Value, ValueKind};
