"""Bad inputs to every command and file type (issue 18, floor 2): each is refused with exit
status 1 (2 for argument syntax) and ONE line on stderr that starts ``aerodelta CMD: error:``
and names the file, channel, row or option at fault, in the command's words; or, for the few
valid but unusual inputs, accepted. In every case no input byte changes and nothing is left
half-written: a refused command creates no file or folder at all, an accepted one only the
outputs it names (no ``.tmp-`` files).

The cases run the CLI in-process (:func:`aerodelta.cli.main`); the crash class (20,000-deep
expressions, deep MathML, entity expansion) runs in a child interpreter so a stack overflow or
memory blow-up fails the test with the child's status instead of killing pytest.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import subprocess
import sys
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import pytest

import aerodelta
from _bad_inputs import (
    Case,
    build_fixtures,
    case,
    csv_lines,
    first_record,
    frame_edit,
    judge,
    prepare,
    replace_text,
    run_main,
    set_cell,
    snapshot,
)
from aerodelta.daveml import load_daveml
from aerodelta.model import DeltaModel

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def bases(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The fixture bases, built once for the module."""
    return build_fixtures(tmp_path_factory.mktemp("bad_inputs_bases"))


# ---- edits -------------------------------------------------------------------------------

ING = "ingest {csv} --out {out} --quiet --no-compat"
ING_CAMP = "ingest {camp} --out {out} --quiet --no-compat"
ING_USER = "ingest {user} --map {user}/map.toml --out {out} --quiet --no-compat --no-plausibility"
FIT = "fit {ing} --out {out}/m.json --no-progress"
FIT_CFG = "fit {ing} --config {cfg}/fit.toml --out {out}/m.json --no-progress"
VALIDATE = "validate --model {model}/model.json {ing} --no-progress"
EXPORT = "export --model {model}/model.json --jsbsim {out}/delta.xml"
CHECK = "check-daveml {dml}/example.dml"
DIAG = "diagnose {ing} --out {out} --no-progress"


#: What a case does to its copy of the inputs, and what an accepted case's outputs must hold.
Setup = Callable[[Path], object]
Check = Callable[[Path], list[str]]
FrameEdit = Callable[[pl.DataFrame], pl.DataFrame]


def _rec(d: Path, base: str = "csv", suffix: str = ".csv") -> Path:
    return first_record(d, base, suffix)


def _csv(edit: Callable[[list[str]], list[str]]) -> Setup:
    return lambda d: csv_lines(_rec(d), edit)


def _cell(column: str, row: int, value: str, base: str = "csv") -> Setup:
    return lambda d: set_cell(_rec(d, base), column, row, value)


def _frame(edit: FrameEdit, base: str = "csv", suffix: str = ".csv") -> Setup:
    return lambda d: frame_edit(_rec(d, base, suffix), edit)


def _pq(edit: FrameEdit) -> Setup:
    return _frame(edit, "camp", ".parquet")


def _write(rel: str, content: str | bytes) -> Setup:
    def go(d: Path) -> None:
        p = d / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            p.write_bytes(content)
        else:
            p.write_text(content)

    return go


def _replace(rel: str, old: str, new: str) -> Setup:
    return lambda d: replace_text(d / rel, old, new)


def _append(rel: str, text: str) -> Setup:
    def go(d: Path) -> None:
        p = d / rel
        p.write_text(p.read_text() + text)

    return go


def _json(edit: Callable[[dict[str, Any]], object]) -> Setup:
    def go(d: Path) -> None:
        p = d / "model" / "model.json"
        doc = json.loads(p.read_text())
        edit(doc)
        p.write_text(json.dumps(doc))

    return go


def _manifest(edit: FrameEdit, base: str = "camp") -> Setup:
    def go(d: Path) -> None:
        p = d / base / "manifest.csv"
        edit(pl.read_csv(p)).write_csv(p)

    return go


def _truncate(rel_or_fn: str | Callable[[Path], Path], keep: float) -> Setup:
    def go(d: Path) -> None:
        p = rel_or_fn(d) if callable(rel_or_fn) else d / rel_or_fn
        data = p.read_bytes()
        p.write_bytes(data[: int(len(data) * keep)])

    return go


def _both(*fns: Setup) -> Setup:
    def go(d: Path) -> None:
        for f in fns:
            f(d)

    return go


