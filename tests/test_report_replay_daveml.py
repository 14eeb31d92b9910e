"""The report's 6-DOF replay section for a DAVE-ML qualified model (issue 19 item 5): it says
which of the six coefficients the user's model gives and which a replay would lack."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest

import aerodelta as ad
from aerodelta.aircraft import BUILTIN_COLUMN
from aerodelta.cli import main
from aerodelta.fit import FitConfig
from aerodelta.plots import FigureSink
from aerodelta.report import replay
from aerodelta.report.context import build_context


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
