//! Integration points X_i and volumes v_i (sum v_i = object volume).
//!
//! Solids: a uniform grid of cell centres inside the bounding box, kept where the inside test
//! says so. Each kept point carries its cell volume, rescaled so the weights sum to the exact
//! volume when the shape knows it (primitives, closed meshes). Point clouds: the given points,
//! with volumes from a voxel-occupancy estimate (occupied voxels x voxel volume, shared among
//! the points of each voxel, so dense clusters do not weigh more than sparse regions) or
//! scaled to a user-given total.

use super::options::{default_points, BasisOptions};
pub use super::resolution::{CloudVolumeOptions, Resolution};
use crate::geometry::{Aabb, Shape};
use crate::material::MaterialField;
use crate::{Error, Point3, Result};
use rayon::prelude::*;
use std::collections::HashMap;

/// Integration points with their quadrature weights.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IntegrationPoints {
    /// Positions, N x 3, metres.
    pub points: Vec<Point3>,
    /// Volumes, N, m^3; positive, summing to the object volume.
    pub volumes: Vec<f64>,
}

impl IntegrationPoints {
    /// Number of points N.
    pub fn len(&self) -> usize {
        self.points.len()
    }
    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
    /// Sum of the volumes, m^3.
    pub fn total_volume(&self) -> f64 {
        self.volumes.iter().sum()
    }

    /// Check the points against their per-point materials: one volume and one material per
    /// point, finite positions, positive finite volumes.
    ///
    /// # Errors
    /// [`Error::LengthMismatch`], [`Error::NonFinite`] or [`Error::InvalidParameter`]
    /// (`volumes`), naming the first offending point.
    pub fn check(&self, material: &MaterialField) -> Result<()> {
        let n = self.len();
        for (what, got) in [
            ("volumes", self.volumes.len()),
            ("material values", material.len()),
        ] {
            if got != n {
                return Err(Error::LengthMismatch {
                    what,
                    expected: n,
                    got,
                });
            }
        }
        crate::error::check_finite_points("integration points", &self.points)?;
        if let Some(i) = self
            .points
            .iter()
            .position(|p| !p.iter().all(|c| c.abs() <= crate::error::MAX_MAGNITUDE))
        {
            return Err(Error::param(
                "points",
                format!("{:?} at point {i}", self.points[i]),
                "coordinates must be at most 1e100 m in magnitude: rescale the points to metres",
            ));
        }
        if let Some(i) = self
            .volumes
            .iter()
            .position(|v| !(*v > 0.0 && crate::error::in_range(*v)))
        {
            return Err(Error::param(
                "volumes",
                format!(
                    "{} at point {i}",
                    crate::error::readable_number(self.volumes[i])
                ),
                "every integration volume must be positive, between 1e-100 and 1e100 m^3",
            ));
        }
        Ok(())
    }
}

/// Most grid cells a bounding box may be cut into (guards against a tiny spacing on a big box
/// exhausting memory): 2^31, ~50 GB of candidate points.
pub const MAX_GRID_CELLS: u128 = 1 << 31;

/// The cells of a bounding box at spacing about `h`: each axis gets round(L / h) >= 1 cells of
/// exactly L / n, so the cells tile the box. [`grid_points`] keeps the centres inside a shape;
/// [`Grid::centers_in`] keeps those inside a window too, the same coordinates bit for bit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Lower corner of the box, metres.
    pub min: Point3,
    /// Cells per axis.
    pub cells: [usize; 3],
    /// Cell edge per axis, metres.
    pub step: [f64; 3],
}

