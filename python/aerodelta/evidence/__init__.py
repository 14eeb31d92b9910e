"""The Part 60 stall-model evidence pack (``aerodelta evidence``, ``docs/evidence.md``).

:func:`write_evidence` reads flight records (and optionally the fitted Δ model), assesses each
stall characteristic of 14 CFR Part 60 Appendix A (Attachment 7, Table A1A) as
``docs/stall.md`` reads it (:mod:`aerodelta.evidence.matrix`), and writes one HTML page
(``OUT/evidence.html``, print-ready) with its figures as PNG files (``OUT/figures/``): the
characteristic-by-characteristic matrix, the α/β envelope plots, a draft Statement of
Compliance and the provenance. The folder is built beside ``OUT`` and renamed into place: a
failure never leaves a partial pack.
"""

from __future__ import annotations

import hashlib
import math
import os
import platform
import shutil
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from aerodelta._fingerprint import data_sha256
from aerodelta._fsutil import replace_dir
from aerodelta.evidence.matrix import (
    FAIL,
    NOT_ASSESSED,
    PASS,
    POWER_ON_CT,
    SHOWN,
    MatrixRow,
    assess,
    stall_form_of,
)
from aerodelta.exceptions import DataError, InvalidInputError
from aerodelta.model import DeltaModel

__all__ = [
    "FAIL",
    "NOT_ASSESSED",
    "PASS",
    "POWER_ON_CT",
    "SHOWN",
    "EvidenceResult",
    "MatrixRow",
    "check_output_folder",
    "frame_sha256",
    "read_sim_buffet",
    "write_evidence",
]

#: The page's file name inside the output folder.
PAGE = "evidence.html"
#: Resolution of the PNG figures, dpi.
DPI = 110


@dataclass
class EvidenceResult:
    """What :func:`write_evidence` wrote.

    Attributes
    ----------
    html
        The page (``OUT/evidence.html``).
    figures
        The PNG files, in figure order (``OUT/figures/NN_<name>.png``).
    rows
        The matrix rows.
    tables
        The tables behind the rows (stall identification, validity, buffet, ...).
    """

    html: Path
    figures: list[Path]
    rows: list[MatrixRow]
    tables: dict[str, pl.DataFrame] = field(default_factory=dict)

    @property
    def matrix(self) -> pl.DataFrame:
        """The matrix as a frame: ``key, item, rule, data, figure, tolerance, status,
        detail``."""
        return pl.DataFrame(
            [r.__dict__ for r in self.rows],
            schema={k: pl.Utf8 for k in MatrixRow.__dataclass_fields__},
        )


def frame_sha256(df: pl.DataFrame) -> str:
    """The data's fingerprint when no files were read: :func:`aerodelta._fingerprint.
    data_sha256`, the hash a model fitted on the same frame records as ``data_sha256``."""
    return data_sha256(df)


