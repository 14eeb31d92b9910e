"""Fixtures and checks of the bad-input suite (``tests/test_bad_inputs.py``, issue 18).

One small virtual campaign is built per test module (:func:`build_fixtures`) and each case
copies only the parts it names (:func:`copy_bases`), breaks them (:class:`Case` ``setup``),
snapshots every byte (:func:`snapshot`), runs the command in-process and compares.
"""

from __future__ import annotations

import hashlib
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

import aerodelta as ad
from aerodelta.cli import COMMANDS, main

#: Maneuvers of the flap-0 campaign kept in the Parquet campaign (``camp``) and, the first
#: :data:`N_CSV` of them, in the CSV campaigns (``csv``, ``user``).
N_CAMP = 8
N_CSV = 4

#: The user's layout of ``user``: own column names and units for three channels.
USER_COLUMNS = {"t": ("time_ms", 1000.0), "alpha_deg": ("AOA", np.pi / 180.0)}
KT = 1852.0 / 3600.0
USER_MAP = """[channels]
t = { source = "time_ms", unit = "ms" }
alpha_deg = { source = "AOA", unit = "rad" }
tas_mps = { source = "KTAS", unit = "kt" }
"""

#: A valid fit configuration and a valid user effect file.
FIT_TOML = 'width_deg = 0.25\nselection = "none"\ncv_folds = 4\n'
EFFECTS_TOML = "[beta_rate]\nCl = ['beta_deg * rhat']\n"


def _copy_campaign(gen: Path, out: Path, ids: Sequence[str], suffix: str) -> None:
    """Write ``ids`` of the generated campaign ``gen`` into ``out/records`` as ``suffix``
    files, with the manifest's ``file`` column naming them and the aircraft file."""
    (out / "records").mkdir(parents=True)
    man = pl.read_csv(gen / "manifest.csv").filter(pl.col("maneuver_id").is_in(list(ids)))
    for mid in ids:
        rec = pl.read_parquet(gen / "records" / f"{mid}.parquet")
        if suffix == ".csv":
            rec.write_csv(out / "records" / f"{mid}.csv")
        else:
            rec.write_parquet(out / "records" / f"{mid}.parquet")
    man.with_columns(pl.format("records/{}" + suffix, "maneuver_id").alias("file")).write_csv(
        out / "manifest.csv"
    )
    shutil.copy(gen / "aircraft.toml", out / "aircraft.toml")


def build_fixtures(root: Path) -> dict[str, Path]:
    """Build every base a case may copy, under ``root``; returns ``name -> path``.

    ``camp``: 8 flap-0 maneuvers as Parquet with manifest and aircraft file; ``csv``: 4 of them
    as CSV; ``user``: the same 4 in the user's layout (``time_ms`` in ms, ``AOA`` in rad,
    ``KTAS`` in kt) with ``map.toml``, ``aircraft.toml``, ``manifest.csv``; ``ing``: the
    ``aerodelta ingest`` output of ``camp``; ``model``: ``model.json`` and
    ``model.params.parquet`` of ``aerodelta fit`` on ``ing``; ``dml``: the example DAVE-ML
    model; ``cfg``: a valid ``fit.toml`` and ``effects.toml``.
    """
    gen = root / "_generated"
    ad.generate_campaign(gen, seed=11, size="quick", progress=False)
    man = pl.read_csv(gen / "manifest.csv")
    ids = man.filter(pl.col("flap_deg") == 0.0)["maneuver_id"].to_list()[:N_CAMP]
    bases = {k: root / k for k in ("camp", "csv", "user", "ing", "model", "dml", "cfg")}
    _copy_campaign(gen, bases["camp"], ids, ".parquet")
    _copy_campaign(gen, bases["csv"], ids[:N_CSV], ".csv")
    user = bases["user"]
    _copy_campaign(gen, user, ids[:N_CSV], ".csv")
    for mid in ids[:N_CSV]:
        path = user / "records" / f"{mid}.csv"
        rec = pl.read_csv(path)
        renamed = {c: pl.col(c) * k for c, (_, k) in USER_COLUMNS.items()}
        rec = rec.with_columns(**renamed, tas_mps=pl.col("tas_mps") / KT).rename(
            {**{c: n for c, (n, _) in USER_COLUMNS.items()}, "tas_mps": "KTAS"}
        )
        rec.write_csv(path)
    (user / "map.toml").write_text(USER_MAP)
    res = ad.ingest(bases["camp"], compat=False, progress=False)
    res.write(bases["ing"])
    model = bases["model"] / "model.json"
    assert main(["fit", str(bases["ing"]), "--out", str(model), "--no-progress"]) == 0
    bases["dml"].mkdir()
    assert main(["write-example-model", str(bases["dml"] / "example.dml")]) == 0
    bases["cfg"].mkdir()
    (bases["cfg"] / "fit.toml").write_text(FIT_TOML)
    (bases["cfg"] / "effects.toml").write_text(EFFECTS_TOML)
    shutil.rmtree(gen)
    return bases


