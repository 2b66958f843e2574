//! The evaluable obstacle ([`Obstacle`]): a [`ColliderShape`] with unit normals, rotations
//! as matrices and meshes loaded, answering penetration queries at any pose.

use super::mesh::MeshObstacle;
use super::penetration::Penetration;
use super::shape::{axis_angle_matrix, ColliderShape};
use crate::linalg3::{dot, mat_t_vec, mat_vec, Mat3};
use crate::sim::motion::Rigid;
use crate::{Point3, Result};
use std::path::Path;
use std::sync::Arc;

/// A unit vector along `v`, or `fallback` when `v` is (nearly) zero.
fn unit_or(v: [f64; 3], len: f64, fallback: [f64; 3]) -> [f64; 3] {
    if len > 0.0 {
        v.map(|x| x / len)
    } else {
        fallback
    }
}

/// An obstacle ready for queries, in its rest frame: what [`ColliderShape`] describes, with
/// unit normals, box rotations as matrices and meshes loaded. Cheap to clone (meshes are
/// shared).
#[derive(Debug, Clone)]
pub enum Obstacle {
    /// Half-space behind the plane through `point` with unit outward `normal`.
    Plane {
        /// Point on the plane, metres.
        point: Point3,
        /// Unit outward normal.
        normal: [f64; 3],
    },
    /// Box [min, max] turned by `rotation` about its centre (None: axis-aligned).
    Box {
        /// Lower corner before the rotation, metres.
        min: Point3,
        /// Upper corner before the rotation, metres.
        max: Point3,
        /// Rotation about the centre, row-major.
        rotation: Option<Mat3>,
    },
    /// Ball.
    Sphere {
        /// Centre, metres.
        center: Point3,
        /// Radius, metres.
        radius: f64,
    },
    /// Capsule around the segment [a, b].
    Capsule {
        /// One end, metres.
        a: Point3,
        /// Other end, metres.
        b: Point3,
        /// Radius, metres.
        radius: f64,
    },
    /// A loaded triangle mesh.
    Mesh(Arc<MeshObstacle>),
}

impl Obstacle {
    /// The queryable form of `shape`. A mesh not yet [`ColliderShape::load`]ed is read here,
    /// with a relative path taken from the working directory.
    ///
    /// # Errors
    /// [`ColliderShape::validate`]'s and, for meshes, [`ColliderShape::load`]'s.
    pub fn new(shape: &ColliderShape) -> Result<Obstacle> {
        shape.validate()?;
        Ok(match shape {
            ColliderShape::Plane { point, normal } => {
                let n = dot(normal, normal).sqrt();
                Obstacle::Plane {
                    point: *point,
                    normal: normal.map(|v| v / n),
                }
            }
            ColliderShape::Box { min, max, rotation } => Obstacle::Box {
                min: *min,
                max: *max,
                rotation: rotation.as_ref().map(axis_angle_matrix).transpose()?,
            },
            ColliderShape::Sphere { center, radius } => Obstacle::Sphere {
                center: *center,
                radius: *radius,
            },
            ColliderShape::Capsule { a, b, radius } => Obstacle::Capsule {
                a: *a,
                b: *b,
                radius: *radius,
            },
            ColliderShape::Mesh(m) => match &m.loaded {
                Some(loaded) => Obstacle::Mesh(loaded.clone()),
                None => Obstacle::Mesh(Arc::new(m.read(Path::new(""))?)),
            },
        })
    }