def _long_record(rows: int) -> Setup:
    """The first CSV record repeated to ``rows`` rows (time continued at its step), past the
    rows polars infers column types from."""

    def go(d: Path) -> None:
        rec = pl.read_csv(_rec(d))
        big = pl.concat([rec] * (rows // rec.height + 1)).head(rows)
        dt = float(rec["t"][1] - rec["t"][0])
        big.with_columns(t=pl.int_range(rows, eager=False) * dt).write_csv(_rec(d))

    return go


def _one_file() -> Setup:
    """The CSV campaign's records as one file ``records/all.csv`` split by ``maneuver_id``."""

    def go(d: Path) -> None:
        files = sorted((d / "csv/records").glob("*.csv"))
        frames = [pl.read_csv(f).with_columns(maneuver_id=pl.lit(f.stem)) for f in files]
        pl.concat(frames).write_csv(d / "csv/records/all.csv")
        for f in files:
            f.unlink()

    return go


def _first_term(doc: dict) -> dict:
    return doc["coefficients"]["Cl"]["terms"][0]


def _set_term(key: str, value: object) -> Setup:
    return _json(lambda doc: _first_term(doc).__setitem__(key, value))


def _first_value(raw: str) -> Setup:
    """Put ``raw`` (JSON text, e.g. ``NaN``) in place of the first value of the first table."""

    def go(d: Path) -> None:
        p = d / "model" / "model.json"
        text = json.dumps(json.loads(p.read_text()))
        p.write_text(re.sub(r'"values": \[\[[^,\]]+', '"values": [[' + raw, text, count=1))

    return go


def _mkdir(rel: str) -> Setup:
    return lambda d: (d / rel).mkdir(parents=True)


def _symlink(rel: str, target: str) -> Setup:
    return lambda d: (d / rel).symlink_to(target)


def _aircraft(old: str, new: str, base: str = "camp") -> Setup:
    return _replace(f"{base}/aircraft.toml", old, new)


def _cfg(text: str) -> Setup:
    return _write("cfg/fit.toml", text)


def _map(text: str) -> Setup:
    return _write("user/map.toml", text)


def _effects(text: str | bytes) -> Setup:
    return _write("cfg/effects.toml", text)


def _dml_replace(old: str, new: str) -> Setup:
    return _replace("dml/example.dml", old, new)


R0 = "m000_f00_straight_p"  # the first maneuver (first record file of every campaign base)
CAMP_FILE = f"camp/records/{R0}.parquet"

# ---- the cases ---------------------------------------------------------------------------

CSV_RECORDS = [
    case("csv-empty-file", "csv", ING, f"{R0}.csv", setup=_write(f"csv/records/{R0}.csv", "")),
    case("csv-header-only", "csv", ING, f"{R0}.csv", setup=_csv(lambda ls: ls[:1])),
    case("csv-one-row", "csv", ING, f"{R0}.csv", setup=_csv(lambda ls: ls[:2])),
    case("csv-five-rows", "csv", ING, f"{R0}.csv", setup=_csv(lambda ls: ls[:6])),
    case("csv-text-in-alpha", "csv", ING, f"{R0}.csv", "alpha_deg",
         setup=_cell("alpha_deg", 100, "abc")),
    case("csv-text-in-time", "csv", ING, f"{R0}.csv", "'t'", setup=_cell("t", 50, "noon")),
    case("csv-text-in-last-row", "csv", ING, f"{R0}.csv", "beta_deg",
         setup=_cell("beta_deg", -1, "n/a")),
    case("csv-bool-in-numeric", "csv", ING, f"{R0}.csv", "p_dps",
         setup=_frame(lambda f: f.with_columns((pl.col("p_dps") > 0).alias("p_dps")))),
    case("csv-nan-run", "csv", ING, f"{R0}.csv", "beta_deg", "rows",
         setup=_frame(lambda f: f.with_columns(
             pl.when(pl.int_range(pl.len()).is_between(500, 700)).then(float("nan"))
             .otherwise(pl.col("beta_deg")).alias("beta_deg")))),
    case("csv-empty-cells", "csv", ING, f"{R0}.csv", "q_dps", "rows",
         setup=_frame(lambda f: f.with_columns(
             pl.when(pl.int_range(pl.len()).is_between(300, 600)).then(None)
             .otherwise(pl.col("q_dps")).alias("q_dps")))),
    case("csv-inf", "csv", ING, f"{R0}.csv", "r_dps", "rows",
         setup=_cell("r_dps", 42, "inf")),
    case("csv-all-nan-column", "csv", ING, f"{R0}.csv", "theta_deg",
         setup=_frame(lambda f: f.with_columns(pl.lit(float("nan")).alias("theta_deg")))),
    case("csv-missing-channel", "csv", ING, f"{R0}.csv", "beta_deg",
         setup=_frame(lambda f: f.drop("beta_deg"))),
    case("csv-missing-time", "csv", ING, f"{R0}.csv", "'t'",
         setup=_frame(lambda f: f.drop("t"))),
    case("csv-duplicate-column", "csv", ING, f"{R0}.csv", "alpha_deg",
         setup=_csv(lambda ls: [f"{ls[0]},alpha_deg"] + [f"{x},1.0" for x in ls[1:]])),
    case("csv-time-backwards", "csv", ING, f"{R0}.csv", "'t'", "rows",
         setup=_cell("t", 200, "1.0")),
    case("csv-time-duplicated", "csv", ING, f"{R0}.csv", "'t'", "rows",
         setup=_frame(lambda f: f.with_columns(
             pl.when(pl.int_range(pl.len()) == 301).then(pl.col("t").shift(1))
             .otherwise(pl.col("t")).alias("t")))),
    case("csv-ragged-row", "csv", ING, f"{R0}.csv",
         setup=_csv(lambda ls: [*ls[:10], ls[10] + ",9,9", *ls[11:]])),
    case("csv-short-row", "csv", ING, f"{R0}.csv",
         setup=_csv(lambda ls: [*ls[:10], ",".join(ls[10].split(",")[:5]), *ls[11:]])),
    case("csv-semicolons", "csv", ING, f"{R0}.csv",
         setup=_csv(lambda ls: [x.replace(",", ";") for x in ls])),
    case("csv-binary-garbage", "csv", ING, f"{R0}.csv",
         setup=_write(f"csv/records/{R0}.csv", bytes(range(256)) * 40)),
    case("csv-latin1-header", "csv", ING, f"{R0}.csv",
         setup=lambda d: _rec(d).write_bytes(
             _rec(d).read_bytes().replace(b"alpha_deg", b"alpha_\xb0", 1))),
    case("csv-alpha-in-radians", "csv", ING, f"{R0}.csv", "alpha_deg", "rad",
         setup=_frame(lambda f: f.with_columns(pl.col("alpha_deg") * (np.pi / 180.0)))),
    case("csv-time-in-ms", "csv", ING, f"{R0}.csv", "'t'",
         setup=_frame(lambda f: f.with_columns(pl.col("t") * 1000.0))),
    case("csv-record-is-a-folder", "csv", ING, f"{R0}.csv", "folder",
         setup=_both(lambda d: _rec(d).unlink(), _mkdir(f"csv/records/{R0}.csv"))),
    case("csv-record-dangling-link", "csv", ING, f"{R0}.csv",
         setup=_both(lambda d: _rec(d).unlink(),
                     _symlink(f"csv/records/{R0}.csv", "/nonexistent/record.csv"))),
    case("csv-record-missing", "csv", ING, f"{R0}.csv", "not found",
         setup=lambda d: _rec(d).unlink()),
    case("csv-fit-text-cell", "csv", "fit {csv} --out {out}/m.json --no-progress",
         f"{R0}.csv", "alpha_deg", setup=_cell("alpha_deg", 100, "abc")),
    case("csv-diagnose-header-only", "csv", "diagnose {csv} --out {out} --no-progress",
         f"{R0}.csv", setup=_csv(lambda ls: ls[:1])),
    case("csv-rolloff-empty", "csv", "rolloff {csv} --out {out} --no-progress --no-figures",
         f"{R0}.csv", setup=_write(f"csv/records/{R0}.csv", "")),
    case("csv-validate-text-cell", "csv model",
         "validate --model {model}/model.json {csv} --no-progress", f"{R0}.csv", "alpha_deg",
         setup=_cell("alpha_deg", 7, "x")),
    case("csv-text-beyond-type-inference", "csv", ING, f"{R0}.csv", "alpha_deg", "row 11000",
         "line 11002", setup=_both(_long_record(12_000), _cell("alpha_deg", 11_000, "abc"))),
    case("csv-multi-maneuver-file-no-manifest-row", "csv", ING, "manifest.csv", "m003",
         setup=_both(_one_file(), _manifest(lambda m: m.drop("file").head(3), "csv"))),
    case("csv-multi-maneuver-file-accepted", "csv", ING, "ingested 4 maneuvers", ok=True,
         creates=["out"], setup=_both(_one_file(), _manifest(lambda m: m.drop("file"), "csv"))),
    case("csv-bom-accepted", "csv", ING, "ingested 4 maneuvers", ok=True, creates=["out"],
         setup=lambda d: _rec(d).write_bytes(b"\xef\xbb\xbf" + _rec(d).read_bytes())),
    case("csv-crlf-accepted", "csv", ING, "ingested 4 maneuvers", ok=True, creates=["out"],
         setup=lambda d: _rec(d).write_bytes(_rec(d).read_bytes().replace(b"\n", b"\r\n"))),
    case("csv-extra-column-accepted", "csv", ING, "ingested 4 maneuvers", ok=True,
         creates=["out"], setup=_frame(lambda f: f.with_columns(pl.lit("x").alias("pilot")))),
]  # fmt: skip

PARQUET_RECORDS = [
    case("pq-truncated", "camp", ING_CAMP, f"{R0}.parquet",
         setup=_truncate(CAMP_FILE, 0.5)),
    case("pq-tail-cut", "camp", ING_CAMP, f"{R0}.parquet",
         setup=_truncate(CAMP_FILE, 0.98)),
    case("pq-random-bytes", "camp", ING_CAMP, f"{R0}.parquet",
         setup=_write(CAMP_FILE, bytes(np.random.default_rng(5).integers(0, 256, 5000,
                                                                          dtype=np.uint8)))),
    case("pq-empty-file", "camp", ING_CAMP, f"{R0}.parquet", setup=_write(CAMP_FILE, b"")),
    case("pq-csv-text", "camp", ING_CAMP, f"{R0}.parquet", setup=_write(CAMP_FILE, "t,a\n1,2\n")),
    case("pq-zero-rows", "camp", ING_CAMP, f"{R0}.parquet", setup=_pq(lambda f: f.head(0))),
    case("pq-numbers-as-text-accepted", "camp", ING_CAMP, "ingested 8 maneuvers", ok=True,
         creates=["out"], setup=_pq(lambda f: f.with_columns(pl.col("beta_deg").cast(pl.Utf8)))),
    case("pq-text-channel", "camp", ING_CAMP, f"{R0}.parquet", "beta_deg",
         setup=_pq(lambda f: f.with_columns(pl.lit("left").alias("beta_deg")))),
    case("pq-list-channel", "camp", ING_CAMP, f"{R0}.parquet", "p_dps",
         setup=_pq(lambda f: f.with_columns(pl.concat_list("p_dps", "q_dps").alias("p_dps")))),
    case("pq-null-run", "camp", ING_CAMP, f"{R0}.parquet", "alpha_deg", "rows",
         setup=_pq(lambda f: f.with_columns(
             pl.when(pl.int_range(pl.len()) < 400).then(None)
             .otherwise(pl.col("alpha_deg")).alias("alpha_deg")))),
    case("pq-missing-channel", "camp", ING_CAMP, f"{R0}.parquet", "tas_mps",
         setup=_pq(lambda f: f.drop("tas_mps"))),
    case("pq-time-reversed", "camp", ING_CAMP, f"{R0}.parquet", "'t'",
         setup=_pq(lambda f: f.reverse())),
    case("pq-int-channel-accepted", "camp", ING_CAMP, "ingested 8 maneuvers", ok=True,
         creates=["out"],
         setup=_pq(lambda f: f.with_columns(pl.col("prop_rpm").round().cast(pl.Int64)))),
    case("pq-float32-accepted", "camp", ING_CAMP, "ingested 8 maneuvers", ok=True,
         creates=["out"], setup=_pq(lambda f: f.with_columns(pl.col("h_m").cast(pl.Float32)))),
    case("pq-fit-corrupt", "camp", "fit {camp} --out {out}/m.json --no-progress",
         f"{R0}.parquet", setup=_truncate(CAMP_FILE, 0.3)),
    case("pq-single-file-no-aircraft", "camp", f"fit {{camp}}/records/{R0}.parquet "
         "--out {out}/m.json --no-progress", "--aircraft"),
    case("pq-unknown-suffix", "camp", "ingest {camp}/records/x.txt --aircraft "
         "{camp}/aircraft.toml --out {out} --quiet", "x.txt", ".csv",
         setup=_write("camp/records/x.txt", "t,alpha_deg\n0,1\n")),
    case("mat-garbage", "camp", "ingest {camp}/records/x.mat --aircraft {camp}/aircraft.toml "
         "--out {out} --quiet", "x.mat", setup=_write("camp/records/x.mat", b"MATLAB 5.0 junk")),
    case("data-missing", "camp", "ingest {d}/nowhere --out {out} --quiet", "nowhere"),
    case("data-empty-folder", "camp", "ingest {d}/empty --aircraft {camp}/aircraft.toml "
         "--out {out} --quiet", "empty", "no record files", setup=_mkdir("empty")),
    case("data-no-aircraft", "camp", ING_CAMP, "--aircraft", "aircraft.toml",
         setup=lambda d: (d / "camp/aircraft.toml").unlink()),
    case("data-ingested-without-parquet", "ing", "fit {ing} --out {out}/m.json --no-progress",
         "data.parquet", setup=lambda d: (d / "ing/data.parquet").unlink()),
    case("ingested-parquet-corrupt", "ing", FIT, "data.parquet",
         setup=_truncate("ing/data.parquet", 0.5)),
    case("ingested-parquet-foreign", "ing", FIT, "data.parquet", "ingest",
         setup=lambda d: pl.DataFrame({"maneuver_id": ["a"], "x": [1.0]}).write_parquet(
             d / "ing/data.parquet")),
]  # fmt: skip

MANIFESTS = [
    case("man-missing-kind", "camp", ING_CAMP, "manifest.csv", "kind",
         setup=_manifest(lambda m: m.drop("kind"))),
    case("man-missing-id", "camp", ING_CAMP, "manifest.csv", "maneuver_id",
         setup=_manifest(lambda m: m.drop("maneuver_id"))),
    case("man-flap-text", "camp", ING_CAMP, "manifest.csv", "flap_deg", "row",
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 2).then(pl.lit("ten"))
             .otherwise(pl.col("flap_deg").cast(pl.Utf8)).alias("flap_deg")))),
    case("man-flap-empty", "camp", ING_CAMP, "manifest.csv", "flap_deg", "row",
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 3).then(None)
             .otherwise(pl.col("flap_deg")).alias("flap_deg")))),
    case("man-flap-nan", "camp", ING_CAMP, "manifest.csv", "flap_deg", "row",
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 1).then(float("nan"))
             .otherwise(pl.col("flap_deg")).alias("flap_deg")))),
    case("man-unknown-kind", "camp", ING_CAMP, "manifest.csv", "kind", "spin",
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 0).then(pl.lit("spin"))
             .otherwise(pl.col("kind")).alias("kind")))),
    case("man-pusher-maybe", "camp", ING_CAMP, "manifest.csv", "pusher", "rows 4",
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 4).then(pl.lit("maybe"))
             .otherwise(pl.col("pusher").cast(pl.Utf8)).alias("pusher")))),
    case("man-duplicated-id", "camp", ING_CAMP, "manifest.csv", "duplicated", R0,
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 1).then(pl.lit(R0))
             .otherwise(pl.col("maneuver_id")).alias("maneuver_id")))),
    case("man-id-empty", "camp", ING_CAMP, "manifest.csv", "maneuver_id", "row",
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 5).then(None)
             .otherwise(pl.col("maneuver_id")).alias("maneuver_id")))),
    case("man-path-escapes", "camp", ING_CAMP, "manifest.csv", "../", "campaign folder",
         setup=_both(_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 0).then(pl.lit(f"../outside/{R0}.parquet"))
             .otherwise(pl.col("file")).alias("file"))),
             lambda d: (d / "outside").mkdir(),
             lambda d: (d / "camp/records" / f"{R0}.parquet").rename(
                 d / "outside" / f"{R0}.parquet"))),
    case("man-path-absolute", "camp", ING_CAMP, "manifest.csv", "/etc/hostname",
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 0).then(pl.lit("/etc/hostname"))
             .otherwise(pl.col("file")).alias("file")))),
    case("man-path-missing", "camp", ING_CAMP, "gone.parquet",
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 0).then(pl.lit("records/gone.parquet"))
             .otherwise(pl.col("file")).alias("file")))),
    case("man-path-empty-cell", "camp", ING_CAMP, "manifest.csv", "file", "row",
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 2).then(None)
             .otherwise(pl.col("file")).alias("file")))),
    case("man-path-is-folder", "camp", ING_CAMP, "records",
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.int_range(pl.len()) == 0).then(pl.lit("records"))
             .otherwise(pl.col("file")).alias("file")))),
    case("man-no-row-for-record", "camp", ING_CAMP, "manifest.csv", "m007",
         setup=_manifest(lambda m: m.drop("file").head(7))),
    case("man-empty-file", "camp", ING_CAMP, "manifest.csv",
         setup=_write("camp/manifest.csv", "")),
    case("man-header-only", "camp", ING_CAMP, "manifest.csv",
         setup=_write("camp/manifest.csv", "maneuver_id,flap_deg,kind,pusher,file\n")),
    case("man-binary", "camp", ING_CAMP, "manifest.csv",
         setup=_write("camp/manifest.csv", bytes(range(256)) * 8)),
    case("man-ragged", "camp", ING_CAMP, "manifest.csv",
         setup=_append("camp/manifest.csv", "x,0.0,straight,true,records/x.parquet,1,2,3\n")),
    case("man-parquet-corrupt", "camp", ING_CAMP.replace("--quiet", "--manifest {d}/m.parquet "
         "--quiet"), "m.parquet", setup=_write("m.parquet", b"PAR1 not really")),
    case("man-option-folder", "camp", ING_CAMP + " --manifest {camp}/records", "--manifest",
         "folder"),
    case("man-option-missing", "camp", ING_CAMP + " --manifest {d}/none.csv", "--manifest",
         "not found"),
    case("man-pusher-number", "camp", ING_CAMP, "manifest.csv", "pusher",
         setup=_manifest(lambda m: m.with_columns(pl.lit(2).alias("pusher")))),
    case("man-extra-columns-accepted", "camp", ING_CAMP, "ingested 8 maneuvers", ok=True,
         creates=["out"],
         setup=_manifest(lambda m: m.with_columns(pl.lit("calm").alias("weather")))),
    case("man-pusher-yes-no-accepted", "camp", ING_CAMP, "ingested 8 maneuvers", ok=True,
         creates=["out"],
         setup=_manifest(lambda m: m.with_columns(
             pl.when(pl.col("pusher")).then(pl.lit("yes")).otherwise(pl.lit("no"))
             .alias("pusher")))),
]  # fmt: skip

