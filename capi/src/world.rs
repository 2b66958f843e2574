//! The live simulation for C: a scene file opened as an opaque `ff_world`, stepped, read and
//! changed between steps. A thin caller of [`freeform::scene::World`]: the same code path as
//! `freeform run` (the scene is read by [`Scene::load`], relative paths resolve against the
//! scene file's directory), without frames or progress output.
//!
//! Indices are 0-based: objects in `[[object]]` order, boundaries in the object's
//! `[[object.boundary]]` order, colliders in `[[collider]]` order. An index out of range is
//! `FF_ERR_INVALID_ARGUMENT` with a message naming the index and the count.

use crate::{guard, out_slice, slice, status_of, Status};
use freeform::options::Front;
use freeform::progress::Silent;
use freeform::scene::{RunSettings, Scene, SceneObject, World};
use freeform::sim::motion::Rigid;
use std::ffi::{c_char, c_int, CStr, CString};
use std::path::PathBuf;

/// An open scene being simulated (C type `ff_world`); see [`ff_world_open`].
pub struct FfWorld {
    pub(crate) world: World,
    /// Object names as C strings, in scene order (for [`ff_world_object_name`]).
    names: Vec<CString>,
    /// The world's warnings as C strings; they only grow, so pointers handed out stay valid.
    warnings: Vec<CString>,
    /// Why stepping stopped for good, with the status later steps return: a strict-mode
    /// warning, or an internal error during a step (the objects may be at different times).
    stopped: Option<(Status, String)>,
}

impl FfWorld {
    /// One step by `step` (the world's own or a recorded one), refused once the world has
    /// stopped; a strict-mode error stops it for good, an internal error (a panic) too.
    pub(crate) fn step_with(
        &mut self,
        step: impl FnOnce(&mut World) -> freeform::Result<()>,
    ) -> CResult<()> {
        if let Some((status, why)) = &self.stopped {
            return Err((*status, format!("the world has stopped ({why}); free it")));
        }
        // Marked until the step returns: a panic in it leaves the objects at unknown times.
        self.stopped = Some((Status::Panic, "an internal error in a step".into()));
        let number = self.world.steps() + 1;
        let r = step(&mut self.world);
        self.stopped = None;
        self.sync_warnings();
        r.map_err(|e| {
            if matches!(e, freeform::Error::Strict { .. }) {
                self.stopped = Some((Status::Strict, format!("at step {number}: {e}")));
            }
            lib_err(e)
        })
    }

    /// Append the world's warnings that are not yet kept as C strings.
    fn sync_warnings(&mut self) {
        let all = self.world.warnings();
        for w in &all[self.warnings.len().min(all.len())..] {
            self.warnings
                .push(CString::new(w.to_string().replace('\0', " ")).unwrap_or_default());
        }
    }
}

/// Last step of one object (C struct `ff_step_report`), from [`ff_world_step_report`].
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FfStepReport {
    /// Step number, 1-based.
    pub step: usize,
    /// Solver iterations.
    pub iterations: usize,
    /// Energy/gradient evaluations.
    pub evaluations: usize,
    /// 1 if the step met the solver tolerance, 0 if not (the state is still finite).
    pub converged: c_int,
    /// 1 if the line search failed to decrease the energy (the step ended early).
    pub line_search_failed: c_int,
    /// Final convergence measure (compare with the scene's `solver.tol`).
    pub residual: f64,
    /// Incremental potential at the end of the step, J.
    pub energy: f64,
    /// Wall time of the step, ms.
    pub wall_ms: f64,
    /// Smallest det F over the cubature points.
    pub min_det: f64,
    /// Cubature points with det F <= 0.
    pub inverted: usize,
    /// Cubature points penetrating a collider at the end of the step.
    pub contacts: usize,
    /// Line-search step halvings, summed over the iterations.
    pub line_search_cutbacks: usize,
}

