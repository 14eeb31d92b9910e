"""The validation report on a quick campaign: every section, self-contained HTML, figures on
disk, the diagnosis renderer on a hand-made document, the envelope rule, the replay geometry,
and the effect derivatives against a model with known parameters."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from _report_data import diagnosis_fixture, quick_fit, quick_report
from aerodelta.campaign import record_state, replay, trim
from aerodelta.cli import main
from aerodelta.model import DeltaModel
from aerodelta.plots import FigureSink
from aerodelta.report import ReportResult, build_report
from aerodelta.report import diagnosis as diag
from aerodelta.report.context import ReportContext
from aerodelta.report.effects import derivative
from aerodelta.report.envelope import LEVELS, classify, identified_by_alpha
from aerodelta.report.replay import divergence, states_frame

SECTIONS = ("timehistory", "effects", "params", "replay", "rolloff", "envelope", "diagnosis")


@pytest.fixture(scope="module")
def report() -> ReportResult:
    return quick_report()


def test_report_has_every_section_and_a_summary_first(report: ReportResult) -> None:
    text = report.html.read_text(encoding="utf-8")
    first = text.index('id="summary"')
    for key in SECTIONS:
        assert f'<section id="{key}">' in text, key
        assert text.index(f'<section id="{key}">') > first
    for word in (
        "Theil",
        "held out",
        "FAR 25.203",
        "Part 60",
        "aileron_reversal",
        "Shrink table",
        "Gap map",
        "Table 3.2",
    ):
        assert word in text, word
    assert [s.key for s in report.sections][1:] == list(SECTIONS)


def test_html_is_self_contained(report: ReportResult) -> None:
    text = report.html.read_text(encoding="utf-8")
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*(https?:)?//""", text, re.I)
    assert "<script" not in text.lower()
    assert "<link" not in text.lower()
    assert text.count("data:image/png;base64,") >= 15


def test_figures_are_written_as_png_and_svg(report: ReportResult) -> None:
    pngs = [f for f in report.figures if f.suffix == ".png"]
    svgs = [f for f in report.figures if f.suffix == ".svg"]
    assert len(pngs) == len(svgs) >= 15
    assert all(f.exists() and f.stat().st_size > 1000 for f in report.figures)
    assert pngs[0].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in svgs[0].read_bytes()[:2000]


def test_time_history_metrics_rank_and_score_held_out(report: ReportResult) -> None:
    th = next(s for s in report.sections if s.key == "timehistory")
    per, overall = th.tables["per_maneuver"], th.tables["overall"]
    _, data, _, held = quick_fit()
    assert set(per.filter(pl.col("held_out"))["maneuver_id"]) == set(held)
    assert per["maneuver_id"].n_unique() == data["maneuver_id"].n_unique()
    # the extended model fits better than the qualified one on the maneuvers it was fitted to
    fitted = overall.filter((pl.col("subset") == "fitted") & (pl.col("coefficient") == "Cl"))
    assert fitted["rms_ext"][0] < fitted["rms_qual"][0]


def test_replays_are_bounded(report: ReportResult) -> None:
    rp = next(s for s in report.sections if s.key == "replay").tables["replay"]
    assert rp.height == 2
    assert rp["bounded"].all(), rp
    assert {"rms_alpha_deg_ext", "rms_alpha_deg_qual"} <= set(rp.columns)


def test_replay_with_a_zero_delta_model_is_the_qualified_replay() -> None:
    _, _, res, _ = quick_fit()
    spec = res.model.to_spec()
    for c in spec["coefficients"].values():
        for term in c["terms"]:
            term["values"] = [[0.0] * len(v) for v in term["values"]]
    zero = DeltaModel.from_spec(spec)
    tr = trim(0.0, 70.0, 1000.0)
    n = 200
    ctl = np.tile(tr["controls_deg"], (n, 1))
    ct = np.full((n, 2), tr["ct"])
    base = replay(0.0, tr["state"], 0.01, ctl, ct, rolloff_seed=5)
    ext = replay(0.0, tr["state"], 0.01, ctl, ct, rolloff_seed=5, delta_model=zero)
    np.testing.assert_array_equal(ext, base)
    moved = replay(0.0, tr["state"], 0.01, ctl, ct, rolloff_seed=5, delta_model=res.model)
    assert moved.shape == base.shape and np.isfinite(moved).all()


