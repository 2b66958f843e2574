//! Gradients through a recorded run, for C (docs/gradients.md; docs/c-api.md "Gradients"):
//! record a world's steps ([`ff_recording_start`], [`ff_recording_step`]), then one reverse
//! pass of a loss given as dL/dz per frame ([`ff_recording_backward`]), and read the
//! gradients ([`ff_gradients_material`] and the rest). A loss on positions of rest points
//! becomes dL/dz with [`ff_world_positions_adjoint`]; [`ff_world_map_points`] gives those
//! positions. A thin caller of [`freeform::scene::WorldRecording`], objects in contact
//! included.

use crate::world::{call, lib_err, object, world_mut, world_ref, CResult, FfWorld};
use crate::{out_slice, slice, Status};
use freeform::scene::{WorldGradients, WorldRecording};
use freeform::sim::gradient::positions_adjoint;
use freeform::sim::object::map_points;
use std::ffi::c_int;

/// A recorded run of a world (C type `ff_recording`); see [`ff_recording_start`].
pub struct FfRecording {
    /// None once the reverse pass consumed it.
    rec: Option<WorldRecording>,
}

/// The gradients of one reverse pass (C type `ff_gradients`); see [`ff_recording_backward`].
pub struct FfGradients {
    g: WorldGradients,
}

unsafe fn recording_mut<'a>(r: *mut FfRecording) -> CResult<&'a mut FfRecording> {
    if r.is_null() {
        return Err((Status::NullPointer, "recording is NULL".into()));
    }
    // SAFETY: a live recording from ff_recording_start, used by one thread at a time.
    Ok(unsafe { &mut *r })
}

unsafe fn gradients_ref<'a>(g: *const FfGradients) -> CResult<&'a WorldGradients> {
    if g.is_null() {
        return Err((Status::NullPointer, "gradients is NULL".into()));
    }
    // SAFETY: live gradients from ff_recording_backward.
    Ok(unsafe { &(*g).g })
}

fn consumed() -> (Status, String) {
    (
        Status::InvalidArgument,
        "the reverse pass was already taken on this recording (it consumes the tape); record \
         the run again"
            .into(),
    )
}

/// Start recording every object of `world` from its current state for about `steps` steps
/// into `*out` (free with [`ff_recording_free`]). The tapes' memory (12 (m + 1) doubles per
/// object and step) is checked first: `FF_ERR_INVALID_ARGUMENT` with the estimate if it
/// would not fit.
#[no_mangle]
pub unsafe extern "C" fn ff_recording_start(
    world: *const FfWorld,
    steps: usize,
    out: *mut *mut FfRecording,
) -> c_int {
    call("ff_recording_start", || {
        let w = unsafe { world_ref(world)? };
        if out.is_null() {
            return Err((Status::NullPointer, "out is NULL".into()));
        }
        let rec = w.world.record(steps).map_err(lib_err)?;
        let boxed = Box::into_raw(Box::new(FfRecording { rec: Some(rec) }));
        // SAFETY: checked non-NULL; the caller provides a writable pointer.
        unsafe { *out = boxed };
        Ok(())
    })
}

/// Free a recording (NULL is ignored).
#[no_mangle]
pub unsafe extern "C" fn ff_recording_free(rec: *mut FfRecording) {
    if !rec.is_null() {
        // SAFETY: made by Box::into_raw in ff_recording_start, freed once by contract.
        drop(unsafe { Box::from_raw(rec) });
    }
}

/// Steps recorded so far (0 for NULL or a consumed recording).
#[no_mangle]
pub unsafe extern "C" fn ff_recording_steps(rec: *const FfRecording) -> usize {
    // SAFETY: NULL or a live recording.
    unsafe { rec.as_ref() }
        .and_then(|r| r.rec.as_ref())
        .map_or(0, WorldRecording::steps)
}

/// One step of `world` (as [`crate::ff_world_step`]), recorded in `rec`: every object is
/// checked against its tape first (`FF_ERR_INVALID_ARGUMENT`, nothing moves, when one was
/// changed by a setter since the recording began).
#[no_mangle]
pub unsafe extern "C" fn ff_recording_step(rec: *mut FfRecording, world: *mut FfWorld) -> c_int {
    call("ff_recording_step", || {
        let r = unsafe { recording_mut(rec)? };
        let w = unsafe { world_mut(world)? };
        let tape = r.rec.as_mut().ok_or_else(consumed)?;
        w.step_with(|world| world.step_recorded(tape).map(|_| ()))
    })
}