    /// A short name of the kind: "plane", "box", "sphere", "capsule" or "mesh".
    pub fn kind(&self) -> &'static str {
        match self {
            Obstacle::Plane { .. } => "plane",
            Obstacle::Box { .. } => "box",
            Obstacle::Sphere { .. } => "sphere",
            Obstacle::Capsule { .. } => "capsule",
            Obstacle::Mesh(_) => "mesh",
        }
    }

    /// The penetration of the point `x` (metres, world frame) into the obstacle moved by
    /// `pose` (x -> R x + t of its rest frame), or None outside.
    pub fn penetration(&self, pose: &Rigid, x: &Point3) -> Option<Penetration> {
        let d: [f64; 3] = std::array::from_fn(|i| x[i] - pose.translation[i]);
        let y = mat_t_vec(&pose.rotation, &d);
        let p = self.penetration_local(&y)?;
        if pose.rotation == Rigid::IDENTITY.rotation {
            Some(p)
        } else {
            Some(p.rotated(&pose.rotation))
        }
    }

    /// The penetration of the point `y` given in the obstacle's rest frame (metres).
    pub fn penetration_local(&self, y: &Point3) -> Option<Penetration> {
        match self {
            Obstacle::Plane { point, normal } => {
                let s: f64 = (0..3).map(|d| (y[d] - point[d]) * normal[d]).sum();
                (s < 0.0).then(|| Penetration::flat(-s, *normal))
            }
            Obstacle::Box { min, max, rotation } => {
                // The point in the unrotated box's frame (exactly y for an axis-aligned box).
                let q = match rotation {
                    None => *y,
                    Some(r) => {
                        let c: [f64; 3] = std::array::from_fn(|d| 0.5 * (min[d] + max[d]));
                        let local = mat_t_vec(r, &std::array::from_fn(|d| y[d] - c[d]));
                        std::array::from_fn(|d| c[d] + local[d])
                    }
                };
                if !(0..3).all(|d| q[d] > min[d] && q[d] < max[d]) {
                    return None;
                }
                // Push out through the nearest face (first one on ties).
                let mut best = (f64::INFINITY, [0.0; 3]);
                for d in 0..3 {
                    let (lo, hi) = (q[d] - min[d], max[d] - q[d]);
                    if lo < best.0 {
                        let mut u = [0.0; 3];
                        u[d] = -1.0;
                        best = (lo, u);
                    }
                    if hi < best.0 {
                        let mut u = [0.0; 3];
                        u[d] = 1.0;
                        best = (hi, u);
                    }
                }
                let u = rotation.as_ref().map_or(best.1, |r| mat_vec(r, &best.1));
                Some(Penetration::flat(best.0, u))
            }
            Obstacle::Sphere { center, radius } => {
                let v: [f64; 3] = std::array::from_fn(|d| y[d] - center[d]);
                let rho = dot(&v, &v).sqrt();
                (rho < *radius).then(|| {
                    let u = unit_or(v, rho, [0.0, 1.0, 0.0]);
                    Penetration::round(*radius, rho, u, None)
                })
            }
            Obstacle::Capsule { a, b, radius } => {
                let e: [f64; 3] = std::array::from_fn(|d| b[d] - a[d]);
                let l2 = dot(&e, &e);
                let ya: [f64; 3] = std::array::from_fn(|d| y[d] - a[d]);
                let s = if l2 > 0.0 { dot(&ya, &e) / l2 } else { 0.0 };
                let (s, middle) = if s <= 0.0 {
                    (0.0, false)
                } else if s >= 1.0 {
                    (1.0, false)
                } else {
                    (s, true)
                };
                let v: [f64; 3] = std::array::from_fn(|d| ya[d] - s * e[d]);
                let rho = dot(&v, &v).sqrt();
                (rho < *radius).then(|| {
                    let axis = middle.then(|| e.map(|x| x / l2.sqrt()));
                    // On the axis itself: any direction across it.
                    let across = axis.map_or([0.0, 1.0, 0.0], |e| any_perpendicular(&e));
                    let u = unit_or(v, rho, across);
                    Penetration::round(*radius, rho, u, axis)
                })
            }
            Obstacle::Mesh(m) => m.penetration_local(y),
        }
    }

    /// Half the obstacle's thinnest extent, metres: past this depth the nearest surface of a
    /// point inside can be the far one, so the penalty would push it on through (a box's
    /// smallest half-size, a sphere's or capsule's radius). Infinite for a mesh (its
    /// thickness is not known; the object's own scale bounds the sweep), None for a plane
    /// (the depth grows without bound along every line into it: nothing to pass through).
    pub fn half_thickness(&self) -> Option<f64> {
        match self {
            Obstacle::Plane { .. } => None,
            Obstacle::Box { min, max, .. } => Some(
                (0..3)
                    .map(|d| 0.5 * (max[d] - min[d]))
                    .fold(f64::INFINITY, f64::min),
            ),
            Obstacle::Sphere { radius, .. } | Obstacle::Capsule { radius, .. } => Some(*radius),
            Obstacle::Mesh(_) => Some(f64::INFINITY),
        }
    }

    /// A sphere (centre, radius; rest frame, metres) that holds every point that can
    /// penetrate, for a cheap rejection; None when the obstacle is unbounded (a plane, a
    /// one-sided mesh surface).
    pub fn bounding_sphere(&self) -> Option<(Point3, f64)> {
        match self {
            Obstacle::Plane { .. } => None,
            Obstacle::Box { min, max, .. } => {
                let c = std::array::from_fn(|d| 0.5 * (min[d] + max[d]));
                let h: [f64; 3] = std::array::from_fn(|d| 0.5 * (max[d] - min[d]));
                Some((c, dot(&h, &h).sqrt()))
            }
            Obstacle::Sphere { center, radius } => Some((*center, *radius)),
            Obstacle::Capsule { a, b, radius } => {
                let c = std::array::from_fn(|d| 0.5 * (a[d] + b[d]));
                let e: [f64; 3] = std::array::from_fn(|d| b[d] - a[d]);
                Some((c, 0.5 * dot(&e, &e).sqrt() + radius))
            }
            Obstacle::Mesh(m) => m.bounding_sphere(),
        }
    }

    /// A triangulated surface of the obstacle in its rest frame, for drawing (vertices V x 3,
    /// metres; triangles F x 3, outward): spheres and capsules as icospheres (capsules
    /// stretched along their axis), boxes as 12 triangles, meshes as they are; None for a
    /// plane (unbounded).
    pub fn surface(&self) -> Option<(Vec<Point3>, Vec<[u32; 3]>)> {
        use crate::geometry::generate::{box_mesh, icosphere};
        match self {
            Obstacle::Plane { .. } => None,
            Obstacle::Box { min, max, rotation } => {
                let size = std::array::from_fn(|d| max[d] - min[d]);
                let (v, t) = box_mesh(size);
                let c: [f64; 3] = std::array::from_fn(|d| 0.5 * (min[d] + max[d]));
                let v = v
                    .iter()
                    .map(|p| {
                        let local: [f64; 3] = std::array::from_fn(|d| p[d] + min[d] - c[d]);
                        let turned = rotation.as_ref().map_or(local, |r| mat_vec(r, &local));
                        std::array::from_fn(|d| c[d] + turned[d])
                    })
                    .collect();
                Some((v, t))
            }
            Obstacle::Sphere { center, radius } => {
                let (v, t) = icosphere(*radius, 2);
                let v = v
                    .iter()
                    .map(|p| std::array::from_fn(|d| p[d] + center[d]))
                    .collect();
                Some((v, t))
            }
            Obstacle::Capsule { a, b, radius } => {
                let (v, t) = icosphere(*radius, 2);
                let e: [f64; 3] = std::array::from_fn(|d| b[d] - a[d]);
                let len = dot(&e, &e).sqrt();
                let axis = if len > 0.0 {
                    e.map(|x| x / len)
                } else {
                    [0.0, 1.0, 0.0]
                };
                let c: [f64; 3] = std::array::from_fn(|d| 0.5 * (a[d] + b[d]));
                // Each half of the sphere moves half the axis length towards its end.
                let v = v
                    .iter()
                    .map(|p| {
                        let side = if dot(p, &axis) >= 0.0 { 0.5 } else { -0.5 };
                        std::array::from_fn(|d| c[d] + p[d] + side * len * axis[d])
                    })
                    .collect();
                Some((v, t))
            }
            Obstacle::Mesh(m) => Some((m.vertices().to_vec(), m.triangles().to_vec())),
        }
    }

    /// The mesh, for mesh obstacles.
    pub fn mesh(&self) -> Option<&MeshObstacle> {
        match self {
            Obstacle::Mesh(m) => Some(m),
            _ => None,
        }
    }
}

/// A unit vector perpendicular to the unit `e`.
fn any_perpendicular(e: &[f64; 3]) -> [f64; 3] {
    let t = if e[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let c = [
        e[1] * t[2] - e[2] * t[1],
        e[2] * t[0] - e[0] * t[2],
        e[0] * t[1] - e[1] * t[0],
    ];
    let n = dot(&c, &c).sqrt();
    c.map(|v| v / n)
}
