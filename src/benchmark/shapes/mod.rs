//! Accuracy on real shapes (issue 18, docs/evaluation.md): the paper's Table 2 protocol over
//! a folder of closed surface meshes against TetGen FEM references.
//!
//! - [`protocol`]: normalization to a unit bounding box, the material, the three boundary
//!   conditions as regions with motions (fix side, pull farthest points, pull ends).
//! - [`tetgen`]: the FEM mesh from the external `tetgen` program.
//! - [`reference`]: the FEM trajectory of one test, cached like the beam's.
//! - [`eval`]: one shape through all tests and bases.
//! - [`report`]: a folder of shapes, per-shape failures, averages and the CSV.

pub mod eval;
pub mod protocol;
pub mod reference;
pub mod report;
pub mod tetgen;

pub use eval::{evaluate_shape, EvalOptions, ShapeEval, ShapeRun};
pub use protocol::{NormalizedShape, Protocol, ShapeTest};
pub use report::{evaluate_dir, EvalReport};
pub use tetgen::TetgenOptions;
