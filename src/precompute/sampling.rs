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
            .volumes
            .iter()
            .position(|v| !(v.is_finite() && *v > 0.0))
        {
            return Err(Error::param(
                "volumes",
                format!("{} at point {i}", self.volumes[i]),
                "every integration volume must be positive and finite",
            ));
        }
        Ok(())
    }
}

/// Most grid cells a bounding box may be cut into (guards against a tiny spacing on a big box
/// exhausting memory): 2^31, ~50 GB of candidate points.
pub const MAX_GRID_CELLS: u128 = 1 << 31;

/// Grid cell centres over `aabb` at spacing about `h` (each axis gets round(L / h) >= 1 cells
/// of exactly L / n, so the cells tile the box), kept where `inside` is true. Volumes are the
/// cell volumes, rescaled to `exact_volume` when given.
pub fn grid_points(
    aabb: &Aabb,
    h: f64,
    exact_volume: Option<f64>,
    inside: &(dyn Fn(&[Point3]) -> Vec<bool> + Sync),
) -> Result<IntegrationPoints> {
    let mut n = [0usize; 3];
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
        n[d] = ((len / h).round() as usize).max(1);
        step[d] = len / n[d] as f64;
    }
    let cells = n.iter().map(|&v| v as u128).product::<u128>();
    if cells > MAX_GRID_CELLS {
        return Err(Error::param("spacing", h, format!("gives {cells} grid cells over the bounding box; use a larger spacing or fewer points")));
    }
    let cell_volume = step[0] * step[1] * step[2];
    // One z-slab at a time keeps memory at the kept points plus one slab of candidates.
    let slabs: Vec<Vec<Point3>> = (0..n[2])
        .into_par_iter()
        .map(|k| {
            let z = aabb.min[2] + (k as f64 + 0.5) * step[2];
            let cand: Vec<Point3> = (0..n[1])
                .flat_map(|j| {
                    let y = aabb.min[1] + (j as f64 + 0.5) * step[1];
                    (0..n[0]).map(move |i| [aabb.min[0] + (i as f64 + 0.5) * step[0], y, z])
                })
                .collect();
            let keep = inside(&cand);
            cand.into_iter()
                .zip(keep)
                .filter_map(|(p, k)| k.then_some(p))
                .collect()
        })
        .collect();
    let points: Vec<Point3> = slabs.into_iter().flatten().collect();
    if points.is_empty() {
        return Err(Error::param(
            "spacing",
            h,
            "no grid point falls inside the shape; use a smaller spacing or more points",
        ));
    }
    let v = match exact_volume {
        Some(vol) => vol / points.len() as f64,
        None => cell_volume,
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

fn median_nn_distance(points: &[Point3]) -> Result<f64> {
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
        let reason = if extent > 0.0 {
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
            let size = [
                aabb.max[0] - aabb.min[0],
                aabb.max[1] - aabb.min[1],
                aabb.max[2] - aabb.min[2],
            ];
            let vol = exact.unwrap_or(size[0] * size[1] * size[2]);
            let h = resolution.spacing(vol)?;
            let inside = |p: &[Point3]| solid.contains(p).unwrap_or_else(|| vec![true; p.len()]);
            grid_points(&aabb, h, exact, &inside)
        }
    }
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
