//! The truth aircraft: the qualified model plus switched-on effects from the
//! library ([`crate::aircraft::effects`]) plus the stochastic roll-off of thesis
//! Section 3.4.3 ([`crate::rolloff`]). It is what the virtual flight test
//! "flies"; the fit never sees it.

use crate::aircraft::effects::{effect, flap_index, ActiveEffect, AlphaShape};
use crate::aircraft::qualified::{
    induced_drag_factor, to_body, FlapModel, QualifiedModel, CL_ALPHA_PER_DEG, FLAP_STALL,
};
use crate::aircraft::turboprop::AircraftRef;
use crate::error::{AeroError, Result};
use crate::kirchhoff::{KirchhoffDrag, KirchhoffParams};
use crate::rolloff::RollOff;
use crate::sim::aero::{AeroCoeffs, AeroInput, AeroModel};
use crate::stall_form::{StallParams, StallState};
use crate::table::Table;

/// An effect request: vocabulary name, magnitude (1 = design), optional shape override.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EffectSpec {
    /// Vocabulary name.
    pub name: String,
    /// Magnitude, 1 = design magnitude.
    #[serde(default = "one")]
    pub magnitude: f64,
    /// Alpha shape replacing the default one.
    #[serde(default)]
    pub shape: Option<AlphaShape>,
}

fn one() -> f64 {
    1.0
}

/// Build the active aerodynamic effects of a request list (measurement effects
/// and `stochastic_rolloff` are skipped: the caller handles them).
///
/// # Errors
/// For an unknown effect name.
pub fn active_effects(specs: &[EffectSpec]) -> Result<Vec<ActiveEffect>> {
    let mut out = Vec::new();
    for s in specs {
        if s.name == "stochastic_rolloff"
            || crate::aircraft::effects::MEASUREMENT_EFFECTS.contains(&s.name.as_str())
        {
            continue;
        }
        let def = effect(&s.name)?;
        let shape = s.shape.unwrap_or(def.shape);
        out.push(ActiveEffect {
            def,
            magnitude: s.magnitude,
            shape,
        });
    }
    Ok(out)
}

/// The longitudinal stall the truth aircraft can fly instead of its qualified
/// static curves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LongitudinalStall {
    /// The qualified model's static C_L and C_m curves (the default).
    #[default]
    Static,
    /// A Kirchhoff flow-separation stall ([`crate::kirchhoff`]) with the
    /// parameters of [`kirchhoff_truth_params`].
    Kirchhoff,
}

/// The Kirchhoff stall of the virtual aircraft at one of its flap settings
/// (0, 5, 10, 15, 35 deg; others take the nearest).
///
/// Attached flow keeps the qualified lift line (C_Lα = 5.2 /rad and the zero-lift
/// alpha of [`FLAP_STALL`]) and pitch line (C_m0 of [`FLAP_STALL`], C_mα = −0.75 /rad);
/// the breakpoint α* lies 1.5 deg above the qualified model's alpha of C_L,max
/// and the steepness is a₁ = 20 /rad, so the static C_L,max is within 3 % of the
/// qualified one and is reached about 1 deg earlier; C_mx = −0.12 is the
/// qualified nose-down break. The time constants, τ₁ = 0.20 + 0.002 δf s and
/// τ₂ = 0.060 + 0.0006 δf s (δf in deg), are representative values of a few
/// tenths (τ₁) and hundredths (τ₂) of a second chosen for this aircraft, not
/// identified from any flight data.
pub fn kirchhoff_truth_params(flap_deg: f64) -> KirchhoffParams {
    let fs = nearest_flap(flap_deg);
    let cl0 = fs.cl_max + 3.0 * CL_ALPHA_PER_DEG - CL_ALPHA_PER_DEG * fs.alpha_max_deg;
    KirchhoffParams {
        tau1: 0.20 + 0.002 * fs.flap_deg,
        tau2: 0.060 + 0.0006 * fs.flap_deg,
        alpha_star: (fs.alpha_max_deg + 1.5).to_radians(),
        a1: 20.0,
        cl_alpha: CL_ALPHA_PER_DEG.to_degrees(),
        alpha0: (-cl0 / CL_ALPHA_PER_DEG).to_radians(),
        cm0: fs.cm0,
        cm_alpha: -0.75,
        cm_x: -0.12,
    }
}

