//! Visible penetration: how deep the points of one object's own surface (its box, sphere,
//! mesh or derived surface, edges and corners included) reach into another object, against
//! the other's sample envelope. The samples' own figure (two spheres overlapping) misses an
//! edge or corner standing out past an object's sample spheres; this one sees it, as a user
//! looking at the surfaces would.

use super::pairs::candidates;
use crate::geometry::Shape;
use crate::precompute::skinning::{Basis, SkinningWeights};
use crate::sim::ReducedSim;
use crate::{Point3, Result};

/// Points on an object's own surface, with its skinning weights there.
#[derive(Debug, Clone)]
pub struct SurfacePoints {
    /// Rest positions, N x 3, metres.
    pub rest: Vec<Point3>,
    weights: SkinningWeights,
}

impl SurfacePoints {
    /// Points on the surface of `shape` about `spacing` metres apart (faces, edges and
    /// corners of a box; a Fibonacci lattice on a sphere; a mesh's vertices and a barycentric
    /// lattice on its larger triangles), with `basis` evaluated there.
    ///
    /// # Errors
    /// The basis's coverage error where the kernels do not reach a surface point; a point
    /// cloud or image (give its derived surface instead).
    pub fn new(shape: &Shape, basis: &Basis, spacing: f64) -> Result<SurfacePoints> {
        let rest = match shape {
            Shape::Box { size } => box_points(size, spacing),
            Shape::Sphere { radius } => sphere_points(*radius, spacing),
            Shape::Mesh(m) => mesh_points(m.vertices(), m.triangles(), spacing),
            Shape::PointCloud(_) | Shape::Image(_) => {
                return Err(crate::Error::param(
                    "shape",
                    shape.kind(),
                    "a point cloud or image has no surface of its own; give the mesh \
                     sim::contact::surface::derived_surface makes of it",
                ))
            }
        };
        let weights = basis.weights(&rest)?;
        Ok(SurfacePoints { rest, weights })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// Deformed positions under `sim`'s current state, N x 3, metres.
    pub fn positions(&self, sim: &ReducedSim) -> Vec<Point3> {
        sim.positions(&self.rest, &self.weights)
    }
}

/// The deepest surface point found by [`deepest_visible`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deepest {
    /// How far it reaches into the other object's envelope, metres (negative: outside).
    pub depth: f64,
    /// The object whose surface point it is.
    pub object: usize,
    /// The point's index among that object's surface points.
    pub point: usize,
    /// The object whose envelope it reaches into.
    pub other: usize,
}

/// The deepest reach of a surface point of one object into another's sample envelope (the
/// union of its samples' spheres); None when no surface point is inside another object's
/// envelope. `surface[i]` and `samples[i]` are object i's deformed surface points and sample
/// centres, `radius[i]` its samples' radii (one per sample).
pub fn deepest_visible(
    surface: &[Vec<Point3>],
    samples: &[&[Point3]],
    radius: &[&[f64]],
) -> Option<Deepest> {
    let n = surface.len();
    let largest: Vec<f64> = radius
        .iter()
        .map(|r| r.iter().fold(0.0, |m: f64, &v| m.max(v)))
        .collect();
    let mut x: Vec<&[Point3]> = surface.iter().map(Vec::as_slice).collect();
    x.extend(samples.iter().copied());
    // Only (surface of i, samples of j) with i != j: every other pair is out of reach.
    let reach = |a: usize, b: usize| {
        if a < n && b >= n && b - n != a {
            largest[b - n]
        } else {
            f64::NEG_INFINITY
        }
    };
    let (pairs, _) = candidates(&x, &reach);
    let mut deepest: Option<Deepest> = None;
    for c in pairs {
        let (p, q) = (x[c.a][c.i], x[c.b][c.j]);
        let r = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt();
        let depth = radius[c.b - n][c.j] - r;
        if deepest.is_none_or(|d| depth > d.depth) {
            deepest = Some(Deepest {
                depth,
                object: c.a,
                point: c.i,
                other: c.b - n,
            });
        }
    }
    deepest
}

/// A grid of nodes about `s` apart on each face of the box [0, l], borders included, so every
/// edge and corner is a point (shared nodes repeat; harmless for a maximum).
fn box_points(l: &[f64; 3], s: f64) -> Vec<Point3> {
    let mut out = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let nu = ((l[u] / s).ceil() as usize).max(1);
        let nv = ((l[v] / s).ceil() as usize).max(1);
        for side in [0.0, l[axis]] {
            for iu in 0..=nu {
                for iv in 0..=nv {
                    let mut p = [0.0; 3];
                    p[axis] = side;
                    p[u] = iu as f64 * l[u] / nu as f64;
                    p[v] = iv as f64 * l[v] / nv as f64;
                    out.push(p);
                }
            }
        }
    }
    out
}

