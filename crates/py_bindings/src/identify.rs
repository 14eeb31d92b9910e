//! Per-bin Δ identification and the qualified model along records (conversion only).
use std::collections::HashMap;

use aero_core::aircraft::qualified::QualifiedModel;
use aero_core::aircraft::records::{qualified_lateral, RecordColumns};
use aero_core::aircraft::turboprop::adx37;
use aero_core::identify::{fit_bins, smooth_parameters, Design, IdentifyOptions, SmoothOptions};
use aero_core::partition::PartitionOptions;
use aero_core::AeroError;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::util::detached;

type Array<'py> = Bound<'py, PyArray1<f64>>;
type SmoothedRow = (String, Vec<f64>, Vec<f64>, usize, String);

fn column<'a>(cols: &'a HashMap<String, &'a [f64]>, name: &str) -> Result<&'a [f64], AeroError> {
    cols.get(name).copied().ok_or_else(|| {
        AeroError::invalid(
            format!("column '{name}'"),
            "is required by the qualified model but missing; run the ingestion first",
        )
    })
}

/// `(Cl, Cn, CY)` of the ADX-37 qualified model along records.
#[pyfunction]
fn qualified_lateral_adx37<'py>(
    py: Python<'py>,
    columns: HashMap<String, PyReadonlyArray1<'py, f64>>,
) -> PyResult<(Array<'py>, Array<'py>, Array<'py>)> {
    let mut cols: HashMap<String, &[f64]> = HashMap::new();
    for (k, v) in &columns {
        cols.insert(k.clone(), v.as_slice()?);
    }
    let [cl, cn, cy] = detached(py, || {
        let model = QualifiedModel::adx37(&adx37())?;
        let c = RecordColumns {
            alpha_deg: column(&cols, "alpha_deg")?,
            beta_deg: column(&cols, "beta_deg")?,
            phat: column(&cols, "phat")?,
            qhat: column(&cols, "qhat")?,
            rhat: column(&cols, "rhat")?,
            alphadot_dps: column(&cols, "alphadot_dps")?,
            betadot_dps: column(&cols, "betadot_dps")?,
            da_deg: column(&cols, "da_deg")?,
            de_deg: column(&cols, "de_deg")?,
            dr_deg: column(&cols, "dr_deg")?,
            dsl_deg: column(&cols, "dsl_deg")?,
            dsr_deg: column(&cols, "dsr_deg")?,
            flap_deg: column(&cols, "flap_deg")?,
            ct_left: column(&cols, "ct_left")?,
            ct_right: column(&cols, "ct_right")?,
            tas_mps: column(&cols, "tas_mps")?,
        };
        qualified_lateral(&model, &c)
    })?;
    Ok((
        cl.into_pyarray(py),
        cn.into_pyarray(py),
        cy.into_pyarray(py),
    ))
}