impl Grid {
    /// The grid of `aabb` at spacing about `h` (metres).
    ///
    /// # Errors
    /// [`Error::InvalidParameter`] for a flat box or more than [`MAX_GRID_CELLS`] cells.
    pub fn new(aabb: &Aabb, h: f64) -> Result<Self> {
        let mut cells = [0usize; 3];
        let mut step = [0.0; 3];
        for d in 0..3 {
            let len = aabb.max[d] - aabb.min[d];
            if !(len.is_finite() && len > 0.0) {
                return Err(Error::param(
                    "shape",
                    format!("extent {len} along axis {d}"),
                    "the shape is flat or empty along this axis",
                ));
            }
            cells[d] = ((len / h).round() as usize).max(1);
            step[d] = len / cells[d] as f64;
        }
        let count = cells.iter().map(|&v| v as u128).product::<u128>();
        if count > MAX_GRID_CELLS {
            return Err(Error::param("spacing", h, format!("gives {count} grid cells over the bounding box; use a larger spacing or fewer points")));
        }
        Ok(Self {
            min: aabb.min,
            cells,
            step,
        })
    }

    /// Volume of one cell, m^3.
    pub fn cell_volume(&self) -> f64 {
        self.step[0] * self.step[1] * self.step[2]
    }

    /// Centre coordinate of cell `i` along axis `d` (the one formula every caller uses).
    fn center(&self, d: usize, i: usize) -> f64 {
        self.min[d] + (i as f64 + 0.5) * self.step[d]
    }

    /// Cell indices along axis `d` whose centres may lie in `[lo, hi]` (one cell of margin
    /// either side against rounding; the exact test is the caller's).
    fn index_range(&self, d: usize, lo: f64, hi: f64) -> std::ops::Range<usize> {
        let n = self.cells[d];
        let first = ((lo - self.min[d]) / self.step[d] - 1.5).floor();
        let last = ((hi - self.min[d]) / self.step[d] + 0.5).ceil();
        let first = if first.is_nan() || first < 0.0 {
            0
        } else {
            (first as usize).min(n)
        };
        let last = if last.is_nan() || last < 0.0 {
            0
        } else {
            (last as usize).min(n)
        };
        first..last.max(first)
    }

    /// Cell centres with `lo <= p <= hi` (every axis) where `inside` is true, in the order of
    /// the whole grid (z-slabs, then y rows, then x), so the result is the whole grid's
    /// [`grid_points`] filtered to the window, bit for bit. Cost: the window's cells only.
    pub fn centers_in(
        &self,
        lo: Point3,
        hi: Point3,
        inside: &(dyn Fn(&[Point3]) -> Vec<bool> + Sync),
    ) -> Vec<Point3> {
        let r: Vec<std::ops::Range<usize>> =
            (0..3).map(|d| self.index_range(d, lo[d], hi[d])).collect();
        let within = |p: &Point3| (0..3).all(|d| p[d] >= lo[d] && p[d] <= hi[d]);
        self.slabs(
            r[2].clone(),
            r[1].clone(),
            r[0].clone(),
            &|p| within(p),
            inside,
        )
    }

    /// Number of grid rows (a row: one y and one z index, all x), nz x ny. Row r = k ny + j;
    /// the grid's points run row by row ([`grid_points`]'s order).
    pub fn rows(&self) -> usize {
        self.cells[1] * self.cells[2]
    }

    /// The centres of rows `rows` where `inside` is true, in the grid's order, and how many
    /// each row holds (bit for bit [`grid_points`]'s points of those rows).
    pub fn row_points(
        &self,
        rows: std::ops::Range<usize>,
        inside: &(dyn Fn(&[Point3]) -> Vec<bool> + Sync),
    ) -> (Vec<Point3>, Vec<u32>) {
        let [nx, ny, _] = self.cells;
        // Batches of about 8,192 candidates per inside test, in parallel.
        let batch = (8192 / nx.max(1)).max(1);
        let starts: Vec<usize> = rows.clone().step_by(batch).collect();
        let parts: Vec<(Vec<Point3>, Vec<u32>)> = starts
            .into_par_iter()
            .map(|first| {
                let last = (first + batch).min(rows.end);
                let cand: Vec<Point3> = (first..last)
                    .flat_map(|r| {
                        let (y, z) = (self.center(1, r % ny), self.center(2, r / ny));
                        (0..nx).map(move |i| [self.center(0, i), y, z])
                    })
                    .collect();
                let keep = inside(&cand);
                let counts = keep
                    .chunks(nx.max(1))
                    .map(|row| row.iter().filter(|&&k| k).count() as u32)
                    .collect();
                let points = cand
                    .into_iter()
                    .zip(keep)
                    .filter_map(|(p, k)| k.then_some(p))
                    .collect();
                (points, counts)
            })
            .collect();
        let (mut points, mut counts) = (Vec::new(), Vec::with_capacity(rows.len()));
        for (p, c) in parts {
            points.extend(p);
            counts.extend(c);
        }
        (points, counts)
    }

