//! The largest value within a radius of each query point, over a fixed set of valued points:
//! the points are binned into a uniform grid of cells, each with its largest value. A ball
//! takes the cells it holds whole by their largest values and scans the points only of the
//! cells its surface cuts whose largest value could still raise the answer. Exact: the same
//! answer as testing every point (squared distance summed x, y, z, compared with `<=`).

use crate::geometry::Aabb;
use crate::Point3;

/// Points with values, binned for [`BallMax::max_within`].
pub(crate) struct BallMax<'a> {
    points: &'a [Point3],
    values: &'a [f64],
    /// The squared radius, metres^2.
    radius2: f64,
    /// Lower corner of the grid and the cells' edge length, metres.
    origin: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    /// The points of cell c are `order[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    order: Vec<u32>,
    /// Largest value of each cell's points (-inf for an empty cell).
    top: Vec<f64>,
}

/// Relative margin of the whole-cell and empty-cell tests, far above the rounding of a box's
/// distance, so that a cell taken whole or skipped is one whose every point the exact
/// per-point test would have taken or skipped; cells within the margin are scanned.
const MARGIN: f64 = 1e-9;

impl<'a> BallMax<'a> {
    /// Bin `points` (metres) with their `values` (one each) for balls of `radius` metres.
    /// Cells are half the radius, coarser when that would make more than two cells a point;
    /// one cell for a radius that is not positive and finite or points that are not finite.
    ///
    /// # Panics
    /// When `values` is not as long as `points` or there are 2^32 points or more (callers
    /// pass one value per integration point, whose count is bounded far below).
    pub(crate) fn new(points: &'a [Point3], values: &'a [f64], radius: f64) -> Self {
        assert_eq!(points.len(), values.len(), "BallMax: one value per point");
        assert!(
            u32::try_from(points.len()).is_ok(),
            "BallMax: u32 point indices"
        );
        let bounds = Aabb::from_points(points).unwrap_or(Aabb {
            min: [0.0; 3],
            max: [0.0; 3],
        });
        let extent = bounds.size();
        let cells_of =
            |cell: f64| -> f64 { extent.iter().map(|e| (e / cell).floor() + 1.0).product() };
        let mut cell = 0.5 * radius;
        if !(cell > 0.0 && cell.is_finite() && extent.iter().all(|e| e.is_finite())) {
            // Degenerate input: one cell, every ball scans every point (still exact).
            cell = f64::INFINITY;
        }
        while cells_of(cell) > 2.0 * points.len().max(1) as f64 {
            cell *= 1.5;
        }
        let dims: [usize; 3] = std::array::from_fn(|a| (extent[a] / cell).floor() as usize + 1);
        let count = dims.iter().product::<usize>();
        let mut grid = Self {
            points,
            values,
            radius2: radius * radius,
            origin: bounds.min,
            cell,
            dims,
            start: vec![0; count + 1],
            order: vec![0; points.len()],
            top: vec![f64::NEG_INFINITY; count],
        };
        // Counting sort of the points by cell.
        let cell_of: Vec<usize> = points.iter().map(|p| grid.cell_index(p)).collect();
        for &c in &cell_of {
            grid.start[c + 1] += 1;
        }
        for c in 0..count {
            grid.start[c + 1] += grid.start[c];
        }
        let mut fill = grid.start.clone();
        for (i, &c) in cell_of.iter().enumerate() {
            grid.order[fill[c] as usize] = i as u32;
            fill[c] += 1;
            grid.top[c] = grid.top[c].max(values[i]);
        }
        grid
    }

    /// The cell holding `p`, clamped to the grid.
    fn cell_index(&self, p: &Point3) -> usize {
        let [i, j, k] = std::array::from_fn(|a| self.axis_cell(a, p[a]));
        (k * self.dims[1] + j) * self.dims[0] + i
    }

    fn axis_cell(&self, a: usize, x: f64) -> usize {
        let t = ((x - self.origin[a]) / self.cell).floor();
        if t <= 0.0 {
            0
        } else {
            (t as usize).min(self.dims[a] - 1)
        }
    }

