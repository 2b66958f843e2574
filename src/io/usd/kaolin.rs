//! Kaolin's physics schemas (Kaolin PR #972, `kaolin/io/usd/custom_schema/schema.usda`):
//! `KaolinPhysicsMaterialAPI` (materials at sample points) and `KaolinSkinnedPhysicsAPI`
//! (materials and skinning weights at cubature points, weights at the render points), both
//! multiple-apply API schemas with attributes `kaolin_physics_material:<instance>:<name>` and
//! `kaolin_skinned_physics:<instance>:<name>`. Weights are flattened row-major (N x M, then
//! N x M x 3 for their gradients), M handles including the constant one (Kaolin appends it
//! last); M is not stored.

use super::layer::{StageMetadata, UsdLayer, UsdValue, WORLD};
use super::read::{open_stage, points_of};
use crate::geometry::{GeometryError, UpAxis};
use crate::material::MaterialField;
use crate::precompute::skinning::{Basis, SkinningWeights};
use crate::Point3;
use openusd::sdf::Value;
use std::path::Path;

/// The material schema's name.
pub const MATERIAL_API: &str = "KaolinPhysicsMaterialAPI";
/// The skinned-physics schema's name.
pub const SKINNED_API: &str = "KaolinSkinnedPhysicsAPI";
/// The material schema's attribute namespace.
pub const MATERIAL_PREFIX: &str = "kaolin_physics_material";
/// The skinned-physics schema's attribute namespace.
pub const SKINNED_PREFIX: &str = "kaolin_skinned_physics";
/// The instance name Kaolin uses unless told otherwise.
pub const DEFAULT_INSTANCE: &str = "default";

/// Points with materials, as both schemas store them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct KaolinPoints {
    /// Sample (or cubature) points, N x 3, metres.
    pub points: Vec<Point3>,
    /// Young's modulus per point, Pa.
    pub youngs: Vec<f64>,
    /// Poisson ratio per point.
    pub poisson: Vec<f64>,
    /// Density per point, kg/m^3.
    pub density: Vec<f64>,
    /// The object's approximate volume, m^3.
    pub volume: f64,
}

/// Skinning weights as `KaolinSkinnedPhysicsAPI` stores them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct KaolinWeights {
    /// Handles M. A run writes freeform's m modes, then the constant handle last (ones,
    /// gradient 0), as Kaolin appends it.
    pub handles: usize,
    /// W_j(X_i) at `values[i * handles + j]`, N x M (freeform's modes in m^(-3/2)).
    pub values: Vec<f64>,
    /// d W_j / d x_k (X_i) at `gradients[(i * handles + j) * 3 + k]`, N x M x 3.
    pub gradients: Vec<f64>,
    /// Weights at the prim's own render points (its `points` or `positions`), R x M.
    pub render: Option<Vec<f64>>,
}

/// What a prim carries of the two schemas (instance `default` unless asked otherwise).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct KaolinPhysics {
    /// `KaolinPhysicsMaterialAPI`: materials at sample points.
    pub material: Option<KaolinPoints>,
    /// `KaolinSkinnedPhysicsAPI`: materials at cubature points and their weights.
    pub skinned: Option<(KaolinPoints, KaolinWeights)>,
}

impl KaolinWeights {
    /// freeform's weights (m + 1 modes, the constant mode first) in Kaolin's handle order:
    /// the m modes, then the constant handle (ones, gradient 0) last, as Kaolin appends it;
    /// `render`: the weights at the render points, likewise.
    pub fn from_modes(w: &SkinningWeights, render: Option<&SkinningWeights>) -> KaolinWeights {
        let handles = w.modes;
        let rows = |values: &[f64]| -> Vec<f64> {
            values
                .chunks(handles)
                .flat_map(|row| row[1..].iter().copied().chain([1.0]))
                .collect()
        };
        KaolinWeights {
            handles,
            values: rows(&w.values),
            gradients: w
                .gradients
                .chunks(handles)
                .flat_map(|row| row[1..].iter().flatten().copied().chain([0.0; 3]))
                .collect(),
            render: render.map(|r| rows(&r.values)),
        }
    }
}

