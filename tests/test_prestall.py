"""Pre-stall regression of the evidence pack (``aerodelta.evidence.prestall``): the extended
model leaves the qualified model unchanged where the Δ is blended out, and the check sees it
when it does not."""

from __future__ import annotations

from typing import Any

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta.aircraft import BUILTIN_COLUMN
from aerodelta.campaign import record_state, replay
from aerodelta.evidence import prestall


@pytest.fixture(scope="module")
def fitted(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    camp = tmp_path_factory.mktemp("prestall") / "camp"
    ad.generate_campaign(camp, seed=41, size="quick", progress=False)
    data = ad.ingest(camp, compat=False, progress=False).data
    return {"data": data, "model": ad.fit(data).model}


def test_extended_equals_qualified_below_the_blend(fitted: dict[str, Any]) -> None:
    chk = prestall.prestall_regression(fitted["data"], fitted["model"])
    t = chk.table
    assert chk.replay_note == ""
    assert t.height == fitted["data"]["maneuver_id"].n_unique()
    assert chk.passed
    assert int(t["samples_blended_out"].sum()) > 10_000
    assert int(t["steps_compared"].sum()) > 10_000
    assert float(t["max_state_diff"].max()) == 0.0
    # the Δ does act past the blend start: the replays differ there (the check is not vacuous)
    moved = [
        float(np.abs(r["alpha_qual_deg"] - r["alpha_ext_deg"]).max()) for r in chk.runs.values()
    ]
    assert max(moved) > 0.1


def test_a_comparison_reaching_past_the_blend_start_fails(
    fitted: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    # told the blend starts 6 deg later than it does, the check compares states the Δ has
    # already moved: it must fail on the maneuvers that go there
    real = prestall.blend_start
    monkeypatch.setattr(prestall, "blend_start", lambda m, f: real(m, f) + 6.0)
    chk = prestall.prestall_regression(fitted["data"], fitted["model"])
    assert not chk.passed
    assert (chk.table["status"] == "FAIL").sum() >= 10
    assert float(chk.table["max_state_diff"].max()) > 1e-3


def test_blend_start_is_the_lowest_alpha_l_of_the_flap(fitted: dict[str, Any]) -> None:
    spec = fitted["model"].to_spec()
    for i, f in enumerate(spec["flaps_deg"]):
        want = min(c["alpha_l_deg"][i] for c in spec["coefficients"].values())
        assert prestall.blend_start(fitted["model"], f) == want


def test_replays_are_the_campaign_replay_of_the_recorded_controls(fitted: dict[str, Any]) -> None:
    # the check's qualified time history is campaign.replay of the record's controls from its
    # first state (independent call here)
    data: pl.DataFrame = fitted["data"]
    mid = data["maneuver_id"][0]
    g = data.filter(pl.col("maneuver_id") == mid).sort("t")
    chk = prestall.prestall_regression(g, fitted["model"])
    controls = np.column_stack([g[c].cast(pl.Float64).fill_null(0.0) for c in prestall.CONTROLS])
    ct = np.column_stack([g[c].cast(pl.Float64).fill_null(0.0) for c in prestall.THRUST])
    t = g["t"].to_numpy()
    x = replay(float(g["flap_deg"][0]), record_state(g.row(0, named=True)),
               float(np.median(np.diff(t))), controls, ct)  # fmt: skip
    alpha = np.degrees(np.arctan2(x[:, 2], x[:, 0]))
    np.testing.assert_array_equal(chk.runs[str(mid)]["alpha_qual_deg"].to_numpy(), alpha)


def test_not_the_builtin_aircraft_checks_the_coefficients_only(fitted: dict[str, Any]) -> None:
    data = fitted["data"].drop(BUILTIN_COLUMN)
    chk = prestall.prestall_regression(data, fitted["model"])
    assert "not flown on the built-in ADX-37" in chk.replay_note
    assert chk.table["steps_compared"].is_null().all()
    assert chk.runs == {}
    assert chk.passed  # the coefficients alone still hold
    assert "time histories not compared" in prestall.describe(chk)
