"""What the commands that read flight records share: one way to name the data, one loader, and
the checks of options and output paths that run before any computation.

The data (``DATA``, positional, or ``--data DATA``) is one of

- a campaign folder: record files in ``DATA`` or ``DATA/records`` (CSV, Parquet, ``.mat``),
  ``manifest.csv`` and ``aircraft.toml`` by default, or the files given with ``--manifest``,
  ``--aircraft`` and, for records in the user's own columns and units, ``--map``;
- one record file (with ``--aircraft``; a ``maneuver_id`` column splits it);
- the output folder of ``aerodelta ingest`` (recognised by its ``data.parquet``), or that
  ``data.parquet`` itself: already mapped and preprocessed, so ``--map``, ``--manifest`` and
  (except where a command says otherwise) ``--aircraft`` do not apply.

The other files an ingest output holds (``compat.csv``, ``smoothing.csv``,
``validation.json``) are never read as flight records.
"""

from __future__ import annotations

import argparse
import math
import shutil
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from aerodelta.exceptions import DataError, InvalidInputError

if TYPE_CHECKING:
    import polars as pl

    from aerodelta.ingest import IngestResult
    from aerodelta.model import DeltaModel

#: Files ``aerodelta ingest`` writes beside ``data.parquet``.
INGEST_FILES = ("data.parquet", "validation.json", "smoothing.csv", "compat.csv")
#: Columns every ingest output has (the loader refuses a Parquet file without them as one).
INGESTED_COLUMNS = ("maneuver_id", "t", "Cl_meas", "Cn_meas", "CY_meas")


def add_data_arguments(parser: argparse.ArgumentParser, *, aircraft_help: str = "") -> None:
    """Declare ``DATA`` (positional, or ``--data``), ``--map``, ``--aircraft``, ``--manifest``."""
    parser.add_argument(
        "data",
        nargs="?",
        metavar="DATA",
        help="campaign folder (records, manifest.csv, aircraft.toml), one record file, or the "
        "output folder of aerodelta ingest (data.parquet)",
    )
    parser.add_argument(
        "--data", dest="data_option", metavar="DATA", help="the same as DATA, as an option"
    )
    parser.add_argument(
        "--map",
        dest="channel_map",
        metavar="FILE",
        help="channel map TOML: the records' own column names and units (aerodelta "
        "map-template writes a skeleton); default: records already in canonical channels",
    )
    parser.add_argument(
        "--aircraft",
        metavar="FILE",
        help=aircraft_help or "aircraft reference TOML (default DATA/aircraft.toml)",
    )
    parser.add_argument(
        "--manifest", metavar="FILE", help="manifest CSV/Parquet (default DATA/manifest.csv)"
    )
    parser.add_argument(
        "--no-plausibility",
        dest="plausibility",
        action="store_false",
        help="skip the kinematic unit and sign check of the raw records (docs/data.md, "
        "Plausibility); for records whose kinematics the check cannot read",
    )


@dataclass(frozen=True)
class DataSource:
    """The resolved data of a command.

    Attributes
    ----------
    path
        What the user named.
    kind
        ``"campaign"`` (a folder of raw records), ``"record"`` (one raw record file) or
        ``"ingested"`` (an ingest output folder or its ``data.parquet``).
    aircraft, channel_map, manifest
        The files that apply (checked to exist), or None.
    plausibility
        Run the kinematic unit and sign check when the records are ingested.
    """

    path: Path
    kind: str
    aircraft: Path | None = None
    channel_map: Path | None = None
    manifest: Path | None = None
    plausibility: bool = True

    @property
    def parquet(self) -> Path:
        """The ``data.parquet`` of an ingest output."""
        return self.path / "data.parquet" if self.path.is_dir() else self.path

    def describe(self) -> str:
        """A few words for messages: what was read."""
        if self.kind == "ingested":
            return f"the ingest output {self.parquet}"
        what = "campaign" if self.kind == "campaign" else "record file"
        extra = [f"map {self.channel_map}"] if self.channel_map else []
        return f"the {what} {self.path}" + (f" ({', '.join(extra)})" if extra else "")


def add_aft_stop_argument(parser: argparse.ArgumentParser) -> None:
    """Declare ``--aft-stop DEG`` (the stall identification's aft-stop criterion)."""
    parser.add_argument(
        "--aft-stop",
        type=float,
        metavar="DEG",
        help="the elevator's aft (nose-up) stop, deg (negative, Etkin); default: the most "
        "nose-up deflection recorded in each maneuver",
    )


