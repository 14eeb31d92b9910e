"""Stochastic roll-off: detection in flight records, statistics, runtime model, metrics.

Thesis Section 3.4.3 (Table 3.2, Figures 3.12-3.14, Eq. 3.20). The detector
runs in the engine (``aero_core::rolloff_detect``); the runtime model too
(``aero_core::rolloff``). This module arranges the records, computes the
per-flap statistics with confidence intervals (numpy only) and the dynamic
roll-control metrics.

>>> import aerodelta.rolloff as ro
>>> cfg = ro.default_config()
>>> round(cfg["alpha_std_deg"], 2), round(cfg["magnitude_cv"], 3)
(1.31, 0.225)
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta import _core
from aerodelta.campaign import _spec
from aerodelta.exceptions import DataError, InvalidInputError

FloatArray = npt.NDArray[np.float64]

#: FAR 25.203(c): the bank angle in a straight stall must not exceed 20 deg.
FAR25_203_MAX_ROLL_DEG = 20.0

_EVENT_SCHEMA = {
    "maneuver_id": pl.String,
    "flap_deg": pl.Float64,
    "kind": pl.String,
    "t_onset": pl.Float64,
    "t_peak": pl.Float64,
    "alpha_onset_deg": pl.Float64,
    "alpha_peak_deg": pl.Float64,
    "alpha_max_deg": pl.Float64,
    "peak": pl.Float64,
    "direction": pl.Int8,
    "duration_s": pl.Float64,
    "noise_sigma": pl.Float64,
    "accepted": pl.Boolean,
    "reason": pl.String,
}


def detect_defaults() -> dict[str, Any]:
    """The detector's default thresholds (keys accepted by ``config``)."""
    return dict(_core.rolloff_detect_defaults())


def _residual(data: pl.DataFrame, residual: str | FloatArray | None) -> FloatArray:
    cl = data["Cl_meas"].to_numpy().astype(np.float64)
    if residual is None:
        for model in ("Cl_qual", "Cl_sim"):
            if model in data.columns:
                return cl - data[model].to_numpy().astype(np.float64)
        return cl
    if isinstance(residual, str):
        if residual not in data.columns:
            raise DataError(f"roll-off detection: residual column '{residual}' is not in the data")
        return data[residual].to_numpy().astype(np.float64)
    r = np.asarray(residual, dtype=np.float64)
    if r.shape != (data.height,):
        raise DataError(
            f"roll-off detection: residual has shape {r.shape}, the data {data.height} rows"
        )
    return r


def detect_rolloff(
    data: pl.DataFrame,
    *,
    residual: str | FloatArray | None = None,
    config: Mapping[str, Any] | None = None,
    quiet_channels: Sequence[str] | Mapping[str, float] = ("dr_deg", "ds_deg"),
    kinds: Sequence[str] | None = ("straight",),
    alpha: str | None = None,
) -> pl.DataFrame:
    """Detect roll-off events in flight records (thesis Section 3.4.3, Table 3.2 procedure).

    Parameters
    ----------
    data
        Ingested records (``aerodelta.ingest(...).data``): ``maneuver_id``, ``t`` [s],
        ``alpha_deg``, ``Cl_meas``, ``da_deg`` and the quiet channels; ``flap_deg`` and
        ``kind`` when present.
    residual
        The rolling-moment signal searched for spikes: ``None`` (default) uses
        ``Cl_meas - Cl_qual`` or ``Cl_meas - Cl_sim`` when such a model column is
        present, else ``Cl_meas`` itself (its slow stall trend is removed by the
        detector's running median); a column name holding a residual (e.g. the
        residual of a fitted Δ model); or an array aligned with the rows of ``data``.
    config
        Detector thresholds overriding :func:`detect_defaults`.
    quiet_channels
        Channels that must stay quasi-constant before an event (step 2 of the
        procedure): names (allowed change 2 deg) or ``{name: allowed change}``.
        Missing channels are skipped.
    kinds
        Maneuver kinds searched (``None``: all).
    alpha
        Angle-of-attack channel [deg] giving the onset, peak and maximum alphas:
        ``None`` (default) uses ``alpha_cg_deg`` (the vane alpha corrected to the
        centre of gravity by ``aerodelta.ingest``) when present, else ``alpha_deg``.
        The raw vane alpha departs from the aircraft's alpha by the pitch and roll
        rates times the vane's lever arm (0.6 deg standard deviation near stall on the
        virtual campaigns, against 0.04 deg for the corrected one).

    Returns
    -------
    polars.DataFrame
        One row per candidate: ``maneuver_id, flap_deg, kind, t_onset, t_peak`` [s],
        ``alpha_onset_deg, alpha_peak_deg`` [deg], ``alpha_max_deg`` (largest alpha of the
        record [deg]: whether the stall passed the spike, see :func:`rolloff_statistics`),
        ``peak`` (signed ΔC_l), ``direction`` (+1 right wing down), ``duration_s,
        noise_sigma, accepted, reason`` (why rejected).
    """
    if alpha is None:
        alpha = "alpha_cg_deg" if "alpha_cg_deg" in data.columns else "alpha_deg"
    need = ["maneuver_id", "t", alpha, "Cl_meas", "da_deg"]
    missing = [c for c in need if c not in data.columns]
    if missing and not (residual is not None and missing == ["Cl_meas"]):
        raise DataError(f"roll-off detection: channels {missing} are missing from the data")
    res = _residual(data, residual) if "Cl_meas" in data.columns or residual is not None else None
    frame = data.with_columns(pl.Series("__res", res)).with_row_index("__row")
    if kinds is not None and "kind" in frame.columns:
        frame = frame.filter(pl.col("kind").is_in(list(kinds)))
    quiet = (
        dict(quiet_channels)
        if isinstance(quiet_channels, Mapping)
        else {c: 2.0 for c in quiet_channels}
    )
    rows: list[dict[str, Any]] = []
    for (mid,), g0 in frame.group_by(["maneuver_id"], maintain_order=True):
        g = g0.sort("t")
        t = g["t"].to_numpy().astype(np.float64)
        alpha_deg = g[alpha].to_numpy().astype(np.float64)
        qs = [
            (name, g[name].to_numpy().astype(np.float64), float(lim))
            for name, lim in quiet.items()
            if name in g.columns
        ]
        ev = _core.rolloff_detect(
            t,
            alpha_deg,
            g["__res"].to_numpy().astype(np.float64),
            g["da_deg"].to_numpy().astype(np.float64),
            qs,
            dict(config) if config else None,
        )
        flap = float(g["flap_deg"][0]) if "flap_deg" in g.columns else float("nan")
        kind = str(g["kind"][0]) if "kind" in g.columns else ""
        for k in range(len(ev["t_onset"])):
            rows.append(
                {
                    "maneuver_id": str(mid),
                    "flap_deg": flap,
                    "kind": kind,
                    "t_onset": float(ev["t_onset"][k]),
                    "t_peak": float(ev["t_peak"][k]),
                    "alpha_onset_deg": float(ev["alpha_onset_deg"][k]),
                    "alpha_peak_deg": float(alpha_deg[int(ev["peak_index"][k])]),
                    "alpha_max_deg": float(np.nanmax(alpha_deg)),
                    "peak": float(ev["peak"][k]),
                    "direction": int(ev["direction"][k]),
                    "duration_s": float(ev["duration_s"][k]),
                    "noise_sigma": float(ev["noise_sigma"][k]),
                    "accepted": ev["rejected"][k] == "",
                    "reason": ev["rejected"][k],
                }
            )
    return pl.DataFrame(rows, schema=_EVENT_SCHEMA)


