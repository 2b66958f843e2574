//! A scene being simulated: the live [`World`] you step, read and change between steps.

use super::contact::{ContactSummary, WorldContact};
use super::render_set::{self, RenderSet};
use super::run::{ObjectSummary, RunSettings, StepRow};
use super::setup::{
    material_at, object_basis, object_image, resolve_shape, ObjectBasis, ResolvedShape,
};
use super::spec::{ObjectSpec, Scene};
use crate::error::check_strict;
use crate::geometry::{PointCloud, Shape, ShapeOptions};
use crate::io::splat::{MovedSplats, Splats};
use crate::linalg3::Mat3;
use crate::material::MaterialField;
use crate::precompute::sampling::IntegrationPoints;
use crate::precompute::skinning::{Basis, SkinningWeights};
use crate::precompute::ImageMaterial;
use crate::progress::Progress;
use crate::report::{Monitors, Stopwatch};
use crate::sim::collider::{self, Collider, Kinematics};
use crate::sim::motion::{Motion, Rigid};
use crate::sim::{Placement, ReducedSim, SimOptions, StepReport};
use crate::{Error, Point3, Result};
use std::sync::OnceLock;

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
/// NumPy arrays, with a per-point Young's modulus), for [`World::with_objects`]. It is drawn
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

/// One object of a [`World`]: its reduced model, its rest points and their skinning
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
            .field("time", &self.sim.time)
            .finish_non_exhaustive()
    }
}

