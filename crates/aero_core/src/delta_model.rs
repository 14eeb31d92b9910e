//! The Δ part of the extended model and its evaluation (thesis Eq. 3.11, 3.12, 3.19).
//!
//! For each coefficient $C_i$ ($i = l, n, Y$) the Δ model is a sum of terms,
//! each a parameter table in angle of attack (one row per flap setting)
//! times a regressor:
//! $$ \Delta C_i = \sum_j \theta_{ij}(\delta_f, \alpha)\, x_j, $$
//! the parameters being the smoothed per-bin estimates resampled on a grid
//! (Eq. 3.19), held beyond their last breakpoint (the tables are clipped at
//! 10 deg past stall, Section 3.4). Between flap settings the tables are
//! interpolated linearly. The extended coefficient blends the correction in
//! linearly between $\alpha_l$ and $\alpha_u$ (Eq. 3.12):
//! $$ C_{i,ext} = C_{i,qual} + w(\alpha)\,\Delta C_i,\quad
//!    w = \min\!\big(1, \max(0, \tfrac{\alpha-\alpha_l}{\alpha_u-\alpha_l})\big). $$
//!
//! The model is stored as one versioned JSON document
//! ([`DELTA_MODEL_SCHEMA`]) that both Python and Rust load. Angles in the
//! tables are in degrees (the `alpha_deg` channel); each regressor carries its
//! own units through the columns it names.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::envelope::{Envelope, EnvelopeSpec};
use crate::error::{AeroError, Result, ResultExt};
use crate::kirchhoff::KirchhoffDrag;
use crate::regressor::{BoundExpr, Expr};
use crate::stall_form::StallParams;
use crate::stall_spec::{CompiledFlap, LongitudinalSpec};
use crate::table::{Axis, Table};
use crate::text::{one_line, shown};

/// Schema identifier written into every model file.
pub const DELTA_MODEL_SCHEMA: &str = "aerodelta.model/1";

/// One term $\theta_j(\delta_f, \alpha)\,x_j$ of a coefficient's Δ model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TermSpec {
    /// Parameter name, e.g. `dCl_beta`.
    pub name: String,
    /// Regressor expression (see [`crate::regressor`]), e.g. `beta_deg`.
    pub regressor: String,
    /// Angle-of-attack breakpoints of the parameter table, deg, increasing.
    pub alpha_deg: Vec<f64>,
    /// Parameter values: one row per flap setting of the model, each on `alpha_deg`.
    pub values: Vec<Vec<f64>>,
    /// Optional lower and upper confidence bounds on the same grid (e.g. 95 %, bootstrap).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub band: Option<Band>,
}

/// A confidence band on a parameter table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Band {
    /// Confidence level, e.g. 0.95.
    pub level: f64,
    /// Lower bound, one row per flap.
    pub lower: Vec<Vec<f64>>,
    /// Upper bound, one row per flap.
    pub upper: Vec<Vec<f64>>,
}

/// The Δ model of one coefficient.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoefficientSpec {
    /// Terms summed into ΔC.
    pub terms: Vec<TermSpec>,
    /// Blending start $\alpha_l$ per flap, deg (Eq. 3.12).
    pub alpha_l_deg: Vec<f64>,
    /// Blending end $\alpha_u$ per flap, deg (Eq. 3.12).
    pub alpha_u_deg: Vec<f64>,
}

