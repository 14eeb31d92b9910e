//! A simulator loading the fitted Δ model and evaluating it every frame.
//!
//! ```text
//! cargo run --release -p aero_core --example extended_model -- out/demo/model.json
//! ```
//! (`bash scripts/demo.sh` writes `out/demo/model.json`.) The model is bound once to the
//! simulator's state layout; each frame then costs a few table lookups and no allocation.
use std::path::Path;
use std::time::Instant;

use aero_core::delta_model::DeltaModel;

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
    let idx = |name: &str| layout.iter().position(|l| *l == name);
    let (ia, iflap) = (idx("alpha_deg"), idx("flap_deg"));
    let frames = 100 * 60 * 10; // ten minutes at 100 Hz
    let t0 = Instant::now();
    let mut peak = vec![0.0f64; names.len()];
    for k in 0..frames {
        let t = k as f64 / 100.0;
        // a slow approach to stall and back, flaps 10
        if let Some(i) = ia {
            state[i] = 4.0 + 14.0 * (0.5 - 0.5 * (t * 0.05).cos());
        }
        if let Some(i) = iflap {
            state[i] = 10.0;
        }
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
    Ok(())
}