/// The reverse pass of a loss L(z_0, ..., z_T) over the recorded run into `*out` (free with
/// [`ff_gradients_free`]). `dl_dz` has `objects` entries (the world's object count), each
/// NULL (L does not see that object) or dL/dz of the object per frame: (T + 1) x
/// [`crate::ff_world_state_len`] doubles, row-major, row 0 the start. Consumes the tape once
/// it succeeds (a refused loss, e.g. with NaN, leaves it for a corrected call). Refused: a
/// changed world, a step that did not converge, an exact Hessian that is not positive
/// definite (each named).
#[no_mangle]
pub unsafe extern "C" fn ff_recording_backward(
    rec: *mut FfRecording,
    world: *const FfWorld,
    dl_dz: *const *const f64,
    objects: usize,
    out: *mut *mut FfGradients,
) -> c_int {
    call("ff_recording_backward", || {
        let r = unsafe { recording_mut(rec)? };
        let w = unsafe { world_ref(world)? };
        if out.is_null() {
            return Err((Status::NullPointer, "out is NULL".into()));
        }
        let tape = r.rec.as_ref().ok_or_else(consumed)?;
        let n = w.world.objects().len();
        if objects != n {
            return Err((
                Status::InvalidArgument,
                format!("dl_dz has {objects} entries; the world has {n} objects"),
            ));
        }
        if dl_dz.is_null() && n > 0 {
            return Err((Status::NullPointer, "dl_dz is NULL".into()));
        }
        let frames = tape.steps() + 1;
        let mut loss = Vec::with_capacity(n);
        for i in 0..n {
            // SAFETY: the caller provides `objects` readable pointers at dl_dz.
            let p = unsafe { *dl_dz.add(i) };
            if p.is_null() {
                loss.push(Vec::new());
                continue;
            }
            let len = w.world.objects()[i].sim().z().len();
            let all = unsafe { slice(p, frames * len, "dl_dz entry")? };
            loss.push(all.chunks(len).map(<[f64]>::to_vec).collect());
        }
        // A refused loss leaves the tape: the pass runs on a copy (12 (m + 1) doubles per
        // object and step), dropped once it succeeded.
        let g = tape.clone().backward(&w.world, &loss).map_err(lib_err)?;
        r.rec = None;
        let boxed = Box::into_raw(Box::new(FfGradients { g }));
        // SAFETY: checked non-NULL.
        unsafe { *out = boxed };
        Ok(())
    })
}

/// Free gradients (NULL is ignored).
#[no_mangle]
pub unsafe extern "C" fn ff_gradients_free(g: *mut FfGradients) {
    if !g.is_null() {
        // SAFETY: made by Box::into_raw in ff_recording_backward, freed once by contract.
        drop(unsafe { Box::from_raw(g) });
    }
}

fn object_gradients(
    g: &WorldGradients,
    index: usize,
) -> CResult<&freeform::sim::gradient::Gradients> {
    g.objects.get(index).ok_or_else(|| {
        (
            Status::InvalidArgument,
            format!(
                "object index {index} is out of range ({} objects)",
                g.objects.len()
            ),
        )
    })
}

/// Object `object`'s material gradients into `out[2]`: dL/dE (per Pa) and dL/dnu, summed
/// over the object (a homogeneous object's; per region: the Rust or Python API).
#[no_mangle]
pub unsafe extern "C" fn ff_gradients_material(
    g: *const FfGradients,
    object_index: usize,
    out: *mut f64,
) -> c_int {
    call("ff_gradients_material", || {
        let o = object_gradients(unsafe { gradients_ref(g)? }, object_index)?;
        out_slice(out, 2, 2, "out")?.copy_from_slice(&[o.youngs_total(), o.poisson_total()]);
        Ok(())
    })
}

/// Object `object`'s dL/dg into `out[3]` (per m/s^2); `FF_ERR_INVALID_ARGUMENT` for an
/// object without gravity.
#[no_mangle]
pub unsafe extern "C" fn ff_gradients_gravity(
    g: *const FfGradients,
    object_index: usize,
    out: *mut f64,
) -> c_int {
    call("ff_gradients_gravity", || {
        let o = object_gradients(unsafe { gradients_ref(g)? }, object_index)?;
        let gravity = o.gravity.ok_or_else(|| {
            (
                Status::InvalidArgument,
                format!("object {object_index} has no gravity, so no gradient by it"),
            )
        })?;
        out_slice(out, 3, 3, "out")?.copy_from_slice(&gravity);
        Ok(())
    })
}

/// Object `object`'s dL/dz_0 and dL/dzdot_0 (the recording's start state) into `z0` and
/// `zdot0`, each of capacity `len` >= [`crate::ff_world_state_len`].
#[no_mangle]
pub unsafe extern "C" fn ff_gradients_state(
    g: *const FfGradients,
    object_index: usize,
    z0: *mut f64,
    zdot0: *mut f64,
    len: usize,
) -> c_int {
    call("ff_gradients_state", || {
        let o = object_gradients(unsafe { gradients_ref(g)? }, object_index)?;
        out_slice(z0, len, o.z0.len(), "z0")?.copy_from_slice(&o.z0);
        out_slice(zdot0, len, o.zdot0.len(), "zdot0")?.copy_from_slice(&o.zdot0);
        Ok(())
    })
}

