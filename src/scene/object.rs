//! One object of a [`super::World`]: its reduced model, rest points and skinning weights,
//! render inputs and materials, and its running summary ([`SceneObject`]); objects the caller
//! prepared from arrays ([`PreparedObject`]).

use super::render_set::{self, RenderSet};
use super::report::{ObjectSummary, StepRow};
use super::settings::RunSettings;
use super::setup::{material_at, object_basis, object_image, ObjectBasis, ResolvedShape};
use super::shape::ShapeSource;
use super::spec::{ObjectSpec, Scene};
use crate::geometry::{PointCloud, Shape, ShapeOptions, ShapeSpec, UpAxis};
use crate::io::splat::{MovedSplats, Splats};
use crate::linalg3::Mat3;
use crate::material::MaterialField;
use crate::precompute::sampling::IntegrationPoints;
use crate::precompute::skinning::{Basis, SkinningWeights};
use crate::precompute::ImageMaterial;
use crate::progress::Progress;
use crate::report::{Stopwatch, Warning};
use crate::sim::Environment;
use crate::sim::{ReducedSim, SimOptions, StepReport};
use crate::{Error, Point3, Result};
use std::sync::Arc;
use std::sync::OnceLock;

/// The render set name of a point cloud's, splat object's or image object's derived contact
/// surface in a `[contact]` scene: its frames are `<object>_contact_surface_NNNNNN.<ext>`.
pub const CONTACT_SURFACE_SET: &str = "contact_surface";

/// The points an object is drawn with: the mesh's vertices, a point cloud's points, or (for
/// primitives) the integration points; rest positions with their skinning weights.
struct RenderPoints {
    /// Rest positions, N x 3, metres; None: the integration points.
    rest: Option<Vec<Point3>>,
    /// Skinning weights at the render points (the integration points' when `rest` is None).
    weights: SkinningWeights,
    /// Mesh triangles (indices into the render points), for mesh shapes.
    triangles: Option<Vec<[u32; 3]>>,
    /// The splats of a 3DGS shape file (their centres are `rest`).
    splats: Option<Splats>,
}

/// An object whose basis, integration points and materials the caller computed (e.g. from
/// NumPy arrays, with a per-point Young's modulus), for [`super::World::with_objects`]. It is drawn
/// at its integration points; `spec.shape` only names it in reports (`spec.basis` and
/// `spec.material` are not used: the basis and materials are these).
#[derive(Debug, Clone)]
pub struct PreparedObject {
    /// Name, boundaries, placement and cubature of the object.
    pub spec: ObjectSpec,
    /// Its skinning basis.
    pub basis: Basis,
    /// Integration points (N x 3, metres) and volumes (N, m^3).
    pub points: IntegrationPoints,
    /// Per-point material (N entries).
    pub material: MaterialField,
}

/// One object of a [`super::World`]: its reduced model, its rest points and their skinning
/// weights, and its running summary.
pub struct SceneObject {
    spec: ObjectSpec,
    sim: ReducedSim,
    basis: Basis,
    points: IntegrationPoints,
    /// Weights at the integration points when they are not the render points: evaluated on
    /// the first request (they are large and only the simulator's setup needs them).
    ip_weights: OnceLock<SkinningWeights>,
    /// Material at the integration points.
    material: MaterialField,
    /// Lame parameters (lambda, mu) at the render points, Pa: made on the first stress
    /// request.
    render_lame: OnceLock<Vec<(f64, f64)>>,
    render: RenderPoints,
    /// Extra render inputs (`render = [...]`).
    render_sets: Vec<RenderSet>,
    /// Materials from a voxel image, for stresses at render points.
    image: Option<ImageMaterial>,
    summary: ObjectSummary,
    /// Whether the inversion warning was given.
    warned_inverted: bool,
}

impl std::fmt::Debug for SceneObject {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SceneObject")
            .field("name", &self.spec.name)
            .field("kernels", &self.basis.kernels.len())
            .field("modes", &self.basis.modes())
            .field("time", &self.sim.time())
            .finish_non_exhaustive()
    }
}

