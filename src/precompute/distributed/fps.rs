//! Kernel placement across ranks: the one-process [`crate::precompute::place_kernels`], bit for
//! bit, while each rank holds only its part of the points.
//!
//! Farthest point sampling is a sequence of global decisions: each rank keeps its points'
//! distances to the centres so far ([`FarthestPoints`]), offers its farthest point, and one
//! [`arg_max`] per centre picks the farthest of all (the lowest global index on ties, as the
//! one-process sampling breaks them) and hands its position to every rank. The first centre is
//! the point farthest from the centroid, which the ranks sum in the one-process order: each
//! continues the running sum of the rank before it (the points of rank r follow those of rank
//! r - 1), so the centroid is the same f64 as in one process.

use super::collective::{agree, arg_max, Collective};
use super::partition::PointPart;
use crate::eigen::block_range;
use crate::precompute::centers::{FarthestPoints, MortonFrame};
use crate::precompute::density::{check_regions_hold_points, kernel_scale_part};
use crate::precompute::rkpm::{support_radii, Kernels};
use crate::precompute::BasisOptions;
use crate::progress::Progress;
use crate::{Error, Point3, Result};

/// The kernels of `opts` (centres by farthest point sampling of all ranks' points, Morton
/// order, support radii) on every rank: the same as the one-process placement over the points
/// of all the `part`s. Collective.
///
/// # Errors
/// As [`crate::precompute::place_kernels`], on every rank alike; [`Error::InvalidParameter`]
/// for more ranks than kernels.
pub fn place_kernels_parts(
    part: &PointPart,
    opts: &BasisOptions,
    comm: &dyn Collective,
    progress: &dyn Progress,
) -> Result<Kernels> {
    let (k, n) = (opts.kernels, part.total);
    if n < k {
        return Err(Error::param(
            "kernels",
            k,
            format!("only {n} integration points; use fewer kernels or more points"),
        ));
    }
    if k < comm.size() {
        return Err(Error::param(
            "kernels",
            k,
            format!(
                "fewer kernels than the {} MPI ranks: every rank owns a block of kernels; use \
                 more kernels or fewer ranks",
                comm.size()
            ),
        ));
    }
    let finite = crate::error::check_finite_points("integration points", &part.points);
    agree(comm, "kernel placement (finite points)", finite)?;
    let points = &part.points;

    // The centroid, summed in the one-process order: rank r continues rank r - 1's sum.
    let total = n as f64;
    let mut centroid = [0.0; 3];
    for r in 0..comm.size() {
        if r == comm.rank() {
            for p in points {
                for d in 0..3 {
                    centroid[d] += p[d] / total;
                }
            }
        }
        comm.broadcast(&mut centroid, r)?;
    }
    let mut best = (f64::NEG_INFINITY, 0usize);
    for (i, p) in points.iter().enumerate() {
        let d = dist2(p, &centroid);
        if d > best.0 {
            best = (d, i);
        }
    }
    // The density's scale is local to each point (the distances to the boundary regions);
    // interface and thin-part refinement, which need a point's neighbours, are refused here.
    let scale = kernel_scale_part(
        points,
        part.volume(),
        k,
        &opts.density,
        &opts.boundary_regions,
        None,
    );
    let scale = agree(comm, "kernel density", scale)?;
    if let Some((_, held)) = &scale {
        let mut total: Vec<f64> = held.iter().map(|&n| n as f64).collect();
        comm.sum(&mut total)?;
        let held: Vec<usize> = total.iter().map(|&n| n as usize).collect();
        check_regions_hold_points(&opts.density.regions, &held)?;
    }
    let scale = scale.map(|(s, _)| s);
    // A point's offer: its position and its scale (1 without a density).
    let offer = |i: usize| {
        let p = points.get(i).copied().unwrap_or([0.0; 3]);
        let s = scale
            .as_ref()
            .and_then(|s| s.get(i).copied())
            .unwrap_or(1.0);
        [p[0], p[1], p[2], s]
    };
    let (_, first, [x, y, z, first_scale]) =
        arg_max(comm, best.0, part.first + best.1, offer(best.1))?;
    let first_at = [x, y, z];
    let mut state = FarthestPoints::with_scale(points, scale.as_deref(), &first_at, first_scale);
    let mut chosen = vec![(first, first_at)];
    progress.begin("centers", Some(k as u64));
    while chosen.len() < k {
        let (d, i) = state.farthest().unwrap_or((f64::NEG_INFINITY, 0));
        let (d_max, index, [x, y, z, c_scale]) = arg_max(comm, d, part.first + i, offer(i))?;
        let c = [x, y, z];
        if d_max.is_nan() || d_max <= 0.0 {
            progress.finish();
            return Err(Error::param(
                "kernels",
                k,
                format!(
                    "the points hold only {} distinct positions; use at most {} kernels",
                    chosen.len(),
                    chosen.len()
                ),
            ));
        }
        chosen.push((index, c));
        state.add_center(&c, c_scale, d_max);
        if chosen.len() % 4096 == 0 {
            progress.set_position(chosen.len() as u64);
        }
    }
    progress.finish();

    // Morton order of the centres in their own frame, ties by point index (as one process).
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for (_, c) in &chosen {
        for d in 0..3 {
            lo[d] = lo[d].min(c[d]);
            hi[d] = hi[d].max(c[d]);
        }
    }
    let frame = MortonFrame::from_bounds(lo, hi);
    let mut keyed: Vec<(u64, usize, Point3)> = chosen
        .into_iter()
        .map(|(i, c)| (frame.code(&c), i, c))
        .collect();
    keyed.sort_unstable_by_key(|&(code, i, _)| (code, i));
    let centers: Vec<Point3> = keyed.into_iter().map(|(_, _, c)| c).collect();
    let radii = support_radii(&centers, &opts.support)?;
    Ok(Kernels {
        centers,
        radii,
        kind: opts.kernel,
    })
}

