//! Which kernels cover which query points (|X - p_k| < a_k), found with a k-d tree over the
//! query points.

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

/// For every query point (N x 3, metres), the kernels whose support contains it
/// (|X - p_k| < a_k, strictly).
///
/// Kernel-centric: one radius query per kernel (with its own radius) in a k-d tree over the
/// query points, in parallel, then a counting-sort transpose into per-point rows. Visiting
/// kernels in ascending order makes every row sorted. Deterministic for any thread count.
pub fn covering_kernels(kernels: &Kernels, queries: &[Point3]) -> CoverPattern {
    let empty = || CoverPattern {
        ptr: vec![0; queries.len() + 1],
        kernels: Vec::new(),
    };
    if kernels.is_empty() || queries.is_empty() {
        return empty();
    }
    let Ok(tree) = ImmutableKdTree::<f64, 3>::new_from_slice(queries) else {
        return empty();
    };
    let lists: Vec<Vec<u32>> = (0..kernels.len())
        .into_par_iter()
        .map(|k| {
            let (p, a) = (kernels.centers[k], kernels.radii[k]);
            let a2 = a * a;
            tree.query(&p)
                .within::<SquaredEuclidean<f64>>(a2)
                .unsorted()
                .execute()
                .iter()
                .filter(|r| r.distance < a2)
                .map(|r| r.item)
                .collect()
        })
        .collect();
    let mut ptr = vec![0usize; queries.len() + 1];
    for list in &lists {
        for &q in list {
            ptr[q as usize + 1] += 1;
        }
    }
    for i in 0..queries.len() {
        ptr[i + 1] += ptr[i];
    }
    let mut next = ptr.clone();
    let mut flat = vec![0u32; ptr[queries.len()]];
    for (k, list) in lists.iter().enumerate() {
        for &q in list {
            flat[next[q as usize]] = k as u32;
            next[q as usize] += 1;
        }
    }
    CoverPattern { ptr, kernels: flat }
}
