//! The longitudinal stall a Δ model carries: the Kirchhoff flow-separation model
//! ([`crate::kirchhoff`]; Fischenberg, AIAA 95-3438, 1995) identified per flap by output error,
//! stored in the model file beside the lateral Δ tables so a simulator that loads the model
//! flies the identified lift break and pitch break (issue 20, item 2).
//!
//! The parameters are those of [`crate::kirchhoff::PARAM_NAMES`] in the engine's units
//! (s, rad, 1/rad). `known` says what the fit took off the measured coefficients before
//! fitting the static curves: `adx37` (the built-in aircraft's qualified control, rate and
//! thrust terms; the curves then replace its qualified `C_L`, `C_m` basic curves) or `none`
//! (the curves are the whole measured coefficients of the fitted records). A flap may also
//! carry the stall's drag ([`crate::kirchhoff::KirchhoffDrag`], names
//! [`crate::kirchhoff::DRAG_NAMES`]); without it the aircraft's own drag is kept.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::error::{AeroError, Result, ResultExt};
use crate::kirchhoff::{KirchhoffDrag, KirchhoffParams, DRAG_NAMES, PARAM_NAMES};

/// The stored longitudinal stall.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LongitudinalSpec {
    /// The stall model: `kirchhoff`.
    pub model: String,
    /// What the fit took off the measured coefficients: `adx37` or `none` (module docs).
    pub known: String,
    /// One entry per flap setting fitted.
    pub flaps: Vec<KirchhoffFlap>,
}

/// The Kirchhoff parameters of one flap setting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KirchhoffFlap {
    /// Flap setting, deg.
    pub flap_deg: f64,
    /// Parameter name ([`PARAM_NAMES`]) -> value, engine units.
    pub params: BTreeMap<String, f64>,
    /// The drag ([`DRAG_NAMES`] -> value), when fitted; empty: the aircraft's drag is kept.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub drag: BTreeMap<String, f64>,
    /// The fit's note (e.g. lags not identified on static data), empty when none.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub note: String,
}

/// One flap setting of a checked [`LongitudinalSpec`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompiledFlap {
    /// Flap setting, deg.
    pub flap_deg: f64,
    /// The separation dynamics, lift and pitching moment.
    pub params: KirchhoffParams,
    /// The drag, when stored.
    pub drag: Option<KirchhoffDrag>,
}

impl KirchhoffFlap {
    /// Store the drag `d` with this flap (`None`: none).
    pub fn set_drag(&mut self, d: Option<&KirchhoffDrag>) {
        self.drag = d.map_or_else(BTreeMap::new, |d| {
            DRAG_NAMES
                .iter()
                .zip(d.to_array())
                .map(|(n, v)| ((*n).to_string(), v))
                .collect()
        });
    }
}

/// The values of `map` in `names` order, refusing an unknown or a missing name (`what`
/// names them in the message, at `place`).
fn named<const N: usize>(
    map: &BTreeMap<String, f64>,
    names: [&str; N],
    place: &str,
    what: &str,
) -> Result<[f64; N]> {
    if let Some(extra) = map.keys().find(|k| !names.contains(&k.as_str())) {
        return Err(AeroError::invalid(
            place,
            format!(
                "unknown {what} '{extra}'; the {what}s are {}",
                names.join(", ")
            ),
        ));
    }
    let mut v = [0.0; N];
    for (slot, name) in v.iter_mut().zip(names) {
        *slot = *map
            .get(name)
            .ok_or_else(|| AeroError::invalid(place, format!("lacks {what} {name}")))?;
    }
    Ok(v)
}

/// Known-term bases a stored stall may declare.
pub const KNOWN: [&str; 2] = ["adx37", "none"];

