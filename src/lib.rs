//! # freeform
//!
//! Mesh-free, reduced-order simulation of elastic objects from RKPM skinning eigenmodes
//! (the FreeForm method). The library follows one data flow
//! (docs/architecture.md draws it):
//!
//! ```text
//! geometry (shape) -> precompute (points, kernels, H_w and M, eigenmodes: a skinning Basis)
//!   -> sim (one reduced object you step) -> scene (objects, colliders, a live World, frames)
//! ```
//!
//! [`precompute::build_basis`] runs the whole precomputation from a [`geometry::Shape`];
//! [`precompute::Problem`] splits it at the eigensolve; every stage is also a public function
//! so a caller can enter the flow anywhere (bring points, kernels or matrices of your own).
//!
//! Units: the library is unit-agnostic but consistent; the docs say "metres", "Pa" and
//! "kg/m^3" for SI input. Shapes: "N x 3" means N rows of `[x, y, z]`.
#![warn(missing_docs)]
// Index loops over 3 x 3 and 4 x 4 arrays read like the formulas they implement.
#![allow(clippy::needless_range_loop)]

pub mod benchmark;
pub mod derivatives;
pub mod eigen;
pub mod elasticity;
pub mod error;
pub mod fem;
pub mod geometry;
pub mod io;
pub mod linalg3;
pub mod material;
pub mod names;
pub mod options;
pub mod precompute;
pub mod progress;
pub mod random;
pub mod render;
pub mod report;
pub mod scene;
pub mod sim;
mod simd;
pub mod sparse;
pub mod triangle;

pub use error::{Error, ErrorKind, Result};

/// A point or vector in 3D, `[x, y, z]` (metres for positions).
pub type Point3 = [f64; 3];
