//! The Goman-Khrabrov (tabulated) separation model and its output-error fit (conversion only).
use std::collections::HashMap;

use aero_core::goman_khrabrov::{outputs, GkParams, X0Table, CORE_NAMES};
use aero_core::kirchhoff::Inputs;
use aero_core::output_error::{fit_tabulated, GkOptions};
use aero_core::AeroError;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::error::to_py;
use crate::kirchhoff::{dict_of, matrix_of, named, series_of};
use crate::util::detached;

type Array<'py> = Bound<'py, PyArray1<f64>>;

/// The parameters from the scalar map `core` and the table `knots` (rad), `values`.
pub(crate) fn params_from(
    core: &HashMap<String, f64>,
    knots: Vec<f64>,
    values: Vec<f64>,
    arg: &str,
) -> PyResult<GkParams> {
    GkParams::from_core(&named(core, CORE_NAMES, arg)?, knots, values).map_err(to_py)
}

fn core_dict(p: &GkParams) -> HashMap<String, f64> {
    let v = p.to_vec();
    let mut c = [0.0; CORE_NAMES.len()];
    c.copy_from_slice(&v[..CORE_NAMES.len()]);
    dict_of(CORE_NAMES, c)
}

/// Scalar parameter names in the engine's order (the node values `x0[k]` follow).
#[pyfunction]
fn goman_khrabrov_core_names() -> Vec<String> {
    CORE_NAMES.iter().map(|s| (*s).to_string()).collect()
}

/// `(x, CL, Cm)` along one record.
#[pyfunction]
fn goman_khrabrov_outputs<'py>(
    py: Python<'py>,
    core: HashMap<String, f64>,
    knots: Vec<f64>,
    values: Vec<f64>,
    t: PyReadonlyArray1<'py, f64>,
    alpha: PyReadonlyArray1<'py, f64>,
    alpha_dot: PyReadonlyArray1<'py, f64>,
) -> PyResult<(Array<'py>, Array<'py>, Array<'py>)> {
    let p = params_from(&core, knots, values, "core")?;
    let (t, a, ad) = (t.as_slice()?, alpha.as_slice()?, alpha_dot.as_slice()?);
    let o = detached(py, || {
        outputs(
            &p,
            &Inputs {
                t,
                alpha: a,
                alpha_dot: ad,
            },
            false,
        )
    })?;
    Ok((
        o.x.into_pyarray(py),
        o.cl.into_pyarray(py),
        o.cm.into_pyarray(py),
    ))
}

/// `(x0(alpha), static CL, static Cm)` at each alpha (rad).
#[pyfunction]
fn goman_khrabrov_static<'py>(
    py: Python<'py>,
    core: HashMap<String, f64>,
    knots: Vec<f64>,
    values: Vec<f64>,
    alpha: PyReadonlyArray1<'py, f64>,
) -> PyResult<(Array<'py>, Array<'py>, Array<'py>)> {
    let p = params_from(&core, knots, values, "core")?;
    let a = alpha.as_slice()?;
    let x: Vec<f64> = a.iter().map(|&a| p.x0.eval(a)).collect();
    let cl: Vec<f64> = a.iter().zip(&x).map(|(&a, &x)| p.cl(a, x)).collect();
    let cm: Vec<f64> = a.iter().zip(&x).map(|(&a, &x)| p.cm(a, x)).collect();
    Ok((x.into_pyarray(py), cl.into_pyarray(py), cm.into_pyarray(py)))
}

/// The spline weights `∂x₀(α)/∂v_k` at each alpha (rad): an `n × K` matrix.
#[pyfunction]
fn goman_khrabrov_weights<'py>(
    py: Python<'py>,
    knots: Vec<f64>,
    alpha: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
    let k = knots.len();
    let t = X0Table::new(knots, vec![1.0; k]).map_err(to_py)?;
    let a = alpha.as_slice()?;
    let w: Vec<f64> = a.iter().flat_map(|&z| t.weights(z)).collect();
    matrix_of(py, w, a.len(), k)
}

/// `(alpha at C_L,max [rad], C_L,max)` of the static curve over the table.
#[pyfunction]
fn goman_khrabrov_cl_max(
    core: HashMap<String, f64>,
    knots: Vec<f64>,
    values: Vec<f64>,
) -> PyResult<(f64, f64)> {
    Ok(params_from(&core, knots, values, "core")?.cl_max())
}

/// Output-error fit of the tabulated form from a start over its knots; a dict of plain values.
#[pyfunction]
#[pyo3(signature = (t, alpha, alpha_dot, cl, cm, core, knots, values, fixed=Vec::new(), max_iter=60, tol=1e-9, max_lag=None))]
#[allow(clippy::too_many_arguments)]
fn output_error_goman_khrabrov<'py>(
    py: Python<'py>,
    t: Vec<PyReadonlyArray1<'py, f64>>,
    alpha: Vec<PyReadonlyArray1<'py, f64>>,
    alpha_dot: Vec<PyReadonlyArray1<'py, f64>>,
    cl: Vec<PyReadonlyArray1<'py, f64>>,
    cm: Option<Vec<PyReadonlyArray1<'py, f64>>>,
    core: HashMap<String, f64>,
    knots: Vec<f64>,
    values: Vec<f64>,
    fixed: Vec<String>,
    max_iter: usize,
    tol: f64,
    max_lag: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let start = params_from(&core, knots, values, "core")?;
    let names = start.names();
    let mut fx = vec![false; names.len()];
    for name in &fixed {
        let j = names.iter().position(|n| n == name).ok_or_else(|| {
            to_py(AeroError::invalid(
                "argument 'fixed'",
                format!("unknown parameter '{name}'; valid: {}", names.join(", ")),
            ))
        })?;
        fx[j] = true;
    }
    let series = series_of(&t, &alpha, &alpha_dot, &cl, cm.as_deref())?;
    let opts = GkOptions {
        max_iter,
        tol,
        fixed: fx,
        max_lag,
    };
    let f = detached(py, || fit_tabulated(&series, &start, &opts))?;
    let np = names.len();
    let d = PyDict::new(py);
    d.set_item("params", core_dict(&f.params))?;
    d.set_item("values", f.params.x0.values().to_vec())?;
    d.set_item("knots", f.params.x0.knots().to_vec())?;
    d.set_item("start", core_dict(&f.start))?;
    d.set_item("start_values", f.start.x0.values().to_vec())?;
    d.set_item("free", f.free)?;
    d.set_item("std_err", f.std_err)?;
    d.set_item("std_err_colored", f.std_err_colored)?;
    d.set_item("cov", matrix_of(py, f.cov, np, np)?)?;
    d.set_item("cov_colored", matrix_of(py, f.cov_colored, np, np)?)?;
    d.set_item("iterations", f.iterations)?;
    d.set_item("converged", f.converged)?;
    d.set_item("cost", f.cost)?;
    d.set_item("residual_var", f.residual_var.to_vec())?;
    d.set_item("n_samples", f.n_samples)?;
    d.set_item("n_maneuvers", f.n_maneuvers)?;
    d.set_item("names", names)?;
    Ok(d)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(goman_khrabrov_core_names, m)?)?;
    m.add_function(wrap_pyfunction!(goman_khrabrov_outputs, m)?)?;
    m.add_function(wrap_pyfunction!(goman_khrabrov_static, m)?)?;
    m.add_function(wrap_pyfunction!(goman_khrabrov_cl_max, m)?)?;
    m.add_function(wrap_pyfunction!(goman_khrabrov_weights, m)?)?;
    m.add_function(wrap_pyfunction!(output_error_goman_khrabrov, m)?)?;
    Ok(())
}
