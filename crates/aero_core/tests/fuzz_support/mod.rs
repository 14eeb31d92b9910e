//! Structured fuzzing of the four parsers that read user files (issue 18):
//! DAVE-ML, the MathML of its calculations, regressor expressions and the Δ
//! model JSON. Shared by the property tests (`tests/fuzz_parsers.rs`, a few
//! hundred cases in the normal `cargo test`) and the floor runner
//! (`examples/fuzz_parsers.rs`, 10^5 cases per parser in release with a
//! counting allocator).
//!
//! Every input is drawn from a proptest strategy, so a seed fixes it:
//! - mutations of valid inputs (built-in DAVE-ML written by the crate's own
//!   writer and hand-written forms, the public models when found, regressors of
//!   the fit's candidate vocabulary, a model JSON written by
//!   [`DeltaModel::to_json`]): bit flips, byte changes, truncation, deletion,
//!   insertion of grammar tokens, repetition of a slice, insertion of nesting;
//! - adversaries: nesting 10 to 100,000 deep, long tokens, huge and special
//!   numbers, many breakpoints, repeated elements, entity tricks, invalid
//!   UTF-8, empty input;
//! - for MathML and regressors also random *valid* expressions with their
//!   value computed here independently, checked against the parser's.
//!
//! [`check`] runs one parser on one input and returns the verdict; anything
//! that is not `Ok` or a typed one-line error is a [`Violation`].

#![allow(dead_code)] // each user (test, example) calls a different part

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

use aero_core::daveml::{merge_xml, DaveModel, ModelSpec};
use aero_core::delta_model::DeltaModel;
use aero_core::regressor::Expr;
use aero_core::{AeroError, ErrorKind};
use proptest::prelude::*;
use proptest::sample::Index;

/// The four parsers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Parser {
    DaveMl,
    MathMl,
    Regressor,
    ModelFile,
}

impl Parser {
    pub const ALL: [Parser; 4] = [
        Parser::DaveMl,
        Parser::MathMl,
        Parser::Regressor,
        Parser::ModelFile,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Parser::DaveMl => "daveml",
            Parser::MathMl => "mathml",
            Parser::Regressor => "regressor",
            Parser::ModelFile => "model-file",
        }
    }
}

/// Longest error message accepted, in characters: one line a person reads.
pub const MAX_MESSAGE: usize = 1000;

/// Stack of the thread each case runs on: Rust's default for spawned threads,
/// smaller than a Python main thread's, so no parser leans on a big stack.
pub const CASE_STACK: usize = 2 << 20;

/// One generated input, with the value a valid expression must evaluate to
/// when the generator knows it.
#[derive(Clone)]
pub struct Case {
    pub bytes: Vec<u8>,
    /// (inputs by name, expected value) for generated valid expressions.
    pub oracle: Option<Oracle>,
    /// What made it: "mutation", "valid", or the adversary's name.
    pub origin: String,
}

impl std::fmt::Debug for Case {
    /// The origin, the size and the first 300 bytes (inputs run to megabytes).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let head = String::from_utf8_lossy(&self.bytes[..self.bytes.len().min(300)]);
        write!(
            f,
            "Case {{ origin: {:?}, {} bytes, starting {head:?}, oracle: {:?} }}",
            self.origin,
            self.bytes.len(),
            self.oracle
        )
    }
}

#[derive(Debug, Clone)]
pub struct Oracle {
    pub inputs: Vec<(String, f64)>,
    pub expected: f64,
}

/// How a case ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    Ok,
    /// Refused with a typed error (its kind).
    Refused(ErrorKind),
}

/// Not `Ok` nor a typed one-line error, or a valid expression evaluating wrong.
#[derive(Debug, Clone)]
pub struct Violation(pub String);

// ---------------------------------------------------------------------------
// Heap accounting.

/// A counting allocator over [`System`](std::alloc::System): the bytes live
/// and their peak, per thread (a case runs on one thread, tests in parallel
/// on several). A `realloc` counts as allocating the new block before freeing
/// the old one, so a growing vector's peak includes both (an upper bound: the
/// system may grow it in place).
#[allow(unsafe_code)]
pub mod heap {
    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    thread_local! {
        static LIVE: Cell<isize> = const { Cell::new(0) };
        static PEAK: Cell<isize> = const { Cell::new(0) };
    }

    fn add(n: isize) {
        let _ = LIVE.try_with(|l| {
            let v = l.get() + n;
            l.set(v);
            let _ = PEAK.try_with(|p| {
                if v > p.get() {
                    p.set(v);
                }
            });
        });
    }

    #[derive(Debug)]
    pub struct Counting;

    // SAFETY: every call is forwarded to `System` unchanged; the counters are
    // plain thread-local cells that never allocate.
    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, l: Layout) -> *mut u8 {
            let p = unsafe { System.alloc(l) };
            if !p.is_null() {
                add(l.size() as isize);
            }
            p
        }
        unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
            let p = unsafe { System.alloc_zeroed(l) };
            if !p.is_null() {
                add(l.size() as isize);
            }
            p
        }
        unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
            unsafe { System.dealloc(p, l) };
            add(-(l.size() as isize));
        }
        unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
            let q = unsafe { System.realloc(p, l, new) };
            if !q.is_null() {
                add(new as isize);
                add(-(l.size() as isize));
            }
            q
        }
    }

    #[global_allocator]
    static ALLOCATOR: Counting = Counting;

    /// Start measuring on this thread: the peak restarts from the live bytes,
    /// which are returned.
    pub fn start() -> isize {
        let live = LIVE.with(Cell::get);
        PEAK.with(|p| p.set(live));
        live
    }

    /// Highest live bytes on this thread since [`start`] returned `base`, above `base`.
    pub fn peak_since(base: isize) -> usize {
        (PEAK.with(Cell::get) - base).max(0) as usize
    }
}

/// The memory floor of issue 18: a parse may use 20 times its input, plus a
/// fixed [`FLOOR_SLACK`] for what every parse allocates whatever the input
/// (error messages, hash tables, the first chunk of each vector).
pub const FLOOR_RATIO: usize = 20;

/// See [`FLOOR_RATIO`].
pub const FLOOR_SLACK: usize = 64 << 10;

/// The heap a parse of `len` bytes may use.
pub fn floor_bytes(len: usize) -> usize {
    FLOOR_RATIO * len + FLOOR_SLACK
}

/// The parse proper of a case (not the uses of its result that follow).
#[derive(Debug, Clone, Copy, Default)]
pub struct Probe {
    /// Highest heap above what was live before, bytes, the result included.
    pub peak: usize,
    pub wall: Duration,
}

fn timed<T>(probe: &mut Probe, f: impl FnOnce() -> T) -> T {
    let base = heap::start();
    let t0 = Instant::now();
    let out = f();
    probe.wall = t0.elapsed();
    probe.peak = heap::peak_since(base);
    out
}

/// One measured case.
#[derive(Debug, Clone)]
pub struct Measured {
    pub verdict: Result<Verdict, Violation>,
    /// The parse.
    pub parse: Probe,
    /// The whole case: parse and uses.
    pub wall: Duration,
}

/// Run `parser` on `case` on a fresh thread ([`bounded`]), measuring the
/// heap's peak and the wall time of the check.
pub fn measure(parser: Parser, case: Arc<Case>, limit: Duration) -> Result<Measured, String> {
    let (m, _) = bounded(limit, move || {
        let mut parse = Probe::default();
        let t0 = Instant::now();
        let verdict = check(parser, &case, &mut parse);
        Measured {
            verdict,
            parse,
            wall: t0.elapsed(),
        }
    })?;
    Ok(m)
}

// ---------------------------------------------------------------------------
// Running one case.

/// Run `parser` on `case`: the parse, then (when it succeeds) a use of the
/// result that must not fail unexpectedly either.
pub fn check(parser: Parser, case: &Case, probe: &mut Probe) -> Result<Verdict, Violation> {
    match parser {
        Parser::DaveMl => check_daveml(case, true, probe),
        Parser::MathMl => check_daveml(case, false, probe),
        Parser::Regressor => check_regressor(case, probe),
        Parser::ModelFile => check_model(&case.bytes, probe),
    }
}

/// `got` equals `want` to 1e-9 relative, or both are NaN, or the same infinity.
fn agree(what: &str, got: f64, want: f64) -> Result<(), Violation> {
    let ok = (got.is_nan() && want.is_nan())
        || got == want
        || (got.is_finite()
            && want.is_finite()
            && (got - want).abs() <= 1e-9 * want.abs().max(1.0));
    if ok {
        Ok(())
    } else {
        Err(Violation(format!(
            "{what} evaluates to {got}, the reference to {want}"
        )))
    }
}

/// An error must be one of `kinds`, one short line, and start with `prefix`.
fn typed(e: &AeroError, kinds: &[ErrorKind], prefix: &str) -> Result<Verdict, Violation> {
    let msg = e.to_string();
    let short: String = msg.chars().take(300).collect();
    if !kinds.contains(&e.kind()) {
        return Err(Violation(format!("error of kind {:?}: {short}", e.kind())));
    }
    if msg.trim().len() <= prefix.len() + 2 {
        return Err(Violation(format!("empty message: {msg:?}")));
    }
    if msg.contains(['\n', '\r']) {
        return Err(Violation(format!("message of several lines: {short:?}")));
    }
    let n = msg.chars().count();
    if n > MAX_MESSAGE {
        return Err(Violation(format!(
            "message of {n} characters (at most {MAX_MESSAGE}): {short}..."
        )));
    }
    if !msg.starts_with(prefix) {
        return Err(Violation(format!("message not naming '{prefix}': {short}")));
    }
    Ok(Verdict::Refused(e.kind()))
}

/// A fixed addition merged into every DAVE-ML file that loads: the path of an
/// aero database receiving its Δ model.
const ADDITION: &str = r#"{"name": "delta", "inputs": [{"id": "fz_alpha", "units": "deg", "initial": 1}],
  "tables": [{"id": "fz_t", "args": ["fz_alpha"], "breakpoints": [[0, 10]], "values": [0, 1]}],
  "outputs": [{"id": "fz_out", "terms": [{"coef": 2, "factors": ["fz_t"]}]}],
  "checks": [{"name": "c", "inputs": {"fz_alpha": 5}}]}"#;

fn check_daveml(case: &Case, merge: bool, probe: &mut Probe) -> Result<Verdict, Violation> {
    let m = match timed(probe, || DaveModel::from_bytes(&case.bytes, "m.dml")) {
        Ok(m) => m,
        Err(e) if case.oracle.is_some() => {
            return Err(Violation(format!("valid MathML refused: {e}")))
        }
        Err(e) => return typed(&e, &[ErrorKind::Parse], "m.dml:"),
    };
    // Evaluate with every input lacking an initial value set, and run the
    // file's own checks: neither may panic, whatever the values.
    let given: Vec<(&str, f64)> = m
        .variables()
        .iter()
        .enumerate()
        .filter(|(i, v)| m.is_free(*i) && v.initial_value.is_none())
        .map(|(_, v)| (v.id.as_str(), 0.25))
        .collect();
    let vals = m
        .evaluate(&given)
        .map_err(|e| Violation(format!("evaluate of a loaded model: {e}")))?;
    if let Some(o) = &case.oracle {
        let out = m
            .index_of("out")
            .ok_or_else(|| Violation("no variable 'out'".into()))?;
        agree("MathML", vals[out], o.expected)?;
    }
    let _ = m.run_checks();
    // The merge re-reads the file twice: done on files up to 256 KiB.
    if merge && case.bytes.len() <= 256 << 10 {
        let text = String::from_utf8_lossy(&case.bytes);
        let spec = ModelSpec::from_json(ADDITION).map_err(|e| Violation(e.to_string()))?;
        match merge_xml(&text, "m.dml", &spec) {
            Ok(merged) => {
                if let Err(e) = DaveModel::from_str(&merged, "merged.dml") {
                    typed(&e, &[ErrorKind::Parse], "merged.dml:")?;
                }
            }
            Err(e) => {
                // A base the addition cannot extend (a required input its
                // check points do not give, a clash of ids) is refused.
                typed(&e, &[ErrorKind::Parse, ErrorKind::InvalidInput], "")?;
            }
        }
    }
    Ok(Verdict::Ok)
}

