//! Embedding the aerodelta 6-DOF loop in a real-time simulator with a custom
//! aerodynamic model: a simulator implements `AeroModel`, trims, then calls
//! `Simulator::step` at 100 Hz (no allocation, no threads in the loop).
//!
//! Run: `cargo run --release -p aero_core --example embed_sim`

use aero_core::aircraft::turboprop::adx37;
use aero_core::sim::aero::{AeroCoeffs, AeroInput, AeroModel, Controls};
use aero_core::sim::eom::{ix, StateVec};
use aero_core::sim::maneuver::{trim, Simulator};

/// A user's linear stability-derivative model (per rad), valid below stall.
#[derive(Debug)]
struct LinearAero;

impl AeroModel for LinearAero {
    fn coefficients(&self, s: &AeroInput) -> AeroCoeffs {
        let a = s.alpha;
        let c = &s.controls;
        let cl_lift = 0.25 + 5.2 * a + 0.35 * c.de + 6.0 * s.q_hat;
        let cd = 0.027 + 0.032 * cl_lift * cl_lift;
        let (cx, cz) = AeroCoeffs::from_lift_drag(cl_lift, cd, a, s.ct_sum());
        AeroCoeffs {
            cx,
            cz,
            cy: -0.78 * s.beta + 0.27 * c.dr,
            cl: -0.095 * s.beta - 0.5 * s.p_hat + 0.15 * s.r_hat - 0.16 * c.da,
            cm: 0.06 - 0.75 * a - 2.0 * c.de - 25.0 * s.q_hat - 0.19 * s.ct_sum(),
            cn: 0.115 * s.beta - 0.16 * s.r_hat - 0.105 * c.dr + 0.012 * c.da,
        }
    }
}

fn main() -> Result<(), aero_core::AeroError> {
    let mut model = LinearAero;
    let mut sim = Simulator::new(adx37(), 0.0, StateVec::zeros(), 0.01);
    let tr = trim(&sim, &model, 90.0, 3000.0)?;
    sim.x = tr.x;
    let thrust = [tr.thrust_n; 2];
    println!(
        "trim: alpha {:.2} deg, elevator {:.2} deg, thrust {:.0} N per engine",
        tr.x[ix::THETA].to_degrees(),
        tr.controls.de.to_degrees(),
        tr.thrust_n
    );
    let t0 = std::time::Instant::now();
    for k in 0..6000 {
        // the host simulator's controls: an aileron doublet at 10 s
        let da = match k {
            1000..=1099 => 5f64.to_radians(),
            1100..=1199 => -5f64.to_radians(),
            _ => 0.0,
        };
        let c = Controls { da, ..tr.controls };
        sim.step(&mut model, &c, thrust);
        if k % 1000 == 999 {
            println!(
                "t {:5.1} s  V {:5.1} m/s  phi {:6.2} deg  h {:7.1} m",
                sim.t,
                sim.air(&sim.x).tas,
                sim.x[ix::PHI].to_degrees(),
                sim.x[ix::H]
            );
        }
    }
    let el = t0.elapsed().as_secs_f64();
    println!(
        "60 s simulated in {:.2} ms ({:.0}x real time)",
        el * 1e3,
        60.0 / el
    );
    Ok(())
}
