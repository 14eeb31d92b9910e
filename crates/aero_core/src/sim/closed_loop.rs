//! Closed-loop replay of a recorded stall maneuver (14 CFR Part 60 Table A1A objective stall
//! tests: stall-warning, buffet-onset and stall speeds within ±3 kt; `docs/evidence.md`).
//!
//! An open-loop replay of recorded controls ([`crate::sim::campaign::replay_adx37_extended`])
//! drifts off the record within seconds once the model differs from the aircraft, and it
//! cannot say at which speed the *simulator* would warn, buffet or stall. Here a pilot flies
//! the maneuver again on the simulator, entering it as the aircraft was flown, and the
//! simulator's own warning, pusher and buffet logic act:
//!
//! - **Entry** (until the simulator shows a stall cue): the pilot tracks the recorded
//!   equivalent-airspeed history (the entry's deceleration, smoothed over [`SPEED_SMOOTH_S`])
//!   with the elevator: the recorded elevator as feed-forward (a trailing mean, so no later push
//!   leaks in), a proportional-integral loop on alpha with pitch-rate damping around
//!   α_ref = α_rec(t) + α_c (α_rec smoothed over [`TRACK_SMOOTH_S`]: the record's gust
//!   responses are not replayed into calm air), and an outer loop that sets α_c from the
//!   airspeed error and its rate. A model that needs less alpha for the same speed gets α_c < 0
//!   and reaches the warning, buffet and stall alphas later, at lower speeds: the differences
//!   the objective test measures. Ailerons and rudder add to the recorded deflections a bank
//!   (PD) and sideslip (P, yaw-rate damping) hold on the recorded bank and sideslip; spoilers
//!   are the recorded ones; each engine gives the recorded thrust (`C_T q̄ S` of the record).
//!   Past the record's stall identification (`t_id_s`) the recorded values are held at it, the
//!   speed loop's correction is held, and the pilot goes on pulling at the test pilot's alpha
//!   rate into the identification (the recorded mean alpha rate from [`PULL_WINDOW_S`] before
//!   it to the peak, at least [`MIN_PULL_DPS`]) from where the reference was: a model that
//!   stalls later than the aircraft is flown on into its own stall, not stopped at the
//!   aircraft's. (Continuing the entry's *deceleration* instead, as the first version did,
//!   unloaded accelerated entries: at 5-8 kt/s the reference's rate jumps at the
//!   identification, the speed loop's rate term kicks alpha down by degrees, and the aircraft
//!   flew on 20-27 kt below the record's stall.)
//! - **Stall cues**: the simulator's pusher (fired at the aircraft's activation alpha), a
//!   g-break (lift lost at no lower alpha with the warning on: the load factor per unit
//!   dynamic pressure, `n / q̄` ∝ C_L, below its maximum of the last [`G_BREAK_WINDOW_S`] by
//!   [`G_BREAK_DN`] at the current `q̄`, as `aerodelta.stall` reads the records; a decelerating
//!   turn's load factor falls with `q̄` at constant C_L, which is no break), a deterrent buffet
//!   (the simulator's buffet schedule at the given level), or [`MAX_EXTEND_S`] past the
//!   record's identification.
//! - **Recovery**: [`REACTION_S`] after the pusher (the pilot lets it push; unless the record
//!   says the pilot resisted it, when the pilot flies on against the push), or, after a g-break
//!   or buffet, once the pilot has pulled on (at the record's alpha rate into its peak, at least
//!   [`MIN_PULL_DPS`]) for as long as the test pilot went past the identification to the peak
//!   alpha (at least [`MIN_DEPTH_S`]); then alpha 4 deg, wings level, the record's highest
//!   thrust, for [`RECOVERY_S`].
//!
//! The run yields the channels the stall identification reads (`aerodelta.stall`): the same
//! code then finds the simulator's warning onset (the records' warning rule: the vane alpha
//! against the aircraft's threshold, with its hysteresis), buffet onset (the simulator's buffet
//! model at the accelerometer, with white noise at the record's floor) and stall
//! identification. Calm air; no roll-off; nominal mass.

use nalgebra::{SVector, Vector3};

use crate::aircraft::qualified::FLAP_STALL;
use crate::aircraft::truth::{active_effects, EffectSpec, KirchhoffStall, TruthAero};
use crate::aircraft::turboprop::{adx37, AircraftRef};
use crate::buffet::{Buffet, BuffetSchedule, BuffetSpec};
use crate::delta_model::DeltaModel;
use crate::error::{AeroError, Result};
use crate::kirchhoff::KirchhoffDrag;
use crate::sim::actuator::Actuator;
use crate::sim::aero::{AeroModel, Controls};
use crate::sim::atmosphere::G0;
use crate::sim::campaign::{actuators, adx37_models, slice};
use crate::sim::eom::ix;
use crate::sim::extended::ExtendedAero;
use crate::sim::maneuver::Simulator;
use crate::sim::pilot::Pusher;
use crate::sim::rng::Stream;
use crate::sim::sensors::stall_warning;
use crate::stall_form::StallParams;