def normal_ppf(p: float) -> float:
    """Standard normal quantile: Newton on ``Φ(x) = erfc(-x/√2)/2`` from 0.

    Φ is concave above 0 and convex below, so the iterates approach the root
    monotonically; converged to 1e-12 within a dozen steps for 1e-12 < p < 1 - 1e-12.
    """
    if not 0.0 < p < 1.0:
        raise InvalidInputError(f"normal_ppf: probability {p} must lie in (0, 1)")
    x = 0.0
    for _ in range(100):
        f = 0.5 * math.erfc(-x / math.sqrt(2.0)) - p
        step = f / (math.exp(-0.5 * x * x) / math.sqrt(2.0 * math.pi))
        x -= step
        if abs(step) < 1e-12:
            break
    return x


def _chi2_cdf(x: float, df: float) -> float:
    """Chi-square CDF: the regularized lower incomplete gamma ``P(df/2, x/2)`` by its series
    ``e^{-y} y^a / Γ(a+1) Σ_n y^n / ((a+1)…(a+n))`` (converges for every ``y = x/2``)."""
    if x <= 0.0:
        return 0.0
    a, y = 0.5 * df, 0.5 * x
    term = total = 1.0
    n = 0
    while term > 1e-16 * total and n < 10_000:
        n += 1
        term *= y / (a + n)
        total += term
    return min(1.0, math.exp(a * math.log(y) - y - math.lgamma(a + 1.0)) * total)


