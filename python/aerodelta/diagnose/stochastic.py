"""The stochastic part of the gap: roll-off spikes (thesis Section 3.4.3).

A roll-off is a transient, uncorrelated C_l spike near stall while the aileron is quiet; it is
not a deterministic effect and no regressor can predict it. It is searched for in the C_l gap
left after the selected deterministic effects, with the thesis's detection procedure
(:func:`aerodelta.rolloff.detect_rolloff`). It is reported when events are found in more
maneuvers than the detector's false-event rate explains (a binomial tail test against the
10 % false-event allowance of issue 6's checks).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import polars as pl

from aerodelta.rolloff import detect_rolloff

#: Per-maneuver false-event rate allowed for the detector (issue 6's checks).
FALSE_EVENT_RATE = 0.10


def _binom_sf(k: int, n: int, p: float) -> float:
    """P(X >= k) for X ~ Binomial(n, p)."""
    return float(sum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k, n + 1)))


def rolloff_finding(frame: pl.DataFrame, residual: np.ndarray) -> dict[str, Any]:
    """Roll-off events in the unexplained C_l gap, and whether they are more than chance."""
    need = {"maneuver_id", "t", "alpha_deg", "da_deg"}
    if not need <= set(frame.columns):
        return {"detected": False, "n_events": 0, "n_searched": 0, "p_value": 1.0,
                "alpha_range_deg": [float("nan")] * 2, "events": []}  # fmt: skip
    try:
        ev = detect_rolloff(frame, residual=np.asarray(residual, dtype=np.float64), kinds=None)
    except Exception as exc:
        return {"detected": False, "n_events": 0, "n_searched": 0, "p_value": 1.0,
                "alpha_range_deg": [float("nan")] * 2, "events": [], "error": str(exc)}  # fmt: skip
    acc = ev.filter(pl.col("accepted")) if ev.height else ev
    n_man = int(frame["maneuver_id"].n_unique())
    k = int(acc["maneuver_id"].n_unique()) if acc.height else 0
    p = _binom_sf(k, n_man, FALSE_EVENT_RATE) if k else 1.0
    detected = bool(k >= 3 and p < 0.01)
    rng = (
        [float(acc["alpha_onset_deg"].quantile(0.1)), float(acc["alpha_onset_deg"].quantile(0.9))]  # type: ignore[arg-type]
        if acc.height
        else [float("nan"), float("nan")]
    )
    events = [
        {
            "maneuver_id": r["maneuver_id"],
            "t_onset_s": float(r["t_onset"]),
            "alpha_onset_deg": float(r["alpha_onset_deg"]),
            "peak": float(r["peak"]),
        }
        for r in acc.head(50).iter_rows(named=True)
    ]
    return {
        "detected": detected,
        "n_events": int(acc.height),
        "n_maneuvers_with_events": k,
        "n_searched": n_man,
        "p_value": p,
        "alpha_range_deg": rng,
        "events": events,
    }