fn check_regressor(case: &Case, probe: &mut Probe) -> Result<Verdict, Violation> {
    let src = String::from_utf8_lossy(&case.bytes);
    let e = match timed(probe, || Expr::parse(&src)) {
        Ok(e) => e,
        Err(err) => {
            if case.oracle.is_some() {
                return Err(Violation(format!("valid regressor refused: {err}")));
            }
            return typed(&err, &[ErrorKind::InvalidInput], "regressor '");
        }
    };
    // Every evaluation path: point, columns and bound (real-time) agree.
    let cols = e.columns();
    let given: Vec<(String, f64)> = match &case.oracle {
        Some(o) => o.inputs.clone(),
        None => cols
            .iter()
            .enumerate()
            .map(|(k, c)| (c.clone(), 0.5 + k as f64))
            .collect(),
    };
    let lookup = |n: &str| given.iter().find(|(k, _)| k == n).map(|p| p.1);
    let point = e.eval_point(&lookup);
    let colvals: Vec<(String, [f64; 1])> = given.iter().map(|(k, x)| (k.clone(), [*x])).collect();
    let by_col = |n: &str| colvals.iter().find(|(k, _)| k == n).map(|p| &p.1[..]);
    let columns = e
        .eval_columns(&by_col, 1)
        .map_err(|err| Violation(format!("eval_columns of a parsed regressor: {err}")))?;
    agree("eval_columns vs eval_point", columns[0], point)?;
    let layout: Vec<&str> = given.iter().map(|(k, _)| k.as_str()).collect();
    let state: Vec<f64> = given.iter().map(|p| p.1).collect();
    match e.bind(&layout) {
        Ok(b) => agree("bound vs eval_point", b.eval(&state), point)?,
        Err(err) => {
            typed(&err, &[ErrorKind::InvalidInput], "regressor")?;
        }
    }
    if let Some(o) = &case.oracle {
        agree("regressor", point, o.expected)?;
    }
    Ok(Verdict::Ok)
}

fn check_model(bytes: &[u8], probe: &mut Probe) -> Result<Verdict, Violation> {
    let m = match timed(probe, || DeltaModel::from_slice(bytes, "model.json")) {
        Ok(m) => m,
        Err(e) => {
            return typed(
                &e,
                &[ErrorKind::Parse, ErrorKind::InvalidInput],
                "model.json",
            )
        }
    };
    // Written back and read again it is the same model.
    let json = m
        .to_json()
        .map_err(|e| Violation(format!("to_json of a loaded model: {e}")))?;
    let again = DeltaModel::from_json(&json, "again.json")
        .map_err(|e| Violation(format!("a loaded model written back does not load: {e}")))?;
    if again.spec() != m.spec() {
        return Err(Violation("a loaded model written back differs".into()));
    }
    // Evaluated at one point of its inputs: no panic.
    let cols: std::collections::HashMap<String, [f64; 1]> = m
        .input_columns()
        .into_iter()
        .enumerate()
        .map(|(k, c)| (c, [0.5 + k as f64]))
        .collect();
    let lookup = |n: &str| cols.get(n).map(|v| &v[..]);
    for c in m.coefficient_names() {
        m.eval_columns(&c, &lookup, 1)
            .map_err(|e| Violation(format!("eval_columns of a loaded model: {e}")))?;
    }
    Ok(Verdict::Ok)
}

/// Run `f` on a fresh thread with a [`CASE_STACK`] stack; `Err` when it panics
/// or has not returned within `limit`.
pub fn bounded<T: Send + 'static>(
    limit: Duration,
    f: impl FnOnce() -> T + Send + 'static,
) -> Result<(T, Duration), String> {
    let (tx, rx) = mpsc::channel();
    let handle = std::thread::Builder::new()
        .stack_size(CASE_STACK)
        .spawn(move || {
            let t0 = Instant::now();
            let out = f();
            let _ = tx.send((out, t0.elapsed()));
        })
        .map_err(|e| format!("cannot spawn: {e}"))?;
    match rx.recv_timeout(limit) {
        Ok(out) => {
            let _ = handle.join();
            Ok(out)
        }
        Err(mpsc::RecvTimeoutError::Timeout) => Err(format!("still running after {limit:?}")),
        Err(mpsc::RecvTimeoutError::Disconnected) => match handle.join() {
            Err(p) => Err(format!("panicked: {}", panic_text(&p))),
            Ok(()) => Err("ended without a result".into()),
        },
    }
}

pub fn panic_text(p: &Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".into())
}

// ---------------------------------------------------------------------------
// Generic pieces.

/// A size drawn log-uniformly in `lo..=hi` (shrinks towards `lo`).
pub fn log_uniform(lo: usize, hi: usize) -> BoxedStrategy<usize> {
    let (l, h) = (lo.max(1) as f64, hi as f64);
    (0.0f64..=1.0)
        .prop_map(move |u| ((l * (h / l).powf(u)).round() as usize).clamp(lo, hi))
        .boxed()
}

/// One edit of a byte string.
#[derive(Debug, Clone)]
pub enum Mutation {
    FlipBit(Index, u8),
    SetByte(Index, u8),
    Truncate(Index),
    Delete(Index, usize),
    /// Insert dictionary token `.1` `.2` times.
    Insert(Index, Index, usize),
    /// Repeat the slice at `.0` of length `.1` `.2` more times.
    Repeat(Index, usize, usize),
    /// Wrap the range from `.0` to `.1` in `.3` levels of nesting pair `.2`.
    Nest(Index, Index, Index, usize),
    /// Copy a slice of the input to another place.
    Splice(Index, usize, Index),
}

fn mutation(dict_len: usize, pairs_len: usize, big: bool) -> BoxedStrategy<Mutation> {
    let _ = (dict_len, pairs_len);
    let times = if big {
        log_uniform(1, 20_000)
    } else {
        log_uniform(1, 200)
    };
    let depth = if big {
        log_uniform(1, 100_000)
    } else {
        log_uniform(1, 2_000)
    };
    prop_oneof![
        3 => (any::<Index>(), 0u8..8).prop_map(|(i, b)| Mutation::FlipBit(i, b)),
        2 => (any::<Index>(), any::<u8>()).prop_map(|(i, b)| Mutation::SetByte(i, b)),
        1 => any::<Index>().prop_map(Mutation::Truncate),
        2 => (any::<Index>(), log_uniform(1, 4096)).prop_map(|(i, n)| Mutation::Delete(i, n)),
        4 => (any::<Index>(), any::<Index>(), log_uniform(1, 3))
            .prop_map(|(i, t, n)| Mutation::Insert(i, t, n)),
        1 => (any::<Index>(), any::<Index>(), times.clone())
            .prop_map(|(i, t, n)| Mutation::Insert(i, t, n)),
        1 => (any::<Index>(), log_uniform(1, 4096), times)
            .prop_map(|(i, l, n)| Mutation::Repeat(i, l, n)),
        2 => (any::<Index>(), any::<Index>(), any::<Index>(), depth)
            .prop_map(|(a, b, p, d)| Mutation::Nest(a, b, p, d)),
        1 => (any::<Index>(), log_uniform(1, 4096), any::<Index>())
            .prop_map(|(a, l, b)| Mutation::Splice(a, l, b)),
    ]
    .boxed()
}

/// Apply `muts` to `seed` with the tokens `dict` and nesting pairs `pairs`.
pub fn mutate(seed: &[u8], muts: &[Mutation], dict: &[&[u8]], pairs: &[(&[u8], &[u8])]) -> Vec<u8> {
    let mut b = seed.to_vec();
    let at = |i: &Index, len: usize| if len == 0 { 0 } else { i.index(len + 1) };
    for m in muts {
        let n = b.len();
        match m {
            Mutation::FlipBit(i, bit) => {
                if n > 0 {
                    let k = i.index(n);
                    b[k] ^= 1 << bit;
                }
            }
            Mutation::SetByte(i, v) => {
                if n > 0 {
                    let k = i.index(n);
                    b[k] = *v;
                }
            }
            Mutation::Truncate(i) => b.truncate(at(i, n)),
            Mutation::Delete(i, len) => {
                let k = at(i, n);
                let e = (k + len).min(n);
                b.drain(k..e);
            }
            Mutation::Insert(i, t, times) => {
                let k = at(i, n);
                let tok = dict[t.index(dict.len())];
                let ins = tok.repeat(*times);
                b.splice(k..k, ins);
            }
            Mutation::Repeat(i, len, times) => {
                let k = at(i, n);
                let e = (k + len).min(n);
                let piece = b[k..e].repeat(*times);
                b.splice(e..e, piece);
            }
            Mutation::Nest(x, y, p, depth) => {
                let (mut s, mut e) = (at(x, n), at(y, n));
                if s > e {
                    std::mem::swap(&mut s, &mut e);
                }
                let (open, close) = pairs[p.index(pairs.len())];
                b.splice(e..e, close.repeat(*depth));
                b.splice(s..s, open.repeat(*depth));
            }
            Mutation::Splice(x, len, y) => {
                let k = at(x, n);
                let e = (k + len).min(n);
                let piece = b[k..e].to_vec();
                let to = at(y, n);
                b.splice(to..to, piece);
            }
        }
        // Keep mutated inputs within a few megabytes.
        b.truncate(8 << 20);
    }
    b
}

/// `seeds` mutated by 1 to 8 edits (or up to 40, rarely).
pub fn mutated(
    seeds: Arc<Vec<Vec<u8>>>,
    dict: &'static [&'static [u8]],
    pairs: &'static [(&'static [u8], &'static [u8])],
    big: bool,
) -> BoxedStrategy<Case> {
    let edits = prop_oneof![
        9 => prop::collection::vec(mutation(dict.len(), pairs.len(), big), 1..=8),
        1 => prop::collection::vec(mutation(dict.len(), pairs.len(), big), 9..=40),
    ];
    (any::<Index>(), edits)
        .prop_map(move |(s, muts)| {
            let seed = &seeds[s.index(seeds.len())];
            Case {
                bytes: mutate(seed, &muts, dict, pairs),
                oracle: None,
                origin: "mutation".into(),
            }
        })
        .boxed()
}

/// Byte sequences that are not UTF-8.
pub const BAD_UTF8: &[&[u8]] = &[
    &[0xFF],
    &[0xC0, 0x80],             // overlong NUL
    &[0xED, 0xA0, 0x80],       // surrogate
    &[0xF4, 0x90, 0x80, 0x80], // past U+10FFFF
    &[0xE2, 0x82],             // truncated
    &[0x80],                   // lone continuation
    &[0xFE, 0xFE, 0xFF, 0xFF],
];

/// `seeds` with an invalid UTF-8 sequence written into them.
pub fn bad_utf8(seeds: Arc<Vec<Vec<u8>>>) -> BoxedStrategy<Case> {
    (
        any::<Index>(),
        any::<Index>(),
        any::<Index>(),
        any::<bool>(),
    )
        .prop_map(move |(s, at, k, replace)| {
            let mut b = seeds[s.index(seeds.len())].clone();
            let pos = if b.is_empty() { 0 } else { at.index(b.len()) };
            let bad = BAD_UTF8[k.index(BAD_UTF8.len())];
            if replace && pos < b.len() {
                let e = (pos + bad.len()).min(b.len());
                b.splice(pos..e, bad.iter().copied());
            } else {
                b.splice(pos..pos, bad.iter().copied());
            }
            Case {
                bytes: b,
                oracle: None,
                origin: "invalid-utf8".into(),
            }
        })
        .boxed()
}

fn case(origin: &str, bytes: Vec<u8>) -> Case {
    Case {
        bytes,
        oracle: None,
        origin: origin.into(),
    }
}

/// Sizes of the adversaries: `big` for the floor runner (inputs up to some
/// 8 MB), smaller (but still 100,000 deep) for the debug-build tests.
#[derive(Debug, Clone, Copy)]
pub struct Scale {
    pub big: bool,
}

impl Scale {
    /// Largest repetition count.
    fn many(self) -> usize {
        if self.big {
            100_000
        } else {
            20_000
        }
    }
    /// Longest token, bytes.
    fn long(self) -> usize {
        if self.big {
            4 << 20
        } else {
            256 << 10
        }
    }
}

// ---------------------------------------------------------------------------
// DAVE-ML.

const HEAD: &str = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
<DAVEfunc xmlns=\"http://daveml.org/2010/DAVEML\" xmlns:mathml2=\"http://www.w3.org/1998/Math/MathML\">\n\
<fileHeader name=\"fuzz\"><author name=\"fuzz\"/><creationDate date=\"2026-01-01\"/></fileHeader>\n";

fn doc(body: &str) -> String {
    format!("{HEAD}{body}</DAVEfunc>\n")
}

fn input_var(id: &str, init: Option<f64>) -> String {
    match init {
        Some(x) => format!(
            "<variableDef name=\"{id}\" varID=\"{id}\" units=\"nd\" initialValue=\"{x}\"><isInput/></variableDef>\n"
        ),
        None => format!(
            "<variableDef name=\"{id}\" varID=\"{id}\" units=\"nd\"><isInput/></variableDef>\n"
        ),
    }
}

fn calc_var(id: &str, math: &str) -> String {
    format!(
        "<variableDef name=\"{id}\" varID=\"{id}\" units=\"nd\"><calculation><math>{math}</math></calculation><isOutput/></variableDef>\n"
    )
}

