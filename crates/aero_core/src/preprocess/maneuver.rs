//! The per-maneuver preprocessing pipeline and its batch form over concatenated records.
//!
//! For each maneuver (canonical units at the edges: deg, deg/s, m/s², m/s, kg/m³):
//! 1. optimal Fourier smoothing ([`super::smooth`]) of alpha, beta, p, q, r, ax, ay, az, tas,
//!    each with its own data-chosen cut-off (reported);
//! 2. $\dot p, \dot q, \dot r$ by central differences of the smoothed rates (SIDPAC `deriv`);
//! 3. accelerometer transfer to the CG ([`super::kinematics::accel_to_cg`]);
//! 4. vane corrections to the CG ([`super::kinematics::vanes_to_cg`]) and
//!    $\dot\alpha, \dot\beta$ of the corrected angles;
//! 5. $\bar q = \tfrac12\rho V^2$, $\hat p = pb/2V$, $\hat q = q\bar c/2V$, $\hat r = rb/2V$;
//! 6. measured coefficients (thesis Eq. 3.2-3.4, [`super::coefficients`]), with the propeller
//!    angular momentum $h_p = k_p\,N_{rpm}$, $k_p = n_{eff} I_p 2\pi/60$.

use super::coefficients::{coefficients, MassGeometry};
use super::deriv::central_diff;
use super::kinematics::{accel_to_cg, vanes_to_cg};
use super::smooth::Smoother;
use crate::error::{AeroError, Result, ResultExt};

/// Input channels, in the order the batch functions take them.
pub const INPUT_COLUMNS: [&str; 13] = [
    "t",
    "alpha_deg",
    "beta_deg",
    "p_dps",
    "q_dps",
    "r_dps",
    "ax_mps2",
    "ay_mps2",
    "az_mps2",
    "tas_mps",
    "rho_kgm3",
    "prop_rpm",
    "unused",
];

/// Channels smoothed (with a reported cut-off), in order.
pub const SMOOTHED_COLUMNS: [&str; 9] = [
    "alpha_deg",
    "beta_deg",
    "p_dps",
    "q_dps",
    "r_dps",
    "ax_mps2",
    "ay_mps2",
    "az_mps2",
    "tas_mps",
];

/// Output columns, in order.
pub const OUTPUT_COLUMNS: [&str; 23] = [
    "alpha_cg_deg",
    "beta_cg_deg",
    "p_s_dps",
    "q_s_dps",
    "r_s_dps",
    "pdot_dps2",
    "qdot_dps2",
    "rdot_dps2",
    "alphadot_dps",
    "betadot_dps",
    "ax_cg_mps2",
    "ay_cg_mps2",
    "az_cg_mps2",
    "tas_s_mps",
    "qbar_pa",
    "phat",
    "qhat",
    "rhat",
    "Cl_meas",
    "Cn_meas",
    "CY_meas",
    "CX_meas",
    "CZ_meas",
];

/// Extra output column (kept separate so the array above stays short): pitching moment.
pub const CM_COLUMN: &str = "Cm_meas";

/// What the pipeline needs to know about the aircraft.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AircraftParams {
    /// Mass, inertias and reference geometry.
    pub mg: MassGeometry,
    /// $k_p$ such that $h_p = k_p N_{rpm}$ (kg m²/s per rpm, thesis sign; 0 without propellers).
    pub prop_h_per_rpm: f64,
    /// Accelerometer position relative to the CG, body axes, m.
    pub accel_m: [f64; 3],
    /// Alpha vane position, m.
    pub alpha_vane_m: [f64; 3],
    /// Beta vane position, m.
    pub beta_vane_m: [f64; 3],
}

/// Options of the pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreprocessOptions {
    /// Smooth before differentiating (SIDPAC-style). Off: raw data, central differences.
    pub smooth: bool,
}

impl Default for PreprocessOptions {
    fn default() -> Self {
        PreprocessOptions { smooth: true }
    }
}

/// Output of one maneuver: columns in the order of [`OUTPUT_COLUMNS`] then Cm, and the
/// smoother cut-offs (Hz) in the order of [`SMOOTHED_COLUMNS`] (Nyquist when not smoothed).
#[derive(Debug, Clone)]
pub struct ManeuverOutput {
    /// Derived columns ([`OUTPUT_COLUMNS`] then [`CM_COLUMN`]).
    pub columns: Vec<Vec<f64>>,
    /// Cut-off per smoothed channel, Hz.
    pub cutoffs_hz: Vec<f64>,
    /// Noise standard deviation per smoothed channel, channel units.
    pub noise_std: Vec<f64>,
}

