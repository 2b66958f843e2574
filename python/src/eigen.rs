//! `freeform.eigsh(h, m, nev)`: the native LOBPCG on the caller's H and M, taken by duck
//! typing: a `scipy.sparse` matrix (anything with `tocoo()`) is assembled once and solved with
//! the GIL released; an object with `matmat` (or `matvec`) and `shape`, like
//! `scipy.sparse.linalg.LinearOperator`, is applied through Python with the GIL held for each
//! call, so it is never called from two threads at once. scipy itself is never imported.

use crate::errors::{invalid, to_py};
use crate::progress::PyProgress;
use faer::{MatMut, MatRef};
use freeform::eigen::lobpcg::Lobpcg;
use freeform::eigen::{
    EigenError, EigenRequest, Eigensolver, LinearOperator, OperatorError, OperatorProblem,
    Preconditioner,
};
use freeform::sparse::SparseMatrix;
use freeform::Error;
use numpy::ndarray::Array2;
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLike2};
use pyo3::prelude::*;
use std::sync::Mutex;

/// A Python object applied as an operator: `matmat(X)` for a K x b block (else `matvec` per
/// column); the first exception it raises is kept and re-raised after the solve.
struct PyOperator {
    object: Py<PyAny>,
    k: usize,
    name: &'static str,
    has_matmat: bool,
    diagonal: Option<Vec<f64>>,
    raised: Mutex<Option<PyErr>>,
}

impl PyOperator {
    fn call(&self, x: MatRef<'_, f64>, mut out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        let (k, b) = (self.k, x.ncols());
        let result = Python::attach(|py| -> PyResult<Result<(), String>> {
            // Row by row: the solver's blocks are row-major, as a C-order array is.
            let mut block = Array2::<f64>::zeros((k, b));
            for (i, mut row) in block.rows_mut().into_iter().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = x[(i, j)];
                }
            }
            let object = self.object.bind(py);
            let y: Bound<'_, PyAny> = if self.has_matmat {
                object.call_method1("matmat", (block.into_pyarray(py),))?
            } else {
                let mut cols = Vec::with_capacity(b);
                for j in 0..b {
                    let column = block.column(j).to_owned().into_pyarray(py);
                    cols.push(object.call_method1("matvec", (column,))?);
                }
                let np = py.import("numpy")?;
                np.call_method1("column_stack", (cols,))?
            };
            let array: PyArrayLike2<'_, f64, AllowTypeChange> = match y.extract() {
                Ok(a) => a,
                Err(_) => {
                    // A 1-D result of length K for one column is fine.
                    let reshaped = y.call_method1("reshape", ((k, b),));
                    match reshaped
                        .and_then(|r| r.extract::<PyArrayLike2<'_, f64, AllowTypeChange>>())
                    {
                        Ok(a) => a,
                        Err(_) => {
                            return Ok(Err(format!(
                                "{} returned something that is not a {k} x {b} array of numbers",
                                self.method()
                            )))
                        }
                    }
                }
            };
            let view = array.as_array();
            if view.shape() != [k, b] {
                return Ok(Err(format!(
                    "{} returned shape {:?} for a {k} x {b} block",
                    self.method(),
                    view.shape()
                )));
            }
            for (i, row) in view.rows().into_iter().enumerate() {
                for (j, &v) in row.iter().enumerate() {
                    out[(i, j)] = v;
                }
            }
            Ok(Ok(()))
        });
        match result {
            Ok(Ok(())) => Ok(()),
            Ok(Err(message)) => Err(OperatorError::new(message)),
            Err(e) => {
                let message = format!("{} raised {e}", self.method());
                if let Ok(mut slot) = self.raised.lock() {
                    slot.get_or_insert(e);
                }
                Err(OperatorError::new(message))
            }
        }
    }

    fn method(&self) -> String {
        format!(
            "{}.{}",
            self.name,
            if self.has_matmat { "matmat" } else { "matvec" }
        )
    }

    fn take_raised(&self) -> Option<PyErr> {
        self.raised.lock().ok()?.take()
    }
}

impl LinearOperator for PyOperator {
    fn dim(&self) -> usize {
        self.k
    }
    fn apply(&self, x: MatRef<'_, f64>, out: MatMut<'_, f64>) -> Result<(), OperatorError> {
        self.call(x, out)
    }
    fn diagonal(&self) -> Option<Vec<f64>> {
        self.diagonal.clone()
    }
}

impl Preconditioner for PyOperator {
    fn apply(&self, r: MatRef<'_, f64>, z: MatMut<'_, f64>) -> Result<(), OperatorError> {
        self.call(r, z)
    }
}

/// H or M as the solver takes it.
enum Operand {
    Assembled(SparseMatrix),
    Python(PyOperator),
}

impl Operand {
    fn op(&self) -> &dyn LinearOperator {
        match self {
            Operand::Assembled(a) => a,
            Operand::Python(p) => p,
        }
    }
}

/// The (rows, cols) of a `.shape` attribute.
fn shape_of(py: Python<'_>, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<(usize, usize)> {
    obj.getattr("shape")
        .and_then(|s| s.extract::<(usize, usize)>())
        .map_err(|_| {
            invalid(
                py,
                format!(
                    "{what}: expected a scipy.sparse matrix (with tocoo) or an operator with matmat or \
                     matvec and shape (like scipy.sparse.linalg.LinearOperator); it has no .shape \
                     of two non-negative ints"
                ),
            )
        })
}

