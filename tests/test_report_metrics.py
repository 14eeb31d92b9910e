"""Report metrics against closed forms and numpy references."""

from __future__ import annotations

import math

import numpy as np
import polars as pl
import pytest

from aerodelta.report.metrics import (
    all_metrics,
    maneuver_metrics,
    offset,
    offset_removed_rms,
    overall_metrics,
    peak_error,
    rank_fits,
    rms_error,
    tic,
)

RNG = np.random.default_rng(11)


def test_rms_and_peak_match_numpy() -> None:
    y, yh = RNG.normal(size=500), RNG.normal(size=500)
    assert rms_error(y, yh) == pytest.approx(np.sqrt(np.mean((y - yh) ** 2)), rel=1e-14)
    assert peak_error(y, yh) == pytest.approx(np.max(np.abs(y - yh)), rel=1e-14)


@pytest.mark.parametrize("a", [0.0, 0.5, 1.0, 2.0, -1.0])
def test_tic_of_a_scaled_signal_is_closed_form(a: float) -> None:
    # ŷ = a y: rms(y - ŷ) = |1 - a| rms(y), rms(ŷ) = |a| rms(y) -> TIC = |1 - a| / (1 + |a|)
    y = np.sin(np.linspace(0, 20, 1001)) + 0.3
    assert tic(y, a * y) == pytest.approx(abs(1 - a) / (1 + abs(a)), abs=1e-14)


def test_offset_removed_error_of_a_shifted_signal_is_zero() -> None:
    y = RNG.normal(size=300)
    assert offset(y + 0.25, y) == pytest.approx(0.25)
    assert offset_removed_rms(y + 0.25, y) == pytest.approx(0.0, abs=1e-14)
    assert rms_error(y + 0.25, y) == pytest.approx(0.25)


def test_rms_splits_into_offset_and_offset_removed() -> None:
    y, yh = RNG.normal(size=400), RNG.normal(0.4, 2.0, size=400)
    m = all_metrics(y, yh)
    assert m["rms"] ** 2 == pytest.approx(m["offset"] ** 2 + m["rms_offset_removed"] ** 2)
    assert m["rms_offset_removed"] == pytest.approx(np.std(y - yh, ddof=0))


def test_non_finite_samples_are_ignored() -> None:
    y = np.array([1.0, 2.0, np.nan, 4.0])
    yh = np.array([1.0, np.inf, 3.0, 2.0])
    assert rms_error(y, yh) == pytest.approx(math.sqrt(4.0 / 2))
    assert math.isnan(rms_error([np.nan], [1.0]))


def test_maneuver_and_overall_metrics_match_a_direct_computation() -> None:
    n = 50
    f = pl.DataFrame(
        {
            "maneuver_id": ["a"] * n + ["b"] * n + ["c"] * n,
            "Cl_meas": RNG.normal(size=3 * n),
            "Cl_qual": RNG.normal(size=3 * n),
            "Cl_ext": RNG.normal(size=3 * n),
        }
    )
    per = maneuver_metrics(f, ["Cl"], held_out=["b"])
    b = f.filter(pl.col("maneuver_id") == "b")
    row = per.filter(pl.col("maneuver_id") == "b").row(0, named=True)
    assert row["held_out"] is True
    want = np.sqrt(np.mean((b["Cl_meas"].to_numpy() - b["Cl_ext"].to_numpy()) ** 2))
    assert row["rms_ext"] == pytest.approx(want)
    ov = overall_metrics(f, ["Cl"], held_out=["b"])
    held = ov.filter(pl.col("subset") == "held out").row(0, named=True)
    assert held["rms_ext"] == pytest.approx(want)
    assert held["tic_qual"] == pytest.approx(tic(b["Cl_meas"].to_numpy(), b["Cl_qual"].to_numpy()))


def test_rank_fits_picks_lowest_median_highest() -> None:
    per = pl.DataFrame(
        {
            "maneuver_id": ["m1", "m2", "m3", "m4", "m5"],
            "coefficient": ["Cl"] * 5,
            "tic_ext": [0.3, 0.1, 0.5, 0.2, float("nan")],
        }
    )
    assert rank_fits(per, "Cl") == {"best": "m2", "typical": "m4", "worst": "m3"}
    assert rank_fits(per, "Cn") == {}
