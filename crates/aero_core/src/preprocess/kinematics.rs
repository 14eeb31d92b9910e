//! Sensor-to-CG transfers (thesis Section 3.3: "all measured states should be transformed
//! to reflect the value as seen from the center of gravity").
//!
//! Body axes (Etkin, thesis Section 3.1): x forward, y right wing, z down; angular velocity
//! $\boldsymbol\omega = (p, q, r)$ in rad/s, sensor position $\mathbf r$ relative to the CG in m.
//!
//! **Accelerometer.** A rigid body's specific force at $\mathbf r$ is
//! $$\mathbf a_s = \mathbf a_{cg} + \dot{\boldsymbol\omega}\times\mathbf r + \boldsymbol\omega\times(\boldsymbol\omega\times\mathbf r),$$
//! hence $\mathbf a_{cg} = \mathbf a_s - \dot{\boldsymbol\omega}\times\mathbf r - \boldsymbol\omega\times(\boldsymbol\omega\times\mathbf r)$
//! (Klein & Morelli 2006, instrumentation corrections).
//!
//! **Vanes.** The air-relative velocity at a vane is $\mathbf V_v = \mathbf V_{cg} +
//! \boldsymbol\omega\times\mathbf r_v$ with $\mathbf V_{cg} = V(\cos\alpha\cos\beta, \sin\beta,
//! \sin\alpha\cos\beta)$ and $\boldsymbol\omega\times\mathbf r = (q r_z - r r_y,\; r r_x - p r_z,\;
//! p r_y - q r_x)$. The alpha vane reads $\alpha_v = \operatorname{atan2}(w_v, u_v)$, the beta
//! vane $\beta_v = \arcsin(v_v/|\mathbf V_v|)$. To first order
//! $\alpha_{cg} \approx \alpha_v + (q x_\alpha - p y_\alpha)/V$ and
//! $\beta_{cg} \approx \beta_v - (r x_\beta - p z_\beta)/V$ (the usual vane position corrections, Klein & Morelli 2006);
//! [`vanes_to_cg`] inverts the exact relations by fixed-point iteration (the map is within
//! $O(\omega r/V)$ of the identity, so it contracts fast).

/// Cross product of two 3-vectors.
#[inline]
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Specific force at the CG from the accelerometer reading at `r_s` (m), one sample.
///
/// `a_s` m/s², `w` rad/s, `wdot` rad/s².
///
/// ```
/// use aero_core::preprocess::kinematics::accel_to_cg_point;
/// // pure yaw rotation at 1 rad/s: a sensor 2 m ahead feels -2 m/s² (centripetal)
/// let a = accel_to_cg_point([-2.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0; 3], [2.0, 0.0, 0.0]);
/// assert!(a.iter().all(|v| v.abs() < 1e-12));
/// ```
#[inline]
pub fn accel_to_cg_point(a_s: [f64; 3], w: [f64; 3], wdot: [f64; 3], r_s: [f64; 3]) -> [f64; 3] {
    let t1 = cross(wdot, r_s);
    let t2 = cross(w, cross(w, r_s));
    [
        a_s[0] - t1[0] - t2[0],
        a_s[1] - t1[1] - t2[1],
        a_s[2] - t1[2] - t2[2],
    ]
}

/// Specific force at the sensor from the one at the CG (the forward map, for synthesis and tests).
#[inline]
pub fn accel_at_sensor_point(
    a_cg: [f64; 3],
    w: [f64; 3],
    wdot: [f64; 3],
    r_s: [f64; 3],
) -> [f64; 3] {
    let t1 = cross(wdot, r_s);
    let t2 = cross(w, cross(w, r_s));
    [
        a_cg[0] + t1[0] + t2[0],
        a_cg[1] + t1[1] + t2[1],
        a_cg[2] + t1[2] + t2[2],
    ]
}

/// Vane angles (rad) seen at `r_alpha` and `r_beta` for a CG airflow `(alpha, beta, v)` and
/// rates `w`; with `flank` the beta vane reads the flank angle $\operatorname{atan2}(v_b, u_b)$
/// of its local flow (a boom-mounted yaw vane) instead of the sideslip $\arcsin(v_b/V_b)$.
#[inline]
pub fn vanes_at_sensor_point(
    alpha: f64,
    beta: f64,
    v: f64,
    w: [f64; 3],
    r_alpha: [f64; 3],
    r_beta: [f64; 3],
    flank: bool,
) -> (f64, f64) {
    let vcg = [
        v * alpha.cos() * beta.cos(),
        v * beta.sin(),
        v * alpha.sin() * beta.cos(),
    ];
    let ra = cross(w, r_alpha);
    let rb = cross(w, r_beta);
    let va = [vcg[0] + ra[0], vcg[1] + ra[1], vcg[2] + ra[2]];
    let vb = [vcg[0] + rb[0], vcg[1] + rb[1], vcg[2] + rb[2]];
    let nb = (vb[0] * vb[0] + vb[1] * vb[1] + vb[2] * vb[2]).sqrt();
    let beta_vane = if flank {
        vb[1].atan2(vb[0])
    } else {
        (vb[1] / nb).clamp(-1.0, 1.0).asin()
    };
    (va[2].atan2(va[0]), beta_vane)
}