/// A hand-written model using every form the reader knows: a shared
/// breakpoint set, a griddedTableDef reused through griddedTableRef, the
/// simple independentVarPts form, limits, extrapolation, piecewise MathML,
/// e-notation and rational numbers, and check data by signalName and varID.
const HANDWRITTEN: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<!DOCTYPE DAVEfunc PUBLIC "-//AIAA//DTD for Flight Dynamic Models - Functions 2.0//EN"
  "http://www.daveml.org/DTDs/2p0/DAVEfunc.dtd">
<!-- hand-written seed of the fuzzer -->
<DAVEfunc xmlns="http://daveml.org/2010/DAVEML">
  <fileHeader name="seed"><author name="fuzz"/><creationDate date="2026-01-01"/>
    <description>Every construct of the reader &amp; a CDATA <![CDATA[<x>]]> section.</description>
  </fileHeader>
  <variableDef name="alpha" varID="ALP" units="deg" minValue="-10" maxValue="45" initialValue="5"><isInput/></variableDef>
  <variableDef name="beta" varID="BETA" units="deg" initialValue="0"><isInput/></variableDef>
  <variableDef name="el" varID="EL" units="deg"><isControl/></variableDef>
  <variableDef name="cx" varID="CX" units="nd"/>
  <variableDef name="cx2" varID="CX2" units="nd"/>
  <variableDef name="cy" varID="CY" units="nd"/>
  <variableDef name="sgn" varID="SGN" units="nd">
    <calculation><math><apply><piecewise>
      <piece><cn>-1</cn><apply><lt/><ci>BETA</ci><cn>0</cn></apply></piece>
      <otherwise><cn type="e-notation">1<sep/>0</cn></otherwise>
    </piecewise></apply></math></calculation>
  </variableDef>
  <variableDef name="total" varID="TOT" units="nd">
    <calculation><math><apply><plus/><ci>CX</ci>
      <apply><times/><ci>SGN</ci><ci>CY</ci><cn type="rational">1<sep/>2</cn></apply>
      <apply><csymbol>atan2</csymbol><ci>BETA</ci><ci>ALP</ci></apply>
      <apply><power/><ci>CX2</ci><cn>2</cn></apply>
      <apply><root/><degree><cn>3</cn></degree><apply><abs/><ci>EL</ci></apply></apply>
    </apply></math></calculation><isOutput/>
  </variableDef>
  <breakpointDef bpID="ALP1" units="deg"><bpVals>-10, 0, 10, 20, 30, 45</bpVals></breakpointDef>
  <breakpointDef bpID="EL1" units="deg"><bpVals>-24 -12 0 12 24</bpVals></breakpointDef>
  <griddedTableDef gtID="CX_T" name="cx table">
    <breakpointRefs><bpRef bpID="EL1"/><bpRef bpID="ALP1"/></breakpointRefs>
    <dataTable><!-- EL rows -->
      -0.099 -0.081 -0.081 -0.063 -0.025 0.044
      -0.048 -0.038 -0.040 -0.021 0.016 0.083
      -0.022 -0.020 -0.021 -0.004 0.032 0.094
      -0.040 -0.038 -0.039 -0.025 0.006 0.062
      -0.083 -0.073 -0.076 -0.072 -0.046 0.012
    </dataTable>
  </griddedTableDef>
  <function name="cx"><independentVarRef varID="EL" min="-24" max="24" extrapolate="neither"/>
    <independentVarRef varID="ALP" extrapolate="both"/><dependentVarRef varID="CX"/>
    <functionDefn name="cx_fn"><griddedTableDef gtID="CX_T2"><breakpointRefs><bpRef bpID="EL1"/><bpRef bpID="ALP1"/></breakpointRefs>
      <dataTable>1,2,3,4,5,6, 7,8,9,10,11,12, 13,14,15,16,17,18, 19,20,21,22,23,24, 25,26,27,28,29,30</dataTable></griddedTableDef></functionDefn>
  </function>
  <function name="cx2"><independentVarRef varID="EL" extrapolate="min"/>
    <independentVarRef varID="ALP" extrapolate="max"/><dependentVarRef varID="CX2"/>
    <functionDefn name="cx2_fn"><griddedTableRef gtID="CX_T"/></functionDefn>
  </function>
  <function name="cy">
    <independentVarPts varID="BETA" extrapolate="both">-20, 0, 20</independentVarPts>
    <dependentVarPts varID="CY">0.3, 0, -0.3</dependentVarPts>
  </function>
  <checkData>
    <staticShot name="one">
      <checkInputs>
        <signal><signalName>alpha</signalName><signalUnits>deg</signalUnits><signalValue>12.5</signalValue></signal>
        <signal><varID>BETA</varID><signalValue>-3</signalValue></signal>
        <signal><signalName>el</signalName><signalUnits>deg</signalUnits><signalValue>5</signalValue></signal>
      </checkInputs>
      <internalValues><signal><varID>SGN</varID><signalValue>-1</signalValue></signal></internalValues>
      <checkOutputs><signal><signalName>total</signalName><signalUnits>nd</signalUnits><signalValue>1</signalValue><tol>1e6</tol></signal></checkOutputs>
    </staticShot>
  </checkData>
</DAVEfunc>
"#;

/// A model written by the crate's own writer (tables, calculations in the
/// regressor language turned into MathML, outputs, generated check data).
fn written_seed() -> String {
    let spec = ModelSpec::from_json(
        r#"{"name": "written", "description": "a & b < c",
        "inputs": [{"id": "alpha_deg", "units": "deg", "min": -10, "max": 40, "initial": 5},
                   {"id": "beta_deg", "units": "deg", "initial": 0},
                   {"id": "da_deg", "units": "deg", "initial": 0},
                   {"id": "phat", "initial": 0}],
        "calculations": [{"id": "db", "expr": "deadband(da_deg, 2)"},
                         {"id": "b2", "expr": "beta_deg^2 - abs(beta_deg) / (1 + phat * phat)"}],
        "tables": [{"id": "Cl_beta", "args": ["alpha_deg"], "breakpoints": [[0, 10, 20, 30]],
                    "values": [-0.001, -0.002, 0.003, 0.004], "extrapolate": "both"},
                   {"id": "Cl_da", "args": ["alpha_deg", "beta_deg"],
                    "breakpoints": [[0, 10, 20, 30], [-10, 0, 10]],
                    "values": [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]}],
        "outputs": [{"id": "dCl", "terms": [{"coef": 1, "factors": ["Cl_beta", "beta_deg"]},
                                            {"coef": 0.5, "factors": ["Cl_da", "db"]},
                                            {"coef": -0.01, "factors": ["b2"]}]}],
        "checks": [{"name": "a", "inputs": {"alpha_deg": 12, "beta_deg": 3, "da_deg": 5, "phat": 0.1}},
                   {"name": "b", "inputs": {"alpha_deg": -20, "beta_deg": -30, "da_deg": -1, "phat": 0}}]}"#,
    )
    .expect("the seed spec parses");
    aero_core::daveml::to_xml(&spec).expect("the seed spec writes")
}

/// The folder of the public NASA models, when present: `AERODELTA_SHARED_DAVEML`,
/// else the first `shared/data/daveml` above the crate.
pub fn shared_daveml_dir() -> Option<PathBuf> {
    if let Ok(d) = std::env::var("AERODELTA_SHARED_DAVEML") {
        return Some(PathBuf::from(d)).filter(|p| p.is_dir());
    }
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .map(|a| a.join("shared/data/daveml"))
        .find(|d| d.is_dir())
}

/// Valid DAVE-ML inputs to mutate: the built-in ones, and the public models
/// of at most `max_bytes` when found (their names are returned too).
pub fn daveml_seeds(max_bytes: usize) -> (Vec<Vec<u8>>, Vec<String>) {
    let mut seeds = vec![HANDWRITTEN.as_bytes().to_vec(), written_seed().into_bytes()];
    let mut names = vec!["handwritten".to_string(), "written by to_xml".to_string()];
    if let Some(dir) = shared_daveml_dir() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .map(|r| r.filter_map(|e| e.ok().map(|e| e.path())).collect())
            .unwrap_or_default();
        files.sort();
        for f in files {
            if f.extension().is_some_and(|e| e == "dml") {
                if let Ok(b) = std::fs::read(&f) {
                    if b.len() <= max_bytes {
                        names.push(f.file_name().unwrap_or_default().to_string_lossy().into());
                        seeds.push(b);
                    }
                }
            }
        }
    }
    (seeds, names)
}

pub const XML_DICT: &[&[u8]] = &[
    b"<",
    b">",
    b"</",
    b"/>",
    b"\"",
    b"'",
    b"=",
    b"&",
    b";",
    b"<apply>",
    b"</apply>",
    b"<plus/>",
    b"<minus/>",
    b"<times/>",
    b"<divide/>",
    b"<ci>",
    b"</ci>",
    b"<cn>",
    b"</cn>",
    b"<sep/>",
    b"<math>",
    b"</math>",
    b"<piecewise>",
    b"<piece>",
    b"<otherwise>",
    b"<![CDATA[",
    b"]]>",
    b"<!--",
    b"-->",
    b"<?pi x?>",
    b"&amp;",
    b"&lt;",
    b"&#0;",
    b"&#xD800;",
    b"&#x110000;",
    b"&#99999999999999999999;",
    b"&undeclared;",
    b"<!DOCTYPE DAVEfunc [<!ENTITY e \"x\">]>",
    b"<!ENTITY x SYSTEM \"file:///etc/passwd\">",
    b"xmlns=\"\"",
    b" xmlns:a=\"urn:a\"",
    b" a:b=\"1\"",
    b"1e308",
    b"1e309",
    b"-1e-400",
    b"NaN",
    b"inf",
    b"-0",
    b"0x10",
    b"18446744073709551616",
    b"999999999999999999999999999999",
    b",",
    b" ",
    b"\n",
    b"\t",
    b"\0",
    b"varID=\"ALP\"",
    b"bpID=\"ALP1\"",
    b"gtID=\"CX_T\"",
    b"<bpRef bpID=\"ALP1\"/>",
    b"<griddedTableRef gtID=\"CX_T\"/>",
    b"<independentVarRef varID=\"ALP\"/>",
    b"<dependentVarRef varID=\"CX\"/>",
    b"<variableDef name=\"v\" varID=\"v\" units=\"nd\"/>",
    b"<isInput/>",
    b"<isOutput/>",
    b"<signal><varID>ALP</varID><signalValue>1</signalValue></signal>",
    b"\xEF\xBB\xBF",
    b"\xFF",
    b"\xC3\xA9",
];

pub const XML_PAIRS: &[(&[u8], &[u8])] = &[
    (b"<apply><plus/><cn>1</cn>", b"</apply>"),
    (b"<apply><minus/>", b"</apply>"),
    (b"<apply>", b"</apply>"),
    (b"<semantics>", b"</semantics>"),
    (b"<math>", b"</math>"),
    (b"<b>", b"</b>"),
    (b"<piecewise><piece>", b"<cn>1</cn></piece></piecewise>"),
    (b"<!--", b"-->"),
    (b"<![CDATA[", b"]]>"),
    (b"<a", b"/>"),
    (b"(", b")"),
    (b"<b>", b""),
    (b"", b"</b>"),
];

/// How MathML nests in an adversary.
#[derive(Debug, Clone, Copy)]
pub enum MathNest {
    ApplyPlus,
    UnaryMinus,
    OperatorlessApply,
    Semantics,
    MathInMath,
    PiecewiseValue,
    PiecewiseCondition,
    Otherwise,
    RootDegree,
    InsideCi,
    Unclosed,
}

const MATH_NESTS: [MathNest; 11] = [
    MathNest::ApplyPlus,
    MathNest::UnaryMinus,
    MathNest::OperatorlessApply,
    MathNest::Semantics,
    MathNest::MathInMath,
    MathNest::PiecewiseValue,
    MathNest::PiecewiseCondition,
    MathNest::Otherwise,
    MathNest::RootDegree,
    MathNest::InsideCi,
    MathNest::Unclosed,
];

