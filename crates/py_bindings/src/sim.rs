//! The virtual flight test: campaigns, replay, trim, the effect library, the
//! aircraft reference, the qualified model's tables and roll-off draws.
//! Conversion and error mapping only.
use aero_core::aircraft::effects::library_json;
use aero_core::aircraft::qualified::QualifiedModel;
use aero_core::aircraft::truth::EffectSpec;
use aero_core::aircraft::turboprop::adx37;
use aero_core::rolloff::{sample_draws, RollOffConfig};
use aero_core::sim::campaign::{
    plan, replay_adx37, replay_adx37_extended, run_campaign, trim_adx37, CampaignSpec,
    ExtendedLayers,
};
use aero_core::sim::closed_loop::{
    closed_loop_adx37, ClosedLoopOptions, ReplayModel, OUTPUT_COLUMNS, RECORD_COLUMNS,
};
use aero_core::sim::dave_aero::{replay_daveml, UserAircraft};
use aero_core::AeroError;
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::daveml::PyDaveModel;
use crate::delta_model::PyDeltaModel;
use crate::error::to_py;
use crate::util::detached;

/// Run a campaign given as JSON; returns one dict per maneuver:
/// `{"id", "meta" (JSON), "record": {name: array}, "truth": {name: array}}`.
#[pyfunction]
fn sim_run_campaign<'py>(py: Python<'py>, spec_json: &str) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let spec = CampaignSpec::from_json(spec_json).map_err(to_py)?;
    let results = detached(py, || run_campaign(&spec))?;
    let mut out = Vec::with_capacity(results.len());
    for m in results {
        let d = PyDict::new(py);
        d.set_item("id", &m.id)?;
        d.set_item("meta", m.meta_json())?;
        let rec = PyDict::new(py);
        for (name, col) in m.record_names.iter().zip(m.record) {
            rec.set_item(name, col.into_pyarray(py))?;
        }
        d.set_item("record", rec)?;
        let tr = PyDict::new(py);
        for (name, col) in m.truth_names.iter().zip(m.truth) {
            tr.set_item(name, col.into_pyarray(py))?;
        }
        d.set_item("truth", tr)?;
        out.push(d);
    }
    Ok(out)
}

/// The maneuver plan of a campaign spec, as JSON (its effects, roll-off, mass variation and
/// vane calibration checked first).
#[pyfunction]
fn sim_plan(spec_json: &str) -> PyResult<String> {
    let spec = CampaignSpec::from_json(spec_json).map_err(to_py)?;
    aero_core::sim::campaign::resolve_effects(&spec).map_err(to_py)?;
    serde_json::to_string(&plan(&spec))
        .map_err(|e| to_py(AeroError::invalid("plan", e.to_string())))
}

/// The default campaign spec, as JSON.
#[pyfunction]
fn sim_default_spec() -> String {
    CampaignSpec::default().to_json()
}

/// Rows of recorded controls (da, de, dr, dsl, dsr deg) and thrust coefficients.
type ReplayRows = (Vec<[f64; 5]>, Vec<[f64; 2]>);

/// Recorded controls (n x 5, deg) and thrust coefficients (n x 2) as rows.
fn replay_rows(
    controls_deg: &PyReadonlyArray2<'_, f64>,
    ct: &PyReadonlyArray2<'_, f64>,
) -> PyResult<ReplayRows> {
    let (cs, ks) = (controls_deg.shape(), ct.shape());
    if cs[1] != 5 || ks[1] != 2 {
        return Err(to_py(AeroError::invalid(
            "replay",
            format!("controls must be n x 5 (da, de, dr, dsl, dsr deg) and ct n x 2; got {cs:?} and {ks:?}"),
        )));
    }
    let c: Vec<[f64; 5]> = controls_deg
        .as_slice()?
        .chunks_exact(5)
        .map(|r| [r[0], r[1], r[2], r[3], r[4]])
        .collect();
    let k: Vec<[f64; 2]> = ct
        .as_slice()?
        .chunks_exact(2)
        .map(|r| [r[0], r[1]])
        .collect();
    Ok((c, k))
}

