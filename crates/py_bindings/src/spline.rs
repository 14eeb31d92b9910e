//! `SmoothingSpline`: a frozen newtype over `aero_core::spline::SmoothingSpline`
//! (cubic smoothing spline with MATLAB `csaps` semantics, thesis Eq. 3.13).
use aero_core::spline::{
    merge_sites, smoothing_spline, Smoothing, SmoothingSpline, SplineExtrapolation,
};
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

use crate::table::PyTable;
use crate::util::{detached, parse_opt};

#[derive(Debug)]
#[pyclass(frozen, name = "SmoothingSpline", module = "aerodelta._core")]
pub struct PySmoothingSpline(pub SmoothingSpline);

/// Fit a smoothing spline; see `aerodelta.smoothing_spline` for the documented wrapper.
///
/// `p=None` without `normalized` picks csaps's automatic p; `normalized=True`
/// maps `p` (default 0.5) through csaps's `normalizedsmooth`.
#[pyfunction(name = "smoothing_spline")]
#[pyo3(signature = (x, y, weights=None, p=None, normalized=false))]
fn fit<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    y: PyReadonlyArray1<'py, f64>,
    weights: Option<PyReadonlyArray1<'py, f64>>,
    p: Option<f64>,
    normalized: bool,
) -> PyResult<PySmoothingSpline> {
    let x = x.as_slice()?;
    let y = y.as_slice()?;
    let w = weights.as_ref().map(|w| w.as_slice()).transpose()?;
    let smoothing = match (normalized, p) {
        (true, s) => Smoothing::Normalized(s),
        (false, Some(p)) => Smoothing::Fixed(p),
        (false, None) => Smoothing::Auto,
    };
    detached(py, || smoothing_spline(x, y, w, smoothing)).map(PySmoothingSpline)
}

/// Sort sites and merge repeated ones by weighted averaging; returns `(x, y, w)`.
#[pyfunction(name = "merge_sites")]
#[pyo3(signature = (x, y, weights=None))]
#[allow(clippy::type_complexity)]
fn merge<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    y: PyReadonlyArray1<'py, f64>,
    weights: Option<PyReadonlyArray1<'py, f64>>,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
)> {
    let x = x.as_slice()?;
    let y = y.as_slice()?;
    let w = weights.as_ref().map(|w| w.as_slice()).transpose()?;
    let (xs, ys, ws) = detached(py, || merge_sites(x, y, w))?;
    Ok((
        xs.into_pyarray(py),
        ys.into_pyarray(py),
        ws.into_pyarray(py),
    ))
}

#[pymethods]
impl PySmoothingSpline {
    /// The breaks (data sites).
    fn breaks<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.0.breaks().to_vec().into_pyarray(py)
    }

    /// Coefficients, flat: per piece `[a3, a2, a1, a0]`.
    fn coefs<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.0.coefs().as_flattened().to_vec().into_pyarray(py)
    }

    /// The smoothing parameter used.
    #[getter]
    fn p(&self) -> f64 {
        self.0.p()
    }

    /// Values or derivatives of order `nu` at `x`; `extrapolate` is 'polynomial' or 'hold'.
    fn eval<'py>(
        &self,
        py: Python<'py>,
        x: PyReadonlyArray1<'py, f64>,
        nu: u32,
        extrapolate: &str,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let ext: SplineExtrapolation = parse_opt("extrapolate", extrapolate)?;
        let x = x.as_slice()?;
        let s = &self.0;
        let out = detached(py, || {
            let mut out = vec![0.0; x.len()];
            s.eval_many(x, nu, ext, &mut out)?;
            Ok(out)
        })?;
        Ok(out.into_pyarray(py))
    }

    /// Resample onto `grid` as a 1-D table with axis `name`.
    fn to_table(&self, name: &str, grid: Vec<f64>, extrapolate: &str) -> PyResult<PyTable> {
        let ext: SplineExtrapolation = parse_opt("extrapolate", extrapolate)?;
        self.0
            .to_table(name, &grid, ext)
            .map(PyTable)
            .map_err(crate::error::to_py)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySmoothingSpline>()?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(fit, m)?)
}
