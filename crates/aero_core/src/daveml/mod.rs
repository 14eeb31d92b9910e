//! DAVE-ML (ANSI/AIAA S-119-2011, "Flight Dynamic Model Exchange using XML")
//! models: read, evaluate, check and write.
//!
//! A DAVE-ML file declares *variables* (`variableDef`: units, optional
//! `minValue`/`maxValue` limits, an optional MathML-2 `calculation`), shared
//! breakpoint sets (`breakpointDef`), gridded tables (`griddedTableDef`, the
//! deprecated inline `griddedTable`, reused through `griddedTableRef`) and
//! *functions* that look a table up with some variables to define another
//! (`independentVarRef` with `min`, `max`, `extrapolate`; or the simple
//! `independentVarPts`/`dependentVarPts` form). `checkData` holds static check
//! cases ("shots"): inputs, the expected outputs with a tolerance and often the
//! expected value of every internal variable.
//!
//! - [`parse`]: XML to a [`DaveModel`], with errors naming element and line;
//! - [`mathml`]: the MathML-2 content subset, precompiled to an expression tree;
//! - [`model`]: evaluation in a topological order computed at load;
//! - [`check`]: the file's static shots, run against the model;
//! - [`write`](mod@write): a [`ModelSpec`] (inputs, gridded tables, sums of products)
//!   written as DAVE-ML with check cases generated from the model itself;
//!   calculations in the regressor language become MathML;
//! - [`merge`]: a [`ModelSpec`] merged into an existing DAVE-ML file (the Δ of
//!   the extended model added to a qualified model), with new check cases.
//!
//! Table lookups use [`crate::table`]: `extrapolate="neither"` holds the end
//! values, `min`/`max` extrapolate linearly below/above, `both` on both sides;
//! `independentVarRef min/max` clamp the input first.

pub mod check;
pub mod mathml;
pub mod merge;
pub mod model;
pub mod parse;
pub mod write;

#[cfg(test)]
mod tests;

pub use check::{CheckKind, CheckRow, Shot};
pub use merge::merge_xml;
pub use model::{DaveModel, Variable};
pub use write::{mathml_of, to_xml, write_model, CalcSpec, ModelSpec};

use crate::error::AeroError;

/// Where a file's text lives: its name (for messages) and its line starts.
#[derive(Debug, Clone)]
pub(crate) struct Source {
    pub file: String,
    line_starts: Vec<usize>,
}

impl Source {
    pub(crate) fn new(file: &str, text: &str) -> Self {
        let mut line_starts = vec![0];
        line_starts.extend(text.match_indices('\n').map(|(i, _)| i + 1));
        Source {
            file: file.to_string(),
            line_starts,
        }
    }

    /// 1-based line of byte offset `pos`.
    pub(crate) fn line_of(&self, pos: usize) -> usize {
        self.line_starts.partition_point(|&s| s <= pos)
    }

    /// 1-based line where `node` starts.
    pub(crate) fn line(&self, node: roxmltree::Node<'_, '_>) -> usize {
        self.line_of(node.range().start)
    }

    /// A parse error at `node`, the message led by the element's tag and its id attribute.
    pub(crate) fn err(&self, node: roxmltree::Node<'_, '_>, msg: impl AsRef<str>) -> AeroError {
        AeroError::parse(
            self.file.clone(),
            self.line(node),
            format!("{}: {}", describe(node), msg.as_ref()),
        )
    }
}

/// `<tag id="...">` for messages: the tag and its identifying attribute, if any.
pub(crate) fn describe(node: roxmltree::Node<'_, '_>) -> String {
    let tag = node.tag_name().name();
    for key in ["varID", "bpID", "gtID", "name"] {
        if let Some(v) = node.attribute(key) {
            return format!("<{tag} {key}=\"{v}\">");
        }
    }
    format!("<{tag}>")
}

/// Parse a list of numbers separated by commas and/or white space, naming the
/// element and line of a bad token.
pub(crate) fn parse_numbers(
    src: &Source,
    node: roxmltree::Node<'_, '_>,
) -> crate::Result<Vec<f64>> {
    let mut out = Vec::new();
    for t in node.descendants().filter(|n| n.is_text()) {
        let text = t.text().unwrap_or("");
        for tok in text.split(|c: char| c == ',' || c.is_whitespace()) {
            if tok.is_empty() {
                continue;
            }
            let v: f64 = tok.parse().map_err(|_| {
                src.err(
                    node,
                    format!(
                        "'{tok}' is not a number (value {} of the list)",
                        out.len() + 1
                    ),
                )
            })?;
            out.push(v);
        }
    }
    Ok(out)
}

/// The concatenated text of a node (all text descendants, comments skipped), trimmed.
pub(crate) fn text_of(node: roxmltree::Node<'_, '_>) -> String {
    let s: String = node
        .descendants()
        .filter(|n| n.is_text())
        .filter_map(|n| n.text())
        .collect();
    s.trim().to_string()
}

/// The element children of `node`.
pub(crate) fn elements<'a, 'i>(
    node: roxmltree::Node<'a, 'i>,
) -> impl Iterator<Item = roxmltree::Node<'a, 'i>> {
    node.children().filter(|n| n.is_element())
}

/// The first element child named `tag`.
pub(crate) fn child<'a, 'i>(
    node: roxmltree::Node<'a, 'i>,
    tag: &str,
) -> Option<roxmltree::Node<'a, 'i>> {
    elements(node).find(|n| n.tag_name().name() == tag)
}

