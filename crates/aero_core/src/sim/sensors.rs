//! Flight-test instrumentation: turns true signals into the canonical record
//! channels. Vanes and accelerometer sit at the positions of the aircraft
//! reference file (so the ingestion's corrections matter); noise, per-maneuver
//! biases and the measurement effects of the vocabulary (vane biases, an
//! undeclared accelerometer offset, control lag, time skew) are applied here.
//!
//! Vane angles from the local air velocity V + ω × r_vane: α_v = atan2(w_v, u_v),
//! β_v = asin(v_v/|V_v|) (or the flank angle atan2(v_v, u_v) for a boom yaw vane), each times
//! 1 + its calibration scale error (upwash, sidewash; none by default) plus its bias.
//! Accelerometer: specific force f_cg + ω̇ × r + ω × (ω × r).
//! The positions are those of `aircraft.toml`, from the datum (the nominal
//! CG); with the CG at `d` from the datum a sensor sits at `r − d` from the CG.

use nalgebra::Vector3;

use crate::aircraft::effects::MeasurementEffects;
use crate::aircraft::turboprop::AircraftRef;
use crate::sim::aero::Controls;
use crate::sim::rng::Stream;

/// True signals at one record instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueSample {
    /// Time, s.
    pub t: f64,
    /// Air-relative body velocity (u, v, w), m/s.
    pub v_air: Vector3<f64>,
    /// Body rates, rad/s.
    pub omega: Vector3<f64>,
    /// Angular acceleration, rad/s².
    pub omega_dot: Vector3<f64>,
    /// Euler angles φ, θ, ψ, rad.
    pub euler: Vector3<f64>,
    /// Specific force at the CG (non-gravitational force / m), m/s².
    pub f_cg: Vector3<f64>,
    /// True airspeed, m/s.
    pub tas: f64,
    /// Density, kg/m³.
    pub rho: f64,
    /// Altitude, m.
    pub h: f64,
    /// Acting surface positions, rad.
    pub controls: Controls,
    /// Thrust coefficients per engine.
    pub ct: [f64; 2],
}

/// Noise standard deviations at noise scale 1.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NoiseSpec {
    /// Vanes, deg.
    pub angle_deg: f64,
    /// Rate gyros, deg/s.
    pub rate_dps: f64,
    /// Attitude, deg.
    pub attitude_deg: f64,
    /// Accelerometers, m/s².
    pub accel_mps2: f64,
    /// Airspeed, m/s.
    pub tas_mps: f64,
    /// Control positions, deg.
    pub control_deg: f64,
    /// Thrust coefficient.
    pub ct: f64,
    /// Per-maneuver gyro bias sd, deg/s.
    pub gyro_bias_dps: f64,
    /// Per-maneuver accelerometer bias sd, m/s².
    pub accel_bias_mps2: f64,
}

impl Default for NoiseSpec {
    /// Typical flight-test instrumentation (Klein & Morelli, Ch. 9 sensor tables).
    fn default() -> Self {
        NoiseSpec {
            angle_deg: 0.05,
            rate_dps: 0.03,
            attitude_deg: 0.03,
            accel_mps2: 0.03,
            tas_mps: 0.15,
            control_deg: 0.05,
            ct: 0.002,
            gyro_bias_dps: 0.02,
            accel_bias_mps2: 0.01,
        }
    }
}

/// The record channels in canonical order (without Cl_sim etc.).
pub const CHANNELS: [&str; 24] = [
    "t",
    "alpha_deg",
    "beta_deg",
    "p_dps",
    "q_dps",
    "r_dps",
    "phi_deg",
    "theta_deg",
    "psi_deg",
    "ax_mps2",
    "ay_mps2",
    "az_mps2",
    "tas_mps",
    "rho_kgm3",
    "da_deg",
    "de_deg",
    "dr_deg",
    "dsl_deg",
    "dsr_deg",
    "flap_deg",
    "ct_left",
    "ct_right",
    "prop_rpm",
    "h_m",
];

/// The discrete channels recorded after [`CHANNELS`]: the stick pusher's activation
/// (1 while it pushes, 0 otherwise or without a pusher) and the stall warning (1 while
/// it warns), as a flight-test recorder logs them from the stall-protection computer.
pub const DISCRETE_CHANNELS: [&str; 2] = ["pusher_active", "stall_warning"];

