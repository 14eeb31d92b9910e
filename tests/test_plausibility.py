"""Plausibility before fitting (issue 18, item 3): kinematic consistency decides units and
signs. A quick virtual campaign is rewritten with one unit mistake at a time (the values in
one unit, the declaration in another); ingestion and ``aerodelta ingest`` refuse each with one
line naming the channel and the likely cause. The clean campaign passes with no warning."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta import DataError
from aerodelta.cli import main

R2D = 180.0 / np.pi
G0 = 9.80665
KT = 1852.0 / 3600.0
FT = 0.3048

#: mistake -> ({channel: factor on the canonical values}, channel named, cause named)
MISTAKES = {
    "beta_rad_as_deg": ({"beta_deg": 1 / R2D}, "beta_deg", "radians declared as degrees"),
    "alpha_rad_as_deg": ({"alpha_deg": 1 / R2D}, "alpha_deg", "radians declared as degrees"),
    "knots_as_mps": ({"tas_mps": 1 / KT}, "tas_mps", "knots declared as m/s"),
    "ft_as_m": ({"h_m": 1 / FT}, "h_m", "ft declared as m"),
    "g_as_mps2": (
        {"ax_mps2": 1 / G0, "ay_mps2": 1 / G0, "az_mps2": 1 / G0},
        "az_mps2",
        "g declared as m/s²",
    ),
    "az_sign": ({"az_mps2": -1.0}, "az_mps2", "sign reversed"),
}

#: maneuvers of the quick campaign used for the mistaken variants (the check is pooled)
SUBSET = 12


@pytest.fixture(scope="module")
def camp(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("plaus")
    out = root / "camp"
    ad.generate_campaign(out, seed=11, size="quick", progress=False)
    return out


def _variant(camp: Path, dest: Path, factors: dict[str, float]) -> Path:
    """The first SUBSET maneuvers with ``factors`` applied (declared units unchanged)."""
    (dest / "records").mkdir(parents=True)
    man = pl.read_csv(camp / "manifest.csv").head(SUBSET)
    man.write_csv(dest / "manifest.csv")
    (dest / "aircraft.toml").write_text((camp / "aircraft.toml").read_text())
    for mid in man["maneuver_id"]:
        rec = pl.read_parquet(camp / "records" / f"{mid}.parquet")
        rec = rec.with_columns(pl.col(c) * f for c, f in factors.items())
        rec.write_parquet(dest / "records" / f"{mid}.parquet")
    return dest


def test_clean_campaign_passes_without_warnings(camp: Path) -> None:
    res = ad.ingest(camp, progress=False)
    warnings = [f for r in res.reports for f in r.findings if f.severity == "warning"]
    assert warnings == [], [str(w) for w in warnings[:5]]
    est = res.plausibility
    assert est is not None
    judged = est.filter(pl.col("verdict") != "not_judged")
    assert set(judged["check"]) >= {"az", "ax", "tas", "alpha", "beta", "h"}
    assert (judged["verdict"] == "plausible").all()
    # the pooled scales are near 1, well inside the 0.8-1.25 band
    for row in judged.iter_rows(named=True):
        assert 0.9 < row["k"] < 1.1, row


@pytest.mark.parametrize("mistake", list(MISTAKES))
def test_unit_mistake_refused_naming_channel_and_cause(
    camp: Path, tmp_path: Path, mistake: str
) -> None:
    factors, channel, cause = MISTAKES[mistake]
    d = _variant(camp, tmp_path / mistake, factors)
    with pytest.raises(DataError) as ei:
        ad.ingest(d, progress=False)
    lines = [ln for ln in str(ei.value).splitlines() if f"'{channel}'" in ln]
    assert len(lines) == 1, str(ei.value)
    assert cause in lines[0], str(ei.value)


def test_cli_ingest_refuses_knots_in_the_users_layout(
    camp: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the user's CSV holds knots under their own name; the map declares m/s
    d = tmp_path / "user"
    (d / "flights").mkdir(parents=True)
    man = pl.read_csv(camp / "manifest.csv").head(SUBSET)
    for mid in man["maneuver_id"]:
        rec = pl.read_parquet(camp / "records" / f"{mid}.parquet")
        rec.with_columns((pl.col("tas_mps") / KT).alias("KTAS")).drop("tas_mps").write_csv(
            d / "flights" / f"{mid}.csv"
        )
    man.with_columns(pl.format("flights/{}.csv", "maneuver_id").alias("file")).write_csv(
        d / "manifest.csv"
    )
    (d / "aircraft.toml").write_text((camp / "aircraft.toml").read_text())
    (d / "map.toml").write_text('[channels]\ntas_mps = { source = "KTAS", unit = "m/s" }\n')
    out = tmp_path / "out"
    rc = main(["ingest", str(d), "--map", str(d / "map.toml"), "--out", str(out), "--quiet"])
    assert rc != 0
    err = capsys.readouterr().err
    hits = [ln for ln in err.splitlines() if "'tas_mps'" in ln]
    assert len(hits) == 1, err
    assert "column 'KTAS'" in hits[0] and "knots declared as m/s" in hits[0]
    assert 'set unit = "kt"' in hits[0]
    m = re.search(r"reads ([\d.]+)x", hits[0])
    assert m and float(m.group(1)) == pytest.approx(1 / KT, rel=0.1)
    assert not (out / "data.parquet").exists()
    # the user may skip the check (records whose kinematics it cannot read); then the records
    # go through, and the option means nothing for an ingest output
    rc = main(
        ["ingest", str(d), "--map", str(d / "map.toml"), "--out", str(out), "--quiet",
         "--no-plausibility"]
    )  # fmt: skip
    assert rc == 0 and (out / "data.parquet").exists()
    capsys.readouterr()
    assert main(["fit", str(out), "--out", str(tmp_path / "m.json"), "--no-plausibility"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--no-plausibility applies to raw records" in err[0], err


def test_cli_ingest_clean_campaign_prints_no_warning(
    camp: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["ingest", str(camp), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "warning" not in out
