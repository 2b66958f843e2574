//! Feature samples: points on an object's convex edges and corners. The ordinary samples sit
//! a thickness t inside the surface, so a box corner stands t (sqrt 3 - 1) and an edge
//! t (sqrt 2 - 1) past their spheres, and sinks that far into a neighbour before any sample
//! touches it. A sample of radius 0 on the edge itself is pushed out of the neighbour's
//! spheres as soon as it enters them, so the edge stays out without standing off the faces
//! beside it (a sphere around the edge would hold them a gap apart). Two such points never
//! touch each other (their contact distance is 0); an edge meeting an edge is held by each
//! one's points against the other's spheres.

use crate::geometry::Shape;
use crate::Point3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use std::collections::HashMap;

/// A surface point is an edge or corner point when it stands more than this many
/// thicknesses t past the ordinary samples' envelope. A flat face between samples a spacing
/// apart stands out at most about 0.3 t (the centre of a lattice cell, sqrt(t^2 + s^2 / 2) - t
/// for s = t, plus a low-discrepancy sequence's larger holes), a right-angled edge 0.41-0.5 t
/// and a cube corner 0.73 t.
pub const FEATURE_PROTRUSION: f64 = 0.3;

/// The spacing of feature samples along an edge that docs/performance.md measures, as a
/// fraction of the thickness t (a scene's `contact.feature_spacing`; the default is 0, none):
/// a neighbour's sphere (radius t) reaches between two of them by at most
/// t - sqrt(t^2 - (s / 2)^2), t / 32 for s = t / 2.
pub const MEASURED_FEATURE_SPACING: f64 = 0.5;

/// Most candidate points [`feature_points`] walks: 4 million (about 100 MB).
pub const MAX_FEATURE_CANDIDATES: usize = 4_000_000;

/// Feature sample positions for `shape` (rest frame, metres): points of its corners and
/// edges that stand more than [`FEATURE_PROTRUSION`] t past the spheres of radius `t`
/// centred at `centres`, kept greedily (corners first) at most `spacing` metres apart along
/// each edge. Spheres have none.
///
/// # Errors
/// The number of candidate points when it would exceed [`MAX_FEATURE_CANDIDATES`] (edges
/// very long against the spacing).
pub fn feature_points(
    shape: &Shape,
    centres: &[Point3],
    t: f64,
    spacing: f64,
) -> Result<Vec<Point3>, usize> {
    // Candidates a quarter spacing apart; one is kept unless a kept point lies within
    // three quarters of the spacing, so kept points along an edge are 0.75-1 spacing apart.
    let step = 0.25 * spacing;
    let radius = 0.75 * spacing;
    let candidates = match shape {
        Shape::Box { size } => {
            let count = 8.0 + 4.0 * size.iter().map(|l| (l / step).ceil()).sum::<f64>();
            check_candidates(count)?;
            box_candidates(size, step)
        }
        Shape::Mesh(m) => mesh_candidates(m.vertices(), m.triangles(), step)?,
        Shape::Sphere { .. } | Shape::PointCloud(_) | Shape::Image(_) => return Ok(Vec::new()),
    };
    let Ok(tree) = ImmutableKdTree::<f64, 3>::new_from_slice(centres) else {
        return Ok(Vec::new());
    };
    let mut kept = CellGrid::new(radius);
    let mut out = Vec::new();
    for p in candidates {
        let nearest = tree
            .query(&p)
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute()
            .distance
            .sqrt();
        if nearest - t <= FEATURE_PROTRUSION * t || kept.covers(&p, &out) {
            continue;
        }
        kept.insert(&p, out.len());
        out.push(p);
    }
    Ok(out)
}

/// `count` candidates (a float: it may not fit an integer) if within
/// [`MAX_FEATURE_CANDIDATES`], else the error [`feature_points`] returns.
fn check_candidates(count: f64) -> Result<(), usize> {
    if count <= MAX_FEATURE_CANDIDATES as f64 {
        Ok(())
    } else {
        Err(count.min(usize::MAX as f64) as usize)
    }
}

