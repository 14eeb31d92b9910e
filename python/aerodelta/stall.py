"""Stall identification from flight records and the validity range it asks for (``docs/stall.md``).

As we read 14 CFR Part 60 Appendix A, Attachment 7 (FSTD Directive 2, full-stall training), the
stall-identification angle of attack is where the first of these occurs: the stick pusher
activates; an uncommanded nose-down pitch that cannot be readily arrested (the pitch break),
possibly with a loss of normal load factor (the g-break); a deterrent buffet; or no further
increase in pitch with the pitch control held at its aft stop for 2 s. The aerodynamic model must
be valid to at least 10 deg of alpha beyond it. This module measures each criterion per maneuver
(:func:`stall_identification`), aggregates them per flap and maneuver kind
(:func:`stall_summary`) and checks the alpha the records cover against the +10 deg requirement
(:func:`validity_range`).

Each criterion, as measured here (constants below, times in s, angles in deg):

- **pusher**: the first sample of the optional ``pusher_active`` discrete above 0.5;
- **pitch break**: the onset of a sudden nose-down pitch (the first sample of a run where the
  pitch-attitude rate, θ smoothed over :data:`SMOOTH_S` then differentiated, is at or below
  ``-PITCH_BREAK_RATE_DPS`` although it was >= 0 within the preceding
  :data:`PITCH_BREAK_WINDOW_S`: the nose starts going down, a steady descending turn is none)
  that the elevator did not command: at the onset it (smoothed over
  :data:`SMOOTH_S`) lies within :data:`COMMAND_TOL_DEG` of its most nose-up position of the
  preceding :data:`COMMAND_WINDOW_S` (positive elevator is nose down, Etkin);
- **g-break**: the first sample where the normal load factor n = -a_z,CG / g, per unit dynamic
  pressure (n / q̄ ∝ C_L; both smoothed over :data:`SMOOTH_S`), has fallen below its maximum of
  the preceding :data:`G_BREAK_WINDOW_S` in the search window by :data:`G_BREAK_DN` at the
  current q̄, while alpha is no lower than where that maximum was: a sudden loss of lift at
  constant or rising alpha (a pushover, the pilot's or the pusher's, loses alpha first; the
  decay of n with q̄ in a decelerating turn, at constant C_L, is no break: an accelerated entry
  loses 0.1 g in under half a second that way). Without q̄, n itself;
- **aft stop**: the end of the first :data:`AFT_STOP_HOLD_S` hold of the elevator within
  :data:`AFT_STOP_TOL_DEG` of its aft (most nose-up) stop in which the smoothed pitch attitude
  rose less than :data:`AFT_STOP_PITCH_DEG`; the stop is the one given, else the most nose-up
  deflection recorded in the maneuver;
- **buffet** (a deterrent buffet): the first sample where the buffet RMS of the raw normal
  accelerometer (:func:`aerodelta.buffet.buffet_rms`: band-passed 4-20 Hz, RMS over the trailing
  0.4 s) reaches :data:`DETERRENT_BUFFET_RMS_G`; not assessed without the raw ``az_mps2``
  channel or below 16 samples per second. The buffet **onset** (where the buffet first clears
  the maneuver's noise floor, :func:`aerodelta.buffet.detect_onset`) is reported beside it, with
  its alpha and speed (Part 60 compares buffet-onset speeds within ±3 kt), but is not a
  stall-identification criterion: light buffet is a warning, not a stall.

Pitch break, g-break and aft stop are searched in the run of samples within
:data:`SEARCH_BELOW_PEAK_DEG` of the maneuver's peak alpha that holds the peak: a stall is
identified around the highest alpha a maneuver reaches (the recovery takes alpha out of the run),
and the same signals earlier in the approach (a gust, a turn entry) are not a stall.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta._groups import Agg, group_agg
from aerodelta.buffet import BAND_HZ, buffet_rms, detect_onset
from aerodelta.exceptions import DataError

FloatArray = npt.NDArray[np.float64]

#: Standard gravity, m/s^2.
G0 = 9.80665
#: ISA sea-level density, kg/m^3 (equivalent airspeed EAS = TAS sqrt(rho / RHO0)).
RHO0 = 1.225
#: Metres per second in one knot.
KT = 1852.0 / 3600.0

#: Centred moving-average window of the pitch attitude and the load factor, s.
SMOOTH_S = 0.3
#: Nose-down pitch-attitude rate of a pitch break, deg/s (reached from a nose not going down:
#: the rate was >= 0 within the preceding :data:`PITCH_BREAK_WINDOW_S`).
PITCH_BREAK_RATE_DPS = 3.0
#: The pitch break is a sudden change: from a nose not going down this long ago at most, s.
PITCH_BREAK_WINDOW_S = 1.0
#: Load factor loss from its maximum of the preceding :data:`G_BREAK_WINDOW_S` that makes a
#: g-break, g.
G_BREAK_DN = 0.1
#: The g-break is a sudden loss: the maximum it is measured from is at most this old, s.
G_BREAK_WINDOW_S = 2.0
#: Look-back window of the "uncommanded" test, s.
COMMAND_WINDOW_S = 1.0
#: Elevator movement nose down (deg) within the look-back window that makes a motion commanded.
COMMAND_TOL_DEG = 0.5
#: Elevator within this much (deg) of the aft stop counts as at the stop.
AFT_STOP_TOL_DEG = 0.5
#: Hold time at the aft stop, s (Attachment 7: 2 s).
AFT_STOP_HOLD_S = 2.0
#: Pitch-attitude rise (deg) over the hold below which the pitch "does not increase further".
AFT_STOP_PITCH_DEG = 0.5
#: Window before stall identification over which the entry's deceleration is measured, s.
ENTRY_DECEL_WINDOW_S = 3.0
#: Fastest entry deceleration of the stall-speed test conditions, kt/s: 14 CFR 25.201(c) flies
#: stalls at up to 1 kt/s, turning-flight stalls at up to 3 kt/s (accelerated entries are
#: faster; there a tenth of a second is a knot).
MAX_TEST_DECEL_KT_S = 3.0
#: Search window: the run of samples within this many deg of the maneuver's peak alpha.
SEARCH_BELOW_PEAK_DEG = 3.0
#: Attachment 7's validity requirement: valid to this many deg beyond stall identification.
VALIDITY_MARGIN_DEG = 10.0
#: Maneuvers that must reach an alpha for the records to cover it.
MIN_MANEUVERS_COVERING = 2

#: Buffet RMS (normal axis, g) of a deterrent buffet: about ±0.2 g peaks, buffet a pilot does
#: not fly deeper into (no regulatory number exists that we know of; docs/stall.md).
DETERRENT_BUFFET_RMS_G = 0.06

#: The criteria in the order ties are broken (a tie: the same sample); Attachment 7's order.
CRITERIA: tuple[str, ...] = ("pusher", "pitch_break", "g_break", "buffet", "aft_stop")

_REQUIRED = ("maneuver_id", "t", "theta_deg", "de_deg", "tas_mps", "rho_kgm3")


def _centred_mean(x: FloatArray, w: int) -> FloatArray:
    """Centred moving average over ``w`` samples (odd), the window shrinking at the ends."""
    if w <= 1 or x.size < 2:
        return x.astype(np.float64, copy=True)
    h = w // 2
    c = np.concatenate(([0.0], np.cumsum(x)))
    k = np.arange(x.size)
    lo = np.maximum(k - h, 0)
    hi = np.minimum(k + h + 1, x.size)
    return (c[hi] - c[lo]) / (hi - lo)


def _window_max(x: FloatArray, w: int) -> FloatArray:
    """Maximum of ``x`` over the ``w`` samples ending at each sample (fewer at the start)."""
    if w <= 1:
        return x.copy()
    pad = np.concatenate((np.full(w - 1, -np.inf), x))
    return np.lib.stride_tricks.sliding_window_view(pad, w).max(axis=1)


def _first(mask: npt.NDArray[np.bool_]) -> int | None:
    """Index of the first True, or None."""
    i = int(np.argmax(mask)) if mask.size else 0
    return i if mask.size and bool(mask[i]) else None


def detect_criteria(
    t: npt.ArrayLike,
    alpha_deg: npt.ArrayLike,
    theta_deg: npt.ArrayLike,
    de_deg: npt.ArrayLike,
    *,
    nz: npt.ArrayLike | None = None,
    qbar: npt.ArrayLike | None = None,
    pusher: npt.ArrayLike | None = None,
    aft_stop_deg: float | None = None,
    buffet_rms_mps2: npt.ArrayLike | None = None,
) -> dict[str, int | None]:
    """Sample index at which each stall-identification criterion is met in one maneuver.

    The definitions are the module's (``docs/stall.md``); the function is the same on recorded
    and on truth signals.

    Parameters
    ----------
    t
        Time, s (increasing, uniform).
    alpha_deg
        Angle of attack, deg (sets the search window).
    theta_deg
        Pitch attitude, deg.
    de_deg
        Elevator, deg (positive nose down, Etkin).
    nz
        Normal load factor, g (``-a_z / g`` at the CG); None: g-break not assessed.
    qbar
        Dynamic pressure (any unit; positive): the g-break reads the loss of ``nz / qbar``
        at the current ``qbar``. None: the loss of ``nz`` itself.
    pusher
        Pusher activation discrete (1 pushing); None: pusher not assessed.
    aft_stop_deg
        The elevator's aft (nose-up) stop, deg; None: the most nose-up deflection recorded.
    buffet_rms_mps2
        Buffet RMS of the normal acceleration, m/s² (:func:`aerodelta.buffet.buffet_rms`);
        None: buffet not assessed.

    Returns
    -------
    dict
        ``pusher``, ``pitch_break``, ``g_break``, ``buffet``, ``aft_stop`` -> sample index or
        None (not met or not assessed), and ``peak`` (index of the peak alpha).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(0.0, 10.0, 0.02)
    >>> alpha = np.minimum(5.0 + 2.0 * t, 18.0)
    >>> push = (t >= 6.0).astype(float)
    >>> detect_criteria(t, alpha, alpha, np.zeros_like(t), pusher=push)["pusher"]
    300
    """
    tt = np.asarray(t, dtype=np.float64)
    a = np.asarray(alpha_deg, dtype=np.float64)
    th = np.asarray(theta_deg, dtype=np.float64)
    de = np.asarray(de_deg, dtype=np.float64)
    n = tt.size
    dt = float(np.median(np.diff(tt))) if n > 1 else 1.0
    w_s = max(1, round(SMOOTH_S / dt) | 1)
    w_c = max(1, round(COMMAND_WINDOW_S / dt) + 1)
    peak = int(np.argmax(a))
    # the window: the run of samples within SEARCH_BELOW_PEAK_DEG of the peak that holds the peak
    near = a >= a[peak] - SEARCH_BELOW_PEAK_DEG
    idx = np.arange(n)
    k0 = int(np.max(np.where(~near[: peak + 1], idx[: peak + 1], -1))) + 1
    after = np.flatnonzero(~near[peak:])
    k1 = peak + int(after[0]) if after.size else n
    win = np.zeros(n, dtype=bool)
    win[k0:k1] = True
    # uncommanded: the elevator within COMMAND_TOL_DEG of its most nose-up position of the
    # preceding window (min de over the window; positive de is nose down)
    de_s = _centred_mean(de, w_s)
    de_min = -_window_max(-de_s, w_c)
    uncommanded = de_s - de_min <= COMMAND_TOL_DEG
    out: dict[str, int | None] = {"peak": peak}
    out["pusher"] = None if pusher is None else _first(np.asarray(pusher, dtype=np.float64) > 0.5)
    th_s = _centred_mean(th, w_s)
    thdot = np.gradient(th_s, tt) if n > 1 else np.zeros(n)
    # a sudden nose-down change of the pitch rate (a steady descending turn is none), counted at
    # the onset of each episode: a push's episode stays commanded however long it lasts
    w_p = max(1, round(PITCH_BREAK_WINDOW_S / dt) + 1)
    down = (_window_max(thdot, w_p) >= 0.0) & (thdot <= -PITCH_BREAK_RATE_DPS)
    onset = down & ~np.concatenate(([False], down[:-1]))
    out["pitch_break"] = _first(win & uncommanded & onset)
    if nz is None:
        out["g_break"] = None
    else:
        ns = _centred_mean(np.asarray(nz, dtype=np.float64), w_s)
        # the load factor at the current dynamic pressure of each earlier sample's lift
        # coefficient: n_j q̄_k / q̄_j
        qs = np.ones(n) if qbar is None else _centred_mean(np.asarray(qbar, dtype=np.float64), w_s)
        cs = ns / qs
        run = np.where(win, cs, -np.inf)
        # the maximum of the preceding G_BREAK_WINDOW_S (inside the search window) and where it
        # was: lift lost at no lower alpha is a stall, a pushover (the pilot's or the pusher's)
        # loses alpha first
        w_g = max(1, round(G_BREAK_WINDOW_S / dt) + 1)
        pad = np.lib.stride_tricks.sliding_window_view(
            np.concatenate((np.full(w_g - 1, -np.inf), run)), w_g
        )
        at_max = np.maximum(idx - (w_g - 1) + np.argmax(pad, axis=1), 0)
        lost = ((run[at_max] - cs) * qs >= G_BREAK_DN) & (a >= a[at_max])
        out["g_break"] = _first(win & lost)
    if buffet_rms_mps2 is None:
        out["buffet"] = None
    else:
        deterrent = np.asarray(buffet_rms_mps2, dtype=np.float64) >= DETERRENT_BUFFET_RMS_G * G0
        out["buffet"] = _first(win & deterrent)
    stop = float(np.min(de)) if aft_stop_deg is None else float(aft_stop_deg)
    held = de <= stop + AFT_STOP_TOL_DEG
    # start of the current hold at each sample: one past the last sample not held
    start = np.maximum.accumulate(np.where(held, -1, idx)) + 1
    start = np.minimum(start, n - 1)
    long_enough = held & (tt - tt[start] >= AFT_STOP_HOLD_S - 1e-9)
    flat = th_s - th_s[start] < AFT_STOP_PITCH_DEG
    out["aft_stop"] = _first(win & long_enough & flat)
    return out


def _entry_decel(t: FloatArray, eas_kt: FloatArray, t_end: float) -> float | None:
    """Mean deceleration (kt/s) of the equivalent airspeed over the
    :data:`ENTRY_DECEL_WINDOW_S` up to ``t_end``; None when the record starts later."""
    t0 = t_end - ENTRY_DECEL_WINDOW_S
    if t.size < 2 or t0 < float(t[0]) - 1e-9:
        return None
    return float(np.interp(t0, t, eas_kt) - np.interp(t_end, t, eas_kt)) / ENTRY_DECEL_WINDOW_S


def _eas_kt(tas: FloatArray, rho: FloatArray) -> FloatArray:
    return tas * np.sqrt(rho / RHO0) / KT


def _check(data: pl.DataFrame) -> None:
    """Refuse data the identification cannot read, in one line."""
    missing = [c for c in _REQUIRED if c not in data.columns]
    if "alpha_cg_deg" not in data.columns and "alpha_deg" not in data.columns:
        missing.append("alpha_deg")
    if missing:
        raise DataError(
            f"stall identification: no {', '.join(missing)} column(s); give ingested records "
            "(aerodelta.ingest) with the canonical channels (docs/data.md)"
        )
    if "flap_deg" not in data.columns:
        raise DataError(
            "stall identification: no flap_deg column; record the flap setting or give a manifest "
            "with flap_deg per maneuver"
        )
    cols = [
        c
        for c in (
            *_REQUIRED[1:],
            *("alpha_cg_deg", "alpha_deg", "az_cg_mps2", "az_mps2", "tas_s_mps", "flap_deg"),
            *("pusher_active", "stall_warning"),
        )
        if c in data.columns
    ]
    bad = data.select(pl.col(cols).cast(pl.Float64).is_nan().or_(pl.col(cols).is_null()).any())
    for c in cols:
        if bad[c][0]:
            rows = (
                data.with_row_index("__row")
                .filter(pl.col(c).cast(pl.Float64).is_nan() | pl.col(c).is_null())
                .select("__row", "maneuver_id")
            )
            mid, row = rows["maneuver_id"][0], int(rows["__row"][0])
            what = "no flap setting" if c == "flap_deg" else "NaN/missing values"
            raise DataError(
                f"stall identification: maneuver {mid}: {c} has {what} ({rows.height} row(s), "
                f"the first at row {row}); fix the record or ingest with allow_interpolation"
            )


def stall_identification(
    data: pl.DataFrame | Any,
    *,
    aft_stop_deg: float | None = None,
) -> pl.DataFrame:
    """Stall-identification alpha per maneuver, by each Attachment 7 criterion.

    Parameters
    ----------
    data
        Ingested records (:func:`aerodelta.ingest` result or its ``data`` frame): ``maneuver_id``,
        ``t``, ``alpha_cg_deg`` (or ``alpha_deg``), ``theta_deg``, ``de_deg``, ``az_cg_mps2`` (or
        ``az_mps2``), ``tas_mps`` (``tas_s_mps`` used when present), ``rho_kgm3``, ``flap_deg``;
        ``kind`` (from the manifest), ``pusher`` (the manifest's pusher armed flag), the
        optional discretes ``pusher_active`` and ``stall_warning`` and the raw normal
        accelerometer ``az_mps2`` (buffet) when present.
    aft_stop_deg
        The elevator's aft (nose-up) stop, deg (negative, Etkin); None: the most nose-up
        deflection recorded in each maneuver is taken as the stop.

    Returns
    -------
    polars.DataFrame
        One row per maneuver: ``maneuver_id``, ``flap_deg``, ``kind``, ``pusher_armed``; per
        criterion ``<c>_t_s`` and ``<c>_alpha_deg`` (null: not met or not assessed) for
        ``warning``, ``pusher``, ``pitch_break``, ``g_break``, ``buffet``, ``aft_stop``;
        ``buffet_onset_t_s``, ``buffet_onset_alpha_deg``, ``v_buffet_onset_keas`` (the buffet
        onset, its alpha and EAS; null: no buffet or not assessed); ``stall_id_by``
        (the first criterion met, null when none), ``stall_id_t_s``, ``stall_id_alpha_deg``,
        ``v_warning_keas`` (equivalent airspeed at the warning onset, kt), ``v_stall_keas`` (at
        stall identification, kt), ``v_min_keas`` (minimum from the start to the identification,
        or to the peak alpha when none, kt), ``v_stall_ktas`` (true airspeed at identification),
        ``entry_decel_kt_s`` (the entry's mean EAS deceleration over the
        :data:`ENTRY_DECEL_WINDOW_S` before the identification, or the peak alpha when none;
        null when the record starts later), ``alpha_peak_deg`` and ``not_assessed`` (the
        criteria the record could not assess, and why). Alphas are at the CG
        (``alpha_cg_deg``) when the data have it.

    Raises
    ------
    DataError
        A missing channel or flap setting, or NaN samples: one line naming the maneuver, the
        channel and the first row.

    Examples
    --------
    >>> # table = aerodelta.stall_identification(aerodelta.ingest("campaign/").data)
    >>> # table.select("maneuver_id", "stall_id_by", "stall_id_alpha_deg", "v_stall_keas")
    """
    df: pl.DataFrame = getattr(data, "data", data)
    if not isinstance(df, pl.DataFrame):
        raise DataError(
            f"stall identification: give a polars DataFrame of ingested records, not "
            f"{type(df).__name__}"
        )
    _check(df)
    acol = "alpha_cg_deg" if "alpha_cg_deg" in df.columns else "alpha_deg"
    zcol = next((c for c in ("az_cg_mps2", "az_mps2") if c in df.columns), None)
    vcol = "tas_s_mps" if "tas_s_mps" in df.columns else "tas_mps"
    has_push = "pusher_active" in df.columns
    has_warn = "stall_warning" in df.columns
    has_raw_az = "az_mps2" in df.columns
    skipped = []
    if not has_raw_az:
        skipped.append("buffet: not assessed (no raw az_mps2 channel)")
    if not has_push:
        skipped.append("pusher: no pusher_active channel")
    if not has_warn:
        skipped.append("stall warning: no stall_warning channel")
    if zcol is None:
        skipped.append("g-break: no az_mps2 channel")
    note = "; ".join(skipped)
    rows = []
    for (mid,), g in df.partition_by("maneuver_id", as_dict=True, maintain_order=True).items():
        rows.append(
            _one(
                str(mid),
                g,
                acol=acol,
                zcol=zcol,
                vcol=vcol,
                has_push=has_push,
                has_warn=has_warn,
                has_raw_az=has_raw_az,
                aft_stop_deg=aft_stop_deg,
                note=note,
            )
        )
    return pl.DataFrame(rows, schema=_SCHEMA, orient="row")


_CRIT_COLUMNS = ("warning", *CRITERIA)
_SCHEMA: dict[str, Any] = {
    "maneuver_id": pl.Utf8,
    "flap_deg": pl.Float64,
    "kind": pl.Utf8,
    "pusher_armed": pl.Boolean,
    **{f"{c}_{s}": pl.Float64 for c in _CRIT_COLUMNS for s in ("t_s", "alpha_deg")},
    "buffet_onset_t_s": pl.Float64,
    "buffet_onset_alpha_deg": pl.Float64,
    "v_buffet_onset_keas": pl.Float64,
    "stall_id_by": pl.Utf8,
    "stall_id_t_s": pl.Float64,
    "stall_id_alpha_deg": pl.Float64,
    "v_warning_keas": pl.Float64,
    "v_stall_keas": pl.Float64,
    "v_min_keas": pl.Float64,
    "v_stall_ktas": pl.Float64,
    "entry_decel_kt_s": pl.Float64,
    "alpha_peak_deg": pl.Float64,
    "not_assessed": pl.Utf8,
}


def _one(
    mid: str,
    g: pl.DataFrame,
    *,
    acol: str,
    zcol: str | None,
    vcol: str,
    has_push: bool,
    has_warn: bool,
    has_raw_az: bool,
    aft_stop_deg: float | None,
    note: str,
) -> list[Any]:
    col = lambda c: g[c].cast(pl.Float64).to_numpy()  # noqa: E731
    t, a = col("t"), col(acol)
    nz = None if zcol is None else -col(zcol) / G0
    rms, k_on = None, None
    fast = t.size > 1 and 0.5 / float(np.median(np.diff(t))) >= 2.0 * BAND_HZ[0]
    if has_raw_az and fast and t.size >= 8:
        onset = detect_onset(t, a, col("az_mps2"))
        rms, k_on = onset["rms_mps2"], onset["onset"]
    elif has_raw_az:
        note = "; ".join([n for n in (note, "buffet: not assessed (sampled below 16 Hz)") if n])
    found = detect_criteria(
        t,
        a,
        col("theta_deg"),
        col("de_deg"),
        nz=nz,
        qbar=0.5 * col("rho_kgm3") * col(vcol) ** 2,
        pusher=col("pusher_active") if has_push else None,
        aft_stop_deg=aft_stop_deg,
        buffet_rms_mps2=rms,
    )
    eas = _eas_kt(col(vcol), col("rho_kgm3"))
    k_warn = _first(col("stall_warning") > 0.5) if has_warn else None
    at = {"warning": k_warn, **{c: found[c] for c in CRITERIA}}
    met = [(at[c], i, c) for i, c in enumerate(CRITERIA) if at[c] is not None]
    k_id, _, by = min(met) if met else (None, 0, None)
    k_end = found["peak"] if k_id is None else k_id
    kind = str(g["kind"][0]) if "kind" in g.columns and g["kind"][0] is not None else "other"
    armed = bool(g["pusher"][0]) if "pusher" in g.columns and g["pusher"][0] is not None else None
    val = lambda x, k: None if k is None else float(x[k])  # noqa: E731
    row: list[Any] = [mid, float(g["flap_deg"][0]), kind, armed]
    for c in _CRIT_COLUMNS:
        row += [val(t, at[c]), val(a, at[c])]
    row += [val(t, k_on), val(a, k_on), val(eas, k_on)]
    row += [
        by,
        val(t, k_id),
        val(a, k_id),
        val(eas, k_warn),
        val(eas, k_id),
        float(np.min(eas[: k_end + 1])),
        None if k_id is None else float(col(vcol)[k_id] / KT),
        _entry_decel(t, eas, float(t[k_end])),
        float(a[found["peak"]]),
        note,
    ]
    return row


def stall_summary(table: pl.DataFrame) -> pl.DataFrame:
    """Per flap and maneuver kind: the stall identification of :func:`stall_identification`.

    Parameters
    ----------
    table
        The per-maneuver table.

    Returns
    -------
    polars.DataFrame
        ``flap_deg``, ``kind``, ``n_maneuvers``, ``n_identified``, ``by_pusher``,
        ``by_pitch_break``, ``by_g_break``, ``by_buffet``, ``by_aft_stop`` (counts),
        ``stall_id_alpha_mean_deg``,
        ``stall_id_alpha_min_deg``, ``stall_id_alpha_max_deg``, ``v_warning_mean_keas``,
        ``v_stall_mean_keas``, ``v_min_mean_keas`` (kt), ``warning_margin_mean_kt`` (warning
        minus stall speed, kt).
    """
    by = pl.col("stall_id_by")
    # the means summed in row order (_groups: a polars group-by mean splits its sums over the
    # thread pool)
    means: dict[str, tuple[str, Agg]] = {
        "stall_id_alpha_mean_deg": ("stall_id_alpha_deg", "mean"),
        "v_warning_mean_keas": ("v_warning_keas", "mean"),
        "v_stall_mean_keas": ("v_stall_keas", "mean"),
        "v_min_mean_keas": ("v_min_keas", "mean"),
        "warning_margin_mean_kt": ("_margin", "mean"),
    }
    return (
        group_agg(
            table.with_columns(
                (pl.col("v_warning_keas") - pl.col("v_stall_keas")).alias("_margin")
            ),
            ["flap_deg", "kind"],
            means,
            exact=[
                pl.len().alias("n_maneuvers"),
                by.is_not_null().sum().alias("n_identified"),
                *[(by == c).sum().alias(f"by_{c}") for c in CRITERIA],
                pl.col("stall_id_alpha_deg").min().alias("stall_id_alpha_min_deg"),
                pl.col("stall_id_alpha_deg").max().alias("stall_id_alpha_max_deg"),
            ],
        )
        .select(
            "flap_deg",
            "kind",
            "n_maneuvers",
            "n_identified",
            *[f"by_{c}" for c in CRITERIA],
            "stall_id_alpha_mean_deg",
            "stall_id_alpha_min_deg",
            "stall_id_alpha_max_deg",
            "v_warning_mean_keas",
            "v_stall_mean_keas",
            "v_min_mean_keas",
            "warning_margin_mean_kt",
        )
        .sort("flap_deg", "kind")
    )


def validity_range(
    data: pl.DataFrame | Any,
    table: pl.DataFrame,
    *,
    band_deg: float = 2.0,
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """The alpha the records cover per flap, against stall identification + 10 deg.

    Parameters
    ----------
    data
        The records the table was computed from (ingested; see :func:`stall_identification`).
    table
        :func:`stall_identification`'s per-maneuver table.
    band_deg
        Width of the alpha bands of the coverage table, deg.

    Returns
    -------
    (coverage, verdict) : (polars.DataFrame, polars.DataFrame)
        ``coverage``: per flap and alpha band (``alpha_lo_deg``, ``alpha_hi_deg``), the
        ``n_maneuvers`` and ``n_samples`` in it. ``verdict``: per flap ``alpha_reached_deg``
        (the highest alpha recorded), ``stall_id_alpha_deg`` (the highest stall-identification
        alpha of the flap's maneuvers: the most demanding), ``required_deg`` (that + 10),
        ``n_maneuvers_beyond`` and ``n_samples_beyond`` (at or above it), ``covered`` (at least
        :data:`MIN_MANEUVERS_COVERING` maneuvers reach it) and ``verdict`` (one line).

    Raises
    ------
    DataError
        For ``band_deg`` not positive, or data without the table's columns.
    """
    if not (math.isfinite(band_deg) and band_deg > 0):
        raise DataError(f"band_deg {band_deg}: give a positive band width in deg, e.g. 2")
    df: pl.DataFrame = getattr(data, "data", data)
    _check(df)
    acol = "alpha_cg_deg" if "alpha_cg_deg" in df.columns else "alpha_deg"
    s = df.select("maneuver_id", pl.col("flap_deg").cast(pl.Float64), pl.col(acol).alias("a"))
    band = (pl.col("a") / band_deg).floor() * band_deg
    coverage = (
        s.with_columns(band.alias("alpha_lo_deg"))
        .group_by("flap_deg", "alpha_lo_deg")
        .agg(
            pl.col("maneuver_id").n_unique().alias("n_maneuvers"),
            pl.len().alias("n_samples"),
        )
        .with_columns((pl.col("alpha_lo_deg") + band_deg).alias("alpha_hi_deg"))
        .select("flap_deg", "alpha_lo_deg", "alpha_hi_deg", "n_maneuvers", "n_samples")
        .sort("flap_deg", "alpha_lo_deg")
    )
    need = table.group_by("flap_deg").agg(
        pl.col("stall_id_alpha_deg").max().alias("stall_id_alpha_deg"),
        pl.len().alias("n_maneuvers"),
    )
    reached = s.group_by("flap_deg").agg(pl.col("a").max().alias("alpha_reached_deg"))
    v = reached.join(need, on="flap_deg", how="left").sort("flap_deg")
    rows = []
    for r in v.iter_rows(named=True):
        sid = r["stall_id_alpha_deg"]
        flap = r["flap_deg"]
        if sid is None:
            rows.append((flap, r["alpha_reached_deg"], None, None, 0, 0, False,
                         f"flap {flap:g}: no stall identified in {r['n_maneuvers'] or 0} "
                         "maneuver(s); the validity range cannot be set"))  # fmt: skip
            continue
        req = sid + VALIDITY_MARGIN_DEG
        beyond = s.filter((pl.col("flap_deg") == flap) & (pl.col("a") >= req))
        nm, ns = beyond["maneuver_id"].n_unique(), beyond.height
        ok = nm >= MIN_MANEUVERS_COVERING
        head = (
            f"flap {flap:g}: data to {r['alpha_reached_deg']:.1f} deg, 10 deg beyond stall "
            f"identification at {sid:.1f} deg needs {req:.1f}: "
        )
        if ok:
            tail = f"covered by {nm} maneuvers ({ns} samples)"
        else:
            short = req - r["alpha_reached_deg"]
            tail = (
                f"not covered: {nm} maneuver(s) reach it"
                + (f", the data stop {short:.1f} deg short" if short > 0 else "")
                + "; cover it with other data (wind tunnel, analysis) and declare it"
            )
        rows.append((flap, r["alpha_reached_deg"], sid, req, nm, ns, ok, head + tail))
    verdict = pl.DataFrame(
        rows,
        schema={
            "flap_deg": pl.Float64,
            "alpha_reached_deg": pl.Float64,
            "stall_id_alpha_deg": pl.Float64,
            "required_deg": pl.Float64,
            "n_maneuvers_beyond": pl.Int64,
            "n_samples_beyond": pl.Int64,
            "covered": pl.Boolean,
            "verdict": pl.Utf8,
        },
        orient="row",
    )
    return coverage, verdict


def virtual_truth(campaign: str | Path, table: pl.DataFrame) -> pl.DataFrame:
    """The truth's stall identification beside ``table``, for a virtual flight-test campaign.

    The truth of each criterion is :func:`detect_criteria` on the simulator's noise-free signals
    (``truth/<id>.parquet``: true alpha at the CG, pitch attitude, acting elevator, load factor,
    and, in a campaign with buffet, the buffet acceleration the accelerometers felt)
    and, for the pusher, the time the simulator's own pusher fired (the campaign's pusher
    maneuvers flown again from ``truth/campaign.json``: same seed, same flight). Speeds: the true
    airspeed as EAS with the recorded density; the warning onset is the recorded discrete's.

    Parameters
    ----------
    campaign
        A folder written by :func:`aerodelta.generate_campaign`.
    table
        :func:`stall_identification` of its records.

    Returns
    -------
    polars.DataFrame
        ``table`` with ``truth_by``, ``truth_t_s``, ``truth_alpha_deg``, ``truth_v_stall_keas``,
        ``truth_v_warning_keas`` and ``truth_<criterion>_t_s`` per criterion.

    Raises
    ------
    DataError
        When ``campaign`` has no ``truth/campaign.json`` (not a virtual campaign).
    """
    from aerodelta import _core  # noqa: PLC0415  (the engine only for virtual campaigns)
    from aerodelta.campaign import maneuver_index  # noqa: PLC0415

    folder = Path(campaign)
    info_path = folder / "truth" / "campaign.json"
    if not info_path.is_file():
        raise DataError(f"{folder}: no truth/campaign.json; give a virtual campaign's folder")
    spec = json.loads(info_path.read_text())["spec"]
    man = pl.read_csv(folder / "manifest.csv")
    fired_ids = man.filter(pl.col("pusher_fired"))["maneuver_id"].to_list()
    # the index has three digits or more: m1000_... is maneuver 1000 (until session 31 the first
    # three digits were read, and a campaign of 1000 maneuvers or more flew the wrong ones)
    spec["only"] = [maneuver_index(m) for m in fired_ids]
    fired: dict[str, float] = {}
    if spec["only"]:
        for m in _core.sim_run_campaign(json.dumps(spec)):
            fired[m["id"]] = float(json.loads(m["meta"])["pusher_fired_at_s"])
    rows = []
    for mid in table["maneuver_id"]:
        tr = pl.read_parquet(folder / "truth" / f"{mid}.parquet")
        rec = pl.read_parquet(folder / "records" / f"{mid}.parquet", columns=["rho_kgm3"])
        t = tr["t"].to_numpy()
        alpha = tr["alpha_true_deg"].to_numpy()
        got = detect_criteria(
            t,
            alpha,
            tr["theta_true_deg"].to_numpy(),
            tr["de_true_deg"].to_numpy(),
            nz=tr["nz_true"].to_numpy(),
            qbar=0.5 * rec["rho_kgm3"].to_numpy() * tr["tas_true_mps"].to_numpy() ** 2,
            # the buffet the accelerometers felt, without the sensor noise and rigid-body motion
            buffet_rms_mps2=buffet_rms(t, tr["buffet_az_true_mps2"].to_numpy())
            if "buffet_az_true_mps2" in tr.columns
            else None,
        )
        times: dict[str, float | None] = {
            c: None if got[c] is None else float(t[got[c]]) for c in CRITERIA[1:]
        }
        times["pusher"] = fired.get(mid)
        met = sorted((v, CRITERIA.index(c), c) for c, v in times.items() if v is not None)
        t_id, by = (met[0][0], met[0][2]) if met else (None, None)
        eas = _eas_kt(tr["tas_true_mps"].to_numpy(), rec["rho_kgm3"].to_numpy())
        t_w = table.filter(pl.col("maneuver_id") == mid)["warning_t_s"][0]
        rows.append(
            {
                "maneuver_id": mid,
                "truth_by": by,
                "truth_t_s": t_id,
                "truth_alpha_deg": None if t_id is None else float(np.interp(t_id, t, alpha)),
                "truth_v_stall_keas": None if t_id is None else float(np.interp(t_id, t, eas)),
                "truth_v_warning_keas": None if t_w is None else float(np.interp(t_w, t, eas)),
                **{f"truth_{c}_t_s": times[c] for c in CRITERIA},
            }
        )
    schema = {
        "maneuver_id": pl.Utf8,
        "truth_by": pl.Utf8,
        **{c: pl.Float64 for c in ("truth_t_s", "truth_alpha_deg", "truth_v_stall_keas")},
        "truth_v_warning_keas": pl.Float64,
        **{f"truth_{c}_t_s": pl.Float64 for c in CRITERIA},
    }
    return table.join(pl.DataFrame(rows, schema=schema), on="maneuver_id", how="left")