/// Object-object contact of the world's last step and the worst of the run so far (C struct
/// `ff_contact_report`), from [`ff_world_contact_report`]: the numbers of the last row of
/// [`freeform::scene::ContactSummary::steps`] and the summary's run-wide worst. All zero for
/// a scene without `[contact]` (`enabled` 0) and before the first step (`step` 0).
///
/// A separate struct, not new fields of [`FfStepReport`]: C callers allocate that one, so
/// growing it would break programs built against the older header.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FfContactReport {
    /// 1 if the scene has a `[contact]` section (object-object contact is modelled), else 0.
    pub enabled: c_int,
    /// Step number the row is for, 1-based (0 before the first step or without contact).
    pub step: usize,
    /// Object pairs whose grown bounding boxes were compared, n (n - 1) / 2.
    pub object_pairs_tested: usize,
    /// Object pairs whose boxes met (they were solved together, in one island).
    pub object_pairs_near: usize,
    /// Sample pairs within contact distance at the end of the step.
    pub sample_pairs_active: usize,
    /// Deepest object-object penetration at the end of the step, metres.
    pub penetration: f64,
    /// The deepest penetration relative to the smaller rest bounding-box diagonal of its two
    /// objects (dimensionless).
    pub penetration_fraction: f64,
    /// Islands of two or more objects this step.
    pub islands: usize,
    /// Objects in the largest island (0 without islands).
    pub largest_island: usize,
    /// Objects solved again because they ended touching another island's objects.
    pub regrouped: usize,
    /// Wall time of the whole world step, ms.
    pub wall_ms: f64,
    /// Worst penetration of the run so far, metres.
    pub worst_penetration: f64,
    /// Worst penetration of the run so far relative to the smaller diagonal of its objects.
    pub worst_penetration_fraction: f64,
    /// Steps so far whose deepest penetration exceeded the scene's tolerance.
    pub steps_over_tolerance: usize,
}

/// The visible penetration of the world's last step and the worst of the run (C struct
/// `ff_visible_penetration`), from [`ff_world_visible_penetration`]: each object's own surface
/// points (box faces with their edges and corners, sphere lattice, mesh vertices, the
/// derived surface of a cloud, splat or image) against the other objects' contact sample
/// envelopes, as [`freeform::scene::ContactStepRow::visible_penetration`] describes; the
/// contact samples' own figure is [`FfContactReport::penetration`]. All zero without
/// `[contact]` (`enabled` 0) and before the first step (`step` 0).
///
/// A struct of its own, not new fields of [`FfContactReport`], which C callers allocate.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FfVisiblePenetration {
    /// 1 if the scene has a `[contact]` section, else 0.
    pub enabled: c_int,
    /// Step number the figures are for, 1-based (0 before the first step or without contact).
    pub step: usize,
    /// Deepest surface point behind another object's samples at the end of the step, metres.
    pub penetration: f64,
    /// The same relative to the smaller rest bounding-box diagonal of the two objects.
    pub penetration_fraction: f64,
    /// The deepest of the run so far, metres.
    pub worst_penetration: f64,
    /// The deepest of the run so far relative to the smaller diagonal of its two objects.
    pub worst_penetration_fraction: f64,
}

pub(crate) type CResult<T> = Result<T, (Status, String)>;

/// [`guard`] with the function's name before every error message. Messages formatted inside
/// (errors, warnings) name options by their scene keys: a world comes from a scene file.
pub(crate) fn call(func: &str, f: impl FnOnce() -> CResult<()>) -> c_int {
    guard(|| {
        Front::Scene
            .scope(f)
            .map_err(|(status, msg)| (status, format!("{func}: {msg}")))
    })
}

pub(crate) unsafe fn world_ref<'a>(w: *const FfWorld) -> CResult<&'a FfWorld> {
    if w.is_null() {
        return Err((Status::NullPointer, "world is NULL".into()));
    }
    // SAFETY: a live world from ff_world_open, not used mutably at the same time (header).
    Ok(unsafe { &*w })
}

/// The world behind `w`, for the functions that return a count (0 or NULL for NULL).
unsafe fn peek<'a>(w: *const FfWorld) -> Option<&'a FfWorld> {
    // SAFETY: NULL or a live world from ff_world_open.
    unsafe { w.as_ref() }
}

/// Object `index` of the world behind `w` (None for NULL or a bad index).
unsafe fn peek_object<'a>(w: *const FfWorld, index: usize) -> Option<&'a SceneObject> {
    unsafe { peek(w) }.and_then(|w| w.world.objects().get(index))
}

pub(crate) unsafe fn world_mut<'a>(w: *mut FfWorld) -> CResult<&'a mut FfWorld> {
    if w.is_null() {
        return Err((Status::NullPointer, "world is NULL".into()));
    }
    // SAFETY: a live world from ff_world_open, used by one thread at a time (header).
    Ok(unsafe { &mut *w })
}

