"""Readers for flight test records (CSV, Parquet, MATLAB ``.mat``), manifests and campaign
folders, with lazy polars scanning so that only what is needed is read.

A record holds one maneuver, or several with a ``maneuver_id`` column. A manifest (CSV or
Parquet) has ``maneuver_id, flap_deg, kind, pusher`` plus free metadata and optionally
``file`` (record path relative to the manifest's folder).
"""

from __future__ import annotations

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
    if not path.is_file():
        raise DataError(f"{path}: record file not found")
    if suffix == ".parquet":
        return pl.scan_parquet(path)
    if suffix == ".csv":
        return pl.scan_csv(path, infer_schema_length=10000)
    if suffix == ".mat":
        return _read_mat(path).lazy()
    raise DataError(f"{path}: unsupported record format '{suffix}' (use .csv, .parquet or .mat)")


def _read_mat(path: Path) -> pl.DataFrame:
    try:
        from scipy.io import loadmat  # noqa: PLC0415  (optional dependency, imported lazily)
    except ImportError as e:  # pragma: no cover
        raise DataError(f"{path}: reading .mat needs scipy: pip install 'aerodelta[mat]'") from e
    try:
        raw = loadmat(path, squeeze_me=True, struct_as_record=False)
    except Exception as e:
        raise DataError(f"{path}: cannot read MATLAB file: {e}") from e
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
    if not path.is_file():
        raise DataError(f"{path}: manifest not found")
    df = pl.read_parquet(path) if path.suffix.lower() == ".parquet" else pl.read_csv(path)
    missing = [c for c in ("maneuver_id", "flap_deg", "kind", "pusher") if c not in df.columns]
    if missing:
        raise DataError(f"{path}: manifest lacks column(s) {', '.join(missing)}")
    df = df.with_columns(
        pl.col("maneuver_id").cast(pl.Utf8),
        pl.col("flap_deg").cast(pl.Float64),
        pl.col("kind").cast(pl.Utf8),
    )
    dup = df.filter(pl.col("maneuver_id").is_duplicated())
    if dup.height:
        raise DataError(
            f"{path}: duplicated maneuver_id {sorted(set(dup['maneuver_id']))} "
            f"(rows {_rows(np.flatnonzero(df['maneuver_id'].is_duplicated().to_numpy()))})"
        )
    bad_kind = np.flatnonzero(~df["kind"].is_in(KINDS).to_numpy())
    if bad_kind.size:
        raise DataError(
            f"{path}: column 'kind', rows {_rows(bad_kind)}: unknown kind(s) "
            f"{sorted(set(df['kind'].gather(bad_kind)))}; allowed: {', '.join(KINDS)}"
        )
    pusher = df["pusher"]
    if pusher.dtype != pl.Boolean:
        s = pusher.cast(pl.Utf8).str.to_lowercase()
        truthy = s.is_in(["true", "1", "yes"])
        falsy = s.is_in(["false", "0", "no"])
        bad = np.flatnonzero(~(truthy | falsy).to_numpy())
        if bad.size:
            raise DataError(f"{path}: column 'pusher', rows {_rows(bad)}: not true/false")
        df = df.with_columns(truthy.alias("pusher"))
    return df


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
    data: str | Path | list[str | Path], manifest: pl.DataFrame | None = None
) -> list[RecordSource]:
    """List the maneuvers in a campaign folder, a file, or a list of files.

    A folder with a manifest that has a ``file`` column uses it; otherwise every record file
    in the folder and its ``records/`` subfolder is one maneuver named by its stem, or several
    when it has a ``maneuver_id`` column.
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
                    RecordSource(str(mid), d / str(f))
                    for mid, f in zip(manifest["maneuver_id"], manifest["file"], strict=False)
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
        if "maneuver_id" in lf.collect_schema().names():
            ids = lf.select(pl.col("maneuver_id").cast(pl.Utf8).unique(maintain_order=True))
            for mid in ids.collect()["maneuver_id"]:
                out.append(RecordSource(str(mid), f, multi=True))
        else:
            out.append(RecordSource(f.stem, f))
    return out
