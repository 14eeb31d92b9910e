//! A deterministic virtual flight-test campaign: the maneuvers of thesis
//! Section 3.2.1 over the five flap settings, with and without the stick
//! pusher, flown by the pilot model on the truth aircraft and recorded by the
//! sensor model. Seed → per-maneuver seeds (SplitMix64) → independent ChaCha
//! streams per component (pilot, gusts, roll-off, sensors), so a maneuver's
//! result depends only on the campaign seed and its index: identical whatever
//! the thread count (`parallel` feature, rayon). With `mass_properties` each
//! maneuver flies its own mass, CG and inertia ([`crate::sim::mass`]), drawn from
//! a stream of its own: the other streams, and a campaign without it, are untouched.
//! With `buffet` the accelerometers also record the stall buffet ([`crate::buffet`]),
//! drawn from its own stream too and added to the recorded `ay_mps2`, `az_mps2` only
//! (structural vibration at the sensor: the flight itself is unchanged).

use nalgebra::Vector3;

use crate::aircraft::effects::{ActiveEffect, MeasurementEffects};
use crate::aircraft::qualified::{FlapModel, FlapStall, QualifiedModel, FLAP_STALL};
use crate::aircraft::truth::{
    active_effects, EffectSpec, KirchhoffStall, LongitudinalStall, TruthAero,
};
use crate::aircraft::turboprop::{adx37, AircraftRef};
use crate::buffet::{Buffet, BuffetMode, BuffetSchedule, BuffetSpec};
use crate::delta_model::DeltaModel;
use crate::error::{AeroError, Result, ResultExt};
use crate::rolloff::{RollOff, RollOffConfig, RollOffDraw};
use crate::sim::actuator::Actuator;
use crate::sim::aero::{AeroModel, Controls};
use crate::sim::atmosphere::{isa, G0};
use crate::sim::engine::{Engine, EngineSpec};
use crate::sim::eom::ix;
use crate::sim::extended::ExtendedAero;
use crate::sim::maneuver::{trim, AirData, Simulator};
use crate::sim::mass::{MassProperties, MassVariation};
use crate::sim::pilot::{Command, Kind, Observation, Pilot, PilotParams, Pusher};
use crate::sim::rng::{derive_seed, Stream};
use crate::sim::sensors::{
    record, stall_warning, NoiseSpec, TrueSample, CHANNELS, DISCRETE_CHANNELS,
    STALL_WARNING_MARGIN_DEG,
};
use crate::sim::turbulence::Dryden;

/// Random streams of one maneuver.
mod stream {
    pub const SETUP: u64 = 1;
    pub const PILOT: u64 = 2;
    pub const GUST: u64 = 3;
    pub const ROLLOFF: u64 = 4;
    pub const SENSORS: u64 = 5;
    pub const MASS: u64 = 6;
    pub const BUFFET: u64 = 7;
}

/// What a campaign contains and how it is flown.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct CampaignSpec {
    /// Campaign seed.
    pub seed: u64,
    /// Repetitions of each (flap, kind, pusher) cell: 5 flaps × 4 kinds × 2 × reps maneuvers.
    pub repetitions: usize,
    /// Effects switched on (aero, measurement and `stochastic_rolloff`).
    pub effects: Vec<EffectSpec>,
    /// Sensor noise scale (0 = noise-free, 1 = nominal).
    pub noise_scale: f64,
    /// Dryden RMS gust intensity, m/s (0 = calm).
    pub turbulence_mps: f64,
    /// Pilot excitation scale (doublets, stick noise), 1 = nominal.
    pub excitation: f64,
    /// Roll-off statistics (thesis Table 3.2 by default).
    pub rolloff: RollOffConfig,
    /// Simulation rate, Hz.
    pub sim_hz: f64,
    /// Record rate, Hz (a divisor of `sim_hz`).
    pub record_hz: f64,
    /// Only maneuvers with these indices (empty = all), for tests and benchmarks.
    pub only: Vec<usize>,
    /// Per-maneuver variation of mass, CG (m, from the datum) and inertia; `None`
    /// (the default, and absent from the JSON) flies every maneuver at the
    /// nominal values of `aircraft.toml`. `Some` with zero ranges flies the
    /// nominal values too but reports them per maneuver.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mass_properties: Option<MassVariation>,
    /// Calibration errors of the vanes (scale factors, flank-angle beta vane); `None` (the
    /// default, absent from the JSON): ideal vanes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vanes: Option<crate::aircraft::effects::VaneCalibration>,
    /// Stall buffet at the accelerometers (onset, modes, intensity; [`BuffetSpec`]); `None`
    /// (the default, absent from the JSON): no buffet, and the records are those of a
    /// campaign without the option, bit for bit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub buffet: Option<BuffetSpec>,
    /// The truth's longitudinal stall: the qualified static curves (the default,
    /// absent from the JSON) or a Kirchhoff flow-separation stall
    /// ([`crate::aircraft::truth::kirchhoff_truth_params`]), whose records then
    /// carry the truth columns `x_sep_true`, `CL_true`, `Cm_true`, `CD_true`.
    #[serde(skip_serializing_if = "is_static")]
    pub longitudinal_stall: LongitudinalStall,
}

fn is_static(s: &LongitudinalStall) -> bool {
    *s == LongitudinalStall::Static
}

impl Default for CampaignSpec {
    fn default() -> Self {
        CampaignSpec {
            seed: 0,
            repetitions: 5,
            effects: Vec::new(),
            noise_scale: 1.0,
            turbulence_mps: 0.5,
            excitation: 1.0,
            rolloff: RollOffConfig::default(),
            sim_hz: 100.0,
            record_hz: 50.0,
            only: Vec::new(),
            mass_properties: None,
            vanes: None,
            buffet: None,
            longitudinal_stall: LongitudinalStall::Static,
        }
    }
}

/// One maneuver of the plan.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ManeuverPlan {
    /// Index in the campaign.
    pub index: usize,
    /// Flap, deg.
    pub flap_deg: f64,
    /// Kind.
    pub kind: Kind,
    /// Stick pusher on.
    pub pusher: bool,
    /// Maneuver seed.
    pub seed: u64,
}

/// The result of one maneuver.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ManeuverResult {
    /// Identifier (`m007_f10_turning_p`).
    pub id: String,
    /// Plan.
    pub plan: ManeuverPlan,
    /// Record channel names.
    pub record_names: Vec<String>,
    /// Record columns.
    #[serde(skip)]
    pub record: Vec<Vec<f64>>,
    /// Truth channel names.
    pub truth_names: Vec<String>,
    /// Truth columns.
    #[serde(skip)]
    pub truth: Vec<Vec<f64>>,
    /// Roll-off draws.
    pub rolloff_draws: Vec<RollOffDraw>,
    /// Maximum true alpha, deg.
    pub max_alpha_deg: f64,
    /// Load factor when alpha first reaches α_max − 1° (stall onset).
    pub load_factor_at_stall: f64,
    /// Whether the pusher fired.
    pub pusher_fired: bool,
    /// Time the pusher fired, s (absent when it did not).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pusher_fired_at_s: Option<f64>,
    /// Maximum |bank|, deg.
    pub max_bank_deg: f64,
    /// The mass properties flown, when the campaign varies them (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mass_properties: Option<MassProperties>,
    /// The buffet injected, when the campaign has one (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub buffet: Option<BuffetTruth>,
}

