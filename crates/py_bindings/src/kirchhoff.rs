//! The Kirchhoff stall model and its output-error fit (conversion only).
use std::collections::HashMap;

use aero_core::aircraft::qualified::QualifiedModel;
use aero_core::aircraft::records::qualified_longitudinal;
use aero_core::aircraft::truth::{
    kirchhoff_truth_drag as truth_drag, kirchhoff_truth_params as truth_params,
};
use aero_core::aircraft::turboprop::adx37;
use aero_core::kirchhoff::{
    outputs, Inputs, KirchhoffDrag, KirchhoffParams, Separation, DRAG_NAMES, N_PARAMS, PARAM_NAMES,
};
use aero_core::output_error::{fit, OeOptions, Series};
use aero_core::stall_form::StallParams;
use aero_core::AeroError;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::error::to_py;
use crate::util::{column_slices, detached, record_columns};

type Array<'py> = Bound<'py, PyArray1<f64>>;
type Matrix<'py> = Bound<'py, PyArray2<f64>>;

/// The values of argument `arg` in `names` order; a missing name is refused.
pub(crate) fn named<const N: usize>(
    d: &HashMap<String, f64>,
    names: [&str; N],
    arg: &str,
) -> PyResult<[f64; N]> {
    let mut v = [0.0; N];
    for (slot, name) in v.iter_mut().zip(names) {
        *slot = *d.get(name).ok_or_else(|| {
            to_py(AeroError::invalid(
                format!("argument '{arg}'"),
                format!("has no '{name}'; give all of {}", names.join(", ")),
            ))
        })?;
    }
    Ok(v)
}

/// `names` -> `values` as a dict.
pub(crate) fn dict_of<const N: usize>(names: [&str; N], values: [f64; N]) -> HashMap<String, f64> {
    names
        .iter()
        .zip(values)
        .map(|(n, v)| ((*n).to_string(), v))
        .collect()
}

fn params_from(d: &HashMap<String, f64>, arg: &str) -> PyResult<KirchhoffParams> {
    Ok(KirchhoffParams::from_array(&named(d, PARAM_NAMES, arg)?))
}

fn params_dict(p: &KirchhoffParams) -> HashMap<String, f64> {
    dict_of(PARAM_NAMES, p.to_array())
}

fn matrix<'py>(py: Python<'py>, v: Vec<f64>, rows: usize) -> PyResult<Matrix<'py>> {
    matrix_of(py, v, rows, N_PARAMS)
}

/// A row-major `rows × cols` matrix as a numpy array.
pub(crate) fn matrix_of<'py>(
    py: Python<'py>,
    v: Vec<f64>,
    rows: usize,
    cols: usize,
) -> PyResult<Matrix<'py>> {
    Array2::from_shape_vec((rows, cols), v)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| to_py(AeroError::invalid("matrix", e.to_string())))
}

/// Parameter names in the engine's order.
#[pyfunction]
fn kirchhoff_param_names() -> Vec<String> {
    PARAM_NAMES.iter().map(|s| (*s).to_string()).collect()
}

/// Drag parameter names in the engine's order.
#[pyfunction]
fn kirchhoff_drag_names() -> Vec<String> {
    DRAG_NAMES.iter().map(|s| (*s).to_string()).collect()
}

/// The virtual aircraft's Kirchhoff stall parameters at a flap setting.
#[pyfunction]
fn kirchhoff_truth_params(flap_deg: f64) -> HashMap<String, f64> {
    params_dict(&truth_params(flap_deg))
}

/// The virtual aircraft's Kirchhoff stall drag at a flap setting (`CD0`, `CD_k`, `CD_x`).
#[pyfunction]
fn kirchhoff_truth_drag(flap_deg: f64) -> HashMap<String, f64> {
    dict_of(DRAG_NAMES, truth_drag(flap_deg, &adx37()).to_array())
}

/// `(alpha at C_L,max [rad], C_L,max)` of the static curve.
#[pyfunction]
fn kirchhoff_cl_max(params: HashMap<String, f64>) -> PyResult<(f64, f64)> {
    let p = params_from(&params, "params")?;
    p.check().map_err(to_py)?;
    Ok(p.cl_max())
}

/// `(x, CL, Cm, dCL/dθ, dCm/dθ)` along one record (sensitivities `None` unless asked).
#[pyfunction]
#[pyo3(signature = (params, t, alpha, alpha_dot, sensitivities=false))]
#[allow(clippy::type_complexity)]
fn kirchhoff_outputs<'py>(
    py: Python<'py>,
    params: HashMap<String, f64>,
    t: PyReadonlyArray1<'py, f64>,
    alpha: PyReadonlyArray1<'py, f64>,
    alpha_dot: PyReadonlyArray1<'py, f64>,
    sensitivities: bool,
) -> PyResult<(
    Array<'py>,
    Array<'py>,
    Array<'py>,
    Option<Matrix<'py>>,
    Option<Matrix<'py>>,
)> {
    let p = params_from(&params, "params")?;
    let (t, a, ad) = (t.as_slice()?, alpha.as_slice()?, alpha_dot.as_slice()?);
    let o = detached(py, || {
        outputs(
            &p,
            &Inputs {
                t,
                alpha: a,
                alpha_dot: ad,
            },
            sensitivities,
        )
    })?;
    let n = o.x.len();
    let (dcl, dcm) = if sensitivities {
        (Some(matrix(py, o.dcl, n)?), Some(matrix(py, o.dcm, n)?))
    } else {
        (None, None)
    };
    Ok((
        o.x.into_pyarray(py),
        o.cl.into_pyarray(py),
        o.cm.into_pyarray(py),
        dcl,
        dcm,
    ))
}

