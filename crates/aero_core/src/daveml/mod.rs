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
//!   the extended model added to a qualified model), with new check cases;
//! - [`uncertainty`]: `uncertainty` of variables and tables (read and checked
//!   against their nominal values; written for tables with confidence bands)
//!   and `provenance` references.
//!
//! Table lookups use [`crate::table`]: `extrapolate="neither"` holds the end
//! values, `min`/`max` extrapolate linearly below/above, `both` on both sides;
//! `independentVarRef min/max` clamp the input first.

pub mod check;
pub mod mathml;
pub mod merge;
pub mod model;
pub mod parse;
pub mod uncertainty;
pub mod write;
mod xml;

#[cfg(test)]
mod limits_tests;
#[cfg(test)]
mod tests;

pub use check::{CheckKind, CheckRow, Shot};
pub use merge::merge_xml;
pub use model::{DaveModel, Variable};
pub use uncertainty::{Bound, Distribution, Effect, Uncertainty};
pub use write::{
    mathml_of, to_xml, write_model, CalcSpec, ModelSpec, ProvenanceSpec, UncertaintySpec,
};

use std::borrow::Cow;

pub(crate) use xml::{parse_document, Node, NodeId};

use crate::error::AeroError;
use crate::text::{one_line, shown};

/// Most attributes one element may have (DAVE-ML elements have a handful; the
/// XML reader checks them for duplicates pairwise).
pub const MAX_ATTRIBUTES: usize = 64;

/// Most distinct namespace prefixes (`xmlns`, `xmlns:p`) a file may declare
/// (DAVE-ML files use one to three; the XML reader keeps a count of open
/// declarations per prefix).
pub const MAX_NAMESPACES: usize = 64;

/// The text to hand to the XML reader ([`xml`]), byte for byte as long as
/// `text` (line breaks kept), so byte offsets and lines are those of `text`:
/// - the document type declaration (`<!DOCTYPE ...>`), if any, blanked out
///   (the public models carry one naming the external DAVE-ML DTD, which is
///   never read);
/// - `<` and `=` inside comments and processing instructions blanked (the
///   reader never looks there; the DOM reader used before reserved memory
///   for every `<` and `=`).
///
/// Refused with an error naming the file and line: an internal subset that
/// declares entities (`<!ENTITY ...>`). DAVE-ML needs none, and expanding them
/// is how a file of a few hundred kilobytes becomes gigabytes of text
/// ("billion laughs", quadratic blowup). The XML reader then refuses any
/// `<!DOCTYPE>` this scan did not find (one outside the prolog). Also
/// refused: an element with more than [`MAX_ATTRIBUTES`] attributes, more
/// than [`MAX_NAMESPACES`] namespace prefixes.
#[cfg(test)]
pub(crate) fn xml_text<'a>(text: &'a str, file: &str) -> crate::Result<Cow<'a, str>> {
    xml_text_counted(text, file).map(|(t, _)| t)
}

/// [`xml_text`], with the elements, attributes and text runs counted on the
/// way (the XML reader sizes its arena from them).
pub(crate) fn xml_text_counted<'a>(
    text: &'a str,
    file: &str,
) -> crate::Result<(Cow<'a, str>, xml::Counts)> {
    let line = |pos: usize| {
        1 + text.as_bytes()[..pos.min(text.len())]
            .iter()
            .filter(|&&c| c == b'\n')
            .count()
    };
    let doctype = doctype_span(text, file)?;
    let (blank, counts) = markup_scan(text.as_bytes(), doctype, file, &line)?;
    if doctype.is_none() && blank.is_empty() {
        return Ok((Cow::Borrowed(text), counts));
    }
    let mut out = text.as_bytes().to_vec();
    if let Some((start, end)) = doctype {
        for c in &mut out[start..end] {
            if *c != b'\n' {
                *c = b' ';
            }
        }
    }
    for (start, end) in blank {
        for c in &mut out[start..end] {
            if matches!(*c, b'<' | b'=') {
                *c = b' ';
            }
        }
    }
    // Only ASCII bytes were replaced by ASCII: still UTF-8.
    String::from_utf8(out)
        .map(|t| (Cow::Owned(t), counts))
        .map_err(|e| AeroError::parse(file, 1, format!("not UTF-8 text: {e}")))
}