/// The buffet a maneuver's accelerometers recorded: its flap setting's schedule and the modes.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BuffetTruth {
    /// Amplitude schedule (onset and full-intensity alpha, deg; normal-axis RMS, m/s²).
    pub schedule: BuffetSchedule,
    /// Structural modes (frequencies, Hz; damping; relative gains).
    pub modes: Vec<BuffetMode>,
}

impl CampaignSpec {
    /// Parse a specification from JSON (missing fields take their defaults).
    ///
    /// # Errors
    /// [`AeroError::Parse`] naming the JSON line and the problem.
    pub fn from_json(text: &str) -> Result<Self> {
        serde_json::from_str(text)
            .map_err(|e| AeroError::parse("campaign spec (JSON)", e.line(), e.to_string()))
    }

    /// The specification as JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }
}

impl ManeuverResult {
    /// Metadata (everything but the columns) as JSON.
    pub fn meta_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }
}

/// The list of maneuvers of a campaign.
pub fn plan(spec: &CampaignSpec) -> Vec<ManeuverPlan> {
    let mut out = Vec::new();
    let mut index = 0;
    for rep in 0..spec.repetitions.max(1) {
        let _ = rep;
        for f in FLAP_STALL {
            for kind in Kind::ALL {
                for pusher in [true, false] {
                    out.push(ManeuverPlan {
                        index,
                        flap_deg: f.flap_deg,
                        kind,
                        pusher,
                        seed: derive_seed(spec.seed, index as u64),
                    });
                    index += 1;
                }
            }
        }
    }
    if !spec.only.is_empty() {
        out.retain(|m| spec.only.contains(&m.index));
    }
    out
}

fn engine_spec(ac: &AircraftRef) -> EngineSpec {
    EngineSpec {
        max_power_w: ac.max_power_w,
        idle_power_w: 0.04 * ac.max_power_w,
        time_constant_s: 1.2,
        efficiency: 0.8,
        max_thrust_n: 30_000.0,
        prop_rpm: ac.prop_rpm,
        density_exponent: 0.7,
    }
}

pub(crate) fn actuators(c0: &Controls) -> [Actuator; 5] {
    let d = f64::to_radians;
    [
        Actuator::new(0.06, d(60.0), d(-20.0), d(20.0), c0.da),
        Actuator::new(0.06, d(40.0), d(-22.0), d(18.0), c0.de),
        Actuator::new(0.08, d(40.0), d(-25.0), d(25.0), c0.dr),
        Actuator::new(0.05, d(90.0), 0.0, d(45.0), 0.0),
        Actuator::new(0.05, d(90.0), 0.0, d(45.0), 0.0),
    ]
}

/// One maneuver in flight: the truth aircraft, its pilot, pusher, actuators,
/// engines and gusts, advanced one fixed step at a time. [`run_maneuver`]
/// records it; [`crate::rolloff_mc`] only summarises it (same flight, same
/// random streams).
#[derive(Debug, Clone)]
pub struct Flight {
    /// The 6-DOF simulator.
    pub sim: Simulator,
    /// The truth aerodynamic model (with the roll-off when on).
    pub model: TruthAero,
    /// The pilot.
    pub pilot: Pilot,
    /// The stick pusher (when the plan has it).
    pub pusher: Option<Pusher>,
    /// Stall parameters of the flap setting.
    pub stall: FlapStall,
    /// Mass properties of the maneuver.
    pub mass: MassProperties,
    /// Weight, N.
    pub weight_n: f64,
    /// Surface positions at the end of the current step, rad.
    pub surfaces: Controls,
    /// Surface positions at the start of the current step (what a sample taken
    /// now records and what acts now), rad; they move linearly to `surfaces`
    /// over the step.
    pub surfaces_start: Controls,
    /// Steps flown.
    pub step_index: usize,
    /// Last step allowed (150 s).
    pub max_steps: usize,
    acts: [Actuator; 5],
    engines: [Engine; 2],
    gusts: Dryden,
    sigma_gust: f64,
}

/// The state of a flight at the start of a step, after the pilot's command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepState {
    /// Air data (gusts included).
    pub air: AirData,
    /// Thrust per engine, N.
    pub thrust_n: [f64; 2],
}

/// The mass properties of maneuver `m`: drawn from its own stream when `spec`
/// varies them, else `None` (the nominal aircraft).
pub fn maneuver_mass(
    spec: &CampaignSpec,
    ac: &AircraftRef,
    m: &ManeuverPlan,
) -> Option<MassProperties> {
    spec.mass_properties
        .map(|v| v.draw(ac, m.seed, stream::MASS))
}

impl Flight {
    /// Trim the truth aircraft and set up the pilot, pusher, engines and gusts of
    /// maneuver `m` (the setup stream's draws in a fixed order), with the mass
    /// properties of [`maneuver_mass`].
    ///
    /// # Errors
    /// When the trim fails or the roll-off configuration is invalid.
    pub fn new(
        spec: &CampaignSpec,
        qual: &QualifiedModel,
        effects: &[ActiveEffect],
        rolloff_on: bool,
        m: &ManeuverPlan,
    ) -> Result<Flight> {
        let mass = maneuver_mass(spec, &qual.aircraft, m)
            .unwrap_or_else(|| MassProperties::nominal(&qual.aircraft));
        Self::with_mass(spec, qual, effects, rolloff_on, m, &mass)
    }

