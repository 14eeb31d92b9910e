"""Write the validation report (thesis Chapter 4): time-history matches, effect plots,
identified parameters, 6-DOF replay, roll-off, validation envelope and, when given, the
sim-to-real diagnosis, as one self-contained HTML file (OUT/report.html) with every figure also
as PNG and SVG in OUT/figures/."""

from __future__ import annotations

import argparse
import sys

from aerodelta.cli._data import (
    add_data_arguments,
    check_at_least,
    existing_file,
    load_data,
    maneuver_ids,
    output_folder,
)

HELP = "write the HTML validation report of a fitted Δ model"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta report``."""
    parser.add_argument("--model", required=True, help="model file from aerodelta fit (.json)")
    add_data_arguments(parser)
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--diagnosis", help="diagnosis.json from aerodelta diagnose")
    parser.add_argument(
        "--held-out",
        default="",
        help="maneuvers left out of the fit: comma-separated ids, or @FILE with one id per line "
        "(aerodelta fit --holdout writes MODEL.holdout.txt)",
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


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta report``."""
    from aerodelta.report import build_report  # noqa: PLC0415  (matplotlib: CLI start-up light)

    check_at_least(args.replays, "--replays", 0)
    existing_file(args.model, "--model")
    existing_file(args.diagnosis, "--diagnosis")
    out = output_folder(args.out)
    held = maneuver_ids(args.held_out)
    progress = not args.no_progress
    data, _ = load_data(args, progress=progress)
    res = build_report(
        args.model,
        data,
        out,
        held_out=held,
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
