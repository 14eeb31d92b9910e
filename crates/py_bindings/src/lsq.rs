//! `ols` and `OlsFit`: a frozen newtype over `aero_core::lsq::OlsFit`, plus
//! the scalar distribution functions of `aero_core::lsq::stats`.
use aero_core::lsq::{self, stats, OlsFit, OlsOptions};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::util::detached;

#[derive(Debug)]
#[pyclass(frozen, name = "OlsFit", module = "aerodelta._core")]
pub struct PyOlsFit(pub OlsFit);

fn arr1<'py>(py: Python<'py>, v: &[f64]) -> Bound<'py, PyArray1<f64>> {
    v.to_vec().into_pyarray(py)
}

fn arr2<'py>(py: Python<'py>, v: &[f64], p: usize) -> PyResult<Bound<'py, PyArray2<f64>>> {
    v.to_vec().into_pyarray(py).reshape([p, p])
}

#[pymethods]
impl PyOlsFit {
    #[getter]
    fn names(&self) -> Vec<String> {
        self.0.names.clone()
    }
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr1(py, &self.0.params)
    }
    #[getter]
    fn cov<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        arr2(py, &self.0.cov, self.0.params.len())
    }
    #[getter]
    fn std_err<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr1(py, &self.0.std_err)
    }
    #[getter]
    fn cov_colored<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        let p = self.0.params.len();
        self.0
            .cov_colored
            .as_deref()
            .map(|c| arr2(py, c, p))
            .transpose()
    }
    #[getter]
    fn std_err_colored<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.0.std_err_colored.as_deref().map(|s| arr1(py, s))
    }
    /// CR2 cluster-robust covariance (None without groups).
    #[getter]
    fn cov_cluster<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        let p = self.0.params.len();
        self.0
            .cluster
            .as_ref()
            .map(|c| arr2(py, &c.cov, p))
            .transpose()
    }
    #[getter]
    fn std_err_cluster<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.0.cluster.as_ref().map(|c| arr1(py, &c.std_err))
    }
    #[getter]
    fn dof_cluster<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.0.cluster.as_ref().map(|c| arr1(py, &c.dof))
    }
    #[getter]
    fn n_clusters(&self) -> Option<usize> {
        self.0.cluster.as_ref().map(|c| c.n_clusters)
    }
    #[getter]
    fn notes_cluster(&self) -> Option<Vec<String>> {
        self.0.cluster.as_ref().map(|c| c.notes.clone())
    }
    #[getter]
    fn t_values<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr1(py, &self.0.t_values)
    }
    #[getter]
    fn p_values<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr1(py, &self.0.p_values)
    }
    #[getter]
    fn partial_f<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr1(py, &self.0.partial_f)
    }
    #[getter]
    fn r2(&self) -> f64 {
        self.0.r2
    }
    #[getter]
    fn r2_adj(&self) -> f64 {
        self.0.r2_adj
    }
    #[getter]
    fn f_value(&self) -> f64 {
        self.0.f_value
    }
    #[getter]
    fn f_pvalue(&self) -> f64 {
        self.0.f_pvalue
    }
    #[getter]
    fn s2(&self) -> f64 {
        self.0.s2
    }
    #[getter]
    fn rss(&self) -> f64 {
        self.0.rss
    }
    #[getter]
    fn tss(&self) -> f64 {
        self.0.tss
    }
    #[getter]
    fn fit_error_pct(&self) -> f64 {
        self.0.fit_error_pct
    }
    #[getter]
    fn press(&self) -> f64 {
        self.0.press
    }
    #[getter]
    fn pse(&self) -> f64 {
        self.0.pse
    }
    #[getter]
    fn singular_values<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr1(py, &self.0.singular_values)
    }
    #[getter]
    fn singular_values_scaled<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr1(py, &self.0.singular_values_scaled)
    }
    #[getter]
    fn condition_number(&self) -> f64 {
        self.0.condition_number
    }
    #[getter]
    fn condition_number_unscaled(&self) -> f64 {
        self.0.collinearity.condition_number_unscaled
    }
    #[getter]
    fn rank(&self) -> usize {
        self.0.rank
    }
    #[getter]
    fn rank_deficient(&self) -> bool {
        self.0.collinearity.rank_deficient
    }
    #[getter]
    fn vif<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        arr1(py, &self.0.collinearity.vif)
    }
    /// Near dependencies as (condition index, column indices, loadings,
    /// variance-decomposition proportions), worst first.
    #[getter]
    #[allow(clippy::type_complexity)]
    fn dependencies(&self) -> Vec<(f64, Vec<usize>, Vec<f64>, Vec<f64>)> {
        self.0
            .collinearity
            .dependencies
            .iter()
            .map(|d| {
                (
                    d.condition_index,
                    d.columns.clone(),
                    d.loadings.clone(),
                    d.proportions.clone(),
                )
            })
            .collect()
    }
    #[getter]
    fn identifiable(&self) -> Vec<bool> {
        self.0.identifiable.clone()
    }
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.0.notes.clone()
    }
    #[getter]
    fn nobs(&self) -> usize {
        self.0.nobs
    }
    #[getter]
    fn dof(&self) -> usize {
        self.0.dof
    }
    #[getter]
    fn df_model(&self) -> usize {
        self.0.df_model
    }
    #[getter]
    fn const_column(&self) -> Option<usize> {
        self.0.const_column
    }
    #[getter]
    fn residual_mean(&self) -> f64 {
        self.0.residual_mean
    }
    #[getter]
    fn dropped_rows(&self) -> Vec<usize> {
        self.0.dropped_rows.clone()
    }
}

