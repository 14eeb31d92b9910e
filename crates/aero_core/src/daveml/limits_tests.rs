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
