"""The stochastic part of the gap: roll-off spikes (thesis Section 3.4.3).

A roll-off is a transient, uncorrelated C_l spike near stall while the aileron is quiet; it is
not a deterministic effect and no regressor can predict it. It is searched for in the C_l gap
left after the selected deterministic effects, with the thesis's detection procedure
(:func:`aerodelta.rolloff.detect_rolloff`); each accepted event's moment, a Gaussian in alpha
with its own random amplitude, is then profiled out of its maneuver's data before the
deterministic effects are selected again. It is reported when events are found in more
maneuvers than the detector's false-event rate explains (a binomial tail test against the
10 % false-event allowance of issue 6's checks), counted over the wings-level (``straight``)
stalls when the records carry maneuver kinds: the thesis derives its roll-off statistics from
wings-level stalls (and :func:`aerodelta.rolloff.detect_rolloff` searches them by default),
while in turning and cross-controlled stalls the maneuver's own rolling moments (sideslip,
rates) leave spikes of deterministic origin (on the DHC-6 with its kinked C_lβ withheld,
gust-driven sideslip left same-sign spikes at the same alpha in its cross-controlled stalls,
and roll-off was called where JSBSim has none). Events of every kind are reported and, once
roll-off is called, profiled out.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import polars as pl

from aerodelta import _core
from aerodelta.diagnosis.cv import SparseColumns
from aerodelta.diagnosis.data import maneuver_codes
from aerodelta.exceptions import AerodeltaError
from aerodelta.rolloff import detect_rolloff

#: Per-maneuver false-event rate allowed for the detector (issue 6's checks).
FALSE_EVENT_RATE = 0.10
#: Maneuver kinds whose events the roll-off call counts (the thesis's wings-level stalls).
CALL_KINDS = ("straight",)


def _binom_sf(k: int, n: int, p: float) -> float:
    """P(X >= k) for X ~ Binomial(n, p): the regularized incomplete beta ``I_p(k, n - k + 1)``
    (Abramowitz & Stegun 26.5.24), which holds for any n (the term-by-term sum of
    ``comb(n, i) p^i (1-p)^(n-i)`` overflowed a float past about 1,030 maneuvers)."""
    if k <= 0:
        return 1.0
    if k > n:
        return 0.0
    return float(_core.beta_inc_reg(float(k), float(n - k + 1), float(p)))


#: The runtime roll-off model's spike shape and the centre search, from the engine
#: (``aero_core::rolloff_events``, after ``aero_core::rolloff``).
_ENGINE = _core.rolloff_event_defaults()

#: Standard deviation in alpha of a roll-off's moment, deg (thesis Figure 3.14 and its text;
#: the runtime model's width).
ROLLOFF_SIGMA_DEG: float = float(_ENGINE["width_deg"])

#: Centres tried above a spike's peak alpha, deg (:func:`refine_centres`).
CENTRE_SHIFTS_DEG: tuple[float, ...] = tuple(float(x) for x in _ENGINE["centre_shifts_deg"])


class _Layout(NamedTuple):
    """The records as the engine reads them: per maneuver its rows in time order,
    ``rows[bounds[i]:bounds[i + 1]]`` for the ``i``-th of ``code`` (maneuver id -> index), and
    the alpha and time columns."""

    code: dict[str, int]
    rows: np.ndarray
    bounds: np.ndarray
    alpha: np.ndarray
    t: np.ndarray


def _by_maneuver(frame: pl.DataFrame) -> _Layout:
    """Row indices of each maneuver in time order, and the alpha and time columns."""
    names, code = maneuver_codes(frame)
    t = frame["t"].to_numpy() if "t" in frame.columns else np.arange(frame.height, dtype=float)
    order = np.lexsort((t, code))
    bounds = np.searchsorted(code[order], np.arange(len(names) + 1))
    return _Layout(
        {m: i for i, m in enumerate(names)},
        np.ascontiguousarray(order, dtype=np.int64),
        np.ascontiguousarray(bounds, dtype=np.int64),
        np.ascontiguousarray(frame["alpha_deg"].to_numpy(), dtype=np.float64),
        np.ascontiguousarray(t, dtype=np.float64),
    )


def _events(
    lay: _Layout, centres: list[tuple[str, float, float]]
) -> tuple[list[int], np.ndarray, np.ndarray, np.ndarray]:
    """The events on the layout's maneuvers (the others are left out): their positions in
    ``centres``, and their maneuver indices, centres and peak times as arrays."""
    keep = [i for i, (m, _, _) in enumerate(centres) if m in lay.code]
    return (
        keep,
        np.array([lay.code[centres[i][0]] for i in keep], dtype=np.int64),
        np.array([float(centres[i][1]) for i in keep], dtype=np.float64),
        np.array([float(centres[i][2]) for i in keep], dtype=np.float64),
    )


def event_regressors(
    frame: pl.DataFrame,
    centres: list[tuple[str, float, float]],
    sigma_deg: float = ROLLOFF_SIGMA_DEG,
) -> np.ndarray:
    """Per-event nuisance columns of the roll-off moment (``n x 2K``, ``K`` the most events of
    one maneuver): for the ``j``-th event ``(maneuver, alpha_c, t_peak)`` of a maneuver (by
    centre), the Gaussian ``g = exp(-u^2/2)``, ``u = (alpha_e - alpha_c)/sigma``, the runtime
    model's shape (thesis Section 3.4.3, Figure 3.14), and ``u g``, its derivative in the
    centre, which absorbs a small error in the centre; zero on the other maneuvers' rows.

    ``alpha_e`` follows the runtime model along the record (``aero_core::rolloff``):

    - zero before the draw: the last armed upward crossing of the re-arm alpha (15 deg) at or
      before the peak (the model is armed at first and re-armed only once alpha falls the
      2-deg hysteresis below the re-arm alpha, so gusts around 15 deg do not redraw); the
      record's first row when it starts above the re-arm alpha;
    - the flown alpha until the stall has reached the centre, then the alpha travelled since,
      ``top + (top - alpha)`` with ``top`` the highest alpha since the draw, so the spike
      decays when the stall turns back instead of being met a second time;
    - zero once that alpha is four widths past the centre (the spike is spent), and after.

    Their amplitudes are a random draw per event, so they are profiled out per maneuver
    (:func:`aerodelta.diagnosis.cv.profile_out`), never predicted. The columns are computed by
    the engine (``aero_core::rolloff_events::event_columns``).

    :func:`event_columns` gives the same columns without their zeros."""
    return event_columns(frame, centres, sigma_deg).dense()


def event_columns(
    frame: pl.DataFrame,
    centres: list[tuple[str, float, float]],
    sigma_deg: float = ROLLOFF_SIGMA_DEG,
) -> SparseColumns:
    """The columns of :func:`event_regressors` as their non-zero entries (a column is zero
    but on its events' maneuvers, from the draw until the spike is spent): per column the
    maneuvers in the order of their first event in ``centres``, each's rows in time order.
    Events on maneuvers the frame does not have are left out."""
    lay = _by_maneuver(frame)
    _, code, centre, t_peak = _events(lay, centres)
    rows, values = _core.rolloff_event_columns(
        lay.rows, lay.bounds, lay.alpha, lay.t, code, centre, t_peak, float(sigma_deg)
    )
    return SparseColumns(frame.height, rows, values)


def refine_centres(
    frame: pl.DataFrame,
    residual: np.ndarray,
    centres: list[tuple[str, float, float]],
    sigma_deg: float = ROLLOFF_SIGMA_DEG,
) -> list[tuple[str, float, float]]:
    """Each event's centre chosen among its peak alpha and up to 1.5 deg above it
    (:data:`CENTRE_SHIFTS_DEG`) by the residual its two columns leave in its maneuver: the
    centre whose columns' least-squares fit explains the most of the residual (sum of squared
    fitted values on the rows where they are non-zero; the first such centre on a tie; the
    peak alpha kept when no centre has three such rows). The same draw serves every centre
    tried. The search runs in the engine (``aero_core::rolloff_events::refine_centres``);
    events on maneuvers the frame does not have keep their centre.

    A stall that turns back before a roll-off's centre meets only its rising flank: the
    spike peaks at the stall's highest alpha, below the centre, and falls off faster in alpha
    than a Gaussian centred at that peak (on a virtual campaign, a flank met 1 deg below the
    centre left 48 % of the spike's RMS with the centre at the peak, none with the centre
    found here). A spike the stall passes peaks at its centre, where the search stays."""
    lay = _by_maneuver(frame)
    keep, code, centre, t_peak = _events(lay, centres)
    refined = _core.rolloff_refine_centres(
        lay.rows, lay.bounds, lay.alpha, lay.t,
        np.ascontiguousarray(residual, dtype=np.float64),
        code, centre, t_peak, float(sigma_deg),
    )  # fmt: skip
    out = [(m, ac, tp) for m, ac, tp in centres]
    for i, c in zip(keep, refined.tolist(), strict=True):
        out[i] = (centres[i][0], c, centres[i][2])
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
    # the call counts the wings-level stalls when the records say which they are
    call = (
        frame.filter(pl.col("kind").is_in(list(CALL_KINDS)))["maneuver_id"].unique()
        if "kind" in frame.columns and frame["kind"].is_in(list(CALL_KINDS)).any()
        else None
    )
    n_all = int(frame["maneuver_id"].n_unique())
    n_man = n_all if call is None else int(call.len())
    counted = (
        acc
        if call is None or not acc.height
        else acc.filter(pl.col("maneuver_id").is_in(call.implode()))
    )
    k = int(counted["maneuver_id"].n_unique()) if counted.height else 0
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
        "n_maneuvers_with_events": int(acc["maneuver_id"].n_unique()) if acc.height else 0,
        "n_searched": n_all,
        # the call's binomial test: the maneuvers with events among those it counts
        "call_kinds": list(CALL_KINDS) if call is not None else [],
        "call_maneuvers_with_events": k,
        "call_maneuvers": n_man,
        "p_value": p,
        "alpha_range_deg": rng,
        "events": events,
        "centres": centres,
    }
