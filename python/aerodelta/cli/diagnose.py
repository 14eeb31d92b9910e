"""Diagnose the gap between a simulator and flight test records (issue 7, DESIGN.md): where it
lies (alpha, flap, flight phase), which unmodelled effect of the vocabulary causes it (scored on
maneuvers held out of each fit), and how far it shrinks once the effect is added.

Writes OUT/diagnosis.json (schema aerodelta.diagnosis/1), OUT/diagnosis.txt (the report printed
here), gap_map.csv, effects.csv, shrink.csv and predictions.parquet."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from aerodelta.cli._data import (
    add_data_arguments,
    check_at_least,
    check_open_unit,
    check_share,
    existing_file,
    load_data,
    output_folder,
)
from aerodelta.diagnosis import DiagnoseConfig, SelectionConfig, diagnose, write_outputs
from aerodelta.diagnosis.vocabulary import default_vocabulary
from aerodelta.exceptions import DataError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

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
        "*_sim columns, else the built-in ADX-37 qualified model",
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
        default=defaults.min_shrink_broad,
        help="smaller share accepted for a broad effect (signed-rank test at alpha/10)",
    )
    parser.add_argument("--per-flap", action="store_true", help="one alpha curve per flap")
    parser.add_argument("--seed", type=int, default=0, help="seed of folds and tests")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def _effects(path: str) -> dict:
    p = Path(path)
    if not p.is_file():
        raise DataError(f"--effects {p}: file not found")
    try:
        with p.open("rb") as fh:
            return tomllib.load(fh)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise DataError(f"--effects {p}: not valid TOML: {e}") from e


def _check_options(args: argparse.Namespace) -> None:
    check_at_least(args.folds, "--folds", 2, "cross-validation holds out one fold of maneuvers")
    check_at_least(args.seed, "--seed", 0)
    check_open_unit(args.alpha, "--alpha", "0.01")
    check_share(args.min_shrink, "--min-shrink", "0.02")
    check_share(args.min_shrink_broad, "--min-shrink-broad", "0.015")
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
    vocab = default_vocabulary()
    if args.effects:
        vocab = vocab.with_user_effects(_effects(args.effects))
    cfg = DiagnoseConfig(
        folds=args.folds,
        selection=SelectionConfig(
            alpha=args.alpha,
            min_shrink=args.min_shrink,
            min_shrink_broad=min(args.min_shrink_broad, args.min_shrink),
            seed=args.seed,
        ),
        per_flap=args.per_flap,
        seed=args.seed,
    )
    progress = not args.no_progress
    for value, option in ((args.data or args.data_option, "DATA"), (args.aircraft, "--aircraft")):
        if value:
            _guard_truth(Path(value), option)
    data, src = load_data(args, progress=progress, aircraft_with_ingested=True)
    d = diagnose(
        data,
        args.model,
        vocabulary=vocab,
        config=cfg,
        aircraft=src.aircraft,
        progress=progress,
    )
    paths = write_outputs(d.result, d.predictions, out)
    print(d.summary())
    print(f"wrote {', '.join(str(p) for p in paths)}")
    return 0