/// The flap setting of [`FLAP_STALL`] nearest to `flap_deg`.
fn nearest_flap(flap_deg: f64) -> crate::aircraft::qualified::FlapStall {
    FLAP_STALL
        .iter()
        .min_by(|a, b| {
            (a.flap_deg - flap_deg)
                .abs()
                .total_cmp(&(b.flap_deg - flap_deg).abs())
        })
        .copied()
        .unwrap_or(FLAP_STALL[0])
}

/// The drag of the virtual aircraft's Kirchhoff stall at a flap setting (nearest of 0, 5,
/// 10, 15, 35 deg), over the aircraft `a` (its aspect ratio sets the polar).
///
/// Attached flow keeps the qualified polar (`C_D0` of [`FLAP_STALL`], `k` of
/// [`induced_drag_factor`]); the fully separated wake adds `C_Dx = 0.30 + 0.002 δf`
/// (δf in deg), a representative value chosen for this aircraft (the qualified curve's own
/// drag rise, `0.9 sin²(α − α_max + 6°)`, reaches 0.07-0.17 at 10-20 deg past its stall), not
/// identified from flight data.
pub fn kirchhoff_truth_drag(flap_deg: f64, a: &AircraftRef) -> KirchhoffDrag {
    let fs = nearest_flap(flap_deg);
    KirchhoffDrag {
        cd0: fs.cd0,
        k: induced_drag_factor(a),
        cd_x: 0.30 + 0.002 * fs.flap_deg,
    }
}

/// A Kirchhoff stall replacing the qualified static C_L and C_m curves: the
/// truth's C_L is the qualified C_L minus its `CL_basic` table plus the
/// Kirchhoff lift, likewise C_m with `Cm_basic` (control, rate and thrust
/// terms unchanged), and with a [`KirchhoffDrag`] likewise C_D with `CD_basic`
/// ([`KirchhoffStall::with_drag`]; without one the qualified drag is kept).
///
/// The separation state is driven by the air-relative α at the CG and its rate
/// as the backward difference of α over each simulation step (not the
/// low-passed α̇ of [`crate::sim::maneuver::FLOW_RATE_TAU_S`] the rate terms
/// feel): the stall is then the model of [`crate::kirchhoff`] as written, with
/// α̇ the rate a flight test measures, so its τ₂ is the one an identification
/// can recover. (Driven by the low-passed rate, the output-error fit of a
/// noise-free, calm-air campaign, recorded then with a 10 ms delay of the state,
/// put τ₂ 3-7 % low and τ₁ 3-7 % high: the
/// filter's 0.04 s lag is of the order of the second-order terms that separate
/// τ₁ from τ₂; `docs/longitudinal.md`.)
#[derive(Debug, Clone)]
pub struct KirchhoffStall {
    /// The separation state (either form of the separation curve).
    pub state: StallState,
    cl_basic: Table,
    cm_basic: Table,
    cd_basic: Table,
    /// The stall's drag, replacing `CD_basic` (`None`: the qualified drag).
    pub drag: Option<KirchhoffDrag>,
    /// `(t, α)` at the last update.
    prev: Option<(f64, f64)>,
}

impl KirchhoffStall {
    /// The virtual aircraft's Kirchhoff stall at `flap_deg` over the qualified model `q`
    /// (the truth of [`kirchhoff_truth_params`]).
    ///
    /// # Errors
    /// If `q` lacks its `CL_basic` or `Cm_basic` table.
    pub fn adx37(q: &QualifiedModel, flap_deg: f64) -> Result<Self> {
        Self::new(q, kirchhoff_truth_params(flap_deg))?
            .with_drag(Some(kirchhoff_truth_drag(flap_deg, &q.aircraft)))
    }

