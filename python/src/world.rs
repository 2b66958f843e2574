//! `freeform.Scene` and `freeform.World`: scenes from TOML or dicts, stepped live.

use crate::basis::{run_released, PyBasis};
use crate::convert::{matrix3, per_point, points_array, report, vec3, vector};
use crate::errors::{invalid, scene_to_py};
use freeform::io::basis::BasisMetadata;
use freeform::material::{Material, MaterialField};
use freeform::options::Front;
use freeform::precompute::sampling::{cloud_volumes, CloudVolumeOptions, IntegrationPoints};
use freeform::scene::StepRow;
use freeform::scene::{ObjectShape, ObjectSpec, PreparedObject, RunSettings, Scene, World};
use freeform::sim::motion::{Motion, Rigid};
use freeform::sim::Boundary;
use freeform::sim::{Placement, StepReport};
use numpy::{IntoPyArray, PyArray2, PyArrayMethods, PyReadwriteArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use serde::de::DeserializeOwned;
use std::path::PathBuf;

/// A Python value (dict, list, tuple, str, bool, numbers, NumPy scalars and arrays) as a
/// serde type, through TOML values: NaN and infinities reach the scene's own checks, which
/// name the field.
fn from_python<T: DeserializeOwned>(
    py: Python<'_>,
    value: &Bound<'_, PyAny>,
    what: &str,
) -> PyResult<T> {
    let value = to_toml(py, value, what)?;
    value
        .try_into()
        .map_err(|e| invalid(py, format!("{what}: {e}")))
}

/// `v` (at `path`, for errors) as a TOML value.
fn to_toml(py: Python<'_>, v: &Bound<'_, PyAny>, path: &str) -> PyResult<toml::Value> {
    use pyo3::types::{PyBool, PyFloat, PyInt, PyString, PyTuple};
    if let Ok(b) = v.cast::<PyBool>() {
        return Ok(toml::Value::Boolean(b.is_true()));
    }
    if let Ok(s) = v.cast::<PyString>() {
        return Ok(toml::Value::String(s.to_string()));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut table = toml::Table::new();
        for (k, x) in d.iter() {
            if x.is_none() {
                continue; // None is an absent key (what `to_dict` writes for an unset option)
            }
            // Int keys are names too (image labels: {1: "bone"}), as the JSON route had them.
            let key: String = match k.extract::<String>() {
                Ok(s) => s,
                Err(_) if k.cast::<PyInt>().is_ok() => k.str()?.to_string(),
                Err(_) => {
                    return Err(invalid(
                        py,
                        format!("{path}: keys must be strings (or ints), got {k}"),
                    ))
                }
            };
            let inner = format!("{path}.{key}");
            table.insert(key, to_toml(py, &x, &inner)?);
        }
        return Ok(toml::Value::Table(table));
    }
    if v.cast::<PyList>().is_ok() || v.cast::<PyTuple>().is_ok() {
        let items: Vec<Bound<'_, PyAny>> = v.try_iter()?.collect::<PyResult<_>>()?;
        return items
            .iter()
            .enumerate()
            .map(|(i, x)| to_toml(py, x, &format!("{path}[{i}]")))
            .collect::<PyResult<Vec<_>>>()
            .map(toml::Value::Array);
    }
    // NumPy: an array becomes nested lists; a scalar is told apart by its dtype's kind.
    let kind = v
        .getattr("dtype")
        .and_then(|d| d.getattr("kind"))
        .and_then(|k| k.extract::<String>())
        .ok();
    if kind.is_some()
        && v.getattr("ndim")
            .and_then(|n| n.extract::<usize>())
            .unwrap_or(0)
            > 0
    {
        return to_toml(py, &v.call_method0("tolist")?, path);
    }
    let integral = matches!(kind.as_deref(), Some("i" | "u")) || v.cast::<PyInt>().is_ok();
    if kind.as_deref() == Some("b") {
        return Ok(toml::Value::Boolean(v.extract::<bool>()?));
    }
    if integral {
        return v
            .extract::<i64>()
            .map(toml::Value::Integer)
            .map_err(|_| invalid(py, format!("{path}: the integer {v} is out of range")));
    }
    if kind.as_deref() == Some("f") || v.cast::<PyFloat>().is_ok() {
        return Ok(toml::Value::Float(v.extract::<f64>()?));
    }
    let ty = v
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into());
    Err(invalid(
        py,
        format!(
            "{path}: a {ty} has no place in a scene (use dicts, lists, strings, booleans and \
             real numbers)"
        ),
    ))
}

