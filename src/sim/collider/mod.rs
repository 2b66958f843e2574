//! Rigid obstacles the objects are pushed out of: planes, boxes (any rigid pose), spheres,
//! capsules and triangle meshes, static or kinematic (moved by a scripted [`Motion`] or by the
//! caller between steps), with one-way coupling: they push the objects, nothing pushes them.
//!
//! Two layers:
//! - [`ColliderShape`] is the description (scene files, the builder API): what the obstacle is
//!   in its rest frame. A mesh names a file ([`MeshCollider`]).
//! - [`Obstacle`] is the evaluable geometry (meshes loaded into a BVH, shared through an
//!   `Arc` by every object of a scene). [`Obstacle::penetration`] answers, for a point and the
//!   obstacle's current pose, the penetration depth d >= 0, the push-out direction u and the
//!   exact Hessian of d^2 / 2: everything the one-sided penalty kappa/2 v d^2 of
//!   [`crate::sim::terms::ContactTerm`] needs for its energy, exact gradient and Hessian.
//!
//! The depth is the distance to the surface for points inside (d = -phi, phi the signed
//! distance), so the penalty is C1 across the surface (value and gradient vanish there).
//! Hessians of d^2/2 = phi^2/2 are grad phi grad phi^T + phi Hess phi:
//! - plane, box: u u^T (phi is linear on each face's region);
//! - sphere: u u^T + (rho - r)/rho (I - u u^T), rho the distance to the centre; the second
//!   part is negative inside (rho < r), so the PSD Hessian keeps u u^T (Gauss-Newton);
//! - capsule: the same about the axis segment (tangent to the axis removed in the middle part);
//! - mesh: d^2/2 = |x - c(x)|^2/2 with c the closest surface point, whose Hessian is the
//!   projector of the closest feature: n n^T on a face, I - e e^T on an edge, I on a vertex
//!   (already PSD).

mod kinematics;
pub mod mesh;
mod obstacle;
mod open_boundary;
mod penetration;
mod shape;

use crate::sim::motion::Motion;
use crate::{Error, Result};
pub use kinematics::{compose, Kinematics};
pub use mesh::{MeshObstacle, Sided};
pub use obstacle::Obstacle;
pub use penetration::Penetration;
use serde::{Deserialize, Serialize};
pub use shape::{ColliderShape, MeshCollider};

/// An obstacle of a scene (`[[collider]]`): its shape, penalty stiffness and kinematics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Collider {
    /// Name (letters, digits, '-', '_'): for errors and reports, and for `parent`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The obstacle in its rest frame.
    pub shape: ColliderShape,
    /// Penalty stiffness, Pa/m^2 (default as for boundaries:
    /// [`crate::sim::object::PENALTY_FACTOR`] x max(rho/h^2, E/D^2) of each object).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<f64>,
    /// Rigid motion of the rest frame over time (default fixed): a scripted kinematic body.
    /// With a `parent`, relative to the parent's moving frame (a joint).
    #[serde(default = "fixed", skip_serializing_if = "is_fixed")]
    pub motion: Motion,
    /// Name of an earlier collider whose pose this one follows: its motion is composed after
    /// the parent's (articulated chains; the robot arm of examples/robot_push.toml).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parent: Option<String>,
}

fn fixed() -> Motion {
    Motion::Fixed
}

fn is_fixed(m: &Motion) -> bool {
    *m == Motion::Fixed
}

impl Collider {
    /// A static, unnamed collider with the default stiffness.
    pub fn new(shape: ColliderShape) -> Collider {
        Collider {
            name: None,
            shape,
            stiffness: None,
            motion: Motion::Fixed,
            parent: None,
        }
    }

    /// With a name (for errors, reports and children's `parent`).
    #[must_use]
    pub fn named(mut self, name: &str) -> Collider {
        self.name = Some(name.to_string());
        self
    }

    /// With a penalty stiffness, Pa/m^2.
    #[must_use]
    pub fn stiffness(mut self, k: f64) -> Collider {
        self.stiffness = Some(k);
        self
    }

    /// Moved by `motion` (relative to the parent's frame when it has a parent).
    #[must_use]
    pub fn motion(mut self, motion: Motion) -> Collider {
        self.motion = motion;
        self
    }

