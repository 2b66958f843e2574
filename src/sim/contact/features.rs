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
fn box_candidates(l: &[f64; 3], step: f64) -> Vec<Point3> {
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

    /// Ordinary samples as the box sampler places them: a lattice about t apart on each face
    /// of the box [0, l], clamped t inside.
    fn lattice(l: &[f64; 3], t: f64) -> Vec<Point3> {
        let mut centres = Vec::new();
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let (nu, nv) = ((l[u] / t) as usize, (l[v] / t) as usize);
            for side in [0.0, l[axis]] {
                for iu in 0..nu {
                    for iv in 0..nv {
                        let mut p = [0.0; 3];
                        p[axis] = side;
                        p[u] = (iu as f64 + 0.5) * l[u] / nu as f64;
                        p[v] = (iv as f64 + 0.5) * l[v] / nv as f64;
                        centres.push(std::array::from_fn(|d| p[d].clamp(t, l[d] - t)));
                    }
                }
            }
        }
        centres
    }

    /// Every point of a box's edges is within 3/4 of the spacing of a feature point, every
    /// corner is one, and every feature point lies on an edge.
    #[test]
    fn box_edges_are_covered_by_feature_points() {
        let l = [0.3, 0.2, 0.1];
        let t = 0.01;
        let centres = lattice(&l, t);
        let spacing = 0.5 * t;
        let r = 0.75 * spacing;
        let f = feature_points(&Shape::Box { size: l }, &centres, t, spacing).unwrap();
        assert!(!f.is_empty());
        // Every corner is a feature centre.
        for c in &box_candidates(&l, 1.0)[..8] {
            assert!(f.iter().any(|p| p == c), "corner {c:?}");
        }
        // Dense points on the edges: each within r of a kept point (the greedy keeps a
        // candidate, walking along the edge, unless a kept one lies within r; a point
        // between two candidates is nearer than the next candidate to every kept point
        // behind it).
        for p in box_candidates(&l, 0.1 * r) {
            let best = f
                .iter()
                .map(|q| (0..3).map(|d| (p[d] - q[d]).powi(2)).sum::<f64>().sqrt())
                .fold(f64::INFINITY, f64::min);
            assert!(best <= r * (1.0 + 1e-9), "{p:?}: {best}");
        }
        // Every feature lies on an edge: two of its coordinates on the box's faces.
        for p in &f {
            let on = (0..3)
                .filter(|&d| p[d].abs() < 1e-12 || (p[d] - l[d]).abs() < 1e-12)
                .count();
            assert!(on >= 2, "{p:?}");
        }
    }

    /// A cube given as a mesh (two triangles a face): its corners are feature points and
    /// every feature point lies on an edge, or on a face diagonal (a mesh edge too) within t
    /// of a corner, where the face itself stands out of the samples clamped t inside.
    #[test]
    fn a_mesh_cube_gets_features_on_its_edges_and_corners() {
        let (v, f) = crate::geometry::generate::box_mesh([1.0, 1.0, 1.0]);
        let mesh =
            crate::geometry::TriMesh::new(v, f, &crate::geometry::ShapeOptions::default()).unwrap();
        let t = 0.04;
        let centres = lattice(&[1.0; 3], t);
        let f = feature_points(&Shape::Mesh(mesh), &centres, t, 0.5 * t).unwrap();
        for c in box_candidates(&[1.0; 3], 1.0).iter().take(8) {
            assert!(f.iter().any(|p| p == c), "corner {c:?}");
        }
        for p in &f {
            let on = (0..3)
                .filter(|&d| p[d].abs() < 1e-12 || (p[d] - 1.0).abs() < 1e-12)
                .count();
            let corner = (0..3)
                .map(|d| p[d].min(1.0 - p[d]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(on >= 2 || corner <= t, "{p:?}");
        }
        // About 12 edges / (0.75-1 spacing) points each.
        assert!((12 * 50..=12 * 70).contains(&f.len()), "{}", f.len());
    }

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
