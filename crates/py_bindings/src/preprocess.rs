//! Flight test preprocessing (`aero_core::preprocess`): conversion and error mapping only.
use aero_core::preprocess::coefficients::MassGeometry;
use aero_core::preprocess::smooth as core_smooth;
use aero_core::preprocess::{compat, deriv, kinematics, maneuver, matched, plausibility};
use aero_core::AeroError;
use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::util::{detached, slice};

type Arr<'py> = Bound<'py, PyArray1<f64>>;

fn slices<'a>(cols: &'a [PyReadonlyArray1<'_, f64>]) -> PyResult<Vec<&'a [f64]>> {
    cols.iter()
        .map(|c| c.as_slice().map_err(PyErr::from))
        .collect()
}

/// Optimal Fourier smoother: `(smoothed, cutoff_hz, noise_std)`.
#[pyfunction]
fn smooth<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    dt: f64,
) -> PyResult<(Arr<'py>, f64, f64)> {
    let xs = x.as_slice()?;
    let r = detached(py, || Ok(core_smooth::smooth(xs, dt)))?;
    Ok((r.values.into_pyarray(py), r.cutoff_hz, r.noise_std))
}

/// SIDPAC-`deriv`-like smoothed derivative: `(derivative, cutoff_hz)`.
#[pyfunction]
fn smooth_deriv<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    dt: f64,
) -> PyResult<(Arr<'py>, f64)> {
    let xs = x.as_slice()?;
    let (d, fc) = detached(py, || {
        Ok(deriv::smooth_deriv(
            &core_smooth::Smoother::new(xs.len()),
            xs,
            dt,
        ))
    })?;
    Ok((d.into_pyarray(py), fc))
}

/// Local polynomial (Savitzky-Golay) derivative.
#[pyfunction]
fn local_poly_deriv<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    dt: f64,
    half_window: usize,
    order: usize,
) -> PyResult<Arr<'py>> {
    let xs = x.as_slice()?;
    let d = detached(py, || deriv::local_poly_deriv(xs, dt, half_window, order))?;
    Ok(d.into_pyarray(py))
}

/// Accelerometer transfer to the CG (rad/s, rad/s², m/s², m).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn accel_to_cg<'py>(
    py: Python<'py>,
    accel: Vec<PyReadonlyArray1<'py, f64>>,
    rates: Vec<PyReadonlyArray1<'py, f64>>,
    rate_derivs: Vec<PyReadonlyArray1<'py, f64>>,
    position_m: [f64; 3],
) -> PyResult<(Arr<'py>, Arr<'py>, Arr<'py>)> {
    let (a, w, wd) = (slices(&accel)?, slices(&rates)?, slices(&rate_derivs)?);
    if a.len() != 3 || w.len() != 3 || wd.len() != 3 {
        return Err(crate::error::to_py(AeroError::invalid(
            "accel_to_cg",
            "accel, rates and rate_derivs take three arrays each",
        )));
    }
    let n = a[0].len();
    if a.iter().chain(&w).chain(&wd).any(|c| c.len() != n) {
        return Err(crate::error::to_py(AeroError::invalid(
            "accel_to_cg",
            "arrays of unequal length",
        )));
    }
    let [x, y, z] = detached(py, || {
        Ok(kinematics::accel_to_cg(
            [a[0], a[1], a[2]],
            [w[0], w[1], w[2]],
            [wd[0], wd[1], wd[2]],
            position_m,
        ))
    })?;
    Ok((x.into_pyarray(py), y.into_pyarray(py), z.into_pyarray(py)))
}

/// Vane angles (rad) to CG angle of attack and sideslip (rad); `flank`: the beta vane reads
/// the flank angle.
#[pyfunction]
#[pyo3(signature = (alpha_vane, beta_vane, tas, rates, alpha_vane_m, beta_vane_m, flank=false))]
#[allow(clippy::too_many_arguments)]
fn vanes_to_cg<'py>(
    py: Python<'py>,
    alpha_vane: PyReadonlyArray1<'py, f64>,
    beta_vane: PyReadonlyArray1<'py, f64>,
    tas: PyReadonlyArray1<'py, f64>,
    rates: Vec<PyReadonlyArray1<'py, f64>>,
    alpha_vane_m: [f64; 3],
    beta_vane_m: [f64; 3],
    flank: bool,
) -> PyResult<(Arr<'py>, Arr<'py>)> {
    let (a, b, v) = (
        alpha_vane.as_slice()?,
        beta_vane.as_slice()?,
        tas.as_slice()?,
    );
    let w = slices(&rates)?;
    let n = a.len();
    if w.len() != 3 || b.len() != n || v.len() != n || w.iter().any(|c| c.len() != n) {
        return Err(crate::error::to_py(AeroError::invalid(
            "vanes_to_cg",
            "alpha, beta, tas and three rate arrays of equal length expected",
        )));
    }
    let (x, y) = detached(py, || {
        Ok(kinematics::vanes_to_cg(
            a,
            b,
            v,
            [w[0], w[1], w[2]],
            alpha_vane_m,
            beta_vane_m,
            flank,
        ))
    })?;
    Ok((x.into_pyarray(py), y.into_pyarray(py)))
}

