"""`aerodelta fit` and `aerodelta demo` run in-process and write what they say."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import polars as pl
import pytest

import aerodelta as ad
from aerodelta.cli import main
from aerodelta.report.context import load_params


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
    # the model file, written last, names its per-bin estimates by hash: a table from another
    # fit (or a fit stopped between the two renames) is refused where it is read
    assert load_params(out) is not None
    params = out.with_suffix(".params.parquet")
    pl.read_parquet(params).head(10).write_parquet(params)
    with pytest.raises(ad.DataError, match=r"not the ones model.json was fitted with"):
        load_params(out)
    bad = tmp_path / "bad.toml"
    bad.write_text("nonsense = 3\n")
    rc = main(["fit", "--data", str(camp), "--config", str(bad), "--out", str(out)])
    assert rc == 1
    assert "unknown setting 'nonsense'" in capsys.readouterr().err


def test_cli_start_up_does_not_load_matplotlib() -> None:
    # the parser imports every subcommand module; the figures' library loads only when a
    # command that draws runs (it cost about 0.2 s on every call)
    code = (
        "import sys, aerodelta.cli as c; c.build_parser(); "
        "sys.exit(1 if 'matplotlib' in sys.modules else 0)"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
