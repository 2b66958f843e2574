//! # freeform
//!
//! Mesh-free, reduced-order simulation of elastic objects from RKPM skinning eigenmodes
//! (the FreeForm method). The library follows one data flow, one module per stage:
//!
//! ```text
//! geometry (shape) -> sampling (integration points, volumes) -> centers (FPS)
//!   -> rkpm (kernels, support radii, shape functions) -> material (E, nu, rho per point)
//!   -> assembly (sparse H_w and M) -> eigen (LOBPCG | dense) -> skinning (weights W(X))
//! ```
//!
//! [`pipeline::build_basis`] runs the whole flow from a [`geometry::Shape`]; every stage is
//! also a public function so a caller can enter the flow anywhere (bring points, kernels or
//! matrices of your own).
//!
//! Units: the library is unit-agnostic but consistent; the docs say "metres", "Pa" and
//! "kg/m^3" for SI input. Shapes: "N x 3" means N rows of `[x, y, z]`.
#![warn(missing_docs)]
// Index loops over 3 x 3 and 4 x 4 arrays read like the formulas they implement.
#![allow(clippy::needless_range_loop)]

pub mod assembly;
pub mod benchmark;
pub mod centers;
#[cfg(feature = "slepc")]
pub mod distributed;
pub mod eigen;
pub mod elasticity;
pub mod error;
pub mod fem;
pub mod geometry;
pub mod io;
pub mod linalg3;
pub mod material;
pub mod pipeline;
pub mod progress;
pub mod report;
pub mod rkpm;
pub mod sampling;
pub mod scene;
pub mod sim;
mod simd;
pub mod skinning;
pub mod sparse;

pub use error::{Error, Result};

/// A point or vector in 3D, `[x, y, z]` (metres for positions).
pub type Point3 = [f64; 3];
