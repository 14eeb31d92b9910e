"""Fit the Kirchhoff flow-separation stall of lift and pitching moment by output error, per flap
(docs/longitudinal.md): time constants tau1, tau2, breakpoint alpha*, steepness a1, the attached
lift and pitch lines and the pitch break C_mx, with Cramér-Rao bounds and the bounds corrected
for coloured residuals, the static C_L,max and its alpha; then the drag along the identified
separation state (CD0, CD_k, CD_x by least squares, cluster-robust errors with the state's
uncertainty carried; --no-cd skips it).

Prints one row per flap and parameter (or JSON with --format json); --out FILE also writes
that table as CSV. The built-in aircraft's qualified control, rate and thrust terms are taken
off the measured coefficients (--known adx37, the default); --known none fits them as measured.
A flap whose records show no separation lag (static aerodynamics) is reported with tau1, tau2
held at the engine's lower bounds and a "not identified" note after the table.

--model M.json --out-model OUT.json writes a copy of the Δ model M carrying the fitted stall
(every flap, with its note), so a simulator that loads OUT flies the identified lift and pitch
break; M itself is not touched.

--form goman-khrabrov fits the static separation curve x0(alpha) as a table (a cubic B-spline
on knots every --knot-spacing deg) instead of the tanh, started from the tanh fit with its lift
line held: for records whose lift curve the tanh cannot follow (a plateau, a second rise). It
prints the scalar parameters, one row per table coefficient (alpha of its knot) and the drag
along the table's state. With --out-model the model file stores the table (knots and
coefficients per flap), which the replays, the exports and the evidence pack fly.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from aerodelta._fsutil import write_atomic
from aerodelta.cli._data import (
    add_data_arguments,
    check_outputs,
    load_model,
    load_records,
    output_file,
    resolve_data,
)
from aerodelta.exceptions import InvalidInputError

if TYPE_CHECKING:
    import polars as pl

    from aerodelta.model import DeltaModel

HELP = "Kirchhoff stall of C_L, C_m (output error) and C_D (tau1, tau2, alpha*, C_L,max)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta longitudinal``."""
    add_data_arguments(parser)
    parser.add_argument("--flaps", metavar="F,...", help="flap settings to fit, deg (default all)")
    parser.add_argument("--no-cm", action="store_true", help="fit C_L only")
    parser.add_argument("--no-cd", action="store_true", help="do not fit the drag")
    parser.add_argument("--known", choices=("adx37", "none"), default="adx37")
    parser.add_argument(
        "--max-iter",
        type=int,
        default=None,
        metavar="N",
        help="iteration bound (default 60; 100 with --form goman-khrabrov)",
    )
    parser.add_argument(
        "--form",
        choices=("kirchhoff", "goman-khrabrov"),
        default="kirchhoff",
        help="static separation curve: Fischenberg's tanh (default) or a table (Goman-Khrabrov)",
    )
    parser.add_argument(
        "--knot-spacing",
        type=float,
        default=None,
        metavar="DEG",
        help="spacing of the table's knots with --form goman-khrabrov, deg (default 1)",
    )
    parser.add_argument("--out", metavar="FILE", help="write the parameter table as CSV")
    parser.add_argument(
        "--model", metavar="FILE", help="Δ model to carry the stall (with --out-model)"
    )
    parser.add_argument(
        "--out-model", metavar="FILE", help="write the --model copy with the stall here"
    )
    parser.add_argument("--format", choices=("table", "json"), default="table")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def _flaps(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        return [float(f) for f in text.split(",")]
    except ValueError:
        raise InvalidInputError(f"--flaps {text}: give flap settings in deg, e.g. 0,15") from None


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta longitudinal``; returns the exit status."""
    from aerodelta.fit import model_frame  # noqa: PLC0415  (CLI start-up light)
    from aerodelta.longitudinal import fit_kirchhoff  # noqa: PLC0415

    if args.max_iter is not None and args.max_iter < 1:
        raise InvalidInputError(f"--max-iter {args.max_iter}: give at least 1")
    flaps = _flaps(args.flaps)
    out = output_file(args.out, "--out", "kirchhoff.csv") if args.out else None
    if (args.model is None) != (args.out_model is None):
        raise InvalidInputError(
            "--model and --out-model go together: the Δ model to copy and where to write the "
            "copy carrying the stall"
        )
    if args.out_model is not None and args.no_cm:
        raise InvalidInputError(
            "--out-model with --no-cm: a simulator flies both curves; fit C_m too"
        )
    gk = args.form == "goman-khrabrov"
    if not gk and args.knot_spacing is not None:
        raise InvalidInputError(
            "--knot-spacing applies to --form goman-khrabrov (the table's knots); the tanh form "
            "has none"
        )
    if gk and args.no_cm:
        raise InvalidInputError("--no-cm with --form goman-khrabrov: the table is fitted with C_m")
    out_model = output_file(args.out_model, "--out-model") if args.out_model else None
    base_model = load_model(args.model) if args.model is not None else None
    src = resolve_data(args)
    if out is not None:
        check_outputs(src, "--out", files=[out])
    if out_model is not None:
        check_outputs(src, "--out-model", files=[out_model], inputs=[Path(args.model)])
    data = model_frame(load_records(src, progress=not args.no_progress))
    if gk:
        return _run_goman_khrabrov(args, data, flaps, out, base_model, out_model)
    res = fit_kirchhoff(
        data,
        flaps=flaps,
        fit_cm=not args.no_cm,
        fit_cd=not args.no_cd,
        known=args.known,
        max_iter=60 if args.max_iter is None else args.max_iter,
    )
    table = res.summary()
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(out, table.write_csv)
    if out_model is not None and base_model is not None:
        out_model.parent.mkdir(parents=True, exist_ok=True)
        base_model.with_longitudinal(res).save(out_model)
    if args.format == "json":
        print(json.dumps(table.to_dicts(), indent=2, allow_nan=True))
        for flap, note in res.notes.items():  # stdout stays the JSON table
            print(f"flap {flap:g}: {note}", file=sys.stderr)
    else:
        print(
            f"{'flap':>4} {'parameter':<17} {'unit':<6} {'estimate':>10} {'CR bound':>10} "
            f"{'coloured':>10} {'clustered':>10} {'total':>10}"
        )

        def num(v: float) -> str:
            return "-" if math.isnan(v) else f"{v:.4g}"

        for r in table.iter_rows(named=True):
            if not math.isfinite(r["estimate"]):
                continue
            print(
                f"{r['flap_deg']:>4g} {r['parameter']:<17} {r['unit']:<6} "
                f"{r['estimate']:>10.4g} {num(r['std_err']):>10} "
                f"{num(r['std_err_colored']):>10} {num(r['std_err_cluster']):>10} "
                f"{num(r['std_err_total']):>10}"
            )
        for flap, note in res.notes.items():
            print(f"flap {flap:g}: {note}")
        if any(ff.drag is not None for ff in res.fits.values()):
            print(
                "drag (CD0, CD_k, CD_x): least squares along the identified separation state; "
                "CR bound = conventional, clustered = CR2 over maneuvers given the state, total "
                "= CR2 with the state's uncertainty (delta method)"
            )
        if out is not None:
            print(f"wrote {out}")
        if out_model is not None:
            print(f"wrote {out_model} (the Δ model with the stall of {len(res.fits)} flap(s))")
    sys.stdout.flush()
    return 0


def _run_goman_khrabrov(  # noqa: PLR0917  (the tanh path's arguments, passed on)
    args: argparse.Namespace,
    data: pl.DataFrame,
    flaps: list[float] | None,
    out: Path | None,
    base_model: DeltaModel | None,
    out_model: Path | None,
) -> int:
    """``--form goman-khrabrov``: the table's fit, printed as the tanh form's is, and stored
    with the Δ model when asked."""
    from aerodelta.goman_khrabrov import fit_goman_khrabrov  # noqa: PLC0415

    res = fit_goman_khrabrov(
        data, flaps=flaps, known=args.known,
        knot_spacing_deg=1.0 if args.knot_spacing is None else args.knot_spacing,
        max_iter=100 if args.max_iter is None else args.max_iter, fit_cd=not args.no_cd,
    )  # fmt: skip
    table = res.summary()
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(out, table.write_csv)
    if out_model is not None and base_model is not None:
        out_model.parent.mkdir(parents=True, exist_ok=True)
        base_model.with_longitudinal(res).save(out_model)
    if args.format == "json":
        print(json.dumps(table.to_dicts(), indent=2, allow_nan=True))
        for flap, note in res.notes.items():
            print(f"flap {flap:g}: {note}", file=sys.stderr)
        return 0

    def num(v: float) -> str:
        return "-" if math.isnan(v) else f"{v:.4g}"

    print(
        f"{'flap':>4} {'parameter':<17} {'unit':<6} {'alpha':>6} {'estimate':>10} "
        f"{'CR bound':>10} {'coloured':>10} {'start':>10}"
    )
    for r in table.iter_rows(named=True):
        print(
            f"{r['flap_deg']:>4g} {r['parameter']:<17} {r['unit']:<6} {num(r['alpha_deg']):>6} "
            f"{r['estimate']:>10.4g} {num(r['std_err']):>10} {num(r['std_err_colored']):>10} "
            f"{num(r['start']):>10}"
        )
    for flap, note in res.notes.items():
        print(f"flap {flap:g}: {note}")
    print(
        "x0[k]: the table's cubic B-spline coefficients (knot alpha in deg); '-' bounds: held "
        "(the lift line, too few samples, or at the bound 0 or 1); start: the start (on "
        "alpha_cl_max_deg, cl_max and cost: the tanh fit's); CD0, CD_k, CD_x: the drag along "
        "the table's state, CR bound = CR2 with the state's uncertainty (the held lift line's "
        "left out)"
    )
    if out is not None:
        print(f"wrote {out}")
    if out_model is not None:
        print(
            f"wrote {out_model} (the Δ model with the tabulated stall of {len(res.fits)} flap(s))"
        )
    sys.stdout.flush()
    return 0