/// This rank's block of the kernels (Morton order, so spatially compact): its rows of H_w and
/// M.
pub fn own_kernels(k: usize, comm: &dyn Collective) -> std::ops::Range<usize> {
    block_range(k, comm.rank(), comm.size())
}

#[inline]
fn dist2(a: &Point3, b: &Point3) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

#[cfg(test)]
mod tests {
    use super::super::collective::run_ranks;
    use super::super::partition::sample_part;
    use super::*;
    use crate::geometry::Shape;
    use crate::precompute::sampling::Resolution;
    use crate::precompute::{place_kernels, sample_with_material};
    use crate::progress::Silent;

    #[test]
    fn the_ranks_place_the_one_process_kernels_bit_for_bit() {
        // A box has many exact distance ties (grid points), a sphere few.
        for shape in [
            Shape::Box {
                size: [2.0, 1.0, 0.5],
            },
            Shape::Sphere { radius: 0.7 },
        ] {
            let opts = BasisOptions {
                kernels: 120,
                resolution: Some(Resolution::Count(4000)),
                ..BasisOptions::default()
            };
            let (whole, _) = sample_with_material(&shape, &opts).unwrap();
            let want = place_kernels(&whole.points, None, &opts).unwrap();
            for size in [1, 2, 3, 4] {
                let got = run_ranks(size, |c| {
                    let part = sample_part(&shape, &opts, c).unwrap();
                    place_kernels_parts(&part, &opts, c, &Silent).unwrap()
                });
                for kernels in got {
                    assert_eq!(kernels.centers, want.centers, "P = {size}");
                    assert_eq!(kernels.radii, want.radii, "P = {size}");
                }
            }
        }
    }

