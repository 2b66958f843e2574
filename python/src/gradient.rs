//! `freeform.Recording`: a world's run recorded for gradients, and the reverse pass
//! (docs/gradients.md); `freeform.map_points` and `freeform.positions_adjoint` carry a loss
//! on positions to the reduced coordinates.

use crate::convert::{array1, points_array};
use crate::errors::{invalid, scene_to_py};
use crate::world::{object_index, step_dict, PyWorld};
use freeform::precompute::skinning::SkinningWeights;
use freeform::scene::WorldRecording;
use freeform::sim::gradient::positions_adjoint as adjoint_of_positions;
use freeform::sim::object::map_points as map_rest_points;
use freeform::sim::ReducedSim;
use numpy::{IntoPyArray, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// A recorded run of every object of a world: ``Recording(world, steps)`` starts it (the
/// tapes' memory is checked first), ``step(world)`` steps the world and records the step,
/// ``backward(world, dl_dz)`` takes the reverse pass once.
#[pyclass(module = "freeform", name = "Recording")]
pub struct PyRecording {
    rec: Option<WorldRecording>,
    names: Vec<String>,
}

fn used(py: Python<'_>) -> PyErr {
    invalid(
        py,
        "backward was already taken on this recording (it consumes the tape); record the run \
         again",
    )
}

#[pymethods]
impl PyRecording {
    /// Start recording every object of ``world`` from its current state, for about ``steps``
    /// steps (a ``[contact]`` scene too: collider and object-object contact and friction are
    /// differentiated; steps that solved objects together as an island are reversed jointly).
    /// Refused (InvalidInputError): tapes that would not fit in memory.
    #[new]
    fn new(py: Python<'_>, world: PyRef<'_, PyWorld>, steps: i128) -> PyResult<PyRecording> {
        let steps = crate::convert::count(py, steps, "steps", usize::MAX)?;
        let rec = world.world.record(steps).map_err(|e| scene_to_py(py, &e))?;
        let names = world
            .world
            .objects()
            .iter()
            .map(|o| o.name().to_string())
            .collect();
        Ok(PyRecording {
            rec: Some(rec),
            names,
        })
    }

    /// Steps recorded.
    fn steps(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(self.rec.as_ref().ok_or_else(|| used(py))?.steps())
    }

    /// Bytes the tapes hold.
    fn tape_bytes(&self, py: Python<'_>) -> PyResult<u64> {
        Ok(self.rec.as_ref().ok_or_else(|| used(py))?.tape_bytes())
    }

    /// One step of ``world``, recorded: the step reports, as ``World.step`` returns them.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        mut world: PyRefMut<'py, PyWorld>,
    ) -> PyResult<Bound<'py, PyList>> {
        let rec = self.rec.as_mut().ok_or_else(|| used(py))?;
        let reports = world
            .world
            .step_recorded(rec)
            .map_err(|e| scene_to_py(py, &e))?;
        let dicts = reports
            .iter()
            .zip(&self.names)
            .map(|(r, n)| step_dict(py, n, r))
            .collect::<PyResult<Vec<_>>>()?;
        PyList::new(py, dicts)
    }

    /// The reverse pass of a loss L(z_0, ..., z_T): ``dl_dz`` maps an object (name) to an
    /// array (T + 1, 12 (m + 1)) of dL/dz per frame (row 0: the start; rows of zeros where L
    /// does not see a frame); objects not named do not enter L. Returns, per object name, a
    /// dict: ``youngs``, ``poisson``, ``density`` (the sums over the object: dL/dE, dL/dnu,
    /// dL/drho of a homogeneous object), ``youngs_per_point``, ``poisson_per_point``,
    /// ``density_per_point`` (per integration point: a region's gradient is the sum over its
    /// points), ``gravity`` (3 values, or None without gravity), ``friction`` (dL/dmu per
    /// collider, or None without collider friction), ``collider_stiffness`` (dL/dkappa per
    /// collider, per Pa/m^2), ``collider_pose`` ((steps, colliders, 2, 6): per recorded step
    /// and collider, at the pose the step began with ``[..., 0, :]`` and at its end
    /// ``[..., 1, :]``, dL/d(translation) then dL/d(rotation), a small world rotation about
    /// the pose's origin; docs/gradients.md), ``boundary_pose`` ((steps, regions, 6): each
    /// held region's target at each step's end, translation then rotation),
    /// ``boundary_stiffness`` (dL/dkappa per held region), ``contact_stiffness`` and
    /// ``contact_friction`` (``[contact]`` scenes, else None: the object's row of dL/dkappa
    /// and dL/dmu of each pair of objects, per other object in world order, the entry of the
    /// object itself its self-contact; a pair's value is in both its objects' rows),
    /// ``placement`` (a dict of ``translation``, ``rotation`` (a small
    /// world rotation on top of the placement's, radians), ``velocity``, ``angular_velocity``,
    /// 3 values each; None when the recording did not start at the object's placement, as
    /// built or set by ``set_placement``, or the object has held regions), ``z0``, ``zdot0``,
    /// ``forward_s``, ``backward_s``, ``exact_hessians`` and ``hessian_products`` (what the
    /// reverse pass's solves took), ``tape_bytes``. Consumes the recording once it succeeds
    /// (a refused loss leaves it for a corrected call).
    fn backward<'py>(
        &mut self,
        py: Python<'py>,
        world: PyRef<'py, PyWorld>,
        dl_dz: &Bound<'py, PyDict>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let rec = self.rec.as_ref().ok_or_else(|| used(py))?;
        let frames = rec.steps() + 1;
        let mut per_object = vec![Vec::new(); self.names.len()];
        for (key, value) in dl_dz.iter() {
            let i = object_index(py, &world.world, &key)?;
            let n = world.world.object(i).sim().z().len();
            let a: PyReadonlyArray2<'py, f64> = value.extract().map_err(|_| {
                invalid(
                    py,
                    format!(
                        "dl_dz[{}]: give a float array of shape ({frames}, {n})",
                        self.names[i]
                    ),
                )
            })?;
            if a.shape() != [frames, n] {
                return Err(invalid(
                    py,
                    format!(
                        "dl_dz[{}] has shape ({}, {}); the recording needs ({frames}, {n}) \
                         (the start and {} recorded steps, 12 (m + 1) values each)",
                        self.names[i],
                        a.shape()[0],
                        a.shape()[1],
                        frames - 1
                    ),
                ));
            }
            let v = a.as_array();
            per_object[i] = (0..frames).map(|t| v.row(t).to_vec()).collect();
        }
        // A refused loss (a bad frame, NaN) leaves the tape for a corrected call: the
        // reverse pass runs on a copy (12 (m + 1) values per step), and the tape is dropped
        // only once it succeeded.
        let rec = self.rec.clone().ok_or_else(|| used(py))?;
        let tapes: Vec<(f64, u64)> = rec
            .objects()
            .iter()
            .map(|r| (r.forward_s(), r.tape_bytes()))
            .collect();
        let w = &world.world;
        let grads = py
            .detach(|| rec.backward(w, &per_object))
            .map_err(|e| scene_to_py(py, &e))?;
        self.rec = None;
        let out = PyDict::new(py);
        let n = grads.objects.len();
        for (i, g) in grads.objects.iter().enumerate() {
            let o = w.object(i);
            let pts = o.rest_points();
            // The object's own weights at its integration points (kept by the object).
            let weights = o.integration_weights().map_err(|e| scene_to_py(py, &e))?;
            let density = g.density(pts, weights).map_err(|e| scene_to_py(py, &e))?;
            let youngs = g
                .youngs_at_points(pts.len())
                .map_err(|e| scene_to_py(py, &e))?;
            let poisson = g
                .poisson_at_points(pts.len())
                .map_err(|e| scene_to_py(py, &e))?;
            let d = PyDict::new(py);
            d.set_item("youngs", g.youngs_total())?;
            d.set_item("poisson", g.poisson_total())?;
            d.set_item("density", density.iter().sum::<f64>())?;
            d.set_item("youngs_per_point", array1(py, youngs))?;
            d.set_item("poisson_per_point", array1(py, poisson))?;
            d.set_item("density_per_point", array1(py, density))?;
            d.set_item("gravity", g.gravity.map(|v| array1(py, v.to_vec())))?;
            d.set_item("friction", g.friction.clone().map(|v| array1(py, v)))?;
            d.set_item(
                "collider_stiffness",
                array1(py, g.collider_stiffness.clone()),
            )?;
            // None where the gradient does not apply (documented above), not an error: the
            // other gradients of the run stand.
            let placement = match g.placement(o.sim(), &o.spec().placement) {
                Ok(p) => {
                    let pd = PyDict::new(py);
                    pd.set_item("translation", array1(py, p.translation.to_vec()))?;
                    pd.set_item("rotation", array1(py, p.rotation.to_vec()))?;
                    pd.set_item("velocity", array1(py, p.velocity.to_vec()))?;
                    pd.set_item("angular_velocity", array1(py, p.angular_velocity.to_vec()))?;
                    Some(pd)
                }
                Err(_) => None,
            };
            d.set_item("placement", placement)?;
            // (steps, colliders, 2, 6): per step and collider, at the step's start and end, the
            // translation's and the rotation's gradient.
            let colliders = g.collider_poses.first().map_or(0, Vec::len);
            let flat: Vec<f64> = g
                .collider_poses
                .iter()
                .flatten()
                .flat_map(|p| {
                    [p.start, p.end]
                        .into_iter()
                        .flat_map(|q| q.translation.into_iter().chain(q.rotation))
                })
                .collect();
            let poses = numpy::ndarray::Array4::from_shape_vec(
                (g.collider_poses.len(), colliders, 2, 6),
                flat,
            )
            .map_err(|e| invalid(py, format!("collider pose gradients: {e}")))?;
            d.set_item("collider_pose", poses.into_pyarray(py))?;
            // (steps, regions, 6): per step and held region, the target's translation and
            // rotation gradients at the step's end.
            let regions = g.boundary_poses.first().map_or(0, Vec::len);
            let flat: Vec<f64> = g
                .boundary_poses
                .iter()
                .flatten()
                .flat_map(|p| p.translation.into_iter().chain(p.rotation))
                .collect();
            let targets =
                numpy::ndarray::Array3::from_shape_vec((g.boundary_poses.len(), regions, 6), flat)
                    .map_err(|e| invalid(py, format!("boundary pose gradients: {e}")))?;
            d.set_item("boundary_pose", targets.into_pyarray(py))?;
            d.set_item(
                "boundary_stiffness",
                array1(py, g.boundary_stiffness.clone()),
            )?;
            // The object's row of the pair matrices (None without [contact]).
            let row =
                |m: &[f64]| (!m.is_empty()).then(|| array1(py, m[i * n..(i + 1) * n].to_vec()));
            d.set_item("contact_stiffness", row(&grads.contact_stiffness))?;
            d.set_item("contact_friction", row(&grads.contact_friction))?;
            d.set_item("z0", array1(py, g.z0.clone()))?;
            d.set_item("zdot0", array1(py, g.zdot0.clone()))?;
            d.set_item("forward_s", tapes[i].0)?;
            d.set_item("backward_s", g.backward_s)?;
            d.set_item("exact_hessians", g.exact_hessians)?;
            d.set_item("hessian_products", g.hessian_products)?;
            d.set_item("tape_bytes", tapes[i].1)?;
            out.set_item(&self.names[i], d)?;
        }
        Ok(out)
    }

    fn __repr__(&self) -> String {
        match &self.rec {
            Some(r) => format!(
                "Recording({} objects, {} steps, {} bytes)",
                self.names.len(),
                r.steps(),
                r.tape_bytes()
            ),
            None => format!("Recording({} objects, backward taken)", self.names.len()),
        }
    }
}