def copy_bases(bases: dict[str, Path], names: Sequence[str], dest: Path) -> None:
    """Copy the named bases into ``dest`` (same names)."""
    for n in names:
        shutil.copytree(bases[n], dest / n)


def snapshot(d: Path) -> dict[str, str]:
    """Every file and folder under ``d``: relative path -> SHA-256 of the bytes (``"dir"``
    for folders, ``"link:TARGET"`` for symbolic links)."""
    out: dict[str, str] = {}
    for p in sorted(d.rglob("*")):
        rel = str(p.relative_to(d))
        if p.is_symlink():
            out[rel] = f"link:{p.readlink()}"
        elif p.is_dir():
            out[rel] = "dir"
        else:
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


# ---- edits a case applies to its copy ----------------------------------------------------


def csv_lines(path: Path, edit: Callable[[list[str]], list[str]]) -> None:
    """Rewrite a CSV file line by line (``edit`` gets the lines without their newlines)."""
    lines = path.read_text().splitlines()
    path.write_text("\n".join(edit(lines)) + "\n")


def set_cell(path: Path, column: str, row: int, value: str) -> None:
    """Put the raw text ``value`` in ``column`` at data row ``row`` (0-based; negative from
    the end) of a CSV."""

    def edit(lines: list[str]) -> list[str]:
        j = lines[0].split(",").index(column)
        i = row + 1 if row >= 0 else len(lines) + row
        cells = lines[i].split(",")
        cells[j] = value
        lines[i] = ",".join(cells)
        return lines

    csv_lines(path, edit)


def frame_edit(path: Path, edit: Callable[[pl.DataFrame], pl.DataFrame]) -> None:
    """Rewrite a CSV or Parquet record through a polars edit."""
    if path.suffix == ".csv":
        edit(pl.read_csv(path)).write_csv(path)
    else:
        edit(pl.read_parquet(path)).write_parquet(path)


def replace_text(path: Path, old: str, new: str) -> None:
    """Replace ``old`` (which must occur) by ``new`` in a text file."""
    text = path.read_text()
    assert old in text, f"{old!r} not in {path}"
    path.write_text(text.replace(old, new, 1))


def first_record(d: Path, base: str, suffix: str = ".csv") -> Path:
    """The first record file (sorted) of a copied campaign base."""
    return sorted((d / base / "records").glob(f"*{suffix}"))[0]