/// The stored Δ model: everything needed to rebuild [`DeltaModel`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DeltaModelSpec {
    /// Always [`DELTA_MODEL_SCHEMA`].
    pub schema: String,
    /// Flap settings of the table rows, deg, increasing.
    pub flaps_deg: Vec<f64>,
    /// Name of the angle-of-attack channel (deg) the tables are indexed by.
    #[serde(default = "default_alpha")]
    pub alpha_channel: String,
    /// Name of the flap channel (deg).
    #[serde(default = "default_flap")]
    pub flap_channel: String,
    /// Per coefficient (`Cl`, `Cn`, `CY`, ...).
    pub coefficients: BTreeMap<String, CoefficientSpec>,
    /// Provenance: library version, data hash, configuration, ... (free form).
    #[serde(default)]
    pub provenance: serde_json::Value,
    /// Stochastic roll-off configuration, when the model carries one (free form here).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rolloff: Option<serde_json::Value>,
    /// The flight data's α/β coverage per flap ([`crate::envelope`]), when the fit wrote it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub envelope: Option<EnvelopeSpec>,
    /// The longitudinal stall identified per flap ([`crate::stall_spec`]), when stored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub longitudinal: Option<LongitudinalSpec>,
}

fn default_alpha() -> String {
    "alpha_deg".into()
}
fn default_flap() -> String {
    "flap_deg".into()
}

#[derive(Debug, Clone)]
struct Term {
    name: String,
    expr: Expr,
    table: Table,
}

#[derive(Debug, Clone)]
struct Coefficient {
    name: String,
    terms: Vec<Term>,
    alpha_l: Table,
    alpha_u: Table,
}

/// A validated, ready-to-evaluate Δ model.
#[derive(Debug, Clone)]
pub struct DeltaModel {
    spec: DeltaModelSpec,
    coefficients: Vec<Coefficient>,
    envelope: Option<Envelope>,
    kirchhoff: Vec<CompiledFlap>,
}

/// Linear blending weight of Eq. 3.12.
#[inline]
pub fn blend_weight(alpha: f64, alpha_l: f64, alpha_u: f64) -> f64 {
    if alpha.is_nan() {
        return f64::NAN;
    }
    if alpha <= alpha_l {
        0.0
    } else if alpha > alpha_u || alpha_u <= alpha_l {
        1.0
    } else {
        (alpha - alpha_l) / (alpha_u - alpha_l)
    }
}

