//! Per-bin Δ identification and the qualified model along records (conversion only).
use std::cell::RefCell;
use std::collections::HashMap;

use aero_core::aircraft::qualified::QualifiedModel;
use aero_core::aircraft::records::qualified_lateral;
use aero_core::aircraft::turboprop::adx37;
use aero_core::band::lowpass_by_maneuver;
use aero_core::bootstrap::{Bootstrap, BootstrapOptions};
use aero_core::identify::{
    BinnedFit, Design, DesignBuffers, IdentifyOptions, SmoothOptions, SmoothedParameter,
};
use aero_core::partition::PartitionOptions;
use aero_core::select::{
    identify_flap as identify_flap_core, CvScore, Method, SelectOptions, Selection,
};
use aero_core::AeroError;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::error::to_py;
use crate::util::{column_slices, detached, record_columns};

type Array<'py> = Bound<'py, PyArray1<f64>>;
type SmoothedRow = (String, Vec<f64>, Vec<f64>, usize, String);
type CvTuple = (Vec<usize>, f64, f64, f64, f64);

/// `(Cl, Cn, CY)` of the ADX-37 qualified model along records.
#[pyfunction]
fn qualified_lateral_adx37<'py>(
    py: Python<'py>,
    columns: HashMap<String, PyReadonlyArray1<'py, f64>>,
) -> PyResult<(Array<'py>, Array<'py>, Array<'py>)> {
    let cols = column_slices(&columns)?;
    let [cl, cn, cy] = detached(py, || {
        let model = QualifiedModel::adx37(&adx37())?;
        let c = record_columns(&cols)?;
        qualified_lateral(&model, &c)
    })?;
    Ok((
        cl.into_pyarray(py),
        cn.into_pyarray(py),
        cy.into_pyarray(py),
    ))
}

/// The per-bin fit and its smoothed parameters as a dict of flat arrays.
fn fit_dict<'py>(
    py: Python<'py>,
    fit: &BinnedFit,
    smoothed: Vec<SmoothedParameter>,
) -> PyResult<Bound<'py, PyDict>> {
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
    d.set_item(
        "std_err_cluster",
        flat(&|b| &b.std_err_cluster).into_pyarray(py),
    )?;
    d.set_item("dof_cluster", flat(&|b| &b.dof_cluster).into_pyarray(py))?;
    d.set_item(
        "ci95_half_width",
        flat(&|b| &b.ci95_half_width).into_pyarray(py),
    )?;
    d.set_item("p_value", flat(&|b| &b.p_value).into_pyarray(py))?;
    d.set_item("partial_f", flat(&|b| &b.partial_f).into_pyarray(py))?;
    d.set_item("excitation", flat(&|b| &b.excitation).into_pyarray(py))?;
    d.set_item(
        "excitation_snr",
        flat(&|b| &b.excitation_snr).into_pyarray(py),
    )?;
    d.set_item("vif", flat(&|b| &b.vif).into_pyarray(py))?;
    d.set_item(
        "identifiable",
        bins.iter()
            .flat_map(|b| b.identifiable.iter().copied())
            .collect::<Vec<bool>>(),
    )?;
    d.set_item(
        "smoothable",
        bins.iter()
            .flat_map(|b| b.smoothable.iter().copied())
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

fn score_tuple(s: &CvScore) -> CvTuple {
    (s.columns.clone(), s.rms, s.tic, s.mse, s.mse_se)
}

fn selection_dict<'py>(
    py: Python<'py>,
    sel: &Selection,
    pool: &BinnedFit,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let flat_b = |v: &Vec<Vec<bool>>| v.iter().flatten().copied().collect::<Vec<bool>>();
    let flat_f = |v: &Vec<Vec<f64>>| v.iter().flatten().copied().collect::<Vec<f64>>();
    d.set_item("selected", flat_b(&sel.selected))?;
    d.set_item("partial_f", flat_f(&sel.partial_f).into_pyarray(py))?;
    d.set_item("correlation", flat_f(&sel.correlation).into_pyarray(py))?;
    d.set_item("kappa", sel.kappa.clone().into_pyarray(py))?;
    d.set_item("fitted", sel.fitted.clone())?;
    d.set_item("count", sel.count.clone())?;
    d.set_item(
        "nested",
        sel.nested.iter().map(score_tuple).collect::<Vec<_>>(),
    )?;
    d.set_item("full", score_tuple(&sel.full))?;
    d.set_item(
        "extra",
        sel.extra.iter().map(score_tuple).collect::<Vec<_>>(),
    )?;
    d.set_item("chosen_k", sel.chosen_k)?;
    d.set_item("pruned", score_tuple(&sel.pruned))?;
    match &sel.outer {
        Some(o) => d.set_item("outer", score_tuple(o))?,
        None => d.set_item("outer", py.None())?,
    }
    d.set_item("outer_chosen", sel.outer_chosen.clone())?;
    d.set_item("pool", fit_dict(py, pool, Vec::new())?)?;
    Ok(d)
}

