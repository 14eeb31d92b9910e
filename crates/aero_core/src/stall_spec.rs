//! The longitudinal stall a Δ model carries: the Kirchhoff flow-separation model
//! ([`crate::kirchhoff`]; Fischenberg, AIAA 95-3438, 1995) identified per flap by output error,
//! stored in the model file beside the lateral Δ tables so a simulator that loads the model
//! flies the identified lift break and pitch break (issue 20, item 2).
//!
//! `model` names the form of the static separation curve ([`crate::stall_form`]):
//! - `kirchhoff`: the tanh curve; the parameters are those of
//!   [`crate::kirchhoff::PARAM_NAMES`] in the engine's units (s, rad, 1/rad);
//! - `goman-khrabrov`: the tabulated curve ([`crate::goman_khrabrov`]); the parameters are
//!   [`crate::goman_khrabrov::CORE_NAMES`], and each flap gives its curve as `x0_knots` (rad,
//!   equally spaced) and `x0_values` (the cubic B-spline's coefficients, in `[0, 1]`).
//!
//! `known` says what the fit took off the measured coefficients before
//! fitting the static curves: `adx37` (the built-in aircraft's qualified control, rate and
//! thrust terms; the curves then replace its qualified `C_L`, `C_m` basic curves) or `none`
//! (the curves are the whole measured coefficients of the fitted records). A flap may also
//! carry the stall's drag ([`crate::kirchhoff::KirchhoffDrag`], names
//! [`crate::kirchhoff::DRAG_NAMES`]); without it the aircraft's own drag is kept.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::error::{AeroError, Result, ResultExt};
use crate::goman_khrabrov::{GkParams, CORE_NAMES};
use crate::kirchhoff::{KirchhoffDrag, KirchhoffParams, DRAG_NAMES, PARAM_NAMES};
use crate::stall_form::StallParams;

/// The forms of the separation curve a stored stall may take (module docs).
pub const FORMS: [&str; 2] = ["kirchhoff", "goman-khrabrov"];

/// The stored longitudinal stall.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LongitudinalSpec {
    /// The form of the separation curve: `kirchhoff` (tanh) or `goman-khrabrov` (table).
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
    /// Parameter name ([`PARAM_NAMES`], or [`CORE_NAMES`] for the tabulated form) -> value,
    /// engine units.
    pub params: BTreeMap<String, f64>,
    /// The tabulated form's knots, rad (equally spaced); empty for the tanh form.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub x0_knots: Vec<f64>,
    /// The tabulated form's spline coefficients, one per knot, in `[0, 1]`; empty for the
    /// tanh form.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub x0_values: Vec<f64>,
    /// The drag ([`DRAG_NAMES`] -> value), when fitted; empty: the aircraft's drag is kept.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub drag: BTreeMap<String, f64>,
    /// The fit's note (e.g. lags not identified on static data), empty when none.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub note: String,
}

