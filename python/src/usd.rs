//! `freeform.read_usd_kaolin`: Kaolin's physics schemas of a USD prim as NumPy arrays (the
//! points, materials and weights a Kaolin basis is made of; `Basis.from_points` or a
//! simulation can start from them).

use crate::basis::run_released;
use crate::convert::{array1, array2, points_array};
use freeform::io::usd::kaolin::{read_kaolin, KaolinPoints};
use freeform::options::Front;
use numpy::PyArrayMethods;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

fn points_dict<'py>(py: Python<'py>, p: KaolinPoints) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("points", points_array(py, &p.points))?;
    d.set_item("youngs", array1(py, p.youngs))?;
    d.set_item("poisson", array1(py, p.poisson))?;
    d.set_item("density", array1(py, p.density))?;
    d.set_item("volume", p.volume)?;
    Ok(d)
}

/// Kaolin's physics schemas on prim ``prim`` (an absolute path, e.g.
/// ``"/World/ball/points"``) of the USD stage at ``path``, instance ``instance``: a dict with
/// ``"material"`` (``KaolinPhysicsMaterialAPI``: ``points`` (N, 3) metres, ``youngs`` Pa,
/// ``poisson``, ``density`` kg/m^3 (N,), ``volume`` m^3) and ``"skinned"``
/// (``KaolinSkinnedPhysicsAPI``: the same at the cubature points plus ``weights`` (N, M),
/// ``gradients`` (N, M, 3) and ``render_weights`` (R, M) or None), each None when the prim
/// does not carry that schema. ``time``: the time code to read at (None: the default
/// values, as Kaolin writes them). Values as stored (the schemas state SI units).
#[pyfunction]
#[pyo3(signature = (path, prim, instance = "default", time = None))]
pub fn read_usd_kaolin<'py>(
    py: Python<'py>,
    path: PathBuf,
    prim: &str,
    instance: &str,
    time: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let k = run_released(py, Front::Python, false, |_| {
        Ok(read_kaolin(&path, prim, instance, time)?)
    })?;
    let out = PyDict::new(py);
    match k.material {
        Some(m) => out.set_item("material", points_dict(py, m)?)?,
        None => out.set_item("material", py.None())?,
    }
    match k.skinned {
        Some((p, w)) => {
            let n = p.points.len();
            let d = points_dict(py, p)?;
            let m = w.handles;
            d.set_item("weights", array2(py, w.values, n, m))?;
            let g = array2(py, w.gradients, n * m, 3).reshape([n, m, 3])?;
            d.set_item("gradients", g)?;
            match w.render {
                Some(r) => {
                    let rows = r.len() / m;
                    d.set_item("render_weights", array2(py, r, rows, m))?
                }
                None => d.set_item("render_weights", py.None())?,
            }
            out.set_item("skinned", d)?;
        }
        None => out.set_item("skinned", py.None())?,
    }
    Ok(out)
}