    #[test]
    fn the_ranks_place_the_one_process_kernels_with_a_density_too() {
        use crate::material::Region;
        use crate::precompute::density::{kernel_scale, DensityBands, DensityRegion, WholeObject};
        use crate::precompute::KernelDensity;
        let shape = Shape::Box {
            size: [2.0, 1.0, 0.5],
        };
        let held = Region::HalfSpace {
            point: [0.4, 0.0, 0.0],
            normal: [-1.0, 0.0, 0.0],
        };
        let opts = BasisOptions {
            kernels: 150,
            resolution: Some(Resolution::Count(4000)),
            boundary_regions: vec![held],
            density: KernelDensity {
                bands: DensityBands {
                    boundaries: 2.0,
                    ..DensityBands::off()
                },
                regions: vec![DensityRegion {
                    region: Region::Sphere {
                        center: [1.6, 0.5, 0.25],
                        radius: 0.3,
                    },
                    factor: 1.5,
                }],
            },
            ..BasisOptions::default()
        };
        let (whole, material) = sample_with_material(&shape, &opts).unwrap();
        let volume: f64 = whole.volumes.iter().sum();
        let scale = kernel_scale(
            &whole.points,
            volume,
            opts.kernels,
            &opts.density,
            &opts.boundary_regions,
            Some(WholeObject {
                material: &material,
                volumes: &whole.volumes,
            }),
        )
        .unwrap();
        let want = place_kernels(&whole.points, scale.as_deref(), &opts).unwrap();
        // The band around x = 0.4 (h0 = (1 / 150)^(1/3) = 0.19 m) holds more kernels than
        // uniform placement puts there: twice as fine is up to 8x per volume.
        let uniform = place_kernels(&whole.points, None, &opts).unwrap();
        let in_band = |k: &crate::precompute::rkpm::Kernels| {
            k.centers
                .iter()
                .filter(|c| (c[0] - 0.4).abs() < 0.19)
                .count()
        };
        assert!(
            in_band(&want) > 2 * in_band(&uniform),
            "{} vs {}",
            in_band(&want),
            in_band(&uniform)
        );
        for size in [1, 3] {
            let got = run_ranks(size, |c| {
                let part = sample_part(&shape, &opts, c).unwrap();
                place_kernels_parts(&part, &opts, c, &Silent).unwrap()
            });
            for kernels in got {
                assert_eq!(kernels, want, "P = {size}");
            }
        }
        // Interface refinement needs a point's neighbours: refused on every rank.
        let interfaces = BasisOptions {
            density: KernelDensity::bands(DensityBands {
                interfaces: 2.0,
                ..DensityBands::off()
            }),
            ..opts
        };
        let errors = run_ranks(2, |c| {
            let part = sample_part(&shape, &interfaces, c).unwrap();
            place_kernels_parts(&part, &interfaces, c, &Silent).unwrap_err()
        });
        for e in errors {
            assert!(e.to_string().contains("across MPI ranks"), "{e}");
        }
    }

    #[test]
    fn too_few_points_or_kernels_fail_on_every_rank() {
        let shape = Shape::Box { size: [1.0; 3] };
        let opts = BasisOptions {
            kernels: 10,
            resolution: Some(Resolution::Count(8)),
            ..BasisOptions::default()
        };
        let errors = run_ranks(3, |c| {
            let part = sample_part(&shape, &opts, c).unwrap();
            place_kernels_parts(&part, &opts, c, &Silent)
                .unwrap_err()
                .to_string()
        });
        assert!(
            errors.iter().all(|e| e.contains("integration points")),
            "{errors:?}"
        );
        let opts = BasisOptions {
            kernels: 10,
            resolution: Some(Resolution::Count(400)),
            ..BasisOptions::default()
        };
        let errors = run_ranks(12, |c| {
            let part = sample_part(&shape, &opts, c).unwrap();
            place_kernels_parts(&part, &opts, c, &Silent)
                .unwrap_err()
                .to_string()
        });
        assert!(
            errors
                .iter()
                .all(|e| e.contains("fewer kernels than the 12 MPI ranks")),
            "{errors:?}"
        );
    }
}
