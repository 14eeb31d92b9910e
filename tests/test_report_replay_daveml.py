"""The report's 6-DOF replay section for a DAVE-ML qualified model (issue 19 item 5): it says
which of the six coefficients the user's model gives and which a replay would lack."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta.aircraft import BUILTIN_COLUMN
from aerodelta.cli import main
from aerodelta.fit import FitConfig
from aerodelta.plots import FigureSink
from aerodelta.report import replay
from aerodelta.report.context import build_context
from aerodelta.report.daveml_replay import daveml_flyer

#: Largest replay difference, DAVE-ML model against the compiled model, as a fraction of each
#: state's range over the maneuver (two implementations of the same tables and aircraft;
#: measured <= 1e-14 on the six flap-0 maneuvers of the quick campaign, with and without Δ).
TOL = 1e-12


def _dml(path: Path, outputs: tuple[str, ...]) -> Path:
    """A DAVE-ML model with ``outputs``, each a table in alpha_deg (values arbitrary)."""
    defs, fns = [], []
    for k, c in enumerate(outputs):
        defs.append(f'<variableDef name="{c}" varID="{c}" units="nd"><isOutput/></variableDef>')
        fns.append(
            f'<function name="{c}_fn"><independentVarPts varID="alpha_deg">-10, 0, 30'
            f'</independentVarPts><dependentVarPts varID="{c}">0, {0.001 * (k + 1)}, 0'
            "</dependentVarPts></function>"
        )
    path.write_text(
        '<?xml version="1.0"?>\n<DAVEfunc xmlns="http://daveml.org/2010/DAVEML">'
        '<fileHeader><author name="test"/><creationDate date="2026-11-26"/></fileHeader>'
        '<variableDef name="alpha" varID="alpha_deg" units="deg"/>'
        + "".join(defs)
        + "".join(fns)
        + "</DAVEfunc>"
    )
    return path


@pytest.fixture(scope="module")
def user(quick_campaign: Path) -> pl.DataFrame:
    """The quick campaign's flap-0 records without the virtual aircraft's mark (user data)."""
    d = ad.ingest(quick_campaign, compat=False, progress=False).data
    return d.filter(pl.col("flap_deg") == 0.0).drop(BUILTIN_COLUMN)


def _text(model: ad.DeltaModel, data: pl.DataFrame, dml: Path) -> str:
    sec = replay.section(build_context(model, data, qualified=str(dml)), FigureSink(None))
    assert not sec.tables
    return " ".join(str(b) for b in sec.body)


def test_daveml_outputs_named(user: pl.DataFrame, tmp_path: Path) -> None:
    """A lateral-only model: the missing outputs named; the exported ADX-37 qualified model
    (lift, drag, side force, three moments) and a body-axis model: all six present."""
    adx = tmp_path / "adx37.dml"
    assert main(["export-qualified", str(adx)]) == 0
    model = ad.fit(user, qualified=adx, config=FitConfig(selection=None)).model
    lateral = _dml(tmp_path / "lateral.dml", ("Cl", "Cn", "CY"))
    text = _text(model, user, lateral)
    assert "Replay not run" in text
    assert (
        "The DAVE-ML model lateral.dml gives CY, Cl, Cn of the coefficients a 6-DOF replay "
        "needs; missing: Cm, CX and CZ (or lift and drag, CL and CD)." in text
    )
    text = _text(model, user, adx)
    assert "adx37.dml gives all six coefficients (CL, CD, CY, Cl, Cm, Cn)" in text
    assert "missing" not in text
    body = _dml(tmp_path / "body.dml", ("CX", "CY", "CZ", "Cl", "Cm", "Cn"))
    text = _text(model, user, body)
    assert "body.dml gives all six coefficients (CX, CZ, CY, Cl, Cm, Cn)" in text
    half = _dml(tmp_path / "half.dml", ("CX", "CY", "Cl", "Cm", "Cn"))
    assert "missing: CX and CZ (or lift and drag, CL and CD)." in _text(model, user, half)


def test_daveml_replay_flies_the_users_aircraft(user: pl.DataFrame, tmp_path: Path) -> None:
    """The exported ADX-37 qualified DAVE-ML model flown on the ADX-37's aircraft file replays
    as the built-in compiled ADX-37 (qualified model, roll-off off), alone and with the fitted
    Δ: two implementations of the same tables and the same aircraft (independent reference:
    ``aerodelta.campaign.replay``). The report section flies it when given the aircraft file,
    and refuses a model without the six coefficients in one sentence."""
    adx = tmp_path / "adx37.dml"
    assert main(["export-qualified", str(adx)]) == 0
    toml = tmp_path / "aircraft.toml"
    toml.write_text(ad.campaign.aircraft_toml())
    model = ad.fit(user, qualified=adx, config=FitConfig(selection=None)).model
    ctx = build_context(model, user, qualified=str(adx))
    fly = daveml_flyer(adx, toml)
    mid = replay.pick_maneuvers(ctx, 1)[0]
    rec = ctx.data.filter(pl.col("maneuver_id") == mid).sort("t")
    for m in (None, model):
        ref = replay.replay_maneuver(rec, controls="all", rolloff_seed=None, model=m)
        got = replay.replay_maneuver(rec, controls="all", model=m, fly=fly)
        assert got.height == ref.height
        for s in replay.STATES:
            err = np.abs(got[s].to_numpy() - ref[s].to_numpy())
            scale = max(float(np.ptp(ref[s].to_numpy())), 1.0)
            assert np.max(err) <= TOL * scale, (m is None, s, float(np.max(err)))
    # the aircraft file is what flies: 10 % more roll inertia moves the replay
    heavy = tmp_path / "heavy.toml"
    heavy.write_text(
        ad.campaign.aircraft_toml().replace("Ixx_kgm2 = 157000.0", "Ixx_kgm2 = 172700.0")
    )
    moved = replay.replay_maneuver(rec, controls="all", model=model, fly=daveml_flyer(adx, heavy))
    assert np.max(np.abs(moved["phi_deg"].to_numpy() - ref["phi_deg"].to_numpy())) > 1e-3
    sec = replay.section(ctx, FigureSink(None), count=1, controls="all", aircraft=toml)
    text = " ".join(str(b) for b in sec.body)
    assert "your DAVE-ML model</b> adx37.dml" in text and "Replay not run" not in text
    row = sec.tables["replay"].row(0, named=True)
    assert row["maneuver_id"] == mid and row["bounded"]
    ref = replay.replay_maneuver(rec, controls="all", rolloff_seed=None, model=model)
    y = rec["phi_deg"].to_numpy()
    want = float(np.sqrt(np.mean((np.interp(rec["t"], ref["t"], ref["phi_deg"]) - y) ** 2)))
    assert row["rms_phi_deg_ext"] == pytest.approx(want, rel=1e-6, abs=1e-9)
    lateral = _dml(tmp_path / "lateral.dml", ("Cl", "Cn", "CY"))
    ctx = build_context(model, user, qualified=str(lateral))
    text = " ".join(str(b) for b in replay.section(ctx, FigureSink(None), aircraft=toml).body)
    assert text.count("Replay not run") == 1
    assert "missing: Cm, CX and CZ (or lift and drag, CL and CD)" in text


def test_cli_report_flies_the_daveml_model(
    user: pl.DataFrame, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``aerodelta report --qualified model.dml --aircraft FILE`` on an ingest output: the
    section flies the user's aircraft with the DAVE-ML model."""
    adx = tmp_path / "adx37.dml"
    assert main(["export-qualified", str(adx)]) == 0
    toml = tmp_path / "aircraft.toml"
    toml.write_text(ad.campaign.aircraft_toml())
    ad.fit(user, qualified=adx, config=FitConfig(selection=None)).model.save(tmp_path / "m.json")
    user.write_parquet(tmp_path / "user.parquet")
    argv = ["report", "--model", str(tmp_path / "m.json"), "--data", str(tmp_path / "user.parquet"),
            "--qualified", str(adx), "--aircraft", str(toml), "--replays", "1", "--no-svg",
            "--no-progress", "--out", str(tmp_path / "rep")]  # fmt: skip
    capsys.readouterr()
    assert main(argv) == 0, capsys.readouterr().err
    html = (tmp_path / "rep" / "report.html").read_text()
    assert "your DAVE-ML model</b> adx37.dml" in html and "Replay not run" not in html
    assert "6-DOF replay of m000_f00_straight_p" in html


