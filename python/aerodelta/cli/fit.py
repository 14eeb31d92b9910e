"""Identify the Δ model from flight test records (thesis Sections 3.3-3.6) and write it.

Reads a campaign folder (records, manifest, aircraft.toml), ingests it, fits the Δ model per
flap and coefficient, and writes the model (JSON, schema aerodelta.model/1) plus the per-bin
estimates (Parquet) beside it."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import polars as pl

from aerodelta.fit import FitConfig, fit
from aerodelta.ingest import ingest

HELP = "identify the Δ (stall) model from flight test data"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta fit``."""
    parser.add_argument("--data", required=True, help="campaign folder (records + manifest)")
    parser.add_argument(
        "--model",
        default="auto",
        choices=["auto", "columns", "adx37"],
        help="qualified model: the records' *_sim columns, or the built-in ADX-37 model",
    )
    parser.add_argument("--config", help="fit settings (TOML, see aerodelta.FitConfig)")
    parser.add_argument("--out", required=True, help="model file to write (.json)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta fit``."""
    cfg = FitConfig.from_toml(args.config) if args.config else FitConfig()
    progress = not args.no_progress
    data = ingest(args.data, compat=False, progress=progress).data
    result = fit(data, qualified=args.model, config=cfg, progress=progress)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    result.model.save(out)
    params = out.with_suffix(".params.parquet")
    tmp = params.with_name(f".{params.name}.tmp")
    result.summary().write_parquet(tmp)
    tmp.replace(params)
    for note in result.notes:
        print(f"note: {note}")
    ident = result.params.group_by("coefficient").agg(
        pl.len().alias("estimates"), pl.col("identifiable").mean().alias("identified")
    )
    for row in ident.sort("coefficient").iter_rows(named=True):
        print(
            f"{row['coefficient']}: {row['estimates']} bin estimates, "
            f"{100 * row['identified']:.0f}% identified"
        )
    # why the rest is not identified: the first clause of each note, most frequent first
    why = (
        result.params.filter(~pl.col("identifiable"))
        .with_columns(pl.col("note").str.split(":").list.first().alias("reason"))
        .group_by("coefficient", "reason")
        .agg(pl.len().alias("n"))
        .sort(["coefficient", "n"], descending=[False, True])
    )
    for row in why.iter_rows(named=True):
        print(f"  {row['coefficient']} not identified: {row['n']} x {row['reason']}")
    print(f"model written to {out}; per-bin estimates in {params}", file=sys.stderr)
    if ident.height == 0 or float(ident["identified"].max() or 0.0) == 0.0:
        print(
            "aerodelta fit: error: no parameter is identified in any alpha bin; the model "
            "holds no Δ (see the notes above and the per-bin table)",
            file=sys.stderr,
        )
        return 1
    return 0
