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
//!    angular momentum $h_p = k_p\,N_{rpm}$, $k_p = n_{eff} I_p 2\pi/60$, and the moments
//!    transferred from the maneuver's CG to the moment reference centre.
//!
//! Positions (sensors, CG, moment reference centre) are body axes from one fixed aircraft
//! datum, so a maneuver flown with another loading ([`ManeuverMass`]) sees its sensors at
//! their positions less its CG.

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
    /// Mass, inertias and reference geometry of the nominal loading.
    pub mg: MassGeometry,
    /// $k_p$ such that $h_p = k_p N_{rpm}$ (kg m²/s per rpm, thesis sign; 0 without propellers).
    pub prop_h_per_rpm: f64,
    /// Accelerometer position from the datum, body axes, m.
    pub accel_m: [f64; 3],
    /// Alpha vane position from the datum, m.
    pub alpha_vane_m: [f64; 3],
    /// Beta vane position from the datum, m.
    pub beta_vane_m: [f64; 3],
    /// CG of the nominal loading from the datum, m (zero: the datum is the CG).
    pub cg_m: [f64; 3],
    /// Moment reference centre from the datum, m: the moment coefficients are about it.
    pub moment_ref_m: [f64; 3],
    /// The beta vane reads the flank angle (a boom yaw vane), not the sideslip.
    pub beta_flank: bool,
}

/// One maneuver's loading: mass, inertia tensor about its CG and CG position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ManeuverMass {
    /// Mass, kg.
    pub mass: f64,
    /// `[Ixx, Iyy, Izz, Ixz, Ixy, Iyz]` about the CG, Etkin sign, kg m².
    pub inertia: [f64; 6],
    /// CG from the datum, body axes, m.
    pub cg_m: [f64; 3],
}

impl ManeuverMass {
    /// Refuses a non-finite or non-positive mass, a non-finite CG or an inertia tensor that is
    /// not positive definite (leading principal minors of the Etkin tensor).
    fn check(&self) -> Result<()> {
        let [ixx, iyy, izz, ixz, ixy, iyz] = self.inertia;
        let finite = self.mass.is_finite()
            && self.inertia.iter().all(|v| v.is_finite())
            && self.cg_m.iter().all(|v| v.is_finite());
        let m2 = ixx * iyy - ixy * ixy;
        let det = ixx * (iyy * izz - iyz * iyz)
            - ixy * (ixy * izz + iyz * ixz)
            - ixz * (ixy * iyz + iyy * ixz);
        if !finite || self.mass <= 0.0 || ixx <= 0.0 || m2 <= 0.0 || det <= 0.0 {
            return Err(AeroError::invalid(
                "mass properties",
                format!(
                    "mass {} kg, inertia {:?} kg m2, CG {:?} m: need a positive mass, a \
                     positive definite inertia tensor and a finite CG",
                    self.mass, self.inertia, self.cg_m
                ),
            ));
        }
        Ok(())
    }
}

impl AircraftParams {
    /// The parameters of a maneuver flown with loading `mm`.
    pub fn with_mass(&self, mm: &ManeuverMass) -> AircraftParams {
        let [ixx, iyy, izz, ixz, ixy, iyz] = mm.inertia;
        AircraftParams {
            mg: MassGeometry {
                mass: mm.mass,
                ixx,
                iyy,
                izz,
                ixz,
                ixy,
                iyz,
                ..self.mg
            },
            cg_m: mm.cg_m,
            ..*self
        }
    }
}