/// A scene: objects, materials, boundaries, colliders, time stepping (docs/scenes.md).
#[pyclass(module = "freeform", name = "Scene")]
#[derive(Clone)]
pub struct PyScene {
    scene: Scene,
    /// Where relative shape paths and the basis cache resolve.
    base_dir: PathBuf,
    /// Objects added from arrays (`add_object`), after the scene's own.
    prepared: Vec<PreparedObject>,
}

#[pymethods]
impl PyScene {
    /// Read a scene file (TOML); relative paths in it resolve against its directory.
    #[staticmethod]
    fn from_file(py: Python<'_>, path: PathBuf) -> PyResult<PyScene> {
        let scene = Scene::load(&path).map_err(|e| scene_to_py(py, &e))?;
        Ok(PyScene {
            scene,
            base_dir: RunSettings::for_scene_file(&path).base_dir,
            prepared: Vec::new(),
        })
    }

    /// A scene from TOML text; relative paths resolve against ``base_dir`` (default: the
    /// current directory).
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = None))]
    fn from_toml(py: Python<'_>, text: &str, base_dir: Option<PathBuf>) -> PyResult<PyScene> {
        let scene = Scene::from_toml(text).map_err(|e| scene_to_py(py, &e))?;
        Ok(PyScene {
            scene,
            base_dir: base_dir.unwrap_or_default(),
            prepared: Vec::new(),
        })
    }

    /// A scene from a dict with the scene file's structure (``{"simulation": {...},
    /// "object": [{...}], "collider": [...], ...}``), validated like a file, except that it
    /// may have no objects: add them from arrays with ``add_object``.
    #[staticmethod]
    #[pyo3(signature = (scene, base_dir = None))]
    fn from_dict(
        py: Python<'_>,
        scene: &Bound<'_, PyAny>,
        base_dir: Option<PathBuf>,
    ) -> PyResult<PyScene> {
        let scene: Scene = from_python(py, scene, "scene")?;
        scene.validate_settings().map_err(|e| scene_to_py(py, &e))?;
        Ok(PyScene {
            scene,
            base_dir: base_dir.unwrap_or_default(),
            prepared: Vec::new(),
        })
    }

    /// Add an object made from arrays: its basis (``Basis.from_points`` on these points),
    /// integration points (N, 3) in metres, per-point (or one) Young's modulus (Pa),
    /// Poisson ratio and density (kg/m^3), volumes (N,) in m^3 (None: estimated from the
    /// cloud), and optionally its boundaries (a list of ``{"region": ..., "motion": ...}``
    /// as in a scene file), placement (a dict) and cubature point count. It is drawn at its
    /// integration points. Not part of ``to_toml`` / ``to_dict``.
    #[pyo3(signature = (name, basis, points, youngs, poisson = None, density = None, volumes = None, *, boundaries = None, placement = None, cubature = None))]
    #[allow(clippy::too_many_arguments)]
    fn add_object(
        &mut self,
        py: Python<'_>,
        name: &str,
        basis: &PyBasis,
        points: &Bound<'_, PyAny>,
        youngs: &Bound<'_, PyAny>,
        poisson: Option<&Bound<'_, PyAny>>,
        density: Option<&Bound<'_, PyAny>>,
        volumes: Option<&Bound<'_, PyAny>>,
        boundaries: Option<&Bound<'_, PyAny>>,
        placement: Option<&Bound<'_, PyAny>>,
        cubature: Option<i128>,
    ) -> PyResult<()> {
        let cubature = cubature
            .map(|n| {
                crate::convert::count(py, n, "cubature", freeform::sim::cubature::MAX_CUBATURE)
            })
            .transpose()?;
        let pts = crate::convert::points(py, points, "points")?;
        let n = pts.len();
        let d = Material::default();
        let or_default = |v: Option<&Bound<'_, PyAny>>, value: f64, what: &str| match v {
            Some(v) if !v.is_none() => per_point(py, v, n, what),
            _ => Ok(vec![value; n]),
        };
        let youngs = per_point(py, youngs, n, "youngs")?;
        let poisson = or_default(poisson, d.poisson, "poisson")?;
        let density = or_default(density, d.density, "density")?;
        let material = MaterialField::from_arrays(youngs, poisson, density)
            .map_err(|e| scene_to_py(py, &e))?;
        let volumes = match volumes {
            Some(v) if !v.is_none() => per_point(py, v, n, "volumes")?,
            _ => {
                cloud_volumes(&pts, &CloudVolumeOptions::default())
                    .map_err(|e| scene_to_py(py, &e))?
                    .0
            }
        };
        let mut spec = ObjectSpec::with_shape(name, ObjectShape::arrays("numpy points"))
            .kernels(basis.basis.kernels.len())
            .modes(basis.basis.modes().saturating_sub(1));
        if let Some(b) = boundaries.filter(|b| !b.is_none()) {
            spec.boundaries = from_python::<Vec<Boundary>>(py, b, "boundaries")?;
        }
        if let Some(p) = placement.filter(|p| !p.is_none()) {
            spec.placement = from_python::<Placement>(py, p, "placement")?;
        }
        spec.cubature = cubature;
        // Names, boundaries and placement are checked with the scene's other objects now,
        // so the mistake is reported here rather than when the world is made.
        let mut all = self.scene.clone();
        all.objects
            .extend(self.prepared.iter().map(|p| p.spec.clone()));
        all.objects.push(spec.clone());
        all.validate().map_err(|e| scene_to_py(py, &e))?;
        self.prepared.push(PreparedObject {
            spec,
            basis: basis.basis.clone(),
            points: IntegrationPoints {
                points: pts,
                volumes,
            },
            material,
        });
        Ok(())
    }

    /// The scene as TOML text (reads back with ``from_toml``).
    fn to_toml(&self, py: Python<'_>) -> PyResult<String> {
        self.scene.to_toml().map_err(|e| scene_to_py(py, &e))
    }

    /// The scene as a dict (the scene file's structure, every default filled in).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        report(py, &self.scene)
    }

    /// Object names, in order (the scene's, then those added with ``add_object``).
    #[getter]
    fn object_names(&self) -> Vec<String> {
        self.scene
            .objects
            .iter()
            .chain(self.prepared.iter().map(|p| &p.spec))
            .map(|o| o.name.clone())
            .collect()
    }

    /// Time step, s.
    #[getter]
    fn dt(&self) -> f64 {
        self.scene.simulation.dt
    }

    /// Steps of a batch run (``freeform run``).
    #[getter]
    fn steps(&self) -> usize {
        self.scene.simulation.steps
    }

    /// Directory that relative paths and the basis cache resolve against.
    #[getter]
    fn base_dir(&self) -> PathBuf {
        self.base_dir.clone()
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene(objects={:?}, dt={}, steps={})",
            self.object_names(),
            self.dt(),
            self.steps()
        )
    }
}

