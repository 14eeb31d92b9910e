//! Write a model as DAVE-ML: input variables (units, limits), gridded tables
//! (one `breakpointDef` per distinct axis, a `function` with an inline
//! `griddedTableDef` per table) and outputs that are MathML sums of products,
//! $y = \sum_k c_k \prod_j x_{kj}$. The `checkData` static shots are generated
//! by evaluating the model itself at the spec's check points, so any DAVE-ML
//! tool can verify the file; every variable's value is listed as an
//! `internalValues` entry. The write is atomic (temporary file in the same
//! folder, then rename).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::model::DaveModel;
use crate::error::{AeroError, Result};

fn default_units() -> String {
    "nd".to_string()
}
fn default_tol() -> f64 {
    1e-9
}
fn one() -> f64 {
    1.0
}

/// A model to write.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSpec {
    /// Model name (`fileHeader name`).
    pub name: String,
    /// Free text for the file header.
    #[serde(default)]
    pub description: String,
    /// Author written in the header (default "aerodelta").
    #[serde(default)]
    pub author: String,
    /// ISO date of the file (default: today, UTC).
    #[serde(default)]
    pub date: Option<String>,
    /// Input variables.
    pub inputs: Vec<InputSpec>,
    /// Calculated variables: expressions in the regressor language
    /// ([`crate::regressor`]), written as MathML.
    #[serde(default)]
    pub calculations: Vec<CalcSpec>,
    /// Gridded tables, each defining one variable.
    #[serde(default)]
    pub tables: Vec<TableSpec>,
    /// Output variables: sums of products of other variables.
    pub outputs: Vec<OutputSpec>,
    /// Points at which check cases are generated.
    #[serde(default)]
    pub checks: Vec<CheckPoint>,
    /// Where the tables come from: written as a `provenance` element of the
    /// file header (merged: of the base file's header), which every table of
    /// the spec cites with a `provenanceRef`.
    #[serde(default)]
    pub provenance: Option<ProvenanceSpec>,
    /// Tolerance written on every generated check output.
    #[serde(default = "default_tol")]
    pub check_tolerance: f64,
    /// An output flagging the states inside a validated envelope, written after the
    /// calculations.
    #[serde(default)]
    pub envelope_flag: Option<EnvelopeFlagSpec>,
}

/// An output variable that is 1 inside a validated envelope and 0 outside
/// ([`crate::envelope::Envelope::contains`]: the alpha band `floor(alpha / band_deg)` of the
/// nearest flap setting, the lower one on a tie, is covered and beta lies in its measured
/// range; a non-finite input is outside), written as MathML `piecewise`
/// ([`envelope_mathml`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvelopeFlagSpec {
    /// `varID` of the flag.
    pub id: String,
    #[serde(default)]
    pub description: String,
    /// `varID`s of the flap setting, angle of attack and sideslip, deg (inputs or
    /// calculations of the spec).
    pub flap: String,
    pub alpha: String,
    pub beta: String,
    /// The envelope.
    pub envelope: crate::envelope::EnvelopeSpec,
}

/// An input variable.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputSpec {
    /// `varID`.
    pub id: String,
    /// `name` (default: the id).
    #[serde(default)]
    pub name: String,
    /// Units, DAVE-ML style (`deg`, `nd`, `rad_s`).
    #[serde(default = "default_units")]
    pub units: String,
    #[serde(default)]
    pub description: String,
    /// Lower limit (`minValue`, also the tables' `independentVarRef min`).
    #[serde(default)]
    pub min: Option<f64>,
    /// Upper limit (`maxValue`, also the tables' `independentVarRef max`).
    #[serde(default)]
    pub max: Option<f64>,
    /// Default value when a caller does not give one.
    #[serde(default)]
    pub initial: Option<f64>,
}

/// DAVE-ML `extrapolate`: where a table continues its end slopes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Extrapolate {
    /// Hold the end values (the default).
    #[default]
    Neither,
    /// Linear below the first breakpoint.
    Min,
    /// Linear above the last breakpoint.
    Max,
    /// Linear on both sides.
    Both,
}

impl Extrapolate {
    fn as_str(self) -> &'static str {
        match self {
            Extrapolate::Neither => "neither",
            Extrapolate::Min => "min",
            Extrapolate::Max => "max",
            Extrapolate::Both => "both",
        }
    }
}

