"""A JSBSim campaign's qualified aircraft as the named qualified model (issue 19 item 3).

Independent references: the campaign's ``Cl_sim``, ``Cn_sim``, ``CY_sim`` columns (the qualified
model evaluated from the aircraft's XML in Python by the campaign, not by JSBSim at set states)
and the fit against them (``qualified="columns"``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

pytest.importorskip("jsbsim", reason="needs the jsbsim package: pip install 'aerodelta[jsbsim]'")

from aerodelta.cli import main
from aerodelta.exceptions import AerodeltaError
from aerodelta.fit import FitConfig, fit, model_frame
from aerodelta.ingest import ingest
from aerodelta.jsbsim_campaign import generate_jsbsim_campaign
from aerodelta.plots import FigureSink
from aerodelta.qualified import for_model, resolve
from aerodelta.report import replay
from aerodelta.report.context import build_context
from aerodelta.smoother_match import through_smoother

COEFS = ("Cl", "Cn", "CY")


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The F-15's three quick maneuvers, noise-free (tests/test_jsbsim_replay.py's fixture)."""
    out = tmp_path_factory.mktemp("qj") / "f15"
    generate_jsbsim_campaign(out, aircraft="f15", seed=1, size="quick", noise=0.0)
    return out


def test_jsbsim_qualified_equals_campaign_columns(quick: Path) -> None:
    """At the recorded states (exact sensors, no smoothing) the JSBSim-evaluated qualified
    coefficients equal the campaign's *_sim columns within 1e-12, the F-15 bound of
    tests/test_jsbsim_replay.py::test_qualified_aircraft_equals_campaign_sim (measured 4e-14;
    the F-15 has no propulsion moments, C*_prop_true = 0), in any row order."""
    frame = model_frame(ingest(quick, compat=False, smooth=False).data)
    q = resolve(frame, f"jsbsim:{quick}")
    assert q.source == f"jsbsim:{quick.name}" and not q.differentiable
    assert quick.name in q.description
    got = q.predict(frame)
    for c in COEFS:
        sim = frame[f"{c}_sim"].to_numpy()
        assert np.ptp(sim) > 1e-3, c  # the columns vary: the comparison means something
        assert np.max(np.abs(got[c] - sim)) < 1e-12, c
    shuffled = frame.sample(fraction=1.0, shuffle=True, seed=7)
    got = q.predict(shuffled)
    for c in COEFS:
        assert np.max(np.abs(got[c] - shuffled[f"{c}_sim"].to_numpy())) < 1e-12, c