/// CG angle of attack and sideslip (rad) from vane readings (rad), one sample: exact
/// inversion of [`vanes_at_sensor_point`]. Given $\beta$, the alpha vane relation has the
/// closed form $\sin(\alpha - \alpha_v) = (c_x\sin\alpha_v - c_z\cos\alpha_v)/(V\cos\beta)$
/// with $\mathbf c = \boldsymbol\omega\times\mathbf r_\alpha$; $\beta$ is found by fixed-point
/// iteration on the beta vane relation (at most 20 steps, stops when a step is below 1e-9 rad; the error left is then ~1e-11 rad). `v` is the
/// true airspeed at the CG, m/s (must be > 0). With `flank` the beta vane reads the flank angle
/// ($\tan\beta_f = \tan\beta/\cos\alpha$ at the vane: 5 % above the sideslip at 18 deg
/// alpha); its Newton step uses $d\beta_f/d\beta \approx 1/\cos\alpha$.
#[inline]
pub fn vanes_to_cg_point(
    alpha_v: f64,
    beta_v: f64,
    v: f64,
    w: [f64; 3],
    r_alpha: [f64; 3],
    r_beta: [f64; 3],
    flank: bool,
) -> (f64, f64) {
    let c = cross(w, r_alpha);
    let (sav, cav) = alpha_v.sin_cos();
    let num = c[0] * sav - c[2] * cav;
    let alpha_of = |cos_b: f64| alpha_v + (num / (v * cos_b)).clamp(-1.0, 1.0).asin();
    let sbv = beta_v.sin();
    let cb = cross(w, r_beta);
    // start from the first-order sideslip correction; Newton steps on sin(beta_vane)
    // (d sin(beta_v)/d beta = cos(beta) to first order) then converge in one or two steps
    let mut b = beta_v - (w[2] * r_beta[0] - w[0] * r_beta[2]) / v;
    let mut cos_b = b.cos();
    let mut a = alpha_of(cos_b);
    for _ in 0..20 {
        let (sa, ca) = a.sin_cos();
        let (sb, cbt) = b.sin_cos();
        let vb = [v * ca * cbt + cb[0], v * sb + cb[1], v * sa * cbt + cb[2]];
        let db = if flank {
            (beta_v - vb[1].atan2(vb[0])) * ca
        } else {
            let nb = (vb[0] * vb[0] + vb[1] * vb[1] + vb[2] * vb[2]).sqrt();
            (sbv - vb[1] / nb) / cbt
        };
        b += db;
        cos_b = cbt - sb * db; // cos(b + db) to O(db^2)
        a = alpha_of(cos_b);
        if db.abs() < 1e-9 {
            break;
        }
    }
    (a, b)
}

/// Batch accelerometer transfer to the CG. All slices have the same length; rates in rad/s,
/// angular accelerations in rad/s², specific forces in m/s². Returns `(ax, ay, az)` at the CG.
#[allow(clippy::too_many_arguments)]
pub fn accel_to_cg(
    a: [&[f64]; 3],
    w: [&[f64]; 3],
    wdot: [&[f64]; 3],
    r_s: [f64; 3],
) -> [Vec<f64>; 3] {
    let n = a[0].len();
    let mut out = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    for i in 0..n {
        let c = accel_to_cg_point(
            [a[0][i], a[1][i], a[2][i]],
            [w[0][i], w[1][i], w[2][i]],
            [wdot[0][i], wdot[1][i], wdot[2][i]],
            r_s,
        );
        out[0][i] = c[0];
        out[1][i] = c[1];
        out[2][i] = c[2];
    }
    out
}