def chi2_ppf(p: float, df: float) -> float:
    """Chi-square quantile.

    For ``df >= 5`` the Wilson-Hilferty cube ``df (1 - 2/(9 df) + z sqrt(2/(9 df)))^3``
    with ``z`` the normal quantile (relative error < 0.5 %); below, where that
    approximation fails (it reaches 0 at small ``p``), bisection on the exact CDF
    (:func:`_chi2_cdf`) to 1e-12 relative.
    """
    if not 0.0 < p < 1.0:
        raise InvalidInputError(f"chi2_ppf: probability {p} must lie in (0, 1)")
    if df >= 5:
        z = normal_ppf(p)
        c = 2.0 / (9.0 * df)
        return df * max(1.0 - c + z * math.sqrt(c), 0.0) ** 3
    lo, hi = 0.0, max(10.0, 10.0 * df)
    while _chi2_cdf(hi, df) < p:
        hi *= 2.0
    while hi - lo > 1e-12 * hi:
        mid = 0.5 * (lo + hi)
        if _chi2_cdf(mid, df) < p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def wilson_interval(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion ``k / n``."""
    if n == 0:
        return (float("nan"), float("nan"))
    z = normal_ppf(0.5 + level / 2)
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(centre - half, 0.0), min(centre + half, 1.0))


def _mean_ci(x: FloatArray, level: float) -> tuple[float, float, float]:
    n = x.size
    m = float(x.mean()) if n else float("nan")
    if n < 2:
        return (m, float("nan"), float("nan"))
    h = float(_core.student_t_ppf(0.5 + level / 2, n - 1)) * float(x.std(ddof=1)) / math.sqrt(n)
    return (m, m - h, m + h)


def _std_ci(x: FloatArray, level: float) -> tuple[float, float, float]:
    n = x.size
    if n < 2:
        return (float("nan"),) * 3
    s = float(x.std(ddof=1))
    a = 1 - level
    lo = s * math.sqrt((n - 1) / chi2_ppf(1 - a / 2, n - 1))
    hi = s * math.sqrt((n - 1) / chi2_ppf(a / 2, n - 1))
    return (s, lo, hi)


def _normal_mass(a: FloatArray, b: FloatArray) -> FloatArray:
    """``Φ(b) - Φ(a)`` for ``a <= b`` elementwise, from the tail on the side of the interval
    (no cancellation when both bounds lie deep in one tail)."""
    erfc = np.frompyfunc(math.erfc, 1, 1)
    r2 = math.sqrt(2.0)
    upper = 0.5 * (erfc(a / r2) - erfc(b / r2)).astype(np.float64)
    lower = 0.5 * (erfc(-b / r2) - erfc(-a / r2)).astype(np.float64)
    return np.maximum(np.where(a > 0, upper, lower), 1e-300)


def _nelder_mead(f: Any, x0: FloatArray, step: FloatArray, iters: int = 2000) -> FloatArray:
    """Minimise ``f`` from ``x0`` (Nelder-Mead, standard coefficients 1, 2, 0.5, 0.5)."""
    pts = [np.asarray(x0, dtype=np.float64)]
    for i in range(x0.size):
        e = np.zeros(x0.size)
        e[i] = step[i]
        pts.append(pts[0] + e)
    vals = [f(p) for p in pts]
    for _ in range(iters):
        order = np.argsort(vals)
        pts = [pts[i] for i in order]
        vals = [vals[i] for i in order]
        if abs(vals[-1] - vals[0]) < 1e-12 and np.ptp(np.array(pts), axis=0).max() < 1e-9:
            break
        c = np.mean(pts[:-1], axis=0)
        xr = c + (c - pts[-1])
        fr = f(xr)
        if fr < vals[0]:
            xe = c + 2.0 * (c - pts[-1])
            fe = f(xe)
            pts[-1], vals[-1] = (xe, fe) if fe < fr else (xr, fr)
        elif fr < vals[-2]:
            pts[-1], vals[-1] = xr, fr
        else:
            xc = c + 0.5 * (pts[-1] - c)
            fc = f(xc)
            if fc < vals[-1]:
                pts[-1], vals[-1] = xc, fc
            else:
                pts = [pts[0] + 0.5 * (p - pts[0]) for p in pts]
                vals = [f(p) for p in pts]
    return pts[int(np.argmin(vals))]


def truncated_normal_fit(
    x: npt.ArrayLike,
    lower: npt.ArrayLike,
    upper: npt.ArrayLike,
    *,
    level: float = 0.95,
    censor_lower: bool = False,
) -> dict[str, float]:
    """Mean and standard deviation of a normal law sampled through per-sample truncation.

    Sample ``i`` is observed only when it falls in ``[lower_i, upper_i]`` (it is then
    distributed as the normal law truncated there). Maximum likelihood over
    ``(μ, ln σ)`` of ``Σ ln φ((x_i - μ)/σ) - ln σ - ln(Φ((u_i - μ)/σ) - Φ((l_i - μ)/σ))``
    (Nelder-Mead), covariance from the observed information (central differences).
    With ``censor_lower`` the lower bound censors instead of truncating: a sample
    below ``lower_i`` is known only to lie below it and contributes
    ``ln Φ((l_i - μ)/σ) - ln Φ((u_i - μ)/σ)`` (a Tobit term; the upper bound still
    truncates).
    Intervals are the small-sample normal ones with the truncated model's standard
    errors: ``μ ± t_{n-1} se(μ) sqrt(n/(n-1))``; ``σ`` reported as ``σ_ML sqrt(n/(n-1))``
    with interval ``σ_ML (n / χ²_{n-1})^{r/2}``, ``r = se(ln σ) sqrt(2n)`` (1 without
    truncation). Without truncation (infinite bounds) both reduce to the Student t and
    chi-square intervals of the sample mean and standard deviation.

    The search is kept within ``σ <= 4 max(s, 0.5)`` and ``μ`` within ``3`` such sigmas of
    the data (``s`` the sample standard deviation): a small sample in a narrow window can make the
    likelihood flat toward ``μ -> -∞, σ -> ∞``; an estimate on that box has no interval.

    Returns
    -------
    dict
        ``mean, mean_lo, mean_hi, std, std_lo, std_hi`` (NaN when ``n < 3``, fewer than 2
        uncensored samples, or the
        information matrix is not positive definite).
    """
    xs = np.asarray(x, dtype=np.float64)
    lo_b = np.broadcast_to(np.asarray(lower, dtype=np.float64), xs.shape)
    hi_b = np.broadcast_to(np.asarray(upper, dtype=np.float64), xs.shape)
    n = xs.size
    nan = float("nan")
    out = dict.fromkeys(("mean", "mean_lo", "mean_hi", "std", "std_lo", "std_hi"), nan)
    if n < 3 or (censor_lower and int((xs >= lo_b).sum()) < 2):
        return out
    sd0 = max(float(xs.std(ddof=1)), 1e-3)
    # box: a small sample deep in a narrow window can push the maximum to mu -> -inf,
    # sigma -> inf (the likelihood flattens); keep sigma below 4 times the larger of the
    # sample spread and 0.5 (deg), mu within 3 such sigmas of the data
    sig_max = 4.0 * max(sd0, 0.5)
    ls_max = math.log(sig_max)
    span = 3.0 * sig_max
    cens = (xs < lo_b) if censor_lower else np.zeros(n, dtype=bool)
    exact = ~cens
    trunc_lo = np.full(n, -np.inf) if censor_lower else lo_b

    def nll(th: FloatArray) -> float:
        mu, ls = float(th[0]), float(th[1])
        if ls > ls_max or not (xs.min() - span <= mu <= xs.max() + span):
            return math.inf
        sg = math.exp(ls)
        z = (xs[exact] - mu) / sg
        mass = _normal_mass((trunc_lo - mu) / sg, (hi_b - mu) / sg)
        val = 0.5 * (z * z).sum() + exact.sum() * ls + np.log(mass).sum()
        if cens.any():
            val -= np.log(_normal_mass(np.full(int(cens.sum()), -np.inf),
                                       (lo_b[cens] - mu) / sg)).sum()  # fmt: skip
        return float(val)

    th = _nelder_mead(nll, np.array([xs.mean(), math.log(sd0)]), np.array([0.5 * sd0, 0.3]))
    th = _nelder_mead(nll, th, np.array([0.1 * sd0, 0.05]))
    mu, ls = float(th[0]), float(th[1])
    sg = math.exp(ls)
    if ls > ls_max - 1e-6 or not (xs.min() - span + 1e-6 <= mu <= xs.max() + span - 1e-6):
        return out
    # observed information by central differences
    h = np.array([1e-3 * sg, 1e-3])
    hess = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            ei, ej = np.eye(2)[i] * h[i], np.eye(2)[j] * h[j]
            hess[i, j] = (
                nll(th + ei + ej) - nll(th + ei - ej) - nll(th - ei + ej) + nll(th - ei - ej)
            ) / (4 * h[i] * h[j])
    try:
        cov = np.linalg.inv(hess)
    except np.linalg.LinAlgError:
        return out
    if not (cov[0, 0] > 0 and cov[1, 1] > 0):
        return out
    a = 1.0 - level
    tq = float(_core.student_t_ppf(0.5 + level / 2, n - 1))
    half = tq * math.sqrt(cov[0, 0]) * math.sqrt(n / (n - 1))
    r = math.sqrt(cov[1, 1]) * math.sqrt(2.0 * n)
    out.update(
        mean=mu,
        mean_lo=mu - half,
        mean_hi=mu + half,
        std=sg * math.sqrt(n / (n - 1)),
        std_lo=sg * (n / chi2_ppf(1 - a / 2, n - 1)) ** (0.5 * r),
        std_hi=sg * (n / chi2_ppf(a / 2, n - 1)) ** (0.5 * r),
    )
    return out


#: Margins (deg) of the complete-spike selection of :func:`rolloff_statistics`.
ONSET_MARGIN_DEG = 0.5
PEAK_MARGIN_DEG = 0.5


def rolloff_statistics(
    events: pl.DataFrame,
    *,
    level: float = 0.95,
    rearm_alpha_deg: float = 15.0,
    truncation: bool | None = None,
    onset_margin_deg: float = ONSET_MARGIN_DEG,
    peak_margin_deg: float = PEAK_MARGIN_DEG,
) -> pl.DataFrame:
    """Roll-off statistics per flap setting (thesis Table 3.2) with confidence intervals.

    Only accepted events count. Without truncation (``truncation=False``, or by default
    when the events have no ``alpha_max_deg`` column, e.g. hand-made tables) every event
    counts as a sample of the configured laws: Student t intervals for the means,
    chi-square for the alpha standard deviation, Wilson score for the right-roll
    probability; the magnitude coefficient of variation is ``std(|peak|) / mean(|peak|)``,
    its interval the chi-square interval of the standard deviation divided by the mean
    (approximate).

    With truncation (default for :func:`detect_rolloff` output, which carries each
    record's ``alpha_max_deg``), the two ways a flight test hides part of a spike are
    accounted for (see ``docs/rolloff.md``):

    - the runtime model draws at the re-arm alpha, so a spike whose onset lies below
      it is cut (onset at the crossing, reduced peak);
    - a stall that turns back before the spike's centre (stick pusher at
      ``alpha_max - 1``) meets only its rising flank (reduced peak, onset of the partial
      spike), or nothing.

    An event is *complete* when its onset lies at least ``onset_margin_deg`` above
    ``rearm_alpha_deg`` and the record's alpha went ``peak_margin_deg`` beyond the
    spike's peak (``alpha_max_deg - alpha_peak_deg``). Which events are complete depends
    on the onset alpha only, not on the magnitude factor or the direction, so the
    magnitude mean and coefficient of variation are computed on the complete events
    alone (unbiased); the direction counts use every accepted event. The onset mean and
    standard deviation are the maximum-likelihood estimates of the normal law of the
    onset truncated to ``[rearm + onset_margin, alpha_max_i - peak_margin - d]`` per
    event (``d``: mean ``alpha_peak - alpha_onset`` of the complete events), see
    :func:`truncated_normal_fit`. When a flap has too few events for that fit (fewer than
    3 right-complete events or 2 uncensored onsets), or fewer than 2 complete events for
    the magnitude, the plain statistics of every accepted event are reported instead
    (biased by the truncation), flagged by ``alpha_method = "sample"`` and
    ``magnitude_method = "all"``.

    Returns
    -------
    polars.DataFrame
        Per flap: ``n`` (accepted events), ``n_onset`` (events in the onset fit),
        ``n_complete`` (events in the magnitude statistics), ``alpha_mean_deg (+_lo, _hi),
        alpha_std_deg (+_lo, _hi), alpha_peak_mean_deg, alpha_method`` (``censored_fit``
        or ``sample``), ``magnitude_mean (+_lo, _hi), magnitude_cv (+_lo, _hi),
        magnitude_method`` (``complete``, ``all`` or ``sample``), ``n_right, n_left,
        p_right (+_lo, _hi)``.
    """
    ev = events.filter(pl.col("accepted")) if "accepted" in events.columns else events
    trunc = "alpha_max_deg" in ev.columns if truncation is None else truncation
    if trunc and "alpha_max_deg" not in ev.columns:
        ev = ev.with_columns(pl.lit(float("inf")).alias("alpha_max_deg"))
    if "alpha_peak_deg" not in ev.columns:
        ev = ev.with_columns(pl.col("alpha_onset_deg").alias("alpha_peak_deg"))
    rows = []
    for flap in sorted(set(ev["flap_deg"].to_list())):
        g = ev.filter(pl.col("flap_deg") == flap)
        d = g["direction"].to_numpy()
        n = int(d.size)
        if trunc:
            low = rearm_alpha_deg + onset_margin_deg
            # the stall passed the spike's peak: its full onset is known or censored below
            r = g.filter(pl.col("alpha_max_deg") - pl.col("alpha_peak_deg") >= peak_margin_deg)
            c = r.filter(pl.col("alpha_onset_deg") >= low)
        else:
            r = c = g
        a = c["alpha_onset_deg"].to_numpy().astype(np.float64)
        apk = c["alpha_peak_deg"].to_numpy().astype(np.float64)
        mag = np.abs(c["peak"].to_numpy().astype(np.float64))
        alpha_method = magnitude_method = "sample"
        if trunc:
            alpha_method = magnitude_method = "censored_fit"
            rise = float(np.mean(apk - a)) if a.size else float("nan")
            upper = r["alpha_max_deg"].to_numpy() - peak_margin_deg - rise
            fit = truncated_normal_fit(
                r["alpha_onset_deg"].to_numpy(), low, upper, level=level, censor_lower=True
            )
            am, alo, ahi = fit["mean"], fit["mean_lo"], fit["mean_hi"]
            sd, slo, shi = fit["std"], fit["std_lo"], fit["std_hi"]
            apk_mean = am + rise
            if not math.isfinite(am) or not math.isfinite(sd):
                # too few events for the fit: the plain sample statistics of every
                # accepted event (biased by the truncation; flagged)
                alpha_method = "sample"
                a_all = g["alpha_onset_deg"].to_numpy().astype(np.float64)
                am, alo, ahi = _mean_ci(a_all, level)
                sd, slo, shi = _std_ci(a_all, level)
                apk_mean = float(g["alpha_peak_deg"].mean())  # type: ignore[arg-type]
            magnitude_method = "complete"
            if mag.size < 2:
                magnitude_method = "all"
                mag = np.abs(g["peak"].to_numpy().astype(np.float64))
        else:
            am, alo, ahi = _mean_ci(a, level)
            sd, slo, shi = _std_ci(a, level)
            apk_mean = float(apk.mean()) if apk.size else float("nan")
        mm, mlo, mhi = _mean_ci(mag, level)
        ms, mslo, mshi = _std_ci(mag, level)
        nr = int((d > 0).sum())
        plo, phi = wilson_interval(nr, n, level)
        rows.append(
            {
                "flap_deg": float(flap),
                "n": n,
                "n_onset": int(r.height),
                "n_complete": int(a.size),
                "alpha_mean_deg": am,
                "alpha_mean_lo": alo,
                "alpha_mean_hi": ahi,
                "alpha_std_deg": sd,
                "alpha_std_lo": slo,
                "alpha_std_hi": shi,
                "alpha_peak_mean_deg": apk_mean,
                "alpha_method": alpha_method,
                "magnitude_method": magnitude_method,
                "magnitude_mean": mm,
                "magnitude_lo": mlo,
                "magnitude_hi": mhi,
                "magnitude_cv": ms / mm,
                "magnitude_cv_lo": mslo / mm,
                "magnitude_cv_hi": mshi / mm,
                "n_right": nr,
                "n_left": n - nr,
                "p_right": nr / n if n else float("nan"),
                "p_right_lo": plo,
                "p_right_hi": phi,
            }
        )
    return pl.DataFrame(rows)


def default_config() -> dict[str, Any]:
    """The runtime model's default configuration (thesis Table 3.2) as a dict."""
    out: dict[str, Any] = json.loads(_core.sim_rolloff_config())
    return out


def config_from_statistics(
    stats: pl.DataFrame, *, width_deg: float = 0.5, rearm_alpha_deg: float = 15.0
) -> dict[str, Any]:
    """A runtime-model configuration (``aero_core::rolloff::RollOffConfig``) from statistics.

    Per flap: the Gaussian centre is the mean alpha at the spike's peak
    (``alpha_peak_mean_deg``; the onset lies ``width sqrt(2 ln 5)`` below it at
    the detector's 20 % onset fraction), the magnitude the mean ``|peak|``, the
    right probability ``p_right``. The alpha spread and magnitude coefficient of
    variation are pooled over flaps, weighted by ``n - 1`` (thesis: one value
    for all settings).
    """
    s = stats.filter(pl.col("n") >= 2)
    if s.height == 0:
        raise InvalidInputError("config_from_statistics: no flap setting has 2 or more events")
    w = (s["n"].to_numpy() - 1).astype(np.float64)
    var_a = s["alpha_std_deg"].to_numpy() ** 2
    cv = s["magnitude_cv"].to_numpy()
    return {
        "flaps": [
            {
                "flap_deg": float(r["flap_deg"]),
                "mean_alpha_deg": float(r["alpha_peak_mean_deg"]),
                "magnitude": float(r["magnitude_mean"]),
                "p_right": float(r["p_right"]),
            }
            for r in s.iter_rows(named=True)
        ],
        "width_deg": float(width_deg),
        "alpha_std_deg": float(math.sqrt((w * var_a).sum() / w.sum())),
        "magnitude_cv": float(math.sqrt((w * cv**2).sum() / w.sum())),
        "rearm_alpha_deg": float(rearm_alpha_deg),
        "scale": 1.0,
    }


def sample_draws(
    config: Mapping[str, Any] | None, flap_deg: float, seed: int, n: int, stream: int = 0
) -> pl.DataFrame:
    """``n`` successive draws of the runtime model (engine ``sample_draws``) for a configuration.

    Returns
    -------
    polars.DataFrame
        ``sign`` (+1 right), ``factor``, ``alpha_shift_deg``, ``center_deg``, ``peak``.
    """
    cfg = json.dumps(dict(config) if config is not None else default_config())
    return pl.DataFrame(
        _core.rolloff_sample_draws(cfg, float(flap_deg), int(seed), int(n), int(stream))
    )


def euler_roll_rate(
    p_dps: npt.ArrayLike,
    q_dps: npt.ArrayLike,
    r_dps: npt.ArrayLike,
    phi_deg: npt.ArrayLike,
    theta_deg: npt.ArrayLike,
) -> FloatArray:
    """φ̇ = p + (q sin φ + r cos φ) tan θ (Euler kinematics), deg/s."""
    ph = np.radians(np.asarray(phi_deg, dtype=np.float64))
    th = np.radians(np.asarray(theta_deg, dtype=np.float64))
    q = np.asarray(q_dps, dtype=np.float64)
    r = np.asarray(r_dps, dtype=np.float64)
    return np.asarray(p_dps, dtype=np.float64) + (q * np.sin(ph) + r * np.cos(ph)) * np.tan(th)


def dynamic_roll(phi_deg: npt.ArrayLike, phidot_dps: npt.ArrayLike) -> FloatArray:
    """Dynamic roll attitude φ' = φ + φ̇ · (1 s) (thesis Eq. 3.20), deg.

    ``phidot_dps`` is the Euler roll rate [deg/s] (see :func:`euler_roll_rate`;
    ``p`` is a close substitute near wings level). The one-second lead makes φ'
    the bank angle reached one second later at the current rate.
    """
    return np.asarray(phi_deg, dtype=np.float64) + np.asarray(phidot_dps, dtype=np.float64)


def max_roll_straight_stalls(
    data: pl.DataFrame, *, limit_deg: float = FAR25_203_MAX_ROLL_DEG
) -> pl.DataFrame:
    """Maximum |φ| of each straight stall against FAR 25.203 (thesis Figure 3.13).

    Returns
    -------
    polars.DataFrame
        ``maneuver_id, flap_deg, max_roll_deg, max_dynamic_roll_deg`` (|φ + p|), ``passed``
        (max |φ| <= ``limit_deg``).
    """
    d = data.filter(pl.col("kind") == "straight") if "kind" in data.columns else data
    keys = ["maneuver_id"] + (["flap_deg"] if "flap_deg" in d.columns else [])
    out = (
        d.group_by(keys, maintain_order=True)
        .agg(
            pl.col("phi_deg").abs().max().alias("max_roll_deg"),
            (pl.col("phi_deg") + pl.col("p_dps")).abs().max().alias("max_dynamic_roll_deg"),
        )
        .with_columns((pl.col("max_roll_deg") <= limit_deg).alias("passed"))
    )
    return out


_MC_FLAPS = (0.0, 5.0, 10.0, 15.0, 35.0)


def monte_carlo(
    n: int,
    seed: int = 0,
    *,
    flap_deg: float = 0.0,
    config: Mapping[str, Any] | None = None,
    noise: float = 1.0,
    turbulence: float = 0.5,
    record_hz: float = 10.0,
    chunk: int | None = None,
    excitation: float = 1.0,
    threads: int | None = None,
    first: int = 0,
    progress: bool = False,
) -> pl.DataFrame:
    """Many straight stalls of the 6-DOF simulator with the roll-off on (engine ``rolloff_mc``).

    Stall ``k`` is the straight stall of repetition ``k // 2`` (stick pusher on for even
    ``k``) at ``flap_deg`` of the campaign with the same seed (``simulate_campaign``):
    same flight, same random streams. The stalls run in parallel in the engine (rayon),
    each reduced to a summary (no time history); the result does not depend on the
    thread count.

    Parameters
    ----------
    n
        Number of stalls (half with the stick pusher, half without).
    seed
        Campaign seed.
    flap_deg
        Flap setting (one of the five of the representative aircraft), deg.
    config
        Roll-off configuration (``None``: thesis Table 3.2; see :func:`config_from_statistics`).
    noise, record_hz
        Unused (nothing is recorded); kept for compatibility.
    turbulence
        Dryden gust RMS, m/s (as the campaign).
    chunk
        Stalls per engine call (``None``: all at once, or 20 calls with ``progress``).
    excitation
        Pilot excitation scale (doublets, stick noise), as the campaign.
    threads
        Size of a dedicated thread pool (``None``: all cores, or ``RAYON_NUM_THREADS``).
    first
        Index of the first stall (a continuation of an earlier run).
    progress
        tqdm progress bar on stderr (per chunk).

    Returns
    -------
    polars.DataFrame
        Per stall: ``maneuver_id`` (the campaign's id of the same maneuver), ``flap_deg``,
        ``stall``,
        ``pusher``, ``pusher_fired``, ``duration_s`` [s], ``max_bank_deg`` (max |φ|),
        ``max_alpha_deg``, ``max_dynamic_roll_deg`` (max |φ + φ̇ · 1 s|, Eq. 3.20, the DRC
        peak), ``far25_203_pass`` (max |φ| <= 20 deg), ``onset_alpha_deg`` (true alpha
        where the injected ΔC_l first reaches 20 % of its largest value; NaN when the
        stall never met the spike), ``onset_t`` [s], ``peak`` (signed largest injected
        ΔC_l, the roll-off magnitude met), ``direction`` (+1 right, -1 left, 0 none),
        ``drawn_peak`` and ``drawn_center_deg`` (the draw that made the roll-off met, else
        the draw at the first 15 deg crossing; 0 and NaN when alpha never crossed it: no
        roll-off acts before the first draw), ``drawn_t`` (its time [s]), ``crossings``
        (counted upward crossings of the re-arm alpha, each a new draw; after a draw alpha
        must fall below the re-arm alpha less ``rearm_hysteresis_deg`` first).
    """
    del noise, record_hz
    if flap_deg not in _MC_FLAPS:
        raise InvalidInputError(f"monte_carlo: flap_deg {flap_deg} is not one of {list(_MC_FLAPS)}")
    if n < 0 or first < 0:
        raise InvalidInputError(f"monte_carlo: n ({n}) and first ({first}) must be >= 0")
    campaign = _spec(
        {},
        seed=seed,
        size=1,
        noise=0.0,
        turbulence=turbulence,
        rolloff=True,
        excitation=excitation,
    )
    if config is not None:
        campaign["rolloff"] = dict(config)
    step = chunk or (max(1, -(-n // 20)) if progress else max(n, 1))
    parts: list[pl.DataFrame] = []
    from tqdm import tqdm  # noqa: PLC0415  (only when flying)

    with tqdm(total=n, unit="stall", disable=not progress, desc="Monte Carlo") as bar:
        for start in range(first, first + n, step):
            spec = {
                "campaign": campaign,
                "flap_deg": float(flap_deg),
                "first": start,
                "n": min(step, first + n - start),
            }
            parts.append(pl.DataFrame(_core.rolloff_monte_carlo(json.dumps(spec), threads)))
            bar.update(spec["n"])
    if not parts:
        parts.append(pl.DataFrame(_core.rolloff_monte_carlo(json.dumps({"n": 0}), threads)))
    df = pl.concat(parts)
    ident = (
        pl.format(
            "m{}_f{}_straight_{}",
            pl.col("maneuver_index").cast(pl.String).str.zfill(3),
            pl.lit(f"{int(flap_deg):02d}"),
            pl.when(pl.col("pusher")).then(pl.lit("p")).otherwise(pl.lit("n")),
        )
    ).alias("maneuver_id")
    flap = pl.lit(float(flap_deg)).alias("flap_deg")
    return df.select(ident, flap, pl.all().exclude("maneuver_index"))


def ks_2samp(x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[float, float]:
    """Two-sample Kolmogorov-Smirnov test (NaNs dropped).

    ``D = max |F_x - F_y|`` over the pooled sample; the p-value is the asymptotic
    Kolmogorov distribution ``Q(√(n m / (n + m)) D)``,
    ``Q(λ) = 2 Σ_{k>=1} (-1)^{k-1} exp(-2 k² λ²)`` (Smirnov 1948), good for ``n, m >= 30``.

    Returns
    -------
    (float, float)
        ``(D, p)``; ``(nan, nan)`` when a sample is empty.
    """
    a = np.sort(np.asarray(x, dtype=np.float64))
    b = np.sort(np.asarray(y, dtype=np.float64))
    a, b = a[~np.isnan(a)], b[~np.isnan(b)]
    n, m = a.size, b.size
    if n == 0 or m == 0:
        return (float("nan"), float("nan"))
    z = np.concatenate([a, b])
    d = float(
        np.max(np.abs(np.searchsorted(a, z, side="right") / n - np.searchsorted(b, z, "right") / m))
    )
    lam = math.sqrt(n * m / (n + m)) * d
    if lam < 0.2:
        return (d, 1.0)
    k = np.arange(1, 101, dtype=np.float64)
    q = 2.0 * float(np.sum((-1.0) ** (k - 1) * np.exp(-2.0 * k * k * lam * lam)))
    return (d, min(max(q, 0.0), 1.0))


#: Quantile levels of the comparison tables.
QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)


def compare_distributions(
    samples: Mapping[str, tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    labels: tuple[str, str] = ("mc", "records"),
    quantiles: Sequence[float] = QUANTILES,
) -> pl.DataFrame:
    """Compare pairs of samples: sizes, means, quantiles and the two-sample KS test.

    Parameters
    ----------
    samples
        ``{quantity: (first sample, second sample)}`` (NaNs dropped).
    labels
        Names of the two samples in the column names.
    quantiles
        Quantile levels (linear interpolation, numpy's default).

    Returns
    -------
    polars.DataFrame
        One row per quantity: ``quantity, n_<a>, n_<b>, mean_<a>, mean_<b>``,
        ``q<pct>_<a>, q<pct>_<b>`` per level, ``ks_statistic, ks_pvalue``.
    """
    la, lb = labels
    rows = []
    for name, (x, y) in samples.items():
        a = np.asarray(x, dtype=np.float64)
        b = np.asarray(y, dtype=np.float64)
        a, b = a[~np.isnan(a)], b[~np.isnan(b)]
        row: dict[str, Any] = {"quantity": name, f"n_{la}": a.size, f"n_{lb}": b.size}
        row[f"mean_{la}"] = float(a.mean()) if a.size else float("nan")
        row[f"mean_{lb}"] = float(b.mean()) if b.size else float("nan")
        for q in quantiles:
            tag = f"q{round(100 * q):02d}"
            row[f"{tag}_{la}"] = float(np.quantile(a, q)) if a.size else float("nan")
            row[f"{tag}_{lb}"] = float(np.quantile(b, q)) if b.size else float("nan")
        row["ks_statistic"], row["ks_pvalue"] = ks_2samp(a, b)
        rows.append(row)
    return pl.DataFrame(rows)


def compare_with_records(
    mc: pl.DataFrame,
    events: pl.DataFrame,
    max_roll: pl.DataFrame,
    *,
    quantiles: Sequence[float] = QUANTILES,
) -> pl.DataFrame:
    """The Monte Carlo against the flight records, per flap setting.

    Onset alpha: the Monte Carlo's ``onset_alpha_deg`` against the accepted detected
    events' ``alpha_onset_deg``; maximum bank: ``max_bank_deg`` against the straight
    stalls' ``max_roll_deg`` (:func:`max_roll_straight_stalls`).

    Parameters
    ----------
    mc
        :func:`monte_carlo` results with a ``flap_deg`` column (one or several flaps).
    events
        :func:`detect_rolloff` output of the records.
    max_roll
        :func:`max_roll_straight_stalls` of the records.

    Returns
    -------
    polars.DataFrame
        :func:`compare_distributions` rows with ``flap_deg`` first; quantities
        ``onset_alpha_deg`` and ``max_bank_deg``.
    """
    ev = events.filter(pl.col("accepted")) if "accepted" in events.columns else events
    out = []
    for flap in sorted(set(mc["flap_deg"].to_list())):
        m = mc.filter(pl.col("flap_deg") == flap)
        e = ev.filter(pl.col("flap_deg") == flap)
        r = max_roll.filter(pl.col("flap_deg") == flap)
        t = compare_distributions(
            {
                "onset_alpha_deg": (
                    m["onset_alpha_deg"].to_numpy(),
                    e["alpha_onset_deg"].to_numpy(),
                ),
                "max_bank_deg": (m["max_bank_deg"].to_numpy(), r["max_roll_deg"].to_numpy()),
            },
            quantiles=quantiles,
        )
        out.append(t.select(pl.lit(float(flap)).alias("flap_deg"), pl.all()))
    return pl.concat(out) if out else pl.DataFrame()


def check_statistics(stats: pl.DataFrame, config: Mapping[str, Any] | None = None) -> pl.DataFrame:
    """Estimated roll-off statistics (:func:`rolloff_statistics`) against a configuration.

    Per flap and quantity, the configured value, the estimate, its interval and whether
    the interval holds the configured value (``False`` when no interval could be computed).
    Quantities: ``alpha_onset_deg`` (the mean
    detected onset; configured: the Gaussian centre less ``width sqrt(2 ln 5)``, where the
    spike reaches the detector's 20 % onset fraction), ``alpha_std_deg`` (configured
    centre shift spread), ``magnitude`` (mean |peak|), ``magnitude_cv`` and ``p_right``.

    Returns
    -------
    polars.DataFrame
        ``flap_deg, quantity, configured, estimate, lo, hi, inside, n``.
    """
    cfg = dict(config) if config is not None else default_config()
    scale = float(cfg.get("scale", 1.0))
    onset_offset = float(cfg["width_deg"]) * math.sqrt(2.0 * math.log(5.0))
    rows = []
    for r in stats.iter_rows(named=True):
        f = min(cfg["flaps"], key=lambda x: abs(float(x["flap_deg"]) - r["flap_deg"]))
        # (quantity, configured value, estimate column, interval column prefix)
        checks = (
            ("alpha_onset_deg", float(f["mean_alpha_deg"]) - onset_offset, "alpha_mean_deg",
             "alpha_mean"),
            ("alpha_std_deg", float(cfg["alpha_std_deg"]), "alpha_std_deg", "alpha_std"),
            ("magnitude", float(f["magnitude"]) * scale, "magnitude_mean", "magnitude"),
            ("magnitude_cv", float(cfg["magnitude_cv"]), "magnitude_cv", "magnitude_cv"),
            ("p_right", float(f["p_right"]), "p_right", "p_right"),
        )  # fmt: skip
        for name, conf, col, ci in checks:
            lo, hi = float(r[f"{ci}_lo"]), float(r[f"{ci}_hi"])
            rows.append(
                {
                    "flap_deg": float(r["flap_deg"]),
                    "quantity": name,
                    "configured": conf,
                    "estimate": float(r[col]),
                    "lo": lo,
                    "hi": hi,
                    "inside": bool(lo <= conf <= hi),
                    "n": int(r["n"]),
                }
            )
    return pl.DataFrame(rows)


#: An injected roll-off whose largest |ΔC_l| is at least this counts as an event to find
#: (clearly above the detector's 0.003 magnitude floor).
INJECTED_MIN = 0.005
#: An accepted event matched to an injected contribution at least this large (within
#: :data:`MATCH_WINDOW_S`) is not a false event, even when that contribution is too small
#: to count as one to find.
PARTIAL_MIN = 0.002
#: Largest distance between a detected and the injected peak time of a match, s.
MATCH_WINDOW_S = 3.0


def score_detection(events: pl.DataFrame, campaign_dir: str | Path) -> dict[str, Any]:
    """Score detected roll-offs against a *virtual* campaign's injected ones (validation only).

    Reads the campaign's truth files (``truth/<maneuver>.parquet``, column
    ``dCl_stochastic_rolloff``), which exist only for virtual flight tests; the detector itself
    never reads them. Per straight stall in ``events`` (maneuvers of kind ``straight``), the
    injected event is the largest |ΔC_l| of the roll-off contribution, its time and true alpha.

    Parameters
    ----------
    events
        :func:`detect_rolloff` output (accepted and rejected candidates).
    campaign_dir
        The campaign folder (holds ``truth/`` and ``manifest.csv``).

    Returns
    -------
    dict
        ``injected`` (events with |peak| >= :data:`INJECTED_MIN`), ``found`` (of those, with an
        accepted event within :data:`MATCH_WINDOW_S` of the injected peak), ``accepted``,
        ``false`` (accepted events matching no injected contribution >= :data:`PARTIAL_MIN`),
        ``recall`` and ``false_rate`` (false / max(accepted, straight stalls)), ``missed`` (the
        maneuvers of the injected events not found, with the detector's rejection reasons) and
        ``matched`` (the accepted events that match, with ``t_true``, ``peak_true``,
        ``alpha_true``).
    """
    truth_dir = Path(campaign_dir) / "truth"
    manifest = pl.read_csv(Path(campaign_dir) / "manifest.csv")
    ids = sorted(manifest.filter(pl.col("kind") == "straight")["maneuver_id"].to_list())
    rows = []
    for mid in ids:
        f = truth_dir / f"{mid}.parquet"
        if not f.exists():
            raise DataError(f"score_detection: {f} is missing (a virtual campaign's truth file)")
        tr = pl.read_parquet(f)
        if "dCl_stochastic_rolloff" not in tr.columns:
            rows.append({"maneuver_id": mid, "t_true": 0.0, "peak_true": 0.0, "alpha_true": 0.0})
            continue
        d = tr["dCl_stochastic_rolloff"].to_numpy()
        k = int(np.argmax(np.abs(d)))
        rows.append(
            {
                "maneuver_id": mid,
                "t_true": float(tr["t"][k]),
                "peak_true": float(d[k]),
                "alpha_true": float(tr["alpha_true_deg"][k]),
            }
        )
    truth = pl.DataFrame(
        rows,
        schema={"maneuver_id": pl.String, "t_true": pl.Float64, "peak_true": pl.Float64,
                "alpha_true": pl.Float64},
    )  # fmt: skip
    acc = events.filter(pl.col("accepted") & pl.col("maneuver_id").is_in(ids))
    j = acc.join(truth, on="maneuver_id", how="left")
    matched = j.filter(
        (pl.col("peak_true").abs() >= PARTIAL_MIN)
        & ((pl.col("t_peak") - pl.col("t_true")).abs() < MATCH_WINDOW_S)
    )
    injected = truth.filter(pl.col("peak_true").abs() >= INJECTED_MIN)
    found = injected.join(matched.select("maneuver_id"), on="maneuver_id", how="semi")
    missed = injected.join(found.select("maneuver_id"), on="maneuver_id", how="anti").join(
        events.group_by("maneuver_id").agg(pl.col("reason").str.join("; ")),
        on="maneuver_id",
        how="left",
    )
    false = j.height - matched.height
    return {
        "injected": injected.height,
        "found": found.height,
        "accepted": j.height,
        "false": false,
        "recall": found.height / injected.height if injected.height else float("nan"),
        "false_rate": false / max(j.height, len(ids), 1),
        "missed": missed,
        "matched": matched,
    }


__all__ = [
    "FAR25_203_MAX_ROLL_DEG",
    "QUANTILES",
    "check_statistics",
    "chi2_ppf",
    "compare_distributions",
    "compare_with_records",
    "config_from_statistics",
    "default_config",
    "detect_defaults",
    "detect_rolloff",
    "dynamic_roll",
    "euler_roll_rate",
    "ks_2samp",
    "max_roll_straight_stalls",
    "monte_carlo",
    "normal_ppf",
    "rolloff_statistics",
    "sample_draws",
    "score_detection",
    "truncated_normal_fit",
    "wilson_interval",
]