fn bootstrap_dict<'py>(py: Python<'py>, b: &Bootstrap) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let flat = |v: &Vec<Vec<f64>>| v.iter().flatten().copied().collect::<Vec<f64>>();
    d.set_item("alpha_deg", b.alpha_deg.clone().into_pyarray(py))?;
    d.set_item("lower", flat(&b.lower).into_pyarray(py))?;
    d.set_item("upper", flat(&b.upper).into_pyarray(py))?;
    d.set_item("bin_std", flat(&b.bin_std).into_pyarray(py))?;
    d.set_item("bin_lower", flat(&b.bin_lower).into_pyarray(py))?;
    d.set_item("bin_upper", flat(&b.bin_upper).into_pyarray(py))?;
    d.set_item(
        "bin_replicates_ok",
        b.bin_replicates_ok
            .iter()
            .flatten()
            .map(|&v| v as f64)
            .collect::<Vec<f64>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "replicates_ok",
        b.replicates_ok
            .iter()
            .map(|&v| v as f64)
            .collect::<Vec<f64>>()
            .into_pyarray(py),
    )?;
    d.set_item("inclusion", b.inclusion.clone().into_pyarray(py))?;
    d.set_item(
        "replicates",
        b.replicates
            .iter()
            .flatten()
            .flatten()
            .copied()
            .collect::<Vec<f64>>()
            .into_pyarray(py),
    )?;
    d.set_item("n_replicates", b.replicates.first().map_or(0, Vec::len))?;
    d.set_item("level", b.level)?;
    Ok(d)
}

thread_local! {
    /// The design storage [`identify_flap`] reuses on each thread: the candidate pool of a
    /// flap is about a dozen megabytes, and a fresh one each call cost its page faults. Held
    /// until the thread's next call or its end (`aerodelta.fit`'s worker threads end with the
    /// fit).
    static DESIGN_BUFFERS: RefCell<DesignBuffers> = RefCell::new(DesignBuffers::default());
}