    /// [`Flight::new`] with the mass properties `mass` (trim, pilot and rigid
    /// body use its weight and inertia, the loads' moments are taken about its CG).
    ///
    /// # Errors
    /// When the trim fails or the roll-off configuration is invalid.
    pub fn with_mass(
        spec: &CampaignSpec,
        qual: &QualifiedModel,
        effects: &[ActiveEffect],
        rolloff_on: bool,
        m: &ManeuverPlan,
        mass: &MassProperties,
    ) -> Result<Flight> {
        let ac = qual.aircraft.clone();
        let fi = FLAP_STALL
            .iter()
            .position(|f| f.flap_deg == m.flap_deg)
            .unwrap_or(0);
        let stall = FLAP_STALL[fi];
        let mut setup = Stream::new(m.seed, stream::SETUP);
        let h0 = 3000.0 + setup.range(-300.0, 300.0);
        let air0 = isa(h0);
        let w = mass.mass_kg * G0;
        let vs = (2.0 * w / (air0.density_kgm3 * ac.s_m2 * stall.cl_max)).sqrt();
        let v0 = match m.kind {
            Kind::Accelerated => 1.55,
            Kind::Turning => 1.35 * 1.075,
            _ => 1.35,
        } * vs
            * setup.range(0.97, 1.05);
        let bank_sign = if setup.bernoulli(0.5) { 1.0 } else { -1.0 };
        let bank = match m.kind {
            Kind::Turning => setup.range(27.0, 33.0),
            Kind::Accelerated => setup.range(30.0, 40.0),
            _ => 0.0,
        }
        .to_radians()
            * bank_sign;
        let dt = 1.0 / spec.sim_hz;

        let rolloff = if rolloff_on {
            Some(RollOff::new(
                spec.rolloff.clone(),
                m.flap_deg,
                m.seed,
                stream::ROLLOFF,
            )?)
        } else {
            None
        };
        let kirchhoff = match spec.longitudinal_stall {
            LongitudinalStall::Static => None,
            LongitudinalStall::Kirchhoff => Some(KirchhoffStall::adx37(qual, m.flap_deg)?),
        };
        let model = TruthAero::new(slice(qual, m.flap_deg)?, effects.to_vec(), rolloff)
            .with_kirchhoff(kirchhoff);
        let mut sim =
            Simulator::with_mass(ac.clone(), m.flap_deg, nalgebra::SVector::zeros(), dt, mass);
        let tr = trim(&sim, &model, v0, h0).context(format!("maneuver {}", m.index))?;
        let t_each = tr.thrust_n;
        sim.x = tr.x;
        let sigma = air0.density_kgm3 / 1.225;
        let espec = engine_spec(&ac);
        let probe = Engine::settled(espec, 0.0, sigma);
        let p_trim = probe.power_for_thrust(t_each, v0);
        let lever_trim = probe.lever_for_power(p_trim, sigma);
        let engines = [
            Engine {
                spec: espec,
                power_w: p_trim,
            },
            Engine {
                spec: espec,
                power_w: p_trim,
            },
        ];
        let levers = match m.kind {
            Kind::AsymmetricThrust => {
                if setup.bernoulli(0.5) {
                    [0.85, 0.0]
                } else {
                    [0.0, 0.85]
                }
            }
            Kind::Accelerated => [lever_trim.clamp(0.0, 1.0); 2],
            _ => [(lever_trim * setup.range(0.6, 1.1)).clamp(0.0, 1.0); 2],
        };
        let params = PilotParams {
            kind: m.kind,
            bank,
            delay_s: setup.range(0.15, 0.35),
            gain: setup.range(0.75, 1.3),
            decel: 0.514 * setup.range(0.8, 1.25),
            pull_rate_dps: match m.kind {
                Kind::Accelerated => setup.range(0.6, 1.0),
                _ => setup.range(0.5, 1.0),
            },
            stall_margin_deg: setup.range(0.5, 3.0),
            levers,
            trim_error: setup.range(-0.5, 0.5).to_radians(),
            excitation: spec.excitation,
            recovery_s: setup.range(7.0, 10.0),
            wing_drop_deg: setup.range(15.0, 30.0),
            aileron_in_stall: setup.bernoulli(0.5),
        };
        let alpha0 = sim.air(&sim.x).alpha.to_degrees();
        let pilot = Pilot::new(
            params,
            stall,
            w / ac.s_m2,
            v0,
            alpha0,
            dt,
            m.seed,
            stream::PILOT,
        );
        let pusher = m.pusher.then(|| Pusher::new(stall.alpha_max_deg - 1.0));
        let acts = actuators(&tr.controls);
        let sig = spec.turbulence_mps;
        let gusts = Dryden::new([sig, sig, sig], m.seed, stream::GUST);
        Ok(Flight {
            sim,
            model,
            pilot,
            pusher,
            stall,
            mass: *mass,
            weight_n: w,
            surfaces: tr.controls,
            surfaces_start: tr.controls,
            step_index: 0,
            max_steps: (150.0 * spec.sim_hz) as usize,
            acts,
            engines,
            gusts,
            sigma_gust: sig,
        })
    }

    /// Start a step: gusts of this step, then what the pilot sees, then the
    /// actuators move: `surfaces_start` (where they are now, what a sample taken
    /// now records) to `surfaces` (where they are at the step's end), linearly
    /// over the step; thrust is held. A replay of the record with the same
    /// interpolation reproduces the flight (Section 4.3).
    pub fn command(&mut self) -> StepState {
        let dt = self.sim.dt;
        let sim = &mut self.sim;
        if self.sigma_gust > 0.0 {
            let tas = sim.air(&sim.x).tas;
            sim.gust = self.gusts.advance(tas, dt);
        }
        let ad = sim.air(&sim.x);
        let qs = ad.qbar * sim.aircraft.s_m2;
        let engines = &mut self.engines;
        let o = Observation {
            t: sim.t,
            alpha: ad.alpha,
            beta: ad.beta,
            p: sim.x[ix::P],
            q: sim.x[ix::Q],
            r: sim.x[ix::R],
            phi: sim.x[ix::PHI],
            tas: ad.tas,
            rho: ad.rho,
            ct_sum: (engines[0].thrust(ad.tas) + engines[1].thrust(ad.tas)) / qs,
        };
        let push = self
            .pusher
            .as_mut()
            .map_or(0.0, |p| p.update(sim.t, ad.alpha.to_degrees()));
        let fired = self.pusher.as_ref().is_some_and(Pusher::has_fired);
        let Command {
            controls: c,
            levers,
        } = self.pilot.command(&o, fired, dt);
        self.surfaces_start = self.surfaces;
        if self.step_index > 0 {
            let acts = &mut self.acts;
            self.surfaces = Controls {
                da: acts[0].advance(c.da, dt),
                de: acts[1].advance(c.de + push, dt),
                dr: acts[2].advance(c.dr, dt),
                dsl: acts[3].advance(c.dsl, dt),
                dsr: acts[4].advance(c.dsr, dt),
            };
            for (e, l) in engines.iter_mut().zip(levers) {
                e.advance(l, ad.rho / 1.225, dt);
            }
        }
        StepState {
            air: ad,
            thrust_n: [engines[0].thrust(ad.tas), engines[1].thrust(ad.tas)],
        }
    }

    /// Whether the pilot has finished the maneuver (recovery complete) or the time is up.
    pub fn done(&self) -> bool {
        self.pilot.done(self.sim.t) || self.step_index + 1 >= self.max_steps
    }

    /// Finish the step started by [`Flight::command`]: integrate over `dt`.
    ///
    /// # Errors
    /// When the state is no longer finite (the simulation diverged).
    pub fn integrate(&mut self, s: &StepState, index: usize) -> Result<()> {
        self.sim.step_interp(
            &mut self.model,
            &self.surfaces_start,
            &self.surfaces,
            s.thrust_n,
        );
        self.step_index += 1;
        if !self.sim.x.iter().all(|v| v.is_finite()) {
            return Err(AeroError::invalid(
                format!("maneuver {index}"),
                format!("the simulation diverged at t = {:.2} s", self.sim.t),
            ));
        }
        Ok(())
    }

    /// Whether the pusher has fired.
    pub fn pusher_fired(&self) -> bool {
        self.pusher.as_ref().is_some_and(Pusher::has_fired)
    }
}

