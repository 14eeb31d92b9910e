//! Hostile and pathological DAVE-ML: deep MathML, entity expansion, long
//! dependency chains and cycles. Each is parsed on a thread with Rust's default
//! 2 MiB test stack, so an unbounded recursion fails the test by overflowing.

use super::write::ModelSpec;
use super::*;
use crate::error::ErrorKind;

const HEAD: &str = "<?xml version=\"1.0\"?>\n<DAVEfunc xmlns=\"http://daveml.org/2010/DAVEML\">\n";

/// `DaveModel::from_str(text, "m.dml")` on a 2 MiB stack.
fn load_small_stack(text: String) -> crate::Result<DaveModel> {
    std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(move || DaveModel::from_str(&text, "m.dml"))
        .expect("spawn")
        .join()
        .expect("no panic")
}

/// The one-line parse error of `text`, checked to name the file.
fn refused(text: String) -> String {
    let e = load_small_stack(text).expect_err("must be refused");
    assert_eq!(e.kind(), ErrorKind::Parse, "{e}");
    let msg = e.to_string();
    assert!(msg.starts_with("m.dml:"), "{msg}");
    assert!(!msg.contains('\n'), "one line: {msg}");
    assert!(msg.len() < 600, "short: {msg}");
    msg
}

/// A variable `y` = 1 + (1 + (... + a)) with `k` nested `<apply><plus/>`
/// (MathML depth k + 1), `a` an input.
fn nested_plus(k: usize) -> String {
    format!(
        "{HEAD}<variableDef name=\"a\" varID=\"a\" units=\"nd\"><isInput/></variableDef>\n\
         <variableDef name=\"y\" varID=\"y\" units=\"nd\"><calculation><math>\n{}<ci>a</ci>{}\n\
         </math></calculation><isOutput/></variableDef>\n</DAVEfunc>\n",
        "<apply><plus/><cn>1</cn>".repeat(k),
        "</apply>".repeat(k)
    )
}

#[test]
fn mathml_6200_deep_is_refused_naming_file_and_variable() {
    let msg = refused(nested_plus(6200));
    assert!(
        msg.starts_with("m.dml:4: <variableDef varID=\"y\">: its calculation nests 6201 MathML elements deep (past 512 on line 5); at most 512 are supported"),
        "{msg}"
    );
    assert!(
        msg.contains("n-ary") && msg.contains("intermediate variables"),
        "{msg}"
    );
    // Deep elements that are not MathML (and so never recursed into) are fine
    // for the XML parser itself: the document is read without recursion.
    let deep = format!(
        "{HEAD}<variableDef name=\"a\" varID=\"a\" units=\"nd\"><description>{}x{}</description><isInput/></variableDef></DAVEfunc>",
        "<b>".repeat(20_000),
        "</b>".repeat(20_000)
    );
    let m = load_small_stack(deep).expect("loads");
    assert_eq!(m.variables()[0].description.len(), 1);
}

#[test]
fn mathml_at_the_depth_limit_compiles_and_evaluates() {
    let k = mathml::MAX_DEPTH - 1;
    let m = load_small_stack(nested_plus(k)).expect("512 deep compiles");
    let v = std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(move || m.evaluate(&[("a", 0.5)]).expect("evaluates"))
        .expect("spawn")
        .join()
        .expect("no panic");
    assert_eq!(v[1], 0.5 + k as f64);
    let msg = refused(nested_plus(k + 1));
    assert!(msg.contains("nests 513 MathML elements deep"), "{msg}");
}

#[test]
fn regressors_at_their_depth_limit_round_trip_through_mathml() {
    // The writer turns a regressor of crate::regressor::MAX_DEPTH into MathML
    // that the reader accepts.
    let expr = vec!["deadband(x, 1)"; crate::regressor::MAX_DEPTH - 3].join(" + ");
    let spec = ModelSpec::from_json(&format!(
        r#"{{"name": "deep", "inputs": [{{"id": "x", "initial": 0}}],
           "calculations": [{{"id": "y", "expr": "{expr}", "is_output": true}}],
           "outputs": [], "checks": [{{"name": "x 3", "inputs": {{"x": 3}}}}]}}"#
    ))
    .expect("spec");
    let xml = std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(move || to_xml(&spec))
        .expect("spawn")
        .join()
        .expect("no panic")
        .expect("writes");
    let m = load_small_stack(xml).expect("reads back");
    assert!(m.run_checks().iter().all(|r| r.pass));
}