def test_diagnosis_renderer_reads_the_schema_and_tolerates_gaps(tmp_path: Path) -> None:
    sec = diag.section(diagnosis_fixture(), FigureSink(None))
    eff = sec.tables["effects"]
    assert eff["effect"].to_list() == ["aileron_reversal", "roll_damping_loss"]
    assert eff["shrink_fraction"][0] == pytest.approx(0.5)
    assert sec.tables["where"].height == 16
    body = "".join(sec.body)
    assert body.count("<figure") == 2  # gap map and shrink plot
    assert ("Cl diagnosis", "<b>aileron_reversal</b>") in sec.summary
    bare = diag.section({"schema": diag.SCHEMA, "coefficients": {"CY": {}}}, FigureSink(None))
    assert bare.tables["effects"].height == 0
    p = tmp_path / "d.json"
    p.write_text('{"schema": "other/1"}')
    with pytest.raises(Exception, match=r"aerodelta\.diagnosis/1"):
        diag.load_diagnosis(p)


def test_envelope_rule() -> None:
    n = np.array([0, 5, 20, 20, 100, 100, 100])
    m = np.array([0, 1, 2, 2, 5, 5, 5])
    f = np.array([1, 1, 0.5, 0.3, 0.9, 0.9, np.nan])
    beyond = np.array([False] * 5 + [True, False])
    got = [LEVELS[k] for k in classify(n, m, f, beyond)]
    assert got == ["none", "low", "moderate", "low", "high", "low", "high"]


def test_replay_initial_state_round_trips_the_record_angles() -> None:
    rec = pl.DataFrame(
        {
            "tas_mps": [70.0],
            "alpha_deg": [12.0],
            "beta_deg": [-3.0],
            "p_dps": [1.0],
            "q_dps": [2.0],
            "r_dps": [-1.0],
            "phi_deg": [10.0],
            "theta_deg": [5.0],
            "psi_deg": [30.0],
            "h_m": [2500.0],
        }
    )
    x = np.array([record_state(rec.row(0, named=True))])
    s = states_frame(x, np.array([0.0])).row(0, named=True)
    assert s["V_mps"] == pytest.approx(70.0)
    assert s["alpha_deg"] == pytest.approx(12.0)
    assert s["beta_deg"] == pytest.approx(-3.0)
    assert s["phi_deg"] == pytest.approx(10.0)
    assert x[0, 11] == 2500.0
    ok, _ = divergence(states_frame(np.repeat(x, 3, axis=0), np.arange(3.0)))
    assert ok
    x[0, 6] = math.radians(150.0)  # a large bank alone is no divergence
    assert divergence(states_frame(x, np.array([0.0])))[0] is True
    x[0, 7] = math.radians(88.0)  # theta past 85 deg is
    assert divergence(states_frame(x, np.array([0.0])))[0] is False


def test_effect_derivative_of_a_known_model() -> None:
    # dCl_beta = 0.01 /deg, blended in between 10 and 12 deg: the Δ derivative is w(α) 0.01
    spec = {
        "schema": "aerodelta.model/1",
        "flaps_deg": [0.0],
        "coefficients": {
            "Cl": {
                "terms": [
                    {
                        "name": "dCl_beta",
                        "regressor": "beta_deg",
                        "alpha_deg": [0.0, 30.0],
                        "values": [[0.01, 0.01]],
                    }
                ],
                "alpha_l_deg": [10.0],
                "alpha_u_deg": [12.0],
            }
        },
    }
    model = DeltaModel.from_spec(spec)
    ctx = ReportContext(
        model=model,
        data=pl.DataFrame(),
        params=None,
        coefficients=["Cl"],
        held_out=[],
        qualified="adx37",
    )
    alpha = np.array([5.0, 11.0, 20.0])
    dq, dd = derivative(ctx, "Cl", "beta_deg", 1.0, flap=0.0, alpha=alpha)
    np.testing.assert_allclose(dd, [0.0, 0.005, 0.01], atol=1e-12)
    assert dq is not None and np.all(np.isfinite(dq))


