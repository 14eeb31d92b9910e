"""The simulator's output in the measured coefficients' band.

The measured coefficients are computed from smoothed signals: ``aerodelta ingest`` smooths each
channel per maneuver (zero-phase optimal Fourier smoothing, SIDPAC ``smoo``) before it
differentiates the rates, so C_l carries the band of the roll rate (its cut-off typically
2-5 Hz), C_n that of the yaw rate and C_Y that of the lateral accelerometer. A simulator's
output has no such limit: it follows the recorded controls at their full band. The gap
``C_meas - C_sim`` then holds the part of every fast input the smoothing removed from the
measurement only, and it reads as an effect: on JSBSim null campaigns (nothing withheld) it
was half to two thirds of the gap's RMS and came out as "rudder effectiveness" (F-15, C_n) or
"aileron effectiveness" with a roll-off (DHC-6, C_l).

So, before the gap is formed, the simulator's output is passed per maneuver through a
zero-phase low-pass at the cut-off the smoother chose for that maneuver's channel (recomputed
here from the raw channel by the same deterministic smoother, ``_core.smooth``): the gap is then
the difference of two signals of the same band, the band-limited equation error of Morelli &
Klein (*Aircraft System Identification*, 2006, Section 5.5, applied to the simulator side). The
smoother's own response is a Wiener weight falling from 1 to 0 around its cut-off; here a
linear ramp from 0.75 to 1.25 times the cut-off stands in for it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import polars as pl

from aerodelta import _core

#: The raw channel whose smoothing sets each measured coefficient's band.
BAND_CHANNEL = {"Cl": "p_dps", "Cn": "r_dps", "CY": "ay_mps2"}

#: The low-pass's ramp, as fractions of the cut-off: weight 1 below, 0 above.
RAMP = (0.75, 1.25)


def lowpass(x: np.ndarray, dt: float, cutoff_hz: float) -> np.ndarray:
    """Zero-phase low-pass of one maneuver's samples: the straight line through the end points
    removed, the rest extended by its odd reflections about both ends (as SIDPAC ``smoo``: no
    jump or kink, and the end values kept), weights falling
    linearly from 1 at ``RAMP[0] * cutoff_hz`` to 0 at ``RAMP[1] * cutoff_hz``, line added
    back. Fewer than 8 samples or a non-positive cut-off: returned unchanged."""
    n = x.size
    if n < 8 or not (cutoff_hz > 0.0 and dt > 0.0):
        return x.astype(float, copy=True)
    line = x[0] + (x[-1] - x[0]) * np.arange(n) / (n - 1)
    d = x - line
    # [odd reflection about the first sample, the data, odd reflection about the last]: value
    # and slope continuous at both ends, and an odd function about each end sample keeps its
    # value there through a symmetric filter
    ext = np.concatenate([-d[:0:-1], d, -d[-2::-1]])
    p = 1 << int(np.ceil(np.log2(ext.size)))
    buf = np.zeros(p)
    buf[: ext.size] = ext
    f = np.fft.rfftfreq(p, dt)
    lo, hi = RAMP[0] * cutoff_hz, RAMP[1] * cutoff_hz
    w = np.clip((hi - f) / (hi - lo), 0.0, 1.0)
    return np.fft.irfft(np.fft.rfft(buf) * w, p)[n - 1 : 2 * n - 1] + line


def _runs(frame: pl.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First and past-the-last row of each maneuver (rows contiguous), and the time column."""
    ids = frame["maneuver_id"].to_numpy()
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    ends = np.r_[starts[1:], ids.size]
    return starts, ends, frame["t"].cast(pl.Float64).to_numpy()


def band_cutoffs(frame: pl.DataFrame) -> dict[str, np.ndarray]:
    """Per coefficient, the smoother's cut-off (Hz) per maneuver in order of appearance
    (``NaN`` where the channel is absent or the maneuver too short)."""
    starts, ends, t = _runs(frame)
    out: dict[str, np.ndarray] = {}
    for coef, ch in BAND_CHANNEL.items():
        fc = np.full(starts.size, np.nan)
        if ch in frame.columns:
            x = frame[ch].cast(pl.Float64).to_numpy()
            for k, (s, e) in enumerate(zip(starts, ends, strict=True)):
                if e - s >= 8:
                    dt = float(np.median(np.diff(t[s:e])))
                    fc[k] = float(_core.smooth(np.ascontiguousarray(x[s:e]), dt)[1])
        out[coef] = fc
    return out


def band_match(
    frame: pl.DataFrame, outputs: Mapping[str, np.ndarray], cutoffs: Mapping[str, np.ndarray]
) -> dict[str, np.ndarray]:
    """Each coefficient's ``outputs`` (one value per row of ``frame``, whose maneuvers are
    contiguous) low-passed per maneuver at ``cutoffs`` (:func:`band_cutoffs`); the
    coefficients of one maneuver are filtered together (:func:`_lowpass_rows`)."""
    starts, ends, t = _runs(frame)
    out: dict[str, np.ndarray] = {c: np.asarray(v, dtype=float).copy() for c, v in outputs.items()}
    for k, (s, e) in enumerate(zip(starts, ends, strict=True)):
        if e - s < 8:
            continue
        todo = [c for c in out if (fc := cutoffs.get(c)) is not None and np.isfinite(fc[k])]
        if not todo:
            continue
        dt = float(np.median(np.diff(t[s:e])))
        fcs = np.array([float(cutoffs[c][k]) for c in todo])
        if not dt > 0.0:
            continue
        ok = fcs > 0.0  # lowpass() leaves a non-positive cut-off's values as they are
        rows = [c for c, keep in zip(todo, ok, strict=True) if keep]
        if rows:
            filtered = _lowpass_rows(np.stack([out[c][s:e] for c in rows]), dt, fcs[ok])
            for c, f in zip(rows, filtered, strict=True):
                out[c][s:e] = f
    return out


def _lowpass_rows(x: np.ndarray, dt: float, cutoffs_hz: np.ndarray) -> np.ndarray:
    """:func:`lowpass` of each row of ``x`` (one maneuver's samples, at least 8) at its own
    cut-off (all positive, as ``dt``), the rows' transforms taken together: the same
    operations row by row, the same numbers as :func:`lowpass` of each row."""
    n = x.shape[1]
    line = x[:, :1] + (x[:, -1:] - x[:, :1]) * np.arange(n) / (n - 1)
    d = x - line
    ext = np.concatenate([-d[:, :0:-1], d, -d[:, -2::-1]], axis=1)
    p = 1 << int(np.ceil(np.log2(ext.shape[1])))
    buf = np.zeros((x.shape[0], p))
    buf[:, : ext.shape[1]] = ext
    f = np.fft.rfftfreq(p, dt)
    w = np.empty((x.shape[0], f.size))
    for i, fc in enumerate(cutoffs_hz):
        lo, hi = RAMP[0] * float(fc), RAMP[1] * float(fc)
        w[i] = np.clip((hi - f) / (hi - lo), 0.0, 1.0)
    spec = np.fft.rfft(buf, axis=1) * w
    return np.fft.irfft(spec, p, axis=1)[:, n - 1 : 2 * n - 1] + line
