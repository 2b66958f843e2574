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

pub use crate::error::FemError;
