"""The CLI takes the user's layout (issue 18, item 2): a small virtual campaign rewritten as a
user would hold it (CSV, time in ms, angles and rates in radians, airspeed in knots, load
factors in g with z up, density in slug/ft³, altitude in ft, own column names, the manifest
and aircraft file elsewhere, a channel map), then every command that reads records run on it
and on the output of ``aerodelta ingest``; ``map-template`` guesses the map back; bad options
and paths give one line in the command's terms and write nothing."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta._fsutil import write_atomic
from aerodelta.cli import main
from aerodelta.cli._data import maneuver_ids
from aerodelta.map_template import guess_channel, map_template

R2D = 180.0 / np.pi
G0 = 9.80665
KT = 1852.0 / 3600.0
FT = 0.3048
SLUG_FT3 = 515.3788183931961

#: user column -> (canonical channel, user value = canonical value * factor)
LAYOUT = {
    "time_ms": ("t", 1000.0),
    "aoa_rad": ("alpha_deg", 1 / R2D),
    "Sideslip": ("beta_deg", 1 / R2D),
    "rollRate": ("p_dps", 1 / R2D),
    "pitchRate": ("q_dps", 1 / R2D),
    "yawRate": ("r_dps", 1 / R2D),
    "BANK": ("phi_deg", 1 / R2D),
    "PITCH": ("theta_deg", 1 / R2D),
    "HDG": ("psi_deg", 1 / R2D),
    "NX": ("ax_mps2", 1 / G0),
    "NY": ("ay_mps2", 1 / G0),
    "NZ": ("az_mps2", -1 / G0),  # load factor, z up
    "KTAS": ("tas_mps", 1 / KT),
    "Rho": ("rho_kgm3", 1 / SLUG_FT3),
    "alt_ft": ("h_m", 1 / FT),
    "Aileron": ("da_deg", 1.0),
    "Elevator": ("de_deg", 1.0),
    "Rudder": ("dr_deg", 1.0),
    "SpoilerL": ("dsl_deg", 1.0),
    "SpoilerR": ("dsr_deg", 1.0),
    "Flap": ("flap_deg", 1.0),
    "CT_L": ("ct_left", 1.0),
    "CT_R": ("ct_right", 1.0),
    "PropSpeed": ("prop_rpm", 1.0),
}

#: The map the user writes for that layout (what map-template must guess).
MAP = {
    "t": ("time_ms", "ms", 1.0),
    "alpha_deg": ("aoa_rad", "rad", 1.0),
    "beta_deg": ("Sideslip", "rad", 1.0),
    "p_dps": ("rollRate", "rad/s", 1.0),
    "q_dps": ("pitchRate", "rad/s", 1.0),
    "r_dps": ("yawRate", "rad/s", 1.0),
    "phi_deg": ("BANK", "rad", 1.0),
    "theta_deg": ("PITCH", "rad", 1.0),
    "psi_deg": ("HDG", "rad", 1.0),
    "ax_mps2": ("NX", "g", 1.0),
    "ay_mps2": ("NY", "g", 1.0),
    "az_mps2": ("NZ", "g", -1.0),
    "tas_mps": ("KTAS", "kt", 1.0),
    "rho_kgm3": ("Rho", "slug/ft3", 1.0),
    "h_m": ("alt_ft", "ft", 1.0),
    "da_deg": ("Aileron", "deg", 1.0),
    "de_deg": ("Elevator", "deg", 1.0),
    "dr_deg": ("Rudder", "deg", 1.0),
    "dsl_deg": ("SpoilerL", "deg", 1.0),
    "dsr_deg": ("SpoilerR", "deg", 1.0),
    "flap_deg": ("Flap", "deg", 1.0),
    "ct_left": ("CT_L", "-", 1.0),
    "ct_right": ("CT_R", "-", 1.0),
    "prop_rpm": ("PropSpeed", "rpm", 1.0),
}


def _map_toml() -> str:
    lines = ["[channels]"]
    for ch, (src, unit, scale) in MAP.items():
        extra = f", scale = {scale}" if scale != 1.0 else ""
        lines.append(f'{ch} = {{ source = "{src}", unit = "{unit}"{extra} }}')
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def layout(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The canonical campaign and the same records in the user's layout."""
    root = tmp_path_factory.mktemp("cli_layout")
    camp = root / "camp"
    ad.generate_campaign(camp, seed=4, size="quick", progress=False)
    user = root / "user"
    (user / "flights").mkdir(parents=True)
    meta = root / "meta"
    meta.mkdir()
    man = pl.read_csv(camp / "manifest.csv")
    for mid in man["maneuver_id"]:
        rec = pl.read_parquet(camp / "records" / f"{mid}.parquet")
        cols = {name: rec[c].to_numpy() * f for name, (c, f) in LAYOUT.items()}
        pl.DataFrame(cols).write_csv(user / "flights" / f"{mid}.csv")
    man.with_columns(pl.format("flights/{}.csv", "maneuver_id").alias("file")).select(
        "maneuver_id", "flap_deg", "kind", "pusher", "file"
    ).write_csv(meta / "maneuvers.csv")
    (meta / "plane.toml").write_text((camp / "aircraft.toml").read_text())
    (meta / "map.toml").write_text(_map_toml())
    return {
        "root": root,
        "camp": camp,
        "user": user,
        "manifest": meta / "maneuvers.csv",
        "aircraft": meta / "plane.toml",
        "map": meta / "map.toml",
    }