impl DeltaModel {
    /// Validate a spec and compile its tables and regressors.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the coefficient, term and what is
    /// wrong (schema, grid, row count, regressor syntax, blend limits).
    pub fn new(spec: DeltaModelSpec) -> Result<Self> {
        if spec.schema != DELTA_MODEL_SCHEMA {
            return Err(AeroError::invalid(
                "model schema",
                format!(
                    "is '{}', this library reads '{DELTA_MODEL_SCHEMA}'",
                    shown(&spec.schema)
                ),
            ));
        }
        let nflap = spec.flaps_deg.len();
        // Axis names only label messages: long or multi-line ones are shown clipped.
        let flap_axis = Axis::new(shown(&spec.flap_channel), spec.flaps_deg.clone())
            .context("model flaps_deg")?;
        // Sized up front: a model file may hold many small coefficients, and a
        // vector grown by doubling would take twice their memory.
        let mut coefficients = Vec::with_capacity(spec.coefficients.len());
        for (cname, c) in &spec.coefficients {
            let place = format!("coefficient {}", shown(cname));
            for (what, v) in [
                ("alpha_l_deg", &c.alpha_l_deg),
                ("alpha_u_deg", &c.alpha_u_deg),
            ] {
                if v.len() != nflap {
                    return Err(AeroError::invalid(
                        format!("{place}, {what}"),
                        format!("has {} entries for {nflap} flap settings", v.len()),
                    ));
                }
            }
            for (k, (l, u)) in c.alpha_l_deg.iter().zip(&c.alpha_u_deg).enumerate() {
                if !(l.is_finite() && u.is_finite() && l <= u) {
                    return Err(AeroError::invalid(
                        format!("{place}, flap {}", spec.flaps_deg[k]),
                        format!("blend limits alpha_l={l}, alpha_u={u} must be finite with alpha_l <= alpha_u"),
                    ));
                }
            }
            let mut terms = Vec::with_capacity(c.terms.len());
            for t in &c.terms {
                let tplace = format!("{place}, term '{}'", shown(&t.name));
                let expr = Expr::parse(&t.regressor).context(tplace.clone())?;
                if t.values.len() != nflap {
                    return Err(AeroError::invalid(
                        tplace,
                        format!(
                            "has {} value rows for {nflap} flap settings",
                            t.values.len()
                        ),
                    ));
                }
                let alpha_axis = Axis::new(shown(&spec.alpha_channel), t.alpha_deg.clone())
                    .context(tplace.clone())?;
                let mut flat = Vec::with_capacity(nflap * t.alpha_deg.len());
                for (k, row) in t.values.iter().enumerate() {
                    if row.len() != t.alpha_deg.len() {
                        return Err(AeroError::invalid(
                            format!("{tplace}, flap {}", spec.flaps_deg[k]),
                            format!(
                                "has {} values for {} alpha breakpoints",
                                row.len(),
                                t.alpha_deg.len()
                            ),
                        ));
                    }
                    if let Some(j) = row.iter().position(|v| !v.is_finite()) {
                        return Err(AeroError::invalid(
                            format!(
                                "{tplace}, flap {}, alpha {}",
                                spec.flaps_deg[k], t.alpha_deg[j]
                            ),
                            "value is not finite; fill unidentified bins before building the model",
                        ));
                    }
                    flat.extend_from_slice(row);
                }
                let table =
                    Table::new(vec![flap_axis.clone(), alpha_axis], flat).context(tplace)?;
                terms.push(Term {
                    name: t.name.clone(),
                    expr,
                    table,
                });
            }
            let one = |v: &Vec<f64>| Table::new(vec![flap_axis.clone()], v.clone());
            coefficients.push(Coefficient {
                name: cname.clone(),
                terms,
                alpha_l: one(&c.alpha_l_deg)?,
                alpha_u: one(&c.alpha_u_deg)?,
            });
        }
        let envelope = spec.envelope.clone().map(Envelope::new).transpose()?;
        let kirchhoff = spec
            .longitudinal
            .as_ref()
            .map(LongitudinalSpec::compile)
            .transpose()?
            .unwrap_or_default();
        Ok(DeltaModel {
            spec,
            coefficients,
            envelope,
            kirchhoff,
        })
    }

    /// The stored stall parameters of a flap setting (deg, exact), in the stored form of the
    /// separation curve ([`crate::stall_form`]), with the basis of their known terms
    /// ([`LongitudinalSpec::known`]); `None` when the model carries none for it.
    pub fn kirchhoff(&self, flap_deg: f64) -> Option<(&StallParams, &str)> {
        let known = self.spec.longitudinal.as_ref()?.known.as_str();
        self.kirchhoff
            .iter()
            .find(|f| f.flap_deg == flap_deg)
            .map(|f| (&f.params, known))
    }

    /// The stored drag of the Kirchhoff stall at a flap setting (deg, exact); `None` when the
    /// model carries no stall or no drag for it.
    pub fn kirchhoff_drag(&self, flap_deg: f64) -> Option<&KirchhoffDrag> {
        self.kirchhoff
            .iter()
            .find(|f| f.flap_deg == flap_deg)
            .and_then(|f| f.drag.as_ref())
    }

    /// The stored stall a simulator of the built-in ADX-37 flies at `flap_deg` (deg, exact):
    /// the Kirchhoff parameters and drag when they were fitted on that aircraft's known terms
    /// (`known == "adx37"`; they then replace its qualified static C_L, C_m and, with the
    /// drag, C_D curves), `None` for another basis or no stall. The rule of every ADX-37
    /// replay of a Δ model (open and closed loop).
    pub fn adx37_stall(&self, flap_deg: f64) -> Option<(StallParams, Option<KirchhoffDrag>)> {
        self.kirchhoff(flap_deg)
            .filter(|(_, known)| *known == "adx37")
            .map(|(p, _)| (p.clone(), self.kirchhoff_drag(flap_deg).copied()))
    }

