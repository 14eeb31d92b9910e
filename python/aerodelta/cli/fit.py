"""Identify the Δ model from flight test records (thesis Sections 3.3-3.6) and write it.

Reads DATA (a campaign folder in the user's layout with --map/--aircraft/--manifest, or the
output folder of aerodelta ingest), fits the Δ model per flap and coefficient, and writes the
model (JSON, schema aerodelta.model/1) plus the per-bin estimates (Parquet) beside it.

With --holdout F the fraction F of the maneuvers of each flap setting (drawn with
--holdout-seed) is left out of the fit; the model is then validated on them (as
aerodelta validate), the ids written to MODEL.holdout.txt and the table to
MODEL.validation.csv."""

from __future__ import annotations

import argparse
import sys

import numpy as np
import polars as pl

from aerodelta._fsutil import write_atomic, write_text_atomic
from aerodelta.cli._data import (
    add_data_arguments,
    check_at_least,
    check_open_unit,
    load_data,
    output_file,
)
from aerodelta.exceptions import DataError

HELP = "identify the Δ (stall) model from flight test data"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta fit``."""
    add_data_arguments(parser)
    parser.add_argument(
        "--model",
        default="auto",
        choices=["auto", "columns", "adx37"],
        help="qualified model: the records' *_sim columns, or the built-in ADX-37 model",
    )
    parser.add_argument("--config", help="fit settings (TOML, see aerodelta.FitConfig)")
    parser.add_argument("--out", required=True, help="model file to write (.json)")
    parser.add_argument(
        "--holdout",
        type=float,
        metavar="F",
        help="leave the fraction F (0 < F < 1) of each flap's maneuvers out of the fit and "
        "validate the model on them (e.g. 0.2)",
    )
    parser.add_argument(
        "--holdout-seed",
        type=int,
        default=0,
        metavar="N",
        help="seed of the --holdout draw (default 0)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def holdout_split(data: pl.DataFrame, fraction: float, seed: int = 0) -> list[str]:
    """The maneuvers ``aerodelta fit --holdout`` leaves out, sorted.

    Per flap setting (a maneuver's first ``flap_deg``), the ids are sorted and
    ``round(fraction * n)`` of them drawn without replacement by
    ``numpy.random.default_rng(seed)`` (flaps in ascending order, one draw each), at least one
    and at most ``n - 1``; a flap with a single maneuver keeps it in the fit.
    """
    per = (
        data.group_by("maneuver_id", maintain_order=True)
        .agg(pl.col("flap_deg").first())
        .with_columns(pl.col("maneuver_id").cast(pl.Utf8))
    )
    rng = np.random.default_rng(seed)
    held: list[str] = []
    flaps = per["flap_deg"].unique().sort(nulls_last=True).to_list()
    for flap in flaps:
        sel = per.filter(
            pl.col("flap_deg").is_null() if flap is None else pl.col("flap_deg") == flap
        )
        ids = sorted(sel["maneuver_id"].to_list())
        n = len(ids)
        if n < 2:
            continue
        k = min(max(int(np.floor(fraction * n + 0.5)), 1), n - 1)
        held.extend(ids[i] for i in rng.permutation(n)[:k])
    return sorted(held)


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta fit``."""
    from aerodelta.cli.validate import format_table  # noqa: PLC0415
    from aerodelta.fit import FitConfig, fit, validate_model  # noqa: PLC0415

    out = output_file(args.out)
    if args.holdout is not None:
        check_open_unit(args.holdout, "--holdout", "0.2")
        check_at_least(args.holdout_seed, "--holdout-seed", 0)
    cfg = FitConfig.from_toml(args.config) if args.config else FitConfig()
    progress = not args.no_progress
    data, src = load_data(args, progress=progress)
    held: list[str] = []
    test = None
    if args.holdout is not None:
        if "flap_deg" not in data.columns:
            raise DataError(f"{src.describe()}: no flap_deg column; check the manifest")
        held = holdout_split(data, args.holdout, args.holdout_seed)
        if not held:
            raise DataError(
                f"--holdout {args.holdout:g}: no flap setting has two maneuvers, nothing can "
                "be held out; fit without --holdout"
            )
        test = data.filter(pl.col("maneuver_id").cast(pl.Utf8).is_in(held))
        data = data.filter(~pl.col("maneuver_id").cast(pl.Utf8).is_in(held))
    result = fit(data, qualified=args.model, config=cfg, progress=progress)
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
    # why the rest is not identified: the first clause of each note without its numbers and
    # term names (one line per kind of reason), most frequent first
    why = (
        result.params.filter(~pl.col("identifiable"))
        .with_columns(
            pl.col("note")
            .str.split(":")
            .list.first()
            .str.replace(r"^collinear with .*", "collinear with other terms")
            .str.replace(r"^\d+ maneuvers? in the bin", "too few maneuvers in the bin")
            .alias("reason")
        )
        .group_by("coefficient", "reason")
        .agg(pl.len().alias("n"))
        .sort(["coefficient", "n"], descending=[False, True])
    )
    for row in why.iter_rows(named=True):
        print(f"  {row['coefficient']} not identified: {row['n']} x {row['reason']}")
    if ident.height == 0 or float(ident["identified"].max() or 0.0) == 0.0:
        print(
            "aerodelta fit: error: no parameter is identified in any alpha bin, so no model is "
            "written (the reasons are listed above; fly more maneuvers per flap or see "
            "docs/identification.md)",
            file=sys.stderr,
        )
        return 1
    out.parent.mkdir(parents=True, exist_ok=True)
    result.model.save(out)
    params = out.with_suffix(".params.parquet")
    write_atomic(params, result.summary().write_parquet)
    written = [out, params]
    if test is not None:
        v = validate_model(result.model, test, qualified=args.model)
        n_all = len(held) + int(data["maneuver_id"].n_unique())
        print(
            f"held out {len(held)} of {n_all} maneuvers (--holdout {args.holdout:g}, "
            f"--holdout-seed {args.holdout_seed}); validation on them:"
        )
        print(format_table(v))
        ids_file = out.with_suffix(".holdout.txt")
        header = (
            f"# maneuvers held out of the fit of {out.name} (aerodelta fit --holdout "
            f"{args.holdout:g} --holdout-seed {args.holdout_seed})\n"
        )
        write_text_atomic(ids_file, header + "".join(f"{m}\n" for m in held))
        val = out.with_suffix(".validation.csv")
        write_atomic(val, v.write_csv)
        written += [ids_file, val]
    print(f"wrote {', '.join(str(p) for p in written)}", file=sys.stderr)
    return 0