def _user_args(lay: dict[str, Path]) -> list[str]:
    return [
        str(lay["user"]),
        "--map", str(lay["map"]),
        "--aircraft", str(lay["aircraft"]),
        "--manifest", str(lay["manifest"]),
    ]  # fmt: skip


@pytest.fixture(scope="module")
def fitted(layout: dict[str, Path]) -> Path:
    """``aerodelta fit`` on the user's layout with a held-out fifth; the model path."""
    out = layout["root"] / "fit" / "deep" / "model.json"  # folders created by the command
    argv = ["fit", *_user_args(layout), "--out", str(out), "--holdout", "0.25", "--no-progress"]
    assert main(argv) == 0
    return out


@pytest.fixture(scope="module")
def ingested(layout: dict[str, Path]) -> Path:
    """``aerodelta ingest`` of the user's layout, compatibility check on (writes compat.csv)."""
    out = layout["root"] / "ingested"
    assert main(["ingest", *_user_args(layout), "--out", str(out), "--quiet"]) == 0
    assert (out / "compat.csv").is_file()
    return out


def test_the_user_layout_ingests_to_the_canonical_records(layout: dict[str, Path]) -> None:
    user = ad.ingest(
        layout["user"],
        aircraft=layout["aircraft"],
        channel_map=layout["map"],
        manifest=layout["manifest"],
        compat=False,
        progress=False,
    ).data
    canon = ad.ingest(layout["camp"], compat=False, progress=False).data
    assert user.height == canon.height
    for c in ("Cl_meas", "Cn_meas", "CY_meas", "alpha_cg_deg", "az_mps2", "tas_mps", "t"):
        np.testing.assert_allclose(user[c].to_numpy(), canon[c].to_numpy(), rtol=0, atol=1e-9)


