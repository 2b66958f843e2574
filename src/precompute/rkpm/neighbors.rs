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
    cover(kernels, None, queries)
}

/// [`covering_kernels`] when only the kernels `candidates` (ascending indices into `kernels`)
/// can reach the queries, e.g. [`kernels_near_box`] of the queries' bounding box: the same
/// pattern (global kernel indices, rows sorted) for a fraction of the queries.
pub fn covering_kernels_among(
    kernels: &Kernels,
    candidates: &[u32],
    queries: &[Point3],
) -> CoverPattern {
    cover(kernels, Some(candidates), queries)
}

/// The kernels (ascending indices) whose support may reach into the box `lo..hi` (metres):
/// every kernel with a point of the box inside its support is listed; a few more may be (the
/// test allows a relative 1e-9 of slack so that round-off never drops one).
pub fn kernels_near_box(kernels: &Kernels, lo: Point3, hi: Point3) -> Vec<u32> {
    (0..kernels.len())
        .into_par_iter()
        .filter(|&k| {
            let c = kernels.centers[k];
            let mut d2 = 0.0;
            for d in 0..3 {
                let gap = (lo[d] - c[d]).max(c[d] - hi[d]).max(0.0);
                d2 += gap * gap;
            }
            let a = kernels.radii[k];
            d2 <= a * a * (1.0 + 1e-9)
        })
        .map(|k| k as u32)
        .collect()
}

fn cover(kernels: &Kernels, candidates: Option<&[u32]>, queries: &[Point3]) -> CoverPattern {
    let empty = || CoverPattern {
        ptr: vec![0; queries.len() + 1],
        kernels: Vec::new(),
    };
    let count = candidates.map_or(kernels.len(), <[u32]>::len);
    if count == 0 || queries.is_empty() {
        return empty();
    }
    let Ok(tree) = ImmutableKdTree::<f64, 3>::new_from_slice(queries) else {
        return empty();
    };
    let id = |c: usize| candidates.map_or(c, |ids| ids[c] as usize);
    let lists: Vec<Vec<u32>> = (0..count)
        .into_par_iter()
        .map(|c| {
            let k = id(c);
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
    for (c, list) in lists.iter().enumerate() {
        for &q in list {
            flat[next[q as usize]] = id(c) as u32;
            next[q as usize] += 1;
        }
    }
    CoverPattern { ptr, kernels: flat }
}
