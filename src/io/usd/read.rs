//! Reading USD prims as shapes (through `openusd`: usda, usdc, usdz; references, payloads and
//! sublayers composed as USD composes them): a `Mesh` (polygons fan-triangulated, holes
//! skipped), a `Points` prim, or a `ParticleField3DGaussianSplat` (its positions), with the
//! prim's transform composed up the hierarchy, the stage's `metersPerUnit` and `upAxis`
//! applied.

use crate::geometry::{GeometryError, PointCloud, Shape, ShapeOptions, UpAxis};
use crate::linalg3::Mat3;
use crate::Point3;
use openusd::gf;
use openusd::schemas::geom::{Imageable, Xformable};
use openusd::sdf::Value;
use openusd::usd::{self, Prim, SchemaBase, SchemaKind, TimeCode};
use std::path::{Path, PathBuf};

/// What kind of prim a [`UsdGeometry`] came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UsdPrimKind {
    /// `Mesh`: points and triangles.
    Mesh,
    /// `Points`: points only.
    Points,
    /// `ParticleField3DGaussianSplat`: the splat centres (`positions`).
    GaussianSplats,
}

/// One prim's geometry in freeform's frame: metres, the asked up axis, transforms applied.
#[derive(Debug, Clone, PartialEq)]
pub struct UsdGeometry {
    /// The prim path read.
    pub prim: String,
    /// What the prim is.
    pub kind: UsdPrimKind,
    /// Points, N x 3, metres.
    pub points: Vec<Point3>,
    /// Triangles (zero-based indices into `points`), for a mesh.
    pub triangles: Option<Vec<[u32; 3]>>,
}

/// USD's fallback `metersPerUnit` when a stage states none (centimetres).
pub const FALLBACK_METERS_PER_UNIT: f64 = 0.01;

/// An error about `prim` (and `attribute`) of the stage at `path`.
pub(crate) fn usd_error(
    path: &Path,
    prim: &str,
    attribute: Option<&str>,
    reason: impl Into<String>,
) -> GeometryError {
    GeometryError::Usd {
        path: path.to_path_buf(),
        prim: prim.to_string(),
        attribute: attribute.map(str::to_string),
        reason: reason.into(),
    }
}

/// An opened, composed stage and the file it came from (for errors): open it once to read
/// several prims or time codes.
pub struct UsdStage {
    pub(crate) path: PathBuf,
    pub(crate) stage: usd::Stage,
}

