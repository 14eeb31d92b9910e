//! The simulation loop (thesis Figure 3.2): aerodynamic model → loads →
//! Eq. 3.1 → RK4, at a fixed step, with the atmosphere, gusts, engines and
//! actuators around it; trim; and replay of recorded control positions
//! (thesis Section 4.3).

use nalgebra::Vector3;

use crate::aircraft::turboprop::AircraftRef;
use crate::error::{AeroError, Result};
use crate::sim::aero::{AeroInput, AeroModel, Controls};
use crate::sim::atmosphere::{isa, G0};
use crate::sim::eom::{derivative, ix, rk4_step, Loads, RigidBody, StateVec};

/// The 6-DOF aircraft: state, environment, and the coupling to an [`AeroModel`].
#[derive(Debug, Clone)]
pub struct Simulator {
    /// Reference values (geometry, mass, propellers).
    pub aircraft: AircraftRef,
    /// Rigid body.
    pub body: RigidBody,
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
    /// Last α̇, β̇ (rad/s), from the previous step (backward difference).
    pub alpha_dot: f64,
    /// Last β̇, rad/s.
    pub beta_dot: f64,
    prev_ab: Option<(f64, f64)>,
}

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
    /// A simulator at state `x` with step `dt` (s).
    pub fn new(aircraft: AircraftRef, flap_deg: f64, x: StateVec, dt: f64) -> Self {
        let body = RigidBody::new(
            aircraft.mass_kg,
            aircraft.ixx,
            aircraft.iyy,
            aircraft.izz,
            aircraft.ixz,
        );
        Simulator {
            aircraft,
            body,
            x,
            t: 0.0,
            dt,
            flap_deg,
            gust: Vector3::zeros(),
            alpha_dot: 0.0,
            beta_dot: 0.0,
            prev_ab: None,
        }
    }

    /// Air data at state `x` (gusts subtracted).
    pub fn air(&self, x: &StateVec) -> AirData {
        let u = x[ix::U] - self.gust.x;
        let v = x[ix::V] - self.gust.y;
        let w = x[ix::W] - self.gust.z;
        let tas = (u * u + v * v + w * w).sqrt().max(1e-3);
        let a = isa(x[ix::H]);
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
    pub fn loads<M: AeroModel + ?Sized>(
        &self,
        model: &M,
        x: &StateVec,
        c: &Controls,
        thrust_n: [f64; 2],
    ) -> Loads {
        let (inp, ad) = self.aero_input(x, c, thrust_n);
        let co = model.coefficients(&inp);
        let ac = &self.aircraft;
        let qs = ad.qbar * ac.s_m2;
        let prop = if ac.n_engines >= 2 { 2.0 } else { 1.0 };
        Loads {
            force: Vector3::new(co.cx, co.cy, co.cz) * qs,
            moment: Vector3::new(
                co.cl * qs * ac.b_m,
                co.cm * qs * ac.cbar_m,
                co.cn * qs * ac.b_m,
            ),
            prop_momentum: prop * ac.prop_inertia * ac.prop_rpm * std::f64::consts::PI / 30.0,
        }
    }

    /// Advance one fixed step with surfaces `c` (rad) and thrusts (N) held over it.
    pub fn step<M: AeroModel + ?Sized>(&mut self, model: &mut M, c: &Controls, thrust_n: [f64; 2]) {
        let (inp, _) = self.aero_input(&self.x, c, thrust_n);
        model.advance(self.t, &inp);
        let x0 = self.x;
        let me = &*self;
        let m = &*model;
        let next = rk4_step(&me.body, &x0, me.dt, |x| me.loads(m, x, c, thrust_n));
        self.x = next;
        self.t += self.dt;
        let ad = self.air(&self.x);
        if let Some((a0, b0)) = self.prev_ab {
            self.alpha_dot = (ad.alpha - a0) / self.dt;
            self.beta_dot = (ad.beta - b0) / self.dt;
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

/// Wings-level trim at airspeed `v` (m/s), altitude `h` (m): alpha, elevator
/// and total thrust such that u̇ = ẇ = q̇ = 0 (Newton with a finite-difference
/// Jacobian). Returns (state, elevator rad, thrust per engine N).
///
/// # Errors
/// [`AeroError::NoConvergence`] when the Newton iteration fails (speed below stall).
pub fn trim<M: AeroModel + ?Sized>(
    sim: &Simulator,
    model: &M,
    v: f64,
    h: f64,
) -> Result<(StateVec, f64, f64)> {
    let state = |z: &[f64; 3]| {
        let mut x = StateVec::zeros();
        x[ix::U] = v * z[0].cos();
        x[ix::W] = v * z[0].sin();
        x[ix::THETA] = z[0];
        x[ix::H] = h;
        x
    };
    let resid = |z: &[f64; 3]| {
        let x = state(z);
        let c = Controls {
            de: z[1],
            ..Controls::default()
        };
        let t = z[2] * sim.aircraft.mass_kg * G0;
        let d = derivative(&sim.body, &x, &sim.loads(model, &x, &c, [t, t]));
        nalgebra::Vector3::new(d[ix::U], d[ix::W], d[ix::Q])
    };
    let mut z = [0.08, 0.0, 0.05];
    let mut r = resid(&z);
    for _ in 0..50 {
        if r.norm() < 1e-10 {
            break;
        }
        let mut j = nalgebra::Matrix3::zeros();
        for k in 0..3 {
            let mut zp = z;
            zp[k] += 1e-6;
            j.set_column(k, &((resid(&zp) - r) / 1e-6));
        }
        let Some(dz) = j.lu().solve(&(-r)) else {
            break;
        };
        for k in 0..3 {
            z[k] += dz[k].clamp(-0.05, 0.05);
        }
        r = resid(&z);
    }
    if r.norm().is_nan() || r.norm() >= 1e-6 || z[0].to_degrees() > 16.0 {
        return Err(AeroError::NoConvergence {
            place: format!("trim at {v:.1} m/s, {h:.0} m"),
            iterations: 50,
            residual: r.norm(),
            message: "no level-flight trim; raise the airspeed above the stall speed".into(),
        });
    }
    Ok((state(&z), z[1], z[2] * sim.aircraft.mass_kg * G0))
}

/// Replay (thesis Section 4.3): drive the simulation with recorded control
/// positions and thrusts from a flight record, from initial state `x0`.
/// `controls[k]` and `thrust_n[k]` act over step k (length `n`); returns the
/// state at each step start and the final one (n + 1 rows).
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
    for (c, t) in controls.iter().zip(thrust_n) {
        sim.step(model, c, *t);
        out.push(sim.x);
    }
    Ok(out)
}
