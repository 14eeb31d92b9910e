"""Validation of canonical flight test records: refuse or warn, never guess.

Refused (severity ``error``; :func:`validate` collects them all, ingestion then raises
:class:`~aerodelta.exceptions.DataError` with every one): missing required channels;
non-increasing or duplicated time; NaN/inf runs (unless short and interpolation is allowed);
a sample rate that changes inside the record; values outside physical ranges; unit errors
betrayed by the data (angles or rates in radians where degrees are declared, found by
comparing the Euler-angle rates with the kinematic rates from p, q, r; accelerations in g).

Warned (severity ``warning``, with what was done): short dropouts interpolated; stuck
(constant) sensor channels; clipped sensors (a flat run at the extreme value).
"""

from __future__ import annotations

import itertools
import json
from dataclasses import asdict, dataclass, field

import numpy as np
import polars as pl

from aerodelta.channels import ALTERNATIVES, CHANNELS, REQUIRED
from aerodelta.readers import _rows

#: Longest NaN run (samples) that may be interpolated when the user allows it.
MAX_INTERP_GAP = 5


@dataclass(frozen=True)
class Finding:
    """One validation finding.

    Attributes
    ----------
    severity : str
        ``error`` (refused), ``warning`` (accepted, with what was done) or ``info``.
    file, maneuver_id, channel : str
        Where.
    rows : str
        0-based row ranges within the maneuver, e.g. ``"120-131, 400"`` (empty: whole record).
    message : str
        What and how to fix.
    """

    severity: str
    file: str
    maneuver_id: str
    channel: str
    rows: str
    message: str

    def __str__(self) -> str:
        rows = f", rows {self.rows}" if self.rows else ""
        where = f" channel '{self.channel}'" if self.channel else ""
        return f"{self.file} [{self.maneuver_id}]{where}{rows}: {self.message}"


