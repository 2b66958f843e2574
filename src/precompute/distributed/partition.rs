//! Each rank's share of the integration points, without any rank holding all of them.
//!
//! A solid is sampled on a grid whose points run row by row ([`Grid::row_points`]). The ranks
//! first count the points of every row (each rank tests 1/P of the rows), share the counts,
//! and then rank r samples exactly the points with global indices in its block
//! [`block_range`]`(N, r, P)`: a contiguous range of the one-process order, bit for bit. Any
//! other window of the grid (a kernel block's supports) is sampled again on demand
//! ([`PointPart::window`]), the same points bit for bit.
//!
//! A point cloud has no grid: its points are the input, which every rank has read whole, so
//! every rank keeps them (documented in docs/slepc.md) and owns its block of them.

use super::collective::{min, Collective};
use crate::eigen::block_range;
use crate::geometry::Shape;
use crate::precompute::centers::MortonFrame;
use crate::precompute::sampling::Resolution;
use crate::precompute::sampling::{sample_shape, solid_grid, Grid, IntegrationPoints};
use crate::precompute::{default_points, BasisOptions};
use crate::{Error, Point3, Result};

/// This rank's share of the integration points (see the module docs).
#[derive(Debug, Clone)]
pub struct PointPart {
    /// Global index of this rank's first point (the one-process order).
    pub first: usize,
    /// All ranks' points, N.
    pub total: usize,
    /// This rank's points `first..first + points.len()`, N_r x 3, metres.
    pub points: Vec<Point3>,
    /// The Morton frame of all N points (their bounding box), for ordering any subset as the
    /// one-process pipeline orders all points.
    pub frame: MortonFrame,
    source: Source,
}

impl PointPart {
    /// The whole object's volume, m^3: the sum of all ranks' point volumes in the one-process
    /// order (so the same f64 as the one-process pipeline's).
    pub fn volume(&self) -> f64 {
        match &self.source {
            Source::Grid { volume, .. } => std::iter::repeat_n(*volume, self.total).sum(),
            Source::Cloud(all) => all.volumes.iter().sum(),
        }
    }
}

#[derive(Debug, Clone)]
enum Source {
    /// A solid's sampling grid; every point has volume `volume`, m^3.
    Grid { grid: Grid, volume: f64 },
    /// A point cloud, whole on every rank.
    Cloud(IntegrationPoints),
}

/// The one-process sampling of `shape` ([`crate::precompute::sample_shape`]) split over the
/// ranks of `comm`. Collective.
///
/// # Errors
/// As [`crate::precompute::sample_shape`] (on every rank alike: the decisions use shared
/// figures only).
pub fn sample_part(shape: &Shape, opts: &BasisOptions, comm: &dyn Collective) -> Result<PointPart> {
    let resolution = opts
        .resolution
        .unwrap_or(Resolution::Count(default_points(opts.kernels)));
    let (rank, size) = (comm.rank(), comm.size());
    if matches!(shape, Shape::PointCloud(_)) {
        let all = sample_shape(shape, resolution, &opts.cloud)?;
        let own = block_range(all.len(), rank, size);
        let frame = frame_of(&all.points, comm)?;
        return Ok(PointPart {
            first: own.start,
            total: all.len(),
            points: all.points[own].to_vec(),
            frame,
            source: Source::Cloud(all),
        });
    }
    let (grid, exact) = solid_grid(shape, resolution)?;
    let inside = inside_of(shape);
    // Count every row's points, each rank 1/P of the rows; the counts are exact in f64.
    let rows = grid.rows();
    let mine = block_range(rows, rank, size);
    let (_, counted) = grid.row_points(mine.clone(), &inside);
    let mut counts = vec![0.0; rows];
    for (slot, c) in counts[mine].iter_mut().zip(counted) {
        *slot = f64::from(c);
    }
    comm.sum(&mut counts)?;
    let total = counts.iter().sum::<f64>() as usize;
    if total == 0 {
        return Err(Error::param(
            "spacing",
            grid.step.iter().copied().fold(0.0, f64::max),
            "no grid point falls inside the shape; use a finer spacing or more points",
        ));
    }
    // This rank's points: the rows that hold global indices own.start..own.end, trimmed.
    let own = block_range(total, rank, size);
    let mut before = 0usize;
    let mut first_row = rows;
    let mut skip = 0usize;
    let mut last_row = rows;
    for (r, &c) in counts.iter().enumerate() {
        let c = c as usize;
        if first_row == rows && before + c > own.start {
            first_row = r;
            skip = own.start - before;
        }
        if before >= own.end {
            last_row = r;
            break;
        }
        before += c;
    }
    let points = if own.is_empty() {
        Vec::new()
    } else {
        let (pts, _) = grid.row_points(first_row..last_row, &inside);
        pts[skip..skip + own.len()].to_vec()
    };
    let volume = exact.map_or(grid.cell_volume(), |v| v / total as f64);
    let frame = frame_of(&points, comm)?;
    Ok(PointPart {
        first: own.start,
        total,
        points,
        frame,
        source: Source::Grid { grid, volume },
    })
}

