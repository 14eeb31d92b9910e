"""Diagnose the gap between a simulator and flight test records (issue 7, DESIGN.md): where it
lies (alpha, flap, flight phase), which unmodelled effect of the vocabulary causes it (scored on
maneuvers held out of each fit), and how far it shrinks once the effect is added.

Writes OUT/diagnosis.json (schema aerodelta.diagnosis/1), OUT/diagnosis.txt (the report printed
here), gap_map.csv, effects.csv, shrink.csv and predictions.parquet."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import polars as pl

from aerodelta._exportutil import shown
from aerodelta._toml import read_toml
from aerodelta.cli._data import (
    add_data_arguments,
    check_at_least,
    check_open_unit,
    check_outputs,
    check_share,
    created,
    existing_file,
    load_model,
    load_records,
    output_folder,
    resolve_data,
)
from aerodelta.diagnosis import DiagnoseConfig, SelectionConfig, diagnose, write_outputs
from aerodelta.diagnosis.vocabulary import default_vocabulary
from aerodelta.exceptions import DataError
from aerodelta.fit import COEFFICIENTS, model_frame

#: Columns the diagnosis adds to the ingested records (zero when absent), which a user
#: effect may read besides those of ``aerodelta.fit.model_frame``.
_ADDED = (
    "kind", "da_deg", "dr_deg", "ds_deg", "ct_left", "ct_right", "alphadot_dps", "betadot_dps",
    "pdot_dps2", "rdot_dps2", "qbar_pa", "ct_diff",
)  # fmt: skip

HELP = "diagnose the sim-to-real gap: where, which effect, how far it shrinks"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta diagnose``."""
    add_data_arguments(
        parser,
        aircraft_help="aircraft reference TOML (default DATA/aircraft.toml, else the built-in "
        "ADX-37); also used with an ingest output",
    )
    parser.add_argument(
        "--model",
        help="the simulator: DAVE-ML (.dml) or aerodelta model (.json); default: the records' "
        "*_sim columns, else the built-in ADX-37 qualified model for data flown on the virtual "
        "aircraft, else refused",
    )
    parser.add_argument(
        "--effects",
        help="TOML of user-defined candidate effects: [name] Cl = ['beta_deg * rhat'], ...",
    )
    parser.add_argument("--folds", type=int, default=5, help="cross-validation folds (maneuvers)")
    defaults = SelectionConfig()
    parser.add_argument("--alpha", type=float, default=defaults.alpha, help="familywise test level")
    parser.add_argument(
        "--min-shrink",
        type=float,
        default=defaults.min_shrink,
        help="smallest share of the held-out gap's squared error an effect must remove",
    )
    parser.add_argument(
        "--min-shrink-broad",
        type=float,
        help="smaller share accepted for a broad effect (signed-rank test at alpha/10; "
        f"default {defaults.min_shrink_broad:g}, at most --min-shrink)",
    )
    flap_curves = parser.add_mutually_exclusive_group()
    flap_curves.add_argument(
        "--per-flap",
        dest="per_flap",
        action="store_const",
        const=True,
        help="always one alpha curve per flap (default: one curve for all flaps, split per "
        "flap where the data show the flaps differ)",
    )
    flap_curves.add_argument(
        "--shared-flaps",
        dest="per_flap",
        action="store_const",
        const=False,
        help="always one alpha curve for all flaps",
    )
    parser.add_argument(
        "--no-nested",
        action="store_true",
        help="skip the outer-fold evaluation (the selection redone without each fold and "
        "scored on it; about a fifth of the run time)",
    )
    parser.add_argument(
        "--no-band-match",
        action="store_true",
        help="compare the simulator's output at its full band (default: low-passed per "
        "maneuver to the band of the measured coefficients, as ingest smoothed them)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of folds and tests")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def _effects(path: str) -> dict[str, dict[str, list[str]]]:
    """The user effects of ``--effects FILE``, checked: ``[name]`` tables of ``coefficient =
    ['expression', ...]`` (polars SQL expressions over the records' columns)."""
    p = existing_file(path, "--effects")
    assert p is not None
    doc, _ = read_toml(p, "effects file")
    if not doc:
        raise DataError(f"--effects {p}: defines no effect; write [name] Cl = ['expression']")
    for name, per in doc.items():
        if not isinstance(per, dict) or not per:
            raise DataError(
                f"{p}: effect '{name}': give a table [{name}] of coefficient = ['expression', ...]"
            )
        for coef, exprs in per.items():
            where = f"{p}: effect '{name}', {coef}"
            if coef not in COEFFICIENTS:
                raise DataError(
                    f"{p}: effect '{name}': unknown coefficient '{coef}'; use "
                    f"{', '.join(COEFFICIENTS)}"
                )
            if (
                not isinstance(exprs, list)
                or not exprs
                or not all(isinstance(e, str) and e.strip() for e in exprs)
            ):
                raise DataError(f"{where} = {exprs!r}: give a list of expression strings")
            for e in exprs:
                try:
                    pl.sql_expr(e)
                except Exception as err:  # polars raises several kinds for a bad expression
                    raise DataError(
                        f"{where}: '{shown(e)}' is not an expression polars reads "
                        f"({_first_line(err)[:200]})"
                    ) from None
    return doc


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def _check_effect_columns(
    effects: dict[str, dict[str, list[str]]], path: str, data: pl.DataFrame
) -> None:
    """Refuse a user effect that reads a column the records do not have."""
    names = {*model_frame(data.head(0)).columns, *_ADDED}
    empty = pl.DataFrame(schema={n: pl.Float64 for n in names})
    for name, per in effects.items():
        for coef, exprs in per.items():
            for e in exprs:
                try:
                    empty.select(pl.sql_expr(e))
                except pl.exceptions.ColumnNotFoundError as err:
                    m = re.search(r'"([^"]+)"', str(err))
                    col = m.group(1) if m else _first_line(err)[:80]
                    raise DataError(
                        f"{path}: effect '{name}', {coef}: '{shown(e)}' reads '{col}', which "
                        "is not a column of the ingested records (docs/data.md)"
                    ) from None
                except Exception as err:
                    raise DataError(
                        f"{path}: effect '{name}', {coef}: '{shown(e)}' cannot be evaluated on "
                        f"the records ({_first_line(err)[:200]})"
                    ) from None


