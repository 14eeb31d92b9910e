"""Inputs of the diagnosis: the records (never the truth) and the aircraft reference."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta.aircraft import Aircraft
from aerodelta.campaign import aircraft_toml
from aerodelta.exceptions import DataError
from aerodelta.fit import model_frame
from aerodelta.ingest import ingest
from aerodelta.qualified import flown_on_builtin

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

IntArray = npt.NDArray[np.int64]

#: Columns the diagnosis needs in every row.
REQUIRED = (
    "maneuver_id", "t", "flap_deg", "alpha_deg", "beta_deg", "phat", "rhat", "tas_mps",
    "Cl_meas", "Cn_meas", "CY_meas",
)  # fmt: skip


def _guard(path: Path) -> Path:
    """Refuse any path inside a campaign's ``truth/`` folder: the diagnosis must never see
    the answer it is tested against."""
    if "truth" in Path(path).resolve().parts:
        raise DataError(
            f"{path}: the diagnosis never reads a campaign's truth files; point it at the "
            "records (the campaign folder or the ingest output)"
        )
    return path


def read_parquet_guarded(path: Path) -> pl.DataFrame:
    """``pl.read_parquet`` that refuses the truth folder."""
    return pl.read_parquet(_guard(path))


def _aircraft(
    aircraft: str | Path | None, folder: Path | None, builtin: bool = True
) -> tuple[Aircraft, str]:
    if aircraft is not None:
        return Aircraft.from_toml(_guard(Path(aircraft))), f"aircraft from {aircraft}"
    if folder is not None and (folder / "aircraft.toml").is_file():
        return Aircraft.from_toml(folder / "aircraft.toml"), f"aircraft from {folder}/aircraft.toml"
    if not builtin:
        raise DataError(
            "no aircraft reference for these records: give it (CLI --aircraft FILE, "
            "aircraft=...); the diagnosis needs the mass, wing area and chord of the aircraft "
            "that flew them, and the built-in ADX-37's belong to another aircraft"
        )
    doc = tomllib.loads(aircraft_toml())
    return Aircraft.from_dict(doc, "built-in ADX-37"), "aircraft: built-in ADX-37 reference"


def load_inputs(
    data: pl.DataFrame | str | Path, aircraft: str | Path | None, *, progress: bool = False
) -> tuple[pl.DataFrame, Aircraft, list[str]]:
    """The model frame (CG angles as ``alpha_deg``/``beta_deg``) in ``(maneuver_id, t)``
    order, the aircraft, and notes.

    ``data`` is an ingested DataFrame, an ingest output folder (``data.parquet``) or a campaign
    folder (``manifest.csv``, ingested here without the compatibility check).
    """
    frame, order, ac, notes = load_records(data, aircraft, progress=progress)
    if order is not None:
        frame = frame.sort(["maneuver_id", "t"])
    return frame, ac, notes


def load_records(
    data: pl.DataFrame | str | Path, aircraft: str | Path | None, *, progress: bool = False
) -> tuple[pl.DataFrame, IntArray | None, Aircraft, list[str]]:
    """:func:`load_inputs` without the copy of the records a sort makes where it can.

    Returns the model frame, ``order``, the aircraft and notes. When each maneuver's rows are
    contiguous and in time order but the maneuvers are not in ``maneuver_id`` order (the
    ingest writes them in flight order: ``m1000_...`` after ``m999_...``, though it sorts
    before), the frame keeps the records' row order (it shares their memory) and ``order`` is
    the permutation of its rows into ``(maneuver_id, t)`` order (:func:`sorted_columns`);
    otherwise ``order`` is ``None`` and the frame is in that order (sorted here if needed,
    a copy of every column).
    """
    notes: list[str] = []
    folder: Path | None = None
    if isinstance(data, pl.DataFrame):
        df = data
    else:
        folder = _guard(Path(data))
        if (folder / "data.parquet").is_file():
            df = read_parquet_guarded(folder / "data.parquet")
            notes.append(f"records from {folder / 'data.parquet'}")
        elif (folder / "manifest.csv").is_file():
            df = ingest(folder, compat=False, progress=progress).data
            notes.append(f"records ingested from the campaign {folder}")
        elif folder.is_file() and folder.suffix == ".parquet":
            df = read_parquet_guarded(folder)
            folder = folder.parent
        else:
            raise DataError(
                f"{folder}: neither an ingest output (data.parquet) nor a campaign "
                "(manifest.csv); run `aerodelta ingest` first or point at the campaign"
            )
    ac, note = _aircraft(aircraft, folder, flown_on_builtin(df))
    notes.append(note)
    frame = model_frame(df)
    if "kind" not in frame.columns:
        frame = frame.with_columns(pl.lit("other").alias("kind"))
    missing = [c for c in REQUIRED if c not in frame.columns]
    if missing:
        raise DataError(
            f"the records lack {missing}; the diagnosis needs ingested data "
            "(`aerodelta ingest` adds the measured coefficients and rates)"
        )
    for c in ("da_deg", "dr_deg", "ds_deg", "ct_left", "ct_right", "alphadot_dps", "betadot_dps",
              "pdot_dps2", "rdot_dps2", "qbar_pa"):  # fmt: skip
        if c not in frame.columns:
            frame = frame.with_columns(pl.lit(0.0).alias(c))
            notes.append(f"channel {c} absent: taken as 0")
    if "ct_diff" not in frame.columns:
        frame = frame.with_columns((pl.col("ct_left") - pl.col("ct_right")).alias("ct_diff"))
    num = [c for c in frame.columns if frame[c].dtype.is_float()]
    before = frame.height
    finite = pl.all_horizontal([pl.col(c).is_finite() for c in REQUIRED if c in num])
    # filter and sort only when they change something: each copies every column of the records
    if int(frame.select(finite.not_().sum()).item()) > 0:
        frame = frame.filter(finite)
        notes.append(f"{before - frame.height} rows with non-finite values dropped")
    if frame.height == 0:
        raise DataError("no usable rows: every row has a missing required channel")
    if _sorted_by_maneuver_and_time(frame):
        # what the sort would have flagged (polars takes faster paths, summing in another
        # order, on a column it knows sorted)
        return frame.with_columns(pl.col("maneuver_id").set_sorted()), None, ac, notes
    if _grouped_by_maneuver_in_time(frame):
        # a sort would copy every column (1.8 GB at 2,000 maneuvers): only the row order
        order = (
            frame.select("maneuver_id", "t")
            .with_row_index("__row")
            .sort(["maneuver_id", "t"])["__row"]
            .cast(pl.Int64)
            .to_numpy()
        )
        return frame, order, ac, notes
    return frame.sort(["maneuver_id", "t"]), None, ac, notes


def _sorted_by_maneuver_and_time(frame: pl.DataFrame) -> bool:
    """True when the rows are in ``(maneuver_id, t)`` order with no repeated pair (then
    sorting them would return them unchanged)."""
    m, t = pl.col("maneuver_id"), pl.col("t")
    step = ((m > m.shift(1)) | ((m == m.shift(1)) & (t > t.shift(1)))).fill_null(False)
    return bool(frame.select(step.slice(1).all()).item()) if frame.height > 1 else True


def _grouped_by_maneuver_in_time(frame: pl.DataFrame) -> bool:
    """True when each maneuver's rows are contiguous and strictly increasing in ``t`` (the
    maneuvers in any order): then the ``(maneuver_id, t)`` order is a permutation of whole
    maneuvers, each kept as it is."""
    m, t = pl.col("maneuver_id"), pl.col("t")
    new = (m != m.shift(1)).fill_null(True)
    runs, distinct, late = frame.select(
        new.sum().alias("runs"),
        m.n_unique().alias("distinct"),
        (new.not_() & (t <= t.shift(1))).fill_null(False).any().alias("late"),
    ).row(0)
    return int(runs) == int(distinct) and not bool(late)


def sorted_columns(
    frame: pl.DataFrame, order: IntArray | None, columns: Sequence[str]
) -> pl.DataFrame:
    """``columns`` of ``frame`` (those it has) in ``(maneuver_id, t)`` order, as the sort of
    :func:`load_inputs` gives them (``frame`` itself when ``order`` is ``None``: it is in that
    order already). ``maneuver_id`` and ``t`` are always included."""
    if order is None:
        return frame
    keep = [c for c in dict.fromkeys(["maneuver_id", "t", *columns]) if c in frame.columns]
    return frame.select(keep).sort(["maneuver_id", "t"])


def in_order(x: npt.NDArray[Any], order: IntArray | None) -> npt.NDArray[Any]:
    """The rows of ``x`` (aligned with the records' frame) in ``(maneuver_id, t)`` order."""
    return x if order is None else x[order]


def maneuver_codes(frame: pl.DataFrame) -> tuple[list[str], np.ndarray]:
    """The sorted distinct ``maneuver_id`` values and each row's index among them (what
    ``np.unique(ids, return_inverse=True)`` gives, without an object array of the ids)."""
    ids = frame["maneuver_id"]
    names = [str(m) for m in ids.unique().sort().to_list()]
    code = (ids.rank("dense") - 1).cast(pl.Int64).to_numpy()
    return names, code
