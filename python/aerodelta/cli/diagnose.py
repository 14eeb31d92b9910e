"""Diagnose the gap between a simulator and flight test records (issue 7, DESIGN.md): where it
lies (alpha, flap, flight phase), which unmodelled effect of the vocabulary causes it (scored on
maneuvers held out of each fit), and how far it shrinks once the effect is added.

Writes OUT/diagnosis.json (schema aerodelta.diagnosis/1), OUT/diagnosis.txt (the report printed
here), gap_map.csv, effects.csv, shrink.csv and predictions.parquet."""

from __future__ import annotations

import argparse
import sys

from aerodelta.diagnosis import DiagnoseConfig, SelectionConfig, diagnose, write_outputs
from aerodelta.diagnosis.vocabulary import default_vocabulary

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

HELP = "diagnose the sim-to-real gap: where, which effect, how far it shrinks"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta diagnose``."""
    parser.add_argument(
        "--data", required=True, help="campaign folder or ingest output (data.parquet)"
    )
    parser.add_argument(
        "--model",
        help="the simulator: DAVE-ML (.dml) or aerodelta model (.json); default: the records' "
        "*_sim columns, else the built-in ADX-37 qualified model",
    )
    parser.add_argument("--aircraft", help="aircraft reference TOML (default DIR/aircraft.toml)")
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


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta diagnose``."""
    vocab = default_vocabulary()
    if args.effects:
        with open(args.effects, "rb") as fh:
            vocab = vocab.with_user_effects(tomllib.load(fh))
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
    d = diagnose(
        args.data,
        args.model,
        vocabulary=vocab,
        config=cfg,
        aircraft=args.aircraft,
        progress=not args.no_progress,
    )
    paths = write_outputs(d.result, d.predictions, args.out)
    print(d.summary())
    print(f"wrote {', '.join(str(p) for p in paths)}")
    return 0
