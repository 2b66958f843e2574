//! Shape functions over many points one chunk at a time: a caller evaluates a spatially
//! compact chunk, uses its values and gradients, and drops them, so memory holds one chunk's
//! (point, kernel) pairs instead of all of them. Per point the result is exactly that of
//! [`evaluate`](super::evaluate): each point's row depends only on the point and its sorted
//! covering kernels.

use super::neighbors::{covering_kernels_among, kernels_near_box};
use super::{evaluate_on, Kernels, ShapeFunctionOptions, ShapeFunctions, ShapeStats};
use crate::report::Stopwatch;
use crate::{Error, Point3, Result};

/// Points per chunk in the pipeline and in [`crate::precompute::skinning::Basis::weights`]:
/// ~35 covering kernels x 36 bytes per (point, kernel) pair make one chunk ~80 MB, while a
/// chunk is still many kernel supports wide, so few of its kernels reach in from outside.
pub const CHUNK_POINTS: usize = 1 << 16;

/// [`evaluate`](super::evaluate) on a chunk of query points (metres), searching only the
/// kernels near the chunk's bounding box ([`kernels_near_box`]); returns also the time of
/// the neighbour search (seconds). Cheapest when the chunk is spatially compact (consecutive
/// points in Morton order).
pub fn evaluate_chunk(
    kernels: &Kernels,
    queries: &[Point3],
    opts: &ShapeFunctionOptions,
) -> (ShapeFunctions, ShapeStats, f64) {
    let clock = Stopwatch::start();
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in queries {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let candidates = if queries.is_empty() {
        Vec::new()
    } else {
        kernels_near_box(kernels, lo, hi)
    };
    let pattern = covering_kernels_among(kernels, &candidates, queries);
    let neighbors = clock.elapsed();
    let (sf, stats) = evaluate_on(kernels, queries, pattern, opts);
    (sf, stats, neighbors)
}

/// [`ShapeStats`] gathered over chunks, with point indices translated to the caller's.
#[derive(Debug, Clone)]
pub struct ChunkedStats {
    stats: ShapeStats,
    /// Kernels covering the worst point (for the coverage error).
    worst_cover: usize,
    pairs: usize,
    points: usize,
    /// Bytes of the largest chunk's shape functions.
    pub largest_chunk_bytes: usize,
}

impl Default for ChunkedStats {
    fn default() -> Self {
        Self {
            stats: ShapeStats {
                min_rcond: f64::INFINITY,
                min_cover: usize::MAX,
                ..ShapeStats::default()
            },
            worst_cover: 0,
            pairs: 0,
            points: 0,
            largest_chunk_bytes: 0,
        }
    }
}

impl ChunkedStats {
    /// Add one chunk's figures; `index(i)` is the caller's index of the chunk's point i.
    /// The worst point is the one of smallest rcond, the smallest caller index among equals
    /// (as a one-pass [`evaluate`](super::evaluate) in the caller's order would name it).
    pub fn add(&mut self, sf: &ShapeFunctions, st: &ShapeStats, index: impl Fn(usize) -> usize) {
        let n = sf.rows();
        if n == 0 {
            return;
        }
        let s = &mut self.stats;
        s.min_cover = s.min_cover.min(st.min_cover);
        s.max_cover = s.max_cover.max(st.max_cover);
        let worst = index(st.min_rcond_point);
        if st.min_rcond < s.min_rcond || (st.min_rcond == s.min_rcond && worst < s.min_rcond_point)
        {
            s.min_rcond = st.min_rcond;
            s.min_rcond_point = worst;
            self.worst_cover = sf.pattern.row(st.min_rcond_point).len();
        }
        s.failed.extend(st.failed.iter().map(|&i| index(i)));
        self.pairs += sf.nnz();
        self.points += n;
        self.largest_chunk_bytes = self.largest_chunk_bytes.max(sf.memory_bytes());
    }

    /// True when some point so far failed the conditioning check.
    pub fn any_failed(&self) -> bool {
        !self.stats.failed.is_empty()
    }

    /// The figures over all chunks (failed points ascending).
    pub fn stats(&self) -> ShapeStats {
        let mut s = self.stats.clone();
        s.failed.sort_unstable();
        if self.points == 0 {
            s.min_rcond = 0.0;
            s.min_cover = 0;
        } else {
            s.mean_cover = self.pairs as f64 / self.points as f64;
        }
        s
    }

    /// [`Error::Coverage`] naming the worst point (its position `position(index)`) when some
    /// point failed the check with threshold `min_rcond`.
    pub fn coverage_error(&self, position: impl Fn(usize) -> Point3, min_rcond: f64) -> Result<()> {
        if self.stats.failed.is_empty() {
            return Ok(());
        }
        let worst = self.stats.min_rcond_point;
        Err(Error::Coverage {
            count: self.stats.failed.len(),
            index: worst,
            position: position(worst),
            covering: self.worst_cover,
            rcond: self.stats.min_rcond,
            min_rcond,
        })
    }
}
