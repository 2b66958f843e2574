//! A run as one time-sampled USD stage (`<out>/run.usda`; docs/usd.md): every object's
//! deformed mesh, points or Gaussian splats and its render inputs, the colliders with their
//! poses, the stress where asked, and Kaolin's physics schemas on each object's prim. Time
//! codes are step indices with `timeCodesPerSecond = 1 / dt`. The samples are held in memory
//! (f32) and the stage is written at the end of the run (also a stopped one), atomically.

use super::object::SceneObject;
use super::stress_arrays::StressArrays;
use super::world::World;
use crate::geometry::UpAxis;
use crate::io::splat::{sigmoid, MovedSplats, Splats};
use crate::io::usd::kaolin::{self, KaolinPoints, KaolinWeights};
use crate::io::usd::{unique_prim_name, StageMetadata, UsdLayer, UsdValue, WORLD};
use crate::sim::motion::Rigid;
use crate::{Point3, Result};
use std::path::{Path, PathBuf};

/// The stage's file name under `--out`.
pub const STAGE_FILE: &str = "run.usda";

/// What a drawn point set is written as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Mesh,
    Points,
    Splats,
}

/// One drawn point set of one frame (an object's own render points or a render input).
pub(super) struct UsdDrawn<'a> {
    /// Positions, N x 3, metres.
    pub x: &'a [Point3],
    /// The set's splats and this frame's moved splats, for splat inputs.
    pub splats: Option<(&'a Splats, &'a MovedSplats)>,
    /// The stress arrays at the points, Pa, where asked.
    pub stress: Option<&'a StressArrays>,
}

/// Writes the run's USD stage (see the module doc).
#[derive(Debug)]
pub struct UsdFrameWriter {
    path: PathBuf,
    layer: Option<UsdLayer>,
    /// Per object: the prim path of its own set, then of each render input, with their kinds.
    objects: Vec<Vec<(String, Kind)>>,
    /// Per collider: its prim (None for no surface to draw).
    colliders: Vec<Option<String>>,
    physics: bool,
}

fn f32s3(x: &[Point3]) -> Vec<[f32; 3]> {
    x.iter().map(|p| p.map(|c| c as f32)).collect()
}

/// The row-vector USD matrix of x -> R x + t.
fn usd_matrix(pose: &Rigid) -> Box<[f64; 16]> {
    let (r, t) = (&pose.rotation, &pose.translation);
    Box::new([
        r[0][0], r[1][0], r[2][0], 0.0, //
        r[0][1], r[1][1], r[2][1], 0.0, //
        r[0][2], r[1][2], r[2][2], 0.0, //
        t[0], t[1], t[2], 1.0,
    ])
}

/// SH coefficients of every splat in USD's layout: per splat (deg + 1)^2 RGB triples, the
/// DC term first (`rest`: freeform's channel-major `f_rest` rows, 3 K per splat).
fn sh_triples(base: &Splats, rest: &[f64]) -> Vec<[f32; 3]> {
    let k = base.rest_per_splat() / 3;
    let mut out = Vec::with_capacity(base.len() * (k + 1));
    for (i, dc) in base.sh_dc.iter().enumerate() {
        out.push(dc.map(|c| c as f32));
        let row = &rest[i * 3 * k..(i + 1) * 3 * k];
        for j in 0..k {
            out.push([row[j] as f32, row[k + j] as f32, row[2 * k + j] as f32]);
        }
    }
    out
}

impl UsdFrameWriter {
    /// A writer of `<out>/run.usda` (`out` must exist); Kaolin's physics schemas on each
    /// object's prim when `physics`.
    pub fn new(out: &Path, physics: bool) -> UsdFrameWriter {
        UsdFrameWriter {
            path: out.join(STAGE_FILE),
            layer: None,
            objects: Vec::new(),
            colliders: Vec::new(),
            physics,
        }
    }

