//! The "qualified" aerodynamic model of the representative aircraft: gridded
//! tables in alpha, flap and controls (thesis Section 3.2.2), each entering
//! one coefficient multiplied by a regressor, holding the last value beyond
//! the ranges of thesis Table 3.1:
//! - static lateral data (β, p̂, r̂, C_T derivatives): alpha −15…15 deg;
//! - control data (aileron, rudder, spoiler tables): alpha −4…10 deg;
//! - sideslip ±40 deg and per-engine C_T −0.1…1.5 (regressors held at the limits);
//! - flaps 0, 5, 10, 15, 35 deg (interpolated between).
//!
//! The longitudinal tables (C_L, C_D, C_m) extend to alpha 40 deg with a real
//! stall (C_L break, nose-down pitch break): the thesis's simulator carried a
//! longitudinal stall model co-developed with the lateral one (Section 4.3),
//! and the lateral post-stall behaviour is what this project studies.
//!
//! Values are representative of a straight, high-aspect-ratio (A = 12.4)
//! high wing with a T-tail (DATCOM-style estimates, Etkin & Reid Ch. 5,
//! Roskam Part VI): C_Lα = 5.2 /rad, C_l,β ≈ −0.095 /rad falling with alpha
//! (the thesis's qualified trend, Section 4.2.1), C_n,β ≈ 0.115 /rad,
//! C_Y,β ≈ −0.78 /rad, C_l,p ≈ −0.50, C_n,r ≈ −0.16, C_l,r ≈ 0.06 + C_L/4,
//! C_n,p ≈ −C_L/8, aileron C_l,δa ≈ −0.16 /rad, rudder C_n,δr ≈ −0.105 /rad,
//! engine arm y = 4.1 m → C_n,CTdiff = y/b = 0.158. Every term is listed by
//! [`QualifiedModel::export`] for DAVE-ML export.
//!
//! Combination: each coefficient is Σ sign · table(inputs) · regressor, with
//! regressors in radians (β, δe) or non-dimensional (p̂, q̂, r̂, α̇c̄/2V, C_T);
//! control tables take the deflection in degrees as an axis and return the
//! increment. Body axes: C_X = −C_D cos α + C_L sin α + C_T,left + C_T,right,
//! C_Z = −C_D sin α − C_L cos α.

use crate::aircraft::turboprop::AircraftRef;
use crate::error::Result;
use crate::sim::aero::{AeroCoeffs, AeroInput, AeroModel};
use crate::table::{Axis, Table};

/// The coefficient a term contributes to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub enum Coef {
    /// Lift (wind axes).
    CL,
    /// Drag (wind axes).
    CD,
    /// Side force (body axes).
    CY,
    /// Rolling moment.
    Cl,
    /// Pitching moment.
    Cm,
    /// Yawing moment.
    Cn,
}

/// A table input (axis variable).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Input {
    /// Angle of attack, deg.
    AlphaDeg,
    /// Flap setting, deg.
    FlapDeg,
    /// Aileron, deg.
    DaDeg,
    /// Rudder, deg.
    DrDeg,
    /// Left spoiler, deg.
    DslDeg,
    /// Right spoiler, deg.
    DsrDeg,
}

/// A regressor multiplying a table value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Regressor {
    /// 1 (the table is the increment).
    One,
    /// β, rad.
    Beta,
    /// p̂ = p b/2V.
    PHat,
    /// q̂ = q c̄/2V.
    QHat,
    /// r̂ = r b/2V.
    RHat,
    /// α̇ c̄/2V.
    AlphaDotHat,
    /// δe, rad.
    De,
    /// C_T,left + C_T,right.
    CtSum,
    /// C_T,left − C_T,right (Eq. 3.17).
    CtDiff,
}

/// Sideslip range of the static data, rad (Table 3.1: ±40°): the qualified model holds beyond.
pub const BETA_MAX: f64 = 40.0 * std::f64::consts::PI / 180.0;
/// Per-engine thrust-coefficient range of the static data (Table 3.1: −0.1 … 1.5).
pub const CT_RANGE: (f64, f64) = (-0.1, 1.5);

#[inline]
fn held_ct(s: &AeroInput) -> (f64, f64) {
    (
        s.ct_left.clamp(CT_RANGE.0, CT_RANGE.1),
        s.ct_right.clamp(CT_RANGE.0, CT_RANGE.1),
    )
}