/// Object `index`, or the library's out-of-range message.
pub(crate) fn object(w: &World, index: usize) -> CResult<&SceneObject> {
    w.object_at(index).map_err(lib_err)
}

pub(crate) fn lib_err(e: freeform::Error) -> (Status, String) {
    (status_of(&e), e.to_string())
}

/// A rigid pose from C arrays (the library's [`Rigid::from_arrays`]): `rotation` 9 doubles
/// row-major (NULL: identity), `translation` 3 doubles (metres, required). Validated by the
/// library where it is used.
unsafe fn pose(rotation: *const f64, translation: *const f64) -> CResult<Rigid> {
    if translation.is_null() {
        return Err((Status::NullPointer, "translation is NULL".into()));
    }
    let t = unsafe { slice(translation, 3, "translation")? };
    let r = if rotation.is_null() {
        None
    } else {
        Some(unsafe { slice(rotation, 9, "rotation")? })
    };
    Rigid::from_arrays(r, Some(t)).map_err(lib_err)
}

/// Open the scene file `scene_path` (TOML, docs/scenes.md) and set up every object (basis
/// from the cache or computed, reduced model, render points), as `freeform run` does: relative
/// paths in the scene resolve against the scene file's directory; no frames are written and
/// nothing is printed. `strict` != 0 turns warnings (at setup and in every step) into
/// `FF_ERR_STRICT`. On success `*out` owns the world; release it with [`ff_world_free`]. On
/// failure `*out` is NULL: `FF_ERR_IO` for an unreadable scene or shape file,
/// `FF_ERR_INVALID_ARGUMENT` for a malformed scene, `FF_ERR_COVERAGE` / `FF_ERR_EIGENSOLVER`
/// for a basis that cannot be built (the message names the object).
#[no_mangle]
pub unsafe extern "C" fn ff_world_open(
    scene_path: *const c_char,
    strict: c_int,
    out: *mut *mut FfWorld,
) -> c_int {
    call("ff_world_open", || {
        if out.is_null() {
            return Err((Status::NullPointer, "out is NULL".into()));
        }
        // SAFETY: checked non-NULL above.
        unsafe { *out = std::ptr::null_mut() };
        if scene_path.is_null() {
            return Err((Status::NullPointer, "scene_path is NULL".into()));
        }
        // SAFETY: the caller passes a NUL-terminated string.
        let bytes = unsafe { CStr::from_ptr(scene_path) }.to_bytes();
        let path = path_of(bytes)?;
        let scene = Scene::load(&path).map_err(lib_err)?;
        // As `freeform run`: relative shape and cache paths are the scene file's.
        let settings = RunSettings {
            strict: strict != 0,
            ..RunSettings::for_scene_file(&path)
        };
        let world = World::new(&scene, &settings, &Silent).map_err(lib_err)?;
        let names = world
            .objects()
            .iter()
            .map(|o| CString::new(o.name()).unwrap_or_default())
            .collect();
        let mut w = Box::new(FfWorld {
            world,
            names,
            warnings: Vec::new(),
            stopped: None,
        });
        w.sync_warnings();
        // SAFETY: checked non-NULL above.
        unsafe { *out = Box::into_raw(w) };
        Ok(())
    })
}

#[cfg(unix)]
fn path_of(bytes: &[u8]) -> CResult<PathBuf> {
    use std::os::unix::ffi::OsStrExt;
    Ok(PathBuf::from(std::ffi::OsStr::from_bytes(bytes)))
}

#[cfg(not(unix))]
fn path_of(bytes: &[u8]) -> CResult<PathBuf> {
    std::str::from_utf8(bytes)
        .map(PathBuf::from)
        .map_err(|_| (Status::InvalidArgument, "scene_path is not UTF-8".into()))
}

/// Release a world (NULL is ignored). Pointers from [`ff_world_object_name`] and
/// [`ff_world_warning`] die with it.
#[no_mangle]
pub unsafe extern "C" fn ff_world_free(world: *mut FfWorld) {
    if !world.is_null() {
        // SAFETY: made by Box::into_raw in ff_world_open, freed once by contract.
        drop(unsafe { Box::from_raw(world) });
    }
}

