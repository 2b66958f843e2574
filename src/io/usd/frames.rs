//! A stage's point-based prims frame by frame (what `freeform render run.usda` draws): which
//! prims there are, the time codes their points are sampled at, and Gaussian splats
//! (`ParticleField3DGaussianSplat`) as centres, covariances, opacities and base colours.

use super::read::{
    open_stage, points_attribute, points_of, shape_of, usd_error, UsdPrimKind, UsdStage,
};
use crate::geometry::{GeometryError, PointCloud, Shape, ShapeOptions, UpAxis};
use crate::io::splat::Splats;
use crate::linalg3::Mat3;
use crate::Point3;
use openusd::sdf::Value;
use openusd::usd::Prim;
use std::path::Path;

/// The point-based prims of a stage and the time codes of their samples.
#[derive(Debug, Clone, PartialEq)]
pub struct UsdStageFrames {
    /// Mesh, Points and ParticleField3DGaussianSplat prims (path, kind), in traversal order.
    pub prims: Vec<(String, UsdPrimKind)>,
    /// The sorted union of their points' (positions') time samples; empty: not animated.
    pub times: Vec<f64>,
    /// The stage's `timeCodesPerSecond` (USD's fallback 24 when unstated).
    pub time_codes_per_second: f64,
}

/// List the stage's point-based prims and the time codes they are sampled at.
///
/// # Errors
/// As [`super::read_usd_geometry`] for a stage that does not open or compose.
pub fn usd_stage_frames(path: &Path) -> Result<UsdStageFrames, GeometryError> {
    open_stage(path)?.frames()
}

impl UsdStage {
    /// The stage's point-based prims and their time codes ([`usd_stage_frames`]).
    ///
    /// # Errors
    /// As [`usd_stage_frames`].
    pub fn frames(&self) -> Result<UsdStageFrames, GeometryError> {
        let stage = self;
        let mut prims = Vec::new();
        let mut times: Vec<f64> = Vec::new();
        for prim in stage.shape_prims() {
            let p = stage.prim(&prim)?;
            let kind = stage.kind(&p)?;
            let name = points_attribute(kind);
            times.extend(p.attribute(name).time_sample_times().unwrap_or_default());
            prims.push((prim, kind));
        }
        times.sort_by(f64::total_cmp);
        times.dedup();
        // USD: timeCodesPerSecond, else framesPerSecond, else 24.
        let rate = |key: &str| {
            match stage.stage.stage_metadata(key) {
                Ok(Some(Value::Double(v))) => Some(v),
                Ok(Some(Value::Float(v))) => Some(f64::from(v)),
                Ok(Some(Value::Int(v))) => Some(f64::from(v)),
                _ => None,
            }
            .filter(|v| v.is_finite() && *v > 0.0)
        };
        let time_codes_per_second = rate("timeCodesPerSecond")
            .or_else(|| rate("framesPerSecond"))
            .unwrap_or(24.0);
        Ok(UsdStageFrames {
            prims,
            times,
            time_codes_per_second,
        })
    }

    /// The splats of `prim` at `time` ([`read_usd_splats`]).
    ///
    /// # Errors
    /// As [`read_usd_splats`].
    pub fn splats(
        &self,
        prim: &str,
        time: Option<f64>,
        up: UpAxis,
    ) -> Result<UsdSplats, GeometryError> {
        let p = self.prim(prim)?;
        if self.kind(&p)? != UsdPrimKind::GaussianSplats {
            return Err(usd_error(
                &self.path,
                prim,
                None,
                "not a ParticleField3DGaussianSplat prim",
            ));
        }
        splats_of(self, &p, time, up)
    }
}

/// Gaussian splats of one prim at one time code, in freeform's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct UsdSplats {
    /// Centres, N x 3, metres.
    pub means: Vec<Point3>,
    /// Covariances R diag(scales^2) R^T pushed through the prim's transform, m^2.
    pub covariances: Vec<Mat3>,
    /// Opacities, 0..1 (as USD stores them; 1 where unstated).
    pub opacities: Vec<f64>,
    /// The degree-0 SH coefficient of each colour channel (zeros where unstated).
    pub sh_dc: Vec<[f64; 3]>,
}

