"""Read, map, validate and preprocess flight test records into one partition-ready table.

Writes DIR_OUT/data.parquet (canonical channels + derived columns), validation.json (every
finding per maneuver), smoothing.csv (cut-offs) and compat.csv (data compatibility estimates);
prints a summary to stdout and progress to stderr.
"""

from __future__ import annotations

import argparse
import json
import sys

HELP = "ingest and preprocess flight test records (CSV, Parquet, .mat)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``aerodelta ingest``."""
    parser.add_argument("--data", required=True, help="campaign folder or record file")
    parser.add_argument("--aircraft", help="aircraft reference TOML (default DATA/aircraft.toml)")
    parser.add_argument("--map", dest="channel_map", help="channel map TOML (default: canonical)")
    parser.add_argument("--manifest", help="manifest CSV/Parquet (default DATA/manifest.csv)")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument(
        "--allow-interpolation", action="store_true", help="interpolate short NaN dropouts"
    )
    parser.add_argument("--no-compat", action="store_true", help="skip the compatibility check")
    parser.add_argument(
        "--apply-compat", action="store_true", help="remove estimated biases and scale factors"
    )
    parser.add_argument("--format", choices=("table", "json"), default="table")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta ingest``; returns the exit status."""
    from aerodelta.ingest import ingest  # noqa: PLC0415  (keeps CLI start-up light)

    res = ingest(
        args.data,
        aircraft=args.aircraft,
        channel_map=args.channel_map,
        manifest=args.manifest,
        allow_interpolation=args.allow_interpolation,
        compat=not args.no_compat,
        apply_compat=args.apply_compat,
        progress=not args.quiet,
    )
    paths = res.write(args.out)
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
        for f in findings.filter(findings["severity"] == "warning").iter_rows(named=True):
            print(f"warning: {f['file']} [{f['maneuver_id']}] {f['channel']}: {f['message']}")
        for p in paths:
            print(f"wrote {p}")
    sys.stdout.flush()
    return 0
