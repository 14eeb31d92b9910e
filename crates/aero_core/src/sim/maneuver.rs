//! The simulation loop (thesis Figure 3.2): aerodynamic model → loads →
//! Eq. 3.1 → RK4, at a fixed step, with the atmosphere, gusts, engines and
//! actuators around it; trim; and replay of recorded control positions
//! (thesis Section 4.3).

use nalgebra::Vector3;

use crate::aircraft::turboprop::AircraftRef;
use crate::error::{AeroError, Result};
use crate::sim::aero::{AeroInput, AeroModel, Controls};
use crate::sim::atmosphere::{isa, G0};
use crate::sim::eom::{derivative, ix, rk4_step_from, rk4_step_stages, Loads, RigidBody, StateVec};
use crate::sim::mass::{moment_about_cg, MassProperties};

/// The 6-DOF aircraft: state, environment, and the coupling to an [`AeroModel`].
#[derive(Debug, Clone)]
pub struct Simulator {
    /// Reference values (geometry, mass, propellers).
    pub aircraft: AircraftRef,
    /// Rigid body: mass and inertia about the actual CG.
    pub body: RigidBody,
    /// CG position from the aircraft's datum (the aerodynamic model's moment
    /// reference centre), body axes, m: the model's moments are transferred to
    /// the CG ([`moment_about_cg`]). Zero for the nominal aircraft.
    pub cg_offset: Vector3<f64>,
    /// State (see [`crate::sim::eom`]).
    pub x: StateVec,
    /// Time, s.
    pub t: f64,
    /// Fixed step, s.
    pub dt: f64,
    /// Flap setting, deg.
    pub flap_deg: f64,
    /// Gust velocity (body axes), m/s: the air moves with it.
    pub gust: Vector3<f64>,
    /// α̇ felt by the aerodynamics, rad/s: the backward difference of the air-relative α
    /// over each step, low-passed with [`FLOW_RATE_TAU_S`] (see there).
    pub alpha_dot: f64,
    /// β̇ felt by the aerodynamics, rad/s (as `alpha_dot`).
    pub beta_dot: f64,
    prev_ab: Option<(f64, f64)>,
    /// Atmosphere held over the RK4 stages of a step (altitude changes < 1 m per step).
    frozen: Option<crate::sim::atmosphere::Air>,
}

/// Time constant of the first-order low-pass through which the aerodynamics feel the flow
/// angles' rates α̇, β̇, s. The air-relative angles move with the gusts, whose Dryden
/// components change by a white-noise increment every step: their raw backward difference
/// carries a broadband noise (its variance grows as 1/dt) that no wing responds to (the
/// unsteady lift follows a gust through the Sears/Küssner lag, over a few chord lengths of
/// travel) and no sensor could record. τ ≈ c̄/V near the stall (2.1 m / 55 m/s = 0.04 s).
/// Before this filter a truth effect in β̇ (sideslip rate) put most of its energy into that
/// noise: the injected ΔC_l correlated with the β̇ a flight test measures (vane, smoothed and
/// differentiated by `ingest`) at 0.55 with 0.5 m/s of turbulence and 0.91 in still air;
/// with it, 0.93 and 0.99 (0.81 at 1 m/s), and the fitted slope is 0.96 of the truth's.
pub const FLOW_RATE_TAU_S: f64 = 0.04;

/// Air-relative quantities at a state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AirData {
    /// Alpha, rad.
    pub alpha: f64,
    /// Beta, rad.
    pub beta: f64,
    /// True airspeed, m/s.
    pub tas: f64,
    /// Density, kg/m³.
    pub rho: f64,
    /// Dynamic pressure, Pa.
    pub qbar: f64,
    /// Speed of sound, m/s.
    pub sound: f64,
}

impl Simulator {
    /// A simulator at state `x` with step `dt` (s): the nominal mass properties
    /// of `aircraft`, the CG at its datum.
    pub fn new(aircraft: AircraftRef, flap_deg: f64, x: StateVec, dt: f64) -> Self {
        let nominal = MassProperties::nominal(&aircraft);
        Self::with_mass(aircraft, flap_deg, x, dt, &nominal)
    }

