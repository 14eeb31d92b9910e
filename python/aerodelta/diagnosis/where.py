"""Where the gap lies: flight phases, the gap map over alpha and phase, the worst segments."""

from __future__ import annotations

from typing import Any

import numpy as np
import polars as pl

from aerodelta import _core
from aerodelta._groups import Groups, group_agg
from aerodelta.exceptions import DataError
from aerodelta.fit import stall_alpha


def student_t_sf(t: float, df: int) -> float:
    """Upper tail probability of Student's t with ``df`` degrees of freedom."""
    if df < 1 or not np.isfinite(t):
        return 0.0 if t > 0 else 1.0
    return 1.0 - float(_core.student_t_cdf(float(t), float(df)))


#: Alpha past which a flap's data count as "at stall" when the stall alpha cannot be detected.
DEFAULT_STALL_DEG = 15.0


def stall_alphas(frame: pl.DataFrame) -> dict[float, float]:
    """Stall alpha per flap, deg: the maximum of the measured C_L (``aerodelta.fit.stall_alpha``),
    or 15 deg when the records lack ``CX_meas``/``CZ_meas``."""
    out: dict[float, float] = {}
    for f in sorted(set(frame["flap_deg"].to_list())):
        sub = frame.filter(pl.col("flap_deg") == f)
        try:
            out[float(f)] = stall_alpha(sub) if "CZ_meas" in sub.columns else DEFAULT_STALL_DEG
        except (DataError, pl.exceptions.ColumnNotFoundError):
            out[float(f)] = DEFAULT_STALL_DEG
    return out


#: Flight phases, in the order of :func:`phase_codes`.
PHASES = ("pre_stall", "stall", "recovery")
#: Alpha regions, in the order of :func:`region_codes`.
REGIONS = ("pre_stall", "stall", "post_stall")


def phase_codes(
    frame: pl.DataFrame, stall: dict[float, float], margin_deg: float = 1.0
) -> np.ndarray:
    """Flight phase per row as an index into :data:`PHASES` (see :func:`phases`); the rows of
    a maneuver are consecutive."""
    out = np.zeros(frame.height, dtype=np.int8)
    a = frame["alpha_deg"].to_numpy()
    f = frame["flap_deg"].to_numpy()
    m = pl.col("maneuver_id")
    new = frame.select((m != m.shift(1)).fill_null(True)).to_series().to_numpy()
    starts = np.flatnonzero(new)
    ends = np.r_[starts[1:], frame.height]
    for s, e in zip(starts, ends, strict=True):
        thr = stall.get(float(f[s]), DEFAULT_STALL_DEG) - margin_deg
        seg = a[s:e]
        above = np.flatnonzero(seg >= thr)
        if above.size == 0:
            continue
        enter = above[0]
        peak = enter + int(np.argmax(seg[enter:]))
        below = np.flatnonzero(seg[peak:] < thr)
        leave = peak + below[0] if below.size else seg.size
        out[s + enter : s + leave] = 1
        out[s + leave : e] = 2
    return out


def phases(frame: pl.DataFrame, stall: dict[float, float], margin_deg: float = 1.0) -> np.ndarray:
    """Flight phase per row: ``pre_stall`` until alpha first reaches ``stall - margin``,
    ``stall`` until alpha falls back below it after its peak, then ``recovery``."""
    return np.array(PHASES)[phase_codes(frame, stall, margin_deg)]


def region_codes(alpha: np.ndarray, flap: np.ndarray, stall: dict[float, float]) -> np.ndarray:
    """Alpha region per row as an index into :data:`REGIONS` (see :func:`region_of`)."""
    s = np.full(np.shape(flap), DEFAULT_STALL_DEG)
    for f, a in stall.items():
        s[flap == f] = a
    return np.where(alpha < s - 2.0, 0, np.where(alpha <= s + 3.0, 1, 2)).astype(np.int8)


def region_of(alpha: np.ndarray, flap: np.ndarray, stall: dict[float, float]) -> np.ndarray:
    """Alpha region per row: ``pre_stall`` (alpha < stall - 2), ``stall`` (to stall + 3),
    ``post_stall`` (beyond)."""
    return np.array(REGIONS)[region_codes(alpha, flap, stall)]


