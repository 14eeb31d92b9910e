//! Measured force and moment coefficients from rates, angular accelerations and
//! specific forces at the CG (thesis Eq. 3.2-3.4; CX, CZ, Cm for completeness), with the
//! full inertia tensor and the moments transferred to a moment reference centre.
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
//!
//! **Products of inertia.** With $I_{xy}$ and $I_{yz}$ (Etkin sign: the tensor holds
//! $-I_{xy}$, $-I_{yz}$ off the diagonal, as it holds $-I_{xz}$) the moments are the full
//! Euler equations $\mathbf M = \mathbf I\dot{\boldsymbol\omega} + \boldsymbol\omega\times
//! (\mathbf I\boldsymbol\omega + \mathbf h)$; Eq. 3.2-3.3 are its $I_{xy} = I_{yz} = 0$ case and
//! the product terms are added to them:
//! $\Delta L = I_{xy}(pr - \dot q) + I_{yz}(r^2 - q^2)$,
//! $\Delta M = -I_{xy}(\dot p + qr) + I_{yz}(pq - \dot r)$,
//! $\Delta N = I_{xy}(q^2 - p^2) - I_{yz}(\dot q + pr)$.
//!
//! **Moment reference centre.** Eq. 3.2-3.3 give the moments about the CG, which moves from
//! test to test (fuel, ballast, crew), while a simulator applies its moment coefficients about
//! a fixed point (JSBSim's `AERORP`, DAVE-ML's moment reference centre). The moments of the
//! measured (aerodynamic + propulsive) force $\mathbf F = m\mathbf a$ about that point are
//! $\mathbf M_{ref} = \mathbf M_{CG} + \mathbf d\times\mathbf F$, $\mathbf d = \mathbf r_{CG} -
//! \mathbf r_{ref}$ (gravity acts at the CG and the accelerometers do not sense it, so it adds
//! nothing): $C_{l,ref} = C_l + (d_y C_Z - d_z C_Y)/b$, $C_{m,ref} = C_m + (d_z C_X - d_x C_Z)/\bar c$,
//! $C_{n,ref} = C_n + (d_x C_Y - d_y C_X)/b$ (the transfer JSBSim's `FGAerodynamics` makes the
//! other way, from `AERORP` to the CG). Thrust moments about a fixed point do not depend on the
//! CG either, so the total coefficients about the reference are a property of the aircraft,
//! not of the loading.

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
    /// Product of inertia $I_{xy}$ (Etkin sign), kg m²; 0 for a symmetric aircraft.
    pub ixy: f64,
    /// Product of inertia $I_{yz}$ (Etkin sign), kg m²; 0 for a symmetric aircraft.
    pub iyz: f64,
}