fn minus(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
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
        minus(ac.accel_m, ac.cg_m),
    );
    let av: Vec<f64> = s[0].iter().map(|v| v * d2r).collect();
    let bv: Vec<f64> = s[1].iter().map(|v| v * d2r).collect();
    let tas = &s[8];
    let (a_cg_rad, b_cg_rad) = vanes_to_cg(
        &av,
        &bv,
        tas,
        [&w[0], &w[1], &w[2]],
        minus(ac.alpha_vane_m, ac.cg_m),
        minus(ac.beta_vane_m, ac.cg_m),
        ac.beta_flank,
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
        minus(ac.cg_m, ac.moment_ref_m),
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
/// (`offsets[0] == 0`, increasing). `masses` holds each maneuver's loading (one per maneuver)
/// or is empty (every maneuver flown with the nominal one of `ac`). Maneuvers run in parallel
/// with the `parallel` feature; results are identical either way.
///
/// # Errors
/// The first failing maneuver's error, with its index as context; `InvalidInput` when
/// `masses` is neither empty nor one per maneuver, or a loading is not physical.
pub fn preprocess_concatenated(
    cols: &[&[f64]],
    offsets: &[usize],
    ac: &AircraftParams,
    masses: &[ManeuverMass],
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
    let nm = offsets.len() - 1;
    if !masses.is_empty() && masses.len() != nm {
        return Err(AeroError::invalid(
            "argument 'masses'",
            format!(
                "{} loadings for {nm} maneuvers; give one per maneuver or none",
                masses.len()
            ),
        ));
    }
    for (m, mm) in masses.iter().enumerate() {
        mm.check().with_context(|| format!("maneuver #{m}"))?;
    }
    let one = |m: usize| -> Result<ManeuverOutput> {
        let (a, b) = (offsets[m], offsets[m + 1]);
        let sub: Vec<&[f64]> = cols.iter().take(12).map(|c| &c[a..b]).collect();
        let acm = masses.get(m).map_or(*ac, |mm| ac.with_mass(mm));
        preprocess_maneuver(&sub, &acm, opts)
            .with_context(|| format!("maneuver #{m} (rows {a}-{})", b - 1))
    };
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
            mg: MassGeometry::principal(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0),
            prop_h_per_rpm: 0.0,
            accel_m: [0.0; 3],
            alpha_vane_m: [0.0; 3],
            beta_vane_m: [0.0; 3],
            cg_m: [0.0; 3],
            moment_ref_m: [0.0; 3],
            beta_flank: false,
        };
        let mut t: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let one = [1.0; 20];
        let cols: Vec<&[f64]> = std::iter::once(&t[..])
            .chain(std::iter::repeat_n(&one[..], 11))
            .collect();
        assert!(
            preprocess_concatenated(&cols, &[0, 25], &ac, &[], &PreprocessOptions::default())
                .is_err()
        );
        let ok =
            preprocess_concatenated(&cols, &[0, 10, 20], &ac, &[], &PreprocessOptions::default())
                .unwrap();
        assert_eq!(ok.columns[0].len(), 20);
        assert_eq!(ok.cutoffs_hz.len(), 18);
        t[5] += 0.05;
        let cols: Vec<&[f64]> = std::iter::once(&t[..])
            .chain(std::iter::repeat_n(&one[..], 11))
            .collect();
        let e = preprocess_concatenated(&cols, &[0, 20], &ac, &[], &PreprocessOptions::default())
            .unwrap_err();
        assert!(e.to_string().contains("rows 4-5"), "{e}");
    }

    /// A smooth synthetic maneuver: every input channel a different slow sine.
    fn record(n: usize) -> Vec<Vec<f64>> {
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.02).collect();
        let wave = |a: f64, f: f64, ph: f64, off: f64| -> Vec<f64> {
            t.iter().map(|x| off + a * (f * x + ph).sin()).collect()
        };
        vec![
            t.clone(),
            wave(4.0, 1.1, 0.2, 10.0),
            wave(3.0, 0.9, 1.0, 0.0),
            wave(20.0, 1.7, 0.3, 0.0),
            wave(8.0, 1.3, 2.0, 0.0),
            wave(12.0, 0.8, 0.7, 0.0),
            wave(1.0, 1.2, 0.1, 0.5),
            wave(2.0, 1.5, 0.4, 0.0),
            wave(3.0, 0.7, 0.9, -9.5),
            wave(5.0, 0.3, 0.0, 80.0),
            vec![1.1; n],
            vec![1000.0; n],
        ]
    }

    fn params() -> AircraftParams {
        AircraftParams {
            mg: MassGeometry::principal(61.0, 27.05, 2.3, 20000.0, 3.0e5, 4.5e5, 7.1e5, 1.5e4),
            prop_h_per_rpm: 2.6,
            accel_m: [0.5, 0.15, 0.3],
            alpha_vane_m: [8.0, -1.4, 0.5],
            beta_vane_m: [8.0, 0.0, -1.2],
            cg_m: [0.2, -0.03, 0.1],
            moment_ref_m: [-0.4, 0.0, 0.05],
            beta_flank: false,
        }
    }

    #[test]
    fn moving_the_datum_moves_nothing() {
        let rec = record(300);
        let cols: Vec<&[f64]> = rec.iter().map(|c| &c[..]).collect();
        let ac = params();
        let opts = PreprocessOptions::default();
        let a = preprocess_maneuver(&cols, &ac, &opts).unwrap();
        let sh = [3.7, -0.4, 1.1];
        let add = |x: [f64; 3]| [x[0] + sh[0], x[1] + sh[1], x[2] + sh[2]];
        let moved = AircraftParams {
            accel_m: add(ac.accel_m),
            alpha_vane_m: add(ac.alpha_vane_m),
            beta_vane_m: add(ac.beta_vane_m),
            cg_m: add(ac.cg_m),
            moment_ref_m: add(ac.moment_ref_m),
            ..ac
        };
        let b = preprocess_maneuver(&cols, &moved, &opts).unwrap();
        for (k, (x, y)) in a.columns.iter().zip(&b.columns).enumerate() {
            let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let err = x
                .iter()
                .zip(y)
                .fold(0.0f64, |m, (u, v)| m.max((u - v).abs()));
            assert!(err <= 1e-12 * scale, "column {k}: {err} of {scale}");
        }
    }

    #[test]
    fn moments_about_the_reference_are_the_cg_ones_plus_d_cross_f() {
        // closed form on the pipeline's own outputs: C_ref = C_cg + (d x C_F) / length
        let rec = record(300);
        let cols: Vec<&[f64]> = rec.iter().map(|c| &c[..]).collect();
        let ac = params();
        let opts = PreprocessOptions::default();
        let at_cg = preprocess_maneuver(
            &cols,
            &AircraftParams {
                moment_ref_m: ac.cg_m,
                ..ac
            },
            &opts,
        )
        .unwrap();
        let at_ref = preprocess_maneuver(&cols, &ac, &opts).unwrap();
        let d = minus(ac.cg_m, ac.moment_ref_m);
        let col = |o: &ManeuverOutput, name: &str| -> Vec<f64> {
            let k = OUTPUT_COLUMNS
                .iter()
                .position(|c| *c == name)
                .unwrap_or(OUTPUT_COLUMNS.len());
            o.columns[k].clone()
        };
        let (cx, cy, cz) = (
            col(&at_cg, "CX_meas"),
            col(&at_cg, "CY_meas"),
            col(&at_cg, "CZ_meas"),
        );
        let (b, cbar) = (ac.mg.b, ac.mg.cbar);
        for i in 0..300 {
            let want = [
                col(&at_cg, "Cl_meas")[i] + (d[1] * cz[i] - d[2] * cy[i]) / b,
                col(&at_cg, "Cn_meas")[i] + (d[0] * cy[i] - d[1] * cx[i]) / b,
                col(&at_cg, CM_COLUMN)[i] + (d[2] * cx[i] - d[0] * cz[i]) / cbar,
            ];
            let got = [
                col(&at_ref, "Cl_meas")[i],
                col(&at_ref, "Cn_meas")[i],
                col(&at_ref, CM_COLUMN)[i],
            ];
            for (g, w) in got.iter().zip(want) {
                assert!(
                    (g - w).abs() <= 1e-12 * w.abs().max(1e-3),
                    "row {i}: {g} vs {w}"
                );
            }
        }
        // the forces do not move
        assert_eq!(col(&at_cg, "CY_meas"), col(&at_ref, "CY_meas"));
    }

    #[test]
    fn each_maneuver_is_processed_with_its_own_loading() {
        let rec = record(200);
        let both: Vec<Vec<f64>> = rec
            .iter()
            .enumerate()
            .map(|(k, c)| {
                let mut v = c.clone();
                let tail: Vec<f64> = if k == 0 {
                    c.iter().map(|t| t + 10.0).collect()
                } else {
                    c.iter().rev().copied().collect()
                };
                v.extend(tail);
                v
            })
            .collect();
        let cols: Vec<&[f64]> = both.iter().map(|c| &c[..]).collect();
        let ac = params();
        let opts = PreprocessOptions::default();
        let loads = [
            ManeuverMass {
                mass: 18500.0,
                inertia: [2.9e5, 4.6e5, 7.0e5, 1.4e4, 800.0, -1200.0],
                cg_m: [0.35, 0.02, 0.12],
            },
            ManeuverMass {
                mass: 21000.0,
                inertia: [3.1e5, 4.4e5, 7.2e5, 1.6e4, 0.0, 0.0],
                cg_m: [0.05, -0.05, 0.08],
            },
        ];
        let out = preprocess_concatenated(&cols, &[0, 200, 400], &ac, &loads, &opts).unwrap();
        for (m, mm) in loads.iter().enumerate() {
            let sub: Vec<&[f64]> = cols.iter().map(|c| &c[200 * m..200 * (m + 1)]).collect();
            let one = preprocess_maneuver(&sub, &ac.with_mass(mm), &opts).unwrap();
            for (k, c) in one.columns.iter().enumerate() {
                assert_eq!(
                    &out.columns[k][200 * m..200 * (m + 1)],
                    &c[..],
                    "column {k}"
                );
            }
        }
        let nominal = preprocess_concatenated(&cols, &[0, 200, 400], &ac, &[], &opts).unwrap();
        assert_ne!(nominal.columns[18], out.columns[18]);
        // a tensor that is not positive definite, and a count that does not match
        let mut bad = loads;
        bad[1].inertia[3] = 6.0e5; // Ixz^2 > Ixx Izz
        let e = preprocess_concatenated(&cols, &[0, 200, 400], &ac, &bad, &opts).unwrap_err();
        assert!(e.to_string().contains("maneuver #1"), "{e}");
        assert!(e.to_string().contains("positive definite"), "{e}");
        let e =
            preprocess_concatenated(&cols, &[0, 200, 400], &ac, &loads[..1], &opts).unwrap_err();
        assert!(e.to_string().contains("one per maneuver"), "{e}");
    }
}