    /// Whether the state (flap, α, β in deg) lies inside the validated envelope of the flight
    /// data ([`Envelope::contains`]); `None` when the model carries no envelope.
    pub fn in_envelope(&self, flap_deg: f64, alpha_deg: f64, beta_deg: f64) -> Option<bool> {
        self.envelope
            .as_ref()
            .map(|e| e.contains(flap_deg, alpha_deg, beta_deg))
    }

    /// [`DeltaModel::in_envelope`] of each row of three columns (deg); `None` when the model
    /// carries no envelope.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] when the columns differ in length.
    pub fn in_envelope_columns(
        &self,
        flap_deg: &[f64],
        alpha_deg: &[f64],
        beta_deg: &[f64],
    ) -> Result<Option<Vec<bool>>> {
        if alpha_deg.len() != flap_deg.len() || beta_deg.len() != flap_deg.len() {
            return Err(AeroError::invalid(
                "in_envelope",
                format!(
                    "columns of {} (flap), {} (alpha) and {} (beta) rows; they must have one length",
                    flap_deg.len(),
                    alpha_deg.len(),
                    beta_deg.len()
                ),
            ));
        }
        Ok(self.envelope.as_ref().map(|e| {
            flap_deg
                .iter()
                .zip(alpha_deg)
                .zip(beta_deg)
                .map(|((f, a), b)| e.contains(*f, *a, *b))
                .collect()
        }))
    }

    /// The stored form.
    pub fn spec(&self) -> &DeltaModelSpec {
        &self.spec
    }

    /// Coefficient names, in evaluation order.
    pub fn coefficient_names(&self) -> Vec<String> {
        self.coefficients.iter().map(|c| c.name.clone()).collect()
    }

    /// Every data column the model reads (alpha, flap and the regressors').
    pub fn input_columns(&self) -> Vec<String> {
        let mut out = vec![
            self.spec.alpha_channel.clone(),
            self.spec.flap_channel.clone(),
        ];
        let mut seen: std::collections::HashSet<String> = out.iter().cloned().collect();
        for c in &self.coefficients {
            for t in &c.terms {
                for col in t.expr.columns() {
                    if seen.insert(col.clone()) {
                        out.push(col);
                    }
                }
            }
        }
        out
    }

    fn coefficient(&self, name: &str) -> Result<&Coefficient> {
        // In name order (built from the spec's BTreeMap).
        self.coefficients
            .binary_search_by(|c| c.name.as_str().cmp(name))
            .map(|k| &self.coefficients[k])
            .map_err(|_| {
                AeroError::invalid(
                    format!("coefficient '{}'", shown(name)),
                    format!(
                        "is not in the model (it has {})",
                        shown(&self.coefficient_names().join(", "))
                    ),
                )
            })
    }

