//! Kernel centres by farthest point sampling (FPS) over the integration points.
//!
//! [`farthest_point_sampling`] is exact FPS accelerated with a grid of cells and a max-heap over
//! cells: after a new centre c is picked at squared distance d_max from the others, only points
//! within sqrt(d_max) of c can get closer, so only the cells meeting that ball are visited. It
//! returns exactly the sequence of the brute-force O(N K) algorithm
//! ([`farthest_point_sampling_brute`]) — same start, same tie-breaking (lowest index) — at a
//! cost of about O(N log K) for well-spread points.
//!
//! With a scale per point s_i ([`farthest_point_sampling_scaled`], from
//! [`super::density::KernelDensity`]) the sampling is weighted: distances are measured in units
//! of the finer of the two local spacings, max(s_i, s_c) |X_i - c|, so centres come s_i times
//! closer together where s_i is larger. The finer one, not the point's own: a kernel placed
//! for a fine region counts as near a coarse point only as far as its own (fine) spacing, so
//! a coarse point next to a refined band still gets kernels of its own around it (with s_i
//! alone it could be "covered" by a plane of fine kernels whose small supports all come from
//! one side). The pruning ball grows to sqrt(d_max) / min s; the brute force has the same
//! option.

use crate::{Error, Point3, Result};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// The first centre: the point farthest from the centroid of all points (lowest index on ties).
fn start_index(points: &[Point3]) -> usize {
    let n = points.len() as f64;
    let mut c = [0.0; 3];
    for p in points {
        for d in 0..3 {
            c[d] += p[d] / n;
        }
    }
    let mut best = (f64::NEG_INFINITY, 0);
    for (i, p) in points.iter().enumerate() {
        let d = dist2(p, &c);
        if d > best.0 {
            best = (d, i);
        }
    }
    best.1
}

/// Squared distance between two points, m^2.
#[inline]
pub(super) fn dist2(a: &Point3, b: &Point3) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

fn check(points: &[Point3], k: usize) -> Result<()> {
    if k == 0 {
        return Err(Error::param("kernels", k, "need at least one kernel"));
    }
    if points.len() < k {
        return Err(Error::param(
            "kernels",
            k,
            format!(
                "only {} integration points to choose centres from; use fewer kernels or more points \
                 ({} / {})",
                points.len(),
                crate::options::POINTS,
                crate::options::SPACING
            ),
        ));
    }
    crate::error::check_finite_points("integration points", points)
}

/// The scale factors must be one per point, finite and positive.
fn check_scale(points: &[Point3], scale: Option<&[f64]>) -> Result<()> {
    let Some(scale) = scale else { return Ok(()) };
    if scale.len() != points.len() {
        return Err(Error::param(
            "kernel density",
            scale.len(),
            format!("one scale per integration point needed ({})", points.len()),
        ));
    }
    if let Some(i) = scale.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(Error::param(
            "kernel density",
            scale[i],
            format!("the scale at integration point {i} must be a positive finite number"),
        ));
    }
    Ok(())
}

fn too_few_distinct(k: usize, found: usize) -> Error {
    Error::param(
        "kernels",
        k,
        format!("the points hold only {found} distinct positions; use at most {found} kernels"),
    )
}

/// Points bucketed into a uniform grid of cells (about [`POINTS_PER_CELL`] points per
/// occupied cell), CSR by cell.
struct CellGrid {
    lo: Point3,
    /// Upper corner of the points' bounding box.
    hi: Point3,
    size: f64,
    dims: [usize; 3],
    /// Cell c holds `order[start[c]..start[c + 1]]` (point indices, ascending).
    start: Vec<usize>,
    order: Vec<u32>,
}

/// Target mean number of points per cell of the FPS grid.
const POINTS_PER_CELL: f64 = 32.0;

