"""Fly held-out maneuvers of a JSBSim campaign (aerodelta campaign --simulator jsbsim) open loop
on the full aircraft (the truth), the qualified aircraft (the withheld terms frozen past the
withhold alpha) and the extended aircraft (qualified + the fitted Δ exported with
aerodelta export --jsbsim), with the recorded surfaces and the campaign pilot's throttle fitted
to the recorded thrust, and print the Theil inequality coefficient of each against the record
on p, r, phi and beta, and extended / qualified (docs/jsbsim_campaign.md)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import polars as pl

from aerodelta.cli._data import created, existing_file, load_model, maneuver_ids, output_file
from aerodelta.exceptions import InvalidInputError

HELP = "closed-loop check of a Δ on a JSBSim campaign: replay held-out maneuvers, Theil per channel"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta jsbsim-replay``."""
    parser.add_argument(
        "--campaign", required=True, help="folder written by aerodelta campaign --simulator jsbsim"
    )
    parser.add_argument("--model", required=True, help="model file from aerodelta fit (.json)")
    parser.add_argument(
        "--held-out",
        default="",
        metavar="IDS",
        help="replay these maneuvers: comma-separated ids or @FILE (aerodelta fit --holdout "
        "writes MODEL.holdout.txt); default every maneuver",
    )
    parser.add_argument("--out", help="also write the table as CSV")
    parser.add_argument("--no-progress", action="store_true", help="no line per maneuver")


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta jsbsim-replay``."""
    from aerodelta.jsbsim_replay import replay_campaign  # noqa: PLC0415

    out = output_file(args.out, example="replay.csv") if args.out else None
    camp = Path(args.campaign)
    if not camp.is_dir():
        raise InvalidInputError(f"--campaign {camp}: folder not found")
    model_file = existing_file(args.model, "--model")
    assert model_file is not None
    model = load_model(model_file)
    ids = maneuver_ids(args.held_out)
    scores = replay_campaign(camp, model, maneuvers=ids or None, progress=not args.no_progress)
    assert isinstance(scores, pl.DataFrame)
    cols = ["maneuver_id", "channel", "tic_full", "tic_qualified", "tic_extended", "ratio"]
    for window in ("predictable", "delta"):
        w = scores.filter(pl.col("window") == window).select(cols)
        print(f"window '{window}' (TIC: 0 perfect, 1 useless; ratio: extended / qualified)")
        with pl.Config(tbl_rows=-1, float_precision=4, tbl_hide_dataframe_shape=True):
            print(w)
    if out is not None:
        from aerodelta._fsutil import write_atomic  # noqa: PLC0415

        with created(out.parent):
            write_atomic(out, scores.write_csv)
        print(f"wrote {out}", file=sys.stderr)
    return 0
