//! `DaveModel`: a frozen newtype over `aero_core::daveml::DaveModel`, and the
//! DAVE-ML writer (the model spec arrives as JSON text from Python).
use std::path::PathBuf;

use aero_core::daveml::{self, DaveModel, ModelSpec};
use numpy::{IntoPyArray, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::util::detached;

/// (shot, varID, name, units, kind, expected, actual, tolerance, pass)
type CheckTuple = (String, String, String, String, String, f64, f64, f64, bool);
/// (varID, name, units, is_input, is_output, initial_value, min_value, max_value)
type VarTuple = (
    String,
    String,
    String,
    bool,
    bool,
    Option<f64>,
    Option<f64>,
    Option<f64>,
);

/// (varID, effect, distribution, numSigmas (NaN: uniform), bounds (empty for a
/// variableRef), bound variables, line)
type UncertaintyTuple = (
    String,
    String,
    String,
    f64,
    Vec<Vec<f64>>,
    Vec<String>,
    usize,
);

#[derive(Debug)]
#[pyclass(frozen, name = "DaveModel", module = "aerodelta._core")]
pub struct PyDaveModel(pub DaveModel);

#[pymethods]
impl PyDaveModel {
    /// Load a DAVE-ML file; see `aerodelta.load_daveml` for the documented wrapper.
    #[new]
    fn new(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        detached(py, || DaveModel::from_file(&path)).map(PyDaveModel)
    }

    /// Compile DAVE-ML text; `name` names it in messages.
    #[staticmethod]
    fn from_string(py: Python<'_>, text: String, name: String) -> PyResult<Self> {
        detached(py, || DaveModel::from_str(&text, &name)).map(PyDaveModel)
    }

    #[getter]
    fn name(&self) -> String {
        self.0.name().to_string()
    }

    #[getter]
    fn inputs(&self) -> Vec<String> {
        self.0.inputs().iter().map(|v| v.id.clone()).collect()
    }

    #[getter]
    fn outputs(&self) -> Vec<String> {
        self.0.outputs().iter().map(|v| v.id.clone()).collect()
    }

    fn uncertainties(&self) -> Vec<UncertaintyTuple> {
        use daveml::{Bound, Distribution};
        self.0
            .uncertainties()
            .iter()
            .map(|u| {
                let (dist, sigmas) = match u.distribution {
                    Distribution::Normal { num_sigmas } => ("normal", num_sigmas),
                    Distribution::Uniform => ("uniform", f64::NAN),
                };
                let values = u
                    .bounds
                    .iter()
                    .map(|b| match b {
                        Bound::Value(v) => vec![*v],
                        Bound::Table(t) => t.clone(),
                        Bound::Variable(_) => Vec::new(),
                    })
                    .collect();
                let refs = u
                    .bounds
                    .iter()
                    .map(|b| match b {
                        Bound::Variable(id) => id.clone(),
                        _ => String::new(),
                    })
                    .collect();
                (
                    u.var_id.clone(),
                    u.effect.as_str().to_string(),
                    dist.to_string(),
                    sigmas,
                    values,
                    refs,
                    u.line,
                )
            })
            .collect()
    }

    fn variables(&self) -> Vec<VarTuple> {
        self.0
            .variables()
            .iter()
            .map(|v| {
                (
                    v.id.clone(),
                    v.name.clone(),
                    v.units.clone(),
                    v.is_input,
                    v.is_output,
                    v.initial_value,
                    v.min_value,
                    v.max_value,
                )
            })
            .collect()
    }

    /// Evaluate at many points: `inputs` maps input varIDs to contiguous float64
    /// arrays of one length; returns a dict of one array per output varID
    /// (default: the model's outputs). The work runs with the GIL released.
    #[pyo3(signature = (inputs, outputs=None))]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        inputs: &Bound<'py, PyDict>,
        outputs: Option<Vec<String>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mut names = Vec::with_capacity(inputs.len());
        let mut arrays = Vec::with_capacity(inputs.len());
        for (k, v) in inputs.iter() {
            names.push(k.extract::<String>()?);
            arrays.push(v.extract::<PyReadonlyArray1<'py, f64>>()?);
        }
        let slices: Vec<&[f64]> = arrays
            .iter()
            .map(|c| c.as_slice())
            .collect::<Result<_, _>>()?;
        let outputs = outputs.unwrap_or_else(|| self.outputs());
        let model = &self.0;
        let cols = detached(py, || {
            let inputs: Vec<(&str, &[f64])> = names
                .iter()
                .map(String::as_str)
                .zip(slices.iter().copied())
                .collect();
            let outs: Vec<&str> = outputs.iter().map(String::as_str).collect();
            model.evaluate_columns(&inputs, &outs)
        })?;
        let out = PyDict::new(py);
        for (name, col) in outputs.iter().zip(cols) {
            out.set_item(name, col.into_pyarray(py))?;
        }
        Ok(out)
    }

    /// Run the file's static check cases.
    fn run_checks(&self, py: Python<'_>) -> PyResult<Vec<CheckTuple>> {
        let model = &self.0;
        let rows = detached(py, || Ok(model.run_checks()))?;
        Ok(rows
            .into_iter()
            .map(|r| {
                (
                    r.shot,
                    r.var_id,
                    r.name,
                    r.units,
                    r.kind.as_str().to_string(),
                    r.expected,
                    r.actual,
                    r.tolerance,
                    r.pass,
                )
            })
            .collect())
    }

    /// Number of static check cases in the file.
    #[getter]
    fn n_shots(&self) -> usize {
        self.0.shots().len()
    }
}

/// Write a model spec (JSON text) as DAVE-ML at `path`, atomically; returns the model read back.
#[pyfunction]
fn daveml_write(py: Python<'_>, path: PathBuf, spec_json: String) -> PyResult<PyDaveModel> {
    detached(py, || {
        let spec = ModelSpec::from_json(&spec_json)?;
        daveml::write_model(&spec, &path)
    })
    .map(PyDaveModel)
}

/// The DAVE-ML text of a model spec (JSON text), check cases included.
#[pyfunction]
fn daveml_to_xml(py: Python<'_>, spec_json: String) -> PyResult<String> {
    detached(py, || daveml::to_xml(&ModelSpec::from_json(&spec_json)?))
}

/// The DAVE-ML text of `base_text` extended by a model spec (JSON text), with
/// new check cases generated from the merged model.
#[pyfunction]
fn daveml_merge_xml(
    py: Python<'_>,
    base_text: String,
    base_name: String,
    spec_json: String,
) -> PyResult<String> {
    detached(py, || {
        daveml::merge_xml(&base_text, &base_name, &ModelSpec::from_json(&spec_json)?)
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDaveModel>()?;
    m.add_function(wrap_pyfunction!(daveml_write, m)?)?;
    m.add_function(wrap_pyfunction!(daveml_to_xml, m)?)?;
    m.add_function(wrap_pyfunction!(daveml_merge_xml, m)?)?;
    Ok(())
}
