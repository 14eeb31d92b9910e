"""The extended model (qualified + blended Δ, thesis Eq. 3.12) exported to DAVE-ML and JSBSim
equals the engine: the engine's ADX-37 qualified model (``aero_core::aircraft``) plus
``aero_core::delta_model`` at random states, checked by reading the DAVE-ML file back and by
evaluating the JSBSim functions inside JSBSim itself (the ``jsbsim`` package)."""

from __future__ import annotations

import itertools
import math
import re
import shutil
from pathlib import Path
from typing import Any

import jsbsim
import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from _jsbsim_fixture import driven
from _jsbsim_fixture import load_with_stall as _load_with_stall
from aerodelta import _core
from aerodelta.cli import main
from aerodelta.daveml import write_example_model
from aerodelta.export import export_extended_daveml, extended_daveml_text
from aerodelta.fit import DEFAULT_STRUCTURES
from aerodelta.jsbsim import (
    DEFAULT_PROPERTIES,
    export_jsbsim,
    jsbsim_stall_system_xml,
    jsbsim_xml,
)
from aerodelta.model import DeltaModel

FIXTURE = Path(__file__).parent / "data" / "jsbsim" / "aircraft" / "aerodelta_fixture"
FLAPS = [0.0, 10.0, 20.0]


def synthetic_model(flaps: list[float] = FLAPS, extra: bool = False) -> DeltaModel:
    """Every default structure term with seeded random tables; blend limits vary per flap,
    one flap with alpha_l == alpha_u (a step). ``extra`` adds terms using every regressor
    function."""
    rng = np.random.default_rng(7)
    coefs: dict[str, Any] = {}
    for c, terms in DEFAULT_STRUCTURES.items():
        ts = list(terms)
        if extra and c == "Cl":
            ts += [
                ("dCl_f1", "pos(beta_deg - 2) + neg(da_deg) * step(rhat)"),
                ("dCl_f2", "-min(phat, 0.01) / 2 + max(dr_deg, -1) ^ 2"),
                ("dCl_f3", "abs(beta_deg) * sqrt(abs(rhat)) + sin(phat) - cos(rhat) * exp(phat)"),
            ]
        out = []
        for name, reg in ts:
            alpha = np.sort(np.concatenate([[-4.0, 24.0], rng.uniform(-3.0, 23.0, 9)]))
            scale = 0.001 if reg != "1" else 0.01
            out.append(
                {"name": name, "regressor": reg, "alpha_deg": alpha.tolist(),
                 "values": (scale * rng.normal(size=(len(flaps), alpha.size))).tolist()}
            )  # fmt: skip
        lo = [8.0 + 0.5 * k for k in range(len(flaps))]
        hi = [v + (0.0 if k == 1 else 2.0 + k) for k, v in enumerate(lo)]
        coefs[c] = {"terms": out, "alpha_l_deg": lo, "alpha_u_deg": hi}
    return DeltaModel.from_spec(
        {"schema": "aerodelta.model/1", "flaps_deg": flaps, "coefficients": coefs}
    )


def random_states(n: int, seed: int = 1, flaps: list[float] = FLAPS) -> dict[str, np.ndarray]:
    """States spread over and beyond the tables, flaps at and between settings."""
    rng = np.random.default_rng(seed)
    return {
        "alpha_deg": rng.uniform(-8.0, 30.0, n),
        "flap_deg": rng.choice([*flaps, 5.0, 13.0, -3.0, flaps[-1] + 4.0], n),
        "beta_deg": rng.uniform(-15.0, 15.0, n),
        "phat": rng.normal(0.0, 0.02, n),
        "qhat": rng.normal(0.0, 0.01, n),
        "rhat": rng.normal(0.0, 0.02, n),
        "alphadot_dps": rng.uniform(-10.0, 10.0, n),
        "betadot_dps": rng.uniform(-10.0, 10.0, n),
        "da_deg": rng.uniform(-20.0, 20.0, n),
        "de_deg": rng.uniform(-10.0, 10.0, n),
        "dr_deg": rng.uniform(-20.0, 20.0, n),
        "dsl_deg": np.where(rng.random(n) < 0.5, rng.uniform(0.0, 30.0, n), 0.0),
        "dsr_deg": np.where(rng.random(n) < 0.5, rng.uniform(0.0, 30.0, n), 0.0),
        "ct_left": rng.uniform(0.0, 0.6, n),
        "ct_right": rng.uniform(0.0, 0.6, n),
        "tas_mps": rng.uniform(50.0, 110.0, n),
    }


def engine_delta(model: DeltaModel, s: dict[str, np.ndarray]) -> pl.DataFrame:
    """The engine's Δ with derived channels computed here (as ``aerodelta.preprocess``)."""
    frame = pl.DataFrame(
        {**s, "ct_diff": s["ct_left"] - s["ct_right"], "ds_deg": s["dsr_deg"] - s["dsl_deg"]}
    )
    return model.evaluate(frame)


@pytest.fixture(scope="module")
def model() -> DeltaModel:
    return synthetic_model()


