//! Measured force and moment coefficients from rates, angular accelerations and
//! specific forces at the CG (thesis Eq. 3.2-3.4; CX, CZ, Cm for completeness).
//!
//! Body axes (Etkin): x forward, y right wing, z down. Rates $p, q, r$ in rad/s, angular
//! accelerations in rad/s², specific forces $a_x, a_y, a_z$ at the CG in m/s², dynamic
//! pressure $\bar q = \tfrac12\rho V^2$ in Pa, inertias in kg m², $S$ m², $b, \bar c$ m.
//!
//! $$C_l = \frac{I_{xx}\dot p - I_{xz}(\dot r + pq) + (I_{zz}-I_{yy})qr}{\bar q S b}
//! \quad\text{(Eq. 3.2)}$$
//! $$C_n = \frac{I_{zz}\dot r - I_{xz}(\dot p - qr) + (I_{yy}-I_{xx})pq + h_p q}{\bar q S b}
//! \quad\text{(Eq. 3.3)}$$
//! $$C_Y = \frac{m a_y}{\bar q S}\ \text{(Eq. 3.4)},\quad C_X = \frac{m a_x}{\bar q S},\quad
//! C_Z = \frac{m a_z}{\bar q S}$$
//! $$C_m = \frac{I_{yy}\dot q + (I_{xx}-I_{zz})pr + I_{xz}(p^2-r^2) - h_p r}{\bar q S \bar c}$$
//!
//! $h_p = \sum_i I_{p}\,\Omega_{p,i}$ (kg m²/s) is the propellers' total angular momentum with the
//! thesis sign (Eq. 3.1d-f, 3.3): $\Omega_p > 0$ for the rotation sense that adds $+I_p\Omega_p q$
//! to $C_n$, i.e. spin angular momentum $-h_p$ along body $x$; then $\boldsymbol\omega\times\mathbf
//! h = (0, -r h_p, q h_p)$ is removed from the measured moments. Two propellers turning the same
//! way give $h_p = 2 I_p \Omega_p$; opposite (counter-rotating) ones cancel, $h_p = 0$.
//! $C_X$ and $C_Z$ include thrust (they are total body-axis force coefficients).

/// Mass and geometry needed by the coefficient equations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassGeometry {
    /// Wing area, m².
    pub s: f64,
    /// Span, m.
    pub b: f64,
    /// Mean aerodynamic chord, m.
    pub cbar: f64,
    /// Mass, kg.
    pub mass: f64,
    /// Roll inertia, kg m².
    pub ixx: f64,
    /// Pitch inertia, kg m².
    pub iyy: f64,
    /// Yaw inertia, kg m².
    pub izz: f64,
    /// Product of inertia (Etkin sign), kg m².
    pub ixz: f64,
}

/// Measured coefficients at one sample.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Coefficients {
    /// Rolling moment coefficient (Eq. 3.2).
    pub cl: f64,
    /// Yawing moment coefficient with the propeller gyroscopic term removed (Eq. 3.3).
    pub cn: f64,
    /// Side force coefficient (Eq. 3.4).
    pub cy: f64,
    /// Axial force coefficient (incl. thrust).
    pub cx: f64,
    /// Normal force coefficient (incl. thrust).
    pub cz: f64,
    /// Pitching moment coefficient with the propeller gyroscopic term removed.
    pub cm: f64,
}