impl CellGrid {
    fn new(points: &[Point3]) -> Self {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in points {
            for d in 0..3 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let ext: Vec<f64> = (0..3).map(|d| hi[d] - lo[d]).collect();
        let max_ext = ext.iter().copied().fold(0.0, f64::max);
        // Cell edge from the bounding-box volume (flat axes count as 1e-3 of the largest);
        // at most ~N cells in all.
        let vol: f64 = ext.iter().map(|e| e.max(1e-3 * max_ext)).product();
        let mut size = (vol * POINTS_PER_CELL / points.len() as f64).cbrt();
        if !(size.is_finite() && size > 0.0) {
            size = 1.0;
        }
        let dims_for = |size: f64| -> [usize; 3] {
            [0, 1, 2].map(|d| ((ext[d] / size) as usize).saturating_add(1).min(1 << 20))
        };
        let mut dims = dims_for(size);
        while dims.iter().product::<usize>() > 4 * points.len() + 8 {
            size *= 1.5;
            dims = dims_for(size);
        }
        let mut grid = CellGrid {
            lo,
            hi,
            size,
            dims,
            start: Vec::new(),
            order: Vec::new(),
        };
        let ncell = dims.iter().product::<usize>();
        let cell_of: Vec<usize> = points.iter().map(|p| grid.cell(p)).collect();
        let mut start = vec![0usize; ncell + 1];
        for &c in &cell_of {
            start[c + 1] += 1;
        }
        for c in 0..ncell {
            start[c + 1] += start[c];
        }
        let mut next = start.clone();
        let mut order = vec![0u32; points.len()];
        for (i, &c) in cell_of.iter().enumerate() {
            order[next[c]] = i as u32;
            next[c] += 1;
        }
        grid.start = start;
        grid.order = order;
        grid
    }

    fn coord(&self, p: &Point3, d: usize) -> usize {
        (((p[d] - self.lo[d]) / self.size) as usize).min(self.dims[d] - 1)
    }

    fn cell(&self, p: &Point3) -> usize {
        self.coord(p, 0) + self.dims[0] * (self.coord(p, 1) + self.dims[1] * self.coord(p, 2))
    }

    fn points(&self, c: usize) -> &[u32] {
        &self.order[self.start[c]..self.start[c + 1]]
    }
}

/// The farthest point of a cell: (squared distance bits, lowest index attaining it).
fn cell_max(grid: &CellGrid, dist: &[f64], c: usize) -> (u64, u32) {
    let mut best = (0u64, u32::MAX);
    for &i in grid.points(c) {
        let b = dist[i as usize].to_bits();
        if b > best.0 || (b == best.0 && i < best.1) {
            best = (b, i);
        }
    }
    best
}

/// Indices of `k` centres chosen by exact farthest point sampling from `points` (N x 3).
/// Errors if k is 0, exceeds N, or exceeds the number of distinct points.
///
/// Points are bucketed into grid cells; a max-heap over cells holds each cell's farthest
/// point ([`FarthestPoints`]). A new centre at squared distance d_max can only bring closer the
/// points within sqrt(d_max) of it, so only the cells meeting that ball are visited and
/// rescanned. Heap keys are (squared distance bits, lowest index), so the sequence is exactly
/// that of the brute force, ties included.
pub fn farthest_point_sampling(points: &[Point3], k: usize) -> Result<Vec<usize>> {
    farthest_point_sampling_scaled(points, None, k)
}

/// [`farthest_point_sampling`] with distances scaled per point: point i is at
/// max(s_i, s_c) |X_i - c| from a centre c (`scale`: N positive finite factors, None for all 1),
/// so the centres' spacing near X_i is about 1 / s_i of what it is where s = 1. The first
/// centre is the same.
pub fn farthest_point_sampling_scaled(
    points: &[Point3],
    scale: Option<&[f64]>,
    k: usize,
) -> Result<Vec<usize>> {
    check(points, k)?;
    check_scale(points, scale)?;
    let s0 = start_index(points);
    let at = |i: usize| scale.map_or(1.0, |s| s[i]);
    let mut state = FarthestPoints::with_scale(points, scale, &points[s0], at(s0));
    let mut chosen = Vec::with_capacity(k);
    chosen.push(s0);
    while chosen.len() < k {
        let Some((d_max, idx)) = state.farthest() else {
            return Err(too_few_distinct(k, chosen.len()));
        };
        if d_max <= 0.0 {
            return Err(too_few_distinct(k, chosen.len()));
        }
        chosen.push(idx);
        state.add_center(&points[idx], at(idx), d_max);
    }
    Ok(chosen)
}

/// The state of an exact farthest point sampling over one set of points (all points, or one
/// MPI rank's part of them): each point's squared distance to the nearest centre so far, and
/// the farthest point, found through a grid of cells and a max-heap over them.
pub struct FarthestPoints<'a> {
    points: &'a [Point3],
    /// Squared scale per point (None: all 1) and 1 / its minimum.
    scale2: Option<Vec<f64>>,
    inv_min_scale2: f64,
    grid: CellGrid,
    /// Scaled squared distance to the nearest centre, s_i^2 |X_i - c|^2.
    dist: Vec<f64>,
    /// Each cell's farthest point: (squared distance bits, lowest index attaining it).
    best: Vec<(u64, u32)>,
    /// Cells by their farthest point; entries whose cell changed since are stale.
    heap: BinaryHeap<(u64, Reverse<u32>, u32)>,
}