@pytest.fixture(scope="module")
def fitted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A model written by ``aerodelta fit`` (through the quick demo)."""
    out = tmp_path_factory.mktemp("demo")
    assert main(["demo", "--quick", "--out", str(out)]) == 0
    return out / "model.json"


def test_daveml_equals_engine_qualified_plus_blended_delta(model: DeltaModel, tmp_path: Path):
    out = export_extended_daveml(tmp_path / "ext.dml", model)
    assert out.max_rel_error <= 1e-12
    checks = ad.check_daveml(tmp_path / "ext.dml")
    assert checks["pass"].all() and checks.filter(pl.col("kind") == "output").height > 100
    # The check cases cover the blend ramp, both sides of it and flaps between settings, all
    # inside the flown envelope (issue 19: beyond the tables' alphas and the model's flaps the
    # file holds edge values no flight supports; those states are verified, not published).
    dave = ad.load_daveml(tmp_path / "ext.dml")
    shots = [s for s in checks["shot"].unique().to_list()]
    assert any("flap 5," in s for s in shots) and any("in blend" in s for s in shots)
    assert not any("beyond tables" in s for s in shots)
    flaps = model.to_spec()["flaps_deg"]
    shot_flaps = [float(re.search(r"flap (-?[\d.]+)", s).group(1)) for s in shots]
    assert min(flaps) <= min(shot_flaps) and max(shot_flaps) <= max(flaps)
    s = random_states(4000)
    got = dave.evaluate(
        {
            "alpha_deg": s["alpha_deg"], "beta_rad": np.radians(s["beta_deg"]),
            "phat": s["phat"], "qhat": s["qhat"], "rhat": s["rhat"], "alphadot_hat": 0.0,
            "alphadot_dps": s["alphadot_dps"], "betadot_dps": s["betadot_dps"],
            "de_rad": np.radians(s["de_deg"]), "da_deg": s["da_deg"], "dr_deg": s["dr_deg"],
            "dsl_deg": s["dsl_deg"], "dsr_deg": s["dsr_deg"], "flap_deg": s["flap_deg"],
            "ct_left": s["ct_left"], "ct_right": s["ct_right"],
        },
        outputs=["Cl_ext", "Cn_ext", "CY_ext", "w_Cl", "dCl"],
    )  # fmt: skip
    cl, cn, cy = _core.qualified_lateral_adx37(
        {**{k: np.ascontiguousarray(v) for k, v in s.items()}, "alphadot_dps": np.zeros(4000)}
    )
    d = engine_delta(model, s)
    w = d["w_Cl"].to_numpy()
    assert ((w > 0) & (w < 1)).sum() > 50 and (w == 0).any() and (w == 1).any()
    for c, q in (("Cl", cl), ("Cn", cn), ("CY", cy)):
        want = q + d[f"d{c}_blended"].to_numpy()
        np.testing.assert_allclose(got[f"{c}_ext"].to_numpy(), want, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(got["w_Cl"].to_numpy(), w, rtol=0, atol=1e-15)


def test_daveml_user_qualified_file_with_mapping(tmp_path: Path) -> None:
    base = tmp_path / "example.dml"
    write_example_model(base)  # names its rates p_hat, r_hat
    model = synthetic_model()
    out = extended_daveml_text(model, base, channel_map={"phat": "p_hat", "rhat": "r_hat"})
    dave = ad.DaveModel.from_string(out.text, "merged")
    assert dave.run_checks()["pass"].all()
    assert {"p_hat", "beta_deg", "ct_left", "dsl_deg"} <= set(dave.inputs)
    assert "phat" not in dave.inputs  # computed from p_hat
    s = random_states(500, seed=3)
    inputs = {
        k: s[k]
        for k in ("alpha_deg", "beta_deg", "da_deg", "dr_deg", "flap_deg", "ct_left", "ct_right",
                  "dsl_deg", "dsr_deg", "alphadot_dps", "betadot_dps")
    } | {"p_hat": s["phat"], "r_hat": s["rhat"]}  # fmt: skip
    got = dave.evaluate(inputs, outputs=["Cl_ext", "Cn_ext", "CY_ext"])
    qual = ad.DaveModel(base).evaluate(
        {k: inputs[k] for k in ("alpha_deg", "beta_deg", "p_hat", "r_hat", "da_deg", "dr_deg")}
    )
    d = engine_delta(model, s)
    for c in ("Cl", "Cn", "CY"):
        want = qual[c].to_numpy() + d[f"d{c}_blended"].to_numpy()
        np.testing.assert_allclose(got[f"{c}_ext"].to_numpy(), want, rtol=1e-12, atol=1e-15)


def test_daveml_errors_name_the_problem(tmp_path: Path) -> None:
    base = tmp_path / "example.dml"
    write_example_model(base)
    with pytest.raises(ad.DataError, match=r"no variable 'Cl_total' for coefficient Cl"):
        extended_daveml_text(synthetic_model(), base, coefficients={"Cl": "Cl_total"})


def test_every_regressor_function_single_flap(tmp_path: Path) -> None:
    """DAVE-ML MathML and JSBSim forms of pos, neg, step, min, max, ^, /, unary minus, abs,
    sqrt, sin, cos, exp; a model of one flap setting (JSBSim tables padded)."""
    model = synthetic_model(flaps=[10.0], extra=True)
    out = extended_daveml_text(model)
    assert out.max_rel_error <= 1e-12
    jsb = _load_jsbsim(tmp_path, jsbsim_xml(model, _TEST_PROPS))
    s = random_states(40, seed=5, flaps=[10.0])
    _compare_jsbsim(jsb, model, s)


# -- JSBSim -------------------------------------------------------------------------------

_TEST_PROPS = {ch: f"test/{ch}" for ch in DEFAULT_PROPERTIES}


def _load_jsbsim(tmp: Path, xml: str) -> Any:
    root = tmp / "jsbsim"
    dest = root / "aircraft" / "aerodelta_fixture"
    dest.mkdir(parents=True)
    shutil.copy(FIXTURE / "aerodelta_fixture.xml", dest)
    (dest / "delta.xml").write_text(xml)
    fdm = jsbsim.FGFDMExec(str(root))
    fdm.set_debug_level(0)
    assert fdm.load_model("aerodelta_fixture")
    return fdm


def _compare_jsbsim(fdm: Any, model: DeltaModel, s: dict[str, np.ndarray]) -> None:
    n = len(s["alpha_deg"])
    want = engine_delta(model, s)
    for c in model.coefficients:
        got = {"delta": [], "w": [], "delta-blended": []}
        for i in range(n):
            for ch in DEFAULT_PROPERTIES:
                if ch in s:
                    fdm[f"test/{ch}"] = float(s[ch][i])
            for k, vals in got.items():
                vals.append(fdm[f"aero/aerodelta/{c}/{k}"])
        np.testing.assert_allclose(got["delta"], want[f"d{c}"], rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(got["w"], want[f"w_{c}"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            got["delta-blended"], want[f"d{c}_blended"], rtol=1e-9, atol=1e-14
        )


def test_jsbsim_functions_equal_engine(model: DeltaModel, tmp_path: Path) -> None:
    """The exported functions evaluated by JSBSim (FGFunction/FGTable) at states set on the
    property tree, against ``aero_core``."""
    fdm = _load_jsbsim(tmp_path, jsbsim_xml(model, _TEST_PROPS))
    _compare_jsbsim(fdm, model, random_states(300, seed=11))


def test_jsbsim_default_properties_in_a_flying_state(fitted: Path, tmp_path: Path) -> None:
    """Default property names: JSBSim's own alpha, beta, p b/2V, r b/2V and qbar after its
    initial conditions; the axis moments equal qbar S b w ΔC of the engine."""
    model = DeltaModel.load(fitted)
    export_jsbsim(tmp_path / "delta.xml", model)
    fdm = _load_jsbsim(tmp_path, (tmp_path / "delta.xml").read_text())
    rows = []
    for alpha, beta, flap, p, r, da in [
        (4.0, 2.0, 0.0, 0.05, -0.02, 3.0),
        (9.0, -4.0, 7.5, -0.1, 0.04, -6.0),
        (14.0, 6.0, 15.0, 0.2, 0.1, 12.0),
        (19.0, -8.0, 35.0, -0.05, 0.0, -3.0),
    ]:
        fdm["ic/vt-kts"] = 120.0
        fdm["ic/h-sl-ft"] = 5000.0
        fdm["ic/alpha-deg"] = alpha
        fdm["ic/beta-deg"] = beta
        fdm["ic/p-rad_sec"] = p
        fdm["ic/r-rad_sec"] = r
        fdm["aerodelta/da-deg"] = da
        fdm["aerodelta/ct-left"] = 0.2
        fdm["aerodelta/ct-right"] = 0.1
        fdm["fcs/flap-pos-deg"] = flap
        assert fdm.run_ic()
        fdm["fcs/flap-pos-deg"] = flap
        st = {
            "alpha_deg": fdm["aero/alpha-deg"], "beta_deg": fdm["aero/beta-deg"],
            "flap_deg": fdm["fcs/flap-pos-deg"],
            "phat": fdm["velocities/p-aero-rad_sec"] * fdm["aero/bi2vel"],
            "rhat": fdm["velocities/r-aero-rad_sec"] * fdm["aero/bi2vel"],
            "alphadot_dps": fdm["aero/alphadot-deg_sec"],
            "betadot_dps": fdm["aero/betadot-deg_sec"], "da_deg": da, "dr_deg": 0.0,
            "dsl_deg": 0.0, "dsr_deg": 0.0, "ct_left": 0.2, "ct_right": 0.1,
        }  # fmt: skip
        assert abs(st["alpha_deg"] - alpha) < 1e-6 and abs(st["phat"]) > 0
        qsb = fdm["aero/qbar-psf"] * fdm["metrics/Sw-sqft"] * fdm["metrics/bw-ft"]
        rows.append(
            st | {"roll": fdm["aero/moment/aerodelta-Cl"] / qsb,
                  "yaw": fdm["aero/moment/aerodelta-Cn"] / qsb,
                  "side": fdm["aero/force/aerodelta-CY"] * fdm["metrics/bw-ft"] / qsb}
        )  # fmt: skip
    df = pl.DataFrame(rows)
    d = engine_delta(model, {k: df[k].to_numpy() for k in df.columns})
    np.testing.assert_allclose(df["roll"], d["dCl_blended"], rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(df["yaw"], d["dCn_blended"], rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(df["side"], d["dCY_blended"], rtol=1e-9, atol=1e-14)
    assert np.abs(d["dCl_blended"].to_numpy()).max() > 1e-4


def test_cli_export_of_a_fitted_model(fitted: Path, tmp_path: Path, capsys) -> None:
    dml, xml = tmp_path / "ext.dml", tmp_path / "ext.xml"
    args = ["export", "--model", str(fitted), "--daveml", str(dml), "--jsbsim", str(xml)]
    assert main([*args, "--property", "da_deg=-1*fcs/left-aileron-pos-deg"]) == 0
    captured = capsys.readouterr()
    text = captured.out
    assert "Cl_ext" in text and "da_deg" in text and "fcs/left-aileron-pos-deg" in text
    # the channels left on declared properties are named, the mapped one is not
    used = set(ad.DeltaModel.load(fitted).input_columns) & set(DEFAULT_PROPERTIES)
    declared = {
        DEFAULT_PROPERTIES[c] for c in used if DEFAULT_PROPERTIES[c].startswith("aerodelta/")
    }
    warned = captured.err
    assert "warning" in warned and "fcs/left-aileron-pos-deg" not in warned
    assert len(declared - {"aerodelta/da-deg"}) >= 1
    for p in sorted(declared - {"aerodelta/da-deg"}):
        assert p in warned, (p, warned)
    assert "aerodelta/da-deg" not in warned
    # every channel on a property of the aircraft's own: nothing left to warn about
    inputs = sorted(ad.DeltaModel.load(fitted).input_columns)
    mapped = [f"--property={c}=fcs/x-{i}" for i, c in enumerate(inputs)]
    assert main([*args, *mapped]) == 0
    assert "warning" not in capsys.readouterr().err
    assert main(["check-daveml", str(dml)]) == 0
    assert '<axis name="ROLL">' in xml.read_text()
    assert main([*args, "--jsbsim-qualified", "--side-axis", "Y"]) == 0
    assert "aero/aerodelta/Cl/qualified" in xml.read_text()
    assert '<axis name="Y">' in xml.read_text()
    assert not list(tmp_path.glob("*.tmp-*"))
    assert main(["export-qualified", str(tmp_path / "q.dml")]) == 0
    q = tmp_path / "q.dml"
    assert (
        main(["export", "--model", str(fitted), "--qualified", str(q), "--daveml", str(dml)]) == 0
    )


def test_jsbsim_body_axis_side_force_and_moments(fitted: Path, tmp_path: Path) -> None:
    """With ``side_axis="Y"`` JSBSim's total body-axis aero force and moments (only the export's
    functions act on the fixture; AERORP at the CG) equal qbar S (b) w ΔC of the engine."""
    model = DeltaModel.load(fitted)
    fdm = _load_jsbsim(tmp_path, jsbsim_xml(model, side_axis="Y"))
    fdm["ic/vt-kts"], fdm["ic/h-sl-ft"] = 110.0, 3000.0
    fdm["ic/alpha-deg"], fdm["ic/beta-deg"], fdm["ic/p-rad_sec"] = 16.0, 5.0, 0.1
    fdm["aerodelta/dr-deg"] = 4.0
    fdm["fcs/flap-pos-deg"] = 10.0
    assert fdm.run_ic()
    st = {
        "alpha_deg": [fdm["aero/alpha-deg"]], "beta_deg": [fdm["aero/beta-deg"]],
        "flap_deg": [10.0], "phat": [fdm["velocities/p-aero-rad_sec"] * fdm["aero/bi2vel"]],
        "rhat": [fdm["velocities/r-aero-rad_sec"] * fdm["aero/bi2vel"]],
        "alphadot_dps": [fdm["aero/alphadot-deg_sec"]],
        "betadot_dps": [fdm["aero/betadot-deg_sec"]], "da_deg": [0.0], "dr_deg": [4.0],
        "dsl_deg": [0.0], "dsr_deg": [0.0], "ct_left": [0.0], "ct_right": [0.0],
    }  # fmt: skip
    d = engine_delta(model, {k: np.asarray(v) for k, v in st.items()})
    qs = fdm["aero/qbar-psf"] * fdm["metrics/Sw-sqft"]
    b = fdm["metrics/bw-ft"]
    assert qs > 0
    np.testing.assert_allclose(fdm["forces/fby-aero-lbs"], qs * d["dCY_blended"][0], rtol=1e-9)
    np.testing.assert_allclose(fdm["moments/l-aero-lbsft"], qs * b * d["dCl_blended"][0], rtol=1e-9)
    np.testing.assert_allclose(fdm["moments/n-aero-lbsft"], qs * b * d["dCn_blended"][0], rtol=1e-9)


def test_jsbsim_with_the_qualified_model(model: DeltaModel, tmp_path: Path) -> None:
    """``qualified=True``: the ADX-37 qualified CY, Cl, Cn (2-D and 3-D tables, clamped
    sideslip and thrust coefficients) evaluated by JSBSim equal the engine's
    (``aero_core::aircraft``) less the thrust's own yaw moment, the lever arm y/b times the
    thrust difference, which JSBSim's propulsion applies (issue 19: it was counted twice),
    and the extended coefficient is qualified + w ΔC."""
    fdm = _load_jsbsim(tmp_path, jsbsim_xml(model, _TEST_PROPS, qualified=True))
    n = 200
    s = random_states(n, seed=13)
    s["beta_deg"] = np.random.default_rng(2).uniform(-50.0, 50.0, n)  # beyond the 40 deg clamp
    s["ct_left"] = np.random.default_rng(3).uniform(-0.3, 1.8, n)
    s["beta_rad"] = np.radians(s["beta_deg"])
    cols = {k: np.ascontiguousarray(v) for k, v in s.items() if k != "beta_rad"}
    cl, cn, cy = _core.qualified_lateral_adx37({**cols, "alphadot_dps": np.zeros(n)})
    # the lever arm of docs/aircraft.md: engines at y = ±4.1 m on the 25.91 m span
    arm = 4.1 / 25.91
    ct = np.clip(s["ct_left"], -0.1, 1.5) - np.clip(s["ct_right"], -0.1, 1.5)
    cn = cn - arm * ct
    d = engine_delta(model, s)
    got: dict[str, list[float]] = {f"{c}/{k}": [] for c in model.coefficients
                                   for k in ("qualified", "extended")}  # fmt: skip
    for i in range(n):
        for ch in DEFAULT_PROPERTIES:
            if ch in s:
                fdm[f"test/{ch}"] = float(s[ch][i])
        for k, vals in got.items():
            vals.append(fdm[f"aero/aerodelta/{k}"])
    for c, q in (("Cl", cl), ("Cn", cn), ("CY", cy)):
        np.testing.assert_allclose(got[f"{c}/qualified"], q, rtol=1e-9, atol=1e-14)
        want = q + d[f"d{c}_blended"].to_numpy()
        np.testing.assert_allclose(got[f"{c}/extended"], want, rtol=1e-9, atol=1e-14)


def test_jsbsim_functions_have_no_one_argument_sums(model: DeltaModel) -> None:
    """JSBSim warns that a ``<sum>`` or ``<product>`` of one argument is a no-op: the export
    writes the argument alone (a one-term Δ, and the qualified model's single-term sums)."""
    import xml.etree.ElementTree as ET  # noqa: PLC0415

    spec = model.to_spec()
    first = next(iter(spec["coefficients"]))
    spec["coefficients"][first]["terms"] = spec["coefficients"][first]["terms"][:1]
    one = DeltaModel.from_spec(spec, "one term")
    for m in (model, one):
        for qualified in (False, True):
            root = ET.fromstring(jsbsim_xml(m, _TEST_PROPS, qualified=qualified))
            for tag in ("sum", "product"):
                for el in root.iter(tag):
                    assert len(list(el)) >= 2, (tag, ET.tostring(el)[:200])


def _with_envelope(model: DeltaModel, flaps: list[float], bands: list[list[tuple]]) -> DeltaModel:
    """``model`` with a hand-built validated envelope (1-deg bands; ``(band, beta_min,
    beta_max)`` per covered band of each flap setting)."""
    spec = model.to_spec()
    spec["envelope"] = {
        "band_deg": 1.0,
        "flaps_deg": flaps,
        "min_maneuvers": 5,
        "bands": [
            [{"band": b, "beta_min_deg": lo, "beta_max_deg": hi, "maneuvers": 5}
             for b, lo, hi in per]
            for per in bands
        ],
    }  # fmt: skip
    return DeltaModel.from_spec(spec, "with envelope")


def _envelope_states(seed: int, flaps: list[float]) -> dict[str, np.ndarray]:
    """Random states, band edges (alpha an exact multiple of the band, and just below), the
    flaps' midpoints (a tie goes to the lower setting) and sideslips at a band's limits."""
    rng = np.random.default_rng(seed)
    n = 400
    s = random_states(n, seed=seed, flaps=flaps)
    s["alpha_deg"] = rng.uniform(-3.0, 22.0, n)
    s["beta_deg"] = rng.uniform(-9.0, 9.0, n)
    s["alpha_deg"][:100] = rng.integers(-3, 28, 100).astype(float)  # band edges
    s["alpha_deg"][100:150] = rng.integers(-3, 28, 50) - 1e-9
    s["beta_deg"][150:200] = rng.choice([-6.0, -5.0, 4.0, 5.0, 8.0, -8.0], 50)
    mids = [0.5 * (a + b) for a, b in itertools.pairwise(flaps)] or flaps
    s["flap_deg"][200:260] = rng.choice(mids, 60)
    return s


def test_jsbsim_in_envelope_flag_equals_engine(model: DeltaModel, tmp_path: Path) -> None:
    """``aero/aerodelta/in-envelope`` evaluated by JSBSim against ``DeltaModel.in_envelope``
    (``aero_core::envelope``): holes between covered bands, bands below zero alpha, a flap
    setting with no covered band, ties between flap settings, a one-flap envelope; a model
    without an envelope has no flag."""
    assert "in-envelope" not in jsbsim_xml(model, _TEST_PROPS)
    cases = [
        (
            FLAPS,
            [
                [
                    (-2, -3.0, 3.0),
                    *[(b, -6.0, 6.0) for b in range(-1, 4)],
                    (5, -5.0, 5.0),
                    *[(b, -8.0, 8.0) for b in (6, 7)],
                    (8, -5.0, 5.0),
                    (9, -6.0, 4.0),
                    (11, -2.0, 8.0),
                    (12, -8.0, 8.0),
                ],
                [],
                [
                    (5, -1.0, 1.0),
                    (6, -5.0, 5.0),
                    *[(b, -7.0, 7.0) for b in range(8, 20)],
                    (20, -4.0, 4.0),
                ],
            ],
        ),
        ([10.0], [[*[(b, -6.0, 6.0) for b in range(0, 5)], (7, -8.0, 4.0), (8, -5.0, 5.0)]]),
    ]
    for k, (flaps, bands) in enumerate(cases):
        m = _with_envelope(model, flaps, bands)
        fdm = _load_jsbsim(tmp_path / f"case{k}", jsbsim_xml(m, _TEST_PROPS))
        s = _envelope_states(k + 1, flaps)
        want = m.in_envelope(
            pl.DataFrame({c: s[c] for c in ("flap_deg", "alpha_deg", "beta_deg")})
        ).to_numpy()
        got = []
        for i in range(len(s["alpha_deg"])):
            for ch in DEFAULT_PROPERTIES:
                if ch in s:
                    fdm[f"test/{ch}"] = float(s[ch][i])
            got.append(fdm["aero/aerodelta/in-envelope"])
        assert 40 <= want.sum() <= len(want) - 40, want.sum()  # both answers are exercised
        np.testing.assert_array_equal(np.asarray(got) == 1.0, want)
        assert set(got) <= {0.0, 1.0}


def test_daveml_in_envelope_flag_equals_engine(model: DeltaModel) -> None:
    """The DAVE-ML export's ``in_envelope`` output (MathML ``piecewise``) read back by the
    DAVE-ML engine against ``DeltaModel.in_envelope``, at the sideslip the file computes from
    the qualified model's ``beta_rad``; the file's other outputs still verify against the
    engine."""
    flaps = FLAPS
    bands = [
        [(-2, -3.0, 3.0), *[(b, -6.0, 6.0) for b in range(-1, 4)], (5, -5.0, 5.0), (9, -6.0, 4.0)],
        [],
        [(5, -1.0, 1.0), (6, -5.0, 5.0), *[(b, -7.0, 7.0) for b in range(8, 20)]],
    ]
    m = _with_envelope(model, flaps, bands)
    assert "in_envelope" not in extended_daveml_text(model).text
    out = extended_daveml_text(m)
    assert out.max_rel_error <= 1e-12
    s = _envelope_states(3, flaps)
    got = out.model.evaluate(
        {"alpha_deg": s["alpha_deg"], "beta_rad": np.radians(s["beta_deg"]),
         "flap_deg": s["flap_deg"]},
        outputs=["in_envelope", "beta_deg"],
    )  # fmt: skip
    frame = pl.DataFrame(
        {"flap_deg": s["flap_deg"], "alpha_deg": s["alpha_deg"], "beta_deg": got["beta_deg"]}
    )
    want = m.in_envelope(frame).to_numpy()
    assert 40 <= want.sum() <= len(want) - 40, want.sum()
    np.testing.assert_array_equal(got["in_envelope"].to_numpy() == 1.0, want)
    assert set(got["in_envelope"].to_list()) <= {0.0, 1.0}


# -- JSBSim: the Kirchhoff stall ---------------------------------------------------------------

_D2R = math.pi / 180.0
#: The virtual aircraft's Kirchhoff truth at flaps 0 and 10 (docs/longitudinal.md), stored as a
#: stall fitted on the ADX-37's known terms.
STALL = {
    0.0: {"tau1": 0.2, "tau2": 0.06, "alpha_star": 21.0 * _D2R, "a1": 20.0, "CL_alpha": 5.2,
          "alpha0": -2.78 * _D2R, "Cm0": 0.06, "Cm_alpha": -0.75, "Cm_x": -0.12},
    10.0: {"tau1": 0.22, "tau2": 0.066, "alpha_star": 20.0 * _D2R, "a1": 20.0, "CL_alpha": 5.2,
           "alpha0": -7.09 * _D2R, "Cm0": 0.03, "Cm_alpha": -0.75, "Cm_x": -0.12},
}  # fmt: skip
#: The truth's drag at flap 0 (``kirchhoff_truth_drag``); flap 10's stall is stored without one
#: (the qualified drag flies there).
STALL_DRAG = {0.0: {"CD0": 0.027, "CD_k": 0.0322, "CD_x": 0.30}}


def stall_model(known: str = "adx37") -> DeltaModel:
    """:func:`synthetic_model` (flaps 0, 10, 20) storing :data:`STALL` at flaps 0 and 10, with
    :data:`STALL_DRAG` at flap 0."""
    spec = synthetic_model().to_spec()
    spec["longitudinal"] = {"model": "kirchhoff", "known": known, "flaps": [
        {"flap_deg": f, "params": p, "note": "",
         **({"drag": STALL_DRAG[f]} if f in STALL_DRAG else {})}
        for f, p in STALL.items()]}  # fmt: skip
    return DeltaModel.from_spec(spec)


def _driven(tmp: Path, aero: str, m: DeltaModel) -> tuple[Any, float, np.ndarray]:
    """The fixture with ``aero`` and ``m``'s stall system (:func:`_jsbsim_fixture.driven`)."""
    return driven(tmp, aero, jsbsim_stall_system_xml(m))


def test_jsbsim_stall_state_and_increments_equal_the_engine(tmp_path: Path) -> None:
    """A pull into the stall and back (5 s, alpha 5 -> 25 -> 5 deg) at flap 0, then 10, then
    20 (no stall stored), alpha and its rate set on the property tree each JSBSim frame:
    - each flap's ``separated-static`` is ``1 - x0(alpha - tau2 alphadot)`` of the engine
      (``aero_core::kirchhoff``) to 1e-12;
    - each flap's separated fraction ``1 - x`` is the engine's exact step
      (``_core.kirchhoff_outputs``, first-order hold) of the same alpha history: the recurrence
      from the previous frame holds to 1e-12 (no frame's delay), and the state is the engine's
      but for the start (attached flow; the engine's is the static ``x0``, 1.4e-5 and 2.8e-5
      below),
      whose difference decays as ``exp(-k dt/tau1)``, to 1e-12;
    - ``x`` is the flap setting's own state there and 1 at the flap without a stall;
    - ``CL-delta``, ``Cm-delta`` are the engine's Kirchhoff lift and moment at JSBSim's ``x``
      less the qualified static curves (the engine's DAVE-ML reading of the exported
      qualified model) to 1e-9, and 0 at flap 20;
    - ``CD-delta`` is the engine's Kirchhoff drag (``KirchhoffDrag``) at JSBSim's ``x`` less
      ``CD_basic`` at flap 0, and 0 at flap 10 (stored without a drag) and 20."""
    m = stall_model()
    fdm, dt, a1 = _driven(tmp_path, jsbsim_xml(m, _TEST_PROPS), m)
    n = a1.size
    alpha = np.concatenate([a1, a1, a1])
    rate = np.concatenate([np.gradient(a1, dt)] * 3)
    flap = np.repeat([0.0, 10.0, 20.0], n)
    names = ["aero/aerodelta/stall/x", "aero/aerodelta/stall/CL-delta",
             "aero/aerodelta/stall/Cm-delta", "aero/aerodelta/stall/CD-delta"]  # fmt: skip
    for i in range(len(STALL)):
        names += [f"aero/aerodelta/stall/flap-{i}/separated{k}" for k in ("-static", "")]
    got: dict[str, list[float]] = {k: [] for k in names}
    for k in range(alpha.size):
        fdm["test/alpha_deg"], fdm["test/alphadot_dps"] = alpha[k], rate[k]
        fdm["test/flap_deg"] = flap[k]
        assert fdm.run()
        for name in names:
            got[name].append(fdm[name])
    g = {k: np.asarray(v) for k, v in got.items()}
    t = np.arange(alpha.size) * dt
    a_rad, r_rad = np.radians(alpha), np.radians(rate)
    qual = ad.export_qualified_daveml(tmp_path / "q.dml").evaluate(
        {"alpha_deg": alpha, "flap_deg": flap}, outputs=["CL_basic", "Cm_basic", "CD_basic"]
    )
    x = g["aero/aerodelta/stall/x"]
    for i, (f, p) in enumerate(STALL.items()):
        v = g[f"aero/aerodelta/stall/flap-{i}/separated-static"]
        s = g[f"aero/aerodelta/stall/flap-{i}/separated"]
        x0, _, _, _ = _core.kirchhoff_point(p, a_rad, r_rad, np.ones_like(a_rad))
        np.testing.assert_allclose(v, 1.0 - x0, rtol=0, atol=1e-12)
        r = dt / p["tau1"]
        e = math.exp(-r)
        gh = 1.0 - (1.0 - e) / r
        step = e * s[:-1] + (1.0 - e - gh) * v[:-1] + gh * v[1:]
        np.testing.assert_allclose(s[1:], step, rtol=0, atol=1e-12)
        x_exact = _core.kirchhoff_outputs(p, t, a_rad, r_rad)[0]
        # the same step from another start: the two differ by the start's difference, decaying
        # as e^k (JSBSim starts attached, the engine at the static x0 of the first sample)
        diff = (1.0 - s) - x_exact
        assert 0.0 < diff[0] <= 1.0 - x_exact[0] < 1e-4
        np.testing.assert_allclose(diff, diff[0] * e ** np.arange(diff.size), rtol=0, atol=1e-12)
        on = flap == f
        np.testing.assert_array_equal(x[on], 1.0 - s[on])
        assert x[on].min() < 0.2  # the flow separates: the stall is flown, not skipped
        _, _, cl, cm = _core.kirchhoff_point(p, a_rad[on], r_rad[on], x[on])
        np.testing.assert_allclose(
            g["aero/aerodelta/stall/CL-delta"][on], cl - qual["CL_basic"].to_numpy()[on],
            rtol=0, atol=1e-9,
        )  # fmt: skip
        np.testing.assert_allclose(
            g["aero/aerodelta/stall/Cm-delta"][on], cm - qual["Cm_basic"].to_numpy()[on],
            rtol=0, atol=1e-9,
        )  # fmt: skip
        dcd = g["aero/aerodelta/stall/CD-delta"][on]
        if f in STALL_DRAG:
            cd = _core.kirchhoff_drag_point(STALL_DRAG[f], cl, np.ascontiguousarray(x[on]))
            np.testing.assert_allclose(dcd, cd - qual["CD_basic"].to_numpy()[on], rtol=0, atol=1e-9)
            assert dcd.max() > 0.05  # the separated wake's drag is flown
        else:
            assert (dcd == 0.0).all()
    off = flap == 20.0
    assert (x[off] == 1.0).all()
    assert (g["aero/aerodelta/stall/CL-delta"][off] == 0.0).all()
    assert (g["aero/aerodelta/stall/Cm-delta"][off] == 0.0).all()
    assert (g["aero/aerodelta/stall/CD-delta"][off] == 0.0).all()


def test_jsbsim_stall_axes_equal_jsbsim_own_wind_to_body_forces(tmp_path: Path) -> None:
    """Default properties, the initial state of a flight past the stall (alpha 19 deg, no
    sideslip, flap 0; the Kirchhoff lift at attached flow differs from the static curve there):
    with ``side_axis="SIDE"`` the lift and drag increments on JSBSim's LIFT and DRAG axes come
    out of JSBSim's own wind-to-body transform as body forces
    ``(L sin alpha - D cos alpha, -L cos alpha - D sin alpha)`` with ``L = qbar S CL-delta``,
    ``D = qbar S CD-delta``; with ``side_axis="Y"`` the export's own X and Z functions give the
    same body forces, and with ``stall_axes="AXIAL"`` (an AXIAL/SIDE/NORMAL aircraft) its
    AXIAL and NORMAL functions through JSBSim's own body-axis convention; PITCH is
    ``qbar S cbar Cm-delta`` in all three. A pair of axes JSBSim does not hold is refused."""
    m = stall_model()
    out = {}
    for axis, stall_axes in (("SIDE", None), ("Y", None), ("SIDE", "AXIAL")):
        text = jsbsim_xml(m, side_axis=axis, stall_axes=stall_axes)
        want = {"SIDE": ("LIFT", "DRAG"), "Y": ("X", "Z"), "AXIAL": ("AXIAL", "NORMAL")}
        for name in want[stall_axes or axis]:
            assert f'<axis name="{name}">' in text, name
        key = stall_axes or axis
        fdm = _load_with_stall(tmp_path / key, text, jsbsim_stall_system_xml(m))
        fdm["ic/vt-kts"], fdm["ic/h-sl-ft"] = 110.0, 3000.0
        fdm["ic/alpha-deg"], fdm["ic/beta-deg"] = 19.0, 0.0
        fdm["fcs/flap-pos-deg"] = 0.0
        assert fdm.run_ic()
        qs = fdm["aero/qbar-psf"] * fdm["metrics/Sw-sqft"]
        alpha = fdm["aero/alpha-rad"]
        lift = qs * fdm["aero/aerodelta/stall/CL-delta"]
        drag = qs * fdm["aero/aerodelta/stall/CD-delta"]
        assert abs(fdm["aero/beta-rad"]) < 1e-9 and abs(lift) > 1.0 and abs(drag) > 1e-3
        ca, sa = math.cos(alpha), math.sin(alpha)
        np.testing.assert_allclose(fdm["forces/fbx-aero-lbs"], lift * sa - drag * ca, rtol=1e-9)
        np.testing.assert_allclose(fdm["forces/fbz-aero-lbs"], -lift * ca - drag * sa, rtol=1e-9)
        np.testing.assert_allclose(
            fdm["moments/m-aero-lbsft"],
            qs * fdm["metrics/cbarw-ft"] * fdm["aero/aerodelta/stall/Cm-delta"], rtol=1e-9,
        )  # fmt: skip
        out[key] = (fdm["forces/fbx-aero-lbs"], fdm["forces/fbz-aero-lbs"])
    np.testing.assert_allclose(out["Y"], out["SIDE"], rtol=1e-9)
    np.testing.assert_allclose(out["AXIAL"], out["SIDE"], rtol=1e-9)
    for axis, stall_axes in (("Y", "AXIAL"), ("Y", "LIFT"), ("SIDE", "X"), ("SIDE", "NORMAL")):
        with pytest.raises(ad.DataError, match="stall_axes"):
            jsbsim_xml(m, side_axis=axis, stall_axes=stall_axes)


def test_jsbsim_stall_state_in_flight_is_the_engines_step_of_jsbsim_alpha(tmp_path: Path) -> None:
    """Default properties, 1 s of flight from alpha 19 deg at flap 0 (the aircraft pitches and
    falls): the separated fraction is the engine's exact step of JSBSim's own alpha and
    alphadot of each frame, from the frame's start (no frame's delay: the aerodynamics step
    the state after JSBSim computes alpha), to 1e-12."""
    m = stall_model()
    fdm = _load_with_stall(tmp_path, jsbsim_xml(m), jsbsim_stall_system_xml(m))
    fdm["ic/vt-kts"], fdm["ic/h-sl-ft"] = 110.0, 3000.0
    fdm["ic/alpha-deg"], fdm["fcs/flap-pos-deg"] = 19.0, 0.0
    assert fdm.run_ic()
    rows = []
    for _ in range(120):
        assert fdm.run()
        rows.append([fdm["aero/alpha-rad"], fdm["aero/alphadot-rad_sec"],
                     fdm["aero/aerodelta/stall/flap-0/separated"]])  # fmt: skip
    a, ad_, s = (np.ascontiguousarray(c) for c in np.asarray(rows).T)
    assert np.ptp(a) > 0.01 and np.abs(ad_).max() > 0.05  # alpha moves
    p, dt = STALL[0.0], fdm["simulation/dt"]
    x0, _, _, _ = _core.kirchhoff_point(p, a, ad_, np.ones_like(a))
    r = dt / p["tau1"]
    e = math.exp(-r)
    gh = 1.0 - (1.0 - e) / r
    v = 1.0 - x0
    np.testing.assert_allclose(
        s[1:], e * s[:-1] + (1.0 - e - gh) * v[:-1] + gh * v[1:], rtol=0, atol=1e-12
    )
    assert s[-1] > 0.01  # the flow separates


def test_jsbsim_stall_fitted_on_the_whole_coefficients_adds_its_dynamics_only(
    tmp_path: Path,
) -> None:
    """A stall fitted with ``known="none"`` (the whole measured C_L, C_m, as on a JSBSim
    aircraft of the user's) adds the separation dynamics over the aircraft's own static
    curves: ``CL-delta`` is the engine's Kirchhoff lift at JSBSim's state less the same at the
    static state ``x0(alpha)``, ``Cm-delta`` is ``Cm_x (x0 - x)``, ``CD-delta`` the engine's
    Kirchhoff drag at the state less at ``x0(alpha)``, all to 1e-9 along a pull into the stall
    and back, and all vanish (below 1e-9) once alpha has been held for 6 s (30 tau1: the
    state's distance to x0 decays as exp(-t/tau1)).
    No qualified table is written."""
    m = stall_model(known="none")
    aero = jsbsim_xml(m, _TEST_PROPS)
    assert "CL_basic" not in aero and "aero/aerodelta/stall/flap-0/x-static" in aero
    fdm, dt, pull = _driven(tmp_path, aero, m)
    n = pull.size
    alpha = np.concatenate([pull, np.full(720, 22.0)])  # then 6 s (30 tau1) held past the break
    rate = np.concatenate([np.gradient(pull, dt), np.zeros(720)])
    rows = []
    for a, r in zip(alpha, rate, strict=True):
        fdm["test/alpha_deg"], fdm["test/alphadot_dps"] = a, r
        assert fdm.run()
        rows.append([fdm["aero/aerodelta/stall/x"], fdm["aero/aerodelta/stall/CL-delta"],
                     fdm["aero/aerodelta/stall/Cm-delta"],
                     fdm["aero/aerodelta/stall/CD-delta"]])  # fmt: skip
    x, dcl, dcm, dcd = (np.ascontiguousarray(c) for c in np.asarray(rows).T)
    p = STALL[0.0]
    a_rad, r_rad = np.radians(alpha), np.radians(rate)
    _, _, cl, _ = _core.kirchhoff_point(p, a_rad, r_rad, x)
    x0s, _, _, _ = _core.kirchhoff_point(p, a_rad, np.zeros_like(a_rad), x)  # x0(alpha)
    _, _, cls, _ = _core.kirchhoff_point(p, a_rad, np.zeros_like(a_rad), x0s)
    np.testing.assert_allclose(dcl, cl - cls, rtol=0, atol=1e-9)
    np.testing.assert_allclose(dcm, p["Cm_x"] * (x0s - x), rtol=0, atol=1e-9)
    d = STALL_DRAG[0.0]
    want = _core.kirchhoff_drag_point(d, cl, x) - _core.kirchhoff_drag_point(d, cls, x0s)
    np.testing.assert_allclose(dcd, want, rtol=0, atol=1e-9)
    assert np.abs(dcl[:n]).max() > 0.01 and np.abs(dcd[:n]).max() > 0.01  # hysteresis flown
    assert np.abs(dcl[-1]) < 1e-9 and np.abs(dcm[-1]) < 1e-9 and np.abs(dcd[-1]) < 1e-9


def test_daveml_stall_fitted_on_the_whole_coefficients_adds_its_dynamics_only() -> None:
    """The DAVE-ML form of the same (``known="none"``): the export's own check cases match the
    engine (``_core.kirchhoff_point``) to 1e-9; ``CL_ext`` and ``Cm_ext`` are the qualified
    ``CL``, ``Cm`` when ``x_sep`` is the static ``x0(alpha)`` (steady flight), and differ by the
    engine's Kirchhoff lift and moment at ``x_sep`` less at ``x0(alpha)`` otherwise, 1e-12."""
    m = stall_model(known="none")
    out = extended_daveml_text(m)
    assert out.max_rel_error <= 1e-9 and out.model.run_checks()["pass"].all()
    # flap 0 stores a drag: CD_ext too (checked against the engine with the rest)
    assert {"x_sep_dot", "CL_ext", "Cm_ext", "CD_ext"} <= set(out.model.outputs)
    rng = np.random.default_rng(3)
    alpha = rng.uniform(0.0, 30.0, 200)
    x = rng.uniform(0.0, 1.0, 200)
    p = STALL[10.0]
    a_rad, still = np.radians(alpha), np.zeros(200)
    xs = _core.kirchhoff_point(p, a_rad, still, x)[0]
    for state, want_zero in ((xs, True), (x, False)):
        got = out.model.evaluate(
            {"alpha_deg": alpha, "flap_deg": np.full(200, 10.0), "x_sep": state,
             "alphadot_dps": still},
            outputs=["CL_ext", "Cm_ext", "CL", "Cm"],
        )  # fmt: skip
        _, _, cl, cm = _core.kirchhoff_point(p, a_rad, still, np.ascontiguousarray(state))
        _, _, cls, cms = _core.kirchhoff_point(p, a_rad, still, xs)
        dcl = got["CL_ext"].to_numpy() - got["CL"].to_numpy()
        dcm = got["Cm_ext"].to_numpy() - got["Cm"].to_numpy()
        np.testing.assert_allclose(dcl, cl - cls, rtol=0, atol=1e-12)
        np.testing.assert_allclose(dcm, cm - cms, rtol=0, atol=1e-12)
        assert (np.abs(dcl).max() < 1e-12) == want_zero


def test_jsbsim_stall_export_refusals_and_files(tmp_path: Path) -> None:
    m = stall_model()
    plain = synthetic_model()
    # without the stall the aerodynamics are those of the model that stores none
    assert jsbsim_xml(m, longitudinal=False) == jsbsim_xml(plain)
    assert "aerodelta/stall" not in jsbsim_xml(m, longitudinal=False)
    with pytest.raises(ad.DataError, match="stores no longitudinal stall"):
        jsbsim_stall_system_xml(plain)
    aero, system = tmp_path / "delta.xml", tmp_path / "stall.xml"
    with pytest.raises(ad.DataError, match=r"<system>.*--jsbsim-system.*--no-longitudinal"):
        export_jsbsim(aero, m)
    with pytest.raises(ad.DataError, match="stores no Kirchhoff stall"):
        export_jsbsim(aero, plain, system_path=system)
    with pytest.raises(ad.DataError, match="leaves its stall out"):
        export_jsbsim(aero, m, longitudinal=False, system_path=system)
    with pytest.raises(ad.DataError, match="give two files"):
        export_jsbsim(aero, m, system_path=aero)
    assert not aero.exists() and not system.exists()
    text = export_jsbsim(aero, m, system_path=system)
    assert aero.read_text() == text and system.read_text() == jsbsim_stall_system_xml(m)
    # the two files are one output: a system file that cannot be written leaves the
    # aerodynamics as they were
    aero.write_text("earlier")
    with pytest.raises(OSError, match="missing"):
        export_jsbsim(aero, m, system_path=tmp_path / "missing" / "stall.xml")
    assert aero.read_text() == "earlier"
    assert not list(tmp_path.glob("*.tmp-*"))