/// Column names of the batch pipeline: `(inputs, smoothed, outputs)`.
#[pyfunction]
fn preprocess_columns() -> (Vec<String>, Vec<String>, Vec<String>) {
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let mut outs = s(&maneuver::OUTPUT_COLUMNS);
    outs.push(maneuver::CM_COLUMN.to_string());
    (
        s(&maneuver::INPUT_COLUMNS[..12]),
        s(&maneuver::SMOOTHED_COLUMNS),
        outs,
    )
}

/// Preprocess concatenated maneuvers: `(output columns, cutoffs_hz (n_man*9), noise_std (n_man*9))`.
///
/// `mass_geometry` = [S, b, cbar, mass, Ixx, Iyy, Izz, Ixz, Ixy, Iyz] of the nominal loading;
/// positions from the aircraft datum (m); `masses` one row per maneuver
/// [mass, Ixx, Iyy, Izz, Ixz, Ixy, Iyz, cg_x, cg_y, cg_z] or None (nominal loading).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (columns, offsets, mass_geometry, prop_h_per_rpm, accel_m, alpha_vane_m, beta_vane_m, smooth=true, cg_m=[0.0; 3], moment_ref_m=[0.0; 3], masses=None, beta_flank=false))]
fn preprocess_batch<'py>(
    py: Python<'py>,
    columns: Vec<PyReadonlyArray1<'py, f64>>,
    offsets: Vec<usize>,
    mass_geometry: [f64; 10],
    prop_h_per_rpm: f64,
    accel_m: [f64; 3],
    alpha_vane_m: [f64; 3],
    beta_vane_m: [f64; 3],
    smooth: bool,
    cg_m: [f64; 3],
    moment_ref_m: [f64; 3],
    masses: Option<PyReadonlyArray2<'py, f64>>,
    beta_flank: bool,
) -> PyResult<(Vec<Arr<'py>>, Arr<'py>, Arr<'py>)> {
    let cols = slices(&columns)?;
    let [s, b, cbar, mass, ixx, iyy, izz, ixz, ixy, iyz] = mass_geometry;
    let ac = maneuver::AircraftParams {
        mg: MassGeometry {
            s,
            b,
            cbar,
            mass,
            ixx,
            iyy,
            izz,
            ixz,
            ixy,
            iyz,
        },
        prop_h_per_rpm,
        accel_m,
        alpha_vane_m,
        beta_vane_m,
        cg_m,
        moment_ref_m,
        beta_flank,
    };
    let loads: Vec<maneuver::ManeuverMass> = match &masses {
        None => Vec::new(),
        Some(a) => {
            let v = a.as_array();
            if v.ncols() != 10 {
                return Err(crate::error::to_py(AeroError::invalid(
                    "argument 'masses'",
                    format!("{} columns; 10 expected", v.ncols()),
                )));
            }
            v.rows()
                .into_iter()
                .map(|r| maneuver::ManeuverMass {
                    mass: r[0],
                    inertia: [r[1], r[2], r[3], r[4], r[5], r[6]],
                    cg_m: [r[7], r[8], r[9]],
                })
                .collect()
        }
    };
    let opts = maneuver::PreprocessOptions { smooth };
    let out = detached(py, || {
        maneuver::preprocess_concatenated(&cols, &offsets, &ac, &loads, &opts)
    })?;
    let arrays = out
        .columns
        .into_iter()
        .map(|c| c.into_pyarray(py))
        .collect();
    Ok((
        arrays,
        out.cutoffs_hz.into_pyarray(py),
        out.noise_std.into_pyarray(py),
    ))
}

