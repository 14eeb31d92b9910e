"""Time the validation report of the 200-maneuver default campaign (as ``aerodelta demo``
builds it) against the 4 s target of issue 18, with peers timed in the same run.

Generates the campaign (seed 0), ingests it, fits the Δ model on four fifths and diagnoses the
campaign (as ``aerodelta demo``) outside the timing, then times, in this order:

- ``build_report`` as the demo calls it (figures drawn in worker processes when the machine
  has two or more CPUs);
- ``build_report(workers=0)``: everything in this process;
- the peer: the same figures (the same data, the same drawing functions) drawn one after
  another with plain matplotlib (its default settings, ``savefig`` to PNG and SVG) in this
  process, i.e. the drawing work a one-process report cannot avoid.

It prints the wall times, the ratios to the peer, each section's share, the peak memory of this
process and of the workers (the largest one). Run: ``python benchmarks/bench_report.py
[--size quick|default] [--no-diagnosis] [--no-svg]``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import resource
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import polars as pl

from aerodelta.campaign import generate_campaign
from aerodelta.diagnosis import diagnose
from aerodelta.fit import FitConfig, fit
from aerodelta.ingest import ingest
from aerodelta.model import with_params_hash
from aerodelta.plots import FigureSink
from aerodelta.report import ReportResult, build_report

TARGET_S = 4.0


class _Recorder(FigureSink):
    """A sink that keeps each figure's drawing function and data instead of drawing it."""

    def __init__(self) -> None:
        super().__init__(None)
        self.jobs: list[tuple[Any, dict[str, Any]]] = []

    def plot(self, draw: Any, name: str, caption: str, **data: Any) -> str:
        self.jobs.append((draw, data))
        return ""


def _peer(jobs: list[tuple[Any, dict[str, Any]]], svg: bool) -> float:
    """Wall time of drawing ``jobs`` with matplotlib's defaults, PNG (110 dpi) and SVG."""
    import matplotlib as mpl  # noqa: PLC0415

    t = time.perf_counter()
    with mpl.rc_context():
        mpl.rcdefaults()
        for draw, data in jobs:
            fig = draw(**data)
            fig.savefig(io.BytesIO(), format="png", dpi=110)
            if svg:
                fig.savefig(io.BytesIO(), format="svg")
    return time.perf_counter() - t


class _DescendantRSS(threading.Thread):
    """Samples the resident memory of this process's descendants (Linux ``/proc``) every
    20 ms: the largest sum over them (the workers together), MB."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.peak_mb = 0.0
        self._halt = threading.Event()

    @staticmethod
    def _children(pid: int) -> list[int]:
        out = []
        for task in Path(f"/proc/{pid}/task").glob("*"):
            with contextlib.suppress(OSError):
                out += [int(c) for c in (task / "children").read_text().split()]
        return out

    def run(self) -> None:
        while not self._halt.wait(0.02):
            todo, total = self._children(os.getpid()), 0.0
            while todo:
                pid = todo.pop()
                try:
                    status = Path(f"/proc/{pid}/status").read_text()
                    total += int(status.split("VmRSS:")[1].split()[0]) / 1e3
                except (OSError, IndexError, ValueError):
                    continue
                todo += self._children(pid)
            self.peak_mb = max(self.peak_mb, total)

    def stop(self) -> float:
        self._halt.set()
        self.join()
        return self.peak_mb


def _timed(label: str, run: Any) -> ReportResult:
    t = time.perf_counter()
    rep = run()
    wall = time.perf_counter() - t
    print(f"{label:<34} {wall:6.2f} s (build_report's own clock {rep.seconds:.2f} s)")
    return rep


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--size", default="default", choices=["quick", "default"])
    ap.add_argument("--no-svg", action="store_true")
    ap.add_argument("--no-diagnosis", action="store_true")
    args = ap.parse_args()
    svg = not args.no_svg
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        t = time.perf_counter()
        generate_campaign(root / "campaign", seed=0, size=args.size, progress=False)
        data = ingest(root / "campaign", compat=False, progress=False).data
        ids = data["maneuver_id"].unique().sort().to_list()
        held = ids[::5]
        res = fit(
            data.filter(~pl.col("maneuver_id").is_in(held)),
            config=FitConfig(bootstrap=100),
            progress=False,
        )
        res.summary().write_parquet(root / "model.params.parquet")
        with_params_hash(res.model, root / "model.params.parquet").save(root / "model.json")
        doc = None if args.no_diagnosis else diagnose(data, progress=False).result
        print(
            f"inputs (campaign, ingest, fit, diagnosis; not timed): "
            f"{time.perf_counter() - t:.0f} s, {len(ids)} maneuvers, {data.height} samples"
        )

        def report(out: str, **kw: Any) -> ReportResult:
            return build_report(
                root / "model.json", data, root / out, held_out=held, diagnosis_doc=doc,
                svg=svg, **kw,
            )  # fmt: skip

        sampler = _DescendantRSS()
        sampler.start()
        rep = _timed("build_report (as the demo)", lambda: report("report"))
        rss_workers = sampler.stop()
        rss_self = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
        here = _timed("build_report(workers=0)", lambda: report("here", workers=0))
        # the figures' data, recorded by a report whose sink only records
        rec = _Recorder()
        import aerodelta.report as r  # noqa: PLC0415

        orig = r.FigureSink
        r.FigureSink = lambda *a, **k: rec  # type: ignore[assignment,misc]
        try:
            report("recorded", workers=0)
        finally:
            r.FigureSink = orig  # type: ignore[misc]
        peer = _peer(rec.jobs, svg)
        print(
            f"{'peer: the figures, plain matplotlib':<34} {peer:6.2f} s ({len(rec.jobs)} figures)"
        )
        verdict = "met" if rep.seconds <= TARGET_S else "MISSED"
        print(
            f"report {rep.seconds:.2f} s (target {TARGET_S:g} s: {verdict}); "
            f"{rep.seconds / peer:.2f}x the peer; in one process {here.seconds / peer:.2f}x; "
            f"{len(rep.figures)} figure files, HTML {rep.html.stat().st_size / 1e6:.1f} MB; "
            f"peak RSS {rss_self:.0f} MB (this process, with the inputs and the fit), "
            f"{rss_workers:.0f} MB (the workers together, sampled)"
        )
        for k, v in rep.timings().items():
            print(f"  {k:<12} {v:6.2f} s  {100 * v / rep.seconds:5.1f} %")
        print(f"  {'(figures)':<12} {rep.figure_wait:6.2f} s  waiting for the workers at the end")


if __name__ == "__main__":
    main()
