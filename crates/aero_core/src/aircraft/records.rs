//! The qualified model evaluated along flight records: the simulator's
//! prediction $C_{i,qualified}$ of thesis Eq. 3.5 at the *measured* states,
//! exactly what a black-box simulator supplies as `Cl_sim`, `Cn_sim`, `CY_sim`.

use crate::aircraft::qualified::{coef_index, Coef, FlapModel, QualifiedModel};
use crate::error::{AeroError, Result};
use crate::sim::aero::{AeroInput, Controls};

/// Speed of sound used for the Mach number when a record has none, m/s (ISA sea level).
pub const SOUND_SPEED_MPS: f64 = 340.294;

/// Record columns the qualified model reads (angles in deg, rates in deg/s).
#[derive(Debug, Clone, Copy)]
pub struct RecordColumns<'a> {
    /// Angle of attack at the CG, deg.
    pub alpha_deg: &'a [f64],
    /// Sideslip at the CG, deg.
    pub beta_deg: &'a [f64],
    /// p̂ = p b/(2V).
    pub phat: &'a [f64],
    /// q̂ = q c̄/(2V).
    pub qhat: &'a [f64],
    /// r̂ = r b/(2V).
    pub rhat: &'a [f64],
    /// α̇, deg/s.
    pub alphadot_dps: &'a [f64],
    /// β̇, deg/s.
    pub betadot_dps: &'a [f64],
    /// Aileron, deg.
    pub da_deg: &'a [f64],
    /// Elevator, deg.
    pub de_deg: &'a [f64],
    /// Rudder, deg.
    pub dr_deg: &'a [f64],
    /// Left spoiler, deg.
    pub dsl_deg: &'a [f64],
    /// Right spoiler, deg.
    pub dsr_deg: &'a [f64],
    /// Flap, deg.
    pub flap_deg: &'a [f64],
    /// Left thrust coefficient.
    pub ct_left: &'a [f64],
    /// Right thrust coefficient.
    pub ct_right: &'a [f64],
    /// True airspeed, m/s.
    pub tas_mps: &'a [f64],
}

/// `[Cl, Cn, CY]` of the qualified model at every row (body axes, total
/// aero + thrust, as the measured coefficients of Eq. 3.2-3.4).
///
/// # Errors
/// [`AeroError::InvalidInput`] naming a column whose length differs.
pub fn qualified_lateral(model: &QualifiedModel, c: &RecordColumns<'_>) -> Result<[Vec<f64>; 3]> {
    check_lengths(c)?;
    let lateral = model.resolve(|c| matches!(c, Coef::Cl | Coef::Cn | Coef::CY));
    // the model sliced at each flap setting of the records (a flight test flies a handful):
    // the general path's values to round-off (`sliced_model_equals_table_walk`), one alpha
    // search per row instead of one per table; other flap values take the general path
    let sliced: Vec<(f64, FlapModel)> = flap_settings(c.flap_deg, MAX_SLICED_FLAPS)
        .into_iter()
        .map(|f| model.at_flap(f).map(|m| (f, m)))
        .collect::<Result<_>>()?;
    let row = |i: usize| -> [f64; 3] {
        let s = input_at(c, i);
        let v = match sliced.iter().find(|(f, _)| *f == s.flap_deg) {
            Some((_, m)) => m.evaluate(&s),
            None => model.evaluate_resolved(&lateral, &s),
        };
        [
            v[coef_index(Coef::Cl)],
            v[coef_index(Coef::Cn)],
            v[coef_index(Coef::CY)],
        ]
    };
    Ok(by_rows(c.alpha_deg.len(), row))
}

