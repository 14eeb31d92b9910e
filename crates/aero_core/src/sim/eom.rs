//! Rigid-body equations of motion, thesis Eq. 3.1 (Etkin), with the I_xz
//! coupling and the propeller gyroscopic terms, integrated by classical RK4 at
//! a fixed step.
//!
//! State (12): u, v, w (m/s, body axes), p, q, r (rad/s), φ, θ, ψ (rad),
//! x_E, y_E (m, north and east), h (m, altitude). Gravity is uniform (g₀)
//! over a flat Earth, which is the thesis's model.
//!
//! The moment equations are written in matrix form,
//! I ω̇ = M − ω × (I ω) − ω × h_p,
//! which expands to Eq. 3.1d-f with the constants c₁…c₉ of the thesis. The
//! propellers' angular momentum is h_p = −I_p Ω_p x̂ (summed over the engines
//! turning the same way), the sign for which Eq. 3.1d-f and Eq. 3.3 hold as
//! printed (+c₇ I_p Ω_p r in q̇, +I_p Ω_p q in C_n,meas).

use nalgebra::{Matrix3, SVector, Vector3};

use crate::sim::atmosphere::G0;

/// The 12-element state vector (see module docs for the order).
pub type StateVec = SVector<f64, 12>;

/// Index of each state in [`StateVec`].
pub mod ix {
    pub const U: usize = 0;
    pub const V: usize = 1;
    pub const W: usize = 2;
    pub const P: usize = 3;
    pub const Q: usize = 4;
    pub const R: usize = 5;
    pub const PHI: usize = 6;
    pub const THETA: usize = 7;
    pub const PSI: usize = 8;
    pub const XE: usize = 9;
    pub const YE: usize = 10;
    pub const H: usize = 11;
}

/// Mass and inertia of the rigid body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidBody {
    /// Mass, kg.
    pub mass: f64,
    /// Inertia tensor about the CG in body axes, kg m² (I_xy = I_yz = 0).
    pub inertia: Matrix3<f64>,
    inv_inertia: Matrix3<f64>,
}

impl RigidBody {
    /// A body with principal-plane inertias and product I_xz (kg m², Etkin's sign:
    /// the tensor holds −I_xz off the diagonal).
    pub fn new(mass: f64, ixx: f64, iyy: f64, izz: f64, ixz: f64) -> Self {
        let inertia = Matrix3::new(ixx, 0.0, -ixz, 0.0, iyy, 0.0, -ixz, 0.0, izz);
        let inv_inertia = inertia.try_inverse().unwrap_or_else(Matrix3::zeros);
        RigidBody {
            mass,
            inertia,
            inv_inertia,
        }
    }
}

/// External loads on the body at one instant (gravity excluded: the EOM add it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Loads {
    /// Aerodynamic + propulsive force, body axes, N.
    pub force: Vector3<f64>,
    /// Moment about the CG, body axes, N m.
    pub moment: Vector3<f64>,
    /// Propeller angular momentum I_p Ω_p (sum over co-rotating engines), kg m²/s.
    pub prop_momentum: f64,
}

impl Loads {
    /// No loads at all (gravity only).
    pub fn zero() -> Self {
        Loads {
            force: Vector3::zeros(),
            moment: Vector3::zeros(),
            prop_momentum: 0.0,
        }
    }
}

/// Angular acceleration from I ω̇ = M − ω × (I ω + h_p) (Eq. 3.1d-f), rad/s².
#[inline]
pub fn angular_acceleration(body: &RigidBody, omega: &Vector3<f64>, loads: &Loads) -> Vector3<f64> {
    let h = body.inertia * omega + Vector3::new(-loads.prop_momentum, 0.0, 0.0);
    body.inv_inertia * (loads.moment - omega.cross(&h))
}

