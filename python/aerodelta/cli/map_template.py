"""Write a channel-map skeleton for the records of a campaign from one record's header and
values: each column's guessed canonical channel and unit (docs/data.md), every guess marked
with a '# REVIEW' comment saying why. The map is refused until the marks are deleted: check each
line (column, unit, sign), fix what is wrong, delete the mark, then give the map to ingest,
fit, diagnose, report, rolloff or validate with --map FILE."""

from __future__ import annotations

import argparse
import sys

from aerodelta.cli._data import created, existing_file, output_file
from aerodelta.exceptions import InvalidInputError

HELP = "write a channel-map skeleton (TOML) from a record's columns, units guessed for review"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta map-template``."""
    parser.add_argument("record", metavar="RECORD", help="one flight record (CSV, Parquet, .mat)")
    parser.add_argument(
        "-o", "--out", metavar="FILE", help="channel map to write (default: print it)"
    )
    parser.add_argument("--force", action="store_true", help="replace an existing --out file")


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta map-template``."""
    from aerodelta._fsutil import write_text_atomic  # noqa: PLC0415
    from aerodelta.map_template import map_template  # noqa: PLC0415

    existing_file(args.record, "RECORD")
    out = output_file(args.out, "--out", "map.toml") if args.out else None
    if out is not None and out.exists() and not args.force:
        raise InvalidInputError(
            f"--out {out}: exists (perhaps a reviewed map); give another name or --force"
        )
    t = map_template(args.record)
    text = t.to_toml()
    missing = t.missing_required()
    left = [g for g in t.guesses if g.note]
    if out is None:
        sys.stdout.write(text)
    else:
        with created(out.parent):
            write_text_atomic(out, text)
        print(f"wrote {out}")
    print(
        f"{len(t.mapped)} column(s) mapped, each marked '# REVIEW'; {len(left)} left out"
        + (f"; required channel(s) not found: {', '.join(missing)}" if missing else ""),
        file=sys.stderr,
    )
    return 0