def gap_map(
    frame: pl.DataFrame,
    gap: np.ndarray,
    phase: np.ndarray | pl.Series,
    bin_deg: float,
    alpha: float,
) -> list[dict[str, Any]]:
    """The gap per flap, alpha bin and phase: bias, RMS and significance.

    The bias test treats maneuvers as the independent units (the mean gap of each maneuver in
    the cell; a t test over maneuvers), which is honest under coloured residuals; the RMS is
    tested against the noise floor, the flap's pre-stall mean square gap after removing each
    maneuver's mean, by a t test over maneuvers of the excess mean square. Cells are
    significant when the smaller p (doubled for the two tests) passes the Benjamini-Hochberg
    rule at false-discovery rate ``alpha`` over all cells, and the effect is material (|bias|
    at least half the noise floor's RMS, or a mean square 25 % above the floor).
    """
    # single-chunk columns: polars sums chunk by chunk, so the records' chunking (the diagnosis
    # does not copy the records into one) would otherwise move the last digits
    df = pl.DataFrame(
        {
            "m": frame["maneuver_id"].rechunk(),
            "flap": frame["flap_deg"].rechunk(),
            "b": np.floor(frame["alpha_deg"].to_numpy() / bin_deg) * bin_deg,
            "phase": phase,
            "g": gap,
        }
    )
    floors = {}
    for f in sorted(set(df["flap"].to_list())):
        pre = df.filter((pl.col("flap") == f) & (pl.col("phase") == "pre_stall"))
        if pre.height >= 20:
            # each maneuver's mean and the mean square summed in row order by numpy (a polars
            # mean over groups splits its sums over the threads; the filtered frame's chunks
            # can follow the thread count too)
            resid = (pre["g"] - Groups.of(pre, ["m"]).over(pre["g"], "mean")).to_numpy()
            floors[f] = float(np.mean(resid * resid))
        else:
            floors[f] = float(np.var(df.filter(pl.col("flap") == f)["g"].to_numpy()))
    # in a fixed order (hash order made the sums below, hence diagnosis.json, differ from run
    # to run in the last digits), each maneuver's means summed in row order (a polars
    # group-by mean splits its sums over the thread pool)
    per_m = group_agg(
        df.with_columns((pl.col("g") ** 2).alias("g2")),
        ["flap", "b", "phase", "m"],
        {"mean": ("g", "mean"), "ms": ("g2", "mean")},
        exact=[pl.len().alias("n")],
    ).sort(["flap", "b", "phase", "m"])
    cells = per_m.group_by(["flap", "b", "phase"], maintain_order=True).agg(
        pl.col("mean").alias("means"),
        pl.col("ms").alias("mss"),
        pl.col("n").sum().alias("n"),
        pl.len().alias("k"),
    )
    cells = cells.filter((pl.col("n") >= 20) & (pl.col("k") >= 2)).sort(["flap", "b", "phase"])
    n_cells = max(cells.height, 1)
    out = []
    for r in cells.iter_rows(named=True):
        means = np.asarray(r["means"])
        mss = np.asarray(r["mss"])
        k = means.size
        floor = floors.get(r["flap"], 0.0)
        bias = float(means.mean())
        rms = float(np.sqrt(mss.mean()))
        se_b = float(means.std(ddof=1) / np.sqrt(k)) if k > 1 else float("inf")
        t_b = abs(bias) / se_b if se_b > 0 else 0.0
        p_b = 2.0 * float(student_t_sf(t_b, k - 1))
        ex = mss - floor
        se_e = float(ex.std(ddof=1) / np.sqrt(k)) if k > 1 else float("inf")
        t_e = float(ex.mean()) / se_e if se_e > 0 else 0.0
        p_e = float(student_t_sf(t_e, k - 1))
        p = min(1.0, 2.0 * min(p_b, p_e))  # two tests per cell: Bonferroni over the pair
        material = abs(bias) >= 0.5 * np.sqrt(floor) or (rms * rms - floor) >= 0.25 * floor
        out.append(
            {
                "flap_deg": float(r["flap"]),
                "alpha_lo_deg": float(r["b"]),
                "alpha_hi_deg": float(r["b"]) + bin_deg,
                "phase": r["phase"],
                "n_points": int(r["n"]),
                "n_maneuvers": int(k),
                "rms": rms,
                "bias": bias,
                "noise_floor_rms": float(np.sqrt(floor)),
                "p_value": p,
                "material": bool(material),
            }
        )
    # Benjamini-Hochberg over the cells: the false-discovery rate among the cells called
    # significant is at most ``alpha`` (the number of bins tested is accounted for).
    ps = np.array([c["p_value"] for c in out])
    order = np.argsort(ps)
    passed = ps[order] <= alpha * (np.arange(1, ps.size + 1) / max(n_cells, 1))
    k = int(np.max(np.flatnonzero(passed))) + 1 if passed.any() else 0
    cut = ps[order][k - 1] if k else -1.0
    for c in out:
        c["significant"] = bool(c["p_value"] <= cut and c.pop("material"))
    return out


def worst_segments(
    frame: pl.DataFrame, gap: np.ndarray, window_s: float = 2.0, top: int = 10
) -> list[dict[str, Any]]:
    """The ``top`` time windows (``window_s`` long, one per maneuver at most) of largest gap
    RMS, traceable to maneuver and time."""
    df = pl.DataFrame(
        {
            "m": frame["maneuver_id"].rechunk(),
            "t": frame["t"].rechunk(),
            "a": frame["alpha_deg"].rechunk(),
            "w": np.floor(frame["t"].to_numpy() / window_s),
            "g2": gap * gap,
        }
    )
    # mean squares summed in row order (a polars group-by mean splits them over the threads)
    w = (
        group_agg(
            df,
            ["m", "w"],
            {"ms": ("g2", "mean")},
            exact=[
                pl.col("t").min().alias("t0"),
                pl.col("t").max().alias("t1"),
                pl.col("a").min().alias("a0"),
                pl.col("a").max().alias("a1"),
                pl.len().alias("n"),
            ],
        )
        .with_columns(pl.col("ms").sqrt().alias("rms"))
        .filter(pl.col("n") >= 5)
        .sort(["rms", "m", "w"], descending=[True, False, False])
        .unique("m", keep="first", maintain_order=True)
        .head(top)
    )
    return [
        {
            "maneuver_id": r["m"],
            "t_start_s": float(r["t0"]),
            "t_end_s": float(r["t1"]),
            "alpha_lo_deg": float(r["a0"]),
            "alpha_hi_deg": float(r["a1"]),
            "rms": float(r["rms"]),
        }
        for r in w.iter_rows(named=True)
    ]