/// A gridded table defining variable `id` from variables `args`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableSpec {
    /// `varID` of the variable the table defines.
    pub id: String,
    #[serde(default)]
    pub name: String,
    #[serde(default = "default_units")]
    pub units: String,
    #[serde(default)]
    pub description: String,
    /// `varID`s of the independent variables, one per axis.
    pub args: Vec<String>,
    /// Strictly increasing breakpoints per axis.
    pub breakpoints: Vec<Vec<f64>>,
    /// Values, row-major with the last axis fastest.
    pub values: Vec<f64>,
    /// Extrapolation on every axis.
    #[serde(default)]
    pub extrapolate: Extrapolate,
    /// Also flag the table's variable `isOutput`.
    #[serde(default)]
    pub is_output: bool,
    /// Lower and upper bounds of the table's values (a confidence band),
    /// written as DAVE-ML `uncertainty`.
    #[serde(default)]
    pub uncertainty: Option<UncertaintySpec>,
}

/// Bounds on a table's values, on the table's own grid, written as
/// `<uncertainty effect="absolute"><uniformPDF>` with two `<bounds>`, each a
/// `dataTable` (DAVE-ML 2.0 reference, section "uncertainty": absolute bounds
/// give the range of values and must bracket the nominal value). DAVE-ML
/// offers Gaussian (symmetric) and uniform distributions only: an asymmetric
/// confidence band is written as uniform absolute bounds, its level stated in
/// the table's description.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UncertaintySpec {
    /// Lower bounds, laid out as `values`.
    pub lower: Vec<f64>,
    /// Upper bounds, laid out as `values`.
    pub upper: Vec<f64>,
}

/// A DAVE-ML `provenance`: who made the data, when, and how.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProvenanceSpec {
    /// `provID` (letters, digits, '_'); merged into a file that already uses
    /// it, a numbered suffix is added.
    pub id: String,
    /// Author's name (default "aerodelta").
    #[serde(default)]
    pub author: String,
    /// Author's organisation (default "aerodelta").
    #[serde(default)]
    pub org: String,
    /// ISO date (default: today, UTC).
    #[serde(default)]
    pub date: Option<String>,
    /// How the data were made (method, data, settings).
    #[serde(default)]
    pub description: String,
}

/// A variable computed from others by an expression of the regressor language
/// ([`crate::regressor`]: `+ - * / ^`, `pos`, `neg`, `deadband`, `step`, `abs`,
/// `sqrt`, `sin`, `cos`, `exp`, `min`, `max`), written as a MathML-2
/// `calculation`. Names in the expression are `varID`s of inputs, other
/// calculations or tables.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalcSpec {
    pub id: String,
    #[serde(default)]
    pub name: String,
    #[serde(default = "default_units")]
    pub units: String,
    #[serde(default)]
    pub description: String,
    /// The expression, e.g. `deadband(da_deg, 2)` or `ct_left - ct_right`.
    pub expr: String,
    /// Also flag the variable `isOutput`.
    #[serde(default)]
    pub is_output: bool,
}

/// One product term $c \prod_j x_j$ of an output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Term {
    #[serde(default = "one")]
    pub coef: f64,
    /// `varID`s multiplied together (empty: the constant `coef`).
    #[serde(default)]
    pub factors: Vec<String>,
}

/// An output variable $y = \sum_k c_k \prod_j x_{kj}$.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    pub id: String,
    #[serde(default)]
    pub name: String,
    #[serde(default = "default_units")]
    pub units: String,
    #[serde(default)]
    pub description: String,
    pub terms: Vec<Term>,
}

/// A point where a check case is generated: input `varID` -> value (inputs not
/// given take their `initial`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckPoint {
    pub name: String,
    pub inputs: BTreeMap<String, f64>,
}

impl ModelSpec {
    /// Read a spec from JSON (the Python bindings pass it this way).
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the JSON problem (field, line, column).
    pub fn from_json(text: &str) -> Result<Self> {
        serde_json::from_str(text)
            .map_err(|e| AeroError::invalid("model spec (JSON)", e.to_string()))
    }