def test_cli_report(tmp_path: Path) -> None:
    # the command on a subset (one flap setting) of the ingested data, ids from a file
    root, data, _, held = quick_fit()
    flap = float(data["flap_deg"].min())
    sub = data.filter(pl.col("flap_deg") == flap)
    sub.write_parquet(tmp_path / "data.parquet")
    ids = sorted(set(held) & set(sub["maneuver_id"].to_list()))
    (tmp_path / "held.txt").write_text("\n".join(ids) + "\n# comment\n")
    rc = main([
        "report", "--model", str(root / "model.json"), "--data", str(tmp_path),
        "--out", str(tmp_path / "out"), "--held-out", f"@{tmp_path / 'held.txt'}",
        "--replays", "1", "--no-svg", "--no-progress",
    ])  # fmt: skip
    assert rc == 0
    html = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert "No diagnosis given" in html
    assert f"flaps {flap:g} deg" in html
    assert not list((tmp_path / "out" / "figures").glob("*.svg"))


def test_load_diagnosis_refuses_binary_and_deep_files_in_one_line(tmp_path: Path) -> None:
    """A binary file or a JSON nested past the parser's depth is a DataError naming the file."""
    b = tmp_path / "d.json"
    b.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ad.DataError, match="not UTF-8") as e:
        diag.load_diagnosis(b)
    assert str(b) in str(e.value) and "\n" not in str(e.value)
    d = tmp_path / "deep.json"
    d.write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(ad.DataError, match="nested too deep") as e:
        diag.load_diagnosis(d)
    assert str(d) in str(e.value)


def test_build_report_reads_its_inputs_before_making_the_folder(tmp_path: Path) -> None:
    """A model file that cannot be read leaves no report folder behind."""
    m = tmp_path / "model.json"
    m.write_text("{not json")
    out = tmp_path / "rep"
    with pytest.raises(ad.AerodeltaError):
        build_report(m, pl.DataFrame({"t": [0.0]}), out)
    assert not out.exists()


def test_a_model_without_provenance_still_builds_its_context() -> None:
    """A model file written by another tool may carry ``"provenance": null``: the report's
    context and the fit summary read it as empty, with the stall alpha unknown, rather than
    crashing on ``None.get``."""
    from aerodelta.model import DeltaModel  # noqa: PLC0415
    from aerodelta.report.context import build_context  # noqa: PLC0415

    _, data, res, held = quick_fit()
    spec = res.model.to_spec()
    spec["provenance"] = None
    bare = DeltaModel.from_spec(spec)
    ctx = build_context(bare, data, held_out=held, qualified="adx37")
    assert ctx.stall_alpha_deg == {}


def test_envelope_pools_each_coefficients_own_bin_in_any_row_order() -> None:
    """The coefficients' bins need not share edges: at each alpha every coefficient adds the
    parameters of its own bin containing it (closed form below), whatever the row order
    (the bins used to be written one over another in the order of a hash grouping)."""
    rows = [
        # coefficient, lo, hi, identifiable flags of the bin's parameters
        ("Cl", 0.0, 4.0, [True, True, False]),
        ("Cl", 4.0, 8.0, [False, False]),
        ("Cn", 0.0, 2.0, [True]),
        ("Cn", 2.0, 8.0, [True, True, True, False]),
        ("CY", 0.0, 4.0, [False]),
        ("CY", 4.0, 6.0, [True, True]),
    ]
    keys = ("coefficient", "flap_deg", "alpha_lo_deg", "alpha_hi_deg", "identifiable")
    records = [(c, 5.0, lo, hi, f) for c, lo, hi, flags in rows for f in flags]
    records.append(("Cl", 0.0, 0.0, 9.0, False))  # another flap: not counted
    params = pl.DataFrame([dict(zip(keys, r, strict=True)) for r in records])
    alpha = np.array([1.0, 3.0, 5.0, 7.0, 9.0])
    want = [(2 + 1 + 0) / 5, (2 + 3 + 0) / 8, (0 + 3 + 2) / 8, (0 + 3) / 6, np.nan]
    for seed in range(5):
        shuffled = params.sample(fraction=1.0, shuffle=True, seed=seed)
        got = identified_by_alpha(shuffled, 5.0, alpha)
        np.testing.assert_array_equal(got, want)
    assert np.isnan(identified_by_alpha(None, 5.0, alpha)).all()
    assert np.isnan(identified_by_alpha(params, 10.0, alpha)).all()