/// Open the stage at `path` (usda, usdc or usdz; every payload loaded).
///
/// # Errors
/// [`GeometryError::Io`] for a missing file; [`GeometryError::Usd`] (prim `/`) when the stage
/// does not open or one of its references, payloads or sublayers does not resolve.
pub(crate) fn open_stage(path: &Path) -> Result<UsdStage, GeometryError> {
    std::fs::metadata(path).map_err(|source| GeometryError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let name = path.to_string_lossy();
    let stage = usd::Stage::open(&name)
        .map_err(|e| usd_error(path, "/", None, format!("the stage does not open: {e:#}")))?;
    if let Some(e) = stage.composition_errors().first() {
        return Err(usd_error(
            path,
            "/",
            None,
            format!("the stage does not compose: {e}"),
        ));
    }
    Ok(UsdStage {
        path: path.to_path_buf(),
        stage,
    })
}

impl UsdStage {
    /// Open the stage at `path` (usda, usdc or usdz; references, payloads and sublayers
    /// composed, every payload loaded).
    ///
    /// # Errors
    /// [`GeometryError::Io`] for a missing file; [`GeometryError::Usd`] (prim `/`) when the
    /// stage does not open or compose.
    pub fn open(path: &Path) -> Result<UsdStage, GeometryError> {
        open_stage(path)
    }

    /// The prim at `prim`, which must exist.
    pub(crate) fn prim(&self, prim: &str) -> Result<Prim, GeometryError> {
        let err = |reason: String| usd_error(&self.path, prim, None, reason);
        let path = openusd::sdf::path(prim).map_err(|e| err(format!("not a prim path: {e}")))?;
        let p = self.stage.prim(path);
        let valid = p.is_valid();
        // References and payloads report failures as the prims they lead to are composed.
        if let Some(e) = self.stage.composition_errors().first() {
            return Err(err(format!("the stage does not compose: {e}")));
        }
        match valid {
            Ok(true) => Ok(p),
            _ => Err(err(format!(
                "no such prim; the stage has {}",
                self.describe_prims()
            ))),
        }
    }

    /// Paths of the prims of the types freeform reads, in traversal order.
    pub(crate) fn shape_prims(&self) -> Vec<String> {
        let mut found = Vec::new();
        let _ = self.stage.traverse(usd::PrimPredicate::DEFAULT, |path| {
            let p = self.stage.prim(path.clone());
            if let Ok(Some(t)) = p.type_name() {
                if kind_of(t.as_str()).is_some() {
                    found.push(path.as_str().to_string());
                }
            }
        });
        found
    }

    fn describe_prims(&self) -> String {
        let found = self.shape_prims();
        if found.is_empty() {
            return "no Mesh, Points or ParticleField3DGaussianSplat prim".into();
        }
        let shown: Vec<&str> = found.iter().take(8).map(String::as_str).collect();
        let more = if found.len() > 8 {
            format!(" and {} more", found.len() - 8)
        } else {
            String::new()
        };
        format!(
            "these mesh, points and splat prims: {}{more}",
            shown.join(", ")
        )
    }

    /// What kind of point-based prim `p` is.
    pub(crate) fn kind(&self, p: &Prim) -> Result<UsdPrimKind, GeometryError> {
        let type_name = p.type_name().ok().flatten().map(|t| t.as_str().to_string());
        type_name.as_deref().and_then(kind_of).ok_or_else(|| {
            usd_error(
                &self.path,
                p.path().as_str(),
                None,
                format!(
                    "the prim is {}; freeform reads Mesh, Points and \
                     ParticleField3DGaussianSplat prims",
                    type_name.map_or("untyped".to_string(), |t| format!("a `{t}`"))
                ),
            )
        })
    }

    /// Value of attribute `name` of `prim` at `time` (None: the default value, or the only
    /// way to read it when it has time samples and no default is refused).
    pub(crate) fn value(
        &self,
        prim: &Prim,
        name: &str,
        time: Option<f64>,
    ) -> Result<Option<Value>, GeometryError> {
        let path = prim.path().as_str();
        let err = |reason: String| usd_error(&self.path, path, Some(name), reason);
        if let Some(t) = time.filter(|t| !t.is_finite()) {
            return Err(err(format!("the time code {t} is not finite")));
        }
        let attr = prim.attribute(name);
        let read = match time {
            Some(t) => attr.get_at::<Value>(TimeCode::new(t)),
            None => {
                let times = attr.time_sample_times().unwrap_or_default();
                match attr.get::<Value>() {
                    Ok(None) if !times.is_empty() => {
                        return Err(err(format!(
                            "{} time samples ({} to {}) and no default value; name the time \
                             code to read (a shape: FILE:{path}@{})",
                            times.len(),
                            times[0],
                            times[times.len() - 1],
                            times[0]
                        )))
                    }
                    other => other,
                }
            }
        };
        read.map_err(|e| err(format!("cannot be read: {e:#}")))
    }

    /// The stage's metres per unit and up axis.
    fn units(&self) -> Result<(f64, UpAxis), GeometryError> {
        let err = |attr: &str, reason: String| usd_error(&self.path, "/", Some(attr), reason);
        let mpu = match self.stage.stage_metadata("metersPerUnit") {
            Ok(None) => FALLBACK_METERS_PER_UNIT,
            Ok(Some(Value::Double(v))) if v.is_finite() && v > 0.0 => v,
            Ok(Some(Value::Float(v))) if v.is_finite() && v > 0.0 => f64::from(v),
            Ok(Some(v)) => {
                return Err(err(
                    "metersPerUnit",
                    format!("{v:?} is not a positive finite number of metres"),
                ))
            }
            Err(e) => return Err(err("metersPerUnit", format!("{e:#}"))),
        };
        let up = match self.stage.stage_metadata("upAxis") {
            Ok(None) => UpAxis::Y,
            Ok(Some(Value::Token(t))) => UpAxis::from_token(t.as_str()).ok_or_else(|| {
                err(
                    "upAxis",
                    format!("`{}` is not supported (USD allows Y or Z)", t.as_str()),
                )
            })?,
            Ok(Some(v)) => return Err(err("upAxis", format!("{v:?} is not Y or Z"))),
            Err(e) => return Err(err("upAxis", format!("{e:#}"))),
        };
        Ok((mpu, up))
    }

    /// Where prim `p`'s coordinates land at `time`, in a frame whose up axis is `up`.
    pub(crate) fn placement(
        &self,
        p: &Prim,
        time: Option<f64>,
        up: UpAxis,
    ) -> Result<Placement, GeometryError> {
        let matrix = self.local_to_world(p, time)?;
        let (meters_per_unit, from) = self.units()?;
        let m = &matrix.0;
        // Affine transforms only: a projective column would bend the points and leave the
        // splats' covariances meaningless.
        if m[3] != 0.0 || m[7] != 0.0 || m[11] != 0.0 || m[15] != 1.0 {
            return Err(usd_error(
                &self.path,
                p.path().as_str(),
                Some("xformOpOrder"),
                format!(
                    "the prim's transform is not affine (last column {:?}); freeform reads \
                     translations, rotations, scales and shears",
                    [m[3], m[7], m[11], m[15]]
                ),
            ));
        }
        Ok(Placement {
            matrix: matrix.0,
            meters_per_unit,
            from,
            to: up,
        })
    }

    /// The prim's local-to-world matrix at `time`: its xform stack and its ancestors', up to
    /// the root or a `!resetXformStack!`.
    fn local_to_world(
        &self,
        prim: &Prim,
        time: Option<f64>,
    ) -> Result<gf::Matrix4d, GeometryError> {
        let tc = time.map_or(TimeCode::EARLIEST, TimeCode::new);
        let mut m = gf::Matrix4d::IDENTITY;
        let mut current = Some(prim.path().clone());
        while let Some(path) = current {
            if path.as_str() == "/" {
                break;
            }
            let view = AnyXformable(self.stage.prim(path.clone()));
            let err = |e: &dyn std::fmt::Display| {
                usd_error(
                    &self.path,
                    path.as_str(),
                    Some("xformOpOrder"),
                    format!("{e:#}"),
                )
            };
            // Row vectors: a point goes through its own prim's stack first.
            m = m * view.local_to_parent_transform(tc).map_err(|e| err(&e))?;
            if view.resets_xform_stack().map_err(|e| err(&e))? {
                break;
            }
            current = path.parent();
        }
        Ok(m)
    }
}

/// Where a prim's own coordinates land in freeform's frame: the prim's local-to-world matrix
/// (row vectors, as USD), then the stage's metres per unit, then its up axis turned to `to`.
pub(crate) struct Placement {
    matrix: [f64; 16],
    meters_per_unit: f64,
    from: UpAxis,
    to: UpAxis,
}

impl Placement {
    /// Point `q` (prim units) in metres in freeform's frame; None when not finite.
    pub(crate) fn point(&self, q: &Point3) -> Option<Point3> {
        let m = &self.matrix;
        let mut x = [0.0; 4];
        for (j, xj) in x.iter_mut().enumerate() {
            *xj = q[0] * m[j] + q[1] * m[4 + j] + q[2] * m[8 + j] + m[12 + j];
        }
        // The matrix is affine (checked when the placement is made): w = 1.
        let world = [x[0], x[1], x[2]].map(|c| c * self.meters_per_unit);
        world
            .iter()
            .all(|c| c.is_finite())
            .then(|| self.from.convert(self.to, world))
    }

    /// The linear part A (column vectors: dx_world = A dx_local), metres per prim unit.
    pub(crate) fn linear(&self) -> Mat3 {
        let m = &self.matrix;
        let cols: [[f64; 3]; 3] = std::array::from_fn(|k| {
            let row = [m[4 * k], m[4 * k + 1], m[4 * k + 2]].map(|c| c * self.meters_per_unit);
            self.from.convert(self.to, row)
        });
        // Row k of USD's matrix is where local axis k goes: column k of A.
        std::array::from_fn(|i| std::array::from_fn(|k| cols[k][i]))
    }
}

/// Any prim viewed as `Xformable` (a prim without `xformOpOrder` has the identity).
struct AnyXformable(Prim);

impl SchemaBase for AnyXformable {
    const KIND: SchemaKind = SchemaKind::ConcreteTyped;
    fn prim(&self) -> &Prim {
        &self.0
    }
}
impl Imageable for AnyXformable {}
impl Xformable for AnyXformable {}

/// The attribute holding a prim's points.
pub(crate) fn points_attribute(kind: UsdPrimKind) -> &'static str {
    match kind {
        UsdPrimKind::GaussianSplats => "positions",
        _ => "points",
    }
}

