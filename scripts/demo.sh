#!/usr/bin/env bash
# The main job, on data and models the project ships itself (no user data needed).
set -euo pipefail
. "$(dirname "${BASH_SOURCE[0]}")/env.sh"
mkdir -p out
aerodelta write-example-model out/example_aero.dml
aerodelta check-daveml out/example_aero.dml "$@"
