//! Roll-off detection (`aero_core::rolloff_detect`), runtime-model draws
//! with a given configuration (`aero_core::rolloff`), and the detected events'
//! nuisance columns and centres for the diagnosis (`aero_core::rolloff_events`).
//! Conversion and error mapping only.
use aero_core::rolloff::{sample_draws, RollOffConfig, SPENT_WIDTHS};
use aero_core::rolloff_detect::{detect, DetectConfig, QuietChannel, RecordSignals};
use aero_core::rolloff_events::{self, Event, Records, SpikeShape, CENTRE_SHIFTS_DEG};
use aero_core::rolloff_mc::{run_monte_carlo, MonteCarloSpec, StallSummary};
use aero_core::AeroError;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::error::to_py;
use crate::util::{detached, indices, slice};

/// The detector's default thresholds as a dict.
#[pyfunction]
fn rolloff_detect_defaults<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let c = DetectConfig::default();
    let d = PyDict::new(py);
    d.set_item("trend_window_s", c.trend_window_s)?;
    d.set_item("threshold_sigma", c.threshold_sigma)?;
    d.set_item("min_magnitude", c.min_magnitude)?;
    d.set_item("min_alpha_deg", c.min_alpha_deg)?;
    d.set_item("onset_fraction", c.onset_fraction)?;
    d.set_item("quiet_window_s", c.quiet_window_s)?;
    d.set_item("max_aileron_change_deg", c.max_aileron_change_deg)?;
    d.set_item("max_duration_s", c.max_duration_s)?;
    d.set_item("first_only", c.first_only)?;
    Ok(d)
}

fn config_from(d: Option<&Bound<'_, PyDict>>) -> PyResult<DetectConfig> {
    let mut c = DetectConfig::default();
    let Some(d) = d else { return Ok(c) };
    for (k, v) in d.iter() {
        let key: String = k.extract()?;
        match key.as_str() {
            "trend_window_s" => c.trend_window_s = v.extract()?,
            "threshold_sigma" => c.threshold_sigma = v.extract()?,
            "min_magnitude" => c.min_magnitude = v.extract()?,
            "min_alpha_deg" => c.min_alpha_deg = v.extract()?,
            "onset_fraction" => c.onset_fraction = v.extract()?,
            "quiet_window_s" => c.quiet_window_s = v.extract()?,
            "max_aileron_change_deg" => c.max_aileron_change_deg = v.extract()?,
            "max_duration_s" => c.max_duration_s = v.extract()?,
            "first_only" => c.first_only = v.extract()?,
            other => {
                return Err(to_py(AeroError::invalid(
                    format!("roll-off detection config key '{other}'"),
                    "is unknown; rolloff_detect_defaults() lists the keys",
                )))
            }
        }
    }
    Ok(c)
}

