//! Deterministic workload for `valgrind --tool=callgrind` instruction counts:
//! `perf_probe table N` (4-D batch lookup of N points) or
//! `perf_probe ols N` (N x 12 OLS with coloured-residual standard errors) or
//! `perf_probe sim N` (N replays of the 60 s stall of `benchmarks/bench_sim.py`).
use aero_core::lsq::{ols, OlsOptions};
use aero_core::table::{Axis, Table};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let what = args.get(1).map_or("table", String::as_str);
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    match what {
        "table" => {
            let axes = vec![
                Axis::new(
                    "alpha",
                    (0..30).map(|i| -10.0 + i as f64 * 45.0 / 29.0).collect(),
                )
                .expect("axis"),
                Axis::new("beta", (0..13).map(|i| -30.0 + i as f64 * 5.0).collect()).expect("axis"),
                Axis::new("flap", vec![0.0, 5.0, 10.0, 15.0, 35.0]).expect("axis"),
                Axis::new("da", (0..9).map(|i| -20.0 + i as f64 * 5.0).collect()).expect("axis"),
            ];
            let nv: usize = 30 * 13 * 5 * 9;
            let values = (0..nv).map(|i| ((i * 7919) % 1000) as f64 * 1e-3).collect();
            let t = Table::new(axes, values).expect("table");
            let lo = [-10.0, -30.0, 0.0, -20.0];
            let span = [45.0, 60.0, 35.0, 40.0];
            let cols: Vec<Vec<f64>> = (0..4)
                .map(|k| {
                    (0..n)
                        .map(|i| {
                            lo[k] + span[k] * (((i * (2 * k + 7919)) % 10007) as f64 / 10007.0)
                        })
                        .collect()
                })
                .collect();
            let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
            let mut out = vec![0.0; n];
            t.eval_columns(&refs, &mut out).expect("eval");
            println!("{}", out.iter().sum::<f64>());
        }
        "sim" => {
            use aero_core::aircraft::truth::EffectSpec;
            use aero_core::sim::campaign::{replay_adx37, trim_adx37};
            let (x0, c0, ct0) = trim_adx37(0.0, 75.0, 3000.0).expect("trim");
            let steps = 6000;
            let controls: Vec<[f64; 5]> = (0..steps)
                .map(|i| {
                    let t = i as f64 * 0.01;
                    let mut c = c0;
                    c[1] += if t < 40.0 {
                        -0.25 * t
                    } else {
                        -10.0 + (t - 40.0)
                    };
                    c
                })
                .collect();
            let ct = vec![[ct0, ct0]; steps];
            let effects: Vec<EffectSpec> = [
                "aileron_effectiveness",
                "roll_damping",
                "dihedral",
                "directional_stability",
                "rudder_effectiveness",
                "lateral_asymmetry",
            ]
            .iter()
            .map(|n| EffectSpec {
                name: (*n).to_string(),
                magnitude: 1.0,
                shape: None,
            })
            .collect();
            let mut acc = 0.0;
            for _ in 0..n.min(1000) {
                let s =
                    replay_adx37(0.0, &effects, Some(1), x0, 0.01, &controls, &ct).expect("replay");
                acc += s.iter().map(|x| x[0] + x[5]).sum::<f64>();
            }
            println!("{acc:.17e}");
        }
        _ => {
            let p = 12;
            let x: Vec<f64> = (0..n * p)
                .map(|ij| {
                    if ij % p == 0 {
                        1.0
                    } else {
                        (((ij * 7919) % 10007) as f64 / 10007.0) - 0.5
                    }
                })
                .collect();
            let mut e = 0.0;
            let z: Vec<f64> = (0..n)
                .map(|i| {
                    e = 0.8 * e + (((i * 104729) % 10007) as f64 / 10007.0 - 0.5) * 0.1;
                    (0..p).map(|j| x[i * p + j] * (j as f64 + 1.0)).sum::<f64>() + e
                })
                .collect();
            let fit = ols(&x, n, p, &z, &OlsOptions::default()).expect("ols");
            println!("{:?}", fit.std_err_colored);
        }
    }
}