    /// Evaluate one coefficient over columns of `n` rows.
    ///
    /// Returns `(delta, weight, terms)`: the unblended ΔC, the blending weight
    /// $w(\alpha)$ of Eq. 3.12, and each term's contribution $\theta_j x_j$
    /// (unblended), in the model's term order. The extended coefficient is
    /// `qualified + weight * delta`.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] for an unknown coefficient or a missing or
    /// mis-sized column.
    #[allow(clippy::type_complexity)]
    pub fn eval_columns<'a>(
        &self,
        coefficient: &str,
        lookup: &dyn Fn(&str) -> Option<&'a [f64]>,
        n: usize,
    ) -> Result<(Vec<f64>, Vec<f64>, Vec<(String, Vec<f64>)>)> {
        let c = self.coefficient(coefficient)?;
        let get = |name: &str| -> Result<&'a [f64]> {
            let col = lookup(name).ok_or_else(|| {
                AeroError::invalid(
                    format!("column '{name}'"),
                    "is required by the model but missing",
                )
            })?;
            if col.len() != n {
                return Err(AeroError::invalid(
                    format!("column '{name}'"),
                    format!("has {} rows, expected {n}", col.len()),
                ));
            }
            Ok(col)
        };
        let alpha = get(&self.spec.alpha_channel)?;
        let flap = get(&self.spec.flap_channel)?;
        let mut delta = vec![0.0; n];
        let mut terms = Vec::with_capacity(c.terms.len());
        let mut theta = vec![0.0; n];
        for t in &c.terms {
            let x = t
                .expr
                .eval_columns(lookup, n)
                .with_context(|| format!("coefficient {}", c.name))?;
            t.table.eval_columns(&[flap, alpha], &mut theta)?;
            let contrib: Vec<f64> = theta.iter().zip(&x).map(|(a, b)| a * b).collect();
            for (d, v) in delta.iter_mut().zip(&contrib) {
                *d += v;
            }
            terms.push((t.name.clone(), contrib));
        }
        let weight: Vec<f64> = alpha
            .iter()
            .zip(flap)
            .map(|(&a, &f)| blend_weight(a, c.alpha_l.eval(&[f]), c.alpha_u.eval(&[f])))
            .collect();
        Ok((delta, weight, terms))
    }

    /// Parameter value of a term at (flap, alpha): for plots and exports.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] for an unknown coefficient or term.
    pub fn parameter(
        &self,
        coefficient: &str,
        term: &str,
        flap_deg: f64,
        alpha_deg: f64,
    ) -> Result<f64> {
        let c = self.coefficient(coefficient)?;
        let t = c.terms.iter().find(|t| t.name == term).ok_or_else(|| {
            AeroError::invalid(
                format!("coefficient {coefficient}, term '{term}'"),
                "is not in the model",
            )
        })?;
        Ok(t.table.eval(&[flap_deg, alpha_deg]))
    }

    /// Resolve the model against a simulator's state-vector layout for
    /// allocation-free evaluation (see [`BoundDeltaModel::eval`]).
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming a channel the layout lacks.
    pub fn bind(&self, layout: &[&str]) -> Result<BoundDeltaModel<'_>> {
        let find = |name: &str| {
            layout.iter().position(|l| *l == name).ok_or_else(|| {
                AeroError::invalid(
                    format!("channel '{name}'"),
                    format!(
                        "is required by the model but not in the state layout ({})",
                        layout.join(", ")
                    ),
                )
            })
        };
        let alpha = find(&self.spec.alpha_channel)?;
        let flap = find(&self.spec.flap_channel)?;
        let mut coefs = Vec::new();
        for c in &self.coefficients {
            let mut terms = Vec::new();
            for t in &c.terms {
                terms.push((t.expr.bind(layout)?, &t.table));
            }
            coefs.push(BoundCoefficient { coef: c, terms });
        }
        Ok(BoundDeltaModel { alpha, flap, coefs })
    }

    /// Serialise to the versioned JSON document.
    ///
    /// # Errors
    /// Never in practice (serialisation of plain data); typed for uniformity.
    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string_pretty(&self.spec)
            .map_err(|e| AeroError::invalid("model", format!("cannot serialise: {e}")))
    }

    /// Parse and validate a JSON document; `source` names it in errors.
    ///
    /// # Errors
    /// [`AeroError::Parse`] with the line for malformed JSON; validation errors as [`DeltaModel::new`].
    pub fn from_json(text: &str, source: &str) -> Result<Self> {
        Self::from_slice(text.as_bytes(), source)
    }

    /// Parse and validate a JSON document given as bytes (a file's
    /// contents); `source` names it in errors.
    ///
    /// # Errors
    /// As [`DeltaModel::from_json`]; bytes that are not UTF-8 are a parse
    /// error with their line.
    pub fn from_slice(bytes: &[u8], source: &str) -> Result<Self> {
        let spec: DeltaModelSpec = serde_json::from_slice(bytes)
            .map_err(|e| AeroError::parse(source, e.line(), one_line(&e.to_string())))?;
        DeltaModel::new(spec).context(source.to_string())
    }

    /// Load from a file.
    ///
    /// # Errors
    /// I/O, parse and validation errors naming the file.
    pub fn load(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| AeroError::io(path, e))?;
        Self::from_slice(&bytes, &path.display().to_string())
    }

    /// Save atomically (temporary file in the same folder, then rename).
    ///
    /// # Errors
    /// I/O errors naming the file.
    pub fn save(&self, path: &Path) -> Result<()> {
        crate::fsutil::write_atomic(path, self.to_json()?.as_bytes())
    }
}

