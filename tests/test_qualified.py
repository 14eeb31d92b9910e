"""The qualified model is named, never guessed (issue 19, item 3).

Data not flown on the built-in virtual aircraft and without the simulator's ``*_sim`` columns
are refused by fit and diagnose; a DAVE-ML qualified model gives the fit the same Δ as the
compiled model it was exported from (two independent implementations of the same tables);
the fitted model records what it was fitted against, and the exports refuse to add a Δ to
another aircraft's qualified model.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta.aircraft import BUILTIN_COLUMN, Aircraft
from aerodelta.cli import main
from aerodelta.exceptions import DataError
from aerodelta.fit import FitConfig, model_frame, qualified_coefficients, validate_model
from aerodelta.qualified import NO_SIMULATOR

CFG = FitConfig(selection=None)


@pytest.fixture(scope="module")
def data(quick_campaign: Path) -> pl.DataFrame:
    d = ad.ingest(quick_campaign, compat=False, progress=False).data
    return d.filter(pl.col("flap_deg") == 0.0)


@pytest.fixture(scope="module")
def qualified_dml(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("dml") / "adx37.dml"
    assert main(["export-qualified", str(path)]) == 0
    return path


def test_virtual_data_are_marked_and_fit_against_the_builtin(data: pl.DataFrame) -> None:
    assert data[BUILTIN_COLUMN].cast(pl.Utf8).unique().to_list() == ["adx37"]
    res = ad.fit(data, config=CFG)
    assert res.model.to_spec()["provenance"]["qualified"] == "adx37"


def test_unmarked_data_without_columns_are_refused(data: pl.DataFrame, tmp_path: Path) -> None:
    user = data.drop(BUILTIN_COLUMN)
    with pytest.raises(DataError) as e:
        ad.fit(user, config=CFG)
    assert str(e.value) == NO_SIMULATOR
    # the diagnosis needs the aircraft that flew them, then the simulator: both named
    with pytest.raises(DataError, match="no aircraft reference"):
        ad.diagnose(user)
    own = tmp_path / "aircraft.toml"
    own.write_text(ad.campaign.aircraft_toml().split("[simulator]")[0])
    with pytest.raises(DataError, match="no qualified model"):
        ad.diagnose(user, aircraft=own)
    # the CLI: one line, exit 1, nothing written
    user.write_parquet(tmp_path / "user.parquet")
    out = tmp_path / "out" / "model.json"
    assert main(["fit", str(tmp_path / "user.parquet"), "--out", str(out), "--no-progress"]) == 1
    assert not out.parent.exists()
    # named on purpose, the built-in model is used
    res = ad.fit(user, qualified="adx37", config=CFG)
    assert res.model.to_spec()["provenance"]["qualified"] == "adx37"


def test_a_daveml_qualified_model_gives_the_builtin_fit(
    data: pl.DataFrame, qualified_dml: Path
) -> None:
    user = data.drop(BUILTIN_COLUMN)
    a = ad.fit(data, config=CFG).params
    b = ad.fit(user, qualified=qualified_dml, config=CFG)
    assert b.model.to_spec()["provenance"]["qualified"] == "daveml:adx37.dml"
    b_params = b.params
    assert a.height == b_params.height > 0
    np.testing.assert_allclose(
        b_params["estimate"].to_numpy(), a["estimate"].to_numpy(), rtol=1e-9, atol=1e-12
    )
    # validation needs the file named again (the model records its name, not its path)
    with pytest.raises(DataError, match="pass its path"):
        validate_model(b.model, user)
    v = validate_model(b.model, user, qualified=qualified_dml)
    assert (v["tic_ratio"] < 1.0).all()


def test_exports_refuse_another_aircrafts_qualified_model(
    data: pl.DataFrame, qualified_dml: Path, tmp_path: Path
) -> None:
    boxed = data.drop(BUILTIN_COLUMN)
    q = ad.fit(boxed, qualified="adx37", config=CFG).model  # a simulator the user names
    sims = qualified_coefficients(model_frame(boxed), "adx37")
    boxed = boxed.with_columns(sims[f"{c}_qual"].alias(f"{c}_sim") for c in ("Cl", "Cn", "CY"))
    model = ad.fit(boxed, config=CFG).model
    assert model.to_spec()["provenance"]["qualified"] == "columns"
    with pytest.raises(DataError, match="not the built-in ADX-37"):
        ad.export_extended_daveml(tmp_path / "ext.dml", model)
    with pytest.raises(DataError, match="not the built-in ADX-37"):
        ad.jsbsim_xml(model, qualified=True)
    # into the user's own DAVE-ML model, and the Δ alone, they go
    ad.export_extended_daveml(tmp_path / "ext.dml", model, qualified=qualified_dml)
    assert "aerodelta" in ad.jsbsim_xml(model)
    assert q.to_spec()["provenance"]["qualified"] == "adx37"
    assert "aerodelta" in ad.jsbsim_xml(q, qualified=True)


def test_aircraft_file_builtin_is_checked() -> None:
    base = {
        "geometry": {"S_m2": 61.0, "b_m": 27.05, "cbar_m": 2.3},
        "mass": {"mass_kg": 2e4, "Ixx_kgm2": 3e5, "Iyy_kgm2": 4.5e5, "Izz_kgm2": 7.1e5,
                 "Ixz_kgm2": 1.5e4},
    }  # fmt: skip
    assert Aircraft.from_dict(base).builtin is None
    assert Aircraft.from_dict({**base, "simulator": {"builtin": "adx37"}}).builtin == "adx37"
    with pytest.raises(DataError, match=r"\[simulator\] builtin = 'f16'"):
        Aircraft.from_dict({**base, "simulator": {"builtin": "f16"}})


def test_report_does_not_replay_another_aircraft(data: pl.DataFrame) -> None:
    """The 6-DOF replay flies the built-in ADX-37: on records of another simulator the
    section says why it is not run instead of flying the wrong aircraft (issue 19 item 5)."""
    from aerodelta.plots import FigureSink  # noqa: PLC0415
    from aerodelta.report import replay  # noqa: PLC0415
    from aerodelta.report.context import build_context  # noqa: PLC0415

    boxed = data.drop(BUILTIN_COLUMN)
    sims = qualified_coefficients(model_frame(boxed), "adx37")
    boxed = boxed.with_columns(sims[f"{c}_qual"].alias(f"{c}_sim") for c in ("Cl", "Cn", "CY"))
    model = ad.fit(boxed, config=CFG).model
    sec = replay.section(build_context(model, boxed), FigureSink(None))
    text = " ".join(str(b) for b in sec.body)
    assert "Replay not run" in text and "Cl_sim" in text
    # on the virtual aircraft's own records it flies (and says nothing of the kind)
    own = ad.fit(data, config=CFG).model
    sec = replay.section(build_context(own, data), FigureSink(None), count=1)
    assert "Replay not run" not in " ".join(str(b) for b in sec.body)