#[cfg(test)]
pub(crate) mod conformance {
    use super::*;
    use std::path::PathBuf;

    /// The folder of the public models: `AERODELTA_SHARED_DAVEML`, else the
    /// first `shared/data/daveml` above the crate (`../../../shared/data/daveml`
    /// in the main checkout). `None` when absent: the reference checks are then
    /// skipped with a message on stderr, unless `AERODELTA_REQUIRE_SHARED` is
    /// set (CI sets it), in which case the test fails.
    pub(crate) fn shared_dir() -> Option<PathBuf> {
        let dir = match std::env::var("AERODELTA_SHARED_DAVEML") {
            Ok(d) => PathBuf::from(d),
            Err(_) => {
                let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
                here.ancestors()
                    .map(|a| a.join("shared/data/daveml"))
                    .find(|d| d.is_dir())
                    .unwrap_or_else(|| here.join("../../../shared/data/daveml"))
            }
        };
        if dir.is_dir() {
            return Some(dir);
        }
        let msg = format!(
            "public DAVE-ML models not found at {}; set AERODELTA_SHARED_DAVEML to their folder",
            dir.display()
        );
        assert!(
            std::env::var_os("AERODELTA_REQUIRE_SHARED").is_none(),
            "{msg} (AERODELTA_REQUIRE_SHARED is set, so this is a failure)"
        );
        eprintln!("SKIPPED: {msg}");
        None
    }

    /// Every static shot and internal value of the public NASA models passes
    /// at the file's own tolerance.
    #[test]
    fn public_models_pass_their_check_cases() {
        let Some(dir) = shared_dir() else { return };
        for f in [
            "F16_aero.dml",
            "HL20_aero.dml",
            "tables.dml",
            "fiveD_table.dml",
            "atmos_76.dml",
            "F16_prop.dml",
        ] {
            let m = DaveModel::from_file(dir.join(f)).unwrap_or_else(|e| panic!("{e}"));
            let rows = m.run_checks();
            assert!(!rows.is_empty(), "{f}: no checks");
            for kind in [CheckKind::Output, CheckKind::Internal] {
                let (n, worst) = rows
                    .iter()
                    .filter(|r| r.kind == kind)
                    .fold((0, 0.0f64), |(n, w), r| {
                        (n + 1, w.max((r.actual - r.expected).abs()))
                    });
                eprintln!(
                    "{f}: {n} {} checks, largest |error| {worst:.3e}",
                    kind.as_str()
                );
            }
            let bad: Vec<String> = rows
                .iter()
                .filter(|r| !r.pass)
                .map(|r| {
                    format!(
                        "{f} '{}' {} {} expected {} actual {} tol {}",
                        r.shot,
                        r.kind.as_str(),
                        r.var_id,
                        r.expected,
                        r.actual,
                        r.tolerance
                    )
                })
                .collect();
            assert!(
                bad.is_empty(),
                "{} of {} failed:\n{}",
                bad.len(),
                rows.len(),
                bad.join("\n")
            );
        }
    }

    #[test]
    fn files_without_checks_load() {
        let Some(dir) = shared_dir() else { return };
        for f in ["simple_aero.dml", "simplest_aero.dml", "twoD_table.dml"] {
            let m = DaveModel::from_file(dir.join(f)).unwrap_or_else(|e| panic!("{e}"));
            assert!(m.shots().is_empty());
        }
    }
}

#[cfg(test)]
mod shared_locate {
    use super::conformance::shared_dir;
    use super::*;

    /// The batch and `evaluate` paths (one locate per shared variable and
    /// breakpoint set) equal the real-time `compute` path bit for bit.
    #[test]
    fn cached_and_plain_paths_agree_bitwise_on_public_models() {
        let Some(dir) = shared_dir() else { return };
        for f in ["F16_aero.dml", "HL20_aero.dml", "atmos_76.dml"] {
            let m = DaveModel::from_file(dir.join(f)).unwrap_or_else(|e| panic!("{e}"));
            assert!(
                m.locators.len()
                    < m.defs
                        .iter()
                        .map(|d| match d {
                            model::Def::Table { args, .. } => args.len(),
                            _ => 0,
                        })
                        .sum::<usize>(),
                "{f}: tables share locators"
            );
            let ins: Vec<usize> = m
                .inputs()
                .iter()
                .filter_map(|v| m.index_of(&v.id))
                .collect();
            let mut plain = vec![0.0; m.variables().len()];
            for k in 0..200u32 {
                // Deterministic spread of inputs, incl. far outside table ranges.
                let set: Vec<(usize, f64)> = ins
                    .iter()
                    .enumerate()
                    .map(|(j, &i)| {
                        (
                            i,
                            ((f64::from(k) * 0.731 + j as f64 * 1.37).sin()) * 60.0 + 1.0,
                        )
                    })
                    .collect();
                let ids: Vec<(&str, f64)> = set
                    .iter()
                    .map(|&(i, x)| (m.variables()[i].id.as_str(), x))
                    .collect();
                let cached = m.evaluate(&ids).expect("evaluate");
                m.compute(&set, &mut plain);
                for (a, b) in cached.iter().zip(&plain) {
                    assert_eq!(a.to_bits(), b.to_bits(), "{f}");
                }
            }
        }
    }
}