    /// A simulator flying `aircraft` with mass properties `mass` (mass, inertia
    /// about the CG, CG position from the datum).
    pub fn with_mass(
        aircraft: AircraftRef,
        flap_deg: f64,
        x: StateVec,
        dt: f64,
        mass: &MassProperties,
    ) -> Self {
        let body = RigidBody::new(mass.mass_kg, mass.ixx, mass.iyy, mass.izz, mass.ixz);
        Simulator {
            aircraft,
            body,
            cg_offset: mass.cg_offset(),
            x,
            t: 0.0,
            dt,
            flap_deg,
            gust: Vector3::zeros(),
            alpha_dot: 0.0,
            beta_dot: 0.0,
            prev_ab: None,
            frozen: None,
        }
    }

    /// Air data at state `x` (gusts subtracted).
    #[inline]
    pub fn air(&self, x: &StateVec) -> AirData {
        let u = x[ix::U] - self.gust.x;
        let v = x[ix::V] - self.gust.y;
        let w = x[ix::W] - self.gust.z;
        let tas = (u * u + v * v + w * w).sqrt().max(1e-3);
        let a = self.frozen.unwrap_or_else(|| isa(x[ix::H]));
        AirData {
            alpha: w.atan2(u),
            beta: (v / tas).clamp(-1.0, 1.0).asin(),
            tas,
            rho: a.density_kgm3,
            qbar: 0.5 * a.density_kgm3 * tas * tas,
            sound: a.sound_speed_mps,
        }
    }

    /// The model input at state `x` with surfaces `c` and engine thrusts (N).
    #[inline]
    pub fn aero_input(
        &self,
        x: &StateVec,
        c: &Controls,
        thrust_n: [f64; 2],
    ) -> (AeroInput, AirData) {
        let ad = self.air(x);
        let ac = &self.aircraft;
        let qs = ad.qbar * ac.s_m2;
        let k = 1.0 / (2.0 * ad.tas);
        (
            AeroInput {
                alpha: ad.alpha,
                beta: ad.beta,
                p_hat: x[ix::P] * ac.b_m * k,
                q_hat: x[ix::Q] * ac.cbar_m * k,
                r_hat: x[ix::R] * ac.b_m * k,
                alpha_dot: self.alpha_dot,
                beta_dot: self.beta_dot,
                controls: *c,
                flap_deg: self.flap_deg,
                ct_left: thrust_n[0] / qs,
                ct_right: thrust_n[1] / qs,
                mach: ad.tas / ad.sound,
                tas: ad.tas,
            },
            ad,
        )
    }

    /// Loads at state `x` from `model`.
    #[inline]
    pub fn loads<M: AeroModel + ?Sized>(
        &self,
        model: &M,
        x: &StateVec,
        c: &Controls,
        thrust_n: [f64; 2],
    ) -> Loads {
        let (inp, ad) = self.aero_input(x, c, thrust_n);
        self.loads_at(model, &inp, &ad)
    }

    /// Loads from `model` at an already formed input and its air data: the
    /// model's moments are about the datum, the loads' about the CG.
    #[inline]
    fn loads_at<M: AeroModel + ?Sized>(&self, model: &M, inp: &AeroInput, ad: &AirData) -> Loads {
        let co = model.coefficients(inp);
        let ac = &self.aircraft;
        let qs = ad.qbar * ac.s_m2;
        let prop = if ac.n_engines >= 2 { 2.0 } else { 1.0 };
        let force = Vector3::new(co.cx, co.cy, co.cz) * qs;
        let m_datum = Vector3::new(
            co.cl * qs * ac.b_m,
            co.cm * qs * ac.cbar_m,
            co.cn * qs * ac.b_m,
        );
        // the nominal aircraft skips the transfer: its loads stay bit for bit what they were
        let moment = if self.cg_offset == Vector3::zeros() {
            m_datum
        } else {
            moment_about_cg(&m_datum, &force, &self.cg_offset)
        };
        Loads {
            force,
            moment,
            prop_momentum: prop * ac.prop_inertia * ac.prop_rpm * std::f64::consts::PI / 30.0,
        }
    }

