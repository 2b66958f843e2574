//! `freeform.Basis`: skinning eigenmodes from a shape or from NumPy points.

use crate::convert::{array1, array2, per_point, points_array, report};
use crate::errors::{invalid, to_py};
use crate::progress::PyProgress;
use faer::Mat;
use freeform::geometry::ShapeOptions;
use freeform::io::basis::BasisMetadata;
use freeform::material::{Material, MaterialField};
use freeform::precompute::rkpm::KernelType;
use freeform::precompute::sampling::{cloud_volumes, IntegrationPoints, Resolution};
use freeform::precompute::skinning::Basis;
use freeform::precompute::{BasisOptions, BasisRun, ModesReport, Problem, SolverConfig};
use freeform::Error;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use std::path::PathBuf;

/// Keyword arguments of the basis builders, with the library's defaults.
const OPTION_KEYS: &[&str] = &[
    "kernels",
    "modes",
    "kernel",
    "support_factor",
    "support_neighbor",
    "points",
    "spacing",
    "eigensolver",
    "tol",
    "max_iter",
    "voxel",
    "total_volume",
    "youngs",
    "poisson",
    "density",
    "allow_open_mesh",
    "regions",
    "progress",
];

fn get<'py, T: for<'a> FromPyObject<'a, 'py>>(
    py: Python<'py>,
    kwargs: Option<&Bound<'py, PyDict>>,
    key: &str,
) -> PyResult<Option<T>> {
    let Some(v) = kwargs.map(|k| k.get_item(key)).transpose()?.flatten() else {
        return Ok(None);
    };
    if v.is_none() {
        return Ok(None);
    }
    v.extract::<T>().map(Some).map_err(|_| {
        invalid(
            py,
            format!(
                "{key} = {}: expected {}",
                v.repr().map(|r| r.to_string()).unwrap_or_default(),
                match std::any::type_name::<T>().rsplit("::").next() {
                    Some("String") => "a str",
                    Some("f64") => "a number",
                    Some("usize") => "a non-negative int",
                    Some("bool") => "True or False",
                    _ => "another type",
                }
            ),
        )
    })
}

/// `BasisOptions` (and the shape options and progress flag) from keyword arguments; keys in
/// `skip` are the caller's own (per-point material of `from_points`).
pub fn options(
    py: Python<'_>,
    kwargs: Option<&Bound<'_, PyDict>>,
    skip: &[&str],
) -> PyResult<(BasisOptions, ShapeOptions, bool)> {
    if let Some(k) = kwargs {
        for key in k.keys() {
            let key: String = key.extract()?;
            if !OPTION_KEYS.contains(&key.as_str()) || skip.contains(&key.as_str()) {
                let known: Vec<&str> = OPTION_KEYS
                    .iter()
                    .copied()
                    .filter(|k| !skip.contains(k))
                    .collect();
                return Err(invalid(
                    py,
                    format!(
                        "unknown option `{key}`; the options are: {}",
                        known.join(", ")
                    ),
                ));
            }
        }
    }
    let mut o = BasisOptions::default();
    if let Some(k) = get(py, kwargs, "kernels")? {
        o.kernels = k;
    }
    if let Some(m) = get(py, kwargs, "modes")? {
        o.modes = m;
    }
    if let Some(name) = get::<String>(py, kwargs, "kernel")? {
        o.kernel = KernelType::from_name(&name).ok_or_else(|| {
            invalid(
                py,
                format!("kernel = '{name}': use 'cubic' (default), 'quartic' or 'gaussian'"),
            )
        })?;
    }
    if let Some(f) = get(py, kwargs, "support_factor")? {
        o.support.factor = f;
    }
    if let Some(n) = get(py, kwargs, "support_neighbor")? {
        o.support.neighbor = n;
    }
    match (
        get::<usize>(py, kwargs, "points")?,
        get::<f64>(py, kwargs, "spacing")?,
    ) {
        (Some(_), Some(_)) => {
            return Err(invalid(
                py,
                "give either points (a count) or spacing (metres), not both",
            ))
        }
        (Some(n), None) => o.resolution = Some(Resolution::Count(n)),
        (None, Some(h)) => o.resolution = Some(Resolution::Spacing(h)),
        (None, None) => {}
    }
    if let Some(s) = get::<String>(py, kwargs, "eigensolver")? {
        o.solver = s.parse::<SolverConfig>().map_err(|e| to_py(py, &e))?;
    }
    if let Some(t) = get(py, kwargs, "tol")? {
        o.tol = t;
    }
    if let Some(n) = get(py, kwargs, "max_iter")? {
        o.max_iter = n;
    }
    o.cloud.voxel = get(py, kwargs, "voxel")?;
    o.cloud.total_volume = get(py, kwargs, "total_volume")?;
    if !skip.contains(&"youngs") {
        let d = Material::default();
        o.material = Material {
            youngs: get(py, kwargs, "youngs")?.unwrap_or(d.youngs),
            poisson: get(py, kwargs, "poisson")?.unwrap_or(d.poisson),
            density: get(py, kwargs, "density")?.unwrap_or(d.density),
        };
    }
    if let Some(regions) = get::<Vec<String>>(py, kwargs, "regions")? {
        o.boundary_regions = regions
            .iter()
            .map(|r| r.parse::<freeform::material::Region>())
            .collect::<freeform::Result<_>>()
            .map_err(|e| to_py(py, &e))?;
    }
    let shape = ShapeOptions {
        allow_open_mesh: get(py, kwargs, "allow_open_mesh")?.unwrap_or(false),
    };
    let progress = get(py, kwargs, "progress")?.unwrap_or(false);
    o.validate().map_err(|e| to_py(py, &e))?;
    Ok((o, shape, progress))
}

/// Run `work` with the GIL released and a [`PyProgress`]; a Ctrl-C becomes KeyboardInterrupt.
pub fn run_released<T: Send>(
    py: Python<'_>,
    show_progress: bool,
    work: impl FnOnce(&PyProgress) -> freeform::Result<T> + Send,
) -> PyResult<T> {
    let progress = PyProgress::new(show_progress);
    let result = py.detach(|| work(&progress));
    match result {
        Ok(v) => Ok(v),
        Err(e @ Error::Cancelled { .. }) => {
            Err(progress.take_interrupt().unwrap_or_else(|| to_py(py, &e)))
        }
        Err(e) => Err(to_py(py, &e)),
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
        let run = run_released(py, show, |progress| {
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
        let run = run_released(py, show, |progress| {
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
        let w = py
            .detach(|| self.basis.weights(&q))
            .map_err(|e| to_py(py, &e))?;
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
        let field = Basis {
            kernels: self.basis.kernels.clone(),
            coefficients: Mat::from_fn(k, c.ncols(), |i, j| c[(i, j)]),
            eigenvalues: vec![0.0; c.ncols()],
        };
        let w = py.detach(|| field.weights(&q)).map_err(|e| to_py(py, &e))?;
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