impl SceneObject {
    /// Build object `index` of `scene`: its shape, basis (cached or computed), reduced model
    /// and render points. Errors name the object ([`Error::Object`]).
    pub(super) fn new(
        index: usize,
        spec: &ObjectSpec,
        scene: &Scene,
        settings: &RunSettings,
        progress: &dyn Progress,
        warnings: &mut Vec<Warning>,
    ) -> Result<(SceneObject, Shape)> {
        let ctx = |e: Error| Error::Object {
            index,
            name: spec.name.clone(),
            source: Box::new(e),
        };
        let file = spec.shape.file(&settings.base_dir);
        // The cache key names a file by its full path, a primitive by its text.
        let shape_spec = match &file {
            Some(path) => path.display().to_string(),
            None => spec.shape.text().to_string(),
        };
        // A 3DGS splat PLY is read once, whole: its centres are the point cloud (integration
        // points come from it as from any cloud; docs/splats.md).
        let (shape, splats) = match (&file, spec.shape.source()) {
            (Some(path), _) if is_splat_file(path) => {
                // Non-unit quaternions are normal in 3DGS files (renderers normalize): they
                // are used normalized and written back with their norm, without a warning.
                let splats = crate::io::splat::read_splats(path).map_err(|e| ctx(e.into()))?;
                let cloud = PointCloud::new(splats.means.clone())
                    .map_err(|e| ctx(e.with_path(path).into()))?;
                (Shape::PointCloud(cloud), Some(splats))
            }
            (_, ShapeSource::Image) => {
                let image = object_image(spec, scene, None, &settings.base_dir).map_err(ctx)?;
                match image {
                    Some(im) => (Shape::Image(im.image().clone()), None),
                    None => {
                        return Err(ctx(Error::Scene {
                            message: "shape = \"image\" needs an [object.image] table".into(),
                        }))
                    }
                }
            }
            (_, ShapeSource::Spec(parsed)) => {
                let opts = ShapeOptions {
                    allow_open_mesh: spec.allow_open_mesh,
                    up_axis: UpAxis::from_gravity(scene.simulation.gravity),
                };
                match parsed.resolved(&settings.base_dir) {
                    // A USD splat prim is simulated and written as splats, like a 3DGS file.
                    ShapeSpec::Usd { path, prim, time } => {
                        crate::io::usd::read_usd_object(&path, prim.as_deref(), time, &opts)
                            .map_err(|e| ctx(e.into()))?
                    }
                    resolved => {
                        let shape = crate::io::read_shape_spec(&resolved, &opts)
                            .map_err(|e| ctx(e.into()))?;
                        (shape, None)
                    }
                }
            }
            (_, ShapeSource::Arrays) => {
                return Err(ctx(Error::Scene {
                    message: format!(
                        "shape \"{}\" is made from arrays: add the object with \
                         World::with_objects",
                        spec.shape.text()
                    ),
                }))
            }
        };
        // A USD prim enters the cache key by what was read (prim, time code, up axis and
        // referenced layers all change it), not by the root layer's bytes.
        let (shape_spec, file) = match spec.shape.source() {
            ShapeSource::Spec(ShapeSpec::Usd { .. }) => (super::cache::geometry_text(&shape), None),
            _ => (shape_spec, file),
        };
        let image = object_image(spec, scene, Some(&shape), &settings.base_dir).map_err(ctx)?;
        let resolved = ResolvedShape {
            shape,
            spec: shape_spec,
            file,
        };
        let clock = Stopwatch::start();
        let parts = object_basis(
            spec,
            &resolved,
            scene,
            settings,
            image.as_ref(),
            progress,
            warnings,
        )
        .map_err(ctx)?;
        let precompute_s = clock.elapsed();
        let mut object = SceneObject::from_parts(
            index,
            spec,
            scene,
            Some(&resolved.shape),
            parts,
            precompute_s,
            progress,
        )?;
        object.render.splats = splats;
        object.image = image;
        object
            .load_render_sets(
                &settings.base_dir,
                UpAxis::from_gravity(scene.simulation.gravity),
            )
            .map_err(ctx)?;
        Ok((object, resolved.shape))
    }

