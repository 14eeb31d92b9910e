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
    check_outputs,
    created,
    existing_file,
    jsbsim_campaign_option,
    load_records,
    output_file,
    qualified_choice,
    resolve_data,
)
from aerodelta.exceptions import DataError, InvalidInputError
from aerodelta.model import with_params_hash

HELP = "identify the Δ (stall) model from flight test data"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta fit``."""
    add_data_arguments(parser)
    parser.add_argument(
        "--model",
        default="auto",
        type=qualified_choice,
        metavar="auto|columns|adx37|jsbsim:DIR|FILE.dml",
        help="qualified model (your simulator): the records' Cl_sim, Cn_sim, CY_sim columns, "
        "a DAVE-ML file, the qualified JSBSim aircraft of a JSBSim campaign folder (jsbsim:DIR, "
        "evaluated at the recorded states), or the built-in ADX-37 (only meaningful for the "
        "virtual campaign); auto: the columns, else the built-in model for data flown on it, "
        "else refused",
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
        metavar="N",
        help="seed of the --holdout draw (default 0)",
    )
    parser.add_argument(
        "--range",
        type=float,
        default=5.0,
        metavar="DEG",
        dest="range_deg",
        help="alpha range of the printed tables, deg: each row aggregates the bins of one "
        "range (default 5)",
    )
    parser.add_argument(
        "--verbose",
        "-v",
        action="store_true",
        help="print one table section per alpha bin (every bin's estimates) instead of ranges",
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
    if not (np.isfinite(args.range_deg) and args.range_deg > 0):
        raise InvalidInputError(
            f"--range {args.range_deg:g}: give an alpha range in deg > 0 (e.g. --range 5), or "
            "--verbose for one table section per bin"
        )
    if args.holdout is None and args.holdout_seed is not None:
        raise InvalidInputError(
            f"--holdout-seed {args.holdout_seed}: seeds the --holdout draw; give --holdout F "
            "too, or drop it"
        )
    if args.holdout is not None:
        check_open_unit(args.holdout, "--holdout", "0.2")
        args.holdout_seed = 0 if args.holdout_seed is None else args.holdout_seed
        check_at_least(args.holdout_seed, "--holdout-seed", 0)
    config = existing_file(args.config, "--config")
    dml = (
        existing_file(args.model, "--model")
        if args.model.lower().endswith((".dml", ".xml"))
        else None
    )
    jsbsim_campaign_option(args.model, "--model")
    src = resolve_data(args)
    outs = [out, out.with_suffix(".params.parquet")]
    if args.holdout is not None:
        outs += [out.with_suffix(".holdout.txt"), out.with_suffix(".validation.csv")]
    check_outputs(src, "--out", files=outs, inputs=[config, dml])
    cfg = FitConfig.from_toml(config) if config else FitConfig()
    progress = not args.no_progress
    data = load_records(src, progress=progress)
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
    # the results report (FitResult.summary_text): header (with the qualified model the fit
    # recorded), identified share per coefficient with the reasons for the rest, per
    # coefficient and flap the parameter tables, the notes
    print(result.summary_text(None if args.verbose else args.range_deg))
    if result.params.is_empty() or not result.params["identifiable"].any():
        print(
            "aerodelta fit: error: no parameter is identified in any alpha bin, so no model is "
            "written (the reasons are listed above; fly more maneuvers per flap or see "
            "docs/identification.md)",
            file=sys.stderr,
        )
        return 1
    v = validate_model(result.model, test, qualified=args.model) if test is not None else None
    with created(out.parent):
        # the params table first, the model file last, recording the table's hash: a kill
        # between the two renames leaves a table the model does not name, which the report
        # refuses
        params = out.with_suffix(".params.parquet")
        write_atomic(params, result.summary().write_parquet)
        with_params_hash(result.model, params).save(out)
    written = [out, params]
    if v is not None:
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