impl SceneObject {
    /// Build object `index` of `scene`: its shape, basis (cached or computed), reduced model
    /// and render points. Errors name the object ([`Error::Object`]).
    fn new(
        index: usize,
        spec: &ObjectSpec,
        scene: &Scene,
        settings: &RunSettings,
        progress: &dyn Progress,
        warnings: &mut Vec<String>,
    ) -> Result<(SceneObject, Shape)> {
        let ctx = |e: Error| Error::Object {
            index,
            name: spec.name.clone(),
            source: Box::new(e),
        };
        let (shape_spec, file) = resolve_shape(&spec.shape, &settings.base_dir);
        // A 3DGS splat PLY is read once, whole: its centres are the point cloud (integration
        // points come from it as from any cloud; docs/splats.md).
        let (shape, splats) = match &file {
            Some(path) if is_splat_file(path) => {
                // Non-unit quaternions are normal in 3DGS files (renderers normalize): they
                // are used normalized and written back with their norm, without a warning.
                let splats = crate::io::splat::read_splats(path).map_err(|e| ctx(e.into()))?;
                let cloud = PointCloud::new(splats.means.clone())
                    .map_err(|e| ctx(e.with_path(path).into()))?;
                (Shape::PointCloud(cloud), Some(splats))
            }
            _ if shape_spec.trim() == "image" => {
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
            _ => {
                let opts = ShapeOptions {
                    allow_open_mesh: spec.allow_open_mesh,
                };
                let shape = crate::io::read_shape(&shape_spec, &opts).map_err(|e| ctx(e.into()))?;
                (shape, None)
            }
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
        object.load_render_sets(&settings.base_dir).map_err(ctx)?;
        Ok((object, resolved.shape))
    }

    /// The reduced model and render points of an object whose basis, integration points and
    /// materials are known (computed in `precompute_s` seconds); `shape` None: drawn at its
    /// integration points.
    fn from_parts(
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
            shape: spec.shape.clone(),
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

    /// Integration points at rest (N x 3, metres) with their volumes (m^3).
    pub fn rest_points(&self) -> &IntegrationPoints {
        &self.points
    }

    fn ip_weights(&self) -> Result<&SkinningWeights> {
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
        let w = self.ip_weights()?;
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

    /// Read the render inputs of the spec (relative to `base_dir`) and evaluate the basis at
    /// them; names must differ (they name the files).
    fn load_render_sets(&mut self, base_dir: &std::path::Path) -> Result<()> {
        for file in &self.spec.render {
            let path = base_dir.join(file);
            let set = RenderSet::load(&path, &self.basis)?;
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

    /// One step; the report's warnings go to `warnings`.
    fn step(&mut self, warnings: &mut Vec<String>) -> StepReport {
        let rep = self.sim.step();
        self.record(rep, warnings)
    }

    /// Keep a step's report in the summary; its warnings go to `warnings`.
    pub(super) fn record(&mut self, rep: StepReport, warnings: &mut Vec<String>) -> StepReport {
        let step = rep.step;
        let name = &self.spec.name;
        if !rep.solve.converged {
            warnings.push(format!(
                "object '{name}': step {step} did not converge ({} iterations, residual {:.2e}{})",
                rep.solve.iterations,
                rep.solve.residual,
                if rep.solve.line_search_failed {
                    ", line search failed"
                } else {
                    ""
                }
            ));
        }
        self.summary.steps.push(StepRow::from(&rep));
        self.summary.monitors.add_step(&rep.solve);
        if rep.solve.info.inverted > 0 && !self.warned_inverted {
            // Once per object: the stable Neo-Hookean energy stays finite through
            // inversion, but the result is rarely what the user meant.
            self.warned_inverted = true;
            warnings.push(format!(
                "object '{name}': step {step}: {} cubature point(s) inverted (det F = {:.2} <= 0); \
                 the material is too soft for the load or the time step too large \
                 (later inversions are counted in the monitors' min_det and each step's `inverted`)",
                rep.solve.info.inverted, rep.solve.info.min_det
            ));
        }
        if rep.solve.cholesky_fallbacks > 0 {
            warnings.push(format!(
                "object '{name}': step {step}: {} Newton Hessian(s) were not positive definite; \
                 the rest Hessian was used instead",
                rep.solve.cholesky_fallbacks
            ));
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
fn check_prepared(p: &PreparedObject) -> Result<()> {
    if p.points.is_empty() {
        return Err(Error::param(
            "points",
            0,
            "the object has no integration points",
        ));
    }
    p.points.check(&p.material)
}

/// A scene being simulated, one step at a time: every object's reduced model, the shared
/// colliders, the time and the warnings so far. [`crate::scene::run`] is a loop over it.
///
/// Between steps you can read each object's state and deformed points, and change gravity,
/// a boundary's motion, an object's placement or a collider's pose.
///
/// ```
/// use freeform::material::Region;
/// use freeform::scene::{ObjectSpec, RunSettings, SceneBuilder, World};
/// use freeform::sim::motion::{Keyframe, Motion};
/// let scene = SceneBuilder::new(0.01, 10)
///     .gravity([0.0, -9.81, 0.0])
///     .object(
///         ObjectSpec::new("beam", "box:2,0.5,0.5")
///             .kernels(60)
///             .modes(4)
///             .hold(Region::HalfSpace { point: [0.2, 0.0, 0.0], normal: [-1.0, 0.0, 0.0] }),
///     )
///     .build()?;
/// let mut world = World::new(&scene, &RunSettings::default(), &freeform::progress::Silent)?;
/// world.step()?;
/// let sagged = world.object(0).render_positions();
/// // Lift the held end by 0.1 m over the next 0.05 s.
/// let now = world.time();
/// world.set_boundary_motion(0, 0, Motion::Keyframes {
///     pivot: [0.0; 3],
///     frames: vec![
///         Keyframe { time: now, translation: [0.0; 3], rotation: None },
///         Keyframe { time: now + 0.05, translation: [0.0, 0.1, 0.0], rotation: None },
///     ],
/// })?;
/// for _ in 0..5 {
///     world.step()?;
/// }
/// assert!((world.time() - 0.06).abs() < 1e-12);
/// assert_eq!(sagged.len(), world.object(0).render_positions().len());
/// # Ok::<(), freeform::Error>(())
/// ```
pub struct World {
    objects: Vec<SceneObject>,
    /// The scene's colliders as defined (meshes loaded).
    colliders: Vec<Collider>,
    /// The colliders' obstacles and current motions (every object holds the same).
    kinematics: Kinematics,
    dt: f64,
    strict: bool,
    warnings: Vec<String>,
    /// Object-object contact (scenes with `[contact]` only).
    contact: Option<WorldContact>,
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("objects", &self.objects)
            .field("time", &self.time())
            .field("steps", &self.steps())
            .finish_non_exhaustive()
    }
}

impl World {
    /// Set up `scene`: every object's basis (from the cache or computed), reduced model and
    /// render points. `settings.base_dir` resolves relative paths; `settings.out` is not used
    /// here (frames are written by observers such as [`super::FrameWriter`]);
    /// `settings.strict` makes the setup's and every step's warnings errors.
    ///
    /// # Errors
    /// [`Error::Object`] (the object's index and name around the stage's own error) for a
    /// shape, basis or setup failure; [`Error::Strict`] for a warning in strict mode.
    pub fn new(scene: &Scene, settings: &RunSettings, progress: &dyn Progress) -> Result<World> {
        World::with_objects(scene, settings, Vec::new(), progress)
    }

    /// [`World::new`] with more objects after the scene's own: objects whose basis, points
    /// and materials the caller made (a scene with none of its own is fine then). All objects
    /// are checked together (unique names, boundaries) as a scene file's are; each prepared
    /// object's basis must cover its integration points.
    ///
    /// # Errors
    /// As [`World::new`]; a prepared object whose materials or volumes do not match its
    /// points is an [`Error::Object`] naming it.
    pub fn with_objects(
        scene: &Scene,
        settings: &RunSettings,
        prepared: Vec<PreparedObject>,
        progress: &dyn Progress,
    ) -> Result<World> {
        let mut all = scene.clone();
        all.objects.extend(prepared.iter().map(|p| p.spec.clone()));
        all.validate()?;
        // Mesh colliders are read once, before any basis is computed, and shared by every
        // object.
        let mut loaded = scene.clone();
        for (i, c) in loaded.colliders.iter_mut().enumerate() {
            let mut shape = c.shape.clone();
            shape.load(&settings.base_dir).map_err(|e| c.error(i, e))?;
            c.shape = shape;
        }
        let kinematics = collider::kinematics(&loaded.colliders)?;
        let scene = &loaded;
        let mut warnings = Vec::new();
        let mut objects = Vec::new();
        let mut shapes = Vec::new();
        for (index, spec) in scene.objects.iter().enumerate() {
            crate::error::check_cancelled(progress, "scene setup")?;
            let (object, shape) =
                SceneObject::new(index, spec, scene, settings, progress, &mut warnings)?;
            objects.push(object);
            shapes.push(Some(shape));
        }
        for (offset, p) in prepared.into_iter().enumerate() {
            let index = scene.objects.len() + offset;
            let ctx = |e: Error| Error::Object {
                index,
                name: p.spec.name.clone(),
                source: Box::new(e),
            };
            check_prepared(&p).map_err(ctx)?;
            let parts = ObjectBasis {
                basis: p.basis,
                points: p.points,
                material: p.material,
                cached: false,
                file: None,
                monitors: Monitors::default(),
            };
            let mut object =
                SceneObject::from_parts(index, &p.spec, scene, None, parts, 0.0, progress)?;
            object.load_render_sets(&settings.base_dir).map_err(ctx)?;
            objects.push(object);
            shapes.push(None);
        }
        let contact = match &scene.contact {
            Some(c) => Some(WorldContact::new(
                c,
                &mut objects,
                &shapes,
                &scene.colliders,
            )?),
            None => None,
        };
        check_strict(settings.strict, &warnings)?;
        Ok(World {
            objects,
            colliders: scene.colliders.clone(),
            kinematics,
            dt: scene.simulation.dt,
            strict: settings.strict,
            warnings,
            contact,
        })
    }

    /// Advance every object by one time step (backward Euler); returns each object's step
    /// report, in object order. A step that does not converge is reported (in the report, the
    /// warnings and the monitors), not an error; the state stays finite. Each object's summary
    /// keeps one row per step (about 100 bytes), as the batch run's report does.
    ///
    /// # Errors
    /// [`Error::Strict`] in strict mode at the first warning this step raises, with every
    /// warning so far. The objects up to the one that raised it have taken the step, the
    /// others and [`World::time`] have not: a strict run is over at that point.
    pub fn step(&mut self) -> Result<Vec<StepReport>> {
        if let Some(c) = self.contact.as_mut() {
            let before = self.warnings.len();
            let reports = c.step(&mut self.objects, &mut self.warnings);
            if self.warnings.len() > before {
                check_strict(self.strict, &self.warnings)?;
            }
            return Ok(reports);
        }
        let mut reports = Vec::with_capacity(self.objects.len());
        let before = self.warnings.len();
        for object in &mut self.objects {
            reports.push(object.step(&mut self.warnings));
            if self.warnings.len() > before {
                check_strict(self.strict, &self.warnings)?;
            }
        }
        Ok(reports)
    }

    /// Simulated time, seconds: the last object's, so a step counts once every object took it
    /// (a scene has at least one object).
    pub fn time(&self) -> f64 {
        self.objects.last().map_or(0.0, |o| o.sim.time)
    }

    /// Time step, seconds.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Steps taken (by every object; see [`World::time`]).
    pub fn steps(&self) -> usize {
        self.objects.last().map_or(0, |o| o.sim.steps)
    }

    /// Number of colliders (the scene's `[[collider]]` tables), for
    /// [`World::set_collider_pose`].
    pub fn collider_count(&self) -> usize {
        self.colliders.len()
    }

    /// The objects, in scene order.
    pub fn objects(&self) -> &[SceneObject] {
        &self.objects
    }

    /// Object `index` (scene order). Panics if out of range, like slice indexing; see
    /// [`World::objects`] or [`World::object_index`].
    pub fn object(&self, index: usize) -> &SceneObject {
        &self.objects[index]
    }

    /// Object `index`, mutable (panics if out of range).
    pub fn object_mut(&mut self, index: usize) -> &mut SceneObject {
        &mut self.objects[index]
    }

    /// The index of the object named `name`.
    pub fn object_index(&self, name: &str) -> Option<usize> {
        self.objects.iter().position(|o| o.spec.name == name)
    }

    /// Warnings so far (setup, non-converged steps, inversions, Cholesky fallbacks).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    fn checked(&mut self, index: usize) -> Result<&mut SceneObject> {
        let count = self.objects.len();
        self.objects.get_mut(index).ok_or_else(|| {
            Error::param(
                "object",
                index,
                format!("the scene has {count} objects (indices from 0)"),
            )
        })
    }

    /// Gravity for every object from the next step on, m/s^2 (None: none).
    pub fn set_gravity(&mut self, gravity: Option<[f64; 3]>) -> Result<()> {
        // Every object validates the same value: the first refuses it or all take it.
        for o in &mut self.objects {
            o.sim.set_gravity(gravity)?;
            o.summary.terms = o.sim.terms();
        }
        Ok(())
    }

    /// A new motion for boundary `boundary` of object `object` (see
    /// [`ReducedSim::set_boundary_motion`]: evaluated at the simulation time, on the placed
    /// rest positions).
    pub fn set_boundary_motion(
        &mut self,
        object: usize,
        boundary: usize,
        motion: Motion,
    ) -> Result<()> {
        self.checked(object)?
            .sim
            .set_boundary_motion(boundary, motion)
    }

    /// Hold boundary `boundary` of object `object` at the rigid pose x = R X + t of its placed
    /// rest positions X from the next step on (a [`Motion::Pose`]): the target a caller moves
    /// between steps, as a gripper or a scripted hand would.
    pub fn set_boundary_pose(
        &mut self,
        object: usize,
        boundary: usize,
        pose: &Rigid,
    ) -> Result<()> {
        self.set_boundary_motion(
            object,
            boundary,
            Motion::Pose {
                rotation: pose.rotation,
                translation: pose.translation,
            },
        )
    }

    /// Set object `object`'s state (reduced coordinates and velocity; see
    /// [`ReducedSim::set_state`]), e.g. one read earlier from `object(i).sim().z`.
    pub fn set_state(&mut self, object: usize, z: &[f64], zdot: &[f64]) -> Result<()> {
        self.checked(object)?.sim.set_state(z, zdot)
    }

    /// Put object `object` back into its rest shape at `placement`, with the placement's
    /// velocities (see [`ReducedSim::reset_placement`]).
    pub fn set_placement(&mut self, object: usize, placement: &Placement) -> Result<()> {
        self.checked(object)?.sim.reset_placement(placement)
    }

    /// The kinematic pose of collider `index`: its shape as defined in the scene, moved by
    /// `pose` (x -> R x + t, metres; R a proper rotation), for every object from the next step
    /// on, whatever its shape (planes, boxes, spheres, capsules, meshes). Poses are absolute
    /// (relative to the scene's definition), not accumulated; for a collider with a `parent`
    /// the pose is relative to the parent's frame (a joint), and children follow. It replaces
    /// the collider's scripted `motion` (as a [`Motion::Pose`]).
    pub fn set_collider_pose(&mut self, index: usize, pose: &Rigid) -> Result<()> {
        pose.validate()?;
        self.set_collider_motion(
            index,
            Motion::Pose {
                rotation: pose.rotation,
                translation: pose.translation,
            },
        )
    }

    /// A new motion for collider `index` from the next step on, evaluated at the simulation
    /// time (a keyframe at [`World::time`] starts now); relative to the parent's frame for a
    /// collider with a `parent`.
    pub fn set_collider_motion(&mut self, index: usize, motion: Motion) -> Result<()> {
        if index >= self.colliders.len() {
            return Err(Error::param(
                "collider",
                index,
                format!(
                    "the scene has {} colliders (indices from 0)",
                    self.colliders.len()
                ),
            ));
        }
        motion.validate()?;
        // Every object takes the same valid motion: none can refuse it after the first.
        for o in &mut self.objects {
            o.sim.set_collider_motion(index, motion.clone())?;
        }
        self.kinematics.set_motion(index, motion)
    }

    /// The scene's colliders as defined (rest frames; meshes loaded).
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// The colliders' obstacles, motions and parents as the objects see them now.
    pub fn collider_kinematics(&self) -> &Kinematics {
        &self.kinematics
    }

    /// The pose of every collider at the current time (x -> R x + t of its rest frame).
    pub fn collider_poses(&self) -> Vec<Rigid> {
        self.kinematics.poses(self.time())
    }

    /// The object-object contact summary so far (None without `[contact]`): per step the
    /// pairs tested and active, the deepest penetration and the islands; the worst
    /// penetration of the run.
    pub fn contact_summary(&self) -> Option<&ContactSummary> {
        self.contact.as_ref().map(|c| &c.summary)
    }

    /// The summaries of all objects, with the means and counts of the steps taken.
    pub fn summaries(&self) -> Vec<ObjectSummary> {
        self.objects
            .iter()
            .map(|o| super::run::finish_summary(o.summary.clone()))
            .collect()
    }
}