fn states_array(py: Python<'_>, states: Vec<[f64; 12]>) -> PyResult<Bound<'_, PyArray2<f64>>> {
    let n = states.len();
    let flat: Vec<f64> = states.into_iter().flatten().collect();
    flat.into_pyarray(py).reshape([n, 12])
}

/// Replay recorded controls on the ADX-37 (see `aero_core::sim::campaign::replay_adx37`).
#[pyfunction]
#[pyo3(signature = (flap_deg, effects_json, x0, dt, controls_deg, ct, rolloff_seed=None))]
#[allow(clippy::too_many_arguments)]
fn sim_replay<'py>(
    py: Python<'py>,
    flap_deg: f64,
    effects_json: &str,
    x0: [f64; 12],
    dt: f64,
    controls_deg: PyReadonlyArray2<'py, f64>,
    ct: PyReadonlyArray2<'py, f64>,
    rolloff_seed: Option<u64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let effects: Vec<EffectSpec> = serde_json::from_str(effects_json)
        .map_err(|e| to_py(AeroError::parse("effects (JSON)", e.line(), e.to_string())))?;
    let (c, k) = replay_rows(&controls_deg, &ct)?;
    let states = detached(py, || {
        replay_adx37(flap_deg, &effects, rolloff_seed, x0, dt, &c, &k)
    })?;
    states_array(py, states)
}

/// Replay recorded controls on the ADX-37 with the extended model (qualified + Δ model;
/// see `aero_core::sim::campaign::replay_adx37_extended`).
#[pyfunction]
/// `lateral_delta=False` flies the model's stored stall alone (`ExtendedLayers::StallOnly`).
#[pyo3(signature = (flap_deg, model, x0, dt, controls_deg, ct, rolloff_seed=None, lateral_delta=true))]
#[allow(clippy::too_many_arguments)]
fn sim_replay_extended<'py>(
    py: Python<'py>,
    flap_deg: f64,
    model: &Bound<'py, PyDeltaModel>,
    x0: [f64; 12],
    dt: f64,
    controls_deg: PyReadonlyArray2<'py, f64>,
    ct: PyReadonlyArray2<'py, f64>,
    rolloff_seed: Option<u64>,
    lateral_delta: bool,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (c, k) = replay_rows(&controls_deg, &ct)?;
    let delta = &model.get().0;
    let layers = if lateral_delta {
        ExtendedLayers::Extended
    } else {
        ExtendedLayers::StallOnly
    };
    let states = detached(py, || {
        replay_adx37_extended(flap_deg, delta, layers, rolloff_seed, x0, dt, &c, &k)
    })?;
    states_array(py, states)
}

/// Replay recorded controls on a user's aircraft flown by a DAVE-ML model (plus a Δ model;
/// see `aero_core::sim::dave_aero::replay_daveml`). `aircraft`: S_m2, b_m, cbar_m, mass_kg,
/// Ixx, Iyy, Izz, Ixz (kg m²), n_engines, prop_inertia_kgm2, prop_rpm, and the CG from the
/// model's moment reference centre x, y, z (m, body axes).
#[pyfunction]
#[pyo3(signature = (model, aircraft, flap_deg, x0, dt, controls_deg, ct, delta=None))]
#[allow(clippy::too_many_arguments)]
fn sim_replay_daveml<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyDaveModel>,
    aircraft: [f64; 14],
    flap_deg: f64,
    x0: [f64; 12],
    dt: f64,
    controls_deg: PyReadonlyArray2<'py, f64>,
    ct: PyReadonlyArray2<'py, f64>,
    delta: Option<&Bound<'py, PyDeltaModel>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (c, k) = replay_rows(&controls_deg, &ct)?;
    let a = aircraft;
    if !(a[8].is_finite() && a[8] >= 0.0 && a[8].fract() == 0.0) {
        return Err(to_py(AeroError::invalid(
            "aircraft n_engines",
            format!("{} must be a whole number >= 0", a[8]),
        )));
    }
    let ac = UserAircraft {
        s_m2: a[0],
        b_m: a[1],
        cbar_m: a[2],
        mass_kg: a[3],
        ixx: a[4],
        iyy: a[5],
        izz: a[6],
        ixz: a[7],
        n_engines: a[8] as usize,
        prop_inertia: a[9],
        prop_rpm: a[10],
        cg_offset_m: [a[11], a[12], a[13]],
    };
    let dave = &model.get().0;
    let dm = delta.map(|d| &d.get().0);
    let states = detached(py, || {
        replay_daveml(&ac, dave, dm, flap_deg, x0, dt, &c, &k)
    })?;
    states_array(py, states)
}

/// Wings-level trim of the qualified ADX-37: (states, controls deg, C_T per engine).
#[pyfunction]
fn sim_trim(flap_deg: f64, v: f64, h: f64) -> PyResult<(Vec<f64>, Vec<f64>, f64)> {
    let (x, c, ct) = trim_adx37(flap_deg, v, h).map_err(to_py)?;
    Ok((x.to_vec(), c.to_vec(), ct))
}

