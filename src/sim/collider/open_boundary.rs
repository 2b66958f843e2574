//! The open boundary of a one-sided surface collider (an open container's rim, the edge of a
//! terrain): beyond it the surface continues as the planes of its boundary triangles, so a
//! point's penetration is continuous where it crosses those planes.
//!
//! Why: the pseudo-normal test alone puts a point above a container's rim and just outside
//! its wall behind the rim edge by its whole distance to that edge, and a point just inside
//! in front of it: the penalty jumped by the point's height above the rim as it crossed the
//! wall's plane, and a Newton line search cannot pass such a jump (docs/performance.md, the
//! 64-object pour). Measured from the boundary triangle's plane instead, the depth starts at
//! zero on that plane and equals the face's own depth where the face's region begins.

use super::penetration::Penetration;
use crate::geometry::boundary_edges;
use crate::linalg3::{cross, dot, identity_minus_outer, norm, sub};
use crate::Point3;
use std::collections::HashMap;

/// The boundary edges (edges of one triangle) of a triangle mesh and their triangles.
#[derive(Debug, Clone)]
pub(super) struct OpenBoundary {
    /// Each boundary edge (smaller vertex index first) and its triangle.
    edges: HashMap<(u32, u32), u32>,
    /// Each vertex on the boundary and the triangles of its boundary edges.
    vertices: HashMap<u32, Vec<u32>>,
}

fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

impl OpenBoundary {
    /// The boundary of the triangles `triangles` (F x 3 vertex indices).
    pub(super) fn of(triangles: &[[u32; 3]]) -> OpenBoundary {
        let open = boundary_edges(triangles);
        let mut vertices: HashMap<u32, Vec<u32>> = HashMap::new();
        for &(a, b, t) in &open {
            for v in [a, b] {
                vertices.entry(v).or_default().push(t);
            }
        }
        let edges = open.into_iter().map(|(a, b, t)| ((a, b), t)).collect();
        // Keep each list in triangle order so that ties between planes resolve the same way
        // whatever the mesh's edge order.
        for list in vertices.values_mut() {
            list.sort_unstable();
            list.dedup();
        }
        OpenBoundary { edges, vertices }
    }

    /// Number of boundary edges (0 for a closed mesh).
    pub(super) fn edges(&self) -> usize {
        self.edges.len()
    }

    /// The triangle of the edge (a, b) if it is a boundary edge.
    pub(super) fn edge_planes(&self, a: u32, b: u32) -> Option<&[u32]> {
        self.edges.get(&key(a, b)).map(std::slice::from_ref)
    }

    /// The triangles of the boundary edges at vertex `v` if it is on the boundary.
    pub(super) fn vertex_planes(&self, v: u32) -> Option<&[u32]> {
        self.vertices.get(&v).map(Vec::as_slice)
    }
}

/// A plane of a boundary triangle: a point on it (the boundary vertex the planes of one
/// query share) and its unit normal towards the free side (metres), and the triangle's
/// centroid (which side of another plane the triangle lies on).
#[derive(Debug, Clone, Copy)]
pub(super) struct Plane {
    pub(super) on: Point3,
    pub(super) normal: [f64; 3],
    pub(super) centroid: Point3,
}

impl Plane {
    /// How far `y` is behind the plane, metres (negative in front).
    fn depth(&self, y: &Point3) -> f64 {
        dot(&sub(&self.on, y), &self.normal)
    }
}

/// Below this |n1 x n2| two planes count as parallel (one plane).
const PARALLEL: f64 = 1e-9;