def _check_options(args: argparse.Namespace) -> None:
    check_at_least(args.folds, "--folds", 2, "cross-validation holds out one fold of maneuvers")
    check_at_least(args.seed, "--seed", 0)
    check_open_unit(args.alpha, "--alpha", "0.01")
    check_share(args.min_shrink, "--min-shrink", "0.02")
    if args.min_shrink_broad is not None:
        check_share(args.min_shrink_broad, "--min-shrink-broad", "0.015")
        if args.min_shrink_broad > args.min_shrink:
            raise DataError(
                f"--min-shrink-broad {args.min_shrink_broad:g}: the share a broad effect needs "
                f"is at most --min-shrink ({args.min_shrink:g}); give a smaller value"
            )
    existing_file(args.model, "--model")


def _guard_truth(path: Path, option: str) -> None:
    if "truth" in path.resolve().parts:
        raise DataError(
            f"{option} {path}: the diagnosis never reads a campaign's truth files; give the "
            "campaign folder or the ingest output"
        )


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta diagnose``."""
    _check_options(args)
    out = output_folder(args.out)
    broad = args.min_shrink_broad
    if broad is None:  # the default, lowered to a smaller --min-shrink
        broad = min(SelectionConfig().min_shrink_broad, args.min_shrink)
    cfg = DiagnoseConfig(
        folds=args.folds,
        selection=SelectionConfig(
            alpha=args.alpha, min_shrink=args.min_shrink, min_shrink_broad=broad, seed=args.seed
        ),
        per_flap=args.per_flap,
        seed=args.seed,
        nested=not args.no_nested,
        band_match=not args.no_band_match,
    )
    progress = not args.no_progress
    for value, option in ((args.data or args.data_option, "DATA"), (args.aircraft, "--aircraft")):
        if value:
            _guard_truth(Path(value), option)
    src = resolve_data(args, aircraft_with_ingested=True)
    model = existing_file(args.model, "--model")
    effects_file = existing_file(args.effects, "--effects")
    check_outputs(src, "--out", folder=out, inputs=[model, effects_file])
    effects = _effects(args.effects) if args.effects else None
    if model is not None and model.suffix.lower() == ".json":
        load_model(model)  # refused here in the command's words, before the data are read
    data = load_records(src, progress=progress)
    vocab = default_vocabulary()
    if effects is not None:
        _check_effect_columns(effects, args.effects, data)
        vocab = vocab.with_user_effects(effects)
    d = diagnose(
        data,
        args.model,
        vocabulary=vocab,
        config=cfg,
        aircraft=src.aircraft,
        progress=progress,
    )
    with created(out):
        paths = write_outputs(d.result, d.predictions, out)
    print(d.summary())
    print(f"wrote {', '.join(str(p) for p in paths)}")
    return 0