/// The 8 corners, then points `step` apart (at most) along the 12 edges of the box [0, l].
pub(super) fn box_candidates(l: &[f64; 3], step: f64) -> Vec<Point3> {
    let mut out: Vec<Point3> = (0..8)
        .map(|c| std::array::from_fn(|d| if c >> d & 1 == 1 { l[d] } else { 0.0 }))
        .collect();
    for axis in 0..3 {
        let n = ((l[axis] / step).ceil() as usize).max(1);
        for c in 0..4 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for k in 1..n {
                let mut p = [0.0; 3];
                p[axis] = k as f64 * l[axis] / n as f64;
                p[u] = if c & 1 == 1 { l[u] } else { 0.0 };
                p[v] = if c & 2 == 2 { l[v] } else { 0.0 };
                out.push(p);
            }
        }
    }
    out
}

/// A mesh's vertices, then points `step` apart (at most) along each of its edges (inner
/// points only, each edge once).
fn mesh_candidates(v: &[Point3], tris: &[[u32; 3]], step: f64) -> Result<Vec<Point3>, usize> {
    let mut edges: Vec<(u32, u32)> = tris
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let length = |&(a, b): &(u32, u32)| {
        let (p, q) = (v[a as usize], v[b as usize]);
        (0..3).map(|d| (q[d] - p[d]).powi(2)).sum::<f64>().sqrt()
    };
    let inner = |e: &(u32, u32)| (length(e) / step).ceil().max(1.0) - 1.0;
    check_candidates(v.len() as f64 + edges.iter().map(inner).sum::<f64>())?;
    let mut out: Vec<Point3> = v.to_vec();
    for (a, b) in edges {
        let (p, q) = (v[a as usize], v[b as usize]);
        let n = (length(&(a, b)) / step).ceil() as usize;
        for k in 1..n {
            let s = k as f64 / n as f64;
            out.push(std::array::from_fn(|d| p[d] + s * (q[d] - p[d])));
        }
    }
    Ok(out)
}

/// Kept feature points hashed into cells of one radius, to ask whether a point lies within
/// that radius of any of them.
struct CellGrid {
    radius: f64,
    cells: HashMap<[i64; 3], Vec<usize>>,
}

impl CellGrid {
    fn new(radius: f64) -> CellGrid {
        CellGrid {
            radius,
            cells: HashMap::new(),
        }
    }

    fn cell(&self, p: &Point3) -> [i64; 3] {
        p.map(|x| (x / self.radius).floor() as i64)
    }

    fn insert(&mut self, p: &Point3, index: usize) {
        let c = self.cell(p);
        self.cells.entry(c).or_default().push(index);
    }

    /// Whether a kept centre (in `points`) lies within the radius of `p`.
    fn covers(&self, p: &Point3, points: &[Point3]) -> bool {
        let c = self.cell(p);
        let r2 = self.radius * self.radius;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = self.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    if list
                        .iter()
                        .any(|&i| (0..3).map(|d| (points[i][d] - p[d]).powi(2)).sum::<f64>() <= r2)
                    {
                        return true;
                    }
                }
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Edges far longer than the spacing are refused with the candidate count, not walked.
    #[test]
    fn too_many_candidates_are_refused() {
        let e = feature_points(&Shape::Box { size: [1e3; 3] }, &[[0.0; 3]], 1e-4, 1e-4);
        assert!(matches!(e, Err(n) if n > MAX_FEATURE_CANDIDATES), "{e:?}");
    }

    /// A sphere has no edge or corner.
    #[test]
    fn a_sphere_has_no_features() {
        let f = feature_points(&Shape::Sphere { radius: 1.0 }, &[[0.0; 3]], 0.1, 0.05).unwrap();
        assert!(f.is_empty());
    }
}
