//! The pilot model and the stick pusher flying the stall maneuvers of thesis
//! Section 3.2.1:
//! - straight stalls: wings level, constant power, deceleration ≈ 1 kt/s;
//! - turning stalls: the same in a ≈30° bank;
//! - accelerated stalls: elevator pulled progressively faster in a steep turn,
//!   load factor > 1.3 at stall;
//! - asymmetric-thrust stalls: very different power on the two engines, wings
//!   level, rudder against the yaw;
//!
//! with or without the stick pusher, then the recovery (nose down to 4° alpha,
//! full power, wings level).
//!
//! The pilot flies an alpha schedule: α_ref(t) from the lift equation at the
//! reference speed V_ref(t) = V₀ − 1 kt/s · t (load factor n = 1/cos φ_ref),
//! tracked by the elevator (feedforward from the pitching-moment table, PI on
//! alpha, damping on q); ailerons hold the bank (PD), the rudder cancels
//! sideslip (PI). Gains, delay and trim errors vary per maneuver, and the
//! pilot adds random doublets and stick noise so lateral states are excited;
//! `excitation` scales both (low excitation was the thesis's main difficulty,
//! Section 3.3.3). In straight stalls the doublets stop within
//! [`STRAIGHT_HOLD_BELOW_STALL_DEG`] of α_max until the recovery (controls held).

use crate::aircraft::qualified::{lift_curve, pitch_curve, FlapStall};
use crate::sim::aero::Controls;
use crate::sim::rng::Stream;

/// The kind of a maneuver (campaign manifest `kind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// Straight stall.
    Straight,
    /// Turning stall (≈30° bank).
    Turning,
    /// Accelerated stall (n > 1.3).
    Accelerated,
    /// Asymmetric-thrust stall.
    AsymmetricThrust,
}

impl Kind {
    /// Manifest name.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Straight => "straight",
            Kind::Turning => "turning",
            Kind::Accelerated => "accelerated",
            Kind::AsymmetricThrust => "asymmetric_thrust",
        }
    }
    /// All kinds.
    pub const ALL: [Kind; 4] = [
        Kind::Straight,
        Kind::Turning,
        Kind::Accelerated,
        Kind::AsymmetricThrust,
    ];
}

/// The stick pusher: a nose-down elevator increment when alpha exceeds the
/// activation alpha, held for a minimum time and until alpha has dropped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pusher {
    /// Activation alpha, deg.
    pub alpha_on_deg: f64,
    /// Alpha below which it releases (after the minimum time), deg.
    pub alpha_off_deg: f64,
    /// Elevator increment, rad (positive = nose down).
    pub push_rad: f64,
    /// Minimum push time, s.
    pub min_time_s: f64,
    /// Time it fired, s (NaN before).
    pub fired_at: f64,
    active: bool,
}

impl Pusher {
    /// A pusher firing at `alpha_on_deg`.
    pub fn new(alpha_on_deg: f64) -> Self {
        Pusher {
            alpha_on_deg,
            alpha_off_deg: alpha_on_deg - 6.0,
            push_rad: 14f64.to_radians(),
            min_time_s: 1.5,
            fired_at: f64::NAN,
            active: false,
        }
    }
    /// Elevator increment at time `t` and alpha `alpha_deg`, rad.
    pub fn update(&mut self, t: f64, alpha_deg: f64) -> f64 {
        if !self.active && alpha_deg > self.alpha_on_deg {
            self.active = true;
            if self.fired_at.is_nan() {
                self.fired_at = t;
            }
        } else if self.active
            && alpha_deg < self.alpha_off_deg
            && t - self.fired_at > self.min_time_s
        {
            self.active = false;
        }
        if self.active {
            self.push_rad
        } else {
            0.0
        }
    }
    /// Whether it is pushing now (the activation discrete a flight-test
    /// recorder logs as `pusher_active`).
    pub fn is_active(&self) -> bool {
        self.active
    }
    /// Whether it has fired.
    pub fn has_fired(&self) -> bool {
        !self.fired_at.is_nan()
    }
}