CHANNEL_MAPS = [
    case("map-syntax", "user", ING_USER, "map.toml", "line",
         setup=_map("[channels\nt = { source = 'time_ms', unit = 'ms' }\n")),
    case("map-unknown-unit", "user", ING_USER, "map.toml", "alpha_deg", "furlong",
         setup=_replace("user/map.toml", 'unit = "rad"', 'unit = "furlong"')),
    case("map-wrong-dimension", "user", ING_USER, "map.toml", "alpha_deg",
         setup=_replace("user/map.toml", 'unit = "rad"', 'unit = "m/s"')),
    case("map-unknown-channel", "user", ING_USER, "map.toml", "aoa_deg",
         setup=_append("user/map.toml", 'aoa_deg = { source = "AOA", unit = "rad" }\n')),
    case("map-same-channel-twice", "user", ING_USER, "map.toml", "alpha_deg",
         setup=_append("user/map.toml", 'alpha_deg = { source = "AOA", unit = "deg" }\n')),
    case("map-same-source-twice", "user", ING_USER, "map.toml", "AOA",
         setup=_append("user/map.toml", 'beta_deg = { source = "AOA", unit = "rad" }\n')),
    case("map-no-source", "user", ING_USER, "map.toml", "alpha_deg", "source",
         setup=_replace("user/map.toml", 'source = "AOA", ', "")),
    case("map-source-absent", "user", ING_USER, "AOA_X", f"{R0}.csv",
         setup=_replace("user/map.toml", '"AOA"', '"AOA_X"')),
    case("map-scale-string", "user", ING_USER, "map.toml", "tas_mps", "scale",
         setup=_replace("user/map.toml", 'unit = "kt" }', 'unit = "kt", scale = "2" }')),
    case("map-scale-nan", "user", ING_USER, "map.toml", "tas_mps", "scale",
         setup=_replace("user/map.toml", 'unit = "kt" }', 'unit = "kt", scale = nan }')),
    case("map-scale-zero", "user", ING_USER, "map.toml", "tas_mps", "scale",
         setup=_replace("user/map.toml", 'unit = "kt" }', 'unit = "kt", scale = 0 }')),
    case("map-offset-string", "user", ING_USER, "map.toml", "tas_mps", "offset",
         setup=_replace("user/map.toml", 'unit = "kt" }', 'unit = "kt", offset = "x" }')),
    case("map-offset-inf", "user", ING_USER, "map.toml", "tas_mps", "offset",
         setup=_replace("user/map.toml", 'unit = "kt" }', 'unit = "kt", offset = inf }')),
    case("map-source-number", "user", ING_USER, "map.toml", "alpha_deg", "source",
         setup=_replace("user/map.toml", 'source = "AOA"', "source = 3")),
    case("map-unit-number", "user", ING_USER, "map.toml", "alpha_deg", "unit",
         setup=_replace("user/map.toml", 'unit = "rad"', "unit = 1")),
    case("map-entry-string", "user", ING_USER, "map.toml", "alpha_deg",
         setup=_replace("user/map.toml", 'alpha_deg = { source = "AOA", unit = "rad" }',
                        'alpha_deg = "AOA"')),
    case("map-empty", "user", ING_USER, "map.toml", "[channels]", setup=_map("")),
    case("map-channels-not-table", "user", ING_USER, "map.toml", "[channels]",
         setup=_map("channels = 3\n")),
    case("map-unknown-key", "user", ING_USER, "map.toml", "alpha_deg", "units",
         setup=_replace("user/map.toml", 'unit = "rad"', 'unit = "rad", units = "deg"')),
    case("map-unreviewed", "user", ING_USER, "map.toml", "REVIEW", "line 3",
         setup=_replace("user/map.toml", 'unit = "rad" }', 'unit = "rad" }  # REVIEW: guessed')),
    case("map-latin1", "user", ING_USER, "map.toml", "UTF-8",
         setup=_write("user/map.toml", b"[channels]\n# \xb0 degrees\n")),
    case("map-option-folder", "user", ING_USER.replace("{user}/map.toml", "{user}"), "--map",
         "folder"),
    case("map-option-missing", "user", ING_USER.replace("{user}/map.toml", "{d}/no.toml"),
         "--map", "not found"),
    case("map-text-source-column", "user", ING_USER, f"{R0}.csv", "AOA",
         setup=_cell("AOA", 12, "stall", "user")),
    case("map-fit-syntax", "user",
         "fit {user} --map {user}/map.toml --out {out}/m.json --no-progress --no-plausibility",
         "map.toml", setup=_map("[channels]\nt = \n")),
    case("map-with-ingested", "ing user", "fit {ing} --map {user}/map.toml --out {out}/m.json",
         "--map", "ingest output"),
]  # fmt: skip

