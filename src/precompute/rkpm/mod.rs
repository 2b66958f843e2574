//! Reproducing Kernel Particle Method: kernel centres with support radii, and linear-reproducing
//! shape functions phi_k(X) with analytic gradients (design.md section 2, "RKPM").

mod chunks;
mod kernel;
mod neighbors;
mod shape_functions;
mod support;

pub use chunks::{evaluate_chunk, ChunkedStats, CHUNK_POINTS};
pub use kernel::{KernelType, GAUSSIAN_ALPHA};
pub use neighbors::{covering_kernels, covering_kernels_among, kernels_near_box, CoverPattern};
pub use shape_functions::{
    evaluate, evaluate_on, reproducing_error, ReproducingError, ShapeFunctionOptions,
    ShapeFunctions, ShapeStats,
};
pub use support::{support_radii, SupportOptions, MAX_SUPPORT_FACTOR};

use crate::Point3;

/// A set of RKPM kernels: centres p_k (K x 3, metres), support radii a_k (K, metres) and the
/// window function.
#[derive(Debug, Clone, PartialEq)]
pub struct Kernels {
    /// Kernel centres, K x 3, metres.
    pub centers: Vec<Point3>,
    /// Support radii, K, metres: kernel k is non-zero only for |X - p_k| < a_k.
    pub radii: Vec<f64>,
    /// Window function.
    pub kind: KernelType,
}

impl Kernels {
    /// Number of kernels K.
    pub fn len(&self) -> usize {
        self.centers.len()
    }

    /// True when there are no kernels.
    pub fn is_empty(&self) -> bool {
        self.centers.is_empty()
    }
}
