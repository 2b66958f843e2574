//! A scene being simulated: the live [`World`] you step, read and change between steps.

use super::contact::WorldContact;
use super::object::{check_prepared, PreparedObject, SceneObject};
use super::report::{ContactSummary, ObjectSummary};
use super::settings::RunSettings;
use super::setup::ObjectBasis;
use super::spec::Scene;
use crate::error::check_strict;
use crate::progress::Progress;
use crate::report::{Monitors, Warning};
use crate::sim::collider::{Collider, Kinematics};
use crate::sim::motion::{Motion, Rigid};
use crate::sim::{Environment, Placement, StepReport};
use crate::{Error, Result};
use std::sync::Arc;

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
///         ObjectSpec::new("beam", "box:2,0.5,0.5")?
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
    /// Gravity and the colliders' obstacles and current motions: one, shared by every object
    /// (a setter changes it here and hands it to them again).
    env: Arc<Environment>,
    dt: f64,
    /// Simulated time, seconds, and steps taken: advanced once every object took a step.
    time: f64,
    steps: usize,
    strict: bool,
    /// Set when strict mode stopped a step: the world stops for good (its objects may be
    /// part-way through that step).
    stopped: bool,
    warnings: Vec<Warning>,
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
        let up = crate::geometry::UpAxis::from_gravity(scene.simulation.gravity);
        for (i, c) in loaded.colliders.iter_mut().enumerate() {
            let mut shape = c.shape.clone();
            shape
                .load_in(&settings.base_dir, up)
                .map_err(|e| c.error(i, e))?;
            c.shape = shape;
        }
        let env = Arc::new(Environment::new(
            loaded.simulation.gravity,
            &loaded.colliders,
        )?);
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
            object
                .load_render_sets(&settings.base_dir, up)
                .map_err(ctx)?;
            objects.push(object);
            shapes.push(None);
        }
        for (index, o) in objects.iter_mut().enumerate() {
            o.share_environment(env.clone())
                .map_err(|e| Error::Object {
                    index,
                    name: o.name().to_string(),
                    source: Box::new(e),
                })?;
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
            env,
            dt: scene.simulation.dt,
            time: 0.0,
            steps: 0,
            strict: settings.strict,
            stopped: false,
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
    /// others have not ([`World::time`] counts the step only when every object took it). The
    /// world then stops for good: every later step returns [`Error::Strict`] again with the
    /// same warnings and moves nothing ([`World::stopped`]); reading and the setters stay.
    pub fn step(&mut self) -> Result<Vec<StepReport>> {
        if self.stopped {
            return Err(Error::Strict {
                warnings: self.warnings.clone(),
            });
        }
        let r = self.step_all();
        if matches!(r, Err(Error::Strict { .. })) {
            self.stopped = true;
        }
        r
    }

    /// Whether strict mode stopped the world (every later [`World::step`] is refused).
    pub fn stopped(&self) -> bool {
        self.stopped
    }

    /// One step of every object (with contact, of the islands), strict mode checked.
    fn step_all(&mut self) -> Result<Vec<StepReport>> {
        if let Some(c) = self.contact.as_mut() {
            let before = self.warnings.len();
            let reports = c.step(&mut self.objects, &mut self.warnings);
            // Every object took the step, so it counts even when strict mode stops here.
            self.advance_clock();
            if self.warnings.len() > before {
                check_strict(self.strict, &self.warnings)?;
            }
            return Ok(reports);
        }
        let mut reports = Vec::with_capacity(self.objects.len());
        let before = self.warnings.len();
        let last = self.objects.len().saturating_sub(1);
        for i in 0..self.objects.len() {
            reports.push(self.objects[i].step(&mut self.warnings));
            if i == last {
                // Every object took the step: it counts, even when strict mode stops here.
                self.advance_clock();
            }
            if self.warnings.len() > before {
                check_strict(self.strict, &self.warnings)?;
            }
        }
        Ok(reports)
    }

    /// Count a step every object took: t += dt, as each object's own clock advances.
    fn advance_clock(&mut self) {
        self.time += self.dt;
        self.steps += 1;
    }

    /// Simulated time, seconds: the world's own clock, advanced once every object took a
    /// step (a strict-mode stop part-way through the objects does not count).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Time step, seconds.
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Steps taken (by every object; see [`World::time`]).
    pub fn steps(&self) -> usize {
        self.steps
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
        self.objects.iter().position(|o| o.spec().name == name)
    }

    /// Warnings so far (setup, non-converged steps, inversions, Cholesky fallbacks).
    pub fn warnings(&self) -> &[Warning] {
        &self.warnings
    }

    fn checked(&mut self, index: usize) -> Result<&mut SceneObject> {
        let count = self.objects.len();
        self.objects
            .get_mut(index)
            .ok_or_else(|| no_object_at(index, count))
    }

    /// Object `index`, or an error saying how many there are (the check every front end
    /// uses).
    pub fn object_at(&self, index: usize) -> Result<&SceneObject> {
        self.objects
            .get(index)
            .ok_or_else(|| no_object_at(index, self.objects.len()))
    }

    /// The index of the object named `name`, or an error listing the names.
    pub fn object_named(&self, name: &str) -> Result<usize> {
        self.object_index(name).ok_or_else(|| {
            let names: Vec<&str> = self.objects.iter().map(|o| o.name()).collect();
            Error::param(
                "object",
                format!("'{name}'"),
                format!(
                    "no object named '{name}'; the scene has: {}",
                    names.join(", ")
                ),
            )
        })
    }

    /// The world's gravity now, m/s^2 (None: none).
    pub fn gravity(&self) -> Option<[f64; 3]> {
        self.env.gravity()
    }

    /// Gravity for every object from the next step on, m/s^2 (None: none).
    pub fn set_gravity(&mut self, gravity: Option<[f64; 3]>) -> Result<()> {
        Arc::make_mut(&mut self.env).set_gravity(gravity)?;
        self.share_environment()
    }

    /// Hand the world's environment to every object again after it changed (each had the
    /// old one; the colliders match, so none refuses).
    fn share_environment(&mut self) -> Result<()> {
        for o in &mut self.objects {
            o.share_environment(self.env.clone())?;
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
            .sim_mut()
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
        self.checked(object)?.sim_mut().set_state(z, zdot)
    }

    /// Put object `object` back into its rest shape at `placement`, with the placement's
    /// velocities (see [`ReducedSim::reset_placement`]).
    pub fn set_placement(&mut self, object: usize, placement: &Placement) -> Result<()> {
        let o = self.checked(object)?;
        o.sim_mut().reset_placement(placement)?;
        o.placed_at(placement);
        Ok(())
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
        Arc::make_mut(&mut self.env).set_collider_motion(index, motion)?;
        self.share_environment()
    }

    /// The scene's colliders as defined (rest frames; meshes loaded).
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// The colliders' obstacles, motions and parents as the objects see them now.
    pub fn collider_kinematics(&self) -> &Kinematics {
        self.env.kinematics()
    }

    /// The pose of every collider at the current time (x -> R x + t of its rest frame).
    pub fn collider_poses(&self) -> Vec<Rigid> {
        self.env.kinematics().poses(self.time())
    }

    /// The object-object contact summary so far (None without `[contact]`): per step the
    /// pairs tested and active, the deepest penetration and the islands; the worst
    /// penetration of the run.
    pub fn contact_summary(&self) -> Option<&ContactSummary> {
        self.contact.as_ref().map(|c| &c.summary)
    }

    /// The object-object contact state (None without `[contact]`).
    pub(super) fn contact_state(&self) -> Option<&WorldContact> {
        self.contact.as_ref()
    }

    /// The summaries of all objects, with the means and counts of the steps taken.
    pub fn summaries(&self) -> Vec<ObjectSummary> {
        self.objects
            .iter()
            .map(|o| super::report::finish_summary(o.summary().clone()))
            .collect()
    }
}

/// The error for object `index` of `count`.
fn no_object_at(index: usize, count: usize) -> Error {
    Error::param(
        "object",
        index,
        format!("the scene has {count} objects (indices from 0)"),
    )
}