impl<'a> FarthestPoints<'a> {
    /// Distances of `points` (N x 3, metres; at most 2^32 of them) to a first centre `first`.
    pub fn new(points: &'a [Point3], first: &Point3) -> Self {
        Self::with_scale(points, None, first, 1.0)
    }

    /// [`FarthestPoints::new`] with distances scaled by `scale` (N positive finite factors,
    /// checked by the caller) and the first centre's scale `first_scale`, as
    /// [`farthest_point_sampling_scaled`].
    pub fn with_scale(
        points: &'a [Point3],
        scale: Option<&[f64]>,
        first: &Point3,
        first_scale: f64,
    ) -> Self {
        let grid = CellGrid::new(points);
        let scale2: Option<Vec<f64>> = scale.map(|s| s.iter().map(|v| v * v).collect());
        let inv_min_scale2 = scale2.as_ref().map_or(1.0, |s| {
            1.0 / s.iter().copied().fold(f64::INFINITY, f64::min)
        });
        let dist: Vec<f64> = match &scale2 {
            None => points.iter().map(|p| dist2(p, first)).collect(),
            Some(s2) => {
                let c2 = first_scale * first_scale;
                points
                    .iter()
                    .zip(s2)
                    .map(|(p, s)| s.max(c2) * dist2(p, first))
                    .collect()
            }
        };
        let ncell = grid.start.len() - 1;
        let best: Vec<(u64, u32)> = (0..ncell).map(|c| cell_max(&grid, &dist, c)).collect();
        // Non-negative f64 bit patterns order like the numbers; Reverse makes the lowest index
        // win ties, as in the brute force.
        let heap = best
            .iter()
            .enumerate()
            .filter(|(_, b)| b.1 != u32::MAX)
            .map(|(c, &(bits, i))| (bits, Reverse(i), c as u32))
            .collect();
        Self {
            points,
            scale2,
            inv_min_scale2,
            grid,
            dist,
            best,
            heap,
        }
    }

    /// The farthest point from the centres so far: (squared distance, m^2; its index, the
    /// lowest on ties). None for an empty set.
    pub fn farthest(&mut self) -> Option<(f64, usize)> {
        loop {
            let &(bits, Reverse(i), c) = self.heap.peek()?;
            if self.best[c as usize] == (bits, i) {
                return Some((f64::from_bits(bits), i as usize));
            }
            self.heap.pop(); // stale: the cell's farthest point changed since
        }
    }

    /// Add a centre `c` of scale `c_scale` (1 without a scale) that was the farthest point
    /// overall at (scaled) squared distance `d_max`: only points within sqrt(d_max) / min s of
    /// it can come closer, so only those cells are visited.
    pub fn add_center(&mut self, c: &Point3, c_scale: f64, d_max: f64) {
        if self.points.is_empty() {
            return;
        }
        let r = (d_max * self.inv_min_scale2).sqrt();
        let grid = &self.grid;
        let c2 = c_scale * c_scale;
        // A ball that misses this set's bounding box changes nothing (another rank's part).
        if (0..3).any(|d| c[d] + r < grid.lo[d] || c[d] - r > grid.hi[d]) {
            return;
        }
        let lo = [0, 1, 2].map(|d| grid.coord(&[c[0] - r, c[1] - r, c[2] - r], d));
        let hi = [0, 1, 2].map(|d| grid.coord(&[c[0] + r, c[1] + r, c[2] + r], d));
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let cell = x + grid.dims[0] * (y + grid.dims[1] * z);
                    let mut changed = false;
                    for &i in grid.points(cell) {
                        let i = i as usize;
                        let mut d = dist2(&self.points[i], c);
                        if let Some(s2) = &self.scale2 {
                            d *= s2[i].max(c2);
                        }
                        if d < self.dist[i] {
                            self.dist[i] = d;
                            changed = true;
                        }
                    }
                    if changed {
                        let b = cell_max(grid, &self.dist, cell);
                        self.best[cell] = b;
                        self.heap.push((b.0, Reverse(b.1), cell as u32));
                    }
                }
            }
        }
    }
}