/// MathML nested `depth` deep around `<ci>a</ci>`.
pub fn math_nest(kind: MathNest, depth: usize) -> String {
    let (open, inner, close): (&str, &str, &str) = match kind {
        MathNest::ApplyPlus => ("<apply><plus/><cn>1</cn>", "<ci>a</ci>", "</apply>"),
        MathNest::UnaryMinus => ("<apply><minus/>", "<ci>a</ci>", "</apply>"),
        MathNest::OperatorlessApply => ("<apply>", "<ci>a</ci>", "</apply>"),
        MathNest::Semantics => ("<semantics>", "<ci>a</ci>", "</semantics>"),
        MathNest::MathInMath => ("<math>", "<ci>a</ci>", "</math>"),
        MathNest::PiecewiseValue => (
            "<piecewise><piece>",
            "<ci>a</ci>",
            "<apply><gt/><ci>a</ci><cn>0</cn></apply></piece></piecewise>",
        ),
        MathNest::PiecewiseCondition => (
            "<piecewise><piece><cn>1</cn>",
            "<ci>a</ci>",
            "</piece></piecewise>",
        ),
        MathNest::Otherwise => (
            "<piecewise><otherwise>",
            "<ci>a</ci>",
            "</otherwise></piecewise>",
        ),
        MathNest::RootDegree => (
            "<apply><root/><degree>",
            "<cn>2</cn>",
            "</degree><ci>a</ci></apply>",
        ),
        MathNest::InsideCi => ("<ci><b>", "a", "</b></ci>"),
        MathNest::Unclosed => ("<apply><plus/><cn>1</cn>", "<ci>a</ci>", ""),
    };
    let mut s = String::with_capacity((open.len() + close.len()) * depth + inner.len());
    for _ in 0..depth {
        s.push_str(open);
    }
    s.push_str(inner);
    for _ in 0..depth {
        s.push_str(close);
    }
    s
}

/// A DAVE-ML document whose variable `out` is calculated by `math`, with
/// inputs `a`, `b`, `c` (initial values 0.5, -1.25, 3).
pub fn math_doc(math: &str) -> String {
    doc(&format!(
        "{}{}{}{}",
        input_var("a", Some(0.5)),
        input_var("b", Some(-1.25)),
        input_var("c", Some(3.0)),
        calc_var("out", math)
    ))
}

/// Where a long token or a special number goes in a DAVE-ML file.
#[derive(Debug, Clone, Copy)]
pub enum Slot {
    Units,
    VarId,
    InitialValue,
    MinValue,
    BpValue,
    DataValue,
    Description,
    TagName,
    CiName,
    Cn,
    CnExponent,
    SignalValue,
    Tol,
    IndepMin,
    Comment,
    CData,
    Pi,
    AttrName,
    Extrapolate,
}

const SLOTS: [Slot; 19] = [
    Slot::Units,
    Slot::VarId,
    Slot::InitialValue,
    Slot::MinValue,
    Slot::BpValue,
    Slot::DataValue,
    Slot::Description,
    Slot::TagName,
    Slot::CiName,
    Slot::Cn,
    Slot::CnExponent,
    Slot::SignalValue,
    Slot::Tol,
    Slot::IndepMin,
    Slot::Comment,
    Slot::CData,
    Slot::Pi,
    Slot::AttrName,
    Slot::Extrapolate,
];

/// A small valid model with `tok` put in `slot` (raw: the caller escapes).
pub fn daveml_with(slot: Slot, tok: &str) -> String {
    let (mut units, mut vid, mut init, mut minv) = ("nd", "a", "0.5".to_string(), "-100");
    let (mut bp, mut data, mut desc, mut tag) = ("0", "1", String::new(), "b");
    let (mut ci, mut cn, mut cne, mut sv) = ("a", "2", "1", "0.5".to_string());
    let (mut tol, mut imin, mut comment, mut cdata, mut pi) = ("1e-6", "-5", "", "", "");
    let (mut attr, mut extra) = ("name", "neither");
    let t = tok;
    match slot {
        Slot::Units => units = t,
        Slot::VarId => vid = t,
        Slot::InitialValue => init = t.to_string(),
        Slot::MinValue => minv = t,
        Slot::BpValue => bp = t,
        Slot::DataValue => data = t,
        Slot::Description => desc = t.to_string(),
        Slot::TagName => tag = t,
        Slot::CiName => ci = t,
        Slot::Cn => cn = t,
        Slot::CnExponent => cne = t,
        Slot::SignalValue => sv = t.to_string(),
        Slot::Tol => tol = t,
        Slot::IndepMin => imin = t,
        Slot::Comment => comment = t,
        Slot::CData => cdata = t,
        Slot::Pi => pi = t,
        Slot::AttrName => attr = t,
        Slot::Extrapolate => extra = t,
    }
    let vid_ref = if matches!(slot, Slot::VarId) { t } else { "a" };
    let ci_ref = if matches!(slot, Slot::CiName) {
        ci
    } else {
        vid_ref
    };
    doc(&format!(
        "<!--{comment}--><?pi {pi}?>\n\
         <variableDef {attr}=\"a\" varID=\"{vid}\" units=\"{units}\" initialValue=\"{init}\" minValue=\"{minv}\"><description>{desc}<![CDATA[{cdata}]]><{tag}/></description><isInput/></variableDef>\n\
         <variableDef name=\"y\" varID=\"y\" units=\"nd\"/>\n\
         <variableDef name=\"z\" varID=\"z\" units=\"nd\"><calculation><math><apply><plus/><ci>{ci_ref}</ci><cn>{cn}</cn><cn type=\"e-notation\">1<sep/>{cne}</cn><ci>y</ci></apply></math></calculation><isOutput/></variableDef>\n\
         <breakpointDef bpID=\"B\"><bpVals>{bp}, 1e3</bpVals></breakpointDef>\n\
         <function name=\"f\"><independentVarRef varID=\"{vid_ref}\" min=\"{imin}\" extrapolate=\"{extra}\"/><dependentVarRef varID=\"y\"/>\
         <functionDefn><griddedTableDef><breakpointRefs><bpRef bpID=\"B\"/></breakpointRefs><dataTable>{data}, 2</dataTable></griddedTableDef></functionDefn></function>\n\
         <checkData><staticShot name=\"s\"><checkInputs><signal><varID>{vid_ref}</varID><signalValue>{sv}</signalValue></signal></checkInputs>\
         <checkOutputs><signal><varID>z</varID><signalValue>0</signalValue><tol>{tol}</tol></signal></checkOutputs></staticShot></checkData>\n"
    ))
}

/// Special number spellings.
pub const NUMBERS: &[&str] = &[
    "1e308",
    "1e309",
    "-1e309",
    "1e-400",
    "4.9e-324",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "infinity",
    "+5",
    "0x1p3",
    "1_000",
    "\u{FF11}",
    "-0",
    "1e99999999999999999999",
    ".",
    "",
    "1,2",
    "1.7976931348623157e308",
    "-.5e-3",
    "5.",
    "1e",
    "--1",
];

/// One DAVE-ML adversary.
#[derive(Debug, Clone)]
pub enum XmlAdversary {
    Empty,
    Whitespace(usize),
    BomOnly,
    DeclarationOnly,
    NestGeneric(usize),
    NestUnclosed(usize),
    MathNest(MathNest, usize),
    MathWide(usize, usize),
    LongToken(Slot, usize, u8),
    Number(Slot, usize),
    ManyBreakpoints(usize),
    DimOverflow(usize, usize),
    ManyVariables(usize),
    SharedTable(usize, usize),
    SharedBreakpoints(usize, usize),
    ManyShots(usize, usize),
    ManyFunctions(usize),
    Chain(usize),
    Cycle(usize),
    BillionLaughs(usize),
    Quadratic(usize, usize),
    ExternalEntity,
    ParameterEntity,
    EntityInAttribute,
    CharRef(usize),
    DoctypeTrick(usize, usize),
    Dense(usize, usize),
}

fn xml_adversary(scale: Scale) -> BoxedStrategy<XmlAdversary> {
    use XmlAdversary as A;
    let many = scale.many();
    let long = scale.long();
    let slot = (0..SLOTS.len()).prop_map(|k| SLOTS[k]);
    prop_oneof![
        1 => Just(A::Empty),
        1 => log_uniform(1, 1 << 20).prop_map(A::Whitespace),
        1 => Just(A::BomOnly),
        1 => Just(A::DeclarationOnly),
        1 => log_uniform(10, 100_000).prop_map(A::NestGeneric),
        1 => log_uniform(10, 100_000).prop_map(A::NestUnclosed),
        2 => ((0..MATH_NESTS.len()), log_uniform(10, 100_000))
            .prop_map(|(k, d)| A::MathNest(MATH_NESTS[k], d)),
        1 => (0usize..5, log_uniform(1, many)).prop_map(|(op, n)| A::MathWide(op, n)),
        2 => (slot.clone(), log_uniform(1, long), any::<u8>())
            .prop_map(|(s, n, c)| A::LongToken(s, n, c)),
        2 => (slot, 0..NUMBERS.len()).prop_map(|(s, k)| A::Number(s, k)),
        1 => log_uniform(1, many * 5).prop_map(A::ManyBreakpoints),
        1 => (2usize..=9, log_uniform(2, 1 << 16)).prop_map(|(d, p)| A::DimOverflow(d, p)),
        1 => log_uniform(1, many).prop_map(A::ManyVariables),
        1 => (log_uniform(1, many / 4), log_uniform(1, 100_000)).prop_map(|(m, n)| A::SharedTable(m, n)),
        1 => (log_uniform(1, many / 4), log_uniform(1, 10_000))
            .prop_map(|(m, n)| A::SharedBreakpoints(m.min(2_000_000 / n).max(1), n)),
        1 => (log_uniform(1, many / 4), log_uniform(1, many / 4)).prop_map(|(s, n)| A::ManyShots(s, n)),
        1 => log_uniform(1, many / 4).prop_map(A::ManyFunctions),
        1 => log_uniform(1, many / 4).prop_map(A::Chain),
        1 => log_uniform(1, many / 4).prop_map(A::Cycle),
        1 => (1usize..=12).prop_map(A::BillionLaughs),
        1 => (log_uniform(1, 1 << 20), log_uniform(1, 1 << 16)).prop_map(|(l, r)| A::Quadratic(l, r)),
        1 => Just(A::ExternalEntity),
        1 => Just(A::ParameterEntity),
        1 => Just(A::EntityInAttribute),
        1 => (0usize..8).prop_map(A::CharRef),
        1 => (0usize..8, log_uniform(1, many)).prop_map(|(k, n)| A::DoctypeTrick(k, n)),
        3 => (0usize..9, log_uniform(1, many * 5)).prop_map(|(k, n)| A::Dense(k, n)),
    ]
    .boxed()
}

fn numbers_list(n: usize, sep: &str) -> String {
    let mut s = String::with_capacity(n * 8);
    for k in 0..n {
        if k > 0 {
            s.push_str(sep);
        }
        let _ = write!(s, "{k}");
    }
    s
}

fn entity_doc(subset: &str, body: &str) -> String {
    format!(
        "<?xml version=\"1.0\"?>\n<!DOCTYPE DAVEfunc [\n{subset}\n]>\n<DAVEfunc xmlns=\"http://daveml.org/2010/DAVEML\">\n\
         <variableDef name=\"a\" varID=\"a\" units=\"nd\"><description>{body}</description><isInput/></variableDef>\n</DAVEfunc>\n"
    )
}