/// Per-bin identification of one coefficient at one flap setting, then smoothing.
#[pyfunction]
#[pyo3(signature = (regressors, columns, z, alpha_deg, maneuver, width_deg, min_points_per_param, min_maneuvers, max_width_deg, colored, min_excitation, p, weighted, grid_step_deg, alpha_max_deg, min_identified_bins))]
#[allow(clippy::too_many_arguments)]
fn identify_bins<'py>(
    py: Python<'py>,
    regressors: Vec<(String, String)>,
    columns: HashMap<String, PyReadonlyArray1<'py, f64>>,
    z: PyReadonlyArray1<'py, f64>,
    alpha_deg: PyReadonlyArray1<'py, f64>,
    maneuver: PyReadonlyArray1<'py, u64>,
    width_deg: f64,
    min_points_per_param: usize,
    min_maneuvers: usize,
    max_width_deg: Option<f64>,
    colored: bool,
    min_excitation: f64,
    p: f64,
    weighted: bool,
    grid_step_deg: f64,
    alpha_max_deg: f64,
    min_identified_bins: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let mut cols: HashMap<String, &[f64]> = HashMap::new();
    for (k, v) in &columns {
        cols.insert(k.clone(), v.as_slice()?);
    }
    let (z, alpha, man) = (z.as_slice()?, alpha_deg.as_slice()?, maneuver.as_slice()?);
    let (fit, smoothed) = detached(py, || {
        let lookup = |name: &str| cols.get(name).copied();
        let design = Design::build(&regressors, &lookup, z.len())?;
        let opts = IdentifyOptions {
            partition: PartitionOptions {
                width_deg,
                min_points_per_param,
                min_maneuvers,
                max_width_deg,
                ..PartitionOptions::default()
            },
            colored,
            min_excitation,
            ..IdentifyOptions::default()
        };
        let fit = fit_bins(&design, z, alpha, man, &opts)?;
        let sm = smooth_parameters(
            &fit,
            &SmoothOptions {
                p,
                weighted,
                grid_step_deg,
                alpha_max_deg,
                min_identified_bins,
            },
        )?;
        Ok((fit, sm))
    })?;
    let d = PyDict::new(py);
    let bins = &fit.bins;
    let flat = |f: &dyn Fn(&aero_core::identify::BinFit) -> &Vec<f64>| -> Vec<f64> {
        bins.iter().flat_map(|b| f(b).iter().copied()).collect()
    };
    d.set_item("names", fit.names.clone())?;
    d.set_item(
        "alpha_lo",
        bins.iter()
            .map(|b| b.alpha_lo)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "alpha_hi",
        bins.iter()
            .map(|b| b.alpha_hi)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "n",
        bins.iter()
            .map(|b| b.n as u64)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "n_maneuvers",
        bins.iter()
            .map(|b| b.n_maneuvers as u64)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "r2",
        bins.iter()
            .map(|b| b.r2)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "condition_number",
        bins.iter()
            .map(|b| b.condition_number)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "residual_std",
        bins.iter()
            .map(|b| b.residual_std)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "bin_note",
        bins.iter().map(|b| b.note.clone()).collect::<Vec<_>>(),
    )?;
    d.set_item("params", flat(&|b| &b.params).into_pyarray(py))?;
    d.set_item("std_err", flat(&|b| &b.std_err).into_pyarray(py))?;
    d.set_item(
        "std_err_colored",
        flat(&|b| &b.std_err_colored).into_pyarray(py),
    )?;
    d.set_item("partial_f", flat(&|b| &b.partial_f).into_pyarray(py))?;
    d.set_item("excitation", flat(&|b| &b.excitation).into_pyarray(py))?;
    d.set_item("vif", flat(&|b| &b.vif).into_pyarray(py))?;
    d.set_item(
        "identifiable",
        bins.iter()
            .flat_map(|b| b.identifiable.iter().copied())
            .collect::<Vec<bool>>(),
    )?;
    d.set_item(
        "notes",
        bins.iter()
            .flat_map(|b| b.notes.iter().cloned())
            .collect::<Vec<String>>(),
    )?;
    d.set_item(
        "consistency_scatter",
        fit.consistency
            .iter()
            .map(|c| c.scatter)
            .collect::<Vec<_>>(),
    )?;
    d.set_item(
        "consistency_step_z",
        fit.consistency.iter().map(|c| c.step_z).collect::<Vec<_>>(),
    )?;
    d.set_item(
        "consistency_pairs",
        fit.consistency.iter().map(|c| c.pairs).collect::<Vec<_>>(),
    )?;
    let sm: Vec<SmoothedRow> = smoothed
        .into_iter()
        .map(|s| (s.name, s.alpha_deg, s.values, s.bins_used, s.note))
        .collect();
    d.set_item("smoothed", sm)?;
    Ok(d)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(qualified_lateral_adx37, m)?)?;
    m.add_function(wrap_pyfunction!(identify_bins, m)?)?;
    Ok(())
}
