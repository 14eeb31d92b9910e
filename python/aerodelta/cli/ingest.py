"""Read, map, validate and preprocess flight test records into one partition-ready table.

Writes DIR_OUT/data.parquet (canonical channels + derived columns), validation.json (every
finding per maneuver), smoothing.csv (cut-offs) and compat.csv (data compatibility estimates);
prints a summary to stdout and progress to stderr.
"""

from __future__ import annotations

import argparse
import json
import sys

from aerodelta.cli import cli_wording
from aerodelta.cli._data import (
    add_data_arguments,
    check_outputs,
    created,
    ingest_source,
    output_folder,
    resolve_data,
)
from aerodelta.exceptions import InvalidInputError
from aerodelta.ingest import COMPAT_METHODS, summarise

HELP = "ingest and preprocess flight test records (CSV, Parquet, .mat)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``aerodelta ingest``."""
    add_data_arguments(parser)
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument(
        "--allow-interpolation", action="store_true", help="interpolate short NaN dropouts"
    )
    parser.add_argument("--no-compat", action="store_true", help="skip the compatibility check")
    parser.add_argument(
        "--vane-scale",
        action="store_true",
        help="also estimate the alpha and beta vanes' scale factors (upwash, sidewash) in the "
        "compatibility check; needs alpha and sideslip sweeps within the maneuvers",
    )
    parser.add_argument(
        "--compat-method",
        choices=COMPAT_METHODS,
        default="auto",
        help="flight-path reconstruction of the compatibility check: output-error (steady air), "
        "innovations (a one-step predictor that follows gusts; about 3x slower) or auto "
        "(innovations with --vane-scale, else output-error; default)",
    )
    parser.add_argument(
        "--apply-compat", action="store_true", help="remove estimated biases and scale factors"
    )
    parser.add_argument("--format", choices=("table", "json"), default="table")
    parser.add_argument(
        "--quiet", "--no-progress", dest="quiet", action="store_true", help="no progress bar"
    )


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta ingest``; returns the exit status."""
    if args.apply_compat and args.no_compat:
        raise InvalidInputError("--apply-compat needs the compatibility check: drop --no-compat")
    if args.vane_scale and args.no_compat:
        raise InvalidInputError("--vane-scale needs the compatibility check: drop --no-compat")
    if args.compat_method != "auto" and args.no_compat:
        raise InvalidInputError("--compat-method needs the compatibility check: drop --no-compat")
    out = output_folder(args.out)
    src = resolve_data(args)
    if src.kind == "ingested":
        raise InvalidInputError(
            f"{src.path} is already an aerodelta ingest output (data.parquet); give the "
            "campaign folder or a record file"
        )
    if src.path.is_dir() and out.resolve() == src.path.resolve():
        raise InvalidInputError(
            f"--out {out}: is the campaign folder itself; write the ingest output into a "
            "folder of its own"
        )
    check_outputs(src, "--out", folder=out)
    res = ingest_source(
        src,
        progress=not args.quiet,
        allow_interpolation=args.allow_interpolation,
        compat=not args.no_compat,
        apply_compat=args.apply_compat,
        vane_scale=args.vane_scale,
        compat_method=args.compat_method,
    )
    with created(out):
        paths = res.write(out)
    findings = res.report_frame()
    summary = {
        "maneuvers": len(res.reports),
        "rows": res.data.height,
        "warnings": int((findings["severity"] == "warning").sum()),
        "files": [str(p) for p in paths],
    }
    if args.format == "json":
        print(json.dumps(summary, indent=2))
    else:
        print(f"ingested {summary['maneuvers']} maneuvers, {summary['rows']} rows")
        # one line per channel and kind of finding, with the files that repeat it
        warned = [f for r in res.reports for f in r.findings if f.severity == "warning"]
        for line in summarise(warned):
            print(f"warning: {cli_wording(line, 'ingest')}")
        for p in paths:
            print(f"wrote {p}")
    sys.stdout.flush()
    return 0