impl Regressor {
    /// Value of the regressor at an input, β and C_T held at the Table 3.1 limits.
    #[inline]
    pub fn value(self, s: &AeroInput, alpha_dot_hat: f64) -> f64 {
        match self {
            Regressor::One => 1.0,
            Regressor::Beta => s.beta.clamp(-BETA_MAX, BETA_MAX),
            Regressor::PHat => s.p_hat,
            Regressor::QHat => s.q_hat,
            Regressor::RHat => s.r_hat,
            Regressor::AlphaDotHat => alpha_dot_hat,
            Regressor::De => s.controls.de,
            Regressor::CtSum => {
                let (l, r) = held_ct(s);
                l + r
            }
            Regressor::CtDiff => {
                let (l, r) = held_ct(s);
                l - r
            }
        }
    }
}

/// One term of the qualified model: sign · table(inputs) · regressor added to `coef`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Term {
    /// Target coefficient.
    pub coef: Coef,
    /// Name of the table in [`QualifiedModel::tables`].
    pub table: String,
    /// The input feeding each table axis, in axis order.
    pub inputs: Vec<Input>,
    /// The multiplying regressor.
    pub regressor: Regressor,
    /// +1 or −1.
    pub sign: f64,
}

/// Stall parameters of one flap setting (see [`QualifiedModel::adx37`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlapStall {
    /// Flap, deg.
    pub flap_deg: f64,
    /// Alpha of C_L,max, deg.
    pub alpha_max_deg: f64,
    /// C_L,max.
    pub cl_max: f64,
    /// Zero-lift drag.
    pub cd0: f64,
    /// Pitching moment at zero alpha.
    pub cm0: f64,
}

/// Lift-curve slope, per deg (5.2 /rad: Helmbold/DATCOM for A = 12.4 with fuselage).
pub const CL_ALPHA_PER_DEG: f64 = 5.2 * std::f64::consts::PI / 180.0;

/// Stall parameters per flap: C_L,max rising with flap (Dash 8 class: ≈1.75
/// clean to ≈2.45 landing, from published stall speeds), alpha of C_L,max
/// slightly falling with flap; the roll-off alphas of Table 3.2 (17.1-18.0 deg)
/// lie just below.
pub const FLAP_STALL: [FlapStall; 5] = [
    FlapStall {
        flap_deg: 0.0,
        alpha_max_deg: 19.5,
        cl_max: 1.75,
        cd0: 0.027,
        cm0: 0.06,
    },
    FlapStall {
        flap_deg: 5.0,
        alpha_max_deg: 19.0,
        cl_max: 1.95,
        cd0: 0.032,
        cm0: 0.045,
    },
    FlapStall {
        flap_deg: 10.0,
        alpha_max_deg: 18.5,
        cl_max: 2.05,
        cd0: 0.040,
        cm0: 0.03,
    },
    FlapStall {
        flap_deg: 15.0,
        alpha_max_deg: 18.5,
        cl_max: 2.15,
        cd0: 0.050,
        cm0: 0.015,
    },
    FlapStall {
        flap_deg: 35.0,
        alpha_max_deg: 18.0,
        cl_max: 2.45,
        cd0: 0.095,
        cm0: -0.04,
    },
];

/// The basic lift curve of one flap setting, with a real stall: linear to
/// α₁ = α_max − 6°, a parabolic rounding to C_L,max at α_max, then a drop of
/// 25 % of C_L,max with a Gaussian onset (the C_L break).
pub fn lift_curve(f: &FlapStall, alpha_deg: f64) -> f64 {
    let a = CL_ALPHA_PER_DEG;
    let a1 = f.alpha_max_deg - 6.0;
    let cl0 = f.cl_max + 3.0 * a - a * f.alpha_max_deg;
    if alpha_deg <= a1 {
        cl0 + a * alpha_deg
    } else if alpha_deg <= f.alpha_max_deg {
        cl0 + a * alpha_deg - a * (alpha_deg - a1).powi(2) / 12.0
    } else {
        let z = (alpha_deg - f.alpha_max_deg) / 2.5;
        f.cl_max - 0.25 * f.cl_max * (1.0 - (-z * z).exp())
    }
}

/// The induced-drag factor `k = 1/(π e A)` of the qualified polar (Oswald factor `e` = 0.8,
/// aspect ratio `A = b²/S`).
pub fn induced_drag_factor(aircraft: &AircraftRef) -> f64 {
    polar_factor(aircraft.aspect_ratio())
}

/// `1/(π e A)` with `e` = 0.8 at aspect ratio `ar`.
fn polar_factor(ar: f64) -> f64 {
    1.0 / (std::f64::consts::PI * ar * 0.8)
}

/// The basic drag of one flap setting: the parabolic polar of [`lift_curve`] plus a drag rise
/// past `α_max − 6°` (aspect ratio `ar`).
pub fn drag_curve(f: &FlapStall, alpha_deg: f64, ar: f64) -> f64 {
    let cl = lift_curve(f, alpha_deg);
    let k = polar_factor(ar);
    let sep = (alpha_deg - (f.alpha_max_deg - 6.0))
        .max(0.0)
        .to_radians()
        .sin();
    f.cd0 + k * cl * cl + 0.9 * sep * sep
}