/// Record columns the replay reads, in this order (units in the names; controls Etkin).
pub const RECORD_COLUMNS: [&str; 16] = [
    "t",
    "alpha_deg",
    "beta_deg",
    "p_dps",
    "q_dps",
    "r_dps",
    "phi_deg",
    "tas_mps",
    "rho_kgm3",
    "da_deg",
    "de_deg",
    "dr_deg",
    "dsl_deg",
    "dsr_deg",
    "ct_left",
    "ct_right",
];

/// Channels of the simulated time history, at the record's rate: time (s), CG alpha and the
/// alpha the vane reads (deg), sideslip, bank, pitch attitude (deg), pitch rate (deg/s), acting
/// elevator (deg), true airspeed (m/s), density (kg/m³), normal specific force at the CG and
/// at the accelerometer with the buffet and noise (m/s²), the pusher and warning discretes,
/// and the pilot's alpha reference (deg).
pub const OUTPUT_COLUMNS: [&str; 15] = [
    "t",
    "alpha_cg_deg",
    "alpha_deg",
    "beta_deg",
    "phi_deg",
    "theta_deg",
    "q_dps",
    "de_deg",
    "tas_mps",
    "rho_kgm3",
    "az_cg_mps2",
    "az_mps2",
    "pusher_active",
    "stall_warning",
    "alpha_ref_deg",
];

/// Smoothing of the recorded airspeed the pilot tracks (centred moving average), s.
pub const SPEED_SMOOTH_S: f64 = 2.0;
/// Smoothing of the recorded alpha and pitch rate the pilot follows (centred moving average),
/// s; the elevator's feed-forward is a trailing mean over twice that (no later push leaks
/// into it): the record's gust responses and noise are not replayed into calm air.
pub const TRACK_SMOOTH_S: f64 = 0.6;
/// Time constant of the low-pass on the simulator's airspeed rate in the speed loop, s.
const RATE_TAU_S: f64 = 1.0;
/// Longest the pilot keeps pulling past the record's identification without a stall cue, s.
pub const MAX_EXTEND_S: f64 = 15.0;
/// Window before the record's stall identification over which the test pilot's pull (mean
/// alpha rate to the peak alpha, flown on past the identification and past a stall cue) is
/// measured, s.
pub const PULL_WINDOW_S: f64 = 2.0;
/// Least pull past the record's identification and past a stall cue, deg/s.
pub const MIN_PULL_DPS: f64 = 0.5;
/// Least time the pilot pulls on past a g-break or deterrent buffet before recovering, s.
pub const MIN_DEPTH_S: f64 = 0.3;
/// Pilot reaction from recognition to recovery input, s.
pub const REACTION_S: f64 = 0.3;
/// Simulated time after recognition, s (the recovery takes alpha out of the stall).
pub const RECOVERY_S: f64 = 4.0;
/// Load-factor loss of the online g-break at the current dynamic pressure, g (as
/// `aerodelta.stall.G_BREAK_DN`).
pub const G_BREAK_DN: f64 = 0.1;
/// Look-back of the online g-break, s (as `aerodelta.stall.G_BREAK_WINDOW_S`).
pub const G_BREAK_WINDOW_S: f64 = 2.0;
/// Recovery alpha, deg.
const RECOVERY_ALPHA_DEG: f64 = 4.0;

// speed loop: α_c = K_V e + K_D ė + K_I ∫e (rad, e in m/s); the phugoid-like response of speed
// to alpha is about V̈ ≈ −6 m/s³ per rad at these speeds, so K_V, K_D give ω ≈ 0.3 rad/s, ζ ≈ 0.7
const K_V: f64 = 0.01;
const K_D: f64 = 0.05;
const K_I: f64 = 0.001;
const ALPHA_C_MAX: f64 = 0.2; // rad
                              // alpha loop (the campaign pilot's nominal gains, rad per rad and per rad/s)
const K_A: f64 = 0.9;
const K_AI: f64 = 0.6;
const K_Q: f64 = 0.3;

/// Options of a closed-loop replay (JSON keys as the field names; absent: default).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClosedLoopOptions {
    /// Flap setting, deg (one of the ADX-37's five).
    pub flap_deg: f64,
    /// The aircraft's stall-warning threshold on the alpha vane, deg (None: no warning).
    pub warning_alpha_deg: Option<f64>,
    /// Hysteresis of the warning, deg.
    pub warning_hysteresis_deg: f64,
    /// The aircraft's pusher activation alpha at the CG, deg (None: no pusher).
    pub pusher_alpha_deg: Option<f64>,
    /// The pilot resisted the pusher in the record (keeps the entry law against the push).
    pub resist_pusher: bool,
    /// Time of the record's stall identification (its peak alpha when none), s: the end of
    /// the entry.
    pub t_id_s: f64,
    /// Time of the record's peak alpha (the test pilot's deepest point), s.
    pub t_peak_s: f64,
    /// Normal-axis buffet RMS the pilot recognises as a deterrent buffet, m/s² (None: not a
    /// recognition cue).
    pub deterrent_buffet_rms_mps2: Option<f64>,
    /// The simulator's buffet model (None: no buffet).
    pub buffet: Option<BuffetSpec>,
    /// White noise added to the accelerometer's normal channel, m/s² (the record's floor).
    pub az_noise_mps2: f64,
    /// Seed of the buffet and noise draws.
    pub seed: u64,
    /// Simulation rate, Hz (a multiple of the record rate).
    pub sim_hz: f64,
}

