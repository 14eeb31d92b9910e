"""Plan a flight test before flying it: fly N seeded virtual campaigns of a test matrix (TOML),
fit (and optionally diagnose) each on a Dask cluster, and report per parameter and alpha range
the predicted standard error, band width and probability of being identified, per effect the
probability the diagnosis names it, and a recommendation. With --compare, two matrices side
by side; with --rolloff N, the roll-off Monte Carlo of N stalls on the same engine.

Writes into OUT: summary.json, params.csv, effects.csv, coverage.csv, recommendation.txt,
band.png, run.json and tasks/ (one file per finished seed: a rerun resumes). See docs/plan.md.
Results go to stdout, progress to stderr.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from aerodelta.cli._data import check_at_least, existing_file, output_folder
from aerodelta.exceptions import InvalidInputError

HELP = "plan a flight test: Monte Carlo of virtual campaigns of a test matrix (Dask)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta plan``."""
    parser.add_argument("matrix", nargs="?", help="test matrix (TOML; docs/plan.md)")
    parser.add_argument("--compare", metavar="OTHER", help="a second test matrix, side by side")
    parser.add_argument("--campaigns", type=int, default=20, help="campaigns per matrix")
    parser.add_argument("--seed", type=int, default=1, help="first seed (seeds SEED..SEED+N-1)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers", type=int, default=2, help="local Dask worker processes (one thread each)"
    )
    where.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler, tcp://host:8786")
    parser.add_argument("--out", required=True, help="output folder (a rerun resumes)")
    parser.add_argument(
        "--rolloff",
        type=int,
        metavar="STALLS",
        help="run the roll-off Monte Carlo of STALLS straight stalls instead of a matrix",
    )
    parser.add_argument("--flap", type=float, default=0.0, help="--rolloff: flap setting, deg")
    parser.add_argument("--chunk", type=int, default=5000, help="--rolloff: stalls per task")
    parser.add_argument(
        "--format", choices=("table", "json"), default="table", help="stdout format"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def _rolloff(args: argparse.Namespace) -> int:
    from aerodelta.plan.rolloff import run_rolloff_study  # noqa: PLC0415

    check_at_least(args.rolloff, "--rolloff", 1)
    check_at_least(args.chunk, "--chunk", 1)
    r = run_rolloff_study(
        args.rolloff,
        seed=args.seed,
        out=output_folder(args.out),
        flap_deg=args.flap,
        chunk=args.chunk,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=not args.no_progress,
    )
    if args.format == "json":
        print(json.dumps(r.summary, indent=1, sort_keys=True))
    else:
        s = r.summary
        print(
            f"roll-off Monte Carlo: {s['stalls']} stalls at flap {args.flap:g} (seed {args.seed})"
        )
        if s["stalls"]:
            print(f"  FAR 25.203 (max bank <= 20 deg) passed: {s['far25_203_pass']:.1%}")
            print(f"  roll-off met: {s['rolloff_met']:.1%}, to the right: {s['right_share']:.1%}")
            print(
                f"  max bank p50/p95/p99: {s['max_bank_deg_p50']:.1f} / "
                f"{s['max_bank_deg_p95']:.1f} / {s['max_bank_deg_p99']:.1f} deg"
            )
        for f in r.failures:
            print(f"  chunk from stall {f['first']} failed: {f['error']}")
        print(f"wrote {r.path / 'summary.json'} ({len(r.ran)} chunks run now)")
    return 1 if r.failures else 0


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta plan``; 1 when a task failed (reported with its seed)."""
    from aerodelta.plan.study import compare_plans, run_plan  # noqa: PLC0415

    if args.scheduler is None:
        check_at_least(args.workers, "--workers", 1)
    if args.rolloff is not None:
        if args.matrix or args.compare:
            raise InvalidInputError("--rolloff runs the Monte Carlo alone; drop the matrix")
        return _rolloff(args)
    if not args.matrix:
        raise InvalidInputError("give a test matrix (MATRIX.toml) or --rolloff STALLS")
    check_at_least(args.campaigns, "--campaigns", 1)
    check_at_least(args.seed, "--seed", 0)
    matrix = existing_file(args.matrix, "MATRIX") or Path(args.matrix)
    out = output_folder(args.out)
    common = {
        "campaigns": args.campaigns,
        "seed": args.seed,
        "out": out,
        "workers": args.workers,
        "scheduler": args.scheduler,
        "progress": not args.no_progress,
    }
    if args.compare:
        other = existing_file(args.compare, "--compare") or Path(args.compare)
        a, b, table = compare_plans(matrix, other, **common)
        results = [a, b]
    else:
        results = [run_plan(matrix, **common)]
        table = None
    if args.format == "json":
        doc = {r.matrix.name: json.loads((r.path / "summary.json").read_text()) for r in results}
        print(json.dumps(doc, indent=1, sort_keys=True))
    else:
        for r in results:
            print(r.recommendation, end="")
            print(f"wrote {r.path} (seeds run now: {len(r.ran)}, resumed: "
                  f"{len(r.seeds) - len(r.ran) - len(r.failures)})")  # fmt: skip
        if table is not None:
            print(
                f"side by side: {Path(out) / 'compare.csv'} ({table.height} rows), "
                f"{Path(out) / 'compare.png'}"
            )
    return 1 if any(r.failures for r in results) else 0
