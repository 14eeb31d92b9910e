"""The Kirchhoff stall stored with the Δ model (``DeltaModel.with_longitudinal``,
``aero_core::stall_spec``; issue 20 item 2: the extended model carries the stall).

References: the output-error fit itself (its parameters must come back bit for bit from the
file) and the closed-loop replay given those parameters explicitly (the replay of the model
carrying them must be the same flight, sample for sample), on the quick stall campaign of seed
41 (buffet and the Kirchhoff stall on).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta import _core
from aerodelta.cli import main
from aerodelta.closed_loop import closed_loop_replay
from aerodelta.exceptions import InvalidInputError
from aerodelta.fit import model_frame
from aerodelta.longitudinal import PARAMS, fit_kirchhoff
from aerodelta.model import DeltaModel


@pytest.fixture(scope="module")
def fitted(stall_campaign: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    data = ad.ingest(stall_campaign, compat=False, progress=False).data
    root = tmp_path_factory.mktemp("stallmodel")
    model = ad.fit(data).model
    model.save(root / "model.json")
    stall = fit_kirchhoff(model_frame(data), flaps=[0.0, 15.0], known="adx37")
    return {"data": data, "model": model, "stall": stall, "root": root}


def test_the_stall_survives_the_file_bit_for_bit(fitted: dict[str, Any]) -> None:
    model, stall = fitted["model"], fitted["stall"]
    assert model.kirchhoff is None and model.kirchhoff_known is None
    assert model.adx37_stall_flaps == []
    m2 = model.with_longitudinal(stall)
    path = fitted["root"] / "with_stall.json"
    m2.save(path)
    back = DeltaModel.load(path)
    assert back.kirchhoff_known == "adx37"
    assert back.adx37_stall_flaps == [0.0, 15.0]
    # a stall fitted on the whole measured coefficients is not flown over the ADX-37's curves
    whole = DeltaModel.from_spec({**back.to_spec(), "longitudinal": {
        **back.to_spec()["longitudinal"], "known": "none"}})  # fmt: skip
    assert whole.kirchhoff_known == "none" and whole.adx37_stall_flaps == []
    k = back.kirchhoff
    assert k is not None and sorted(k) == [0.0, 15.0]
    for f in (0.0, 15.0):
        assert set(k[f]) == set(PARAMS)
        assert all(k[f][n] == stall[f].params[n] for n in PARAMS)  # exact, not approximate
        # and the drag along the state, fitted by default, likewise
        d = stall[f].drag
        assert d is not None and back.kirchhoff_drag[f] == d.params
    # the lateral Δ is untouched
    spec, spec2 = model.to_spec(), back.to_spec()
    assert spec2.pop("longitudinal")["model"] == "kirchhoff"
    assert spec2 == spec


def test_the_replay_flies_the_stored_stall(fitted: dict[str, Any]) -> None:
    data, model, stall = fitted["data"], fitted["model"], fitted["stall"]
    ids = (
        data.filter(pl.col("flap_deg").is_in([0.0, 15.0]) & (pl.col("kind") == "straight"))[
            "maneuver_id"
        ]
        .unique()
        .sort()
        .to_list()
    )

    def with_drag(f: float) -> dict[str, float]:
        d = stall[f].drag
        assert d is not None
        return {**stall[f].params, **d.params}

    given = closed_loop_replay(
        data, model=model, kirchhoff={f: with_drag(f) for f in (0.0, 15.0)}, maneuvers=ids
    )
    stored = closed_loop_replay(data, model=model.with_longitudinal(stall), maneuvers=ids)
    static = closed_loop_replay(data, model=model, maneuvers=ids)
    assert stored.setup["model_kirchhoff_flaps"] == [0.0, 15.0]
    assert given.setup["kirchhoff_flaps"] == [0.0, 15.0]
    for mid in ids:
        assert stored.runs[mid].equals(given.runs[mid]), mid
    # without the stall the qualified static curves fly: another flight
    assert any(not static.runs[m].equals(given.runs[m]) for m in ids)
    # the stored drag flies too: the stall given without it (the qualified drag) is another
    # flight, and a stall stored without it (fit_cd=False) is that one
    no_drag = closed_loop_replay(
        data, model=model, kirchhoff={f: stall[f].params for f in (0.0, 15.0)}, maneuvers=ids
    )
    assert any(not no_drag.runs[m].equals(given.runs[m]) for m in ids)
    plain = fit_kirchhoff(model_frame(data), flaps=[0.0, 15.0], known="adx37", fit_cd=False)
    assert model.with_longitudinal(plain).kirchhoff_drag == {}
    stored_plain = closed_loop_replay(data, model=model.with_longitudinal(plain), maneuvers=ids)
    for mid in ids:
        assert stored_plain.runs[mid].equals(no_drag.runs[mid]), mid


def test_replays_count_the_time_outside_the_envelope(fitted: dict[str, Any]) -> None:
    """The replay's time outside the validated envelope against two envelopes whose answer is
    known: one covering every state (0 s) and one covering none (the run's whole duration);
    the envelope only flags, the flight is the same."""
    data, model = fitted["data"], fitted["model"]
    ids = data["maneuver_id"].unique().sort().to_list()[:3]
    spec = model.to_spec()
    env = spec["envelope"]
    w = float(env["band_deg"])

    def with_bands(beta_lo: float, beta_hi: float) -> DeltaModel:
        bands = [
            [
                {"band": b, "beta_min_deg": beta_lo, "beta_max_deg": beta_hi, "maneuvers": 99}
                for b in range(-int(90 / w), int(90 / w) + 1)
            ]
            for _ in env["flaps_deg"]
        ]
        return DeltaModel.from_spec({**spec, "envelope": {**env, "bands": bands}})

    fitted_env = closed_loop_replay(data, model=model, maneuvers=ids)
    everywhere = closed_loop_replay(data, model=with_bands(-90.0, 90.0), maneuvers=ids)
    nowhere = closed_loop_replay(data, model=with_bands(80.0, 81.0), maneuvers=ids)
    assert fitted_env.setup["envelope"] and everywhere.setup["envelope"]
    for mid in ids:
        run = fitted_env.runs[mid]
        assert everywhere.runs[mid].equals(run) and nowhere.runs[mid].equals(run)
        duration = float(run["t"][-1] - run["t"][0])

        def outside(res: Any, m: str = mid) -> float:
            return float(res.table.filter(pl.col("maneuver_id") == m)["outside_envelope_s"][0])

        assert outside(everywhere) == 0.0
        assert outside(nowhere) == pytest.approx(duration, rel=1e-12)
        assert 0.0 <= outside(fitted_env) <= duration
    # no model, no envelope: not counted
    qual = closed_loop_replay(data, maneuvers=ids[:1])
    assert qual.table["outside_envelope_s"].null_count() == 1 and not qual.setup["envelope"]


def test_the_open_loop_replay_flies_the_stored_stall_and_the_prestall_check_splits(
    fitted: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The open-loop replay of a model storing the stall (flaps 0 and 15) flies it, as the
    closed-loop replays do (``aero_core``'s own test compares it with the virtual aircraft's
    Kirchhoff truth): past the stall it leaves the qualified replay; at flap 10, where no stall
    is stored, the qualified curves fly. The pre-stall regression then compares the extended
    model with the same model without its lateral Δ (bit for bit, stall on both sides) and the
    stall with the qualified model (within Part 60 Table A2A 2.c tolerances); tightened
    tolerances make exactly the stall's flaps fail."""
    from aerodelta.campaign import record_state, replay  # noqa: PLC0415
    from aerodelta.evidence import prestall  # noqa: PLC0415

    data, model = fitted["data"], fitted["model"]
    m2 = model.with_longitudinal(fitted["stall"])
    flown: dict[float, bool] = {}
    for flap in (0.0, 10.0, 15.0):
        mid = str(
            data.filter((pl.col("flap_deg") == flap) & (pl.col("kind") == "straight"))[
                "maneuver_id"
            ].min()
        )
        g = data.filter(pl.col("maneuver_id") == mid).sort("t")
        c = np.column_stack([g[x].cast(pl.Float64).fill_null(0.0) for x in prestall.CONTROLS])
        ct = np.column_stack([g[x].cast(pl.Float64).fill_null(0.0) for x in prestall.THRUST])
        x0, dt = record_state(g.row(0, named=True)), float(np.median(np.diff(g["t"])))
        qual = replay(flap, x0, dt, c, ct)
        stall_only = replay(flap, x0, dt, c, ct, delta_model=m2, lateral_delta=False)
        assert np.isfinite(stall_only).all()
        flown[flap] = not np.array_equal(stall_only, qual)
        # without a stored stall the model's no-Δ replay is the qualified one
        assert np.array_equal(
            replay(flap, x0, dt, c, ct, delta_model=model, lateral_delta=False), qual
        )
    assert flown == {0.0: True, 10.0: False, 15.0: True}
    with pytest.raises(InvalidInputError, match="lateral_delta=False"):
        replay(0.0, x0, dt, c, ct, lateral_delta=False)

    chk = prestall.prestall_regression(data, m2)
    t = chk.table
    assert chk.passed, prestall.describe(chk)
    assert t.filter(pl.col("stall_flown"))["flap_deg"].unique().sort().to_list() == [0.0, 15.0]
    assert float(t["max_state_diff"].max()) == 0.0  # the lateral Δ adds exactly nothing there
    dev = t.filter(pl.col("stall_flown") & (pl.col("steps_compared") > 50))
    assert dev.height >= 4
    # the stall acts before the blend start, within the tolerances
    assert (dev["stall_dh_ft"] > 0.0).all() and (dev["stall_dtheta_deg"] > 0.0).all()
    assert t.filter(~pl.col("stall_flown"))["stall_dv_kt"].null_count() == int(
        (~t["stall_flown"]).sum()
    )
    assert "stored stall (flap 0, 15)" in prestall.describe(chk)
    # tolerances under the measured deviations: the stall's maneuvers fail, the others pass
    tight = {k: 0.5 * float(dev[c].min()) for k, c in zip(
        prestall.STALL_TOLERANCES, ("stall_dv_kt", "stall_dh_ft", "stall_dtheta_deg"), strict=True
    )}  # fmt: skip
    monkeypatch.setattr(prestall, "STALL_TOLERANCES", tight)
    bad = prestall.prestall_regression(data, m2).table
    failed = bad.filter(pl.col("status") == "FAIL")
    assert set(failed["maneuver_id"]) >= set(dev["maneuver_id"])
    assert failed["stall_flown"].all()
    assert (bad.filter(~pl.col("stall_flown"))["status"] == "PASS").all()


def _pull(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A smooth pull into the stall and back: alpha 10 -> 24 -> 10 deg over 3 s, and its rate
    (deg, deg/s)."""
    w = np.pi / 1.5
    return 17.0 - 7.0 * np.cos(w * t), 7.0 * w * np.sin(w * t)


def _rk4_host(dave: ad.DaveModel, t: np.ndarray, flap: float) -> np.ndarray:
    """A host integrating the exported state: RK4 on the DAVE-ML file's ``x_sep_dot`` along
    :func:`_pull`, from its ``x_sep_0``."""

    def state(s: float, x: float, out: str) -> float:
        a, r = _pull(np.array([s]))
        inputs = {"alpha_deg": a, "alphadot_dps": r, "flap_deg": [flap], "x_sep": [x]}
        return float(dave.evaluate(inputs, outputs=[out])[out][0])

    xs = [state(t[0], 1.0, "x_sep_0")]
    for k in range(t.size - 1):
        h, x = t[k + 1] - t[k], xs[-1]
        k1 = state(t[k], x, "x_sep_dot")
        k2 = state(t[k] + 0.5 * h, x + 0.5 * h * k1, "x_sep_dot")
        k3 = state(t[k] + 0.5 * h, x + 0.5 * h * k2, "x_sep_dot")
        k4 = state(t[k + 1], x + h * k3, "x_sep_dot")
        xs.append(x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4))
    return np.asarray(xs)


def test_the_daveml_export_carries_the_stall_state(fitted: dict[str, Any], tmp_path: Path) -> None:
    """The extended DAVE-ML file of a model with its Kirchhoff stall: the separation point is a
    state input ``x_sep`` with its derivative ``x_sep_dot`` (the export itself compares every
    sampled state with the engine's ``KirchhoffParams`` to 1e-12). Here: a host integrating
    ``x_sep_dot`` by RK4 along a pull into the stall follows the engine's exact state
    (``kirchhoff_outputs``), and ``CL_ext``, ``Cm_ext`` with that state are the engine's lift and
    moment in place of the static curves."""
    from aerodelta.export import export_extended_daveml  # noqa: PLC0415

    model, stall = fitted["model"], fitted["stall"]
    m2 = model.with_longitudinal(stall)
    out = export_extended_daveml(tmp_path / "ext.dml", m2)
    dave = ad.DaveModel(tmp_path / "ext.dml")
    assert {"x_sep_dot", "x_sep_0", "CL_ext", "Cm_ext", "CD_ext"} <= set(dave.outputs)
    assert "x_sep" in dave.inputs and dave.run_checks()["pass"].all()
    assert out.max_rel_error <= 1e-12
    # a smooth pull into the stall and back at flap 15, 200 Hz: the engine's exact steps of the
    # sampled input against the host's RK4 of the file's derivative
    t = np.arange(0.0, 3.0, 0.005)
    alpha, rate = _pull(t)
    p = stall[15.0].params
    x_eng, cl_eng, cm_eng, _, _ = _core.kirchhoff_outputs(p, t, np.radians(alpha), np.radians(rate))
    x_host = _rk4_host(dave, t, 15.0)
    assert np.min(x_eng) < 0.2  # the flow separates, and reattaches
    assert x_eng[-1] > 0.9
    assert np.max(np.abs(x_host - x_eng)) < 1e-4
    got = dave.evaluate(
        {"alpha_deg": alpha, "flap_deg": np.full(t.size, 15.0), "x_sep": x_eng,
         "alphadot_dps": rate},
        outputs=["CL_ext", "Cm_ext", "CL", "Cm", "CL_basic", "Cm_basic", "CD_ext", "CD",
                 "CD_basic"],
    )  # fmt: skip
    np.testing.assert_allclose(
        got["CL_ext"].to_numpy(),
        got["CL"].to_numpy() - got["CL_basic"].to_numpy() + cl_eng, rtol=1e-12, atol=1e-14,
    )  # fmt: skip
    np.testing.assert_allclose(
        got["Cm_ext"].to_numpy(),
        got["Cm"].to_numpy() - got["Cm_basic"].to_numpy() + cm_eng, rtol=1e-12, atol=1e-14,
    )  # fmt: skip
    # the drag along the same state: the engine's KirchhoffDrag in place of CD_basic
    d = stall[15.0].drag
    assert d is not None
    cd_eng = _core.kirchhoff_drag_point(d.params, cl_eng, x_eng)
    np.testing.assert_allclose(
        got["CD_ext"].to_numpy(),
        got["CD"].to_numpy() - got["CD_basic"].to_numpy() + cd_eng, rtol=1e-12, atol=1e-14,
    )  # fmt: skip
    # a flap setting without a stored stall: no state dynamics, the qualified totals
    mid = dave.evaluate(
        {"alpha_deg": alpha, "flap_deg": np.full(t.size, 10.0), "x_sep": x_eng,
         "alphadot_dps": rate},
        outputs=["x_sep_dot", "CL_ext", "CL"],
    )  # fmt: skip
    assert np.all(mid["x_sep_dot"].to_numpy() == 0.0)
    assert np.array_equal(mid["CL_ext"].to_numpy(), mid["CL"].to_numpy())


def test_a_stall_the_qualified_file_cannot_carry_is_refused(
    fitted: dict[str, Any], tmp_path: Path
) -> None:
    from aerodelta.daveml import write_example_model  # noqa: PLC0415
    from aerodelta.export import extended_daveml_text  # noqa: PLC0415

    m2 = fitted["model"].with_longitudinal(fitted["stall"])
    base = tmp_path / "example.dml"
    write_example_model(base)  # no CL_basic, Cm_basic, CL, Cm
    # the stall stores its drag (fit_kirchhoff's default): C_D's curve and total are needed too
    with pytest.raises(
        ad.DataError, match=r"no CL_basic, Cm_basic, CD_basic, CL, Cm, CD.*--no-longitudinal"
    ):
        extended_daveml_text(m2, base, channel_map={"phat": "p_hat", "rhat": "r_hat"})
    out = extended_daveml_text(
        m2, base, channel_map={"phat": "p_hat", "rhat": "r_hat"}, longitudinal=False
    )
    assert "x_sep" not in out.model.inputs and "CL_ext" not in out.model.outputs


def test_cli_export_of_a_model_with_its_stall(
    fitted: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "with_stall.json"
    fitted["model"].with_longitudinal(fitted["stall"]).save(path)
    dml, xml, sysx = tmp_path / "ext.dml", tmp_path / "delta.xml", tmp_path / "stall.xml"
    argv = ["export", "--model", str(path), "--daveml", str(dml), "--jsbsim", str(xml)]
    # the JSBSim export carries the stall, whose state needs the <system> file
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and "--jsbsim-system" in err and "flaps 0, 15 deg" in err
    assert not dml.exists() and not xml.exists()
    rc = main([*argv, "--jsbsim-system", str(sysx)])
    out, err = capsys.readouterr()
    assert rc == 0
    assert "longitudinal stall at flaps 0, 15 deg" in out
    assert f"wrote {sysx}" in out and "LIFT, DRAG and PITCH" in out
    assert "aero/aerodelta/stall/CL-delta" in xml.read_text()
    assert "aero/aerodelta/stall/CD-delta" in xml.read_text()
    # an AXIAL/SIDE/NORMAL aircraft takes the stall's forces on AXIAL and NORMAL
    rc = main([*argv, "--jsbsim-system", str(sysx), "--stall-axes", "AXIAL"])
    out = capsys.readouterr().out
    assert rc == 0 and "AXIAL, NORMAL and PITCH" in out
    assert '<axis name="AXIAL">' in xml.read_text() and '<axis name="LIFT">' not in xml.read_text()
    # axes JSBSim does not combine: refused before anything is written
    dml2, xml2 = tmp_path / "b" / "ext.dml", tmp_path / "b" / "delta.xml"
    bad = ["export", "--model", str(path), "--daveml", str(dml2), "--jsbsim", str(xml2),
           "--jsbsim-system", str(sysx), "--side-axis", "Y", "--stall-axes", "LIFT"]  # fmt: skip
    assert main(bad) == 2 and "stall_axes 'LIFT' with side_axis 'Y'" in capsys.readouterr().err
    assert not dml2.exists() and not xml2.exists() and not dml2.parent.exists()
    assert 'name="aerodelta/stall/flap-1/separated-previous"' in sysx.read_text()
    assert "x_sep" in ad.DaveModel(dml).inputs
    assert not list(tmp_path.glob("*.tmp-*"))
    rc = main([*argv, "--no-longitudinal", "--jsbsim-system", str(sysx)])
    assert rc == 2 and "--no-longitudinal" in capsys.readouterr().err
    # the stall's CL and Cm totals may be named with --coef (here as they are called)
    rc = main([*argv, "--jsbsim-system", str(sysx), "--coef", "CL=CL", "--coef", "Cm=Cm"])
    assert rc == 0, capsys.readouterr().err
    rc = main([*argv, "--no-longitudinal", "--coef", "CL=CL"])
    assert rc != 0 and "has no coefficient 'CL'" in capsys.readouterr().err
    rc = main(["export", "--model", str(path), "--daveml", str(dml), "--no-longitudinal"])
    assert rc == 0 and "x_sep" not in ad.DaveModel(dml).inputs
    assert "longitudinal stall at flaps" not in capsys.readouterr().out


def test_refusals(fitted: dict[str, Any], tmp_path: Path) -> None:
    data, model = fitted["data"], fitted["model"]
    lift_only = fit_kirchhoff(model_frame(data), flaps=[0.0], fit_cm=False)
    with pytest.raises(InvalidInputError, match="fit_cm=False"):
        model.with_longitudinal(lift_only)
    spec = model.with_longitudinal(fitted["stall"]).to_spec()
    del spec["longitudinal"]["flaps"][0]["params"]["tau1"]
    with pytest.raises(ad.AerodeltaError, match=r"flap 0.*lacks parameter tau1"):
        DeltaModel.from_spec(spec)


def test_cli_writes_a_copy_and_leaves_the_model_alone(
    fitted: dict[str, Any], stall_campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = fitted["root"] / "model.json"
    before = hashlib.sha256(src.read_bytes()).hexdigest()
    out = tmp_path / "out" / "model_stall.json"
    argv = ["longitudinal", str(stall_campaign), "--flaps", "0,15", "--no-progress"]
    assert main([*argv, "--model", str(src), "--out-model", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    assert hashlib.sha256(src.read_bytes()).hexdigest() == before
    got = DeltaModel.load(out).kirchhoff
    assert got is not None
    for f in (0.0, 15.0):
        assert got[f] == pytest.approx(fitted["stall"][f].params, rel=0, abs=0)
    # one clear line for a half-given pair, an overwrite of the input, a lift-only fit
    for extra, text in (
        (["--model", str(src)], "--model and --out-model go together"),
        (["--model", str(src), "--out-model", str(src)], "--out-model"),
        (["--model", str(src), "--out-model", str(out), "--no-cm"], "fit C_m too"),
    ):
        assert main([*argv, *extra]) != 0
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and text in err[0], err
    assert json.loads(out.read_text())["longitudinal"]["known"] == "adx37"