    /// A Kirchhoff stall with the parameters `params` (e.g. fitted by
    /// [`crate::output_error::fit`]) replacing the static curves of the qualified model `q`:
    /// `TruthAero::new(slice, vec![], None).with_kirchhoff(Some(stall))` is then the
    /// qualified model with the identified longitudinal stall, and an
    /// [`crate::sim::extended::ExtendedAero`] over it carries the separation state
    /// (its `advance` reaches the base model's).
    ///
    /// # Errors
    /// If `q` lacks its `CL_basic`, `Cm_basic` or `CD_basic` table, or `params` fail their
    /// check ([`KirchhoffParams::check`], [`crate::goman_khrabrov::GkParams::check`]).
    pub fn new(q: &QualifiedModel, params: impl Into<StallParams>) -> Result<Self> {
        let table = |name: &str| {
            q.tables
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, t)| t.clone())
                .ok_or_else(|| AeroError::invalid("qualified model", format!("no table '{name}'")))
        };
        Ok(KirchhoffStall {
            state: StallState::new(params.into())?,
            cl_basic: table("CL_basic")?,
            cm_basic: table("Cm_basic")?,
            cd_basic: table("CD_basic")?,
            drag: None,
            prev: None,
        })
    }

    /// The same stall with the drag `drag` replacing the qualified `CD_basic` (`None`: the
    /// qualified drag is kept).
    ///
    /// # Errors
    /// If `drag` fails [`KirchhoffDrag::check`].
    pub fn with_drag(mut self, drag: Option<KirchhoffDrag>) -> Result<Self> {
        if let Some(d) = &drag {
            d.check()?;
        }
        self.drag = drag;
        Ok(self)
    }

    /// Advance the separation state to time `t` (s) at the input `s` (module docs of
    /// [`KirchhoffStall`]: α̇ as the backward difference of α; at the first update,
    /// the input's α̇). A second call at the same time changes nothing.
    pub fn advance(&mut self, t: f64, s: &AeroInput) {
        if self.prev.is_some_and(|(t0, _)| t0 == t) {
            return; // already at `t`
        }
        let alpha_dot = match self.prev {
            Some((t0, a0)) if t > t0 => (s.alpha - a0) / (t - t0),
            _ => s.alpha_dot,
        };
        self.prev = Some((t, s.alpha));
        self.state.update(t, s.alpha, alpha_dot);
    }

    /// `[ΔC_L, ΔC_D, ΔC_m]` replacing the static curves at `s` (ΔC_D zero without a drag),
    /// and the separation point.
    #[inline]
    pub fn delta(&self, s: &AeroInput) -> ([f64; 3], f64) {
        let x = self.state.x_at(s.alpha, s.alpha_dot);
        let p = &self.state.params;
        let at = [s.alpha.to_degrees(), s.flap_deg];
        let cl = p.cl(s.alpha, x);
        let dcd = self
            .drag
            .as_ref()
            .map_or(0.0, |d| d.cd(cl, x) - self.cd_basic.eval(&at));
        (
            [
                cl - self.cl_basic.eval(&at),
                dcd,
                p.cm(s.alpha, x) - self.cm_basic.eval(&at),
            ],
            x,
        )
    }
}

/// Qualified + effects + roll-off at one flap setting.
#[derive(Debug, Clone)]
pub struct TruthAero {
    /// The qualified model at this flap.
    pub qualified: FlapModel,
    /// Effects switched on.
    pub effects: Vec<ActiveEffect>,
    /// The stochastic roll-off, if on.
    pub rolloff: Option<RollOff>,
    /// The Kirchhoff longitudinal stall, if on.
    pub kirchhoff: Option<KirchhoffStall>,
    flap_i: usize,
}