/// The basic pitching moment of one flap setting (C_mα = −0.75/rad, nose-down break past α_max − 1°).
pub fn pitch_curve(f: &FlapStall, alpha_deg: f64) -> f64 {
    // static margin ≈ 14 % c̄: C_mα = −0.75 /rad; nose-down pitch break past α_max − 1°
    let base = f.cm0 - 0.75 * alpha_deg.to_radians();
    let a_b = f.alpha_max_deg - 1.0;
    let brk = if alpha_deg > a_b {
        let z = (alpha_deg - a_b) / 2.5;
        -0.12 * (1.0 - (-z * z).exp())
    } else {
        0.0
    };
    base + brk
}

fn grid(from: f64, to: f64, step: f64) -> Vec<f64> {
    let n = ((to - from) / step).round() as usize;
    (0..=n).map(|i| from + step * i as f64).collect()
}

/// The qualified model: named tables and the terms combining them.
#[derive(Debug, Clone)]
pub struct QualifiedModel {
    /// Named tables.
    pub tables: Vec<(String, Table)>,
    /// The terms (see module docs).
    pub terms: Vec<Term>,
    /// Reference values used by the model.
    pub aircraft: AircraftRef,
}

/// The flap axis shared by every table.
pub const FLAPS: [f64; 5] = [0.0, 5.0, 10.0, 15.0, 35.0];

