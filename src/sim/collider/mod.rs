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

pub mod mesh;

use crate::linalg3::{dot, mat_t_vec, mat_vec, mul, outer, transpose, Mat3};
use crate::sim::motion::{rotation_matrix, AxisAngle, Motion, Rigid};
use crate::{Error, Point3, Result};
pub use mesh::{MeshObstacle, Sided};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;

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

/// An obstacle as described in a scene, in its rest frame (before any motion).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ColliderShape {
    /// The half-space behind a plane: points with (x - point) . normal < 0 penetrate.
    Plane {
        /// A point on the plane, metres.
        point: Point3,
        /// Normal pointing out of the obstacle (any non-zero length).
        normal: [f64; 3],
    },
    /// A box [min, max] (metres), turned by `rotation` about its centre (none: axis-aligned).
    Box {
        /// Lower corner before the rotation, metres.
        min: Point3,
        /// Upper corner before the rotation, metres.
        max: Point3,
        /// Rotation about the box centre (axis of any non-zero length, degrees).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        rotation: Option<AxisAngle>,
    },
    /// A solid ball.
    Sphere {
        /// Centre, metres.
        center: Point3,
        /// Radius, metres (> 0).
        radius: f64,
    },
    /// The points within `radius` of the segment [a, b] (a == b: a sphere).
    Capsule {
        /// One end of the axis, metres.
        a: Point3,
        /// The other end of the axis, metres.
        b: Point3,
        /// Radius, metres (> 0).
        radius: f64,
    },
    /// A triangle mesh read from a file (OBJ, STL, OFF, PLY): a closed solid or a one-sided
    /// surface ([`MeshCollider`]).
    Mesh(MeshCollider),
}

/// A triangle-mesh obstacle: the file, how its inside is decided, and where it is placed.
///
/// The file is read once per scene and shared by every object ([`ColliderShape::load`]).
#[derive(Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshCollider {
    /// The mesh file, OBJ, STL, OFF or PLY with faces (relative paths: to the scene file).
    pub file: PathBuf,
    /// `solid` (default): a closed, consistently oriented mesh whose inside is the obstacle;
    /// `outside`: a one-sided surface (may be open) whose triangle normals point to the free
    /// side ([`Sided`]).
    #[serde(default)]
    pub sided: Sided,
    /// Uniform scale applied to the file's coordinates first (e.g. 0.01 for centimetres).
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub scale: f64,
    /// Rotation about the file's origin, after the scale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation: Option<AxisAngle>,
    /// Translation after the rotation, metres.
    #[serde(default, skip_serializing_if = "is_zero3")]
    pub translation: [f64; 3],
    /// The mesh once read (shared by every object of a scene); `None` until loaded.
    #[serde(skip)]
    pub loaded: Option<Arc<MeshObstacle>>,
}

fn one() -> f64 {
    1.0
}

fn is_one(v: &f64) -> bool {
    *v == 1.0
}

fn is_zero3(v: &[f64; 3]) -> bool {
    *v == [0.0; 3]
}

impl MeshCollider {
    /// A solid mesh collider of `file` at its file coordinates.
    pub fn new(file: impl Into<PathBuf>) -> MeshCollider {
        MeshCollider {
            file: file.into(),
            sided: Sided::Solid,
            scale: 1.0,
            rotation: None,
            translation: [0.0; 3],
            loaded: None,
        }
    }

    /// The placement x -> R (scale X) + t of the file's coordinates.
    pub(crate) fn placement(&self) -> Result<(f64, Rigid)> {
        if !(self.scale > 0.0 && self.scale.is_finite()) {
            return Err(Error::param(
                "scale",
                self.scale,
                "a mesh collider's scale must be positive and finite",
            ));
        }
        finite3("translation", &self.translation)?;
        let rotation = match &self.rotation {
            None => Rigid::IDENTITY.rotation,
            Some(a) => axis_angle_matrix(a)?,
        };
        Ok((
            self.scale,
            Rigid {
                rotation,
                translation: self.translation,
            },
        ))
    }
}