def test_daveml_replay_moves_the_models_moments_to_the_cg(tmp_path: Path) -> None:
    """A DAVE-ML model's moments are about its moment reference centre: with the CG at
    d from it (aircraft file ``cg_m`` − ``moment_ref_m``) the replay takes
    ``M_cg = M_ref − d × F``. Reference: the same model with its moment tables transferred to
    the CG by hand (``Cl − (d_y C_Z − d_z C_Y)/b``, ``Cm − (d_z C_X − d_x C_Z)/c̄``,
    ``Cn − (d_x C_Y − d_y C_X)/b``, exact at the breakpoints and so everywhere for linear
    tables) flown with the CG at its reference centre."""
    import dataclasses  # noqa: PLC0415

    from aerodelta.aircraft import Aircraft  # noqa: PLC0415

    toml = tmp_path / "aircraft.toml"
    toml.write_text(ad.campaign.aircraft_toml())
    base = Aircraft.from_toml(toml)
    b, c = base.b_m, base.cbar_m
    d = np.array([0.3, 0.05, -0.1])
    alpha = [-10.0, 0.0, 10.0, 20.0, 30.0]
    f = {
        "CX": np.array([-0.05, 0.0, 0.05, 0.04, 0.0]),
        "CY": np.array([0.01, 0.02, 0.03, 0.02, 0.01]),
        "CZ": np.array([0.8, -0.2, -1.0, -1.4, -1.2]),
        "Cl": np.array([0.001, 0.0, -0.001, 0.002, 0.0]),
        "Cm": np.array([0.05, 0.02, -0.03, -0.06, -0.08]),
        "Cn": np.array([0.0, 0.001, 0.002, 0.0, -0.001]),
    }
    moved = dict(f)
    moved["Cl"] = f["Cl"] - (d[1] * f["CZ"] - d[2] * f["CY"]) / b
    moved["Cm"] = f["Cm"] - (d[2] * f["CX"] - d[0] * f["CZ"]) / c
    moved["Cn"] = f["Cn"] - (d[0] * f["CY"] - d[1] * f["CX"]) / b

    def write(path: Path, tables: dict[str, np.ndarray]) -> Path:
        defs = "".join(
            f'<variableDef name="{k}" varID="{k}" units="nd"><isOutput/></variableDef>'
            for k in tables
        )
        fns = "".join(
            f'<function name="{k}_fn"><independentVarPts varID="alpha_deg">'
            f'{", ".join(map(repr, alpha))}</independentVarPts><dependentVarPts varID="{k}">'
            f"{', '.join(map(repr, v.tolist()))}</dependentVarPts></function>"
            for k, v in tables.items()
        )
        path.write_text(
            '<?xml version="1.0"?>\n<DAVEfunc xmlns="http://daveml.org/2010/DAVEML">'
            '<fileHeader><author name="test" org="t"/><creationDate date="2026-11-26"/>'
            '</fileHeader><variableDef name="alpha" varID="alpha_deg" units="deg"/>'
            + defs + fns + "</DAVEfunc>"
        )  # fmt: skip
        return path

    about_ref, about_cg = write(tmp_path / "ref.dml", f), write(tmp_path / "cg.dml", moved)
    off = dataclasses.replace(base, cg_m=tuple(d), moment_ref_m=(0.0, 0.0, 0.0))
    on = dataclasses.replace(base, cg_m=tuple(d), moment_ref_m=tuple(d))
    x0 = [60.0, 1.0, 4.0, 0.02, 0.0, 0.01, 0.05, 0.06, 0.0, 0.0, 0.0, 1500.0]
    n = 300
    controls = np.column_stack([np.linspace(0, 5, n), np.zeros(n), np.linspace(0, -3, n),
                                np.zeros(n), np.zeros(n)])  # fmt: skip
    ct = np.full((n, 2), 0.1)
    got = daveml_flyer(about_ref, off)(0.0, x0, 0.01, controls, ct, None)
    want = daveml_flyer(about_cg, on)(0.0, x0, 0.01, controls, ct, None)
    assert np.all(np.isfinite(want))
    scale = np.maximum(np.ptp(want, axis=0), 1.0)
    assert np.max(np.abs(got - want) / scale) < 1e-12
    # the check can fail: the same model with its centre taken as the CG flies differently
    wrong = daveml_flyer(about_ref, on)(0.0, x0, 0.01, controls, ct, None)
    assert np.max(np.abs(wrong - want) / scale) > 1e-4