/// The error of a tag `<tag>` with `n` attributes, more than [`MAX_ATTRIBUTES`].
fn too_many_attributes(file: &str, line: usize, tag: &str, n: usize) -> AeroError {
    AeroError::parse(
        file,
        line,
        format!(
            "<{}> has {n} attributes; at most {MAX_ATTRIBUTES} are read \
             (DAVE-ML elements have a handful); remove the others",
            shown(tag)
        ),
    )
}

/// Byte offset of the first `pat` in `b` at or after `from`.
fn find(b: &[u8], from: usize, pat: &[u8]) -> Option<usize> {
    b.get(from..)
        .and_then(|rest| rest.windows(pat.len()).position(|w| w == pat))
        .map(|k| from + k)
}

/// Outside the document type declaration `doctype`: the spans of comments
/// and processing instructions (not the XML declaration) holding a `<` or
/// `=`, the limits on attributes and namespace declarations, and the counts
/// of start tags, attributes and text runs. Stops quietly at anything
/// unterminated: the XML reader names the problem.
fn markup_scan(
    b: &[u8],
    doctype: Option<(usize, usize)>,
    file: &str,
    line: &dyn Fn(usize) -> usize,
) -> crate::Result<(Vec<(usize, usize)>, xml::Counts)> {
    let mut blank = Vec::new();
    let mut counts = xml::Counts::default();
    // End of the previous markup: characters between it and the next '<' are
    // text; text and CDATA sections not separated by other markup are one run.
    let (mut last, mut in_run) = (0, false);
    let mut prefixes: std::collections::HashSet<&[u8]> = std::collections::HashSet::new();
    let declaration_at = usize::from(b.starts_with(&[0xEF, 0xBB, 0xBF])) * 3;
    let mut i = 0;
    let holds = |s: usize, e: usize| b[s..e].iter().any(|&c| matches!(c, b'<' | b'='));
    while let Some(k) = b.get(i..).and_then(|r| r.iter().position(|&c| c == b'<')) {
        let s = i + k;
        let rest = &b[s..];
        if s > last {
            counts.texts += usize::from(!in_run);
            in_run = true;
        }
        let cdata = rest.starts_with(b"<![CDATA[");
        if let Some((_, end)) = doctype.filter(|d| d.0 == s) {
            i = end;
        } else if rest.starts_with(b"<!--") {
            let Some(e) = find(b, s + 4, b"-->") else {
                break;
            };
            if holds(s + 4, e) {
                blank.push((s + 4, e));
            }
            i = e + 3;
        } else if rest.starts_with(b"<![CDATA[") {
            let Some(e) = find(b, s + 9, b"]]>") else {
                break;
            };
            counts.texts += usize::from(!in_run);
            i = e + 3;
        } else if rest.starts_with(b"<?") {
            let Some(e) = find(b, s + 2, b"?>") else {
                break;
            };
            let declaration = s == declaration_at
                && rest.starts_with(b"<?xml")
                && rest
                    .get(5)
                    .is_some_and(|c| c.is_ascii_whitespace() || *c == b'?');
            if !declaration && holds(s + 2, e) {
                blank.push((s + 2, e));
            }
            i = e + 2;
        } else if rest.starts_with(b"<!") {
            i = s + 2;
        } else {
            // A tag: up to '>' outside quotes, counting attributes ('=')
            // and namespace declarations.
            let (mut j, mut quote, mut attributes) = (s + 1, None, 0usize);
            let end = loop {
                let Some(&c) = b.get(j) else { break None };
                match (quote, c) {
                    (Some(q), c) if c == q => quote = None,
                    (Some(_), _) => {}
                    (None, b'"' | b'\'') => quote = Some(c),
                    (None, b'>') => break Some(j),
                    (None, b'=') => attributes += 1,
                    (None, c) if c.is_ascii_whitespace() => {
                        let name = &b[j + 1..];
                        if name.starts_with(b"xmlns")
                            && name
                                .get(5)
                                .is_some_and(|&d| d == b':' || d == b'=' || d.is_ascii_whitespace())
                        {
                            let len = name
                                .iter()
                                .position(|&d| d == b'=' || d.is_ascii_whitespace())
                                .unwrap_or(name.len());
                            prefixes.insert(&name[..len]);
                        }
                    }
                    (None, _) => {}
                }
                j += 1;
            };
            let Some(end) = end else { break };
            if rest.get(1) != Some(&b'/') {
                counts.elements += 1;
                counts.attributes += attributes;
            }
            let tag = || {
                let name: Vec<u8> = b[s + 1..end]
                    .iter()
                    .take_while(|c| !c.is_ascii_whitespace() && !matches!(c, b'/' | b'>'))
                    .copied()
                    .collect();
                String::from_utf8_lossy(&name).into_owned()
            };
            if attributes > MAX_ATTRIBUTES {
                return Err(too_many_attributes(file, line(s), &tag(), attributes));
            }
            if prefixes.len() > MAX_NAMESPACES {
                return Err(AeroError::parse(
                    file,
                    line(s),
                    format!(
                        "<{}>: the file declares more than {MAX_NAMESPACES} XML namespace \
                         prefixes (DAVE-ML files use one to three); remove the others",
                        shown(&tag())
                    ),
                ));
            }
            i = end + 1;
        }
        last = i;
        in_run = cdata;
    }
    if b.len() > last && !in_run {
        counts.texts += 1;
    }
    Ok((blank, counts))
}

