"""The qualified model seen through the ingestion's smoother (``aerodelta.smoother_match``).

The reference is the ingestion's own output: it stores the smoothed roll and yaw rates
(``p_s_dps``, ``r_s_dps``) it built the measured C_l and C_n from, so a "coefficient" equal to
``p_dps / qbar`` passed through the match must come back as ``p_s_dps / qbar``: the same Wiener
weights, redesigned from the raw channel, on every maneuver, whatever the row order.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta.fit import model_frame
from aerodelta.smoother_match import MEASURED_CHANNEL, through_smoother


@pytest.fixture(scope="module")
def frame(quick_campaign: Path) -> pl.DataFrame:
    return model_frame(ad.ingest(quick_campaign, compat=False, progress=False).data)


def _rates_over_qbar(df: pl.DataFrame) -> dict[str, np.ndarray]:
    q = df["qbar_pa"].to_numpy()
    return {"Cl": df["p_dps"].to_numpy() / q, "Cn": df["r_dps"].to_numpy() / q}


def test_the_ingestions_smoothing_is_reproduced_in_any_row_order(frame: pl.DataFrame) -> None:
    assert MEASURED_CHANNEL["Cl"] == "p_dps" and MEASURED_CHANNEL["Cn"] == "r_dps"
    # rows shuffled: the match sorts each maneuver by time
    df = frame.with_row_index("row").sample(fraction=1.0, shuffle=True, seed=3)
    out, rep = through_smoother(df, _rates_over_qbar(df))
    n_man = df["maneuver_id"].n_unique()
    assert (rep.matched, rep.unsmoothed, rep.changed, rep.nonfinite) == (n_man, 0, 0, 0)
    assert rep.note() is None
    q = df["qbar_pa"].to_numpy()
    for c, stored in (("Cl", "p_s_dps"), ("Cn", "r_s_dps")):
        want = df[stored].to_numpy()
        scale = np.abs(want).max()
        np.testing.assert_allclose(out[c] * q, want, rtol=0, atol=1e-9 * scale)
        # and the smoothing did something (the quick campaign has sensor noise)
        assert np.abs(df[MEASURED_CHANNEL[c]].to_numpy() - want).max() > 1e-3 * scale


def test_a_maneuver_cut_after_ingestion_is_left_at_full_band_and_named(
    frame: pl.DataFrame,
) -> None:
    first = frame["maneuver_id"][0]
    t0 = frame.filter(pl.col("maneuver_id") == first)["t"].min()
    # its first second dropped
    cut = frame.filter((pl.col("maneuver_id") != first) | (pl.col("t") > t0 + 1.0))
    given = _rates_over_qbar(cut)
    out, rep = through_smoother(cut, given)
    assert rep.changed == 1 and rep.matched == cut["maneuver_id"].n_unique() - 1
    rows = (cut["maneuver_id"] == first).to_numpy()
    np.testing.assert_array_equal(out["Cl"][rows], given["Cl"][rows])
    assert "1 maneuver(s) whose rows changed since the ingestion" in (rep.note() or "")


def test_records_ingested_without_smoothing_are_left_as_they_are(quick_campaign: Path) -> None:
    raw = model_frame(ad.ingest(quick_campaign, compat=False, smooth=False, progress=False).data)
    given = _rates_over_qbar(raw)
    out, rep = through_smoother(raw, given)
    assert rep.unsmoothed == raw["maneuver_id"].n_unique() and rep.matched == 0
    assert rep.note() is None
    for c in given:
        np.testing.assert_array_equal(out[c], given[c])


def test_a_frame_without_the_ingestions_columns_is_named_not_matched() -> None:
    df = pl.DataFrame({"t": [0.0, 0.1], "maneuver_id": ["a", "a"], "p_dps": [0.0, 1.0]})
    out, rep = through_smoother(df, {"Cl": np.array([1.0, 2.0])})
    np.testing.assert_array_equal(out["Cl"], [1.0, 2.0])
    assert rep.skipped and "p_s_dps" in (rep.note() or "")


def test_the_fit_passes_the_qualified_model_through_and_says_where_it_could_not(
    quick_campaign: Path,
) -> None:
    data = ad.ingest(quick_campaign, compat=False, progress=False).data
    first = data["maneuver_id"][0]
    t0 = data.filter(pl.col("maneuver_id") == first)["t"].min()
    cut = data.filter((pl.col("maneuver_id") != first) | (pl.col("t") > t0 + 1.0))
    cfg = ad.FitConfig(selection=None)
    whole = ad.fit(data, config=cfg)
    assert not any("full band" in n for n in whole.notes)
    noted = ad.fit(cut, config=cfg)
    assert any("left at full band for 1 maneuver(s) whose rows changed" in n for n in noted.notes)
    # the switch: without the match the fit differs (the quick campaign is noisy)
    off = ad.fit(data, config=ad.FitConfig(selection=None, smoother_match=False))
    assert not off.params["estimate"].equals(whole.params["estimate"])