impl Default for ClosedLoopOptions {
    fn default() -> Self {
        ClosedLoopOptions {
            flap_deg: 0.0,
            warning_alpha_deg: None,
            warning_hysteresis_deg: crate::sim::sensors::STALL_WARNING_HYSTERESIS_DEG,
            pusher_alpha_deg: None,
            resist_pusher: false,
            t_id_s: f64::NAN,
            t_peak_s: f64::NAN,
            deterrent_buffet_rms_mps2: None,
            buffet: None,
            az_noise_mps2: 0.0,
            seed: 0,
            sim_hz: 100.0,
        }
    }
}

impl ClosedLoopOptions {
    /// Parse options from JSON.
    ///
    /// # Errors
    /// [`AeroError::Parse`] naming the problem.
    pub fn from_json(text: &str) -> Result<Self> {
        serde_json::from_str(text)
            .map_err(|e| AeroError::parse("closed-loop options (JSON)", e.line(), e.to_string()))
    }
}

/// The simulated time history of one closed-loop replay.
#[derive(Debug, Clone)]
pub struct ClosedLoopRun {
    /// Columns in [`OUTPUT_COLUMNS`] order.
    pub columns: Vec<Vec<f64>>,
    /// Time the pilot recognised the stall, s (None: it never did within the run).
    pub recognised_at_s: Option<f64>,
    /// What made the pilot recognise it: `pusher`, `g_break` or `time`.
    pub recognised_by: Option<&'static str>,
    /// Time the simulator's pusher fired, s.
    pub pusher_fired_at_s: Option<f64>,
    /// The speed loop's alpha correction at recognition (model minus record), deg.
    pub alpha_correction_deg: f64,
}

impl ClosedLoopRun {
    /// Metadata as JSON.
    pub fn meta_json(&self) -> String {
        serde_json::json!({
            "recognised_at_s": self.recognised_at_s,
            "recognised_by": self.recognised_by,
            "pusher_fired_at_s": self.pusher_fired_at_s,
            "alpha_correction_deg": self.alpha_correction_deg,
        })
        .to_string()
    }
}

/// A record resampled for the pilot: linear interpolation, ends held.
struct Track<'a> {
    t: &'a [f64],
    cols: Vec<Vec<f64>>,
    eas: Vec<f64>,
    eas_rate: Vec<f64>,
    thrust: [Vec<f64>; 2],
}

impl Track<'_> {
    fn at(&self, y: &[f64], tq: f64) -> f64 {
        crate::sim::interp_held(self.t, y, tq)
    }
    fn col(&self, name: &str, tq: f64) -> f64 {
        let k = RECORD_COLUMNS.iter().position(|c| *c == name).unwrap_or(0);
        self.at(&self.cols[k], tq)
    }
}

fn centred_mean(x: &[f64], w: usize) -> Vec<f64> {
    let h = w / 2;
    let mut c = vec![0.0; x.len() + 1];
    for (i, v) in x.iter().enumerate() {
        c[i + 1] = c[i] + v;
    }
    (0..x.len())
        .map(|k| {
            let lo = k.saturating_sub(h);
            let hi = (k + h + 1).min(x.len());
            (c[hi] - c[lo]) / (hi - lo) as f64
        })
        .collect()
}

fn trailing_mean(x: &[f64], w: usize) -> Vec<f64> {
    let mut c = vec![0.0; x.len() + 1];
    for (i, v) in x.iter().enumerate() {
        c[i + 1] = c[i] + v;
    }
    (0..x.len())
        .map(|k| {
            let lo = (k + 1).saturating_sub(w.max(1));
            (c[k + 1] - c[lo]) / (k + 1 - lo) as f64
        })
        .collect()
}

