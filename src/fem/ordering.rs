//! Fill-reducing orderings for the sparse Cholesky factorization of the FEM system.
//!
//! - [`OrderingKind::Amd`]: faer's approximate minimum degree on the DoF graph.
//! - [`OrderingKind::NestedDissection`]: a geometric nested dissection of the node graph.
//!   The node set is split at the median of its longest bounding-box axis; the nodes of the
//!   lower half that touch the upper half form the separator; both halves are ordered
//!   recursively and the separator goes last. Sets of at most [`ND_LEAF`] nodes keep their
//!   input order. Each node's 3 DoFs stay consecutive.
//!
//! `docs/performance.md` ("FEM reference: fill-reducing ordering") records which is faster on
//! the beam meshes and by how much.

use crate::Point3;
use serde::{Deserialize, Serialize};

/// Which fill-reducing ordering the FEM solver hands to faer's symbolic Cholesky.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OrderingKind {
    /// faer's approximate minimum degree (the default: see docs/performance.md).
    #[default]
    Amd,
    /// Geometric nested dissection by coordinate bisection (this module).
    NestedDissection,
}

/// Largest node set left unsplit by the nested dissection.
pub const ND_LEAF: usize = 64;

/// Geometric nested dissection of a graph with `positions.len()` nodes.
///
/// `positions`: node coordinates (N x 3, metres); `adjacency[i]`: the neighbours of node i
/// (indices < N, symmetric). Returns the elimination order of the nodes: `order[k]` is the
/// node eliminated k-th (a permutation of 0..N).
pub fn nested_dissection(positions: &[Point3], adjacency: &[Vec<usize>]) -> Vec<usize> {
    let n = positions.len();
    let mut order = Vec::with_capacity(n);
    let mut stamp = vec![0u32; n];
    let mut epoch = 0u32;
    let mut all: Vec<usize> = (0..n).collect();
    dissect(
        &mut all, positions, adjacency, &mut stamp, &mut epoch, &mut order,
    );
    debug_assert_eq!(order.len(), n);
    order
}

fn dissect(
    set: &mut [usize],
    positions: &[Point3],
    adjacency: &[Vec<usize>],
    stamp: &mut [u32],
    epoch: &mut u32,
    order: &mut Vec<usize>,
) {
    if set.len() <= ND_LEAF {
        order.extend_from_slice(set);
        return;
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for &i in set.iter() {
        for a in 0..3 {
            lo[a] = lo[a].min(positions[i][a]);
            hi[a] = hi[a].max(positions[i][a]);
        }
    }
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    let mid = set.len() / 2;
    // Ties broken by index so the split is deterministic.
    set.select_nth_unstable_by(mid, |&a, &b| {
        positions[a][axis]
            .total_cmp(&positions[b][axis])
            .then(a.cmp(&b))
    });
    *epoch += 1;
    let tag = *epoch;
    let (left, right) = set.split_at_mut(mid);
    for &i in right.iter() {
        stamp[i] = tag;
    }
    let (mut inner, mut separator): (Vec<usize>, Vec<usize>) = (Vec::new(), Vec::new());
    for &i in left.iter() {
        if adjacency[i].iter().any(|&j| stamp[j] == tag) {
            separator.push(i);
        } else {
            inner.push(i);
        }
    }
    let mut right = right.to_vec();
    dissect(&mut inner, positions, adjacency, stamp, epoch, order);
    dissect(&mut right, positions, adjacency, stamp, epoch, order);
    separator.sort_unstable();
    order.extend_from_slice(&separator);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_dissection_is_a_permutation_with_separators_last() {
        // A 10 x 10 x 10 grid graph (6-neighbours).
        let n = 10;
        let id = |i: usize, j: usize, k: usize| i + n * (j + n * k);
        let mut pos = vec![[0.0; 3]; n * n * n];
        let mut adj = vec![Vec::new(); n * n * n];
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    pos[id(i, j, k)] = [i as f64, j as f64, k as f64];
                    if i + 1 < n {
                        adj[id(i, j, k)].push(id(i + 1, j, k));
                        adj[id(i + 1, j, k)].push(id(i, j, k));
                    }
                    if j + 1 < n {
                        adj[id(i, j, k)].push(id(i, j + 1, k));
                        adj[id(i, j + 1, k)].push(id(i, j, k));
                    }
                    if k + 1 < n {
                        adj[id(i, j, k)].push(id(i, j, k + 1));
                        adj[id(i, j, k + 1)].push(id(i, j, k));
                    }
                }
            }
        }
        let order = nested_dissection(&pos, &adj);
        let mut sorted = order.clone();
        sorted.sort();
        assert_eq!(sorted, (0..n * n * n).collect::<Vec<_>>());
        // The top-level separator is one grid plane (100 nodes) and comes last.
        let last: Vec<usize> = order[order.len() - 100..].to_vec();
        assert!(
            (0..3).any(|a| last.iter().all(|&i| pos[i][a] == pos[last[0]][a])),
            "the last 100 nodes are not one grid plane"
        );
    }
}