impl QualifiedModel {
    /// Build the representative aircraft's qualified model.
    ///
    /// # Errors
    /// Only if a table is malformed (a bug); kept as a value, not a panic.
    pub fn adx37(aircraft: &AircraftRef) -> Result<Self> {
        let ar = aircraft.aspect_ratio();
        let a_long = grid(-10.0, 40.0, 1.0);
        let a_stat = grid(-15.0, 15.0, 2.5);
        let a_ctrl = grid(-4.0, 10.0, 2.0);
        let flaps = FLAPS.to_vec();
        let mut tables: Vec<(String, Table)> = Vec::new();
        let mut terms: Vec<Term> = Vec::new();
        let cl_of = |fi: usize, a: f64| lift_curve(&FLAP_STALL[fi], a);

        // 2-D (alpha, flap) tables
        let mut add2 = |name: &str,
                        alphas: &Vec<f64>,
                        coef: Coef,
                        regressor: Regressor,
                        f: &dyn Fn(usize, f64) -> f64|
         -> Result<()> {
            let mut vals = Vec::with_capacity(alphas.len() * flaps.len());
            for &a in alphas {
                for fi in 0..flaps.len() {
                    vals.push(f(fi, a));
                }
            }
            let t = Table::new(
                vec![
                    Axis::new("alpha_deg", alphas.clone())?,
                    Axis::new("flap_deg", flaps.clone())?,
                ],
                vals,
            )?;
            tables.push((name.to_string(), t));
            terms.push(Term {
                coef,
                table: name.to_string(),
                inputs: vec![Input::AlphaDeg, Input::FlapDeg],
                regressor,
                sign: 1.0,
            });
            Ok(())
        };
        let fd = |fi: usize| FLAPS[fi];
        // longitudinal
        add2("CL_basic", &a_long, Coef::CL, Regressor::One, &|fi, a| {
            cl_of(fi, a)
        })?;
        add2("CD_basic", &a_long, Coef::CD, Regressor::One, &|fi, a| {
            drag_curve(&FLAP_STALL[fi], a, ar)
        })?;
        add2("Cm_basic", &a_long, Coef::Cm, Regressor::One, &|fi, a| {
            pitch_curve(&FLAP_STALL[fi], a)
        })?;
        add2("CL_de", &a_long, Coef::CL, Regressor::De, &|_, _| 0.35)?;
        add2("Cm_de", &a_long, Coef::Cm, Regressor::De, &|_, a| {
            -2.0 * (1.0 - 0.004 * a.max(0.0))
        })?;
        add2("CL_q", &a_long, Coef::CL, Regressor::QHat, &|_, _| 6.0)?;
        add2("Cm_q", &a_long, Coef::Cm, Regressor::QHat, &|_, _| -25.0)?;
        add2(
            "Cm_alphadot",
            &a_long,
            Coef::Cm,
            Regressor::AlphaDotHat,
            &|_, _| -8.0,
        )?;
        let zt = aircraft.thrust_line_above_cg_m / aircraft.cbar_m;
        add2("Cm_CT", &a_long, Coef::Cm, Regressor::CtSum, &|_, _| -zt)?;
        // lateral static
        add2("Cl_beta", &a_stat, Coef::Cl, Regressor::Beta, &|fi, a| {
            -(0.095 + 0.0004 * fd(fi)) * (1.0 - 0.02 * a)
        })?;
        add2("Cn_beta", &a_stat, Coef::Cn, Regressor::Beta, &|fi, a| {
            0.115 + 0.0003 * fd(fi) - 0.0015 * a
        })?;
        add2("CY_beta", &a_stat, Coef::CY, Regressor::Beta, &|fi, _| {
            -0.78 - 0.002 * fd(fi)
        })?;
        add2("Cl_p", &a_stat, Coef::Cl, Regressor::PHat, &|fi, a| {
            -0.50 - 0.0015 * fd(fi) + 0.008 * a.max(0.0)
        })?;
        add2("Cn_p", &a_stat, Coef::Cn, Regressor::PHat, &|fi, a| {
            -cl_of(fi, a) / 8.0
        })?;
        add2("CY_p", &a_stat, Coef::CY, Regressor::PHat, &|_, _| -0.05)?;
        add2("Cl_r", &a_stat, Coef::Cl, Regressor::RHat, &|fi, a| {
            0.06 + cl_of(fi, a) / 4.0
        })?;
        add2("Cn_r", &a_stat, Coef::Cn, Regressor::RHat, &|fi, a| {
            -0.16 - 0.02 * cl_of(fi, a).powi(2)
        })?;
        add2("CY_r", &a_stat, Coef::CY, Regressor::RHat, &|_, _| 0.40)?;
        add2("Cl_CT", &a_stat, Coef::Cl, Regressor::CtSum, &|_, _| 0.005)?;
        add2("Cn_CT", &a_stat, Coef::Cn, Regressor::CtSum, &|_, _| -0.010)?;
        add2("CY_CT", &a_stat, Coef::CY, Regressor::CtSum, &|_, _| 0.020)?;
        add2(
            "Cl_CTdiff",
            &a_stat,
            Coef::Cl,
            Regressor::CtDiff,
            &|fi, _| 0.04 + 0.002 * fd(fi),
        )?;
        let arm = aircraft.engine_y_m / aircraft.b_m;
        add2(
            "Cn_CTdiff",
            &a_stat,
            Coef::Cn,
            Regressor::CtDiff,
            &|_, _| arm,
        )?;

        // 3-D control tables (alpha, deflection, flap): increments
        let mut add3 = |name: &str,
                        coef: Coef,
                        input: Input,
                        axis_name: &str,
                        defl: Vec<f64>,
                        f: &dyn Fn(usize, f64, f64) -> f64,
                        sign: f64,
                        extra_input: Option<Input>|
         -> Result<()> {
            let mut vals = Vec::new();
            for &a in &a_ctrl {
                for &d in &defl {
                    for fi in 0..flaps.len() {
                        vals.push(f(fi, a, d));
                    }
                }
            }
            let t = Table::new(
                vec![
                    Axis::new("alpha_deg", a_ctrl.clone())?,
                    Axis::new(axis_name, defl.clone())?,
                    Axis::new("flap_deg", flaps.clone())?,
                ],
                vals,
            )?;
            tables.push((name.to_string(), t));
            terms.push(Term {
                coef,
                table: name.to_string(),
                inputs: vec![Input::AlphaDeg, input, Input::FlapDeg],
                regressor: Regressor::One,
                sign: 1.0,
            });
            if let Some(other) = extra_input {
                terms.push(Term {
                    coef,
                    table: name.to_string(),
                    inputs: vec![Input::AlphaDeg, other, Input::FlapDeg],
                    regressor: Regressor::One,
                    sign,
                });
            }
            Ok(())
        };
        let da_bp = vec![
            -20.0, -15.0, -10.0, -5.0, -2.0, 0.0, 2.0, 5.0, 10.0, 15.0, 20.0,
        ];
        let sat = |d: f64, full: f64, loss: f64| d.to_radians() * (1.0 - loss * (d / full).powi(2));
        add3(
            "Cl_da",
            Coef::Cl,
            Input::DaDeg,
            "da_deg",
            da_bp.clone(),
            &|fi, a, d| -(0.16 + 0.0004 * fd(fi)) * (1.0 - 0.01 * a.max(0.0)) * sat(d, 20.0, 0.15),
            1.0,
            None,
        )?;
        add3(
            "Cn_da",
            Coef::Cn,
            Input::DaDeg,
            "da_deg",
            da_bp,
            &|fi, a, d| (0.006 + 0.006 * cl_of(fi, a)) * d.to_radians(),
            1.0,
            None,
        )?;
        let dr_bp = vec![-25.0, -15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0, 25.0];
        add3(
            "Cn_dr",
            Coef::Cn,
            Input::DrDeg,
            "dr_deg",
            dr_bp.clone(),
            &|_, _, d| -0.105 * sat(d, 25.0, 0.12),
            1.0,
            None,
        )?;
        add3(
            "CY_dr",
            Coef::CY,
            Input::DrDeg,
            "dr_deg",
            dr_bp.clone(),
            &|_, _, d| 0.27 * sat(d, 25.0, 0.12),
            1.0,
            None,
        )?;
        add3(
            "Cl_dr",
            Coef::Cl,
            Input::DrDeg,
            "dr_deg",
            dr_bp,
            &|_, _, d| 0.025 * d.to_radians(),
            1.0,
            None,
        )?;
        // one roll spoiler (right, up positive); the left one enters with the opposite sign
        let ds_bp = vec![0.0, 5.0, 10.0, 20.0, 30.0, 45.0];
        let spl = |d: f64| match d {
            d if d <= 5.0 => 0.0001 * d,
            d if d <= 10.0 => 0.0005 + 0.0005 * (d - 5.0),
            d if d <= 20.0 => 0.003 + 0.0006 * (d - 10.0),
            d if d <= 30.0 => 0.009 + 0.0005 * (d - 20.0),
            d => 0.014 + 0.000_266_666_666_666_666_7 * (d - 30.0),
        };
        add3(
            "Cl_ds",
            Coef::Cl,
            Input::DsrDeg,
            "ds_deg",
            ds_bp.clone(),
            &|fi, _, d| spl(d) * (1.0 + 0.005 * fd(fi)),
            -1.0,
            Some(Input::DslDeg),
        )?;
        add3(
            "Cn_ds",
            Coef::Cn,
            Input::DsrDeg,
            "ds_deg",
            ds_bp,
            &|_, _, d| 0.08 * spl(d),
            -1.0,
            Some(Input::DslDeg),
        )?;

        Ok(QualifiedModel {
            tables,
            terms,
            aircraft: aircraft.clone(),
        })
    }

