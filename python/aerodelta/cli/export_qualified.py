"""Write the built-in ADX-37 qualified aerodynamic model as a DAVE-ML file with its own check
cases (the simulator model of the virtual flight test, before any stall correction)."""

from __future__ import annotations

import argparse
import sys

from aerodelta.cli._data import created, output_file
from aerodelta.export import export_qualified_daveml

HELP = "write the built-in qualified model (ADX-37) as DAVE-ML"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta export-qualified``."""
    parser.add_argument("out", help="DAVE-ML file to write (.dml)")


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta export-qualified``."""
    out = output_file(args.out, "OUT", "adx37.dml")
    with created(out.parent):
        m = export_qualified_daveml(out)
    print(f"wrote {args.out}: inputs {', '.join(m.inputs)}; outputs {', '.join(m.outputs)}")
    print("verify with: aerodelta check-daveml " + str(args.out), file=sys.stderr)
    return 0