fn check_record(cols: &[Vec<f64>]) -> Result<()> {
    if cols.len() != RECORD_COLUMNS.len() {
        return Err(AeroError::invalid(
            "closed-loop replay",
            format!(
                "the record has {} columns; give {} ({})",
                cols.len(),
                RECORD_COLUMNS.len(),
                RECORD_COLUMNS.join(", ")
            ),
        ));
    }
    let n = cols[0].len();
    if n < 10 {
        return Err(AeroError::invalid(
            "closed-loop replay",
            format!("the record has {n} samples; give at least 10"),
        ));
    }
    for (name, c) in RECORD_COLUMNS.iter().zip(cols) {
        if c.len() != n {
            return Err(AeroError::invalid(
                format!("closed-loop replay, column {name}"),
                format!("{} samples where t has {n}", c.len()),
            ));
        }
        if let Some(k) = c.iter().position(|v| !v.is_finite()) {
            return Err(AeroError::invalid(
                format!("closed-loop replay, column {name}"),
                format!("row {k} is not a finite number; fill or drop it"),
            ));
        }
    }
    let t = &cols[0];
    if let Some(k) = t.windows(2).position(|w| w[1] <= w[0]) {
        return Err(AeroError::invalid(
            "closed-loop replay, column t",
            format!("not increasing at row {}", k + 1),
        ));
    }
    for (k, (&v, &r)) in cols[7].iter().zip(&cols[8]).enumerate() {
        if v <= 1.0 || r <= 0.0 {
            return Err(AeroError::invalid(
                "closed-loop replay, columns tas_mps / rho_kgm3",
                format!("row {k}: airspeed {v} m/s, density {r} kg/m³; both must be positive"),
            ));
        }
    }
    Ok(())
}

