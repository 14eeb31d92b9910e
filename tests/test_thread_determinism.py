"""Same data, same bytes whatever the number of threads (the brief's determinism rule).

The engine's thread pool is sized once per process, so each fit runs in a child interpreter
with ``RAYON_NUM_THREADS`` set: 1 thread, then 3 (more workers than this machine's cores, so
the bins and bootstrap replicates are split and stolen differently). The params table
(estimates, every standard error incl. the coloured-residual one, bootstrap bands) and the
model file must be byte-identical.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

_CHILD = r"""
import hashlib, json, sys
import aerodelta as ad
from aerodelta.ingest import ingest

data = ingest(sys.argv[1], compat=False).data
res = ad.fit(data, config=ad.FitConfig(bootstrap=20, seed=3))
table = res.summary()
print(hashlib.sha256(table.write_ipc(None).getvalue()).hexdigest())
print(hashlib.sha256(table["std_err_colored"].to_numpy().tobytes()).hexdigest())
print(hashlib.sha256(json.dumps(res.model.to_spec(), sort_keys=True).encode()).hexdigest())
"""


def _fit_digest(campaign: Path, threads: int) -> list[str]:
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, str(campaign)],
        env=env, capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.split()


def test_fit_bytes_do_not_depend_on_thread_count(quick_campaign: Path) -> None:
    one = _fit_digest(quick_campaign, 1)
    three = _fit_digest(quick_campaign, 3)
    assert len(one) == 3
    assert one == three, "params table / std_err_colored / model differ between 1 and 3 threads"
    assert hashlib.sha256(b"").hexdigest() not in one