/// Brute-force O(N K) farthest point sampling; the reference that
/// [`farthest_point_sampling`] reproduces exactly. Use it only for small inputs and tests.
pub fn farthest_point_sampling_brute(points: &[Point3], k: usize) -> Result<Vec<usize>> {
    farthest_point_sampling_brute_scaled(points, None, k)
}

/// Brute-force [`farthest_point_sampling_scaled`]: the reference it reproduces exactly.
pub fn farthest_point_sampling_brute_scaled(
    points: &[Point3],
    scale: Option<&[f64]>,
    k: usize,
) -> Result<Vec<usize>> {
    check(points, k)?;
    check_scale(points, scale)?;
    let s2 = |i: usize| scale.map_or(1.0, |s| s[i] * s[i]);
    let s0 = start_index(points);
    let mut dist: Vec<f64> = (0..points.len())
        .map(|i| s2(i).max(s2(s0)) * dist2(&points[i], &points[s0]))
        .collect();
    let mut chosen = vec![s0];
    while chosen.len() < k {
        let mut best = (0.0, usize::MAX);
        for (i, &d) in dist.iter().enumerate() {
            if d > best.0 {
                best = (d, i);
            }
        }
        if best.1 == usize::MAX {
            return Err(too_few_distinct(k, chosen.len()));
        }
        chosen.push(best.1);
        let (c, c2) = (points[best.1], s2(best.1));
        for (i, p) in points.iter().enumerate() {
            dist[i] = dist[i].min(s2(i).max(c2) * dist2(p, &c));
        }
    }
    Ok(chosen)
}

/// Spread the lower 21 bits of `v` to every third bit.
fn spread3(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// Reorder `indices` (into `points`) along a Morton (Z-order) curve over their bounding box,
/// ties by index. Spatially close kernels then get close numbers: assembly reuses cached
/// point data between consecutive rows, and H_w and M get a narrow profile. Deterministic.
pub fn morton_order(points: &[Point3], indices: &mut [usize]) {
    if indices.is_empty() {
        return;
    }
    let frame = morton_frame(points, indices);
    morton_order_in(points, indices, &frame);
}

/// The box a Morton order quantizes over: lower corner (metres) and the largest extent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MortonFrame {
    /// Lower corner of the bounding box, metres.
    pub lo: Point3,
    /// Largest edge of the bounding box, metres (0 for coincident points).
    pub extent: f64,
}

/// The bounding box of `points[indices]` as a [`MortonFrame`].
pub fn morton_frame(points: &[Point3], indices: &[usize]) -> MortonFrame {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for &i in indices.iter() {
        for d in 0..3 {
            lo[d] = lo[d].min(points[i][d]);
            hi[d] = hi[d].max(points[i][d]);
        }
    }
    MortonFrame::from_bounds(lo, hi)
}

impl MortonFrame {
    /// The frame of a bounding box with corners `lo` and `hi` (metres), e.g. one reduced over
    /// MPI ranks: the same frame as [`morton_frame`] of the points it bounds.
    pub fn from_bounds(lo: Point3, hi: Point3) -> Self {
        let extent = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
        MortonFrame { lo, extent }
    }

    /// The Morton code of `p` (points outside the frame clamp to its faces).
    pub fn code(&self, p: &Point3) -> u64 {
        let scale = if self.extent > 0.0 {
            ((1u64 << 21) - 1) as f64 / self.extent
        } else {
            0.0
        };
        // `as` saturates.
        let q = |d: usize| ((p[d] - self.lo[d]) * scale) as u64;
        spread3(q(0)) | (spread3(q(1)) << 1) | (spread3(q(2)) << 2)
    }
}