    /// Advance one fixed step with surfaces `c` (rad) and thrusts (N) held over it
    /// (zero-order hold: the simulator-loop form, one control sample per frame).
    pub fn step<M: AeroModel + ?Sized>(&mut self, model: &mut M, c: &Controls, thrust_n: [f64; 2]) {
        self.frozen = Some(isa(self.x[ix::H]));
        self.step_frozen(model, c, c, thrust_n);
    }

    /// Advance one fixed step while the surfaces move linearly from `c0` (their
    /// position at the step start) to `c1` (at its end): first-order hold, the
    /// RK4 stages see the surfaces where they are at the stage time (t, t + dt/2,
    /// t + dt). This is how a continuous actuator acts; with a zero-order hold the
    /// moment of the surface reached at the step's end acts over the whole step,
    /// half a step early, and a record of the positions at the sample times then
    /// lags the moments it caused by dt/2 (a built-in time skew between controls
    /// and measured coefficients).
    pub fn step_interp<M: AeroModel + ?Sized>(
        &mut self,
        model: &mut M,
        c0: &Controls,
        c1: &Controls,
        thrust_n: [f64; 2],
    ) {
        self.frozen = Some(isa(self.x[ix::H]));
        self.step_frozen(model, c0, c1, thrust_n);
    }

    /// Advance one step with thrust from thrust coefficients C_T (T = C_T q̄ S at the step start).
    pub fn step_ct<M: AeroModel + ?Sized>(&mut self, model: &mut M, c: &Controls, ct: [f64; 2]) {
        self.step_ct_interp(model, c, c, ct);
    }

    /// [`Simulator::step_ct`] with the surfaces moving linearly from `c0` to `c1`
    /// over the step ([`Simulator::step_interp`]).
    pub fn step_ct_interp<M: AeroModel + ?Sized>(
        &mut self,
        model: &mut M,
        c0: &Controls,
        c1: &Controls,
        ct: [f64; 2],
    ) {
        self.frozen = Some(isa(self.x[ix::H]));
        let qs = self.air(&self.x).qbar * self.aircraft.s_m2;
        self.step_frozen(model, c0, c1, [ct[0] * qs, ct[1] * qs]);
    }

    fn step_frozen<M: AeroModel + ?Sized>(
        &mut self,
        model: &mut M,
        c0: &Controls,
        c1: &Controls,
        thrust_n: [f64; 2],
    ) {
        let (inp, ad) = self.aero_input(&self.x, c0, thrust_n);
        model.advance(self.t, &inp);
        let x0 = self.x;
        let me = &*self;
        let m = &*model;
        // the first stage's input is the one just computed (same state, atmosphere, α̇)
        let first = me.loads_at(m, &inp, &ad);
        let next = if c0 == c1 {
            rk4_step_from(&me.body, &x0, me.dt, &first, |x| {
                me.loads(m, x, c0, thrust_n)
            })
        } else {
            let mid = c0.lerp(c1, 0.5);
            rk4_step_stages(
                &me.body,
                &x0,
                me.dt,
                &first,
                |x| me.loads(m, x, &mid, thrust_n),
                |x| me.loads(m, x, c1, thrust_n),
            )
        };
        self.x = next;
        self.t += self.dt;
        let ad = self.air(&self.x); // angles only: the frozen atmosphere is fine here
        self.frozen = None;
        if let Some((a0, b0)) = self.prev_ab {
            let w = self.dt / (FLOW_RATE_TAU_S + self.dt);
            self.alpha_dot += w * ((ad.alpha - a0) / self.dt - self.alpha_dot);
            self.beta_dot += w * ((ad.beta - b0) / self.dt - self.beta_dot);
        }
        self.prev_ab = Some((ad.alpha, ad.beta));
    }

    /// State derivative at the current state (for accelerations and sensors).
    pub fn derivative<M: AeroModel + ?Sized>(
        &self,
        model: &M,
        c: &Controls,
        thrust_n: [f64; 2],
    ) -> (StateVec, Loads) {
        let l = self.loads(model, &self.x, c, thrust_n);
        (derivative(&self.body, &self.x, &l), l)
    }
}