impl PartialEq for MeshCollider {
    /// The description only (file, side, placement), not whether it was loaded.
    fn eq(&self, other: &Self) -> bool {
        self.file == other.file
            && self.sided == other.sided
            && self.scale == other.scale
            && self.rotation == other.rotation
            && self.translation == other.translation
    }
}

impl std::fmt::Debug for MeshCollider {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshCollider")
            .field("file", &self.file)
            .field("sided", &self.sided)
            .field("scale", &self.scale)
            .field("rotation", &self.rotation)
            .field("translation", &self.translation)
            .field("loaded", &self.loaded.is_some())
            .finish()
    }
}

fn finite3(name: &'static str, v: &[f64; 3]) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::param(name, format!("{v:?}"), "must be finite"))
    }
}

fn positive_radius(radius: f64) -> Result<()> {
    if radius > 0.0 && radius.is_finite() {
        Ok(())
    } else {
        Err(Error::param(
            "radius",
            radius,
            "a sphere or capsule radius must be positive and finite (metres)",
        ))
    }
}

/// The rotation matrix of an axis (any non-zero length) and an angle in degrees.
pub(crate) fn axis_angle_matrix(a: &AxisAngle) -> Result<Mat3> {
    let n = a.axis.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !(n > 0.0 && n.is_finite() && a.degrees.is_finite()) {
        return Err(Error::param(
            "rotation",
            format!("{a:?}"),
            "needs a finite, non-zero axis and a finite angle (degrees)",
        ));
    }
    Ok(rotation_matrix(
        &a.axis.map(|v| v / n),
        a.degrees.to_radians(),
    ))
}

impl ColliderShape {
    /// A short name of the kind: "plane", "box", "sphere", "capsule" or "mesh".
    pub fn kind(&self) -> &'static str {
        match self {
            ColliderShape::Plane { .. } => "plane",
            ColliderShape::Box { .. } => "box",
            ColliderShape::Sphere { .. } => "sphere",
            ColliderShape::Capsule { .. } => "capsule",
            ColliderShape::Mesh(_) => "mesh",
        }
    }

    /// Check the numbers (finite values, a non-zero normal, min < max, positive radii and
    /// scale, non-zero rotation axes). Reads no file: [`ColliderShape::load`] checks meshes.
    pub fn validate(&self) -> Result<()> {
        match self {
            ColliderShape::Plane { point, normal } => {
                let ok = point.iter().chain(normal).all(|v| v.is_finite())
                    && normal.iter().any(|v| *v != 0.0);
                if !ok {
                    return Err(Error::param(
                        "collider",
                        format!("{self:?}"),
                        "a plane needs a finite point and a non-zero normal",
                    ));
                }
            }
            ColliderShape::Box { min, max, rotation } => {
                let ok =
                    min.iter().chain(max).all(|v| v.is_finite()) && (0..3).all(|d| min[d] < max[d]);
                if !ok {
                    return Err(Error::param(
                        "collider",
                        format!("{self:?}"),
                        "a box needs finite corners with min < max on every axis",
                    ));
                }
                if let Some(r) = rotation {
                    axis_angle_matrix(r)?;
                }
            }
            ColliderShape::Sphere { center, radius } => {
                finite3("center", center)?;
                positive_radius(*radius)?;
            }
            ColliderShape::Capsule { a, b, radius } => {
                finite3("a", a)?;
                finite3("b", b)?;
                positive_radius(*radius)?;
            }
            ColliderShape::Mesh(m) => {
                m.placement()?;
                if m.file.as_os_str().is_empty() {
                    return Err(Error::param(
                        "file",
                        "\"\"",
                        "a mesh collider needs a file (OBJ, STL, OFF or PLY)",
                    ));
                }
            }
        }
        Ok(())
    }

    /// Read a mesh collider's file (relative paths against `base_dir`) into its shared,
    /// queryable form, unless it was read already; nothing to do for the other shapes.
    ///
    /// # Errors
    /// The file readers' errors with the path; [`crate::geometry::GeometryError`]s for a solid
    /// mesh that is not closed, a degenerate triangle (naming the triangle) or an empty mesh.
    pub fn load(&mut self, base_dir: &Path) -> Result<()> {
        if let ColliderShape::Mesh(m) = self {
            if m.loaded.is_none() {
                m.loaded = Some(Arc::new(MeshObstacle::load(m, base_dir)?));
            }
        }
        Ok(())
    }
}