/// The span of the document type declaration (`<!DOCTYPE ...>`), if any.
///
/// # Errors
/// An internal subset declaring entities, or a declaration not closed.
fn doctype_span(text: &str, file: &str) -> crate::Result<Option<(usize, usize)>> {
    let b = text.as_bytes();
    let line = |pos: usize| {
        1 + b[..pos.min(b.len())]
            .iter()
            .filter(|&&c| c == b'\n')
            .count()
    };
    let find = |from: usize, pat: &[u8]| find(b, from, pat);
    let skip_ws = |mut i: usize| {
        while b.get(i).is_some_and(u8::is_ascii_whitespace) {
            i += 1;
        }
        i
    };
    // Prolog: BOM, XML declaration, comments, processing instructions.
    let mut i = if b.starts_with(&[0xEF, 0xBB, 0xBF]) {
        3
    } else {
        0
    };
    loop {
        i = skip_ws(i);
        let end = if b[i..].starts_with(b"<?") {
            find(i + 2, b"?>").map(|k| k + 2)
        } else if b[i..].starts_with(b"<!--") {
            find(i + 4, b"-->").map(|k| k + 3)
        } else {
            break;
        };
        match end {
            Some(e) => i = e,
            // Unterminated: the XML reader names the problem.
            None => return Ok(None),
        }
    }
    if !b[i..].starts_with(b"<!DOCTYPE") {
        return Ok(None);
    }
    let start = i;
    let unclosed = || {
        AeroError::parse(
            file,
            line(start),
            "the <!DOCTYPE> declaration is not closed; end it with '>' (or ']>' after an internal subset)",
        )
    };
    // Name and external id, up to '[' or '>' outside quotes.
    let mut j = start + 9;
    let mut quote = None;
    let subset = loop {
        let c = *b.get(j).ok_or_else(unclosed)?;
        j += 1;
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), _) => {}
            (None, b'"' | b'\'') => quote = Some(c),
            (None, b'[') => break true,
            (None, b'>') => break false,
            (None, _) => {}
        }
    };
    if subset {
        // Internal subset: declarations, comments, PIs, parameter-entity references.
        loop {
            j = skip_ws(j);
            let rest = b.get(j..).filter(|r| !r.is_empty()).ok_or_else(unclosed)?;
            if rest.starts_with(b"]") {
                j = skip_ws(j + 1);
                if b.get(j) != Some(&b'>') {
                    return Err(unclosed());
                }
                j += 1;
                break;
            } else if rest.starts_with(b"<!--") {
                j = find(j + 4, b"-->").ok_or_else(unclosed)? + 3;
            } else if rest.starts_with(b"<?") {
                j = find(j + 2, b"?>").ok_or_else(unclosed)? + 2;
            } else if rest.starts_with(b"<!ENTITY") {
                let k = skip_ws(j + 8);
                let k = if b.get(k) == Some(&b'%') {
                    skip_ws(k + 1)
                } else {
                    k
                };
                let name_end = (k..b.len())
                    .find(|&e| b[e].is_ascii_whitespace() || b[e] == b'>')
                    .unwrap_or(b.len());
                let name = shown(&String::from_utf8_lossy(&b[k..name_end]));
                return Err(AeroError::parse(
                    file,
                    line(j),
                    format!(
                        "<!ENTITY {name}>: the <!DOCTYPE> declares an XML entity; DAVE-ML files need \
                         none and entity expansion can blow a small file up to gigabytes, so they \
                         are not read; remove the <!ENTITY> declarations and write their text out"
                    ),
                ));
            } else if rest.starts_with(b"<!") {
                // <!ELEMENT>, <!ATTLIST>, <!NOTATION>: up to '>' outside quotes.
                let mut quote = None;
                j += 2;
                loop {
                    let c = *b.get(j).ok_or_else(unclosed)?;
                    j += 1;
                    match (quote, c) {
                        (Some(q), c) if c == q => quote = None,
                        (Some(_), _) => {}
                        (None, b'"' | b'\'') => quote = Some(c),
                        (None, b'>') => break,
                        (None, _) => {}
                    }
                }
            } else if rest.starts_with(b"%") {
                j = find(j, b";").ok_or_else(unclosed)? + 1;
            } else {
                return Err(AeroError::parse(
                    file,
                    line(j),
                    "unexpected text in the internal subset of the <!DOCTYPE> declaration; \
                     DAVE-ML files need none: remove the '[ ... ]' part",
                ));
            }
        }
    }
    Ok(Some((start, j)))
}