fn kind_of(type_name: &str) -> Option<UsdPrimKind> {
    match type_name {
        "Mesh" => Some(UsdPrimKind::Mesh),
        "Points" => Some(UsdPrimKind::Points),
        "ParticleField3DGaussianSplat" => Some(UsdPrimKind::GaussianSplats),
        _ => None,
    }
}

/// Points of a `point3f[]` / `point3d[]` / `point3h[]` value, in file units.
pub(crate) fn points_of(value: Value) -> Option<Vec<Point3>> {
    Some(match value {
        Value::Vec3fVec(v) => v
            .into_iter()
            .map(|p| [f64::from(p.x), f64::from(p.y), f64::from(p.z)])
            .collect(),
        Value::Vec3dVec(v) => v.into_iter().map(|p| [p.x, p.y, p.z]).collect(),
        Value::Vec3hVec(v) => v
            .into_iter()
            .map(|p| [p.x.to_f64(), p.y.to_f64(), p.z.to_f64()])
            .collect(),
        _ => return None,
    })
}

fn ints_of(value: Value) -> Option<Vec<i32>> {
    match value {
        Value::IntVec(v) => Some(v),
        _ => None,
    }
}

/// Read the geometry of prim `prim` (None: the stage's only Mesh, Points or
/// ParticleField3DGaussianSplat prim) of the stage at `path`, at time code `time` (None: the
/// default values), in metres in a frame whose up axis is `up`.
///
/// # Errors
/// [`GeometryError::Io`] for a missing file; [`GeometryError::Usd`], naming the prim and the
/// attribute, for a stage that does not open or compose, a prim that does not exist or is of
/// another type, no prim to choose or several, a mesh without points or with faces that index
/// past them, time-sampled points read without a time code, non-finite coordinates, or
/// units or an up axis the reader does not support.
pub fn read_usd_geometry(
    path: &Path,
    prim: Option<&str>,
    time: Option<f64>,
    up: UpAxis,
) -> Result<UsdGeometry, GeometryError> {
    open_stage(path)?.geometry(prim, time, up)
}