AIRCRAFT = [
    case("ac-syntax", "camp", ING_CAMP, "aircraft.toml", "line",
         setup=_append("camp/aircraft.toml", "[mass\n")),
    case("ac-missing-area", "camp", ING_CAMP, "aircraft.toml", "S_m2", "missing",
         setup=_aircraft("S_m2 = 54.35\n", "")),
    case("ac-negative-mass", "camp", ING_CAMP, "aircraft.toml", "mass_kg", "positive",
         setup=_aircraft("mass_kg = 15000.0", "mass_kg = -15000.0")),
    case("ac-nan-inertia", "camp", ING_CAMP, "aircraft.toml", "Ixx_kgm2", "finite",
         setup=_aircraft("Ixx_kgm2 = 157000.0", "Ixx_kgm2 = nan")),
    case("ac-string-span", "camp", ING_CAMP, "aircraft.toml", "b_m",
         setup=_aircraft("b_m = 25.91", 'b_m = "25.91"')),
    case("ac-inertia-not-pd", "camp", ING_CAMP, "aircraft.toml", "Ixz_kgm2",
         setup=_aircraft("Ixz_kgm2 = 12000.0", "Ixz_kgm2 = 400000.0")),
    case("ac-rotation", "camp", ING_CAMP, "aircraft.toml", "prop_rotation",
         setup=_aircraft('prop_rotation = "ccw"', 'prop_rotation = "clockwise"')),
    case("ac-rotation-same", "camp", ING_CAMP, "aircraft.toml", "prop_rotation", "'cw' or",
         setup=_aircraft('prop_rotation = "ccw"', 'prop_rotation = "same"')),
    case("ac-rotation-missing", "camp", ING_CAMP, "aircraft.toml", "prop_rotation",
         "missing", setup=_aircraft('prop_rotation = "ccw"\n', '')),
    case("ac-engines-text", "camp", ING_CAMP, "aircraft.toml", "n_engines",
         setup=_aircraft("n_engines = 2", 'n_engines = "two"')),
    case("ac-engines-fraction", "camp", ING_CAMP, "aircraft.toml", "n_engines",
         setup=_aircraft("n_engines = 2", "n_engines = 2.5")),
    case("ac-engines-negative", "camp", ING_CAMP, "aircraft.toml", "n_engines",
         setup=_aircraft("n_engines = 2", "n_engines = -1")),
    case("ac-rpm-text", "camp", ING_CAMP, "aircraft.toml", "prop_rpm_fixed",
         setup=_aircraft("prop_rpm_fixed = 1020.0", 'prop_rpm_fixed = "fast"')),
    case("ac-rpm-negative", "camp", ING_CAMP, "aircraft.toml", "prop_rpm_fixed",
         setup=_aircraft("prop_rpm_fixed = 1020.0", "prop_rpm_fixed = -5.0")),
    case("ac-rpm-channel-number", "camp", ING_CAMP, "aircraft.toml", "prop_rpm_channel",
         setup=_aircraft('prop_rpm_channel = "prop_rpm"', "prop_rpm_channel = 7")),
    case("ac-rpm-channel-not-canonical", "camp", ING_CAMP, "aircraft.toml", "NPL",
         setup=_aircraft('prop_rpm_channel = "prop_rpm"', 'prop_rpm_channel = "NPL"')),
    case("ac-unknown-key", "camp", ING_CAMP, "aircraft.toml", "prop_effciency",
         setup=_aircraft("n_engines = 2", "n_engines = 2\nprop_effciency = 0.8")),
    case("ac-unknown-table", "camp", ING_CAMP, "aircraft.toml", "engine",
         setup=_append("camp/aircraft.toml", "[engine]\nthrust = 3\n")),
    case("ac-prop-inertia-negative", "camp", ING_CAMP, "aircraft.toml", "prop_inertia_kgm2",
         setup=_aircraft("prop_inertia_kgm2 = 60.0", "prop_inertia_kgm2 = -60.0")),
    case("ac-bom-accepted", "camp", ING_CAMP, "ingested 8 maneuvers", ok=True, creates=["out"],
         setup=lambda d: (d / "camp/aircraft.toml").write_bytes(
             b"\xef\xbb\xbf" + (d / "camp/aircraft.toml").read_bytes())),
    case("ac-sensor-two-numbers", "camp", ING_CAMP, "aircraft.toml", "accel_m",
         setup=_aircraft("accel_m = [-1.2, 0.25, 0.6]", "accel_m = [-1.2, 0.25]")),
    case("ac-sensor-nan", "camp", ING_CAMP, "aircraft.toml", "alpha_vane_m",
         setup=_aircraft("alpha_vane_m = [9.5, 0.0, 0.0]", "alpha_vane_m = [nan, 0.0, 0.0]")),
    case("ac-geometry-not-table", "camp", ING_CAMP, "aircraft.toml", "geometry",
         setup=lambda d: (d / "camp/aircraft.toml").write_text(
             "geometry = 3\n" + (d / "camp/aircraft.toml").read_text().split("[geometry]")[1]
             .replace("S_m2", "[extra]\nS_m2", 1))),
    case("ac-empty", "camp", ING_CAMP, "aircraft.toml", "missing",
         setup=_write("camp/aircraft.toml", "")),
    case("ac-latin1", "camp", ING_CAMP, "aircraft.toml", "UTF-8",
         setup=_write("camp/aircraft.toml", b'name = "\xe9"\n')),
    case("ac-efficiency-above-one", "camp", ING_CAMP, "aircraft.toml", "prop_efficiency",
         setup=_aircraft("n_engines = 2", "n_engines = 2\nprop_efficiency = 1.7")),
    case("ac-option-folder", "camp", ING_CAMP + " --aircraft {camp}", "--aircraft", "folder"),
    case("ac-option-missing", "camp", ING_CAMP + " --aircraft {d}/no.toml", "--aircraft",
         "not found"),
    case("ac-diagnose-bad", "ing", DIAG + " --aircraft {d}/a.toml", "a.toml", "S_m2",
         setup=_write("a.toml", "[geometry]\nS_m2 = -1\n")),
]  # fmt: skip

N_DEEP = 20_000
DEEP = "(" * N_DEEP + "beta_deg" + ")" * N_DEEP

FIT_CONFIGS = [
    case("cfg-syntax", "ing cfg", FIT_CFG, "fit.toml", "line", setup=_cfg("width_deg = \n")),
    case("cfg-unknown-key", "ing cfg", FIT_CFG, "fit.toml", "widht_deg",
         setup=_cfg("widht_deg = 0.3\n")),
    case("cfg-width-text", "ing cfg", FIT_CFG, "fit.toml", "width_deg",
         setup=_cfg('width_deg = "wide"\n')),
    case("cfg-width-negative", "ing cfg", FIT_CFG, "fit.toml", "width_deg",
         setup=_cfg("width_deg = -0.2\n")),
    case("cfg-width-zero", "ing cfg", FIT_CFG, "fit.toml", "width_deg",
         setup=_cfg("width_deg = 0.0\n")),
    case("cfg-folds-one", "ing cfg", FIT_CFG, "fit.toml", "cv_folds",
         setup=_cfg("cv_folds = 1\n")),
    case("cfg-folds-text", "ing cfg", FIT_CFG, "fit.toml", "cv_folds",
         setup=_cfg('cv_folds = "5"\n')),
    case("cfg-folds-float", "ing cfg", FIT_CFG, "fit.toml", "cv_folds",
         setup=_cfg("cv_folds = 5.5\n")),
    case("cfg-band-level", "ing cfg", FIT_CFG, "fit.toml", "band_level",
         setup=_cfg("band_level = 1.5\n")),
    case("cfg-p-zero", "ing cfg", FIT_CFG, "fit.toml", "p", setup=_cfg("p = 0\n")),
    case("cfg-seed-negative", "ing cfg", FIT_CFG, "fit.toml", "seed",
         setup=_cfg("seed = -1\n")),
    case("cfg-bootstrap-negative", "ing cfg", FIT_CFG, "fit.toml", "bootstrap",
         setup=_cfg("bootstrap = -5\n")),
    case("cfg-max-vif-negative", "ing cfg", FIT_CFG, "fit.toml", "max_vif",
         setup=_cfg("max_vif = -1.0\n")),
    case("cfg-band-hz-negative", "ing cfg", FIT_CFG, "fit.toml", "band_hz",
         setup=_cfg("band_hz = -2.5\n")),
    case("cfg-grid-step-zero", "ing cfg", FIT_CFG, "fit.toml", "grid_step_deg",
         setup=_cfg("grid_step_deg = 0.0\n")),
    case("cfg-colored-text", "ing cfg", FIT_CFG, "fit.toml", "colored",
         setup=_cfg('colored = "yes"\n')),
    case("cfg-selection-unknown", "ing cfg", FIT_CFG, "fit.toml", "selection", "forward",
         setup=_cfg('selection = "forward"\n')),
    case("cfg-blend-reversed", "ing cfg", FIT_CFG, "fit.toml", "alpha_l_deg",
         setup=_cfg("alpha_l_deg = 12.0\nalpha_u_deg = 10.0\n")),
    case("cfg-structures-number", "ing cfg", FIT_CFG, "fit.toml", "structures",
         setup=_cfg("structures = 3\n")),
    case("cfg-structures-string", "ing cfg", FIT_CFG, "fit.toml", "structures", "Cl",
         setup=_cfg('selection = "none"\n[structures]\nCl = "dCl_0"\n')),
    case("cfg-structures-one-element", "ing cfg", FIT_CFG, "fit.toml", "structures", "Cl",
         setup=_cfg('selection = "none"\n[structures]\nCl = [["dCl_0"]]\n')),
    case("cfg-structures-unknown-coef", "ing cfg", FIT_CFG, "fit.toml", "Cm",
         setup=_cfg('selection = "none"\n[structures]\nCm = [["dCm_0", "1"]]\n')),
    case("cfg-regressor-unknown-column", "ing cfg", FIT_CFG, "dCl_x", "foo_deg",
         setup=_cfg('selection = "none"\n[structures]\nCl = [["dCl_x", "foo_deg"]]\n')),
    case("cfg-regressor-syntax", "ing cfg", FIT_CFG, "fit.toml", "dCl_x",
         setup=_cfg('selection = "none"\n[structures]\nCl = [["dCl_x", "beta_deg +"]]\n')),
    case("cfg-regressor-duplicate-name", "ing cfg", FIT_CFG, "fit.toml", "dCl_0",
         setup=_cfg('selection = "none"\n[structures]\n'
                    'Cl = [["dCl_0", "1"], ["dCl_0", "beta_deg"]]\n')),
    case("cfg-stall-key-text", "ing cfg", FIT_CFG, "fit.toml", "stall_alpha_deg", "zero",
         setup=_cfg("[stall_alpha_deg]\nzero = 15.0\n")),
    case("cfg-stall-value-text", "ing cfg", FIT_CFG, "fit.toml", "stall_alpha_deg",
         setup=_cfg('[stall_alpha_deg]\n"0" = "high"\n')),
    case("cfg-stall-not-table", "ing cfg", FIT_CFG, "fit.toml", "stall_alpha_deg",
         setup=_cfg("stall_alpha_deg = 15.0\n")),
    case("cfg-candidates-number", "ing cfg", FIT_CFG, "fit.toml", "candidates",
         setup=_cfg("candidates = 1\n")),
    case("cfg-latin1", "ing cfg", FIT_CFG, "fit.toml", "UTF-8",
         setup=_cfg(b"# \xb0\nwidth_deg = 0.2\n")),
    case("cfg-binary", "ing cfg", FIT_CFG, "fit.toml", setup=_cfg(bytes(range(256)))),
    case("cfg-option-missing", "ing", "fit {ing} --config {d}/no.toml --out {out}/m.json",
         "--config", "not found"),
    case("cfg-option-folder", "ing cfg", "fit {ing} --config {cfg} --out {out}/m.json",
         "--config", "folder"),
    case("cfg-valid-accepted", "ing cfg", FIT_CFG, ok=True,
         creates=["out/m.json", "out/m.params.parquet"]),
    case("cfg-example-accepted", "ing cfg", FIT_CFG, ok=True,
         creates=["out/m.json", "out/m.params.parquet"],
         setup=_cfg((ROOT / "examples" / "fit.toml").read_text())),
    case("cfg-blend-per-flap-reversed", "ing cfg", FIT_CFG, "fit.toml", "alpha_l_deg", "flap 10",
         setup=_cfg('[alpha_l_deg]\n"0" = 8.0\n"10" = 13.0\n[alpha_u_deg]\n"0" = 10.0\n'
                    '"10" = 12.0\n')),
    case("cfg-band-hz-unknown-coefficient", "ing cfg", FIT_CFG, "fit.toml", "band_hz", "Cm",
         setup=_cfg("[band_hz]\nCm = 2.5\n")),
    case("cfg-max-width-below-width", "ing cfg", FIT_CFG, "fit.toml", "max_width_deg",
         setup=_cfg("width_deg = 1.0\nmax_width_deg = 0.5\n")),
    case("cfg-regressor-unknown-function", "ing cfg", FIT_CFG, "fit.toml", "dCl_x", "frob",
         setup=_cfg('selection = "none"\n[structures]\nCl = [["dCl_x", "frob(beta_deg)"]]\n')),
]  # fmt: skip