def file_table(paths: Sequence[Path], root: Path | None = None) -> tuple[pl.DataFrame, str]:
    """Per file (sorted by path): ``path`` (relative to ``root`` when inside it), ``bytes``,
    ``sha256``; and the SHA-256 of the ``"sha256  path"`` lines, one per file."""
    rows = []
    for p in sorted({Path(x) for x in paths}):
        data = p.read_bytes()
        name = str(p)
        if root is not None:
            try:
                name = str(p.resolve().relative_to(root.resolve()))
            except ValueError:
                name = str(p)
        rows.append({"path": name, "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()})
    frame = pl.DataFrame(rows, schema={"path": pl.Utf8, "bytes": pl.Int64, "sha256": pl.Utf8})
    frame = frame.sort("path")
    digest = hashlib.sha256(
        "".join(f"{s}  {p}\n" for p, s in zip(frame["path"], frame["sha256"], strict=True)).encode()
    ).hexdigest()
    return frame, digest


def read_sim_buffet(value: str | Path | Sequence[float] | pl.DataFrame) -> pl.DataFrame:
    """The simulator's buffet frequencies: a CSV or Parquet file (``flap_deg``, ``freq_hz``,
    optional ``axis`` ``nz``/``ny``; Hz), a frame with those columns, or plain frequencies
    (Hz) that apply to every flap (``flap_deg`` null, expanded by the caller).

    Raises
    ------
    InvalidInputError
        A file that does not exist or cannot be read, a missing column or a frequency that is
        not a positive number: one line naming the file, the column and the row.
    """
    if isinstance(value, pl.DataFrame):
        frame, where = value, "sim_buffet"
    elif isinstance(value, (str, Path)):
        p = Path(value)
        where = str(p)
        if not p.is_file():
            raise InvalidInputError(
                f"{p}: simulator buffet file not found; give a CSV with columns flap_deg, freq_hz"
            )
        try:
            frame = pl.read_parquet(p) if p.suffix.lower() == ".parquet" else pl.read_csv(p)
        except Exception as e:  # polars raises several kinds for a malformed file
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise InvalidInputError(
                f"{p}: cannot read the simulator buffet frequencies ({first}); give a CSV with "
                "columns flap_deg, freq_hz"
            ) from e
    else:
        v = np.asarray(list(value), dtype=np.float64)
        frame, where = pl.DataFrame({"flap_deg": [None] * v.size, "freq_hz": v}), "sim_buffet"
        frame = frame.with_columns(pl.col("flap_deg").cast(pl.Float64))
    missing = [c for c in ("flap_deg", "freq_hz") if c not in frame.columns]
    if missing:
        raise InvalidInputError(
            f"{where}: no column {', '.join(missing)}; the simulator buffet frequencies need "
            "flap_deg (deg) and freq_hz (Hz) columns"
        )
    try:
        f = frame["freq_hz"].cast(pl.Float64, strict=True).to_numpy()
        flap = frame["flap_deg"].cast(pl.Float64, strict=True)
    except Exception:
        raise InvalidInputError(
            f"{where}: flap_deg and freq_hz must be numbers (deg, Hz)"
        ) from None
    bad = np.flatnonzero(~(np.isfinite(f) & (f > 0)))
    if bad.size:
        raise InvalidInputError(
            f"{where}: freq_hz row {int(bad[0]) + 1} is {float(f[bad[0]]):g}; give a positive "
            "frequency in Hz"
        )
    cols = [flap.alias("flap_deg"), pl.Series("freq_hz", f)]
    if "axis" in frame.columns:
        ax = frame["axis"].cast(pl.Utf8)
        wrong = [i for i, a in enumerate(ax.to_list()) if a not in ("nz", "ny")]
        if wrong:
            raise InvalidInputError(
                f"{where}: axis row {wrong[0] + 1} is {ax[wrong[0]]!r}; use nz (normal) or ny "
                "(lateral)"
            )
        cols.append(ax.alias("axis"))
    return pl.DataFrame(cols)


def _virtual_sim_buffet(campaign: Path) -> tuple[pl.DataFrame, str] | None:
    """The virtual ADX-37's runtime buffet model of a campaign flown with buffet (its modes,
    every flap), or None."""
    from aerodelta.buffet import virtual_buffet_truth  # noqa: PLC0415

    if not (campaign / "truth" / "campaign.json").is_file():
        return None
    try:
        truth = virtual_buffet_truth(campaign)
    except DataError:
        return None
    frame = truth.select("flap_deg", pl.col("modes_hz").alias("freq_hz")).explode("freq_hz")
    modes = ", ".join(f"{f:g}" for f in truth["modes_hz"][0])
    return frame, (
        f"the virtual ADX-37 simulator's buffet model (aero_core::buffet with the campaign's "
        f"BuffetSpec, truth/campaign.json): {modes} Hz"
    )


def _virtual_buffet_model(campaign: Path | None) -> dict[str, Any] | None:
    """The BuffetSpec a virtual campaign was flown with (``truth/campaign.json``), or None."""
    import json  # noqa: PLC0415

    if campaign is None:
        return None
    path = campaign / "truth" / "campaign.json"
    try:
        spec = json.loads(path.read_text())["spec"]
    except (OSError, ValueError, KeyError):
        return None
    b = spec.get("buffet") if isinstance(spec, dict) else None
    return dict(b) if isinstance(b, dict) else None


def _png_size(png: bytes) -> tuple[int, int]:
    w, h = struct.unpack(">II", png[16:24])
    return int(w), int(h)


def check_output_folder(out: Path, overwrite: bool) -> None:
    """Refuse a file at ``out``, an existing pack without ``overwrite``, and a non-empty folder
    that is not an evidence pack (it would be replaced whole)."""
    if out.exists() and not out.is_dir():
        raise InvalidInputError(f"{out}: is a file; give a folder for the evidence pack")
    if out.exists() and any(out.iterdir()):
        if not overwrite:
            raise InvalidInputError(
                f"{out}: exists; pass overwrite=True to replace an earlier evidence pack, or give "
                "a new folder"
            )
        if not (out / PAGE).is_file():
            raise InvalidInputError(
                f"{out}: holds other files, not an evidence pack ({PAGE} missing); give a new "
                "folder (it would be replaced whole)"
            )


def write_evidence(
    data: str | os.PathLike[str] | pl.DataFrame | Any,
    out: str | os.PathLike[str],
    *,
    model: str | os.PathLike[str] | DeltaModel | None = None,
    params: pl.DataFrame | None = None,
    sim_buffet: str | os.PathLike[str] | Sequence[float] | pl.DataFrame | None = "auto",
    campaign: str | os.PathLike[str] | None = None,
    sources: Sequence[str | os.PathLike[str]] = (),
    aft_stop_deg: float | None = None,
    power_on_ct: float = POWER_ON_CT,
    longitudinal: bool = True,
    replay: bool = True,
    overwrite: bool = False,
    command: str | None = None,
    data_label: str | None = None,
    stall_form: str = "auto",
) -> EvidenceResult:
    """Write the Part 60 stall-model evidence pack.

    Parameters
    ----------
    data
        The flight records: ingested (a frame, an :class:`aerodelta.IngestResult`, an
        ``aerodelta ingest`` output folder or its ``data.parquet``) or a campaign folder
        (ingested here, without the compatibility check).
    out
        Output folder: ``OUT/evidence.html`` and ``OUT/figures/*.png``.
    model
        The fitted Δ model (``aerodelta fit``; path or :class:`DeltaModel`): the degraded
        lateral-directional stability row and the validated envelope's outline. Its per-bin
        estimates are read from ``MODEL.params.parquet`` beside a model path when present.
    params
        The per-bin estimates when ``model`` is a :class:`DeltaModel`.
    sim_buffet
        The simulator's predominant buffet frequencies (Hz) for the ±2 Hz comparison: a CSV or
        Parquet file (``flap_deg``, ``freq_hz``, optional ``axis``), a frame, or frequencies
        that apply to every flap; ``"auto"``: the virtual ADX-37's buffet model when the data
        are a virtual campaign flown with buffet, else none; None: no comparison.
    campaign
        The campaign folder the records come from (for ``"auto"`` when ``data`` is a frame).
    sources
        Files the records were read from, hashed into the provenance (found automatically when
        ``data`` is a path).
    aft_stop_deg
        The elevator's aft stop, deg (negative, Etkin); None: the recorded extreme.
    power_on_ct
        Thrust coefficient, summed over the engines, from which a stall entry is power-on (-).
    longitudinal
        Fit the Kirchhoff stall by output error where it applies.
    stall_form
        Its separation curve: ``"kirchhoff"`` (the tanh), ``"goman-khrabrov"`` (the table,
        :func:`aerodelta.goman_khrabrov.fit_goman_khrabrov`) or ``"auto"`` (the form ``model``
        stores, else the tanh). The replays fly the fitted stall at the flaps the model stores
        none for.
    replay
        Fly the closed-loop replays of the stall maneuvers with the extended model (the fitted
        Δ model, the Kirchhoff stall fitted here; :func:`aerodelta.closed_loop_replay`) for the
        ±3 kt speed rows; needs ``model`` and records flown on the built-in ADX-37. With
        ``sim_buffet="auto"`` on a virtual campaign flown with buffet, the replayed simulator
        carries the campaign's buffet model (else none: the buffet-onset row is not assessed).
    overwrite
        Replace an existing evidence pack at ``out``.
    command
        The command line to record in the provenance (default: this call).
    data_label
        A few words naming the data on the page (default: from ``data``).

    Returns
    -------
    EvidenceResult

    Raises
    ------
    InvalidInputError, DataError
        Bad options or data, in one line naming the file, channel or row.

    Examples
    --------
    >>> # res = write_evidence("campaign/", "evidence/", model="model.json")
    >>> # res.matrix.select("item", "status")
    """
    from aerodelta import __version__  # noqa: PLC0415
    from aerodelta.plots import render, style  # noqa: PLC0415
    from aerodelta.report.html import generated_at  # noqa: PLC0415

    out = Path(out)
    check_output_folder(out, overwrite)
    if not (math.isfinite(power_on_ct) and power_on_ct > 0):
        raise InvalidInputError(
            f"power_on_ct {power_on_ct}: give a positive thrust coefficient, e.g. 0.03"
        )
    if aft_stop_deg is not None and not math.isfinite(aft_stop_deg):
        raise InvalidInputError(f"aft_stop_deg {aft_stop_deg}: give the stop in deg, e.g. -22")
    generated = generated_at()
    frame, source_text, files, root = _load(data)
    source_text = data_label or source_text
    files = [*files, *(Path(s) for s in sources)]
    camp = Path(campaign) if campaign is not None else root
    delta, model_path = _model(model)
    form = stall_form_of(stall_form, delta)  # refused here, before the records are assessed
    if model_path is not None and params is None:
        from aerodelta.report.context import load_params  # noqa: PLC0415

        params = load_params(model_path)
    sim, sim_source = None, ""
    buffet_model = None
    if isinstance(sim_buffet, str) and sim_buffet == "auto":
        got = _virtual_sim_buffet(camp) if camp is not None and camp.is_dir() else None
        if got is not None:
            sim, sim_source = got
            buffet_model = _virtual_buffet_model(camp)
    elif sim_buffet is not None:
        sim = read_sim_buffet(sim_buffet)  # type: ignore[arg-type]
        sim_source = (
            f"given ({sim_buffet})" if isinstance(sim_buffet, (str, os.PathLike)) else "given"
        )
    if sim is not None and sim["flap_deg"].null_count():
        flaps = sorted({float(f) for f in frame["flap_deg"].unique().drop_nulls()})
        common = sim.filter(pl.col("flap_deg").is_null()).drop("flap_deg")
        sim = pl.concat(
            [
                sim.filter(pl.col("flap_deg").is_not_null()),
                *(common.with_columns(pl.lit(f).alias("flap_deg")).select(sim.columns)
                  for f in flaps),
            ]
        )  # fmt: skip
    result = assess(
        frame,
        model=delta,
        params=params,
        sim_buffet=sim,
        sim_buffet_source=sim_source,
        aft_stop_deg=aft_stop_deg,
        power_on_ct=power_on_ct,
        longitudinal=longitudinal,
        buffet_model=buffet_model,
        replay=replay,
        stall_form=form,
    )
    if files:
        ftable, digest = file_table(files, camp)
    else:
        ftable, digest = None, frame_sha256(frame)
    info: dict[str, Any] = {
        "version": __version__,
        "runtime": f"{platform.python_version()} / {np.__version__} / {pl.__version__}",
        "command": command or _call_text(data, out, model, sim_buffet),
        "data": source_text,
        "data_sha256": digest,
        "files": ftable,
        "model": str(model_path) if model_path is not None else (
            "a DeltaModel object" if delta is not None else None),
        "model_sha256": hashlib.sha256(model_path.read_bytes()).hexdigest()
        if model_path is not None else None,
        "options": f"aft_stop_deg={aft_stop_deg}, power_on_ct={power_on_ct:g}, "
        f"longitudinal={longitudinal} ({form}), replay={replay}, simulator buffet: "
        f"{sim_source or 'none'}",
        "generated": generated.strftime("%Y-%m-%d %H:%M:%S UTC"),
    }  # fmt: skip
    from aerodelta.evidence.page import render_page  # noqa: PLC0415

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        (tmp / "figures").mkdir(parents=True)
        written: dict[str, tuple[str, tuple[int, int]]] = {}
        names: list[str] = []
        for i, spec in enumerate(result.figures, start=1):
            with style():
                fig = spec.draw(**spec.kwargs)
                png, _ = render(fig, dpi=DPI, svg=False)
            rel = f"figures/{i:02d}_{spec.name}.png"
            (tmp / rel).write_bytes(png)
            written[spec.anchor] = (rel, _png_size(png))
            names.append(rel)
        page = render_page(result, written, info, generated)
        (tmp / PAGE).write_text(page, encoding="utf-8")
        replace_dir(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return EvidenceResult(
        html=out / PAGE,
        figures=[out / n for n in names],
        rows=result.rows,
        tables=result.tables,
    )


def _call_text(data: object, out: Path, model: object, sim_buffet: object) -> str:
    d = f"<DataFrame {data.height} rows>" if isinstance(data, pl.DataFrame) else repr(str(data))
    m = "" if model is None else f", model={str(model)!r}"
    s = "" if isinstance(sim_buffet, str) and sim_buffet == "auto" else ", sim_buffet=..."
    return f"aerodelta.evidence.write_evidence({d}, {str(out)!r}{m}{s})"


def _model(
    model: str | os.PathLike[str] | DeltaModel | None,
) -> tuple[DeltaModel | None, Path | None]:
    if model is None or isinstance(model, DeltaModel):
        return model, None
    p = Path(model)
    if p.is_dir():
        raise InvalidInputError(f"model {p}: is a folder; give the model file (model.json)")
    if not p.is_file():
        raise InvalidInputError(f"model {p}: file not found (aerodelta fit writes model.json)")
    return DeltaModel.load(p), p


def _load(data: Any) -> tuple[pl.DataFrame, str, list[Path], Path | None]:
    """(ingested frame, a phrase naming it, the files read, the campaign folder or None)."""
    frame = getattr(data, "data", None)
    if isinstance(frame, pl.DataFrame):
        return frame, f"ingested records ({frame['maneuver_id'].n_unique()} maneuvers)", [], None
    if isinstance(data, pl.DataFrame):
        if "maneuver_id" not in data.columns:
            raise DataError("evidence: the frame has no maneuver_id column; give ingested records")
        return data, f"ingested records ({data['maneuver_id'].n_unique()} maneuvers)", [], None
    if not isinstance(data, (str, os.PathLike)):
        raise InvalidInputError(
            f"evidence: data must be a path or a polars DataFrame, not {type(data).__name__}"
        )
    p = Path(data)
    if not p.exists():
        raise DataError(f"{p}: no such file or folder (give the campaign folder or ingest output)")
    parquet = p / "data.parquet" if p.is_dir() else p
    if parquet.is_file() and parquet.suffix.lower() == ".parquet":
        try:
            frame = pl.read_parquet(parquet)
        except Exception as e:
            raise DataError(
                f"{parquet}: cannot read the ingest output; run aerodelta ingest again"
            ) from e
        if "maneuver_id" not in frame.columns:
            raise DataError(f"{parquet}: not an aerodelta ingest output (no maneuver_id column)")
        return frame, f"the ingest output {parquet}", [parquet], None
    if not p.is_dir():
        raise DataError(f"{p}: give the campaign folder or an aerodelta ingest output")
    from aerodelta.ingest import ingest  # noqa: PLC0415
    from aerodelta.readers import find_records, read_manifest  # noqa: PLC0415

    manifest_path = p / "manifest.csv"
    manifest = read_manifest(manifest_path) if manifest_path.is_file() else None
    frame = ingest(p, compat=False, progress=False).data
    files = [r.path for r in find_records(p, manifest)]
    files += [f for f in (manifest_path, p / "aircraft.toml") if f.is_file()]
    return frame, f"the campaign {p}", files, p