def test_fit_takes_map_aircraft_manifest_and_holds_out(
    layout: dict[str, Path], fitted: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert fitted.is_file() and fitted.with_suffix(".params.parquet").is_file()
    held = maneuver_ids("@" + str(fitted.with_suffix(".holdout.txt")))
    man = pl.read_csv(layout["manifest"])
    # a quarter of each flap's eight maneuvers, the same draw for the same seed
    assert len(held) == 10 and set(held) <= set(man["maneuver_id"])
    per_flap = man.filter(pl.col("maneuver_id").is_in(held)).group_by("flap_deg").len()
    assert sorted(per_flap["len"].to_list()) == [2] * 5
    val = pl.read_csv(fitted.with_suffix(".validation.csv"))
    assert val["coefficient"].sort().to_list() == ["CY", "Cl", "Cn"]
    assert (val["tic_ratio"] > 0).all() and (
        val.filter(pl.col("coefficient") == "Cn")["tic_ratio"] < 1
    ).all()
    model = ad.DeltaModel.load(fitted)
    assert model.to_spec()["provenance"]["maneuvers"] == 30


def test_validate_prints_the_held_out_table(
    layout: dict[str, Path], fitted: Path, ingested: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    held = "@" + str(fitted.with_suffix(".holdout.txt"))
    capsys.readouterr()
    argv = ["validate", "--model", str(fitted), *_user_args(layout), "--held-out", held]
    assert main([*argv, "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "on 10 maneuvers" in out and "TIC qual" in out and "ratio" in out
    rows = {ln.split()[0] for ln in out.splitlines()[2:5]}
    assert rows == {"CY", "Cl", "Cn"}
    # the same numbers from the ingest output, as JSON, and equal to what fit --holdout wrote
    csv = ingested.parent / "v" / "validation.csv"
    argv = ["validate", "--model", str(fitted), "--data", str(ingested), "--held-out", held]
    assert main([*argv, "--json", "--out", str(csv)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["maneuvers"] == 10
    want = pl.read_csv(fitted.with_suffix(".validation.csv")).sort("coefficient")
    got = pl.DataFrame(doc["coefficients"]).sort("coefficient")
    np.testing.assert_allclose(got["tic_ratio"].to_numpy(), want["tic_ratio"].to_numpy(), rtol=1e-9)
    assert {"rms_ratio", "tic_ratio"} <= set(got.columns)
    assert pl.read_csv(csv).height == 3


def test_ingest_output_goes_to_every_command(
    layout: dict[str, Path], fitted: Path, ingested: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = layout["root"]
    # fit reads data.parquet, never compat.csv as a flight record
    model = root / "from_ingest" / "model.json"
    assert main(["fit", str(ingested), "--out", str(model), "--no-progress"]) == 0
    assert model.is_file()
    d = root / "diag"
    assert main(["diagnose", str(ingested), "--out", str(d), "--folds", "3", "--no-progress"]) == 0
    assert (d / "diagnosis.json").is_file()
    r = root / "ro"
    argv = ["rolloff", *_user_args(layout), "--out", str(r), "--no-figures", "--no-progress"]
    assert main(argv) == 0
    assert (r / "events.csv").is_file()
    rep = root / "rep"
    argv = ["report", "--model", str(fitted), "--data", str(ingested), "--out", str(rep)]
    held = "@" + str(fitted.with_suffix(".holdout.txt"))
    assert main([*argv, "--replays", "0", "--no-svg", "--no-progress", "--held-out", held]) == 0
    assert (rep / "report.html").is_file()
    capsys.readouterr()


def test_map_template_guesses_the_layout_and_round_trips(
    layout: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rec = sorted((layout["user"] / "flights").glob("*straight*.csv"))[0]
    out = tmp_path / "maps" / "map.toml"
    assert main(["map-template", str(rec), "-o", str(out)]) == 0
    text = out.read_text()
    entries = [ln for ln in text.splitlines() if re.match(r"^\w+ = \{", ln)]
    assert len(entries) == len(MAP) and all("# REVIEW: " in ln for ln in entries)
    # unreviewed, the loader refuses it and says exactly which lines to review
    with pytest.raises(ad.DataError) as e:
        ad.ChannelMap.from_toml(out)
    msg = str(e.value)
    assert f"{len(MAP)} guess(es)" in msg and "'# REVIEW' mark" in msg and "\n" not in msg
    assert "line 9 t," in msg and "alpha_deg" in msg
    # ... and so does every command given it
    capsys.readouterr()
    argv = ["fit", str(layout["user"]), "--map", str(out), "--aircraft", str(layout["aircraft"])]
    assert main([*argv, "--out", str(tmp_path / "m.json")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not reviewed yet" in err
    assert not (tmp_path / "m.json").exists()
    # deleting nothing but the marks gives a map equal to the user's own
    out.write_text(re.sub(r"\s*# REVIEW:.*", "", text))
    cmap = ad.ChannelMap.from_toml(out)
    got = {e.name: (e.source, e.unit, e.scale) for e in cmap.entries}
    assert got == MAP
    # refuses to replace it without --force
    assert main(["map-template", str(rec), "-o", str(out)]) == 1
    assert "--force" in capsys.readouterr().err
    assert main(["map-template", str(rec), "-o", str(out), "--force"]) == 0


def test_map_template_parquet_units_and_names(tmp_path: Path) -> None:
    t = np.arange(0.0, 30.0, 0.02)
    w = np.sin(0.7 * t)
    rec = pl.DataFrame(
        {
            "Time": t,  # seconds
            "alpha": 12 + 5 * w,  # deg
            "beta_deg": 3 * w,
            "P": 10 * w,  # deg/s
            "Q": 5 * w,
            "R": 5 * w,
            "az": -G0 + 2 * w,  # m/s2, z down
            "Ax_ftps2": 3 * w,  # ft/s2 by name
            "ay": 0.5 * w,
            "TAS": 60 + 3 * w,  # m/s
            "OAT": 5 + w,  # degC
            "run": ["a"] * len(t),
            "mystery": w,
        }
    )
    rec.write_parquet(tmp_path / "r.parquet")
    tpl = map_template(tmp_path / "r.parquet")
    units = {g.channel: (g.unit, g.scale) for g in tpl.mapped}
    assert units["t"] == ("s", 1.0)
    assert units["alpha_deg"] == ("deg", 1.0) and units["beta_deg"] == ("deg", 1.0)
    assert units["p_dps"] == ("deg/s", 1.0)
    assert units["az_mps2"] == ("m/s2", 1.0) and units["ay_mps2"] == ("m/s2", 1.0)
    assert units["ax_mps2"] == ("ft/s2", 1.0)
    assert units["tas_mps"][0] == "m/s" and units["sat_k"] == ("degC", 1.0)
    left = {g.column: g.note for g in tpl.guesses if g.note}
    assert set(left) == {"run", "mystery"} and "not numeric" in left["run"]
    assert set(tpl.missing_required()) >= {"phi_deg", "da_deg"}
    text = tpl.to_toml()
    assert '# phi_deg = { source = "?"' in text and '# "mystery": name not recognised' in text


def test_guess_channel_names() -> None:
    assert guess_channel("rollRate_rad_s") == ("p_dps", "rad/s")
    assert guess_channel("alt_ft") == ("h_m", "ft")
    assert guess_channel("NZ_g") == ("az_mps2", "g")
    assert guess_channel("PSI") == ("psi_deg", None)
    assert guess_channel("ps_psi") == ("ps_pa", "psi")
    assert guess_channel("Cl_sim") == ("Cl_sim", "-")


def _one_line_error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    capsys.readouterr()
    assert main(argv) == 1, argv
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"aerodelta {argv[0]}: error: ")
    for api in ("aircraft=", "channel_map=", "manifest=", ".tmp-", "Traceback"):
        assert api not in err, err
    return err


def test_bad_options_and_paths_give_one_line_and_write_nothing(
    layout: dict[str, Path], ingested: Path, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    user = str(layout["user"])
    ing = str(ingested)
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    only_compat = tmp_path / "half_ingest"
    only_compat.mkdir()
    (only_compat / "compat.csv").write_text("maneuver_id,parameter\n")
    new = tmp_path / "new"
    cases: list[tuple[list[str], str]] = [
        (["fit", user, "--out", str(new / "m.json")], "give --aircraft FILE"),
        (["fit", ing, "--map", str(layout["map"]), "--out", "m.json"], "--map applies to raw"),
        (["fit", ing, "--aircraft", str(layout["aircraft"]), "--out", "m.json"], "drop it"),
        (["fit", str(only_compat), "--out", "m.json"], "no data.parquet"),
        (["fit", user, "--map", str(tmp_path / "nope.toml"), "--out", "m.json"], "--map"),
        (["fit", ing, "--out", str(tmp_path)], "is a folder; give a file name"),
        (["fit", ing, "--out", str(a_file / "m.json")], "is a file, not a folder"),
        (["fit", ing, "--out", str(new / "m.json"), "--holdout", "0"], "--holdout 0"),
        (["fit", ing, "--out", str(new / "m.json"), "--holdout", "1.5"], "between 0 and 1"),
        (["fit", "--out", str(new / "m.json")], "no data"),
        (["fit", user, "--data", ing, "--out", str(new / "m.json")], "given twice"),
        (["diagnose", ing, "--out", str(new), "--folds", "1"], "--folds 1: must be at least 2"),
        (["diagnose", ing, "--out", str(new), "--folds", "0"], "--folds 0"),
        (["diagnose", ing, "--out", str(new), "--alpha", "5"], "--alpha 5"),
        (["diagnose", ing, "--out", str(a_file)], "is a file; give a folder"),
        (["diagnose", str(layout["camp"] / "truth"), "--out", str(new)], "truth"),
        (["rolloff", ing, "--out", str(new), "--level", "95"], "--level 95"),
        (["rolloff", ing, "--out", str(a_file)], "is a file"),
        (["report", "--model", str(tmp_path / "no.json"), ing, "--out", str(new)], "--model"),
        (["validate", "--model", str(tmp_path / "no.json"), ing], "--model"),
        (["ingest", ing, "--out", str(new)], "already an aerodelta ingest output"),
        (["ingest", *_user_args(layout), "--out", user], "campaign folder itself"),
        (["map-template", str(tmp_path / "none.csv")], "file not found"),
        (["diagnose", ing, "--out", str(new), "--seed", "-1"], "--seed -1"),
        (
            ["fit", ing, "--out", str(new / "m.json"), "--holdout", "0.2", "--holdout-seed", "-1"],
            "--holdout-seed -1",
        ),
        (["campaign", "--out", ing, "--quick"], "give --overwrite"),
        (["demo", "--out", str(a_file), "--quick"], "is a file"),
    ]
    for argv, want in cases:
        err = _one_line_error(capsys, argv)
        assert want in err, (argv, err)
    assert not new.exists(), "a refused command created its output"
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    header = tmp_path / "header.csv"
    header.write_text("time_ms,aoa_rad\n")
    assert "cannot read the record" in _one_line_error(capsys, ["map-template", str(empty)])
    assert "no data rows" in _one_line_error(capsys, ["map-template", str(header)])


def test_a_three_maneuver_fit_fails_without_writing_a_model(
    layout: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    few = tmp_path / "three.csv"
    pl.read_csv(layout["manifest"]).head(3).write_csv(few)
    out = tmp_path / "m.json"
    argv = ["fit", str(layout["user"]), "--map", str(layout["map"])]
    argv += ["--aircraft", str(layout["aircraft"]), "--manifest", str(few), "--out", str(out)]
    err = _one_line_error(capsys, [*argv, "--no-progress"])
    assert "too little data" in err
    assert not out.exists() and not out.with_suffix(".params.parquet").exists()


def test_write_atomic_names_the_file_not_its_temporary(tmp_path: Path) -> None:
    target = tmp_path / "missing" / "data.csv"
    with pytest.raises(OSError) as e:
        write_atomic(target, pl.DataFrame({"a": [1]}).write_csv)
    assert str(target) in str(e.value) and ".tmp-" not in str(e.value)


def test_export_creates_its_folder(fitted: Path, tmp_path: Path) -> None:
    out = tmp_path / "a" / "b" / "delta.xml"
    assert main(["export", "--model", str(fitted), "--jsbsim", str(out)]) == 0
    assert out.is_file()


def test_exit_status_and_one_line_in_a_real_process(layout: dict[str, Path]) -> None:
    r = subprocess.run(
        [sys.executable, "-m", "aerodelta", "diagnose", str(layout["user"]), "--out", "x",
         "--alpha", "5"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert r.returncode == 1
    assert r.stderr.strip() == (
        "aerodelta diagnose: error: --alpha 5: must lie strictly between 0 and 1 "
        "(e.g. --alpha 0.01)"
    )