/// What the pilot sees (true values: the pilot flies the aircraft, not the recorder).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Observation {
    /// Time, s.
    pub t: f64,
    /// Alpha, rad.
    pub alpha: f64,
    /// Beta, rad.
    pub beta: f64,
    /// Rates, rad/s.
    pub p: f64,
    /// Pitch rate, rad/s.
    pub q: f64,
    /// Yaw rate, rad/s.
    pub r: f64,
    /// Bank, rad.
    pub phi: f64,
    /// True airspeed, m/s.
    pub tas: f64,
    /// Density, kg/m³.
    pub rho: f64,
    /// Total thrust coefficient.
    pub ct_sum: f64,
}

/// The pilot's commands.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Command {
    /// Surface commands, rad.
    pub controls: Controls,
    /// Power levers (0 idle … 1 max).
    pub levers: [f64; 2],
}

/// Flight phase of a maneuver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Approaching the stall.
    Approach,
    /// Recovering.
    Recovery,
}

/// Per-maneuver pilot parameters (drawn by the campaign).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PilotParams {
    /// Maneuver kind.
    pub kind: Kind,
    /// Bank target during the approach, rad (signed).
    pub bank: f64,
    /// Reaction delay, s.
    pub delay_s: f64,
    /// Gain scale (1 = nominal).
    pub gain: f64,
    /// Deceleration, m/s² (≈ 1 kt/s = 0.514).
    pub decel: f64,
    /// Pull rate past the stall (non-pusher) or in accelerated stalls, deg/s.
    pub pull_rate_dps: f64,
    /// Alpha past C_L,max at which the pilot recognises the stall (non-pusher), deg.
    pub stall_margin_deg: f64,
    /// Power levers during the approach.
    pub levers: [f64; 2],
    /// Elevator trim error, rad.
    pub trim_error: f64,
    /// Excitation scale (doublet rate and amplitude, stick noise), 1 = nominal.
    pub excitation: f64,
    /// Recovery duration, s.
    pub recovery_s: f64,
    /// Bank excursion from the target that makes the pilot recover at once (wing drop), deg.
    pub wing_drop_deg: f64,
    /// Whether the pilot keeps fighting the roll with full aileron gain while still
    /// stalled (the thesis's pilots often did, Section 3.4.3), or first lowers alpha
    /// with ailerons nearly neutral (the proper recovery technique, Section 4.2.2).
    pub aileron_in_stall: bool,
}

const DELAY_SLOTS: usize = 64;

/// In a straight stall the pilot holds the controls (no deliberate doublets, stick
/// noise only) once alpha is within this many degrees of α_max, until the recovery:
/// a certification straight stall observes what the aircraft does by itself (thesis
/// Sections 3.2.1 and 3.4.3; its roll-off events were read where the aileron was
/// quasi-constant). 6° covers the roll-off onsets of Table 3.2 (17.1-18.0° on
/// α_max 18.5-19.5°) with their spread and a doublet's 2.2 s.
pub const STRAIGHT_HOLD_BELOW_STALL_DEG: f64 = 6.0;

/// The pilot.
#[derive(Debug, Clone)]
pub struct Pilot {
    /// Parameters.
    pub params: PilotParams,
    /// Stall parameters of the flap setting.
    pub stall: FlapStall,
    /// Current phase.
    pub phase: Phase,
    /// Time the recovery began, s.
    pub recovery_at: f64,
    /// Wing loading W/S, N/m².
    wing_loading: f64,
    v0: f64,
    alpha_hold_t: f64,
    int_alpha: f64,
    int_beta: f64,
    rng: Stream,
    doublet: Option<(f64, f64, f64, bool)>, // (start, half period, amplitude, aileron?)
    next_doublet: f64,
    noise: [f64; 2],
    buf: [Command; DELAY_SLOTS],
    head: usize,
    delay_steps: usize,
    /// Alpha at the start of an accelerated pull, deg.
    alpha_start_deg: f64,
}