    /// The reduced model and render points of an object whose basis, integration points and
    /// materials are known (computed in `precompute_s` seconds); `shape` None: drawn at its
    /// integration points.
    pub(super) fn from_parts(
        index: usize,
        spec: &ObjectSpec,
        scene: &Scene,
        shape: Option<&Shape>,
        parts: ObjectBasis,
        precompute_s: f64,
        progress: &dyn Progress,
    ) -> Result<SceneObject> {
        let ctx = |e: Error| Error::Object {
            index,
            name: spec.name.clone(),
            source: Box::new(e),
        };
        let ObjectBasis {
            basis,
            points,
            material,
            cached,
            file: basis_file,
            monitors,
        } = parts;
        let clock = Stopwatch::start();
        progress.begin(&format!("setup {}", spec.name), None);
        let opts = SimOptions {
            dt: scene.simulation.dt,
            gravity: scene.simulation.gravity,
            cubature: spec.cubature.unwrap_or(scene.solver.cubature),
            newton: scene.solver.newton(),
            boundaries: spec.boundaries.clone(),
            colliders: scene.colliders.clone(),
            placement: spec.placement,
        };
        // The weights at the integration points feed the simulator; a primitive is also drawn
        // at those points, so it keeps them instead of evaluating the basis twice.
        let ip_weights = basis.weights(&points.points).map_err(ctx)?;
        let sim = ReducedSim::with_weights(&basis, &points, &material, &ip_weights, &opts)
            .map_err(ctx)?;
        crate::sim::object::check_start_outside_colliders(
            sim.environment(),
            &scene.colliders,
            &points.points,
            &spec.placement.transform().map_err(ctx)?,
            sim.diagonal(),
        )
        .map_err(ctx)?;
        let (rest, triangles) = match shape {
            Some(Shape::Mesh(m)) => (Some(m.vertices().to_vec()), Some(m.triangles().to_vec())),
            Some(other) => (other.render_points().map(<[Point3]>::to_vec), None),
            None => (None, None),
        };
        let render_weights = match &rest {
            Some(r) => basis.weights(r).map_err(|e| {
                ctx(Error::Scene {
                    message: format!(
                        "the skinning weights cannot be evaluated at the render points ({e}); \
                         more kernels or a larger support factor cover them"
                    ),
                })
            })?,
            None => ip_weights,
        };
        progress.finish();
        let render_count = rest.as_ref().map_or(points.len(), Vec::len);
        let summary = ObjectSummary {
            name: spec.name.clone(),
            shape: spec.shape.text().to_string(),
            kernels: basis.kernels.len(),
            modes: basis.modes() - 1,
            points: points.len(),
            cubature_points: sim.cubature().len(),
            render_points: render_count,
            terms: sim.terms(),
            basis_cached: cached,
            basis_file: basis_file.map(|p| p.display().to_string()),
            precompute_s,
            setup_s: clock.elapsed(),
            step_ms_mean: 0.0,
            step_ms_max: 0.0,
            iterations_mean: 0.0,
            iterations_max: 0,
            nonconverged_steps: 0,
            line_search_failures: 0,
            line_search_cutbacks: 0,
            min_det: f64::INFINITY,
            monitors,
            steps: Vec::new(),
        };
        Ok(SceneObject {
            spec: spec.clone(),
            sim,
            basis,
            points,
            ip_weights: OnceLock::new(),
            material,
            render_lame: OnceLock::new(),
            render_sets: Vec::new(),
            image: None,
            render: RenderPoints {
                rest,
                weights: render_weights,
                triangles,
                splats: None,
            },
            summary,
            warned_inverted: false,
        })
    }

    /// The object's name (from the scene).
    pub fn name(&self) -> &str {
        &self.spec.name
    }

    /// The object's specification as given in the scene.
    pub fn spec(&self) -> &ObjectSpec {
        &self.spec
    }

    /// The object was put back at `placement` ([`super::World::set_placement`]): its spec
    /// says so from now on (the placement a gradient is taken at).
    pub(super) fn placed_at(&mut self, placement: &crate::sim::Placement) {
        self.spec.placement = *placement;
    }

    /// The reduced model: state `z` and `zdot` (12 (m + 1) each), time, terms, cubature.
    pub fn sim(&self) -> &ReducedSim {
        &self.sim
    }

    /// The reduced model, mutable: set `zdot` (a kick) or the state between steps.
    pub fn sim_mut(&mut self) -> &mut ReducedSim {
        &mut self.sim
    }

    /// The skinning basis (kernels, coefficients, eigenvalues).
    pub fn basis(&self) -> &Basis {
        &self.basis
    }

    /// Skinning weights at the render points ([`Self::render_rest`]), evaluated at setup.
    pub fn render_weights(&self) -> &SkinningWeights {
        &self.render.weights
    }

    /// Materials at the integration points (N entries: Pa, -, kg/m^3).
    pub fn materials(&self) -> &MaterialField {
        &self.material
    }

