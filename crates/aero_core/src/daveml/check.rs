//! `checkData` static shots: read them (resolving each signal to a variable,
//! refusing unit mismatches) and run them against the model.
//!
//! A check passes when $|y_\text{actual} - y_\text{expected}| \le \text{tol}$
//! (DAVE-ML: "a maximum absolute difference between the expected and actual
//! value"). Outputs use their own `<tol>` ([`DEFAULT_TOL`] when absent).
//! `internalValues` carry no tolerance; they are checked at the largest output
//! tolerance of their shot, so a model passes its internal checks exactly when
//! its outputs are verified to the same accuracy.

use std::collections::HashMap;

use super::model::DaveModel;
use super::{child, elements, text_of, Node, Source};
use crate::error::Result;
use crate::text::shown;

/// Tolerance of a check output that gives no `<tol>`.
pub const DEFAULT_TOL: f64 = 1e-6;

/// One `staticShot`: inputs, optional internal values, expected outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct Shot {
    /// `name` attribute.
    pub name: String,
    /// Line of the `staticShot` element.
    pub line: usize,
    /// (variable index, value) set as inputs.
    pub inputs: Vec<(usize, f64)>,
    /// (variable index, expected value) from `internalValues`.
    pub internals: Vec<(usize, f64)>,
    /// (variable index, expected value, tolerance) from `checkOutputs`.
    pub outputs: Vec<(usize, f64, f64)>,
}

/// Whether a check row is a shot's output or one of its internal values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CheckKind {
    /// From `checkOutputs`, with the file's tolerance.
    Output,
    /// From `internalValues`.
    Internal,
}

impl CheckKind {
    /// `"output"` or `"internal"`.
    pub fn as_str(self) -> &'static str {
        match self {
            CheckKind::Output => "output",
            CheckKind::Internal => "internal",
        }
    }
}

/// The result of one check: a variable in one shot.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckRow {
    /// Shot name.
    pub shot: String,
    /// Variable `varID`.
    pub var_id: String,
    /// Variable `name`.
    pub name: String,
    /// Variable units.
    pub units: String,
    /// Output or internal value.
    pub kind: CheckKind,
    /// Value given by the file.
    pub expected: f64,
    /// Value computed by the model.
    pub actual: f64,
    /// Largest absolute difference accepted.
    pub tolerance: f64,
    /// `|actual - expected| <= tolerance` (false for NaN).
    pub pass: bool,
}

#[derive(Clone, Copy, PartialEq)]
enum Role {
    Input,
    Internal,
    Output,
}

fn number(src: &Source, node: Node<'_>) -> Result<f64> {
    let t = text_of(node);
    t.parse::<f64>()
        .map_err(|_| src.err(node, format!("'{}' is not a number", shown(&t))))
}

/// Variables by `name`, in file order.
type ByName<'m> = HashMap<&'m str, Vec<usize>>;

/// Resolve a `<signal>` to (variable, value, tolerance).
fn signal(
    src: &Source,
    sig: Node<'_>,
    model: &DaveModel,
    by_name: &ByName<'_>,
    shot: &str,
    role: Role,
) -> Result<(usize, f64, Option<f64>)> {
    let shot = shown(shot);
    let value_node = child(sig, "signalValue")
        .ok_or_else(|| src.err(sig, format!("in shot '{shot}' has no <signalValue>")))?;
    let value = number(src, value_node)?;
    let tol = match child(sig, "tol") {
        Some(t) => Some(number(src, t)?),
        None => None,
    };
    if let Some(idn) = child(sig, "varID").or_else(|| child(sig, "signalID")) {
        let id = text_of(idn);
        let i = model.index_of(&id).ok_or_else(|| {
            let id = shown(&id);
            src.err(
                idn,
                format!("in shot '{shot}': unknown varID '{id}'; no <variableDef varID=\"{id}\">"),
            )
        })?;
        return Ok((i, value, tol));
    }
    let name_node = child(sig, "signalName").ok_or_else(|| {
        src.err(
            sig,
            format!("in shot '{shot}' has neither <signalName> nor <varID>"),
        )
    })?;
    let name = text_of(name_node);
    let vars = model.variables();
    let mut cands: Vec<usize> = by_name.get(name.as_str()).cloned().unwrap_or_default();
    if cands.is_empty() {
        cands = model.index_of(&name).into_iter().collect();
    }
    if cands.is_empty() {
        let name = shown(&name);
        return Err(src.err(
            name_node,
            format!("in shot '{shot}': unknown signal '{name}'; no <variableDef name=\"{name}\">"),
        ));
    }
    if let Some(u) = child(sig, "signalUnits") {
        let units = text_of(u);
        let same: Vec<usize> = cands
            .iter()
            .copied()
            .filter(|&i| vars[i].units == units)
            .collect();
        if same.is_empty() {
            let v = &vars[cands[0]];
            return Err(src.err(
                u,
                format!(
                    "unit mismatch in shot '{shot}', signal '{}': the check gives '{}' but <variableDef varID=\"{}\"> (line {}) is in '{}'; give the value in '{}'",
                    shown(&name), shown(&units), shown(&v.id), v.line, shown(&v.units), shown(&v.units)
                ),
            ));
        }
        cands = same;
    }
    let pick = cands
        .iter()
        .copied()
        .find(|&i| match role {
            Role::Input => model.is_free(i),
            Role::Output => vars[i].is_output,
            Role::Internal => true,
        })
        .unwrap_or(cands[0]);
    Ok((pick, value, tol))
}