/// `[C_L, C_m, C_L,basic, C_m,basic, C_D, C_D,basic]` of the qualified model at every
/// row: the wind-axis lift, the pitching moment and the wind-axis drag (total, as
/// measured), and the parts of them the static curves (the `CL_basic`, `Cm_basic`,
/// `CD_basic` tables) give; the difference is what control, rate and thrust terms add.
///
/// # Errors
/// [`AeroError::InvalidInput`] naming a column whose length differs.
pub fn qualified_longitudinal(
    model: &QualifiedModel,
    c: &RecordColumns<'_>,
) -> Result<[Vec<f64>; 6]> {
    check_lengths(c)?;
    let all = model.resolve(|c| matches!(c, Coef::CL | Coef::Cm | Coef::CD));
    let basic: Vec<_> = all
        .iter()
        .filter(|(t, _)| matches!(t.table.as_str(), "CL_basic" | "Cm_basic" | "CD_basic"))
        .copied()
        .collect();
    let (il, im, id) = (
        coef_index(Coef::CL),
        coef_index(Coef::Cm),
        coef_index(Coef::CD),
    );
    let row = |i: usize| -> [f64; 6] {
        let s = input_at(c, i);
        let v = model.evaluate_resolved(&all, &s);
        let b = model.evaluate_resolved(&basic, &s);
        [v[il], v[im], b[il], b[im], v[id], b[id]]
    };
    Ok(by_rows(c.alpha_deg.len(), row))
}

fn check_lengths(c: &RecordColumns<'_>) -> Result<()> {
    let n = c.alpha_deg.len();
    let cols: [(&str, &[f64]); 16] = [
        ("alpha_deg", c.alpha_deg),
        ("beta_deg", c.beta_deg),
        ("phat", c.phat),
        ("qhat", c.qhat),
        ("rhat", c.rhat),
        ("alphadot_dps", c.alphadot_dps),
        ("betadot_dps", c.betadot_dps),
        ("da_deg", c.da_deg),
        ("de_deg", c.de_deg),
        ("dr_deg", c.dr_deg),
        ("dsl_deg", c.dsl_deg),
        ("dsr_deg", c.dsr_deg),
        ("flap_deg", c.flap_deg),
        ("ct_left", c.ct_left),
        ("ct_right", c.ct_right),
        ("tas_mps", c.tas_mps),
    ];
    for (name, col) in cols {
        if col.len() != n {
            return Err(AeroError::invalid(
                format!("qualified model input '{name}'"),
                format!("has {} rows, alpha_deg has {n}", col.len()),
            ));
        }
    }
    Ok(())
}

/// The model input at row `i` (lengths checked).
fn input_at(c: &RecordColumns<'_>, i: usize) -> AeroInput {
    AeroInput {
        alpha: c.alpha_deg[i].to_radians(),
        beta: c.beta_deg[i].to_radians(),
        p_hat: c.phat[i],
        q_hat: c.qhat[i],
        r_hat: c.rhat[i],
        alpha_dot: c.alphadot_dps[i].to_radians(),
        beta_dot: c.betadot_dps[i].to_radians(),
        controls: Controls {
            da: c.da_deg[i].to_radians(),
            de: c.de_deg[i].to_radians(),
            dr: c.dr_deg[i].to_radians(),
            dsl: c.dsl_deg[i].to_radians(),
            dsr: c.dsr_deg[i].to_radians(),
        },
        flap_deg: c.flap_deg[i],
        ct_left: c.ct_left[i],
        ct_right: c.ct_right[i],
        mach: c.tas_mps[i] / SOUND_SPEED_MPS,
        tas: c.tas_mps[i],
    }
}

/// Flap settings sliced by [`qualified_lateral`] at most.
const MAX_SLICED_FLAPS: usize = 16;

/// The distinct finite values of `flap` in order of appearance, or none when there are more
/// than `max` (a continuous flap channel: the general path then serves every row).
fn flap_settings(flap: &[f64], max: usize) -> Vec<f64> {
    let mut seen: Vec<f64> = Vec::new();
    let mut last = f64::NAN;
    for &f in flap {
        // rows come in runs of one setting
        if f == last {
            continue;
        }
        last = f;
        if !f.is_finite() || seen.contains(&f) {
            continue;
        }
        if seen.len() == max {
            return Vec::new();
        }
        seen.push(f);
    }
    seen
}