/// How deep a point is in an obstacle, and the derivatives the penalty needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Penetration {
    /// Depth d > 0, metres (distance to the obstacle's surface).
    pub depth: f64,
    /// Unit push-out direction: the outward gradient of the signed distance.
    pub normal: [f64; 3],
    /// Exact Hessian of d^2/2 with respect to the point (3 x 3, dimensionless).
    pub hessian: Mat3,
    /// Its positive semi-definite part, for Newton (equal to `hessian` where that is PSD).
    pub hessian_psd: Mat3,
}

impl Penetration {
    /// A penetration whose d^2/2 is linear-squared along `u` (planes, boxes): Hessian u u^T.
    fn flat(depth: f64, u: [f64; 3]) -> Penetration {
        let h = outer(&u);
        Penetration {
            depth,
            normal: u,
            hessian: h,
            hessian_psd: h,
        }
    }

    /// Depth `r - rho` from a round surface at distance `rho` from its core (a point, or a
    /// segment with unit direction `axis`), along the unit `u`.
    fn round(r: f64, rho: f64, u: [f64; 3], axis: Option<[f64; 3]>) -> Penetration {
        let uu = outer(&u);
        // Curvature part (rho - r)/rho P, P the projector across u (and across the axis).
        let c = if rho > 0.0 { (rho - r) / rho } else { 0.0 };
        let hessian = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let id = if i == j { 1.0 } else { 0.0 };
                let along = axis.map_or(0.0, |e| e[i] * e[j]);
                uu[i][j] + c * (id - along - uu[i][j])
            })
        });
        Penetration {
            depth: r - rho,
            normal: u,
            hessian,
            hessian_psd: uu,
        }
    }

    /// The same penetration seen in the world frame of a pose with rotation `r`.
    fn rotated(self, r: &Mat3) -> Penetration {
        let rt = transpose(r);
        let turn = |h: &Mat3| mul(&mul(r, h), &rt);
        Penetration {
            depth: self.depth,
            normal: mat_vec(r, &self.normal),
            hessian: turn(&self.hessian),
            hessian_psd: turn(&self.hessian_psd),
        }
    }
}

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
                None => Obstacle::Mesh(Arc::new(MeshObstacle::load(m, Path::new(""))?)),
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

/// The composition `outer` after `inner`: x -> outer(inner(x)).
pub fn compose(outer: &Rigid, inner: &Rigid) -> Rigid {
    let t = outer.apply(&inner.translation);
    Rigid {
        rotation: mul(&outer.rotation, &inner.rotation),
        translation: t,
    }
}

/// The obstacles of a scene with their kinematics: each one's [`Motion`] (scripted, or a
/// [`Motion::Pose`] set by the caller) and optional parent, whose pose it follows
/// (articulated chains: a child's motion is relative to its parent's frame).
#[derive(Debug, Clone)]
pub struct Kinematics {
    obstacles: Vec<Obstacle>,
    motions: Vec<Motion>,
    parents: Vec<Option<usize>>,
}