/// Read every `staticShot` of a `checkData` element.
pub(crate) fn parse_check_data(src: &Source, cd: Node<'_>, model: &DaveModel) -> Result<Vec<Shot>> {
    let mut by_name: ByName<'_> = HashMap::new();
    for (i, v) in model.variables().iter().enumerate() {
        by_name.entry(v.name.as_str()).or_default().push(i);
    }
    let mut shots = Vec::new();
    for s in elements(cd).filter(|n| n.tag_name() == "staticShot") {
        let name = s.attribute("name").unwrap_or("").trim().to_string();
        let mut shot = Shot {
            name: name.clone(),
            line: src.line(s),
            inputs: Vec::new(),
            internals: Vec::new(),
            outputs: Vec::new(),
        };
        let signals = |tag: &str| -> Vec<Node> {
            child(s, tag)
                .map(|c| elements(c).filter(|n| n.tag_name() == "signal").collect())
                .unwrap_or_default()
        };
        for sig in signals("checkInputs") {
            let (i, v, _) = signal(src, sig, model, &by_name, &name, Role::Input)?;
            if !model.is_free(i) {
                return Err(src.err(
                    sig,
                    format!(
                        "in shot '{}': '{}' is computed by the model and cannot be a check input",
                        shown(&name),
                        shown(&model.variables()[i].id)
                    ),
                ));
            }
            shot.inputs.push((i, v));
        }
        for sig in signals("internalValues") {
            let (i, v, _) = signal(src, sig, model, &by_name, &name, Role::Internal)?;
            shot.internals.push((i, v));
        }
        for sig in signals("checkOutputs") {
            let (i, v, t) = signal(src, sig, model, &by_name, &name, Role::Output)?;
            shot.outputs.push((i, v, t.unwrap_or(DEFAULT_TOL)));
        }
        if let Err(e) = model.input_indices(
            shot.inputs
                .iter()
                .map(|&(i, _)| model.variables()[i].id.as_str()),
        ) {
            return Err(src.err(s, format!("check inputs are incomplete: {e}")));
        }
        shots.push(shot);
    }
    Ok(shots)
}

impl DaveModel {
    /// Run every static shot of the file: one row per checked output and per
    /// internal value, in file order.
    pub fn run_checks(&self) -> Vec<CheckRow> {
        let mut rows = Vec::new();
        let mut values = vec![0.0; self.vars.len()];
        let mut cache = super::model::LocCache::new(self.locators.len());
        for shot in &self.shots {
            self.compute_cached(&shot.inputs, &mut values, &mut cache);
            let shot_tol = shot.outputs.iter().map(|o| o.2).fold(f64::NAN, f64::max);
            let shot_tol = if shot_tol.is_nan() {
                DEFAULT_TOL
            } else {
                shot_tol
            };
            let mut row = |i: usize, expected: f64, tolerance: f64, kind: CheckKind| {
                let v = &self.vars[i];
                let actual = values[i];
                rows.push(CheckRow {
                    shot: shot.name.clone(),
                    var_id: v.id.clone(),
                    name: v.name.clone(),
                    units: v.units.clone(),
                    kind,
                    expected,
                    actual,
                    tolerance,
                    pass: (actual - expected).abs() <= tolerance,
                });
            };
            for &(i, e, t) in &shot.outputs {
                row(i, e, t, CheckKind::Output);
            }
            for &(i, e) in &shot.internals {
                row(i, e, shot_tol, CheckKind::Internal);
            }
        }
        rows
    }
}