/// Advance every object by one time step (backward Euler, the scene's `dt`). A step that does
/// not converge is not an error: [`ff_world_step_report`] says so (and a warning is added).
/// In strict mode the first warning of the step gives `FF_ERR_STRICT` and the world stops
/// for good: later steps give `FF_ERR_STRICT` again (reading stays possible). After an
/// internal error in a step (`FF_ERR_PANIC`) later steps give `FF_ERR_PANIC`.
#[no_mangle]
pub unsafe extern "C" fn ff_world_step(world: *mut FfWorld) -> c_int {
    call("ff_world_step", || {
        let w = unsafe { world_mut(world)? };
        w.step_with(|world| world.step().map(|_| ()))
    })
}

/// The last step of object `object` into `*out`; `FF_ERR_INVALID_ARGUMENT` before the first
/// step.
#[no_mangle]
pub unsafe extern "C" fn ff_world_step_report(
    world: *const FfWorld,
    object_index: usize,
    out: *mut FfStepReport,
) -> c_int {
    call("ff_world_step_report", || {
        let w = unsafe { world_ref(world)? };
        if out.is_null() {
            return Err((Status::NullPointer, "out is NULL".into()));
        }
        let o = object(&w.world, object_index)?;
        let row = o.summary().steps.last().ok_or_else(|| {
            (
                Status::InvalidArgument,
                format!(
                    "object {object_index} ('{}') has taken no step yet",
                    o.name()
                ),
            )
        })?;
        // SAFETY: checked non-NULL; the caller provides a writable ff_step_report.
        unsafe {
            *out = FfStepReport {
                step: row.step,
                iterations: row.iterations,
                evaluations: row.evaluations,
                converged: row.converged.into(),
                line_search_failed: row.line_search_failed.into(),
                residual: row.residual,
                energy: row.energy,
                wall_ms: row.wall_ms,
                min_det: row.min_det,
                inverted: row.inverted,
                contacts: row.contacts,
                line_search_cutbacks: row.line_search_cutbacks,
            }
        };
        Ok(())
    })
}

/// Object-object contact of the last world step, and the worst of the run, into `*out`
/// (see [`FfContactReport`]). Never an error for a valid world: a scene without `[contact]`
/// gives all zeros with `enabled` 0, and a step count of 0 means no step was taken yet.
#[no_mangle]
pub unsafe extern "C" fn ff_world_contact_report(
    world: *const FfWorld,
    out: *mut FfContactReport,
) -> c_int {
    call("ff_world_contact_report", || {
        let w = unsafe { world_ref(world)? };
        if out.is_null() {
            return Err((Status::NullPointer, "out is NULL".into()));
        }
        let mut rep = FfContactReport::default();
        if let Some(s) = w.world.contact_summary() {
            rep.enabled = 1;
            rep.worst_penetration = s.worst_penetration;
            rep.worst_penetration_fraction = s.worst_penetration_fraction;
            rep.steps_over_tolerance = s.steps_over_tolerance;
            if let Some(row) = s.steps.last() {
                rep.step = row.step;
                rep.object_pairs_tested = row.object_pairs_tested;
                rep.object_pairs_near = row.object_pairs_near;
                rep.sample_pairs_active = row.sample_pairs_active;
                rep.penetration = row.penetration;
                rep.penetration_fraction = row.penetration_fraction;
                rep.islands = row.island_count();
                // Sizes are sorted largest first.
                rep.largest_island = row.largest_island();
                rep.regrouped = row.regrouped;
                rep.wall_ms = row.wall_ms;
            }
        }
        // SAFETY: checked non-NULL; the caller provides a writable ff_contact_report.
        unsafe { *out = rep };
        Ok(())
    })
}

/// The visible penetration of the last world step and the worst of the run into `*out` (see
/// [`FfVisiblePenetration`]). Never an error for a valid world: a scene without `[contact]`
/// gives all zeros with `enabled` 0, and a step count of 0 means no step was taken yet.
#[no_mangle]
pub unsafe extern "C" fn ff_world_visible_penetration(
    world: *const FfWorld,
    out: *mut FfVisiblePenetration,
) -> c_int {
    call("ff_world_visible_penetration", || {
        let w = unsafe { world_ref(world)? };
        if out.is_null() {
            return Err((Status::NullPointer, "out is NULL".into()));
        }
        let mut rep = FfVisiblePenetration::default();
        if let Some(s) = w.world.contact_summary() {
            rep.enabled = 1;
            rep.worst_penetration = s.worst_visible_penetration;
            rep.worst_penetration_fraction = s.worst_visible_penetration_fraction;
            if let Some(row) = s.steps.last() {
                rep.step = row.step;
                rep.penetration = row.visible_penetration;
                rep.penetration_fraction = row.visible_penetration_fraction;
            }
        }
        // SAFETY: checked non-NULL; the caller provides a writable ff_visible_penetration.
        unsafe { *out = rep };
        Ok(())
    })
}