/// A scene being simulated: step it, read and change it between steps.
#[pyclass(module = "freeform", name = "World")]
pub struct PyWorld {
    pub(crate) world: World,
}

/// An object given by index or name (the library checks both).
pub(crate) fn object_index(
    py: Python<'_>,
    world: &World,
    object: &Bound<'_, PyAny>,
) -> PyResult<usize> {
    if let Ok(name) = object.extract::<String>() {
        return world.object_named(&name).map_err(|e| scene_to_py(py, &e));
    }
    let index: i64 = object
        .extract()
        .map_err(|_| invalid(py, "object: give its index (int) or its name (str)"))?;
    let index = usize::try_from(index)
        .map_err(|_| invalid(py, format!("object {index}: indices count from 0")))?;
    world.object_at(index).map_err(|e| scene_to_py(py, &e))?;
    Ok(index)
}

/// A step report as a dict: the JSON report's step row (serde), with the object's name, the
/// time and the boundary deviation always present (None without boundaries).
pub(crate) fn step_dict<'py>(
    py: Python<'py>,
    name: &str,
    r: &StepReport,
) -> PyResult<Bound<'py, PyDict>> {
    let row = StepRow::from(r);
    let d = report(py, &row)?.cast_into::<PyDict>()?;
    d.set_item("object", name)?;
    d.set_item("time", r.time)?;
    d.set_item("boundary_rms_deviation", row.boundary_rms_deviation)?;
    Ok(d)
}

