//! Broad phase between the objects of an island: the boxes of each object's deformed samples
//! first, then, for each pair of objects whose boxes come within reach, a k-d tree over one
//! object's samples queried with the other's; for self-contact, a k-d tree over one object's
//! samples queried with its own, keeping the pairs that are far apart at rest.

use crate::Point3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

/// A candidate sample pair: sample `i` of body `a` and sample `j` of body `b` (a < b; or
/// a == b and i < j for a pair of one body's samples, self-contact).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Candidate {
    /// First body (index into the island's bodies).
    pub a: usize,
    /// Second body, >= `a`.
    pub b: usize,
    /// Sample of body `a`.
    pub i: usize,
    /// Sample of body `b`.
    pub j: usize,
}

/// What a broad phase tested.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BroadStats {
    /// Object pairs whose boxes were compared.
    pub object_pairs: usize,
    /// Object pairs whose boxes came within reach (their samples were searched).
    pub object_pairs_near: usize,
}

fn bounds(x: &[Point3]) -> (Point3, Point3) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in x {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (lo, hi)
}

/// The points of `tree` strictly closer than sqrt(`r2`) metres to `p`, in increasing index
/// order (so sums over pairs do not depend on the tree's traversal).
fn within(tree: &ImmutableKdTree<f64, 3>, p: &Point3, r2: f64) -> impl Iterator<Item = usize> {
    let mut found: Vec<usize> = tree
        .query(p)
        .within::<SquaredEuclidean<f64>>(r2)
        .unsorted()
        .execute()
        .iter()
        .filter(|n| n.distance < r2)
        .map(|n| n.item as usize)
        .collect();
    found.sort_unstable();
    found.into_iter()
}

/// Every sample pair (i of body a, j of body b, a < b) closer than `reach(a, b)` metres,
/// for sample positions `x` (one list per body), in the order (a, b, i, j): sums over the
/// result do not depend on the thread count.
pub fn candidates<P: AsRef<[Point3]>>(
    x: &[P],
    reach: &dyn Fn(usize, usize) -> f64,
) -> (Vec<Candidate>, BroadStats) {
    let x: Vec<&[Point3]> = x.iter().map(AsRef::as_ref).collect();
    let boxes: Vec<(Point3, Point3)> = x.iter().map(|p| bounds(p)).collect();
    let mut trees: Vec<Option<ImmutableKdTree<f64, 3>>> = (0..x.len()).map(|_| None).collect();
    let mut out = Vec::new();
    let mut stats = BroadStats::default();
    for a in 0..x.len() {
        for b in a + 1..x.len() {
            stats.object_pairs += 1;
            let r = reach(a, b);
            let (la, ha) = boxes[a];
            let (lb, hb) = boxes[b];
            if (0..3).any(|d| la[d] > hb[d] + r || lb[d] > ha[d] + r) || x[a].is_empty() {
                continue;
            }
            stats.object_pairs_near += 1;
            if trees[b].is_none() {
                // A k-d tree over finite points cannot fail to build; non-finite positions
                // (never produced by a finite z) would leave the pair untested.
                trees[b] = ImmutableKdTree::new_from_slice(x[b]).ok();
            }
            let Some(tree) = &trees[b] else { continue };
            let r2 = r * r;
            for (i, p) in x[a].iter().enumerate() {
                if (0..3).any(|d| p[d] < lb[d] - r || p[d] > hb[d] + r) {
                    continue;
                }
                out.extend(within(tree, p, r2).map(|j| Candidate { a, b, i, j }));
            }
        }
    }
    (out, stats)
}

/// Every pair (i < j) of body `a`'s samples closer than `reach` metres at positions `x` whose
/// rest positions `rest` are at least `exclusion` metres apart (nearer samples belong to one
/// patch of surface, held apart by the material itself), in the order (i, j).
pub fn self_candidates(
    a: usize,
    x: &[Point3],
    rest: &[Point3],
    reach: f64,
    exclusion: f64,
) -> Vec<Candidate> {
    let mut out = Vec::new();
    if x.len() < 2 {
        return out;
    }
    // As in `candidates`: finite positions always build; non-finite ones leave no pairs.
    let Ok(tree) = ImmutableKdTree::<f64, 3>::new_from_slice(x) else {
        return out;
    };
    let (r2, ex2) = (reach * reach, exclusion * exclusion);
    for (i, p) in x.iter().enumerate() {
        let far_at_rest = |j: &usize| {
            let (u, v) = (rest[i], rest[*j]);
            (0..3).map(|k| (u[k] - v[k]).powi(2)).sum::<f64>() >= ex2
        };
        out.extend(
            within(&tree, p, r2)
                .filter(|&j| j > i)
                .filter(far_at_rest)
                .map(|j| Candidate { a, b: a, i, j }),
        );
    }
    out
}