/// Where the run's worst visible penetration was (C struct `ff_visible_spot`), from
/// [`ff_world_visible_spot`]: the `[contact]` report's `worst_visible_at`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FfVisibleSpot {
    /// 1 if a surface point has reached into another object so far, else 0 (then every
    /// other field is 0).
    pub found: c_int,
    /// The step it was measured after, 1-based.
    pub step: usize,
    /// Index of the object whose surface point it is.
    pub surface_object: usize,
    /// Index of the object whose contact samples it reached into.
    pub other_object: usize,
    /// The point in its object's rest frame (before placement), metres.
    pub rest_point: [f64; 3],
}

/// Where the run's worst visible penetration was into `*out` (see [`FfVisibleSpot`]): `found`
/// 0 without `[contact]`, before the first step, or while no surface point has reached in.
#[no_mangle]
pub unsafe extern "C" fn ff_world_visible_spot(
    world: *const FfWorld,
    out: *mut FfVisibleSpot,
) -> c_int {
    call("ff_world_visible_spot", || {
        let w = unsafe { world_ref(world)? };
        if out.is_null() {
            return Err((Status::NullPointer, "out is NULL".into()));
        }
        let spot = w
            .world
            .contact_summary()
            .and_then(|s| s.worst_visible_at.as_ref());
        let rep = spot.map_or_else(FfVisibleSpot::default, |v| FfVisibleSpot {
            found: 1,
            step: v.step,
            surface_object: v.surface_index,
            other_object: v.other_index,
            rest_point: v.rest_point,
        });
        // SAFETY: checked non-NULL; the caller provides a writable ff_visible_spot.
        unsafe { *out = rep };
        Ok(())
    })
}

/// Steps of object `object` that did not converge so far (0 for NULL or a bad index).
#[no_mangle]
pub unsafe extern "C" fn ff_world_nonconverged_steps(
    world: *const FfWorld,
    object_index: usize,
) -> usize {
    unsafe { peek_object(world, object_index) }.map_or(0, |o| {
        o.summary().steps.iter().filter(|s| !s.converged).count()
    })
}

/// Simulated time, seconds (0 for NULL).
#[no_mangle]
pub unsafe extern "C" fn ff_world_time(world: *const FfWorld) -> f64 {
    unsafe { peek(world) }.map_or(0.0, |w| w.world.time())
}

/// Time step, seconds (0 for NULL).
#[no_mangle]
pub unsafe extern "C" fn ff_world_dt(world: *const FfWorld) -> f64 {
    unsafe { peek(world) }.map_or(0.0, |w| w.world.dt())
}

/// Steps taken by every object (0 for NULL).
#[no_mangle]
pub unsafe extern "C" fn ff_world_steps(world: *const FfWorld) -> usize {
    unsafe { peek(world) }.map_or(0, |w| w.world.steps())
}

/// Number of objects (0 for NULL).
#[no_mangle]
pub unsafe extern "C" fn ff_world_object_count(world: *const FfWorld) -> usize {
    unsafe { peek(world) }.map_or(0, |w| w.world.objects().len())
}

/// Number of colliders of the scene (0 for NULL).
#[no_mangle]
pub unsafe extern "C" fn ff_world_collider_count(world: *const FfWorld) -> usize {
    unsafe { peek(world) }.map_or(0, |w| w.world.collider_count())
}

/// Number of boundaries of object `object` (0 for NULL or a bad index).
#[no_mangle]
pub unsafe extern "C" fn ff_world_boundary_count(
    world: *const FfWorld,
    object_index: usize,
) -> usize {
    unsafe { peek_object(world, object_index) }.map_or(0, |o| o.sim().boundaries().len())
}