/// Data compatibility check of one maneuver (SI, rad, at the CG). Returns a dict with
/// `names`, `params`, `std_err` (the estimated parameters only: the vane scale factors with
/// `scale_factors`, the innovation gains with `gusts`), `outputs`, `rms_before`, `rms_after`,
/// `iterations`, `converged`.
#[pyfunction]
#[pyo3(signature = (t, accel, rates, tas, alpha, beta, euler, max_iter=20, scale_factors=false, r_alpha=[0.0; 3], r_beta=[0.0; 3], flank=false, gusts=false))]
#[allow(clippy::too_many_arguments)]
fn compat_check<'py>(
    py: Python<'py>,
    t: PyReadonlyArray1<'py, f64>,
    accel: Vec<PyReadonlyArray1<'py, f64>>,
    rates: Vec<PyReadonlyArray1<'py, f64>>,
    tas: PyReadonlyArray1<'py, f64>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
    euler: Vec<PyReadonlyArray1<'py, f64>>,
    max_iter: usize,
    scale_factors: bool,
    r_alpha: [f64; 3],
    r_beta: [f64; 3],
    flank: bool,
    gusts: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let (a, w, e) = (slices(&accel)?, slices(&rates)?, slices(&euler)?);
    if a.len() != 3 || w.len() != 3 || e.len() != 3 {
        return Err(crate::error::to_py(AeroError::invalid(
            "compat_check",
            "accel, rates and euler take three arrays each",
        )));
    }
    let inp = compat::CompatInput {
        t: t.as_slice()?,
        accel: [a[0], a[1], a[2]],
        rates: [w[0], w[1], w[2]],
        tas: tas.as_slice()?,
        alpha: alpha.as_slice()?,
        beta: beta.as_slice()?,
        euler: [e[0], e[1], e[2]],
        vanes: compat::Vanes {
            r_alpha,
            r_beta,
            flank,
        },
    };
    let r = detached(py, || compat::check(&inp, max_iter, scale_factors, gusts))?;
    let keep = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .zip(&r.estimated)
            .filter(|(_, e)| **e)
            .map(|(x, _)| *x)
            .collect()
    };
    let names: Vec<&str> = compat::PARAM_NAMES
        .iter()
        .zip(&r.estimated)
        .filter(|(_, e)| **e)
        .map(|(n, _)| *n)
        .collect();
    let d = PyDict::new(py);
    d.set_item("names", names)?;
    d.set_item("params", keep(&r.params))?;
    d.set_item("std_err", keep(&r.std_err))?;
    d.set_item("outputs", compat::OUTPUT_NAMES.to_vec())?;
    d.set_item("rms_before", r.rms_before)?;
    d.set_item("rms_after", r.rms_after)?;
    d.set_item("iterations", r.iterations)?;
    d.set_item("converged", r.converged)?;
    Ok(d)
}

/// Unit and sign plausibility of a campaign (`aero_core::preprocess::plausibility`): channels
/// back to back (SI, rad), `offsets` the maneuver boundaries, `candidates` one list of
/// ratios per check (order of `plausibility::CHECKS`), `vane_offset` vane minus CG alpha, beta. Returns one dict per check:
/// `channel`, `k`, `se`, `blocks`, `verdict` ("plausible", "not_judged", "mistake", "far"),
/// `candidate` (index or None), and per maneuver `k_m`, `se_m`, `verdict_m`, `candidate_m`.
#[pyfunction]
#[pyo3(signature = (offsets, t, accel, rates, tas, alpha, beta, euler, vane_offset, h, candidates))]
#[allow(clippy::too_many_arguments)]
fn plausibility_check<'py>(
    py: Python<'py>,
    offsets: Vec<usize>,
    t: PyReadonlyArray1<'py, f64>,
    accel: Vec<PyReadonlyArray1<'py, f64>>,
    rates: Vec<PyReadonlyArray1<'py, f64>>,
    tas: PyReadonlyArray1<'py, f64>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
    euler: Vec<PyReadonlyArray1<'py, f64>>,
    vane_offset: Vec<PyReadonlyArray1<'py, f64>>,
    h: Option<PyReadonlyArray1<'py, f64>>,
    candidates: Vec<Vec<f64>>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let (a, w, e) = (slices(&accel)?, slices(&rates)?, slices(&euler)?);
    let vo = slices(&vane_offset)?;
    let nc = plausibility::CHECKS.len();
    if a.len() != 3 || w.len() != 3 || e.len() != 2 || vo.len() != 2 || candidates.len() != nc {
        return Err(crate::error::to_py(AeroError::invalid(
            "plausibility_check",
            format!(
                "accel and rates take three arrays, euler and vane_offset two, candidates {nc} lists"
            ),
        )));
    }
    let hs = match &h {
        Some(x) => Some(x.as_slice()?),
        None => None,
    };
    let inp = plausibility::PlausInput {
        offsets: &offsets,
        t: t.as_slice()?,
        accel: [a[0], a[1], a[2]],
        rates: [w[0], w[1], w[2]],
        tas: tas.as_slice()?,
        alpha: alpha.as_slice()?,
        beta: beta.as_slice()?,
        euler: [e[0], e[1]],
        vane_offset: [vo[0], vo[1]],
        h: hs,
    };
    let cands: [&[f64]; 7] = std::array::from_fn(|i| candidates[i].as_slice());
    let res = detached(py, || plausibility::check(&inp, &cands))?;
    let word = |v: plausibility::Verdict| -> (&'static str, Option<usize>) {
        match v {
            plausibility::Verdict::Plausible => ("plausible", None),
            plausibility::Verdict::NotJudged => ("not_judged", None),
            plausibility::Verdict::Mistake(j) => ("mistake", Some(j)),
            plausibility::Verdict::Far => ("far", None),
        }
    };
    res.into_iter()
        .map(|r| {
            let d = PyDict::new(py);
            d.set_item("channel", r.channel)?;
            d.set_item("k", r.k)?;
            d.set_item("se", r.se)?;
            d.set_item("blocks", r.blocks)?;
            let (v, c) = word(r.verdict);
            d.set_item("verdict", v)?;
            d.set_item("candidate", c)?;
            let km: Vec<f64> = r.per_maneuver.iter().map(|x| x.0).collect();
            let sm: Vec<f64> = r.per_maneuver.iter().map(|x| x.1).collect();
            let (vm, cm): (Vec<&str>, Vec<Option<usize>>) =
                r.per_maneuver.iter().map(|x| word(x.2)).unzip();
            d.set_item("k_m", km)?;
            d.set_item("se_m", sm)?;
            d.set_item("verdict_m", vm)?;
            d.set_item("candidate_m", cm)?;
            Ok(d)
        })
        .collect()
}

