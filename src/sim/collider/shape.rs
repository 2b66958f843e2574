//! What a scene says an obstacle is ([`ColliderShape`], a mesh file with its placement in
//! [`MeshCollider`]) and the checks of those numbers; reading a mesh file makes its
//! [`MeshObstacle`].

use super::mesh::{MeshObstacle, Sided};
use crate::geometry::UpAxis;
use crate::linalg3::Mat3;
use crate::sim::motion::{rotation_matrix, AxisAngle, Rigid};
use crate::{Error, Point3, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;

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
    /// The mesh file, OBJ, STL, OFF or PLY with faces, or a USD stage's mesh prim
    /// (`scene.usda:/World/Table`; docs/usd.md) (relative paths: to the scene file).
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
    /// Read and validate the mesh file (a relative `file` is taken from `base_dir`), placed
    /// by its scale, rotation and translation.
    ///
    /// # Errors
    /// A bad scale or rotation or an empty file name; the readers' `Io` and `Parse` errors
    /// (a PLY without faces is a `Parse` error); the mesh checks of
    /// [`MeshObstacle::from_triangles`].
    pub fn read(&self, base_dir: &Path) -> Result<MeshObstacle> {
        self.read_in(base_dir, UpAxis::Y)
    }

    /// As [`Self::read`], a USD stage's mesh read into a frame whose up axis is `up` (a
    /// scene's, from its gravity); other formats have no up axis.
    ///
    /// # Errors
    /// As [`Self::read`].
    pub fn read_in(&self, base_dir: &Path, up: UpAxis) -> Result<MeshObstacle> {
        ColliderShape::Mesh(self.clone()).validate()?;
        let (scale, pose) = self.placement()?;
        MeshObstacle::read_in(&base_dir.join(&self.file), scale, &pose, self.sided, up)
    }

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
pub(super) fn axis_angle_matrix(a: &AxisAngle) -> Result<Mat3> {
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
        self.load_in(base_dir, UpAxis::Y)
    }

    /// As [`Self::load`], a USD stage's mesh read into a frame whose up axis is `up`.
    ///
    /// # Errors
    /// As [`Self::load`].
    pub fn load_in(&mut self, base_dir: &Path, up: UpAxis) -> Result<()> {
        if let ColliderShape::Mesh(m) = self {
            if m.loaded.is_none() {
                m.loaded = Some(Arc::new(m.read_in(base_dir, up)?));
            }
        }
        Ok(())
    }
}