fn float3s(v: Value) -> Option<Vec<[f64; 3]>> {
    points_of(v)
}

fn quats(v: Value) -> Option<Vec<[f64; 4]>> {
    Some(match v {
        Value::QuatfVec(q) => q
            .into_iter()
            .map(|q| [q.w, q.x, q.y, q.z].map(f64::from))
            .collect(),
        Value::QuathVec(q) => q
            .into_iter()
            .map(|q| [q.w, q.x, q.y, q.z].map(|c| c.to_f64()))
            .collect(),
        Value::QuatdVec(q) => q.into_iter().map(|q| [q.w, q.x, q.y, q.z]).collect(),
        _ => return None,
    })
}

fn floats(v: Value) -> Option<Vec<f64>> {
    match v {
        Value::FloatVec(v) => Some(v.into_iter().map(f64::from).collect()),
        Value::DoubleVec(v) => Some(v),
        Value::HalfVec(v) => Some(v.into_iter().map(|c| c.to_f64()).collect()),
        _ => None,
    }
}

/// Read the splats of `prim` (a `ParticleField3DGaussianSplat`) at `time`, in a frame whose
/// up axis is `up`.
///
/// # Errors
/// [`GeometryError::Usd`], naming the attribute, for a prim of another type, missing
/// positions, or arrays whose lengths or types disagree with the positions.
pub fn read_usd_splats(
    path: &Path,
    prim: &str,
    time: Option<f64>,
    up: UpAxis,
) -> Result<UsdSplats, GeometryError> {
    open_stage(path)?.splats(prim, time, up)
}

/// A splat prim's attributes at one time code, in the prim's own units and frame.
struct RawSplats {
    local: Vec<Point3>,
    /// Unit quaternions (w, x, y, z); a zero or missing one is the identity.
    rotations: Vec<[f64; 4]>,
    /// Linear scales (1 where unstated).
    scales: Vec<[f64; 3]>,
    opacities: Vec<f64>,
    degree: usize,
    /// (degree + 1)^2 RGB triples per splat, DC first (zeros where unstated).
    sh: Vec<[f64; 3]>,
}

fn raw_splats(stage: &UsdStage, p: &Prim, time: Option<f64>) -> Result<RawSplats, GeometryError> {
    let prim = p.path().as_str().to_string();
    let err = |attr: &str, reason: String| usd_error(&stage.path, &prim, Some(attr), reason);
    let read = |name: &str| stage.value(p, name, time);
    let local = read("positions")?
        .and_then(float3s)
        .ok_or_else(|| err("positions", "missing, or not a point3f[] array".into()))?;
    let n = local.len();
    let checked = |name: &str, len: usize| -> Result<(), GeometryError> {
        match len == n {
            true => Ok(()),
            false => Err(err(name, format!("{len} values for {n} positions"))),
        }
    };
    let rotations = match read("orientations")? {
        None => vec![[1.0, 0.0, 0.0, 0.0]; n],
        Some(v) => quats(v).ok_or_else(|| err("orientations", "not a quatf[]".into()))?,
    };
    checked("orientations", rotations.len())?;
    // Renderers normalize quaternions; a zero one is the identity.
    let rotations = rotations
        .into_iter()
        .map(|q| {
            let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
            if norm > 0.0 && norm.is_finite() {
                q.map(|c| c / norm)
            } else {
                [1.0, 0.0, 0.0, 0.0]
            }
        })
        .collect();
    let scales = match read("scales")? {
        None => vec![[1.0; 3]; n],
        Some(v) => float3s(v).ok_or_else(|| err("scales", "not a float3[]".into()))?,
    };
    checked("scales", scales.len())?;
    let opacities = match read("opacities")? {
        None => vec![1.0; n],
        Some(v) => floats(v).ok_or_else(|| err("opacities", "not a float[]".into()))?,
    };
    checked("opacities", opacities.len())?;
    let degree = match stage.value(p, "radiance:sphericalHarmonicsDegree", None)? {
        Some(Value::Int(d)) if (0..=3).contains(&d) => d as usize,
        None => 3,
        Some(other) => {
            return Err(err(
                "radiance:sphericalHarmonicsDegree",
                format!("{other:?} is not a degree 0 to 3"),
            ))
        }
    };
    let per = (degree + 1) * (degree + 1);
    let sh_name = "radiance:sphericalHarmonicsCoefficients";
    let sh = match read(sh_name)? {
        None => vec![[0.0; 3]; n * per],
        Some(v) => {
            let sh = float3s(v).ok_or_else(|| err(sh_name, "not a float3[]".into()))?;
            if sh.len() != n * per {
                return Err(err(
                    sh_name,
                    format!("{} triples for {n} splats of degree {degree}", sh.len()),
                ));
            }
            sh
        }
    };
    Ok(RawSplats {
        local,
        rotations,
        scales,
        opacities,
        degree,
        sh,
    })
}