/// A wings-level trimmed flight condition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trim {
    /// State (θ = α: level flight).
    pub x: StateVec,
    /// Surface positions, rad.
    pub controls: Controls,
    /// Thrust per engine, N.
    pub thrust_n: f64,
}

/// Wings-level, level-flight trim at airspeed `v` (m/s), altitude `h` (m):
/// α, β, δe, thrust, δa, δr such that u̇ = v̇ = ẇ = ṗ = q̇ = ṙ = 0 (Newton with
/// a finite-difference Jacobian; the lateral unknowns balance the
/// propellers' asymmetric slipstream terms).
///
/// # Errors
/// [`AeroError::NoConvergence`] when the Newton iteration fails (speed below stall).
pub fn trim<M: AeroModel + ?Sized>(sim: &Simulator, model: &M, v: f64, h: f64) -> Result<Trim> {
    type V6 = nalgebra::SVector<f64, 6>;
    let w = sim.body.mass * G0;
    let build = |z: &V6| {
        let mut x = StateVec::zeros();
        let (a, b) = (z[0], z[1]);
        x[ix::U] = v * a.cos() * b.cos();
        x[ix::V] = v * b.sin();
        x[ix::W] = v * a.sin() * b.cos();
        x[ix::THETA] = (x[ix::W] / x[ix::U]).atan();
        x[ix::H] = h;
        let c = Controls {
            da: z[4],
            de: z[2],
            dr: z[5],
            ..Controls::default()
        };
        (x, c, z[3] * w)
    };
    let resid = |z: &V6| {
        let (x, c, t) = build(z);
        let d = derivative(&sim.body, &x, &sim.loads(model, &x, &c, [t, t]));
        V6::from([d[ix::U], d[ix::V], d[ix::W], d[ix::P], d[ix::Q], d[ix::R]])
    };
    let mut z = V6::from([0.08, 0.0, 0.0, 0.05, 0.0, 0.0]);
    let mut r = resid(&z);
    for _ in 0..60 {
        if r.norm() < 1e-11 {
            break;
        }
        let mut j = nalgebra::SMatrix::<f64, 6, 6>::zeros();
        for k in 0..6 {
            let mut zp = z;
            zp[k] += 1e-7;
            j.set_column(k, &((resid(&zp) - r) / 1e-7));
        }
        let Some(dz) = j.lu().solve(&(-r)) else {
            break;
        };
        z += dz.map(|d| d.clamp(-0.05, 0.05));
        r = resid(&z);
    }
    if r.norm().is_nan() || r.norm() >= 1e-7 || z[0].to_degrees() > 16.0 {
        return Err(AeroError::NoConvergence {
            place: format!("trim at {v:.1} m/s, {h:.0} m"),
            iterations: 60,
            residual: r.norm(),
            message: "no level-flight trim; raise the airspeed above the stall speed".into(),
        });
    }
    let (x, controls, t) = build(&z);
    Ok(Trim {
        x,
        controls,
        thrust_n: t,
    })
}

/// Replay (thesis Section 4.3): drive the simulation with recorded control
/// positions and thrusts from a flight record, from initial state `x0`.
/// `controls[k]` is the surfaces' position at the start of step k; they move
/// linearly to `controls[k + 1]` over the step (the last row is held), as in
/// the virtual flight test ([`Simulator::step_interp`]); `thrust_n[k]` is held
/// over step k (length `n`). Returns the state at each step start and the
/// final one (n + 1 rows).
pub fn replay<M: AeroModel + ?Sized>(
    sim: &mut Simulator,
    model: &mut M,
    controls: &[Controls],
    thrust_n: &[[f64; 2]],
) -> Result<Vec<StateVec>> {
    if controls.len() != thrust_n.len() {
        return Err(AeroError::invalid(
            "replay",
            format!(
                "{} control rows but {} thrust rows; give one of each per step",
                controls.len(),
                thrust_n.len()
            ),
        ));
    }
    let mut out = Vec::with_capacity(controls.len() + 1);
    out.push(sim.x);
    for (k, (c, t)) in controls.iter().zip(thrust_n).enumerate() {
        let next = controls.get(k + 1).unwrap_or(c);
        sim.step_interp(model, c, next, *t);
        out.push(sim.x);
    }
    Ok(out)
}

