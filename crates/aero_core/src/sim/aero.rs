//! The aerodynamic model interface of the simulator loop: one trait, so the
//! same loop runs the qualified model, the truth model, an extended model or a
//! user's own model (thesis Section 3.1.1, Figure 3.2).
//!
//! Conventions (Etkin, thesis Section 3.1): body axes x forward, y right,
//! z down; positive aileron rolls left, positive rudder yaws left, positive
//! elevator pitches nose down. Angles and rates are in **radians** inside the
//! engine. The coefficients are **total** (aerodynamic + propulsive) body-axis
//! coefficients about the moment reference centre, the aircraft's datum (its
//! nominal CG), because that is what flight test measures (thesis Eq. 3.2-3.4,
//! transferred from each maneuver's CG to the datum); the simulator moves the
//! moments to the actual CG ([`crate::sim::mass`]). A model includes its thrust terms through the
//! per-engine thrust coefficients `ct_left`, `ct_right` (Table 3.1 CT ranges).

/// Control-surface positions acting on the airframe, rad.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Controls {
    /// Aileron (positive rolls left), rad.
    pub da: f64,
    /// Elevator (positive pitches nose down), rad.
    pub de: f64,
    /// Rudder (positive yaws left), rad.
    pub dr: f64,
    /// Left roll spoiler (0 retracted, positive up), rad.
    pub dsl: f64,
    /// Right roll spoiler, rad.
    pub dsr: f64,
}

impl Controls {
    /// `self + w (other − self)`, surface by surface.
    #[must_use]
    pub fn lerp(&self, other: &Controls, w: f64) -> Controls {
        let f = |a: f64, b: f64| a + w * (b - a);
        Controls {
            da: f(self.da, other.da),
            de: f(self.de, other.de),
            dr: f(self.dr, other.dr),
            dsl: f(self.dsl, other.dsl),
            dsr: f(self.dsr, other.dsr),
        }
    }
}

/// Everything an aerodynamic model may depend on at one instant.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AeroInput {
    /// Angle of attack at the CG, rad.
    pub alpha: f64,
    /// Sideslip at the CG, rad.
    pub beta: f64,
    /// p̂ = p b/(2V), -.
    pub p_hat: f64,
    /// q̂ = q c̄/(2V), -.
    pub q_hat: f64,
    /// r̂ = r b/(2V), -.
    pub r_hat: f64,
    /// Rate of change of alpha, rad/s.
    pub alpha_dot: f64,
    /// Rate of change of beta, rad/s.
    pub beta_dot: f64,
    /// Control positions, rad.
    pub controls: Controls,
    /// Flap setting, deg (0, 5, 10, 15, 35 for the representative aircraft).
    pub flap_deg: f64,
    /// Thrust coefficient of the left engine, T/(q̄ S).
    pub ct_left: f64,
    /// Thrust coefficient of the right engine, T/(q̄ S).
    pub ct_right: f64,
    /// Mach number.
    pub mach: f64,
    /// True airspeed, m/s (for α̇c̄/2V).
    pub tas: f64,
}

impl AeroInput {
    /// Thesis Eq. 3.17: C_T,diff = C_T,left − C_T,right (positive yaws right).
    pub fn ct_diff(&self) -> f64 {
        self.ct_left - self.ct_right
    }
    /// Total thrust coefficient C_T,left + C_T,right.
    pub fn ct_sum(&self) -> f64 {
        self.ct_left + self.ct_right
    }
}

/// Body-axis force and moment coefficients about the moment reference centre
/// (the datum; the nominal CG) (total: aero + thrust).
///
/// Forces are divided by q̄S, rolling and yawing moments by q̄Sb, pitching
/// moment by q̄Sc̄ (thesis Eq. 3.1).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AeroCoeffs {
    /// Axial force coefficient C_X (positive forward).
    pub cx: f64,
    /// Side force coefficient C_Y (positive right).
    pub cy: f64,
    /// Normal force coefficient C_Z (positive down).
    pub cz: f64,
    /// Rolling moment coefficient C_l (positive right wing down).
    pub cl: f64,
    /// Pitching moment coefficient C_m (positive nose up).
    pub cm: f64,
    /// Yawing moment coefficient C_n (positive nose right).
    pub cn: f64,
}

impl AeroCoeffs {
    /// Body-axis C_X, C_Z from wind-axis lift and drag at angle of attack `alpha` (rad),
    /// plus an axial thrust coefficient `ct_sum` along the body x axis.
    pub fn from_lift_drag(cl_lift: f64, cd: f64, alpha: f64, ct_sum: f64) -> (f64, f64) {
        let (sa, ca) = alpha.sin_cos();
        (-cd * ca + cl_lift * sa + ct_sum, -cd * sa - cl_lift * ca)
    }
}

/// An aerodynamic model the simulator loop can run.
///
/// `coefficients` must be a pure function of its input (the RK4 stages call it
/// four times per step). A model with memory (the stochastic roll-off of
/// thesis Section 3.4.3) updates that memory in [`AeroModel::advance`], which the
/// loop calls once per fixed step with the state at the start of the step.
pub trait AeroModel {
    /// Total body-axis coefficients at one instant.
    fn coefficients(&self, input: &AeroInput) -> AeroCoeffs;
    /// Update internal state once per step (time `t`, s). Default: stateless.
    fn advance(&mut self, _t: f64, _input: &AeroInput) {}
}

impl<M: AeroModel + ?Sized> AeroModel for Box<M> {
    fn coefficients(&self, input: &AeroInput) -> AeroCoeffs {
        (**self).coefficients(input)
    }
    fn advance(&mut self, t: f64, input: &AeroInput) {
        (**self).advance(t, input)
    }
}