    /// The largest value of the points within the radius of `q` (distance <= radius), or
    /// -inf when there is none.
    pub(crate) fn max_within(&self, q: &Point3) -> f64 {
        // The box of a cell, padded so that a point binned into it by rounding lies inside.
        let pad = self.cell * MARGIN;
        // The cells within reach, with the same margin: at most 6 along an axis, since cells
        // are at least half the radius.
        let r = self.radius2.sqrt() * (1.0 + MARGIN) + pad;
        let lo: [usize; 3] = std::array::from_fn(|a| self.axis_cell(a, q[a] - r));
        let hi: [usize; 3] = std::array::from_fn(|a| self.axis_cell(a, q[a] + r));
        // Per axis and cell: the squared distance from q to the cell's slab, and to its far
        // side; a box's distances are the sums over the axes.
        let mut near = [[0.0f64; SPAN]; 3];
        let mut far = [[0.0f64; SPAN]; 3];
        for a in 0..3 {
            for (s, c) in (lo[a]..=hi[a]).enumerate() {
                let b0 = self.origin[a] + c as f64 * self.cell - pad;
                let b1 = b0 + self.cell + 2.0 * pad;
                // The first and last cells hold the points clamped into them.
                let b0 = if c == 0 { f64::NEG_INFINITY } else { b0 };
                let b1 = if c + 1 == self.dims[a] {
                    f64::INFINITY
                } else {
                    b1
                };
                let d = (b0 - q[a]).max(q[a] - b1).max(0.0);
                let f = (q[a] - b0).max(b1 - q[a]);
                near[a][s] = d * d;
                far[a][s] = f * f;
            }
        }
        let whole = self.radius2 * (1.0 - MARGIN);
        let none = self.radius2 * (1.0 + MARGIN);
        let mut best = f64::NEG_INFINITY;
        // The cells the ball's surface cuts: (cell, its largest value).
        let mut cut = [(0usize, 0.0f64); SPAN * SPAN * SPAN];
        let mut n_cut = 0;
        for (sk, k) in (lo[2]..=hi[2]).enumerate() {
            for (sj, j) in (lo[1]..=hi[1]).enumerate() {
                let row = (k * self.dims[1] + j) * self.dims[0];
                let (near_kj, far_kj) = (near[2][sk] + near[1][sj], far[2][sk] + far[1][sj]);
                for (si, i) in (lo[0]..=hi[0]).enumerate() {
                    if near_kj + near[0][si] > none {
                        continue;
                    }
                    let top = self.top[row + i];
                    if far_kj + far[0][si] <= whole {
                        best = best.max(top);
                    } else {
                        cut[n_cut] = (row + i, top);
                        n_cut += 1;
                    }
                }
            }
        }
        for &(id, top) in &cut[..n_cut] {
            if top <= best {
                continue;
            }
            for &i in &self.order[self.start[id] as usize..self.start[id + 1] as usize] {
                let (p, v) = (&self.points[i as usize], self.values[i as usize]);
                if v > best && distance2(p, q) <= self.radius2 {
                    best = v;
                }
            }
        }
        best
    }
}

/// Most cells a ball's reach spans along an axis (cells are at least half the radius).
const SPAN: usize = 6;

/// Squared distance, summed x, y, z.
fn distance2(a: &Point3, b: &Point3) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every point tested: the definition the grid must reproduce exactly.
    fn brute(points: &[Point3], values: &[f64], q: &Point3, radius: f64) -> f64 {
        points
            .iter()
            .zip(values)
            .filter(|(p, _)| distance2(p, q) <= radius * radius)
            .map(|(_, &v)| v)
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// A deterministic scatter in [0, 1)^3 (a fixed linear congruential sequence).
    fn scatter(n: usize, seed: u64) -> Vec<Point3> {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| [next(), 2.0 * next(), 0.5 * next()])
            .collect()
    }

    #[test]
    fn equals_testing_every_point() {
        let points = scatter(3000, 7);
        let values: Vec<f64> = points
            .iter()
            .map(|p| (7.0 * p[0]).sin() + p[1] * p[2])
            .collect();
        let queries = scatter(400, 99);
        for radius in [0.02, 0.1, 0.37, 3.0] {
            let grid = BallMax::new(&points, &values, radius);
            for q in queries.iter().chain(&points[..200]) {
                assert_eq!(
                    grid.max_within(q),
                    brute(&points, &values, q, radius),
                    "radius {radius}, query {q:?}"
                );
            }
        }
    }

    #[test]
    fn points_on_a_grid_and_on_the_ball_are_counted() {
        // Grid points at exactly the radius (3 spacings) from a grid query: `<=` takes them.
        let h = 0.25;
        let points: Vec<Point3> = (0..9)
            .flat_map(|i| (0..9).flat_map(move |j| (0..9).map(move |k| [i, j, k])))
            .map(|[i, j, k]| [i as f64 * h, j as f64 * h, k as f64 * h])
            .collect();
        let values: Vec<f64> = (0..points.len()).map(|i| (i % 13) as f64).collect();
        let grid = BallMax::new(&points, &values, 3.0 * h);
        for q in &points {
            assert_eq!(grid.max_within(q), brute(&points, &values, q, 3.0 * h));
        }
        // Far from every point: nothing within reach.
        assert_eq!(grid.max_within(&[10.0, 10.0, 10.0]), f64::NEG_INFINITY);
    }

    #[test]
    fn a_degenerate_radius_falls_back_to_one_cell_and_stays_exact() {
        let points = scatter(500, 3);
        let values: Vec<f64> = (0..points.len()).map(|i| i as f64).collect();
        for radius in [0.0, f64::INFINITY, f64::NAN] {
            let grid = BallMax::new(&points, &values, radius);
            assert_eq!(grid.dims, [1, 1, 1], "radius {radius}");
            for q in &points[..50] {
                let got = grid.max_within(q);
                let want = brute(&points, &values, q, radius);
                assert!(got == want, "radius {radius}: {got} against {want}");
            }
        }
    }
}