impl MassGeometry {
    /// The principal-plane case: no $I_{xy}$, $I_{yz}$.
    #[allow(clippy::too_many_arguments)]
    pub fn principal(
        s: f64,
        b: f64,
        cbar: f64,
        mass: f64,
        ixx: f64,
        iyy: f64,
        izz: f64,
        ixz: f64,
    ) -> Self {
        MassGeometry {
            s,
            b,
            cbar,
            mass,
            ixx,
            iyy,
            izz,
            ixz,
            ixy: 0.0,
            iyz: 0.0,
        }
    }
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
/// dynamic pressure `qbar` Pa, propeller angular momentum `h_p` kg m²/s (thesis sign); the
/// moments about the point the CG is `arm` m from (body axes, $\mathbf d$ above; zero: about
/// the CG).
///
/// ```
/// use aero_core::preprocess::coefficients::{coefficients_point, MassGeometry};
/// let mg = MassGeometry::principal(10.0, 10.0, 1.0, 1000.0, 100.0, 200.0, 300.0, 0.0);
/// let c = coefficients_point(&mg, [0.0; 3], [0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 100.0, 0.0);
/// assert!((c.cl - 100.0 / (100.0 * 10.0 * 10.0)).abs() < 1e-15);
/// assert!((c.cy - 1000.0 / (100.0 * 10.0)).abs() < 1e-15);
/// ```
#[inline]
pub fn coefficients_point(
    mg: &MassGeometry,
    arm: [f64; 3],
    w: [f64; 3],
    wdot: [f64; 3],
    a: [f64; 3],
    qbar: f64,
    h_p: f64,
) -> Coefficients {
    let [p, q, r] = w;
    let [pd, qd, rd] = wdot;
    let qs = qbar * mg.s;
    let (ixy, iyz) = (mg.ixy, mg.iyz);
    let f = [mg.mass * a[0], mg.mass * a[1], mg.mass * a[2]];
    let [dx, dy, dz] = arm;
    // Eq. 3.2-3.3 and the pitch equation, then the product terms, then d x F: each added
    // term is exactly zero for a principal-plane body about its CG, so those results are
    // bit for bit Eq. 3.2-3.3.
    let l = mg.ixx * pd - mg.ixz * (rd + p * q)
        + (mg.izz - mg.iyy) * q * r
        + (ixy * (p * r - qd) + iyz * (r * r - q * q))
        + (dy * f[2] - dz * f[1]);
    let n = mg.izz * rd - mg.ixz * (pd - q * r)
        + (mg.iyy - mg.ixx) * p * q
        + h_p * q
        + (ixy * (q * q - p * p) - iyz * (qd + p * r))
        + (dx * f[1] - dy * f[0]);
    let m = mg.iyy * qd + (mg.ixx - mg.izz) * p * r + mg.ixz * (p * p - r * r) - h_p * r
        + (iyz * (p * q - rd) - ixy * (pd + q * r))
        + (dz * f[0] - dx * f[2]);
    Coefficients {
        cl: l / (qs * mg.b),
        cn: n / (qs * mg.b),
        cy: f[1] / qs,
        cx: f[0] / qs,
        cz: f[2] / qs,
        cm: m / (qs * mg.cbar),
    }
}

/// Batch form of [`coefficients_point`] over equal-length slices; `h_p` per sample.
/// Returns `[Cl, Cn, CY, CX, CZ, Cm]`.
pub fn coefficients(
    mg: &MassGeometry,
    arm: [f64; 3],
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
            arm,
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

    fn tensor(mg: &MassGeometry) -> Matrix3<f64> {
        Matrix3::new(
            mg.ixx, -mg.ixy, -mg.ixz, -mg.ixy, mg.iyy, -mg.iyz, -mg.ixz, -mg.iyz, mg.izz,
        )
    }

    #[test]
    fn moments_match_euler_equations_with_rotor() {
        // independent check: M = I wdot + w x (I w + h), h = (-h_p, 0, 0) (thesis sign),
        // the principal-plane body of Eq. 3.2-3.3 and then a full tensor
        let mut mg = MassGeometry::principal(61.0, 27.05, 2.3, 20000.0, 3.0e5, 4.5e5, 7.1e5, 1.5e4);
        for (ixy, iyz) in [(0.0, 0.0), (2.2e3, -4.1e3)] {
            mg.ixy = ixy;
            mg.iyz = iyz;
            let inertia = tensor(&mg);
            let w = Vector3::new(0.3, -0.2, 0.25);
            let wd = Vector3::new(-0.5, 0.7, 0.1);
            let h_p = 2.0 * 25.0 * 106.8;
            let h = Vector3::new(-h_p, 0.0, 0.0);
            let mom = inertia * wd + w.cross(&(inertia * w + h));
            let qbar = 3000.0;
            let c = coefficients_point(
                &mg,
                [0.0; 3],
                w.into(),
                wd.into(),
                [0.1, 0.2, -9.0],
                qbar,
                h_p,
            );
            let qs = qbar * mg.s;
            assert!((c.cl - mom[0] / (qs * mg.b)).abs() < 1e-14);
            assert!((c.cm - mom[1] / (qs * mg.cbar)).abs() < 1e-14);
            assert!((c.cn - mom[2] / (qs * mg.b)).abs() < 1e-14);
            assert!((c.cz - mg.mass * -9.0 / qs).abs() < 1e-14);
        }
    }

    /// A rigid body of point masses, summed particle by particle: the moment of the
    /// non-gravitational forces about a fixed body point P is
    /// sum_i (r_i - r_P) x m_i (a_i - g), a_i = a_CG + wdot x rho_i + w x (w x rho_i),
    /// rho_i = r_i - r_CG. The coefficients computed from the CG's inertia (found from the
    /// particles, not from the formula under test), the CG's specific force and the arm
    /// CG - P must equal it, for two loadings of the same airframe (ballast moved).
    #[test]
    fn moments_about_the_reference_equal_the_particle_sum() {
        let airframe: [([f64; 3], f64); 6] = [
            ([3.0, 0.0, 0.2], 4000.0),
            ([-6.0, 0.1, -0.8], 2500.0),
            ([0.5, 7.0, -0.3], 3000.0),
            ([0.4, -7.0, -0.3], 3000.0),
            ([-1.0, 0.3, 0.6], 6000.0),
            ([1.5, -0.6, 0.4], 1500.0),
        ];
        let r_ref = Vector3::new(0.7, -0.05, 0.15);
        let w = Vector3::new(0.4, -0.15, 0.3);
        let wd = Vector3::new(-0.8, 0.5, 0.25);
        let f_cg = Vector3::new(1.5, -2.0, -11.0); // specific force at the CG, m/s^2
        let qbar = 2500.0;
        let (s, b, cbar) = (61.0, 27.05, 2.3);
        for ballast in [([4.0, 0.2, 0.1], 800.0), ([-5.0, -0.4, 0.5], 1500.0)] {
            let parts: Vec<(Vector3<f64>, f64)> = airframe
                .iter()
                .chain(std::iter::once(&ballast))
                .map(|(r, m)| (Vector3::from(*r), *m))
                .collect();
            let mass: f64 = parts.iter().map(|(_, m)| m).sum();
            let r_cg = parts.iter().map(|(r, m)| r * *m).sum::<Vector3<f64>>() / mass;
            // inertia tensor about the CG from the particles: sum m (|rho|^2 1 - rho rho')
            let mut i_cg = Matrix3::zeros();
            for (r, m) in &parts {
                let rho = r - r_cg;
                i_cg += (Matrix3::identity() * rho.norm_squared() - rho * rho.transpose()) * *m;
            }
            let mut want = Vector3::zeros();
            for (r, m) in &parts {
                let rho = r - r_cg;
                let a_i = f_cg + wd.cross(&rho) + w.cross(&w.cross(&rho));
                want += (r - r_ref).cross(&(a_i * *m));
            }
            let d = r_cg - r_ref;
            let mg = MassGeometry {
                s,
                b,
                cbar,
                mass,
                ixx: i_cg[(0, 0)],
                iyy: i_cg[(1, 1)],
                izz: i_cg[(2, 2)],
                ixz: -i_cg[(0, 2)],
                ixy: -i_cg[(0, 1)],
                iyz: -i_cg[(1, 2)],
            };
            let arm = [d.x, d.y, d.z];
            let c = coefficients_point(&mg, arm, w.into(), wd.into(), f_cg.into(), qbar, 0.0);
            let qs = qbar * s;
            let rel = |got: f64, m: f64, len: f64| (got * qs * len - m).abs() / want.norm();
            assert!(rel(c.cl, want.x, b) < 1e-12, "{}", rel(c.cl, want.x, b));
            assert!(
                rel(c.cm, want.y, cbar) < 1e-12,
                "{}",
                rel(c.cm, want.y, cbar)
            );
            assert!(rel(c.cn, want.z, b) < 1e-12, "{}", rel(c.cn, want.z, b));
        }
    }
}
