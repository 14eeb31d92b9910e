//! A simulator loading the fitted Δ model and evaluating it every frame.
//!
//! ```text
//! cargo run --release -p aero_core --example extended_model -- out/demo/model.json
//! ```
//! (`bash scripts/demo.sh` or `aerodelta fit ... --out model.json` writes the model.) The model
//! is bound once to the simulator's state layout; each frame then costs a few table lookups
//! and no allocation. The simulator adds the blended corrections `w ΔC` to its qualified
//! coefficients (thesis Eq. 3.12). Channels the model derives from others (`ct_diff =
//! ct_left - ct_right`, `ds_deg = dsr_deg - dsl_deg`, as the ingestion does) are computed by
//! the simulator before the call. At the end the frame path is checked against the batch
//! path ([`DeltaModel::eval_columns`]) on the last few hundred frames.
use std::path::Path;
use std::time::Instant;

use aero_core::delta_model::DeltaModel;

/// A slow approach to stall and back with sideslip, rate and control activity, flaps
/// stepping through the settings and between them: channel -> value at time `t` (s).
fn maneuver(name: &str, t: f64) -> f64 {
    match name {
        "alpha_deg" => 4.0 + 16.0 * (0.5 - 0.5 * (t * 0.05).cos()),
        "flap_deg" => [0.0, 5.0, 7.5, 10.0, 15.0, 25.0, 35.0][((t / 90.0) as usize) % 7],
        "beta_deg" => 6.0 * (t * 0.7).sin(),
        "phat" => 0.03 * (t * 1.3).sin(),
        "rhat" => 0.02 * (t * 0.9).cos(),
        "qhat" => 0.005 * (t * 0.4).sin(),
        "da_deg" => 10.0 * (t * 0.5).sin(),
        "dr_deg" => 8.0 * (t * 0.3).cos(),
        "ct_left" => 0.25,
        "ct_right" => 0.15 + 0.1 * (t * 0.05).sin(),
        "dsr_deg" => (20.0 * (t * 0.2).sin()).max(0.0),
        "dsl_deg" => (-20.0 * (t * 0.2).sin()).max(0.0),
        "alphadot_dps" => 16.0 * 0.025 * (t * 0.05).sin(),
        "betadot_dps" => 4.2 * (t * 0.7).cos(),
        _ => 0.0,
    }
}

/// One frame's state in `layout` order, derived channels included.
fn fill_state(layout: &[&str], t: f64, state: &mut [f64]) {
    for (s, name) in state.iter_mut().zip(layout) {
        *s = match *name {
            "ct_diff" => maneuver("ct_left", t) - maneuver("ct_right", t),
            "ds_deg" => maneuver("dsr_deg", t) - maneuver("dsl_deg", t),
            n => maneuver(n, t),
        };
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "out/demo/model.json".to_string());
    let model = DeltaModel::load(Path::new(&path))?;
    // The simulator's state vector: the model's input channels in an order of its choosing.
    let layout_owned = model.input_columns();
    let layout: Vec<&str> = layout_owned.iter().map(String::as_str).collect();
    let bound = model.bind(&layout)?;
    let names = model.coefficient_names();
    println!("model {path}: coefficients {names:?}, inputs {layout:?}");

    let mut state = vec![0.0; layout.len()];
    let mut out = vec![0.0; names.len()];
    let rate = 100.0;
    let frames = 100 * 60 * 10; // ten minutes at 100 Hz
    let t0 = Instant::now();
    let mut peak = vec![0.0f64; names.len()];
    for k in 0..frames {
        fill_state(&layout, k as f64 / rate, &mut state);
        bound.eval(&state, &mut out);
        for (p, o) in peak.iter_mut().zip(&out) {
            *p = p.max(o.abs());
        }
    }
    let per = t0.elapsed().as_secs_f64() / frames as f64;
    println!(
        "{frames} frames, {:.0} ns per frame; peak |w dC|: {peak:?}",
        per * 1e9
    );

    // The frame path equals the batch path (same tables, same blend, Eq. 3.12).
    let n = 500;
    let mut cols = vec![vec![0.0; n]; layout.len()];
    let mut frame_out = vec![vec![0.0; n]; names.len()];
    for i in 0..n {
        fill_state(&layout, (frames - n + i) as f64 / rate, &mut state);
        for (c, v) in cols.iter_mut().zip(&state) {
            c[i] = *v;
        }
        bound.eval(&state, &mut out);
        for (f, o) in frame_out.iter_mut().zip(&out) {
            f[i] = *o;
        }
    }
    let lookup = |name: &str| -> Option<&[f64]> {
        layout
            .iter()
            .position(|l| *l == name)
            .map(|j| cols[j].as_slice())
    };
    let mut worst = 0.0f64;
    for (c, f) in names.iter().zip(&frame_out) {
        let (delta, weight, _) = model.eval_columns(c, &lookup, n)?;
        for ((d, w), v) in delta.iter().zip(&weight).zip(f) {
            worst = worst.max((w * d - v).abs());
        }
    }
    println!("frame path vs batch path over {n} frames: largest |difference| {worst:.1e}");
    if worst > 1e-12 {
        return Err(format!("frame and batch paths differ by {worst}").into());
    }
    Ok(())
}
