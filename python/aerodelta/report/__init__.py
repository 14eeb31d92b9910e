"""The validation report (thesis Chapter 4 as a product): one self-contained HTML file with a
summary first, and every figure also written as PNG and SVG beside it.

Sections: time-history matches (4.1), effect plots (4.2), identified parameters against alpha,
6-DOF replay (4.3), roll-off, the simulator validation envelope and the sim-to-real diagnosis.

>>> from aerodelta.report import build_report  # doctest: +SKIP
>>> build_report(model, data, "out/report", held_out=ids)  # doctest: +SKIP
"""

from __future__ import annotations

import os
import re
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import polars as pl
from tqdm import tqdm

from aerodelta._fsutil import write_text_atomic
from aerodelta.aircraft import Aircraft
from aerodelta.exceptions import InvalidInputError
from aerodelta.model import DeltaModel
from aerodelta.plots import FigureSink
from aerodelta.report import (
    diagnosis,
    effects,
    envelope,
    params,
    replay,
    rolloff_section,
    timehistory,
)
from aerodelta.report.context import build_context, load_params
from aerodelta.report.diagnosis import load_diagnosis
from aerodelta.report.html import Section, esc, generated_at, page
from aerodelta.report.metrics import (
    all_metrics,
    maneuver_metrics,
    offset_removed_rms,
    overall_metrics,
    peak_error,
    rank_fits,
    rms_error,
    tic,
)

REPORT_NAME = "report.html"


@dataclass
class ReportResult:
    """What :func:`build_report` wrote.

    Attributes
    ----------
    html
        The report file.
    figures
        PNG and SVG files written beside it (in ``figures/``).
    sections
        The sections built, with their tables and timings.
    seconds
        Total time, s.
    figure_wait
        Time spent waiting, after the last section, for the figures drawn in worker
        processes, s.
    """

    html: Path
    figures: list[Path]
    sections: list[Section] = field(default_factory=list)
    seconds: float = 0.0
    figure_wait: float = 0.0

    def timings(self) -> dict[str, float]:
        """Seconds per section."""
        return {s.key: s.seconds for s in self.sections}