def aft_stop_deg(args: argparse.Namespace) -> float | None:
    """``--aft-stop`` in deg (None: not given); a non-finite value is refused in one line."""
    if args.aft_stop is not None and not math.isfinite(args.aft_stop):
        raise InvalidInputError(f"--aft-stop {args.aft_stop}: give the stop in deg, e.g. -22")
    return args.aft_stop


def _data_path(args: argparse.Namespace) -> Path:
    pos, opt = getattr(args, "data", None), getattr(args, "data_option", None)
    if pos and opt and Path(pos) != Path(opt):
        raise InvalidInputError(
            f"the data is given twice ({pos} and --data {opt}); give DATA or --data DATA once"
        )
    value = pos or opt
    if not value:
        raise InvalidInputError(
            f"no data: give the campaign folder or the ingest output, aerodelta {args.command} "
            "DATA (or --data DATA)"
        )
    return Path(value)


def qualified_choice(value: str) -> str:
    """``--model``: auto, columns, adx37, jsbsim:DIR (a JSBSim campaign folder) or a DAVE-ML
    file (their existence is checked with the other inputs)."""
    if (
        value in ("auto", "columns", "adx37")
        or value.lower().endswith((".dml", ".xml"))
        or (value.startswith("jsbsim:") and len(value) > len("jsbsim:"))
    ):
        return value
    raise argparse.ArgumentTypeError(
        f"invalid choice: {value!r} (use auto, columns, adx37, jsbsim:DIR or a DAVE-ML file, .dml)"
    )


def jsbsim_campaign_option(value: str, option: str) -> Path | None:
    """The campaign folder of a ``jsbsim:DIR`` qualified model (checked to exist), else None."""
    if not value.startswith("jsbsim:"):
        return None
    p = Path(value[len("jsbsim:") :])
    if not p.is_dir():
        raise InvalidInputError(
            f"{option} {value}: folder not found; name a JSBSim campaign folder "
            "(aerodelta campaign --simulator jsbsim)"
        )
    return p


def existing_file(value: str | None, option: str) -> Path | None:
    if value is None:
        return None
    p = Path(value)
    if p.is_dir():
        raise InvalidInputError(f"{option} {p}: is a folder; give the file")
    if not p.is_file():
        raise InvalidInputError(f"{option} {p}: file not found")
    return p


def load_model(value: str | Path, option: str = "--model") -> DeltaModel:
    """A Δ model file (``aerodelta fit`` output) for a command: it exists, loads, and corrects
    the coefficients the commands know (Cl, Cn, CY).

    Raises
    ------
    InvalidInputError, ParseError
        The option or the file named.
    """
    from aerodelta.fit import COEFFICIENTS  # noqa: PLC0415
    from aerodelta.model import DeltaModel  # noqa: PLC0415

    p = existing_file(str(value), option)
    assert p is not None
    model = DeltaModel.load(p)
    unknown = [c for c in model.coefficients if c not in COEFFICIENTS]
    if unknown:
        raise InvalidInputError(
            f"{option} {p}: corrects coefficient(s) {', '.join(unknown)}; an aerodelta model "
            f"corrects {', '.join(COEFFICIENTS)}"
        )
    return model


def _is_ingested_parquet(p: Path) -> bool:
    import polars as pl  # noqa: PLC0415  (keeps CLI start-up light)

    try:
        names = pl.read_parquet_schema(p)
    except Exception as e:  # polars raises several kinds for a file that is not Parquet
        raise DataError(
            f"{p}: cannot read this Parquet file ({_first_line(e)}); check the file"
        ) from e
    return all(c in names for c in INGESTED_COLUMNS)


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def resolve_data(args: argparse.Namespace, *, aircraft_with_ingested: bool = False) -> DataSource:
    """Classify the data and check the files that go with it (nothing is read but headers).

    ``aircraft_with_ingested``: the command uses ``--aircraft`` even with an ingest output
    (``diagnose``); elsewhere ``--aircraft`` with an ingest output is refused as meaningless.

    Raises
    ------
    InvalidInputError
        Options that do not apply, files that do not exist (option and file named).
    DataError
        Data that is neither a campaign, a record nor an ingest output.
    """
    p = _data_path(args)
    cmap = existing_file(getattr(args, "channel_map", None), "--map")
    aircraft = existing_file(getattr(args, "aircraft", None), "--aircraft")
    manifest = existing_file(getattr(args, "manifest", None), "--manifest")
    if not p.exists():
        raise DataError(f"{p}: no such file or folder (give the campaign folder or ingest output)")
    if p.is_dir():
        if (p / "data.parquet").is_file():
            kind = "ingested"
        else:
            others = [n for n in INGEST_FILES[1:] if (p / n).is_file()]
            if others:
                raise DataError(
                    f"{p}: holds {', '.join(others)} of an aerodelta ingest output but no "
                    "data.parquet; run aerodelta ingest again, or give the campaign folder"
                )
            kind = "campaign"
    elif p.suffix.lower() == ".parquet" and _is_ingested_parquet(p):
        kind = "ingested"
    else:
        kind = "record"
    plausibility = bool(getattr(args, "plausibility", True))
    if kind == "ingested":
        given = [o for o, v in (("--map", cmap), ("--manifest", manifest)) if v is not None]
        if not plausibility:
            given.append("--no-plausibility")
        if aircraft is not None and not aircraft_with_ingested:
            given.append("--aircraft")
        if given:
            many = len(given) > 1
            raise InvalidInputError(
                f"{' and '.join(given)} {'apply' if many else 'applies'} to raw records, but "
                f"{p} is an aerodelta ingest output (already mapped and preprocessed); drop "
                f"{'them' if many else 'it'} or give the campaign folder"
            )
        return DataSource(p, kind, aircraft=aircraft)
    if aircraft is None:
        default = p / "aircraft.toml" if p.is_dir() else None
        if default is None:
            raise InvalidInputError(
                f"{p}: a record file needs --aircraft FILE (the aircraft reference TOML, see "
                "docs/data.md)"
            )
        if not default.is_file():
            raise InvalidInputError(
                f"{p}: no aircraft reference: give --aircraft FILE (TOML, see docs/data.md) or "
                f"put aircraft.toml in {p}"
            )
        aircraft = default
    if manifest is None and p.is_dir() and (p / "manifest.csv").is_file():
        manifest = p / "manifest.csv"
    return DataSource(
        p, kind, aircraft=aircraft, channel_map=cmap, manifest=manifest, plausibility=plausibility
    )