/// `(x0, x_dot, CL, Cm)` at each `(alpha, alpha_dot, x)` (rad, rad/s, -): the ODE's input
/// `x₀(α − τ₂ α̇)` and right-hand side, and the static-curve lift and pitching moment at the
/// separation point `x` (`StallParams::{x0_lagged, x_dot, cl, cm}`). The tanh form by default;
/// with `knots` (rad) and `values` the tabulated form (Goman-Khrabrov), whose `params` are its
/// core names.
#[pyfunction]
#[pyo3(signature = (params, alpha, alpha_dot, x, knots=None, values=None))]
fn kirchhoff_point<'py>(
    py: Python<'py>,
    params: HashMap<String, f64>,
    alpha: PyReadonlyArray1<'py, f64>,
    alpha_dot: PyReadonlyArray1<'py, f64>,
    x: PyReadonlyArray1<'py, f64>,
    knots: Option<Vec<f64>>,
    values: Option<Vec<f64>>,
) -> PyResult<(Array<'py>, Array<'py>, Array<'py>, Array<'py>)> {
    let p: StallParams = match (knots, values) {
        (None, None) => params_from(&params, "params")?.into(),
        (Some(k), Some(v)) => crate::goman_khrabrov::params_from(&params, k, v, "params")?.into(),
        _ => {
            return Err(to_py(AeroError::invalid(
                "kirchhoff_point",
                "give both knots and values (the tabulated form) or neither (the tanh form)",
            )))
        }
    };
    p.check_params().map_err(to_py)?;
    let (a, ad, xs) = (alpha.as_slice()?, alpha_dot.as_slice()?, x.as_slice()?);
    if ad.len() != a.len() || xs.len() != a.len() {
        return Err(to_py(AeroError::invalid(
            "kirchhoff_point",
            format!(
                "alpha, alpha_dot and x have {}, {} and {} values; give one of each per point",
                a.len(),
                ad.len(),
                xs.len()
            ),
        )));
    }
    let pts = || a.iter().zip(ad).zip(xs).map(|((&a, &ad), &x)| (a, ad, x));
    let x0: Vec<f64> = pts().map(|(a, ad, _)| p.x0_lagged(a, ad)).collect();
    let xd: Vec<f64> = pts().map(|(a, ad, x)| p.x_dot(a, ad, x)).collect();
    let cl: Vec<f64> = pts().map(|(a, _, x)| p.cl(a, x)).collect();
    let cm: Vec<f64> = pts().map(|(a, _, x)| p.cm(a, x)).collect();
    Ok((
        x0.into_pyarray(py),
        xd.into_pyarray(py),
        cl.into_pyarray(py),
        cm.into_pyarray(py),
    ))
}

/// `C_D` of the stall's drag (`KirchhoffDrag::cd`) at each Kirchhoff lift `cl` and separation
/// point `x`.
#[pyfunction]
fn kirchhoff_drag_point<'py>(
    py: Python<'py>,
    drag: HashMap<String, f64>,
    cl: PyReadonlyArray1<'py, f64>,
    x: PyReadonlyArray1<'py, f64>,
) -> PyResult<Array<'py>> {
    let d = KirchhoffDrag::from_array(&named(&drag, DRAG_NAMES, "drag")?);
    d.check().map_err(to_py)?;
    let (cl, x) = (cl.as_slice()?, x.as_slice()?);
    if cl.len() != x.len() {
        return Err(to_py(AeroError::invalid(
            "kirchhoff_drag_point",
            format!(
                "cl and x have {} and {} values; give one of each per point",
                cl.len(),
                x.len()
            ),
        )));
    }
    let cd: Vec<f64> = cl.iter().zip(x).map(|(&c, &x)| d.cd(c, x)).collect();
    Ok(cd.into_pyarray(py))
}

/// One [`Series`] per maneuver from the per-maneuver arrays (the lists must be equally long).
pub(crate) fn series_of<'a, 'py>(
    t: &'a [PyReadonlyArray1<'py, f64>],
    alpha: &'a [PyReadonlyArray1<'py, f64>],
    alpha_dot: &'a [PyReadonlyArray1<'py, f64>],
    cl: &'a [PyReadonlyArray1<'py, f64>],
    cm: Option<&'a [PyReadonlyArray1<'py, f64>]>,
) -> PyResult<Vec<Series<'a>>> {
    let k = t.len();
    let counts = [
        alpha.len(),
        alpha_dot.len(),
        cl.len(),
        cm.map_or(k, <[_]>::len),
    ];
    if counts.iter().any(|&c| c != k) {
        return Err(to_py(AeroError::invalid(
            "output-error fit",
            format!("give one array per maneuver in every list (t has {k}, others {counts:?})"),
        )));
    }
    let mut series = Vec::with_capacity(k);
    for i in 0..k {
        series.push(Series {
            inputs: Inputs {
                t: t[i].as_slice()?,
                alpha: alpha[i].as_slice()?,
                alpha_dot: alpha_dot[i].as_slice()?,
            },
            cl: cl[i].as_slice()?,
            cm: match cm {
                Some(c) => Some(c[i].as_slice()?),
                None => None,
            },
        });
    }
    Ok(series)
}