/// OLS of z on the columns of a C-contiguous (N, p) float64 X; see `aerodelta.ols`.
#[pyfunction]
#[pyo3(signature = (x, z, rows=None, names=None, drop_nan=false, colored=true, max_lag=None, min_norm=false, collinear_cond=lsq::COLLINEAR_COND_DEFAULT, groups=None))]
#[allow(clippy::too_many_arguments)]
fn ols<'py>(
    py: Python<'py>,
    x: PyReadonlyArray2<'py, f64>,
    z: PyReadonlyArray1<'py, f64>,
    rows: Option<PyReadonlyArray1<'py, u64>>,
    names: Option<Vec<String>>,
    drop_nan: bool,
    colored: bool,
    max_lag: Option<usize>,
    min_norm: bool,
    collinear_cond: f64,
    groups: Option<PyReadonlyArray1<'py, u64>>,
) -> PyResult<PyOlsFit> {
    let (n, p) = (x.shape()[0], x.shape()[1]);
    let xs = x.as_slice()?;
    let zs = z.as_slice()?;
    let rows: Option<Vec<usize>> = match &rows {
        Some(r) => Some(r.as_slice()?.iter().map(|&i| i as usize).collect()),
        None => None,
    };
    let opts = OlsOptions {
        drop_nan,
        colored,
        max_lag,
        min_norm,
        collinear_cond,
        names: names.unwrap_or_default(),
    };
    let gs = match &groups {
        Some(g) => Some(g.as_slice()?),
        None => None,
    };
    let fit = detached(py, || match (&rows, gs) {
        (Some(r), Some(g)) => lsq::ols_rows_clustered(xs, n, p, zs, r, g, &opts),
        (Some(r), None) => lsq::ols_rows(xs, n, p, zs, r, &opts),
        (None, Some(g)) => lsq::ols_clustered(xs, n, p, zs, g, &opts),
        (None, None) => lsq::ols(xs, n, p, zs, &opts),
    })?;
    Ok(PyOlsFit(fit))
}

/// Student t CDF.
#[pyfunction]
fn student_t_cdf(t: f64, df: f64) -> f64 {
    stats::student_t_cdf(t, df)
}

/// Student t quantile.
#[pyfunction]
fn student_t_ppf(prob: f64, df: f64) -> f64 {
    stats::student_t_ppf(prob, df)
}

/// Fisher F CDF.
#[pyfunction]
fn f_cdf(f: f64, d1: f64, d2: f64) -> f64 {
    stats::f_cdf(f, d1, d2)
}

/// Fisher F survival function.
#[pyfunction]
fn f_sf(f: f64, d1: f64, d2: f64) -> f64 {
    stats::f_sf(f, d1, d2)
}

/// Regularized incomplete beta function I_x(a, b).
#[pyfunction]
fn beta_inc_reg(a: f64, b: f64, x: f64) -> f64 {
    stats::beta_inc_reg(a, b, x)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyOlsFit>()?;
    m.add_function(wrap_pyfunction!(ols, m)?)?;
    m.add_function(wrap_pyfunction!(student_t_cdf, m)?)?;
    m.add_function(wrap_pyfunction!(student_t_ppf, m)?)?;
    m.add_function(wrap_pyfunction!(f_cdf, m)?)?;
    m.add_function(wrap_pyfunction!(f_sf, m)?)?;
    m.add_function(wrap_pyfunction!(beta_inc_reg, m)?)?;
    Ok(())
}