    /// Centres of cells `xs x ys x zs` kept by `keep` and then `inside`, one z-slab at a time
    /// (memory: the kept points plus one slab of candidates).
    fn slabs(
        &self,
        zs: std::ops::Range<usize>,
        ys: std::ops::Range<usize>,
        xs: std::ops::Range<usize>,
        keep: &(dyn Fn(&Point3) -> bool + Sync),
        inside: &(dyn Fn(&[Point3]) -> Vec<bool> + Sync),
    ) -> Vec<Point3> {
        let slabs: Vec<Vec<Point3>> = zs
            .into_par_iter()
            .map(|k| {
                let z = self.center(2, k);
                let cand: Vec<Point3> = ys
                    .clone()
                    .flat_map(|j| {
                        let y = self.center(1, j);
                        xs.clone().map(move |i| [self.center(0, i), y, z])
                    })
                    .filter(|p| keep(p))
                    .collect();
                if cand.is_empty() {
                    return cand;
                }
                let inner = inside(&cand);
                cand.into_iter()
                    .zip(inner)
                    .filter_map(|(p, k)| k.then_some(p))
                    .collect()
            })
            .collect();
        slabs.into_iter().flatten().collect()
    }
}

/// Grid cell centres over `aabb` at spacing about `h` ([`Grid`]), kept where `inside` is
/// true. Volumes are the cell volumes, rescaled to `exact_volume` when given.
pub fn grid_points(
    aabb: &Aabb,
    h: f64,
    exact_volume: Option<f64>,
    inside: &(dyn Fn(&[Point3]) -> Vec<bool> + Sync),
) -> Result<IntegrationPoints> {
    let grid = Grid::new(aabb, h)?;
    let [nx, ny, nz] = grid.cells;
    let points = grid.slabs(0..nz, 0..ny, 0..nx, &|_| true, inside);
    if points.is_empty() {
        return Err(Error::param(
            "spacing",
            h,
            "no grid point falls inside the shape; use a smaller spacing or more points",
        ));
    }
    let v = match exact_volume {
        Some(vol) => vol / points.len() as f64,
        None => grid.cell_volume(),
    };
    Ok(IntegrationPoints {
        volumes: vec![v; points.len()],
        points,
    })
}

/// Quadrature weights for a point cloud (N x 3, metres), and the voxel edge used.
pub fn cloud_volumes(points: &[Point3], opts: &CloudVolumeOptions) -> Result<(Vec<f64>, f64)> {
    if points.is_empty() {
        return Err(Error::param("points", 0, "the point cloud is empty"));
    }
    crate::error::check_finite_points("point cloud", points)?;
    let voxel = match opts.voxel {
        Some(v) if v.is_finite() && v > 0.0 => v,
        Some(v) => {
            return Err(Error::param(
                "voxel",
                v,
                "voxel size must be a positive length",
            ))
        }
        None => 2.0 * median_nn_distance(points)?,
    };
    let key = |p: &Point3| {
        [
            (p[0] / voxel).floor() as i64,
            (p[1] / voxel).floor() as i64,
            (p[2] / voxel).floor() as i64,
        ]
    };
    let mut counts: HashMap<[i64; 3], u32> = HashMap::new();
    for p in points {
        *counts.entry(key(p)).or_insert(0) += 1;
    }
    let v3 = voxel * voxel * voxel;
    if !(v3.is_finite() && v3 > 0.0) {
        return Err(Error::param(
            "voxel",
            voxel,
            format!(
                "a voxel of this edge has volume {v3:e} m^3, which f64 cannot represent; the \
                 coordinates are not in metres at a usable scale: rescale the point cloud"
            ),
        ));
    }
    let mut vols: Vec<f64> = points.iter().map(|p| v3 / counts[&key(p)] as f64).collect();
    if let Some(total) = opts.total_volume {
        if !(total.is_finite() && total > 0.0) {
            return Err(Error::param(
                "volume",
                total,
                "total volume must be a positive number of m^3",
            ));
        }
        let s = total / vols.iter().sum::<f64>();
        vols.iter_mut().for_each(|v| *v *= s);
    }
    Ok((vols, voxel))
}