/// Preprocess one maneuver. `cols` are the channels of [`INPUT_COLUMNS`] (the last, unused,
/// may be empty), all of the same length; `t` uniformly sampled.
///
/// # Errors
/// `TooLittleData` under 8 samples; `InvalidInput` for unequal lengths, a non-uniform or
/// non-increasing time vector, or a non-positive airspeed or density.
pub fn preprocess_maneuver(
    cols: &[&[f64]],
    ac: &AircraftParams,
    opts: &PreprocessOptions,
) -> Result<ManeuverOutput> {
    let n = cols[0].len();
    if n < 8 {
        return Err(AeroError::too_little(
            "maneuver",
            format!("{n} samples; need at least 8"),
        ));
    }
    for (k, c) in cols.iter().enumerate().take(12) {
        if c.len() != n {
            return Err(AeroError::invalid(
                format!("channel '{}'", INPUT_COLUMNS[k]),
                format!("{} samples where 't' has {n}", c.len()),
            ));
        }
    }
    let t = cols[0];
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    if dt.is_nan() || dt <= 0.0 {
        return Err(AeroError::invalid("channel 't'", "time does not increase"));
    }
    for i in 1..n {
        let d = t[i] - t[i - 1];
        if d.is_nan() || d <= 0.0 || (d - dt).abs() > 0.01 * dt {
            return Err(AeroError::invalid(
                "channel 't'",
                format!("rows {}-{}: step {d} s where the record's mean step is {dt} s; resample to a uniform rate", i - 1, i),
            ));
        }
    }
    for (k, name) in [(9usize, "tas_mps"), (10, "rho_kgm3")] {
        if let Some(i) = cols[k]
            .iter()
            .position(|v| v.is_nan() || *v <= 0.0 || !v.is_finite())
        {
            return Err(AeroError::invalid(
                format!("channel '{name}'"),
                format!("row {i}: value {} is not positive", cols[k][i]),
            ));
        }
    }
    let sm = Smoother::new(n);
    let nyq = 0.5 / dt;
    let mut cut = Vec::with_capacity(9);
    let mut noise = Vec::with_capacity(9);
    let mut s: Vec<Vec<f64>> = Vec::with_capacity(9);
    if opts.smooth {
        // channels 1..=9 in pairs sharing one complex FFT
        let mut push = |r: super::smooth::Smoothed| {
            cut.push(r.cutoff_hz);
            noise.push(r.noise_std);
            s.push(r.values);
        };
        for k in [1usize, 3, 5, 7] {
            let (a, b) = sm.smooth_pair(cols[k], cols[k + 1], dt);
            push(a);
            push(b);
        }
        push(sm.smooth(cols[9], dt));
    } else {
        for k in 1..=9 {
            cut.push(nyq);
            noise.push(0.0);
            s.push(cols[k].to_vec());
        }
    }
    let d2r = std::f64::consts::PI / 180.0;
    let w: Vec<Vec<f64>> = (2..5)
        .map(|k| s[k].iter().map(|v| v * d2r).collect())
        .collect();
    let wd: Vec<Vec<f64>> = w.iter().map(|x| central_diff(x, dt)).collect();
    let a_cg = accel_to_cg(
        [&s[5], &s[6], &s[7]],
        [&w[0], &w[1], &w[2]],
        [&wd[0], &wd[1], &wd[2]],
        ac.accel_m,
    );
    let av: Vec<f64> = s[0].iter().map(|v| v * d2r).collect();
    let bv: Vec<f64> = s[1].iter().map(|v| v * d2r).collect();
    let tas = &s[8];
    let (a_cg_rad, b_cg_rad) = vanes_to_cg(
        &av,
        &bv,
        tas,
        [&w[0], &w[1], &w[2]],
        ac.alpha_vane_m,
        ac.beta_vane_m,
    );
    let alphadot = central_diff(&a_cg_rad, dt);
    let betadot = central_diff(&b_cg_rad, dt);
    let rho = cols[10];
    let qbar: Vec<f64> = rho.iter().zip(tas).map(|(r, v)| 0.5 * r * v * v).collect();
    let mg = &ac.mg;
    let hat = |x: &[f64], len: f64| -> Vec<f64> {
        x.iter()
            .zip(tas)
            .map(|(a, v)| a * len / (2.0 * v))
            .collect()
    };
    let h_p: Vec<f64> = cols[11].iter().map(|rpm| ac.prop_h_per_rpm * rpm).collect();
    let coef = coefficients(
        mg,
        [&w[0], &w[1], &w[2]],
        [&wd[0], &wd[1], &wd[2]],
        [&a_cg[0], &a_cg[1], &a_cg[2]],
        &qbar,
        &h_p,
    );
    let r2d = 1.0 / d2r;
    let deg = |x: &[f64]| -> Vec<f64> { x.iter().map(|v| v * r2d).collect() };
    let phat = hat(&w[0], mg.b);
    let qhat = hat(&w[1], mg.cbar);
    let rhat = hat(&w[2], mg.b);
    let [cl, cn, cy, cx, cz, cm] = coef;
    let [ax, ay, az] = a_cg;
    let columns = vec![
        deg(&a_cg_rad),
        deg(&b_cg_rad),
        s[2].clone(),
        s[3].clone(),
        s[4].clone(),
        deg(&wd[0]),
        deg(&wd[1]),
        deg(&wd[2]),
        deg(&alphadot),
        deg(&betadot),
        ax,
        ay,
        az,
        tas.clone(),
        qbar,
        phat,
        qhat,
        rhat,
        cl,
        cn,
        cy,
        cx,
        cz,
        cm,
    ];
    Ok(ManeuverOutput {
        columns,
        cutoffs_hz: cut,
        noise_std: noise,
    })
}