impl TruthAero {
    /// Assemble a truth model.
    pub fn new(qualified: FlapModel, effects: Vec<ActiveEffect>, rolloff: Option<RollOff>) -> Self {
        let flap_i = flap_index(qualified.flap_deg);
        TruthAero {
            qualified,
            effects,
            rolloff,
            kirchhoff: None,
            flap_i,
        }
    }

    /// The same truth with a Kirchhoff longitudinal stall.
    #[must_use]
    pub fn with_kirchhoff(mut self, k: Option<KirchhoffStall>) -> Self {
        self.kirchhoff = k;
        self
    }

    /// The separation point at `s` (NaN without the Kirchhoff stall).
    pub fn separation(&self, s: &AeroInput) -> f64 {
        self.kirchhoff
            .as_ref()
            .map_or(f64::NAN, |k| k.state.x_at(s.alpha, s.alpha_dot))
    }

    /// Per effect `[ΔC_Y, ΔC_l, ΔC_n]`, in the order of `self.effects`.
    pub fn contributions(&self, s: &AeroInput, out: &mut [[f64; 3]]) {
        for (o, e) in out.iter_mut().zip(&self.effects) {
            *o = e.contribution(s, self.flap_i);
        }
    }

    /// Roll-off ΔC_l at `s` (0 when off).
    pub fn rolloff_cl(&self, s: &AeroInput) -> f64 {
        self.rolloff
            .as_ref()
            .map_or(0.0, |r| r.delta_cl(s.alpha.to_degrees()))
    }

    /// `[CL, CD, CY, Cl, Cm, Cn]` of the qualified model alone.
    pub fn qualified_coeffs(&self, s: &AeroInput) -> [f64; 6] {
        self.qualified.evaluate(s)
    }
}

impl AeroModel for TruthAero {
    #[inline]
    fn coefficients(&self, s: &AeroInput) -> AeroCoeffs {
        let mut c = self.qualified.evaluate(s);
        for e in &self.effects {
            let d = e.contribution(s, self.flap_i);
            c[2] += d[0];
            c[3] += d[1];
            c[5] += d[2];
        }
        c[3] += self.rolloff_cl(s);
        if let Some(k) = &self.kirchhoff {
            let (d, _) = k.delta(s);
            c[0] += d[0];
            c[1] += d[1];
            c[4] += d[2];
        }
        to_body(&c, s)
    }

