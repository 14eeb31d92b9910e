//! Tests of parsing, evaluation order, malformed files, extrapolation and the writer.

use super::write::{CheckPoint, Extrapolate, InputSpec, OutputSpec, TableSpec, Term};
use super::*;
use crate::error::ErrorKind;

const HEAD: &str = "<?xml version=\"1.0\"?>\n<DAVEfunc xmlns=\"http://daveml.org/2010/DAVEML\">\n";

fn model(body: &str) -> crate::Result<DaveModel> {
    DaveModel::from_str(&format!("{HEAD}{body}</DAVEfunc>\n"), "m.dml")
}

fn err(body: &str) -> String {
    let e = model(body).expect_err("must fail");
    assert_eq!(e.kind(), ErrorKind::Parse, "{e}");
    e.to_string()
}

const ONE_D: &str = r#"<variableDef name="x" varID="x" units="deg"><isInput/></variableDef>
<variableDef name="y" varID="y" units="nd"><isOutput/></variableDef>
<breakpointDef bpID="XB"><bpVals>0, 1, 3</bpVals></breakpointDef>
<function name="f"><independentVarRef varID="x" EXTRA/><dependentVarRef varID="y"/>
<functionDefn><griddedTableDef gtID="T"><breakpointRefs><bpRef bpID="XB"/></breakpointRefs>
<dataTable>0 10 20</dataTable></griddedTableDef></functionDefn></function>
"#;

fn one_d(extra: &str) -> DaveModel {
    model(&ONE_D.replace("EXTRA", extra)).expect("valid")
}

fn y_at(m: &DaveModel, x: f64) -> f64 {
    let v = m.evaluate(&[("x", x)]).expect("eval");
    v[m.index_of("y").expect("y")]
}