def read_ingested(src: DataSource) -> pl.DataFrame:
    """The ``data.parquet`` of an ingest output, checked to be one."""
    import polars as pl  # noqa: PLC0415

    path = src.parquet
    try:
        df = pl.read_parquet(path)
    except Exception as e:
        raise DataError(
            f"{path}: cannot read the ingest output ({_first_line(e)}); run aerodelta ingest again"
        ) from e
    missing = [c for c in INGESTED_COLUMNS if c not in df.columns]
    if missing:
        raise DataError(
            f"{path}: not an aerodelta ingest output (no column {', '.join(missing)}); give the "
            "campaign folder or the folder written by aerodelta ingest"
        )
    return df


def ingest_source(src: DataSource, *, progress: bool, **options: object) -> IngestResult:
    """``aerodelta.ingest`` on a campaign or record (``options``: its keyword arguments);
    returns the :class:`aerodelta.ingest.IngestResult`."""
    import polars as pl  # noqa: PLC0415

    from aerodelta.ingest import ingest  # noqa: PLC0415

    if src.kind == "ingested":
        raise InvalidInputError(
            f"{src.path} is already an aerodelta ingest output; give the campaign folder"
        )
    try:
        return ingest(
            src.path,
            aircraft=src.aircraft,
            channel_map=src.channel_map,
            manifest=src.manifest,
            progress=progress,
            **{"plausibility": src.plausibility, **options},  # type: ignore[arg-type]
        )
    except pl.exceptions.PolarsError as e:
        hint = " (check the records against --map)" if src.channel_map else ""
        raise DataError(f"{src.path}: cannot read the records: {_first_line(e)}{hint}") from e


def load_records(src: DataSource, *, progress: bool = False) -> pl.DataFrame:
    """The ingested records of any data: read from an ingest output, or ingested here
    (without the compatibility check, as ``aerodelta ingest --no-compat``)."""
    if src.kind == "ingested":
        return read_ingested(src)
    return ingest_source(src, progress=progress, compat=False).data


def load_data(
    args: argparse.Namespace, *, progress: bool = False, aircraft_with_ingested: bool = False
) -> tuple[pl.DataFrame, DataSource]:
    """:func:`resolve_data` then :func:`load_records`."""
    src = resolve_data(args, aircraft_with_ingested=aircraft_with_ingested)
    return load_records(src, progress=progress), src


# ---- options and output paths, checked before any computation ----


def check_open_unit(value: float, option: str, example: str = "0.05") -> None:
    """Refuse a probability or level outside (0, 1)."""
    if not 0.0 < value < 1.0:
        raise InvalidInputError(
            f"{option} {value:g}: must lie strictly between 0 and 1 (e.g. {option} {example})"
        )


def check_share(value: float, option: str, example: str) -> None:
    """Refuse a share outside [0, 1)."""
    if not 0.0 <= value < 1.0:
        raise InvalidInputError(
            f"{option} {value:g}: a share must lie in [0, 1) (e.g. {option} {example})"
        )