/// The effect library as JSON.
#[pyfunction]
fn sim_effect_library() -> String {
    library_json()
}

/// The aircraft reference file (TOML text).
#[pyfunction]
fn sim_aircraft_toml() -> String {
    adx37().to_toml()
}

/// The qualified model: (tables as (name, axis names, breakpoints, values), terms JSON).
#[pyfunction]
#[allow(clippy::type_complexity)]
fn sim_qualified_tables<'py>(
    py: Python<'py>,
) -> PyResult<(
    Vec<(
        String,
        Vec<String>,
        Vec<Vec<f64>>,
        Bound<'py, PyArray1<f64>>,
    )>,
    String,
)> {
    let q = QualifiedModel::adx37(&adx37()).map_err(to_py)?;
    let (tables, terms) = q.export();
    let t = tables
        .iter()
        .map(|(name, t)| {
            (
                name.clone(),
                t.axes().iter().map(|a| a.name.clone()).collect(),
                t.axes().iter().map(|a| a.breakpoints().to_vec()).collect(),
                t.values().to_vec().into_pyarray(py),
            )
        })
        .collect();
    let terms = serde_json::to_string(terms)
        .map_err(|e| to_py(AeroError::invalid("terms", e.to_string())))?;
    Ok((t, terms))
}

/// `n` roll-off draws at a flap setting: dict of arrays sign, factor, alpha_shift_deg, center_deg, peak.
#[pyfunction]
#[pyo3(signature = (flap_deg, seed, n, stream=0))]
fn sim_rolloff_draws<'py>(
    py: Python<'py>,
    flap_deg: f64,
    seed: u64,
    n: usize,
    stream: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let draws = detached(py, || {
        sample_draws(&RollOffConfig::default(), flap_deg, seed, stream, n)
    })?;
    crate::rolloff::draws_dict(py, &draws)
}

/// The default roll-off configuration (thesis Table 3.2) as JSON.
#[pyfunction]
fn sim_rolloff_config() -> PyResult<String> {
    serde_json::to_string(&RollOffConfig::default())
        .map_err(|e| to_py(AeroError::invalid("rolloff", e.to_string())))
}

