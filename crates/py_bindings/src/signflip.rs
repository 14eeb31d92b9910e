//! Sign-flip randomization counts (`aero_core::signflip`). Conversion only.
use aero_core::signflip::{flip_hits, flip_hits_many, FlipJob, FlipOptions, Pcg64};
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;

use crate::util::detached;

/// `(hits, draws)`: sign draws with `sum(s * weights) >= w`, the signs those of numpy's
/// `integers(0, 2, size=(k, n), dtype=np.int8) * 2 - 1` from the PCG64 at `state`, `inc`
/// (`Generator.bit_generator.state["state"]`), `per_call` draws per call; `draws` first, then
/// `draws * tail` in all when fewer than `min_hits` reached `w`.
#[pyfunction]
#[pyo3(signature = (weights, w, state, inc, draws, per_call, tail, min_hits))]
#[allow(clippy::too_many_arguments)]
fn sign_flip_hits(
    py: Python<'_>,
    weights: PyReadonlyArray1<'_, f64>,
    w: f64,
    state: u128,
    inc: u128,
    draws: usize,
    per_call: usize,
    tail: usize,
    min_hits: u64,
) -> PyResult<(u64, u64)> {
    let weights = weights.as_slice()?.to_vec();
    let opts = FlipOptions {
        draws,
        per_call,
        tail,
        min_hits,
    };
    detached(py, || {
        Ok(flip_hits(&weights, w, Pcg64::new(state, inc), &opts))
    })
}

/// [`sign_flip_hits`] of many tests at once (`weights[i]`, `ws[i]`, `states[i]`, `incs[i]`),
/// run in parallel; the same counts as one call each.
#[pyfunction]
#[pyo3(signature = (weights, ws, states, incs, draws, per_call, tail, min_hits))]
#[allow(clippy::too_many_arguments)]
fn sign_flip_hits_many(
    py: Python<'_>,
    weights: Vec<PyReadonlyArray1<'_, f64>>,
    ws: Vec<f64>,
    states: Vec<u128>,
    incs: Vec<u128>,
    draws: usize,
    per_call: usize,
    tail: usize,
    min_hits: u64,
) -> PyResult<Vec<(u64, u64)>> {
    let n = weights.len();
    if ws.len() != n || states.len() != n || incs.len() != n {
        return Err(crate::error::to_py(aero_core::AeroError::invalid(
            "sign_flip_hits_many",
            format!(
                "{n} weight vectors but {} statistics, {} states and {} increments",
                ws.len(),
                states.len(),
                incs.len()
            ),
        )));
    }
    let mut jobs = Vec::with_capacity(n);
    for (((wt, w), st), inc) in weights.iter().zip(ws).zip(states).zip(incs) {
        jobs.push(FlipJob {
            weights: wt.as_slice()?.to_vec(),
            w,
            rng: Pcg64::new(st, inc),
        });
    }
    let opts = FlipOptions {
        draws,
        per_call,
        tail,
        min_hits,
    };
    detached(py, || Ok(flip_hits_many(&jobs, &opts)))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sign_flip_hits, m)?)?;
    m.add_function(wrap_pyfunction!(sign_flip_hits_many, m)?)?;
    Ok(())
}