MODELS = [
    case("model-truncated", "ing model", VALIDATE, "model.json",
         setup=_truncate("model/model.json", 0.5)),
    case("model-empty", "ing model", VALIDATE, "model.json", setup=_write("model/model.json", "")),
    case("model-binary", "ing model", VALIDATE, "model.json",
         setup=_write("model/model.json", bytes(range(256)))),
    case("model-array", "ing model", VALIDATE, "model.json",
         setup=_write("model/model.json", "[1, 2, 3]")),
    case("model-wrong-schema", "ing model", VALIDATE, "model.json", "aerodelta.model/9",
         setup=_json(lambda doc: doc.__setitem__("schema", "aerodelta.model/9"))),
    case("model-no-schema", "ing model", VALIDATE, "model.json", "schema",
         setup=_json(lambda doc: doc.pop("schema"))),
    case("model-no-coefficients", "ing model", VALIDATE, "model.json", "coefficients",
         setup=_json(lambda doc: doc.pop("coefficients"))),
    case("model-term-no-values", "ing model", VALIDATE, "model.json", "values", "column",
         setup=_json(lambda doc: _first_term(doc).pop("values"))),
    case("model-values-short", "ing model", VALIDATE, "model.json", "dCl_0",
         setup=_json(lambda doc: _first_term(doc).__setitem__(
             "values", [_first_term(doc)["values"][0][:-3]]))),
    case("model-alpha-unsorted", "ing model", VALIDATE, "model.json", "dCl_0",
         setup=_json(lambda doc: _first_term(doc).__setitem__(
             "alpha_deg", list(reversed(_first_term(doc)["alpha_deg"]))))),
    case("model-values-nan", "ing model", VALIDATE, "model.json", "column 6",
         setup=_first_value('NaN')),
    case("model-values-huge", "ing model", VALIDATE, "model.json", "out of range", "column 6",
         setup=_first_value('1e400')),
    case("model-values-text", "ing model", VALIDATE, "model.json", '"x"', "column 6",
         setup=_first_value('"x"')),
    case("model-regressor-unknown-fn", "ing model", VALIDATE, "model.json", "dCl_0", "foo",
         setup=_set_term("regressor", "foo(beta_deg)")),
    case("model-regressor-syntax", "ing model", VALIDATE, "model.json", "dCl_0",
         setup=_set_term("regressor", "beta_deg * * 2")),
    case("model-regressor-number", "ing model", VALIDATE, "model.json", "string", "column",
         setup=_set_term("regressor", 5)),
    case("model-flaps-empty", "ing model", VALIDATE, "model.json", "flaps_deg",
         setup=_json(lambda doc: doc.__setitem__("flaps_deg", []))),
    case("model-blend-missing", "ing model", VALIDATE, "model.json", "alpha_l_deg",
         setup=_json(lambda doc: doc["coefficients"]["Cl"].pop("alpha_l_deg"))),
    case("model-unknown-coefficient", "ing model", VALIDATE, "model.json", "Cm",
         setup=_json(lambda doc: doc["coefficients"].__setitem__(
             "Cm", doc["coefficients"].pop("Cl")))),
    case("model-option-missing", "ing", "validate --model {d}/no.json {ing}", "--model",
         "not found"),
    case("model-option-folder", "ing model", "validate --model {model} {ing}", "--model",
         "folder"),
    case("model-export-truncated", "model", EXPORT, "model.json",
         setup=_truncate("model/model.json", 0.7)),
    case("model-rolloff-truncated", "ing model",
         "rolloff {ing} --model {model}/model.json --out {out} --no-progress --no-figures",
         "model.json", setup=_truncate("model/model.json", 0.7)),
    case("model-diagnose-truncated", "ing model", DIAG + " --model {model}/model.json",
         "model.json", setup=_truncate("model/model.json", 0.7)),
    case("model-report-truncated", "ing model",
         "report --model {model}/model.json {ing} --out {out} --no-progress", "model.json",
         setup=_truncate("model/model.json", 0.7)),
    case("model-report-params-mismatch", "ing model",
         "report --model {model}/model.json {ing} --out {out} --no-progress",
         "model.params.parquet",
         setup=lambda d: pl.read_parquet(d / "model/model.params.parquet").head(5).write_parquet(
             d / "model/model.params.parquet")),
    case("model-validate-data-lacks-column", "ing model", VALIDATE, "data.parquet", "beta_deg",
         setup=lambda d: pl.read_parquet(d / "ing/data.parquet").drop(
             "beta_deg", "beta_cg_deg").write_parquet(d / "ing/data.parquet")),
    case("model-validate-vane-beta-dropped-accepted", "ing model", VALIDATE, "TIC", ok=True,
         setup=lambda d: pl.read_parquet(d / "ing/data.parquet").drop("beta_deg").write_parquet(
             d / "ing/data.parquet")),
]  # fmt: skip

DAVEML = [
    case("dml-unclosed", "dml", CHECK, "example.dml", "never closed",
         setup=_dml_replace("</DAVEfunc>", "")),
    case("dml-mismatched-tag", "dml", CHECK, "example.dml:10:", "fileheader",
         setup=_dml_replace("</fileHeader>", "</fileheader>")),
    case("dml-empty", "dml", CHECK, "example.dml", setup=_write("dml/example.dml", "")),
    case("dml-binary", "dml", CHECK, "example.dml",
         setup=_write("dml/example.dml", bytes(range(256)) * 4)),
    case("dml-wrong-root", "dml", CHECK, "example.dml", "DAVEfunc",
         setup=_write("dml/example.dml", '<?xml version="1.0"?>\n<html><body/></html>\n')),
    case("dml-entity-declaration", "dml", CHECK, "example.dml", "entit",
         setup=_dml_replace('"http://www.daveml.org/DTDs/2p0/DAVEfunc.dtd">',
                            '"x.dtd" [<!ENTITY a "aaaa">]>')),
    case("dml-external-entity", "dml", CHECK, "example.dml", "entit",
         setup=_both(
             _dml_replace('"http://www.daveml.org/DTDs/2p0/DAVEfunc.dtd">',
                          '"x.dtd" [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>'),
             _dml_replace("<fileVersion>", "<fileVersion>&xxe;"))),
    case("dml-missing-breakpoints", "dml", CHECK, "example.dml", "alpha_deg_bp",
         setup=_dml_replace('bpID="alpha_deg_bp"', 'bpID="other_bp"')),
    case("dml-breakpoints-unsorted", "dml", CHECK, "example.dml", "alpha_deg_bp",
         setup=_dml_replace("-4.0, 0.0, 4.0", "4.0, 0.0, -4.0")),
    case("dml-breakpoint-text", "dml", CHECK, "example.dml:109:", "bpVals", "zero",
         setup=_dml_replace("-4.0, 0.0, 4.0", "-4.0, zero, 4.0")),
    case("dml-table-short", "dml", CHECK, "example.dml", "Cl_beta",
         setup=_dml_replace("-0.1, -0.1, -0.1, -0.1, -0.1, -0.085", "-0.1, -0.1, -0.085")),
    case("dml-undefined-variable", "dml", CHECK, "example.dml", "Cl_nope",
         setup=_dml_replace("<ci>Cl_p</ci>", "<ci>Cl_nope</ci>")),
    case("dml-unknown-mathml", "dml", CHECK, "example.dml", "frobnicate",
         setup=_dml_replace("<plus/>", "<frobnicate/>")),
    case("dml-cn-text", "dml", CHECK, "example.dml:71:", "'one'",
         setup=_dml_replace("<cn>0.017453292519943295</cn>", "<cn>one</cn>")),
    case("dml-cycle", "dml", CHECK, "example.dml", "Cl",
         setup=_dml_replace("<ci>p_hat</ci>", "<ci>Cl</ci>")),
    case("dml-file-missing", "dml", "check-daveml {d}/none.dml", "none.dml"),
    case("dml-file-folder", "dml", "check-daveml {dml}", "dml"),
    case("dml-export-qualified-bad", "dml model",
         "export --model {model}/model.json --qualified {dml}/example.dml --daveml "
         "{out}/x.dml", "example.dml", setup=_dml_replace("</DAVEfunc>", "")),
    case("dml-diagnose-model-bad", "ing dml", DIAG + " --model {dml}/example.dml",
         "example.dml", setup=_dml_replace("</DAVEfunc>", "")),
]  # fmt: skip