impl Kinematics {
    /// Obstacles with their motions and parents (indices of earlier obstacles).
    ///
    /// # Errors
    /// Lengths that differ, an invalid motion, or a parent that is not an earlier obstacle.
    pub fn new(
        obstacles: Vec<Obstacle>,
        motions: Vec<Motion>,
        parents: Vec<Option<usize>>,
    ) -> Result<Kinematics> {
        if motions.len() != obstacles.len() || parents.len() != obstacles.len() {
            return Err(Error::LengthMismatch {
                what: "collider motions and parents (one per collider)",
                expected: obstacles.len(),
                got: motions.len().min(parents.len()),
            });
        }
        for (i, (m, p)) in motions.iter().zip(&parents).enumerate() {
            m.validate()?;
            if let Some(p) = p {
                if *p >= i {
                    return Err(Error::param(
                        "parent",
                        p,
                        format!(
                            "collider {i}: a parent must be a collider listed before its child"
                        ),
                    ));
                }
            }
        }
        Ok(Kinematics {
            obstacles,
            motions,
            parents,
        })
    }

    /// Number of obstacles.
    pub fn len(&self) -> usize {
        self.obstacles.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.obstacles.is_empty()
    }

    /// The obstacles, rest frames.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// Each obstacle's own motion (relative to its parent's frame when it has one).
    pub fn motions(&self) -> &[Motion] {
        &self.motions
    }

    /// Each obstacle's parent.
    pub fn parents(&self) -> &[Option<usize>] {
        &self.parents
    }

    /// The pose of every obstacle at time `t` (seconds): its motion at `t`, after its
    /// parent's pose.
    pub fn poses(&self, t: f64) -> Vec<Rigid> {
        let mut poses: Vec<Rigid> = Vec::with_capacity(self.len());
        for (m, p) in self.motions.iter().zip(&self.parents) {
            let own = m.at(t);
            let pose = match p {
                Some(p) => compose(&poses[*p], &own),
                None => own,
            };
            poses.push(pose);
        }
        poses
    }

    /// Replace obstacle `index`'s motion from now on.
    ///
    /// # Errors
    /// An index out of range or an invalid motion.
    pub fn set_motion(&mut self, index: usize, motion: Motion) -> Result<()> {
        motion.validate()?;
        let count = self.len();
        let m = self.motions.get_mut(index).ok_or_else(|| {
            Error::param(
                "collider",
                index,
                format!("there are {count} colliders (indices from 0)"),
            )
        })?;
        *m = motion;
        Ok(())
    }

    /// Replace obstacle `index`'s geometry (its motion and parent stay).
    ///
    /// # Errors
    /// An index out of range.
    pub fn set_obstacle(&mut self, index: usize, obstacle: Obstacle) -> Result<()> {
        let count = self.len();
        let o = self.obstacles.get_mut(index).ok_or_else(|| {
            Error::param(
                "collider",
                index,
                format!("there are {count} colliders (indices from 0)"),
            )
        })?;
        *o = obstacle;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let h = 1e-6;
        for shape in &shapes {
            let o = Obstacle::new(shape).unwrap();
            let mut inside = 0;
            for x in &points {
                let Some(p) = o.penetration(&pose, x) else {
                    continue;
                };
                inside += 1;
                let grad = g(&o, x);
                for i in 0..3 {
                    let mut xp = *x;
                    let mut xm = *x;
                    xp[i] += h;
                    xm[i] -= h;
                    // Central differences of smooth quadratics: error O(h^2) ~ 1e-12,
                    // rounding ~ 1e-16 / h = 1e-10.
                    let fd = (f(&o, &xp) - f(&o, &xm)) / (2.0 * h);
                    assert!(
                        (fd - grad[i]).abs() < 1e-8,
                        "{shape:?} grad {i}: {fd} vs {}",
                        grad[i]
                    );
                    let (gp, gm) = (g(&o, &xp), g(&o, &xm));
                    for j in 0..3 {
                        let fd = (gp[j] - gm[j]) / (2.0 * h);
                        assert!(
                            (fd - p.hessian[j][i]).abs() < 1e-7,
                            "{shape:?} hessian {j}{i}: {fd} vs {}",
                            p.hessian[j][i]
                        );
                    }
                }
            }
            assert!(inside >= 2, "{shape:?}: only {inside} test points inside");
        }
    }
}
