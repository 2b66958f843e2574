//! Which kernels cover which query points (|X - p_k| < a_k), found with a k-d tree over the
//! centres.

use super::Kernels;
use crate::Point3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

/// Sparsity pattern of the shape functions: for query point i, the covering kernels are
/// `kernels[ptr[i]..ptr[i + 1]]`, sorted ascending.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CoverPattern {
    /// Row pointers, length N + 1.
    pub ptr: Vec<usize>,
    /// Kernel indices, length nnz.
    pub kernels: Vec<u32>,
}

impl CoverPattern {
    /// Number of query points N.
    pub fn rows(&self) -> usize {
        self.ptr.len().saturating_sub(1)
    }
    /// Kernel indices covering point i.
    pub fn row(&self, i: usize) -> &[u32] {
        &self.kernels[self.ptr[i]..self.ptr[i + 1]]
    }
    /// Number of (point, kernel) pairs.
    pub fn nnz(&self) -> usize {
        self.kernels.len()
    }
}

/// For every query point (N x 3, metres), the kernels whose support contains it.
/// Runs in parallel over query points; the result is deterministic.
pub fn covering_kernels(kernels: &Kernels, queries: &[Point3]) -> CoverPattern {
    if kernels.is_empty() {
        return CoverPattern {
            ptr: vec![0; queries.len() + 1],
            kernels: Vec::new(),
        };
    }
    let tree: ImmutableKdTree<f64, 3> = match ImmutableKdTree::new_from_slice(&kernels.centers) {
        Ok(t) => t,
        // Construction only fails on empty input, handled above.
        Err(_) => {
            return CoverPattern {
                ptr: vec![0; queries.len() + 1],
                kernels: Vec::new(),
            }
        }
    };
    let a_max = kernels.radii.iter().copied().fold(0.0, f64::max);
    let rows: Vec<Vec<u32>> = queries
        .par_iter()
        .map(|x| {
            let found = tree
                .query(x)
                .within::<SquaredEuclidean<f64>>(a_max * a_max)
                .unsorted()
                .execute();
            let mut row: Vec<u32> = found
                .iter()
                .filter_map(|r| {
                    let k = r.item as usize;
                    let a = kernels.radii[k];
                    (r.distance < a * a).then_some(k as u32)
                })
                .collect();
            row.sort_unstable();
            row
        })
        .collect();
    let mut ptr = Vec::with_capacity(rows.len() + 1);
    ptr.push(0);
    let mut total = 0;
    for r in &rows {
        total += r.len();
        ptr.push(total);
    }
    let mut flat = Vec::with_capacity(total);
    for r in rows {
        flat.extend_from_slice(&r);
    }
    CoverPattern { ptr, kernels: flat }
}