/// Replay with recorded thrust coefficients: each step converts C_T to thrust
/// with the current dynamic pressure (T = C_T q̄ S).
///
/// # Errors
/// When the two input lists differ in length.
pub fn replay_ct<M: AeroModel + ?Sized>(
    sim: &mut Simulator,
    model: &mut M,
    controls: &[Controls],
    ct: &[[f64; 2]],
) -> Result<Vec<StateVec>> {
    if controls.len() != ct.len() {
        return Err(AeroError::invalid(
            "replay",
            format!(
                "{} control rows but {} C_T rows; give one of each per step",
                controls.len(),
                ct.len()
            ),
        ));
    }
    let mut out = Vec::with_capacity(controls.len() + 1);
    out.push(sim.x);
    for (i, (c, k)) in controls.iter().zip(ct).enumerate() {
        let next = controls.get(i + 1).unwrap_or(c);
        sim.step_ct_interp(model, c, next, *k);
        out.push(sim.x);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aircraft::qualified::{QualifiedAero, QualifiedModel};
    use crate::aircraft::turboprop::adx37;
    use crate::sim::aero::AeroCoeffs;
    use crate::sim::mass::MassProperties;
    use nalgebra::{SMatrix, SVector};

    fn qualified(flap: f64) -> QualifiedAero {
        let q = QualifiedModel::adx37(&adx37()).unwrap();
        QualifiedAero {
            model: q.at_flap(flap).unwrap(),
        }
    }

    #[test]
    fn trimmed_level_flight_stays_trimmed_for_60_s() {
        let mut model = qualified(0.0);
        let mut sim = Simulator::new(adx37(), 0.0, StateVec::zeros(), 0.01);
        let tr = trim(&sim, &model, 85.0, 3000.0).unwrap();
        let (x0, c, t) = (tr.x, tr.controls, tr.thrust_n);
        sim.x = x0;
        for _ in 0..6000 {
            sim.step(&mut model, &c, [t, t]);
        }
        let d = sim.x - x0;
        assert!(d[ix::U].abs() < 1e-4 && d[ix::W].abs() < 1e-4, "{d}");
        assert!(d[ix::THETA].abs() < 1e-6 && d[ix::Q].abs() < 1e-7);
        assert!(d[ix::H].abs() < 1e-3, "altitude drift {}", d[ix::H]);
        assert!(d[ix::PHI].abs() < 1e-6 && d[ix::V].abs() < 1e-4 && d[ix::R].abs() < 1e-7);
        assert!((sim.x[ix::XE].hypot(sim.x[ix::YE]) - 85.0 * 60.0).abs() < 1e-2);
    }

    /// Roll-rate-only aerodynamics: C_l = C_l,p p̂ (all else zero), and lift = weight.
    #[derive(Debug)]
    struct RollOnly {
        clp: f64,
        cz: f64,
    }
    impl AeroModel for RollOnly {
        fn coefficients(&self, s: &AeroInput) -> AeroCoeffs {
            AeroCoeffs {
                cl: self.clp * s.p_hat,
                cz: self.cz,
                ..AeroCoeffs::default()
            }
        }
    }

    #[test]
    fn roll_mode_time_constant_matches_clp_and_inertia() {
        // τ = −I'_xx 2V / (q̄ S b² C_l,p) with I'_xx = I_xx − I_xz²/I_zz (the roll
        // equation with I_xz coupling, ṗ = c₃ L for N = 0: c₃ = I_zz/Γ).
        let ac = adx37();
        let (v, h, clp) = (80.0, 3000.0, -0.5);
        let rho = isa(h).density_kgm3;
        let qs = 0.5 * rho * v * v * ac.s_m2;
        let mut model = RollOnly {
            clp,
            cz: -ac.mass_kg * G0 / qs,
        };
        let mut x = StateVec::zeros();
        x[ix::U] = v;
        x[ix::H] = h;
        x[ix::P] = 0.1;
        let mut sim = Simulator::new(ac.clone(), 0.0, x, 0.001);
        let ixx_eff = ac.ixx - ac.ixz * ac.ixz / ac.izz;
        let tau = -ixx_eff * 2.0 * v / (qs * ac.b_m * ac.b_m * clp);
        let target = 0.1 * (-1.0f64).exp();
        let mut prev = (0.0, 0.1);
        let mut t_e = f64::NAN;
        for _ in 0..5000 {
            sim.step(&mut model, &Controls::default(), [0.0, 0.0]);
            let p = sim.x[ix::P];
            if p <= target {
                t_e = prev.0 + (prev.1 - target) / (prev.1 - p) * (sim.t - prev.0);
                break;
            }
            prev = (sim.t, p);
        }
        assert!(
            (t_e / tau - 1.0).abs() < 0.03,
            "simulated {t_e} s vs {tau} s"
        );
    }

    #[test]
    fn steady_heading_sideslip_balances() {
        // Solve u̇ = v̇ = ẇ = ṗ = q̇ = ṙ = 0 at β = 5° for (α, δe, T, δa, δr, φ),
        // then fly it: the state holds and the heading stays constant.
        let mut model = qualified(0.0);
        let ac = adx37();
        let sim = Simulator::new(ac.clone(), 0.0, StateVec::zeros(), 0.01);
        let (v, h, beta) = (80.0, 3000.0, 5f64.to_radians());
        let build = |z: &SVector<f64, 6>| {
            let mut x = StateVec::zeros();
            x[ix::U] = v * z[0].cos() * beta.cos();
            x[ix::V] = v * beta.sin();
            x[ix::W] = v * z[0].sin() * beta.cos();
            x[ix::PHI] = z[5];
            x[ix::H] = h;
            // level: θ such that ḣ = 0
            let mut th = z[0];
            for _ in 0..30 {
                let f = x[ix::U] * th.sin()
                    - x[ix::V] * th.cos() * z[5].sin()
                    - x[ix::W] * th.cos() * z[5].cos();
                let df = x[ix::U] * th.cos()
                    + x[ix::V] * th.sin() * z[5].sin()
                    + x[ix::W] * th.sin() * z[5].cos();
                th -= f / df;
            }
            x[ix::THETA] = th;
            let c = Controls {
                da: z[3],
                de: z[1],
                dr: z[4],
                ..Controls::default()
            };
            (x, c, [z[2] * 1e4, z[2] * 1e4])
        };
        let resid = |z: &SVector<f64, 6>| {
            let (x, c, t) = build(z);
            let d = derivative(&sim.body, &x, &sim.loads(&model, &x, &c, t));
            SVector::<f64, 6>::from([d[0], d[1], d[2], d[3], d[4], d[5]])
        };
        let mut z = SVector::<f64, 6>::from([0.05, 0.0, 0.5, 0.0, 0.0, 0.0]);
        for _ in 0..40 {
            let r = resid(&z);
            let mut j = SMatrix::<f64, 6, 6>::zeros();
            for k in 0..6 {
                let mut zp = z;
                zp[k] += 1e-7;
                j.set_column(k, &((resid(&zp) - r) / 1e-7));
            }
            z -= j.lu().solve(&r).unwrap();
        }
        assert!(resid(&z).norm() < 1e-9);
        // β > 0 (wind from the right): C_n,β yaws the nose right, positive rudder holds it left
        assert!(
            z[4] > 0.0,
            "right sideslip is held by positive (left-yawing) rudder: {}",
            z[4]
        );
        assert!(z[5] > 0.0, "and a bank into the wind: {}", z[5]);
        let (x0, c, t) = build(&z);
        let mut s2 = Simulator::new(ac, 0.0, x0, 0.01);
        for _ in 0..1000 {
            s2.step(&mut model, &c, t);
        }
        let d = s2.x - x0;
        assert!(d[ix::PSI].abs() < 1e-5, "heading drift {}", d[ix::PSI]);
        assert!(d[ix::P].abs() < 1e-6 && d[ix::R].abs() < 1e-6);
        assert!(d[ix::V].abs() < 1e-3 && d[ix::PHI].abs() < 1e-5);
    }

    /// Constant total coefficients whatever the state.
    #[derive(Debug)]
    struct Constant(AeroCoeffs);
    impl AeroModel for Constant {
        fn coefficients(&self, _: &AeroInput) -> AeroCoeffs {
            self.0
        }
    }

    #[test]
    fn loads_moments_are_taken_about_the_actual_cg() {
        // M_cg = M_datum − d × F, written out per component, with F the aero + thrust force
        let ac = adx37();
        let co = AeroCoeffs {
            cx: 0.05,
            cy: -0.03,
            cz: -1.6,
            cl: 0.004,
            cm: -0.02,
            cn: 0.003,
        };
        let model = Constant(co);
        let mut x = StateVec::zeros();
        x[ix::U] = 60.0;
        x[ix::W] = 8.0;
        x[ix::H] = 3000.0;
        let mass = MassProperties {
            mass_kg: 14_500.0,
            cg_m: [-0.1, 0.03, 0.05],
            ixx: 1.6e5,
            iyy: 2.6e5,
            izz: 3.4e5,
            ixz: 1.1e4,
        };
        let nominal = Simulator::new(ac.clone(), 0.0, x, 0.01);
        let moved = Simulator::with_mass(ac.clone(), 0.0, x, 0.01, &mass);
        let c = Controls::default();
        let l0 = nominal.loads(&model, &x, &c, [5e3, 5e3]);
        let l1 = moved.loads(&model, &x, &c, [5e3, 5e3]);
        let qs = nominal.air(&x).qbar * ac.s_m2;
        let f = [co.cx * qs, co.cy * qs, co.cz * qs];
        let m = [
            co.cl * qs * ac.b_m,
            co.cm * qs * ac.cbar_m,
            co.cn * qs * ac.b_m,
        ];
        let d = mass.cg_m;
        let want = [
            m[0] - (d[1] * f[2] - d[2] * f[1]),
            m[1] - (d[2] * f[0] - d[0] * f[2]),
            m[2] - (d[0] * f[1] - d[1] * f[0]),
        ];
        for k in 0..3 {
            assert!((l0.moment[k] - m[k]).abs() < 1e-9 * m[k].abs().max(1.0));
            assert!(
                (l1.moment[k] - want[k]).abs() < 1e-9 * want[k].abs().max(1.0),
                "{k}"
            );
            assert_eq!(l0.force[k], l1.force[k]);
        }
        // the aft CG under lift adds nose-up moment: d_x F_z = (−0.1)(−1.6 q̄S)
        assert!(l1.moment.y - l0.moment.y > 0.15 * qs);
        // and the rigid body is the maneuver's
        assert_eq!(
            moved.body,
            RigidBody::new(14_500.0, 1.6e5, 2.6e5, 3.4e5, 1.1e4)
        );
    }

    #[test]
    fn trim_uses_the_maneuvers_weight_and_cg() {
        // a heavier aircraft trims at a higher alpha, an aft CG with less nose-up elevator
        let model = qualified(0.0);
        let ac = adx37();
        let mut heavy = MassProperties::nominal(&ac);
        heavy.mass_kg *= 1.05;
        let mut aft = MassProperties::nominal(&ac);
        aft.cg_m[0] = -0.1;
        let at = |m: &MassProperties| {
            let sim = Simulator::with_mass(ac.clone(), 0.0, StateVec::zeros(), 0.01, m);
            trim(&sim, &model, 85.0, 3000.0).unwrap()
        };
        let (t0, th, ta) = (at(&MassProperties::nominal(&ac)), at(&heavy), at(&aft));
        let alpha = |t: &Trim| t.x[ix::W].atan2(t.x[ix::U]);
        assert!(alpha(&th) > alpha(&t0) + 1e-3);
        // positive elevator pitches nose down: the aft CG's nose-up moment is trimmed by more
        assert!(
            ta.controls.de > t0.controls.de + 1e-3,
            "{} vs {}",
            ta.controls.de,
            t0.controls.de
        );
    }
}