/// The virtual aircraft's stall-warning computer warns when the alpha vane reads at least
/// α_max − this margin (deg), α_max the flap setting's C_L,max alpha: ≈ 5-6 % above the
/// 1-g stall speed on the ADX-37's lift curves, the margin a stall warning gives.
pub const STALL_WARNING_MARGIN_DEG: f64 = 5.0;

/// The warning stops once the vane reads this far (deg) below its onset threshold
/// (hysteresis: vane noise does not make it chatter).
pub const STALL_WARNING_HYSTERESIS_DEG: f64 = 0.5;

/// The stall-warning discrete (0/1 per sample) of a recorded alpha-vane signal: on at the
/// first sample with `alpha_vane_deg[k] ≥ on_deg`, off at the first sample after it with
/// `alpha_vane_deg[k] < on_deg − STALL_WARNING_HYSTERESIS_DEG` (a Schmitt trigger on the
/// vane, as a stall-warning computer's alpha comparator is).
///
/// ```
/// use aero_core::sim::sensors::stall_warning;
/// let w = stall_warning(&[10.0, 14.1, 13.8, 13.4, 14.0], 14.0);
/// assert_eq!(w, vec![0.0, 1.0, 1.0, 0.0, 1.0]);
/// ```
pub fn stall_warning(alpha_vane_deg: &[f64], on_deg: f64) -> Vec<f64> {
    let off = on_deg - STALL_WARNING_HYSTERESIS_DEG;
    let mut on = false;
    alpha_vane_deg
        .iter()
        .map(|&a| {
            if a >= on_deg {
                on = true;
            } else if a < off {
                on = false;
            }
            if on {
                1.0
            } else {
                0.0
            }
        })
        .collect()
}

fn shifted(t: &[f64], y: &[f64], shift: f64) -> Vec<f64> {
    // value at t_k + shift by linear interpolation, holding the ends
    t.iter()
        .map(|&tk| crate::sim::interp_held(t, y, tk + shift))
        .collect()
}