    /// The stage file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The prim tree, the static attributes (topology, splat opacities, colliders' rest
    /// surfaces) and the physics schemas, from the world before its first frame.
    fn layout(&mut self, world: &World) -> Result<UsdLayer> {
        let mut layer = UsdLayer::new(StageMetadata {
            time_codes_per_second: Some(1.0 / world.dt()),
            time_range: None,
            // The same rule as the scene's USD inputs are read by.
            up_axis: UpAxis::from_gravity(world.gravity()),
            meters_per_unit: 1.0,
            documentation: "freeform run: time codes are step indices".into(),
        });
        let mut top = Vec::new();
        for object in world.objects() {
            let name = unique_prim_name(object.name(), &mut top);
            let root = layer.define(WORLD, &name, "Xform");
            let mut taken = Vec::new();
            let mut sets = Vec::new();
            let own_kind = kind_of(object.triangles().is_some(), object.splats().is_some());
            let own = geometry_prim(&mut layer, &root, &mut taken, "", own_kind);
            static_attributes(
                &mut layer,
                &own,
                own_kind,
                object.render_rest(),
                object.triangles(),
                object.splats(),
            );
            if self.physics {
                physics(&mut layer, &own, object)?;
            }
            sets.push((own, own_kind));
            for set in object.render_sets() {
                let kind = kind_of(set.triangles().is_some(), set.splats().is_some());
                let prim = geometry_prim(&mut layer, &root, &mut taken, set.name(), kind);
                static_attributes(
                    &mut layer,
                    &prim,
                    kind,
                    set.rest(),
                    set.triangles(),
                    set.splats(),
                );
                sets.push((prim, kind));
            }
            self.objects.push(sets);
        }
        let kin = world.collider_kinematics();
        let poses = world.collider_poses();
        if !world.colliders().is_empty() {
            let group = layer.define(WORLD, &unique_prim_name("colliders", &mut top), "Scope");
            let mut taken = Vec::new();
            for (i, obstacle) in kin.obstacles().iter().enumerate() {
                let name = world.colliders()[i]
                    .name
                    .clone()
                    .unwrap_or_else(|| format!("collider_{i}"));
                // A plane is drawn as one square; the other shapes as their triangles.
                let (rest, counts, indices) = match obstacle.surface() {
                    Some((rest, triangles)) => (
                        rest,
                        vec![3; triangles.len()],
                        triangles.iter().flatten().map(|&v| v as i32).collect(),
                    ),
                    None => match plane_quad(obstacle, world, &poses[i]) {
                        Some(corners) => (corners, vec![4], vec![0, 1, 2, 3]),
                        None => {
                            self.colliders.push(None);
                            continue;
                        }
                    },
                };
                let prim = layer.define(&group, &unique_prim_name(&name, &mut taken), "Mesh");
                layer.set(
                    &prim,
                    "points",
                    "point3f[]",
                    UsdValue::Float3s(f32s3(&rest)),
                );
                layer.set(&prim, "faceVertexCounts", "int[]", UsdValue::Ints(counts));
                layer.set(&prim, "faceVertexIndices", "int[]", UsdValue::Ints(indices));
                layer.set_uniform(
                    &prim,
                    "xformOpOrder",
                    "token[]",
                    UsdValue::Tokens(vec!["xformOp:transform".into()]),
                );
                self.colliders.push(Some(prim));
            }
        }
        Ok(layer)
    }

    /// Start frame `frame`: lay the stage out from the world at the first frame.
    ///
    /// # Errors
    /// Weights that cannot be evaluated for the physics schemas.
    pub(super) fn begin_frame(&mut self, world: &World) -> Result<()> {
        if self.layer.is_none() {
            self.layer = Some(self.layout(world)?);
        }
        Ok(())
    }

    /// Time samples of set `set` (0: the object's own, then its render inputs) of object
    /// `object` at frame `frame` (a step index).
    pub(super) fn drawn(&mut self, object: usize, set: usize, frame: usize, d: UsdDrawn<'_>) {
        let (Some(layer), Some((prim, kind))) = (
            self.layer.as_mut(),
            self.objects.get(object).and_then(|sets| sets.get(set)),
        ) else {
            return;
        };
        frame_attributes(layer, prim, *kind, frame as f64, &d);
    }

    /// End frame `frame`: the colliders' poses and the stage's time range.
    pub(super) fn end_frame(&mut self, world: &World, frame: usize) {
        let Some(layer) = self.layer.as_mut() else {
            return;
        };
        let t = frame as f64;
        let poses = world.collider_poses();
        for (prim, pose) in self.colliders.iter().zip(&poses) {
            if let Some(prim) = prim {
                let m = UsdValue::Matrix4(usd_matrix(pose));
                layer.push_sample(prim, "xformOp:transform", "matrix4d", t, m);
            }
        }
        let meta = &mut layer.metadata;
        let start = meta.time_range.map_or(t, |(s, _)| s);
        meta.time_range = Some((start, t));
    }

    /// Write the stage with the frames so far (once: the samples are handed to the writer);
    /// its path, None when no frame was added or it was written already.
    ///
    /// # Errors
    /// [`crate::Error::Io`] when the file cannot be written.
    pub fn finish(&mut self) -> Result<Option<PathBuf>> {
        let Some(layer) = self.layer.take() else {
            return Ok(None);
        };
        crate::io::usd::write_usda(&layer, &self.path)?;
        Ok(Some(self.path.clone()))
    }
}

