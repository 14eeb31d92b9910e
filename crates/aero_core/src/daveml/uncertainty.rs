//! DAVE-ML `uncertainty` and `provenance` (ANSI/AIAA S-119-2011; DAVE-ML 2.0
//! reference manual, sections "uncertainty", "normalPDF", "uniformPDF",
//! "bounds", "provenance").
//!
//! An `uncertainty` sits in a `variableDef` or a `griddedTableDef`:
//! `effect` is `additive`, `multiplicative`, `percentage` or `absolute`; the
//! distribution is a `normalPDF` (`numSigmas`, one `bounds`) or a
//! `uniformPDF` (one symmetric or two asymmetric `bounds`); a bound is a
//! number, a `dataTable` shaped as the nominal table, or a `variableRef`.
//! Checked here, each failure naming the element and its line:
//! - the element structure above, `numSigmas` a positive number;
//! - a `dataTable` bound holds one value per value of the nominal table;
//! - absolute uniform bounds are two, and bracket the nominal value (table
//!   values, or a variable's `initialValue`): "if absolute, the specified
//!   range of values must bracket the nominal value";
//! - additive asymmetric bounds bracket zero (`-y`, `+x`); a single
//!   symmetric bound (additive, multiplicative, percentage, normal) is not
//!   negative;
//! - every `provenanceRef` names the `provID` of a `provenance` element.

use std::collections::HashSet;

use super::model::{Def, Variable};
use super::{child, elements, parse_numbers, Node, Source};
use crate::error::Result;
use crate::text::shown;

/// How the bounds act on the nominal value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Effect {
    /// Added to the nominal value.
    Additive,
    /// Multiplying the nominal value.
    Multiplicative,
    /// Percent of the nominal value.
    Percentage,
    /// The values themselves.
    Absolute,
}

impl Effect {
    /// The attribute value.
    pub fn as_str(self) -> &'static str {
        match self {
            Effect::Additive => "additive",
            Effect::Multiplicative => "multiplicative",
            Effect::Percentage => "percentage",
            Effect::Absolute => "absolute",
        }
    }
}

/// The distribution of the uncertain value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distribution {
    /// Gaussian; the bound is `num_sigmas` standard deviations.
    Normal {
        /// Standard deviations the bound stands for.
        num_sigmas: f64,
    },
    /// Uniform between the bounds.
    Uniform,
}

/// One `bounds` element.
#[derive(Debug, Clone, PartialEq)]
pub enum Bound {
    /// A number.
    Value(f64),
    /// A table of bounds shaped as the nominal table.
    Table(Vec<f64>),
    /// The value of another variable (`variableRef`).
    Variable(String),
}

/// An `uncertainty` element, attached to the variable it describes.
#[derive(Debug, Clone, PartialEq)]
pub struct Uncertainty {
    /// `varID` of the uncertain variable (a table's: the variable its function defines).
    pub var_id: String,
    pub effect: Effect,
    pub distribution: Distribution,
    /// One bound (symmetric) or two (lower, upper).
    pub bounds: Vec<Bound>,
    /// Line of the `uncertainty` element.
    pub line: usize,
}

