"""The ``aerodelta`` command line: one module per subcommand, no logic the API lacks.

Known errors print one line on stderr and exit 1; ``--debug`` shows the traceback.
Results go to stdout, progress to stderr.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from aerodelta import __version__
from aerodelta.exceptions import AerodeltaError

# Subcommand name -> module under aerodelta.cli exposing add_arguments(parser) and run(args) -> int.
COMMANDS: dict[str, str] = {}


def _register(name: str, module: str) -> None:
    COMMANDS[name] = module


_register("check-daveml", "check_daveml")
_register("write-example-model", "write_example_model")
_register("campaign", "campaign")
_register("fit", "fit")
_register("demo", "demo")
_register("export-qualified", "export_qualified")
_register("export", "export")
_register("ingest", "ingest")
_register("diagnose", "diagnose")
_register("rolloff", "rolloff")
_register("report", "report")
_register("validate", "validate")
_register("map-template", "map_template")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every registered subcommand."""
    parser = argparse.ArgumentParser(
        prog="aerodelta",
        description="Extend a simulator's aero model into stall from flight test data; "
        "diagnose the sim-to-real gap.",
    )
    parser.add_argument("--version", action="version", version=f"aerodelta {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on error")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, modname in COMMANDS.items():
        mod = importlib.import_module(f"aerodelta.cli.{modname}")
        p = sub.add_parser(name, help=mod.HELP, description=mod.__doc__)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``aerodelta`` command; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "_run", None) is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args._run(args))
    except (AerodeltaError, OSError) as e:
        if args.debug:
            raise
        print(f"aerodelta {args.command}: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