/// An internal DTD subset declaring `decl`, then `body` inside a valid model.
fn with_subset(decl: &str, body: &str) -> String {
    format!(
        "<?xml version=\"1.0\"?>\n<!-- a comment -->\n<!DOCTYPE DAVEfunc [\n{decl}\n]>\n\
         <DAVEfunc xmlns=\"http://daveml.org/2010/DAVEML\">\n\
         <variableDef name=\"a\" varID=\"a\" units=\"nd\"><description>{body}</description><isInput/></variableDef>\n</DAVEfunc>\n"
    )
}

#[test]
fn quadratic_entity_expansion_of_a_160_kb_file_is_refused() {
    // One 80 kB entity referenced 20,000 times: 1.6 GB once expanded.
    let text = with_subset(
        &format!("<!ENTITY big \"{}\">", "x".repeat(80_000)),
        &"&big;".repeat(16_000),
    );
    assert!(text.len() > 160_000);
    let msg = refused(text);
    assert!(
        msg.starts_with("m.dml:4: <!ENTITY big>: the <!DOCTYPE> declares an XML entity"),
        "{msg}"
    );
    assert!(msg.contains("remove the <!ENTITY> declarations"), "{msg}");
}

#[test]
fn billion_laughs_is_refused() {
    let mut decl = String::from("<!ENTITY lol \"lol\">\n");
    for k in 1..10 {
        let prev = if k == 1 {
            "lol".to_string()
        } else {
            format!("lol{}", k - 1)
        };
        decl.push_str(&format!(
            "<!ENTITY lol{k} \"{}\">\n",
            format!("&{prev};").repeat(10)
        ));
    }
    let msg = refused(with_subset(&decl, "&lol9;"));
    assert!(msg.starts_with("m.dml:4: <!ENTITY lol>:"), "{msg}");
    // Parameter entities, after a harmless declaration and a comment, too.
    let msg = refused(with_subset(
        "<!ATTLIST DAVEfunc x CDATA \"<!ENTITY no>\">\n<!-- <!ENTITY no> -->\n<!ENTITY % pe \"x\">",
        "",
    ));
    assert!(msg.starts_with("m.dml:6: <!ENTITY pe>:"), "{msg}");
    // The same file merged into is refused as well.
    let spec = ModelSpec::from_json(r#"{"name": "add", "inputs": [{"id": "a"}], "outputs": []}"#)
        .expect("spec");
    let e = merge_xml(&with_subset(&decl, "&lol9;"), "base.dml", &spec).unwrap_err();
    assert!(e.to_string().contains("base.dml:4: <!ENTITY lol>"), "{e}");
}

#[test]
fn doctype_without_entities_is_ignored_and_lines_stay_right() {
    // The public models' form (external DTD), spread over lines, and an
    // internal subset without entities: both read, error lines unchanged.
    let ext = "<?xml version=\"1.0\"?>\n<!DOCTYPE DAVEfunc\n  PUBLIC \"-//AIAA//DTD for Flight Dynamic Models - Functions 2.0//EN\"\n  \"http://www.daveml.org/DTDs/2p0/DAVEfunc.dtd\">\n<DAVEfunc xmlns=\"http://daveml.org/2010/DAVEML\">\n<variableDef name=\"a\" varID=\"a\" units=\"nd\"><isInput/></variableDef>\n</DAVEfunc>\n";
    let m = load_small_stack(ext.to_string()).expect("loads");
    assert_eq!(m.variables().len(), 1);
    let bad = ext.replace(
        "<isInput/>",
        "<calculation><math><ci>zz</ci></math></calculation>",
    );
    let msg = refused(bad);
    assert!(
        msg.starts_with("m.dml:6: <ci>: unknown varID 'zz'"),
        "{msg}"
    );
    let m = load_small_stack(with_subset(
        "<!ELEMENT DAVEfunc ANY>\n<!-- <!ENTITY in a comment> -->\n<?pi x?>",
        "ok &amp; &#65;",
    ))
    .expect("loads");
    assert_eq!(m.variables()[0].description, "ok & A");
    // An entity declared nowhere is a clear XML error, not expanded.
    let msg = refused(with_subset("<!ELEMENT DAVEfunc ANY>", "&undeclared;"));
    assert!(
        msg.contains("malformed XML") && msg.contains("undeclared"),
        "{msg}"
    );
    // Unclosed or misplaced declarations.
    let msg = refused("<?xml version=\"1.0\"?>\n<!DOCTYPE DAVEfunc [ <!ELEMENT a ANY>".into());
    assert!(
        msg.starts_with("m.dml:2: the <!DOCTYPE> declaration is not closed"),
        "{msg}"
    );
    let msg = refused(format!("{HEAD}<!DOCTYPE x></DAVEfunc>"));
    assert!(msg.starts_with("m.dml:"), "{msg}");
}

#[test]
fn long_calculation_chain_loads_and_a_long_cycle_is_one_line() {
    // y9999 = y9998 + 1, ..., y0 = a + 1, declared last-first so the
    // dependency walk goes 10,000 deep.
    let n = 10_000;
    let mut body = String::new();
    for k in (0..n).rev() {
        let dep = if k == 0 {
            "a".to_string()
        } else {
            format!("y{}", k - 1)
        };
        body.push_str(&format!(
            "<variableDef name=\"y{k}\" varID=\"y{k}\" units=\"nd\"><calculation><math><apply><plus/><ci>{dep}</ci><cn>1</cn></apply></math></calculation></variableDef>\n"
        ));
    }
    let text = format!(
        "{HEAD}<variableDef name=\"a\" varID=\"a\" units=\"nd\"><isInput/></variableDef>\n{body}</DAVEfunc>\n"
    );
    let m = load_small_stack(text.clone()).expect("loads");
    let v = m.evaluate(&[("a", 0.5)]).expect("evaluates");
    assert_eq!(v[m.index_of("y9999").expect("y9999")], 0.5 + n as f64);
    // Close the chain into a cycle: y0 = y9999 + 1.
    let cyc = text.replace("<ci>a</ci>", "<ci>y9999</ci>");
    let msg = refused(cyc);
    assert!(
        msg.contains("dependency cycle of 10000 variables") && msg.contains(" -> ... -> "),
        "{msg}"
    );
}

/// `n` functions looking up one `griddedTableDef` of `len` values through
/// `griddedTableRef`, function `k` clamping its input at `min = k`.
fn shared_table(n: usize, len: usize) -> String {
    let vals: Vec<String> = (0..len).map(|k| k.to_string()).collect();
    let mut body = format!(
        "<variableDef name=\"a\" varID=\"a\" units=\"nd\"><isInput/></variableDef>\n\
         <breakpointDef bpID=\"B\"><bpVals>{}</bpVals></breakpointDef>\n\
         <griddedTableDef gtID=\"T\"><breakpointRefs><bpRef bpID=\"B\"/></breakpointRefs><dataTable>{}</dataTable></griddedTableDef>\n",
        vals.join(" "),
        vals.join(",")
    );
    for k in 0..n {
        body.push_str(&format!(
            "<variableDef name=\"y{k}\" varID=\"y{k}\" units=\"nd\"/><function name=\"f{k}\">\
             <independentVarRef varID=\"a\" min=\"{k}\"/><dependentVarRef varID=\"y{k}\"/>\
             <functionDefn><griddedTableRef gtID=\"T\"/></functionDefn></function>\n"
        ));
    }
    format!("{HEAD}{body}</DAVEfunc>\n")
}

#[test]
fn a_gridded_table_referenced_by_many_functions_is_read_once_and_shared() {
    // 2000 references to a 20,000-value table: 320 MB if each function kept
    // its own copy of the values and breakpoints.
    let m = load_small_stack(shared_table(2000, 20_000)).expect("loads");
    let tables: Vec<&crate::table::Table> = m
        .defs
        .iter()
        .filter_map(|d| match d {
            model::Def::Table { table, .. } => Some(table),
            _ => None,
        })
        .collect();
    assert_eq!(tables.len(), 2000);
    let (values, bps) = (
        tables[0].values().as_ptr(),
        tables[0].axes()[0].breakpoints().as_ptr(),
    );
    assert!(tables.iter().all(|t| t.values().as_ptr() == values));
    assert!(tables
        .iter()
        .all(|t| t.axes()[0].breakpoints().as_ptr() == bps));
    // Each keeps its own limits: y_k(a) = max(a, k) on the identity table.
    let v = m.evaluate(&[("a", 1234.5)]).expect("evaluates");
    for (k, want) in [
        (0usize, 1234.5),
        (1000, 1234.5),
        (1500, 1500.0),
        (1999, 1999.0),
    ] {
        let i = m.index_of(&format!("y{k}")).expect("y");
        assert_eq!(v[i], want, "y{k}");
    }
    // One locator per distinct (variable, limits): 2000.
    assert_eq!(m.locators.len(), 2000);
}

#[test]
fn breakpoints_whose_product_overflows_are_refused() {
    // 8 sets of 256 breakpoints need 256^8 = 2^64 values: the product wrapped
    // to 0 and an empty dataTable was accepted (then looked up out of bounds).
    let bps: Vec<String> = (0..256).map(|k| k.to_string()).collect();
    let mut body = String::new();
    for k in 0..8 {
        body.push_str(&format!(
            "<variableDef name=\"a{k}\" varID=\"a{k}\" units=\"nd\" initialValue=\"1\"/>\
             <breakpointDef bpID=\"B{k}\"><bpVals>{}</bpVals></breakpointDef>\n",
            bps.join(" ")
        ));
    }
    body.push_str("<variableDef name=\"y\" varID=\"y\" units=\"nd\"/><function name=\"f\">");
    for k in 0..8 {
        body.push_str(&format!("<independentVarRef varID=\"a{k}\"/>"));
    }
    body.push_str("<dependentVarRef varID=\"y\"/><functionDefn><griddedTableDef><breakpointRefs>");
    for k in 0..8 {
        body.push_str(&format!("<bpRef bpID=\"B{k}\"/>"));
    }
    body.push_str(
        "</breakpointRefs><dataTable></dataTable></griddedTableDef></functionDefn></function>",
    );
    let msg = refused(format!("{HEAD}{body}</DAVEfunc>\n"));
    assert!(
        msg.contains("has 0 values but its breakpoints (a0:256 x a1:256")
            && msg.contains("need more than memory can hold"),
        "{msg}"
    );
}

#[test]
fn attribute_and_namespace_floods_are_refused_with_the_line() {
    // The XML parser compares attributes pairwise: 300,000 took minutes.
    let attrs: String = (0..65).map(|k| format!(" a{k}=\"\"")).collect();
    let msg = refused(format!(
        "{HEAD}<variableDef name=\"a\" varID=\"a\" units=\"nd\">\n<description><b{attrs}/></description></variableDef></DAVEfunc>"
    ));
    assert!(
        msg.starts_with("m.dml:4: <b> has 65 attributes; at most 64 are read"),
        "{msg}"
    );
    // 35 elements declaring 2 prefixes each.
    let ns: String = (0..35)
        .map(|k| format!("<b xmlns:p{k}=\"urn:x\" xmlns:q{k}=\"urn:y\"/>"))
        .collect();
    let msg = refused(format!("{HEAD}{ns}</DAVEfunc>"));
    assert!(
        msg.contains("declares more than 64 XML namespace prefixes"),
        "{msg}"
    );
    // 64 attributes, and one namespace declared on every element, are fine.
    let attrs: String = (0..64).map(|k| format!(" a{k}=\"\"")).collect();
    let many_math: String = (0..200)
        .map(|k| format!("<variableDef name=\"v{k}\" varID=\"v{k}\" units=\"nd\"><calculation><math xmlns=\"http://www.w3.org/1998/Math/MathML\"><cn>{k}</cn></math></calculation></variableDef>\n"))
        .collect();
    let m = load_small_stack(format!(
        "{HEAD}<variableDef name=\"a\" varID=\"a\" units=\"nd\"><description><b{attrs}/></description></variableDef>{many_math}</DAVEfunc>"
    ))
    .expect("loads");
    assert_eq!(m.variables().len(), 201);
}

#[test]
fn comments_and_processing_instructions_are_blanked_not_changed_in_meaning() {
    // '<' and '=' in comments and PIs are blanked before the DOM parse (the
    // parser reserves memory per '<' and '='); nothing the reader uses moves.
    let text = format!(
        "<?xml version=\"1.0\"?>\n<!-- a<=b -->\n<DAVEfunc xmlns=\"http://daveml.org/2010/DAVEML\">\n\
         <variableDef name=\"a\" varID=\"a\" units=\"nd\" initialValue=\"2\"><description>x = 1 <!-- {} --> and<?pi k=\"<\"?> y</description><isInput/></variableDef>\n\
         <variableDef name=\"y\" varID=\"y\" units=\"nd\"/>\n\
         <function name=\"f\"><independentVarPts varID=\"a\">1,<!--<=-->2<?p=?> 3</independentVarPts><dependentVarPts varID=\"y\">10 20<!-- = --> 30</dependentVarPts></function>\n\
         <variableDef name=\"z\" varID=\"zz\" units=\"nd\"><calculation><math><ci>nope</ci></math></calculation></variableDef>\n</DAVEfunc>\n",
        "<=".repeat(1000)
    );
    let xml = xml_text(&text, "m.dml").expect("scans");
    assert_eq!(xml.len(), text.len());
    assert!(xml.starts_with("<?xml version=\"1.0\"?>"));
    assert_eq!(text.matches('<').count() - xml.matches('<').count(), 1003);
    assert_eq!(text.matches('=').count() - xml.matches('=').count(), 1005);
    // The error line is the file's: the unknown <ci> on line 7.
    let msg = refused(text.clone());
    assert!(
        msg.starts_with("m.dml:7: <ci>: unknown varID 'nope'"),
        "{msg}"
    );
    let ok = text.replace("<ci>nope</ci>", "<ci>y</ci>");
    let m = load_small_stack(ok).expect("loads");
    assert_eq!(m.variables()[0].description, "x = 1  and y");
    let v = m.evaluate(&[("a", 2.5)]).expect("evaluates");
    assert_eq!(v[m.index_of("y").expect("y")], 25.0);
}

#[test]
fn bytes_that_are_not_utf8_are_a_parse_error_naming_line_and_offset() {
    let mut b = format!("{HEAD}<variableDef name=\"a\" varID=\"a\" units=\"nd\"/>\n</DAVEfunc>")
        .into_bytes();
    let at = b.len() - 12;
    b.insert(at, 0xFF);
    let e = DaveModel::from_bytes(&b, "m.dml").expect_err("refused");
    assert_eq!(e.kind(), ErrorKind::Parse);
    assert_eq!(
        e.to_string(),
        format!("m.dml:3: not UTF-8 text: byte 0xFF at offset {at} is not valid UTF-8; save the file as UTF-8")
    );
}

#[test]
fn messages_quoting_huge_or_multi_line_values_stay_one_short_line() {
    let long = "v".repeat(1 << 20);
    let msg = refused(format!(
        "{HEAD}<variableDef name=\"a\" varID=\"{long}\" units=\"nd\" initialValue=\"1&#10;2\"/></DAVEfunc>"
    ));
    assert!(
        msg.contains("(1048576 characters)")
            && msg.contains("attribute initialValue=\"1\\n2\" is not a number"),
        "{msg}"
    );
}
