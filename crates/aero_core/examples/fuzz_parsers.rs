//! The fuzzing floor of issue 18: 10^5 structured cases per parser (DAVE-ML,
//! MathML, regressor, model file), each on a fresh 2 MiB-stack thread,
//! counting Ok and refused inputs, crashes (panics), hangs (a parse over the
//! hang threshold; a case still running after 120 s stops the run), contract
//! violations (an error that is not a typed
//! one-line message naming the file, a valid expression evaluating wrong), and
//! the peak heap of each parse (a counting allocator, reset per case) against
//! the floor of 20 times the input (plus 64 KiB of fixed cost).
//!
//! ```text
//! cargo run --release -p aero_core --example fuzz_parsers -- --cases 100000
//! cargo run --release -p aero_core --example fuzz_parsers -- --parser mathml --cases 1000 --start 500
//! cargo run --release -p aero_core --example fuzz_parsers -- --parser daveml --replay failing.bin
//! ```
//! Options: `--cases N` per parser (100000), `--parser NAME` (repeatable;
//! daveml, mathml, regressor, model-file; all by default), `--seed S` (18),
//! `--start K` (first case index: case K of a seed is always the same input),
//! `--hang-ms` (1000), `--save DIR` (inputs of failing cases;
//! `target/fuzz-failures`), `--replay FILE`. Exit status 1 when a floor fails.

#[path = "../tests/fuzz_support/mod.rs"]
mod fuzz_support;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use fuzz_support::{
    cases, daveml_seeds, floor_bytes, measure, Case, Parser, Scale, Verdict, Violation,
    FLOOR_RATIO, FLOOR_SLACK,
};
use proptest::strategy::{Strategy, ValueTree};
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

/// A case still running after this long is stopped and the run fails.
const ABORT_AFTER: Duration = Duration::from_secs(120);

/// Inputs at least this large are "large" for the ratio reported.
const LARGE: usize = 64 << 10;

#[derive(Debug)]
struct Args {
    cases: u64,
    parsers: Vec<Parser>,
    seed: u64,
    start: u64,
    hang: Duration,
    save: PathBuf,
    replay: Option<PathBuf>,
    classes: bool,
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        cases: 100_000,
        parsers: Vec::new(),
        seed: 18,
        start: 0,
        hang: Duration::from_millis(1000),
        save: PathBuf::from(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../target/fuzz-failures"
        )),
        replay: None,
        classes: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let mut val = || it.next().ok_or_else(|| format!("{k} needs a value"));
        let num = |v: String| {
            v.parse::<u64>()
                .map_err(|_| format!("{k}: '{v}' is not a whole number"))
        };
        match k.as_str() {
            "--cases" => a.cases = num(val()?)?,
            "--seed" => a.seed = num(val()?)?,
            "--start" => a.start = num(val()?)?,
            "--hang-ms" => a.hang = Duration::from_millis(num(val()?)?),
            "--save" => a.save = PathBuf::from(val()?),
            "--replay" => a.replay = Some(PathBuf::from(val()?)),
            "--classes" => a.classes = true,
            "--parser" => {
                let v = val()?;
                let p = Parser::ALL
                    .into_iter()
                    .find(|p| p.name() == v)
                    .ok_or_else(|| format!("--parser: '{v}' is not one of daveml, mathml, regressor, model-file"))?;
                a.parsers.push(p);
            }
            "-h" | "--help" => {
                return Err("usage: fuzz_parsers [--cases N] [--parser NAME]... [--seed S] [--start K] [--hang-ms MS] [--save DIR] [--replay FILE]".into())
            }
            other => return Err(format!("unknown option '{other}'; see --help")),
        }
    }
    if a.parsers.is_empty() {
        a.parsers = Parser::ALL.to_vec();
    }
    Ok(a)
}

/// Case `i` of parser `p` under `seed`: the same input on every run.
fn draw(strategy: &proptest::strategy::BoxedStrategy<Case>, seed: u64, p: Parser, i: u64) -> Case {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&i.to_le_bytes());
    key[16] = p as u8;
    let rng = TestRng::from_seed(RngAlgorithm::ChaCha, &key);
    let mut runner = TestRunner::new_with_rng(Config::default(), rng);
    match strategy.new_tree(&mut runner) {
        Ok(t) => t.current(),
        Err(e) => panic!("the generator failed: {e}"),
    }
}

#[derive(Debug, Default)]
struct Stats {
    cases: u64,
    ok: u64,
    refused: u64,
    crashes: u64,
    hangs: u64,
    violations: u64,
    over_floor: u64,
    max_wall: Duration,
    max_parse_wall: Duration,
    total_wall: Duration,
    max_bytes: usize,
    /// (peak / input, input bytes, peak, origin) of the worst large input.
    worst_large: Option<(f64, usize, usize, String)>,
    /// (peak - floor, input bytes, peak, origin) of the case closest to (or over) the floor.
    worst_floor: Option<(i64, usize, usize, String)>,
    /// Largest peak of a small input.
    max_small_peak: usize,
    /// Per input class (the origin up to its first parenthesis): cases over
    /// the floor, and the worst (peak / input, case, input bytes).
    over_by_class: std::collections::BTreeMap<String, (u64, f64, u64, usize)>,
    examples: Vec<String>,
}