/// One flap setting of a checked [`LongitudinalSpec`].
#[derive(Debug, Clone, PartialEq)]
pub struct CompiledFlap {
    /// Flap setting, deg.
    pub flap_deg: f64,
    /// The separation dynamics, lift and pitching moment, in the stored form.
    pub params: StallParams,
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
    /// stall or of its drag), a parameter or a table of the other form, a table the tabulated
    /// form cannot run with ([`GkParams::from_core`]: too few knots, unequal spacing, a
    /// coefficient outside [0, 1]), values the model cannot run with
    /// ([`KirchhoffParams::check`], [`GkParams::check`], [`KirchhoffDrag::check`]).
    pub fn compile(&self) -> Result<Vec<CompiledFlap>> {
        let tabulated = match self.model.as_str() {
            "kirchhoff" => false,
            "goman-khrabrov" => true,
            other => {
                return Err(AeroError::invalid(
                    "model longitudinal.model",
                    format!(
                        "is '{other}'; this library reads {}",
                        FORMS.map(|f| format!("'{f}'")).join(" or ")
                    ),
                ))
            }
        };
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
            let params: StallParams = if tabulated {
                if let Some(k) = f.params.keys().find(|k| {
                    PARAM_NAMES.contains(&k.as_str()) && !CORE_NAMES.contains(&k.as_str())
                }) {
                    return Err(AeroError::invalid(
                        place,
                        format!(
                            "gives '{k}', a parameter of the tanh curve, but the model is \
                             'goman-khrabrov' (its curve is the table x0_knots, x0_values); \
                             set model = 'kirchhoff' or give the table"
                        ),
                    ));
                }
                let v = named(&f.params, CORE_NAMES, &place, "parameter")?;
                GkParams::from_core(&v, f.x0_knots.clone(), f.x0_values.clone())
                    .context(place.clone())?
                    .into()
            } else {
                if !(f.x0_knots.is_empty() && f.x0_values.is_empty()) {
                    return Err(AeroError::invalid(
                        place,
                        "gives a separation table (x0_knots, x0_values) but the model is \
                         'kirchhoff' (the tanh curve); set model = 'goman-khrabrov' or drop \
                         the table",
                    ));
                }
                let v = named(&f.params, PARAM_NAMES, &place, "parameter")?;
                let p = KirchhoffParams::from_array(&v);
                p.check().context(place.clone())?;
                p.into()
            };
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
                params,
                drag,
            });
        }
        Ok(out)
    }

    /// A spec from fitted parameters per flap (`known` as in the module docs).
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] when the flaps mix the two forms (a model stores one).
    pub fn from_params(known: &str, flaps: &[(f64, StallParams, String)]) -> Result<Self> {
        let model = flaps.first().map_or("kirchhoff", |(_, p, _)| p.form());
        if let Some((f, p, _)) = flaps.iter().find(|(_, p, _)| p.form() != model) {
            return Err(AeroError::invalid(
                format!("longitudinal stall, flap {f}"),
                format!(
                    "is in the '{}' form and an earlier flap in '{model}'; a model stores one \
                     form for every flap",
                    p.form()
                ),
            ));
        }
        let pairs = |names: &[&str], v: &[f64]| -> BTreeMap<String, f64> {
            names
                .iter()
                .zip(v)
                .map(|(n, v)| ((*n).to_string(), *v))
                .collect()
        };
        Ok(LongitudinalSpec {
            model: model.into(),
            known: known.into(),
            flaps: flaps
                .iter()
                .map(|(f, p, note)| {
                    let (params, x0_knots, x0_values) = match p {
                        StallParams::Kirchhoff(k) => {
                            (pairs(&PARAM_NAMES, &k.to_array()), Vec::new(), Vec::new())
                        }
                        StallParams::GomanKhrabrov(g) => (
                            pairs(&CORE_NAMES, &g.to_vec()[..CORE_NAMES.len()]),
                            g.x0.knots().to_vec(),
                            g.x0.values().to_vec(),
                        ),
                    };
                    KirchhoffFlap {
                        flap_deg: *f,
                        params,
                        x0_knots,
                        x0_values,
                        drag: BTreeMap::new(),
                        note: note.clone(),
                    }
                })
                .collect(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::goman_khrabrov::X0Table;
    use crate::kirchhoff::tests::truth as params;

    #[test]
    fn round_trips_and_refuses_what_it_cannot_fly() {
        let spec = LongitudinalSpec::from_params("adx37", &[(0.0, params().into(), String::new())])
            .unwrap();
        let text = serde_json::to_string(&spec).unwrap();
        let back: LongitudinalSpec = serde_json::from_str(&text).unwrap();
        let plain = CompiledFlap {
            flap_deg: 0.0,
            params: params().into(),
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
        assert!(msg(&bad).contains("reads 'kirchhoff' or 'goman-khrabrov'"));
    }

    /// A tabulated stall: the truth's lags and lines over a table of its curve.
    fn table_params() -> GkParams {
        let p = params();
        let knots: Vec<f64> = (0..12)
            .map(|k| (6.0 + 2.0 * k as f64).to_radians())
            .collect();
        let values = knots.iter().map(|&a| p.x0(a)).collect();
        GkParams::with_table(&p, X0Table::new(knots, values).unwrap())
    }

    #[test]
    fn the_tabulated_form_round_trips_and_is_checked() {
        let g = table_params();
        let spec =
            LongitudinalSpec::from_params("none", &[(10.0, g.clone().into(), "n".into())]).unwrap();
        assert_eq!(spec.model, "goman-khrabrov");
        let text = serde_json::to_string(&spec).unwrap();
        assert!(
            text.contains("x0_knots") && !text.contains("alpha_star"),
            "{text}"
        );
        let back: LongitudinalSpec = serde_json::from_str(&text).unwrap();
        let c = back.compile().unwrap();
        assert_eq!(c[0].params, StallParams::GomanKhrabrov(g.clone()));
        let msg = |s: &LongitudinalSpec| s.compile().unwrap_err().to_string();
        // a knot off the uniform spacing, named with its flap
        let mut bad = spec.clone();
        bad.flaps[0].x0_knots[3] += 1e-4;
        let m = msg(&bad);
        assert!(m.contains("flap 10") && m.contains("knot 3"), "{m}");
        // a value outside [0, 1]
        let mut bad = spec.clone();
        bad.flaps[0].x0_values[2] = 1.2;
        assert!(msg(&bad).contains("knot 2"), "{}", msg(&bad));
        // no table at all
        let mut bad = spec.clone();
        bad.flaps[0].x0_knots.clear();
        bad.flaps[0].x0_values.clear();
        assert!(msg(&bad).contains("knots"), "{}", msg(&bad));
        // a tanh parameter in the tabulated form, an unknown one
        let mut bad = spec.clone();
        bad.flaps[0].params.insert("a1".into(), 20.0);
        let m = msg(&bad);
        assert!(m.contains("'a1', a parameter of the tanh curve"), "{m}");
        let mut bad = spec.clone();
        bad.flaps[0].params.insert("tau3".into(), 1.0);
        let m = msg(&bad);
        assert!(m.contains("unknown parameter 'tau3'"), "{m}");
        // a table given to the tanh form
        let mut tanh =
            LongitudinalSpec::from_params("none", &[(0.0, params().into(), String::new())])
                .unwrap();
        tanh.flaps[0].x0_knots = spec.flaps[0].x0_knots.clone();
        tanh.flaps[0].x0_values = spec.flaps[0].x0_values.clone();
        assert!(
            msg(&tanh).contains("set model = 'goman-khrabrov'"),
            "{}",
            msg(&tanh)
        );
        // one form per model
        let e = LongitudinalSpec::from_params(
            "none",
            &[
                (0.0, params().into(), String::new()),
                (10.0, g.into(), String::new()),
            ],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("flap 10") && e.contains("one form"), "{e}");
    }
}