/// Coefficients at one sample: rates `w` rad/s, `wdot` rad/s², specific force `a` m/s² at the CG,
/// dynamic pressure `qbar` Pa, propeller angular momentum `h_p` kg m²/s (thesis sign).
///
/// ```
/// use aero_core::preprocess::coefficients::{coefficients_point, MassGeometry};
/// let mg = MassGeometry { s: 10.0, b: 10.0, cbar: 1.0, mass: 1000.0,
///                         ixx: 100.0, iyy: 200.0, izz: 300.0, ixz: 0.0 };
/// let c = coefficients_point(&mg, [0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 100.0, 0.0);
/// assert!((c.cl - 100.0 / (100.0 * 10.0 * 10.0)).abs() < 1e-15);
/// assert!((c.cy - 1000.0 / (100.0 * 10.0)).abs() < 1e-15);
/// ```
#[inline]
pub fn coefficients_point(
    mg: &MassGeometry,
    w: [f64; 3],
    wdot: [f64; 3],
    a: [f64; 3],
    qbar: f64,
    h_p: f64,
) -> Coefficients {
    let [p, q, r] = w;
    let [pd, qd, rd] = wdot;
    let qs = qbar * mg.s;
    let l = mg.ixx * pd - mg.ixz * (rd + p * q) + (mg.izz - mg.iyy) * q * r;
    let n = mg.izz * rd - mg.ixz * (pd - q * r) + (mg.iyy - mg.ixx) * p * q + h_p * q;
    let m = mg.iyy * qd + (mg.ixx - mg.izz) * p * r + mg.ixz * (p * p - r * r) - h_p * r;
    Coefficients {
        cl: l / (qs * mg.b),
        cn: n / (qs * mg.b),
        cy: mg.mass * a[1] / qs,
        cx: mg.mass * a[0] / qs,
        cz: mg.mass * a[2] / qs,
        cm: m / (qs * mg.cbar),
    }
}

/// Batch form of [`coefficients_point`] over equal-length slices; `h_p` per sample.
/// Returns `[Cl, Cn, CY, CX, CZ, Cm]`.
pub fn coefficients(
    mg: &MassGeometry,
    w: [&[f64]; 3],
    wdot: [&[f64]; 3],
    a: [&[f64]; 3],
    qbar: &[f64],
    h_p: &[f64],
) -> [Vec<f64>; 6] {
    let n = qbar.len();
    let mut out: [Vec<f64>; 6] = Default::default();
    for o in out.iter_mut() {
        o.reserve_exact(n);
    }
    for i in 0..n {
        let c = coefficients_point(
            mg,
            [w[0][i], w[1][i], w[2][i]],
            [wdot[0][i], wdot[1][i], wdot[2][i]],
            [a[0][i], a[1][i], a[2][i]],
            qbar[i],
            h_p[i],
        );
        out[0].push(c.cl);
        out[1].push(c.cn);
        out[2].push(c.cy);
        out[3].push(c.cx);
        out[4].push(c.cz);
        out[5].push(c.cm);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    #[test]
    fn moments_match_euler_equations_with_rotor() {
        // independent check: M = I wdot + w x (I w + h), h = (-h_p, 0, 0) (thesis sign)
        let mg = MassGeometry {
            s: 61.0,
            b: 27.05,
            cbar: 2.3,
            mass: 20000.0,
            ixx: 3.0e5,
            iyy: 4.5e5,
            izz: 7.1e5,
            ixz: 1.5e4,
        };
        let inertia = Matrix3::new(mg.ixx, 0.0, -mg.ixz, 0.0, mg.iyy, 0.0, -mg.ixz, 0.0, mg.izz);
        let w = Vector3::new(0.3, -0.2, 0.25);
        let wd = Vector3::new(-0.5, 0.7, 0.1);
        let h_p = 2.0 * 25.0 * 106.8;
        let h = Vector3::new(-h_p, 0.0, 0.0);
        let mom = inertia * wd + w.cross(&(inertia * w + h));
        let qbar = 3000.0;
        let c = coefficients_point(&mg, w.into(), wd.into(), [0.1, 0.2, -9.0], qbar, h_p);
        let qs = qbar * mg.s;
        assert!((c.cl - mom[0] / (qs * mg.b)).abs() < 1e-14);
        assert!((c.cm - mom[1] / (qs * mg.cbar)).abs() < 1e-14);
        assert!((c.cn - mom[2] / (qs * mg.b)).abs() < 1e-14);
        assert!((c.cz - mg.mass * -9.0 / qs).abs() < 1e-14);
    }
}
