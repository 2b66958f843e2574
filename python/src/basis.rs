//! `freeform.Basis`: skinning eigenmodes from a shape or from NumPy points.

use crate::convert::{array1, array2, per_point, points_array, report};
use crate::errors::{invalid, to_py, to_py_in};
use crate::progress::PyProgress;
use faer::Mat;
use freeform::geometry::ShapeOptions;
use freeform::io::basis::BasisMetadata;
use freeform::material::{Material, MaterialField};
use freeform::options::Front;
use freeform::precompute::sampling::{cloud_volumes, IntegrationPoints};
use freeform::precompute::skinning::Basis;
use freeform::precompute::{
    BasisOptions, BasisRun, ModesReport, OptionTable, Problem, Value, ValueKind,
};
use freeform::Error;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use std::path::PathBuf;

/// The keyword of the builders that is not a basis option: show a progress bar.
const PROGRESS: &str = "progress";

/// The value `v` of keyword `key`, of the kind the option table asks for.
fn value(py: Python<'_>, key: &str, v: &Bound<'_, PyAny>, kind: ValueKind) -> PyResult<Value> {
    let expected = match kind {
        ValueKind::Count => "a non-negative int",
        ValueKind::Number => "a number",
        ValueKind::Switch => "True or False",
        ValueKind::Choice(_) | ValueKind::Text => "a str",
        ValueKind::Texts => "a list of str",
    };
    let value = match kind {
        ValueKind::Count => v.extract::<usize>().ok().map(Value::Count),
        ValueKind::Number => v.extract::<f64>().ok().map(Value::Number),
        ValueKind::Switch => v.extract::<bool>().ok().map(Value::Switch),
        ValueKind::Choice(_) | ValueKind::Text => v.extract::<String>().ok().map(Value::Text),
        ValueKind::Texts => v.extract::<Vec<String>>().ok().map(Value::Texts),
    };
    value.ok_or_else(|| {
        invalid(
            py,
            format!(
                "{key} = {}: expected {expected}",
                v.repr().map(|r| r.to_string()).unwrap_or_default()
            ),
        )
    })
}

/// `BasisOptions` (and the shape options and progress flag) from keyword arguments: one
/// keyword per row of the library's option table, with its defaults. Keys in `skip` are the
/// caller's own (per-point material of `from_points`).
pub fn options(
    py: Python<'_>,
    kwargs: Option<&Bound<'_, PyDict>>,
    skip: &[&str],
) -> PyResult<(BasisOptions, ShapeOptions, bool)> {
    let table = OptionTable::basis();
    let mut given = Vec::new();
    let mut progress = false;
    for (key, v) in kwargs.into_iter().flat_map(|k| k.iter()) {
        let key: String = key.extract()?;
        if key == PROGRESS {
            if !v.is_none() {
                progress = value(py, &key, &v, ValueKind::Switch)? == Value::Switch(true);
            }
            continue;
        }
        let row = table
            .find(Front::Python, &key)
            .filter(|_| !skip.contains(&key.as_str()));
        let Some(row) = row else {
            let mut known = table.names(Front::Python);
            known.retain(|k| !skip.contains(k));
            known.push(PROGRESS);
            return Err(invalid(
                py,
                format!(
                    "unknown option `{key}`; the options are: {}",
                    known.join(", ")
                ),
            ));
        };
        if !v.is_none() {
            given.push((row, value(py, &key, &v, row.kind)?));
        }
    }
    let choices = table.apply(given).map_err(|e| to_py(py, &e))?;
    choices.options.validate().map_err(|e| to_py(py, &e))?;
    Ok((choices.options, choices.shape, progress))
}

/// Run `work` with the GIL released and a [`PyProgress`]; a Ctrl-C becomes KeyboardInterrupt.
pub fn run_released<T: Send>(
    py: Python<'_>,
    front: Front,
    show_progress: bool,
    work: impl FnOnce(&PyProgress) -> freeform::Result<T> + Send,
) -> PyResult<T> {
    let progress = PyProgress::new(show_progress);
    // Messages formatted while it runs (warnings) name options as `front` does.
    let result = py.detach(|| front.scope(|| work(&progress)));
    match result {
        Ok(v) => Ok(v),
        Err(e @ Error::Cancelled { .. }) => Err(progress
            .take_interrupt()
            .unwrap_or_else(|| to_py_in(py, &e, front))),
        Err(e) => Err(to_py_in(py, &e, front)),
    }
}

/// Skinning eigenmodes: RKPM kernels and the coefficients of m + 1 modes (mode 0 constant).
#[pyclass(module = "freeform", name = "Basis", frozen)]
pub struct PyBasis {
    pub basis: Basis,
    /// What `save` writes (as `freeform modes` does).
    pub metadata: BasisMetadata,
    /// The build report (from the build, or from a file that stores one).
    pub report: Option<ModesReport>,
}

