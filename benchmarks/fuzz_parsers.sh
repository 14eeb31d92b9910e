#!/usr/bin/env bash
# The fuzzing floor of issue 18: 10^5 structured cases per parser (DAVE-ML,
# MathML, regressor, model file) in release, each on a fresh 2 MiB-stack
# thread, with a counting allocator: per parser the cases, Ok/refused counts,
# crashes, hangs (a case over 1 s), contract violations, the slowest case and
# the parse's peak heap against 20 times its input; PASS/FAIL lines.
#
#   bash benchmarks/fuzz_parsers.sh                      # 100000 cases per parser
#   CASES=2000 bash benchmarks/fuzz_parsers.sh --parser regressor
#   bash benchmarks/fuzz_parsers.sh --classes            # memory/time of every input class
#
# Other options are the example's (crates/aero_core/examples/fuzz_parsers.rs):
# --seed, --start (case K of a seed is always the same input), --hang-ms,
# --save DIR (inputs of failing cases), --replay FILE. Set
# AERODELTA_SHARED_DAVEML to the public models' folder to mutate them too.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -p aero_core --example fuzz_parsers
exec "${CARGO_TARGET_DIR:-target}/release/examples/fuzz_parsers" --cases "${CASES:-100000}" "$@"
