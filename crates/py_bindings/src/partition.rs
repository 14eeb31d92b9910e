//! `AlphaBins`: a frozen newtype over `aero_core::partition::AlphaBins`
//! (alpha partitioning, thesis Section 3.3.1).
use aero_core::partition::{partition_alpha, AlphaBins, PartitionOptions};
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

use crate::util::detached;

#[derive(Debug)]
#[pyclass(frozen, name = "AlphaBins", module = "aerodelta._core")]
pub struct PyAlphaBins(pub AlphaBins);

/// Partition alpha samples; see `aerodelta.partition_alpha` for the documented wrapper.
#[pyfunction(name = "partition_alpha")]
#[pyo3(signature = (
    alpha_deg, n_params, width_deg=0.2, min_points_per_param=10, maneuver_id=None,
    min_maneuvers=1, alpha_range=None, max_width_deg=None, anchor_deg=0.0
))]
#[allow(clippy::too_many_arguments)]
fn partition<'py>(
    py: Python<'py>,
    alpha_deg: PyReadonlyArray1<'py, f64>,
    n_params: usize,
    width_deg: f64,
    min_points_per_param: usize,
    maneuver_id: Option<PyReadonlyArray1<'py, u64>>,
    min_maneuvers: usize,
    alpha_range: Option<(f64, f64)>,
    max_width_deg: Option<f64>,
    anchor_deg: f64,
) -> PyResult<PyAlphaBins> {
    let alpha = alpha_deg.as_slice()?;
    let ids = maneuver_id.as_ref().map(|m| m.as_slice()).transpose()?;
    let opts = PartitionOptions {
        width_deg,
        min_points_per_param,
        min_maneuvers,
        range_deg: alpha_range,
        max_width_deg,
        anchor_deg,
    };
    detached(py, || partition_alpha(alpha, n_params, ids, &opts)).map(PyAlphaBins)
}

#[pymethods]
impl PyAlphaBins {
    /// Bin edges, deg.
    fn edges<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.0.edges.clone().into_pyarray(py)
    }

    /// Samples per bin.
    fn counts<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<usize>> {
        self.0.counts.clone().into_pyarray(py)
    }

    /// Distinct maneuvers per bin, or None without maneuver ids.
    fn maneuvers<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<usize>>> {
        self.0.maneuvers.clone().map(|m| m.into_pyarray(py))
    }

    /// Bin of each sample, -1 outside the range.
    fn index<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        self.0.index.clone().into_pyarray(py)
    }

    /// Per bin, whether it misses the requirement.
    fn underfilled<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        self.0.underfilled.clone().into_pyarray(py)
    }

    #[getter]
    fn required_points(&self) -> usize {
        self.0.required_points
    }

    #[getter]
    fn required_maneuvers(&self) -> usize {
        self.0.required_maneuvers
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyAlphaBins>()?;
    m.add_function(wrap_pyfunction!(partition, m)?)
}
