"""Write the validation report (thesis Chapter 4): time-history matches, effect plots,
identified parameters, 6-DOF replay, roll-off, validation envelope and, when given, the
sim-to-real diagnosis, as one self-contained HTML file (OUT/report.html) with every figure also
as PNG and SVG in OUT/figures/."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from aerodelta.cli._data import (
    add_data_arguments,
    check_at_least,
    check_outputs,
    created,
    existing_file,
    jsbsim_campaign_option,
    load_model,
    load_records,
    maneuver_ids,
    output_folder,
    qualified_choice,
    resolve_data,
)
from aerodelta.exceptions import DataError, InvalidInputError

HELP = "write the HTML validation report of a fitted Δ model"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta report``."""
    parser.add_argument("--model", required=True, help="model file from aerodelta fit (.json)")
    add_data_arguments(
        parser,
        aircraft_help="aircraft reference TOML (default DATA/aircraft.toml); with a DAVE-ML "
        "--qualified model the 6-DOF replay flies this aircraft",
    )
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
        type=qualified_choice,
        metavar="auto|columns|adx37|jsbsim:DIR|FILE.dml",
        help="the qualified model (as aerodelta fit --model); auto: the one the fit recorded; "
        "jsbsim:DIR also replays the JSBSim campaign's aircraft (as --jsbsim-campaign DIR)",
    )
    parser.add_argument("--replays", type=int, default=3, help="maneuvers replayed in 6-DOF")
    parser.add_argument(
        "--replay-controls",
        default="elevator",
        choices=["elevator", "all"],
        help="feed the recorded elevator and thrust only (thesis Section 4.3), or all controls",
    )
    parser.add_argument(
        "--jsbsim-campaign",
        metavar="DIR",
        help="the JSBSim campaign (aerodelta campaign --simulator jsbsim) the records come from: "
        "the 6-DOF replay flies its JSBSim aircraft, qualified and qualified + Δ, as aerodelta "
        "jsbsim-replay (default: the built-in ADX-37, for its own records only)",
    )
    parser.add_argument("--no-svg", action="store_true", help="PNG figures only")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def _diagnosis(path: Path) -> dict[str, Any]:
    """``--diagnosis FILE`` read and checked (``aerodelta.report.diagnosis.load_diagnosis``),
    with the failures it lets through (bytes that are not text, nesting too deep) as one line."""
    from aerodelta.report.diagnosis import load_diagnosis  # noqa: PLC0415

    try:
        return load_diagnosis(path)
    except (UnicodeDecodeError, RecursionError) as e:
        what = "not UTF-8 text" if isinstance(e, UnicodeDecodeError) else "nested too deeply"
        raise DataError(
            f"--diagnosis {path}: cannot read the diagnosis ({what}); give the diagnosis.json "
            "of aerodelta diagnose"
        ) from None


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta report``."""
    from aerodelta.report import build_report  # noqa: PLC0415  (matplotlib: CLI start-up light)
    from aerodelta.report.context import load_params  # noqa: PLC0415

    check_at_least(args.replays, "--replays", 0)
    model_file = existing_file(args.model, "--model")
    diagnosis_file = existing_file(args.diagnosis, "--diagnosis")
    dml = (
        existing_file(args.qualified, "--qualified")
        if args.qualified.lower().endswith((".dml", ".xml"))
        else None
    )
    assert model_file is not None
    jsbsim_campaign_option(args.qualified, "--qualified")
    campaign = Path(args.jsbsim_campaign) if args.jsbsim_campaign else None
    if campaign is not None and not campaign.is_dir():
        raise InvalidInputError(f"--jsbsim-campaign {campaign}: folder not found")
    out = output_folder(args.out)
    held = maneuver_ids(args.held_out)
    progress = not args.no_progress
    src = resolve_data(args, aircraft_with_ingested=True)
    check_outputs(src, "--out", folder=out, inputs=[model_file, diagnosis_file, dml])
    # every input file read before the output folder is made: a bad one leaves nothing behind
    model = load_model(model_file)
    params = load_params(model_file)
    doc = _diagnosis(diagnosis_file) if diagnosis_file is not None else None
    data = load_records(src, progress=progress)
    with created(out):
        res = build_report(
            model,
            data,
            out,
            params_table=params,
            held_out=held,
            diagnosis_doc=doc,
            qualified=args.qualified,
            replay_count=args.replays,
            replay_controls=args.replay_controls,
            jsbsim_campaign=campaign,
            aircraft=src.aircraft,
            svg=not args.no_svg,
            progress=progress,
        )
    print(f"report: {res.html} ({len(res.figures)} figure files) in {res.seconds:.1f} s")
    for k, v in res.timings().items():
        print(f"  {k:<12} {v:6.2f} s", file=sys.stderr)
    return 0