/// The index of the object named `name` into `*out`; `FF_ERR_INVALID_ARGUMENT` (listing the
/// names) if there is none.
#[no_mangle]
pub unsafe extern "C" fn ff_world_object_index(
    world: *const FfWorld,
    name: *const c_char,
    out: *mut usize,
) -> c_int {
    call("ff_world_object_index", || {
        let w = unsafe { world_ref(world)? };
        if name.is_null() || out.is_null() {
            return Err((Status::NullPointer, "name or out is NULL".into()));
        }
        // SAFETY: the caller passes a NUL-terminated string.
        let name = unsafe { CStr::from_ptr(name) }.to_string_lossy();
        let index = w.world.object_named(&name).map_err(lib_err)?;
        // SAFETY: checked non-NULL above.
        unsafe { *out = index };
        Ok(())
    })
}

/// The name of object `object` (NUL-terminated; NULL for NULL or a bad index). Owned by the
/// world: valid until [`ff_world_free`].
#[no_mangle]
pub unsafe extern "C" fn ff_world_object_name(
    world: *const FfWorld,
    object_index: usize,
) -> *const c_char {
    unsafe { peek(world) }
        .and_then(|w| w.names.get(object_index))
        .map_or(std::ptr::null(), |n| n.as_ptr())
}

/// Number of render points N of object `object` (0 for NULL or a bad index): a mesh's
/// vertices, a point cloud's points, or a primitive's integration points.
#[no_mangle]
pub unsafe extern "C" fn ff_world_point_count(world: *const FfWorld, object_index: usize) -> usize {
    unsafe { peek_object(world, object_index) }.map_or(0, |o| o.render_rest().len())
}

/// Copy points (N x 3 row-major, metres) into `out` (capacity `len` doubles, >= 3 N).
fn copy_points(points: &[[f64; 3]], out: *mut f64, len: usize) -> CResult<()> {
    let o = out_slice(out, len, 3 * points.len(), "out")?;
    for (dst, p) in o.chunks_exact_mut(3).zip(points) {
        dst.copy_from_slice(p);
    }
    Ok(())
}

/// Deformed render points of object `object` (N x 3 row-major, metres: `out[3 i + d]`; what
/// `freeform run` writes as frames) into `out` (capacity `len` >= 3 N doubles).
#[no_mangle]
pub unsafe extern "C" fn ff_world_positions(
    world: *const FfWorld,
    object_index: usize,
    out: *mut f64,
    len: usize,
) -> c_int {
    call("ff_world_positions", || {
        let w = unsafe { world_ref(world)? };
        let o = object(&w.world, object_index)?;
        copy_points(&o.render_positions(), out, len)
    })
}

/// Rest positions of the render points of object `object` (N x 3 row-major, metres, before
/// the placement) into `out` (capacity `len` >= 3 N doubles).
#[no_mangle]
pub unsafe extern "C" fn ff_world_rest_positions(
    world: *const FfWorld,
    object_index: usize,
    out: *mut f64,
    len: usize,
) -> c_int {
    call("ff_world_rest_positions", || {
        let w = unsafe { world_ref(world)? };
        let o = object(&w.world, object_index)?;
        copy_points(o.render_rest(), out, len)
    })
}

/// Hold boundary `boundary` of object `object` at the rigid pose x = R X + t of its placed
/// rest positions X, from the next step on (whatever the time: a target the caller moves
/// between steps). `rotation`: R, 9 doubles row-major, a proper rotation (orthonormal, det +1,
/// to 1e-9), NULL for the identity; `translation`: t, 3 doubles, metres.
#[no_mangle]
pub unsafe extern "C" fn ff_world_set_boundary_pose(
    world: *mut FfWorld,
    object_index: usize,
    boundary: usize,
    rotation: *const f64,
    translation: *const f64,
) -> c_int {
    call("ff_world_set_boundary_pose", || {
        let w = unsafe { world_mut(world)? };
        let p = unsafe { pose(rotation, translation)? };
        w.world
            .set_boundary_pose(object_index, boundary, &p)
            .map_err(lib_err)
    })
}