/// The penetration of `y` beyond the open boundary, where the surface continues as `planes`
/// (one plane at a boundary edge, usually two at a boundary vertex): the distance from `y`
/// to the free region, None when `y` is in it. One plane: the depth behind it. Two: the
/// free region is the wedge in front of both when each triangle lies in front of the
/// other's plane (a container's rim corner), else the union of the two fronts; the distance
/// to either is exact, so the depth is continuous, and it equals the distance to the wall
/// edge that ends at the vertex where the walls meet along a straight edge (a prism's).
/// More planes (a vertex where several open edges meet): the deepest plane's depth.
pub(super) fn behind_planes(y: &Point3, planes: &[Plane]) -> Option<Penetration> {
    let flat = |p: &Plane| {
        let d = p.depth(y);
        (d > 0.0).then(|| Penetration::flat(d, p.normal))
    };
    match planes {
        [] => None,
        [one] => flat(one),
        [p1, p2] => {
            let axis = cross(&p1.normal, &p2.normal);
            if norm(&axis) < PARALLEL {
                return deepest(y, planes);
            }
            let (d1, d2) = (p1.depth(y), p2.depth(y));
            let c = dot(&p1.normal, &p2.normal);
            if p2.depth(&p1.centroid) < 0.0 && p1.depth(&p2.centroid) < 0.0 {
                // The free region is the wedge in front of both: the nearest point of it is
                // y itself, its projection onto one plane (if in front of the other), or on
                // the line where the planes meet. Projecting y onto plane 1 changes its
                // depth behind plane 2 to d2 - d1 c.
                if d1 <= 0.0 && d2 <= 0.0 {
                    None
                } else if d1 > 0.0 && d2 - d1 * c <= 0.0 {
                    flat(p1)
                } else if d2 > 0.0 && d1 - d2 * c <= 0.0 {
                    flat(p2)
                } else {
                    let u = axis.map(|v| v / norm(&axis));
                    let w = sub(y, &p1.on);
                    let along = dot(&w, &u);
                    let across: [f64; 3] = std::array::from_fn(|k| w[k] - along * u[k]);
                    let depth = norm(&across);
                    // Distance to a line: the Hessian of d^2/2 is the projector across it.
                    let h = identity_minus_outer(&u);
                    (depth > 0.0).then(|| Penetration {
                        depth,
                        normal: across.map(|v| -v / depth),
                        hessian: h,
                        hessian_psd: h,
                    })
                }
            } else {
                // The union of the two fronts: the nearer of the two.
                let d = d1.min(d2);
                (d > 0.0).then(|| {
                    let p = if d1 <= d2 { p1 } else { p2 };
                    Penetration::flat(d, p.normal)
                })
            }
        }
        _ => deepest(y, planes),
    }
}

/// The depth behind the deepest of `planes`.
fn deepest(y: &Point3, planes: &[Plane]) -> Option<Penetration> {
    let mut best: Option<(f64, [f64; 3])> = None;
    for p in planes {
        let d = p.depth(y);
        if d > 0.0 && best.is_none_or(|(b, _)| d > b) {
            best = Some((d, p.normal));
        }
    }
    best.map(|(d, n)| Penetration::flat(d, n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_open_box_has_its_rim_as_boundary() {
        // The five faces of a unit box without its top (y = 1), two triangles each.
        let (v, t) = crate::geometry::generate::box_mesh([1.0, 1.0, 1.0]);
        let top: Vec<usize> = (0..t.len())
            .filter(|&f| t[f].iter().all(|&i| v[i as usize][1] > 0.0))
            .collect();
        assert_eq!(top.len(), 2);
        let open: Vec<[u32; 3]> = (0..t.len())
            .filter(|f| !top.contains(f))
            .map(|f| t[f])
            .collect();
        let b = OpenBoundary::of(&open);
        assert_eq!(b.edges(), 4);
        // Every rim corner joins two rim edges, of two different walls.
        for (i, p) in v.iter().enumerate() {
            let planes = b.vertex_planes(i as u32);
            if p[1] > 0.0 {
                let planes = planes.expect("a rim vertex");
                assert_eq!(planes.len(), 2, "{p:?}");
            } else {
                assert!(planes.is_none(), "{p:?}");
            }
        }
        assert_eq!(OpenBoundary::of(&t).edges(), 0);
    }

    #[test]
    fn the_depth_beyond_a_rim_corner_is_the_distance_to_the_free_wedge() {
        // Two walls of a container meeting at x = z = 0 (free side x < 0 and z < 0).
        let wall = |normal: [f64; 3], centroid: Point3| Plane {
            on: [0.0; 3],
            normal,
            centroid,
        };
        let planes = [
            wall([-1.0, 0.0, 0.0], [0.0, 0.5, -0.5]),
            wall([0.0, 0.0, -1.0], [-0.5, 0.5, 0.0]),
        ];
        let p = behind_planes(&[0.2, 5.0, -0.1], &planes).unwrap();
        assert_eq!(p.depth, 0.2);
        assert_eq!(p.normal, [-1.0, 0.0, 0.0]);
        // Behind both: the distance to the corner line (the y axis).
        let p = behind_planes(&[0.3, 5.0, 0.4], &planes).unwrap();
        assert!((p.depth - 0.5).abs() < 1e-15, "{}", p.depth);
        assert!((p.normal[0] + 0.6).abs() < 1e-15 && (p.normal[2] + 0.8).abs() < 1e-15);
        assert!(behind_planes(&[-0.1, 5.0, -0.3], &planes).is_none());
        assert!(behind_planes(&[0.0, 5.0, -0.3], &planes).is_none());
        // A dome's rim (each triangle behind the other's plane): the union of the fronts.
        let dome = [
            wall([-1.0, 0.0, 0.0], [0.0, 0.5, 0.5]),
            wall([0.0, 0.0, -1.0], [0.5, 0.5, 0.0]),
        ];
        let p = behind_planes(&[0.3, 5.0, 0.4], &dome).unwrap();
        assert_eq!(p.depth, 0.3);
        assert!(behind_planes(&[0.3, 5.0, -0.4], &dome).is_none());
    }
}