/// The bytes of an adversary.
pub fn render_xml(a: &XmlAdversary) -> Vec<u8> {
    use XmlAdversary as A;
    let s: String = match a {
        A::Empty => String::new(),
        A::Whitespace(n) => " \n\t".repeat(n / 3 + 1),
        A::BomOnly => "\u{FEFF}".into(),
        A::DeclarationOnly => "<?xml version=\"1.0\"?>".into(),
        A::NestGeneric(d) => doc(&format!(
            "<variableDef name=\"a\" varID=\"a\" units=\"nd\"><description>{}x{}</description><isInput/></variableDef>\n",
            "<b>".repeat(*d),
            "</b>".repeat(*d)
        )),
        A::NestUnclosed(d) => doc(&"<b>".repeat(*d)),
        A::MathNest(k, d) => math_doc(&math_nest(*k, *d)),
        A::MathWide(op, n) => {
            let (o, arg) = [
                ("<plus/>", "<ci>a</ci>"),
                ("<times/>", "<cn>1.0001</cn>"),
                ("<min/>", "<ci>b</ci>"),
                ("<lt/>", "<ci>c</ci>"),
                ("<and/>", "<true/>"),
            ][*op % 5];
            math_doc(&format!("<apply>{o}{}</apply>", arg.repeat(*n)))
        }
        A::LongToken(slot, n, c) => {
            // A long run of one character (a letter, digit or the byte's
            // character when printable), or of a multi-byte character.
            let ch = match c % 4 {
                0 => 'x',
                1 => '9',
                2 => 'é',
                _ => char::from(32 + c % 95),
            };
            let tok: String = std::iter::repeat_n(ch, *n).collect();
            let tok = tok.replace('&', "&amp;").replace('<', "&lt;").replace('"', "&quot;");
            daveml_with(*slot, &tok)
        }
        A::Number(slot, k) => daveml_with(*slot, NUMBERS[*k]),
        A::ManyBreakpoints(n) => doc(&format!(
            "{}<variableDef name=\"y\" varID=\"y\" units=\"nd\"><isOutput/></variableDef>\n\
             <breakpointDef bpID=\"B\"><bpVals>{}</bpVals></breakpointDef>\n\
             <function name=\"f\"><independentVarRef varID=\"a\"/><dependentVarRef varID=\"y\"/><functionDefn><griddedTableDef>\
             <breakpointRefs><bpRef bpID=\"B\"/></breakpointRefs><dataTable>{}</dataTable></griddedTableDef></functionDefn></function>\n",
            input_var("a", Some(1.5)),
            numbers_list(*n, ","),
            numbers_list(*n, " ")
        )),
        A::DimOverflow(d, p) => {
            let mut body = String::new();
            for k in 0..*d {
                body.push_str(&input_var(&format!("a{k}"), Some(0.5)));
                let _ = writeln!(body, "<breakpointDef bpID=\"B{k}\"><bpVals>{}</bpVals></breakpointDef>", numbers_list(*p, " "));
            }
            body.push_str("<variableDef name=\"y\" varID=\"y\" units=\"nd\"><isOutput/></variableDef>\n<function name=\"f\">");
            for k in 0..*d {
                let _ = write!(body, "<independentVarRef varID=\"a{k}\"/>");
            }
            body.push_str("<dependentVarRef varID=\"y\"/><functionDefn><griddedTableDef><breakpointRefs>");
            for k in 0..*d {
                let _ = write!(body, "<bpRef bpID=\"B{k}\"/>");
            }
            body.push_str("</breakpointRefs><dataTable></dataTable></griddedTableDef></functionDefn></function>\n");
            doc(&body)
        }
        A::ManyVariables(n) => {
            let mut body = String::with_capacity(n * 60);
            for k in 0..*n {
                let _ = writeln!(body, "<variableDef name=\"v{k}\" varID=\"v{k}\" units=\"nd\" initialValue=\"{k}\"/>");
            }
            doc(&body)
        }
        A::SharedTable(m, n) => {
            let mut body = input_var("a", Some(2.5));
            let _ = writeln!(body, "<breakpointDef bpID=\"B\"><bpVals>{}</bpVals></breakpointDef>", numbers_list(*n, " "));
            let _ = writeln!(body, "<griddedTableDef gtID=\"T\"><breakpointRefs><bpRef bpID=\"B\"/></breakpointRefs><dataTable>{}</dataTable></griddedTableDef>", numbers_list(*n, " "));
            for k in 0..*m {
                let _ = writeln!(body, "<variableDef name=\"y{k}\" varID=\"y{k}\" units=\"nd\"/><function name=\"f{k}\"><independentVarRef varID=\"a\" min=\"{k}\"/><dependentVarRef varID=\"y{k}\"/><functionDefn><griddedTableRef gtID=\"T\"/></functionDefn></function>");
            }
            doc(&body)
        }
        A::SharedBreakpoints(m, n) => {
            let mut body = input_var("a", Some(2.5));
            let _ = writeln!(body, "<breakpointDef bpID=\"B\"><bpVals>{}</bpVals></breakpointDef>", numbers_list(*n, " "));
            let data = "0 ".repeat(*n);
            for k in 0..*m {
                let _ = writeln!(body, "<variableDef name=\"y{k}\" varID=\"y{k}\" units=\"nd\"/><function name=\"f{k}\"><independentVarRef varID=\"a\" extrapolate=\"both\"/><dependentVarRef varID=\"y{k}\"/><functionDefn><griddedTableDef><breakpointRefs><bpRef bpID=\"B\"/></breakpointRefs><dataTable>{data}</dataTable></griddedTableDef></functionDefn></function>");
            }
            doc(&body)
        }
        A::ManyShots(s, n) => {
            let mut body = String::with_capacity(n * 60 + s * 120);
            for k in 0..*n {
                let _ = writeln!(body, "<variableDef name=\"v{k}\" varID=\"v{k}\" units=\"nd\" initialValue=\"{k}\"><isInput/></variableDef>");
            }
            body.push_str("<checkData>\n");
            for k in 0..*s {
                let v = k % n;
                let _ = writeln!(body, "<staticShot name=\"s{k}\"><checkInputs><signal><signalName>v{v}</signalName><signalUnits>nd</signalUnits><signalValue>{k}</signalValue></signal></checkInputs><checkOutputs><signal><signalName>v{v}</signalName><signalValue>{k}</signalValue></signal></checkOutputs></staticShot>");
            }
            body.push_str("</checkData>\n");
            doc(&body)
        }
        A::ManyFunctions(m) => {
            let mut body = String::new();
            for k in 0..*m {
                let _ = writeln!(body, "<variableDef name=\"a{k}\" varID=\"a{k}\" units=\"nd\" initialValue=\"0.5\"/><variableDef name=\"y{k}\" varID=\"y{k}\" units=\"nd\"/><function name=\"f{k}\"><independentVarPts varID=\"a{k}\">0 1</independentVarPts><dependentVarPts varID=\"y{k}\">0 {k}</dependentVarPts></function>");
            }
            doc(&body)
        }
        A::Chain(n) | A::Cycle(n) => {
            let mut body = input_var("a", Some(0.5));
            for k in (0..*n).rev() {
                let dep = match (k, a) {
                    (0, A::Cycle(_)) => format!("y{}", n - 1),
                    (0, _) => "a".to_string(),
                    _ => format!("y{}", k - 1),
                };
                body.push_str(&calc_var(
                    &format!("y{k}"),
                    &format!("<apply><plus/><ci>{dep}</ci><cn>1</cn></apply>"),
                ));
            }
            doc(&body)
        }
        A::BillionLaughs(levels) => {
            let mut subset = String::from("<!ENTITY lol \"lol\">\n");
            for k in 1..*levels {
                let prev = if k == 1 { "lol".to_string() } else { format!("lol{}", k - 1) };
                let _ = writeln!(subset, "<!ENTITY lol{k} \"{}\">", format!("&{prev};").repeat(10));
            }
            let last = if *levels <= 1 { "lol".to_string() } else { format!("lol{}", levels - 1) };
            entity_doc(&subset, &format!("&{last};"))
        }
        A::Quadratic(len, refs) => entity_doc(
            &format!("<!ENTITY big \"{}\">", "x".repeat(*len)),
            &"&big;".repeat(*refs),
        ),
        A::ExternalEntity => entity_doc("<!ENTITY ext SYSTEM \"file:///etc/passwd\">", "&ext;"),
        A::ParameterEntity => entity_doc(
            "<!ENTITY % pe SYSTEM \"http://example.invalid/evil.dtd\">\n%pe;",
            "x",
        ),
        A::EntityInAttribute => entity_doc("<!ENTITY e \"1\">", "<b x=\"&e;\"/>"),
        A::CharRef(k) => {
            let r = ["&#0;", "&#xD800;", "&#x110000;", "&#99999999999;", "&#x;", "&#;", "&#65", "&#x41;&#x10FFFF;"][*k % 8];
            daveml_with(Slot::Description, r)
        }
        A::DoctypeTrick(k, n) => match k % 8 {
            0 => "<?xml version=\"1.0\"?>\n<!DOCTYPE DAVEfunc [ <!ELEMENT a ANY>".into(),
            1 => format!("{HEAD}<!DOCTYPE x></DAVEfunc>"),
            2 => entity_doc(&"<!ATTLIST DAVEfunc x CDATA \"y\">\n".repeat(*n), ""),
            3 => format!("<!DOCTYPE DAVEfunc {}>\n<DAVEfunc/>", "[".repeat(*n)),
            4 => entity_doc(&"<!-- comment -->\n".repeat(*n), ""),
            5 => format!("<!DOCTYPE DAVEfunc \"{}\n<DAVEfunc/>", "x".repeat(*n)),
            6 => format!("<!DOCTYPE DAVEfunc [{}]>\n<DAVEfunc/>", "%pe;".repeat(*n)),
            _ => format!("<?xml version=\"1.0\"?>{}<!DOCTYPE DAVEfunc>\n<DAVEfunc/>", "<?p?>".repeat(*n)),
        },
        A::Dense(k, n) => {
            // Markup as dense as XML allows, inside a valid model.
            let body = match k % 9 {
                0 => "<a/>".repeat(*n),
                1 => "<a/>x".repeat(*n),
                2 => "=".repeat(*n),
                3 => format!("<!--{}-->", "<".repeat(*n)),
                4 => format!("<a{}/>", (0..*n).map(|i| format!(" a{i}=\"\"")).collect::<String>()),
                5 => format!("<a{}/>", (0..*n).map(|i| format!(" xmlns:p{i}=\"u\"")).collect::<String>()),
                6 => "<!---->".repeat(*n),
                7 => "&amp;".repeat(*n),
                _ => "<![CDATA[]]>x".repeat(*n),
            };
            daveml_with(Slot::Description, &body)
        }
    };
    s.into_bytes()
}

/// DAVE-ML inputs: mutations of `seeds`, invalid UTF-8 and adversaries.
pub fn daveml_cases(seeds: Arc<Vec<Vec<u8>>>, scale: Scale) -> BoxedStrategy<Case> {
    prop_oneof![
        6 => mutated(seeds.clone(), XML_DICT, XML_PAIRS, scale.big),
        1 => bad_utf8(seeds),
        4 => xml_adversary(scale).prop_map(|a| case(&format!("{a:?}").chars().take(40).collect::<String>(), render_xml(&a))),
    ]
    .boxed()
}

// ---------------------------------------------------------------------------
// MathML: random valid expressions with their value, and adversaries.