fn splats_of(
    stage: &UsdStage,
    p: &Prim,
    time: Option<f64>,
    up: UpAxis,
) -> Result<UsdSplats, GeometryError> {
    let raw = raw_splats(stage, p, time)?;
    let place = stage.placement(p, time, up)?;
    let a = place.linear();
    let n = raw.local.len();
    let mut means = Vec::with_capacity(n);
    let mut covariances = Vec::with_capacity(n);
    for i in 0..n {
        means.push(place.point(&raw.local[i]).ok_or_else(|| {
            usd_error(
                &stage.path,
                p.path().as_str(),
                Some("positions"),
                format!("position {i} is not finite after the transform"),
            )
        })?);
        let s = raw.scales[i];
        let r = crate::linalg3::quat_to_matrix(&raw.rotations[i]);
        // Sigma = (A R) diag(s^2) (A R)^T.
        let ar: Mat3 = std::array::from_fn(|r_| {
            std::array::from_fn(|c| (0..3).map(|k| a[r_][k] * r[k][c]).sum())
        });
        covariances.push(std::array::from_fn(|x| {
            std::array::from_fn(|y| (0..3).map(|k| ar[x][k] * s[k] * s[k] * ar[y][k]).sum())
        }));
    }
    let per = (raw.degree + 1) * (raw.degree + 1);
    Ok(UsdSplats {
        means,
        covariances,
        opacities: raw.opacities,
        sh_dc: raw.sh.into_iter().step_by(per).collect(),
    })
}

/// A splat prim as 3DGS splats in freeform's frame (what a scene object made from it is
/// simulated and written with): centres through the prim's transform, orientations turned and
/// scales multiplied by it, opacities and SH coefficients as stored (the SH is not turned).
///
/// # Errors
/// As [`read_usd_splats`]; [`GeometryError::Usd`] for a transform that is not a rotation
/// with a uniform scale (a shear or a mirror has no splat form: bake it into the splats), a
/// scale that is not positive, or an opacity outside [0, 1].
pub fn read_usd_splat_object(
    path: &Path,
    prim: &str,
    time: Option<f64>,
    up: UpAxis,
) -> Result<Splats, GeometryError> {
    open_stage(path)?.splat_object(prim, time, up)
}

impl UsdStage {
    /// The splats of `prim` as [`read_usd_splat_object`] reads them.
    ///
    /// # Errors
    /// As [`read_usd_splat_object`].
    pub fn splat_object(
        &self,
        prim: &str,
        time: Option<f64>,
        up: UpAxis,
    ) -> Result<Splats, GeometryError> {
        splat_object(self, prim, time, up)
    }
}