fn kind_of(mesh: bool, splats: bool) -> Kind {
    if splats {
        Kind::Splats
    } else if mesh {
        Kind::Mesh
    } else {
        Kind::Points
    }
}

/// Define the geometry prim of one set under `root`: `surface`, `points` or `splats` for an
/// object's own set, the input's name for a render input.
fn geometry_prim(
    layer: &mut UsdLayer,
    root: &str,
    taken: &mut Vec<String>,
    input: &str,
    kind: Kind,
) -> String {
    let (default, type_name) = match kind {
        Kind::Mesh => ("surface", "Mesh"),
        Kind::Points => ("points", "Points"),
        Kind::Splats => ("splats", "ParticleField3DGaussianSplat"),
    };
    let name = if input.is_empty() { default } else { input };
    layer.define(root, &unique_prim_name(name, taken), type_name)
}

/// Written once: the rest geometry as the default value of the per-frame attributes (what a
/// reader sees without a time code: Kaolin reads a prim's points so), the topology, the
/// splats' opacities, degree and rest SH.
fn static_attributes(
    layer: &mut UsdLayer,
    prim: &str,
    kind: Kind,
    rest: &[Point3],
    triangles: Option<&[[u32; 3]]>,
    splats: Option<&Splats>,
) {
    match (kind, splats) {
        (Kind::Splats, Some(s)) => {
            layer.set(
                prim,
                "positions",
                "point3f[]",
                UsdValue::Float3s(f32s3(&s.means)),
            );
            let q = s.rotations.iter().map(|q| q.map(|c| c as f32)).collect();
            layer.set(prim, "orientations", "quatf[]", UsdValue::Quats(q));
            let scales = s
                .log_scales
                .iter()
                .map(|l| l.map(|c| c.exp() as f32))
                .collect();
            layer.set(prim, "scales", "float3[]", UsdValue::Float3s(scales));
            let opacities = s.opacities.iter().map(|&o| sigmoid(o) as f32).collect();
            layer.set(prim, "opacities", "float[]", UsdValue::Floats(opacities));
            layer.set_uniform(
                prim,
                "radiance:sphericalHarmonicsDegree",
                "int",
                UsdValue::Int(s.sh_degree as i32),
            );
            let name = "radiance:sphericalHarmonicsCoefficients";
            layer.set(
                prim,
                name,
                "float3[]",
                UsdValue::Float3s(sh_triples(s, &s.sh_rest)),
            );
            // As 3DGRUT writes it: the coefficients per splat.
            layer.element_size(
                prim,
                name,
                "float3[]",
                ((s.sh_degree + 1) * (s.sh_degree + 1)) as i32,
            );
        }
        _ => layer.set(prim, "points", "point3f[]", UsdValue::Float3s(f32s3(rest))),
    }
    if let (Kind::Mesh, Some(t)) = (kind, triangles) {
        let idx = t.iter().flatten().map(|&v| v as i32).collect();
        layer.set(
            prim,
            "faceVertexCounts",
            "int[]",
            UsdValue::Ints(vec![3; t.len()]),
        );
        layer.set(prim, "faceVertexIndices", "int[]", UsdValue::Ints(idx));
        layer.set_uniform(
            prim,
            "subdivisionScheme",
            "token",
            UsdValue::Token("none".into()),
        );
    }
}

/// One frame's time samples of one set.
fn frame_attributes(layer: &mut UsdLayer, prim: &str, kind: Kind, t: f64, d: &UsdDrawn<'_>) {
    match (kind, d.splats) {
        (Kind::Splats, Some((base, moved))) => {
            layer.push_sample(
                prim,
                "positions",
                "point3f[]",
                t,
                UsdValue::Float3s(f32s3(&moved.means)),
            );
            let q = moved
                .rotations
                .iter()
                .map(|q| q.map(|c| c as f32))
                .collect();
            layer.push_sample(prim, "orientations", "quatf[]", t, UsdValue::Quats(q));
            let s = moved
                .log_scales
                .iter()
                .map(|s| s.map(|c| c.exp() as f32))
                .collect();
            layer.push_sample(prim, "scales", "float3[]", t, UsdValue::Float3s(s));
            // Turned SH colours per frame; unturned ones are the rest default.
            if let Some(rest) = &moved.sh_rest {
                let sh = UsdValue::Float3s(sh_triples(base, rest));
                let name = "radiance:sphericalHarmonicsCoefficients";
                layer.push_sample(prim, name, "float3[]", t, sh);
            }
        }
        _ => {
            layer.push_sample(
                prim,
                "points",
                "point3f[]",
                t,
                UsdValue::Float3s(f32s3(d.x)),
            );
        }
    }
    if let Some(sigma) = d.stress {
        stress_primvars(layer, prim, t, sigma);
    }
}