/// [`morton_order`] over a given frame: a subset of a point set ordered in the whole set's
/// frame keeps the whole set's relative order (ties by index, so the subset's indices must
/// keep the whole set's order).
pub fn morton_order_in(points: &[Point3], indices: &mut [usize], frame: &MortonFrame) {
    let mut keyed: Vec<(u64, usize)> = indices
        .par_iter()
        .map(|&i| (frame.code(&points[i]), i))
        .collect();
    keyed.par_sort_unstable();
    for (slot, (_, i)) in indices.iter_mut().zip(keyed) {
        *slot = i;
    }
}

/// Spacing quality of a centre set: nearest-neighbour distances between centres
/// (min, mean, max, metres). Uniform sets have min/max close to 1.
pub fn spacing_stats(centers: &[Point3]) -> (f64, f64, f64) {
    if centers.len() < 2 {
        return (0.0, 0.0, 0.0);
    }
    let Ok(tree) = ImmutableKdTree::<f64, 3>::new_from_slice(centers) else {
        return (0.0, 0.0, 0.0);
    };
    let two = std::num::NonZero::new(2).expect("2 > 0");
    let d: Vec<f64> = centers
        .iter()
        .map(|c| {
            tree.query(c)
                .nearest_n::<SquaredEuclidean<f64>>(two)
                .execute()
                .last()
                .map_or(0.0, |r| r.distance.sqrt())
        })
        .collect();
    let min = d.iter().copied().fold(f64::INFINITY, f64::min);
    let max = d.iter().copied().fold(0.0, f64::max);
    (min, d.iter().sum::<f64>() / d.len() as f64, max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud(n: usize, seed: u64) -> Vec<Point3> {
        let mut r = crate::random::SplitMix64::new(seed);
        (0..n)
            .map(|_| [5.0 * r.next_f64(), r.next_f64(), r.next_f64()])
            .collect()
    }

    #[test]
    fn tree_fps_equals_brute_force() {
        let pts = cloud(3000, 7);
        assert_eq!(
            farthest_point_sampling(&pts, 200).unwrap(),
            farthest_point_sampling_brute(&pts, 200).unwrap()
        );
        // A regular grid has many exact distance ties: tie-breaking must agree too.
        let grid: Vec<Point3> = (0..1000)
            .map(|i| [(i % 10) as f64, ((i / 10) % 10) as f64, (i / 100) as f64])
            .collect();
        assert_eq!(
            farthest_point_sampling(&grid, 150).unwrap(),
            farthest_point_sampling_brute(&grid, 150).unwrap()
        );
    }

    #[test]
    fn a_subset_ordered_in_the_whole_frame_keeps_the_whole_order() {
        let pts = cloud(2000, 11);
        let mut all: Vec<usize> = (0..pts.len()).collect();
        morton_order(&pts, &mut all);
        let frame = morton_frame(&pts, &(0..pts.len()).collect::<Vec<_>>());
        let keep = |i: usize| pts[i][0] < 0.3 && pts[i][1] > -0.2;
        let sub: Vec<Point3> = (0..pts.len())
            .filter(|&i| keep(i))
            .map(|i| pts[i])
            .collect();
        let back: Vec<usize> = (0..pts.len()).filter(|&i| keep(i)).collect();
        let mut order: Vec<usize> = (0..sub.len()).collect();
        morton_order_in(&sub, &mut order, &frame);
        let want: Vec<usize> = all.into_iter().filter(|&i| keep(i)).collect();
        assert_eq!(order.iter().map(|&i| back[i]).collect::<Vec<_>>(), want);
    }

    #[test]
    fn morton_order_is_a_local_permutation() {
        let grid: Vec<Point3> = (0..64)
            .map(|i| [(i % 4) as f64, ((i / 4) % 4) as f64, (i / 16) as f64])
            .collect();
        let mut idx: Vec<usize> = (0..64).rev().collect();
        morton_order(&grid, &mut idx);
        let mut sorted = idx.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..64).collect::<Vec<_>>());
        // The first 8 along the curve fill the 2 x 2 x 2 corner cube.
        assert!(
            idx[..8].iter().all(|&i| grid[i].iter().all(|&c| c < 2.0)),
            "{:?}",
            &idx[..8]
        );
        assert_eq!(idx[0], 0);
        assert_eq!(idx[1], 1); // x bit first
        assert_eq!(idx[2], 4); // then y
    }

    #[test]
    fn tree_fps_equals_brute_force_on_flat_clustered_and_duplicated_sets() {
        // A flat plate (zero extent in z), a dense cluster inside a sparse cloud, duplicates.
        let plate: Vec<Point3> = cloud(4000, 21)
            .into_iter()
            .map(|p| [p[0], p[1], 0.0])
            .collect();
        let mut clustered = cloud(2000, 22);
        clustered.extend(
            cloud(3000, 23)
                .into_iter()
                .map(|p| [1.0 + 1e-3 * p[0], 0.5 + 1e-3 * p[1], 0.5 + 1e-3 * p[2]]),
        );
        let mut dup = cloud(1500, 24);
        dup.extend_from_within(..1500);
        for pts in [plate, clustered, dup] {
            assert_eq!(
                farthest_point_sampling(&pts, 300).unwrap(),
                farthest_point_sampling_brute(&pts, 300).unwrap()
            );
        }
    }

    #[test]
    fn rejects_bad_requests() {
        let pts = cloud(10, 1);
        assert!(farthest_point_sampling(&pts, 0).is_err());
        assert!(farthest_point_sampling(&pts, 11).is_err());
        let dup = vec![[1.0, 2.0, 3.0]; 5];
        let e = farthest_point_sampling(&dup, 2).unwrap_err().to_string();
        assert!(e.contains("1 distinct"), "{e}");
        let mut nan = cloud(10, 2);
        nan[3][1] = f64::NAN;
        assert!(matches!(
            farthest_point_sampling(&nan, 2),
            Err(Error::NonFinite { index: 3, .. })
        ));
    }

    #[test]
    fn scaled_fps_equals_its_brute_force_and_follows_the_scale() {
        let pts = cloud(6000, 31);
        // Twice as fine for x < 1 (a fifth of the volume), graded over 1 < x < 2.
        let scale: Vec<f64> = pts
            .iter()
            .map(|p| 2.0 - (p[0] - 1.0).clamp(0.0, 1.0))
            .collect();
        let fast = farthest_point_sampling_scaled(&pts, Some(&scale), 300).unwrap();
        let brute = farthest_point_sampling_brute_scaled(&pts, Some(&scale), 300).unwrap();
        assert_eq!(fast, brute);
        // Spacing 1/2 in x < 1 is 8x the kernels per volume of x > 2: with 1/5 and 3/5 of
        // the volume, about 8 / 3 as many kernels in the first fifth as in the last three.
        let fine = fast.iter().filter(|&&i| pts[i][0] < 1.0).count() as f64;
        let coarse = fast.iter().filter(|&&i| pts[i][0] > 2.0).count() as f64;
        let ratio = fine / coarse;
        // FPS covers the faces of this thin (1 x 1 cross-section) box first, which takes a
        // larger share of the coarse kernels, so the ratio comes out below 8/3 (1.84 with
        // these points); uniform sampling gives about 1/3, so the interval separates them.
        assert!((1.5..3.5).contains(&ratio), "fine {fine} coarse {coarse}");
        // All ones is the unweighted sampling.
        assert_eq!(
            farthest_point_sampling_scaled(&pts, Some(&vec![1.0; pts.len()]), 200).unwrap(),
            farthest_point_sampling(&pts, 200).unwrap()
        );
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let mut s = scale.clone();
            s[17] = bad;
            let e = farthest_point_sampling_scaled(&pts, Some(&s), 10).unwrap_err();
            assert!(e.to_string().contains("integration point 17"), "{e}");
        }
    }

    #[test]
    fn spacing_is_uniform() {
        // FPS on a dense uniform cloud: nearest-centre distances vary by less than 3x
        // (random sampling of the same count gives ratios of 10x and more).
        let pts = cloud(20_000, 3);
        let idx = farthest_point_sampling(&pts, 300).unwrap();
        let c: Vec<Point3> = idx.iter().map(|&i| pts[i]).collect();
        let (min, _, max) = spacing_stats(&c);
        assert!(max / min < 3.0, "min {min} max {max}");
    }
}
