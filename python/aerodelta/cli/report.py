"""Write the validation report (thesis Chapter 4): time-history matches, effect plots,
identified parameters, 6-DOF replay, roll-off, validation envelope and, when given, the
sim-to-real diagnosis, as one self-contained HTML file (OUT/report.html) with every figure also
as PNG and SVG in OUT/figures/."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import polars as pl

from aerodelta.exceptions import DataError
from aerodelta.ingest import ingest

HELP = "write the HTML validation report of a fitted Δ model"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta report``."""
    parser.add_argument("--model", required=True, help="model file from aerodelta fit (.json)")
    parser.add_argument(
        "--data",
        required=True,
        help="campaign folder (manifest.csv), aerodelta ingest output folder (data.parquet) "
        "or a data.parquet file",
    )
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--diagnosis", help="diagnosis.json from aerodelta diagnose")
    parser.add_argument(
        "--held-out",
        default="",
        help="maneuvers left out of the fit: comma-separated ids, or @FILE with one id per line",
    )
    parser.add_argument(
        "--qualified",
        default="auto",
        choices=["auto", "columns", "adx37"],
        help="source of the qualified coefficients (as aerodelta fit --model)",
    )
    parser.add_argument("--replays", type=int, default=3, help="maneuvers replayed in 6-DOF")
    parser.add_argument(
        "--replay-controls",
        default="elevator",
        choices=["elevator", "all"],
        help="feed the recorded elevator and thrust only (thesis Section 4.3), or all controls",
    )
    parser.add_argument("--no-svg", action="store_true", help="PNG figures only")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def read_data(path: str | Path, *, progress: bool = False) -> pl.DataFrame:
    """Ingested records from a campaign folder, an ingest output folder or a Parquet file."""
    p = Path(path)
    if p.is_file():
        return pl.read_parquet(p)
    if (p / "data.parquet").is_file():
        return pl.read_parquet(p / "data.parquet")
    if (p / "manifest.csv").is_file():
        return ingest(p, compat=False, progress=progress).data
    raise DataError(
        f"{p}: neither a data.parquet file, an ingest output folder nor a campaign folder "
        "(manifest.csv); run aerodelta ingest or pass the campaign folder"
    )


def held_out_ids(spec: str) -> list[str]:
    """Ids from ``a,b,c`` or ``@file`` (one per line, ``#`` comments)."""
    if spec.startswith("@"):
        lines = Path(spec[1:]).read_text(encoding="utf-8").splitlines()
        return [x.split("#")[0].strip() for x in lines if x.split("#")[0].strip()]
    return [x.strip() for x in spec.split(",") if x.strip()]


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta report``."""
    from aerodelta.report import build_report  # noqa: PLC0415  (matplotlib: CLI start-up light)

    progress = not args.no_progress
    data = read_data(args.data, progress=progress)
    res = build_report(
        args.model,
        data,
        args.out,
        held_out=held_out_ids(args.held_out),
        diagnosis_doc=args.diagnosis,
        qualified=args.qualified,
        replay_count=args.replays,
        replay_controls=args.replay_controls,
        svg=not args.no_svg,
        progress=progress,
    )
    print(f"report: {res.html} ({len(res.figures)} figure files) in {res.seconds:.1f} s")
    for k, v in res.timings().items():
        print(f"  {k:<12} {v:6.2f} s", file=sys.stderr)
    return 0