/// Time derivative of the state, thesis Eq. 3.1a-l (with Eq. 3.1b's g cosθ sinφ).
#[inline]
pub fn derivative(body: &RigidBody, x: &StateVec, loads: &Loads) -> StateVec {
    let (u, v, w) = (x[ix::U], x[ix::V], x[ix::W]);
    let (p, q, r) = (x[ix::P], x[ix::Q], x[ix::R]);
    let (sphi, cphi) = x[ix::PHI].sin_cos();
    let (sth, cth) = x[ix::THETA].sin_cos();
    let (spsi, cpsi) = x[ix::PSI].sin_cos();
    let f = loads.force / body.mass;
    let omega = Vector3::new(p, q, r);
    let wdot = angular_acceleration(body, &omega, loads);
    let mut d = StateVec::zeros();
    d[ix::U] = r * v - q * w + f.x - G0 * sth;
    d[ix::V] = p * w - r * u + f.y + G0 * cth * sphi;
    d[ix::W] = q * u - p * v + f.z + G0 * cth * cphi;
    d[ix::P] = wdot.x;
    d[ix::Q] = wdot.y;
    d[ix::R] = wdot.z;
    d[ix::PHI] = p + sth / cth * (q * sphi + r * cphi);
    d[ix::THETA] = q * cphi - r * sphi;
    d[ix::PSI] = (q * sphi + r * cphi) / cth;
    d[ix::XE] = u * cpsi * cth
        + v * (cpsi * sth * sphi - spsi * cphi)
        + w * (cpsi * sth * cphi + spsi * sphi);
    d[ix::YE] = u * spsi * cth
        + v * (spsi * sth * sphi + cpsi * cphi)
        + w * (spsi * sth * cphi - cpsi * sphi);
    d[ix::H] = u * sth - v * cth * sphi - w * cth * cphi;
    d
}

/// One classical RK4 step of length `dt` (s); `loads(x)` gives the loads at a
/// state (the controls are held over the step).
pub fn rk4_step(
    body: &RigidBody,
    x: &StateVec,
    dt: f64,
    mut loads: impl FnMut(&StateVec) -> Loads,
) -> StateVec {
    let first = loads(x);
    rk4_step_from(body, x, dt, &first, loads)
}

/// [`rk4_step`] with the loads at the step start already known (`first = loads(x)`).
#[inline]
pub fn rk4_step_from(
    body: &RigidBody,
    x: &StateVec,
    dt: f64,
    first: &Loads,
    mut loads: impl FnMut(&StateVec) -> Loads,
) -> StateVec {
    let k1 = derivative(body, x, first);
    let x2 = x + k1 * (0.5 * dt);
    let k2 = derivative(body, &x2, &loads(&x2));
    let x3 = x + k2 * (0.5 * dt);
    let k3 = derivative(body, &x3, &loads(&x3));
    let x4 = x + k3 * dt;
    let k4 = derivative(body, &x4, &loads(&x4));
    x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (dt / 6.0)
}

/// One RK4 step whose inputs change within the step: `mid` gives the loads at
/// the two half-step stages, `end` at the last one (`first` at the start).
/// With `mid == end` it is [`rk4_step_from`].
pub fn rk4_step_stages(
    body: &RigidBody,
    x: &StateVec,
    dt: f64,
    first: &Loads,
    mut mid: impl FnMut(&StateVec) -> Loads,
    mut end: impl FnMut(&StateVec) -> Loads,
) -> StateVec {
    let k1 = derivative(body, x, first);
    let x2 = x + k1 * (0.5 * dt);
    let k2 = derivative(body, &x2, &mid(&x2));
    let x3 = x + k2 * (0.5 * dt);
    let k3 = derivative(body, &x3, &mid(&x3));
    let x4 = x + k3 * dt;
    let k4 = derivative(body, &x4, &end(&x4));
    x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (dt / 6.0)
}

