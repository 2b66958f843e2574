//! The FEM reference: a full-order finite element solver on linear tetrahedra, the ground
//! truth that the reduced model is measured against (design.md sections 2 and 3).
//!
//! - [`TetMesh`] ([`tetmesh`]): a validated tetrahedral mesh; [`TetMesh::structured_box`]
//!   builds the conforming 6-tets-per-cube mesh of a box.
//! - [`readers`]: TetGen `.node/.ele`, Gmsh `.msh` (v4.1 ASCII) and MEDIT `.mesh`.
//! - [`voxel`]: a voxel tet mesher for watertight triangle meshes (staircase boundary).
//! - [`element`]: linear (4-node) or quadratic (10-node) tets: shape-function gradients,
//!   quadrature, lumped masses, materials; energy, forces and Hessians of the same stable
//!   Neo-Hookean energy as the reduced model.
//! - [`solver`]: backward Euler as minimisation of the incremental potential, Newton with
//!   backtracking line search, exact or PSD-projected element Hessians, faer sparse Cholesky with a
//!   symbolic factorization reused across iterations and steps; Dirichlet nodes (held or
//!   prescribed motion) and the one-sided plane penalty.
//! - [`ordering`]: fill-reducing orderings (faer's AMD or a geometric nested dissection).
//! - [`beam`]: the standard beam bend/twist reference runs (design.md section 3), cached on
//!   disk keyed by every parameter; [`FemBeamConfig::reference`] is the recommended
//!   reference (quadratic tets, 4 cubes per metre; docs/accuracy.md says why).
//! - [`metric`]: the error metric between any trajectory and a reference trajectory.

pub mod beam;
pub mod element;
pub mod metric;
pub mod ordering;
pub mod readers;
pub mod solver;
pub mod tetmesh;
pub mod voxel;

pub use beam::{
    nested_difference, run_beam_reference, BeamReference, BeamTest, CacheStatus, FemBeamConfig,
};
pub use element::{fe_nodes, ElementOrder, Elements, TetMaterials};
pub use metric::{trajectory_error, TrajectoryError};
pub use ordering::OrderingKind;
pub use readers::read_tet_mesh;
pub use solver::{FemParams, FemSolver, HessianMode, PlanePenalty, StepInfo};
pub use tetmesh::TetMesh;
pub use voxel::{voxel_tet_mesh, VoxelMesh};

use std::path::PathBuf;

/// Errors of the FEM stage: mesh files, mesh validity, the Newton solver, trajectories.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FemError {
    /// A mesh file could not be parsed; `line` is 1-based (0 when the file ended early).
    #[error("{path}:{line}: {reason}")]
    Parse {
        /// File involved.
        path: PathBuf,
        /// 1-based line number of the offending token (0: unexpected end of file).
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// File involved.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The tetrahedral mesh is unusable (empty, bad index, non-finite or flat element).
    #[error("invalid tetrahedral mesh: {0}")]
    Mesh(String),
    /// Newton did not reach the tolerance within the iteration cap. The solver state holds
    /// the last iterate, so a caller may inspect it or continue.
    #[error(
        "Newton did not converge in step {step}: {iterations} iterations, last step \
         max |dx| = {step_norm:.3e} m (tolerance {tolerance:.3e} m), gradient max norm \
         {gradient_norm:.3e} N; reduce the time step or raise max_newton_iterations"
    )]
    NotConverged {
        /// 0-based step index.
        step: usize,
        /// Iterations done.
        iterations: usize,
        /// Largest nodal update of the last iteration, metres.
        step_norm: f64,
        /// The absolute tolerance it was compared to, metres.
        tolerance: f64,
        /// Largest nodal gradient (force residual) at the last iterate, N.
        gradient_norm: f64,
    },
    /// The line search found no decrease of the incremental potential along the Newton
    /// direction (the direction is not a descent direction, or round-off dominates).
    #[error("line search failed in step {step}, iteration {iteration}: {detail}")]
    LineSearch {
        /// 0-based step index.
        step: usize,
        /// 0-based Newton iteration.
        iteration: usize,
        /// Energies and step sizes tried.
        detail: String,
    },
    /// A NaN or infinity appeared in the state, energy or gradient.
    #[error("non-finite {what} in step {step}, iteration {iteration}")]
    NonFinite {
        /// What became non-finite.
        what: &'static str,
        /// 0-based step index.
        step: usize,
        /// 0-based Newton iteration.
        iteration: usize,
    },
    /// The sparse Cholesky factorization failed (the system is not positive definite, e.g.
    /// a static solve with too few held nodes).
    #[error("sparse Cholesky failed: {0}")]
    Factorization(String),
    /// Trajectories handed to the error metric do not fit together.
    #[error("trajectory {what}: {detail}")]
    Trajectory {
        /// Which input ("reference", "candidate", "rest").
        what: &'static str,
        /// Shape, NaN or emptiness problem, with frame and node indices.
        detail: String,
    },
}