/// Closed-loop replay of a recorded stall maneuver on the ADX-37 (see
/// `aero_core::sim::closed_loop`). `record`: n x 16 in `sim_closed_loop_columns()[0]` order;
/// `model`: the fitted Δ model (the extended model) or None (the qualified model with the
/// truth effects `effects_json`); `kirchhoff`: the 9 Kirchhoff parameters of this flap
/// (`aero_core::kirchhoff::PARAM_NAMES`), or with `x0_knots` (rad) and `x0_values` the 7 core
/// parameters of the tabulated form (`aero_core::goman_khrabrov::CORE_NAMES`), or None
/// (static curves), with `kirchhoff_drag` its 3 drag parameters (`DRAG_NAMES`) or None (the
/// qualified drag). Returns the simulated history (m x 15, `sim_closed_loop_columns()[1]`
/// order) and its metadata as JSON.
#[pyfunction]
#[pyo3(signature = (record, x0, options_json, model=None, kirchhoff=None, effects_json=None, kirchhoff_drag=None, x0_knots=None, x0_values=None))]
#[allow(clippy::too_many_arguments)]
fn sim_closed_loop<'py>(
    py: Python<'py>,
    record: PyReadonlyArray2<'py, f64>,
    x0: [f64; 12],
    options_json: &str,
    model: Option<&Bound<'py, PyDeltaModel>>,
    kirchhoff: Option<Vec<f64>>,
    effects_json: Option<&str>,
    kirchhoff_drag: Option<[f64; 3]>,
    x0_knots: Option<Vec<f64>>,
    x0_values: Option<Vec<f64>>,
) -> PyResult<(Bound<'py, PyArray2<f64>>, String)> {
    let shape = record.shape();
    if shape[1] != RECORD_COLUMNS.len() {
        return Err(to_py(AeroError::invalid(
            "closed-loop replay",
            format!(
                "the record must be n x {} ({}); got {shape:?}",
                RECORD_COLUMNS.len(),
                RECORD_COLUMNS.join(", ")
            ),
        )));
    }
    let flat = record.as_slice()?;
    let k = RECORD_COLUMNS.len();
    let cols: Vec<Vec<f64>> = (0..k)
        .map(|j| flat.iter().skip(j).step_by(k).copied().collect())
        .collect();
    let opts = ClosedLoopOptions::from_json(options_json).map_err(to_py)?;
    let effects: Vec<EffectSpec> = match effects_json {
        Some(text) => serde_json::from_str(text)
            .map_err(|e| to_py(AeroError::parse("effects (JSON)", e.line(), e.to_string())))?,
        None => Vec::new(),
    };
    if kirchhoff.is_none() && kirchhoff_drag.is_some() {
        return Err(to_py(AeroError::invalid(
            "closed-loop replay",
            "a Kirchhoff drag without the stall's parameters: give kirchhoff too",
        )));
    }
    let stall = match (kirchhoff, x0_knots, x0_values) {
        (None, None, None) => None,
        (Some(v), None, None) => {
            let a: [f64; 9] = v.as_slice().try_into().map_err(|_| {
                to_py(AeroError::invalid(
                    "closed-loop replay",
                    format!(
                        "kirchhoff has {} values; the tanh form takes 9 ({})",
                        v.len(),
                        aero_core::kirchhoff::PARAM_NAMES.join(", ")
                    ),
                ))
            })?;
            Some(aero_core::stall_form::StallParams::Kirchhoff(
                aero_core::kirchhoff::KirchhoffParams::from_array(&a),
            ))
        }
        (Some(v), Some(knots), Some(values)) => {
            let names = aero_core::goman_khrabrov::CORE_NAMES;
            if v.len() != names.len() {
                return Err(to_py(AeroError::invalid(
                    "closed-loop replay",
                    format!(
                        "kirchhoff has {} values; the tabulated form takes {} ({})",
                        v.len(),
                        names.len(),
                        names.join(", ")
                    ),
                )));
            }
            let mut c = [0.0; aero_core::goman_khrabrov::N_CORE];
            c.copy_from_slice(&v);
            let p = aero_core::goman_khrabrov::GkParams::from_core(&c, knots, values)
                .map_err(|e| to_py(e.context("closed-loop replay")))?;
            Some(p.into())
        }
        _ => {
            return Err(to_py(AeroError::invalid(
                "closed-loop replay",
                "x0_knots and x0_values go together, with the tabulated form's kirchhoff \
                 parameters",
            )))
        }
    };
    let kp = stall.map(|p| {
        (
            p,
            kirchhoff_drag.map(|d| aero_core::kirchhoff::KirchhoffDrag::from_array(&d)),
        )
    });
    let delta = model.map(|m| &m.get().0);
    let run = detached(py, || {
        let which = match &delta {
            Some(d) => ReplayModel::Extended {
                delta: d,
                kirchhoff: kp.clone(),
            },
            None => ReplayModel::Truth {
                effects: &effects,
                kirchhoff: kp.clone(),
            },
        };
        closed_loop_adx37(&which, &cols, x0, &opts)
    })?;
    let m = run.columns.first().map_or(0, Vec::len);
    let mut out = Vec::with_capacity(m * OUTPUT_COLUMNS.len());
    for i in 0..m {
        out.extend(run.columns.iter().map(|c| c[i]));
    }
    Ok((
        out.into_pyarray(py).reshape([m, OUTPUT_COLUMNS.len()])?,
        run.meta_json(),
    ))
}

/// The closed-loop replay's record columns and output columns.
#[pyfunction]
fn sim_closed_loop_columns() -> (Vec<&'static str>, Vec<&'static str>) {
    (RECORD_COLUMNS.to_vec(), OUTPUT_COLUMNS.to_vec())
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sim_closed_loop, m)?)?;
    m.add_function(wrap_pyfunction!(sim_closed_loop_columns, m)?)?;
    m.add_function(wrap_pyfunction!(sim_run_campaign, m)?)?;
    m.add_function(wrap_pyfunction!(sim_plan, m)?)?;
    m.add_function(wrap_pyfunction!(sim_default_spec, m)?)?;
    m.add_function(wrap_pyfunction!(sim_replay, m)?)?;
    m.add_function(wrap_pyfunction!(sim_replay_extended, m)?)?;
    m.add_function(wrap_pyfunction!(sim_replay_daveml, m)?)?;
    m.add_function(wrap_pyfunction!(sim_trim, m)?)?;
    m.add_function(wrap_pyfunction!(sim_effect_library, m)?)?;
    m.add_function(wrap_pyfunction!(sim_aircraft_toml, m)?)?;
    m.add_function(wrap_pyfunction!(sim_qualified_tables, m)?)?;
    m.add_function(wrap_pyfunction!(sim_rolloff_draws, m)?)?;
    m.add_function(wrap_pyfunction!(sim_rolloff_config, m)?)?;
    Ok(())
}