/// `row(i)` for every row (in parallel with the `parallel` feature), as columns.
fn by_rows<const K: usize>(
    n: usize,
    row: impl Fn(usize) -> [f64; K] + Sync + Send,
) -> [Vec<f64>; K] {
    #[cfg(feature = "parallel")]
    let rows: Vec<[f64; K]> = {
        use rayon::prelude::*;
        (0..n).into_par_iter().map(row).collect()
    };
    #[cfg(not(feature = "parallel"))]
    let rows: Vec<[f64; K]> = (0..n).map(row).collect();
    std::array::from_fn(|k| rows.iter().map(|r| r[k]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aircraft::turboprop::adx37;

    /// Record columns in the order of the struct's fields.
    fn columns(c: [&[f64]; 16]) -> RecordColumns<'_> {
        let [alpha_deg, beta_deg, phat, qhat, rhat, alphadot_dps, betadot_dps, da_deg, de_deg, dr_deg, dsl_deg, dsr_deg, flap_deg, ct_left, ct_right, tas_mps] =
            c;
        RecordColumns {
            alpha_deg,
            beta_deg,
            phat,
            qhat,
            rhat,
            alphadot_dps,
            betadot_dps,
            da_deg,
            de_deg,
            dr_deg,
            dsl_deg,
            dsr_deg,
            flap_deg,
            ct_left,
            ct_right,
            tas_mps,
        }
    }

    #[test]
    fn rows_equal_single_point_evaluation() {
        let q = QualifiedModel::adx37(&adx37()).expect("model");
        let n = 50;
        let v = |a: f64, b: f64| -> Vec<f64> { (0..n).map(|i| a + b * i as f64).collect() };
        let (alpha, beta, p, qh, r) = (
            v(-2.0, 0.5),
            v(-5.0, 0.2),
            v(-0.02, 0.001),
            v(0.0, 0.0),
            v(0.01, -0.0005),
        );
        let (ad, bd, da, de, dr) = (
            v(0.1, 0.0),
            v(0.0, 0.01),
            v(-10.0, 0.4),
            v(0.0, 0.0),
            v(3.0, -0.1),
        );
        let (dsl, dsr, flap, ctl, ctr, tas) = (
            v(0.0, 0.0),
            v(0.0, 0.2),
            v(10.0, 0.0),
            v(0.1, 0.0),
            v(0.12, 0.0),
            v(60.0, 0.1),
        );
        let cols = columns([
            &alpha, &beta, &p, &qh, &r, &ad, &bd, &da, &de, &dr, &dsl, &dsr, &flap, &ctl, &ctr,
            &tas,
        ]);
        let [cl, cn, cy] = qualified_lateral(&q, &cols).expect("evaluates");
        let fm = q.at_flap(10.0).expect("slice");
        for i in 0..n {
            let s = AeroInput {
                alpha: alpha[i].to_radians(),
                beta: beta[i].to_radians(),
                p_hat: p[i],
                q_hat: qh[i],
                r_hat: r[i],
                alpha_dot: ad[i].to_radians(),
                beta_dot: bd[i].to_radians(),
                controls: Controls {
                    da: da[i].to_radians(),
                    de: 0.0,
                    dr: dr[i].to_radians(),
                    dsl: 0.0,
                    dsr: dsr[i].to_radians(),
                },
                flap_deg: 10.0,
                ct_left: 0.1,
                ct_right: 0.12,
                mach: tas[i] / SOUND_SPEED_MPS,
                tas: tas[i],
            };
            let w = fm.evaluate(&s);
            assert!((cl[i] - w[coef_index(Coef::Cl)]).abs() < 1e-12);
            assert!((cn[i] - w[coef_index(Coef::Cn)]).abs() < 1e-12);
            assert!((cy[i] - w[coef_index(Coef::CY)]).abs() < 1e-12);
        }
        let [lift, cm, lift_b, cm_b, drag, drag_b] =
            qualified_longitudinal(&q, &cols).expect("evaluates");
        for i in 0..n {
            let s = input_at(&cols, i);
            let w = fm.evaluate(&s);
            assert!((lift[i] - w[coef_index(Coef::CL)]).abs() < 1e-12);
            assert!((cm[i] - w[coef_index(Coef::Cm)]).abs() < 1e-12);
            assert!((drag[i] - w[coef_index(Coef::CD)]).abs() < 1e-12);
            // the static curves at table nodes are the curves of qualified.rs
            let st = crate::aircraft::qualified::FLAP_STALL[2];
            if alpha[i].fract() == 0.0 {
                let lc = crate::aircraft::qualified::lift_curve(&st, alpha[i]);
                let pc = crate::aircraft::qualified::pitch_curve(&st, alpha[i]);
                assert!((lift_b[i] - lc).abs() < 1e-12 && (cm_b[i] - pc).abs() < 1e-12);
                let a = adx37();
                let dc = crate::aircraft::qualified::drag_curve(&st, alpha[i], a.aspect_ratio());
                assert!((drag_b[i] - dc).abs() < 1e-12);
            }
        }
        let short = RecordColumns {
            tas_mps: &tas[..3],
            ..cols
        };
        assert!(qualified_lateral(&q, &short)
            .unwrap_err()
            .to_string()
            .contains("tas_mps"));
    }

    /// Records at a few flap settings (sliced) and at many (a continuous flap channel, the
    /// general path), with a NaN flap: every row equals the general path's evaluation.
    #[test]
    fn sliced_rows_equal_the_table_walk_at_any_flap() {
        let q = QualifiedModel::adx37(&adx37()).expect("model");
        let lateral = q.resolve(|c| matches!(c, Coef::Cl | Coef::Cn | Coef::CY));
        let n = 120;
        let v = |f: &dyn Fn(f64) -> f64| -> Vec<f64> { (0..n).map(|i| f(i as f64)).collect() };
        let (alpha, beta, p, qh, r) = (
            v(&|i| -18.0 + 0.5 * i),
            v(&|i| 8.0 * (0.1 * i).sin()),
            v(&|i| 0.02 * (0.3 * i).cos()),
            v(&|_| 0.004),
            v(&|i| -0.01 * (0.2 * i).sin()),
        );
        let (ad, bd, da, de, dr) = (
            v(&|i| (0.05 * i).sin()),
            v(&|i| (0.07 * i).cos()),
            v(&|i| 25.0 * (0.2 * i).sin()),
            v(&|_| -2.0),
            v(&|i| 28.0 * (0.13 * i).cos()),
        );
        let (dsl, dsr, ctl, ctr, tas) = (
            v(&|i| (40.0 * (0.17 * i).sin()).max(0.0)),
            v(&|i| (40.0 * (0.19 * i).cos()).max(0.0)),
            v(&|_| 0.1),
            v(&|_| 0.05),
            v(&|i| 55.0 + 0.1 * i),
        );
        let few = v(&|i| [0.0, 10.0, 35.0][(i as usize / 7) % 3]);
        let mut few_nan = few.clone();
        few_nan[5] = f64::NAN;
        let many = v(&|i| 0.3 * i);
        for flap in [&few, &few_nan, &many] {
            let cols = columns([
                &alpha, &beta, &p, &qh, &r, &ad, &bd, &da, &de, &dr, &dsl, &dsr, flap, &ctl, &ctr,
                &tas,
            ]);
            let got = qualified_lateral(&q, &cols).expect("evaluates");
            for i in 0..n {
                let w = q.evaluate_resolved(&lateral, &input_at(&cols, i));
                for (k, c) in [Coef::Cl, Coef::Cn, Coef::CY].into_iter().enumerate() {
                    let want = w[coef_index(c)];
                    let ok =
                        (got[k][i] - want).abs() < 1e-12 || (got[k][i].is_nan() && want.is_nan());
                    assert!(ok, "row {i} flap {}: {} vs {want}", flap[i], got[k][i]);
                }
            }
        }
        assert_eq!(flap_settings(&few_nan, 16), vec![0.0, 10.0, 35.0]);
        assert!(flap_settings(&many, 16).is_empty());
    }
}
