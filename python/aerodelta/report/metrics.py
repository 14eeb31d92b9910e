"""Fit metrics of a predicted coefficient time history against the measured one (thesis Ch. 4).

All functions ignore samples where either signal is not finite. Units are those of the inputs
(coefficients are dimensionless).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta.fit import theil_inequality

FloatArray = npt.NDArray[np.float64]

#: Metric columns of :func:`maneuver_metrics`, per model.
METRICS = ("rms", "tic", "peak", "rms_offset_removed", "offset")


def _pair(measured: npt.ArrayLike, predicted: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    y = np.asarray(measured, dtype=np.float64)
    yh = np.asarray(predicted, dtype=np.float64)
    if y.shape != yh.shape:
        raise ValueError(f"measured {y.shape} and predicted {yh.shape} differ in shape")
    ok = np.isfinite(y) & np.isfinite(yh)
    return y[ok], yh[ok]


def rms_error(measured: npt.ArrayLike, predicted: npt.ArrayLike) -> float:
    """Root-mean-square error ``sqrt(mean((y - ŷ)²))`` (NaN when no sample is finite)."""
    y, yh = _pair(measured, predicted)
    return float(np.sqrt(np.mean((y - yh) ** 2))) if y.size else math.nan


def tic(measured: npt.ArrayLike, predicted: npt.ArrayLike) -> float:
    """Theil inequality coefficient ``rms(y - ŷ) / (rms(y) + rms(ŷ))``: 0 perfect, 1 useless.

    The same definition as :func:`aerodelta.fit.theil_inequality` (Theil 1966; Jategaonkar,
    *Flight Vehicle System Identification*, Eq. 11.6), which it calls.
    """
    y, yh = _pair(measured, predicted)
    return theil_inequality(y, yh) if y.size else math.nan


def peak_error(measured: npt.ArrayLike, predicted: npt.ArrayLike) -> float:
    """Largest absolute error ``max |y - ŷ|``."""
    y, yh = _pair(measured, predicted)
    return float(np.max(np.abs(y - yh))) if y.size else math.nan


def offset(measured: npt.ArrayLike, predicted: npt.ArrayLike) -> float:
    """Mean error ``mean(y - ŷ)`` (the constant offset between the two signals)."""
    y, yh = _pair(measured, predicted)
    return float(np.mean(y - yh)) if y.size else math.nan


def offset_removed_rms(measured: npt.ArrayLike, predicted: npt.ArrayLike) -> float:
    """RMS error once the mean error is removed: the standard deviation of ``y - ŷ``.

    ``rms² = offset² + offset_removed²``; a fit whose error is mostly a constant offset (as the
    thesis notes for C_Y, Section 4.1.3) has a small offset-removed error.
    """
    y, yh = _pair(measured, predicted)
    return float(np.std(y - yh)) if y.size else math.nan


def all_metrics(measured: npt.ArrayLike, predicted: npt.ArrayLike) -> dict[str, float]:
    """Every metric of :data:`METRICS` for one signal pair."""
    return {
        "rms": rms_error(measured, predicted),
        "tic": tic(measured, predicted),
        "peak": peak_error(measured, predicted),
        "rms_offset_removed": offset_removed_rms(measured, predicted),
        "offset": offset(measured, predicted),
    }


def maneuver_metrics(
    frame: pl.DataFrame,
    coefficients: Sequence[str] = ("Cl", "Cn", "CY"),
    held_out: Sequence[str] = (),
) -> pl.DataFrame:
    """Metrics per maneuver and coefficient, qualified and extended model.

    Parameters
    ----------
    frame
        ``maneuver_id`` and per coefficient ``C``: ``C_meas``, ``C_qual``, ``C_ext``.
    coefficients
        Coefficients to score.
    held_out
        Maneuvers not used in the fit (flagged in the ``held_out`` column).

    Returns
    -------
    polars.DataFrame
        One row per maneuver and coefficient: ``maneuver_id, coefficient, held_out, n`` and
        ``<metric>_qual`` / ``<metric>_ext`` for each of :data:`METRICS`, plus extra columns of
        ``frame`` that are constant per maneuver (``flap_deg``, ``kind``, ``pusher``).
    """
    held = set(held_out)
    extra = [c for c in ("flap_deg", "kind", "pusher") if c in frame.columns]
    used = [f"{c}_{m}" for c in coefficients for m in ("meas", "qual", "ext")]
    rows = []
    # only the columns scored: the groups are gathered from them, not from every channel
    for (mid,), g in frame.select("maneuver_id", *extra, *used).group_by(
        ["maneuver_id"], maintain_order=True
    ):
        info = {c: g[c][0] for c in extra}
        for c in coefficients:
            meas = g[f"{c}_meas"].to_numpy()
            row: dict[str, object] = {
                "maneuver_id": str(mid),
                "coefficient": c,
                "held_out": str(mid) in held,
                "n": g.height,
                **info,
            }
            for model in ("qual", "ext"):
                m = all_metrics(meas, g[f"{c}_{model}"].to_numpy())
                row.update({f"{k}_{model}": v for k, v in m.items()})
            rows.append(row)
    return pl.DataFrame(rows).sort(["coefficient", "maneuver_id"])


def overall_metrics(
    frame: pl.DataFrame,
    coefficients: Sequence[str] = ("Cl", "Cn", "CY"),
    held_out: Sequence[str] = (),
) -> pl.DataFrame:
    """Metrics pooled over all samples, per coefficient and subset (all / fitted / held out)."""
    held = set(held_out)
    is_held = frame["maneuver_id"].cast(pl.Utf8).is_in(list(held)).to_numpy()
    subsets = {"all": np.ones(frame.height, dtype=bool)}
    if held:
        subsets["fitted"] = ~is_held
        subsets["held out"] = is_held
    rows = []
    for c in coefficients:
        meas = frame[f"{c}_meas"].to_numpy()
        for name, mask in subsets.items():
            if not mask.any():
                continue
            row: dict[str, object] = {"coefficient": c, "subset": name, "n": int(mask.sum())}
            for model in ("qual", "ext"):
                m = all_metrics(meas[mask], frame[f"{c}_{model}"].to_numpy()[mask])
                row.update({f"{k}_{model}": v for k, v in m.items()})
            rows.append(row)
    return pl.DataFrame(rows)


def rank_fits(per_maneuver: pl.DataFrame, coefficient: str, by: str = "tic_ext") -> dict[str, str]:
    """Best, typical (median) and worst maneuver of one coefficient by a metric (lower is better).

    Returns
    -------
    dict
        ``{"best": id, "typical": id, "worst": id}`` (empty when no maneuver has the metric).
    """
    g = per_maneuver.filter((pl.col("coefficient") == coefficient) & pl.col(by).is_finite()).sort(
        [by, "maneuver_id"]
    )
    if g.height == 0:
        return {}
    ids = g["maneuver_id"].to_list()
    return {"best": ids[0], "typical": ids[(len(ids) - 1) // 2], "worst": ids[-1]}