/// Outputs of [`preprocess_concatenated`].
#[derive(Debug, Clone)]
pub struct BatchOutput {
    /// Concatenated derived columns ([`OUTPUT_COLUMNS`] then [`CM_COLUMN`]).
    pub columns: Vec<Vec<f64>>,
    /// Row-major `n_maneuvers x 9` cut-offs, Hz.
    pub cutoffs_hz: Vec<f64>,
    /// Row-major `n_maneuvers x 9` noise standard deviations.
    pub noise_std: Vec<f64>,
}

/// Preprocess many maneuvers stored back to back: `cols` as in [`preprocess_maneuver`] over
/// the whole campaign, `offsets` the start row of each maneuver plus the total length
/// (`offsets[0] == 0`, increasing). Maneuvers run in parallel with the `parallel` feature;
/// results are identical either way.
///
/// # Errors
/// The first failing maneuver's error, with its index as context.
pub fn preprocess_concatenated(
    cols: &[&[f64]],
    offsets: &[usize],
    ac: &AircraftParams,
    opts: &PreprocessOptions,
) -> Result<BatchOutput> {
    let total = cols.first().map_or(0, |c| c.len());
    if offsets.len() < 2
        || offsets[0] != 0
        || offsets[offsets.len() - 1] != total
        || offsets.windows(2).any(|w| w[1] <= w[0])
    {
        return Err(AeroError::invalid(
            "argument 'offsets'",
            format!("must start at 0, increase strictly and end at the row count {total}"),
        ));
    }
    if cols.len() < 12 {
        return Err(AeroError::invalid(
            "argument 'columns'",
            format!("{} columns; 12 expected", cols.len()),
        ));
    }
    let one = |m: usize| -> Result<ManeuverOutput> {
        let (a, b) = (offsets[m], offsets[m + 1]);
        let sub: Vec<&[f64]> = cols.iter().take(12).map(|c| &c[a..b]).collect();
        preprocess_maneuver(&sub, ac, opts)
            .with_context(|| format!("maneuver #{m} (rows {a}-{})", b - 1))
    };
    let nm = offsets.len() - 1;
    #[cfg(feature = "parallel")]
    let outs: Vec<Result<ManeuverOutput>> = {
        use rayon::prelude::*;
        (0..nm).into_par_iter().map(one).collect()
    };
    #[cfg(not(feature = "parallel"))]
    let outs: Vec<Result<ManeuverOutput>> = (0..nm).map(one).collect();
    let ncol = OUTPUT_COLUMNS.len() + 1;
    let mut columns: Vec<Vec<f64>> = (0..ncol).map(|_| Vec::with_capacity(total)).collect();
    let mut cutoffs_hz = Vec::with_capacity(nm * 9);
    let mut noise_std = Vec::with_capacity(nm * 9);
    for o in outs {
        let o = o?;
        for (dst, src) in columns.iter_mut().zip(o.columns) {
            dst.extend_from_slice(&src);
        }
        cutoffs_hz.extend_from_slice(&o.cutoffs_hz);
        noise_std.extend_from_slice(&o.noise_std);
    }
    Ok(BatchOutput {
        columns,
        cutoffs_hz,
        noise_std,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_bad_offsets_and_non_uniform_time() {
        let ac = AircraftParams {
            mg: MassGeometry {
                s: 1.0,
                b: 1.0,
                cbar: 1.0,
                mass: 1.0,
                ixx: 1.0,
                iyy: 1.0,
                izz: 1.0,
                ixz: 0.0,
            },
            prop_h_per_rpm: 0.0,
            accel_m: [0.0; 3],
            alpha_vane_m: [0.0; 3],
            beta_vane_m: [0.0; 3],
        };
        let mut t: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let one = [1.0; 20];
        let cols: Vec<&[f64]> = std::iter::once(&t[..])
            .chain(std::iter::repeat_n(&one[..], 11))
            .collect();
        assert!(
            preprocess_concatenated(&cols, &[0, 25], &ac, &PreprocessOptions::default()).is_err()
        );
        let ok = preprocess_concatenated(&cols, &[0, 10, 20], &ac, &PreprocessOptions::default())
            .unwrap();
        assert_eq!(ok.columns[0].len(), 20);
        assert_eq!(ok.cutoffs_hz.len(), 18);
        t[5] += 0.05;
        let cols: Vec<&[f64]> = std::iter::once(&t[..])
            .chain(std::iter::repeat_n(&one[..], 11))
            .collect();
        let e = preprocess_concatenated(&cols, &[0, 20], &ac, &PreprocessOptions::default())
            .unwrap_err();
        assert!(e.to_string().contains("rows 4-5"), "{e}");
    }
}
