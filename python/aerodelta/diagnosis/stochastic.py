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

from typing import Any

import numpy as np
import polars as pl

from aerodelta import _core
from aerodelta.diagnosis.cv import SparseColumns
from aerodelta.diagnosis.data import maneuver_codes
from aerodelta.exceptions import AerodeltaError
from aerodelta.rolloff import detect_rolloff

#: Per-maneuver false-event rate allowed for the detector (issue 6's checks).
FALSE_EVENT_RATE = 0.10


def _binom_sf(k: int, n: int, p: float) -> float:
    """P(X >= k) for X ~ Binomial(n, p): the regularized incomplete beta ``I_p(k, n - k + 1)``
    (Abramowitz & Stegun 26.5.24), which holds for any n (the term-by-term sum of
    ``comb(n, i) p^i (1-p)^(n-i)`` overflowed a float past about 1,030 maneuvers)."""
    if k <= 0:
        return 1.0
    if k > n:
        return 0.0
    return float(_core.beta_inc_reg(float(k), float(n - k + 1), float(p)))


#: Standard deviation in alpha of a roll-off's moment, deg (thesis Figure 3.14 and its text).
ROLLOFF_SIGMA_DEG = 0.5


#: Re-arm alpha of the runtime roll-off model, deg: a draw is made when alpha crosses it upward
#: (``aero_core::rolloff``; thesis Section 3.4.3).
REARM_ALPHA_DEG = 15.0

#: Re-arm hysteresis of the runtime model, deg (``rearm_hysteresis_deg``, default 2).
REARM_HYSTERESIS_DEG = 2.0

#: A spike is spent once the alpha travelled past its centre exceeds this many widths
#: (``aero_core::rolloff::SPENT_WIDTHS``).
SPENT_WIDTHS = 4.0


def travelled_alpha(alpha: np.ndarray, centre: float) -> np.ndarray:
    """The alpha at which the runtime roll-off model evaluates its Gaussian along one stall,
    deg (``aero_core::rolloff``): ``alpha`` until the stall has reached the centre, then the
    alpha travelled since, ``top + (top - alpha)`` with ``top`` the highest alpha so far, so
    the spike decays when the stall turns back instead of being met a second time."""
    top = np.maximum.accumulate(alpha)
    return np.where(top >= centre, 2.0 * top - alpha, alpha)


def draw_index(a_m: np.ndarray, t_m: np.ndarray, tp: float) -> int:
    """Index of the sample at which the runtime model made the draw met at time ``tp``: the
    last armed upward crossing of the re-arm alpha before it (the model is armed at first and
    re-armed only once alpha falls :data:`REARM_HYSTERESIS_DEG` below the re-arm alpha, so
    gusts around 15 deg do not redraw); 0 when the record starts above it."""
    up = np.flatnonzero((a_m[1:] >= REARM_ALPHA_DEG) & (a_m[:-1] < REARM_ALPHA_DEG)) + 1
    low = a_m < REARM_ALPHA_DEG - REARM_HYSTERESIS_DEG
    start, armed, prev = 0, True, 0
    for i in up:
        if t_m[i] > tp:
            break
        if not armed and low[prev:i].any():
            armed = True
        if armed:
            start, armed, prev = int(i), False, int(i)
    return start


def _spike_columns(
    a_m: np.ndarray, start: int, ac: float, sigma_deg: float
) -> tuple[np.ndarray, np.ndarray]:
    """The two nuisance columns of one event along one maneuver (rows in time order), the
    draw at row ``start`` (:func:`draw_index`)."""
    g = np.zeros(a_m.size)
    ug = np.zeros(a_m.size)
    eff = travelled_alpha(a_m[start:], ac)
    live = ~np.maximum.accumulate(eff >= ac + SPENT_WIDTHS * sigma_deg)
    u = (eff[live] - ac) / sigma_deg
    idx = np.flatnonzero(live) + start
    g[idx] = np.exp(-0.5 * u * u)
    ug[idx] = u * g[idx]
    return g, ug


def _by_maneuver(frame: pl.DataFrame) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """Row indices of each maneuver in time order, and the alpha and time columns."""
    names, code = maneuver_codes(frame)
    t = frame["t"].to_numpy() if "t" in frame.columns else np.arange(frame.height, dtype=float)
    order = np.lexsort((t, code))
    bounds = np.searchsorted(code[order], np.arange(len(names) + 1))
    rows = {m: order[bounds[i] : bounds[i + 1]] for i, m in enumerate(names)}
    return rows, frame["alpha_deg"].to_numpy(), t


def event_regressors(
    frame: pl.DataFrame,
    centres: list[tuple[str, float, float]],
    sigma_deg: float = ROLLOFF_SIGMA_DEG,
) -> np.ndarray:
    """Per-event nuisance columns of the roll-off moment (``n x 2K``, ``K`` the most events of
    one maneuver): for the ``j``-th event ``(maneuver, alpha_c, t_peak)`` of a maneuver, the
    Gaussian ``g = exp(-u^2/2)``, ``u = (alpha_e - alpha_c)/sigma``, the runtime model's shape
    (thesis Section 3.4.3, Figure 3.14), and ``u g``, its derivative in the centre, which
    absorbs a small error in the centre; zero on the other maneuvers' rows.

    ``alpha_e`` follows the runtime model along the record (``aero_core::rolloff``): zero
    before the draw (the last armed upward crossing of the re-arm alpha before the peak,
    :func:`draw_index`), the alpha travelled past the centre once the stall has reached it
    (:func:`travelled_alpha`, so the spike is not met again on the way down), and zero once
    the spike is spent. Their amplitudes are a random draw per event, so they are profiled out
    per maneuver (:func:`aerodelta.diagnosis.cv.profile_out`), never predicted.

    :func:`event_columns` gives the same columns without their zeros."""
    return event_columns(frame, centres, sigma_deg).dense()


