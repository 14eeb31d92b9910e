"""`aerodelta fit` and `aerodelta demo` run in-process and write what they say."""

from __future__ import annotations

from pathlib import Path

import pytest

import aerodelta as ad
from aerodelta.cli import main


def test_demo_quick_writes_model_and_validation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["demo", "--quick", "--seed", "2", "--no-progress", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "held-out maneuvers" in out and "Cl" in out
    assert "explained" in out, "the demo reports recovery against the truth"
    m = ad.DeltaModel.load(tmp_path / "model.json")
    assert m.coefficients == ["CY", "Cl", "Cn"]
    assert (tmp_path / "validation.csv").exists()


def test_fit_cli_and_bad_config(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    camp = tmp_path / "camp"
    ad.generate_campaign(camp, seed=4, size="quick", progress=False)
    out = tmp_path / "m" / "model.json"
    assert main(["fit", "--data", str(camp), "--out", str(out), "--no-progress"]) == 0
    assert out.exists() and out.with_suffix(".params.parquet").exists()
    assert "identified" in capsys.readouterr().out
    bad = tmp_path / "bad.toml"
    bad.write_text("nonsense = 3\n")
    rc = main(["fit", "--data", str(camp), "--config", str(bad), "--out", str(out)])
    assert rc == 1
    assert "unknown setting 'nonsense'" in capsys.readouterr().err