/// A rigid pose from NumPy arrays (the library's [`Rigid::from_arrays`]): rotation 3 x 3
/// (None: identity), translation 3 values in metres (None: zero).
fn rigid(
    py: Python<'_>,
    rotation: Option<&Bound<'_, PyAny>>,
    translation: Option<&Bound<'_, PyAny>>,
) -> PyResult<Rigid> {
    let rotation = match rotation {
        Some(r) if !r.is_none() => Some(matrix3(py, r, "rotation")?),
        _ => None,
    };
    let translation = match translation {
        Some(t) if !t.is_none() => Some(vec3(py, t, "translation")?),
        _ => None,
    };
    let flat = rotation.map(|r| r.concat());
    Rigid::from_arrays(flat.as_deref(), translation.as_ref().map(|t| &t[..]))
        .map_err(|e| scene_to_py(py, &e))
}

#[pymethods]
impl PyWorld {
    /// Set the scene up: every object's basis (from the cache or computed; releases the GIL,
    /// Ctrl-C interrupts), reduced model and render points. ``strict=True`` makes warnings
    /// errors (StrictModeError); ``cache=False`` computes every basis afresh.
    #[new]
    #[pyo3(signature = (scene, *, strict = false, progress = false, cache = None))]
    fn new(
        py: Python<'_>,
        scene: &PyScene,
        strict: bool,
        progress: bool,
        cache: Option<bool>,
    ) -> PyResult<PyWorld> {
        let mut s = scene.scene.clone();
        if let Some(enabled) = cache {
            s.cache.enabled = enabled;
        }
        let settings = RunSettings {
            base_dir: scene.base_dir.clone(),
            out: None,
            strict,
        };
        let prepared = scene.prepared.clone();
        let world = run_released(py, Front::Scene, progress, |p| {
            World::with_objects(&s, &settings, prepared, p)
        })?;
        Ok(PyWorld { world })
    }