# ---- the cases -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One bad (or tricky but valid) input.

    Attributes
    ----------
    id
        Test id.
    bases
        Fixture bases copied into the case folder before ``setup``.
    argv
        The command line; ``{d}`` is the case folder, ``{camp}`` etc. the copied bases,
        ``{out}`` a path that does not exist yet.
    want
        Substrings the one error line must hold (the file, channel, row or option, and the
        gist), or that stdout must hold for an accepted case.
    setup
        Breaks the copied inputs (gets the case folder).
    ok
        The input is valid: exit 0 and ``creates`` written.
    creates
        Paths (relative to the case folder) an accepted case must write; only these and what
        lies under them may be new.
    status
        The exit status of a refused case (1; 2 for argument syntax).
    check
        For an accepted case: what is wrong with its outputs (gets the case folder).
    """

    id: str
    bases: tuple[str, ...]
    argv: tuple[str, ...]
    want: tuple[str, ...] = ()
    setup: Callable[[Path], object] | None = None
    ok: bool = False
    creates: tuple[str, ...] = ()
    status: int = 1
    check: Callable[[Path], list[str]] | None = None


def case(
    id: str,
    bases: str,
    argv: str,
    *want: str,
    setup: Callable[[Path], object] | None = None,
    ok: bool = False,
    creates: Sequence[str] = (),
    status: int = 1,
    check: Callable[[Path], list[str]] | None = None,
) -> Case:
    """A :class:`Case` from a space-separated base list and command line (arguments with
    spaces are not needed by any case)."""
    return Case(
        id,
        tuple(bases.split()),
        tuple(argv.split()),
        tuple(want),
        setup,
        ok,
        tuple(creates),
        status,
        check,
    )


# ---- running and judging a case ----------------------------------------------------------

#: API wording that must never reach a CLI user, and internals that must never be named.
FORBIDDEN = (
    "Traceback",
    "aircraft=",
    "channel_map=",
    "manifest=",
    "apply_compat=",
    "pass ",
    ".tmp-",
    "panicked",
    "RUST_BACKTRACE",
)


def prepare(c: Case, bases: dict[str, Path], d: Path) -> list[str]:
    """Copy the case's bases into ``d``, break them, and return its command line."""
    copy_bases(bases, c.bases, d)
    if c.setup is not None:
        c.setup(d)
    where = {"d": d, "out": d / "out", **{b: d / b for b in c.bases}}
    return [a.format(**where) for a in c.argv]


def run_main(argv: list[str]) -> int:
    """``aerodelta.cli.main(argv)``; argparse's exit (status 2) as a status."""
    try:
        return main(argv)
    except SystemExit as e:
        return int(e.code or 0)


def judge(
    c: Case,
    d: Path,
    argv: list[str],
    *,
    status: int,
    out: str,
    err: str,
    before: dict[str, str],
    after: dict[str, str],
) -> list[str]:
    """What is wrong with the outcome of case ``c`` run in folder ``d`` (empty: nothing)."""
    problems: list[str] = []
    changed = sorted(k for k, v in before.items() if after.get(k) != v)
    if changed:
        problems.append(f"inputs modified or removed: {changed}")
    new = sorted(set(after) - set(before))
    temps = [n for n in new if ".tmp" in n or ".old-" in n]
    if temps:
        problems.append(f"temporary files left: {temps}")
    if c.ok:
        if status != 0:
            problems.append(f"refused (status {status}): {err[-1500:]}")
        problems += [f"{p} not written" for p in c.creates if p not in after]
        stray = [
            n
            for n in new
            if not any(n == p or n.startswith(p + "/") or p.startswith(n + "/") for p in c.creates)
        ]
        if stray:
            problems.append(f"wrote outside its outputs: {stray}")
        problems += [f"{w!r} not in the output" for w in c.want if w not in out + err]
        noise = [x for x in err.splitlines() if "Warning:" in x or "Traceback" in x]
        if noise:
            problems.append(f"warnings on stderr: {noise[:3]}")
        if c.check is not None:
            problems += c.check(d)
        return problems
    lines = [x for x in err.splitlines() if x.strip()]
    if status != c.status:
        problems.append(f"status {status}, not {c.status}")
    if len(lines) != 1:
        problems.append(f"{len(lines)} lines on stderr:\n{err[-3000:]}")
        return problems
    line = lines[0]
    cmd = f"aerodelta {argv[0]}" if argv[0] in COMMANDS else "aerodelta"
    if not line.startswith(f"{cmd}: error: "):
        problems.append(f"not an error line of {cmd}: {line[:600]}")
    if len(line) > 1200:
        problems.append(f"{len(line)} characters: {line[:600]}...")
    problems += [f"{w!r} not named in: {line[:1200]}" for w in c.want if w not in line]
    problems += [f"{b!r} in: {line[:1200]}" for b in FORBIDDEN if b in line]
    if new:
        problems.append(f"a refused command wrote {new}")
    return problems