    pub(crate) fn validate(&self) -> Result<()> {
        let mut known: Vec<&str> = Vec::new();
        let place = |what: &str, id: &str| format!("model spec '{}', {what} '{id}'", self.name);
        let declare = |what: &str, id: &str, known: &mut Vec<&str>| -> Result<()> {
            if id.is_empty()
                || !id.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                || id.starts_with(|c: char| c.is_ascii_digit())
            {
                return Err(AeroError::invalid(
                    place(what, id),
                    "ids must be non-empty, letters, digits and '_', not starting with a digit",
                ));
            }
            if known.contains(&id) {
                return Err(AeroError::invalid(
                    place(what, id),
                    "is declared twice; ids must be unique",
                ));
            }
            Ok(())
        };
        for i in &self.inputs {
            declare("input", &i.id, &mut known)?;
            known.push(&i.id);
            if let (Some(lo), Some(hi)) = (i.min, i.max) {
                if lo > hi {
                    return Err(AeroError::invalid(
                        place("input", &i.id),
                        format!("min {lo} exceeds max {hi}"),
                    ));
                }
            }
        }
        for c in &self.calculations {
            declare("calculation", &c.id, &mut known)?;
            known.push(&c.id);
        }
        for t in &self.tables {
            declare("table", &t.id, &mut known)?;
            if t.args.len() != t.breakpoints.len() {
                return Err(AeroError::invalid(
                    place("table", &t.id),
                    format!(
                        "has {} args but {} breakpoint lists; give one per axis",
                        t.args.len(),
                        t.breakpoints.len()
                    ),
                ));
            }
            for a in &t.args {
                if !known.contains(&a.as_str()) {
                    return Err(AeroError::invalid(
                        place("table", &t.id),
                        format!("argument '{a}' is not an input or an earlier table"),
                    ));
                }
            }
            if let Some(k) = t.values.iter().position(|v| !v.is_finite()) {
                return Err(AeroError::invalid(
                    place("table", &t.id),
                    format!("value {k} is {}; values must be finite", t.values[k]),
                ));
            }
            let axes = t
                .args
                .iter()
                .zip(&t.breakpoints)
                .map(|(a, b)| crate::table::Axis::new(a.clone(), b.clone()))
                .collect::<Result<Vec<_>>>()
                .map_err(|e| e.context(place("table", &t.id)))?;
            crate::table::Table::new(axes, t.values.clone())
                .map_err(|e| e.context(place("table", &t.id)))?;
            if let Some(u) = &t.uncertainty {
                check_bounds(&t.values, u)
                    .map_err(|m| AeroError::invalid(place("table", &t.id), m))?;
            }
            known.push(&t.id);
        }
        for c in &self.calculations {
            let e = crate::regressor::Expr::parse(&c.expr)
                .map_err(|e| e.context(place("calculation", &c.id)))?;
            for col in e.columns() {
                if col == c.id || !known.contains(&col.as_str()) {
                    return Err(AeroError::invalid(
                        place("calculation", &c.id),
                        format!("'{col}' is not an input, another calculation or a table"),
                    ));
                }
            }
        }
        if let Some(f) = &self.envelope_flag {
            declare("envelope flag", &f.id, &mut known)?;
            for v in [&f.flap, &f.alpha, &f.beta] {
                if !known.contains(&v.as_str()) {
                    return Err(AeroError::invalid(
                        place("envelope flag", &f.id),
                        format!("'{v}' is not an input, a calculation or a table"),
                    ));
                }
            }
            crate::envelope::Envelope::new(f.envelope.clone())
                .map_err(|e| e.context(place("envelope flag", &f.id)))?;
            known.push(&f.id);
        }
        for o in &self.outputs {
            declare("output", &o.id, &mut known)?;
            for term in &o.terms {
                if !term.coef.is_finite() {
                    return Err(AeroError::invalid(
                        place("output", &o.id),
                        "term coefficients must be finite",
                    ));
                }
                for f in &term.factors {
                    if !known.contains(&f.as_str()) {
                        return Err(AeroError::invalid(
                            place("output", &o.id),
                            format!("factor '{f}' is not an input, a table or an earlier output"),
                        ));
                    }
                }
            }
            known.push(&o.id);
        }
        if let Some(p) = &self.provenance {
            declare("provenance", &p.id, &mut Vec::new())?;
        }
        if self.check_tolerance.is_nan() || self.check_tolerance < 0.0 {
            return Err(AeroError::invalid(
                place("check_tolerance", ""),
                "must be a non-negative number",
            ));
        }
        Ok(())
    }
}

/// Absolute bounds must be as many as the values, finite, and bracket them
/// (DAVE-ML 2.0: "the specified range of values must bracket the nominal
/// value").
fn check_bounds(values: &[f64], u: &UncertaintySpec) -> std::result::Result<(), String> {
    for (what, b) in [("lower", &u.lower), ("upper", &u.upper)] {
        if b.len() != values.len() {
            return Err(format!(
                "uncertainty has {} {what} bounds for {} values; give one per value",
                b.len(),
                values.len()
            ));
        }
        if let Some(k) = b.iter().position(|v| !v.is_finite()) {
            return Err(format!(
                "uncertainty {what} bound {k} is {}; bounds must be finite",
                b[k]
            ));
        }
    }
    let tol = |v: f64| 1e-12 * v.abs().max(1e-300);
    if let Some(k) = (0..values.len()).find(|&k| {
        u.lower[k] > values[k] + tol(values[k]) || u.upper[k] < values[k] - tol(values[k])
    }) {
        return Err(format!(
            "uncertainty bounds [{}, {}] at value {k} do not bracket the value {}",
            u.lower[k], u.upper[k], values[k]
        ));
    }
    Ok(())
}