/// The `uncertainty` child of `node` (a `variableDef` or `griddedTableDef`)
/// for variable `var`, checked against its nominal value: the values of
/// `def` when it is a table, else the variable's `initialValue`.
pub(crate) fn parse(
    src: &Source,
    node: Node<'_>,
    var: &Variable,
    def: &Def,
    known: &dyn Fn(&str) -> bool,
) -> Result<Option<Uncertainty>> {
    let Some(u) = child(node, "uncertainty") else {
        return Ok(None);
    };
    let effect =
        match u.attribute("effect").map(str::trim) {
            Some("additive") => Effect::Additive,
            Some("multiplicative") => Effect::Multiplicative,
            Some("percentage") => Effect::Percentage,
            Some("absolute") => Effect::Absolute,
            Some(other) => {
                return Err(src.err(
                    u,
                    format!(
                        "effect '{}' is not one of additive, multiplicative, percentage, absolute",
                        shown(other)
                    ),
                ))
            }
            None => return Err(src.err(
                u,
                "has no effect attribute; give additive, multiplicative, percentage or absolute",
            )),
        };
    let pdf = elements(u)
        .next()
        .ok_or_else(|| src.err(u, "is empty; give a <normalPDF> or a <uniformPDF>"))?;
    let distribution = match pdf.tag_name() {
        "normalPDF" => {
            let s = pdf.attribute("numSigmas").ok_or_else(|| {
                src.err(
                    pdf,
                    "has no numSigmas attribute; give the sigmas the bound stands for",
                )
            })?;
            let num_sigmas: f64 = s.trim().parse().unwrap_or(f64::NAN);
            if !(num_sigmas.is_finite() && num_sigmas > 0.0) {
                return Err(src.err(
                    pdf,
                    format!("numSigmas '{}' is not a positive number", shown(s)),
                ));
            }
            Distribution::Normal { num_sigmas }
        }
        "uniformPDF" => Distribution::Uniform,
        other => {
            return Err(src.err(
                pdf,
                format!(
                    "<{}> is not a distribution; give <normalPDF> or <uniformPDF>",
                    shown(other)
                ),
            ))
        }
    };
    let nominal: Option<Vec<f64>> = match def {
        Def::Table { table, .. } => Some(table.values().to_vec()),
        _ => var.initial_value.map(|v| vec![v]),
    };
    let is_table = matches!(def, Def::Table { .. });
    let mut bounds = Vec::new();
    for b in elements(pdf).filter(|n| n.tag_name() == "bounds") {
        bounds.push(bound(src, b, is_table, nominal.as_deref(), known)?);
    }
    let want = match distribution {
        Distribution::Normal { .. } => 1..=1,
        Distribution::Uniform => 1..=2,
    };
    if !want.contains(&bounds.len()) {
        return Err(src.err(
            pdf,
            format!(
                "has {} <bounds>; give {}",
                bounds.len(),
                if matches!(distribution, Distribution::Normal { .. }) {
                    "one (the bound at numSigmas)"
                } else {
                    "one (symmetric) or two (lower, upper)"
                }
            ),
        ));
    }
    // Element-wise values of a bound, the one number repeated.
    let n = nominal.as_ref().map_or(1, Vec::len);
    let values = |b: &Bound| -> Option<Vec<f64>> {
        match b {
            Bound::Value(v) => Some(vec![*v; n]),
            Bound::Table(t) => Some(t.clone()),
            Bound::Variable(_) => None,
        }
    };
    match (effect, bounds.as_slice()) {
        (Effect::Absolute, [_]) => {
            return Err(src.err(
                pdf,
                "absolute uncertainty needs two bounds (lower, upper) bracketing the nominal value",
            ))
        }
        (Effect::Absolute, [lo, hi]) => {
            if let (Some(lo), Some(hi), Some(nom)) = (values(lo), values(hi), nominal.as_ref()) {
                if let Some(k) = (0..nom.len()).find(|&k| !(lo[k] <= nom[k] && nom[k] <= hi[k])) {
                    return Err(src.err(
                        pdf,
                        format!(
                            "absolute bounds [{}, {}] do not bracket the nominal value {} (value {} of '{}'); the lower bound comes first",
                            lo[k], hi[k], nom[k], k + 1, shown(&var.id)
                        ),
                    ));
                }
            }
        }
        (_, [lo, hi]) => {
            if let (Some(lo), Some(hi)) = (values(lo), values(hi)) {
                let n = lo.len().min(hi.len());
                let unbracketed = (0..n).find(|&k| !(lo[k] <= 0.0 && 0.0 <= hi[k]));
                if let (Effect::Additive, Some(k)) = (effect, unbracketed) {
                    return Err(src.err(
                        pdf,
                        format!(
                            "additive bounds [{}, {}] (value {}) do not bracket 0; give the lower (-y) then the upper (+x) deviation",
                            lo[k], hi[k], k + 1
                        ),
                    ));
                }
                if let Some(k) = (0..n).find(|&k| lo[k] > hi[k]) {
                    return Err(src.err(
                        pdf,
                        format!("bounds [{}, {}] (value {}) are in the wrong order; give the lower first", lo[k], hi[k], k + 1),
                    ));
                }
            }
        }
        (_, [one]) => {
            if let Some(v) = values(one) {
                if let Some(k) = v.iter().position(|x| *x < 0.0) {
                    return Err(src.err(
                        pdf,
                        format!(
                            "a symmetric bound (±x) must not be negative: value {} is {}",
                            k + 1,
                            v[k]
                        ),
                    ));
                }
            }
        }
        _ => {}
    }
    Ok(Some(Uncertainty {
        var_id: var.id.clone(),
        effect,
        distribution,
        bounds,
        line: src.line(u),
    }))
}