/// Fly one closed-loop replay with `model` on `ac` (module docs) from state `x0`.
///
/// # Errors
/// For a malformed record or options, or when the simulation diverges.
pub fn fly_closed_loop<M: AeroModel + ?Sized>(
    model: &mut M,
    ac: &AircraftRef,
    record: &[Vec<f64>],
    x0: [f64; 12],
    opts: &ClosedLoopOptions,
) -> Result<ClosedLoopRun> {
    check_record(record)?;
    if !(opts.sim_hz.is_finite() && opts.sim_hz > 0.0) {
        return Err(AeroError::invalid(
            "closed-loop options sim_hz",
            format!("{}: give a positive rate, e.g. 100", opts.sim_hz),
        ));
    }
    let t = &record[0];
    let n = t.len();
    let dt_rec = (t[n - 1] - t[0]) / (n - 1) as f64;
    let decim = (opts.sim_hz * dt_rec).round().max(1.0) as usize;
    let dt = dt_rec / decim as f64;
    let clamp_t = |v: f64, fallback: f64| {
        if v.is_finite() {
            v.clamp(t[0], t[n - 1])
        } else {
            fallback
        }
    };
    let t_peak = clamp_t(opts.t_peak_s, t[n - 1]);
    let t_id = clamp_t(opts.t_id_s, t_peak).min(t_peak);
    // the recorded EAS (smoothed) and its rate, each engine's thrust, and the alpha, pitch
    // rate (centred means) and elevator (trailing mean: no later push leaks into it) the pilot
    // follows
    let eas_raw: Vec<f64> = record[7]
        .iter()
        .zip(&record[8])
        .map(|(v, r)| v * (r / 1.225).sqrt())
        .collect();
    let eas = centred_mean(&eas_raw, ((SPEED_SMOOTH_S / dt_rec).round() as usize) | 1);
    let eas_rate: Vec<f64> = (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            (eas[b] - eas[a]) / (t[b] - t[a])
        })
        .collect();
    let thrust: [Vec<f64>; 2] = [14, 15].map(|j| {
        (0..n)
            .map(|k| record[j][k] * 0.5 * record[8][k] * record[7][k] * record[7][k] * ac.s_m2)
            .collect()
    });
    let max_thrust = [0, 1].map(|e| thrust[e].iter().fold(0.0f64, |m, v| m.max(*v)));
    let ws = ((TRACK_SMOOTH_S / dt_rec).round() as usize) | 1;
    let smoothed: Vec<Vec<f64>> = record
        .iter()
        .enumerate()
        .map(|(j, c)| match RECORD_COLUMNS[j] {
            "alpha_deg" | "q_dps" => centred_mean(c, ws),
            "de_deg" => trailing_mean(c, 2 * ws),
            _ => c.clone(),
        })
        .collect();
    let tr = Track {
        t,
        cols: smoothed,
        eas,
        eas_rate,
        thrust,
    };
    // the test pilot's pull into and past the identification (recorded mean alpha rate to the
    // peak) and how long it lasted
    let depth = (t_peak - t_id).max(MIN_DEPTH_S);
    let t_pull = (t_id - PULL_WINDOW_S).max(t[0]);
    let pull = if t_peak - t_pull > 0.5 {
        (tr.col("alpha_deg", t_peak) - tr.col("alpha_deg", t_pull)) / (t_peak - t_pull)
    } else {
        0.0
    }
    .max(MIN_PULL_DPS)
    .to_radians();

    let stall = FLAP_STALL
        .iter()
        .find(|f| f.flap_deg == opts.flap_deg)
        .copied()
        .ok_or_else(|| {
            AeroError::invalid(
                "closed-loop options flap_deg",
                format!(
                    "{}: the ADX-37 flies flap 0, 5, 10, 15 or 35 deg",
                    opts.flap_deg
                ),
            )
        })?;
    let mut buffet = opts
        .buffet
        .as_ref()
        .map(|b| {
            let sched = BuffetSchedule::for_alpha_max(b, stall.alpha_max_deg);
            Buffet::new(b, sched, dt_rec, opts.seed, 1)
        })
        .transpose()?;
    let mut noise = Stream::new(opts.seed, 2);

    let mut sim = Simulator::new(ac.clone(), opts.flap_deg, SVector::from(x0), dt);
    sim.t = t[0];
    let d = f64::to_radians;
    let c0 = Controls {
        da: d(record[9][0]),
        de: d(record[10][0]),
        dr: d(record[11][0]),
        dsl: d(record[12][0]),
        dsr: d(record[13][0]),
    };
    let mut acts: [Actuator; 5] = actuators(&c0);
    let mut surfaces = c0;
    let mut pusher = opts.pusher_alpha_deg.map(Pusher::new);
    let r_vane = Vector3::new(ac.alpha_vane_m[0], ac.alpha_vane_m[1], ac.alpha_vane_m[2]);
    let w_n = sim.body.mass * G0;

    let (mut int_v, mut int_a) = (0.0f64, 0.0f64);
    let mut alpha_c = 0.0f64;
    let mut prev_eas: Option<f64> = None;
    let mut eas_rate_lp = 0.0f64;
    let mut recognised: Option<(f64, &'static str)> = None;
    let mut recover_at = f64::INFINITY;
    let mut nz_hist: Vec<(f64, f64, f64)> = Vec::new(); // (t, nz / q̄, alpha deg)
    let mut cols: Vec<Vec<f64>> = (0..OUTPUT_COLUMNS.len()).map(|_| Vec::new()).collect();
    let mut warn_on = false;
    let mut alpha_at_cue = 0.0f64;
    // the entry's last reference before the record's identification, pulled on from there
    let mut alpha_ref_prev = 0.0f64;
    let mut alpha_ref_id: Option<f64> = None;
    let t_stop_max = t_id + MAX_EXTEND_S + depth + REACTION_S + RECOVERY_S;
    let mut step = 0usize;
    loop {
        let tn = sim.t;
        let ad = sim.air(&sim.x);
        let x = sim.x;
        let alpha_deg = ad.alpha.to_degrees();
        let entry = recognised.is_none();
        let recovering = tn >= recover_at;
        // the recorded values the pilot follows: now, up to the record's identification
        let tq = tn.min(t_id);
        let thrust_n = if recovering {
            max_thrust
        } else {
            [tr.at(&tr.thrust[0], tq), tr.at(&tr.thrust[1], tq)]
        };
        // the sample of this instant (surfaces acting now)
        let (_, loads) = sim.derivative(model, &surfaces, thrust_n);
        let nz = -loads.force.z / w_n;
        let va = Vector3::new(x[ix::U], x[ix::V], x[ix::W])
            + Vector3::new(x[ix::P], x[ix::Q], x[ix::R]).cross(&r_vane);
        let alpha_vane = va.z.atan2(va.x).to_degrees();
        if let Some(thr) = opts.warning_alpha_deg {
            if alpha_vane >= thr {
                warn_on = true;
            } else if alpha_vane < thr - opts.warning_hysteresis_deg {
                warn_on = false;
            }
        }
        // the pilot: the speed loop sets the alpha correction up to the record's
        // identification, then holds it
        let eas_sim = ad.tas * (ad.rho / 1.225).sqrt();
        if let Some(p) = prev_eas {
            eas_rate_lp += dt / (RATE_TAU_S + dt) * ((eas_sim - p) / dt - eas_rate_lp);
        }
        prev_eas = Some(eas_sim);
        if entry && tn <= t_id {
            let e = eas_sim - tr.at(&tr.eas, tn);
            let edot = eas_rate_lp - tr.at(&tr.eas_rate, tn);
            int_v = (int_v + e * dt).clamp(-ALPHA_C_MAX / K_I, ALPHA_C_MAX / K_I);
            alpha_c = (K_V * e + K_D * edot + K_I * int_v).clamp(-ALPHA_C_MAX, ALPHA_C_MAX);
        }
        let alpha_ref = match recognised {
            _ if recovering => d(RECOVERY_ALPHA_DEG),
            Some((tc, _)) => alpha_at_cue + pull * (tn - tc),
            None if tn <= t_id => d(tr.col("alpha_deg", tn)) + alpha_c,
            None => *alpha_ref_id.get_or_insert(alpha_ref_prev) + pull * (tn - t_id),
        };
        alpha_ref_prev = alpha_ref;
        let q_ref = if recovering || !entry || tn > t_id {
            0.0
        } else {
            d(tr.col("q_dps", tn))
        };
        let ea = ad.alpha - alpha_ref;
        int_a = (int_a + ea * dt).clamp(-0.3, 0.3);
        let de_ff = d(tr.col("de_deg", tq));
        let de_cmd = de_ff + K_A * ea + K_AI * int_a + K_Q * (x[ix::Q] - q_ref);
        let (phi_ref, p_ref, beta_ref, r_ref) = if recovering {
            (0.0, 0.0, 0.0, 0.0)
        } else if entry {
            (
                d(tr.col("phi_deg", tq)),
                d(tr.col("p_dps", tq)),
                d(tr.col("beta_deg", tq)),
                d(tr.col("r_dps", tq)),
            )
        } else {
            (
                d(tr.col("phi_deg", tq)),
                0.0,
                d(tr.col("beta_deg", tq)),
                0.0,
            )
        };
        let da_ff = if recovering {
            0.0
        } else {
            d(tr.col("da_deg", tq))
        };
        let da_cmd = da_ff + 0.6 * (x[ix::PHI] - phi_ref) + 0.25 * (x[ix::P] - p_ref);
        let dr_cmd =
            d(tr.col("dr_deg", tq)) - 0.8 * (ad.beta - beta_ref) + 0.2 * (x[ix::R] - r_ref);
        let (dsl_cmd, dsr_cmd) = if recovering {
            (0.0, 0.0)
        } else {
            (d(tr.col("dsl_deg", tq)), d(tr.col("dsr_deg", tq)))
        };
        let push = pusher.as_mut().map_or(0.0, |p| p.update(tn, alpha_deg));
        let fired = pusher.as_ref().is_some_and(Pusher::has_fired);
        // recognition: the simulator's stall cues (its pusher, a g-break with the warning on,
        // a deterrent buffet), or the time limit
        if recognised.is_none() && step > 0 {
            // n / q̄ (per Pa): the lift coefficient up to the constant W / S
            let qbar = 0.5 * ad.rho * ad.tas * ad.tas;
            let c_now = nz / qbar;
            nz_hist.push((tn, c_now, alpha_deg));
            let start = nz_hist.partition_point(|h| h.0 < tn - G_BREAK_WINDOW_S);
            let (mut best, mut a_best) = (f64::NEG_INFINITY, 0.0);
            for h in &nz_hist[start..] {
                if h.1 > best {
                    best = h.1;
                    a_best = h.2;
                }
            }
            let warning_ok = opts.warning_alpha_deg.is_none() || warn_on;
            let deterrent = match (&buffet, opts.deterrent_buffet_rms_mps2) {
                (Some(b), Some(level)) => b.schedule().rms_mps2(alpha_deg) >= level,
                _ => false,
            };
            recognised = if fired && !opts.resist_pusher {
                Some((tn, "pusher"))
            } else if warning_ok && (best - c_now) * qbar >= G_BREAK_DN && alpha_deg >= a_best {
                Some((tn, "g_break"))
            } else if deterrent {
                Some((tn, "buffet"))
            } else if tn > t_id + MAX_EXTEND_S {
                Some((tn, "time"))
            } else {
                None
            };
            if let Some((tc, by)) = recognised {
                // recovery: at once after the pusher (or the time limit), else after pulling
                // on as long as the test pilot did past the identification
                alpha_at_cue = alpha_ref;
                recover_at = match by {
                    "g_break" | "buffet" => tc + depth,
                    _ => tc + REACTION_S,
                };
            }
        }
        if step % decim == 0 {
            let [_, bz] = buffet.as_mut().map_or([0.0, 0.0], |b| b.step(alpha_deg));
            let az_cg = loads.force.z / sim.body.mass;
            let row = [
                tn,
                alpha_deg,
                alpha_vane,
                ad.beta.to_degrees(),
                x[ix::PHI].to_degrees(),
                x[ix::THETA].to_degrees(),
                x[ix::Q].to_degrees(),
                surfaces.de.to_degrees(),
                ad.tas,
                ad.rho,
                az_cg,
                az_cg + bz + opts.az_noise_mps2 * noise.normal(),
                if pusher.as_ref().is_some_and(Pusher::is_active) {
                    1.0
                } else {
                    0.0
                },
                if warn_on { 1.0 } else { 0.0 },
                alpha_ref.to_degrees(),
            ];
            for (c, v) in cols.iter_mut().zip(row) {
                c.push(v);
            }
        }
        if tn >= recover_at + RECOVERY_S || tn >= t_stop_max {
            break;
        }
        let next = Controls {
            da: acts[0].advance(da_cmd, dt),
            de: acts[1].advance(de_cmd + push, dt),
            dr: acts[2].advance(dr_cmd, dt),
            dsl: acts[3].advance(dsl_cmd, dt),
            dsr: acts[4].advance(dsr_cmd, dt),
        };
        sim.step_interp(model, &surfaces, &next, thrust_n);
        surfaces = next;
        step += 1;
        if !sim.x.iter().all(|v| v.is_finite()) {
            return Err(AeroError::invalid(
                "closed-loop replay",
                format!("the simulation diverged at t = {:.2} s", sim.t),
            ));
        }
    }
    // the warning discrete with the records' rule on the vane alpha (Schmitt trigger)
    if let Some(thr) = opts.warning_alpha_deg {
        if (opts.warning_hysteresis_deg - crate::sim::sensors::STALL_WARNING_HYSTERESIS_DEG).abs()
            < 1e-12
        {
            cols[13] = stall_warning(&cols[2], thr);
        }
    }
    Ok(ClosedLoopRun {
        columns: cols,
        recognised_at_s: recognised.map(|r| r.0),
        recognised_by: recognised.map(|r| r.1),
        pusher_fired_at_s: pusher.map(|p| p.fired_at).filter(|v| v.is_finite()),
        alpha_correction_deg: alpha_c.to_degrees(),
    })
}

