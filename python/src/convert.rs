//! NumPy arrays and Python values in and out: any float dtype and layout is converted once
//! to float64 on the way in; results are new float64 arrays.

use crate::errors::invalid;
use numpy::ndarray::Array2;
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLike1, PyArrayLike2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use serde_json::Value;

/// An N x 3 array of points (any real dtype, any layout), metres, checked finite.
pub fn points(py: Python<'_>, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f64; 3]>> {
    real(py, obj, what)?;
    let array: PyArrayLike2<'_, f64, AllowTypeChange> = obj.extract().map_err(|_| {
        invalid(
            py,
            format!(
                "{what}: expected an N x 3 array of numbers (got {})",
                describe(obj)
            ),
        )
    })?;
    let view = array.as_array();
    if view.ncols() != 3 {
        return Err(invalid(
            py,
            format!("{what}: expected N x 3, got shape {:?}", view.shape()),
        ));
    }
    let mut out = Vec::with_capacity(view.nrows());
    for (i, row) in view.rows().into_iter().enumerate() {
        let p = [row[0], row[1], row[2]];
        if !p.iter().all(|v| v.is_finite()) {
            return Err(invalid(
                py,
                format!("{what}: row {i} is not finite ({:?})", p),
            ));
        }
        out.push(p);
    }
    Ok(out)
}

/// A 1-D array of `n` numbers, or one number for all `n`.
pub fn per_point(
    py: Python<'_>,
    obj: &Bound<'_, PyAny>,
    n: usize,
    what: &str,
) -> PyResult<Vec<f64>> {
    if let Ok(v) = obj.extract::<f64>() {
        return Ok(vec![v; n]);
    }
    exactly(
        py,
        obj,
        n,
        what,
        "a number or a 1-D array",
        " (one per point)",
    )
}

/// A 1-D array of exactly `n` numbers.
pub fn vector(py: Python<'_>, obj: &Bound<'_, PyAny>, n: usize, what: &str) -> PyResult<Vec<f64>> {
    exactly(py, obj, n, what, "a 1-D array", "")
}

/// A 1-D array of `n` numbers; `expected` and `per` word the errors.
fn exactly(
    py: Python<'_>,
    obj: &Bound<'_, PyAny>,
    n: usize,
    what: &str,
    expected: &str,
    per: &str,
) -> PyResult<Vec<f64>> {
    real(py, obj, what)?;
    let array: PyArrayLike1<'_, f64, AllowTypeChange> = obj.extract().map_err(|_| {
        invalid(
            py,
            format!(
                "{what}: expected {expected} of {n} numbers (got {})",
                describe(obj)
            ),
        )
    })?;
    let view = array.as_array();
    if view.len() != n {
        return Err(invalid(
            py,
            format!("{what}: expected {n} values{per}, got {}", view.len()),
        ));
    }
    Ok(view.to_vec())
}

/// A 3 x 3 matrix, e.g. a rotation.
pub fn matrix3(py: Python<'_>, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[[f64; 3]; 3]> {
    real(py, obj, what)?;
    let array: PyArrayLike2<'_, f64, AllowTypeChange> = obj.extract().map_err(|_| {
        invalid(
            py,
            format!("{what}: expected a 3 x 3 array (got {})", describe(obj)),
        )
    })?;
    let view = array.as_array();
    if view.shape() != [3, 3] {
        return Err(invalid(
            py,
            format!(
                "{what}: expected a 3 x 3 array, got shape {:?}",
                view.shape()
            ),
        ));
    }
    Ok(std::array::from_fn(|i| {
        std::array::from_fn(|j| view[(i, j)])
    }))
}

/// A 3-vector.
pub fn vec3(py: Python<'_>, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 3]> {
    let v = vector(py, obj, 3, what)?;
    Ok([v[0], v[1], v[2]])
}

/// Refuse an array of complex dtype (NumPy would cast it to its real part with only a
/// warning): "any real dtype" is the promise.
pub fn real(py: Python<'_>, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<()> {
    let kind = obj
        .getattr("dtype")
        .and_then(|d| d.getattr("kind"))
        .and_then(|k| k.extract::<String>())
        .ok();
    if kind.as_deref() == Some("c") {
        return Err(invalid(
            py,
            format!(
                "{what}: complex values are not accepted (pass the real part, x.real, if that \
                 is what you mean)"
            ),
        ));
    }
    Ok(())
}

fn describe(obj: &Bound<'_, PyAny>) -> String {
    let ty = obj
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into());
    match obj.getattr("shape") {
        Ok(shape) => format!("{ty} of shape {shape}"),
        Err(_) => ty,
    }
}

/// Rows x cols row-major values as a new float64 array.
pub fn array2<'py>(
    py: Python<'py>,
    values: Vec<f64>,
    rows: usize,
    cols: usize,
) -> Bound<'py, PyArray2<f64>> {
    // rows * cols == values.len() at every call site (built from those sizes).
    Array2::from_shape_vec((rows, cols), values)
        .expect("values fill rows x cols")
        .into_pyarray(py)
}

/// Points as a new N x 3 float64 array.
pub fn points_array<'py>(py: Python<'py>, points: &[[f64; 3]]) -> Bound<'py, PyArray2<f64>> {
    array2(
        py,
        points.iter().flatten().copied().collect(),
        points.len(),
        3,
    )
}

/// A vector as a new 1-D float64 array.
pub fn array1<'py>(py: Python<'py>, values: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    values.into_pyarray(py)
}

/// A JSON value (reports, summaries, metadata) as Python dicts, lists and numbers.
pub fn json<'py>(py: Python<'py>, value: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_u64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(u)) => u.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(json(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, v) in map {
                dict.set_item(k, json(py, v)?)?;
            }
            dict.into_any()
        }
    })
}

/// Any serializable report as Python values.
pub fn report<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let v = serde_json::to_value(value)
        .map_err(|e| invalid(py, format!("cannot convert a report: {e}")))?;
    json(py, &v)
}

/// A count or an index given as a Python int (`v`, taken as i128 so that values past i64
/// still reach here), as usize: a negative one, or one above `max`, is an
/// `InvalidInputError` naming `what`, not pyo3's bare `OverflowError`.
pub fn count(py: Python<'_>, v: i128, what: &str, max: usize) -> PyResult<usize> {
    match usize::try_from(v) {
        Ok(n) if n <= max => Ok(n),
        Ok(_) => Err(crate::errors::invalid(
            py,
            format!("{what} = {v}: at most {max}"),
        )),
        Err(_) => Err(crate::errors::invalid(
            py,
            format!("{what} = {v}: must be a non-negative integer"),
        )),
    }
}
