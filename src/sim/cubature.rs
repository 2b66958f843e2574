//! Cubature points for the elastic energy while simulating: a subset of the integration
//! points chosen by farthest point sampling, each carrying the volume of the integration
//! points nearest to it (a Voronoi aggregation), so the volumes still sum to the object volume.

use crate::material::MaterialField;
use crate::precompute::centers::farthest_point_sampling;
use crate::precompute::sampling::IntegrationPoints;
use crate::{Error, Point3, Result};
use kiddo::{ImmutableKdTree, SquaredEuclidean};

/// Default number of cubature points (all integration points if there are fewer).
pub const DEFAULT_CUBATURE: usize = 5000;

/// Most cubature points a scene may ask for: 1,000,000 (200 times the default), a typo
/// guard; each costs about (m + 1) x 100 bytes and is evaluated at every step.
pub const MAX_CUBATURE: usize = 1_000_000;

/// The points at which the elastic energy is evaluated during simulation.
#[derive(Debug, Clone, PartialEq)]
pub struct Cubature {
    /// Rest positions, C x 3, metres.
    pub points: Vec<Point3>,
    /// Volumes, C, m^3 (sum = the integration points' total volume).
    pub volumes: Vec<f64>,
    /// Lame lambda per point, Pa (the material of the chosen integration point).
    pub lambda: Vec<f64>,
    /// Lame mu per point, Pa.
    pub mu: Vec<f64>,
    /// Index of each cubature point among the integration points.
    pub source: Vec<usize>,
}

impl Cubature {
    /// Number of cubature points C.
    pub fn len(&self) -> usize {
        self.points.len()
    }
    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// Choose `count` cubature points among `ip` (all of them when `count >= N`, with their own
/// volumes). Otherwise farthest point sampling picks the points and each integration point's
/// volume goes to its nearest chosen point. Each cubature point keeps the material of the
/// integration point it sits on.
pub fn select(ip: &IntegrationPoints, material: &MaterialField, count: usize) -> Result<Cubature> {
    let n = ip.len();
    if material.len() != n {
        return Err(Error::LengthMismatch {
            what: "material (points)",
            expected: n,
            got: material.len(),
        });
    }
    if count == 0 {
        return Err(Error::param(
            "cubature",
            0,
            "need at least one cubature point (default 5000)",
        ));
    }
    let (source, volumes) = if count >= n {
        ((0..n).collect::<Vec<_>>(), ip.volumes.clone())
    } else {
        let chosen = farthest_point_sampling(&ip.points, count)?;
        let pts: Vec<Point3> = chosen.iter().map(|&i| ip.points[i]).collect();
        let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(&pts)
            .map_err(|e| Error::param("cubature", count, format!("k-d tree: {e:?}")))?;
        let one = std::num::NonZero::new(1).expect("1 > 0");
        let mut volumes = vec![0.0; count];
        for (x, v) in ip.points.iter().zip(&ip.volumes) {
            let nearest = tree
                .query(x)
                .nearest_n::<SquaredEuclidean<f64>>(one)
                .execute();
            let c = nearest.first().map(|r| r.item as usize).unwrap_or(0);
            volumes[c] += v;
        }
        (chosen, volumes)
    };
    let (lambda, mu): (Vec<f64>, Vec<f64>) = source.iter().map(|&i| material.lame(i)).unzip();
    Ok(Cubature {
        points: source.iter().map(|&i| ip.points[i]).collect(),
        volumes,
        lambda,
        mu,
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::Material;

    #[test]
    fn volumes_are_conserved_and_counts_respected() {
        let mut points = Vec::new();
        for i in 0..20 {
            for j in 0..10 {
                for k in 0..5 {
                    points.push([i as f64 * 0.1, j as f64 * 0.1, k as f64 * 0.1]);
                }
            }
        }
        let n = points.len();
        let ip = IntegrationPoints {
            volumes: vec![1e-3; n],
            points,
        };
        let mat = MaterialField::homogeneous(n, &Material::default()).unwrap();
        let c = select(&ip, &mat, 100).unwrap();
        assert_eq!(c.len(), 100);
        // Every integration volume lands on exactly one cubature point.
        let total: f64 = c.volumes.iter().sum();
        assert!((total - ip.total_volume()).abs() < 1e-12);
        assert!(c.volumes.iter().all(|&v| v >= 1e-3));
        let all = select(&ip, &mat, 10 * n).unwrap();
        assert_eq!(all.len(), n);
        assert_eq!(all.volumes, ip.volumes);
        assert!(select(&ip, &mat, 0).is_err());
    }
}