impl UsdStage {
    /// The geometry of prim `prim` (None: the stage's only point-based prim) at `time`, as
    /// [`read_usd_geometry`] reads it.
    ///
    /// # Errors
    /// As [`read_usd_geometry`].
    pub fn geometry(
        &self,
        prim: Option<&str>,
        time: Option<f64>,
        up: UpAxis,
    ) -> Result<UsdGeometry, GeometryError> {
        let stage = self;
        let path = self.path.as_path();
        let prim_path =
            match prim {
                Some(p) => p.to_string(),
                None => {
                    let found = stage.shape_prims();
                    match found.as_slice() {
                        [one] => one.clone(),
                        [] => return Err(usd_error(
                            path,
                            "/",
                            None,
                            "the stage has no Mesh, Points or ParticleField3DGaussianSplat prim",
                        )),
                        _ => {
                            return Err(usd_error(
                                path,
                                "/",
                                None,
                                format!(
                                "the stage has several prims to read; name one as FILE:/Prim/Path \
                                 ({})",
                                stage.describe_prims()
                            ),
                            ))
                        }
                    }
                }
            };
        let p = stage.prim(&prim_path)?;
        let err = |attr: Option<&str>, reason: String| usd_error(path, &prim_path, attr, reason);
        let kind = stage.kind(&p)?;
        let points_name = points_attribute(kind);
        let raw = stage
            .value(&p, points_name, time)?
            .ok_or_else(|| err(Some(points_name), "the prim has no points".into()))?;
        let local = points_of(raw).ok_or_else(|| {
            err(
                Some(points_name),
                "not an array of 3-vectors (point3f[], point3d[] or point3h[])".into(),
            )
        })?;
        if local.is_empty() {
            return Err(err(
                Some(points_name),
                "the prim has no points (empty array)".into(),
            ));
        }
        let place = stage.placement(&p, time, up)?;
        let triangles = match kind {
            UsdPrimKind::Mesh => {
                let mut t = mesh_triangles(stage, &p, time, local.len(), &err)?;
                // Faces wind counter-clockwise about the outside in a right-handed mesh; a
                // left-handed one, or a mirroring transform (but not both), turns them.
                let left = matches!(
                    stage.value(&p, "orientation", None)?,
                    Some(Value::Token(o)) if o.as_str() == "leftHanded"
                );
                if left != (crate::linalg3::det3(&place.linear()) < 0.0) {
                    for tri in &mut t {
                        tri.swap(1, 2);
                    }
                }
                Some(t)
            }
            _ => None,
        };
        let mut points = Vec::with_capacity(local.len());
        for (i, q) in local.iter().enumerate() {
            let world = place.point(q).ok_or_else(|| {
                err(
                    Some(points_name),
                    format!("point {i} is not finite after the prim's transform ({q:?})"),
                )
            })?;
            points.push(world);
        }
        Ok(UsdGeometry {
            prim: prim_path.clone(),
            kind,
            points,
            triangles,
        })
    }
}