/// An object's model, rest points ``points`` (N x 3) and their skinning weights.
fn object_points<'w>(
    py: Python<'_>,
    world: &'w PyWorld,
    object: &Bound<'_, PyAny>,
    points: &Bound<'_, PyAny>,
) -> PyResult<(&'w ReducedSim, Vec<[f64; 3]>, SkinningWeights)> {
    let i = object_index(py, &world.world, object)?;
    let rest = crate::convert::points(py, points, "points")?;
    let o = world.world.object(i);
    let w = o.basis().weights(&rest).map_err(|e| scene_to_py(py, &e))?;
    Ok((o.sim(), rest, w))
}

/// Positions of rest points ``points`` (N x 3, metres; inside or near the object) under the
/// object's current state: x = X + sum_j W_j(X) Z_j [X; 1], (N, 3) metres.
#[pyfunction]
pub fn map_points<'py>(
    py: Python<'py>,
    world: PyRef<'py, PyWorld>,
    object: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let (sim, rest, w) = object_points(py, &world, object, points)?;
    let x = map_rest_points(sim.layout(), sim.z(), &rest, &w);
    Ok(points_array(py, &x).into_any())
}

/// dL/dz (12 (m + 1)) of a loss on the positions of rest points ``points`` (N x 3, metres),
/// from ``dl_dx`` (N x 3): the transpose of ``map_points``'s map, which is linear in z.
#[pyfunction]
pub fn positions_adjoint<'py>(
    py: Python<'py>,
    world: PyRef<'py, PyWorld>,
    object: &Bound<'py, PyAny>,
    points: &Bound<'py, PyAny>,
    dl_dx: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let (sim, rest, w) = object_points(py, &world, object, points)?;
    let g = crate::convert::points(py, dl_dx, "dl_dx")?;
    let dz = adjoint_of_positions(sim.layout(), &rest, &w, &g).map_err(|e| scene_to_py(py, &e))?;
    Ok(array1(py, dz).into_any())
}