impl PyBasis {
    fn from_run(run: BasisRun, shape: &str, options: &BasisOptions) -> PyBasis {
        PyBasis {
            metadata: BasisMetadata::for_modes(shape, options, &run.report),
            basis: run.basis,
            report: Some(run.report),
        }
    }
}

#[pymethods]
impl PyBasis {
    /// Build a basis from a shape: a spec (``"box:2,1,1"``, ``"sphere:0.5"``) or a mesh /
    /// point-cloud file (OBJ, STL, OFF, PLY). Options as keywords, with the library's defaults
    /// (docs/python.md lists them). Releases the GIL; Ctrl-C interrupts.
    #[staticmethod]
    #[pyo3(signature = (shape, **options))]
    fn from_shape(
        py: Python<'_>,
        shape: &str,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<PyBasis> {
        let (opts, shape_opts, show) = self::options(py, options, &[])?;
        let run = run_released(py, Front::Python, show, |progress| {
            let s = freeform::io::read_shape(shape, &shape_opts)?;
            Problem::from_shape(&s, &opts, progress)?.solve(progress)
        })?;
        Ok(PyBasis::from_run(run, shape, &opts))
    }

    /// Build a basis from integration points (N x 3, metres) with per-point (or one)
    /// Young's modulus (Pa), Poisson ratio and density (kg/m^3), and volumes (N, m^3; None:
    /// estimated from the cloud, see ``voxel`` and ``total_volume``). Releases the GIL.
    #[staticmethod]
    #[pyo3(signature = (points, youngs, poisson = None, density = None, volumes = None, **options))]
    fn from_points(
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        youngs: &Bound<'_, PyAny>,
        poisson: Option<&Bound<'_, PyAny>>,
        density: Option<&Bound<'_, PyAny>>,
        volumes: Option<&Bound<'_, PyAny>>,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<PyBasis> {
        let (opts, _, show) = self::options(py, options, &["youngs", "poisson", "density"])?;
        let pts = crate::convert::points(py, points, "points")?;
        let n = pts.len();
        let d = Material::default();
        let youngs = per_point(py, youngs, n, "youngs")?;
        let poisson = match poisson {
            Some(v) if !v.is_none() => per_point(py, v, n, "poisson")?,
            _ => vec![d.poisson; n],
        };
        let density = match density {
            Some(v) if !v.is_none() => per_point(py, v, n, "density")?,
            _ => vec![d.density; n],
        };
        let volumes = match volumes {
            Some(v) if !v.is_none() => Some(per_point(py, v, n, "volumes")?),
            _ => None,
        };
        let run = run_released(py, Front::Python, show, |progress| {
            let material = MaterialField::from_arrays(youngs, poisson, density)?;
            let volumes = match volumes {
                Some(v) => v,
                None => cloud_volumes(&pts, &opts.cloud)?.0,
            };
            let ip = IntegrationPoints {
                points: pts,
                volumes,
            };
            Problem::from_points(ip, material, &opts, progress)?.solve(progress)
        })?;
        Ok(PyBasis::from_run(run, "numpy points", &opts))
    }

    /// Read a basis file (``.npz``, as written by ``save`` or ``freeform modes``).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<PyBasis> {
        let loaded = py
            .detach(|| freeform::io::basis::load(&path))
            .map_err(|e| to_py(py, &e))?;
        Ok(PyBasis {
            basis: loaded.basis,
            report: loaded.metadata.report.clone(),
            metadata: loaded.metadata,
        })
    }

