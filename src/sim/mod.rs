//! Reduced-order simulation (design.md section 2, "Reduced simulation"; the paper's
//! Eqs. 1-2): m + 1 affine handles driven by the skinning eigenmodes, backward Euler as
//! minimisation of the incremental potential, Newton or quasi-Newton per step.
//!
//! - [`cubature`]: the subset of integration points that carries the elastic energy.
//! - [`elastic`]: the elastic energy, gradient and Hessian in z (structured, no dense
//!   per-point 9 x 12 (m + 1) blocks).
//! - [`terms`]: inertia, gravity, boundary and collider penalties.
//! - [`collider`]: obstacles (planes, boxes, spheres, capsules, triangle meshes) and their
//!   kinematics (scripted or caller-set poses, articulated chains).
//! - [`contact`]: object-object contact (samples, broad phase, pair penalty, islands).
//! - [`friction`]: the smoothed lagged friction of every contact (IPC's f0, f1).
//! - [`environment`]: gravity and the colliders, owned once by whoever steps the objects.
//! - [`motion`]: prescribed rigid motions for boundaries.
//! - [`newton`]: the per-step minimiser and its strategies.
//! - [`object`]: one simulated object (setup, state, stepping).
//! - [`deformation`]: the deformation map's gradient F at any points.
//! - [`gaussian`]: Gaussian splats carried by F (covariance, rotation, SH colour).
//! - [`gradient`]: reverse-mode gradients of a loss over a recorded run (the adjoint of each
//!   converged step).

pub mod collider;
pub mod contact;
pub mod cubature;
pub mod deformation;
pub mod elastic;
pub mod environment;
pub mod friction;
pub mod gaussian;
pub mod gradient;
mod lanes;
pub mod motion;
pub mod newton;
pub mod object;
pub mod terms;

pub use collider::Collider;
pub use environment::Environment;
pub use newton::{HessianStrategy, InitialGuess, NewtonOptions};
pub use object::{Boundary, Placement, ReducedSim, SimOptions, StepReport};