def event_columns(
    frame: pl.DataFrame,
    centres: list[tuple[str, float, float]],
    sigma_deg: float = ROLLOFF_SIGMA_DEG,
) -> SparseColumns:
    """The columns of :func:`event_regressors` as their non-zero entries (a column is zero
    but on its events' maneuvers, from the draw until the spike is spent)."""
    rows_of, alpha, t = _by_maneuver(frame)
    per: dict[str, list[tuple[float, float]]] = {}
    for m, ac, tp in centres:
        if m in rows_of:
            per.setdefault(m, []).append((float(ac), float(tp)))
    k = max((len(v) for v in per.values()), default=0)
    rows: list[list[np.ndarray]] = [[] for _ in range(2 * k)]
    vals: list[list[np.ndarray]] = [[] for _ in range(2 * k)]
    for m, cs in per.items():
        r_m = rows_of[m]
        for j, (ac, tp) in enumerate(sorted(cs, key=lambda x: x[0])):
            start = draw_index(alpha[r_m], t[r_m], tp)
            g, ug = _spike_columns(alpha[r_m], start, ac, sigma_deg)
            for c, v in ((2 * j, g), (2 * j + 1, ug)):
                nz = np.flatnonzero(v)
                rows[c].append(r_m[nz])
                vals[c].append(v[nz])
    return SparseColumns(
        frame.height,
        [np.concatenate(r) if r else np.zeros(0, dtype=np.int64) for r in rows],
        [np.concatenate(v) if v else np.zeros(0) for v in vals],
    )


#: Centres tried above a spike's peak alpha, deg (:func:`refine_centres`).
CENTRE_SHIFTS_DEG = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5)


def refine_centres(
    frame: pl.DataFrame,
    residual: np.ndarray,
    centres: list[tuple[str, float, float]],
    sigma_deg: float = ROLLOFF_SIGMA_DEG,
) -> list[tuple[str, float, float]]:
    """Each event's centre chosen among its peak alpha and up to 1.5 deg above it
    (:data:`CENTRE_SHIFTS_DEG`) by the residual its two columns leave in its maneuver.

    A stall that turns back before a roll-off's centre meets only its rising flank: the
    spike peaks at the stall's highest alpha, below the centre, and falls off faster in alpha
    than a Gaussian centred at that peak (on a virtual campaign, a flank met 1 deg below the
    centre left 48 % of the spike's RMS with the centre at the peak, none with the centre
    found here). A spike the stall passes peaks at its centre, where the search stays."""
    rows_of, alpha, t = _by_maneuver(frame)
    out = []
    for m, ac, tp in centres:
        rows = rows_of.get(m)
        if rows is None:
            out.append((m, ac, tp))
            continue
        r = residual[rows]
        start = draw_index(alpha[rows], t[rows], tp)  # the same draw for every centre tried
        best, best_c = -1.0, ac
        for dc in CENTRE_SHIFTS_DEG:
            g, ug = _spike_columns(alpha[rows], start, ac + dc, sigma_deg)
            x = np.column_stack([g, ug])
            nz = np.flatnonzero(np.any(x != 0.0, axis=1))
            if nz.size < 3:
                continue
            coef, *_ = np.linalg.lstsq(x[nz], r[nz], rcond=None)
            explained = float(np.sum((x[nz] @ coef) ** 2))
            if explained > best:
                best, best_c = explained, ac + dc
        out.append((m, best_c, tp))
    return out


#: The channels :func:`aerodelta.rolloff.detect_rolloff` reads (it is given only these: it
#: splits the records by maneuver, copying every column it is given).
DETECTOR_CHANNELS = (
    "maneuver_id", "t", "alpha_deg", "Cl_meas", "da_deg", "dr_deg", "ds_deg", "flap_deg", "kind",
)  # fmt: skip


def rolloff_finding(frame: pl.DataFrame, residual: np.ndarray) -> dict[str, Any]:
    """Roll-off events in the unexplained C_l gap, and whether they are more than chance."""
    need = {"maneuver_id", "t", "alpha_deg", "da_deg"}

    def not_searched(why: str) -> dict[str, Any]:
        return {"detected": False, "n_events": 0, "n_searched": 0, "p_value": 1.0,
                "alpha_range_deg": [float("nan")] * 2, "events": [], "centres": [],
                "note": f"roll-off not searched: {why}"}  # fmt: skip

    if not need <= set(frame.columns):
        return not_searched(f"the records lack {sorted(need - set(frame.columns))}")
    try:
        # the frame's alpha_deg is already the CG-referred alpha (the detector's default channel)
        ev = detect_rolloff(
            frame.select([c for c in DETECTOR_CHANNELS if c in frame.columns]),
            residual=np.asarray(residual, dtype=np.float64),
            kinds=None,
            alpha="alpha_deg",
        )
    except AerodeltaError as exc:  # the detector refusing these data; anything else propagates
        return not_searched(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
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
    centres = refine_centres(
        frame,
        np.asarray(residual, dtype=np.float64),
        [
            (r["maneuver_id"], float(r["alpha_peak_deg"]), float(r["t_peak"]))
            for r in ev.iter_rows(named=True)
        ],
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
        "centres": centres,
    }