/// Batch vane correction: `(alpha_cg, beta_cg)` in rad from vane angles in rad, airspeed in m/s
/// and rates in rad/s. Samples with a non-positive or non-finite airspeed are returned as read.
pub fn vanes_to_cg(
    alpha_v: &[f64],
    beta_v: &[f64],
    v: &[f64],
    w: [&[f64]; 3],
    r_alpha: [f64; 3],
    r_beta: [f64; 3],
    flank: bool,
) -> (Vec<f64>, Vec<f64>) {
    let n = alpha_v.len();
    let mut a = Vec::with_capacity(n);
    let mut b = Vec::with_capacity(n);
    for i in 0..n {
        if v[i] > 0.0 && v[i].is_finite() {
            let (ai, bi) = vanes_to_cg_point(
                alpha_v[i],
                beta_v[i],
                v[i],
                [w[0][i], w[1][i], w[2][i]],
                r_alpha,
                r_beta,
                flank,
            );
            a.push(ai);
            b.push(bi);
        } else {
            a.push(alpha_v[i]);
            b.push(beta_v[i]);
        }
    }
    (a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pure_rotation_cg_transfer_is_exact() {
        // rotation about the CG only: the CG feels nothing, the sensor feels centripetal + tangential
        let w = [0.3, -0.2, 0.5];
        let wdot = [0.1, 0.4, -0.2];
        let r = [1.5, -0.4, 0.8];
        let at_sensor = accel_at_sensor_point([0.0; 3], w, wdot, r);
        // independent: centripetal = w (w.r) - r |w|^2
        let wr = w[0] * r[0] + w[1] * r[1] + w[2] * r[2];
        let w2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
        let tang = cross(wdot, r);
        for k in 0..3 {
            let want = w[k] * wr - r[k] * w2 + tang[k];
            assert!((at_sensor[k] - want).abs() < 1e-14);
        }
        let back = accel_to_cg_point(at_sensor, w, wdot, r);
        assert!(back.iter().all(|v| v.abs() < 1e-14));
    }

    #[test]
    fn vane_inversion_is_exact_and_matches_first_order_formula() {
        let (alpha, beta, v) = (0.2, -0.05, 60.0);
        let w = [0.2, 0.15, -0.1];
        let ra = [8.0, -1.4, 0.5];
        let rb = [8.0, 0.0, -1.2];
        let (av, bv) = vanes_at_sensor_point(alpha, beta, v, w, ra, rb, false);
        let (a, b) = vanes_to_cg_point(av, bv, v, w, ra, rb, false);
        assert!((a - alpha).abs() < 1e-12 && (b - beta).abs() < 1e-12);
        // first-order: alpha = alpha_v + (q x - p y)/V, beta = beta_v - (r x - p z)/V
        let a1 = av + (w[1] * ra[0] - w[0] * ra[1]) / v;
        let b1 = bv - (w[2] * rb[0] - w[0] * rb[2]) / v;
        assert!((a1 - alpha).abs() < 3e-3, "{a1} vs {alpha}");
        assert!((b1 - beta).abs() < 3e-3, "{b1} vs {beta}");
    }

    /// A flank-angle yaw vane: its reading is tan(beta_f) = v/u, independently computed here
    /// from the local velocity, and the inversion gives back the CG sideslip, up to 20 deg of
    /// sideslip at 28 deg alpha (where flank and sideslip differ by 12 %).
    #[test]
    fn flank_vane_reading_and_inversion() {
        let w = [0.2, 0.15, -0.1];
        let ra = [8.0, -1.4, 0.5];
        let rb = [8.0, 0.0, -1.2];
        for &(alpha, beta) in &[(0.31_f64, 0.12_f64), (0.49, -0.35), (0.05, 0.02)] {
            let v = 55.0;
            let (av, bv) = vanes_at_sensor_point(alpha, beta, v, w, ra, rb, true);
            let vel = [
                v * alpha.cos() * beta.cos(),
                v * beta.sin(),
                v * alpha.sin() * beta.cos(),
            ];
            let c = cross(w, rb);
            let want = ((vel[1] + c[1]) / (vel[0] + c[0])).atan();
            assert!((bv - want).abs() < 1e-14);
            let (a, b) = vanes_to_cg_point(av, bv, v, w, ra, rb, true);
            assert!(
                (a - alpha).abs() < 1e-10 && (b - beta).abs() < 1e-10,
                "{a} {b}"
            );
            // read as a sideslip vane, the flank angle is the wrong angle (by 1/cos(alpha) - 1:
            // 5 % at 18 deg alpha, 13 % at 28 deg)
            let (_, b_wrong) = vanes_to_cg_point(av, bv, v, w, ra, rb, false);
            if alpha > 0.3 {
                assert!(
                    (b_wrong - beta).abs() > 0.03 * beta.abs(),
                    "{b_wrong} {beta}"
                );
            }
        }
    }
}
