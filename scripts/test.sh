#!/usr/bin/env bash
# All tests: Rust (aero_core unit, property and doc tests) and Python (pytest).
set -euo pipefail
. "$(dirname "${BASH_SOURCE[0]}")/env.sh"
# The public DAVE-ML reference models (NASA check cases) are not part of the repo:
# they live in ../shared/data/daveml or $AERODELTA_SHARED_DAVEML. Without them the
# reference checks are skipped, and said so here; CI sets AERODELTA_REQUIRE_SHARED so
# that a missing folder fails instead.
ref="${AERODELTA_SHARED_DAVEML:-}"
if [ -z "$ref" ]; then
  for base in .. ../.. ../../..; do
    if [ -d "$base/shared/data/daveml" ]; then ref="$base/shared/data/daveml"; break; fi
  done
fi
if [ -n "$ref" ] && [ -d "$ref" ]; then
  echo "[aerodelta] DAVE-ML reference checks use $ref" >&2
elif [ -n "${AERODELTA_REQUIRE_SHARED:-}" ]; then
  echo "[aerodelta] error: AERODELTA_REQUIRE_SHARED is set but the public DAVE-ML models were not found (../shared/data/daveml or AERODELTA_SHARED_DAVEML)" >&2
  exit 1
else
  echo "[aerodelta] note: public DAVE-ML models not found (../shared/data/daveml); their reference checks are SKIPPED (set AERODELTA_SHARED_DAVEML=DIR to run them)" >&2
fi
echo "[aerodelta] Rust tests" >&2
cargo clippy --workspace --all-targets -- -D warnings
cargo test --workspace --exclude py_bindings --all-targets
cargo test --workspace --exclude py_bindings --doc
echo "[aerodelta] Python tests" >&2
set +e
python -m pytest "$@"
rc=$?
set -e
if [ "$rc" -eq 5 ]; then
  echo "[aerodelta] pytest collected no tests (exit 5): treated as success, but this should not happen" >&2
  rc=0
fi
exit "$rc"