/// Write `basis` as a USD stage Kaolin loads (`freeform modes --usd`): one `Points` prim
/// `/World/<name>` (a valid prim name) at the integration points (N x 3, metres), carrying
/// `KaolinPhysicsMaterialAPI` (the points' materials and total volume, `volumes` N, m^3) and
/// `KaolinSkinnedPhysicsAPI` with the same points as cubature points and the weights there
/// ([`KaolinWeights::from_modes`]). Written atomically.
///
/// # Errors
/// Weights that cannot be evaluated at the points (coverage); [`crate::Error::Io`] when the
/// file cannot be written.
pub fn write_basis_stage(
    path: &Path,
    name: &str,
    points: &[Point3],
    volumes: &[f64],
    material: &MaterialField,
    basis: &Basis,
) -> crate::Result<()> {
    let mut layer = UsdLayer::new(StageMetadata {
        time_codes_per_second: None,
        time_range: None,
        up_axis: UpAxis::Y,
        meters_per_unit: 1.0,
        documentation: "freeform basis: Kaolin's physics schemas at the integration points".into(),
    });
    let prim = layer.define(
        WORLD,
        &super::unique_prim_name(name, &mut Vec::new()),
        "Points",
    );
    let f3 = points.iter().map(|p| p.map(|c| c as f32)).collect();
    layer.set(&prim, "points", "point3f[]", UsdValue::Float3s(f3));
    let at_points = KaolinPoints {
        points: points.to_vec(),
        youngs: material.youngs.clone(),
        poisson: material.poisson.clone(),
        density: material.density.clone(),
        volume: volumes.iter().sum(),
    };
    write_material(&mut layer, &prim, DEFAULT_INSTANCE, &at_points);
    let w = basis.weights(points)?;
    let weights = KaolinWeights::from_modes(&w, Some(&w));
    write_skinned(&mut layer, &prim, DEFAULT_INSTANCE, &at_points, &weights);
    super::write_usda(&layer, path)
}

fn f32s(v: &[f64]) -> Vec<f32> {
    v.iter().map(|&x| x as f32).collect()
}

fn write_points(layer: &mut UsdLayer, prim: &str, prefix: &str, p: &KaolinPoints) {
    let pts = p.points.iter().map(|q| q.map(|c| c as f32)).collect();
    layer.set(
        prim,
        &format!("{prefix}:pts"),
        "point3f[]",
        UsdValue::Float3s(pts),
    );
    layer.set(
        prim,
        &format!("{prefix}:yms"),
        "float[]",
        UsdValue::Floats(f32s(&p.youngs)),
    );
    layer.set(
        prim,
        &format!("{prefix}:prs"),
        "float[]",
        UsdValue::Floats(f32s(&p.poisson)),
    );
    layer.set(
        prim,
        &format!("{prefix}:rhos"),
        "float[]",
        UsdValue::Floats(f32s(&p.density)),
    );
    layer.set(
        prim,
        &format!("{prefix}:appx_vol"),
        "float",
        UsdValue::Float(p.volume as f32),
    );
}

/// Apply `KaolinPhysicsMaterialAPI:<instance>` to `prim` with every attribute it defines.
pub fn write_material(layer: &mut UsdLayer, prim: &str, instance: &str, p: &KaolinPoints) {
    layer.apply_api(prim, &format!("{MATERIAL_API}:{instance}"));
    write_points(layer, prim, &format!("{MATERIAL_PREFIX}:{instance}"), p);
}

/// Apply `KaolinSkinnedPhysicsAPI:<instance>` to `prim` with every attribute it defines
/// (`renderable_skinning_weights` when `w.render` is given).
pub fn write_skinned(
    layer: &mut UsdLayer,
    prim: &str,
    instance: &str,
    p: &KaolinPoints,
    w: &KaolinWeights,
) {
    let prefix = format!("{SKINNED_PREFIX}:{instance}");
    layer.apply_api(prim, &format!("{SKINNED_API}:{instance}"));
    write_points(layer, prim, &prefix, p);
    let set = |layer: &mut UsdLayer, name: &str, v: &[f64]| {
        layer.set(
            prim,
            &format!("{prefix}:{name}"),
            "float[]",
            UsdValue::Floats(f32s(v)),
        );
    };
    set(layer, "skinning_weights", &w.values);
    set(layer, "dwdx", &w.gradients);
    if let Some(r) = &w.render {
        set(layer, "renderable_skinning_weights", r);
    }
}