    /// Following the collider named `parent` (listed earlier).
    #[must_use]
    pub fn parent(mut self, parent: &str) -> Collider {
        self.parent = Some(parent.to_string());
        self
    }

    /// Wrap an error about this collider (index `index`) with its index and name.
    pub fn error(&self, index: usize, e: Error) -> Error {
        Error::Collider {
            index,
            name: self.name.clone(),
            source: Box::new(e),
        }
    }
}

/// Check a scene's colliders without reading files: names (unique, letters, digits, '-',
/// '_'), shapes, stiffness, motions, and parents (an earlier collider's name).
///
/// # Errors
/// [`Error::Collider`] naming the first bad collider.
pub fn validate_colliders(colliders: &[Collider]) -> Result<()> {
    parents(colliders).map(|_| ())
}

/// The parent index of each collider (validating everything as [`validate_colliders`]).
fn parents(colliders: &[Collider]) -> Result<Vec<Option<usize>>> {
    let mut out = Vec::with_capacity(colliders.len());
    for (i, c) in colliders.iter().enumerate() {
        let fail = |e: Error| c.error(i, e);
        if let Some(name) = &c.name {
            let ok = !name.is_empty()
                && name
                    .chars()
                    .all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_');
            if !ok {
                return Err(fail(Error::param(
                    "name",
                    format!("'{name}'"),
                    "a collider name must be non-empty and use only letters, digits, '-' and '_'",
                )));
            }
            if colliders[..i].iter().any(|o| o.name.as_ref() == Some(name)) {
                return Err(fail(Error::param(
                    "name",
                    format!("'{name}'"),
                    "two colliders have this name",
                )));
            }
        }
        c.shape.validate().map_err(fail)?;
        if let Some(k) = c.stiffness {
            if !(k > 0.0 && k.is_finite()) {
                return Err(fail(Error::param(
                    "stiffness",
                    k,
                    "a collider penalty stiffness (Pa/m^2) must be positive and finite",
                )));
            }
        }
        c.motion.validate().map_err(fail)?;
        let parent = match &c.parent {
            None => None,
            Some(p) => Some(
                colliders[..i]
                    .iter()
                    .position(|o| o.name.as_ref() == Some(p))
                    .ok_or_else(|| {
                        fail(Error::param(
                            "parent",
                            format!("'{p}'"),
                            "no collider listed before this one has that name (a parent \
                             comes first)",
                        ))
                    })?,
            ),
        };
        out.push(parent);
    }
    Ok(out)
}

