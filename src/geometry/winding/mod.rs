//! Generalized winding number of a triangle mesh: the exact solid-angle sum and a hierarchical
//! ("fast winding number") evaluation.
//!
//! The winding number of a closed, outward-oriented surface S at a query point q is
//!
//! ```text
//! w(q) = 1/(4 pi) * sum over triangles of Omega_t(q)
//! ```
//!
//! with Omega_t the signed solid angle of triangle t seen from q (Van Oosterom and Strackee,
//! 1983): `tan(Omega/2) = det[a b c] / (|a||b||c| + (a.b)|c| + (b.c)|a| + (c.a)|b|)`, where
//! a, b, c are the triangle's vertices minus q. For a watertight mesh w is 1 inside and 0
//! outside (integer-valued, jumping across the surface); for meshes with holes it varies
//! smoothly and `w >= 0.5` is still a sensible inside test (Jacobson, Kavan and
//! Sorkine-Hornung 2013).
//!
//! [`WindingTree`] evaluates the same sum in O(log F) per query for far regions, following
//! Barill, Dickson, Schmidt, Levin and Jacobson, "Fast Winding Numbers for Soups and Clouds"
//! (2018): a bounding volume hierarchy over triangles stores, per node, a Taylor expansion of
//! the node's contribution about its area-weighted centroid (dipole, quadrupole and octupole
//! terms, see `moments.rs`); a node
//! whose centre is farther than `beta` times its radius from the query is summed by its
//! expansion, closer nodes are opened, and leaves near the query are summed exactly.

mod batch;
mod eval;
mod moments;
mod tree;

pub use tree::{WindingParams, WindingTree};

use crate::Point3;
use rayon::prelude::*;

// The 3-vector helpers of the winding-number code are linalg3's.
pub(crate) use crate::linalg3::{cross, dot, norm, sub};

/// Unit normal of the triangle `(a, b, c)`, `(b - a) x (c - a)` normalized; zero when the
/// triangle has no area.
pub(crate) fn unit_normal(a: &Point3, b: &Point3, c: &Point3) -> Point3 {
    let n = cross(&sub(b, a), &sub(c, a));
    let l = norm(&n);
    if l > 0.0 {
        n.map(|x| x / l)
    } else {
        [0.0; 3]
    }
}

/// Signed solid angle (steradians, in [-2 pi, 2 pi]) of the triangle `(a, b, c)` (metres) seen
/// from `q` (metres); positive when q is on the side the counter-clockwise normal
/// `(b - a) x (c - a)` points away from (the inside of an outward-oriented mesh).
///
/// Van Oosterom-Strackee formula. Returns 0 when q coincides with a vertex or lies in the
/// triangle's plane outside it, and +-2 pi when q lies in the triangle itself.
#[inline]
pub fn solid_angle(a: &Point3, b: &Point3, c: &Point3, q: &Point3) -> f64 {
    let a = sub(a, q);
    let b = sub(b, q);
    let c = sub(c, q);
    let (la, lb, lc) = (norm(&a), norm(&b), norm(&c));
    let det = dot(&a, &cross(&b, &c));
    let den = la * lb * lc + dot(&a, &b) * lc + dot(&b, &c) * la + dot(&c, &a) * lb;
    2.0 * det.atan2(den)
}

/// Exact generalized winding number at `q` (metres): the O(F) solid-angle sum over
/// `triangles` (F x 3 indices into `vertices`, V x 3, metres), divided by 4 pi.
///
/// # Panics
/// If an index is out of range (never for a [`crate::geometry::TriMesh`]'s own arrays).
pub fn winding_number_exact(vertices: &[Point3], triangles: &[[u32; 3]], q: &Point3) -> f64 {
    let sum: f64 = triangles
        .iter()
        .map(|t| {
            solid_angle(
                &vertices[t[0] as usize],
                &vertices[t[1] as usize],
                &vertices[t[2] as usize],
                q,
            )
        })
        .sum();
    sum / (4.0 * std::f64::consts::PI)
}

/// [`winding_number_exact`] for every point of `points` (N x 3, metres), rayon-parallel over
/// points. Costs N x F solid angles: a reference for tests, not for sampling.
pub fn winding_numbers_exact(
    vertices: &[Point3],
    triangles: &[[u32; 3]],
    points: &[Point3],
) -> Vec<f64> {
    points
        .par_iter()
        .map(|q| winding_number_exact(vertices, triangles, q))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn octant_triangle_subtends_one_eighth_of_the_sphere() {
        // The triangle with vertices on the three positive axes, seen from the origin, covers
        // exactly one octant of the view sphere: 4 pi / 8.
        let w = solid_angle(
            &[1.0, 0.0, 0.0],
            &[0.0, 1.0, 0.0],
            &[0.0, 0.0, 1.0],
            &[0.0; 3],
        );
        assert!((w - PI / 2.0).abs() < 1e-14, "{w}");
        // Reversed orientation flips the sign.
        let w = solid_angle(
            &[1.0, 0.0, 0.0],
            &[0.0, 0.0, 1.0],
            &[0.0, 1.0, 0.0],
            &[0.0; 3],
        );
        assert!((w + PI / 2.0).abs() < 1e-14, "{w}");
    }

    #[test]
    fn degenerate_positions_give_finite_values() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert_eq!(solid_angle(&a, &b, &c, &a), 0.0); // at a vertex
        assert_eq!(solid_angle(&a, &b, &c, &[2.0, 2.0, 0.0]), 0.0); // in plane, outside
        let inside = solid_angle(&a, &b, &c, &[0.2, 0.2, 0.0]);
        assert!((inside.abs() - 2.0 * PI).abs() < 1e-12);
    }
}