/// One `bounds` element: a number, a `dataTable` with one value per nominal
/// value (only for a table), or a `variableRef`.
fn bound(
    src: &Source,
    b: Node<'_>,
    is_table: bool,
    nominal: Option<&[f64]>,
    known: &dyn Fn(&str) -> bool,
) -> Result<Bound> {
    let out = if let Some(t) = child(b, "dataTable") {
        let v = parse_numbers(src, t)?;
        if !is_table {
            return Err(src.err(
                b,
                "holds a <dataTable> but the uncertain variable is not defined by a gridded table; give a number",
            ));
        }
        let n = nominal.map_or(0, <[f64]>::len);
        if v.len() != n {
            return Err(src.err(
                t,
                format!(
                    "holds {} bounds for a table of {n} values; give one per table value",
                    v.len()
                ),
            ));
        }
        Bound::Table(v)
    } else if let Some(r) = child(b, "variableRef") {
        let id = r.attribute("varID").unwrap_or("").trim();
        if !known(id) {
            return Err(src.err(
                r,
                format!("varID '{}' is not a variable of the file", shown(id)),
            ));
        }
        Bound::Variable(id.to_string())
    } else if let Some(other) = elements(b).next() {
        return Err(src.err(
            other,
            "is not supported in <bounds>; give a number, a <dataTable> or a <variableRef>",
        ));
    } else {
        let v = parse_numbers(src, b)?;
        match v.as_slice() {
            [x] => Bound::Value(*x),
            _ => return Err(src.err(b, format!("holds {} numbers; give one", v.len()))),
        }
    };
    let finite = match &out {
        Bound::Value(x) => x.is_finite(),
        Bound::Table(t) => t.iter().all(|x| x.is_finite()),
        Bound::Variable(_) => true,
    };
    if !finite {
        return Err(src.err(b, "holds a value that is not finite"));
    }
    Ok(out)
}

