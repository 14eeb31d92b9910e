"""The withheld-effect suite on JSBSim aircraft (issue 17, item 5): the magnitude option of the
JSBSim campaign, the map from JSBSim terms to the diagnosis vocabulary, the split of a term's
true Δ into vocabulary parts, and one small case end to end through the suite's code."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import polars as pl
import pytest

pytest.importorskip("jsbsim", reason="needs the jsbsim package: pip install 'aerodelta[jsbsim]'")

from aerodelta.diagnosis.withheld import (
    jsbsim_components,
    jsbsim_false_alarms,
    jsbsim_term_effects,
)
from aerodelta.exceptions import InvalidInputError
from aerodelta.jsbsim_campaign import generate_jsbsim_campaign, lateral_terms

ROOT = Path(__file__).resolve().parents[1]


def _suite():
    spec = importlib.util.spec_from_file_location(
        "jsbsim_diagnosis_suite", ROOT / "benchmarks" / "jsbsim_diagnosis_suite.py"
    )
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_withhold_scale_withholds_that_fraction_of_the_change(tmp_path: Path) -> None:
    kw = {"aircraft": "f15", "seed": 4, "size": "quick", "only": [2], "noise": 0.0}
    generate_jsbsim_campaign(tmp_path / "full", withhold="Cnb,Clp", **kw)
    generate_jsbsim_campaign(tmp_path / "half", withhold="Cnb,Clp", withhold_scale=0.5, **kw)
    (rec_f,) = (tmp_path / "full" / "records").glob("*.parquet")
    rec_h = tmp_path / "half" / "records" / rec_f.name
    a, b = pl.read_parquet(rec_f), pl.read_parquet(rec_h)
    tf = pl.read_parquet(tmp_path / "full" / "truth" / rec_f.name)
    th = pl.read_parquet(tmp_path / "half" / "truth" / rec_f.name)
    # the same flight; only the qualified model differs, by half the withheld change
    sim = ["Cl_sim", "Cn_sim", "CY_sim"]
    assert a.drop(sim).equals(b.drop(sim))
    assert float(tf["dCn_true"].abs().max()) > 1e-3  # the stall reaches past 12 deg
    for c in ("Cl", "Cn"):
        total = tf[f"{c}_true"] + tf[f"{c}_prop_true"]
        np.testing.assert_allclose(th[f"d{c}_true"], 0.5 * tf[f"d{c}_true"], rtol=1e-12, atol=0)
        np.testing.assert_allclose(b[f"{c}_sim"], total - 0.5 * tf[f"d{c}_true"], atol=1e-15)
    jf = json.loads((tmp_path / "full" / "truth" / "truth.json").read_text())
    jh = json.loads((tmp_path / "half" / "truth" / "truth.json").read_text())
    assert jh["withhold_scale"] == 0.5
    df = np.asarray(jf["withheld"][0]["derivatives"]["0"]["beta_deg"]["delta"])
    dh = np.asarray(jh["withheld"][0]["derivatives"]["0"]["beta_deg"]["delta"])
    np.testing.assert_allclose(dh, 0.5 * df, rtol=1e-12)
    with pytest.raises(InvalidInputError, match="withhold_scale"):
        generate_jsbsim_campaign(tmp_path / "bad", withhold="Cnb", withhold_scale=-1.0, **kw)


def test_jsbsim_terms_map_to_the_vocabulary() -> None:
    f15 = jsbsim_term_effects(lateral_terms("f15"))
    assert f15["Clb"] == {"Cl": "dihedral"}
    assert f15["Cnb"] == {"Cn": "directional_stability"}
    assert f15["Clp"] == {"Cl": "roll_damping"}
    assert f15["Cnr"] == {"Cn": "yaw_damping"}
    assert f15["Cnp"] == {"Cn": "yaw_due_to_roll_rate"}
    assert f15["ClDa"] == {"Cl": "aileron_effectiveness"}
    assert f15["Cndr"] == {"Cn": "rudder_effectiveness"}
    # a side-force term moves C_l and C_n through the arm to the aero reference point
    assert f15["CYb"] == {"CY": "sideforce_beta", "Cl": "dihedral", "Cn": "directional_stability"}
    # C_Y has no aileron effect in the vocabulary: out-of-list
    assert f15["CYda"]["CY"] is None
    dhc6 = jsbsim_term_effects(lateral_terms("DHC6"))
    assert dhc6["CYp"]["CY"] is None and dhc6["CYr"]["CY"] is None


def test_components_split_a_table_nonlinear_in_sideslip() -> None:
    # a Δ = 0.01 + 0.002 beta + 0.0005 beta^2 in one alpha bin: the projection on [1, beta]
    # gives the intercept to lateral_asymmetry, the slope to dihedral, and leaves the
    # quadratic's part orthogonal to [1, beta] as the out-of-list rest
    rng = np.random.default_rng(2)
    beta = rng.uniform(-8, 8, 4000)
    d = 0.01 + 0.002 * beta + 0.0005 * beta**2
    truth = pl.DataFrame(
        {
            "alpha_deg": np.full(beta.size, 14.5),
            "flap_deg": np.zeros(beta.size),
            "beta_deg": beta,
            "phat": np.zeros(beta.size),
            "rhat": np.zeros(beta.size),
            "dterm_Clb": d,
            "dCl_true": d,
            "dCn_true": np.zeros(beta.size),
            "dCY_true": np.zeros(beta.size),
        }
    )
    comps = jsbsim_components(truth, {"Clb": 1.0}, {"Clb": {"Cl": "dihedral"}}, {"Clb": "ROLL"})
    x = np.column_stack([np.ones_like(beta), beta, beta**2])
    q = x[:, :2]
    fit = q @ np.linalg.lstsq(q, d, rcond=None)[0]
    np.testing.assert_allclose(comps["dihedral"]["Cl"] + comps["lateral_asymmetry"]["Cl"], fit)
    np.testing.assert_allclose(comps["unlisted:Clb"]["Cl"], d - fit, atol=1e-12)
    assert np.std(comps["dihedral"]["Cl"] / beta) < 1e-9  # a pure slope times beta
    assert float(np.sum(comps["unlisted:Clb"]["Cl"] ** 2)) > 0.05 * float(np.sum(d**2))


def test_one_f15_case_end_to_end(tmp_path: Path) -> None:
    """A withheld Cnb at full size on the F-15 (seed 7, 4 maneuvers per entry kind) is named
    directional stability on C_n, with no false alarm; the scoring reads the truth."""
    suite = _suite()
    case = suite.Case("singles", {"Cnb": 1.0}, 7, label="Cnb x1")
    r = suite.run_case("f15", case, size=4, workdir=str(tmp_path))
    assert r.affected.get("directional_stability") == ["Cn"]
    assert r.right_top == {"Cn": "directional_stability"}
    assert r.found == {"top": True}
    assert r.false_alarms == []
    assert r.shrink_ratio["Cn"] > 0.8
    s = suite.summarize([r])
    assert s["singles_top"] == {"design": "1/1"}


def test_false_alarm_rule_follows_the_virtual_suite() -> None:
    # a withheld part found below the 3 % share is not a false alarm; another effect on a
    # coefficient the part barely touches is (and "untouched" only where nothing moves it);
    # an effect where only an out-of-list part acts is a misattribution
    shares = {
        "sideforce_beta": {"CY": 0.016, "Cl": 0.001},
        "unlisted:Clb": {"Cn": 0.2},
    }
    sig = {
        "CY": ["sideforce_beta", "rudder_effectiveness"],
        "Cl": ["roll_damping"],
        "Cn": ["directional_stability"],
    }
    fa, untouched, mis = jsbsim_false_alarms(sig, {}, shares)
    assert fa == ["CY:rudder_effectiveness", "Cl:roll_damping"]
    assert untouched == ["Cl:roll_damping"]
    assert mis == ["Cn:directional_stability"]
    # a rival reported ambiguous with a withheld part is not a confident wrong answer
    fa, _, _ = jsbsim_false_alarms(sig, {"CY:rudder_effectiveness": ["sideforce_beta"]}, shares)
    assert fa == ["Cl:roll_damping"]


def test_time_skew_named_on_a_null_with_late_rates_is_not_a_false_alarm() -> None:
    """A null whose recorded rates are late holds a real timing error: naming time_skew is the
    right answer there, and a false alarm where the rates are not late; anything else named
    stays a false alarm either way."""
    sig = {"Cl": ["time_skew"], "Cn": ["time_skew", "sideslip_rate"], "CY": []}
    fa, _, _ = jsbsim_false_alarms(sig, {}, {})
    assert fa == ["Cl:time_skew", "Cn:time_skew", "Cn:sideslip_rate"]
    fa, _, _ = jsbsim_false_alarms(sig, {}, {}, timing_lag=True)
    assert fa == ["Cn:sideslip_rate"]