/// The median distance from a point of `points` (N x 3, metres) to its nearest other point,
/// metres (over at most about 20,000 of them).
///
/// # Errors
/// [`Error::InvalidParameter`] when every point has a duplicate or the points coincide.
pub fn median_nn_distance(points: &[Point3]) -> Result<f64> {
    use kiddo::{ImmutableKdTree, SquaredEuclidean};
    let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(points)
        .map_err(|e| Error::param("points", points.len(), format!("k-d tree: {e:?}")))?;
    let stride = (points.len() / 20_000).max(1);
    let two = std::num::NonZero::new(2).expect("2 > 0");
    let mut d: Vec<f64> = points
        .par_iter()
        .step_by(stride)
        .map(|p| {
            tree.query(p)
                .nearest_n::<SquaredEuclidean<f64>>(two)
                .execute()
                .last()
                .map_or(0.0, |r| r.distance.sqrt())
        })
        .filter(|&d| d > 0.0)
        .collect();
    if d.is_empty() {
        // The largest edge, not the diagonal: squaring it would underflow as well.
        let extent = crate::geometry::Aabb::from_points(points)
            .map_or(0.0, |b| b.size().into_iter().fold(0.0, f64::max));
        let distinct: std::collections::HashSet<[u64; 3]> =
            points.iter().map(|p| p.map(f64::to_bits)).collect();
        let reason = if extent > 0.0 && distinct.len() < points.len() {
            format!(
                "every point has an exact duplicate ({} points at {} distinct positions), so \
                 the spacing of the cloud is unknown: remove the duplicates (for example \
                 numpy.unique(points, axis=0)) or give the voxel size",
                points.len(),
                distinct.len()
            )
        } else if extent > 0.0 {
            format!(
                "the points are too close together for f64 distances (largest bounding-box \
                 edge {extent:e} m): rescale the point cloud to metres"
            )
        } else {
            "all points coincide: the cloud has no extent".to_string()
        };
        return Err(Error::param("points", points.len(), reason));
    }
    d.sort_by(f64::total_cmp);
    Ok(d[d.len() / 2])
}

/// Integration points for a shape (N x 3, metres, with volumes, m^3): a grid inside solids, the
/// (optionally downsampled) points of a point cloud with voxel-occupancy volumes.
pub fn sample_shape(
    shape: &Shape,
    resolution: Resolution,
    cloud: &CloudVolumeOptions,
) -> Result<IntegrationPoints> {
    match shape {
        Shape::PointCloud(pc) => {
            let all = pc.points();
            let points = match resolution {
                Resolution::Count(n) if n < all.len() => downsample(all, n),
                Resolution::Count(_) => all.to_vec(),
                Resolution::Spacing(h) => {
                    let why = format!(
                        "a point cloud's points are its integration points; use {} N to \
                         downsample",
                        crate::options::POINTS
                    );
                    return Err(Error::param("spacing", h, why));
                }
            };
            let (volumes, _) = cloud_volumes(&points, cloud)?;
            Ok(IntegrationPoints { points, volumes })
        }
        solid => {
            let aabb = solid.bounding_box();
            let exact = solid.volume();
            let h = resolution.spacing(exact.unwrap_or_else(|| box_volume(&aabb)))?;
            let inside = |p: &[Point3]| solid.contains(p).unwrap_or_else(|| vec![true; p.len()]);
            grid_points(&aabb, h, exact, &inside)
        }
    }
}

fn box_volume(aabb: &Aabb) -> f64 {
    (0..3).map(|d| aabb.max[d] - aabb.min[d]).product()
}