/// Every `provenanceRef` of the document names a `provenance provID`.
pub(crate) fn check_provenance_refs(src: &Source, root: Node<'_>) -> Result<()> {
    let ids: HashSet<&str> = root
        .descendants()
        .filter(|n| n.tag_name() == "provenance")
        .filter_map(|n| n.attribute("provID"))
        .map(str::trim)
        .collect();
    for r in root
        .descendants()
        .filter(|n| n.tag_name() == "provenanceRef")
    {
        let id = r.attribute("provID").unwrap_or("").trim();
        if !ids.contains(id) {
            return Err(src.err(
                r,
                format!(
                    "provID '{}' names no <provenance provID=\"...\"> in the file",
                    shown(id)
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::{merge_xml, to_xml, DaveModel, ModelSpec};
    use super::*;

    /// DAVE-ML 2.0 reference manual, uncertainty examples 1 and 3 and the
    /// public `Examples/uncertain_1D_table.dml` (typed in).
    const REFERENCE: &str = r#"<?xml version="1.0"?>
<DAVEfunc xmlns="http://daveml.org/2010/DAVEML">
  <fileHeader><author name="" org=""/><creationDate date=""/></fileHeader>
  <variableDef name="angleOfAttack" varID="Alpha_deg" units="deg"><isStdAIAA/></variableDef>
  <variableDef name="CD zero" varID="CDo" units="nd" initialValue="0.005">
    <isOutput/>
    <uncertainty effect="absolute">
      <uniformPDF><bounds>0.001</bounds><bounds>0.010</bounds></uniformPDF>
    </uncertainty>
  </variableDef>
  <variableDef name="Cm_u" varID="Cm_u" units="nd">
    <isOutput/>
    <uncertainty effect="additive">
      <uniformPDF><bounds>-0.50</bounds><bounds>0.00</bounds></uniformPDF>
    </uncertainty>
  </variableDef>
  <variableDef name="Cm_t" varID="Cm_t" units="nd"><isOutput/></variableDef>
  <breakpointDef bpID="ALP"><bpVals>0, 5, 10, 15, 20, 25, 30, 35</bpVals></breakpointDef>
  <function name="Nominal Cm">
    <independentVarRef varID="Alpha_deg"/>
    <dependentVarRef varID="Cm_u"/>
    <functionDefn><griddedTableDef>
      <breakpointRefs><bpRef bpID="ALP"/></breakpointRefs>
      <dataTable>5.2, 4.3, 3.1, 1.8, 0.3, 0.1, 0.0, -0.1</dataTable>
    </griddedTableDef></functionDefn>
  </function>
  <function name="Uncertain Cm">
    <independentVarRef varID="Alpha_deg"/>
    <dependentVarRef varID="Cm_t"/>
    <functionDefn><griddedTableDef gtID="example_table">
      <breakpointRefs><bpRef bpID="ALP"/></breakpointRefs>
      <uncertainty effect="multiplicative">
        <normalPDF numSigmas="3"><bounds><dataTable>
          0.10, 0.08, 0.06, 0.05, 0.05, 0.06, 0.07, 0.12
        </dataTable></bounds></normalPDF>
      </uncertainty>
      <dataTable>5.2, 4.3, 3.1, 1.8, 0.3, 0.1, 0.0, -0.1</dataTable>
    </griddedTableDef></functionDefn>
  </function>
</DAVEfunc>
"#;

    #[test]
    fn reference_manual_examples_read_back() {
        let m = DaveModel::from_str(REFERENCE, "ref.dml").expect("parses");
        let u = m.uncertainties();
        assert_eq!(u.len(), 3);
        assert_eq!(u[0].var_id, "CDo");
        assert_eq!(u[0].effect, Effect::Absolute);
        assert_eq!(u[0].distribution, Distribution::Uniform);
        assert_eq!(u[0].bounds, vec![Bound::Value(0.001), Bound::Value(0.010)]);
        assert_eq!(u[1].var_id, "Cm_u");
        assert_eq!(u[1].effect, Effect::Additive);
        assert_eq!(u[1].bounds, vec![Bound::Value(-0.5), Bound::Value(0.0)]);
        assert_eq!(u[2].var_id, "Cm_t");
        assert_eq!(u[2].effect, Effect::Multiplicative);
        assert_eq!(u[2].distribution, Distribution::Normal { num_sigmas: 3.0 });
        assert_eq!(
            u[2].bounds,
            vec![Bound::Table(vec![
                0.10, 0.08, 0.06, 0.05, 0.05, 0.06, 0.07, 0.12
            ])]
        );
        // the nominal model is unchanged by its uncertainty
        let v = m.evaluate(&[("Alpha_deg", 12.5)]).expect("evaluates");
        assert!((v[m.index_of("Cm_t").expect("Cm_t")] - 2.45).abs() < 1e-12);
    }

    fn refused(from: &str, to: &str) -> String {
        assert!(REFERENCE.contains(from), "fixture holds {from}");
        DaveModel::from_str(&REFERENCE.replacen(from, to, 1), "bad.dml")
            .expect_err("refused")
            .to_string()
    }

    #[test]
    fn malformed_uncertainty_is_named_with_its_line() {
        let e = refused("<bounds>0.001</bounds>", "<bounds>0.006</bounds>");
        assert!(
            e.starts_with("bad.dml:8") && e.contains("do not bracket the nominal value 0.005"),
            "{e}"
        );
        let e = refused(
            "<bounds>0.001</bounds><bounds>0.010</bounds>",
            "<bounds>0.001</bounds>",
        );
        assert!(e.contains("absolute uncertainty needs two bounds"), "{e}");
        let e = refused("effect=\"additive\"", "effect=\"relative\"");
        assert!(e.contains("effect 'relative' is not one of"), "{e}");
        let e = refused("<bounds>-0.50</bounds>", "<bounds>0.20</bounds>");
        assert!(e.contains("do not bracket 0"), "{e}");
        let e = refused("0.07, 0.12\n", "0.07\n");
        assert!(e.contains("holds 7 bounds for a table of 8 values"), "{e}");
        let e = refused("numSigmas=\"3\"", "numSigmas=\"-1\"");
        assert!(e.contains("numSigmas '-1' is not a positive number"), "{e}");
        let e = refused(
            "<bounds>0.010</bounds>",
            "<bounds>0.010</bounds><bounds>0.02</bounds>",
        );
        assert!(e.contains("has 3 <bounds>"), "{e}");
        let e = refused(
            "<bounds>0.010</bounds>",
            "<bounds><variableRef varID=\"nope\"/></bounds>",
        );
        assert!(e.contains("varID 'nope' is not a variable"), "{e}");
        let e = refused("<fileHeader>", "<fileHeader><provenanceRef provID=\"p1\"/>");
        assert!(e.contains("provID 'p1' names no <provenance"), "{e}");
    }

    fn banded(lower: &[f64], upper: &[f64]) -> ModelSpec {
        ModelSpec::from_json(&format!(
            r#"{{"name": "band", "inputs": [{{"id": "alpha_deg", "units": "deg", "initial": 0}}],
               "tables": [{{"id": "dCl_p", "args": ["alpha_deg"], "breakpoints": [[10, 20, 30]],
                           "values": [0.0, -0.1, -0.2], "is_output": true,
                           "uncertainty": {{"lower": {lower:?}, "upper": {upper:?}}}}}],
               "outputs": [],
               "provenance": {{"id": "aerodelta_fit", "date": "2026-11-26",
                               "description": "equation-error fit & bootstrap"}}}}"#
        ))
        .expect("spec")
    }

    #[test]
    fn written_bands_read_back_as_absolute_uniform_bounds() {
        let xml = to_xml(&banded(&[-0.01, -0.15, -0.3], &[0.01, -0.05, -0.2])).expect("xml");
        // DTD order in the table: provenanceRef, breakpointRefs, uncertainty, dataTable
        let at = |t: &str| xml.find(t).expect(t);
        assert!(at("<provenanceRef") < at("<breakpointRefs"));
        assert!(at("</breakpointRefs>") < at("<uncertainty"));
        assert!(at("</uncertainty>") < at("<dataTable> <!--"));
        assert!(at("<provenance provID=\"aerodelta_fit\">") < at("</fileHeader>"));
        assert!(xml.contains("equation-error fit &amp; bootstrap"));
        let m = DaveModel::from_str(&xml, "band.dml").expect("parses");
        let u = m.uncertainties();
        assert_eq!(u.len(), 1);
        assert_eq!(u[0].var_id, "dCl_p");
        assert_eq!(
            (u[0].effect, u[0].distribution),
            (Effect::Absolute, Distribution::Uniform)
        );
        assert_eq!(
            u[0].bounds,
            vec![
                Bound::Table(vec![-0.01, -0.15, -0.3]),
                Bound::Table(vec![0.01, -0.05, -0.2])
            ]
        );
        // a band that does not hold its value, or of the wrong length, is refused
        let e = to_xml(&banded(&[-0.01, -0.05, -0.3], &[0.01, 0.0, -0.2]))
            .expect_err("refused")
            .to_string();
        assert!(
            e.contains("'dCl_p'") && e.contains("do not bracket the value -0.1"),
            "{e}"
        );
        let e = to_xml(&banded(&[-0.01, -0.15], &[0.01, -0.05]))
            .expect_err("refused")
            .to_string();
        assert!(e.contains("2 lower bounds for 3 values"), "{e}");
    }

    #[test]
    fn merged_provenance_joins_the_base_header_with_a_unique_id() {
        let base = to_xml(&banded(&[-0.01, -0.15, -0.3], &[0.01, -0.05, -0.2])).expect("base");
        let add = ModelSpec::from_json(
            r#"{"name": "more", "inputs": [{"id": "alpha_deg", "units": "deg"}],
                "tables": [{"id": "dCn_r", "args": ["alpha_deg"], "breakpoints": [[10, 30]],
                            "values": [0.0, 0.05], "is_output": true,
                            "uncertainty": {"lower": [0.0, 0.01], "upper": [0.0, 0.09]}}],
                "outputs": [], "checks": [{"name": "c", "inputs": {"alpha_deg": 25}}],
                "provenance": {"id": "aerodelta_fit", "date": "2026-11-27", "description": "second"}}"#,
        )
        .expect("spec");
        let xml = merge_xml(&base, "base.dml", &add).expect("merges");
        let header = &xml[..xml.find("</fileHeader>").expect("header")];
        assert!(header.contains("provID=\"aerodelta_fit\""));
        assert!(header.contains("provID=\"aerodelta_fit_2\""));
        assert!(xml.contains("<provenanceRef provID=\"aerodelta_fit_2\"/>"));
        let m = DaveModel::from_str(&xml, "merged").expect("parses");
        assert_eq!(m.uncertainties().len(), 2);
        assert!(m.run_checks().iter().all(|r| r.pass));
    }
}