impl LongitudinalSpec {
    /// Validate and return each flap's parameters, in the stored order.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the flap and the parameter: an unknown model or
    /// known-term basis, a repeated or non-finite flap, a missing or unknown parameter (of the
    /// stall or of its drag), values the model cannot run with ([`KirchhoffParams::check`],
    /// [`KirchhoffDrag::check`]).
    pub fn compile(&self) -> Result<Vec<CompiledFlap>> {
        if self.model != "kirchhoff" {
            return Err(AeroError::invalid(
                "model longitudinal.model",
                format!("is '{}'; this library reads 'kirchhoff'", self.model),
            ));
        }
        if !KNOWN.contains(&self.known.as_str()) {
            return Err(AeroError::invalid(
                "model longitudinal.known",
                format!("is '{}'; give 'adx37' or 'none'", self.known),
            ));
        }
        let mut out: Vec<CompiledFlap> = Vec::with_capacity(self.flaps.len());
        for f in &self.flaps {
            let place = format!("model longitudinal, flap {}", f.flap_deg);
            if !f.flap_deg.is_finite() {
                return Err(AeroError::invalid(place, "flap_deg is not finite"));
            }
            if out.iter().any(|g| g.flap_deg == f.flap_deg) {
                return Err(AeroError::invalid(
                    place,
                    "appears twice; give each flap once",
                ));
            }
            let v = named(&f.params, PARAM_NAMES, &place, "parameter")?;
            let p = KirchhoffParams::from_array(&v);
            p.check().context(place.clone())?;
            let drag = if f.drag.is_empty() {
                None
            } else {
                let d = KirchhoffDrag::from_array(&named(
                    &f.drag,
                    DRAG_NAMES,
                    &place,
                    "drag parameter",
                )?);
                d.check().context(place)?;
                Some(d)
            };
            out.push(CompiledFlap {
                flap_deg: f.flap_deg,
                params: p,
                drag,
            });
        }
        Ok(out)
    }

    /// A spec from fitted parameters per flap (`known` as in the module docs).
    pub fn from_params(known: &str, flaps: &[(f64, KirchhoffParams, String)]) -> Self {
        LongitudinalSpec {
            model: "kirchhoff".into(),
            known: known.into(),
            flaps: flaps
                .iter()
                .map(|(f, p, note)| KirchhoffFlap {
                    flap_deg: *f,
                    params: PARAM_NAMES
                        .iter()
                        .zip(p.to_array())
                        .map(|(n, v)| ((*n).to_string(), v))
                        .collect(),
                    drag: BTreeMap::new(),
                    note: note.clone(),
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kirchhoff::tests::truth as params;

    #[test]
    fn round_trips_and_refuses_what_it_cannot_fly() {
        let spec = LongitudinalSpec::from_params("adx37", &[(0.0, params(), String::new())]);
        let text = serde_json::to_string(&spec).unwrap();
        let back: LongitudinalSpec = serde_json::from_str(&text).unwrap();
        let plain = CompiledFlap {
            flap_deg: 0.0,
            params: params(),
            drag: None,
        };
        assert_eq!(back.compile().unwrap(), vec![plain]);
        assert!(!text.contains("drag"), "no drag stored: no key ({text})");
        // with its drag
        let d = KirchhoffDrag {
            cd0: 0.03,
            k: 0.045,
            cd_x: 0.3,
        };
        let mut dragged = spec.clone();
        dragged.flaps[0].set_drag(Some(&d));
        let text = serde_json::to_string(&dragged).unwrap();
        let back: LongitudinalSpec = serde_json::from_str(&text).unwrap();
        assert_eq!(back.compile().unwrap()[0].drag, Some(d));
        let msg_d = |s: &LongitudinalSpec| s.compile().unwrap_err().to_string();
        let mut bad = dragged.clone();
        bad.flaps[0].drag.remove("CD_x");
        assert!(
            msg_d(&bad).contains("lacks drag parameter CD_x"),
            "{}",
            msg_d(&bad)
        );
        let mut bad = dragged.clone();
        bad.flaps[0].drag.insert("CD_y".into(), 1.0);
        assert!(msg_d(&bad).contains("unknown drag parameter 'CD_y'"));
        let mut bad = dragged;
        bad.flaps[0].drag.insert("CD0".into(), f64::NAN);
        assert!(msg_d(&bad).contains("flap 0") && msg_d(&bad).contains("CD0"));
        let msg = |s: &LongitudinalSpec| s.compile().unwrap_err().to_string();
        let mut bad = spec.clone();
        bad.flaps[0].params.remove("tau2");
        assert!(msg(&bad).contains("flap 0") && msg(&bad).contains("lacks parameter tau2"));
        let mut bad = spec.clone();
        bad.flaps[0].params.insert("tau3".into(), 1.0);
        assert!(msg(&bad).contains("unknown parameter 'tau3'"));
        let mut bad = spec.clone();
        bad.flaps[0].params.insert("tau1".into(), -0.1);
        assert!(
            msg(&bad).contains("flap 0") && msg(&bad).contains("tau1"),
            "{}",
            msg(&bad)
        );
        let mut bad = spec.clone();
        bad.flaps.push(bad.flaps[0].clone());
        assert!(msg(&bad).contains("appears twice"));
        let mut bad = spec.clone();
        bad.known = "f16".into();
        assert!(msg(&bad).contains("'adx37' or 'none'"));
        let mut bad = spec;
        bad.model = "goman".into();
        assert!(msg(&bad).contains("reads 'kirchhoff'"));
    }
}
