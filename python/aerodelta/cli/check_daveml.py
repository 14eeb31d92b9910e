"""Run the static check cases of a DAVE-ML file and report each one.

For every shot and checked output: expected and actual value, tolerance and
pass/fail; internal values (``internalValues``) are counted and listed when they
fail (all of them with ``--internal``). Ends with "N checks, N passed, N failed",
then the variables and tables that carry an ``uncertainty`` (checked when the file
is read: absolute bounds bracket their nominal values, table bounds have its shape).
Exit status 1 when any check fails or the file is malformed (one error line
naming the element and line).
"""

from __future__ import annotations

import argparse
import json
import sys

from aerodelta.daveml import load_daveml

HELP = "run a DAVE-ML file's check cases (expected vs actual per shot and output)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", help="DAVE-ML model (.dml/.xml)")
    parser.add_argument(
        "--format", choices=["table", "json"], default="table", help="output format (default table)"
    )
    parser.add_argument(
        "--internal", action="store_true", help="also list every internal value checked"
    )


def _fmt(x: float) -> str:
    return f"{x:.10g}"


def run(args: argparse.Namespace) -> int:
    model = load_daveml(args.file)
    checks = model.run_checks()
    n = checks.height
    n_fail = int((~checks["pass"]).sum()) if n else 0
    n_out = int((checks["kind"] == "output").sum()) if n else 0
    unc = model.uncertainty()
    summary = {
        "checks": n,
        "passed": n - n_fail,
        "failed": n_fail,
        "outputs": n_out,
        "internal": n - n_out,
        "shots": model.n_shots,
    }
    if args.format == "json":
        rows = checks.to_dicts()
        for r in rows:
            r["error"] = r["actual"] - r["expected"]
        print(
            json.dumps(
                {
                    "file": str(args.file),
                    "model": model.name,
                    "checks": rows,
                    "uncertainty": unc.drop("bounds").to_dicts(),
                    "summary": summary,
                },
                indent=1,
            )
        )
    else:
        shown = (
            checks
            if args.internal
            else checks.filter((checks["kind"] == "output") | ~checks["pass"])
        )
        print(f"{args.file}: model '{model.name}', {model.n_shots} check cases")
        if shown.height:
            w_shot = max(4, *(len(s) for s in shown["shot"]))
            w_var = max(8, *(len(s) for s in shown["variable"]))
            head = (
                f"{'shot':<{w_shot}}  {'variable':<{w_var}}  {'kind':<8}  {'expected':>17}  "
                f"{'actual':>17}  {'|error|':>9}  {'tolerance':>9}  result"
            )
            print(head)
            print("-" * len(head))
            for r in shown.iter_rows(named=True):
                err = abs(r["actual"] - r["expected"])
                print(
                    f"{r['shot']:<{w_shot}}  {r['variable']:<{w_var}}  {r['kind']:<8}  "
                    f"{_fmt(r['expected']):>17}  {_fmt(r['actual']):>17}  {err:9.2e}  "
                    f"{r['tolerance']:9.2e}  {'pass' if r['pass'] else 'FAIL'}"
                )
        print(
            f"{n} checks, {n - n_fail} passed, {n_fail} failed "
            f"({n_out} outputs, {n - n_out} internal values)"
        )
        if unc.height:
            kinds = unc.group_by("effect", "distribution", maintain_order=True).len()
            what = ", ".join(
                f"{r['len']} {r['effect']} {r['distribution']}" for r in kinds.iter_rows(named=True)
            )
            print(
                f"uncertainty: {unc.height} variables or tables ({what}), each consistent with "
                "its nominal value"
            )
    if n == 0:
        print(f"note: {args.file} has no checkData static shots; nothing verified", file=sys.stderr)
    return 1 if n_fail else 0