impl PointPart {
    /// The range of global indices this rank owns.
    pub fn own(&self) -> std::ops::Range<usize> {
        self.first..self.first + self.points.len()
    }

    /// The volume of all N points, m^3, summed as the one-process report sums it (in order).
    pub fn total_volume(&self) -> f64 {
        match &self.source {
            Source::Grid { volume, .. } => (0..self.total).fold(0.0, |sum, _| sum + volume),
            Source::Cloud(all) => all.total_volume(),
        }
    }

    /// Every integration point (of all ranks) with `lo <= p <= hi` on every axis, in the
    /// one-process order, with its volume (m^3): bit for bit the one-process points and
    /// volumes. Cost: the window's grid cells (a cloud: a scan of its points).
    pub fn window(&self, shape: &Shape, lo: Point3, hi: Point3) -> IntegrationPoints {
        let within = |p: &Point3| (0..3).all(|d| p[d] >= lo[d] && p[d] <= hi[d]);
        match &self.source {
            Source::Grid { grid, volume } => {
                let points = grid.centers_in(lo, hi, &inside_of(shape));
                IntegrationPoints {
                    volumes: vec![*volume; points.len()],
                    points,
                }
            }
            Source::Cloud(all) => {
                let keep: Vec<usize> = (0..all.len()).filter(|&i| within(&all.points[i])).collect();
                IntegrationPoints {
                    points: keep.iter().map(|&i| all.points[i]).collect(),
                    volumes: keep.iter().map(|&i| all.volumes[i]).collect(),
                }
            }
        }
    }
}

/// The inside test sampling uses (a shape that cannot tell keeps every point).
fn inside_of(shape: &Shape) -> impl Fn(&[Point3]) -> Vec<bool> + Sync + '_ {
    move |p: &[Point3]| shape.contains(p).unwrap_or_else(|| vec![true; p.len()])
}

/// The Morton frame of the union of every rank's `points` (their bounding box, exact).
fn frame_of(points: &[Point3], comm: &dyn Collective) -> Result<MortonFrame> {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in points {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    min(comm, &mut lo)?;
    comm.max(&mut hi)?;
    Ok(MortonFrame::from_bounds(lo, hi))
}

#[cfg(test)]
mod tests {
    use super::super::collective::run_ranks;
    use super::*;
    use crate::precompute::centers::morton_frame;
    use crate::precompute::sample_with_material;

    #[test]
    fn the_parts_are_the_one_process_points_bit_for_bit() {
        let sphere = Shape::Sphere { radius: 0.7 };
        let cloud = Shape::PointCloud(
            crate::geometry::PointCloud::new(
                (0..500)
                    .map(|i| {
                        let t = i as f64;
                        [t.sin(), (1.3 * t).cos(), 0.01 * t]
                    })
                    .collect(),
            )
            .unwrap(),
        );
        for shape in [sphere, cloud] {
            let opts = BasisOptions {
                kernels: 50,
                resolution: Some(Resolution::Count(3000)),
                ..BasisOptions::default()
            };
            let (whole, _) = sample_with_material(&shape, &opts).unwrap();
            let all: Vec<usize> = (0..whole.len()).collect();
            let whole_frame = morton_frame(&whole.points, &all);
            for size in 1..5 {
                let parts = run_ranks(size, |c| sample_part(&shape, &opts, c).unwrap());
                let joined: Vec<Point3> = parts.iter().flat_map(|p| p.points.clone()).collect();
                assert_eq!(joined, whole.points, "P = {size}");
                for p in &parts {
                    assert_eq!(p.total, whole.len());
                    assert_eq!(p.frame, whole_frame);
                    // A window is the whole sampling filtered to it, volumes included.
                    let (lo, hi) = ([-0.2, -0.5, -0.3], [0.4, 0.1, 0.3]);
                    let w = p.window(&shape, lo, hi);
                    let keep: Vec<usize> = (0..whole.len())
                        .filter(|&i| {
                            (0..3)
                                .all(|d| whole.points[i][d] >= lo[d] && whole.points[i][d] <= hi[d])
                        })
                        .collect();
                    assert_eq!(
                        w.points,
                        keep.iter().map(|&i| whole.points[i]).collect::<Vec<_>>()
                    );
                    assert_eq!(
                        w.volumes,
                        keep.iter().map(|&i| whole.volumes[i]).collect::<Vec<_>>()
                    );
                }
            }
        }
    }
}
