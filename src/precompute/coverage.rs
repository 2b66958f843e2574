//! Coverage repair: the supports of the kernels nearest a badly covered point grow (x1.25 a
//! round) until every point has a well-conditioned moment matrix. The assembly repairs its
//! integration points ([`super::problem`]); here the same repair runs first on the shape's own
//! surface ([`crate::geometry::Shape::surface_probes`]), where the basis is evaluated later
//! (a FEM reference's nodes, render points, contact samples) but the integration points,
//! half a cell inside, do not reach: a box's corners see an eighth of the kernels an interior
//! point sees, and a kernel density can pull kernels away from them.

use super::centers::{dist2, morton_order};
use super::density::bulk_spacing;
use super::options::BasisOptions;
use super::rkpm::{evaluate_chunk, ChunkedStats, Kernels, CHUNK_POINTS};
use crate::geometry::Shape;
use crate::{Error, Point3, Result};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use std::collections::BTreeSet;

/// Factor by which one repair round grows a support radius.
pub const ENLARGE_FACTOR: f64 = 1.25;

/// Kernels whose supports grow around each badly covered point: this many (4 kernels in
/// general position reproduce linear fields).
const NEAREST: usize = 4;

/// Centres searched for kernels that do not reach a badly covered point yet.
const SEARCHED: usize = 64;

/// Grow by [`ENLARGE_FACTOR`] the supports of [`NEAREST`] kernels around each of `points`
/// (metres): the nearest whose supports do not reach the point yet, so that kernels from new
/// directions cover it (growing kernels that already cover a point whose covering centres are
/// nearly coplanar, at a thin rim, leaves them coplanar); the nearest ones when all of the
/// [`SEARCHED`] nearest reach it. Returns the kernels grown (each once a round).
pub fn enlarge_near(kernels: &mut Kernels, points: &[Point3]) -> Result<BTreeSet<usize>> {
    let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(&kernels.centers)
        .map_err(|e| Error::param("kernels", kernels.len(), format!("k-d tree: {e:?}")))?;
    let searched = std::num::NonZero::new(SEARCHED).expect("SEARCHED > 0");
    let mut grow = BTreeSet::new();
    for p in points {
        // Nearest first (kiddo sorts them).
        let near = tree
            .query(p)
            .nearest_n::<SquaredEuclidean<f64>>(searched)
            .execute();
        let ids = near.iter().map(|r| r.item as usize);
        let reaches = |k: usize| dist2(p, &kernels.centers[k]) < kernels.radii[k].powi(2);
        let mut outside = 0;
        for k in ids.clone().filter(|&k| !reaches(k)).take(NEAREST) {
            grow.insert(k);
            outside += 1;
        }
        if outside == 0 {
            grow.extend(ids.take(NEAREST));
        }
    }
    for &k in &grow {
        kernels.radii[k] *= ENLARGE_FACTOR;
    }
    Ok(grow)
}

/// What [`cover_surface`] did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceCover {
    /// Surface points checked.
    pub points: usize,
    /// Kernels whose supports were grown for them.
    pub enlarged: BTreeSet<usize>,
    /// Surface points still badly covered after the last round.
    pub uncovered: usize,
    /// The worst of those (position, metres; reciprocal condition number of its moment
    /// matrix, 0 when singular), for the warning.
    pub worst: Option<(Point3, f64)>,
}

impl SurfaceCover {
    /// The warning to show when some surface points stay uncovered.
    pub fn warning(&self, rounds: usize) -> Option<String> {
        let (p, rcond) = self.worst?;
        Some(format!(
            "{} of the shape's {} surface points are not covered by enough kernels after {rounds} \
             rounds of support enlargement (worst at [{:.4}, {:.4}, {:.4}], reciprocal condition \
             number {rcond:.1e}): the basis cannot be evaluated there; increase the support factor \
             (--support) or the number of kernels",
            self.uncovered, self.points, p[0], p[1], p[2]
        ))
    }
}

/// Repair the coverage of `shape`'s surface ([`Shape::surface_probes`] at half the bulk kernel
/// spacing of `volume`, m^3: several points between neighbouring kernels, so no gap on the
/// surface goes unchecked) with [`cover_surface`]; nothing to do without a shape (given points).
pub fn cover_shape_surface(
    kernels: &mut Kernels,
    shape: Option<&Shape>,
    volume: f64,
    opts: &BasisOptions,
) -> Result<SurfaceCover> {
    let probes = shape.map_or_else(Vec::new, |s| {
        s.surface_probes(0.5 * bulk_spacing(volume, opts.kernels))
    });
    cover_surface(kernels, &probes, opts)
}

/// Repair the coverage of `probes` (surface points, N x 3, metres) for up to
/// `opts.coverage_repair_rounds` rounds: each round evaluates the shape functions at every
/// probe (in Morton-ordered chunks, so memory holds one chunk's) and grows the supports of the
/// kernels nearest the badly covered ones. Deterministic (the same on every MPI rank). Probes
/// that stay badly covered are counted, not an error: the basis may never be evaluated there.
pub fn cover_surface(
    kernels: &mut Kernels,
    probes: &[Point3],
    opts: &BasisOptions,
) -> Result<SurfaceCover> {
    let mut out = SurfaceCover {
        points: probes.len(),
        ..SurfaceCover::default()
    };
    if probes.is_empty() {
        return Ok(out);
    }
    let mut order: Vec<usize> = (0..probes.len()).collect();
    morton_order(probes, &mut order);
    let sorted: Vec<Point3> = order.iter().map(|&i| probes[i]).collect();
    for round in 0..=opts.coverage_repair_rounds {
        let mut stats = ChunkedStats::default();
        for (c, chunk) in sorted.chunks(CHUNK_POINTS).enumerate() {
            let (sf, st, _) = evaluate_chunk(kernels, chunk, &opts.shape_functions);
            stats.add(&sf, &st, |i| c * CHUNK_POINTS + i);
        }
        let stats = stats.stats();
        if stats.failed.is_empty() {
            return Ok(out);
        }
        let failed: Vec<Point3> = stats.failed.iter().map(|&i| sorted[i]).collect();
        if round == opts.coverage_repair_rounds {
            out.uncovered = failed.len();
            out.worst = Some((sorted[stats.min_rcond_point], stats.min_rcond));
            return Ok(out);
        }
        out.enlarged.extend(enlarge_near(kernels, &failed)?);
    }
    Ok(out)
}