/// Object `object`'s gradients by collider `collider`'s friction coefficient and penalty
/// stiffness into `out[2]`: dL/dmu (0 without collider friction) and dL/dkappa (per Pa/m^2).
#[no_mangle]
pub unsafe extern "C" fn ff_gradients_collider(
    g: *const FfGradients,
    object_index: usize,
    collider: usize,
    out: *mut f64,
) -> c_int {
    call("ff_gradients_collider", || {
        let o = object_gradients(unsafe { gradients_ref(g)? }, object_index)?;
        let count = o.collider_stiffness.len();
        let kappa = o.collider_stiffness.get(collider).ok_or_else(|| {
            (
                Status::InvalidArgument,
                format!("collider index {collider} is out of range ({count} colliders)"),
            )
        })?;
        let mu = o.friction.as_ref().map_or(0.0, |f| f[collider]);
        out_slice(out, 2, 2, "out")?.copy_from_slice(&[mu, *kappa]);
        Ok(())
    })
}

/// The gradients by the penalty stiffness and the friction coefficient of the pair of objects
/// (`a`, `b`) into `out[2]`: dL/dkappa (per Pa/m^2, of the stiffness as the scene gives it)
/// and dL/dmu; `a` = `b` is the object's self-contact. `FF_ERR_INVALID_ARGUMENT` for a scene
/// without `[contact]`.
#[no_mangle]
pub unsafe extern "C" fn ff_gradients_contact_pair(
    g: *const FfGradients,
    a: usize,
    b: usize,
    out: *mut f64,
) -> c_int {
    call("ff_gradients_contact_pair", || {
        let g = unsafe { gradients_ref(g)? };
        let n = g.objects.len();
        if g.contact_stiffness.is_empty() {
            return Err((
                Status::InvalidArgument,
                "the scene has no [contact] section, so no pair gradients".into(),
            ));
        }
        if a >= n || b >= n {
            return Err((
                Status::InvalidArgument,
                format!("object pair ({a}, {b}) is out of range ({n} objects)"),
            ));
        }
        let k = a * n + b;
        out_slice(out, 2, 2, "out")?
            .copy_from_slice(&[g.contact_stiffness[k], g.contact_friction[k]]);
        Ok(())
    })
}

/// 3 `count`: the doubles of `count` points, refused when it overflows.
fn triple(count: usize) -> CResult<usize> {
    count.checked_mul(3).ok_or((
        Status::InvalidArgument,
        format!("count = {count} is too large"),
    ))
}

/// The weights of `count` rest points (count x 3 doubles, metres) of object `object`.
unsafe fn rest_points(
    w: &FfWorld,
    object_index: usize,
    points: *const f64,
    count: usize,
) -> CResult<(
    Vec<[f64; 3]>,
    freeform::precompute::skinning::SkinningWeights,
)> {
    let o = object(&w.world, object_index)?;
    let flat = unsafe { slice(points, triple(count)?, "points")? };
    let rest: Vec<[f64; 3]> = flat.chunks(3).map(|p| [p[0], p[1], p[2]]).collect();
    let weights = o.basis().weights(&rest).map_err(lib_err)?;
    Ok((rest, weights))
}

/// Positions of `count` rest points `points` (count x 3, metres; inside or near object
/// `object`) under its current state into `out` (capacity `len` >= 3 count).
#[no_mangle]
pub unsafe extern "C" fn ff_world_map_points(
    world: *const FfWorld,
    object_index: usize,
    points: *const f64,
    count: usize,
    out: *mut f64,
    len: usize,
) -> c_int {
    call("ff_world_map_points", || {
        let w = unsafe { world_ref(world)? };
        let (rest, weights) = unsafe { rest_points(w, object_index, points, count)? };
        let sim = object(&w.world, object_index)?.sim();
        let x = map_points(sim.layout(), sim.z(), &rest, &weights);
        let o = out_slice(out, len, triple(count)?, "out")?;
        for (dst, p) in o.chunks_mut(3).zip(&x) {
            dst.copy_from_slice(p);
        }
        Ok(())
    })
}

/// dL/dz (into `out`, capacity `len` >= [`crate::ff_world_state_len`]) of a loss on the
/// positions of `count` rest points `points` (count x 3, metres) of object `object`, from
/// `dl_dx` (count x 3): the transpose of [`ff_world_map_points`]'s map, which is linear in z.
#[no_mangle]
pub unsafe extern "C" fn ff_world_positions_adjoint(
    world: *const FfWorld,
    object_index: usize,
    points: *const f64,
    count: usize,
    dl_dx: *const f64,
    out: *mut f64,
    len: usize,
) -> c_int {
    call("ff_world_positions_adjoint", || {
        let w = unsafe { world_ref(world)? };
        let (rest, weights) = unsafe { rest_points(w, object_index, points, count)? };
        let flat = unsafe { slice(dl_dx, triple(count)?, "dl_dx")? };
        let g: Vec<[f64; 3]> = flat.chunks(3).map(|p| [p[0], p[1], p[2]]).collect();
        let sim = object(&w.world, object_index)?.sim();
        let dz = positions_adjoint(sim.layout(), &rest, &weights, &g).map_err(lib_err)?;
        out_slice(out, len, dz.len(), "out")?.copy_from_slice(&dz);
        Ok(())
    })
}