/// The aerodynamics of a closed-loop replay on the ADX-37.
#[derive(Debug, Clone)]
pub enum ReplayModel<'a> {
    /// The extended model: the qualified model plus the fitted Δ model, and the fitted
    /// Kirchhoff stall (replacing the static C_L, C_m curves, and C_D with its drag) when
    /// given.
    Extended {
        /// The fitted Δ model.
        delta: &'a DeltaModel,
        /// Stall parameters of this flap (either form), with its drag or not; None: the
        /// stall the Δ model stores for the flap ([`DeltaModel::adx37_stall`]) when fitted on
        /// the ADX-37's known terms, else the qualified static curves.
        kirchhoff: Option<(StallParams, Option<KirchhoffDrag>)>,
    },
    /// A truth model of the virtual aircraft: the qualified model with these effects and
    /// Kirchhoff parameters (e.g. the campaign's own, or deliberately wrong ones).
    Truth {
        /// Effects switched on (aerodynamic ones act; others are ignored).
        effects: &'a [EffectSpec],
        /// Stall parameters (either form) and drag, when the longitudinal stall is on.
        kirchhoff: Option<(StallParams, Option<KirchhoffDrag>)>,
    },
}

/// Fly one closed-loop replay of a record on the ADX-37 with `model` (module docs).
///
/// # Errors
/// For an unknown effect, an invalid Δ model or Kirchhoff parameters, a malformed record or
/// options, or when the simulation diverges.
pub fn closed_loop_adx37(
    model: &ReplayModel<'_>,
    record: &[Vec<f64>],
    x0: [f64; 12],
    opts: &ClosedLoopOptions,
) -> Result<ClosedLoopRun> {
    let (qual, _) = adx37_models()?;
    if !FLAP_STALL.iter().any(|f| f.flap_deg == opts.flap_deg) {
        return Err(AeroError::invalid(
            "closed-loop options flap_deg",
            format!(
                "{}: the ADX-37 flies flap 0, 5, 10, 15 or 35 deg",
                opts.flap_deg
            ),
        ));
    }
    let ac = adx37();
    let stall = |p: Option<(StallParams, Option<KirchhoffDrag>)>| {
        p.map(|(p, d)| KirchhoffStall::new(qual, p).and_then(|k| k.with_drag(d)))
            .transpose()
    };
    match model {
        ReplayModel::Extended { delta, kirchhoff } => {
            // the stall given, else the one the model carries for this flap when it was fitted
            // on the ADX-37's known terms (it then replaces the qualified static curves)
            let k = kirchhoff
                .clone()
                .or_else(|| delta.adx37_stall(opts.flap_deg));
            let base = TruthAero::new(slice(qual, opts.flap_deg)?, Vec::new(), None)
                .with_kirchhoff(stall(k)?);
            let mut m = ExtendedAero::new(base, delta)?;
            fly_closed_loop(&mut m, &ac, record, x0, opts)
        }
        ReplayModel::Truth { effects, kirchhoff } => {
            let aero = active_effects(effects)?;
            let mut m = TruthAero::new(slice(qual, opts.flap_deg)?, aero, None)
                .with_kirchhoff(stall(kirchhoff.clone())?);
            fly_closed_loop(&mut m, &ac, record, x0, opts)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::campaign::{run_campaign, CampaignSpec};

    fn column(names: &[String], cols: &[Vec<f64>], name: &str) -> Vec<f64> {
        let k = names.iter().position(|c| c == name).expect(name);
        cols[k].clone()
    }

    #[test]
    fn a_calm_noise_free_pusher_stall_replayed_with_its_truth_fires_where_the_aircraft_did() {
        // flap 0, straight, pusher: the maneuver flown by the campaign's own pilot, replayed by
        // the closed-loop pilot on the same (qualified) model; the CG alpha, sideslip and
        // airspeed of the record are the truth's, the rest is the noise-free record
        let spec = CampaignSpec {
            seed: 3,
            repetitions: 1,
            noise_scale: 0.0,
            turbulence_mps: 0.0,
            only: vec![0],
            ..CampaignSpec::default()
        };
        let m = run_campaign(&spec).expect("campaign").remove(0);
        assert!(m.plan.pusher && m.pusher_fired, "{}", m.id);
        let rec = |n: &str| column(&m.record_names, &m.record, n);
        let tru = |n: &str| column(&m.truth_names, &m.truth, n);
        let record: Vec<Vec<f64>> = RECORD_COLUMNS
            .iter()
            .map(|c| match *c {
                "alpha_deg" => tru("alpha_true_deg"),
                "beta_deg" => tru("beta_true_deg"),
                "tas_mps" => tru("tas_true_mps"),
                other => rec(other),
            })
            .collect();
        let (t, alpha) = (&record[0], &record[1]);
        let k_peak = (0..t.len())
            .max_by(|&a, &b| alpha[a].total_cmp(&alpha[b]))
            .expect("samples");
        let (v, a, b) = (
            record[7][0],
            record[1][0].to_radians(),
            record[2][0].to_radians(),
        );
        let d = f64::to_radians;
        let x0 = [
            v * a.cos() * b.cos(),
            v * b.sin(),
            v * a.sin() * b.cos(),
            d(record[3][0]),
            d(record[4][0]),
            d(record[5][0]),
            d(record[6][0]),
            d(rec("theta_deg")[0]),
            d(rec("psi_deg")[0]),
            0.0,
            0.0,
            rec("h_m")[0],
        ];
        let fired = m.pusher_fired_at_s.expect("fired");
        let stall = FLAP_STALL[0];
        let opts = ClosedLoopOptions {
            flap_deg: 0.0,
            warning_alpha_deg: Some(stall.alpha_max_deg - 5.0),
            pusher_alpha_deg: Some(stall.alpha_max_deg - 1.0),
            t_id_s: fired,
            t_peak_s: t[k_peak],
            ..ClosedLoopOptions::default()
        };
        let model = ReplayModel::Truth {
            effects: &[],
            kirchhoff: None,
        };
        let run = closed_loop_adx37(&model, &record, x0, &opts).expect("replay");
        assert_eq!(run.recognised_by, Some("pusher"));
        let t_sim = run.pusher_fired_at_s.expect("the simulator's pusher fired");
        assert!((t_sim - fired).abs() < 1.0, "{t_sim} vs {fired}");
        // the speed at the firing: the record's against the simulated history's (EAS, kt)
        let eas = |tas: f64, rho: f64| tas * (rho / 1.225).sqrt() / 0.514_444;
        let at = |ts: &[f64], y: &[f64], tq: f64| {
            let j = ts.partition_point(|&x| x < tq).min(ts.len() - 1);
            y[j]
        };
        let v_rec = eas(at(t, &record[7], fired), at(t, &record[8], fired));
        let c = &run.columns;
        let v_sim = eas(at(&c[0], &c[8], t_sim), at(&c[0], &c[9], t_sim));
        assert!((v_sim - v_rec).abs() < 1.5, "{v_sim} vs {v_rec} kt");
        // the discretes are 0/1 and the pusher's starts at the firing
        assert!(c[12].iter().chain(&c[13]).all(|&x| x == 0.0 || x == 1.0));
        let k = c[12].iter().position(|&x| x == 1.0).expect("pusher active");
        assert!((c[0][k] - t_sim).abs() < 0.03);
    }

    #[test]
    fn bad_records_and_options_are_refused_naming_the_column() {
        let n = 20;
        let mut record: Vec<Vec<f64>> = (0..RECORD_COLUMNS.len()).map(|_| vec![1.0; n]).collect();
        record[0] = (0..n).map(|k| k as f64 * 0.02).collect();
        record[7] = vec![50.0; n];
        record[7][4] = f64::NAN;
        let model = ReplayModel::Truth {
            effects: &[],
            kirchhoff: None,
        };
        let x0 = [
            50.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.05, 0.0, 0.0, 0.0, 3000.0,
        ];
        let opts = ClosedLoopOptions::default();
        let e = closed_loop_adx37(&model, &record, x0, &opts)
            .unwrap_err()
            .to_string();
        assert!(e.contains("tas_mps") && e.contains("row 4"), "{e}");
        record[7][4] = 50.0;
        record[0][7] = record[0][6];
        let e = closed_loop_adx37(&model, &record, x0, &opts)
            .unwrap_err()
            .to_string();
        assert!(e.contains("column t") && e.contains("row 7"), "{e}");
        record[0] = (0..n).map(|k| k as f64 * 0.02).collect();
        let bad = ClosedLoopOptions {
            flap_deg: 7.0,
            ..ClosedLoopOptions::default()
        };
        let e = closed_loop_adx37(&model, &record, x0, &bad)
            .unwrap_err()
            .to_string();
        assert!(e.contains("flap_deg"), "{e}");
        let e = ClosedLoopOptions::from_json(r#"{"flap": 0}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("flap"), "{e}");
    }
}