/// A MathML expression with its reference semantics (MathML 2 content markup
/// as DAVE-ML defines it: booleans 1/0, relations chained pairwise, piecewise
/// NaN without a true piece nor otherwise).
#[derive(Debug, Clone)]
pub enum MExpr {
    Num(f64),
    Var(usize),
    Nary(&'static str, Vec<MExpr>),
    Unary(&'static str, Box<MExpr>),
    Binary(&'static str, Box<MExpr>, Box<MExpr>),
    Piecewise(Vec<(MExpr, MExpr)>, Option<Box<MExpr>>),
}

const M_VARS: [(&str, f64); 3] = [("a", 0.5), ("b", -1.25), ("c", 3.0)];

const M_NARY: [&str; 11] = [
    "plus", "times", "min", "max", "and", "or", "eq", "neq", "gt", "lt", "leq",
];
const M_UNARY: [&str; 12] = [
    "minus", "abs", "exp", "sin", "cos", "tan", "arctan", "floor", "ceiling", "not", "sqrt", "ln",
];
const M_BINARY: [&str; 5] = ["minus", "divide", "power", "atan2", "rem"];

fn is_true(x: f64) -> bool {
    x != 0.0 && !x.is_nan()
}
fn truth(b: bool) -> f64 {
    if b {
        1.0
    } else {
        0.0
    }
}

impl MExpr {
    /// The reference value.
    pub fn value(&self) -> f64 {
        match self {
            MExpr::Num(x) => *x,
            MExpr::Var(i) => M_VARS[*i].1,
            MExpr::Nary(op, args) => {
                let v: Vec<f64> = args.iter().map(MExpr::value).collect();
                let chain = |f: fn(f64, f64) -> bool| truth(v.windows(2).all(|w| f(w[0], w[1])));
                match *op {
                    "plus" => v.iter().fold(0.0, |s, x| s + x),
                    "times" => v.iter().fold(1.0, |s, x| s * x),
                    "min" => v.iter().copied().fold(f64::INFINITY, |m, x| {
                        if x.is_nan() || x < m {
                            x
                        } else {
                            m
                        }
                    }),
                    "max" => v.iter().copied().fold(f64::NEG_INFINITY, |m, x| {
                        if x.is_nan() || x > m {
                            x
                        } else {
                            m
                        }
                    }),
                    "and" => truth(v.iter().all(|&x| is_true(x))),
                    "or" => truth(v.iter().any(|&x| is_true(x))),
                    "eq" => chain(|a, b| a == b),
                    "neq" => chain(|a, b| a != b),
                    "gt" => chain(|a, b| a > b),
                    "lt" => chain(|a, b| a < b),
                    _ => chain(|a, b| a <= b),
                }
            }
            MExpr::Unary(op, a) => {
                let x = a.value();
                match *op {
                    "minus" => -x,
                    "abs" => x.abs(),
                    "exp" => x.exp(),
                    "sin" => x.sin(),
                    "cos" => x.cos(),
                    "tan" => x.tan(),
                    "arctan" => x.atan(),
                    "floor" => x.floor(),
                    "ceiling" => x.ceil(),
                    "not" => truth(!is_true(x)),
                    "sqrt" => x.sqrt(),
                    _ => x.ln(),
                }
            }
            MExpr::Binary(op, a, b) => {
                let (x, y) = (a.value(), b.value());
                match *op {
                    "minus" => x - y,
                    "divide" => x / y,
                    "power" => x.powf(y),
                    "atan2" => x.atan2(y),
                    _ => x % y,
                }
            }
            MExpr::Piecewise(pieces, otherwise) => {
                for (v, c) in pieces {
                    if is_true(c.value()) {
                        return v.value();
                    }
                }
                otherwise.as_ref().map_or(f64::NAN, |o| o.value())
            }
        }
    }

    /// Content MathML, with random white space from `ws`.
    pub fn render(&self, out: &mut String, ws: &mut dyn Iterator<Item = bool>) {
        fn sp(out: &mut String, ws: &mut dyn Iterator<Item = bool>) {
            if ws.next().unwrap_or(false) {
                out.push_str("\n  ");
            }
        }
        match self {
            MExpr::Num(x) => {
                let _ = write!(out, "<cn>{x:?}</cn>");
            }
            MExpr::Var(i) => {
                let _ = write!(out, "<ci> {} </ci>", M_VARS[*i].0);
            }
            MExpr::Nary(op, args) => {
                let _ = write!(out, "<apply><{op}/>");
                for a in args {
                    sp(out, ws);
                    a.render(out, ws);
                }
                out.push_str("</apply>");
            }
            MExpr::Unary(op, a) => {
                if *op == "sqrt" {
                    out.push_str("<apply><csymbol>sqrt</csymbol>");
                } else {
                    let _ = write!(out, "<apply><{op}/>");
                }
                a.render(out, ws);
                out.push_str("</apply>");
            }
            MExpr::Binary(op, a, b) => {
                if *op == "atan2" {
                    out.push_str("<apply><csymbol definitionURL=\"http://daveml.org/function_spaces.html#atan2\">atan2</csymbol>");
                } else {
                    let _ = write!(out, "<apply><{op}/>");
                }
                a.render(out, ws);
                sp(out, ws);
                b.render(out, ws);
                out.push_str("</apply>");
            }
            MExpr::Piecewise(pieces, otherwise) => {
                out.push_str("<piecewise>");
                for (v, c) in pieces {
                    out.push_str("<piece>");
                    v.render(out, ws);
                    c.render(out, ws);
                    out.push_str("</piece>");
                }
                if let Some(o) = otherwise {
                    out.push_str("<otherwise>");
                    o.render(out, ws);
                    out.push_str("</otherwise>");
                }
                out.push_str("</piecewise>");
            }
        }
    }
}

fn m_leaf() -> BoxedStrategy<MExpr> {
    prop_oneof![
        (0usize..3).prop_map(MExpr::Var),
        prop_oneof![
            Just(0.0),
            Just(1.0),
            Just(-2.5),
            Just(0.125),
            Just(1e-3),
            Just(7.0)
        ]
        .prop_map(MExpr::Num),
    ]
    .boxed()
}

/// Random valid MathML expressions, up to a few levels and dozens of nodes.
pub fn m_expr() -> BoxedStrategy<MExpr> {
    m_leaf()
        .prop_recursive(6, 48, 5, |inner| {
            prop_oneof![
                (
                    (0..M_NARY.len()),
                    prop::collection::vec(inner.clone(), 2..5)
                )
                    .prop_map(|(k, a)| MExpr::Nary(M_NARY[k], a)),
                ((0..M_UNARY.len()), inner.clone())
                    .prop_map(|(k, a)| MExpr::Unary(M_UNARY[k], Box::new(a))),
                ((0..M_BINARY.len()), inner.clone(), inner.clone())
                    .prop_map(|(k, a, b)| MExpr::Binary(M_BINARY[k], Box::new(a), Box::new(b))),
                (
                    prop::collection::vec((inner.clone(), inner.clone()), 1..3),
                    prop::option::of(inner)
                )
                    .prop_map(|(p, o)| MExpr::Piecewise(p, o.map(Box::new))),
            ]
        })
        .boxed()
}

pub const MATH_DICT: &[&[u8]] = &[
    b"<apply>",
    b"</apply>",
    b"<plus/>",
    b"<minus/>",
    b"<times/>",
    b"<divide/>",
    b"<power/>",
    b"<root/>",
    b"<degree><cn>3</cn></degree>",
    b"<logbase><cn>2</cn></logbase>",
    b"<log/>",
    b"<ci>a</ci>",
    b"<ci>nope</ci>",
    b"<cn>1</cn>",
    b"<cn type=\"e-notation\">1<sep/>400</cn>",
    b"<cn type=\"rational\">1<sep/>0</cn>",
    b"<sep/>",
    b"<piecewise>",
    b"</piecewise>",
    b"<piece>",
    b"</piece>",
    b"<otherwise>",
    b"</otherwise>",
    b"<csymbol>atan2</csymbol>",
    b"<csymbol>sign</csymbol>",
    b"<csymbol></csymbol>",
    b"<semantics>",
    b"<math>",
    b"<pi/>",
    b"<notanumber/>",
    b"<infinity/>",
    b"<eq/>",
    b"<and/>",
    b"<not/>",
    b"<gamma/>",
    b"<",
    b">",
    b"/",
    b"&amp;",
    b"1e309",
];

/// MathML inputs: valid expressions with their value, mutations of valid
/// ones, nesting and width adversaries.
pub fn mathml_cases(scale: Scale) -> BoxedStrategy<Case> {
    let valid = (m_expr(), any::<u64>()).prop_map(|(e, ws)| {
        let mut math = String::new();
        let mut bits = (0..64).map(move |k| (ws >> k) & 1 == 1).cycle();
        e.render(&mut math, &mut bits);
        Case {
            bytes: math_doc(&math).into_bytes(),
            oracle: Some(Oracle {
                inputs: Vec::new(),
                expected: e.value(),
            }),
            origin: "valid".into(),
        }
    });
    let mutated_valid = (
        m_expr(),
        prop::collection::vec(mutation(MATH_DICT.len(), XML_PAIRS.len(), scale.big), 1..6),
    )
        .prop_map(|(e, muts)| {
            let mut math = String::new();
            e.render(&mut math, &mut std::iter::repeat(false));
            // Mutate only the MathML, then put it in the document.
            let m = mutate(math.as_bytes(), &muts, MATH_DICT, XML_PAIRS);
            let d = math_doc(&String::from_utf8_lossy(&m));
            case("mutation", d.into_bytes())
        });
    let many = scale.many();
    let adversary = prop_oneof![
        4 => ((0..MATH_NESTS.len()), log_uniform(10, 100_000))
            .prop_map(|(k, d)| case("nesting", math_doc(&math_nest(MATH_NESTS[k], d)).into_bytes())),
        1 => ((0..MATH_NESTS.len()), 500usize..=520)
            .prop_map(|(k, d)| case("nesting at the limit", math_doc(&math_nest(MATH_NESTS[k], d)).into_bytes())),
        2 => (0usize..5, log_uniform(1, many))
            .prop_map(|(op, n)| case("wide", render_xml(&XmlAdversary::MathWide(op, n)))),
        1 => (log_uniform(1, many / 4), log_uniform(1, 64)).prop_map(|(n, d)| {
            let n = n.min(200_000 / d).max(1);
            // Many calculations, each nested a little: the depth check per calculation.
            let mut body = input_var("a", Some(0.5));
            for k in 0..n {
                let _ = write!(body, "{}", calc_var(&format!("v{k}"), &math_nest(MathNest::ApplyPlus, d)));
            }
            case("many calculations", doc(&body).into_bytes())
        }),
        1 => (0..NUMBERS.len(), 0usize..3).prop_map(|(k, form)| {
            let n = NUMBERS[k];
            let cn = match form {
                0 => format!("<cn>{n}</cn>"),
                1 => format!("<cn type=\"e-notation\">{n}<sep/>{n}</cn>"),
                _ => format!("<cn type=\"rational\">1<sep/>{n}</cn>"),
            };
            case("number", math_doc(&format!("<apply><plus/>{cn}<ci>a</ci></apply>")).into_bytes())
        }),
    ];
    prop_oneof![3 => valid, 3 => mutated_valid, 3 => adversary].boxed()
}

// ---------------------------------------------------------------------------
// Regressors.

/// Columns of the fit's candidate vocabulary (`python/aerodelta/fit.py`).
pub const COLUMNS: [&str; 12] = [
    "beta_deg",
    "phat",
    "rhat",
    "da_deg",
    "dr_deg",
    "ct_left",
    "ct_right",
    "ct_diff",
    "ds_deg",
    "betadot_dps",
    "alphadot_dps",
    "alpha_deg",
];

/// The candidate regressors of the fit (`CANDIDATE_TERMS`).
pub const CANDIDATES: [&str; 17] = [
    "1",
    "beta_deg",
    "phat",
    "rhat",
    "deadband(da_deg, 2)",
    "dr_deg",
    "ct_left + ct_right",
    "ct_diff",
    "ds_deg",
    "betadot_dps",
    "alphadot_dps * ds_deg",
    "alphadot_dps * beta_deg",
    "alphadot_dps * betadot_dps",
    "beta_deg * ds_deg",
    "beta_deg^2",
    "beta_deg^3",
    "abs(beta_deg)",
];

fn col_value(k: usize) -> f64 {
    // Distinct, of both signs, some inside deadband(x, 2)'s band.
    [
        3.5, -0.25, 1.75, -4.0, 0.5, 2.25, -1.5, 0.0, 6.0, -2.75, 1.25, 14.0,
    ][k % 12]
}

/// A regressor with reference semantics (the module documentation of
/// `aero_core::regressor`: deadband(x, k) = (x-k)+ + (x+k)-, step(x) = 1 for
/// x > 0 else 0, min/max propagating NaN, `^` right-associative and binding
/// tighter than unary minus).
#[derive(Debug, Clone)]
pub enum RExpr {
    Num(f64),
    Col(usize),
    Neg(Box<RExpr>),
    Bin(char, Box<RExpr>, Box<RExpr>),
    Call(&'static str, Vec<RExpr>),
}

const R_FUNCS: [(&str, usize); 11] = [
    ("pos", 1),
    ("neg", 1),
    ("deadband", 2),
    ("step", 1),
    ("abs", 1),
    ("sqrt", 1),
    ("sin", 1),
    ("cos", 1),
    ("exp", 1),
    ("min", 2),
    ("max", 2),
];

impl RExpr {
    pub fn value(&self) -> f64 {
        match self {
            RExpr::Num(x) => *x,
            RExpr::Col(k) => col_value(*k),
            RExpr::Neg(a) => -a.value(),
            RExpr::Bin(op, a, b) => {
                let (x, y) = (a.value(), b.value());
                match op {
                    '+' => x + y,
                    '-' => x - y,
                    '*' => x * y,
                    '/' => x / y,
                    // Small whole exponents by multiplication (the module's
                    // rule): (-0.7)^y for y near 1e12 is 0 if y is whole, NaN
                    // if it is not, and powi and powf round 0.001^-4 apart.
                    _ if y.fract() == 0.0 && y.abs() <= 16.0 => x.powi(y as i32),
                    _ => x.powf(y),
                }
            }
            RExpr::Call(f, args) => {
                let x = args[0].value();
                let y = args.get(1).map_or(0.0, RExpr::value);
                let nan2 = x.is_nan() || y.is_nan();
                match *f {
                    "pos" => x.max(0.0),
                    "neg" => x.min(0.0),
                    "deadband" if nan2 => f64::NAN,
                    "deadband" => (x - y).max(0.0) + (x + y).min(0.0),
                    "step" if x.is_nan() => f64::NAN,
                    "step" => truth(x > 0.0),
                    "abs" => x.abs(),
                    "sqrt" => x.sqrt(),
                    "sin" => x.sin(),
                    "cos" => x.cos(),
                    "exp" => x.exp(),
                    "min" if nan2 => f64::NAN,
                    "min" => x.min(y),
                    "max" if nan2 => f64::NAN,
                    _ => x.max(y),
                }
            }
        }
    }

    /// Binding strength of the top operator (atoms 5, `^` 4, unary minus 3,
    /// `* /` 2, `+ -` 1).
    fn prec(&self) -> u8 {
        match self {
            RExpr::Num(x) if *x < 0.0 => 3,
            RExpr::Num(_) | RExpr::Col(_) | RExpr::Call(..) => 5,
            RExpr::Neg(_) => 3,
            RExpr::Bin('^', ..) => 4,
            RExpr::Bin('*' | '/', ..) => 2,
            RExpr::Bin(..) => 1,
        }
    }

    /// Source text with the fewest parentheses the grammar needs (or all of
    /// them when `full`), spaced by `ws`.
    pub fn render(&self, full: bool, ws: &mut dyn Iterator<Item = bool>) -> String {
        fn sp(ws: &mut dyn Iterator<Item = bool>) -> &'static str {
            if ws.next().unwrap_or(false) {
                " "
            } else {
                ""
            }
        }
        let wrap = |e: &RExpr, need: bool, ws: &mut dyn Iterator<Item = bool>| {
            let s = e.render(full, ws);
            if need || (full && e.prec() < 5) {
                format!("({s})")
            } else {
                s
            }
        };
        match self {
            RExpr::Num(x) => format!("{x}"),
            RExpr::Col(k) => COLUMNS[*k].to_string(),
            RExpr::Neg(a) => {
                let s = sp(ws);
                let inner = wrap(a, a.prec() < 3, ws);
                format!("-{s}{inner}")
            }
            RExpr::Bin(op, a, b) => {
                let p = self.prec();
                let (la, rb) = if *op == '^' {
                    (a.prec() <= 4, b.prec() < 3)
                } else {
                    (a.prec() < p, b.prec() <= p)
                };
                let l = wrap(a, la, ws);
                let (s1, s2) = (sp(ws), sp(ws));
                let r = wrap(b, rb, ws);
                format!("{l}{s1}{op}{s2}{r}")
            }
            RExpr::Call(f, args) => {
                let parts: Vec<String> = args.iter().map(|a| a.render(full, ws)).collect();
                format!("{f}({})", parts.join(", "))
            }
        }
    }
}

fn r_leaf() -> BoxedStrategy<RExpr> {
    prop_oneof![
        3 => (0..COLUMNS.len()).prop_map(RExpr::Col),
        1 => prop_oneof![Just(1.0), Just(2.0), Just(0.5), Just(3.0), Just(1e-3), Just(-2.0), Just(12.75)]
            .prop_map(RExpr::Num),
    ]
    .boxed()
}

/// Random valid regressors of a few levels.
pub fn r_expr() -> BoxedStrategy<RExpr> {
    r_leaf()
        .prop_recursive(6, 40, 3, |inner| {
            prop_oneof![
                inner.clone().prop_map(|a| RExpr::Neg(Box::new(a))),
                (
                    prop_oneof![Just('+'), Just('-'), Just('*'), Just('/'), Just('^')],
                    inner.clone(),
                    inner.clone()
                )
                    .prop_map(|(op, a, b)| RExpr::Bin(
                        op,
                        Box::new(a),
                        Box::new(b)
                    )),
                ((0..R_FUNCS.len()), prop::collection::vec(inner, 2)).prop_map(|(k, mut a)| {
                    let (f, n) = R_FUNCS[k];
                    a.truncate(n);
                    RExpr::Call(f, a)
                }),
            ]
        })
        .boxed()
}

pub const REG_DICT: &[&[u8]] = &[
    b"(",
    b")",
    b"-",
    b"+",
    b"*",
    b"/",
    b"^",
    b",",
    b" ",
    b"deadband(",
    b"abs(",
    b"min(",
    b"step(",
    b"unknown(",
    b"1e308",
    b"1e999",
    b"1e-999",
    b".",
    b"..",
    b"1.2.3",
    b"1e",
    b"1e+",
    b"beta_deg",
    b"_",
    b"\xC3\xA9",
    b"\xE2\x80\x8B",
    b"\xF0\x9D\x9B\xBC",
    b"\t",
    b"\0",
    b"9999999999999999999999",
    b"$",
];

pub const REG_PAIRS: &[(&[u8], &[u8])] = &[
    (b"(", b")"),
    (b"abs(", b")"),
    (b"deadband(", b", 2)"),
    (b"-", b""),
    (b"", b"^2"),
    (b"", b" + 1"),
    (b"(", b""),
];

/// One regressor adversary.
#[derive(Debug, Clone)]
pub enum RegAdversary {
    Parens(usize),
    UnaryMinus(usize),
    PowerChain(usize),
    Calls(usize, usize),
    FlatSum(usize),
    FlatProduct(usize),
    SumOfProducts(usize, usize),
    Balanced(usize),
    LongName(usize),
    LongNumber(usize),
    Number(usize),
    Pattern(Vec<u8>, usize),
    Empty,
    Whitespace(usize),
    Unclosed(usize),
    Closers(usize),
}

fn reg_adversary(scale: Scale) -> BoxedStrategy<RegAdversary> {
    use RegAdversary as R;
    let long = if scale.big { 1 << 20 } else { 64 << 10 };
    prop_oneof![
        log_uniform(10, 100_000).prop_map(R::Parens),
        log_uniform(10, 100_000).prop_map(R::UnaryMinus),
        log_uniform(10, 100_000).prop_map(R::PowerChain),
        (0..R_FUNCS.len(), log_uniform(10, 100_000)).prop_map(|(f, d)| R::Calls(f, d)),
        log_uniform(10, 100_000).prop_map(R::FlatSum),
        log_uniform(10, 100_000).prop_map(R::FlatProduct),
        (log_uniform(1, 300), log_uniform(1, 300)).prop_map(|(r, c)| R::SumOfProducts(r, c)),
        (1usize..=17).prop_map(R::Balanced),
        log_uniform(1, long).prop_map(R::LongName),
        log_uniform(1, long).prop_map(R::LongNumber),
        (0..NUMBERS.len()).prop_map(R::Number),
        (
            prop::collection::vec(prop::sample::select(b"()-^+*/,a1 ".to_vec()), 1..8),
            log_uniform(10, 100_000)
        )
            .prop_map(|(p, n)| R::Pattern(p, n)),
        Just(R::Empty),
        log_uniform(1, long).prop_map(R::Whitespace),
        log_uniform(1, 100_000).prop_map(R::Unclosed),
        log_uniform(1, 100_000).prop_map(R::Closers),
    ]
    .boxed()
}

/// The text of a regressor adversary.
pub fn render_regressor(a: &RegAdversary) -> String {
    use RegAdversary as R;
    match a {
        R::Parens(d) => format!("{}beta_deg{}", "(".repeat(*d), ")".repeat(*d)),
        R::UnaryMinus(d) => format!("{}beta_deg", "-".repeat(*d)),
        R::PowerChain(n) => vec!["beta_deg"; n + 1].join(" ^ "),
        R::Calls(f, d) => {
            let (name, arity) = R_FUNCS[*f];
            let close = if arity == 2 { ", 2)" } else { ")" };
            format!(
                "{}beta_deg{}",
                format!("{name}(").repeat(*d),
                close.repeat(*d)
            )
        }
        R::FlatSum(n) => vec!["beta_deg"; *n].join(" + "),
        R::FlatProduct(n) => vec!["phat"; *n].join("*"),
        R::SumOfProducts(r, c) => vec![vec!["a"; *c].join("*"); *r].join("+"),
        R::Balanced(d) => {
            let mut s = "a".to_string();
            for _ in 0..*d {
                s = format!("({s}+{s})");
            }
            s
        }
        R::LongName(n) => "b".repeat(*n),
        R::LongNumber(n) => "9".repeat(*n),
        R::Number(k) => format!("{} * beta_deg", NUMBERS[*k]),
        R::Pattern(p, n) => String::from_utf8_lossy(&p.repeat(*n)).into_owned(),
        R::Empty => String::new(),
        R::Whitespace(n) => " ".repeat(*n),
        R::Unclosed(n) => "(".repeat(*n),
        R::Closers(n) => format!("a{}", ")".repeat(*n)),
    }
}

/// Regressor inputs: valid expressions with their value (fewest and all
/// parentheses), the candidates mutated, adversaries.
pub fn regressor_cases(scale: Scale) -> BoxedStrategy<Case> {
    let valid = (r_expr(), any::<bool>(), any::<u64>()).prop_map(|(e, full, ws)| {
        let mut bits = (0..64).map(move |k| (ws >> k) & 1 == 1).cycle();
        let src = e.render(full, &mut bits);
        Case {
            bytes: src.into_bytes(),
            oracle: Some(Oracle {
                inputs: COLUMNS
                    .iter()
                    .enumerate()
                    .map(|(k, c)| (c.to_string(), col_value(k)))
                    .collect(),
                expected: e.value(),
            }),
            origin: "valid".into(),
        }
    });
    let seeds: Arc<Vec<Vec<u8>>> =
        Arc::new(CANDIDATES.iter().map(|c| c.as_bytes().to_vec()).collect());
    prop_oneof![
        3 => valid,
        4 => mutated(seeds, REG_DICT, REG_PAIRS, scale.big),
        3 => reg_adversary(scale).prop_map(|a| case(&format!("{a:?}").chars().take(40).collect::<String>(), render_regressor(&a).into_bytes())),
    ]
    .boxed()
}

// ---------------------------------------------------------------------------
// Model files.

/// A model as `aerodelta fit` writes it: the thesis structures of Cl, Cn and
/// CY on three flap settings, a confidence band, provenance and roll-off.
pub fn model_seed() -> Vec<u8> {
    use aero_core::delta_model::{Band, CoefficientSpec, DeltaModelSpec, TermSpec};
    let alpha: Vec<f64> = (0..21).map(|k| 10.0 + 0.5 * f64::from(k)).collect();
    let flaps = vec![0.0, 10.0, 20.0];
    let mut coefficients = std::collections::BTreeMap::new();
    for (ci, c) in ["Cl", "Cn", "CY"].iter().enumerate() {
        let terms = CANDIDATES
            .iter()
            .enumerate()
            .filter(|(k, _)| (k + ci) % 3 != 2)
            .map(|(k, reg)| {
                let row = |f: usize| -> Vec<f64> {
                    alpha
                        .iter()
                        .map(|a| {
                            ((k as f64 + 1.0) * 1e-3 * (a * 0.1 + f as f64).sin() * 1e3).round()
                                / 1e3
                        })
                        .collect()
                };
                let values: Vec<Vec<f64>> = (0..3).map(row).collect();
                let band = (k % 2 == 0).then(|| Band {
                    level: 0.95,
                    lower: values
                        .iter()
                        .map(|r| r.iter().map(|v| v - 1e-3).collect())
                        .collect(),
                    upper: values
                        .iter()
                        .map(|r| r.iter().map(|v| v + 1e-3).collect())
                        .collect(),
                });
                TermSpec {
                    name: format!("d{c}_{k}"),
                    regressor: reg.to_string(),
                    alpha_deg: alpha.clone(),
                    values,
                    band,
                }
            })
            .collect();
        coefficients.insert(
            c.to_string(),
            CoefficientSpec {
                terms,
                alpha_l_deg: vec![12.0, 11.0, 10.0],
                alpha_u_deg: vec![14.0, 13.0, 12.5],
            },
        );
    }
    let spec = DeltaModelSpec {
        schema: aero_core::delta_model::DELTA_MODEL_SCHEMA.into(),
        flaps_deg: flaps,
        alpha_channel: "alpha_deg".into(),
        flap_channel: "flap_deg".into(),
        coefficients,
        provenance: serde_json::json!({
            "library": "aerodelta 0.1.0", "data_sha256": "ab".repeat(32),
            "config": {"width_deg": 0.2, "structures": {"Cl": [["dCl_0", "1"]]}, "alpha": 0.05},
            "params_sha256": "cd".repeat(32)
        }),
        rolloff: Some(serde_json::json!({"enabled": true, "sigma_deg": [0.5, 0.7], "seed": 7})),
        envelope: None,
        longitudinal: None,
    };
    DeltaModel::new(spec)
        .expect("the seed model is valid")
        .to_json()
        .expect("serialises")
        .into_bytes()
}

pub const JSON_DICT: &[&[u8]] = &[
    b"{",
    b"}",
    b"[",
    b"]",
    b"\"",
    b",",
    b":",
    b"null",
    b"true",
    b"-",
    b"1e400",
    b"-1e400",
    b"1e-400",
    b"NaN",
    b"Infinity",
    b"18446744073709551616",
    b"\"schema\": \"aerodelta.model/1\",",
    b"\"values\": [[",
    b"\"regressor\": \"",
    b"\"alpha_deg\": [",
    b"\"flaps_deg\": [0],",
    b"\\u0000",
    b"\\ud800",
    b"\\",
    b"\\x",
    b"[[[[[[[[",
    b"]]]]]]]]",
    b"((((((((",
    b"deadband(",
    b"^",
    b"\xEF\xBB\xBF",
    b"\xFF",
    b" ",
    b"0",
    b"-0",
    b"1.5",
];

pub const JSON_PAIRS: &[(&[u8], &[u8])] =
    &[(b"[", b"]"), (b"{\"a\":", b"}"), (b"(", b")"), (b"-", b"")];

/// One model-file adversary.
#[derive(Debug, Clone)]
pub enum ModelAdversary {
    /// `[[[...]]]` or `{"a":{...}}` `.1` deep in field `.0`.
    Deep(usize, usize, bool),
    ManyAlpha(usize),
    ManyFlaps(usize),
    ManyTerms(usize),
    ManyCoefficients(usize),
    LongString(usize, usize),
    Number(usize, usize),
    Regressor(RegAdversary),
    DuplicateKeys(usize),
    Literal(usize),
}

fn model_adversary(scale: Scale) -> BoxedStrategy<ModelAdversary> {
    use ModelAdversary as M;
    let many = scale.many();
    let long = scale.long();
    prop_oneof![
        2 => (0usize..4, log_uniform(10, 100_000), any::<bool>()).prop_map(|(f, d, o)| M::Deep(f, d, o)),
        1 => log_uniform(1, many * 5).prop_map(M::ManyAlpha),
        1 => log_uniform(1, many).prop_map(M::ManyFlaps),
        1 => log_uniform(1, many / 4).prop_map(M::ManyTerms),
        1 => log_uniform(1, many / 8).prop_map(M::ManyCoefficients),
        1 => (0usize..6, log_uniform(1, long)).prop_map(|(f, n)| M::LongString(f, n)),
        1 => (0usize..5, 0usize..12).prop_map(|(f, k)| M::Number(f, k)),
        2 => reg_adversary(scale).prop_map(M::Regressor),
        1 => log_uniform(2, many).prop_map(M::DuplicateKeys),
        1 => (0usize..10).prop_map(M::Literal),
    ]
    .boxed()
}

fn model_json(flaps: &str, coefs: &str, provenance: &str) -> String {
    format!(
        "{{\"schema\": \"aerodelta.model/1\", \"flaps_deg\": {flaps}, \"coefficients\": {{{coefs}}}, \"provenance\": {provenance}}}"
    )
}

fn coef_json(name: &str, terms: &str, nflap: usize) -> String {
    let l = vec!["10"; nflap].join(",");
    let u = vec!["12"; nflap].join(",");
    format!("\"{name}\": {{\"terms\": [{terms}], \"alpha_l_deg\": [{l}], \"alpha_u_deg\": [{u}]}}")
}

fn term_json(name: &str, reg: &str, alpha: &str, values: &str) -> String {
    format!("{{\"name\": \"{name}\", \"regressor\": \"{reg}\", \"alpha_deg\": {alpha}, \"values\": {values}}}")
}

/// The bytes of a model-file adversary.
pub fn render_model(a: &ModelAdversary) -> Vec<u8> {
    use ModelAdversary as M;
    let one_term = |reg: &str| coef_json("Cl", &term_json("t", reg, "[10, 20]", "[[0, 1]]"), 1);
    let s = match a {
        M::Deep(field, d, obj) => {
            let (o, c) = if *obj { ("{\"a\":", "}") } else { ("[", "]") };
            let deep = format!("{}0{}", o.repeat(*d), c.repeat(*d));
            match field {
                0 => model_json("[0]", &one_term("1"), &deep),
                1 => model_json(
                    "[0]",
                    &coef_json("Cl", &term_json("t", "1", "[10, 20]", &deep), 1),
                    "{}",
                ),
                2 => model_json(&deep, &one_term("1"), "{}"),
                _ => deep,
            }
        }
        M::ManyAlpha(n) => {
            let alpha = format!("[{}]", numbers_list(*n, ","));
            let vals = format!("[[{}]]", vec!["0"; *n].join(","));
            model_json(
                "[0]",
                &coef_json("Cl", &term_json("t", "beta_deg", &alpha, &vals), 1),
                "{}",
            )
        }
        M::ManyFlaps(n) => {
            let rows = format!("[{}]", vec!["[0,1]"; *n].join(","));
            model_json(
                &format!("[{}]", numbers_list(*n, ",")),
                &coef_json("Cl", &term_json("t", "1", "[10, 20]", &rows), *n),
                "{}",
            )
        }
        M::ManyTerms(n) => {
            let terms: Vec<String> = (0..*n)
                .map(|k| term_json(&format!("t{k}"), "phat", "[10]", "[[1]]"))
                .collect();
            model_json("[0]", &coef_json("Cl", &terms.join(","), 1), "{}")
        }
        M::ManyCoefficients(n) => {
            let coefs: Vec<String> = (0..*n)
                .map(|k| coef_json(&format!("C{k}"), &term_json("t", "1", "[10]", "[[1]]"), 1))
                .collect();
            model_json("[0]", &coefs.join(","), "{}")
        }
        M::LongString(field, n) => {
            let long = "x".repeat(*n);
            match field {
                0 => model_json("[0]", &coef_json("Cl", &term_json(&long, "1", "[10]", "[[1]]"), 1), "{}"),
                1 => model_json("[0]", &one_term(&long), "{}"),
                2 => model_json("[0]", &coef_json(&long, &term_json("t", "1", "[10]", "[[1]]"), 1), "{}"),
                3 => model_json("[0]", &one_term("1"), &format!("\"{long}\"")),
                4 => format!("{{\"schema\": \"{long}\", \"flaps_deg\": [0], \"coefficients\": {{}}}}"),
                _ => format!("{{\"schema\": \"aerodelta.model/1\", \"alpha_channel\": \"{long}\", \"flaps_deg\": [0], \"coefficients\": {{{}}}}}", one_term("1")),
            }
        }
        M::Number(field, k) => {
            let ones = "1".repeat(400);
            let n = [
                "1e400",
                "-1e400",
                "1e-400",
                "NaN",
                "Infinity",
                "18446744073709551616",
                &ones,
                "-0",
                "0.0000000000000000000000001e-300",
                "1E+2",
                "+1",
                "01",
            ][*k % 12];
            match field {
                0 => model_json(&format!("[{n}]"), &one_term("1"), "{}"),
                1 => model_json("[0]", &coef_json("Cl", &term_json("t", "1", &format!("[{n}, 1e300]"), "[[0, 1]]"), 1), "{}"),
                2 => model_json("[0]", &coef_json("Cl", &term_json("t", "1", "[10, 20]", &format!("[[{n}, 1]]")), 1), "{}"),
                3 => model_json("[0]", &format!("\"Cl\": {{\"terms\": [], \"alpha_l_deg\": [{n}], \"alpha_u_deg\": [1e300]}}"), "{}"),
                _ => model_json("[0]", &one_term(&format!("{n} * beta_deg")), &format!("{{\"x\": {n}}}")),
            }
        }
        M::Regressor(r) => {
            let reg = render_regressor(r)
                .replace('\\', "\\\\")
                .replace('"', "\\\"");
            model_json("[0]", &one_term(&reg), "{}")
        }
        M::DuplicateKeys(n) => {
            let keys: String = (0..*n).map(|_| "\"flaps_deg\": [0],").collect();
            format!("{{\"schema\": \"aerodelta.model/1\", {keys} \"coefficients\": {{}}}}")
        }
        M::Literal(k) => [
            "",
            "null",
            "[]",
            "1",
            "\"x\"",
            "   ",
            "\u{FEFF}{}",
            "{}",
            "{\"schema\": 1}",
            "{\"schema\": \"aerodelta.model/1\"}",
        ][*k % 10]
            .to_string(),
    };
    s.into_bytes()
}

/// Model-file inputs: the seed mutated, invalid UTF-8, adversaries.
pub fn model_cases(scale: Scale) -> BoxedStrategy<Case> {
    let seeds = Arc::new(vec![model_seed()]);
    prop_oneof![
        6 => mutated(seeds.clone(), JSON_DICT, JSON_PAIRS, scale.big),
        1 => bad_utf8(seeds),
        4 => model_adversary(scale).prop_map(|a| case(&format!("{a:?}").chars().take(40).collect::<String>(), render_model(&a))),
    ]
    .boxed()
}

/// The strategy of `parser`'s inputs.
pub fn cases(parser: Parser, daveml_seeds: Arc<Vec<Vec<u8>>>, scale: Scale) -> BoxedStrategy<Case> {
    match parser {
        Parser::DaveMl => daveml_cases(daveml_seeds, scale),
        Parser::MathMl => mathml_cases(scale),
        Parser::Regressor => regressor_cases(scale),
        Parser::ModelFile => model_cases(scale),
    }
}

// ---------------------------------------------------------------------------
// Input classes at a chosen size, for the memory and time profile.

/// A named input class: its parser and its input at size knob `n`.
pub type Class = (Parser, String, Box<dyn Fn(usize) -> Vec<u8>>);

/// Every adversary family, one class each, for `--classes`.
pub fn classes() -> Vec<Class> {
    use ModelAdversary as M;
    use RegAdversary as R;
    use XmlAdversary as X;
    let mut out: Vec<Class> = Vec::new();
    let mut x = |name: &str, f: Box<dyn Fn(usize) -> XmlAdversary>| {
        out.push((
            Parser::DaveMl,
            name.to_string(),
            Box::new(move |n| render_xml(&f(n))),
        ));
    };
    x("nested elements", Box::new(X::NestGeneric));
    x("unclosed nesting", Box::new(X::NestUnclosed));
    for k in MATH_NESTS {
        x(
            &format!("MathML {k:?}"),
            Box::new(move |n| X::MathNest(k, n)),
        );
    }
    for (k, op) in ["plus", "times", "min", "lt", "and"].iter().enumerate() {
        x(
            &format!("MathML wide {op}"),
            Box::new(move |n| X::MathWide(k, n)),
        );
    }
    x(
        "long description",
        Box::new(|n| X::LongToken(Slot::Description, n, 0)),
    );
    x("long varID", Box::new(|n| X::LongToken(Slot::VarId, n, 0)));
    x(
        "long number",
        Box::new(|n| X::LongToken(Slot::BpValue, n, 1)),
    );
    x("many breakpoints", Box::new(X::ManyBreakpoints));
    x("many variables", Box::new(X::ManyVariables));
    x(
        "griddedTableRef x n (1000 values)",
        Box::new(|n| X::SharedTable(n, 1000)),
    );
    x(
        "griddedTableRef x 100 (n values)",
        Box::new(|n| X::SharedTable(100, n)),
    );
    x(
        "breakpoint set x n (100 values)",
        Box::new(|n| X::SharedBreakpoints(n, 100)),
    );
    x("check shots x n", Box::new(|n| X::ManyShots(n, n)));
    x("functions x n", Box::new(X::ManyFunctions));
    x("calculation chain", Box::new(X::Chain));
    x("dependency cycle", Box::new(X::Cycle));
    for (k, what) in [
        "<a/>",
        "<a/>x",
        "= in text",
        "< in a comment",
        "attributes",
        "namespaces",
        "empty comments",
        "&amp;",
        "CDATA",
    ]
    .iter()
    .enumerate()
    {
        x(&format!("dense {what}"), Box::new(move |n| X::Dense(k, n)));
    }
    x("DTD attribute lists", Box::new(|n| X::DoctypeTrick(2, n)));
    x("DTD comments", Box::new(|n| X::DoctypeTrick(4, n)));
    x(
        "quadratic entity",
        Box::new(|n| X::Quadratic(n, n / 10 + 1)),
    );
    let mut r = |name: &str, f: Box<dyn Fn(usize) -> RegAdversary>| {
        out.push((
            Parser::Regressor,
            name.to_string(),
            Box::new(move |n| render_regressor(&f(n)).into_bytes()),
        ));
    };
    r("parentheses", Box::new(R::Parens));
    r("unary minus", Box::new(R::UnaryMinus));
    r("power chain", Box::new(R::PowerChain));
    r("abs( calls", Box::new(|n| R::Calls(4, n)));
    r("flat sum", Box::new(R::FlatSum));
    r(
        "sum of products",
        Box::new(|n| R::SumOfProducts(n / 100 + 1, 100)),
    );
    r(
        "balanced",
        Box::new(|n| R::Balanced(((n as f64).log2() as usize).clamp(1, 22))),
    );
    r("long name", Box::new(R::LongName));
    r("long number", Box::new(R::LongNumber));
    r("(- pattern", Box::new(|n| R::Pattern(b"(-".to_vec(), n)));
    r(
        "min(a,a,... arguments",
        Box::new(|n| R::Pattern(b",a".to_vec(), n)),
    );
    let mut m = |name: &str, f: Box<dyn Fn(usize) -> ModelAdversary>| {
        out.push((
            Parser::ModelFile,
            name.to_string(),
            Box::new(move |n| render_model(&f(n))),
        ));
    };
    m("many alpha breakpoints", Box::new(M::ManyAlpha));
    m("many flaps", Box::new(M::ManyFlaps));
    m("many terms", Box::new(M::ManyTerms));
    m("many coefficients", Box::new(M::ManyCoefficients));
    m("deep provenance", Box::new(|n| M::Deep(0, n, false)));
    m("long term name", Box::new(|n| M::LongString(0, n)));
    m("long provenance string", Box::new(|n| M::LongString(3, n)));
    m("duplicate keys", Box::new(M::DuplicateKeys));
    out
}