/// Per-bin identification of one coefficient at one flap setting with an optional
/// structure selection over a candidate pool and an optional bootstrap over maneuvers.
#[pyfunction]
#[pyo3(signature = (regressors, columns, z, alpha_deg, maneuver, width_deg, min_points_per_param, min_maneuvers, max_width_deg, colored, min_excitation, p, weighted, grid_step_deg, alpha_max_deg, min_identified_bins, selection, f_in, f_out, forced, min_bins, folds, seed, extra, bootstrap, level, t=None, band_hz=None, min_excitation_snr=3.0, min_maneuvers_identified=5, bootstrap_reselect=false, max_vif=10.0, prune_collinear=true, nested_cv=true, companions=Vec::new()))]
#[allow(clippy::too_many_arguments)]
fn identify_flap<'py>(
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
    selection: Option<String>,
    f_in: f64,
    f_out: f64,
    forced: Vec<usize>,
    min_bins: usize,
    folds: usize,
    seed: u64,
    extra: Vec<Vec<usize>>,
    bootstrap: usize,
    level: f64,
    t: Option<PyReadonlyArray1<'py, f64>>,
    band_hz: Option<f64>,
    min_excitation_snr: f64,
    min_maneuvers_identified: usize,
    bootstrap_reselect: bool,
    max_vif: f64,
    prune_collinear: bool,
    nested_cv: bool,
    companions: Vec<(usize, usize)>,
) -> PyResult<Bound<'py, PyDict>> {
    let cols = column_slices(&columns)?;
    let (z, alpha, man) = (z.as_slice()?, alpha_deg.as_slice()?, maneuver.as_slice()?);
    let t = match &t {
        Some(a) => Some(a.as_slice()?),
        None => None,
    };
    let method = match selection.as_deref() {
        None => None,
        Some("stepwise") => Some(Method::Stepwise),
        Some("mof") => Some(Method::Mof),
        Some(other) => {
            return Err(to_py(AeroError::invalid(
                "selection",
                format!("is '{other}'; use 'stepwise', 'mof' or None"),
            )))
        }
    };
    let out = detached(py, || {
        let lookup = |name: &str| cols.get(name).copied();
        // the storage of this thread's previous design (a fit's (flap, coefficient) tasks run
        // one after another on each of its threads)
        let mut buffers = DESIGN_BUFFERS.with(RefCell::take);
        let mut design = Design::build_into(&regressors, &lookup, z.len(), &mut buffers)?;
        let mut zf: Option<Vec<f64>> = None;
        if let Some(fc) = band_hz {
            let t = t.ok_or_else(|| {
                AeroError::invalid("band_hz", "needs the time column 't' of the records")
            })?;
            let mut zv = z.to_vec();
            lowpass_by_maneuver(&mut design, &mut zv, man, t, fc)?;
            zf = Some(zv);
        }
        let z: &[f64] = zf.as_deref().unwrap_or(z);
        let identify = IdentifyOptions {
            partition: PartitionOptions {
                width_deg,
                min_points_per_param,
                min_maneuvers,
                max_width_deg,
                ..PartitionOptions::default()
            },
            colored,
            min_excitation,
            min_excitation_snr,
            min_maneuvers_identified,
            max_vif,
            prune_collinear,
            ..IdentifyOptions::default()
        };
        let so = method.map(|method| SelectOptions {
            method,
            f_in,
            f_out,
            max_vif,
            forced: forced.clone(),
            min_bins,
            folds,
            seed,
            min_excitation,
            min_excitation_snr,
            min_points_per_param,
            extra: extra.clone(),
            nested: nested_cv,
            companions: companions.clone(),
        });
        let smooth = SmoothOptions {
            p,
            weighted,
            grid_step_deg,
            alpha_max_deg,
            min_identified_bins,
        };
        let bo = (bootstrap > 0).then_some(BootstrapOptions {
            replicates: bootstrap,
            seed,
            level,
            min_points_per_param,
            min_maneuvers,
            reselect: bootstrap_reselect,
        });
        let out = identify_flap_core(
            &design,
            z,
            alpha,
            man,
            &identify,
            so.as_ref(),
            &smooth,
            bo.as_ref(),
        );
        buffers.recycle(design);
        DESIGN_BUFFERS.with(|b| b.replace(buffers));
        out
    })?;
    let d = fit_dict(py, &out.fit, out.smoothed)?;
    d.set_item("chosen", out.chosen.clone())?;
    let pruned: Vec<(usize, String)> = out
        .pruned
        .iter()
        .map(|p| (p.column, p.note.clone()))
        .collect();
    d.set_item("pruned", pruned)?;
    match (&out.selection, &out.pool_fit) {
        (Some(sel), Some(pf)) => d.set_item("selection", selection_dict(py, sel, pf)?)?,
        _ => d.set_item("selection", py.None())?,
    }
    match &out.bootstrap {
        Some(b) => d.set_item("bootstrap", bootstrap_dict(py, b)?)?,
        None => d.set_item("bootstrap", py.None())?,
    }
    Ok(d)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(qualified_lateral_adx37, m)?)?;
    m.add_function(wrap_pyfunction!(identify_flap, m)?)?;
    Ok(())
}