/// The mesh's faces, fan-triangulated (holes skipped), checked against `n` points.
fn mesh_triangles(
    stage: &UsdStage,
    p: &Prim,
    time: Option<f64>,
    n: usize,
    err: &dyn Fn(Option<&str>, String) -> GeometryError,
) -> Result<Vec<[u32; 3]>, GeometryError> {
    let (counts_name, indices_name) = ("faceVertexCounts", "faceVertexIndices");
    let read_ints = |name: &str| -> Result<Option<Vec<i32>>, GeometryError> {
        match stage.value(p, name, time)? {
            None => Ok(None),
            Some(v) => ints_of(v)
                .map(Some)
                .ok_or_else(|| err(Some(name), "not an int[] array".into())),
        }
    };
    let counts = read_ints(counts_name)?
        .ok_or_else(|| err(Some(counts_name), "the mesh has no faces".into()))?;
    let indices = read_ints(indices_name)?.ok_or_else(|| {
        err(
            Some(indices_name),
            "the mesh has no face vertex indices".into(),
        )
    })?;
    let holes: Vec<i32> = read_ints("holeIndices")?.unwrap_or_default();
    let mut triangles = Vec::with_capacity(indices.len());
    let mut start = 0usize;
    for (f, &c) in counts.iter().enumerate() {
        if c < 3 {
            return Err(err(
                Some(counts_name),
                format!("face {f} has {c} vertices (at least 3 are needed)"),
            ));
        }
        let c = c as usize;
        let Some(face) = indices.get(start..start + c) else {
            return Err(err(
                Some(indices_name),
                format!(
                    "{} indices, fewer than the {} the face counts add up to",
                    indices.len(),
                    counts.iter().map(|&c| c.max(0) as usize).sum::<usize>()
                ),
            ));
        };
        start += c;
        let mut idx = Vec::with_capacity(c);
        for &v in face {
            if v < 0 || v as usize >= n {
                return Err(err(
                    Some(indices_name),
                    format!("face {f} indexes point {v}, past the {n} points"),
                ));
            }
            idx.push(v as u32);
        }
        if holes.contains(&(f as i32)) {
            continue;
        }
        for k in 1..c - 1 {
            triangles.push([idx[0], idx[k], idx[k + 1]]);
        }
    }
    if start != indices.len() {
        return Err(err(
            Some(indices_name),
            format!(
                "{} indices, more than the {start} the face counts add up to",
                indices.len()
            ),
        ));
    }
    Ok(triangles)
}

/// The shape a USD prim describes: a mesh prim as a watertight [`crate::geometry::TriMesh`]
/// (or an open one with `opts.allow_open_mesh`), a points or splat prim as a point cloud.
///
/// # Errors
/// As [`read_usd_geometry`]; the mesh checks of [`crate::geometry::TriMesh::new`] with the
/// file's path.
pub fn read_usd_shape(
    path: &Path,
    prim: Option<&str>,
    time: Option<f64>,
    opts: &ShapeOptions,
) -> Result<Shape, GeometryError> {
    shape_of(
        path,
        read_usd_geometry(path, prim, time, opts.up_axis)?,
        opts,
    )
}

/// The shape of geometry `g` read from the stage at `path`: a checked mesh, or a cloud.
pub(crate) fn shape_of(
    path: &Path,
    g: UsdGeometry,
    opts: &ShapeOptions,
) -> Result<Shape, GeometryError> {
    match g.triangles {
        Some(t) => {
            let label = PathBuf::from(format!("{}:{}", path.display(), g.prim));
            Ok(Shape::Mesh(super::super::file::mesh_from_file_data(
                &label, g.points, t, opts,
            )?))
        }
        None => Ok(Shape::PointCloud(PointCloud::new(g.points)?)),
    }
}