EFFECTS = [
    case("eff-syntax", "ing cfg", DIAG + " --effects {cfg}/effects.toml", "effects.toml",
         "line", setup=_effects("[beta_rate\n")),
    case("eff-unknown-coefficient", "ing cfg", DIAG + " --effects {cfg}/effects.toml",
         "effects.toml", "Cm", setup=_effects("[x]\nCm = ['beta_deg']\n")),
    case("eff-bad-expression", "ing cfg", DIAG + " --effects {cfg}/effects.toml",
         "effects.toml", "beta_rate", setup=_effects("[beta_rate]\nCl = ['beta_deg * * rhat']\n")),
    case("eff-unknown-column", "ing cfg", DIAG + " --effects {cfg}/effects.toml",
         "effects.toml", "foo_deg", setup=_effects("[beta_rate]\nCl = ['foo_deg * rhat']\n")),
    case("eff-not-table", "ing cfg", DIAG + " --effects {cfg}/effects.toml", "effects.toml",
         "beta_rate", setup=_effects("beta_rate = 3\n")),
    case("eff-regressors-string", "ing cfg", DIAG + " --effects {cfg}/effects.toml",
         "effects.toml", "beta_rate", setup=_effects("[beta_rate]\nCl = 'beta_deg'\n")),
    case("eff-regressor-number", "ing cfg", DIAG + " --effects {cfg}/effects.toml",
         "effects.toml", "beta_rate", setup=_effects("[beta_rate]\nCl = [3]\n")),
    case("eff-empty-list", "ing cfg", DIAG + " --effects {cfg}/effects.toml",
         "effects.toml", "beta_rate", setup=_effects("[beta_rate]\nCl = []\n")),
    case("eff-empty-file", "ing cfg", DIAG + " --effects {cfg}/effects.toml", "effects.toml",
         setup=_effects("")),
    case("eff-latin1", "ing cfg", DIAG + " --effects {cfg}/effects.toml", "effects.toml",
         setup=_effects(b"# \xb0\n[a]\nCl = ['beta_deg']\n")),
    case("eff-missing", "ing", DIAG + " --effects {d}/none.toml", "--effects", "not found"),
    case("eff-sql-injection-ish", "ing cfg", DIAG + " --effects {cfg}/effects.toml",
         "effects.toml", "beta_rate",
         setup=_effects("[beta_rate]\nCl = ['beta_deg; DROP TABLE data']\n")),
]  # fmt: skip

A_FILE = _write("a_file", "x")