/// The sampling grid of a solid (not a point cloud) at `resolution`, and its exact volume
/// (m^3) where the shape knows it: what [`sample_shape`] samples, for callers that sample
/// parts of it ([`Grid::centers_in`]).
///
/// # Errors
/// As [`sample_shape`]; [`Error::InvalidParameter`] for a point cloud.
pub fn solid_grid(shape: &Shape, resolution: Resolution) -> Result<(Grid, Option<f64>)> {
    if matches!(shape, Shape::PointCloud(_)) {
        return Err(Error::param(
            "shape",
            "a point cloud",
            "a point cloud has no sampling grid; its points are its integration points",
        ));
    }
    let aabb = shape.bounding_box();
    let exact = shape.volume();
    let h = resolution.spacing(exact.unwrap_or_else(|| box_volume(&aabb)))?;
    Ok((Grid::new(&aabb, h)?, exact))
}

/// A deterministic, spatially unbiased subset of `n` points (seeded partial Fisher-Yates),
/// returned in input order.
fn downsample(points: &[Point3], n: usize) -> Vec<Point3> {
    let mut idx: Vec<usize> = (0..points.len()).collect();
    let mut rng = crate::random::SplitMix64::new(0x5EED_F1EE);
    for i in 0..n {
        let j = i + (rng.next_u64() % (points.len() - i) as u64) as usize;
        idx.swap(i, j);
    }
    let mut keep = idx[..n].to_vec();
    keep.sort_unstable();
    keep.into_iter().map(|i| points[i]).collect()
}