/// Fly one maneuver of `plan` on the truth aircraft.
///
/// # Errors
/// When the trim fails or an effect name is unknown.
pub fn run_maneuver(
    spec: &CampaignSpec,
    qual: &QualifiedModel,
    effects: &[ActiveEffect],
    meas: &MeasurementEffects,
    rolloff_on: bool,
    m: &ManeuverPlan,
) -> Result<ManeuverResult> {
    let varied = maneuver_mass(spec, &qual.aircraft, m);
    fly(spec, qual, effects, meas, rolloff_on, m, varied)
}

/// [`run_maneuver`] with the mass properties `varied` (`None`: nominal, not reported).
fn fly(
    spec: &CampaignSpec,
    qual: &QualifiedModel,
    effects: &[ActiveEffect],
    meas: &MeasurementEffects,
    rolloff_on: bool,
    m: &ManeuverPlan,
    varied: Option<MassProperties>,
) -> Result<ManeuverResult> {
    let ac = qual.aircraft.clone();
    let mass = varied.unwrap_or_else(|| MassProperties::nominal(&ac));
    let mut f = Flight::with_mass(spec, qual, effects, rolloff_on, m, &mass)?;
    let decim = ((spec.sim_hz / spec.record_hz).round() as usize).max(1);
    let (stall, w, max_steps) = (f.stall, f.weight_n, f.max_steps);
    let mut samples: Vec<TrueSample> = Vec::with_capacity(max_steps / decim + 2);
    let mut truth_rows: Vec<[f64; 8]> = Vec::with_capacity(max_steps / decim + 2);
    let mut eff_rows: Vec<[f64; 3]> = Vec::with_capacity((max_steps / decim + 2) * effects.len());
    let mut contrib = vec![[0.0; 3]; effects.len()];
    // the pusher's activation discrete, and the truth of the stall-identification quantities:
    // true airspeed, load factor at the CG, pitch rate, pitch attitude, acting elevator
    let mut pusher_rows: Vec<f64> = Vec::with_capacity(max_steps / decim + 2);
    let mut stall_rows: Vec<[f64; 5]> = Vec::with_capacity(max_steps / decim + 2);
    // the stall buffet, one frame per record sample at the true alpha (its own stream)
    let mut buffet = spec
        .buffet
        .as_ref()
        .map(|b| {
            let sched = BuffetSchedule::for_alpha_max(b, stall.alpha_max_deg);
            Buffet::new(b, sched, decim as f64 / spec.sim_hz, m.seed, stream::BUFFET)
        })
        .transpose()?;
    let mut buffet_rows: Vec<[f64; 3]> = Vec::new();
    // the Kirchhoff stall's truth: separation point, wind-axis C_L, C_m, C_D (with it on)
    let mut long_rows: Vec<[f64; 4]> = Vec::new();
    let (mut max_alpha, mut n_at, mut max_bank) = (f64::NEG_INFINITY, 1.0, 0.0f64);
    for step in 0..max_steps {
        let st = f.command();
        let (ad, thrust) = (st.air, st.thrust_n);
        if step % decim == 0 && f.model.kirchhoff.is_some() {
            // the separation state at this sample's time before it is recorded (the loop
            // advances the model's memory only when it integrates the step, after the
            // record): the recorded loads and x_sep_true are then those of x(t), not of
            // x(t − dt). Advancing twice to the same time is a no-op.
            let (inp, _) = f.sim.aero_input(&f.sim.x, &f.surfaces_start, thrust);
            let t = f.sim.t;
            if let Some(k) = f.model.kirchhoff.as_mut() {
                k.advance(t, &inp);
            }
        }
        let (sim, model, surfaces) = (&f.sim, &f.model, f.surfaces_start);
        if step % decim == 0 {
            let (xd, loads) = sim.derivative(model, &surfaces, thrust);
            let (inp, _) = sim.aero_input(&sim.x, &surfaces, thrust);
            let coeffs = model.coefficients(&inp);
            let qc = model.qualified_coeffs(&inp);
            if let Some(k) = &model.kirchhoff {
                let (d, x) = k.delta(&inp);
                long_rows.push([x, qc[0] + d[0], coeffs.cm, qc[1] + d[1]]);
            }
            model.contributions(&inp, &mut contrib);
            eff_rows.extend_from_slice(&contrib);
            truth_rows.push([
                sim.t,
                ad.alpha.to_degrees(),
                ad.beta.to_degrees(),
                coeffs.cl,
                coeffs.cn,
                coeffs.cy,
                qc[3],
                model.rolloff_cl(&inp),
            ]);
            // qualified Cn, CY kept in the last two columns of a second row array
            truth_rows.push([qc[5], qc[2], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
            let x = &sim.x;
            samples.push(TrueSample {
                t: sim.t,
                v_air: Vector3::new(x[ix::U], x[ix::V], x[ix::W]) - sim.gust,
                omega: Vector3::new(x[ix::P], x[ix::Q], x[ix::R]),
                omega_dot: Vector3::new(xd[ix::P], xd[ix::Q], xd[ix::R]),
                euler: Vector3::new(x[ix::PHI], x[ix::THETA], x[ix::PSI]),
                f_cg: loads.force / mass.mass_kg,
                tas: ad.tas,
                rho: ad.rho,
                h: x[ix::H],
                controls: surfaces,
                ct: [inp.ct_left, inp.ct_right],
            });
            let n = -loads.force.z / w;
            pusher_rows.push(if f.pusher.as_ref().is_some_and(Pusher::is_active) {
                1.0
            } else {
                0.0
            });
            stall_rows.push([
                ad.tas,
                n,
                x[ix::Q].to_degrees(),
                x[ix::THETA].to_degrees(),
                surfaces.de.to_degrees(),
            ]);
            let a_deg = ad.alpha.to_degrees();
            if let Some(b) = buffet.as_mut() {
                let [ay, az] = b.step(a_deg);
                buffet_rows.push([ay, az, b.schedule().rms_mps2(a_deg)]);
            }
            if a_deg >= stall.alpha_max_deg - 1.0 && max_alpha < stall.alpha_max_deg - 1.0 {
                n_at = n; // load factor at the stall onset (first reach of α_max − 1°)
            }
            max_alpha = max_alpha.max(a_deg);
            max_bank = max_bank.max(x[ix::PHI].abs().to_degrees());
        }
        if f.pilot.done(f.sim.t) {
            break;
        }
        f.integrate(&st, m.index)?;
    }
    let mut meas_cols = record(
        &samples,
        &ac,
        &mass.cg_offset(),
        m.flap_deg,
        meas,
        &NoiseSpec::default(),
        spec.noise_scale,
        m.seed,
        stream::SENSORS,
    );
    // the discretes: the pusher's activation, and the stall warning of the virtual aircraft's
    // warning computer, which compares the alpha vane's reading with a per-flap threshold
    let warning = stall_warning(
        &meas_cols[1],
        stall.alpha_max_deg - STALL_WARNING_MARGIN_DEG,
    );
    meas_cols.push(pusher_rows);
    meas_cols.push(warning);
    if buffet.is_some() {
        // structural vibration at the sensor: added to what the accelerometers record
        for (k, r) in buffet_rows.iter().enumerate() {
            meas_cols[10][k] += r[0];
            meas_cols[11][k] += r[1];
        }
    }
    // truth columns
    let ns = samples.len();
    let mut truth_names: Vec<String> = [
        "t",
        "alpha_true_deg",
        "beta_true_deg",
        "Cl_true",
        "Cn_true",
        "CY_true",
        "Cl_qual",
        "Cn_qual",
        "CY_qual",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let mut truth: Vec<Vec<f64>> = (0..9).map(|_| Vec::with_capacity(ns)).collect();
    for k in 0..ns {
        let a = &truth_rows[2 * k];
        let b = &truth_rows[2 * k + 1];
        for (j, v) in [a[0], a[1], a[2], a[3], a[4], a[5], a[6], b[0], b[1]]
            .iter()
            .enumerate()
        {
            truth[j].push(*v);
        }
    }
    for (ei, e) in effects.iter().enumerate() {
        for (ci, cname) in ["CY", "Cl", "Cn"].iter().enumerate() {
            truth_names.push(format!("d{cname}_{}", e.def.name));
            truth.push(
                (0..ns)
                    .map(|k| eff_rows[k * effects.len() + ei][ci])
                    .collect(),
            );
        }
    }
    if rolloff_on {
        truth_names.push("dCl_stochastic_rolloff".into());
        truth.push((0..ns).map(|k| truth_rows[2 * k][7]).collect());
    }
    for (j, name) in [
        "tas_true_mps",
        "nz_true",
        "q_true_dps",
        "theta_true_deg",
        "de_true_deg",
    ]
    .iter()
    .enumerate()
    {
        truth_names.push((*name).into());
        truth.push(stall_rows.iter().map(|r| r[j]).collect());
    }
    if buffet.is_some() {
        for (j, name) in [
            "buffet_ay_true_mps2",
            "buffet_az_true_mps2",
            "buffet_rms_true_mps2",
        ]
        .iter()
        .enumerate()
        {
            truth_names.push((*name).into());
            truth.push(buffet_rows.iter().map(|r| r[j]).collect());
        }
    }
    if !long_rows.is_empty() {
        for (j, name) in ["x_sep_true", "CL_true", "Cm_true", "CD_true"]
            .iter()
            .enumerate()
        {
            truth_names.push((*name).into());
            truth.push(long_rows.iter().map(|r| r[j]).collect());
        }
    }
    let id = format!(
        "m{:03}_f{:02}_{}_{}",
        m.index,
        m.flap_deg as i64,
        m.kind.name(),
        if m.pusher { "p" } else { "n" }
    );
    Ok(ManeuverResult {
        id,
        plan: *m,
        record_names: CHANNELS
            .iter()
            .chain(DISCRETE_CHANNELS.iter())
            .map(|s| s.to_string())
            .collect(),
        record: meas_cols,
        truth_names,
        truth,
        rolloff_draws: f
            .model
            .rolloff
            .as_ref()
            .map(|r| r.history.clone())
            .unwrap_or_default(),
        max_alpha_deg: max_alpha,
        load_factor_at_stall: n_at,
        pusher_fired: f.pusher_fired(),
        pusher_fired_at_s: f
            .pusher
            .as_ref()
            .map(|p| p.fired_at)
            .filter(|t| t.is_finite()),
        max_bank_deg: max_bank,
        mass_properties: varied,
        buffet: buffet.map(|b| BuffetTruth {
            schedule: *b.schedule(),
            modes: spec
                .buffet
                .as_ref()
                .map(|s| s.modes.clone())
                .unwrap_or_default(),
        }),
    })
}

/// Split the effect requests into aerodynamic effects, measurement effects and the roll-off switch.
///
/// # Errors
/// For an unknown effect name or an invalid roll-off configuration.
pub fn resolve_effects(
    spec: &CampaignSpec,
) -> Result<(Vec<ActiveEffect>, MeasurementEffects, bool, f64)> {
    let aero = active_effects(&spec.effects)?;
    let mut meas = MeasurementEffects::none();
    let mut rolloff_scale = 0.0;
    for e in &spec.effects {
        if e.name == "stochastic_rolloff" {
            rolloff_scale = e.magnitude;
        } else if crate::aircraft::effects::MEASUREMENT_EFFECTS.contains(&e.name.as_str()) {
            meas.set(&e.name, e.magnitude)?;
        }
    }
    spec.rolloff.validate()?;
    if let Some(b) = &spec.buffet {
        let decim = ((spec.sim_hz / spec.record_hz).round()).max(1.0);
        b.validate(decim / spec.sim_hz)?;
    }
    if let Some(v) = &spec.mass_properties {
        v.validate()?;
    }
    if let Some(c) = spec.vanes {
        for (name, k) in [("alpha_scale", c.alpha_scale), ("beta_scale", c.beta_scale)] {
            if !k.is_finite() || k.abs() >= 0.5 {
                return Err(AeroError::invalid(
                    format!("vanes.{name}"),
                    format!("{k}: a vane scale error is a fraction below 0.5 in size (e.g. 0.05)"),
                ));
            }
        }
        meas.vanes = c;
    }
    Ok((aero, meas, rolloff_scale > 0.0, rolloff_scale))
}

/// Run a whole campaign (in parallel with the `parallel` feature; same result either way).
///
/// # Errors
/// The first maneuver error, with its index.
pub fn run_campaign(spec: &CampaignSpec) -> Result<Vec<ManeuverResult>> {
    let (qual, _) = adx37_models()?;
    let (aero, meas, rolloff_on, scale) = resolve_effects(spec)?;
    let mut spec = spec.clone();
    spec.rolloff.scale *= if rolloff_on { scale } else { 1.0 };
    let plans = plan(&spec);
    let run = |m: &ManeuverPlan| run_maneuver(&spec, qual, &aero, &meas, rolloff_on, m);
    #[cfg(feature = "parallel")]
    let results: Vec<Result<ManeuverResult>> = {
        use rayon::prelude::*;
        plans.par_iter().map(run).collect()
    };
    #[cfg(not(feature = "parallel"))]
    let results: Vec<Result<ManeuverResult>> = plans.iter().map(run).collect();
    results.into_iter().collect()
}

/// The ADX-37 qualified model and its slices at the five flap settings, built once.
///
/// # Errors
/// Only if a table is malformed (a bug).
pub fn adx37_models() -> Result<&'static (QualifiedModel, Vec<FlapModel>)> {
    static MODELS: std::sync::OnceLock<
        std::result::Result<(QualifiedModel, Vec<FlapModel>), String>,
    > = std::sync::OnceLock::new();
    let built = MODELS.get_or_init(|| {
        let q = QualifiedModel::adx37(&adx37()).map_err(|e| e.to_string())?;
        let slices = FLAP_STALL
            .iter()
            .map(|f| q.at_flap(f.flap_deg))
            .collect::<Result<Vec<_>>>()
            .map_err(|e| e.to_string())?;
        Ok((q, slices))
    });
    built
        .as_ref()
        .map_err(|e| AeroError::invalid("ADX-37 qualified model", e.clone()))
}

/// The qualified model of `q` at `flap_deg`: a cached slice for the five standard settings.
pub(crate) fn slice(q: &QualifiedModel, flap_deg: f64) -> Result<FlapModel> {
    let (_, slices) = adx37_models()?;
    match slices.iter().find(|s| s.flap_deg == flap_deg) {
        Some(s) if q.aircraft == adx37() => Ok(s.clone()),
        _ => q.at_flap(flap_deg),
    }
}

/// Replay recorded controls (deg) and thrust coefficients on the ADX-37 from
/// state `x0`: the qualified model when `effects` is empty, else the truth
/// model with those effects and, when `rolloff_seed` is given, the roll-off.
/// Returns the 12 states at each step (n + 1 rows).
///
/// # Errors
/// For unknown effects or mismatched input lengths.
pub fn replay_adx37(
    flap_deg: f64,
    effects: &[EffectSpec],
    rolloff_seed: Option<u64>,
    x0: [f64; 12],
    dt: f64,
    controls_deg: &[[f64; 5]],
    ct: &[[f64; 2]],
) -> Result<Vec<[f64; 12]>> {
    let (qual, _) = adx37_models()?;
    let aero = active_effects(effects)?;
    let rolloff = replay_rolloff(flap_deg, rolloff_seed)?;
    let mut model = TruthAero::new(slice(qual, flap_deg)?, aero, rolloff);
    replay_with(&mut model, flap_deg, x0, dt, controls_deg, ct)
}

/// What an open-loop replay of a Δ model flies over the qualified ADX-37
/// ([`replay_adx37_extended`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExtendedLayers {
    /// The extended model: the lateral Δ (thesis Eq. 3.12) and the stored longitudinal stall.
    Extended,
    /// The stored longitudinal stall alone, no lateral Δ: the baseline against which the Δ's
    /// blend-out is checked (pre-stall regression), and the stall's own effect is measured
    /// against the qualified model.
    StallOnly,
}

/// Replay recorded controls on the ADX-37 with the **extended** model: the qualified
/// model plus the fitted Δ model `delta` (thesis Section 4.3, Eq. 3.12), and the
/// stochastic roll-off when `rolloff_seed` is given. Arguments and result as
/// [`replay_adx37`]. The stall the model stores for the flap replaces the qualified static
/// C_L, C_m curves when it was fitted on the ADX-37's known terms
/// ([`DeltaModel::adx37_stall`]), as in the closed-loop replays
/// ([`crate::sim::closed_loop::closed_loop_adx37`]); `layers` chooses whether the lateral Δ
/// flies too.
///
/// # Errors
/// For a Δ model the loop cannot run (see [`ExtendedAero::new`]), invalid stored stall
/// parameters, or mismatched inputs.
#[allow(clippy::too_many_arguments)]
pub fn replay_adx37_extended(
    flap_deg: f64,
    delta: &DeltaModel,
    layers: ExtendedLayers,
    rolloff_seed: Option<u64>,
    x0: [f64; 12],
    dt: f64,
    controls_deg: &[[f64; 5]],
    ct: &[[f64; 2]],
) -> Result<Vec<[f64; 12]>> {
    let (qual, _) = adx37_models()?;
    let rolloff = replay_rolloff(flap_deg, rolloff_seed)?;
    let stall = delta
        .adx37_stall(flap_deg)
        .map(|(p, d)| KirchhoffStall::new(qual, p).and_then(|k| k.with_drag(d)))
        .transpose()?;
    let mut base =
        TruthAero::new(slice(qual, flap_deg)?, Vec::new(), rolloff).with_kirchhoff(stall);
    match layers {
        ExtendedLayers::Extended => {
            let mut model = ExtendedAero::new(base, delta)?;
            replay_with(&mut model, flap_deg, x0, dt, controls_deg, ct)
        }
        ExtendedLayers::StallOnly => replay_with(&mut base, flap_deg, x0, dt, controls_deg, ct),
    }
}

fn replay_rolloff(flap_deg: f64, seed: Option<u64>) -> Result<Option<RollOff>> {
    seed.map(|seed| RollOff::new(RollOffConfig::default(), flap_deg, seed, stream::ROLLOFF))
        .transpose()
}

fn replay_with<M: AeroModel>(
    model: &mut M,
    flap_deg: f64,
    x0: [f64; 12],
    dt: f64,
    controls_deg: &[[f64; 5]],
    ct: &[[f64; 2]],
) -> Result<Vec<[f64; 12]>> {
    let mut sim = Simulator::new(adx37(), flap_deg, nalgebra::SVector::from(x0), dt);
    replay_states(&mut sim, model, controls_deg, ct)
}

/// Fly `sim` with `model` through recorded controls (da, de, dr, dsl, dsr in deg, Etkin) and
/// thrust coefficients per engine; the 12 states at each step (n + 1 rows).
///
/// # Errors
/// Mismatched input lengths ([`crate::sim::maneuver::replay_ct`]).
pub(crate) fn replay_states<M: AeroModel + ?Sized>(
    sim: &mut Simulator,
    model: &mut M,
    controls_deg: &[[f64; 5]],
    ct: &[[f64; 2]],
) -> Result<Vec<[f64; 12]>> {
    let d = f64::to_radians;
    let controls: Vec<Controls> = controls_deg
        .iter()
        .map(|c| Controls {
            da: d(c[0]),
            de: d(c[1]),
            dr: d(c[2]),
            dsl: d(c[3]),
            dsr: d(c[4]),
        })
        .collect();
    let states = crate::sim::maneuver::replay_ct(sim, model, &controls, ct)?;
    Ok(states.iter().map(|x| x.data.0[0]).collect())
}

/// The wings-level trim of the ADX-37 qualified model at `v` (m/s), `h` (m), flap (deg):
/// (12 states, controls δa, δe, δr, δsl, δsr in deg, C_T per engine).
///
/// # Errors
/// When no trim exists (below the stall speed).
pub fn trim_adx37(flap_deg: f64, v: f64, h: f64) -> Result<([f64; 12], [f64; 5], f64)> {
    let ac = adx37();
    let (qual, _) = adx37_models()?;
    let model = TruthAero::new(slice(qual, flap_deg)?, Vec::new(), None);
    let sim = Simulator::new(ac.clone(), flap_deg, nalgebra::SVector::zeros(), 0.01);
    let tr = trim(&sim, &model, v, h)?;
    let c = tr.controls;
    let qs = sim.air(&tr.x).qbar * ac.s_m2;
    Ok((
        tr.x.data.0[0],
        [c.da, c.de, c.dr, c.dsl, c.dsr].map(f64::to_degrees),
        tr.thrust_n / qs,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aircraft::truth::EffectSpec;
    use crate::sim::aero::AeroModel;

    fn quick(seed: u64) -> CampaignSpec {
        CampaignSpec {
            seed,
            repetitions: 1,
            effects: vec![EffectSpec {
                name: "stochastic_rolloff".into(),
                magnitude: 1.0,
                shape: None,
            }],
            ..CampaignSpec::default()
        }
    }

    #[test]
    fn maneuvers_reach_the_stall_and_recover() {
        let r = run_campaign(&quick(3)).unwrap();
        assert_eq!(r.len(), 40);
        reach_the_stall_and_recover(&r);
    }

    fn reach_the_stall_and_recover(r: &[ManeuverResult]) {
        for m in r {
            let stall = FLAP_STALL
                .iter()
                .find(|f| f.flap_deg == m.plan.flap_deg)
                .unwrap();
            assert!(
                m.max_alpha_deg > stall.alpha_max_deg - 3.5,
                "{}: max alpha {}",
                m.id,
                m.max_alpha_deg
            );
            assert!(
                m.max_alpha_deg < 40.0,
                "{}: max alpha {}",
                m.id,
                m.max_alpha_deg
            );
            if m.plan.pusher && matches!(m.plan.kind, Kind::Straight | Kind::Turning) {
                assert!(m.pusher_fired, "{}", m.id);
            }
            if m.plan.pusher {
                // the pusher bounds alpha (a wing drop may end the approach earlier)
                assert!(m.max_alpha_deg < stall.alpha_max_deg + 8.0, "{}", m.id);
            }
            if m.plan.kind == Kind::Accelerated {
                assert!(
                    m.load_factor_at_stall > 1.3,
                    "{}: n = {}",
                    m.id,
                    m.load_factor_at_stall
                );
            }
            let t = &m.record[0];
            assert!(
                t.len() > 500 && *t.last().unwrap() < 150.0,
                "{}: duration {}",
                m.id,
                t.last().unwrap()
            );
        }
    }

    #[test]
    fn records_carry_the_pusher_and_stall_warning_discretes() {
        let mut s = quick(3);
        s.only = vec![0, 1, 12];
        for m in run_campaign(&s).unwrap() {
            let col = |name: &str| {
                let k = m.record_names.iter().position(|c| c == name).unwrap();
                &m.record[k]
            };
            let (t, alpha) = (col("t"), col("alpha_deg"));
            let (push, warn) = (col("pusher_active"), col("stall_warning"));
            assert!(push.iter().chain(warn).all(|&v| v == 0.0 || v == 1.0));
            let first = |x: &[f64]| x.iter().position(|&v| v == 1.0);
            // the pusher's discrete starts at the first record sample at or after its firing
            match (m.pusher_fired_at_s, first(push)) {
                (Some(tf), Some(k)) => {
                    assert!(
                        t[k] >= tf - 1e-9 && t[k] - tf < 1.5 / s.record_hz,
                        "{}",
                        m.id
                    );
                }
                (None, None) => assert!(!m.plan.pusher || !m.pusher_fired, "{}", m.id),
                other => panic!("{}: {other:?}", m.id),
            }
            // the warning starts where the vane first reads the flap's threshold
            let stall = FLAP_STALL
                .iter()
                .find(|f| f.flap_deg == m.plan.flap_deg)
                .unwrap();
            let on = stall.alpha_max_deg - STALL_WARNING_MARGIN_DEG;
            let k = first(warn).unwrap();
            assert!(
                alpha[k] >= on && alpha[..k].iter().all(|&a| a < on),
                "{}",
                m.id
            );
            let tk = m.truth_names.iter().position(|c| c == "nz_true").unwrap();
            assert_eq!(m.truth[tk].len(), t.len());
        }
    }

    #[cfg(feature = "parallel")]
    #[test]
    fn thread_count_does_not_change_results() {
        let mut s = quick(8);
        s.only = vec![0, 3, 9, 14];
        let mut varied = s.clone();
        varied.mass_properties = Some(MassVariation {
            cg_range_m: [0.21, 0.05, 0.1],
            mass_range: 0.1,
            inertia_range: 0.1,
        });
        for s in [s, varied] {
            let many = run_campaign(&s).unwrap();
            let one = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .unwrap()
                .install(|| run_campaign(&s).unwrap());
            for (a, b) in many.iter().zip(&one) {
                assert_eq!(a.record, b.record);
                assert_eq!(a.truth, b.truth);
                assert_eq!(a.mass_properties, b.mass_properties);
            }
        }
    }

    #[test]
    fn same_seed_same_campaign() {
        let mut s = quick(5);
        s.only = vec![1, 17];
        let a = run_campaign(&s).unwrap();
        let b = run_campaign(&s).unwrap();
        assert_eq!(a[1].record, b[1].record);
        s.seed = 6;
        let c = run_campaign(&s).unwrap();
        assert_ne!(a[1].record, c[1].record);
    }

    /// Fly the maneuvers of `spec` with the mass properties `mass` (reported).
    fn fly_with(spec: &CampaignSpec, mass: &MassProperties) -> Vec<ManeuverResult> {
        let (qual, _) = adx37_models().unwrap();
        let (aero, meas, rolloff_on, _) = resolve_effects(spec).unwrap();
        plan(spec)
            .iter()
            .map(|m| fly(spec, qual, &aero, &meas, rolloff_on, m, Some(*mass)).unwrap())
            .collect()
    }

    #[test]
    fn zero_ranges_fly_the_nominal_campaign_bit_for_bit() {
        let mut off = quick(4);
        off.only = vec![0, 7, 13, 26, 39];
        let mut zero = off.clone();
        zero.mass_properties = Some(MassVariation::default());
        let (a, b) = (run_campaign(&off).unwrap(), run_campaign(&zero).unwrap());
        let nominal = MassProperties::nominal(&adx37());
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(x.record, y.record, "{}", x.id);
            assert_eq!(x.truth, y.truth, "{}", x.id);
            assert_eq!(x.mass_properties, None);
            assert_eq!(y.mass_properties, Some(nominal));
            assert!(!x.meta_json().contains("mass_properties"));
            assert!(y
                .meta_json()
                .contains("\"mass_properties\":{\"mass_kg\":15000.0"));
        }
        // the default spec's JSON has no trace of the option (campaign.json unchanged)
        assert!(!CampaignSpec::default().to_json().contains("mass"));
        let parsed = CampaignSpec::from_json(&zero.to_json()).unwrap();
        assert_eq!(parsed, zero);
        // and a varied campaign differs, with the same maneuver seeds
        let mut varied = off.clone();
        varied.mass_properties = Some(MassVariation {
            cg_range_m: [0.21, 0.05, 0.1],
            mass_range: 0.1,
            inertia_range: 0.1,
        });
        let c = run_campaign(&varied).unwrap();
        for (x, z) in a.iter().zip(&c) {
            assert_eq!(x.plan, z.plan);
            assert_ne!(x.record, z.record, "{}", x.id);
        }
    }

    #[test]
    fn buffet_adds_its_vibration_to_the_accelerometers_and_changes_nothing_else() {
        // the same maneuvers without and with the buffet: every record column but ay, az is
        // bit for bit the same, and ay, az differ by exactly the truth's buffet columns (the
        // flight is untouched); the buffet is silent below the flap's onset alpha and present
        // above it; the default spec's JSON has no trace of the option
        let mut off = quick(4);
        off.only = vec![0, 9, 21];
        let mut on = off.clone();
        on.buffet = Some(BuffetSpec::default());
        let (a, b) = (run_campaign(&off).unwrap(), run_campaign(&on).unwrap());
        assert!(!CampaignSpec::default().to_json().contains("buffet"));
        for (x, y) in a.iter().zip(&b) {
            assert!(x.buffet.is_none() && !x.meta_json().contains("buffet"));
            let truth = y.buffet.as_ref().unwrap();
            assert_eq!(x.truth_names, y.truth_names[..x.truth_names.len()]);
            assert_eq!(x.truth[..], y.truth[..x.truth.len()]);
            let col = |name: &str| {
                let k = y.truth_names.iter().position(|c| c == name).unwrap();
                &y.truth[k]
            };
            let (by, bz, rms) = (
                col("buffet_ay_true_mps2"),
                col("buffet_az_true_mps2"),
                col("buffet_rms_true_mps2"),
            );
            for (k, name) in x.record_names.iter().enumerate() {
                match name.as_str() {
                    "ay_mps2" | "az_mps2" => {
                        let add = if name == "ay_mps2" { by } else { bz };
                        let pairs = y.record[k].iter().zip(&x.record[k]);
                        for (i, (d, (got, base))) in add.iter().zip(pairs).enumerate() {
                            assert_eq!(*got, base + d, "{} {i}", x.id);
                        }
                    }
                    _ => assert_eq!(x.record[k], y.record[k], "{}: {name}", x.id),
                }
            }
            let alpha = col("alpha_true_deg");
            let onset = truth.schedule.onset_alpha_deg;
            let below: Vec<usize> = (0..alpha.len()).filter(|&i| alpha[i] < onset).collect();
            // silent while alpha has stayed below the onset (before the first crossing the
            // modes are at rest)
            let first_above = alpha
                .iter()
                .position(|&v| v >= onset)
                .unwrap_or(alpha.len());
            assert!(below.iter().all(|&i| rms[i] == 0.0));
            assert!(bz[..first_above].iter().all(|&v| v == 0.0), "{}", x.id);
            if first_above < alpha.len() {
                let peak = bz[first_above..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
                assert!(peak > truth.schedule.onset_rms_mps2, "{}: {peak}", x.id);
            }
            let stall = FLAP_STALL
                .iter()
                .find(|f| f.flap_deg == x.plan.flap_deg)
                .unwrap();
            assert_eq!(onset, stall.alpha_max_deg - 2.0);
        }
        // a mode above the record's Nyquist frequency is refused before flying
        let mut bad = on.clone();
        bad.buffet.as_mut().unwrap().modes[0].freq_hz = 30.0;
        let e = run_campaign(&bad).unwrap_err().to_string();
        assert!(e.contains("buffet.modes[0].freq_hz"), "{e}");
    }

    #[test]
    fn bad_mass_ranges_are_refused_before_flying() {
        let mut s = quick(1);
        s.mass_properties = Some(MassVariation {
            cg_range_m: [0.5, 0.0, 0.0],
            ..MassVariation::default()
        });
        let e = run_campaign(&s).unwrap_err().to_string();
        assert!(
            e.contains("cg_range_m x = 0.5") && e.contains("0.39"),
            "{e}"
        );
        let e = CampaignSpec::from_json(r#"{"mass_properties": {"cg_range": [0.1, 0, 0]}}"#)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cg_range"), "{e}");
    }

    #[test]
    fn dynamics_about_the_cg_transfer_to_the_datums_coefficients() {
        // on the simulator's exact state through a stall with the CG off the datum: the rigid
        // body's I ω̇ + ω × (I ω + h_p) about the CG plus d × F is the truth model's moment
        // about the datum (C_l q̄Sb, C_m q̄Sc̄, C_n q̄Sb), and F/m is what the EOM accelerate with
        let mut s = quick(2);
        s.only = vec![3];
        let (qual, _) = adx37_models().unwrap();
        let (aero, _, rolloff_on, _) = resolve_effects(&s).unwrap();
        let m = plan(&s)[0];
        let mass = MassProperties {
            mass_kg: 15_600.0,
            cg_m: [-0.1, 0.025, 0.05],
            ixx: 1.5e5,
            iyy: 2.8e5,
            izz: 3.2e5,
            ixz: 1.25e4,
        };
        let mut f = Flight::with_mass(&s, qual, &aero, rolloff_on, &m, &mass).unwrap();
        let ac = adx37();
        let d = mass.cg_offset();
        let (mut checked, mut max_transfer, mut max_alpha) = (0, 0.0f64, 0.0f64);
        while !f.done() {
            let st = f.command();
            if f.step_index % 50 == 0 {
                let sim = &f.sim;
                let (xd, loads) = sim.derivative(&f.model, &f.surfaces_start, st.thrust_n);
                let (inp, ad) = sim.aero_input(&sim.x, &f.surfaces_start, st.thrust_n);
                let co = f.model.coefficients(&inp);
                let qs = ad.qbar * ac.s_m2;
                let w = Vector3::new(sim.x[ix::P], sim.x[ix::Q], sim.x[ix::R]);
                let wd = Vector3::new(xd[ix::P], xd[ix::Q], xd[ix::R]);
                let i = sim.body.inertia;
                let h = i * w + Vector3::new(-loads.prop_momentum, 0.0, 0.0);
                let m_cg = i * wd + w.cross(&h);
                let m_datum = m_cg + d.cross(&loads.force);
                let want = Vector3::new(
                    co.cl * qs * ac.b_m,
                    co.cm * qs * ac.cbar_m,
                    co.cn * qs * ac.b_m,
                );
                let f_body = Vector3::new(co.cx, co.cy, co.cz) * qs;
                assert!(
                    (m_datum - want).norm() < 1e-6 * want.norm().max(1e3),
                    "{m_datum} vs {want}"
                );
                assert!((loads.force - f_body).norm() < 1e-9 * f_body.norm());
                max_transfer = max_transfer.max(d.cross(&loads.force).norm());
                max_alpha = max_alpha.max(inp.alpha.to_degrees());
                checked += 1;
            }
            f.integrate(&st, m.index).unwrap();
        }
        assert!(
            checked > 40 && max_alpha > f.stall.alpha_max_deg - 3.5,
            "{checked} {max_alpha}"
        );
        // the transfer is not negligible: d_x W ≈ 0.1 m × 150 kN
        assert!(max_transfer > 1.0e4, "{max_transfer}");
    }

    #[test]
    fn cg_at_the_range_limits_still_trims_reaches_the_stall_and_recovers() {
        // every maneuver of a quick campaign with the CG at the aft (lighter aircraft, lower
        // stall speed) and forward (heavier) end of MAX_CG_X_RANGE_M, y and z off the datum
        let ac = adx37();
        let half = crate::sim::mass::MAX_CG_X_RANGE_M / 2.0;
        for (dx, scale) in [(-half, 0.95), (half, 1.05)] {
            let mass = MassProperties {
                mass_kg: ac.mass_kg * scale,
                cg_m: [dx, 0.025, 0.05],
                ixx: ac.ixx * scale,
                iyy: ac.iyy * scale,
                izz: ac.izz * scale,
                ixz: ac.ixz * scale,
            };
            let r = fly_with(&quick(3), &mass);
            assert_eq!(r.len(), 40);
            reach_the_stall_and_recover(&r);
        }
    }
}