#[derive(Debug)]
struct BoundCoefficient<'m> {
    coef: &'m Coefficient,
    terms: Vec<(BoundExpr, &'m Table)>,
}

/// A [`DeltaModel`] bound to a state layout: the simulator's real-time path.
#[derive(Debug)]
pub struct BoundDeltaModel<'m> {
    alpha: usize,
    flap: usize,
    coefs: Vec<BoundCoefficient<'m>>,
}

impl BoundDeltaModel<'_> {
    /// Blended corrections $w(\alpha)\,\Delta C_i$ for every coefficient, in
    /// [`DeltaModel::coefficient_names`] order, written into `out`.
    /// No allocation; NaN inputs give NaN outputs.
    #[inline]
    pub fn eval(&self, state: &[f64], out: &mut [f64]) {
        let alpha = state.get(self.alpha).copied().unwrap_or(f64::NAN);
        let flap = state.get(self.flap).copied().unwrap_or(f64::NAN);
        for (c, o) in self.coefs.iter().zip(out.iter_mut()) {
            let mut d = 0.0;
            for (x, table) in &c.terms {
                d += table.eval(&[flap, alpha]) * x.eval(state);
            }
            let w = blend_weight(
                alpha,
                c.coef.alpha_l.eval(&[flap]),
                c.coef.alpha_u.eval(&[flap]),
            );
            *o = w * d;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> DeltaModelSpec {
        let mut coefficients = BTreeMap::new();
        coefficients.insert(
            "Cl".to_string(),
            CoefficientSpec {
                terms: vec![
                    TermSpec {
                        name: "dCl_0".into(),
                        regressor: "1".into(),
                        alpha_deg: vec![10.0, 20.0],
                        values: vec![vec![0.0, 0.01], vec![0.0, 0.03]],
                        band: None,
                    },
                    TermSpec {
                        name: "dCl_da".into(),
                        regressor: "deadband(da_deg, 2)".into(),
                        alpha_deg: vec![10.0, 15.0, 20.0],
                        values: vec![vec![0.0, 0.001, 0.002], vec![0.0, 0.002, 0.004]],
                        band: None,
                    },
                ],
                alpha_l_deg: vec![8.0, 10.0],
                alpha_u_deg: vec![12.0, 14.0],
            },
        );
        DeltaModelSpec {
            schema: DELTA_MODEL_SCHEMA.into(),
            flaps_deg: vec![0.0, 10.0],
            alpha_channel: "alpha_deg".into(),
            flap_channel: "flap_deg".into(),
            coefficients,
            provenance: serde_json::json!({"test": true}),
            rolloff: None,
            envelope: None,
            longitudinal: None,
        }
    }

    #[test]
    fn a_stored_kirchhoff_stall_survives_the_file_and_is_checked_on_load() {
        let p = crate::kirchhoff::tests::truth();
        let m = DeltaModel::new(spec()).unwrap();
        assert!(m.kirchhoff(0.0).is_none());
        let mut s = spec();
        s.longitudinal = Some(
            LongitudinalSpec::from_params("adx37", &[(10.0, p.into(), "note".into())]).unwrap(),
        );
        let m = DeltaModel::from_json(&DeltaModel::new(s.clone()).unwrap().to_json().unwrap(), "m")
            .unwrap();
        assert_eq!(m.kirchhoff(10.0), Some((&p.into(), "adx37")));
        assert!(m.kirchhoff(0.0).is_none());
        assert_eq!(m.spec(), &s);
        if let Some(l) = s.longitudinal.as_mut() {
            l.flaps[0].params.insert("a1".into(), 0.0);
        }
        let msg = DeltaModel::new(s).unwrap_err().to_string();
        assert!(msg.contains("flap 10") && msg.contains("a1"), "{msg}");
    }

    #[test]
    fn envelope_is_read_checked_and_answers() {
        let m = DeltaModel::new(spec()).unwrap();
        assert_eq!(m.in_envelope(0.0, 12.0, 0.0), None);
        let mut s = spec();
        s.envelope = Some(crate::envelope::EnvelopeSpec {
            band_deg: 1.0,
            flaps_deg: vec![0.0, 10.0],
            bands: vec![
                vec![crate::envelope::EnvelopeBand {
                    band: 12,
                    beta_min_deg: -4.0,
                    beta_max_deg: 3.0,
                    maneuvers: 5,
                }],
                vec![],
            ],
            min_maneuvers: 2,
        });
        let m = DeltaModel::new(s.clone()).unwrap();
        assert_eq!(m.in_envelope(0.0, 12.5, 2.0), Some(true));
        assert_eq!(m.in_envelope(0.0, 12.5, 3.5), Some(false));
        assert_eq!(m.in_envelope(10.0, 12.5, 0.0), Some(false));
        // round trip through the JSON document, and a malformed one refused on load
        let back = DeltaModel::from_json(&m.to_json().unwrap(), "t").unwrap();
        assert_eq!(back.spec(), m.spec());
        let mut bad = s;
        if let Some(e) = bad.envelope.as_mut() {
            e.bands[0][0].beta_max_deg = f64::NAN;
        }
        let msg = DeltaModel::new(bad).unwrap_err().to_string();
        assert!(msg.contains("envelope, flap 0, band 12"), "{msg}");
    }

    #[test]
    fn blend_weight_is_eq_3_12() {
        assert_eq!(blend_weight(5.0, 8.0, 12.0), 0.0);
        assert_eq!(blend_weight(8.0, 8.0, 12.0), 0.0);
        assert_eq!(blend_weight(10.0, 8.0, 12.0), 0.5);
        assert_eq!(blend_weight(12.0, 8.0, 12.0), 1.0);
        assert_eq!(blend_weight(30.0, 8.0, 12.0), 1.0);
        assert!(blend_weight(f64::NAN, 8.0, 12.0).is_nan());
    }

    #[test]
    fn columns_and_bound_paths_agree_with_hand_values() {
        let m = DeltaModel::new(spec()).expect("valid");
        // flap 5 (halfway), alpha 15, da 6 -> deadband 4
        let alpha = [15.0, 25.0, 9.0];
        let flap = [5.0, 0.0, 0.0];
        let da = [6.0, -3.0, 10.0];
        let lookup = |n: &str| -> Option<&[f64]> {
            match n {
                "alpha_deg" => Some(&alpha),
                "flap_deg" => Some(&flap),
                "da_deg" => Some(&da),
                _ => None,
            }
        };
        let (delta, w, terms) = m.eval_columns("Cl", &lookup, 3).expect("evaluates");
        // row 0: dCl_0 at alpha 15: flap0 0.005, flap10 0.015 -> 0.01; dCl_da: 0.0015*4 = 0.006
        assert!((delta[0] - (0.01 + 0.006)).abs() < 1e-15);
        // blend: alpha_l 9, alpha_u 13 at flap 5 -> alpha 15 beyond -> 1
        assert_eq!(w[0], 1.0);
        // row 1: alpha 25 held at 20: 0.01 + 0.002*(-1) = 0.008
        assert!((delta[1] - 0.008).abs() < 1e-15);
        // row 2: alpha 9 held at 10: 0 + 0; blend at flap0 (8..12): 0.25
        assert_eq!(delta[2], 0.0);
        assert_eq!(w[2], 0.25);
        assert_eq!(terms.len(), 2);
        let layout = ["alpha_deg", "da_deg", "flap_deg"];
        let b = m.bind(&layout).expect("binds");
        for i in 0..3 {
            let mut out = [0.0];
            b.eval(&[alpha[i], da[i], flap[i]], &mut out);
            assert!((out[0] - w[i] * delta[i]).abs() < 1e-16);
        }
    }

    #[test]
    fn json_round_trip_and_atomic_save() {
        let m = DeltaModel::new(spec()).expect("valid");
        let dir = std::env::temp_dir().join(format!("aerodelta-dm-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("tmp dir");
        let path = dir.join("model.json");
        m.save(&path).expect("saves");
        let back = DeltaModel::load(&path).expect("loads");
        assert_eq!(back.spec(), m.spec());
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn validation_errors_name_the_place() {
        let mut s = spec();
        s.schema = "other/9".into();
        assert!(DeltaModel::new(s)
            .unwrap_err()
            .to_string()
            .contains("this library reads"));
        let mut s = spec();
        if let Some(c) = s.coefficients.get_mut("Cl") {
            c.terms[1].values[1].pop();
        }
        let e = DeltaModel::new(s).unwrap_err().to_string();
        assert!(
            e.contains("term 'dCl_da', flap 10") && e.contains("2 values for 3"),
            "{e}"
        );
        let mut s = spec();
        if let Some(c) = s.coefficients.get_mut("Cl") {
            c.terms[0].values[0][1] = f64::NAN;
        }
        let e = DeltaModel::new(s).unwrap_err().to_string();
        assert!(e.contains("alpha 20") && e.contains("not finite"), "{e}");
        let e = DeltaModel::from_json("{\n\"schema\": 3", "m.json")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("m.json:2:"), "{e}");
        let m = DeltaModel::new(spec()).expect("valid");
        assert!(m
            .bind(&["alpha_deg", "flap_deg"])
            .unwrap_err()
            .to_string()
            .contains("da_deg"));
    }

    #[test]
    fn model_bytes_that_are_not_utf8_name_the_line() {
        let mut b = br#"{"schema": "aerodelta.model/1",
"flaps_deg": [0], "coefficients": {}}"#
            .to_vec();
        b.insert(40, 0xFF);
        let e = DeltaModel::from_slice(&b, "m.json").unwrap_err();
        assert_eq!(e.kind(), crate::error::ErrorKind::Parse);
        let msg = e.to_string();
        assert!(
            msg.starts_with("m.json:2: invalid unicode code point"),
            "{msg}"
        );
    }

    #[test]
    fn long_names_in_a_model_give_short_messages() {
        let long = "n".repeat(100_000);
        let text = format!(
            r#"{{"schema": "aerodelta.model/1", "flaps_deg": [0], "coefficients": {{"Cl": {{"terms": [{{"name": "{long}", "regressor": "1 +", "alpha_deg": [10], "values": [[1]]}}], "alpha_l_deg": [10], "alpha_u_deg": [12]}}}}}}"#
        );
        let msg = DeltaModel::from_json(&text, "m.json")
            .unwrap_err()
            .to_string();
        assert!(
            msg.len() < 600 && msg.contains("(100000 characters)"),
            "{msg}"
        );
        let msg = DeltaModel::from_json(&format!(r#"{{"schema": "{long}"}}"#), "m.json")
            .unwrap_err()
            .to_string();
        assert!(
            msg.len() < 1000 && msg.starts_with("m.json:1: missing field"),
            "{msg}"
        );
    }
}