/// Where a file's text lives: its name (for messages) and its line starts.
#[derive(Debug, Clone)]
pub(crate) struct Source {
    pub file: String,
    /// Byte offsets of the line starts (texts are under 4 GiB: see
    /// [`parse_document`]), in a vector of exactly their number.
    line_starts: Vec<u32>,
}

impl Source {
    pub(crate) fn new(file: &str, text: &str) -> Self {
        let mut line_starts = Vec::with_capacity(1 + text.matches('\n').count());
        line_starts.push(0);
        line_starts.extend(
            text.match_indices('\n')
                .map(|(i, _)| u32::try_from(i + 1).unwrap_or(u32::MAX)),
        );
        Source {
            file: file.to_string(),
            line_starts,
        }
    }

    /// 1-based line of byte offset `pos`.
    pub(crate) fn line_of(&self, pos: usize) -> usize {
        self.line_starts.partition_point(|&s| s as usize <= pos)
    }

    /// 1-based line where `node` starts.
    pub(crate) fn line(&self, node: Node<'_>) -> usize {
        self.line_of(node.range().start)
    }

    /// A parse error at `node`, the message led by the element's tag and its id attribute.
    pub(crate) fn err(&self, node: Node<'_>, msg: impl AsRef<str>) -> AeroError {
        AeroError::parse(
            self.file.clone(),
            self.line(node),
            one_line(&format!("{}: {}", describe(node), msg.as_ref())),
        )
    }
}

/// `<tag id="...">` for messages: the tag and its identifying attribute, if any.
pub(crate) fn describe(node: Node<'_>) -> String {
    let tag = node.tag_name();
    for key in ["varID", "bpID", "gtID", "name"] {
        if let Some(v) = node.attribute(key) {
            return format!("<{} {key}=\"{}\">", shown(tag), shown(v));
        }
    }
    format!("<{}>", shown(tag))
}

/// Parse a list of numbers separated by commas and/or white space, naming the
/// element and line of a bad token.
pub(crate) fn parse_numbers(src: &Source, node: Node<'_>) -> crate::Result<Vec<f64>> {
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
                        "'{}' is not a number (value {} of the list)",
                        shown(tok),
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
pub(crate) fn text_of(node: Node<'_>) -> String {
    let s: String = node
        .descendants()
        .filter(|n| n.is_text())
        .filter_map(|n| n.text())
        .collect();
    s.trim().to_string()
}

/// The element children of `node`.
pub(crate) fn elements<'a>(node: Node<'a>) -> impl Iterator<Item = Node<'a>> {
    node.children().filter(|n| n.is_element())
}

/// The first element child named `tag`.
pub(crate) fn child<'a>(node: Node<'a>, tag: &str) -> Option<Node<'a>> {
    elements(node).find(|n| n.tag_name() == tag)
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