OPTIONS = [
    case("opt-folds-zero", "ing", DIAG + " --folds 0", "--folds 0"),
    case("opt-folds-one", "ing", DIAG + " --folds 1", "--folds 1", "at least 2"),
    case("opt-folds-text", "ing", DIAG + " --folds two", "--folds", "two", status=2),
    case("opt-alpha-five", "ing", DIAG + " --alpha 5", "--alpha 5"),
    case("opt-alpha-zero", "ing", DIAG + " --alpha 0", "--alpha 0"),
    case("opt-alpha-nan", "ing", DIAG + " --alpha nan", "--alpha nan"),
    case("opt-diag-seed-negative", "ing", DIAG + " --seed -1", "--seed -1"),
    case("opt-min-shrink", "ing", DIAG + " --min-shrink 1.5", "--min-shrink 1.5"),
    case("opt-min-shrink-broad-above", "ing", DIAG + " --min-shrink 0.02 --min-shrink-broad 0.5",
         "--min-shrink-broad"),
    case("opt-diag-out-file", "ing", "diagnose {ing} --out {d}/a_file --no-progress", "--out",
         "is a file", setup=A_FILE),
    case("opt-diag-truth", "camp", "diagnose {d}/truth/x --out {out}", "truth",
         setup=_mkdir("truth/x")),
    case("opt-level-95", "ing", "rolloff {ing} --out {out} --level 95", "--level 95"),
    case("opt-mc-negative", "ing", "rolloff {ing} --out {out} --monte-carlo -1", "--monte-carlo"),
    case("opt-threads-zero", "ing", "rolloff {ing} --out {out} --monte-carlo 2 --threads 0",
         "--threads 0"),
    case("opt-rolloff-seed", "ing", "rolloff {ing} --out {out} --monte-carlo 2 --seed -2",
         "--seed -2"),
    case("opt-rolloff-threads-without-mc", "ing", "rolloff {ing} --out {out} --threads 2",
         "--threads", "--monte-carlo"),
    case("opt-rolloff-out-file", "ing", "rolloff {ing} --out {d}/a_file", "--out", "is a file",
         setup=A_FILE),
    case("opt-rolloff-qualified-columns", "ing",
         "rolloff {ing} --out {out} --qualified columns --no-figures", "columns", "Cl_sim"),
    case("opt-demo-bootstrap", "camp", "demo --out {out} --quick --bootstrap -1", "--bootstrap"),
    case("opt-demo-seed", "camp", "demo --out {out} --quick --seed -3", "--seed -3"),
    case("opt-demo-out-file", "camp", "demo --out {d}/a_file --quick", "is a file",
         setup=A_FILE),
    case("opt-holdout-zero", "ing", FIT + " --holdout 0", "--holdout 0"),
    case("opt-holdout-one", "ing", FIT + " --holdout 1", "--holdout 1"),
    case("opt-holdout-negative", "ing", FIT + " --holdout -0.2", "--holdout -0.2"),
    case("opt-holdout-nan", "ing", FIT + " --holdout nan", "--holdout nan"),
    case("opt-holdout-seed-negative", "ing", FIT + " --holdout 0.2 --holdout-seed -1",
         "--holdout-seed -1"),
    case("opt-holdout-seed-alone", "ing", FIT + " --holdout-seed 4", "--holdout-seed",
         "--holdout"),
    case("opt-range-zero", "ing", FIT + " --range 0", "--range 0"),
    case("opt-range-nan", "ing", FIT + " --range nan", "--range nan"),
    case("opt-fit-out-folder", "ing", "fit {ing} --out {ing} --no-progress", "--out", "folder"),
    case("opt-fit-out-under-file", "ing", "fit {ing} --out {d}/a_file/m.json --no-progress",
         "a_file", "is a file", setup=A_FILE),
    case("opt-fit-out-over-input", "ing", "fit {ing} --out {ing}/data.parquet --no-progress",
         "--out", "data.parquet"),
    case("opt-fit-data-twice", "ing camp", "fit {camp} --data {ing} --out {out}/m.json",
         "given twice"),
    case("opt-fit-no-data", "ing", "fit --out {out}/m.json", "no data"),
    case("opt-fit-no-out", "ing", "fit {ing}", "--out", status=2),
    case("opt-fit-unknown-option", "ing", FIT + " --fold 3", "--fold", status=2),
    case("opt-fit-model-choice", "ing", FIT + " --model f16", "--model", "f16", status=2),
    case("opt-fit-model-dml-missing", "ing", FIT + " --model {d}/nowhere.dml", "--model",
         "nowhere.dml", "file not found"),
    case("opt-validate-qualified-choice", "ing model", VALIDATE + " --qualified f16",
         "--qualified", "f16", status=2),
    case("opt-fit-no-plausibility-ingested", "ing", FIT + " --no-plausibility",
         "--no-plausibility"),
    case("opt-ingest-out-file", "camp", "ingest {camp} --out {d}/a_file --quiet", "--out",
         "is a file", setup=A_FILE),
    case("opt-ingest-out-campaign", "camp", "ingest {camp} --out {camp} --quiet",
         "campaign folder itself"),
    case("opt-ingest-out-records", "camp", "ingest {camp} --out {camp}/records --quiet",
         "--out", "records"),
    case("opt-fit-out-into-campaign", "camp", "fit {camp} --out {camp}/m.json --no-progress",
         "--out", "m.params.parquet", "flight record"),
    case("opt-fit-out-over-config", "ing cfg", FIT_CFG.replace("{out}/m.json", "{cfg}/fit.toml"),
         "--out", "fit.toml", "overwrite"),
    case("opt-diagnose-out-campaign", "camp", "diagnose {camp} --out {camp}/records",
         "--out", "records"),
    case("opt-ingest-compat-both", "camp",
         "ingest {camp} --out {out} --apply-compat --no-compat --quiet", "--apply-compat"),
    case("opt-ingest-compat-method-no-compat", "camp",
         "ingest {camp} --out {out} --compat-method innovations --no-compat --quiet",
         "--compat-method", "--no-compat"),
    case("opt-ingest-compat-method-unknown", "camp",
         "ingest {camp} --out {out} --compat-method filter --quiet", "--compat-method",
         status=2),
    case("opt-ingest-ingested", "ing", "ingest {ing} --out {out} --quiet", "ingest output"),
    case("opt-validate-out-folder", "ing model", VALIDATE + " --out {ing}", "--out", "folder"),
    case("opt-validate-held-out-unknown", "ing model", VALIDATE + " --held-out m999",
         "--held-out", "m999"),
    case("opt-validate-held-out-missing-file", "ing model", VALIDATE + " --held-out @{d}/ids.txt",
         "--held-out", "ids.txt"),
    case("opt-validate-held-out-binary", "ing model", VALIDATE + " --held-out @{d}/ids.txt",
         "--held-out", "ids.txt", setup=_write("ids.txt", b"\xff\xfe\x00bad")),
    case("opt-validate-held-out-empty", "ing model", VALIDATE + " --held-out ,", "--held-out"),
    case("opt-validate-qualified-columns", "ing model", VALIDATE + " --qualified columns",
         "columns", "Cl_sim"),
    case("opt-report-diagnosis-binary", "ing model",
         "report --model {model}/model.json {ing} --out {out} --diagnosis {d}/dg.json "
         "--no-progress", "dg.json", setup=_write("dg.json", bytes(range(256)))),
    case("opt-report-diagnosis-deep", "ing model",
         "report --model {model}/model.json {ing} --out {out} --diagnosis {d}/dg.json "
         "--no-progress", "dg.json", setup=_write("dg.json", "[" * 100_000 + "]" * 100_000)),
    case("opt-validate-held-out-folder", "ing model", VALIDATE + " --held-out @{ing}",
         "--held-out", "folder"),
    case("opt-report-replays", "ing model",
         "report --model {model}/model.json {ing} --out {out} --replays -1", "--replays -1"),
    case("opt-report-out-file", "ing model",
         "report --model {model}/model.json {ing} --out {d}/a_file", "--out", "is a file",
         setup=A_FILE),
    case("opt-report-diagnosis-missing", "ing model",
         "report --model {model}/model.json {ing} --out {out} --diagnosis {d}/no.json",
         "--diagnosis", "not found"),
    case("opt-report-diagnosis-bad", "ing model",
         "report --model {model}/model.json {ing} --out {out} --diagnosis {d}/dg.json "
         "--no-progress", "dg.json", setup=_write("dg.json", "{not json")),
    case("opt-export-nothing", "model", "export --model {model}/model.json", "--daveml",
         "--jsbsim", status=2),
    case("opt-export-qualified-jsbsim", "model dml",
         "export --model {model}/model.json --jsbsim {out}/x.xml --jsbsim-qualified "
         "--qualified {dml}/example.dml", "--jsbsim-qualified", status=2),
    case("opt-export-property-no-equals", "model", EXPORT + " --property da_deg",
         "--property", "da_deg"),
    case("opt-export-property-unknown-channel", "model", EXPORT + " --property zz_deg=a/b",
         "--property", "zz_deg"),
    case("opt-export-property-bad-chars", "model", EXPORT + " --property da_deg=fcs/a\"b",
         "--property", "da_deg"),
    case("opt-export-map-bad", "model dml",
         "export --model {model}/model.json --daveml {out}/x.dml --map alpha_deg", "--map"),
    case("opt-export-coef-unknown", "model",
         "export --model {model}/model.json --daveml {out}/x.dml --coef Cm=Cm_total", "--coef",
         "Cm"),
    case("opt-export-seed", "model", EXPORT + " --seed -1", "--seed -1"),
    case("opt-export-out-folder", "model", "export --model {model}/model.json --jsbsim {model}",
         "--jsbsim", "folder"),
    case("opt-export-property-without-jsbsim", "model",
         "export --model {model}/model.json --daveml {out}/x.dml --property da_deg=a/b",
         "--property", "--jsbsim", status=2),
    case("opt-export-map-without-daveml", "model", EXPORT + " --map alpha_deg=alpha",
         "--map", "--daveml", status=2),
    case("opt-export-same-file", "model",
         "export --model {model}/model.json --jsbsim {out}/x --daveml {out}/x", "--daveml",
         "--jsbsim"),
    case("opt-campaign-exists", "camp", "campaign --out {camp} --quick", "--overwrite"),
    case("opt-campaign-list-terms-builtin", "camp", "campaign --list-terms", "--list-terms"),
    case("opt-campaign-effects-jsbsim", "camp",
         "campaign --simulator jsbsim --out {out} --effects none", "--effects"),
    case("opt-campaign-seed", "camp", "campaign --out {out} --quick --seed -1", "--seed -1"),
    case("opt-campaign-vane-scale-text", "camp", "campaign --out {out} --quick --vane-scale 5",
         "--vane-scale", "KA,KB"),
    case("opt-campaign-vane-scale-large", "camp",
         "campaign --out {out} --quick --vane-scale 0.8,0", "alpha_scale", "0.8"),
    case("opt-campaign-flank-jsbsim", "camp",
         "campaign --simulator jsbsim --out {out} --flank-vane", "--flank-vane"),
    case("opt-campaign-effects", "camp", "campaign --out {out} --quick --effects warp_drive",
         "warp_drive"),
    case("opt-campaign-effect-magnitude", "camp",
         "campaign --out {out} --quick --effects dihedral=lots", "dihedral"),
    case("opt-campaign-noise-negative", "camp", "campaign --out {out} --quick --noise-scale -1",
         "--noise-scale"),
    case("opt-campaign-turbulence-negative", "camp",
         "campaign --out {out} --quick --turbulence -1", "--turbulence"),
    case("opt-campaign-excitation-nan", "camp", "campaign --out {out} --quick --excitation nan",
         "--excitation"),
    case("opt-campaign-turbulence-and-calm", "camp",
         "campaign --out {out} --quick --turbulence 1 --no-turbulence", "--no-turbulence"),
    case("opt-campaign-withhold-builtin", "camp",
         "campaign --out {out} --quick --withhold none", "--withhold", "jsbsim"),
    case("opt-campaign-no-out", "camp", "campaign --quick", "--out", status=2),
    case("opt-campaign-out-under-file", "camp", "campaign --out {d}/a_file/c --quick",
         "a_file", setup=A_FILE),
    case("opt-map-template-missing", "camp", "map-template {d}/none.csv", "none.csv"),
    case("opt-map-template-folder", "camp", "map-template {camp}", "folder"),
    case("opt-map-template-empty", "camp", "map-template {d}/e.csv", "e.csv",
         setup=_write("e.csv", "")),
    case("opt-map-template-header-only", "camp", "map-template {d}/h.csv", "h.csv",
         "no data rows", setup=_write("h.csv", "time_ms,aoa\n")),
    case("opt-map-template-corrupt-parquet", "camp", "map-template {d}/x.parquet", "x.parquet",
         setup=_write("x.parquet", b"PAR1garbage")),
    case("opt-map-template-exists", "csv", f"map-template {{csv}}/records/{R0}.csv -o "
         "{d}/a_file", "--out", "--force", setup=A_FILE),
    case("opt-map-template-out-folder", "csv", f"map-template {{csv}}/records/{R0}.csv -o "
         "{csv}", "--out", "folder"),
    case("opt-export-qualified-folder", "dml", "export-qualified {dml}", "folder"),
    case("opt-write-example-under-file", "dml", "write-example-model {d}/a_file/x.dml",
         "a_file", setup=A_FILE),
    case("opt-check-daveml-format", "dml", CHECK + " --format yaml", "--format", status=2),
    case("opt-unknown-command", "dml", "frobnicate {dml}", "frobnicate", status=2),
    case("opt-fit-unknown-option-value", "ing", FIT + " --holdout", "--holdout", status=2),
]  # fmt: skip

NESTED = "{d}/new/deeper/"


def _ingested(rel: str, n: int) -> Check:
    """An accepted ingest: its four files, ``n`` maneuvers in ``data.parquet``."""

    def check(d: Path) -> list[str]:
        out = d / rel
        files = ("data.parquet", "validation.json", "smoothing.csv")
        bad = [f"{f} missing" for f in files if not (out / f).is_file()]
        got = pl.read_parquet(out / "data.parquet")["maneuver_id"].n_unique()
        return bad + ([f"{got} maneuvers, not {n}"] if got != n else [])

    return check


def _model_pair(rel: str) -> Check:
    """An accepted fit: the model loads and names its per-bin table by hash."""

    def check(d: Path) -> list[str]:
        model = d / rel
        params = model.with_suffix(".params.parquet")
        DeltaModel.load(model)
        want = json.loads(model.read_text())["provenance"]["params_sha256"]
        got = hashlib.sha256(params.read_bytes()).hexdigest()
        return [] if got == want else [f"{params.name} is not the table {model.name} names"]

    return check


def _xml(rel: str, *needles: str) -> Check:
    """An accepted export: well-formed XML holding ``needles``."""

    def check(d: Path) -> list[str]:
        text = (d / rel).read_text()
        ET.fromstring(text)
        return [f"{n!r} not in {rel}" for n in needles if n not in text]

    return check


def _daveml_checks(rel: str) -> Check:
    """An accepted DAVE-ML file: it loads and passes its own check cases."""

    def check(d: Path) -> list[str]:
        checks = load_daveml(d / rel).run_checks()
        return [] if checks.height and checks["pass"].all() else [f"{rel}: check cases fail"]

    return check


def _file_holds(rel: str, *needles: str) -> Check:
    def check(d: Path) -> list[str]:
        text = (d / rel).read_text()
        return [f"{n!r} not in {rel}" for n in needles if n not in text]

    return check


