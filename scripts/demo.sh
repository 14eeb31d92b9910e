#!/usr/bin/env bash
# The main job, on the built-in virtual flight test campaign (no data of the user's needed):
# fly the campaign, ingest it, fit the Δ model, validate it on held-out maneuvers.
set -euo pipefail
. "$(dirname "${BASH_SOURCE[0]}")/env.sh"
aerodelta demo --out out/demo "$@"