fn save(dir: &PathBuf, p: Parser, i: u64, what: &str, case: &Case) -> String {
    let _ = std::fs::create_dir_all(dir);
    let f = dir.join(format!("{}-{i}-{what}.bin", p.name()));
    match std::fs::write(&f, &case.bytes) {
        Ok(()) => f.display().to_string(),
        Err(e) => format!("(not saved: {e})"),
    }
}

fn note(st: &mut Stats, line: String) {
    if st.examples.len() < 12 {
        eprintln!("  {line}");
        st.examples.push(line);
    }
}

fn run_parser(args: &Args, p: Parser, strategy: &proptest::strategy::BoxedStrategy<Case>) -> Stats {
    let mut st = Stats::default();
    let t_start = Instant::now();
    for i in args.start..args.start + args.cases {
        if (i - args.start) % 10_000 == 0 && i > args.start {
            eprintln!(
                "  {}: {} cases in {:.0} s",
                p.name(),
                i - args.start,
                t_start.elapsed().as_secs_f64()
            );
        }
        let case = Arc::new(draw(strategy, args.seed, p, i));
        let len = case.bytes.len();
        st.cases += 1;
        st.max_bytes = st.max_bytes.max(len);
        let m = match measure(p, case.clone(), ABORT_AFTER) {
            Ok(m) => m,
            Err(e) if e.starts_with("panicked") => {
                st.crashes += 1;
                let f = save(&args.save, p, i, "crash", &case);
                note(
                    &mut st,
                    format!(
                        "CRASH case {i} ({}, {len} bytes): {e}; input {f}",
                        case.origin
                    ),
                );
                continue;
            }
            Err(e) => {
                st.hangs += 1;
                let f = save(&args.save, p, i, "hang", &case);
                note(
                    &mut st,
                    format!(
                        "HANG case {i} ({}, {len} bytes): {e}; input {f}",
                        case.origin
                    ),
                );
                // The stuck thread keeps running: stop here.
                break;
            }
        };
        st.total_wall += m.wall;
        st.max_wall = st.max_wall.max(m.wall);
        st.max_parse_wall = st.max_parse_wall.max(m.parse.wall);
        if m.parse.wall > args.hang {
            st.hangs += 1;
            let f = save(&args.save, p, i, "slow", &case);
            note(
                &mut st,
                format!(
                    "HANG case {i} ({}, {len} bytes): {:.2} s (parse {:.2} s); input {f}",
                    case.origin,
                    m.wall.as_secs_f64(),
                    m.parse.wall.as_secs_f64()
                ),
            );
        }
        match m.verdict {
            Ok(Verdict::Ok) => st.ok += 1,
            Ok(Verdict::Refused(_)) => st.refused += 1,
            Err(Violation(v)) => {
                st.violations += 1;
                let f = save(&args.save, p, i, "violation", &case);
                note(
                    &mut st,
                    format!(
                        "VIOLATION case {i} ({}, {len} bytes): {v}; input {f}",
                        case.origin
                    ),
                );
            }
        }
        let peak = m.parse.peak;
        let excess = peak as i64 - floor_bytes(len) as i64;
        if excess > 0 {
            st.over_floor += 1;
            let class = case.origin.split('(').next().unwrap_or("").to_string();
            let r = peak as f64 / len.max(1) as f64;
            let e = st.over_by_class.entry(class).or_insert((0, 0.0, i, len));
            e.0 += 1;
            if r > e.1 {
                (e.1, e.2, e.3) = (r, i, len);
            }
            let f = save(&args.save, p, i, "memory", &case);
            note(
                &mut st,
                format!("MEMORY case {i} ({}, {len} bytes): parse peak {peak} bytes = {:.1}x; input {f}", case.origin, peak as f64 / len.max(1) as f64),
            );
        }
        if st.worst_floor.as_ref().is_none_or(|w| excess > w.0) {
            st.worst_floor = Some((excess, len, peak, case.origin.clone()));
        }
        if len >= LARGE {
            let r = peak as f64 / len as f64;
            if st.worst_large.as_ref().is_none_or(|w| r > w.0) {
                st.worst_large = Some((r, len, peak, case.origin.clone()));
            }
        } else {
            st.max_small_peak = st.max_small_peak.max(peak);
        }
    }
    st
}