/// Detect roll-off candidates in one record: dict of arrays (onset_index,
/// peak_index, t_onset, t_peak, alpha_onset_deg, peak, direction, duration_s,
/// noise_sigma) and a list `rejected` (empty string = accepted).
#[pyfunction]
#[pyo3(signature = (t, alpha_deg, cl_residual, da_deg, quiet, config=None))]
fn rolloff_detect<'py>(
    py: Python<'py>,
    t: PyReadonlyArray1<'py, f64>,
    alpha_deg: PyReadonlyArray1<'py, f64>,
    cl_residual: PyReadonlyArray1<'py, f64>,
    da_deg: PyReadonlyArray1<'py, f64>,
    quiet: Vec<(String, PyReadonlyArray1<'py, f64>, f64)>,
    config: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let cfg = config_from(config)?;
    let sig = RecordSignals {
        t: t.as_slice()?,
        alpha_deg: alpha_deg.as_slice()?,
        cl_residual: cl_residual.as_slice()?,
        da_deg: da_deg.as_slice()?,
    };
    let others = quiet
        .iter()
        .map(|(name, v, m)| {
            Ok(QuietChannel {
                name: name.as_str(),
                values: v.as_slice()?,
                max_change: *m,
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let ev = detached(py, || detect(&sig, &others, &cfg))?;
    let d = PyDict::new(py);
    let f = |g: &dyn Fn(&aero_core::rolloff_detect::RolloffEvent) -> f64| {
        ev.iter().map(g).collect::<Vec<f64>>()
    };
    d.set_item(
        "onset_index",
        ev.iter()
            .map(|e| e.onset_index as i64)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item(
        "peak_index",
        ev.iter()
            .map(|e| e.peak_index as i64)
            .collect::<Vec<_>>()
            .into_pyarray(py),
    )?;
    d.set_item("t_onset", f(&|e| e.t_onset).into_pyarray(py))?;
    d.set_item("t_peak", f(&|e| e.t_peak).into_pyarray(py))?;
    d.set_item(
        "alpha_onset_deg",
        f(&|e| e.alpha_onset_deg).into_pyarray(py),
    )?;
    d.set_item("peak", f(&|e| e.peak).into_pyarray(py))?;
    d.set_item("direction", f(&|e| f64::from(e.direction)).into_pyarray(py))?;
    d.set_item("duration_s", f(&|e| e.duration_s).into_pyarray(py))?;
    d.set_item("noise_sigma", f(&|e| e.noise_sigma).into_pyarray(py))?;
    d.set_item(
        "rejected",
        ev.iter().map(|e| e.rejected.clone()).collect::<Vec<_>>(),
    )?;
    Ok(d)
}

/// `n` roll-off draws of the runtime model with a configuration given as JSON
/// (`RollOffConfig`): dict of arrays sign, factor, alpha_shift_deg, center_deg, peak.
#[pyfunction]
#[pyo3(signature = (config_json, flap_deg, seed, n, stream=0))]
fn rolloff_sample_draws<'py>(
    py: Python<'py>,
    config_json: &str,
    flap_deg: f64,
    seed: u64,
    n: usize,
    stream: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let cfg: RollOffConfig = serde_json::from_str(config_json).map_err(|e| {
        to_py(AeroError::parse(
            "roll-off config (JSON)",
            e.line(),
            e.to_string(),
        ))
    })?;
    let draws = detached(py, || sample_draws(&cfg, flap_deg, seed, stream, n))?;
    draws_dict(py, &draws)
}

/// Roll-off draws as a dict of numpy columns (shared with the simulator bindings).
pub(crate) fn draws_dict<'py>(
    py: Python<'py>,
    draws: &[aero_core::rolloff::RollOffDraw],
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let col = |f: &dyn Fn(&aero_core::rolloff::RollOffDraw) -> f64| {
        draws.iter().map(f).collect::<Vec<f64>>()
    };
    d.set_item("sign", col(&|r| r.sign).into_pyarray(py))?;
    d.set_item("factor", col(&|r| r.factor).into_pyarray(py))?;
    d.set_item(
        "alpha_shift_deg",
        col(&|r| r.alpha_shift_deg).into_pyarray(py),
    )?;
    d.set_item("center_deg", col(&|r| r.center_deg).into_pyarray(py))?;
    d.set_item("peak", col(&|r| r.peak).into_pyarray(py))?;
    Ok(d)
}

/// Monte Carlo of straight stalls (`aero_core::rolloff_mc`) from a JSON
/// `MonteCarloSpec`; `threads` sizes a dedicated rayon pool (None: global pool).
/// Returns a dict of numpy columns, one row per stall.
#[pyfunction]
#[pyo3(signature = (spec_json, threads=None))]
fn rolloff_monte_carlo<'py>(
    py: Python<'py>,
    spec_json: &str,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let spec = MonteCarloSpec::from_json(spec_json).map_err(to_py)?;
    let rows = detached(py, || run_monte_carlo(&spec, threads))?;
    let d = PyDict::new(py);
    let f = |g: &dyn Fn(&StallSummary) -> f64| rows.iter().map(g).collect::<Vec<f64>>();
    let i = |g: &dyn Fn(&StallSummary) -> i64| rows.iter().map(g).collect::<Vec<i64>>();
    let b = |g: &dyn Fn(&StallSummary) -> bool| rows.iter().map(g).collect::<Vec<bool>>();
    d.set_item("stall", i(&|r| r.stall as i64).into_pyarray(py))?;
    d.set_item(
        "maneuver_index",
        i(&|r| r.maneuver_index as i64).into_pyarray(py),
    )?;
    d.set_item("pusher", b(&|r| r.pusher).into_pyarray(py))?;
    d.set_item("pusher_fired", b(&|r| r.pusher_fired).into_pyarray(py))?;
    d.set_item("duration_s", f(&|r| r.duration_s).into_pyarray(py))?;
    d.set_item("max_alpha_deg", f(&|r| r.max_alpha_deg).into_pyarray(py))?;
    d.set_item("max_bank_deg", f(&|r| r.max_bank_deg).into_pyarray(py))?;
    d.set_item(
        "max_dynamic_roll_deg",
        f(&|r| r.max_dynamic_roll_deg).into_pyarray(py),
    )?;
    d.set_item("far25_203_pass", b(&|r| r.far25_203_pass).into_pyarray(py))?;
    d.set_item(
        "onset_alpha_deg",
        f(&|r| r.onset_alpha_deg).into_pyarray(py),
    )?;
    d.set_item("onset_t", f(&|r| r.onset_t).into_pyarray(py))?;
    d.set_item("peak", f(&|r| r.peak).into_pyarray(py))?;
    d.set_item("direction", i(&|r| i64::from(r.direction)).into_pyarray(py))?;
    d.set_item("drawn_peak", f(&|r| r.drawn_peak).into_pyarray(py))?;
    d.set_item(
        "drawn_center_deg",
        f(&|r| r.drawn_center_deg).into_pyarray(py),
    )?;
    d.set_item("drawn_t", f(&|r| r.drawn_t).into_pyarray(py))?;
    d.set_item("crossings", i(&|r| r.crossings as i64).into_pyarray(py))?;
    Ok(d)
}

/// The default Monte Carlo spec, as JSON.
#[pyfunction]
fn rolloff_mc_default_spec() -> PyResult<String> {
    serde_json::to_string(&MonteCarloSpec::default())
        .map_err(|e| to_py(AeroError::invalid("Monte Carlo spec", e.to_string())))
}

/// The runtime model's spike shape the event columns follow and the centre shifts the
/// refinement tries (`aero_core::rolloff_events`), as a dict.
#[pyfunction]
fn rolloff_event_defaults<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let s = SpikeShape::default();
    let d = PyDict::new(py);
    d.set_item("width_deg", s.width_deg)?;
    d.set_item("rearm_alpha_deg", s.rearm_alpha_deg)?;
    d.set_item("rearm_hysteresis_deg", s.rearm_hysteresis_deg)?;
    d.set_item("spent_widths", SPENT_WIDTHS)?;
    d.set_item("centre_shifts_deg", CENTRE_SHIFTS_DEG.to_vec())?;
    Ok(d)
}

/// The events from three equal-length arrays (maneuver index, centre, peak time).
fn events(
    maneuver: &PyReadonlyArray1<'_, i64>,
    centre_deg: &PyReadonlyArray1<'_, f64>,
    t_peak: &PyReadonlyArray1<'_, f64>,
) -> PyResult<Vec<Event>> {
    let m = indices("maneuver", maneuver)?;
    let (c, t) = (slice("centre_deg", centre_deg)?, slice("t_peak", t_peak)?);
    if c.len() != m.len() || t.len() != m.len() {
        return Err(to_py(AeroError::invalid(
            "roll-off events",
            format!(
                "maneuver, centre_deg and t_peak have {}, {} and {} entries; give one each per event",
                m.len(),
                c.len(),
                t.len()
            ),
        )));
    }
    Ok(m.iter()
        .zip(c.iter().zip(t))
        .map(|(&maneuver, (&centre_deg, &t_peak))| Event {
            maneuver,
            centre_deg,
            t_peak,
        })
        .collect())
}

/// Per-column rows and values of the events' nuisance columns
/// (`aero_core::rolloff_events::event_columns`). `rows[bounds[m]:bounds[m + 1]]` are
/// maneuver `m`'s rows in time order; `maneuver` indexes them.
#[pyfunction]
#[pyo3(signature = (rows, bounds, alpha_deg, t, maneuver, centre_deg, t_peak, sigma_deg))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn rolloff_event_columns<'py>(
    py: Python<'py>,
    rows: PyReadonlyArray1<'py, i64>,
    bounds: PyReadonlyArray1<'py, i64>,
    alpha_deg: PyReadonlyArray1<'py, f64>,
    t: PyReadonlyArray1<'py, f64>,
    maneuver: PyReadonlyArray1<'py, i64>,
    centre_deg: PyReadonlyArray1<'py, f64>,
    t_peak: PyReadonlyArray1<'py, f64>,
    sigma_deg: f64,
) -> PyResult<(
    Vec<Bound<'py, PyArray1<i64>>>,
    Vec<Bound<'py, PyArray1<f64>>>,
)> {
    let (rows, bounds) = (indices("rows", &rows)?, indices("bounds", &bounds)?);
    let rec = Records {
        alpha_deg: slice("alpha_deg", &alpha_deg)?,
        t: slice("t", &t)?,
        rows: &rows,
        bounds: &bounds,
    };
    let ev = events(&maneuver, &centre_deg, &t_peak)?;
    let shape = SpikeShape::with_width(sigma_deg);
    let cols = detached(py, || rolloff_events::event_columns(&rec, &ev, &shape))?;
    let mut out_rows = Vec::with_capacity(cols.len());
    let mut out_values = Vec::with_capacity(cols.len());
    for c in cols {
        out_rows.push(
            c.rows
                .iter()
                .map(|&r| r as i64)
                .collect::<Vec<i64>>()
                .into_pyarray(py),
        );
        out_values.push(c.values.into_pyarray(py));
    }
    Ok((out_rows, out_values))
}