/// The `provenance` element of `p` with `provID` `id`, indented for a file header.
pub(crate) fn provenance_xml(p: &ProvenanceSpec, id: &str) -> String {
    let mut x = String::new();
    let _ = writeln!(x, "    <provenance provID=\"{}\">", esc(id));
    let _ = writeln!(
        x,
        "      <author name=\"{}\" org=\"{}\"/>",
        esc(or(&p.author, "aerodelta")),
        esc(or(&p.org, "aerodelta"))
    );
    let date = p.date.clone().unwrap_or_else(today);
    let _ = writeln!(x, "      <creationDate date=\"{}\"/>", esc(&date));
    if !p.description.is_empty() {
        let _ = writeln!(
            x,
            "      <description>{}</description>",
            esc(&p.description)
        );
    }
    let _ = writeln!(x, "    </provenance>");
    x
}

fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            _ => o.push(c),
        }
    }
    o
}

/// Shortest text that reads back as the same `f64`.
fn num(x: f64) -> String {
    format!("{x:?}")
}

fn or<'a>(a: &'a str, b: &'a str) -> &'a str {
    if a.is_empty() {
        b
    } else {
        a
    }
}

/// Today's date (UTC) as `YYYY-MM-DD` (H. Hinnant's civil-from-days algorithm).
fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let z = (secs / 86_400) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

