"""Readers for flight test records (CSV, Parquet, MATLAB ``.mat``), manifests and campaign
folders, with lazy polars scanning so that only what is needed is read.

A record holds one maneuver, or several with a ``maneuver_id`` column. A manifest (CSV or
Parquet) has ``maneuver_id, flap_deg, kind, pusher`` plus free metadata and optionally
``file`` (record path relative to the manifest's folder).
"""

from __future__ import annotations

import os
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from aerodelta.exceptions import DataError

#: Maneuver kinds of thesis Section 3.2.1 (plus ``other``).
KINDS = ("straight", "turning", "accelerated", "asymmetric_thrust", "other")
RECORD_SUFFIXES = (".parquet", ".csv", ".mat")


def scan_record(path: str | Path) -> pl.LazyFrame:
    """Lazily scan one record file (``.csv``, ``.parquet``; ``.mat`` is read eagerly with scipy).

    ``.mat`` files hold one numeric vector per channel (top-level variables, or the fields of
    a single top-level struct); needs the ``mat`` extra (scipy).

    Raises
    ------
    DataError
        Unknown suffix, unreadable file, or a ``.mat`` without equal-length vectors.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        raise DataError(f"{path}: is a folder, not a record file")
    if not path.is_file():
        raise DataError(f"{path}: record file not found")
    if suffix not in RECORD_SUFFIXES:
        raise DataError(
            f"{path}: unsupported record format '{suffix}' (use .csv, .parquet or .mat)"
        )
    if path.stat().st_size == 0:
        raise DataError(f"{path}: cannot read the record: the file is empty (0 bytes)")
    if suffix == ".parquet":
        return pl.scan_parquet(path)
    if suffix == ".csv":
        _check_csv_header(path)
        return pl.scan_csv(path, infer_schema_length=10000)
    return _read_mat(path).lazy()


def _check_csv_header(path: Path) -> None:
    """Refuse a CSV header that names a column twice (polars would rename the second copy and
    read the first as the channel, silently)."""
    with path.open("rb") as f:
        head = f.readline(1 << 20)
    names = [
        n.strip().strip('"').strip()
        for n in head.decode("utf-8", errors="replace").lstrip("\ufeff").rstrip("\r\n").split(",")
    ]
    twice = sorted(n for n, k in Counter(names).items() if k > 1)
    if twice:
        raise DataError(
            f"{path}: the header names column(s) {', '.join(repr(n) for n in twice)} more than "
            "once; keep one column per name"
        )


def _read_mat(path: Path) -> pl.DataFrame:
    try:
        from scipy.io import loadmat  # noqa: PLC0415  (optional dependency, imported lazily)
    except ImportError as e:  # pragma: no cover
        raise DataError(f"{path}: reading .mat needs scipy: pip install 'aerodelta[mat]'") from e
    try:
        raw = loadmat(path, squeeze_me=True, struct_as_record=False)
    except Exception as e:
        raise DataError(f"{path}: cannot read MATLAB file: {_first_line(e)}") from e
    vars_ = {k: v for k, v in raw.items() if not k.startswith("__")}
    if len(vars_) == 1:
        (only,) = vars_.values()
        if hasattr(only, "_fieldnames"):
            vars_ = {f: getattr(only, f) for f in only._fieldnames}
    cols: dict[str, np.ndarray] = {}
    for k, v in vars_.items():
        arr = np.asarray(v)
        if arr.ndim == 1 and arr.dtype.kind in "fiub":
            cols[k] = arr.astype(np.float64)
        elif arr.ndim == 1 and arr.dtype.kind in "US":
            cols[k] = arr.astype(str)
    lengths = {len(v) for v in cols.values()}
    if not cols or len(lengths) != 1:
        raise DataError(
            f"{path}: expected equal-length 1-D channel vectors, got "
            + ", ".join(f"{k}[{len(v)}]" for k, v in cols.items())
        )
    return pl.DataFrame(cols)


def read_manifest(path: str | Path) -> pl.DataFrame:
    """Read and validate a manifest (CSV or Parquet).

    Returns
    -------
    polars.DataFrame
        ``maneuver_id`` (str), ``flap_deg`` (f64), ``kind`` (str), ``pusher`` (bool), then the
        other columns as read.

    Raises
    ------
    DataError
        Missing columns, duplicate ids, unknown kinds or non-boolean pusher values, naming rows.
    """
    path = Path(path)
    if path.is_dir():
        raise DataError(f"{path}: is a folder; give the manifest file (CSV or Parquet)")
    if not path.is_file():
        raise DataError(f"{path}: manifest not found")
    text_cols = ("maneuver_id", "kind", "pusher", "file", "flap_deg")
    try:
        if path.suffix.lower() == ".parquet":
            df = pl.read_parquet(path)
        else:
            header = pl.scan_csv(path, infer_schema_length=0).collect_schema().names()
            df = pl.read_csv(path, schema_overrides={c: pl.Utf8 for c in text_cols if c in header})
    except (pl.exceptions.PolarsError, OSError, ValueError) as e:
        raise DataError(f"{path}: cannot read the manifest: {_first_line(e)}") from e
    missing = [c for c in ("maneuver_id", "flap_deg", "kind", "pusher") if c not in df.columns]
    if missing:
        raise DataError(
            f"{path}: manifest lacks column(s) {', '.join(missing)} (it needs maneuver_id, "
            "flap_deg, kind, pusher; docs/data.md)"
        )
    if df.height == 0:
        raise DataError(f"{path}: the manifest lists no maneuver (no rows below the header)")
    ids = df["maneuver_id"].cast(pl.Utf8).str.strip_chars()
    empty = np.flatnonzero((ids.is_null() | (ids == "")).to_numpy())
    if empty.size:
        raise DataError(f"{path}: column 'maneuver_id', rows {_rows(empty)}: empty")
    flap = numeric_column(
        df, "flap_deg", str(path), "a flap angle in deg; give a number in every row"
    )
    df = df.with_columns(
        ids.alias("maneuver_id"), flap.alias("flap_deg"), pl.col("kind").cast(pl.Utf8)
    )
    dup = df.filter(pl.col("maneuver_id").is_duplicated())
    if dup.height:
        raise DataError(
            f"{path}: duplicated maneuver_id {sorted(set(dup['maneuver_id']))} "
            f"(rows {_rows(np.flatnonzero(df['maneuver_id'].is_duplicated().to_numpy()))})"
        )
    bad_kind = np.flatnonzero(~df["kind"].is_in(KINDS).fill_null(False).to_numpy())
    if bad_kind.size:
        raise DataError(
            f"{path}: column 'kind', rows {_rows(bad_kind)}: unknown kind(s) "
            f"{sorted({str(k) for k in df['kind'].gather(bad_kind)})}; allowed: {', '.join(KINDS)}"
        )
    pusher = df["pusher"]
    if pusher.dtype != pl.Boolean or pusher.null_count():
        s = pusher.cast(pl.Utf8).str.strip_chars().str.to_lowercase()
        truthy = s.is_in(["true", "1", "yes"]).fill_null(False)
        falsy = s.is_in(["false", "0", "no"]).fill_null(False)
        bad = np.flatnonzero(~(truthy | falsy).to_numpy())
        if bad.size:
            raise DataError(
                f"{path}: column 'pusher', rows {_rows(bad)}: not true/false (also 1/0, yes/no)"
            )
        df = df.with_columns(truthy.alias("pusher"))
    if "file" in df.columns:
        f = df["file"].cast(pl.Utf8).str.strip_chars()
        empty = np.flatnonzero((f.is_null() | (f == "")).to_numpy())
        if empty.size:
            raise DataError(
                f"{path}: column 'file', rows {_rows(empty)}: empty; give each maneuver's record "
                "file (relative to the campaign folder), or drop the column"
            )
        df = df.with_columns(f.alias("file"))
    return df


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def numeric_column(df: pl.DataFrame, column: str, source: str, what: str) -> pl.Series:
    """A manifest column as finite floats (text trimmed, then parsed).

    Raises
    ------
    DataError
        ``"{source}: column '{column}', rows ...: X is not {what}"`` for empty cells, text that
        is not a number, NaN and infinities.
    """
    text = df[column].cast(pl.Utf8).str.strip_chars()
    val = text.cast(pl.Float64, strict=False)
    bad = np.flatnonzero((val.is_null() | val.is_nan() | val.is_infinite()).to_numpy())
    if bad.size:
        shown = sorted({str(v) for v in text.gather(bad).to_list()})[:5]
        raise DataError(
            f"{source}: column '{column}', rows {_rows(bad)}: {', '.join(shown)} is not {what}"
        )
    return val


def _rows(idx: np.ndarray | list[int]) -> str:
    """Compact row list, e.g. ``3-7, 12``."""
    idx = sorted(int(i) for i in idx)
    if not idx:
        return ""
    parts = []
    start = prev = idx[0]
    for i in idx[1:]:
        if i == prev + 1:
            prev = i
            continue
        parts.append(f"{start}-{prev}" if prev > start else f"{start}")
        start = prev = i
    parts.append(f"{start}-{prev}" if prev > start else f"{start}")
    if len(parts) > 8:
        parts = [*parts[:8], f"... ({len(idx)} rows)"]
    return ", ".join(parts)


@dataclass(frozen=True)
class RecordSource:
    """One maneuver to read: its id, the file, and whether the file holds several maneuvers."""

    maneuver_id: str
    path: Path
    multi: bool = False


def find_records(
    data: str | Path | list[str | Path],
    manifest: pl.DataFrame | None = None,
    manifest_name: str = "manifest",
) -> list[RecordSource]:
    """List the maneuvers in a campaign folder, a file, or a list of files.

    A folder with a manifest that has a ``file`` column uses it (paths relative to the folder,
    never outside it); otherwise every record file in the folder and its ``records/`` subfolder
    is one maneuver named by its stem, or several when it has a ``maneuver_id`` column.

    Raises
    ------
    DataError
        A manifest path that is absolute or leaves the folder, or names no record file
        (``manifest_name`` and the row named); a record whose columns cannot be read.
    """
    if isinstance(data, (list, tuple)):
        files = [Path(p) for p in data]
        base = None
    else:
        d = Path(data)
        if d.is_file():
            files, base = [d], None
        elif d.is_dir():
            base = d
            if manifest is not None and "file" in manifest.columns:
                return [
                    RecordSource(str(mid), _manifest_file(d, str(f), i, manifest_name))
                    for i, (mid, f) in enumerate(
                        zip(manifest["maneuver_id"], manifest["file"], strict=True)
                    )
                ]
            files = sorted(
                p
                for folder in (d, d / "records")
                if folder.is_dir()
                for p in folder.iterdir()
                if p.suffix.lower() in RECORD_SUFFIXES and p.stem != "manifest"
            )
        else:
            raise DataError(f"{d}: no such file or folder")
    if not files:
        raise DataError(f"{base}: no record files (.parquet, .csv, .mat) found")
    out: list[RecordSource] = []
    for f in files:
        lf = scan_record(f)
        try:
            names = lf.collect_schema().names()
            if "maneuver_id" in names:
                ids = lf.select(pl.col("maneuver_id").cast(pl.Utf8).unique(maintain_order=True))
                mids = ids.collect()["maneuver_id"].to_list()
        except pl.exceptions.PolarsError as e:
            raise DataError(f"{f}: cannot read the record: {_first_line(e)}") from e
        if "maneuver_id" in names:
            out.extend(RecordSource(str(mid), f, multi=True) for mid in mids)
        else:
            out.append(RecordSource(f.stem, f))
    return out


_PARENT = re.compile(r"(^|[\\/])\.\.([\\/]|$)")


def _manifest_file(folder: Path, rel: str, row: int, manifest_name: str) -> Path:
    """The record file a manifest row names, confined to the campaign folder."""
    where = f"{manifest_name}: column 'file', row {row}"
    if os.path.isabs(rel) or rel.startswith(("/", "\\")) or _PARENT.search(rel):
        raise DataError(
            f"{where}: '{rel}' is outside the campaign folder {folder}; give the record's path "
            "relative to that folder, without '..' (copy or link the record into it)"
        )
    p = folder / rel
    if p.is_dir():
        raise DataError(f"{where}: '{rel}' is a folder in {folder}, not a record file")
    if not p.is_file():
        raise DataError(f"{where}: '{rel}' not found in the campaign folder {folder}")
    return p