impl Pilot {
    /// A pilot for one maneuver starting at airspeed `v0` (m/s).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        params: PilotParams,
        stall: FlapStall,
        wing_loading: f64,
        v0: f64,
        alpha0_deg: f64,
        dt: f64,
        seed: u64,
        stream: u64,
    ) -> Self {
        let mut rng = Stream::new(seed, stream);
        let first = rng.range(2.0, 8.0) / params.excitation.max(1e-3);
        let delay_steps = ((params.delay_s / dt).round() as usize).clamp(0, DELAY_SLOTS - 1);
        Pilot {
            params,
            stall,
            phase: Phase::Approach,
            recovery_at: f64::NAN,
            wing_loading,
            v0,
            alpha_hold_t: f64::NAN,
            int_alpha: 0.0,
            int_beta: 0.0,
            rng,
            doublet: None,
            next_doublet: first,
            noise: [0.0; 2],
            buf: [Command::default(); DELAY_SLOTS],
            head: 0,
            delay_steps,
            alpha_start_deg: alpha0_deg,
        }
    }

    /// Alpha on the lift curve's rising branch giving `cl` (clamped to α_max), deg.
    fn alpha_for_cl(&self, cl: f64) -> f64 {
        let (mut lo, mut hi) = (-10.0, self.stall.alpha_max_deg);
        if cl >= self.stall.cl_max {
            return hi;
        }
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if lift_curve(&self.stall, mid) < cl {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// The alpha the pilot aims for at `o`, deg.
    fn alpha_ref_deg(&mut self, o: &Observation) -> f64 {
        if self.phase == Phase::Recovery {
            return 4.0;
        }
        let t = o.t;
        match self.params.kind {
            Kind::Accelerated => {
                // progressively faster pull: α̇ = r₀ (1 + t/8) deg/s after 3 s of turn entry
                let tt = (t - 3.0).max(0.0);
                self.alpha_start_deg + self.params.pull_rate_dps * (tt + tt * tt / 16.0)
            }
            _ => {
                let vref = (self.v0 - self.params.decel * t).max(20.0);
                let n = 1.0 / self.params.bank.cos().max(0.3);
                let q = 0.5 * o.rho * vref * vref;
                let cl = n * self.wing_loading / q - 0.0;
                let a = self.alpha_for_cl(cl);
                if a >= self.stall.alpha_max_deg - 1e-6 {
                    if self.alpha_hold_t.is_nan() {
                        self.alpha_hold_t = t;
                    }
                    a + self.params.pull_rate_dps * (t - self.alpha_hold_t)
                } else {
                    a
                }
            }
        }
    }

    /// Decide the commands at `o` (before the reaction delay); `pusher_fired`
    /// triggers the recovery.
    fn decide(&mut self, o: &Observation, pusher_fired: bool, dt: f64) -> Command {
        let p = self.params;
        let alpha_deg = o.alpha.to_degrees();
        let wing_drop = alpha_deg > self.stall.alpha_max_deg - 3.0
            && (o.phi - p.bank).abs().to_degrees() > p.wing_drop_deg;
        if self.phase == Phase::Approach
            && (pusher_fired
                || wing_drop
                || alpha_deg > self.stall.alpha_max_deg + p.stall_margin_deg)
        {
            self.phase = Phase::Recovery;
            self.recovery_at = o.t;
            self.int_alpha *= 0.3;
        }
        let a_ref = self.alpha_ref_deg(o).to_radians();
        let g = p.gain;
        // elevator: feedforward from the pitching-moment table + PI on alpha + q damping
        let cm_de = -2.0 * (1.0 - 0.004 * a_ref.to_degrees().max(0.0));
        let cm_ff = pitch_curve(&self.stall, a_ref.to_degrees()) - 0.19 * o.ct_sum;
        let e = o.alpha - a_ref;
        self.int_alpha = (self.int_alpha + e * dt).clamp(-0.3, 0.3);
        let de = -cm_ff / cm_de + p.trim_error + g * (0.9 * e + 0.6 * self.int_alpha + 0.3 * o.q);
        // ailerons: bank hold (PD); the bank target is zero in the recovery
        let bank = if self.phase == Phase::Recovery {
            0.0
        } else {
            p.bank
        };
        let mut da = g * (0.6 * (o.phi - bank) + 0.25 * o.p);
        if self.phase == Phase::Recovery
            && !p.aileron_in_stall
            && alpha_deg > self.stall.alpha_max_deg - 2.0
        {
            da *= 0.3;
        }
        // rudder: cancel sideslip (PI) and damp yaw
        self.int_beta = (self.int_beta + o.beta * dt).clamp(-0.5, 0.5);
        let mut dr = g * (-0.8 * o.beta - 0.5 * self.int_beta + 0.2 * o.r);
        // excitation: doublets and stick noise
        let x = p.excitation;
        let hold = p.kind == Kind::Straight
            && self.phase == Phase::Approach
            && alpha_deg > self.stall.alpha_max_deg - STRAIGHT_HOLD_BELOW_STALL_DEG;
        if x > 0.0 {
            if !hold && self.doublet.is_none() && o.t >= self.next_doublet {
                let half = self.rng.range(0.5, 1.1);
                let amp = x * self.rng.range(3.0, 8.0).to_radians();
                let sign = if self.rng.bernoulli(0.5) { 1.0 } else { -1.0 };
                let aileron = self.rng.bernoulli(0.6);
                self.doublet = Some((o.t, half, sign * amp, aileron));
                self.next_doublet = o.t + 2.0 * half + self.rng.range(3.0, 12.0) / x;
            }
            if let Some((t0, half, amp, aileron)) = self.doublet {
                let tau = o.t - t0;
                let v = if tau < half {
                    amp
                } else if tau < 2.0 * half {
                    -amp
                } else {
                    self.doublet = None;
                    0.0
                };
                if aileron {
                    da += v;
                } else {
                    dr += v;
                }
            }
            let a = (-dt / 0.8f64).exp();
            let k = (1.0 - a * a).sqrt() * x * 0.8f64.to_radians();
            self.noise[0] = a * self.noise[0] + k * self.rng.normal();
            self.noise[1] = a * self.noise[1] + k * self.rng.normal();
            da += self.noise[0];
            dr += self.noise[1];
        }
        // roll spoilers follow the wheel beyond 3° of aileron (left roll: left spoiler up)
        let b = 3f64.to_radians();
        let dsl = 2.0 * (da - b).max(0.0);
        let dsr = 2.0 * (-da - b).max(0.0);
        let levers = if self.phase == Phase::Recovery && o.t - self.recovery_at > 1.0 {
            [1.0, 1.0]
        } else {
            p.levers
        };
        Command {
            controls: Controls {
                da,
                de,
                dr,
                dsl,
                dsr,
            },
            levers,
        }
    }

    /// The command acting now: decided `delay_s` ago (ring buffer, no allocation).
    pub fn command(&mut self, o: &Observation, pusher_fired: bool, dt: f64) -> Command {
        let c = self.decide(o, pusher_fired, dt);
        self.buf[self.head] = c;
        let out_i = (self.head + DELAY_SLOTS - self.delay_steps) % DELAY_SLOTS;
        let out = if o.t < self.params.delay_s {
            c
        } else {
            self.buf[out_i]
        };
        self.head = (self.head + 1) % DELAY_SLOTS;
        out
    }

    /// Whether the maneuver is over.
    pub fn done(&self, t: f64) -> bool {
        self.phase == Phase::Recovery && t - self.recovery_at > self.params.recovery_s
    }
}