    /// Integration points at rest (N x 3, metres) with their volumes (m^3).
    pub fn rest_points(&self) -> &IntegrationPoints {
        &self.points
    }

    /// Skinning weights at the integration points ([`Self::rest_points`]), evaluated once:
    /// the render weights when the object is drawn at its integration points, else computed on
    /// first use and kept.
    pub fn integration_weights(&self) -> Result<&SkinningWeights> {
        if self.render.rest.is_none() {
            return Ok(&self.render.weights);
        }
        if let Some(w) = self.ip_weights.get() {
            return Ok(w);
        }
        // The simulator was built from these weights, so they evaluate here too.
        let w = self.basis.weights(&self.points.points)?;
        Ok(self.ip_weights.get_or_init(|| w))
    }

    /// Deformed positions of the integration points, N x 3, metres. For a mesh or a point
    /// cloud their skinning weights are evaluated on the first call and kept.
    pub fn integration_positions(&self) -> Result<Vec<Point3>> {
        let w = self.integration_weights()?;
        Ok(self.sim.positions(&self.points.points, w))
    }

    /// Rest positions of the render points, N x 3, metres: a mesh's vertices, a point
    /// cloud's points, or a primitive's integration points.
    pub fn render_rest(&self) -> &[Point3] {
        self.render.rest.as_deref().unwrap_or(&self.points.points)
    }

    /// Mesh triangles over the render points (mesh shapes only).
    pub fn triangles(&self) -> Option<&[[u32; 3]]> {
        self.render.triangles.as_deref()
    }

    /// Deformed positions of the render points (what the frames hold), N x 3, metres.
    pub fn render_positions(&self) -> Vec<Point3> {
        self.sim.positions(self.render_rest(), &self.render.weights)
    }

    /// The splats of an object whose shape file is a 3DGS splat PLY (rest state, as read).
    pub fn splats(&self) -> Option<&Splats> {
        self.render.splats.as_ref()
    }

    /// The current frame of a splat object (None for other shapes): centres moved to
    /// `positions` (the deformed render points, [`SceneObject::render_positions`]),
    /// covariances pushed forward by the deformation gradient at each centre and re-derived as
    /// log-scales and rotations, and with `rotate_sh` the SH colour rotated by the polar
    /// rotation ([`crate::sim::gaussian::deform_splats`]).
    pub fn splat_frame(&self, positions: Vec<Point3>, rotate_sh: bool) -> Option<MovedSplats> {
        let s = self.render.splats.as_ref()?;
        Some(render_set::splat_frame(
            &self.sim,
            self.render_rest(),
            &self.render.weights,
            s,
            positions,
            rotate_sh,
        ))
    }

    /// Cauchy stress at the render points, N, Pa (3 x 3 row-major, symmetric): the object's
    /// material (with its region overrides, at the rest positions) at the deformation
    /// gradient of the skinning map there. Points with det F <= 0 (inverted; counted in the
    /// step monitors) get zero stress.
    pub fn render_stress(&self) -> Result<Vec<Mat3>> {
        let lame = match self.render_lame.get() {
            Some(l) => l,
            None => {
                let field = match &self.render.rest {
                    // Prepared objects carry per-point materials no region describes.
                    None => self.material.clone(),
                    Some(rest) => material_at(rest, &self.spec, self.image.as_ref())?,
                };
                self.render_lame.get_or_init(|| render_set::lame_of(&field))
            }
        };
        Ok(render_set::stress(
            &self.sim,
            self.render_rest(),
            &self.render.weights,
            lame,
        ))
    }

    /// The object's extra render inputs (`render = [...]`), in scene order.
    pub fn render_sets(&self) -> &[RenderSet] {
        &self.render_sets
    }

    /// Cauchy stress at the points of render set `set` (see [`SceneObject::render_stress`]).
    pub fn render_set_stress(&self, set: &RenderSet) -> Result<Vec<Mat3>> {
        set.stress(&self.sim, &self.spec, self.image.as_ref())
    }

