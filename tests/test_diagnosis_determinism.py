"""Two small regressions of the gap diagnosis (issue 17): the binomial tail past 1,030
maneuvers, and the gap map's bytes from one process to the next."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from scipy.stats import binom

from aerodelta.diagnosis.stochastic import _binom_sf


@pytest.mark.parametrize(
    ("k", "n", "p"),
    [(0, 10, 0.3), (1, 10, 0.3), (3, 10, 0.05), (10, 10, 0.5), (11, 10, 0.5), (60, 2000, 0.02),
     (40, 2000, 0.02), (3, 5000, 0.0005), (1200, 5000, 0.25)],
)  # fmt: skip
def test_binomial_tail_matches_scipy_for_any_campaign_size(k: int, n: int, p: float) -> None:
    want = float(binom.sf(k - 1, n, p)) if k > 0 else 1.0
    got = _binom_sf(k, n, p)
    assert got == pytest.approx(want, rel=1e-9, abs=1e-300)


_SCRIPT = """
import json, numpy as np, polars as pl
from aerodelta.diagnosis.where import gap_map
rng = np.random.default_rng(4)
n = 40_000
frame = pl.DataFrame({
    "maneuver_id": rng.integers(0, 300, n),
    "flap_deg": rng.choice([0.0, 10.0, 20.0], n),
    "alpha_deg": rng.uniform(0, 25, n),
})
gap = rng.normal(0, 1e-3, n) + 1e-3 * (frame["alpha_deg"].to_numpy() > 15)
phase = np.where(frame["alpha_deg"].to_numpy() > 14, "stall", "pre_stall")
print(json.dumps(gap_map(frame, gap, phase, 1.0, 0.05)))
"""


def test_gap_map_is_the_same_bytes_in_every_process() -> None:
    # polars seeds its hash per process: two processes aggregate in different hash orders
    runs = [
        subprocess.run(
            [sys.executable, "-c", _SCRIPT], capture_output=True, text=True, check=True
        ).stdout
        for _ in range(3)
    ]
    assert json.loads(runs[0])  # cells were found
    assert runs[0] == runs[1] == runs[2]