fn report(args: &Args, p: Parser, st: &Stats) -> bool {
    let n = p.name();
    println!(
        "{n}: cases {}, ok {}, refused (typed error) {}, crashes {}, hangs {} (parse over {} ms), violations {}",
        st.cases,
        st.ok,
        st.refused,
        st.crashes,
        st.hangs,
        args.hang.as_millis(),
        st.violations
    );
    println!(
        "{n}: wall per case (parse and uses of its result) max {:.3} s, parse max {:.3} s, mean case {:.2} ms; largest input {} bytes",
        st.max_wall.as_secs_f64(),
        st.max_parse_wall.as_secs_f64(),
        st.total_wall.as_secs_f64() * 1e3 / st.cases.max(1) as f64,
        st.max_bytes
    );
    match &st.worst_large {
        Some((r, len, peak, origin)) => println!(
            "{n}: peak heap / input, inputs >= {} KiB: max {r:.2}x ({peak} bytes for {len} bytes, {origin})",
            LARGE >> 10
        ),
        None => println!("{n}: no input >= {} KiB", LARGE >> 10),
    }
    println!(
        "{n}: largest parse peak of a smaller input {} bytes; over the floor ({FLOOR_RATIO}x input + {} KiB): {} cases{}",
        st.max_small_peak,
        FLOOR_SLACK >> 10,
        st.over_floor,
        st.worst_floor
            .as_ref()
            .map(|(e, len, peak, o)| format!(
                "; closest: {peak} bytes for {len} bytes ({o}), {} the floor by {} bytes",
                if *e > 0 { "over" } else { "under" },
                e.abs()
            ))
            .unwrap_or_default()
    );
    for (class, (count, r, i, len)) in &st.over_by_class {
        println!(
            "{n}: over the floor: {count} cases of {class}, worst {r:.1}x (case {i}, {len} bytes)"
        );
    }
    let pass = st.crashes == 0
        && st.hangs == 0
        && st.violations == 0
        && st.over_floor == 0
        && st.cases == args.cases;
    println!("{} {n}", if pass { "PASS" } else { "FAIL" });
    pass
}

/// The memory and time of every input class at a few sizes, and of the
/// public models as they are.
fn profile_classes(args: &Args, seeds: &[Vec<u8>], names: &[String]) {
    println!(
        "parser | class | n | input bytes | parse peak bytes | peak / input | parse ms | verdict"
    );
    let row = |p: Parser, name: &str, n: usize, bytes: Vec<u8>| {
        let len = bytes.len();
        let case = Case {
            bytes,
            oracle: None,
            origin: name.into(),
        };
        match measure(p, Arc::new(case), ABORT_AFTER) {
            Ok(m) => println!(
                "{} | {name} | {n} | {len} | {} | {:.2} | {:.1} | {}",
                p.name(),
                m.parse.peak,
                m.parse.peak as f64 / len.max(1) as f64,
                m.parse.wall.as_secs_f64() * 1e3,
                match &m.verdict {
                    Ok(Verdict::Ok) => "ok".to_string(),
                    Ok(Verdict::Refused(k)) => format!("refused ({k})"),
                    Err(Violation(v)) =>
                        format!("VIOLATION {}", v.chars().take(200).collect::<String>()),
                }
            ),
            Err(e) => println!("{} | {name} | {n} | {len} | - | - | - | {e}", p.name()),
        }
    };
    for (bytes, name) in seeds.iter().zip(names) {
        row(Parser::DaveMl, name, 1, bytes.clone());
    }
    for (p, name, make) in fuzz_support::classes() {
        if !args.parsers.contains(&p) {
            continue;
        }
        for n in [1_000usize, 30_000, 300_000] {
            let bytes = make(n);
            if bytes.len() > 64 << 20 {
                println!(
                    "{} | {name} | {n} | {} | (skipped: over 64 MiB)",
                    p.name(),
                    bytes.len()
                );
                continue;
            }
            row(p, &name, n, bytes);
        }
    }
}

fn main() {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("fuzz_parsers: {e}");
            std::process::exit(2);
        }
    };
    let (seeds, names) = daveml_seeds(usize::MAX);
    if let Some(f) = &args.replay {
        let bytes = match std::fs::read(f) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("fuzz_parsers: {}: {e}", f.display());
                std::process::exit(2);
            }
        };
        for &p in &args.parsers {
            let case = Case {
                bytes: bytes.clone(),
                oracle: None,
                origin: "replay".into(),
            };
            let m = measure(p, Arc::new(case), ABORT_AFTER);
            println!("{}: {m:?}", p.name());
        }
        return;
    }
    if args.classes {
        profile_classes(&args, &seeds, &names);
        return;
    }
    println!(
        "fuzz_parsers: {} cases per parser, seed {}, first case {}; DAVE-ML seeds: {}",
        args.cases,
        args.seed,
        args.start,
        names.join(", ")
    );
    let seeds = Arc::new(seeds);
    let mut all = true;
    for &p in &args.parsers {
        let strategy = cases(p, seeds.clone(), Scale { big: true });
        let t0 = Instant::now();
        let st = run_parser(&args, p, &strategy);
        all &= report(&args, p, &st);
        println!("{}: {:.0} s", p.name(), t0.elapsed().as_secs_f64());
    }
    println!("{}", if all { "PASS all" } else { "FAIL" });
    if !all {
        std::process::exit(1);
    }
}