/// The first stage of every precomputation: the integration points (N x 3, metres, with
/// volumes, m^3) of `shape` at
/// `opts.resolution` (default [`default_points`] of `opts.kernels`) and the material at each
/// ([`BasisOptions::material_field`]: `opts.material`, a voxel image's materials, then
/// `opts.overrides` in order). The pipeline, the MPI path and
/// the scene's basis cache all call this, so they sample a shape the same way.
pub fn sample_with_material(
    shape: &Shape,
    opts: &BasisOptions,
) -> Result<(IntegrationPoints, MaterialField)> {
    let resolution = opts
        .resolution
        .unwrap_or(Resolution::Count(default_points(opts.kernels)));
    let points = sample_shape(shape, resolution, &opts.cloud)?;
    let material = opts.material_field(shape, &points.points)?;
    Ok((points, material))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_of_the_grid_is_the_grid_filtered_to_it_bit_for_bit() {
        // A sphere's inside test and a step that does not divide the box: the window's
        // points must be exactly the full grid's inside it, in the same order (the MPI path
        // relies on it for bit-identical rows).
        let shape = Shape::Sphere { radius: 0.7 };
        let (grid, _) = solid_grid(&shape, Resolution::Count(3000)).unwrap();
        let inside = |p: &[Point3]| shape.contains(p).unwrap();
        let [nx, ny, nz] = grid.cells;
        let all = grid.slabs(0..nz, 0..ny, 0..nx, &|_| true, &inside);
        for (lo, hi) in [
            ([-0.31, -0.2, -0.05], [0.12, 0.33, 0.4]),
            ([-1.0; 3], [1.0; 3]),
            ([0.5, 0.5, 0.5], [0.6, 0.6, 0.6]),
            ([2.0; 3], [3.0; 3]),
        ] {
            let want: Vec<Point3> = (all.iter().copied())
                .filter(|p| (0..3).all(|d| p[d] >= lo[d] && p[d] <= hi[d]))
                .collect();
            assert_eq!(grid.centers_in(lo, hi, &inside), want, "{lo:?}..{hi:?}");
        }
        // The whole grid through sample_shape is the same set.
        let full = sample_shape(&shape, Resolution::Count(3000), &Default::default()).unwrap();
        assert_eq!(full.points, all);
        assert!(solid_grid(
            &Shape::PointCloud(crate::geometry::PointCloud::new(vec![[0.0; 3]; 4]).unwrap()),
            Resolution::Count(10)
        )
        .is_err());
    }

    #[test]
    fn box_grid_tiles_exactly() {
        let b = Aabb {
            min: [0.0; 3],
            max: [5.0, 1.0, 1.0],
        };
        let ip = grid_points(&b, 0.1, None, &|p| vec![true; p.len()]).unwrap();
        assert_eq!(ip.len(), 50 * 10 * 10);
        assert!((ip.total_volume() - 5.0).abs() < 1e-12);
        // Spacing 0.3 does not divide 5: 17 x 3 x 3 cells of 5/17 x 1/3 x 1/3 still tile.
        let ip = grid_points(&b, 0.3, None, &|p| vec![true; p.len()]).unwrap();
        assert_eq!(ip.len(), 17 * 3 * 3);
        assert!((ip.total_volume() - 5.0).abs() < 1e-12);
    }

    #[test]
    fn inside_filter_and_exact_volume() {
        let b = Aabb {
            min: [-1.0; 3],
            max: [1.0; 3],
        };
        let inside = |p: &[Point3]| {
            p.iter()
                .map(|x| x[0] * x[0] + x[1] * x[1] + x[2] * x[2] < 1.0)
                .collect()
        };
        let exact = 4.0 / 3.0 * std::f64::consts::PI;
        let raw = grid_points(&b, 0.05, None, &inside).unwrap();
        // Cell counting converges like h / R: within 1 % at h = 0.05.
        assert!(
            (raw.total_volume() / exact - 1.0).abs() < 0.01,
            "{}",
            raw.total_volume()
        );
        let ip = grid_points(&b, 0.05, Some(exact), &inside).unwrap();
        // Summing ~33k equal weights accumulates ~N eps relative round-off.
        assert!((ip.total_volume() / exact - 1.0).abs() < 1e-10);
        assert!(grid_points(&b, 0.05, None, &|p| vec![false; p.len()]).is_err());
        assert!(grid_points(&b, 1e-9, None, &inside).is_err());
    }

    #[test]
    fn a_cloud_of_duplicated_points_is_refused_naming_the_duplicates() {
        let distinct: Vec<Point3> = (0..10).map(|i| [i as f64, 0.5 * i as f64, 0.0]).collect();
        let pts: Vec<Point3> = (0..1000).map(|i| distinct[i % 10]).collect();
        let e = cloud_volumes(&pts, &CloudVolumeOptions::default()).unwrap_err();
        assert!(
            e.to_string()
                .contains("1000 points at 10 distinct positions"),
            "{e}"
        );
    }

    #[test]
    fn cloud_volumes_handle_density_variation() {
        // A unit cube sampled on a 20^3 grid, plus 8000 extra points crammed into one corner
        // cell: voxel weights must still sum to ~ the cube volume.
        let mut pts: Vec<Point3> = (0..8000)
            .map(|i| {
                [
                    ((i % 20) as f64 + 0.5) / 20.0,
                    (((i / 20) % 20) as f64 + 0.5) / 20.0,
                    ((i / 400) as f64 + 0.5) / 20.0,
                ]
            })
            .collect();
        for i in 0..8000 {
            pts.push([
                0.01 + 1e-5 * (i % 20) as f64,
                0.01 + 1e-5 * ((i / 20) % 20) as f64,
                0.01 + 1e-5 * (i / 400) as f64,
            ]);
        }
        let (v, voxel) = cloud_volumes(
            &pts,
            &CloudVolumeOptions {
                voxel: Some(0.1),
                total_volume: None,
            },
        )
        .unwrap();
        assert_eq!(voxel, 0.1);
        let total: f64 = v.iter().sum();
        assert!((total - 1.0).abs() < 1e-9, "{total}");
        let (v, _) = cloud_volumes(
            &pts,
            &CloudVolumeOptions {
                voxel: Some(0.1),
                total_volume: Some(2.0),
            },
        )
        .unwrap();
        assert!((v.iter().sum::<f64>() - 2.0).abs() < 1e-12);
        assert!(cloud_volumes(&[], &CloudVolumeOptions::default()).is_err());
        assert!(cloud_volumes(&[[1.0; 3]; 4], &CloudVolumeOptions::default()).is_err());
    }
}