/// A Fibonacci lattice on the sphere of radius r, about `s` apart.
fn sphere_points(r: f64, s: f64) -> Vec<Point3> {
    let count = ((4.0 * std::f64::consts::PI * r * r / (s * s)).ceil() as usize).max(12);
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
            let rho = (1.0 - y * y).max(0.0).sqrt();
            let phi = golden * i as f64;
            [r * rho * phi.cos(), r * y, r * rho * phi.sin()]
        })
        .collect()
}

/// The vertices, and on every triangle with an edge longer than `s` a barycentric lattice of
/// k = ceil(longest edge / s) divisions per edge (its corners left out: they are vertices).
fn mesh_points(v: &[Point3], tris: &[[u32; 3]], s: f64) -> Vec<Point3> {
    let mut out = v.to_vec();
    let dist = |a: Point3, b: Point3| (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>().sqrt();
    for t in tris {
        let [a, b, c] = t.map(|i| v[i as usize]);
        let longest = dist(a, b).max(dist(b, c)).max(dist(c, a));
        let k = (longest / s).ceil() as usize;
        if k < 2 {
            continue;
        }
        for i in 0..=k {
            for j in 0..=k - i {
                let corner = (i == k) || (j == k) || (i == 0 && j == 0);
                if corner {
                    continue;
                }
                let (p, q) = (i as f64 / k as f64, j as f64 / k as f64);
                out.push(std::array::from_fn(|d| {
                    a[d] + p * (b[d] - a[d]) + q * (c[d] - a[d])
                }));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_points_include_every_corner_and_lie_on_the_faces() {
        let l = [0.3, 0.2, 0.1];
        let p = box_points(&l, 0.05);
        for corner in 0..8 {
            let c: Point3 = std::array::from_fn(|d| if corner >> d & 1 == 1 { l[d] } else { 0.0 });
            assert!(p.contains(&c), "{c:?}");
        }
        for x in &p {
            let on_face = (0..3).any(|d| x[d] == 0.0 || x[d] == l[d]);
            assert!(
                on_face && (0..3).all(|d| (0.0..=l[d]).contains(&x[d])),
                "{x:?}"
            );
        }
    }

    #[test]
    fn mesh_points_lie_on_the_triangles_and_include_the_vertices() {
        let (v, f) = crate::geometry::generate::box_mesh([1.0, 1.0, 1.0]);
        let p = mesh_points(&v, &f, 0.25);
        assert!(v.iter().all(|c| p.contains(c)));
        // On the unit cube's surface: some coordinate at 0 or 1, all within [0, 1].
        for x in &p {
            let on = (0..3).any(|d| x[d].abs() < 1e-12 || (x[d] - 1.0).abs() < 1e-12);
            assert!(
                on && x.iter().all(|c| (-1e-12..=1.0 + 1e-12).contains(c)),
                "{x:?}"
            );
        }
        assert!(p.len() > 6 * 16);
    }

    /// Two envelopes: a surface point 0.25 inside a sample's sphere of radius 0.5 is found
    /// with its objects; a point 0.1 inside a smaller sphere (radius 0.2) is measured against
    /// that sphere's own radius; a point outside every sphere gives nothing.
    #[test]
    fn the_deepest_surface_point_is_found() {
        let surface = vec![
            vec![[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]],
            vec![[9.0, 9.0, 9.0]],
        ];
        let a_samples = vec![[9.0, 9.0, 9.3]];
        let b_samples = vec![[0.25, 0.0, 0.0], [5.1, 0.0, 0.0]];
        let samples: Vec<&[Point3]> = vec![&a_samples, &b_samples];
        let radii: [&[f64]; 2] = [&[0.5], &[0.5, 0.2]];
        let d = deepest_visible(&surface, &samples, &radii).unwrap();
        assert_eq!((d.object, d.point, d.other), (0, 0, 1));
        assert!((d.depth - 0.25).abs() < 1e-15);
        // Object 1's point is 0.3 from object 0's sample: 0.2 deep.
        let only_b = vec![vec![], vec![[9.0, 9.0, 9.0]]];
        let d = deepest_visible(&only_b, &samples, &radii).unwrap();
        assert_eq!((d.object, d.point, d.other), (1, 0, 0));
        assert!((d.depth - 0.2).abs() < 1e-12);
        // 0.1 from the small sphere's centre (radius 0.2): 0.1 deep; no large sphere is near.
        let small = vec![vec![[5.0, 0.0, 0.0]], vec![]];
        let d = deepest_visible(&small, &samples, &radii).unwrap();
        assert!((d.depth - 0.1).abs() < 1e-12, "{d:?}");
        let far = vec![vec![[5.0, 3.0, 0.0]], vec![]];
        assert_eq!(deepest_visible(&far, &samples, &radii), None);
    }
}