/// `primvars:stress` (9 values per point, row-major), `primvars:principal_stress` and
/// `primvars:von_mises`, Pa, per point (`vertex`).
fn stress_primvars(layer: &mut UsdLayer, prim: &str, t: f64, s: &StressArrays) {
    let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    let flat = f32s(&s.tensor.concat());
    let p3 = s.principal.iter().map(|p| p.map(|v| v as f32)).collect();
    for (name, ty, value, size) in [
        (
            "primvars:stress",
            "float[]",
            UsdValue::Floats(flat),
            Some(9),
        ),
        (
            "primvars:principal_stress",
            "float3[]",
            UsdValue::Float3s(p3),
            None,
        ),
        (
            "primvars:von_mises",
            "float[]",
            UsdValue::Floats(f32s(&s.von_mises)),
            None,
        ),
    ] {
        if layer.sample_count(prim, name) == 0 {
            layer.primvar_metadata(prim, name, ty, "vertex", size);
        }
        layer.push_sample(prim, name, ty, t, value);
    }
}

/// Kaolin's two physics schemas on `prim`: materials at the integration points, materials
/// and weights at the cubature points, weights at the prim's own (render) points.
fn physics(layer: &mut UsdLayer, prim: &str, object: &SceneObject) -> Result<()> {
    let material = object.materials();
    let ip = object.rest_points();
    let volume = ip.total_volume();
    kaolin::write_material(
        layer,
        prim,
        kaolin::DEFAULT_INSTANCE,
        &KaolinPoints {
            points: ip.points.clone(),
            youngs: material.youngs.clone(),
            poisson: material.poisson.clone(),
            density: material.density.clone(),
            volume,
        },
    );
    let cubature = object.sim().cubature();
    let pick = |v: &[f64]| cubature.source.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    let w = object.basis().weights(&cubature.points)?;
    kaolin::write_skinned(
        layer,
        prim,
        kaolin::DEFAULT_INSTANCE,
        &KaolinPoints {
            points: cubature.points.clone(),
            youngs: pick(&material.youngs),
            poisson: pick(&material.poisson),
            density: pick(&material.density),
            volume,
        },
        &KaolinWeights::from_modes(&w, Some(object.render_weights())),
    );
    Ok(())
}

/// A square of a plane collider, centred under the objects and twice their extent along the
/// plane: its four corners (counter-clockwise about the outward normal) in the rest frame. It
/// only shows where the plane is; the obstacle is the whole half-space.
fn plane_quad(
    obstacle: &crate::sim::collider::Obstacle,
    world: &World,
    pose: &Rigid,
) -> Option<Vec<Point3>> {
    use crate::linalg3::{cross, dot, norm};
    let crate::sim::collider::Obstacle::Plane { point, normal } = obstacle else {
        return None;
    };
    // The objects where they start (the first frame), in the plane's rest frame: x -> R^T
    // (x - t) for the plane's pose now.
    let (r, t) = (&pose.rotation, &pose.translation);
    let rest: Vec<Point3> = world
        .objects()
        .iter()
        .flat_map(|o| o.render_positions())
        .map(|x| std::array::from_fn(|i| (0..3).map(|k| r[k][i] * (x[k] - t[k])).sum()))
        .collect();
    let n = rest.len().max(1) as f64;
    let c: Point3 = std::array::from_fn(|d| rest.iter().map(|p| p[d]).sum::<f64>() / n);
    let off = dot(&std::array::from_fn(|d| c[d] - point[d]), normal);
    let centre: Point3 = std::array::from_fn(|d| c[d] - off * normal[d]);
    // The largest distance along the plane from the centre to a point of an object.
    let extent = rest
        .iter()
        .map(|p| {
            let r: [f64; 3] = std::array::from_fn(|d| p[d] - centre[d]);
            let along = dot(&r, normal);
            norm(&std::array::from_fn(|d| r[d] - along * normal[d]))
        })
        .fold(0.0, f64::max);
    let half = 2.0 * extent.max(1e-3);
    let a = if normal[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let an = dot(&a, normal);
    let u0: [f64; 3] = std::array::from_fn(|d| a[d] - an * normal[d]);
    let len = norm(&u0);
    let u: [f64; 3] = u0.map(|x| x / len);
    let v = cross(normal, &u);
    let corner = |su: f64, sv: f64| -> Point3 {
        std::array::from_fn(|d| centre[d] + half * (su * u[d] + sv * v[d]))
    };
    Some(vec![
        corner(-1.0, -1.0),
        corner(1.0, -1.0),
        corner(1.0, 1.0),
        corner(-1.0, 1.0),
    ])
}