#[test]
fn extrapolate_semantics() {
    // Segments: slope 10 on [0,1], 5 on [1,3].
    let m = one_d("");
    assert_eq!(
        (y_at(&m, -1.0), y_at(&m, 0.5), y_at(&m, 2.0), y_at(&m, 5.0)),
        (0.0, 5.0, 15.0, 20.0)
    );
    let m = one_d(r#"extrapolate="neither""#);
    assert_eq!((y_at(&m, -1.0), y_at(&m, 5.0)), (0.0, 20.0));
    let m = one_d(r#"extrapolate="min""#);
    assert_eq!((y_at(&m, -1.0), y_at(&m, 5.0)), (-10.0, 20.0));
    let m = one_d(r#"extrapolate="max""#);
    assert_eq!((y_at(&m, -1.0), y_at(&m, 5.0)), (0.0, 30.0));
    let m = one_d(r#"extrapolate="both""#);
    assert_eq!((y_at(&m, -1.0), y_at(&m, 5.0)), (-10.0, 30.0));
    // min/max clamp the input before extrapolation.
    let m = one_d(r#"extrapolate="both" min="-0.5" max="4""#);
    assert_eq!((y_at(&m, -1.0), y_at(&m, 5.0)), (-5.0, 25.0));
}

#[test]
fn topological_order_is_independent_of_file_order() {
    // c = b * 2 declared before b = a + 1; a is an input; d limited by maxValue.
    let m = model(
        r#"<variableDef name="c" varID="c" units="nd"><calculation><math><apply><times/><ci>b</ci><cn>2</cn></apply></math></calculation><isOutput/></variableDef>
<variableDef name="d" varID="d" units="nd" maxValue="5"><calculation><math><apply><plus/><ci>c</ci><ci>k</ci></apply></math></calculation></variableDef>
<variableDef name="b" varID="b" units="nd"><calculation><math><apply><plus/><ci>a</ci><cn>1</cn></apply></math></calculation></variableDef>
<variableDef name="a" varID="a" units="nd"><isInput/></variableDef>
<variableDef name="k" varID="k" units="nd" initialValue="0.25"/>
"#,
    )
    .expect("valid");
    let v = m.evaluate(&[("a", 0.5)]).expect("eval");
    assert_eq!(v, vec![3.0, 3.25, 1.5, 0.5, 0.25]);
    let v = m.evaluate(&[("a", 3.0), ("k", 1.0)]).expect("eval");
    assert_eq!(v[1], 5.0, "maxValue limits d = 9 to 5");
    let ins: Vec<&str> = m.inputs().iter().map(|v| v.id.as_str()).collect();
    assert_eq!(ins, vec!["a"]);
    let outs: Vec<&str> = m.outputs().iter().map(|v| v.id.as_str()).collect();
    assert_eq!(outs, vec!["c"]);
    // A missing input without initial value is named.
    let e = m.evaluate(&[]).expect_err("missing");
    assert!(e.to_string().contains("input 'a' (a) is missing"), "{e}");
    let e = m.evaluate(&[("a", 1.0), ("b", 1.0)]).expect_err("computed");
    assert!(e.to_string().contains("input 'b'"), "{e}");
    // Batch path equals the single-point path.
    let xs: Vec<f64> = (0..10_000).map(|i| i as f64 * 1e-3).collect();
    let cols = m
        .evaluate_columns(&[("a", &xs)], &["d", "c"])
        .expect("batch");
    for (i, &x) in xs.iter().enumerate() {
        let v = m.evaluate(&[("a", x)]).expect("eval");
        assert_eq!(cols[0][i].to_bits(), v[1].to_bits());
        assert_eq!(cols[1][i].to_bits(), v[0].to_bits());
    }
}

#[test]
fn cycle_is_an_error_naming_its_variables() {
    let e = err(
        r#"<variableDef name="a" varID="a" units="nd"><calculation><math><apply><plus/><ci>b</ci><cn>1</cn></apply></math></calculation></variableDef>
<variableDef name="b" varID="b" units="nd"><calculation><math><apply><times/><ci>a</ci><cn>2</cn></apply></math></calculation></variableDef>
"#,
    );
    assert!(e.contains("dependency cycle a -> b -> a"), "{e}");
    assert!(e.starts_with("m.dml:3:"), "{e}");
}

#[test]
fn unknown_varid_names_element_and_line() {
    let e = err(&ONE_D.replace(
        r#"<independentVarRef varID="x" EXTRA/>"#,
        r#"<independentVarRef varID="xx"/>"#,
    ));
    assert!(
        e.starts_with("m.dml:6: <independentVarRef varID=\"xx\">: unknown varID 'xx'"),
        "{e}"
    );
    let e = err(&ONE_D.replace("EXTRA", "").replace(
        r#"<dependentVarRef varID="y"/>"#,
        r#"<dependentVarRef varID="yy"/>"#,
    ));
    assert!(
        e.starts_with("m.dml:6: <dependentVarRef varID=\"yy\">: unknown varID 'yy'"),
        "{e}"
    );
}

#[test]
fn wrong_table_size_names_element_and_line() {
    let e = err(&ONE_D.replace("EXTRA", "").replace("0 10 20", "0 10 20 30"));
    assert!(e.starts_with("m.dml:7: <griddedTableDef gtID=\"T\">: table: has 4 values but its breakpoints (x:3) need 3"), "{e}");
}

#[test]
fn non_increasing_breakpoints_name_element_and_line() {
    let e = err(&ONE_D.replace("EXTRA", "").replace("0, 1, 3", "0, 1, 1"));
    assert!(
        e.starts_with(
            "m.dml:5: <breakpointDef bpID=\"XB\">: axis 'XB', breakpoint 2: 1 does not exceed"
        ),
        "{e}"
    );
}

#[test]
fn unit_mismatch_in_check_case_names_element_and_line() {
    let shot = |units: &str| {
        format!(
            "{}<checkData><staticShot name=\"s1\"><checkInputs>\n<signal><signalName>x</signalName><signalUnits>{units}</signalUnits><signalValue>0.5</signalValue></signal></checkInputs>\n<checkOutputs><signal><signalName>y</signalName><signalUnits>nd</signalUnits><signalValue>5</signalValue><tol>1e-12</tol></signal></checkOutputs></staticShot></checkData>\n",
            ONE_D.replace("EXTRA", "")
        )
    };
    let m = model(&shot("deg")).expect("valid");
    let rows = m.run_checks();
    assert_eq!(rows.len(), 1);
    assert!(rows[0].pass && rows[0].actual == 5.0 && rows[0].kind == CheckKind::Output);
    let e = err(&shot("rad"));
    assert!(e.starts_with("m.dml:10: <signalUnits>: unit mismatch in shot 's1', signal 'x': the check gives 'rad' but <variableDef varID=\"x\"> (line 3) is in 'deg'"), "{e}");
}

#[test]
fn malformed_xml_and_unsupported_elements_are_parse_errors() {
    let e = DaveModel::from_str("<DAVEfunc><variableDef", "bad.dml").expect_err("xml");
    assert!(e.to_string().starts_with("bad.dml:1: malformed XML"), "{e}");
    let e = err(&ONE_D.replace("EXTRA", r#"interpolate="cubicSpline""#));
    assert!(
        e.contains("interpolate=\"cubicSpline\" is not supported"),
        "{e}"
    );
}

fn spec() -> ModelSpec {
    let input = |id: &str, units: &str, min: f64, max: f64| InputSpec {
        id: id.into(),
        name: String::new(),
        units: units.into(),
        description: format!("input {id}"),
        min: Some(min),
        max: Some(max),
        initial: Some(0.0),
    };
    ModelSpec {
        name: "round trip".into(),
        description: "test & <check>".into(),
        author: String::new(),
        date: Some("2026-01-01".into()),
        inputs: vec![
            input("a", "deg", -10.0, 30.0),
            input("b", "deg", -20.0, 20.0),
        ],
        calculations: vec![],
        tables: vec![
            TableSpec {
                id: "Ta".into(),
                name: String::new(),
                units: "_rad".into(),
                description: String::new(),
                args: vec!["a".into()],
                breakpoints: vec![vec![-5.0, 0.0, 10.0, 20.0]],
                values: vec![0.1, -0.2, 0.3, 1.0 / 3.0],
                extrapolate: Extrapolate::Neither,
                is_output: false,
                uncertainty: None,
            },
            TableSpec {
                id: "Tab".into(),
                name: String::new(),
                units: "nd".into(),
                description: String::new(),
                args: vec!["a".into(), "b".into()],
                breakpoints: vec![vec![-5.0, 0.0, 10.0, 20.0], vec![-10.0, 10.0]],
                values: (0..8).map(|i| f64::from(i) * 0.1 - 0.35).collect(),
                extrapolate: Extrapolate::Both,
                is_output: true,
                uncertainty: None,
            },
        ],
        outputs: vec![OutputSpec {
            id: "C".into(),
            name: "coefficient".into(),
            units: "nd".into(),
            description: String::new(),
            terms: vec![
                Term {
                    coef: 1.0,
                    factors: vec!["Ta".into(), "b".into()],
                },
                Term {
                    coef: 0.5,
                    factors: vec!["Tab".into()],
                },
                Term {
                    coef: -0.01,
                    factors: vec![],
                },
            ],
        }],
        checks: vec![
            CheckPoint {
                name: "zero".into(),
                inputs: [("a".to_string(), 0.0)].into_iter().collect(),
            },
            CheckPoint {
                name: "mid".into(),
                inputs: [("a".to_string(), 7.3), ("b".to_string(), -4.1)]
                    .into_iter()
                    .collect(),
            },
            CheckPoint {
                name: "beyond".into(),
                inputs: [("a".to_string(), 45.0), ("b".to_string(), 15.0)]
                    .into_iter()
                    .collect(),
            },
        ],
        check_tolerance: 1e-9,
        provenance: None,
        envelope_flag: None,
    }
}

#[test]
fn writer_round_trip_reproduces_values_and_passes_its_checks() {
    let s = spec();
    let dir = std::env::temp_dir().join(format!("aerodelta-daveml-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let path = dir.join("rt.dml");
    let written = write_model(&s, &path).expect("write");
    let m = DaveModel::from_file(&path).expect("read back");
    assert_eq!(m.name(), "round trip");
    let rows = m.run_checks();
    // 3 shots x (2 outputs + 5 internal values)
    assert_eq!(rows.len(), 21);
    assert!(rows.iter().all(|r| r.pass && r.actual == r.expected));
    // Closed form at the "mid" point: Ta(7.3) interpolated, Tab bilinear, input limits.
    let v = m.evaluate(&[("a", 7.3), ("b", -4.1)]).expect("eval");
    let ta = -0.2 + (0.3 + 0.2) * 0.73;
    let fb = (-4.1 + 10.0) / 20.0;
    let row = |i: usize| {
        (f64::from(2 * i as u32) * 0.1 - 0.35) * (1.0 - fb)
            + (f64::from(2 * i as u32 + 1) * 0.1 - 0.35) * fb
    };
    let tab = row(1) * 0.27 + row(2) * 0.73;
    let c = ta * -4.1 + 0.5 * tab - 0.01;
    assert!((v[m.index_of("C").expect("C")] - c).abs() < 1e-14);
    // "beyond": a = 45 is limited to maxValue 30, then Tab extrapolates linearly to 30.
    let v = m.evaluate(&[("a", 45.0), ("b", 15.0)]).expect("eval");
    let w = written.evaluate(&[("a", 30.0), ("b", 15.0)]).expect("eval");
    assert_eq!(v, w);
    let outs: Vec<&str> = m.outputs().iter().map(|v| v.id.as_str()).collect();
    assert_eq!(outs, vec!["Tab", "C"]);
    assert!(std::fs::read_dir(&dir).expect("dir").all(|e| !e
        .expect("entry")
        .file_name()
        .to_string_lossy()
        .contains(".tmp-")));
    std::fs::remove_dir_all(&dir).expect("cleanup");
}

#[test]
fn writer_rejects_bad_specs_by_name() {
    let mut s = spec();
    s.tables[0].args[0] = "zz".into();
    let e = to_xml(&s).expect_err("unknown arg");
    assert!(
        e.to_string()
            .contains("table 'Ta': argument 'zz' is not an input"),
        "{e}"
    );
    let mut s = spec();
    s.tables[1].values.pop();
    let e = to_xml(&s).expect_err("size");
    assert!(
        e.to_string().contains("table 'Tab'") && e.to_string().contains("need 8"),
        "{e}"
    );
    let mut s = spec();
    s.checks[0].inputs.insert("q".into(), 1.0);
    let e = to_xml(&s).expect_err("unknown input");
    assert!(e.to_string().contains("check point 'zero'"), "{e}");
    let json = serde_json::to_string(&spec()).expect("json");
    assert_eq!(ModelSpec::from_json(&json).expect("back"), spec());
}

#[test]
fn fast_1d_2d_lookups_equal_table_eval_bit_for_bit() {
    use crate::table::{Axis, Extrapolation, Table};
    let ax = |n: &str, b: &[f64], e: Extrapolation| {
        Axis::new(n, b.to_vec())
            .expect("axis")
            .with_extrapolation(e, e)
            .with_limits(Some(-7.0), None)
            .expect("limits")
    };
    for e in [Extrapolation::Hold, Extrapolation::Linear] {
        let bx = [-2.0, 0.0, 1.5, 4.0];
        let by = [0.0, 0.7, 3.0];
        let t1 = Table::new(vec![ax("x", &bx, e)], vec![0.3, -1.1, 2.7, 0.9]).expect("t1");
        let v2: Vec<f64> = (0..12).map(|k| (f64::from(k) * 0.37).sin()).collect();
        let t2 = Table::new(vec![ax("x", &bx, e), ax("y", &by, e)], v2).expect("t2");
        let t2s = Table::new(
            vec![ax("x", &bx, e), ax("y", &[1.0], e)],
            vec![1.0, 2.0, 4.0, 8.0],
        )
        .expect("t2s");
        for k in 0..400 {
            let x = -9.0 + f64::from(k) * 0.035;
            let y = 4.5 - f64::from(k) * 0.021;
            assert_eq!(model::lookup_1d(&t1, x).to_bits(), t1.eval(&[x]).to_bits());
            assert_eq!(
                model::lookup_2d(&t2, x, y).to_bits(),
                t2.eval(&[x, y]).to_bits()
            );
            assert_eq!(
                model::lookup_2d(&t2s, x, y).to_bits(),
                t2s.eval(&[x, y]).to_bits()
            );
        }
        assert!(model::lookup_1d(&t1, f64::NAN).is_nan());
    }
}

/// The envelope flag written as MathML and evaluated by this crate's DAVE-ML engine equals
/// [`crate::envelope::Envelope::contains`] on band edges (alpha an exact multiple of the band
/// and the next float below), holes, negative bands, flap ties, flaps beyond the settings, a
/// flap setting without a covered band, non-finite inputs; and one flap setting alone.
#[test]
fn envelope_flag_mathml_equals_the_envelope_rule() {
    use crate::envelope::{Envelope, EnvelopeBand, EnvelopeSpec};
    let band = |band, lo, hi| EnvelopeBand {
        band,
        beta_min_deg: lo,
        beta_max_deg: hi,
        maneuvers: 5,
    };
    let envs = [
        EnvelopeSpec {
            band_deg: 1.0,
            flaps_deg: vec![0.0, 10.0, 20.0],
            bands: vec![
                vec![
                    band(-2, -3.0, 3.0),
                    band(0, -6.0, 6.0),
                    band(1, -6.0, 6.0),
                    band(3, -7.0, 2.0),
                ],
                vec![],
                vec![band(5, -1.0, 1.0), band(6, -5.0, 5.0), band(8, -7.0, 7.0)],
            ],
            min_maneuvers: 5,
        },
        EnvelopeSpec {
            band_deg: 0.5,
            flaps_deg: vec![15.0],
            bands: vec![vec![
                band(6, -4.0, 4.0),
                band(7, -6.0, 3.0),
                band(9, -2.0, 2.0),
            ]],
            min_maneuvers: 5,
        },
    ];
    let mut rng = crate::sim::rng::Stream::new(5, 1);
    for (k, env) in envs.iter().enumerate() {
        let spec = ModelSpec::from_json(
            r#"{"name": "flag", "inputs": [{"id": "flap", "units": "deg"},
                {"id": "alpha", "units": "deg"}, {"id": "beta", "units": "deg"}], "outputs": []}"#,
        )
        .expect("spec");
        let spec = ModelSpec {
            envelope_flag: Some(super::write::EnvelopeFlagSpec {
                id: "in_envelope".into(),
                description: String::new(),
                flap: "flap".into(),
                alpha: "alpha".into(),
                beta: "beta".into(),
                envelope: env.clone(),
            }),
            ..spec
        };
        let m = DaveModel::from_str(&to_xml(&spec).expect("xml"), "flag.dml").expect("parse");
        let out = m.index_of("in_envelope").expect("flag");
        let e = Envelope::new(env.clone()).expect("envelope");
        let mut flaps = vec![-3.0, 0.0, 4.0, 5.0, 10.0, 15.0, 16.0, 20.0, 27.0];
        flaps.extend([5.0_f64.next_up(), 15.0_f64.next_down()]);
        let covered = env.bands.iter().flatten().map(|b| b.band);
        let (b0, b1) = (
            covered.clone().min().unwrap_or(0),
            covered.max().unwrap_or(0),
        );
        let mut seen = [0usize; 2];
        for i in 0..3000 {
            let flap = flaps[i % flaps.len()];
            // the covered bands and one band either side
            let mut alpha = env.band_deg * ((b0 - 1) as f64 + (b1 - b0 + 3) as f64 * rng.uniform());
            if i % 3 == 0 {
                alpha = (alpha / env.band_deg).round() * env.band_deg; // a band edge
            } else if i % 3 == 1 {
                alpha = ((alpha / env.band_deg).round() * env.band_deg).next_down();
            }
            let beta = if i % 5 == 0 {
                [-7.0, -6.0, -3.0, 2.0, 3.0, 6.0][i % 6]
            } else {
                -7.0 + 14.0 * rng.uniform()
            };
            let got = m
                .evaluate(&[("flap", flap), ("alpha", alpha), ("beta", beta)])
                .expect("evaluate")[out];
            let want = e.contains(flap, alpha, beta);
            assert_eq!(
                got,
                f64::from(u8::from(want)),
                "{k}: flap {flap} alpha {alpha} beta {beta}"
            );
            seen[usize::from(want)] += 1;
        }
        assert!(seen[0] > 300 && seen[1] > 300, "{seen:?}");
        for bad in [
            (f64::NAN, 2.5, 0.0),
            (0.0, f64::NAN, 0.0),
            (0.0, 0.5, f64::NAN),
            (f64::INFINITY, 3.2, 0.0),
        ] {
            let v = m
                .evaluate(&[("flap", bad.0), ("alpha", bad.1), ("beta", bad.2)])
                .expect("evaluate")[out];
            assert_eq!(v, 0.0, "{bad:?}");
        }
    }
}