/// The recorded channels ([`CHANNELS`] order) of a maneuver flown with the
/// CG at `cg_offset` (m, body axes) from the datum the sensor positions of `ac`
/// are measured from (and the samples' `f_cg`, `v_air`, at that CG).
#[allow(clippy::too_many_arguments)]
pub fn record(
    samples: &[TrueSample],
    ac: &AircraftRef,
    cg_offset: &Vector3<f64>,
    flap_deg: f64,
    meas: &MeasurementEffects,
    noise: &NoiseSpec,
    noise_scale: f64,
    seed: u64,
    stream: u64,
) -> Vec<Vec<f64>> {
    let mut rng = Stream::new(seed, stream);
    let ns = noise_scale;
    let gb = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * (noise.gyro_bias_dps * ns);
    let ab = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * (noise.accel_bias_mps2 * ns);
    let v3 = |a: [f64; 3]| Vector3::new(a[0], a[1], a[2]);
    // positions from the actual CG (x − 0 = x: the nominal CG changes no bit)
    let r_acc = v3(ac.accel_m) + v3(meas.accelerometer_offset_m) - cg_offset;
    let r_a = v3(ac.alpha_vane_m) - cg_offset;
    let r_b = v3(ac.beta_vane_m) - cg_offset;
    let n = samples.len();
    let mut cols: Vec<Vec<f64>> = (0..CHANNELS.len()).map(|_| Vec::with_capacity(n)).collect();
    // Noise-free values and noise of the channels a timing effect moves: the delay acts on
    // what the sensor sees, and each recorded sample keeps its own noise (shifting the noisy
    // record by interpolation would also average the noise of neighbouring samples, a
    // low-pass no recorder applies).
    let mut timed: Vec<usize> = Vec::new();
    if meas.time_skew_s != 0.0 {
        timed.extend([1usize, 2, 12]);
    }
    if meas.control_lag_s != 0.0 {
        timed.extend(14usize..=18);
    }
    let mut clean: Vec<Vec<f64>> = timed.iter().map(|_| Vec::with_capacity(n)).collect();
    let mut noisy_part: Vec<Vec<f64>> = timed.iter().map(|_| Vec::with_capacity(n)).collect();
    for s in samples {
        let mut nz = |sd: f64| sd * ns * rng.normal();
        let va = s.v_air + s.omega.cross(&r_a);
        let vb = s.v_air + s.omega.cross(&r_b);
        let cal = &meas.vanes;
        let alpha_v =
            (1.0 + cal.alpha_scale) * va.z.atan2(va.x).to_degrees() + meas.alpha_vane_bias_deg;
        let beta_flow = if cal.beta_flank {
            vb.y.atan2(vb.x)
        } else {
            (vb.y / vb.norm()).clamp(-1.0, 1.0).asin()
        };
        let beta_v = (1.0 + cal.beta_scale) * beta_flow.to_degrees() + meas.beta_vane_bias_deg;
        let acc = s.f_cg + s.omega_dot.cross(&r_acc) + s.omega.cross(&s.omega.cross(&r_acc)) + ab;
        let rates = s.omega.map(f64::to_degrees) + gb;
        let c = &s.controls;
        // noise per channel, drawn in channel order (the same stream whatever the effects);
        // time, density, flap, propeller speed and altitude are recorded without noise
        let e: [f64; 24] = [
            0.0,
            nz(noise.angle_deg),
            nz(noise.angle_deg),
            nz(noise.rate_dps),
            nz(noise.rate_dps),
            nz(noise.rate_dps),
            nz(noise.attitude_deg),
            nz(noise.attitude_deg),
            nz(noise.attitude_deg),
            nz(noise.accel_mps2),
            nz(noise.accel_mps2),
            nz(noise.accel_mps2),
            nz(noise.tas_mps),
            0.0,
            nz(noise.control_deg),
            nz(noise.control_deg),
            nz(noise.control_deg),
            nz(noise.control_deg),
            nz(noise.control_deg),
            0.0,
            nz(noise.ct),
            nz(noise.ct),
            0.0,
            0.0,
        ];
        let truth = [
            s.t,
            alpha_v,
            beta_v,
            rates.x,
            rates.y,
            rates.z,
            s.euler.x.to_degrees(),
            s.euler.y.to_degrees(),
            s.euler.z.to_degrees(),
            acc.x,
            acc.y,
            acc.z,
            s.tas,
            s.rho,
            c.da.to_degrees(),
            c.de.to_degrees(),
            c.dr.to_degrees(),
            c.dsl.to_degrees(),
            c.dsr.to_degrees(),
            flap_deg,
            s.ct[0],
            s.ct[1],
            ac.prop_rpm,
            s.h,
        ];
        for ((col, v), ek) in cols.iter_mut().zip(truth).zip(e) {
            col.push(v + ek);
        }
        for (i, &k) in timed.iter().enumerate() {
            clean[i].push(truth[k]);
            noisy_part[i].push(e[k]);
        }
    }
    if n >= 2 {
        let t = cols[0].clone();
        // air data recorded late: rec(t) = true(t − τ) + noise(t); recorded controls lead
        // the acting ones: rec(t) = acting(t + τ) + noise(t)
        for (i, &k) in timed.iter().enumerate() {
            let shift = if k <= 12 {
                -meas.time_skew_s
            } else {
                meas.control_lag_s
            };
            cols[k] = shifted(&t, &clean[i], shift)
                .iter()
                .zip(&noisy_part[i])
                .map(|(v, e)| v + e)
                .collect();
        }
    }
    cols
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aircraft::turboprop::adx37;

    #[test]
    fn time_skew_delays_what_the_vane_sees_and_keeps_each_sample_noise() {
        // alpha(t) = 5 + 2 sin(2 pi 0.5 t) deg seen by a vane at the CG (no rotation), 50 Hz;
        // the same seed with and without 10 ms of skew (half a sample): the records differ by
        // the noise-free signal's delay only, so each sample keeps its own noise (shifting the
        // noisy record would have averaged neighbouring samples' noise, halving its variance)
        let ac = adx37();
        let mut ac0 = ac.clone();
        ac0.alpha_vane_m = [0.0; 3];
        let alpha = |t: f64| 5.0 + 2.0 * (std::f64::consts::PI * t).sin();
        let samples: Vec<TrueSample> = (0..500)
            .map(|k| {
                let t = 0.02 * k as f64;
                TrueSample {
                    t,
                    v_air: Vector3::new(60.0, 0.0, 60.0 * alpha(t).to_radians().tan()),
                    omega: Vector3::zeros(),
                    omega_dot: Vector3::zeros(),
                    euler: Vector3::zeros(),
                    f_cg: Vector3::new(0.0, 0.0, -9.8),
                    tas: 60.0,
                    rho: 1.0,
                    h: 3000.0,
                    controls: Controls::default(),
                    ct: [0.1, 0.1],
                }
            })
            .collect();
        let noise = NoiseSpec::default();
        let mut skew = MeasurementEffects::none();
        skew.time_skew_s = 0.01;
        let a = record(
            &samples,
            &ac0,
            &Vector3::zeros(),
            0.0,
            &MeasurementEffects::none(),
            &noise,
            1.0,
            3,
            0,
        );
        let b = record(
            &samples,
            &ac0,
            &Vector3::zeros(),
            0.0,
            &skew,
            &noise,
            1.0,
            3,
            0,
        );
        let mut max_err: f64 = 0.0;
        let mut e_var = 0.0;
        for k in 1..499 {
            let t = 0.02 * k as f64;
            let delay = alpha(t - 0.01) - alpha(t); // closed form of the delay alone
            max_err = max_err.max((b[1][k] - a[1][k] - delay).abs());
            e_var += (a[1][k] - alpha(t)).powi(2) / 498.0;
        }
        // linear interpolation of the clean 50 Hz samples: error <= dt^2/8 max|alpha''|
        let bound = 0.02f64.powi(2) / 8.0 * 2.0 * std::f64::consts::PI.powi(2) * 1.0001;
        assert!(max_err < bound, "{max_err} vs {bound}");
        assert!(
            (e_var.sqrt() / noise.angle_deg - 1.0).abs() < 0.15,
            "{}",
            e_var.sqrt()
        );
        // untouched channels are identical
        assert_eq!(a[3], b[3]);
        assert_eq!(a[14], b[14]);
    }

    /// One level, unaccelerated-attitude sample with air velocity `v_air`, rates `omega` and
    /// angular acceleration `omega_dot` (specific force 9.8 m/s² up).
    fn one_sample(v_air: Vector3<f64>, omega: Vector3<f64>, omega_dot: Vector3<f64>) -> TrueSample {
        TrueSample {
            t: 0.0,
            v_air,
            omega,
            omega_dot,
            euler: Vector3::zeros(),
            f_cg: Vector3::new(0.0, 0.0, -9.8),
            tas: v_air.norm(),
            rho: 1.0,
            h: 3000.0,
            controls: Controls::default(),
            ct: [0.1, 0.1],
        }
    }

    /// The noise-free record of `s` with the CG at `cg` from the datum and effects `meas`.
    fn record_one(s: TrueSample, cg: &Vector3<f64>, meas: &MeasurementEffects) -> Vec<Vec<f64>> {
        record(
            &[s],
            &adx37(),
            cg,
            0.0,
            meas,
            &NoiseSpec::default(),
            0.0,
            0,
            0,
        )
    }

    #[test]
    fn accelerometer_and_vane_kinematics() {
        let ac = adx37();
        let s = one_sample(
            Vector3::new(60.0, 0.0, 6.0),
            Vector3::new(0.0, 0.1, 0.0),
            Vector3::new(0.5, 0.0, 0.0),
        );
        let cols = record_one(s, &Vector3::zeros(), &MeasurementEffects::none());
        let r = ac.accel_m;
        // ω̇ × r with ω̇ = (0.5,0,0): (0, -0.5 r_z, 0.5 r_y); ω×(ω×r) with ω=(0,q,0): (-q² r_x, 0, -q² r_z)
        assert!((cols[9][0] - (-0.01 * r[0])).abs() < 1e-12);
        assert!((cols[10][0] - (-0.5 * r[2])).abs() < 1e-12);
        assert!((cols[11][0] - (-9.8 + 0.5 * r[1] - 0.01 * r[2])).abs() < 1e-12);
        // vane: w_local = w − q x_vane
        let xv = ac.alpha_vane_m[0];
        let expect = (6.0 - 0.1 * xv).atan2(60.0).to_degrees();
        assert!((cols[1][0] - expect).abs() < 1e-12);
    }

    #[test]
    fn sensors_sit_at_their_datum_positions_minus_the_cg_offset() {
        // the CG 0.1 m aft, 0.03 m right, 0.05 m below the datum: each sensor is r − d from it
        let ac = adx37();
        let d = Vector3::new(-0.1, 0.03, 0.05);
        let s = one_sample(
            Vector3::new(60.0, 1.0, 6.0),
            Vector3::new(0.0, 0.1, 0.0),
            Vector3::new(0.5, 0.0, 0.0),
        );
        let rec = |off: &Vector3<f64>| record_one(s, off, &MeasurementEffects::none());
        let cols = rec(&d);
        let r = [
            ac.accel_m[0] - d.x,
            ac.accel_m[1] - d.y,
            ac.accel_m[2] - d.z,
        ];
        assert!((cols[9][0] - (-0.01 * r[0])).abs() < 1e-12);
        assert!((cols[10][0] - (-0.5 * r[2])).abs() < 1e-12);
        assert!((cols[11][0] - (-9.8 + 0.5 * r[1] - 0.01 * r[2])).abs() < 1e-12);
        // ω × r with ω = (0, q, 0) is (q z, 0, −q x): the alpha vane at x = 9.5 + 0.1,
        // z = −0.05 from the CG sees u = 60 + q z, w = 6 − q x
        let (xa, za) = (ac.alpha_vane_m[0] - d.x, ac.alpha_vane_m[2] - d.z);
        let expect = (6.0 - 0.1 * xa).atan2(60.0 + 0.1 * za).to_degrees();
        assert!((cols[1][0] - expect).abs() < 1e-12);
        // the beta vane: v is unchanged, u = 60 + q z, w = 6 − q x
        let (xb, zb) = (ac.beta_vane_m[0] - d.x, ac.beta_vane_m[2] - d.z);
        let vb = Vector3::new(60.0 + 0.1 * zb, 1.0, 6.0 - 0.1 * xb);
        let expect = (vb.y / vb.norm()).asin().to_degrees();
        assert!((cols[2][0] - expect).abs() < 1e-12);
        // and the offset matters: the nominal CG records other values
        let nominal = rec(&Vector3::zeros());
        assert!((nominal[1][0] - cols[1][0]).abs() > 1e-3);
        assert!((nominal[11][0] - cols[11][0]).abs() > 1e-3);
    }

    /// Upwash and sidewash scale errors multiply the angle each vane sees, and a flank vane
    /// reads atan2(v, u) of its local flow (computed here from the local velocity).
    #[test]
    fn vane_calibration_errors() {
        use crate::aircraft::effects::VaneCalibration;
        let ac = adx37();
        let s = one_sample(
            Vector3::new(55.0, 9.0, 16.0),
            Vector3::new(0.05, 0.1, -0.08),
            Vector3::zeros(),
        );
        let rec = |meas: &MeasurementEffects| record_one(s, &Vector3::zeros(), meas);
        let ideal = rec(&MeasurementEffects::none());
        let mut m = MeasurementEffects::none();
        m.alpha_vane_bias_deg = 0.7;
        m.vanes = VaneCalibration {
            alpha_scale: 0.06,
            beta_scale: -0.08,
            beta_flank: true,
        };
        let cal = rec(&m);
        assert!((cal[1][0] - (1.06 * ideal[1][0] + 0.7)).abs() < 1e-12);
        let rb = Vector3::from(ac.beta_vane_m);
        let vb = s.v_air + s.omega.cross(&rb);
        let flank = vb.y.atan2(vb.x).to_degrees();
        assert!((cal[2][0] - 0.92 * flank).abs() < 1e-12);
        assert!(
            (flank - ideal[2][0]).abs() > 0.1,
            "flank and sideslip differ at 16 deg alpha"
        );
    }
}
