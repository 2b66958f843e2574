//! Each rank's rows of H_w and M: its block of kernels, the integration points in their
//! supports (sampled again from the grid, [`PointPart::window`]), the shape functions there
//! (with every kernel covering them) and the streamed assembly of those rows only.
//!
//! The rows are the one-process rows bit for bit: every point of an owned kernel's support is
//! in the window, and the points are summed in the one-process (Morton) order.

use super::collective::{agree, Collective};
use super::fps::own_kernels;
use super::partition::PointPart;
use crate::eigen::RowPencil;
use crate::geometry::Shape;
use crate::precompute::centers::morton_order_in;
use crate::precompute::rkpm::{covering_kernels, Kernels, CHUNK_POINTS};
use crate::precompute::stream::{assemble_streamed_rows, Streamed, StreamedAssembly};
use crate::precompute::BasisOptions;
use crate::progress::Progress;
use crate::{Error, Point3, Result};

/// This rank's rows, assembled, and the integration points it evaluated.
#[derive(Debug)]
pub struct OwnRows {
    /// The rows (one per owned kernel) and the figures of their stream.
    pub assembly: StreamedAssembly<RowPencil>,
    /// Integration points this rank evaluated (those in its kernels' supports).
    pub points: usize,
}

/// Assemble this rank's rows of H_w and M (its block of `kernels`, [`own_kernels`]).
/// Collective.
///
/// # Errors
/// On every rank when any rank fails: a material that cannot be evaluated, non-finite sums,
/// or points not covered well enough (the distributed run does not repair coverage:
/// [`Error::Coverage`] on the rank that holds the worst point, an [`Error::InvalidParameter`]
/// naming the count on the others).
pub fn assemble_own_rows(
    shape: &Shape,
    part: &PointPart,
    kernels: &Kernels,
    opts: &BasisOptions,
    comm: &dyn Collective,
    progress: &dyn Progress,
) -> Result<OwnRows> {
    let mine = own_kernels(kernels.len(), comm);
    let own = Kernels {
        centers: kernels.centers[mine.clone()].to_vec(),
        radii: kernels.radii[mine.clone()].to_vec(),
        kind: kernels.kind,
    };
    let (lo, hi) = support_box(&own);
    let window = part.window(shape, lo, hi);
    // The one-process order (Morton over all points, ties by index: the window keeps it).
    let mut order: Vec<usize> = (0..window.len()).collect();
    morton_order_in(&window.points, &mut order, &part.frame);
    // Only the points some owned kernel covers contribute to the owned rows. Tested a block at
    // a time: a whole window's cover lists would take ~150 bytes per point.
    let (mut points, mut volumes) = (Vec::new(), Vec::new());
    for block in order.chunks(COVER_BLOCK) {
        let candidates: Vec<Point3> = block.iter().map(|&i| window.points[i]).collect();
        let cover = covering_kernels(&own, &candidates);
        for (c, &i) in block.iter().enumerate() {
            if !cover.row(c).is_empty() {
                points.push(candidates[c]);
                volumes.push(window.volumes[i]);
            }
        }
    }
    drop((order, window));
    let material = agree(comm, "materials", opts.material_field(shape, &points))?;
    let weights = material.hessian_weights();
    drop(material);
    let streamed = assemble_streamed_rows(
        kernels,
        &points,
        &volumes,
        &weights,
        &opts.shape_functions,
        chunk_points(points.len()),
        mine,
        progress,
    );
    drop((volumes, weights));
    let streamed = agree(comm, "shape functions and assembly", streamed)?;
    // Every rank must take the same decision on coverage: reduce the failure count first.
    let local_failed = match &streamed {
        Streamed::Assembled(_) => 0,
        Streamed::Uncovered(stats) => stats.stats().failed.len(),
    };
    let mut failed = [local_failed as f64];
    comm.sum(&mut failed)?;
    match streamed {
        Streamed::Assembled(done) if failed[0] == 0.0 => Ok(OwnRows {
            assembly: *done,
            points: points.len(),
        }),
        other => {
            if let Streamed::Uncovered(stats) = other {
                stats.coverage_error(|i| points[i], opts.shape_functions.min_rcond)?;
            }
            Err(Error::param(
                "support",
                opts.support.factor,
                format!(
                    "{} point(s) on other MPI ranks are not covered by enough kernels; the \
                     distributed run does not repair coverage: raise {} or run without MPI",
                    failed[0],
                    crate::options::SUPPORT_FACTOR
                ),
            ))
        }
    }
}

/// Window points tested for cover at once.
const COVER_BLOCK: usize = 8192;

/// Points per streamed chunk for a rank evaluating `points` points: a chunk's shape functions
/// take ~1.9 kB per point at the default support, so the one-process chunk (2^16 points, ~120
/// MB) would be a fixed cost on every rank; 1/32 of the rank's points keeps the chunk at a
/// small share of its memory. The rows do not depend on the chunk size (bit for bit).
fn chunk_points(points: usize) -> usize {
    (points / 32).clamp(2048, CHUNK_POINTS)
}

/// Bounding box of the kernels' supports (centre +- radius).
fn support_box(k: &Kernels) -> (Point3, Point3) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (c, &r) in k.centers.iter().zip(&k.radii) {
        for d in 0..3 {
            lo[d] = lo[d].min(c[d] - r);
            hi[d] = hi[d].max(c[d] + r);
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::super::collective::run_ranks;
    use super::super::fps::place_kernels_parts;
    use super::super::partition::sample_part;
    use super::*;
    use crate::precompute::sampling::Resolution;
    use crate::precompute::Problem;
    use crate::progress::Silent;

    #[test]
    fn the_ranks_rows_are_the_one_process_rows_bit_for_bit() {
        let shape = Shape::Sphere { radius: 0.6 };
        let opts = BasisOptions {
            kernels: 150,
            resolution: Some(Resolution::Count(6000)),
            ..BasisOptions::default()
        };
        let problem = Problem::from_shape(&shape, &opts, &Silent).unwrap();
        let (h, m) = (problem.matrices().hessian(), problem.matrices().mass());
        for size in [1, 2, 3] {
            let parts = run_ranks(size, |c| {
                let part = sample_part(&shape, &opts, c).unwrap();
                let kernels = place_kernels_parts(&part, &opts, c, &Silent).unwrap();
                assemble_own_rows(&shape, &part, &kernels, &opts, c, &Silent).unwrap()
            });
            let mut next = 0;
            for own in parts {
                let rows = &own.assembly.assembled;
                assert_eq!(rows.first, next, "P = {size}");
                for r in 0..rows.rows() {
                    let j = rows.first + r;
                    let span = rows.ptr[r]..rows.ptr[r + 1];
                    // Column j of the symmetric CSC matrices is row j.
                    let (hs, ms) = (h.symbolic(), m.symbolic());
                    let want = &hs.row_idx()[hs.col_range(j)];
                    assert_eq!(&rows.cols[span.clone()], want, "row {j}, P = {size}");
                    assert_eq!(
                        &rows.hessian[span.clone()],
                        &h.val()[hs.col_range(j)],
                        "row {j}"
                    );
                    assert_eq!(&rows.mass[span], &m.val()[ms.col_range(j)], "row {j}");
                }
                next += rows.rows();
            }
            assert_eq!(next, opts.kernels);
        }
    }
}