/// A model's coefficients seen through the smoother of their measurement's channel
/// (`aero_core::preprocess::matched::through_smoother`): per `(reference, target)` the
/// filtered target, and the counts `(matched, unsmoothed, changed, nonfinite)`.
#[pyfunction]
#[pyo3(signature = (t, maneuver, check_raw, check_smoothed, scale, channels))]
#[allow(clippy::type_complexity)]
fn through_smoother<'py>(
    py: Python<'py>,
    t: PyReadonlyArray1<'py, f64>,
    maneuver: PyReadonlyArray1<'py, u64>,
    check_raw: PyReadonlyArray1<'py, f64>,
    check_smoothed: PyReadonlyArray1<'py, f64>,
    scale: PyReadonlyArray1<'py, f64>,
    channels: Vec<(PyReadonlyArray1<'py, f64>, PyReadonlyArray1<'py, f64>)>,
) -> PyResult<(Vec<Arr<'py>>, (usize, usize, usize, usize))> {
    let (t, man, raw, smoothed, scale) = (
        slice("t", &t)?,
        slice("maneuver", &maneuver)?,
        slice("check_raw", &check_raw)?,
        slice("check_smoothed", &check_smoothed)?,
        slice("scale", &scale)?,
    );
    let mut chans = Vec::with_capacity(channels.len());
    for (r, x) in &channels {
        chans.push(matched::Channel {
            reference: slice("reference", r)?,
            target: slice("target", x)?,
        });
    }
    let (out, rep) = detached(py, || {
        matched::through_smoother(t, man, raw, smoothed, scale, &chans)
    })?;
    Ok((
        out.into_iter().map(|v| v.into_pyarray(py)).collect(),
        (rep.matched, rep.unsmoothed, rep.changed, rep.nonfinite),
    ))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(smooth, m)?)?;
    m.add_function(wrap_pyfunction!(smooth_deriv, m)?)?;
    m.add_function(wrap_pyfunction!(local_poly_deriv, m)?)?;
    m.add_function(wrap_pyfunction!(accel_to_cg, m)?)?;
    m.add_function(wrap_pyfunction!(vanes_to_cg, m)?)?;
    m.add_function(wrap_pyfunction!(preprocess_columns, m)?)?;
    m.add_function(wrap_pyfunction!(preprocess_batch, m)?)?;
    m.add_function(wrap_pyfunction!(compat_check, m)?)?;
    m.add_function(wrap_pyfunction!(plausibility_check, m)?)?;
    m.add_function(wrap_pyfunction!(through_smoother, m)?)?;
    Ok(())
}