    fn advance(&mut self, t: f64, s: &AeroInput) {
        if let Some(r) = self.rolloff.as_mut() {
            r.update(t, s.alpha.to_degrees());
        }
        if let Some(k) = self.kirchhoff.as_mut() {
            k.advance(t, s);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aircraft::turboprop::adx37;
    use crate::delta_model::DeltaModel;
    use crate::sim::extended::ExtendedAero;

    fn lift(c: &crate::sim::aero::AeroCoeffs, s: &AeroInput) -> f64 {
        let (sa, ca) = s.alpha.sin_cos();
        -c.cz * ca + (c.cx - s.ct_sum()) * sa
    }

    fn at(alpha_deg: f64) -> AeroInput {
        AeroInput {
            alpha: alpha_deg.to_radians(),
            flap_deg: 10.0,
            tas: 55.0,
            ..AeroInput::default()
        }
    }

    #[test]
    fn kirchhoff_base_replaces_the_static_curves_and_an_extended_model_carries_its_state() {
        let q = QualifiedModel::adx37(&adx37()).expect("model");
        let mut p = kirchhoff_truth_params(10.0);
        p.tau1 = 0.3; // "fitted" parameters other than the truth's
        let stall = KirchhoffStall::new(&q, p).expect("stall");
        let base = TruthAero::new(q.at_flap(10.0).expect("slice"), Vec::new(), None)
            .with_kirchhoff(Some(stall));
        // static: before any update the lift is the Kirchhoff static curve (no control,
        // rate or thrust terms at this input)
        for a in [4.0, 17.0, 20.0, 25.0] {
            let s = at(a);
            let cl = lift(&base.coefficients(&s), &s);
            assert!((cl - p.cl_static(s.alpha)).abs() < 1e-12, "{a}: {cl}");
        }
        let text = r#"{"schema": "aerodelta.model/1", "flaps_deg": [10.0], "coefficients": {}}"#;
        let delta = DeltaModel::from_json(text, "test").expect("empty Δ model");
        let mut ext = ExtendedAero::new(base, &delta).expect("extended");
        // pull from 10 to 24 deg at 20 deg/s: the state lags, so lift overshoots the static
        // curve past the break, and the extended model's loop reaches the state
        let dt = 0.01;
        let mut s = at(10.0);
        for k in 0..=70 {
            s = at(10.0 + 0.2 * k as f64);
            s.alpha_dot = 20f64.to_radians();
            ext.advance(k as f64 * dt, &s);
        }
        let cl = lift(&ext.coefficients(&s), &s);
        assert!(
            cl > p.cl_static(s.alpha) + 0.1,
            "{cl} vs {}",
            p.cl_static(s.alpha)
        );
        let x = ext.base.separation(&s);
        assert!(x > p.x0(s.alpha) && x < 1.0);
        // bad parameters are refused with their name
        p.a1 = -1.0;
        let e = KirchhoffStall::new(&q, p).unwrap_err();
        assert!(e.to_string().contains("a1"), "{e}");
    }

    fn drag(c: &crate::sim::aero::AeroCoeffs, s: &AeroInput) -> f64 {
        let (sa, ca) = s.alpha.sin_cos();
        -(c.cx - s.ct_sum()) * ca - c.cz * sa
    }

    #[test]
    fn the_kirchhoff_drag_replaces_the_basic_drag_and_is_the_polar_in_attached_flow() {
        let q = QualifiedModel::adx37(&adx37()).expect("model");
        let p = kirchhoff_truth_params(10.0);
        let d = kirchhoff_truth_drag(10.0, &q.aircraft);
        let slice = || q.at_flap(10.0).expect("slice");
        let with = TruthAero::new(slice(), Vec::new(), None)
            .with_kirchhoff(Some(KirchhoffStall::adx37(&q, 10.0).expect("stall")));
        let without = TruthAero::new(slice(), Vec::new(), None).with_kirchhoff(Some(
            KirchhoffStall::new(&q, p).expect("stall without drag"),
        ));
        let plain = TruthAero::new(slice(), Vec::new(), None);
        let fs = FLAP_STALL[2];
        for a in [0.0, 8.0, 17.0, 20.0, 25.0, 30.0] {
            let s = at(a);
            // static state before any update: the drag is the Kirchhoff drag at x0(alpha)
            let x = p.x0(s.alpha);
            let want = d.cd(p.cl(s.alpha, x), x);
            let cd = drag(&with.coefficients(&s), &s);
            assert!((cd - want).abs() < 1e-12, "{a}: {cd} vs {want}");
            // no drag given: the qualified drag, whatever the lift does
            let q_cd = drag(&plain.coefficients(&s), &s);
            assert!((drag(&without.coefficients(&s), &s) - q_cd).abs() < 1e-12);
            if a <= fs.alpha_max_deg - 6.0 {
                // attached flow (below the qualified drag rise): the qualified polar within
                // the little separation x0 already has (about 1e-3)
                assert!((cd - q_cd).abs() < 2e-3, "{a}: {cd} vs {q_cd}");
            }
        }
        // deep stall: the separated wake's drag dominates, over the qualified drag rise
        let s = at(35.0);
        assert!(drag(&with.coefficients(&s), &s) > drag(&plain.coefficients(&s), &s) + 0.05);
        // a non-finite drag is refused with its name
        let bad = KirchhoffDrag {
            cd_x: f64::NAN,
            ..d
        };
        let e = KirchhoffStall::new(&q, p)
            .and_then(|k| k.with_drag(Some(bad)))
            .unwrap_err();
        assert!(e.to_string().contains("CD_x"), "{e}");
    }
}
