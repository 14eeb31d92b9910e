//! The truth aircraft: the qualified model plus switched-on effects from the
//! library ([`crate::aircraft::effects`]) plus the stochastic roll-off of thesis
//! Section 3.4.3 ([`crate::rolloff`]). It is what the virtual flight test
//! "flies"; the fit never sees it.

use crate::aircraft::effects::{effect, flap_index, ActiveEffect, AlphaShape};
use crate::aircraft::qualified::{to_body, FlapModel};
use crate::error::Result;
use crate::rolloff::RollOff;
use crate::sim::aero::{AeroCoeffs, AeroInput, AeroModel};

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

/// Qualified + effects + roll-off at one flap setting.
#[derive(Debug, Clone)]
pub struct TruthAero {
    /// The qualified model at this flap.
    pub qualified: FlapModel,
    /// Effects switched on.
    pub effects: Vec<ActiveEffect>,
    /// The stochastic roll-off, if on.
    pub rolloff: Option<RollOff>,
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
            flap_i,
        }
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
        to_body(&c, s)
    }

    fn advance(&mut self, t: f64, s: &AeroInput) {
        if let Some(r) = self.rolloff.as_mut() {
            r.update(t, s.alpha.to_degrees());
        }
    }
}