    /// Draw `mesh`, the object's derived contact surface, with its frames as the render set
    /// [`CONTACT_SURFACE_SET`].
    ///
    /// # Errors
    /// A render input of that name already, or vertices the kernels do not cover.
    pub(super) fn add_contact_surface(&mut self, mesh: &crate::geometry::TriMesh) -> Result<()> {
        if self
            .render_sets
            .iter()
            .any(|s| s.name() == CONTACT_SURFACE_SET)
        {
            return Err(Error::param(
                "render",
                CONTACT_SURFACE_SET,
                "the derived contact surface's frames carry this name; rename the render file",
            ));
        }
        let set = RenderSet::derived(CONTACT_SURFACE_SET, &self.basis, mesh).map_err(|e| {
            Error::Scene {
                message: format!(
                    "the contact surface derived from the object's points reaches where its \
                     kernels do not ({e}); raise {} so the supports reach a point spacing \
                     past the outermost points",
                    crate::options::SUPPORT_FACTOR
                ),
            }
        })?;
        self.render_sets.push(set);
        Ok(())
    }

    /// Read the render inputs of the spec (relative to `base_dir`) and evaluate the basis at
    /// them; names must differ (they name the files).
    pub(super) fn load_render_sets(
        &mut self,
        base_dir: &std::path::Path,
        up: UpAxis,
    ) -> Result<()> {
        for file in &self.spec.render {
            let path = base_dir.join(file);
            let set = RenderSet::load(&path, &self.basis, up)?;
            if set.name() == self.spec.name
                || self.render_sets.iter().any(|s| s.name() == set.name())
            {
                return Err(Error::param(
                    "render",
                    path.display(),
                    format!(
                        "its frames would be named '{}' like another of the object's; rename \
                         the file",
                        set.name()
                    ),
                ));
            }
            self.render_sets.push(set);
        }
        Ok(())
    }

    /// Deformed mesh vertices, V x 3, metres (None unless the shape is a mesh).
    pub fn mesh_vertices(&self) -> Option<Vec<Point3>> {
        self.render
            .triangles
            .as_ref()
            .map(|_| self.render_positions())
    }

    /// The summary so far (per-step rows, monitors; means are filled at the end).
    pub fn summary(&self) -> &ObjectSummary {
        &self.summary
    }

    /// Gravity from the next step on, m/s^2 (None: none); the summary's term list follows.
    /// Step in the world's environment `env` (its gravity and colliders) from now on; the
    /// summary's term list follows.
    pub(super) fn share_environment(&mut self, env: Arc<Environment>) -> Result<()> {
        self.sim.share_environment(env)?;
        self.summary.terms = self.sim.terms();
        Ok(())
    }

    /// One step; the report's warnings go to `warnings`.
    pub(super) fn step(&mut self, warnings: &mut Vec<Warning>) -> StepReport {
        let rep = self.sim.step();
        self.record(rep, warnings)
    }

    /// Keep a step's report in the summary; its warnings go to `warnings`.
    pub(super) fn record(&mut self, rep: StepReport, warnings: &mut Vec<Warning>) -> StepReport {
        let step = rep.step;
        let name = &self.spec.name;
        if !rep.solve.converged {
            warnings.push(Warning::NotConverged {
                object: name.clone(),
                step,
                iterations: rep.solve.iterations,
                residual: rep.solve.residual,
                line_search_failed: rep.solve.line_search_failed,
            });
        }
        self.summary.steps.push(StepRow::from(&rep));
        self.summary.monitors.add_step(&rep.solve);
        if rep.solve.info.inverted > 0 && !self.warned_inverted {
            // Once per object: the stable Neo-Hookean energy stays finite through
            // inversion, but the result is rarely what the user meant.
            self.warned_inverted = true;
            warnings.push(Warning::Inverted {
                object: name.clone(),
                step,
                points: rep.solve.info.inverted,
                min_det: rep.solve.info.min_det,
            });
        }
        if rep.solve.cholesky_fallbacks > 0 {
            warnings.push(Warning::HessianFallback {
                object: name.clone(),
                step,
                count: rep.solve.cholesky_fallbacks,
            });
        }
        rep
    }
}

/// Whether `path` names a 3DGS splat PLY (a `.ply` whose vertex element has splat
/// properties); any error reading the header leaves the file to the shape reader.
fn is_splat_file(path: &std::path::Path) -> bool {
    let ply = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
    ply && crate::io::splat::is_splat_ply(path).unwrap_or(false)
}

/// A prepared object has points, with materials and volumes that match them.
pub(super) fn check_prepared(p: &PreparedObject) -> Result<()> {
    if p.points.is_empty() {
        return Err(Error::param(
            "points",
            0,
            "the object has no integration points",
        ));
    }
    p.points.check(&p.material)
}
