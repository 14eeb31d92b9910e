"""The stochastic part of the gap: roll-off spikes (thesis Section 3.4.3).

A roll-off is a transient, uncorrelated C_l spike near stall while the aileron is quiet; it is
not a deterministic effect and no regressor can predict it. It is searched for in the C_l gap
left after the selected deterministic effects, with the thesis's detection procedure
(:func:`aerodelta.rolloff.detect_rolloff`); each accepted event's moment, a Gaussian in alpha
with its own random amplitude, is then profiled out of its maneuver's data before the
deterministic effects are selected again. It is reported when events are found in more
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


#: Standard deviation in alpha of a roll-off's moment, deg (thesis Figure 3.14 and its text).
ROLLOFF_SIGMA_DEG = 0.5


def event_regressors(
    frame: pl.DataFrame, centres: list[tuple[str, float]], sigma_deg: float = ROLLOFF_SIGMA_DEG
) -> np.ndarray:
    """Per-event nuisance columns of the roll-off moment (``n x 2K``, ``K`` the most events of
    one maneuver): for the ``j``-th event of a maneuver, centred at ``alpha_c``, the Gaussian
    ``g = exp(-u^2/2)``, ``u = (alpha - alpha_c)/sigma``, the runtime model's shape (thesis
    Section 3.4.3), and ``u g``, its derivative in the centre, which absorbs the error of
    taking the spike's peak alpha for the centre; zero on the other maneuvers' rows. Their
    amplitudes are a random draw per event, so they are profiled out per maneuver
    (:func:`aerodelta.diagnosis.cv.profile_out`), never predicted."""
    names, code = np.unique(frame["maneuver_id"].to_numpy(), return_inverse=True)
    alpha = frame["alpha_deg"].to_numpy()
    order = np.argsort(code, kind="stable")
    bounds = np.searchsorted(code[order], np.arange(names.size + 1))
    where = {str(m): i for i, m in enumerate(names)}
    per: dict[int, list[float]] = {}
    for m, a in centres:
        if m in where:
            per.setdefault(where[m], []).append(a)
    k = max((len(v) for v in per.values()), default=0)
    out = np.zeros((frame.height, 2 * k))
    for i, cs in per.items():
        rows = order[bounds[i] : bounds[i + 1]]
        for j, ac in enumerate(sorted(cs)):
            u = (alpha[rows] - ac) / sigma_deg
            g = np.exp(-0.5 * u * u)
            out[rows, 2 * j] = g
            out[rows, 2 * j + 1] = u * g
    return out


def rolloff_finding(frame: pl.DataFrame, residual: np.ndarray) -> dict[str, Any]:
    """Roll-off events in the unexplained C_l gap, and whether they are more than chance."""
    need = {"maneuver_id", "t", "alpha_deg", "da_deg"}
    if not need <= set(frame.columns):
        return {"detected": False, "n_events": 0, "n_searched": 0, "p_value": 1.0,
                "alpha_range_deg": [float("nan")] * 2, "events": [], "centres": []}  # fmt: skip
    try:
        # the frame's alpha_deg is already the CG-referred alpha (the detector's default channel)
        ev = detect_rolloff(
            frame,
            residual=np.asarray(residual, dtype=np.float64),
            kinds=None,
            alpha="alpha_deg",
        )
    except Exception as exc:
        return {"detected": False, "n_events": 0, "n_searched": 0, "p_value": 1.0,
                "alpha_range_deg": [float("nan")] * 2, "events": [], "centres": [],
                "error": str(exc)}  # fmt: skip
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
    # every spike-shaped candidate's (maneuver, alpha at the spike's peak), accepted or not: a
    # roll-off the pilot answered with the aileron at once is rejected by step 2 of the
    # procedure but is still a moment no regressor predicts
    centres = [(r["maneuver_id"], float(r["alpha_peak_deg"])) for r in ev.iter_rows(named=True)]
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
        "centres": centres,
    }
