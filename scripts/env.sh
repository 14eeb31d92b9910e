# Sourced by scripts/demo.sh and scripts/test.sh: make sure .venv holds this
# checkout's aerodelta (built from source with maturin) and its test peers.
# Rebuilds when any tracked source file changed since the last install.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
py="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  echo "[aerodelta] creating .venv" >&2
  "$py" -m venv .venv
fi
# shellcheck disable=SC1091
. .venv/bin/activate
stamp_now="$( (git ls-files -s 2>/dev/null; git diff 2>/dev/null; git ls-files --others --exclude-standard 2>/dev/null | xargs -r cat 2>/dev/null) | sha256sum | cut -c1-16)"
if [ ! -f .install-stamp ] || [ "$(cat .install-stamp)" != "$stamp_now" ] || ! python -c "import aerodelta" 2>/dev/null; then
  echo "[aerodelta] installing aerodelta with its test extras into .venv (builds the Rust engine)" >&2
  python -m pip install --quiet --upgrade pip
  # Show the build's progress (cargo's Compiling lines; a cold build takes minutes) and keep the
  # full log; on failure print its tail.
  log="$(mktemp "${TMPDIR:-/tmp}/aerodelta-install.XXXXXX")"
  set +e
  python -m pip install -v ".[test]" 2>&1 | tee "$log" \
    | { grep --line-buffered -E '^ *(Compiling|Finished|Built wheel|Successfully installed)' >&2 || true; }
  rc=${PIPESTATUS[0]}
  set -e
  if [ "$rc" -ne 0 ]; then
    echo "[aerodelta] install failed (pip exit $rc); last lines of $log:" >&2
    tail -n 60 "$log" >&2
    exit 1
  fi
  rm -f "$log"
  echo "$stamp_now" > .install-stamp
fi