    /// The named tables and the terms combining them (for DAVE-ML export).
    pub fn export(&self) -> (&[(String, Table)], &[Term]) {
        (&self.tables, &self.terms)
    }

    fn table(&self, name: &str) -> Option<&Table> {
        self.tables.iter().find(|(n, _)| n == name).map(|(_, t)| t)
    }

    /// Wind-axis C_L, C_D and body C_Y, C_l, C_m, C_n by walking the terms (general path).
    pub fn evaluate_terms(&self, s: &AeroInput) -> [f64; 6] {
        self.evaluate_resolved(&self.resolve(|_| true), s)
    }

    /// The terms of the coefficients `keep` selects, each with its table (the
    /// name lookup done once, for evaluating many states with
    /// [`QualifiedModel::evaluate_resolved`]); a term whose table is missing is
    /// left out, as [`QualifiedModel::evaluate_terms`] skips it.
    pub fn resolve(&self, keep: impl Fn(Coef) -> bool) -> Vec<(&Term, &Table)> {
        self.terms
            .iter()
            .filter(|t| keep(t.coef))
            .filter_map(|t| self.table(&t.table).map(|tab| (t, tab)))
            .collect()
    }

    /// [`QualifiedModel::evaluate_terms`] over resolved terms: the coefficients
    /// of the terms given (the others stay 0), in `[CL, CD, CY, Cl, Cm, Cn]`.
    pub fn evaluate_resolved(&self, terms: &[(&Term, &Table)], s: &AeroInput) -> [f64; 6] {
        let adh = s.alpha_dot * self.aircraft.cbar_m / (2.0 * s.tas.max(1.0));
        let mut out = [0.0; 6];
        for (term, t) in terms {
            let mut x = [0.0; 3];
            for (k, inp) in term.inputs.iter().enumerate() {
                x[k] = input_value(*inp, s);
            }
            let v = t.eval(&x[..term.inputs.len()]) * term.regressor.value(s, adh) * term.sign;
            out[coef_index(term.coef)] += v;
        }
        out
    }

    /// Precompute the model at one flap setting for the real-time path.
    ///
    /// # Errors
    /// If a term names a missing table (a bug).
    pub fn at_flap(&self, flap_deg: f64) -> Result<FlapModel> {
        FlapModel::new(self, flap_deg)
    }
}

/// Index of a coefficient in the `[CL, CD, CY, Cl, Cm, Cn]` array.
pub fn coef_index(c: Coef) -> usize {
    match c {
        Coef::CL => 0,
        Coef::CD => 1,
        Coef::CY => 2,
        Coef::Cl => 3,
        Coef::Cm => 4,
        Coef::Cn => 5,
    }
}