def build_report(
    model: DeltaModel | str | Path,
    data: pl.DataFrame,
    out: str | Path,
    *,
    params_table: pl.DataFrame | None = None,
    held_out: Sequence[str] = (),
    diagnosis_doc: Mapping[str, Any] | str | Path | None = None,
    qualified: str = "auto",
    replay_count: int = 3,
    replay_controls: str = "elevator",
    jsbsim_campaign: str | os.PathLike[str] | None = None,
    aircraft: Aircraft | str | os.PathLike[str] | None = None,
    svg: bool = True,
    title: str = "aerodelta validation report",
    progress: bool = False,
    workers: int | None = None,
) -> ReportResult:
    """Build the validation report.

    Parameters
    ----------
    model
        The fitted Δ model, or the path of its file (``aerodelta fit`` output; the per-bin
        estimates ``<model>.params.parquet`` beside it are read when ``params_table`` is None).
    data
        Ingested records (``aerodelta.ingest(...).data``).
    out
        Output folder: ``report.html`` and ``figures/`` are written there.
    params_table
        Per-bin estimates (``FitResult.summary()``).
    held_out
        Maneuver ids left out of the fit (marked in the plots and scored apart).
    diagnosis_doc
        ``diagnosis.json`` (path or parsed dict), optional.
    qualified
        Source of the qualified coefficients (see :func:`aerodelta.fit.qualified_coefficients`).
    replay_count
        Maneuvers replayed in the 6-DOF simulator.
    replay_controls
        ``"elevator"``: the recorded elevator and thrust, lateral controls at zero (as the
        thesis, Section 4.3); ``"all"``: every recorded control.
    jsbsim_campaign
        The JSBSim campaign folder (``aerodelta campaign --simulator jsbsim``) the records were
        ingested from: the 6-DOF replay then flies its JSBSim aircraft, the qualified one and
        the qualified one with the fitted Δ, as ``aerodelta jsbsim-replay`` (also when
        ``qualified`` is ``"jsbsim:DIR"``). ``None``: the built-in ADX-37, for its records only.
    aircraft
        The aircraft file (or :class:`aerodelta.aircraft.Aircraft`) of the records: with a
        DAVE-ML qualified model giving the six coefficients, the 6-DOF replay flies this
        aircraft with that model (``aerodelta.report.daveml_replay``). Read for nothing else.
    svg
        Also write SVG files of the figures.
    title
        Report title.
    progress
        Progress bar on stderr.
    workers
        Worker processes drawing the figures while the sections are computed (0: draw in this
        process). ``None``: :func:`default_workers` (two on a multi-core machine when the records
        hold at least :data:`POOL_MIN_SAMPLES` samples, else none). The files are the same
        bytes either way.

    Returns
    -------
    ReportResult
    """
    t0 = time.perf_counter()
    generated = generated_at()  # a bad SOURCE_DATE_EPOCH is refused before the work
    out = Path(out)
    # every input is read before the output folder is made (a bad input leaves nothing behind)
    if isinstance(model, (str, Path)):
        path = Path(model)
        if params_table is None:
            params_table = load_params(path)
        model = DeltaModel.load(path)
    doc = (
        load_diagnosis(diagnosis_doc)
        if isinstance(diagnosis_doc, (str, Path))
        else (dict(diagnosis_doc) if diagnosis_doc is not None else None)
    )
    out.mkdir(parents=True, exist_ok=True)
    figdir = out / "figures"
    if figdir.is_dir():  # figures of an earlier report in the same folder
        for f in figdir.iterdir():
            if re.fullmatch(r"\d{3}_.+\.(png|svg)", f.name):
                f.unlink()
    if workers is None:
        workers = default_workers(data.height)
    elif workers < 0:
        raise InvalidInputError(f"workers={workers}: use 0 (draw here) or a positive count")
    with FigureSink(figdir, svg=svg, workers=workers) as sink:
        steps = [
            ("time histories", lambda c: timehistory.section(c, sink)),
            ("effects", lambda c: effects.section(c, sink)),
            ("parameters", lambda c: params.section(c, sink)),
            (
                "6-DOF replay",
                lambda c: replay.section(
                    c,
                    sink,
                    count=replay_count,
                    controls=replay_controls,
                    jsbsim_campaign=jsbsim_campaign,
                    aircraft=aircraft,
                ),
            ),
            ("roll-off", lambda c: rolloff_section.section(c, sink)),
            ("envelope", lambda c: envelope.section(c, sink)),
            ("diagnosis", lambda c: diagnosis.section(c.diagnosis, sink)),
        ]
        bar = tqdm(
            total=len(steps) + 3, desc="report", unit="step", file=sys.stderr, disable=not progress
        )
        bar.set_postfix_str("models along the records")
        ctx = build_context(
            model, data, params=params_table, held_out=held_out, qualified=qualified, diagnosis=doc
        )
        prep = time.perf_counter() - t0
        bar.update(1)
        sections: list[Section] = []
        for name, fn in steps:
            bar.set_postfix_str(name)
            ts = time.perf_counter()
            s = fn(ctx)
            s.seconds = time.perf_counter() - ts
            sections.append(s)
            bar.update(1)
        # the figures still being drawn in the workers (their time is not in any section's)
        bar.set_postfix_str("figures")
        ts = time.perf_counter()
        sink.finish()
        for s in sections:
            s.body = [sink.fill(b) for b in s.body]
        figure_wait = time.perf_counter() - ts
        bar.update(1)
    bar.set_postfix_str("writing HTML")
    n_man = ctx.data["maneuver_id"].n_unique()
    intro = (
        f"<p>{n_man} maneuvers, {ctx.data.height} samples, flaps "
        f"{', '.join(f'{f:g}' for f in ctx.flaps)} deg; {len(ctx.held_out)} maneuvers held out "
        f"of the fit; qualified model: {esc(ctx.qualified)}; coefficients "
        f"{', '.join(ctx.coefficients)}. Figures are also in <code>figures/</code> as PNG"
        f"{' and SVG' if svg else ''}.</p>"
    )
    doc_html = page(
        title,
        f"Δ model validation (thesis Chapter 4), {n_man} maneuvers",
        intro,
        sections,
        generated=generated,
    )
    target = out / REPORT_NAME
    write_text_atomic(target, doc_html)
    bar.update(1)
    bar.close()
    prep_sec = Section("prepare", "prepare", seconds=prep)
    return ReportResult(
        html=target,
        figures=list(sink.written),
        sections=[prep_sec, *sections],
        seconds=time.perf_counter() - t0,
        figure_wait=figure_wait,
    )


#: Records (samples) from which :func:`build_report` draws in worker processes by default
#: (about ten maneuvers; a toy report is drawn before two interpreters would have started).
POOL_MIN_SAMPLES = 20_000
#: Worker processes :func:`build_report` uses by default.
POOL_WORKERS = 2


def default_workers(samples: int) -> int:
    """Figure workers for a report of ``samples`` records: :data:`POOL_WORKERS` when the
    process may run on two or more CPUs and ``samples >= POOL_MIN_SAMPLES``, else 0 (a small
    report is drawn faster than two interpreters start)."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return POOL_WORKERS if cpus >= 2 and samples >= POOL_MIN_SAMPLES else 0


__all__ = [
    "REPORT_NAME",
    "ReportResult",
    "all_metrics",
    "build_report",
    "default_workers",
    "load_diagnosis",
    "maneuver_metrics",
    "offset_removed_rms",
    "overall_metrics",
    "peak_error",
    "rank_fits",
    "rms_error",
    "tic",
]
