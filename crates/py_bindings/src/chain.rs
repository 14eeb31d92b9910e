//! Measurement-chain calibration (`aero_core::chain`). Conversion only.
use std::collections::HashMap;

use aero_core::chain::{calibrate_all, ChainInput, ChainOptions, ChainOutcome};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;

use crate::util::{column_slices, detached, slice};

/// One coefficient's estimates: `(tau_s, kappa_s2, t_tau, t_kappa, samples, maneuvers)`.
type Estimate = (f64, f64, f64, f64, usize, usize);

/// Per coefficient `(q, meas, terms)`: `(why_skipped, estimate, corrected)`, `why_skipped`
/// `""` and the other two set when calibrated; see `aerodelta.fit.calibrate_chain`.
#[pyfunction]
#[pyo3(signature = (t, maneuver, trusted, coefficients, columns, min_samples, min_maneuvers))]
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
fn calibrate_chain<'py>(
    py: Python<'py>,
    t: PyReadonlyArray1<'py, f64>,
    maneuver: PyReadonlyArray1<'py, u64>,
    trusted: PyReadonlyArray1<'py, bool>,
    coefficients: Vec<(
        PyReadonlyArray1<'py, f64>,
        PyReadonlyArray1<'py, f64>,
        Vec<(String, String)>,
    )>,
    columns: HashMap<String, PyReadonlyArray1<'py, f64>>,
    min_samples: usize,
    min_maneuvers: usize,
) -> PyResult<Vec<(String, Option<Estimate>, Option<Bound<'py, PyArray1<f64>>>)>> {
    let (t, man, trusted) = (
        slice("t", &t)?,
        slice("maneuver", &maneuver)?,
        slice("trusted", &trusted)?,
    );
    let cols = column_slices(&columns)?;
    let mut inputs = Vec::with_capacity(coefficients.len());
    for (q, meas, terms) in &coefficients {
        inputs.push(ChainInput {
            q: slice("q", q)?,
            meas: slice("meas", meas)?,
            terms,
        });
    }
    let opts = ChainOptions {
        min_samples,
        min_maneuvers,
    };
    let lookup = |name: &str| cols.get(name).copied();
    let out = detached(py, || {
        calibrate_all(t, man, trusted, &inputs, &lookup, &opts)
    })?;
    Ok(out
        .into_iter()
        .map(|o| match o {
            ChainOutcome::Skipped(why) => (why, None, None),
            ChainOutcome::Calibrated {
                estimate: e,
                corrected,
            } => (
                String::new(),
                Some((
                    e.skew_s,
                    e.curvature_s2,
                    e.t_skew,
                    e.t_curvature,
                    e.samples,
                    e.maneuvers,
                )),
                Some(PyArray1::from_vec(py, corrected)),
            ),
        })
        .collect())
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(calibrate_chain, m)?)?;
    Ok(())
}