#[inline]
fn input_value(inp: Input, s: &AeroInput) -> f64 {
    match inp {
        Input::AlphaDeg => s.alpha.to_degrees(),
        Input::FlapDeg => s.flap_deg,
        Input::DaDeg => s.controls.da.to_degrees(),
        Input::DrDeg => s.controls.dr.to_degrees(),
        Input::DslDeg => s.controls.dsl.to_degrees(),
        Input::DsrDeg => s.controls.dsr.to_degrees(),
    }
}

/// Uniform alpha grid of the precomputed path, deg: it contains every
/// breakpoint of the tables, so its linear interpolation is exact.
const A0: f64 = -15.0;
const DA: f64 = 0.5;
const NA: usize = 111; // -15 ... 40

/// Number of regressors (see [`Regressor`]).
const NREG: usize = 9;

fn reg_index(r: Regressor) -> usize {
    match r {
        Regressor::One => 0,
        Regressor::Beta => 1,
        Regressor::PHat => 2,
        Regressor::QHat => 3,
        Regressor::RHat => 4,
        Regressor::AlphaDotHat => 5,
        Regressor::De => 6,
        Regressor::CtSum => 7,
        Regressor::CtDiff => 8,
    }
}

/// The control inputs of the sliced model (one locate each per call).
const CTRL_INPUTS: [Input; 4] = [Input::DaDeg, Input::DrDeg, Input::DslDeg, Input::DsrDeg];

/// A control table sliced at one flap: for each (alpha row, deflection
/// segment) cell its four corners `[v(i, j), v(i, j+1) − v(i, j), v(i+1, j),
/// v(i+1, j+1) − v(i+1, j)]` (the differences as the interpolation forms them).
#[derive(Debug, Clone)]
struct ControlTerm {
    coef: usize,
    input: usize,
    sign: f64,
    cells: Vec<[f64; 4]>,
}

/// The qualified model sliced at one flap setting, resampled on a uniform
/// alpha grid: identical values to the general path, one alpha search per
/// call, contiguous rows, one search per control input.
#[derive(Debug, Clone)]
pub struct FlapModel {
    /// Flap, deg.
    pub flap_deg: f64,
    ncols: usize,
    /// Per alpha interval i and 2-D column j (columns grouped by coefficient,
    /// term order kept within a coefficient): `[v(i), v(i+1) − v(i)]`, sign applied.
    grid: Vec<[f64; 2]>,
    /// Column range of each coefficient in `grid` rows.
    coef_cols: [(usize, usize); 6],
    /// Regressor index of each column.
    col_reg: Vec<u8>,
    /// Control tables grouped by input, inputs in order of first appearance
    /// in the terms (so every coefficient still sums its terms in term order).
    ctrl: Vec<ControlGroup>,
    cbar: f64,
}

/// The control tables on one input: one locate serves them all.
#[derive(Debug, Clone)]
struct ControlGroup {
    input: Input,
    /// Deflection breakpoints.
    bp: Vec<f64>,
    /// Segment index for each whole degree from the first breakpoint (an O(1)
    /// locate; every breakpoint is a whole degree), empty otherwise.
    seg: Vec<u8>,
    /// Coefficient index and sign of each table.
    coef: Vec<u8>,
    sign: Vec<f64>,
    /// Cells `[(i · segments + j) · tables + t]` (see [`ControlTerm`]).
    cells: Vec<[f64; 4]>,
}