    /// Write the basis file (``.npz``: kernels, coefficients, eigenvalues, metadata);
    /// all or nothing.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| freeform::io::basis::save(&path, &self.basis, &self.metadata))
            .map_err(|e| to_py(py, &e))
    }

    /// Number of kernels K.
    #[getter]
    fn kernels(&self) -> usize {
        self.basis.kernels.len()
    }

    /// Number of non-constant modes m (``eigenvalues`` has m + 1 entries).
    #[getter]
    fn modes(&self) -> usize {
        self.basis.modes().saturating_sub(1)
    }

    /// Window function name ('cubic', 'quartic' or 'gaussian').
    #[getter]
    fn kernel(&self) -> &'static str {
        self.basis.kernels.kind.name()
    }

    /// Eigenvalues, (m + 1,), ascending, Pa/m^2 (the first ~0: the constant mode).
    #[getter]
    fn eigenvalues<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.basis.eigenvalues.clone())
    }

    /// Coefficients c, (K, m + 1), M-orthonormal (c^T M c = I).
    #[getter]
    fn coefficients<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let c = &self.basis.coefficients;
        let (k, q) = (c.nrows(), c.ncols());
        let values = (0..k)
            .flat_map(|i| (0..q).map(move |j| c[(i, j)]))
            .collect();
        array2(py, values, k, q)
    }

    /// Kernel centres, (K, 3), metres.
    #[getter]
    fn centers<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, &self.basis.kernels.centers)
    }

    /// Kernel support radii, (K,), metres.
    #[getter]
    fn radii<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.basis.kernels.radii.clone())
    }

    /// The build report (eigen-residuals, timings, coverage, warnings, monitors) as a dict,
    /// or None for a file written without one.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match &self.report {
            Some(r) => report(py, r),
            None => Ok(py.None().into_bound(py)),
        }
    }

    /// The basis file's metadata (version, shape, options, report) as a dict.
    #[getter]
    fn metadata<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        crate::convert::json(py, &self.metadata.to_json())
    }

    /// Warnings of the build (poor conditioning, residuals above the tolerance), as text.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        match &self.report {
            Some(r) => r.warnings.clone(),
            None => self.metadata.warnings(),
        }
    }

    /// Skinning weights W at query points (N x 3, metres): (N, m + 1) in m^(-3/2); with
    /// ``gradients=True`` also grad W, (N, m + 1, 3). Points must be covered by the kernels
    /// (inside or near the object), else CoverageError.
    #[pyo3(signature = (points, gradients = false))]
    fn weights<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        gradients: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let q = crate::convert::points(py, points, "points")?;
        let w = interruptible_weights(py, &self.basis, &q)?;
        let (n, m) = (q.len(), w.modes);
        let values = array2(py, w.values, n, m);
        if !gradients {
            return Ok(values.into_any());
        }
        let g: Vec<f64> = w.gradients.iter().flatten().copied().collect();
        let g = array2(py, g, n * m, 3).reshape([n, m, 3])?;
        Ok(PyTuple::new(py, [values.into_any(), g.into_any()])?.into_any())
    }

    /// The RKPM field sum_k phi_k(x) C[k, :] at query points (N x 3) for any coefficients
    /// C (K x q): (N, q). With C = ``coefficients`` this is ``weights``; with C the kernel
    /// centres it reproduces x (RKPM's linear completeness).
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
        coefficients: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let q = crate::convert::points(py, points, "points")?;
        crate::convert::real(py, coefficients, "coefficients")?;
        let c: numpy::PyArrayLike2<'_, f64, numpy::AllowTypeChange> = coefficients
            .extract()
            .map_err(|_| invalid(py, "coefficients: expected a K x q array of numbers"))?;
        let c = c.as_array();
        let k = self.basis.kernels.len();
        if c.nrows() != k || c.ncols() == 0 {
            return Err(invalid(
                py,
                format!("coefficients: expected {k} rows (one per kernel) and at least one column, got shape {:?}", c.shape()),
            ));
        }
        if let Some(((i, j), v)) = c.indexed_iter().find(|(_, v)| !v.is_finite()) {
            return Err(invalid(
                py,
                format!("coefficients: entry ({i}, {j}) is not finite ({v})"),
            ));
        }
        let field = Basis {
            kernels: self.basis.kernels.clone(),
            coefficients: Mat::from_fn(k, c.ncols(), |i, j| c[(i, j)]),
            eigenvalues: vec![0.0; c.ncols()],
        };
        let w = interruptible_weights(py, &field, &q)?;
        Ok(array2(py, w.values, q.len(), w.modes))
    }

    fn __repr__(&self) -> String {
        format!(
            "Basis(kernels={}, modes={}, kernel='{}', shape={:?})",
            self.kernels(),
            self.modes(),
            self.kernel(),
            self.metadata.shape.as_deref().unwrap_or("?")
        )
    }
}

/// Points per chunk of [`interruptible_weights`]: about 0.1 s of work each.
const WEIGHTS_CHUNK: usize = 100_000;

/// `basis.weights(q)` in chunks of [`WEIGHTS_CHUNK`] points with the GIL released, checking
/// for Ctrl-C (a pending Python signal) between chunks: 20M points take minutes. Each point's
/// weights are independent of the others, so the result is the same as in one call.
fn interruptible_weights(
    py: Python<'_>,
    basis: &Basis,
    q: &[freeform::Point3],
) -> PyResult<freeform::precompute::skinning::SkinningWeights> {
    if q.is_empty() {
        return basis.weights(q).map_err(|e| to_py(py, &e));
    }
    let mut all = freeform::precompute::skinning::SkinningWeights {
        modes: basis.modes(),
        values: Vec::with_capacity(q.len() * basis.modes()),
        gradients: Vec::with_capacity(q.len() * basis.modes()),
    };
    for chunk in q.chunks(WEIGHTS_CHUNK) {
        let Ok(w) = py.detach(|| basis.weights(chunk)) else {
            // The error of the whole array (a coverage error's index, count and worst point
            // are over all points, not the chunk's).
            return basis.weights(q).map_err(|e| to_py(py, &e));
        };
        all.values.extend(w.values);
        all.gradients.extend(w.gradients);
        py.check_signals()?;
    }
    Ok(all)
}