/// Move collider `collider` to the rigid pose x -> R x + t of its definition in the scene,
/// for every object from the next step on (absolute, not accumulated: a kinematic obstacle;
/// it replaces the collider's scripted motion, and for a collider with a parent it is relative
/// to the parent's frame). Any shape takes any rigid pose. `rotation` and `translation` as in
/// [`ff_world_set_boundary_pose`].
#[no_mangle]
pub unsafe extern "C" fn ff_world_set_collider_pose(
    world: *mut FfWorld,
    collider: usize,
    rotation: *const f64,
    translation: *const f64,
) -> c_int {
    call("ff_world_set_collider_pose", || {
        let w = unsafe { world_mut(world)? };
        let p = unsafe { pose(rotation, translation)? };
        w.world.set_collider_pose(collider, &p).map_err(lib_err)
    })
}

/// Gravity for every object from the next step on: `gravity`, 3 doubles, m/s^2 (finite); NULL
/// turns gravity off.
#[no_mangle]
pub unsafe extern "C" fn ff_world_set_gravity(world: *mut FfWorld, gravity: *const f64) -> c_int {
    call("ff_world_set_gravity", || {
        let w = unsafe { world_mut(world)? };
        let g = if gravity.is_null() {
            None
        } else {
            let g = unsafe { slice(gravity, 3, "gravity")? };
            Some([g[0], g[1], g[2]])
        };
        w.world.set_gravity(g).map_err(lib_err)
    })
}

/// Length of object `object`'s state vectors z and zdot: 12 (m + 1) for m + 1 modes (0 for
/// NULL or a bad index). z holds the 3 x 4 affine handles Z_j of x(X) = X + sum_j W_j(X) Z_j
/// [X; 1] at `z[4 (m + 1) r + 4 j + a]` = Z_j\[r\]\[a\]; zdot = dz/dt (per second).
#[no_mangle]
pub unsafe extern "C" fn ff_world_state_len(world: *const FfWorld, object_index: usize) -> usize {
    unsafe { peek_object(world, object_index) }.map_or(0, |o| o.sim().z().len())
}

/// Copy object `object`'s reduced coordinates z and velocity zdot (12 (m + 1) each, layout
/// in [`ff_world_state_len`]) into `z` and `zdot`, each of capacity `len` >=
/// [`ff_world_state_len`].
#[no_mangle]
pub unsafe extern "C" fn ff_world_get_state(
    world: *const FfWorld,
    object_index: usize,
    z: *mut f64,
    zdot: *mut f64,
    len: usize,
) -> c_int {
    call("ff_world_get_state", || {
        let w = unsafe { world_ref(world)? };
        let sim = object(&w.world, object_index)?.sim();
        let n = sim.z().len();
        let zo = out_slice(z, len, n, "z")?;
        let zdo = out_slice(zdot, len, n, "zdot")?;
        zo.copy_from_slice(sim.z());
        zdo.copy_from_slice(sim.zdot());
        Ok(())
    })
}

/// Set object `object`'s state from `z` and `zdot` (each exactly `len` =
/// [`ff_world_state_len`] finite doubles), e.g. one saved with [`ff_world_get_state`]; the
/// solver's history is dropped, time goes on. All or nothing: a refused state leaves the
/// object as it was.
#[no_mangle]
pub unsafe extern "C" fn ff_world_set_state(
    world: *mut FfWorld,
    object_index: usize,
    z: *const f64,
    zdot: *const f64,
    len: usize,
) -> c_int {
    call("ff_world_set_state", || {
        let w = unsafe { world_mut(world)? };
        if z.is_null() || zdot.is_null() {
            return Err((Status::NullPointer, "z or zdot is NULL".into()));
        }
        let z = unsafe { slice(z, len, "z")? };
        let zdot = unsafe { slice(zdot, len, "zdot")? };
        w.world.set_state(object_index, z, zdot).map_err(lib_err)
    })
}

/// Number of warnings so far (setup, steps that did not converge, inversions, Newton Hessian
/// fallbacks; 0 for NULL).
#[no_mangle]
pub unsafe extern "C" fn ff_world_warning_count(world: *const FfWorld) -> usize {
    unsafe { peek(world) }.map_or(0, |w| w.warnings.len())
}

/// Warning `index` (NUL-terminated; NULL for NULL or a bad index). Owned by the world: valid
/// until [`ff_world_free`].
#[no_mangle]
pub unsafe extern "C" fn ff_world_warning(world: *const FfWorld, index: usize) -> *const c_char {
    unsafe { peek(world) }
        .and_then(|w| w.warnings.get(index))
        .map_or(std::ptr::null(), |s| s.as_ptr())
}