fn operand(py: Python<'_>, obj: &Bound<'_, PyAny>, name: &'static str) -> PyResult<Operand> {
    let (rows, cols) = shape_of(py, obj, name)?;
    if rows != cols {
        return Err(invalid(
            py,
            format!("{name} is {rows} x {cols}; it must be square"),
        ));
    }
    if obj.hasattr("tocoo")? {
        let coo = obj.call_method0("tocoo")?;
        let get = |attr: &str| -> PyResult<Vec<f64>> {
            let a: numpy::PyArrayLike1<'_, f64, AllowTypeChange> = coo.getattr(attr)?.extract()?;
            Ok(a.as_array().to_vec())
        };
        let (r, c, v) = (get("row")?, get("col")?, get("data")?);
        let index_range = u32::MAX as f64;
        if rows.max(cols) > u32::MAX as usize
            || v.len() > freeform::sparse::MAX_ENTRIES
            || r.iter()
                .chain(&c)
                .any(|&i| !(0.0..index_range).contains(&i) || i.fract() != 0.0)
        {
            return Err(invalid(
                py,
                format!(
                    "{name}: indices must be whole numbers in [0, 2^32 - 1) and at most {} \
                     entries (the native sparse matrix has 32-bit indices)",
                    freeform::sparse::MAX_ENTRIES
                ),
            ));
        }
        // Whole numbers in u32's range, checked above.
        let triplets: Vec<faer::sparse::Triplet<u32, u32, f64>> = r
            .iter()
            .zip(&c)
            .zip(&v)
            .map(|((&i, &j), &x)| faer::sparse::Triplet::new(i as u32, j as u32, x))
            .collect();
        let matrix = SparseMatrix::try_new_from_triplets(rows, cols, &triplets)
            .map_err(|e| invalid(py, format!("{name}: {e:?}")))?;
        return Ok(Operand::Assembled(matrix));
    }
    let has_matmat = obj.hasattr("matmat")?;
    if !has_matmat && !obj.hasattr("matvec")? {
        return Err(invalid(
            py,
            format!(
                "{name}: expected a scipy.sparse matrix (with tocoo) or an operator with matmat or \
                 matvec and shape (like scipy.sparse.linalg.LinearOperator)"
            ),
        ));
    }
    let diagonal = if obj.hasattr("diagonal")? {
        let d: numpy::PyArrayLike1<'_, f64, AllowTypeChange> =
            obj.call_method0("diagonal")?.extract()?;
        Some(d.as_array().to_vec())
    } else {
        None
    };
    Ok(Operand::Python(PyOperator {
        object: obj.clone().unbind(),
        k: rows,
        name,
        has_matmat,
        diagonal,
        raised: Mutex::new(None),
    }))
}

/// The `nev` smallest eigenpairs of H x = lambda M x (H PSD with the constant vector in its
/// null space, M SPD), by freeform's native LOBPCG: `(values, vectors)`, values ascending
/// (nev,), vectors K x nev, M-orthonormal, the constant mode first.
#[pyfunction]
#[pyo3(signature = (h, m, nev, tol = 1e-8, max_iter = 1000, preconditioner = None, check_symmetry = false, progress = false))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub fn eigsh<'py>(
    py: Python<'py>,
    h: &Bound<'py, PyAny>,
    m: &Bound<'py, PyAny>,
    nev: i128,
    tol: f64,
    max_iter: i128,
    preconditioner: Option<&Bound<'py, PyAny>>,
    check_symmetry: bool,
    progress: bool,
) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyArray2<f64>>)> {
    let nev = crate::convert::count(py, nev, "nev", usize::MAX)?;
    let max_iter = crate::convert::count(py, max_iter, "max_iter", usize::MAX)?;
    let h = operand(py, h, "h")?;
    let m = operand(py, m, "m")?;
    let pre = match preconditioner {
        None => None,
        Some(p) => match operand(py, p, "preconditioner")? {
            Operand::Python(op) => Some(op),
            Operand::Assembled(_) => {
                return Err(invalid(
                    py,
                    "preconditioner: give an object with matmat or matvec applying T ~ (H + sigma M)^-1",
                ))
            }
        },
    };
    let request = EigenRequest { nev, tol, max_iter };
    let mut problem = OperatorProblem::new(h.op(), m.op()).with_symmetry_probe(check_symmetry);
    if let Some(p) = &pre {
        problem = problem.with_preconditioner(p);
    }
    let solver = Lobpcg::default();
    let shown = PyProgress::new(progress);
    // Released: assembled operators never need the GIL, Python ones take it for each
    // application (one at a time: the solver applies from this thread only).
    let result = py.detach(|| solver.solve_operators(&problem, &request, &shown));
    for operand in [&h, &m] {
        if let Operand::Python(op) = operand {
            if let Some(e) = op.take_raised() {
                return Err(e);
            }
        }
    }
    if let Some(e) = pre.as_ref().and_then(|p| p.take_raised()) {
        return Err(e);
    }
    let solution = match result.and_then(|s| s.into_converged()) {
        Ok(s) => s,
        Err(EigenError::Cancelled { iterations }) => {
            return Err(shown
                .take_interrupt()
                .unwrap_or_else(|| to_py(py, &Error::Eigen(EigenError::Cancelled { iterations }))))
        }
        Err(e) => return Err(to_py(py, &Error::Eigen(e))),
    };
    let k = solution.vectors.nrows();
    let vectors = Array2::from_shape_fn((k, solution.values.len()), |(i, j)| {
        solution.vectors[(i, j)]
    });
    Ok((solution.values.into_pyarray(py), vectors.into_pyarray(py)))
}