/// Each event's refined centre, deg (`aero_core::rolloff_events::refine_centres` over
/// `CENTRE_SHIFTS_DEG`); the layout as for `rolloff_event_columns`.
#[pyfunction]
#[pyo3(signature = (rows, bounds, alpha_deg, t, residual, maneuver, centre_deg, t_peak, sigma_deg))]
#[allow(clippy::too_many_arguments)]
fn rolloff_refine_centres<'py>(
    py: Python<'py>,
    rows: PyReadonlyArray1<'py, i64>,
    bounds: PyReadonlyArray1<'py, i64>,
    alpha_deg: PyReadonlyArray1<'py, f64>,
    t: PyReadonlyArray1<'py, f64>,
    residual: PyReadonlyArray1<'py, f64>,
    maneuver: PyReadonlyArray1<'py, i64>,
    centre_deg: PyReadonlyArray1<'py, f64>,
    t_peak: PyReadonlyArray1<'py, f64>,
    sigma_deg: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (rows, bounds) = (indices("rows", &rows)?, indices("bounds", &bounds)?);
    let rec = Records {
        alpha_deg: slice("alpha_deg", &alpha_deg)?,
        t: slice("t", &t)?,
        rows: &rows,
        bounds: &bounds,
    };
    let residual = slice("residual", &residual)?;
    let ev = events(&maneuver, &centre_deg, &t_peak)?;
    let shape = SpikeShape::with_width(sigma_deg);
    let out = detached(py, || {
        rolloff_events::refine_centres(&rec, residual, &ev, &CENTRE_SHIFTS_DEG, &shape)
    })?;
    Ok(out.into_pyarray(py))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(rolloff_event_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(rolloff_event_columns, m)?)?;
    m.add_function(wrap_pyfunction!(rolloff_refine_centres, m)?)?;
    m.add_function(wrap_pyfunction!(rolloff_monte_carlo, m)?)?;
    m.add_function(wrap_pyfunction!(rolloff_mc_default_spec, m)?)?;
    m.add_function(wrap_pyfunction!(rolloff_detect_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(rolloff_detect, m)?)?;
    m.add_function(wrap_pyfunction!(rolloff_sample_draws, m)?)?;
    Ok(())
}