ACCEPTED = [
    case("ok-ingest-nested", "camp", f"ingest {{camp}} --out {NESTED}ing --quiet --no-compat",
         "ingested 8 maneuvers", ok=True, creates=["new/deeper/ing"],
         check=_ingested("new/deeper/ing", 8)),
    case("ok-ingest-user-layout", "user", ING_USER.replace("{out}", NESTED + "ing"),
         "ingested 4 maneuvers", ok=True, creates=["new/deeper/ing"],
         check=_ingested("new/deeper/ing", 4)),
    case("ok-fit-nested", "ing", f"fit {{ing}} --out {NESTED}m.json --no-progress", ok=True,
         creates=["new/deeper/m.json", "new/deeper/m.params.parquet"],
         check=_model_pair("new/deeper/m.json")),
    case("ok-validate-nested", "ing model", VALIDATE + f" --out {NESTED}v.csv", ok=True,
         creates=["new/deeper/v.csv"], check=_file_holds("new/deeper/v.csv", "Cl,", "Cn,", "CY,")),
    case("ok-rolloff-nested", "ing", f"rolloff {{ing}} --out {NESTED}ro --no-figures "
         "--no-progress", ok=True, creates=["new/deeper/ro"],
         check=_file_holds("new/deeper/ro/summary.json", '"maneuvers": 8')),
    case("ok-export-jsbsim-nested", "model",
         f"export --model {{model}}/model.json --jsbsim {NESTED}delta.xml", ok=True,
         creates=["new/deeper/delta.xml"], check=_xml("new/deeper/delta.xml", "aerodelta")),
    case("ok-export-property-product", "model",
         f"export --model {{model}}/model.json --jsbsim {NESTED}delta.xml "
         "--property da_deg=-1*fcs/aileron-pos-deg", ok=True, creates=["new/deeper/delta.xml"],
         check=_xml("new/deeper/delta.xml", "fcs/aileron-pos-deg")),
    case("ok-export-daveml-nested", "model",
         f"export --model {{model}}/model.json --daveml {NESTED}x.dml", ok=True,
         creates=["new/deeper/x.dml"], check=_daveml_checks("new/deeper/x.dml")),
    case("ok-map-template-nested", "user",
         f"map-template {{user}}/records/{R0}.csv -o {NESTED}map.toml", ok=True,
         creates=["new/deeper/map.toml"],
         check=_file_holds("new/deeper/map.toml", "[channels]", "# REVIEW")),
    case("ok-export-qualified-nested", "dml", f"export-qualified {NESTED}q.dml", ok=True,
         creates=["new/deeper/q.dml"], check=_daveml_checks("new/deeper/q.dml")),
    case("ok-write-example-nested", "dml", f"write-example-model {NESTED}e.dml", ok=True,
         creates=["new/deeper/e.dml"], check=_daveml_checks("new/deeper/e.dml")),
    case("ok-check-daveml", "dml", CHECK, "0 failed", ok=True),
    case("ok-campaign-nested", "camp", f"campaign --out {NESTED}c --quick --seed 2", ok=True,
         creates=["new/deeper/c"],
         check=lambda d: [] if pl.read_csv(d / "new/deeper/c/manifest.csv").height == 40
         else ["the campaign lacks maneuvers"]),
    case("ok-fit-holdout-nested", "ing",
         f"fit {{ing}} --out {NESTED}m.json --holdout 0.25 --holdout-seed 3 --no-progress",
         "held out 2 of 8 maneuvers", ok=True,
         creates=["new/deeper/m.json", "new/deeper/m.params.parquet", "new/deeper/m.holdout.txt",
                  "new/deeper/m.validation.csv"],
         check=_model_pair("new/deeper/m.json")),
]  # fmt: skip

CASES: list[Case] = [
    *CSV_RECORDS,
    *PARQUET_RECORDS,
    *MANIFESTS,
    *CHANNEL_MAPS,
    *AIRCRAFT,
    *FIT_CONFIGS,
    *MODELS,
    *DAVEML,
    *EFFECTS,
    *OPTIONS,
    *ACCEPTED,
]


def test_the_suite_is_as_large_as_issue_18_asks() -> None:
    ids = [c.id for c in (*CASES, *CRASH_CASES)]
    assert len(ids) == len(set(ids)), "duplicate case ids"
    assert len(CASES) + len(CRASH_CASES) >= 150


@pytest.mark.parametrize("c", CASES, ids=[c.id for c in CASES])
def test_bad_input(
    c: Case,
    bases: dict[str, Path],
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    d = tmp_path
    argv = prepare(c, bases, d)
    before = snapshot(d)
    monkeypatch.chdir(d)  # anything written relative to the working folder is seen too
    capfd.readouterr()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # a user sees every warning as lines on stderr
        status = run_main(argv)
    out, err = capfd.readouterr()
    err += "".join(
        warnings.formatwarning(w.message, w.category, w.filename, w.lineno) for w in caught
    )
    problems = judge(c, d, argv, status=status, out=out, err=err, before=before, after=snapshot(d))
    assert not problems, "\n".join(problems)


# ---- the crash class, in a child interpreter ---------------------------------------------


def _billion_laughs() -> str:
    ents = ['<!ENTITY l0 "lollollollollollollollollollol">']
    ents += [f'<!ENTITY l{i} "{f"&l{i - 1};" * 10}">' for i in range(1, 10)]
    return (
        '<?xml version="1.0"?>\n<!DOCTYPE DAVEfunc [' + "".join(ents) + "]>\n"
        '<DAVEfunc xmlns="http://daveml.org/2010/DAVEML"><fileHeader name="&l9;"/></DAVEfunc>\n'
    )


def _quadratic_blowup() -> str:
    big = "x" * 50_000
    return (
        f'<?xml version="1.0"?>\n<!DOCTYPE DAVEfunc [<!ENTITY big "{big}">]>\n'
        '<DAVEfunc xmlns="http://daveml.org/2010/DAVEML"><fileHeader name="'
        + "&big;" * 3000
        + '"/></DAVEfunc>\n'
    )


def _deep_mathml(k: int) -> str:
    return (
        '<?xml version="1.0"?>\n<DAVEfunc xmlns="http://daveml.org/2010/DAVEML">\n'
        '<variableDef name="a" varID="a" units="nd"><isInput/></variableDef>\n'
        '<variableDef name="b" varID="b" units="nd"><calculation>'
        '<math xmlns="http://www.w3.org/1998/Math/MathML">'
        + "<apply><plus/><cn>1</cn>" * k
        + "<ci>a</ci>"
        + "</apply>" * k
        + "</math></calculation><isOutput/></variableDef>\n</DAVEfunc>\n"
    )


def _deep_model(d: Path) -> None:
    p = d / "model" / "model.json"
    doc = json.loads(p.read_text())
    doc["coefficients"]["Cl"]["terms"][1]["regressor"] = DEEP
    p.write_text(json.dumps(doc))


CRASH_CASES = [
    case("crash-deep-regressor-in-model", "ing model", VALIDATE, "model.json", "levels deep",
         setup=_deep_model),
    case("crash-deep-regressor-in-export", "model", EXPORT, "model.json", "levels deep",
         setup=_deep_model),
    case("crash-deep-regressor-in-config", "ing cfg", FIT_CFG, "fit.toml", "levels deep",
         setup=_cfg(f'selection = "none"\n[structures]\nCl = [["dCl_deep", "{DEEP}"]]\n')),
    case("crash-flat-regressor-in-config", "ing cfg", FIT_CFG, "fit.toml", "deep",
         setup=_cfg('selection = "none"\n[structures]\nCl = [["dCl_flat", "'
                    + " + ".join(["beta_deg"] * N_DEEP) + '"]]\n')),
    case("crash-deep-effect", "ing cfg", DIAG + " --effects {cfg}/effects.toml", "effects.toml",
         setup=_effects(f"[deep]\nCl = ['{DEEP}']\n")),
    case("crash-deep-mathml", "dml", CHECK, "example.dml", "deep",
         setup=_write("dml/example.dml", _deep_mathml(6_200))),
    case("crash-billion-laughs", "dml", CHECK, "example.dml", "entit",
         setup=_write("dml/example.dml", _billion_laughs())),
    case("crash-quadratic-entity", "dml", CHECK, "example.dml", "entit",
         setup=_write("dml/example.dml", _quadratic_blowup())),
    case("crash-deep-toml-config", "ing cfg", FIT_CFG, "fit.toml",
         setup=_cfg("x = " + "[" * N_DEEP + "]" * N_DEEP + "\n")),
    case("crash-deep-json-model", "ing model", VALIDATE, "model.json",
         setup=_write("model/model.json", "[" * N_DEEP + "]" * N_DEEP)),
    case("crash-deep-map", "user", ING_USER, "map.toml",
         setup=_map("[channels]\nt = " + "[" * N_DEEP + "]" * N_DEEP + "\n")),
    case("crash-huge-csv-line", "csv", ING, f"{R0}.csv",
         setup=_csv(lambda ls: [ls[0], "9" * 5_000_000, *ls[2:]])),
]  # fmt: skip


@pytest.mark.parametrize("c", CRASH_CASES, ids=[c.id for c in CRASH_CASES])
def test_crash_class_in_a_child(c: Case, bases: dict[str, Path], tmp_path: Path) -> None:
    d = tmp_path
    argv = prepare(c, bases, d)
    before = snapshot(d)
    # the child imports the same aerodelta as this process
    env = {**os.environ, "PYTHONPATH": str(Path(aerodelta.__file__).resolve().parent.parent)}
    r = subprocess.run(
        [sys.executable, "-m", "aerodelta", *argv],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=d,
        env=env,
    )
    assert r.returncode >= 0, f"killed by signal {-r.returncode}: {r.stderr[-2000:]}"
    problems = judge(
        c,
        d,
        argv,
        status=r.returncode,
        out=r.stdout,
        err=r.stderr,
        before=before,
        after=snapshot(d),
    )
    assert not problems, "\n".join(problems)