/// Output-error fit over maneuvers; returns a dict of plain values.
#[pyfunction]
#[pyo3(signature = (t, alpha, alpha_dot, cl, cm=None, start=None, fixed=Vec::new(), max_iter=60, tol=1e-9, max_lag=None))]
#[allow(clippy::too_many_arguments)]
fn output_error_kirchhoff<'py>(
    py: Python<'py>,
    t: Vec<PyReadonlyArray1<'py, f64>>,
    alpha: Vec<PyReadonlyArray1<'py, f64>>,
    alpha_dot: Vec<PyReadonlyArray1<'py, f64>>,
    cl: Vec<PyReadonlyArray1<'py, f64>>,
    cm: Option<Vec<PyReadonlyArray1<'py, f64>>>,
    start: Option<HashMap<String, f64>>,
    fixed: Vec<String>,
    max_iter: usize,
    tol: f64,
    max_lag: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let start = start.map(|d| params_from(&d, "start")).transpose()?;
    let mut fx = [false; N_PARAMS];
    for name in &fixed {
        let j = PARAM_NAMES.iter().position(|n| n == name).ok_or_else(|| {
            to_py(AeroError::invalid(
                "argument 'fixed'",
                format!(
                    "unknown parameter '{name}'; valid: {}",
                    PARAM_NAMES.join(", ")
                ),
            ))
        })?;
        fx[j] = true;
    }
    let series = series_of(&t, &alpha, &alpha_dot, &cl, cm.as_deref())?;
    let opts = OeOptions {
        max_iter,
        tol,
        start,
        fixed: fx,
        max_lag,
    };
    let f = detached(py, || fit(&series, &opts))?;
    let d = PyDict::new(py);
    d.set_item("params", params_dict(&f.params))?;
    d.set_item("start", params_dict(&f.start))?;
    d.set_item("free", f.free.to_vec())?;
    d.set_item("std_err", f.std_err.to_vec())?;
    d.set_item("std_err_colored", f.std_err_colored.to_vec())?;
    d.set_item("cov", matrix(py, f.cov, N_PARAMS)?)?;
    d.set_item("cov_colored", matrix(py, f.cov_colored, N_PARAMS)?)?;
    d.set_item("iterations", f.iterations)?;
    d.set_item("converged", f.converged)?;
    d.set_item("cost", f.cost)?;
    d.set_item("residual_var", f.residual_var.to_vec())?;
    d.set_item("n_samples", f.n_samples)?;
    d.set_item("n_maneuvers", f.n_maneuvers)?;
    d.set_item("names", kirchhoff_param_names())?;
    Ok(d)
}

/// `(CL, Cm, CL_basic, Cm_basic, CD, CD_basic)` of the ADX-37 qualified model along records.
#[pyfunction]
#[allow(clippy::type_complexity)]
fn qualified_longitudinal_adx37<'py>(
    py: Python<'py>,
    columns: HashMap<String, PyReadonlyArray1<'py, f64>>,
) -> PyResult<(
    Array<'py>,
    Array<'py>,
    Array<'py>,
    Array<'py>,
    Array<'py>,
    Array<'py>,
)> {
    let cols = column_slices(&columns)?;
    let [a, b, c, d, e, f] = detached(py, || {
        let model = QualifiedModel::adx37(&adx37())?;
        let r = record_columns(&cols)?;
        qualified_longitudinal(&model, &r)
    })?;
    Ok((
        a.into_pyarray(py),
        b.into_pyarray(py),
        c.into_pyarray(py),
        d.into_pyarray(py),
        e.into_pyarray(py),
        f.into_pyarray(py),
    ))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(kirchhoff_param_names, m)?)?;
    m.add_function(wrap_pyfunction!(kirchhoff_truth_params, m)?)?;
    m.add_function(wrap_pyfunction!(kirchhoff_truth_drag, m)?)?;
    m.add_function(wrap_pyfunction!(kirchhoff_drag_names, m)?)?;
    m.add_function(wrap_pyfunction!(kirchhoff_drag_point, m)?)?;
    m.add_function(wrap_pyfunction!(kirchhoff_cl_max, m)?)?;
    m.add_function(wrap_pyfunction!(kirchhoff_outputs, m)?)?;
    m.add_function(wrap_pyfunction!(kirchhoff_point, m)?)?;
    m.add_function(wrap_pyfunction!(output_error_kirchhoff, m)?)?;
    m.add_function(wrap_pyfunction!(qualified_longitudinal_adx37, m)?)?;
    Ok(())
}
