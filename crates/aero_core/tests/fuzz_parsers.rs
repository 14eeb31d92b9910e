//! Property tests of the parsers that read user files (issue 18): DAVE-ML,
//! MathML, regressor expressions and the Δ model JSON, each on a few hundred
//! structured inputs (mutations of valid files, nesting 10 to 100,000 deep,
//! long tokens, special numbers, repeated elements, entity tricks, invalid
//! UTF-8, empty input; random valid expressions checked against a value
//! computed here). Each case runs on its own thread with a 2 MiB stack and
//! must end within a minute (debug build), with `Ok` or a typed one-line
//! error naming the file, and a parse heap within the floor: 20 times the
//! input plus 64 KiB, for every parser.
//!
//! The floor itself (10^5 cases per parser, release) is run by
//! `benchmarks/fuzz_parsers.sh`; the seeds here are fixed, so a failure
//! reproduces.

mod fuzz_support;

use std::cell::Cell;
use std::sync::Arc;
use std::time::Duration;

use fuzz_support::{
    cases, daveml_seeds, measure, Parser, Scale, Verdict, Violation, FLOOR_RATIO, FLOOR_SLACK,
};
use proptest::test_runner::{Config, RngSeed, TestCaseError, TestRunner};

/// Longest a case may run in a debug build before it counts as a hang.
const LIMIT: Duration = Duration::from_secs(60);

/// Public models larger than this are mutated only by the floor runner.
const SEED_BYTES: usize = 200_000;

fn run(parser: Parser, n: u32, seed: u64) {
    let (seeds, _) = daveml_seeds(SEED_BYTES);
    let strategy = cases(parser, Arc::new(seeds), Scale { big: false });
    let mut runner = TestRunner::new(Config {
        cases: n,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        max_shrink_iters: 64,
        ..Config::default()
    });
    let ratio = FLOOR_RATIO;
    let (ok, refused, largest) = (Cell::new(0u32), Cell::new(0u32), Cell::new(0usize));
    let outcome = runner.run(&strategy, |c| {
        let (len, origin) = (c.bytes.len(), c.origin.clone());
        largest.set(largest.get().max(len));
        let what = |msg: String| TestCaseError::fail(format!("{origin} ({len} bytes): {msg}"));
        let m = measure(parser, Arc::new(c), LIMIT).map_err(what)?;
        match m.verdict {
            Ok(Verdict::Ok) => ok.set(ok.get() + 1),
            Ok(Verdict::Refused(_)) => refused.set(refused.get() + 1),
            Err(Violation(v)) => return Err(what(v)),
        }
        if m.parse.peak > ratio * len + FLOOR_SLACK {
            return Err(what(format!(
                "the parse used {} bytes of heap, over {ratio} x {len} + {FLOOR_SLACK}",
                m.parse.peak
            )));
        }
        Ok(())
    });
    if let Err(e) = outcome {
        panic!("{}: {e}", parser.name());
    }
    eprintln!(
        "{}: {} cases, {} ok, {} refused, largest input {} bytes",
        parser.name(),
        n,
        ok.get(),
        refused.get(),
        largest.get()
    );
    // The generators reach both outcomes and large inputs.
    assert_eq!(ok.get() + refused.get(), n);
    assert!(
        ok.get() >= n / 20 && refused.get() >= n / 5,
        "{} ok, {} refused",
        ok.get(),
        refused.get()
    );
    assert!(
        largest.get() > 100_000,
        "largest input {} bytes",
        largest.get()
    );
}

#[test]
fn daveml_reader_returns_ok_or_a_typed_error() {
    run(Parser::DaveMl, 400, 0xDA7E_0001);
}

#[test]
fn mathml_compiler_returns_ok_or_a_typed_error_and_valid_math_evaluates_right() {
    run(Parser::MathMl, 600, 0x3A7E_0002);
}

#[test]
fn regressor_parser_returns_ok_or_a_typed_error_and_valid_expressions_evaluate_right() {
    run(Parser::Regressor, 1500, 0x4E90_0003);
}

#[test]
fn model_file_reader_returns_ok_or_a_typed_error() {
    run(Parser::ModelFile, 400, 0x30DE_0004);
}
