//! `DeltaModel`: a frozen newtype over `aero_core::delta_model::DeltaModel`.
use std::collections::HashMap;
use std::path::PathBuf;

use aero_core::delta_model::DeltaModel;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::error::to_py;
use crate::util::{column_slices, detached};

#[derive(Debug)]
#[pyclass(frozen, name = "DeltaModel", module = "aerodelta._core")]
pub struct PyDeltaModel(pub DeltaModel);

#[pymethods]
impl PyDeltaModel {
    /// Parse and validate a model from its JSON text; `source` names it in errors.
    #[staticmethod]
    fn from_json(text: &str, source: &str) -> PyResult<Self> {
        DeltaModel::from_json(text, source)
            .map(PyDeltaModel)
            .map_err(to_py)
    }

    /// Load a model file.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        detached(py, || DeltaModel::load(&path)).map(PyDeltaModel)
    }

    fn to_json(&self) -> PyResult<String> {
        self.0.to_json().map_err(to_py)
    }

    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let m = &self.0;
        detached(py, || m.save(&path))
    }

    #[getter]
    fn coefficient_names(&self) -> Vec<String> {
        self.0.coefficient_names()
    }

    #[getter]
    fn input_columns(&self) -> Vec<String> {
        self.0.input_columns()
    }

    fn parameter(
        &self,
        coefficient: &str,
        term: &str,
        flap_deg: f64,
        alpha_deg: f64,
    ) -> PyResult<f64> {
        self.0
            .parameter(coefficient, term, flap_deg, alpha_deg)
            .map_err(to_py)
    }

    /// Per row, whether (flap, alpha, beta) in deg lies in the model's validated envelope;
    /// None when the model carries no envelope.
    fn in_envelope<'py>(
        &self,
        py: Python<'py>,
        flap_deg: PyReadonlyArray1<'py, f64>,
        alpha_deg: PyReadonlyArray1<'py, f64>,
        beta_deg: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Option<Bound<'py, PyArray1<bool>>>> {
        let (f, a, b) = (
            flap_deg.as_slice()?,
            alpha_deg.as_slice()?,
            beta_deg.as_slice()?,
        );
        let m = &self.0;
        let out = detached(py, || m.in_envelope_columns(f, a, b))?;
        Ok(out.map(|v| v.into_pyarray(py)))
    }

    /// Evaluate one coefficient over named float64 columns of `n` rows.
    /// Returns (delta, weight, {term: contribution}).
    #[allow(clippy::type_complexity)]
    fn eval_columns<'py>(
        &self,
        py: Python<'py>,
        coefficient: &str,
        columns: HashMap<String, PyReadonlyArray1<'py, f64>>,
        n: usize,
    ) -> PyResult<(
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyDict>,
    )> {
        let slices = column_slices(&columns)?;
        let m = &self.0;
        let (delta, weight, terms) = detached(py, || {
            let lookup = |name: &str| slices.get(name).copied();
            m.eval_columns(coefficient, &lookup, n)
        })?;
        let d = PyDict::new(py);
        for (name, v) in terms {
            d.set_item(name, v.into_pyarray(py))?;
        }
        Ok((delta.into_pyarray(py), weight.into_pyarray(py), d))
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDeltaModel>()
}