def check_at_least(value: int, option: str, low: int, why: str = "") -> None:
    """Refuse an integer option below ``low``."""
    if value < low:
        raise InvalidInputError(
            f"{option} {value}: must be at least {low}" + (f" ({why})" if why else "")
        )


def _blocking_ancestor(p: Path) -> Path | None:
    for a in p.parents:
        if a.exists():
            return None if a.is_dir() else a
    return None


def output_folder(value: str, option: str = "--out") -> Path:
    """An output folder that can be created: refuse a file in its place (or in its path)."""
    p = Path(value)
    if p.exists() and not p.is_dir():
        raise InvalidInputError(
            f"{option} {p}: is a file; give a folder (it is created when absent)"
        )
    block = _blocking_ancestor(p)
    if block is not None:
        raise InvalidInputError(f"{option} {p}: {block} is a file, not a folder")
    return p


def output_file(value: str, option: str = "--out", example: str = "model.json") -> Path:
    """An output file that can be written: refuse a folder in its place or a file in its path
    (missing folders are created when writing)."""
    p = Path(value)
    if p.is_dir():
        raise InvalidInputError(f"{option} {p}: is a folder; give a file name, e.g. {p / example}")
    block = _blocking_ancestor(p)
    if block is not None:
        raise InvalidInputError(f"{option} {p}: {block} is a file, not a folder")
    return p


def maneuver_ids(spec: str, option: str = "--held-out") -> list[str]:
    """Ids from ``a,b,c`` or ``@FILE`` (one per line, ``#`` comments); an empty ``spec`` is no
    selection (``[]``), a spec naming no id is refused."""
    if not spec:
        return []
    if spec.startswith("@"):
        path = Path(spec[1:])
        if path.is_dir():
            raise InvalidInputError(f"{option} @{path}: is a folder; give a file of ids")
        if not path.is_file():
            raise InvalidInputError(f"{option} @{path}: file not found")
        try:
            lines = path.read_text(encoding="utf-8").splitlines()
        except UnicodeDecodeError as e:
            raise InvalidInputError(f"{option} @{path}: not a UTF-8 text file") from e
        ids = [x.split("#")[0].strip() for x in lines if x.split("#")[0].strip()]
    else:
        ids = [x.strip() for x in spec.split(",") if x.strip()]
    if not ids:
        raise InvalidInputError(
            f"{option} {spec}: names no maneuver; give ids as a,b,c or @FILE (one per line)"
        )
    return ids


@contextmanager
def created(folder: Path) -> Iterator[Path]:
    """Create ``folder`` (and missing parents) for a command's outputs; if the command fails
    before it returns, the folders created here are removed with what was written into them,
    so a refused or interrupted command leaves nothing half-written. Existing folders (and
    what they held) are kept."""
    top = None
    for p in (folder, *folder.parents):
        if p.exists():
            break
        top = p
    folder.mkdir(parents=True, exist_ok=True)
    try:
        yield folder
    except BaseException:
        if top is not None:
            shutil.rmtree(top, ignore_errors=True)
        raise


def check_outputs(
    src: DataSource | None,
    option: str,
    *,
    folder: Path | None = None,
    files: Sequence[Path] = (),
    inputs: Sequence[Path | None] = (),
) -> None:
    """Refuse outputs that would overwrite an input file, or land where the campaign's records
    are read from (``DATA`` and ``DATA/records``: a CSV or Parquet output there would be read
    as a flight record the next time).

    Raises
    ------
    InvalidInputError
        Naming the option and the file.
    """
    from aerodelta.readers import RECORD_SUFFIXES  # noqa: PLC0415

    given = [p for p in inputs if p is not None]
    if src is not None:
        given += [p for p in (src.aircraft, src.channel_map, src.manifest) if p is not None]
        given.append(src.parquet if src.kind == "ingested" else src.path)
    taken = {p.resolve(): p for p in given if p.exists()}
    for f in files:
        if f.resolve() in taken:
            raise InvalidInputError(
                f"{option} {f}: would overwrite the input {taken[f.resolve()]}; write the "
                "output elsewhere"
            )
    if src is None or src.kind != "campaign":
        return
    reads = {src.path.resolve(), (src.path / "records").resolve()}
    if folder is not None and folder.resolve() in reads:
        raise InvalidInputError(
            f"{option} {folder}: is where the campaign's records are read from; its outputs "
            "would be read as flight records the next time: write them into a folder of their own"
        )
    for f in files:
        if f.parent.resolve() in reads and f.suffix.lower() in RECORD_SUFFIXES:
            raise InvalidInputError(
                f"{option} {f}: writes {f.name} where the campaign's records are read from (it "
                "would be read as a flight record the next time); write it elsewhere"
            )