fn body(spec: &ModelSpec) -> String {
    let mut x = String::new();
    let _ = writeln!(x, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>");
    let _ = writeln!(x, "<!DOCTYPE DAVEfunc PUBLIC \"-//AIAA//DTD for Flight Dynamic Models - Functions 2.0//EN\"\n  \"http://www.daveml.org/DTDs/2p0/DAVEfunc.dtd\">");
    let _ = writeln!(x, "<DAVEfunc xmlns=\"http://daveml.org/2010/DAVEML\">");
    let _ = writeln!(x, "  <fileHeader name=\"{}\">", esc(&spec.name));
    let _ = writeln!(
        x,
        "    <author name=\"{}\" org=\"aerodelta\"/>",
        esc(or(&spec.author, "aerodelta"))
    );
    let date = spec.date.clone().unwrap_or_else(today);
    let _ = writeln!(x, "    <creationDate date=\"{}\"/>", esc(&date));
    let _ = writeln!(
        x,
        "    <fileVersion>written by aerodelta {}</fileVersion>",
        env!("CARGO_PKG_VERSION")
    );
    if !spec.description.is_empty() {
        let _ = writeln!(
            x,
            "    <description>{}</description>",
            esc(&spec.description)
        );
    }
    if let Some(p) = &spec.provenance {
        x.push_str(&provenance_xml(p, &p.id));
    }
    let _ = writeln!(x, "  </fileHeader>");
    let prov = spec.provenance.as_ref().map(|p| p.id.as_str());
    let parts = sections(spec, &[], "", prov);
    x.push_str(&parts.variables);
    x.push_str(&parts.breakpoints);
    x.push_str(&parts.functions);
    x
}

/// The three groups of DAVE-ML elements a spec adds, each in DTD order.
pub(crate) struct Sections {
    /// `variableDef`s: inputs (less `skip_inputs`), calculations, tables, outputs.
    pub variables: String,
    /// `breakpointDef`s.
    pub breakpoints: String,
    /// `function`s (one per table).
    pub functions: String,
}

/// Opens a `variableDef` (name defaulting to the ID) with its description, if any.
fn open_variable(x: &mut String, name: &str, id: &str, units: &str, description: &str) {
    let _ = writeln!(
        x,
        "  <variableDef name=\"{}\" varID=\"{}\" units=\"{}\">",
        esc(or(name, id)),
        esc(id),
        esc(units)
    );
    if !description.is_empty() {
        let _ = writeln!(x, "    <description>{}</description>", esc(description));
    }
}

/// The elements of `spec`, leaving out the `variableDef` of the inputs in
/// `skip_inputs` (declared by the model the elements are merged into), every
/// `bpID` and `gtID` led by `id_prefix`.
/// `prov`: the `provID` the tables cite, if any.
pub(crate) fn sections(
    spec: &ModelSpec,
    skip_inputs: &[&str],
    id_prefix: &str,
    prov: Option<&str>,
) -> Sections {
    let mut x = String::new();
    for i in spec
        .inputs
        .iter()
        .filter(|i| !skip_inputs.contains(&i.id.as_str()))
    {
        let mut attrs = format!(
            "name=\"{}\" varID=\"{}\" units=\"{}\"",
            esc(or(&i.name, &i.id)),
            esc(&i.id),
            esc(&i.units)
        );
        if let Some(v) = i.initial {
            let _ = write!(attrs, " initialValue=\"{}\"", num(v));
        }
        if let Some(v) = i.min {
            let _ = write!(attrs, " minValue=\"{}\"", num(v));
        }
        if let Some(v) = i.max {
            let _ = write!(attrs, " maxValue=\"{}\"", num(v));
        }
        let _ = writeln!(x, "  <variableDef {attrs}>");
        if !i.description.is_empty() {
            let _ = writeln!(x, "    <description>{}</description>", esc(&i.description));
        }
        let _ = writeln!(x, "    <isInput/>\n  </variableDef>");
    }
    for c in &spec.calculations {
        open_variable(&mut x, &c.name, &c.id, &c.units, &c.description);
        // Validated before writing: a parse error cannot happen here.
        let math = crate::regressor::Expr::parse(&c.expr)
            .map(|e| mathml_of(&e))
            .unwrap_or_else(|_| "<notanumber/>".to_string());
        let _ = writeln!(
            x,
            "    <calculation>\n      <math xmlns=\"http://www.w3.org/1998/Math/MathML\">\n        {math}\n      </math>\n    </calculation>"
        );
        if c.is_output {
            let _ = writeln!(x, "    <isOutput/>");
        }
        let _ = writeln!(x, "  </variableDef>");
    }
    if let Some(f) = &spec.envelope_flag {
        open_variable(&mut x, &f.id, &f.id, "nd", &f.description);
        let math = envelope_mathml(&f.envelope, &f.flap, &f.alpha, &f.beta);
        let _ = writeln!(
            x,
            "    <calculation>\n      <math xmlns=\"http://www.w3.org/1998/Math/MathML\">\n        {math}\n      </math>\n    </calculation>\n    <isOutput/>\n  </variableDef>"
        );
    }
    for t in &spec.tables {
        open_variable(&mut x, &t.name, &t.id, &t.units, &t.description);
        if t.is_output {
            let _ = writeln!(x, "    <isOutput/>");
        }
        let _ = writeln!(x, "  </variableDef>");
    }
    for o in &spec.outputs {
        open_variable(&mut x, &o.name, &o.id, &o.units, &o.description);
        let _ = writeln!(
            x,
            "    <calculation>\n      <math xmlns=\"http://www.w3.org/1998/Math/MathML\">"
        );
        let _ = writeln!(x, "{}", sum_of_products(&o.terms, "        "));
        let _ = writeln!(
            x,
            "      </math>\n    </calculation>\n    <isOutput/>\n  </variableDef>"
        );
    }

    let variables = std::mem::take(&mut x);
    // One breakpointDef per distinct (variable, breakpoints).
    let mut bps: Vec<(String, &str, &Vec<f64>)> = Vec::new();
    let mut table_bps: Vec<Vec<String>> = Vec::new();
    for t in &spec.tables {
        let mut ids = Vec::new();
        for (a, b) in t.args.iter().zip(&t.breakpoints) {
            let found = bps
                .iter()
                .find(|(_, va, vb)| *va == a.as_str() && *vb == b)
                .map(|e| e.0.clone());
            let id = found.unwrap_or_else(|| {
                let k = bps.iter().filter(|(_, va, _)| *va == a.as_str()).count();
                let id = if k == 0 {
                    format!("{id_prefix}{a}_bp")
                } else {
                    format!("{id_prefix}{a}_bp{}", k + 1)
                };
                bps.push((id.clone(), a.as_str(), b));
                id
            });
            ids.push(id);
        }
        table_bps.push(ids);
    }
    let units_of = |id: &str| -> String {
        spec.inputs
            .iter()
            .find(|i| i.id == id)
            .map(|i| i.units.clone())
            .or_else(|| {
                spec.tables
                    .iter()
                    .find(|t| t.id == id)
                    .map(|t| t.units.clone())
            })
            .unwrap_or_default()
    };
    for (id, var, vals) in &bps {
        let _ = writeln!(
            x,
            "  <breakpointDef name=\"{}\" bpID=\"{}\" units=\"{}\">",
            esc(id),
            esc(id),
            esc(&units_of(var))
        );
        let v: Vec<String> = vals.iter().map(|&b| num(b)).collect();
        let _ = writeln!(
            x,
            "    <bpVals>{}</bpVals>\n  </breakpointDef>",
            v.join(", ")
        );
    }
    let breakpoints = std::mem::take(&mut x);
    for (t, ids) in spec.tables.iter().zip(&table_bps) {
        let _ = writeln!(x, "  <function name=\"{}\">", esc(or(&t.name, &t.id)));
        for a in &t.args {
            let mut attrs = format!("varID=\"{}\"", esc(a));
            if let Some(i) = spec.inputs.iter().find(|i| &i.id == a) {
                if let Some(v) = i.min {
                    let _ = write!(attrs, " min=\"{}\"", num(v));
                }
                if let Some(v) = i.max {
                    let _ = write!(attrs, " max=\"{}\"", num(v));
                }
            }
            let _ = writeln!(
                x,
                "    <independentVarRef {attrs} extrapolate=\"{}\"/>",
                t.extrapolate.as_str()
            );
        }
        let _ = writeln!(x, "    <dependentVarRef varID=\"{}\"/>", esc(&t.id));
        let _ = writeln!(x, "    <functionDefn name=\"{}_fn\">", esc(&t.id));
        let _ = writeln!(
            x,
            "      <griddedTableDef name=\"{0}_table\" gtID=\"{1}{0}_table\">",
            esc(&t.id),
            esc(id_prefix)
        );
        if let Some(p) = prov {
            let _ = writeln!(x, "        <provenanceRef provID=\"{}\"/>", esc(p));
        }
        let _ = writeln!(x, "        <breakpointRefs>");
        for id in ids {
            let _ = writeln!(x, "          <bpRef bpID=\"{}\"/>", esc(id));
        }
        let _ = writeln!(x, "        </breakpointRefs>");
        let row = t.breakpoints.last().map_or(1, |b| b.len().max(1));
        let rows = |x: &mut String, values: &[f64], indent: &str| {
            for chunk in values.chunks(row) {
                let v: Vec<String> = chunk.iter().map(|&b| num(b)).collect();
                let _ = writeln!(x, "{indent}{}", v.join(", "));
            }
        };
        if let Some(u) = &t.uncertainty {
            let _ = writeln!(
                x,
                "        <uncertainty effect=\"absolute\">\n          <uniformPDF>"
            );
            for (what, b) in [("lower", &u.lower), ("upper", &u.upper)] {
                let _ = writeln!(
                    x,
                    "            <bounds> <!-- {what} -->\n              <dataTable>"
                );
                rows(&mut x, b, "                ");
                let _ = writeln!(x, "              </dataTable>\n            </bounds>");
            }
            let _ = writeln!(x, "          </uniformPDF>\n        </uncertainty>");
        }
        let _ = writeln!(
            x,
            "        <dataTable> <!-- last breakpoint varies fastest -->"
        );
        rows(&mut x, &t.values, "          ");
        let _ = writeln!(
            x,
            "        </dataTable>\n      </griddedTableDef>\n    </functionDefn>\n  </function>"
        );
    }
    Sections {
        variables,
        breakpoints,
        functions: x,
    }
}

/// MathML-2 content markup of the validated-envelope flag ([`EnvelopeFlagSpec`]): 1 inside,
/// 0 outside, by the rule of [`crate::envelope::Envelope::contains`]. One `piece` per flap
/// setting, for the flaps between the midpoints to its neighbours (`mid_(k-1) < flap <=
/// mid_k`: a tie goes to the lower setting), holding one `piece` per covered band `b`:
/// `b <= alpha / band_deg < b + 1` (that is `floor(alpha / band_deg) = b`: `b` and `b + 1`
/// are exact) and `beta_min <= beta <= beta_max`. Every comparison with NaN is false and each
/// flap region asks `|flap| <= f64::MAX`, so a non-finite input falls through to the
/// `otherwise` 0, as in the engine.
pub fn envelope_mathml(
    env: &crate::envelope::EnvelopeSpec,
    flap: &str,
    alpha: &str,
    beta: &str,
) -> String {
    let ap = |op: &str, args: &[String]| format!("<apply><{op}/>{}</apply>", args.concat());
    let ci = |v: &str| format!("<ci>{}</ci>", esc(v));
    let cn = |v: f64| format!("<cn>{}</cn>", num(v));
    let ratio = ap("divide", &[ci(alpha), cn(env.band_deg)]);
    let otherwise = "<otherwise><cn>0</cn></otherwise>";
    let f = &env.flaps_deg;
    let mut flaps = String::new();
    for (k, bands) in env.bands.iter().enumerate() {
        let mut inside = String::new();
        for b in bands {
            let lo = b.band as f64;
            let cond = ap(
                "and",
                &[
                    ap("geq", &[ratio.clone(), cn(lo)]),
                    ap("lt", &[ratio.clone(), cn(lo + 1.0)]),
                    ap("geq", &[ci(beta), cn(b.beta_min_deg)]),
                    ap("leq", &[ci(beta), cn(b.beta_max_deg)]),
                ],
            );
            let _ = write!(inside, "<piece><cn>1</cn>{cond}</piece>");
        }
        let value = format!("<piecewise>{inside}{otherwise}</piecewise>");
        // a finite flap (an infinite one would fall in the first or last region)
        let mut region = vec![ap("leq", &[ap("abs", &[ci(flap)]), cn(f64::MAX)])];
        if k > 0 {
            region.push(ap("gt", &[ci(flap), cn(0.5 * (f[k - 1] + f[k]))]));
        }
        if k + 1 < f.len() {
            region.push(ap("leq", &[ci(flap), cn(0.5 * (f[k] + f[k + 1]))]));
        }
        let cond = if region.len() == 1 {
            region.remove(0)
        } else {
            ap("and", &region)
        };
        let _ = write!(flaps, "<piece>{value}{cond}</piece>");
    }
    format!("<piecewise>{flaps}{otherwise}</piecewise>")
}

/// MathML-2 content markup of a regressor expression ([`crate::regressor`]):
/// `deadband(x, k)` becomes `max(x - k, 0) + min(x + k, 0)` (thesis Eq.
/// 3.15-3.16), `pos`/`neg` a `max`/`min` with 0, `step(x)` a `piecewise`
/// (1 where x > 0, else 0).
pub fn mathml_of(e: &crate::regressor::Expr) -> String {
    use crate::regressor::{BinOp, Expr, Func};
    let ap = |op: &str, args: &[String]| format!("<apply><{op}/>{}</apply>", args.concat());
    match e {
        Expr::Const(c) => format!("<cn>{}</cn>", num(*c)),
        Expr::Column(n) => format!("<ci>{}</ci>", esc(n)),
        Expr::Neg(a) => ap("minus", &[mathml_of(a)]),
        Expr::Bin(op, a, b) => {
            let tag = match op {
                BinOp::Add => "plus",
                BinOp::Sub => "minus",
                BinOp::Mul => "times",
                BinOp::Div => "divide",
                BinOp::Pow => "power",
            };
            ap(tag, &[mathml_of(a), mathml_of(b)])
        }
        Expr::Call(f, args) => {
            let a: Vec<String> = args.iter().map(mathml_of).collect();
            let first = a.first().cloned().unwrap_or_else(|| "<notanumber/>".into());
            let second = a.get(1).cloned().unwrap_or_else(|| "<cn>0</cn>".into());
            let zero = "<cn>0</cn>".to_string();
            match f {
                Func::Pos => ap("max", &[first, zero]),
                Func::Neg => ap("min", &[first, zero]),
                Func::Deadband => ap(
                    "plus",
                    &[
                        ap("max", &[ap("minus", &[first.clone(), second.clone()]), zero.clone()]),
                        ap("min", &[ap("plus", &[first, second]), zero]),
                    ],
                ),
                Func::Step => format!(
                    "<piecewise><piece><cn>1</cn>{}</piece><otherwise><cn>0</cn></otherwise></piecewise>",
                    ap("gt", &[first, zero])
                ),
                Func::Abs => ap("abs", &[first]),
                Func::Sqrt => ap("root", &[first]),
                Func::Sin => ap("sin", &[first]),
                Func::Cos => ap("cos", &[first]),
                Func::Exp => ap("exp", &[first]),
                Func::Min => ap("min", &[first, second]),
                Func::Max => ap("max", &[first, second]),
            }
        }
    }
}

fn sum_of_products(terms: &[Term], ind: &str) -> String {
    let term = |t: &Term, ind: &str| -> String {
        let mut parts: Vec<String> = Vec::new();
        if t.coef != 1.0 || t.factors.is_empty() {
            parts.push(format!("<cn>{}</cn>", num(t.coef)));
        }
        parts.extend(t.factors.iter().map(|f| format!("<ci>{}</ci>", esc(f))));
        if parts.len() == 1 {
            format!("{ind}{}", parts[0])
        } else {
            format!("{ind}<apply><times/>{}</apply>", parts.join(""))
        }
    };
    match terms {
        [] => format!("{ind}<cn>0</cn>"),
        [one] => term(one, ind),
        many => {
            let inner: Vec<String> = many.iter().map(|t| term(t, &format!("{ind}  "))).collect();
            format!(
                "{ind}<apply>\n{ind}  <plus/>\n{}\n{ind}</apply>",
                inner.join("\n")
            )
        }
    }
}

/// The DAVE-ML text of `spec`, with check cases generated by evaluating it.
///
/// # Errors
/// [`AeroError::InvalidInput`] naming the spec element at fault (duplicate or
/// unknown ids, table shape, non-increasing breakpoints, a check point missing
/// an input).
pub fn to_xml(spec: &ModelSpec) -> Result<String> {
    spec.validate()?;
    let mut x = body(spec);
    if !spec.checks.is_empty() {
        let model = DaveModel::from_str(&format!("{x}</DAVEfunc>\n"), &spec.name)?;
        let inputs: Vec<&str> = spec.inputs.iter().map(|i| i.id.as_str()).collect();
        x.push_str(&check_data(
            &model,
            &inputs,
            &spec.checks,
            spec.check_tolerance,
            &spec.name,
        )?);
    }
    x.push_str("</DAVEfunc>\n");
    Ok(x)
}

/// The `checkData` element: one static shot per check point, its expected
/// values computed by evaluating `model` (inputs listed in the order of
/// `inputs`, every variable as an internal value, outputs with `tolerance`).
pub(crate) fn check_data(
    model: &DaveModel,
    inputs: &[&str],
    checks: &[CheckPoint],
    tolerance: f64,
    spec_name: &str,
) -> Result<String> {
    let mut x = String::new();
    let vars = model.variables();
    let _ = writeln!(x, "  <checkData>");
    for cp in checks {
        let given: Vec<(&str, f64)> = cp.inputs.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let values = model.evaluate(&given).map_err(|e| {
            e.context(format!(
                "model spec '{spec_name}', check point '{}'",
                cp.name
            ))
        })?;
        let _ = writeln!(
            x,
            "    <staticShot name=\"{}\">\n      <checkInputs>",
            esc(&cp.name)
        );
        for id in inputs {
            let Some(k) = model.index_of(id) else {
                continue;
            };
            let _ = writeln!(
                x,
                "        <signal> <signalName>{}</signalName> <signalUnits>{}</signalUnits> <signalValue>{}</signalValue> </signal>",
                esc(&vars[k].name), esc(&vars[k].units), num(cp.inputs.get(*id).copied().unwrap_or(values[k]))
            );
        }
        let _ = writeln!(x, "      </checkInputs>\n      <internalValues>");
        for (k, v) in vars.iter().enumerate() {
            let _ = writeln!(
                x,
                "        <signal> <varID>{}</varID> <signalValue>{}</signalValue> </signal>",
                esc(&v.id),
                num(values[k])
            );
        }
        let _ = writeln!(x, "      </internalValues>\n      <checkOutputs>");
        for (k, v) in vars.iter().enumerate().filter(|(_, v)| v.is_output) {
            let _ = writeln!(
                x,
                "        <signal> <signalName>{}</signalName> <signalUnits>{}</signalUnits> <signalValue>{}</signalValue> <tol>{}</tol> </signal>",
                esc(&v.name), esc(&v.units), num(values[k]), num(tolerance)
            );
        }
        let _ = writeln!(x, "      </checkOutputs>\n    </staticShot>");
    }
    let _ = writeln!(x, "  </checkData>");
    Ok(x)
}

/// Write `spec` to `path` atomically (`path.tmp-<pid>`, then rename) and return
/// the model read back from the written text, its checks verified.
///
/// # Errors
/// As [`to_xml`]; [`AeroError::Io`] when the file cannot be written;
/// [`AeroError::InvalidInput`] if the written file fails its own checks.
pub fn write_model(spec: &ModelSpec, path: &Path) -> Result<DaveModel> {
    let text = to_xml(spec)?;
    let model = DaveModel::from_str(&text, &path.display().to_string())?;
    if let Some(bad) = model.run_checks().into_iter().find(|r| !r.pass) {
        return Err(AeroError::invalid(
            format!(
                "model spec '{}', shot '{}', variable '{}'",
                spec.name, bad.shot, bad.var_id
            ),
            format!(
                "the written model gives {} where its check expects {}",
                bad.actual, bad.expected
            ),
        ));
    }
    let file_name = path.file_name().ok_or_else(|| {
        AeroError::invalid(format!("output path '{}'", path.display()), "names no file")
    })?;
    let tmp = path.with_file_name(format!(
        "{}.tmp-{}",
        file_name.to_string_lossy(),
        std::process::id()
    ));
    std::fs::write(&tmp, text.as_bytes()).map_err(|e| AeroError::io(&tmp, e))?;
    if let Err(e) = std::fs::rename(&tmp, path) {
        let _ = std::fs::remove_file(&tmp);
        return Err(AeroError::io(path, e));
    }
    Ok(model)
}