@pytest.fixture(scope="module")
def f15_clean(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A noise-free F-15 campaign of nine maneuvers (its C_Y has no withheld Δ)."""
    camp = tmp_path_factory.mktemp("qjf") / "f15"
    generate_jsbsim_campaign(camp, aircraft="f15", seed=4, size=3, noise=0.0)
    return camp


def _z(a: pl.DataFrame, b: pl.DataFrame) -> pl.DataFrame:
    """The two fits' summaries joined, identified in both, with |difference| / std_err."""
    key = ["coefficient", "flap_deg", "param", "alpha_lo_deg"]
    assert a.height == b.height
    j = a.join(b, on=key, suffix="_j")
    assert j.height == a.height
    assert (j["identifiable"] == j["identifiable_j"]).all()
    j = j.filter(pl.col("identifiable"))
    return j.with_columns(
        ((pl.col("estimate") - pl.col("estimate_j")).abs() / pl.col("std_err")).alias("z")
    )


def test_fit_against_jsbsim_equals_fit_against_columns(f15_clean: Path) -> None:
    """A fit with qualified='jsbsim:DIR' gives the Δ of qualified='columns' within the
    standard errors: every parameter identified in both, |difference| <= 0.1 standard error
    (measured 0.017, median 7e-4, when written; 0.083 with session 27's selection; on this
    noise-free F-15 campaign of nine maneuvers, where
    the two qualified models differ only by the ingestion's smoothing of the states JSBSim is
    set to: alpha, beta (5e-4 deg), rates, airspeed); the provenance records the campaign.
    With sensor noise (scale 1, same campaign) the difference is up to 9.3 standard errors in
    a few bins below the withhold alpha (dCl_r at 7.8 deg; median 0.19): the columns are the
    qualified model at the true states, JSBSim is evaluated at the measured ones, as the fit's
    regressors are. Both at full band (``smoother_match=False``): the default fit's C_Y residual
    is at rounding level on this campaign (next test), where standard errors of 1e-8 measure
    rounding, not the data."""
    camp = f15_clean
    data = ingest(camp).data
    cfg = FitConfig(smoother_match=False)
    cols = fit(data, qualified="columns", config=cfg)
    jsb = fit(data, qualified=f"jsbsim:{camp}", config=cfg)
    assert jsb.model.to_spec()["provenance"]["qualified"] == "jsbsim:f15"
    j = _z(cols.summary(), jsb.summary())
    assert j.height > 100
    assert j["z"].max() <= 0.1
    # the report named with the campaign as its qualified model replays its JSBSim aircraft
    ctx = build_context(jsb.model, data, qualified=f"jsbsim:{camp}")
    sec = replay.section(ctx, FigureSink(None), count=1)
    tic = sec.tables["jsbsim_tic"]
    assert np.isfinite(tic["tic_extended"].to_numpy()).all()


def test_the_qualified_side_force_seen_through_the_smoother_is_the_measured_one(
    f15_clean: Path,
) -> None:
    """The independent reference is JSBSim: in a noise-free campaign whose C_Y has no Δ, the
    measured C_Y is JSBSim's side force through the ingestion's smoothing. At full band the
    qualified C_Y differs from it by 7.7e-4 rms (the transients the smoother took), through the
    ingestion's own weights (``aerodelta.smoother_match``) by 1.3e-8 (columns) and 8e-8
    (JSBSim at the smoothed states); the default fits then agree on C_l and C_n within 0.2
    standard errors (measured 0.10) and find no C_Y Δ (|estimate| <= 2e-5, measured 8e-6)."""
    data = ingest(f15_clean).data
    frame = model_frame(data)
    meas = frame["CY_meas"].to_numpy()
    for source, full_band, matched in (
        ("columns", 5e-4, 1e-7),
        (f"jsbsim:{f15_clean}", 5e-4, 5e-7),
    ):
        q = resolve(frame, source).predict(frame)
        seen, rep = through_smoother(frame, q)
        assert rep.matched == frame["maneuver_id"].n_unique()
        assert np.sqrt(np.mean((meas - q["CY"]) ** 2)) > full_band
        assert np.sqrt(np.mean((meas - seen["CY"]) ** 2)) < matched
    j = _z(
        fit(data, qualified="columns").summary(),
        fit(data, qualified=f"jsbsim:{f15_clean}").summary(),
    )
    assert j.filter(pl.col("coefficient") != "CY")["z"].max() <= 0.2
    cy = j.filter(pl.col("coefficient") == "CY")
    assert cy.height > 100
    assert max(cy["estimate"].abs().max(), cy["estimate_j"].abs().max()) <= 2e-5


def test_refusals(quick: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A propeller aircraft, a missing folder, missing channels, and 'auto' for a model fitted
    against a JSBSim campaign are refused in one line."""
    frame = model_frame(ingest(quick, compat=False, smooth=False).data)
    dhc6 = tmp_path / "dhc6"
    generate_jsbsim_campaign(dhc6, aircraft="DHC6", seed=1, size="quick", noise=0.0, only=(4,))
    with pytest.raises(AerodeltaError, match=r"has propellers \(Propeller\).*qualified='columns'"):
        resolve(frame, f"jsbsim:{dhc6}")
    with pytest.raises(AerodeltaError, match="no such JSBSim campaign folder"):
        resolve(frame, f"jsbsim:{tmp_path / 'nope'}")
    q = resolve(frame, f"jsbsim:{quick}")
    with pytest.raises(AerodeltaError, match="the records lack psi_deg"):
        q.predict(frame.drop("psi_deg"))
    bad = frame.with_columns(
        pl.when(pl.int_range(pl.len()) == 5).then(None).otherwise(pl.col("h_m")).alias("h_m")
    )
    with pytest.raises(AerodeltaError, match="channel h_m, row 5: not a finite number"):
        q.predict(bad)
    spec = {"provenance": {"qualified": "jsbsim:f15"}}
    with pytest.raises(AerodeltaError, match="campaign f15; name the campaign folder again"):
        for_model(spec, "auto", "unused")
    assert for_model(spec, f"jsbsim:{quick}", "unused") == f"jsbsim:{quick}"
    capsys.readouterr()  # the ingestion's progress above
    argv = ["fit", "--data", str(quick), "--out", str(tmp_path / "m.json"), "--no-progress"]
    assert main([*argv, "--model", f"jsbsim:{tmp_path / 'nope'}"]) == 1
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert err == [
        f"aerodelta fit: error: --model jsbsim:{tmp_path / 'nope'}: folder not found; name a "
        "JSBSim campaign folder (aerodelta campaign --simulator jsbsim)"
    ]