/// The evaluable obstacles of `colliders` with their motions and parents. Meshes not yet
/// [`ColliderShape::load`]ed are read here (relative paths from the working directory).
///
/// # Errors
/// [`validate_colliders`]'s, and a mesh that cannot be read or used, as [`Error::Collider`].
pub fn kinematics(colliders: &[Collider]) -> Result<Kinematics> {
    let parents = parents(colliders)?;
    let obstacles = colliders
        .iter()
        .enumerate()
        .map(|(i, c)| Obstacle::new(&c.shape).map_err(|e| c.error(i, e)))
        .collect::<Result<Vec<_>>>()?;
    Kinematics::new(
        obstacles,
        colliders.iter().map(|c| c.motion.clone()).collect(),
        parents,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::derivatives::{check_derivatives, Floors};
    use crate::sim::motion::{rotation_matrix, AxisAngle, Rigid};
    use crate::Point3;

    /// A two-link chain stays connected: the child's joint (its rest `a`, the parent's rest
    /// `b`) goes where the parent's tip goes, at every time, and the child turns by the sum of
    /// the angles (both joints about z).
    #[test]
    fn a_child_follows_its_parent_at_the_joint() {
        let capsule = |a: Point3, b: Point3| {
            Obstacle::new(&ColliderShape::Capsule { a, b, radius: 0.1 }).unwrap()
        };
        let turn = |pivot: Point3, rate: f64| Motion::Rotate {
            pivot,
            axis: [0.0, 0.0, 1.0],
            degrees_per_second: rate,
        };
        let joint = [1.0, 0.0, 0.0];
        let kin = Kinematics::new(
            vec![capsule([0.0; 3], joint), capsule(joint, [1.5, 0.0, 0.0])],
            vec![turn([0.0; 3], 30.0), turn(joint, 45.0)],
            vec![None, Some(0)],
        )
        .unwrap();
        for t in [0.0, 0.5, 1.0, 2.0] {
            let p = kin.poses(t);
            let (tip, elbow) = (p[0].apply(&joint), p[1].apply(&joint));
            for d in 0..3 {
                assert!(
                    (tip[d] - elbow[d]).abs() < 1e-14,
                    "t {t}: {tip:?} vs {elbow:?}"
                );
            }
            // The child's end: the elbow plus 0.5 m along the summed angle.
            let angle = (75.0 * t).to_radians();
            let end = p[1].apply(&[1.5, 0.0, 0.0]);
            let expected = [
                elbow[0] + 0.5 * angle.cos(),
                elbow[1] + 0.5 * angle.sin(),
                0.0,
            ];
            for d in 0..3 {
                assert!((end[d] - expected[d]).abs() < 1e-14, "t {t}: {end:?}");
            }
        }
        // A parent must come first.
        let err = Kinematics::new(
            vec![capsule([0.0; 3], joint)],
            vec![Motion::Fixed],
            vec![Some(0)],
        )
        .unwrap_err();
        assert!(err.to_string().contains("listed before"), "{err}");
    }

    /// Central differences of d^2/2 against the push-out gradient -d u and of that gradient
    /// against the exact Hessian, at points inside each primitive (away from region seams).
    #[test]
    fn primitive_derivatives_match_finite_differences() {
        let turn = AxisAngle {
            axis: [1.0, 2.0, 0.5],
            degrees: 37.0,
        };
        let shapes = [
            ColliderShape::Plane {
                point: [0.1, 0.2, 0.3],
                normal: [0.3, 1.0, -0.2],
            },
            ColliderShape::Box {
                min: [-0.5, -0.3, -0.4],
                max: [0.6, 0.5, 0.4],
                rotation: Some(turn),
            },
            ColliderShape::Sphere {
                center: [0.05, -0.02, 0.01],
                radius: 0.7,
            },
            ColliderShape::Capsule {
                a: [-0.4, 0.0, 0.1],
                b: [0.5, 0.2, -0.1],
                radius: 0.5,
            },
        ];
        let pose = Rigid {
            rotation: rotation_matrix(&[0.0, 0.6, 0.8], 0.9),
            translation: [0.02, -0.01, 0.03],
        };
        let points = [
            [0.1, 0.15, 0.05],
            [-0.2, 0.1, -0.05],
            [0.3, -0.1, 0.1],
            [0.6, 0.3, -0.1],
        ];
        let f = |o: &Obstacle, x: &Point3| {
            o.penetration(&pose, x)
                .map_or(0.0, |p| 0.5 * p.depth * p.depth)
        };
        let g = |o: &Obstacle, x: &Point3| {
            o.penetration(&pose, x)
                .map_or([0.0; 3], |p| p.normal.map(|u| -p.depth * u))
        };
        let coords: Vec<Vec<f64>> = (0..3)
            .map(|k| (0..3).map(|i| if i == k { 1.0 } else { 0.0 }).collect())
            .collect();
        for shape in &shapes {
            let o = Obstacle::new(shape).unwrap();
            let mut inside = 0;
            for x in &points {
                let Some(p) = o.penetration(&pose, x) else {
                    continue;
                };
                inside += 1;
                let energy = |y: &[f64], grad: &mut [f64]| {
                    let y = [y[0], y[1], y[2]];
                    grad.copy_from_slice(&g(&o, &y));
                    f(&o, &y)
                };
                let hess = |_: &[f64]| faer::Mat::from_fn(3, 3, |r, c| p.hessian[r][c]);
                // Central differences of smooth quadratics: error O(h^2) ~ 1e-12, rounding
                // ~ 1e-16 / h = 1e-10. Floors of 1 (depths and normals are O(1)) make the
                // bounds the old absolute ones, 1e-8 and 1e-7.
                let check =
                    check_derivatives(energy, Some(&hess), x, &coords, 1e-6, Floors::both(1.0));
                assert!(
                    check.gradient < 1e-8 && check.hessian < 1e-7,
                    "{shape:?} at {x:?}: {check:?}"
                );
            }
            assert!(inside >= 2, "{shape:?}: only {inside} test points inside");
        }
    }
}
