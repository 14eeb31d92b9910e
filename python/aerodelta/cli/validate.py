"""Validate a fitted Δ model on flight records (thesis Chapter 4): per coefficient, the RMS error
and Theil inequality coefficient (TIC) of the qualified model and of the extended model
(qualified + blended Δ) against the measured coefficients, and their ratios (below 1: the
extended model is closer to the flight data).

Use records held out of the fit: another campaign, or the maneuvers aerodelta fit --holdout
left out (--held-out @MODEL.holdout.txt)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

import polars as pl

from aerodelta.cli._data import (
    add_data_arguments,
    check_outputs,
    created,
    existing_file,
    load_model,
    load_records,
    maneuver_ids,
    output_file,
    qualified_choice,
    resolve_data,
)
from aerodelta.exceptions import DataError

HELP = "held-out metrics of a fitted Δ model: RMS and Theil coefficient, qualified vs extended"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta validate``."""
    parser.add_argument("--model", required=True, help="model file from aerodelta fit (.json)")
    add_data_arguments(parser)
    parser.add_argument(
        "--held-out",
        default="",
        metavar="IDS",
        help="validate on these maneuvers only: comma-separated ids, or @FILE with one id per "
        "line (aerodelta fit --holdout writes MODEL.holdout.txt)",
    )
    parser.add_argument(
        "--qualified",
        default="auto",
        type=qualified_choice,
        metavar="auto|columns|adx37|FILE.dml",
        help="the qualified model (as aerodelta fit --model); auto: the one the fit recorded "
        "(a DAVE-ML file must be named again)",
    )
    parser.add_argument("--out", help="also write the table as CSV")
    parser.add_argument("--json", action="store_true", help="print the table as JSON")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def with_rms_ratio(v: pl.DataFrame) -> pl.DataFrame:
    """The validation table with ``rms_ratio`` (extended / qualified) beside ``tic_ratio``."""
    if "rms_ratio" in v.columns:
        return v
    return v.with_columns((pl.col("rms_extended") / pl.col("rms_qualified")).alias("rms_ratio"))


def format_table(v: pl.DataFrame) -> str:
    """The validation table (``aerodelta.fit.validate_model``) as text."""
    v = with_rms_ratio(v)
    lines = [
        f"{'coef':<5} {'rms qual':>10} {'rms ext':>10} {'ratio':>6}   "
        f"{'TIC qual':>8} {'TIC ext':>8} {'ratio':>6}"
    ]
    for r in v.iter_rows(named=True):
        lines.append(
            f"{r['coefficient']:<5} {r['rms_qualified']:>10.5f} {r['rms_extended']:>10.5f} "
            f"{r['rms_ratio']:>6.2f}   {r['tic_qualified']:>8.4f} {r['tic_extended']:>8.4f} "
            f"{r['tic_ratio']:>6.2f}"
        )
    lines.append(
        "(rms: error against the measured coefficient; TIC: Theil inequality coefficient, 0 "
        "perfect, 1 useless; ratio: extended / qualified, below 1 the extended model is better)"
    )
    return "\n".join(lines)


def _json_safe(x: Any) -> Any:
    return None if isinstance(x, float) and not math.isfinite(x) else x


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta validate``."""
    from aerodelta.fit import model_frame, validate_model  # noqa: PLC0415

    out = output_file(args.out, example="validation.csv") if args.out else None
    model_file = existing_file(args.model, "--model")
    assert model_file is not None
    dml = (
        existing_file(args.qualified, "--qualified")
        if args.qualified.lower().endswith((".dml", ".xml"))
        else None
    )
    ids = maneuver_ids(args.held_out)
    src = resolve_data(args)
    check_outputs(src, "--out", files=[out] if out else [], inputs=[model_file, dml])
    model = load_model(model_file)
    data = load_records(src, progress=not args.no_progress)
    if ids:
        have = set(data["maneuver_id"].cast(pl.Utf8).unique().to_list())
        missing = [m for m in ids if m not in have]
        if missing:
            more = f" and {len(missing) - 5} more" if len(missing) > 5 else ""
            raise DataError(
                f"--held-out: maneuver(s) {', '.join(missing[:5])}{more} not in "
                f"{src.describe()}; give the data the model was fitted from"
            )
        data = data.filter(pl.col("maneuver_id").cast(pl.Utf8).is_in(ids))
    lacking = sorted(set(model.input_columns) - set(model_frame(data.head(0)).columns))
    if lacking:
        raise DataError(
            f"{src.describe()}: no column {', '.join(lacking)}, which the model {model_file} "
            "reads; give records with those channels"
        )
    v = with_rms_ratio(validate_model(model, data, qualified=args.qualified))
    n = int(data["maneuver_id"].n_unique())
    if args.json:
        doc = {
            "model": str(args.model),
            "data": str(src.path),
            "maneuvers": n,
            "rows": data.height,
            "coefficients": [{k: _json_safe(x) for k, x in r.items()} for r in v.to_dicts()],
        }
        print(json.dumps(doc, indent=2))
    else:
        print(f"{args.model} on {n} maneuvers ({data.height} rows) of {src.describe()}:")
        print(format_table(v))
    if out is not None:
        from aerodelta._fsutil import write_atomic  # noqa: PLC0415

        with created(out.parent):
            write_atomic(out, v.write_csv)
        print(f"wrote {out}", file=sys.stderr)
    return 0