/// Body-to-Earth (NED) rotation matrix for Euler angles φ, θ, ψ (rad).
pub fn body_to_ned(phi: f64, theta: f64, psi: f64) -> Matrix3<f64> {
    let (sf, cf) = phi.sin_cos();
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = psi.sin_cos();
    Matrix3::new(
        ct * cp,
        sf * st * cp - cf * sp,
        cf * st * cp + sf * sp,
        ct * sp,
        sf * st * sp + cf * cp,
        cf * st * sp - sf * cp,
        -st,
        sf * ct,
        cf * ct,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body() -> RigidBody {
        RigidBody::new(15_000.0, 1.6e5, 2.7e5, 3.3e5, 1.2e4)
    }

    #[test]
    fn free_fall_conserves_energy() {
        // Gravity only, no rotation: kinetic + potential energy is constant.
        let b = body();
        let mut x = StateVec::zeros();
        x[ix::U] = 80.0;
        x[ix::W] = 3.0;
        x[ix::THETA] = 0.1;
        x[ix::H] = 3000.0;
        let e0 = 0.5 * (80.0f64.powi(2) + 9.0) + G0 * 3000.0;
        for _ in 0..2000 {
            x = rk4_step(&b, &x, 0.01, |_| Loads::zero());
        }
        let v2 = x[ix::U].powi(2) + x[ix::V].powi(2) + x[ix::W].powi(2);
        let e = 0.5 * v2 + G0 * x[ix::H];
        assert!(
            ((e - e0) / e0).abs() < 1e-9,
            "energy drift {}",
            (e - e0) / e0
        );
    }

    #[test]
    fn torque_free_rotation_conserves_angular_momentum_and_energy() {
        // Torque-free tumbling with I_xz and a spinning propeller: the angular
        // momentum vector (I ω + h_p) is constant in the inertial frame.
        let b = body();
        let hp = 2.0 * 60.0 * 107.0;
        let mut x = StateVec::zeros();
        x[ix::P] = 0.8;
        x[ix::Q] = -0.4;
        x[ix::R] = 0.3;
        let loads = Loads {
            prop_momentum: hp,
            ..Loads::zero()
        };
        let hvec = |x: &StateVec| {
            let w = Vector3::new(x[ix::P], x[ix::Q], x[ix::R]);
            let hb = b.inertia * w + Vector3::new(-hp, 0.0, 0.0);
            body_to_ned(x[ix::PHI], x[ix::THETA], x[ix::PSI]) * hb
        };
        let energy = |x: &StateVec| {
            let w = Vector3::new(x[ix::P], x[ix::Q], x[ix::R]);
            0.5 * w.dot(&(b.inertia * w))
        };
        let h0 = hvec(&x);
        let e0 = energy(&x);
        for _ in 0..2000 {
            x = rk4_step(&b, &x, 0.0005, |_| loads);
            // keep away from the Euler singularity: the check is over 1 s
        }
        let h1 = hvec(&x);
        assert!(
            (h1 - h0).norm() / h0.norm() < 1e-8,
            "dH/H = {}",
            (h1 - h0).norm() / h0.norm()
        );
        assert!(((energy(&x) - e0) / e0).abs() < 1e-8);
    }

    #[test]
    fn matrix_form_equals_thesis_constants() {
        // Eq. 3.1d-f with c1..c9 against the matrix form.
        let (ix_, iy, iz, ixz) = (1.6e5, 2.7e5, 3.3e5, 1.2e4);
        let b = RigidBody::new(1.0, ix_, iy, iz, ixz);
        let (p, q, r, ipw) = (0.3, -0.2, 0.5, 5000.0);
        let (l, m, n) = (1.0e4, -2.0e4, 3.0e3);
        let loads = Loads {
            force: Vector3::zeros(),
            moment: Vector3::new(l, m, n),
            prop_momentum: ipw,
        };
        let d = angular_acceleration(&b, &Vector3::new(p, q, r), &loads);
        let g = ix_ * iz - ixz * ixz;
        let c1 = ((iy - iz) * iz - ixz * ixz) / g;
        let c2 = (ix_ - iy + iz) * ixz / g;
        let c3 = iz / g;
        let c4 = ixz / g;
        let c5 = (iz - ix_) / iy;
        let c6 = ixz / iy;
        let c7 = 1.0 / iy;
        let c8 = ((ix_ - iy) * ix_ + ixz * ixz) / g;
        let c9 = ix_ / g;
        let pd = (c1 * r + c2 * p - c4 * ipw) * q + c3 * l + c4 * n;
        let qd = (c5 * p + c7 * ipw) * r - c6 * (p * p - r * r) + c7 * m;
        let rd = (c8 * p - c2 * r - c9 * ipw) * q + c9 * n + c4 * l;
        assert!((d.x - pd).abs() < 1e-12 && (d.y - qd).abs() < 1e-12 && (d.z - rd).abs() < 1e-12);
    }
}
