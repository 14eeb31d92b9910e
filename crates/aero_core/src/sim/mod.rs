//! The 6-DOF simulator (thesis Section 3.1.1, Eq. 3.1) and the virtual flight
//! test built on it. One concept per module:
//! - [`atmosphere`]: ISA to 20 km;
//! - [`eom`]: rigid-body equations of motion, RK4;
//! - [`mass`]: per-maneuver mass, CG and inertia, and the moment transfer from the datum to the CG;
//! - [`aero`]: the [`aero::AeroModel`] trait any aerodynamic model implements;
//! - [`extended`]: a base model plus a fitted Δ model in the loop (thesis Section 4.3);
//! - [`dave_aero`]: a DAVE-ML model as the loop's aerodynamics (the user's own simulator);
//! - [`engine`], [`actuator`]: turboprop and control-surface actuators;
//! - [`turbulence`]: Dryden gusts (MIL-F-8785C);
//! - [`pilot`]: the pilot model and stick pusher flying the stall maneuvers of Section 3.2.1;
//! - [`sensors`]: flight-test instrumentation (positions, noise, biases, lags);
//! - [`maneuver`]: the simulation loop of one maneuver, and replay of recorded controls;
//! - [`campaign`]: a deterministic campaign of maneuvers;
//! - [`closed_loop`]: closed-loop replay of a recorded stall maneuver (objective stall tests);
//! - [`rng`]: seeded portable random streams.

pub mod actuator;
pub mod aero;
pub mod atmosphere;
pub mod campaign;
pub mod closed_loop;
pub mod dave_aero;
pub mod engine;
pub mod eom;
pub mod extended;
pub mod maneuver;
pub mod mass;
pub mod pilot;
pub mod rng;
pub mod sensors;
pub mod turbulence;

/// `y` at time `tq` by linear interpolation in `t` (increasing, at least one sample), the end
/// values held outside `[t_0, t_{n-1}]`.
pub(crate) fn interp_held(t: &[f64], y: &[f64], tq: f64) -> f64 {
    let n = t.len();
    if n < 2 || tq <= t[0] {
        return y[0];
    }
    if tq >= t[n - 1] {
        return y[n - 1];
    }
    let j = (t.partition_point(|&x| x <= tq) - 1).min(n - 2);
    let f = (tq - t[j]) / (t[j + 1] - t[j]);
    y[j] + f * (y[j + 1] - y[j])
}