    /// Advance every object by ``count`` steps (backward Euler; GIL released); returns the
    /// last step's reports, one dict per object. A step that does not converge is reported
    /// (``converged`` False, a warning), not raised, unless the world is strict.
    #[pyo3(signature = (count = 1))]
    fn step<'py>(&mut self, py: Python<'py>, count: i128) -> PyResult<Bound<'py, PyList>> {
        let count = crate::convert::count(py, count, "count", freeform::scene::MAX_STEPS)?;
        let world = &mut self.world;
        let reports = run_released(py, Front::Scene, false, |progress| {
            let mut last = Vec::new();
            for _ in 0..count {
                freeform::error::check_cancelled(progress, "step")?;
                last = world.step()?;
            }
            Ok(last)
        })?;
        let list = PyList::empty(py);
        for (object, r) in self.world.objects().iter().zip(&reports) {
            list.append(step_dict(py, object.name(), r)?)?;
        }
        Ok(list)
    }

    /// Simulated time, s.
    #[getter]
    fn time(&self) -> f64 {
        self.world.time()
    }

    /// Time step, s.
    #[getter]
    fn dt(&self) -> f64 {
        self.world.dt()
    }

    /// Steps taken.
    #[getter]
    fn steps(&self) -> usize {
        self.world.steps()
    }

    /// Object names, in order.
    #[getter]
    fn object_names(&self) -> Vec<String> {
        self.world
            .objects()
            .iter()
            .map(|o| o.name().to_string())
            .collect()
    }

    /// Warnings so far (setup, non-converged steps, inversions).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.world
            .warnings()
            .iter()
            .map(|w| Front::Scene.render(w))
            .collect()
    }

    /// Deformed render points of an object (index or name): mesh vertices, point-cloud
    /// points, or integration points of a primitive; (N, 3), metres. With ``out`` (a
    /// writable (N, 3) float array; float64 is written in place without a copy, float32 is
    /// rounded on assignment) they are written there and ``out`` is returned: no new NumPy
    /// array per call in a stepping loop.
    #[pyo3(signature = (object, out = None))]
    fn positions<'py>(
        &self,
        py: Python<'py>,
        object: &Bound<'py, PyAny>,
        out: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let i = object_index(py, &self.world, object)?;
        let x = self.world.object(i).render_positions();
        let Some(out) = out else {
            return Ok(points_array(py, &x).into_any());
        };
        let shape: Option<Vec<usize>> = out.getattr("shape").and_then(|s| s.extract()).ok();
        if shape.as_deref() != Some(&[x.len(), 3][..]) {
            return Err(invalid(
                py,
                format!(
                    "out: expected an array of shape ({}, 3), got {shape:?}",
                    x.len()
                ),
            ));
        }
        let Ok(out64) = out.cast::<PyArray2<f64>>() else {
            // Another dtype: a real float one takes the values by NumPy's assignment.
            let kind = out
                .getattr("dtype")
                .and_then(|d| d.getattr("kind"))
                .and_then(|k| k.extract::<String>())
                .unwrap_or_default();
            if kind != "f" {
                return Err(invalid(
                    py,
                    format!(
                        "out: expected a float array (float64 or float32), got dtype kind {kind:?}"
                    ),
                ));
            }
            out.set_item(py.Ellipsis(), points_array(py, &x))?;
            return Ok(out.clone());
        };
        let mut rw: PyReadwriteArray2<'_, f64> = out64
            .try_readwrite()
            .map_err(|e| invalid(py, format!("out: not writable ({e})")))?;
        let mut view = rw.as_array_mut();
        for (mut row, p) in view.rows_mut().into_iter().zip(&x) {
            row[0] = p[0];
            row[1] = p[1];
            row[2] = p[2];
        }
        drop(rw);
        Ok(out.clone())
    }

    /// Cauchy stress at the render points, (N, 3, 3), Pa: the object's material (with its
    /// region overrides) at the deformation gradient of the skinning map; zero at inverted
    /// points (det F <= 0).
    fn stress<'py>(
        &self,
        py: Python<'py>,
        object: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let i = object_index(py, &self.world, object)?;
        let sigma = self
            .world
            .object(i)
            .render_stress()
            .map_err(|e| scene_to_py(py, &e))?;
        let n = sigma.len();
        let flat: Vec<f64> = sigma.iter().flatten().flatten().copied().collect();
        Ok(crate::convert::array2(py, flat, n * 3, 3)
            .reshape([n, 3, 3])?
            .into_any())
    }

    /// Rest positions of the render points, (N, 3), metres.
    fn rest_positions<'py>(
        &self,
        py: Python<'py>,
        object: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let i = object_index(py, &self.world, object)?;
        Ok(points_array(py, self.world.object(i).render_rest()))
    }

    /// Deformed integration points, (N, 3), metres.
    fn integration_positions<'py>(
        &self,
        py: Python<'py>,
        object: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let i = object_index(py, &self.world, object)?;
        let x = self
            .world
            .object(i)
            .integration_positions()
            .map_err(|e| scene_to_py(py, &e))?;
        Ok(points_array(py, &x))
    }

    /// Mesh triangles (T, 3) as indices into the render points, or None for points.
    fn triangles<'py>(
        &self,
        py: Python<'py>,
        object: &Bound<'py, PyAny>,
    ) -> PyResult<Option<Bound<'py, PyArray2<u32>>>> {
        let i = object_index(py, &self.world, object)?;
        Ok(self.world.object(i).triangles().map(|t| {
            let n = t.len();
            let flat: Vec<u32> = t.iter().flatten().copied().collect();
            numpy::ndarray::Array2::from_shape_vec((n, 3), flat)
                .expect("3 indices per triangle")
                .into_pyarray(py)
        }))
    }

    /// The reduced state (z, zdot): two arrays of 12 (m + 1) values. z holds the 3 x 4
    /// affine handles Z_j of x(X) = X + sum_j W_j(X) Z_j [X; 1] with
    /// ``z[4 (m + 1) r + 4 j + a] = Z_j[r, a]``; zdot = dz/dt (per s).
    fn state<'py>(
        &self,
        py: Python<'py>,
        object: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let i = object_index(py, &self.world, object)?;
        let sim = self.world.object(i).sim();
        Ok((
            sim.z().to_vec().into_pyarray(py).into_any(),
            sim.zdot().to_vec().into_pyarray(py).into_any(),
        ))
    }

    /// Set the reduced state (as returned by ``state``); all or nothing.
    fn set_state(
        &mut self,
        py: Python<'_>,
        object: &Bound<'_, PyAny>,
        z: &Bound<'_, PyAny>,
        zdot: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let i = object_index(py, &self.world, object)?;
        let n = self.world.object(i).sim().z().len();
        let z = vector(py, z, n, "z")?;
        let zdot = vector(py, zdot, n, "zdot")?;
        self.world
            .set_state(i, &z, &zdot)
            .map_err(|e| scene_to_py(py, &e))
    }

    /// Gravity for every object from the next step on, m/s^2 (None: off).
    fn set_gravity(&mut self, py: Python<'_>, gravity: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let g = match gravity {
            Some(g) if !g.is_none() => Some(vec3(py, g, "gravity")?),
            _ => None,
        };
        self.world.set_gravity(g).map_err(|e| scene_to_py(py, &e))
    }

    /// Hold boundary ``boundary`` of an object at the rigid pose x = R X + t of its placed
    /// rest positions X from the next step on (rotation 3 x 3 proper, None: identity;
    /// translation in metres).
    #[pyo3(signature = (object, boundary, rotation = None, translation = None))]
    fn set_boundary_pose(
        &mut self,
        py: Python<'_>,
        object: &Bound<'_, PyAny>,
        boundary: i128,
        rotation: Option<&Bound<'_, PyAny>>,
        translation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let boundary = crate::convert::count(py, boundary, "boundary", usize::MAX)?;
        let i = object_index(py, &self.world, object)?;
        let pose = rigid(py, rotation, translation)?;
        self.world
            .set_boundary_pose(i, boundary, &pose)
            .map_err(|e| scene_to_py(py, &e))
    }

    /// A new motion for a boundary, as in a scene file: ``"fixed"``,
    /// ``{"translate": {"velocity": [...]}}``, ``{"rotate": {...}}``,
    /// ``{"keyframes": {...}}`` or ``{"pose": {...}}``; evaluated at the simulation time.
    fn set_boundary_motion(
        &mut self,
        py: Python<'_>,
        object: &Bound<'_, PyAny>,
        boundary: i128,
        motion: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let boundary = crate::convert::count(py, boundary, "boundary", usize::MAX)?;
        let i = object_index(py, &self.world, object)?;
        let motion: Motion = from_python(py, motion, "motion")?;
        self.world
            .set_boundary_motion(i, boundary, motion)
            .map_err(|e| scene_to_py(py, &e))
    }

    /// The kinematic pose of collider ``collider`` (its scene definition moved by
    /// x -> R x + t; absolute; it replaces the collider's scripted motion, and for a collider
    /// with a parent it is relative to the parent's frame). Any shape takes any rigid pose.
    #[pyo3(signature = (collider, rotation = None, translation = None))]
    fn set_collider_pose(
        &mut self,
        py: Python<'_>,
        collider: i128,
        rotation: Option<&Bound<'_, PyAny>>,
        translation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let collider = crate::convert::count(py, collider, "collider", usize::MAX)?;
        let pose = rigid(py, rotation, translation)?;
        self.world
            .set_collider_pose(collider, &pose)
            .map_err(|e| scene_to_py(py, &e))
    }

    /// Put an object back into its rest shape at a placement, as in a scene file:
    /// ``{"translation": [...], "rotation": {"axis": [...], "degrees": d}, "velocity": [...],
    /// "angular_velocity": [...]}`` (missing keys: zero).
    fn set_placement(
        &mut self,
        py: Python<'_>,
        object: &Bound<'_, PyAny>,
        placement: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let i = object_index(py, &self.world, object)?;
        let placement: Placement = from_python(py, placement, "placement")?;
        self.world
            .set_placement(i, &placement)
            .map_err(|e| scene_to_py(py, &e))
    }

    /// An object's basis (a copy).
    fn basis(&self, py: Python<'_>, object: &Bound<'_, PyAny>) -> PyResult<PyBasis> {
        let i = object_index(py, &self.world, object)?;
        let o = self.world.object(i);
        Ok(PyBasis {
            basis: o.basis().clone(),
            metadata: BasisMetadata {
                shape: Some(o.spec().shape.text().to_string()),
                ..BasisMetadata::default()
            },
            report: None,
        })
    }

    /// Object-object contact of the last step (scenes with ``[contact]``), a dict, or None
    /// without ``[contact]`` or before the first step: ``step``; ``object_pairs_tested``
    /// (object boxes compared, n (n - 1) / 2) and ``object_pairs_near`` (boxes that met);
    /// ``sample_pairs_active`` (sample pairs within contact distance at the end of the
    /// step); ``penetration`` (deepest, metres) and ``penetration_fraction`` (of the smaller
    /// rest bounding-box diagonal of the two objects); ``visible_penetration`` and
    /// ``visible_penetration_fraction`` (an object's own surface points); ``islands`` (sizes
    /// of the islands of two or more objects, largest first), ``island_count``,
    /// ``largest_island`` (0 without islands); ``regrouped`` (objects solved again);
    /// ``wall_ms`` (the world step, ms).
    #[getter]
    fn contact<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(row) = self.world.contact_summary().and_then(|s| s.steps.last()) else {
            return Ok(None);
        };
        let d = report(py, row)?;
        d.set_item("island_count", row.island_count())?;
        d.set_item("largest_island", row.largest_island())?;
        Ok(Some(d))
    }

    /// The object-object contact summary of the run so far, a dict with the structure of
    /// ``freeform run --json``'s ``contact`` (None without ``[contact]``): per-step rows as
    /// ``contact`` gives them (without the ``island_count`` and ``largest_island``
    /// shorthands), ``worst_penetration`` (metres), ``worst_penetration_fraction``,
    /// ``worst_visible_penetration`` (metres) and ``worst_visible_penetration_fraction`` (an
    /// object's own surface points into another object), ``worst_visible_at`` (a dict:
    /// ``step``, ``surface_object``, ``other_object``, ``rest_point``; or None),
    /// ``steps_over_tolerance``,
    /// ``step_ms_mean`` (ms), per object ``samples`` (of them ``feature_samples``, points on
    /// convex edges and corners), ``thickness`` (metres),
    /// ``derived_surface_triangles`` (point clouds, splats and images; None for others) and
    /// ``surface_points``, and the pair ``stiffness`` (Pa/m^2, objects x objects, row-major).
    fn contact_summary<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.world
            .contact_summary()
            .map(|s| report(py, s))
            .transpose()
    }

    /// Every object's summary (per-step rows, means, monitors) as dicts.
    fn summaries<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        report(py, &self.world.summaries())
    }

    fn __repr__(&self) -> String {
        format!(
            "World(objects={:?}, time={}, steps={})",
            self.object_names(),
            self.time(),
            self.steps()
        )
    }
}
