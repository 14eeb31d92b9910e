"""The report's 6-DOF replay on a JSBSim campaign's own aircraft (issue 19 item 5).

Independent references: ``aerodelta.jsbsim_replay.replay_campaign`` called here on its own (the
command ``aerodelta jsbsim-replay``'s path) and the campaign's record files read here; the RMS
differences are recomputed from them. A noise-free quick DHC-6 campaign at flaps 0 and 20 (the
two maneuvers of tests/test_jsbsim_replay.py's DHC-6 fixture) keeps the test short.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import polars as pl
import pytest

pytest.importorskip("jsbsim", reason="needs the jsbsim package: pip install 'aerodelta[jsbsim]'")

from aerodelta.cli import main
from aerodelta.ingest import ingest
from aerodelta.jsbsim_campaign import generate_jsbsim_campaign
from aerodelta.jsbsim_replay import CHANNELS, replay_campaign
from aerodelta.model import DeltaModel
from aerodelta.plots import FigureSink
from aerodelta.report import build_report, replay
from aerodelta.report.context import build_context
from test_jsbsim_replay import _synthetic_model

HELD = "DHC6_004"
STATE_COLUMN = {"V_mps": "tas_mps", "alpha_deg": "alpha_deg", "beta_deg": "beta_deg",
                "theta_deg": "theta_deg", "phi_deg": "phi_deg"}  # fmt: skip


@pytest.fixture(scope="module")
def setup(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, pl.DataFrame, DeltaModel]:
    """(campaign folder, its ingested records, a seeded Δ model fitted "against the columns")."""
    root = tmp_path_factory.mktemp("jsbrep")
    camp = root / "DHC6"
    generate_jsbsim_campaign(camp, aircraft="DHC6", seed=1, size="quick", noise=0.0, only=(0, 4))
    data = ingest(camp).data
    spec = _synthetic_model([0.0, 20.0, 40.0]).to_spec()
    spec["provenance"] = {"qualified": "columns"}
    return camp, data, DeltaModel.from_spec(spec)


def test_report_replays_the_jsbsim_aircraft(
    setup: tuple[Path, pl.DataFrame, DeltaModel], tmp_path: Path
) -> None:
    """The section flies the campaign's qualified and extended aircraft (one straight stall per
    flap), with finite TICs equal to replay_campaign's for the held-out maneuver and RMS
    differences equal to the ones recomputed from its replays and the record file."""
    camp, data, model = setup
    res = build_report(
        model, data, tmp_path / "rep", held_out=[HELD], jsbsim_campaign=camp, workers=0,
        svg=False, replay_count=3,
    )  # fmt: skip
    sec = next(s for s in res.sections if s.key == "replay")
    text = " ".join(str(b) for b in sec.body)
    assert "not run" not in text and "Replay not run" not in text
    rows = sec.tables["replay"]
    # straight stalls first, one per flap (DHC6_000: flap 0 straight; DHC6_004: flap 20 turning)
    assert rows["maneuver_id"].to_list() == ["DHC6_000", HELD]
    assert rows["bounded"].all()
    tic = sec.tables["jsbsim_tic"]
    assert set(tic["window"]) == {"delta", "predictable"}
    assert set(tic["maneuver_id"]) == {HELD, "DHC6_000", "pooled"}
    for c in ("tic_qualified", "tic_extended", "tic_full", "ratio"):
        x = tic[c].to_numpy()
        assert np.isfinite(x).all() and (x > 0).all(), c
    # the Δ acts: the extended aircraft does not fly as the qualified one
    assert (tic["tic_extended"] != tic["tic_qualified"]).all()
    names = [f.name for f in res.figures]
    assert any(n.endswith(f"replay_jsbsim_{HELD}.png") for n in names)
    assert f"JSBSim replay of {HELD}" in res.html.read_text()

    # independent path: the jsbsim-replay function on the held-out maneuver alone
    ref, reps = replay_campaign(camp, model, maneuvers=[HELD], keep_replays=True)
    for window in ("delta", "predictable"):
        for ch in CHANNELS:
            mine = tic.filter(
                (pl.col("maneuver_id") == HELD) & (pl.col("window") == window)
                & (pl.col("channel") == ch)
            )  # fmt: skip
            theirs = ref.filter(
                (pl.col("maneuver_id") == HELD) & (pl.col("window") == window)
                & (pl.col("channel") == ch)
            )  # fmt: skip
            for c in ("tic_qualified", "tic_extended", "tic_full", "t_end_s"):
                assert mine[c][0] == pytest.approx(theirs[c][0], rel=1e-12, abs=0.0), (window, c)
    rec = pl.read_parquet(camp / "records" / f"{HELD}.parquet")
    row = rows.filter(pl.col("maneuver_id") == HELD).row(0, named=True)
    for variant, tag in (("qualified", "qual"), ("extended", "ext")):
        rep = reps.filter(pl.col("variant") == variant)
        assert rep.height == rec.height
        for s, col in STATE_COLUMN.items():
            err = rep[col].to_numpy() - rec[col].to_numpy()
            assert row[f"rms_{s}_{tag}"] == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-12)
    ext = reps.filter(pl.col("variant") == "extended")
    assert row["max_bank_deg_ext"] == pytest.approx(np.max(np.abs(ext["phi_deg"].to_numpy())))


def _section_text(ctx: object, campaign: Path | None) -> str:
    sec = replay.section(ctx, FigureSink(None), count=2, jsbsim_campaign=campaign)  # type: ignore[arg-type]
    assert not sec.tables  # nothing flown
    return " ".join(str(b) for b in sec.body)


def test_refusals_are_one_sentence(
    setup: tuple[Path, pl.DataFrame, DeltaModel],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Without the jsbsim package, for a folder that is no JSBSim campaign, and for another
    campaign's records, the section says so in one sentence and flies nothing."""
    camp, data, model = setup
    ctx = build_context(model, data, held_out=[HELD])
    empty = tmp_path / "empty"
    empty.mkdir()
    text = _section_text(ctx, empty)
    assert text.count("JSBSim replay not run") == 1
    assert "truth.json: missing; give a folder written by aerodelta campaign" in text
    other = tmp_path / "other"
    generate_jsbsim_campaign(other, aircraft="DHC6", seed=2, size="quick", noise=0.0, only=(0, 4))
    text = _section_text(ctx, other)
    assert text.count("JSBSim replay not run") == 1
    assert "differ from the campaign" in text and "(time or airspeed)" in text
    monkeypatch.setitem(sys.modules, "jsbsim", None)  # import jsbsim now raises ImportError
    text = _section_text(ctx, camp)
    assert text.count("JSBSim replay not run") == 1
    assert "the jsbsim package is not installed" in text


def test_cli_option(
    setup: tuple[Path, pl.DataFrame, DeltaModel],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``aerodelta report --jsbsim-campaign DIR`` replays the JSBSim aircraft; a missing folder
    is one error line."""
    camp, _, model = setup
    model.save(tmp_path / "model.json")
    argv = ["report", "--model", str(tmp_path / "model.json"), "--data", str(camp),
            "--held-out", HELD, "--replays", "1", "--no-svg", "--no-progress"]  # fmt: skip
    bad = tmp_path / "nope"
    assert main([*argv, "--out", str(tmp_path / "r0"), "--jsbsim-campaign", str(bad)]) == 1
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert err == [f"aerodelta report: error: --jsbsim-campaign {bad}: folder not found"]
    assert not (tmp_path / "r0").exists()
    assert main([*argv, "--out", str(tmp_path / "r1"), "--jsbsim-campaign", str(camp)]) == 0
    html = (tmp_path / "r1" / "report.html").read_text()
    # one replay: the straight stall first
    assert "JSBSim replay of DHC6_000" in html and "JSBSim replay not run" not in html