fn splat_object(
    stage: &UsdStage,
    prim: &str,
    time: Option<f64>,
    up: UpAxis,
) -> Result<Splats, GeometryError> {
    let path = stage.path.as_path();
    let p = stage.prim(prim)?;
    let err = |attr: &str, reason: String| usd_error(path, prim, Some(attr), reason);
    let raw = raw_splats(stage, &p, time)?;
    let place = stage.placement(&p, time, up)?;
    let a = place.linear();
    // A = c Q with Q a rotation: A^T A = c^2 I and det A > 0.
    let ata: Mat3 =
        std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[k][i] * a[k][j]).sum()));
    let c2 = (ata[0][0] + ata[1][1] + ata[2][2]) / 3.0;
    let off = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| (ata[i][j] - if i == j { c2 } else { 0.0 }).abs())
        .fold(0.0, f64::max);
    let similar = c2 > 0.0 && off <= 1e-9 * c2 && crate::linalg3::det3(&a) > 0.0;
    if !similar {
        return Err(err(
            "xformOpOrder",
            "a splat prim's transform must be a rotation with a uniform scale (and a \
             translation); bake shears, non-uniform scales and mirrors into the splats"
                .into(),
        ));
    }
    let c = c2.sqrt();
    let q: Mat3 = a.map(|row| row.map(|v| v / c));
    let n = raw.local.len();
    let (mut means, mut log_scales, mut rotations) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..n {
        means.push(place.point(&raw.local[i]).ok_or_else(|| {
            err(
                "positions",
                format!("position {i} is not finite after the transform"),
            )
        })?);
        let s = raw.scales[i];
        if !s.iter().all(|v| *v > 0.0 && v.is_finite()) {
            return Err(err(
                "scales",
                format!("splat {i} has scales {s:?}; they must be positive"),
            ));
        }
        log_scales.push(s.map(|v| (c * v).ln()));
        let r = crate::linalg3::mul(&q, &crate::linalg3::quat_to_matrix(&raw.rotations[i]));
        rotations.push(crate::linalg3::matrix_to_quat(&r));
    }
    let mut logits = Vec::with_capacity(n);
    for (i, &o) in raw.opacities.iter().enumerate() {
        if !(0.0..=1.0).contains(&o) {
            return Err(err(
                "opacities",
                format!("splat {i} has opacity {o}, outside [0, 1]"),
            ));
        }
        // 3DGS files store the opacity before the sigmoid; 0 and 1 are kept finite.
        let o = o.clamp(1e-7, 1.0 - 1e-7);
        logits.push((o / (1.0 - o)).ln());
    }
    let per = (raw.degree + 1) * (raw.degree + 1);
    let k = per - 1;
    let mut sh_dc = Vec::with_capacity(n);
    let mut sh_rest = Vec::with_capacity(n * 3 * k);
    for block in raw.sh.chunks(per) {
        sh_dc.push(block[0]);
        // freeform's rows are channel-major: f_rest_{c K + j} is coefficient j + 1 of channel c.
        for ch in 0..3 {
            sh_rest.extend(block[1..].iter().map(|t| t[ch]));
        }
    }
    Splats::new(
        means, log_scales, rotations, logits, sh_dc, sh_rest, raw.degree,
    )
}

/// The shape a USD prim gives a scene object, and its splats for a splat prim: a mesh or
/// points prim as [`super::read_usd_shape`] reads it, a `ParticleField3DGaussianSplat` as a
/// point cloud of its centres with the splats of [`read_usd_splat_object`] (one opening of
/// the stage).
///
/// # Errors
/// As [`super::read_usd_shape`] and [`read_usd_splat_object`].
pub fn read_usd_object(
    path: &Path,
    prim: Option<&str>,
    time: Option<f64>,
    opts: &ShapeOptions,
) -> Result<(Shape, Option<Splats>), GeometryError> {
    let stage = open_stage(path)?;
    let g = stage.geometry(prim, time, opts.up_axis)?;
    if g.kind == UsdPrimKind::GaussianSplats {
        let splats = stage.splat_object(&g.prim, time, opts.up_axis)?;
        let cloud = PointCloud::new(splats.means.clone())?;
        return Ok((Shape::PointCloud(cloud), Some(splats)));
    }
    Ok((shape_of(path, g, opts)?, None))
}