impl FlapModel {
    fn new(q: &QualifiedModel, flap_deg: f64) -> Result<Self> {
        let mut cols: Vec<(usize, usize, Vec<f64>)> = Vec::new();
        let mut ctrl = Vec::new();
        let mut ctrl_bp: Vec<Vec<f64>> = vec![Vec::new(); CTRL_INPUTS.len()];
        for term in &q.terms {
            let t = q.table(&term.table).ok_or_else(|| {
                crate::error::AeroError::invalid(
                    "qualified model",
                    format!("no table '{}'", term.table),
                )
            })?;
            let ci = coef_index(term.coef);
            if term.inputs.len() == 2 {
                let v = (0..NA)
                    .map(|i| term.sign * t.eval(&[A0 + DA * i as f64, flap_deg]))
                    .collect();
                cols.push((ci, reg_index(term.regressor), v));
            } else {
                let defl = t.axes()[1].breakpoints().to_vec();
                let slot = CTRL_INPUTS
                    .iter()
                    .position(|&x| x == term.inputs[1])
                    .ok_or_else(|| {
                        crate::error::AeroError::invalid("qualified model", "unknown control input")
                    })?;
                if ctrl_bp[slot].is_empty() {
                    ctrl_bp[slot] = defl.clone();
                } else if ctrl_bp[slot] != defl {
                    return Err(crate::error::AeroError::invalid(
                        format!("qualified table '{}'", term.table),
                        "control tables on the same input must share breakpoints",
                    ));
                }
                let m = defl.len();
                let mut v = Vec::with_capacity(NA * m);
                for i in 0..NA {
                    for &d in &defl {
                        v.push(t.eval(&[A0 + DA * i as f64, d, flap_deg]));
                    }
                }
                let mut cells = Vec::with_capacity((NA - 1) * (m - 1));
                for i in 0..NA - 1 {
                    for j in 0..m - 1 {
                        let (p0, p1) = (i * m + j, (i + 1) * m + j);
                        cells.push([v[p0], v[p0 + 1] - v[p0], v[p1], v[p1 + 1] - v[p1]]);
                    }
                }
                ctrl.push(ControlTerm {
                    coef: ci,
                    input: slot,
                    sign: term.sign,
                    cells,
                });
            }
        }
        // group the columns by coefficient, keeping term order within each
        // (the accumulation order of the general path, so sums are identical)
        cols.sort_by_key(|c| c.0);
        let ncols = cols.len();
        let mut coef_cols = [(0usize, 0usize); 6];
        for (ci, r) in coef_cols.iter_mut().enumerate() {
            let start = cols.partition_point(|c| c.0 < ci);
            *r = (
                start,
                start + cols[start..].iter().take_while(|c| c.0 == ci).count(),
            );
        }
        let mut grid = Vec::with_capacity((NA - 1) * ncols);
        for i in 0..NA - 1 {
            for (_, _, v) in &cols {
                grid.push([v[i], v[i + 1] - v[i]]);
            }
        }
        // group the control terms by input, inputs in order of first appearance
        let mut order: Vec<usize> = Vec::new();
        for c in &ctrl {
            if !order.contains(&c.input) {
                order.push(c.input);
            }
        }
        let mut groups = Vec::with_capacity(order.len());
        for &slot in &order {
            let bp = ctrl_bp[slot].clone();
            let terms: Vec<&ControlTerm> = ctrl.iter().filter(|c| c.input == slot).collect();
            let segments = bp.len().saturating_sub(1);
            let mut cells = Vec::with_capacity(terms.len() * (NA - 1) * segments);
            for cell in 0..(NA - 1) * segments {
                for t in &terms {
                    cells.push(t.cells[cell]);
                }
            }
            let seg = if bp.len() < 2 || bp.iter().any(|b| b.fract() != 0.0) {
                Vec::new()
            } else {
                let (lo, hi) = (bp[0], bp[bp.len() - 1]);
                let n = (hi - lo) as usize;
                (0..n)
                    .map(|k| {
                        let d = lo + k as f64;
                        ((bp.partition_point(|&b| b <= d) - 1).min(bp.len() - 2)) as u8
                    })
                    .collect()
            };
            groups.push(ControlGroup {
                input: CTRL_INPUTS[slot],
                bp,
                seg,
                coef: terms.iter().map(|t| t.coef as u8).collect(),
                sign: terms.iter().map(|t| t.sign).collect(),
                cells,
            });
        }
        Ok(FlapModel {
            flap_deg,
            ncols,
            grid,
            coef_cols,
            col_reg: cols.iter().map(|c| c.1 as u8).collect(),
            ctrl: groups,
            cbar: q.aircraft.cbar_m,
        })
    }

    /// `[CL, CD, CY, Cl, Cm, Cn]` at `s` (wind-axis C_L, C_D; body C_Y, C_l, C_m, C_n).
    #[inline]
    pub fn evaluate(&self, s: &AeroInput) -> [f64; 6] {
        let adh = s.alpha_dot * self.cbar / (2.0 * s.tas.max(1.0));
        let (ctl, ctr) = held_ct(s);
        let regs: [f64; NREG] = [
            1.0,
            s.beta.clamp(-BETA_MAX, BETA_MAX),
            s.p_hat,
            s.q_hat,
            s.r_hat,
            adh,
            s.controls.de,
            ctl + ctr,
            ctl - ctr,
        ];
        let x = ((s.alpha.to_degrees() - A0) / DA).clamp(0.0, (NA - 1) as f64);
        let i = (x as usize).min(NA - 2);
        let f = x - i as f64;
        let n = self.ncols;
        let row = &self.grid[i * n..(i + 1) * n];
        let mut regs16 = [0.0; 16];
        regs16[..NREG].copy_from_slice(&regs);
        let mut out = [0.0; 6];
        for (o, &(c0, c1)) in out.iter_mut().zip(&self.coef_cols) {
            let mut acc = 0.0;
            for (p, &ri) in row[c0..c1].iter().zip(&self.col_reg[c0..c1]) {
                // the mask makes the bound evident (ri < 9 by construction)
                acc += (p[0] + f * p[1]) * regs16[usize::from(ri & 15)];
            }
            *o = acc;
        }
        // locate each control input once, then add its tables
        let mut out8 = [0.0; 8];
        out8[..6].copy_from_slice(&out);
        for g in &self.ctrl {
            let bp = &g.bp;
            let m = bp.len();
            if m < 2 {
                continue;
            }
            let d = input_value(g.input, s);
            let (j, w) = if d <= bp[0] {
                (0, 0.0)
            } else if d >= bp[m - 1] {
                (m - 2, 1.0)
            } else {
                let j = match g.seg.get((d - bp[0]) as usize) {
                    Some(&j) => j as usize,
                    None => (bp.partition_point(|&b| b <= d) - 1).min(m - 2),
                };
                (j, (d - bp[j]) / (bp[j + 1] - bp[j]))
            };
            let nt = g.coef.len();
            let base = (i * (m - 1) + j) * nt;
            let Some(cells) = g.cells.get(base..base + nt) else {
                continue;
            };
            for ((v, &ci), &sign) in cells.iter().zip(&g.coef).zip(&g.sign) {
                let a = v[0] + w * v[1];
                let b = v[2] + w * v[3];
                out8[usize::from(ci & 7)] += sign * (a + f * (b - a));
            }
        }
        out.copy_from_slice(&out8[..6]);
        out
    }
}

