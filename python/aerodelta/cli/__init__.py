"""The ``aerodelta`` command line: one module per subcommand, no logic the API lacks.

Known errors print one line on stderr and exit 1; ``--debug`` shows the traceback.
Results go to stdout, progress to stderr.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from typing import NoReturn

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
_register("jsbsim-replay", "jsbsim_replay")
_register("stall-id", "stall_id")
_register("plan", "plan")
_register("longitudinal", "longitudinal")
_register("evidence", "evidence")


def cli_wording(message: str, command: str) -> str:
    """A message's advice in the command line's terms (the library's messages name the Python
    API's arguments)."""
    interp = (
        "give --allow-interpolation"
        if command == "ingest"
        else "run aerodelta ingest --allow-interpolation and give its output folder"
    )
    for api, cli in (
        ("pass allow_interpolation=True", interp),
        ("pass apply_compat=True", "ingest with --apply-compat"),
        ("pass overwrite=True", "give --overwrite"),
        ("pass aircraft=PATH (TOML)", "give --aircraft FILE (TOML)"),
    ):
        message = message.replace(api, cli)
    return message


class _Parser(argparse.ArgumentParser):
    """argparse, with a refused command line as one line (no usage block above it)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every registered subcommand."""
    parser = _Parser(
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
        p.set_defaults(_run=mod.run, _parser=p)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``aerodelta`` command; returns the exit status."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # named by the subcommand's parser, in its words
        getattr(args, "_parser", parser).error(f"unrecognized arguments: {' '.join(extra)}")
    if getattr(args, "_run", None) is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args._run(args))
    except (AerodeltaError, OSError) as e:
        if args.debug:
            raise
        print(
            f"aerodelta {args.command}: error: {cli_wording(str(e), args.command)}", file=sys.stderr
        )
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
