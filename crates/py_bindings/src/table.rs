//! `Table`: a frozen newtype over `aero_core::table::Table`.
use aero_core::table::{Axis, Extrapolation, Table};
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::util::{detached, parse_opt};

#[derive(Debug)]
#[pyclass(frozen, name = "Table", module = "aerodelta._core")]
pub struct PyTable(pub Table);

#[pymethods]
impl PyTable {
    /// Build a table; see `aerodelta.Table` for the documented wrapper.
    #[new]
    #[pyo3(signature = (names, breakpoints, values, below, above, mins, maxs))]
    fn new(
        names: Vec<String>,
        breakpoints: Vec<Vec<f64>>,
        values: PyReadonlyArray1<'_, f64>,
        below: Vec<String>,
        above: Vec<String>,
        mins: Vec<Option<f64>>,
        maxs: Vec<Option<f64>>,
    ) -> PyResult<Self> {
        let n = names.len();
        for (what, len) in [
            ("breakpoints", breakpoints.len()),
            ("below", below.len()),
            ("above", above.len()),
            ("mins", mins.len()),
            ("maxs", maxs.len()),
        ] {
            if len != n {
                return Err(crate::error::to_py(aero_core::AeroError::invalid(
                    format!("argument '{what}'"),
                    format!("has {len} entries for {n} axes"),
                )));
            }
        }
        let mut axes = Vec::with_capacity(n);
        for k in 0..n {
            let lo: Extrapolation = parse_opt("below", &below[k])?;
            let hi: Extrapolation = parse_opt("above", &above[k])?;
            let ax = Axis::new(names[k].clone(), breakpoints[k].clone())
                .and_then(|a| a.with_extrapolation(lo, hi).with_limits(mins[k], maxs[k]))
                .map_err(crate::error::to_py)?;
            axes.push(ax);
        }
        let values = values.as_slice()?.to_vec();
        Table::new(axes, values)
            .map(PyTable)
            .map_err(crate::error::to_py)
    }

    #[getter]
    fn ndim(&self) -> usize {
        self.0.ndim()
    }

    #[getter]
    fn names(&self) -> Vec<String> {
        self.0.axes().iter().map(|a| a.name.clone()).collect()
    }

    #[getter]
    fn breakpoints(&self) -> Vec<Vec<f64>> {
        self.0
            .axes()
            .iter()
            .map(|a| a.breakpoints().to_vec())
            .collect()
    }

    fn values<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.0.values().to_vec().into_pyarray(py)
    }

    /// Evaluate at one point (the real-time path).
    fn eval_point(&self, x: Vec<f64>) -> f64 {
        self.0.eval(&x)
    }

    /// Evaluate at many points, one contiguous float64 array per axis.
    fn eval_columns<'py>(
        &self,
        py: Python<'py>,
        columns: Vec<PyReadonlyArray1<'py, f64>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let slices: Vec<&[f64]> = columns
            .iter()
            .map(|c| c.as_slice())
            .collect::<Result<_, _>>()?;
        let npts = slices.first().map_or(0, |s| s.len());
        let table = &self.0;
        let out = detached(py, || {
            let mut out = vec![0.0; npts];
            table.eval_columns(&slices, &mut out)?;
            Ok(out)
        })?;
        Ok(out.into_pyarray(py))
    }

    /// Evaluate at many points given as a C-contiguous (npoints, ndim) float64 array.
    fn eval_rows<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let npts = points.shape()[0];
        let flat = points.as_slice()?;
        let table = &self.0;
        let out = detached(py, || {
            let mut out = vec![0.0; npts];
            table.eval_rows(flat, &mut out)?;
            Ok(out)
        })?;
        Ok(out.into_pyarray(py))
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTable>()
}