/// Convert `[CL, CD, CY, Cl, Cm, Cn]` to body-axis [`AeroCoeffs`] (thrust along x).
#[inline]
pub fn to_body(c: &[f64; 6], s: &AeroInput) -> AeroCoeffs {
    let (cx, cz) = AeroCoeffs::from_lift_drag(c[0], c[1], s.alpha, s.ct_sum());
    AeroCoeffs {
        cx,
        cy: c[2],
        cz,
        cl: c[3],
        cm: c[4],
        cn: c[5],
    }
}

/// The qualified model as an [`AeroModel`] at one flap setting.
#[derive(Debug, Clone)]
pub struct QualifiedAero {
    /// The sliced model.
    pub model: FlapModel,
}

impl AeroModel for QualifiedAero {
    fn coefficients(&self, s: &AeroInput) -> AeroCoeffs {
        to_body(&self.model.evaluate(s), s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aircraft::turboprop::adx37;
    use crate::sim::aero::Controls;

    #[test]
    fn sliced_model_equals_table_walk() {
        let ac = adx37();
        let q = QualifiedModel::adx37(&ac).unwrap();
        for &flap in &[0.0, 10.0, 35.0, 12.0] {
            let fm = q.at_flap(flap).unwrap();
            for k in 0..200 {
                let kf = k as f64;
                let s = AeroInput {
                    alpha: (-20.0 + 0.33 * kf).to_radians(),
                    beta: (0.07 * kf).sin() * 0.2,
                    p_hat: 0.01 * (kf * 0.3).cos(),
                    q_hat: 0.005,
                    r_hat: -0.01 * (kf * 0.1).sin(),
                    alpha_dot: 0.05,
                    beta_dot: 0.01,
                    controls: Controls {
                        da: (kf * 0.2).sin() * 0.4,
                        de: -0.05,
                        dr: (kf * 0.13).cos() * 0.45,
                        dsl: (kf * 0.17).sin().max(0.0) * 0.8,
                        dsr: (kf * 0.19).cos().max(0.0) * 0.8,
                    },
                    flap_deg: flap,
                    ct_left: 0.1,
                    ct_right: 0.05,
                    mach: 0.2,
                    tas: 60.0,
                };
                let a = fm.evaluate(&s);
                let b = q.evaluate_terms(&s);
                for j in 0..6 {
                    assert!(
                        (a[j] - b[j]).abs() < 1e-12,
                        "coef {j} alpha {} : {} vs {}",
                        s.alpha.to_degrees(),
                        a[j],
                        b[j]
                    );
                }
            }
        }
    }

    #[test]
    fn lift_curve_has_a_stall_and_lateral_tables_hold_beyond_table_3_1() {
        let f = &FLAP_STALL[0];
        let cmax = lift_curve(f, f.alpha_max_deg);
        assert!((cmax - f.cl_max).abs() < 1e-12);
        assert!(lift_curve(f, f.alpha_max_deg - 0.5) < cmax);
        assert!(lift_curve(f, f.alpha_max_deg + 5.0) < 0.85 * cmax);
        let q = QualifiedModel::adx37(&adx37()).unwrap();
        let t = q.table("Cl_beta").unwrap();
        assert_eq!(t.eval(&[15.0, 0.0]), t.eval(&[25.0, 0.0]));
        let t = q.table("Cl_da").unwrap();
        assert_eq!(t.eval(&[10.0, 10.0, 5.0]), t.eval(&[22.0, 10.0, 5.0]));
        assert!(
            t.eval(&[0.0, 10.0, 0.0]) < 0.0,
            "positive aileron rolls left"
        );
    }
}