/// Read the Kaolin physics of `prim` in the stage at `path`, instance `instance` of each
/// schema (a schema the prim does not carry is None), at time code `time` (None: the default
/// values, as Kaolin writes them unless given a time). Values are as stored (the schemas state
/// metres and SI units; the prim's transform and the stage's units are not applied, as in
/// Kaolin).
///
/// # Errors
/// [`GeometryError::Usd`], naming the prim and the attribute, for a stage that does not
/// open, a missing prim, a schema applied with an attribute missing or of the wrong type,
/// arrays whose lengths disagree with the points, or weights not a whole number of handles
/// per point.
pub fn read_kaolin(
    path: &Path,
    prim: &str,
    instance: &str,
    time: Option<f64>,
) -> Result<KaolinPhysics, GeometryError> {
    let stage = open_stage(path)?;
    let p = stage.prim(prim)?;
    let applied: Vec<String> = p
        .api_schemas()
        .unwrap_or_default()
        .iter()
        .map(|t| t.as_str().to_string())
        .collect();
    let err = |attr: &str, reason: String| GeometryError::Usd {
        path: path.to_path_buf(),
        prim: prim.to_string(),
        attribute: Some(attr.to_string()),
        reason,
    };
    let has = |schema: &str, prefix: &str| {
        applied.iter().any(|a| *a == format!("{schema}:{instance}"))
            || p.attribute(format!("{prefix}:{instance}:pts"))
                .get::<Value>()
                .ok()
                .flatten()
                .is_some()
    };
    let floats = |name: &str, required: bool| -> Result<Option<Vec<f64>>, GeometryError> {
        match stage.value(&p, name, time)? {
            None if required => Err(err(name, "missing (the schema requires it)".into())),
            None => Ok(None),
            Some(Value::FloatVec(v)) => Ok(Some(v.into_iter().map(f64::from).collect())),
            Some(Value::DoubleVec(v)) => Ok(Some(v)),
            Some(other) => Err(err(name, format!("not a float[] array ({other:?})"))),
        }
    };
    let points = |prefix: &str| -> Result<KaolinPoints, GeometryError> {
        let name = format!("{prefix}:pts");
        let pts = stage
            .value(&p, &name, time)?
            .ok_or_else(|| err(&name, "missing (the schema requires it)".into()))?;
        let pts = points_of(pts).ok_or_else(|| err(&name, "not a point3f[] array".into()))?;
        let n = pts.len();
        let per_point = |suffix: &str| -> Result<Vec<f64>, GeometryError> {
            let name = format!("{prefix}:{suffix}");
            let v = floats(&name, true)?.unwrap_or_default();
            if v.len() != n {
                return Err(err(&name, format!("{} values for {n} points", v.len())));
            }
            Ok(v)
        };
        let vol_name = format!("{prefix}:appx_vol");
        let volume = match stage.value(&p, &vol_name, time)? {
            Some(Value::Float(v)) => f64::from(v),
            Some(Value::Double(v)) => v,
            None => return Err(err(&vol_name, "missing (the schema requires it)".into())),
            Some(other) => return Err(err(&vol_name, format!("not a float ({other:?})"))),
        };
        Ok(KaolinPoints {
            youngs: per_point("yms")?,
            poisson: per_point("prs")?,
            density: per_point("rhos")?,
            points: pts,
            volume,
        })
    };
    let mut out = KaolinPhysics::default();
    if has(MATERIAL_API, MATERIAL_PREFIX) {
        out.material = Some(points(&format!("{MATERIAL_PREFIX}:{instance}"))?);
    }
    if has(SKINNED_API, SKINNED_PREFIX) {
        let prefix = format!("{SKINNED_PREFIX}:{instance}");
        let pts = points(&prefix)?;
        let n = pts.points.len();
        let w_name = format!("{prefix}:skinning_weights");
        let values = floats(&w_name, true)?.unwrap_or_default();
        if n == 0 || values.is_empty() || values.len() % n != 0 {
            return Err(err(
                &w_name,
                format!(
                    "{} values are not a whole number of handles for {n} points",
                    values.len()
                ),
            ));
        }
        let handles = values.len() / n;
        let g_name = format!("{prefix}:dwdx");
        let gradients = floats(&g_name, true)?.unwrap_or_default();
        if gradients.len() != values.len() * 3 {
            return Err(err(
                &g_name,
                format!("{} values, expected {n} x {handles} x 3", gradients.len()),
            ));
        }
        let r_name = format!("{prefix}:renderable_skinning_weights");
        let render = floats(&r_name, false)?;
        if let Some(r) = &render {
            if r.len() % handles != 0 {
                return Err(err(
                    &r_name,
                    format!(
                        "{} values are not a whole number of rows of {handles}",
                        r.len()
                    ),
                ));
            }
        }
        out.skinned = Some((
            pts,
            KaolinWeights {
                handles,
                values,
                gradients,
                render,
            },
        ));
    }
    Ok(out)
}