@dataclass
class ValidationReport:
    """Every finding of one maneuver."""

    file: str
    maneuver_id: str
    findings: list[Finding] = field(default_factory=list)

    def add(self, severity: str, channel: str, rows: str, message: str) -> None:
        """Record a finding."""
        self.findings.append(Finding(severity, self.file, self.maneuver_id, channel, rows, message))

    @property
    def errors(self) -> list[Finding]:
        """Findings that refuse the record."""
        return [f for f in self.findings if f.severity == "error"]

    @property
    def ok(self) -> bool:
        """True when nothing was refused."""
        return not self.errors

    def to_frame(self) -> pl.DataFrame:
        """One row per finding: severity, file, maneuver_id, channel, rows, message."""
        schema = {k: pl.Utf8 for k in Finding.__dataclass_fields__}
        return pl.DataFrame([asdict(f) for f in self.findings], schema=schema)

    def to_json(self) -> str:
        """JSON with stable keys: ``file``, ``maneuver_id``, ``ok``, ``findings``."""
        return json.dumps(
            {
                "file": self.file,
                "maneuver_id": self.maneuver_id,
                "ok": self.ok,
                "findings": [asdict(f) for f in self.findings],
            },
            indent=2,
        )


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Inclusive (start, end) of each run of True."""
    if not mask.any():
        return []
    d = np.diff(np.concatenate(([0], mask.view(np.int8), [0])))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1) - 1
    return list(zip(starts.tolist(), ends.tolist(), strict=False))


def _fmt_runs(runs: list[tuple[int, int]]) -> str:
    return _rows([i for a, b in runs for i in range(a, b + 1)])


def validate(
    df: pl.DataFrame,
    file: str,
    maneuver_id: str,
    allow_interpolation: bool = False,
) -> tuple[pl.DataFrame, ValidationReport]:
    """Validate one maneuver in canonical units.

    Parameters
    ----------
    df : polars.DataFrame
        The maneuver's canonical channels.
    file, maneuver_id : str
        Where it came from (for the messages).
    allow_interpolation : bool
        Interpolate NaN/inf runs of at most :data:`MAX_INTERP_GAP` samples inside the record
        (with a warning) instead of refusing them.

    Returns
    -------
    (polars.DataFrame, ValidationReport)
        The record (interpolated where allowed) and the findings. The caller refuses the
        record when ``report.ok`` is false.
    """
    rep = ValidationReport(file, maneuver_id)
    cols = set(df.columns)
    if not cols & set(REQUIRED):
        rep.add(
            "error",
            "",
            "",
            f"no column is a channel of the canonical schema (none named {', '.join(REQUIRED[:4])}"
            ", ...; docs/data.md): give a channel map for the file's own column names "
            "(aerodelta map-template writes one), or check that it is comma-separated",
        )
        return df, rep
    for c in REQUIRED:
        if c not in cols:
            rep.add("error", c, "", "required channel missing; map it in the channel map")
    for c, alts in ALTERNATIVES.items():
        if c not in cols and not all(a in cols for a in alts):
            rep.add(
                "error",
                c,
                "",
                f"missing, and cannot be derived (needs {', '.join(alts)}); map one of them",
            )
    n = df.height
    if n < 20:
        rep.add("error", "t", "", f"{n} samples; a maneuver needs at least 20")
        return df, rep
    df = _numeric_channels(df, rep)
    names = [c for c in df.columns if c in CHANNELS]
    # one 2-D copy; the checks below run column-wise on it and loop only over columns at fault
    if names == df.columns and all(t == pl.Float64 for t in df.schema.values()):
        mat = df.to_numpy()
    else:
        mat = df.select(pl.col(names).cast(pl.Float64)).to_numpy()
    data: dict[str, np.ndarray] = {c: mat[:, i] for i, c in enumerate(names)}
    fin = np.isfinite(mat)
    nonfinite_cols = [names[i] for i in np.flatnonzero(~fin.all(axis=0))]
    # non-finite runs
    for c in nonfinite_cols:
        x = data[c]
        bad = ~np.isfinite(x)
        runs = _runs(bad)
        fixable = [(a, b) for a, b in runs if b - a + 1 <= MAX_INTERP_GAP and a > 0 and b < n - 1]
        if allow_interpolation and c != "t" and len(fixable) == len(runs):
            idx = np.arange(n)
            filled = x.copy()
            filled[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
            data[c] = filled
            rep.add(
                "warning",
                c,
                _fmt_runs(runs),
                f"{int(bad.sum())} NaN/inf samples in {len(runs)} dropout(s) linearly interpolated",
            )
        else:
            hint = (
                ""
                if allow_interpolation
                else f"; pass allow_interpolation=True to fill gaps of <= {MAX_INTERP_GAP} samples"
            )
            rep.add(
                "error",
                c,
                _fmt_runs(runs),
                f"{int(bad.sum())} NaN/inf samples in {len(runs)} run(s){hint}",
            )
    t = data.get("t")
    if t is not None and np.isfinite(t).all():
        dt = np.diff(t)
        nonpos = np.flatnonzero(dt <= 0)
        if nonpos.size:
            what = "duplicated" if (dt[nonpos] == 0).all() else "non-increasing"
            rep.add(
                "error",
                "t",
                _rows(sorted({int(i) for k in nonpos for i in (k, k + 1)})),
                f"time is {what}; sort the record and remove duplicates",
            )
        else:
            jumps = np.flatnonzero(np.abs(np.diff(dt)) > 0.01 * dt[:-1]) + 1
            if jumps.size:
                k = int(jumps[0])
                rep.add(
                    "error",
                    "t",
                    _rows(sorted({int(i) for j in jumps for i in (j, j + 1)})),
                    f"sample rate changes inside the record (step {dt[k - 1]:.6g} s before row "
                    f"{k}, {dt[k]:.6g} s at rows {k}-{k + 1}); resample to one rate before "
                    "ingesting",
                )
    # physical ranges (finite samples only)
    lo = np.array([CHANNELS[c].lo for c in names])
    hi = np.array([CHANNELS[c].hi for c in names])
    with np.errstate(invalid="ignore"):
        outside = fin & ((mat < lo) | (mat > hi))
    for i in np.flatnonzero(outside.any(axis=0)):
        c = names[i]
        x = data[c]
        spec = CHANNELS[c]
        out = outside[:, i]
        if out.any():
            rep.add(
                "error",
                c,
                _fmt_runs(_runs(out)),
                f"values {np.nanmin(x):.4g}..{np.nanmax(x):.4g} {spec.unit} outside the physical "
                f"range [{spec.lo:g}, {spec.hi:g}] {spec.unit}; check the declared unit",
            )
    _unit_checks(data, rep)
    _sensor_health(data, rep)
    if allow_interpolation:
        df = df.with_columns(pl.Series(c, data[c]) for c in data if c != "t")
    return df, rep


def _numeric_channels(df: pl.DataFrame, rep: ValidationReport) -> pl.DataFrame:
    """Channels of a type other than a number refused (text cells named by row, true/false,
    lists); numbers stored as text converted. The refused columns are dropped."""
    refused = []
    as_text = []
    for c, dtype in df.schema.items():
        if c not in CHANNELS or dtype.is_numeric():
            continue
        if dtype == pl.Utf8:
            s = df[c].str.strip_chars()
            num = s.cast(pl.Float64, strict=False)
            bad = np.flatnonzero((s.is_not_null() & (s != "") & num.is_null()).to_numpy())
            if not bad.size:
                as_text.append(c)
                continue
            rep.add(
                "error",
                c,
                _rows(bad),
                f"{bad.size} cell(s) are not numbers (the first: {s[int(bad[0])]!r}); fix or "
                "clear them",
            )
        else:
            what = "true/false" if dtype == pl.Boolean else f"{dtype}"
            rep.add(
                "error", c, "", f"holds {what} values, not numbers; give the channel as numbers"
            )
        refused.append(c)
    if as_text:
        df = df.with_columns(
            pl.col(c).str.strip_chars().cast(pl.Float64, strict=False) for c in as_text
        )
    return df.drop(refused) if refused else df


#: Median sample intervals outside which the time cannot be in seconds, s.
_DT_RANGE = (1e-4, 0.5)


def _time_unit_check(t: np.ndarray, rep: ValidationReport) -> None:
    """Refuse a median time step no flight test record has in seconds (10 Hz-10 kHz)."""
    if len(t) < 2:
        return
    with np.errstate(invalid="ignore"):
        dt = float(np.nanmedian(np.diff(t)))
    if not np.isfinite(dt) or dt <= 0.0:
        return
    if dt > _DT_RANGE[1]:
        rep.add(
            "error",
            "t",
            "",
            f"median time step {dt:.4g} s ({1.0 / dt:.3g} Hz), far slower than flight test "
            'records: the time looks like milliseconds declared as seconds; declare unit = "ms" '
            "for t in the channel map",
        )
    elif dt < _DT_RANGE[0]:
        rep.add(
            "error",
            "t",
            "",
            f"median time step {dt:.3g} s ({1.0 / dt:.3g} Hz), far faster than flight test "
            "records: the time looks like seconds declared in a smaller unit; declare its unit "
            "in the channel map",
        )


def _unit_checks(
    data: dict[str, np.ndarray],
    rep: ValidationReport,
    finite: bool | None = None,
    az_median: float | None = None,
) -> None:
    """Refuse unit errors that the data betrays (``finite``: every required channel known to
    be finite; ``az_median``: the median of az when already known)."""
    if "t" in data:
        _time_unit_check(data["t"], rep)
    if finite is None:
        finite = all(np.isfinite(data[c]).all() for c in data if c in REQUIRED)
    a = data.get("alpha_deg")
    if a is not None and np.isfinite(a).all() and np.abs(a).max() < 0.6 and np.ptp(a) > 1e-3:
        _alpha_unit_check(data, rep)
    az = data.get("az_mps2")
    if az is not None and az_median is None and np.isfinite(az).all():
        az_median = float(np.median(az))
    if az is not None and az_median is not None and 0.3 < abs(az_median) < 3.0:
        rep.add(
            "error",
            "az_mps2",
            "",
            f"median az is {az_median:.3g} m/s²: it looks like g declared as m/s²; "
            'declare unit = "g"',
        )
    need = ("t", "p_dps", "q_dps", "r_dps", "phi_deg", "theta_deg")
    if not finite or not all(c in data for c in need):
        return
    # a scale test needs no more than ~1000 points: every k-th sample
    k = max(1, len(data["t"]) // 1000)
    t = data["t"][::k]
    if (np.diff(t) <= 0).any():
        return
    d2r = np.pi / 180.0
    phi_deg, th_deg = data["phi_deg"][::k], data["theta_deg"][::k]
    phi, th = phi_deg * d2r, th_deg * d2r
    p, q, r = data["p_dps"][::k], data["q_dps"][::k], data["r_dps"][::k]
    sphi, cphi = np.sin(phi), np.cos(phi)
    # kinematic Euler rates (thesis Eq. 3.1g-h) in the declared units, deg/s
    phidot_k = p + np.tan(th) * (q * sphi + r * cphi)
    thdot_k = q * cphi - r * sphi
    dt = np.diff(t)
    num = np.concatenate((np.diff(phi_deg) / dt, np.diff(th_deg) / dt))
    kin = np.concatenate((0.5 * (phidot_k[1:] + phidot_k[:-1]), 0.5 * (thdot_k[1:] + thdot_k[:-1])))
    den = float(kin @ kin)
    if den <= 0 or float(num @ num) < 1e-6 * len(num):
        return
    k = float(kin @ num) / den
    corr = float(kin @ num) / np.sqrt(den * float(num @ num))
    if corr < 0.8:
        # the attitude does not follow the rates closely enough to judge their units
        # (the compatibility check reports inconsistent data)
        return
    if 20.0 < k < 200.0:
        rep.add(
            "error",
            "p_dps, q_dps, r_dps",
            "",
            f"the attitude changes {k:.3g}x faster than the body rates say: the rates look like "
            'rad/s declared as deg/s; declare unit = "rad/s"',
        )
    elif 0.005 < k < 0.05:
        rep.add(
            "error",
            "phi_deg, theta_deg",
            "",
            f"the attitude changes {k:.3g}x as fast as the body rates say: attitude looks like "
            'radians declared as degrees; declare unit = "rad"',
        )


def _alpha_kinematic_scale(data: dict[str, np.ndarray]) -> tuple[float, float] | None:
    """Scale and fit of the measured alpha against the alpha that the other channels imply.

    The angle-of-attack rate implied by the rates, specific forces, airspeed and attitude
    (thesis Eq. 3.1a, 3.1c with :math:`\\alpha = \\operatorname{atan2}(w, u)`):
    :math:`\\dot\\alpha = (u\\dot w - w\\dot u)/(u^2 + w^2)`,
    :math:`\\dot u = rv - qw + a_x - g\\sin\\theta`,
    :math:`\\dot w = qu - pv + a_z + g\\cos\\theta\\cos\\phi`, is integrated (trapezoids)
    to :math:`A(t)`, and the measured alpha (rad, as declared) is regressed on
    :math:`[1, t, A]` (the trend absorbs sensor biases). Returns ``(k, r2)``: the coefficient of
    A (1 when alpha is in the declared degrees, 1/57.3 when it is in radians) and the share of
    alpha's detrended variance that A explains; None when a channel is missing, the time is
    not increasing, or A does not vary (nothing to judge by).
    """
    need = ("t", "alpha_deg", "q_dps", "az_mps2", "ax_mps2", "tas_mps", "theta_deg")
    if not all(c in data and np.isfinite(data[c]).all() for c in need):
        return None
    k = max(1, len(data["t"]) // 2000)
    t = data["t"][::k]
    if len(t) < 20 or (np.diff(t) <= 0).any():
        return None
    d2r = np.pi / 180.0

    def col(c: str, scale: float = 1.0) -> np.ndarray:
        x = data.get(c)
        return np.zeros_like(t) if x is None or not np.isfinite(x).all() else x[::k] * scale

    alpha = col("alpha_deg", d2r)
    beta = col("beta_deg", d2r)
    p, q, r = col("p_dps", d2r), col("q_dps", d2r), col("r_dps", d2r)
    phi, th = col("phi_deg", d2r), col("theta_deg", d2r)
    ax, az, vt = col("ax_mps2"), col("az_mps2"), col("tas_mps")
    u = vt * np.cos(alpha) * np.cos(beta)
    v = vt * np.sin(beta)
    w = vt * np.sin(alpha) * np.cos(beta)
    g = 9.80665
    ud = r * v - q * w + ax - g * np.sin(th)
    wd = q * u - p * v + az + g * np.cos(th) * np.cos(phi)
    with np.errstate(invalid="ignore", divide="ignore"):
        adot = (u * wd - w * ud) / (u * u + w * w)
    if not np.isfinite(adot).all():
        return None
    big_a = np.concatenate(([0.0], np.cumsum(0.5 * (adot[1:] + adot[:-1]) * np.diff(t))))
    tc = t - t.mean()
    trend = np.stack([np.ones_like(t), tc], axis=1)

    def detrend(y: np.ndarray) -> np.ndarray:
        return y - trend @ np.linalg.lstsq(trend, y, rcond=None)[0]

    ad, yd = detrend(big_a), detrend(alpha)
    den = float(ad @ ad)
    yy = float(yd @ yd)
    if den <= 1e-12 * len(t) or yy <= 0.0:
        return None
    kk = float(ad @ yd) / den
    r2 = float(ad @ yd) ** 2 / (den * yy)
    return kk, r2


def _alpha_unit_check(data: dict[str, np.ndarray], rep: ValidationReport) -> None:
    """Alpha within ±0.6 deg over a whole record: radians declared as degrees, or a genuine
    low-alpha record? Refuse only when alpha follows the kinematics at 1/57.3 of the declared
    scale (consistent with radians, inconsistent with degrees); warn when the other channels
    cannot tell."""
    a = data["alpha_deg"]
    amax = float(np.abs(a).max())
    fit = _alpha_kinematic_scale(data)
    if fit is not None and fit[1] > 0.8:
        k, _ = fit
        if 0.005 < k < 0.05:
            rep.add(
                "error",
                "alpha_deg",
                "",
                f"alpha stays within ±{amax:.3g} deg and changes {k:.3g}x as fast as the rates, "
                "accelerations and airspeed say: it looks like radians declared as degrees; "
                'declare unit = "rad" in the channel map',
            )
        return
    rep.add(
        "warning",
        "alpha_deg",
        "",
        f"alpha stays within ±{amax:.3g} deg over the whole record and the other channels "
        'cannot confirm its unit; if it is in radians, declare unit = "rad" in the channel map',
    )


_HEALTH_CHANNELS = (
    "alpha_deg",
    "beta_deg",
    "p_dps",
    "q_dps",
    "r_dps",
    "ax_mps2",
    "ay_mps2",
    "az_mps2",
    "tas_mps",
)


def _sensor_health(data: dict[str, np.ndarray], rep: ValidationReport) -> None:
    """Warn on stuck or clipped continuous sensors."""
    n = len(next(iter(data.values())))
    cols = [c for c in _HEALTH_CHANNELS if c in data and np.isfinite(data[c]).all()]
    if not cols:
        return
    sub = np.stack([data[c] for c in cols], axis=1)
    flat = np.ptp(sub, axis=0) == 0.0
    repeats = (np.diff(sub, axis=0) == 0.0).sum(axis=0)
    min_run = max(25, n // 50)
    for j, c in enumerate(cols):
        if not flat[j] and repeats[j] < min_run - 1:
            continue  # no run of repeated values can be long enough
        x = data[c]
        if flat[j]:
            rep.add(
                "warning",
                c,
                "",
                f"constant at {x[0]:.6g} over the whole record: the sensor may be stuck; "
                "its derivatives and coefficients will be meaningless",
            )
            continue
        same = np.concatenate(([False], np.diff(x) == 0.0))
        long_runs = [(a - 1, b) for a, b in _runs(same) if b - a + 2 >= min_run]
        hi, lo = x.max(), x.min()
        clipped = [
            (a, b) for a, b in long_runs if x[a] in (hi, lo) and b - a + 1 >= max(5, n // 200)
        ]
        if clipped:
            rep.add(
                "warning",
                c,
                _fmt_runs(clipped),
                f"flat at its extreme value ({x[clipped[0][0]]:.6g}): the sensor looks clipped; "
                "the samples were kept",
            )
        elif long_runs:
            rep.add(
                "warning",
                c,
                _fmt_runs(long_runs),
                "repeats the same value for a long run: the sensor may have stuck; kept",
            )


def screen_many(
    cols: dict[str, np.ndarray], offsets: np.ndarray
) -> tuple[np.ndarray, list[dict[str, np.ndarray]]]:
    """Vectorised screen of many maneuvers stored back to back (canonical float64 columns,
    every maneuver at least 20 rows and every required channel present).

    Runs the checks of :func:`validate` that can only refuse or warn (non-finite samples,
    time steps, physical ranges, candidates for stuck/clipped sensors, alpha within ±0.6 deg)
    over the whole columns at once, reduced per maneuver.

    Returns
    -------
    (numpy.ndarray, list[dict])
        ``clean[m]``: True when maneuver ``m`` passed every screened check, so that
        :func:`validate` would only add unit-check findings (run :func:`unit_checks_only`);
        False: run :func:`validate` on it for the detailed findings. And the per-maneuver
        column views (no copies).
    """
    starts = offsets[:-1]
    lengths = np.diff(offsets)
    nm = len(lengths)
    clean = np.ones(nm, dtype=bool)
    for c, x in cols.items():
        spec = CHANNELS[c]
        with np.errstate(invalid="ignore"):
            bad = ~np.isfinite(x) | (x < spec.lo) | (x > spec.hi)
        if bad.any():
            clean &= ~np.logical_or.reduceat(bad, starts)
    t = cols["t"]
    dt = np.diff(t)
    # steps inside each maneuver (the step across a boundary is dropped)
    inner = np.ones(len(dt), dtype=bool)
    inner[starts[1:] - 1] = False
    with np.errstate(invalid="ignore"):
        nonpos = (dt <= 0) & inner
        jump = np.zeros(len(dt), dtype=bool)
        jump[1:] = (np.abs(np.diff(dt)) > 0.01 * dt[:-1]) & inner[1:] & inner[:-1]
    badt = np.concatenate((nonpos | jump, [False]))
    if badt.any():
        clean &= ~np.logical_or.reduceat(badt, starts)
    min_run = np.maximum(25, lengths // 50)
    for c in _HEALTH_CHANNELS:
        x = cols.get(c)
        if x is None:
            continue
        with np.errstate(invalid="ignore"):  # inf - inf: the finite check refuses those
            ptp = np.maximum.reduceat(x, starts) - np.minimum.reduceat(x, starts)
        same = np.concatenate((np.diff(x) == 0.0, [False]))
        same[starts[1:] - 1] = False
        repeats = np.add.reduceat(same.view(np.int8).astype(np.int64), starts)
        with np.errstate(invalid="ignore"):
            clean &= ~((ptp == 0.0) | (repeats >= min_run - 1))
    a = cols.get("alpha_deg")
    if a is not None:
        with np.errstate(invalid="ignore"):
            clean &= ~(np.maximum.reduceat(np.abs(a), starts) < 0.6)
    views = [{c: x[s:e] for c, x in cols.items()} for s, e in zip(starts, offsets[1:], strict=True)]
    return clean, views


def az_medians(cols: dict[str, np.ndarray], offsets: np.ndarray) -> np.ndarray | None:
    """Median of ``az_mps2`` per maneuver (one call when all maneuvers have one length)."""
    az = cols.get("az_mps2")
    if az is None:
        return None
    lengths = np.diff(offsets)
    if (lengths == lengths[0]).all():
        return np.median(az.reshape(len(lengths), int(lengths[0])), axis=1)
    return np.array([np.median(az[s:e]) for s, e in itertools.pairwise(offsets)])


def unit_checks_only(
    data: dict[str, np.ndarray], file: str, maneuver_id: str, az_median: float | None = None
) -> ValidationReport:
    """The findings :func:`validate` gives a maneuver that :func:`screen_many` passed
    (every sample finite)."""
    rep = ValidationReport(file, maneuver_id)
    _unit_checks(data, rep, finite=True, az_median=az_median)
    return rep
