"""Stall buffet from flight records: onset, predominant frequencies, amplitude against alpha.

Buffet is structural vibration: the accelerometers record it at a few to a few tens of Hz, the
band the ingestion's smoother removes from ``az_cg_mps2``/``ay_cg_mps2``. Everything here reads
the **raw** accelerometer channels of the records (``az_mps2``, ``ay_mps2``: after ingestion only
a constant bias is removed from them, which no band-pass sees). Definitions (constants below;
``docs/stall.md``, "Buffet"):

- **band-passed acceleration**: the channel with the straight line through its first and last
  samples removed (its periodic extension is then continuous), filtered by a zero-phase FFT mask
  that keeps :data:`BAND_HZ` (a brick wall: no phase shift; the record's first and last second
  carry its edge effects, which the onset search skips);
- **buffet RMS**: the RMS of the band-passed normal acceleration over the trailing
  :data:`RMS_WINDOW_S` (a trailing window: it rises after the buffet starts, not before);
- **approach**: the samples up to where alpha first falls :data:`APPROACH_DROP_DEG` below its
  highest value so far, that value within :data:`APPROACH_NEAR_PEAK_DEG` of the peak alpha (the
  first approach to the stall; a pusher's pitch-down, the recovery and a second stall after
  them are not searched);
- **noise floor** of a maneuver: the :data:`FLOOR_QUANTILE` quantile of the buffet mean square
  over the approach: its quietest part, which buffet, felt only in its last degrees, does not
  reach;
- **onset**: buffet is detected at the first sample of the approach (past the first
  :data:`EDGE_S`) where the buffet RMS reaches :data:`ONSET_FACTOR` times the floor, and its
  onset is the sample after the last one before it where the RMS was at most
  :data:`ONSET_START_FACTOR` times the floor (where the rise began); the alpha (at the CG) and
  equivalent airspeed there are the maneuver's buffet-onset alpha and speed. Per flap, the
  onset alpha is the median over the maneuvers with an onset;
- **buffet segment**: from the onset to the last sample of the run in which the buffet RMS stays
  at or above :data:`ONSET_FACTOR` times the floor (allowing gaps up to :data:`GAP_S`);
- **predominant frequencies**: the peaks of the Welch power spectral density (Hann window,
  :data:`NPERSEG` samples, 50 % overlap, each segment's mean and slope removed) of the
  high-passed (above :data:`HIGHPASS_HZ`) normal and lateral accelerations, averaged over every
  buffet segment of a flap setting that is at least one Welch segment long, each Welch
  segment's periodogram divided by its power in :data:`BAND_HZ` first (every segment's
  spectral shape counts the same: the few deep stalls' heavy buffet would otherwise outweigh
  the rest, leaving fewer effective averages; on development seeds 41-45 this lowered the
  frequency errors of every mode by 10-25 %): local maxima within
  :data:`BAND_HZ` at least :data:`PEAK_REL` of the largest and standing
  :data:`PEAK_PROMINENCE` times above the lower of the two minima beside them, the
  :data:`MAX_PEAKS` largest per axis, each refined to a fraction of a bin by a parabola through
  the logarithm of the three bins around it;
- **amplitude against alpha**: per flap and alpha band of :data:`AMPLITUDE_BAND_DEG`, the RMS of
  the band-passed normal and lateral accelerations over all samples in it.

:func:`compare_frequencies` compares a simulator's predominant frequencies with flight test's:
14 CFR Part 60 Appendix A, Table A1A test 3.f.5 (buffet at approach-to-stall), as we read it,
asks at least three of the predominant frequency "spikes" to be present within ±2 Hz.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta._groups import group_agg
from aerodelta.exceptions import DataError

FloatArray = npt.NDArray[np.float64]

#: Band of the buffet detector and of the spectral peaks, Hz.
BAND_HZ: tuple[float, float] = (4.0, 20.0)
#: High-pass of the spectra, Hz (rigid-body motion lies below it).
HIGHPASS_HZ = 3.0
#: Trailing window of the buffet RMS, s.
RMS_WINDOW_S = 0.4
#: Quantile of the approach's buffet mean square taken as its noise floor.
FLOOR_QUANTILE = 0.2
#: Buffet is detected where the buffet RMS reaches this many times the noise floor ...
ONSET_FACTOR = 3.0
#: ... and its onset dated at the last sample before where the RMS was at most this many times
#: the floor (the rise's start: the structure rings up and the window fills over ~0.2 s, in
#: which alpha near the stall can rise by half a degree).
ONSET_START_FACTOR = 1.5
#: The first and last this many seconds of a record are not searched (the band-pass's and
#: the window's edges).
EDGE_S = 1.0
#: The approach searched for the onset ends where alpha first falls this many deg below its
#: highest value so far, once that is within :data:`APPROACH_NEAR_PEAK_DEG` of the maneuver's
#: peak alpha: the first approach to the stall (what follows, a pusher's pitch-down or the
#: recovery and a second stall, shakes the accelerometers too, but is not the onset; the
#: pilot's doublets at low alpha, early in the approach, do not end it).
APPROACH_DROP_DEG = 4.0
APPROACH_NEAR_PEAK_DEG = 12.0
#: Gaps (s) the buffet RMS may spend below the onset level inside one buffet segment.
GAP_S = 0.5
#: Welch segment length, samples (at 50 Hz: 2.56 s, 0.39 Hz resolution).
NPERSEG = 128
#: FFT length of each Welch segment. Zero padding (NFFT > NPERSEG) gives a finer grid, not a
#: finer resolution: on development seeds 41-45, 512 changed no frequency error by more than
#: 0.04 Hz and doubled the spurious peaks, so none.
NFFT = 128
#: A spectral peak is at least this fraction of the axis's largest.
PEAK_REL = 0.05
#: A spectral peak stands this many times above the lower of the minima beside it.
PEAK_PROMINENCE = 2.0
#: Peaks kept per axis.
MAX_PEAKS = 3
#: Width of the alpha bands of the amplitude table, deg.
AMPLITUDE_BAND_DEG = 1.0
#: Part 60 Table A1A 3.f.5 (as we read it): frequency tolerance, Hz, and spikes to match.
FREQ_TOLERANCE_HZ = 2.0
MIN_SPIKES = 3

#: ISA sea-level density, kg/m^3, and m/s per knot (equivalent airspeed of the onset).
_RHO0 = 1.225
_KT = 1852.0 / 3600.0


def _uniform_dt(t: FloatArray, where: str) -> float:
    if t.size < 8:
        raise DataError(f"{where}: {t.size} samples; a buffet analysis needs at least 8")
    d = np.diff(t)
    dt = float(np.median(d))
    # the ingestion's tolerance (aerodelta.validate: steps within 1 % of each other)
    if not (dt > 0 and np.all(np.abs(d - dt) <= 0.01 * dt + 1e-9)):
        raise DataError(
            f"{where}: the time step is not uniform; resample the record to one rate "
            "(docs/data.md) before the buffet analysis"
        )
    return dt


def bandpass(x: npt.ArrayLike, dt: float, band: tuple[float, float] = BAND_HZ) -> FloatArray:
    """Zero-phase band-pass of one record: end-to-end line removed, FFT mask over ``band``.

    Parameters
    ----------
    x
        Samples (any unit), uniformly spaced.
    dt
        Sample period, s.
    band
        Pass band ``(lo, hi)``, Hz; ``hi`` is clipped to the Nyquist frequency.

    Returns
    -------
    numpy.ndarray
        The band-passed signal, same unit and length.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(0, 10, 0.02)
    >>> y = bandpass(3.0 + 0.5 * t + np.sin(2 * np.pi * 8.0 * t), 0.02)
    >>> err = np.abs(y - np.sin(2 * np.pi * 8.0 * t))
    >>> bool(err[50:-50].max() < 0.02)  # away from the record's first and last second
    True
    """
    v = np.asarray(x, dtype=np.float64)
    n = v.size
    if n < 2:
        return np.zeros_like(v)
    line = v[0] + (v[-1] - v[0]) * np.arange(n) / (n - 1)
    spec = np.fft.rfft(v - line)
    f = np.fft.rfftfreq(n, dt)
    spec[(f < band[0]) | (f > band[1])] = 0.0
    return np.fft.irfft(spec, n)


def trailing_mean_square(x: FloatArray, w: int) -> FloatArray:
    """Mean of ``x**2`` over the ``w`` samples ending at each sample (fewer at the start)."""
    c = np.concatenate(([0.0], np.cumsum(x * x)))
    k = np.arange(x.size)
    lo = np.maximum(k + 1 - w, 0)
    return (c[k + 1] - c[lo]) / (k + 1 - lo)


def buffet_rms(t: npt.ArrayLike, accel_mps2: npt.ArrayLike) -> FloatArray:
    """The buffet RMS of one record: band-passed (:data:`BAND_HZ`) acceleration's RMS over the
    trailing :data:`RMS_WINDOW_S`, m/s².

    Parameters
    ----------
    t
        Time, s (uniform).
    accel_mps2
        Raw accelerometer channel, m/s² (``az_mps2`` for the normal axis).
    """
    tt = np.asarray(t, dtype=np.float64)
    dt = _uniform_dt(tt, "buffet RMS")
    x = bandpass(accel_mps2, dt, _band(dt))
    w = max(2, round(RMS_WINDOW_S / dt))
    return np.sqrt(trailing_mean_square(x, w))


def _band(dt: float) -> tuple[float, float]:
    nyq = 0.5 / dt
    return (BAND_HZ[0], min(BAND_HZ[1], 0.95 * nyq))


def detect_onset(
    t: npt.ArrayLike, alpha_deg: npt.ArrayLike, az_mps2: npt.ArrayLike
) -> dict[str, Any]:
    """Buffet onset and segment of one maneuver (definitions: module docstring).

    Parameters
    ----------
    t
        Time, s (uniform).
    alpha_deg
        Angle of attack, deg (at the CG for ingested records).
    az_mps2
        Raw normal accelerometer, m/s².

    Returns
    -------
    dict
        ``onset`` (sample index or None), ``end`` (last sample of the buffet segment or None),
        ``floor_rms_mps2`` (the noise floor), ``rms_mps2`` (the buffet RMS per sample), ``peak``
        (index of the peak alpha).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> t = np.arange(0.0, 30.0, 0.02)
    >>> alpha = 6.0 + 0.5 * t
    >>> az = -9.8 + 0.03 * rng.standard_normal(t.size)
    >>> az += np.where(alpha >= 17.0, 0.3 * np.sin(2 * np.pi * 8.0 * t), 0.0)
    >>> got = detect_onset(t, alpha, az)
    >>> round(float(alpha[got["onset"]]), 1)
    17.0
    """
    tt = np.asarray(t, dtype=np.float64)
    a = np.asarray(alpha_deg, dtype=np.float64)
    dt = _uniform_dt(tt, "buffet onset")
    rms = buffet_rms(tt, az_mps2)
    ms = rms * rms
    peak = int(np.argmax(a))
    edge = min(max(round(EDGE_S / dt), round(RMS_WINDOW_S / dt)), tt.size // 4)
    top = np.maximum.accumulate(a)
    dropped = np.flatnonzero(
        (a < top - APPROACH_DROP_DEG) & (top >= a[peak] - APPROACH_NEAR_PEAK_DEG)
    )
    stop = int(dropped[0]) if dropped.size else tt.size
    approach = ms[edge : max(stop, edge + 1)]
    floor_ms = float(np.quantile(approach, FLOOR_QUANTILE)) if approach.size else 0.0
    thr = ONSET_FACTOR**2 * floor_ms
    above = approach >= thr
    onset = None
    if above.any() and floor_ms > 0:
        hit = edge + int(np.argmax(above))
        quiet = np.flatnonzero(ms[edge:hit] <= ONSET_START_FACTOR**2 * floor_ms)
        onset = edge + int(quiet[-1]) + 1 if quiet.size else hit
    end = None
    if onset is not None:
        on = ms >= thr
        gap = max(1, round(GAP_S / dt))
        # the segment: from the onset on, until the RMS has stayed below the level for `gap`
        quiet = ~on[onset:]
        run = np.convolve(quiet.astype(np.int64), np.ones(gap, dtype=np.int64), "full")[
            : quiet.size
        ]
        stop = np.flatnonzero(run >= gap)
        last = onset + (int(stop[0]) - gap if stop.size else quiet.size - 1)
        end = max(onset, last)
    return {
        "onset": onset,
        "end": end,
        "floor_rms_mps2": float(np.sqrt(floor_ms)),
        "rms_mps2": rms,
        "peak": peak,
    }


def welch_psd(
    x: npt.ArrayLike, dt: float, nperseg: int = NPERSEG, nfft: int | None = None
) -> tuple[FloatArray, FloatArray]:
    """One-sided Welch power spectral density (Hann, 50 % overlap, linear detrend per segment).

    Parameters
    ----------
    x
        Samples, unit u, at least ``nperseg`` of them.
    dt
        Sample period, s.
    nperseg
        Segment length, samples.
    nfft
        FFT length (zero padding, >= ``nperseg``); None: ``nperseg``.

    Returns
    -------
    (f, psd) : (numpy.ndarray, numpy.ndarray)
        Frequencies, Hz, and the density, u²/Hz (``scipy.signal.welch(x, 1/dt, nperseg=nperseg,
        nfft=nfft, detrend="linear")`` computes the same).

    Raises
    ------
    DataError
        Fewer samples than ``nperseg``.
    """
    v = np.asarray(x, dtype=np.float64)
    n_fft = nperseg if nfft is None else int(nfft)
    if n_fft < nperseg:
        raise DataError(f"Welch PSD: nfft {n_fft} < nperseg {nperseg}; give nfft >= nperseg")
    sums, _, count = _welch_sums(v, dt, nperseg, n_fft)
    if count == 0:
        raise DataError(f"Welch PSD: {v.size} samples, need at least one segment of {nperseg}")
    return np.fft.rfftfreq(n_fft, dt), sums / count


def _welch_sums(
    v: FloatArray, dt: float, nperseg: int, nfft: int
) -> tuple[FloatArray, FloatArray, int]:
    """Sum of the one-sided periodograms of ``v``'s Welch segments, the sum of the same
    periodograms each divided by its power in :data:`BAND_HZ` (each segment's spectral shape,
    weighted equally), and their number."""
    nb = nfft // 2 + 1
    if v.size < nperseg:
        return np.zeros(nb), np.zeros(nb), 0
    step = nperseg // 2
    segs = np.lib.stride_tricks.sliding_window_view(v, nperseg)[::step]
    k = np.arange(nperseg, dtype=np.float64)
    kc = k - k.mean()
    slope = (segs @ kc) / (kc @ kc)
    segs = segs - segs.mean(axis=1, keepdims=True) - slope[:, None] * kc[None, :]
    win = np.hanning(nperseg + 1)[:-1]  # periodic Hann, as scipy's default
    spec = np.fft.rfft(segs * win, n=nfft, axis=1)
    p = (np.abs(spec) ** 2) * dt / float(np.sum(win * win))
    p[:, 1 : nb - (1 if nfft % 2 == 0 else 0)] *= 2.0
    f = np.fft.rfftfreq(nfft, dt)
    power = p[:, (f >= BAND_HZ[0]) & (f <= BAND_HZ[1])].sum(axis=1, keepdims=True)
    shape = p / np.where(power > 0, power, 1.0)
    return p.sum(axis=0), shape.sum(axis=0), int(segs.shape[0])


def spectral_peaks(
    f: npt.ArrayLike,
    psd: npt.ArrayLike,
    *,
    band: tuple[float, float] = BAND_HZ,
    max_peaks: int = MAX_PEAKS,
) -> list[tuple[float, float]]:
    """The predominant frequencies of a spectrum (definition: module docstring).

    Parameters
    ----------
    f
        Frequencies, Hz (uniform bins).
    psd
        Power spectral density.
    band
        Frequencies searched, Hz.
    max_peaks
        Largest number of peaks returned.

    Returns
    -------
    list of (frequency_hz, psd)
        Largest first; the frequency refined by a parabola through the log-PSD of the three
        bins around the peak.

    Examples
    --------
    >>> import numpy as np
    >>> f = np.arange(0, 25.01, 0.25)
    >>> p = 1.0 / (1.0 + ((f - 8.1) / 0.3) ** 2) + 0.5 / (1.0 + ((f - 12.0) / 0.3) ** 2)
    >>> [round(x, 1) for x, _ in spectral_peaks(f, p)]
    [8.1, 12.0]
    """
    ff = np.asarray(f, dtype=np.float64)
    p = np.asarray(psd, dtype=np.float64)
    inside = np.flatnonzero((ff >= band[0]) & (ff <= band[1]))
    if inside.size < 3 or not np.any(p[inside] > 0):
        return []
    k = inside[(inside > 0) & (inside < p.size - 1)]
    is_max = (p[k] > p[k - 1]) & (p[k] >= p[k + 1]) & (p[k] >= PEAK_REL * p[inside].max())
    cand = k[is_max]
    if cand.size == 0:
        return []
    # prominence: above the lower of the minima between the candidate and its neighbours
    # (the band edges bound the outer ones)
    bounds = np.concatenate(([inside[0]], cand, [inside[-1]]))
    mins = np.minimum.reduceat(p[: inside[-1] + 1], bounds[:-1])
    left, right = mins[:-1], mins[1:]
    keep = p[cand] >= PEAK_PROMINENCE * np.minimum(left, right)
    cand = cand[keep]
    order = cand[np.argsort(-p[cand])][:max_peaks]
    df = ff[1] - ff[0]
    lp = np.log(np.maximum(p, np.finfo(float).tiny))
    den = lp[order - 1] - 2.0 * lp[order] + lp[order + 1]
    num = 0.5 * (lp[order - 1] - lp[order + 1])
    delta = np.divide(num, den, out=np.zeros_like(num), where=den < 0)
    return [(float(ff[i] + d * df), float(p[i])) for i, d in zip(order, delta, strict=True)]


def _check(df: pl.DataFrame) -> tuple[str, str | None]:
    need = ["maneuver_id", "t", "flap_deg", "az_mps2"]
    acol = "alpha_cg_deg" if "alpha_cg_deg" in df.columns else "alpha_deg"
    missing = [c for c in [*need, acol] if c not in df.columns]
    if missing:
        raise DataError(
            f"buffet identification: no {', '.join(missing)} column(s); give ingested records "
            "(aerodelta.ingest) with the raw accelerometer channels (docs/data.md)"
        )
    cols = ["t", "flap_deg", "az_mps2", acol] + [c for c in ("ay_mps2",) if c in df.columns]
    bad = df.select(pl.col(cols).cast(pl.Float64).is_nan().or_(pl.col(cols).is_null()).any())
    for c in cols:
        if bad[c][0]:
            rows = (
                df.with_row_index("__row")
                .filter(pl.col(c).cast(pl.Float64).is_nan() | pl.col(c).is_null())
                .select("__row", "maneuver_id")
            )
            raise DataError(
                f"buffet identification: maneuver {rows['maneuver_id'][0]}: {c} has NaN/missing "
                f"values ({rows.height} row(s), the first at row {int(rows['__row'][0])}); fix "
                "the record or ingest with allow_interpolation"
            )
    return acol, "ay_mps2" if "ay_mps2" in df.columns else None


_ONSET_SCHEMA: dict[str, Any] = {
    "maneuver_id": pl.Utf8,
    "flap_deg": pl.Float64,
    "buffet_onset_t_s": pl.Float64,
    "buffet_onset_alpha_deg": pl.Float64,
    "v_buffet_onset_keas": pl.Float64,
    "buffet_end_t_s": pl.Float64,
    "floor_rms_mps2": pl.Float64,
    "buffet_peak_rms_mps2": pl.Float64,
    "alpha_peak_deg": pl.Float64,
}


class BuffetResult:
    """What :func:`buffet_identification` found.

    Attributes
    ----------
    onsets : polars.DataFrame
        Per maneuver: ``maneuver_id``, ``flap_deg``, ``buffet_onset_t_s``,
        ``buffet_onset_alpha_deg``, ``v_buffet_onset_keas`` (null: no buffet),
        ``buffet_end_t_s``, ``floor_rms_mps2``, ``buffet_peak_rms_mps2``, ``alpha_peak_deg``.
    per_flap : polars.DataFrame
        Per flap: ``n_maneuvers``, ``n_buffet``, ``onset_alpha_deg`` (median),
        ``onset_alpha_min_deg``, ``onset_alpha_max_deg``, ``v_buffet_onset_mean_keas``,
        ``n_spectrum_segments``, ``spectrum_s`` (seconds of buffet in the spectra).
    frequencies : polars.DataFrame
        Per flap and axis (``nz``, ``ny``): ``rank`` (1 the largest), ``freq_hz``,
        ``psd_m2s4_hz``.
    spectra : polars.DataFrame
        Per flap and axis: the averaged Welch PSD (``freq_hz``, ``psd_m2s4_hz``).
    amplitude : polars.DataFrame
        Per flap and alpha band: ``alpha_lo_deg``, ``alpha_hi_deg``, ``n_samples``,
        ``nz_rms_mps2``, ``ny_rms_mps2`` (band-passed RMS).
    """

    def __init__(
        self,
        onsets: pl.DataFrame,
        per_flap: pl.DataFrame,
        frequencies: pl.DataFrame,
        spectra: pl.DataFrame,
        amplitude: pl.DataFrame,
    ) -> None:
        self.onsets = onsets
        self.per_flap = per_flap
        self.frequencies = frequencies
        self.spectra = spectra
        self.amplitude = amplitude

    def __repr__(self) -> str:
        n = int(self.onsets["buffet_onset_t_s"].is_not_null().sum())
        return f"BuffetResult({self.onsets.height} maneuvers, {n} with buffet)"


def buffet_identification(data: pl.DataFrame | Any) -> BuffetResult:
    """Buffet onset, predominant frequencies and amplitude against alpha from records.

    Parameters
    ----------
    data
        Ingested records (:func:`aerodelta.ingest` result or its ``data`` frame):
        ``maneuver_id``, ``t``, ``flap_deg``, ``alpha_cg_deg`` (or ``alpha_deg``), the raw
        ``az_mps2`` and (optional) ``ay_mps2``; ``tas_s_mps``/``tas_mps`` and ``rho_kgm3`` for
        the onset speed (null without them). Sampled at 2 * 8 Hz or faster.

    Returns
    -------
    BuffetResult

    Raises
    ------
    DataError
        A missing channel, NaN samples, a non-uniform time step or a sample rate too low for
        the buffet band: one line naming the maneuver and channel.

    Examples
    --------
    >>> # res = aerodelta.buffet_identification(aerodelta.ingest("campaign/").data)
    >>> # res.per_flap, res.frequencies
    """
    df: pl.DataFrame = getattr(data, "data", data)
    if not isinstance(df, pl.DataFrame):
        raise DataError(
            f"buffet identification: give a polars DataFrame of ingested records, not "
            f"{type(df).__name__}"
        )
    acol, ycol = _check(df)
    vcol = next((c for c in ("tas_s_mps", "tas_mps") if c in df.columns), None)
    has_rho = "rho_kgm3" in df.columns
    onset_rows: list[list[Any]] = []
    sums: dict[tuple[float, str], FloatArray] = {}
    shapes: dict[tuple[float, str], FloatArray] = {}
    counts: dict[tuple[float, str], int] = {}
    seconds: dict[float, float] = {}
    amp_parts: list[pl.DataFrame] = []
    dt_all: set[float] = set()
    for (mid,), g in df.partition_by("maneuver_id", as_dict=True, maintain_order=True).items():

        def col(c: str, g: pl.DataFrame = g) -> FloatArray:
            return g[c].cast(pl.Float64).to_numpy()

        t, a, az = col("t"), col(acol), col("az_mps2")
        dt = _uniform_dt(t, f"buffet identification: maneuver {mid}")
        if 0.5 / dt < 2.0 * BAND_HZ[0]:
            raise DataError(
                f"buffet identification: maneuver {mid}: sampled at {1.0 / dt:.3g} Hz, too slow "
                f"for buffet (Nyquist {0.5 / dt:.3g} Hz); record the accelerometers at 16 Hz or "
                "faster"
            )
        dt_all.add(round(dt, 9))
        flap = float(g["flap_deg"][0])
        got = detect_onset(t, a, az)
        k0, k1 = got["onset"], got["end"]
        eas = None
        if k0 is not None and vcol is not None and has_rho:
            eas = float(col(vcol)[k0] * np.sqrt(col("rho_kgm3")[k0] / _RHO0) / _KT)
        rms = got["rms_mps2"]
        onset_rows.append(
            [
                str(mid),
                flap,
                None if k0 is None else float(t[k0]),
                None if k0 is None else float(a[k0]),
                eas,
                None if k1 is None else float(t[k1]),
                got["floor_rms_mps2"],
                None if k0 is None else float(np.max(rms[k0 : k1 + 1])),
                float(a[got["peak"]]),
            ]
        )
        band = _band(dt)
        bp_z = bandpass(az, dt, band)
        bp_y = bandpass(col(ycol), dt, band) if ycol is not None else None
        amp_parts.append(
            pl.DataFrame(
                {
                    "flap_deg": np.full(t.size, flap),
                    "alpha_lo_deg": np.floor(a / AMPLITUDE_BAND_DEG) * AMPLITUDE_BAND_DEG,
                    "z2": bp_z * bp_z,
                    "y2": bp_y * bp_y if bp_y is not None else np.full(t.size, np.nan),
                }
            )
        )
        if k0 is None or k1 is None:
            continue
        hp = (HIGHPASS_HZ, 0.5 / dt)
        axes = [("nz", az)] + ([("ny", col(ycol))] if ycol is not None else [])
        for axis, x in axes:
            seg = bandpass(x, dt, hp)[k0 : k1 + 1]
            s, sh, n = _welch_sums(seg, dt, NPERSEG, NFFT)
            if n:
                key = (flap, axis)
                sums[key] = sums.get(key, np.zeros_like(s)) + s
                shapes[key] = shapes.get(key, np.zeros_like(sh)) + sh
                counts[key] = counts.get(key, 0) + n
                if axis == "nz":
                    seconds[flap] = seconds.get(flap, 0.0) + seg.size * dt
    if len(dt_all) > 1 and sums:
        raise DataError(
            f"buffet identification: the maneuvers are sampled at {len(dt_all)} rates "
            f"({', '.join(f'{1 / d:.4g} Hz' for d in sorted(dt_all))}); resample them to one rate "
            "so their spectra can be averaged"
        )
    onsets = pl.DataFrame(onset_rows, schema=_ONSET_SCHEMA, orient="row")
    dt = next(iter(dt_all)) if dt_all else 0.02
    fgrid = np.fft.rfftfreq(NFFT, dt)
    freq_rows: list[dict[str, Any]] = []
    spec_parts: list[pl.DataFrame] = []
    for (flap, axis), s in sorted(sums.items()):
        psd = s / counts[(flap, axis)]
        spec_parts.append(
            pl.DataFrame(
                {
                    "flap_deg": np.full(fgrid.size, flap),
                    "axis": [axis] * fgrid.size,
                    "freq_hz": fgrid,
                    "psd_m2s4_hz": psd,
                }
            )
        )
        shape = shapes[(flap, axis)] / counts[(flap, axis)]
        for rank, (fq, _) in enumerate(spectral_peaks(fgrid, shape, band=_band(dt)), start=1):
            p = float(np.interp(fq, fgrid, psd))
            freq_rows.append(
                {"flap_deg": flap, "axis": axis, "rank": rank, "freq_hz": fq, "psd_m2s4_hz": p}
            )
    freq_schema = {
        "flap_deg": pl.Float64,
        "axis": pl.Utf8,
        "rank": pl.Int64,
        "freq_hz": pl.Float64,
        "psd_m2s4_hz": pl.Float64,
    }
    frequencies = pl.DataFrame(freq_rows, schema=freq_schema)
    spec_schema = {k: freq_schema[k] for k in ("flap_deg", "axis", "freq_hz", "psd_m2s4_hz")}
    spectra = pl.concat(spec_parts) if spec_parts else pl.DataFrame(schema=spec_schema)
    # float means summed in row order (_groups: a polars group-by mean splits its sums over
    # the thread pool, and the last digits followed the thread count)
    per_flap = (
        group_agg(
            onsets,
            ["flap_deg"],
            {"v_buffet_onset_mean_keas": ("v_buffet_onset_keas", "mean")},
            exact=[
                pl.len().alias("n_maneuvers"),
                pl.col("buffet_onset_alpha_deg").is_not_null().sum().alias("n_buffet"),
                pl.col("buffet_onset_alpha_deg").median().alias("onset_alpha_deg"),
                pl.col("buffet_onset_alpha_deg").min().alias("onset_alpha_min_deg"),
                pl.col("buffet_onset_alpha_deg").max().alias("onset_alpha_max_deg"),
            ],
        )
        .join(
            pl.DataFrame(
                {
                    "flap_deg": [k[0] for k in counts if k[1] == "nz"],
                    "n_spectrum_segments": [v for k, v in counts.items() if k[1] == "nz"],
                    "spectrum_s": [seconds[k[0]] for k in counts if k[1] == "nz"],
                },
                schema={
                    "flap_deg": pl.Float64,
                    "n_spectrum_segments": pl.Int64,
                    "spectrum_s": pl.Float64,
                },
            ),
            on="flap_deg",
            how="left",
        )
        .sort("flap_deg")
    )
    amplitude = (
        group_agg(
            pl.concat(amp_parts),
            ["flap_deg", "alpha_lo_deg"],
            {"nz_rms_mps2": ("z2", "mean"), "ny_rms_mps2": ("y2", "mean")},
            exact=[pl.len().alias("n_samples")],
        )
        .with_columns(
            pl.col("nz_rms_mps2").sqrt(),
            pl.col("ny_rms_mps2").sqrt(),
            (pl.col("alpha_lo_deg") + AMPLITUDE_BAND_DEG).alias("alpha_hi_deg"),
        )
        .select(
            "flap_deg", "alpha_lo_deg", "alpha_hi_deg", "n_samples", "nz_rms_mps2", "ny_rms_mps2"
        )
        .sort("flap_deg", "alpha_lo_deg")
    )
    return BuffetResult(onsets, per_flap, frequencies, spectra, amplitude)


def compare_frequencies(
    simulated: pl.DataFrame | Sequence[float],
    flight_test: pl.DataFrame | Sequence[float],
    *,
    tolerance_hz: float = FREQ_TOLERANCE_HZ,
    min_spikes: int = MIN_SPIKES,
) -> pl.DataFrame:
    """Simulator against flight-test predominant buffet frequencies, pass/fail per flap.

    The flight-test spikes are paired one to one with the simulated ones of the same flap (and
    axis, when both frames have ``axis``) so that the most pairs lie within ``tolerance_hz``;
    those spikes are present (a spike without a pair shows the nearest simulated one). A flap
    passes when at least ``min(min_spikes, number of flight-test spikes)`` are present (Part 60
    Table A1A 3.f.5 as we read it: three spikes within ±2 Hz).

    Parameters
    ----------
    simulated, flight_test
        :attr:`BuffetResult.frequencies` frames (``flap_deg``, ``freq_hz``, optional ``axis``),
        or plain frequency lists (Hz) for one configuration (flap 0 is assumed).
    tolerance_hz
        Frequency tolerance, Hz.
    min_spikes
        Spikes required.

    Returns
    -------
    polars.DataFrame
        One row per flight-test spike: ``flap_deg``, ``axis``, ``flight_hz``, ``simulated_hz``
        (its pair, or the nearest; null: none), ``diff_hz``, ``present``; and per flap
        ``n_present``,
        ``n_required`` and ``flap_pass``.

    Examples
    --------
    >>> compare_frequencies([7.4, 9.9, 12.8], [7.5, 9.2, 12.6])["flap_pass"].to_list()
    [True, True, True]
    """
    if not (np.isfinite(tolerance_hz) and tolerance_hz > 0):
        raise DataError(f"tolerance_hz {tolerance_hz}: give a positive tolerance in Hz, e.g. 2")
    sim, ft = _freq_frame(simulated, "simulated"), _freq_frame(flight_test, "flight_test")
    by_axis = "axis" in sim.columns and "axis" in ft.columns
    keys = ["flap_deg", "axis"] if by_axis else ["flap_deg"]
    rows = []
    for key, fg in ft.group_by(keys, maintain_order=True):
        cand = sim.filter(pl.col("flap_deg") == key[0])
        if by_axis:
            cand = cand.filter(pl.col("axis") == key[1])
        f_ft = fg["freq_hz"].to_numpy().astype(np.float64)
        f_sim = cand["freq_hz"].to_numpy().astype(np.float64)
        # one to one, the most spikes within the tolerance: in ascending order, each flight
        # spike takes the lowest unused simulated one not below f - tolerance (optimal for
        # intervals on a line); a spike left without one shows the nearest simulated spike
        order_ft, order_sim = np.argsort(f_ft), np.argsort(f_sim)
        match = np.full(f_ft.size, -1)
        j = 0
        for i in order_ft:
            while j < f_sim.size and f_sim[order_sim[j]] < f_ft[i] - tolerance_hz:
                j += 1
            if j < f_sim.size and f_sim[order_sim[j]] <= f_ft[i] + tolerance_hz:
                match[i] = order_sim[j]
                j += 1
        paired = match >= 0
        for i in np.flatnonzero(~paired):
            if f_sim.size:
                match[i] = int(np.argmin(np.abs(f_sim - f_ft[i])))
        for i, f in enumerate(f_ft):
            best = None if match[i] < 0 else float(f_sim[match[i]])
            diff = None if best is None else best - float(f)
            rows.append(
                {
                    "flap_deg": float(key[0]),
                    "axis": str(key[1]) if by_axis else None,
                    "flight_hz": float(f),
                    "simulated_hz": best,
                    "diff_hz": diff,
                    "present": bool(paired[i]),
                }
            )
    out = pl.DataFrame(
        rows,
        schema={
            "flap_deg": pl.Float64,
            "axis": pl.Utf8,
            "flight_hz": pl.Float64,
            "simulated_hz": pl.Float64,
            "diff_hz": pl.Float64,
            "present": pl.Boolean,
        },
    )
    per = out.group_by("flap_deg").agg(
        pl.col("present").sum().alias("n_present"),
        pl.min_horizontal(pl.len(), pl.lit(min_spikes)).alias("n_required"),
    )
    return (
        out.join(per, on="flap_deg", how="left")
        .with_columns((pl.col("n_present") >= pl.col("n_required")).alias("flap_pass"))
        .sort("flap_deg", "axis", "flight_hz")
    )


def _freq_frame(x: pl.DataFrame | Sequence[float], name: str) -> pl.DataFrame:
    if isinstance(x, pl.DataFrame):
        missing = [c for c in ("flap_deg", "freq_hz") if c not in x.columns]
        if missing:
            raise DataError(
                f"compare_frequencies: {name} has no {', '.join(missing)} column(s); give "
                "BuffetResult.frequencies or a list of frequencies in Hz"
            )
        return x
    v = np.asarray(list(x), dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise DataError(f"compare_frequencies: {name} has non-finite frequencies; give Hz values")
    return pl.DataFrame({"flap_deg": np.zeros(v.size), "freq_hz": v})


def virtual_buffet_truth(campaign: str | Path) -> pl.DataFrame:
    """The buffet injected into a virtual campaign (``aerodelta campaign --buffet``).

    Parameters
    ----------
    campaign
        The campaign folder (reads ``truth/campaign.json``).

    Returns
    -------
    polars.DataFrame
        Per flap: ``flap_deg``, ``onset_alpha_deg``, ``full_alpha_deg``, ``onset_rms_mps2``,
        ``max_rms_mps2`` and ``modes_hz`` (list), ``dominant_axis`` (list: ``nz`` or ``ny`` per
        mode, the accelerometer with the larger gain).

    Raises
    ------
    DataError
        The campaign has no buffet.
    """
    path = Path(campaign) / "truth" / "campaign.json"
    info = json.loads(path.read_text())
    b = info.get("buffet")
    if not b:
        raise DataError(
            f"{path}: the campaign has no buffet; generate it with `aerodelta campaign --buffet`"
        )
    rows = []
    for flap, s in sorted(b["schedules"].items(), key=lambda kv: float(kv[0])):
        rows.append(
            {
                "flap_deg": float(flap),
                "onset_alpha_deg": s["onset_alpha_deg"],
                "full_alpha_deg": s["full_alpha_deg"],
                "onset_rms_mps2": s["onset_rms_mps2"],
                "max_rms_mps2": s["max_rms_mps2"],
                "modes_hz": [m["freq_hz"] for m in b["modes"]],
                "dominant_axis": [
                    "nz" if abs(m["nz_gain"]) >= abs(m["ny_gain"]) else "ny" for m in b["modes"]
                ],
            }
        )
    return pl.DataFrame(rows)
