"""Write the Part 60 stall-model evidence pack (docs/evidence.md): one HTML page, print-ready,
with its figures as PNG files beside it (OUT/evidence.html, OUT/figures/). It holds the
characteristic-by-characteristic matrix (each Attachment 7 / Table A1A stall item, the data and
figure that show it, its tolerance and a status: PASS/FAIL, shown, or not assessed and why),
the alpha/beta envelope plots per flap and maneuver kind, a draft Statement of Compliance the
sponsor completes, and the provenance (input files' SHA-256, aerodelta version, command).

Prints one line per matrix row (or the matrix as JSON with --format json) and the page's path.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from pathlib import Path

from aerodelta.cli._data import (
    add_aft_stop_argument,
    add_data_arguments,
    aft_stop_deg,
    check_outputs,
    existing_file,
    load_model,
    load_records,
    output_folder,
    resolve_data,
)
from aerodelta.exceptions import InvalidInputError

HELP = "Part 60 stall-model evidence pack: matrix, envelope plots, draft Statement of Compliance"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta evidence``."""
    add_data_arguments(parser)
    parser.add_argument(
        "--model",
        metavar="FILE",
        help="the fitted Δ model (aerodelta fit): degraded lateral-directional stability row "
        "and the validated envelope's outline (per-bin estimates from FILE's .params.parquet)",
    )
    parser.add_argument(
        "--out", metavar="DIR", default="evidence", help="output folder (default: evidence)"
    )
    parser.add_argument(
        "--sim-buffet",
        metavar="FILE",
        default="auto",
        help="the simulator's predominant buffet frequencies, CSV or Parquet with flap_deg, "
        "freq_hz (Hz) and optional axis (nz/ny), for the ±2 Hz comparison; 'auto' (default): "
        "the virtual ADX-37's buffet model for a virtual campaign flown with buffet; 'none'",
    )
    add_aft_stop_argument(parser)
    parser.add_argument(
        "--power-on-ct",
        type=float,
        default=None,
        metavar="CT",
        help="thrust coefficient (sum over the engines) at stall identification from which an "
        "entry is power-on (default 0.03)",
    )
    parser.add_argument(
        "--no-longitudinal",
        action="store_true",
        help="do not fit the Kirchhoff longitudinal stall (its row says so)",
    )
    parser.add_argument(
        "--stall-form",
        choices=("auto", "kirchhoff", "goman-khrabrov"),
        default="auto",
        help="separation curve of the longitudinal fit: the tanh (kirchhoff), the table "
        "(goman-khrabrov), or auto: the one --model stores, else the tanh",
    )
    parser.add_argument(
        "--no-replay",
        action="store_true",
        help="do not fly the closed-loop replays of the stall maneuvers (the ±3 kt speed rows "
        "then say so)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier pack at --out")
    parser.add_argument("--format", choices=("table", "json"), default="table")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta evidence``; returns the exit status."""
    from aerodelta.evidence import (  # noqa: PLC0415
        POWER_ON_CT,
        check_output_folder,
        read_sim_buffet,
        write_evidence,
    )
    from aerodelta.readers import find_records, read_manifest  # noqa: PLC0415

    ct = POWER_ON_CT if args.power_on_ct is None else args.power_on_ct
    if not (math.isfinite(ct) and ct > 0):
        raise InvalidInputError(
            f"--power-on-ct {ct:g}: give a positive thrust coefficient, e.g. 0.03"
        )
    aft_stop = aft_stop_deg(args)
    sim: str | Path | None = None
    if args.sim_buffet == "auto":
        sim = "auto"
    elif args.sim_buffet != "none":
        sim = existing_file(str(args.sim_buffet), "--sim-buffet")
        assert sim is not None
        read_sim_buffet(sim)  # refused here, in one line, before the records are read
    out = output_folder(args.out, "--out")
    check_output_folder(out, args.overwrite)
    src = resolve_data(args)
    if args.model:
        load_model(args.model)  # refused here, in one line, before the records are read
    check_outputs(src, "--out", folder=out, inputs=[Path(args.model) if args.model else None])
    data = load_records(src, progress=not args.no_progress)
    sources: list[Path] = []
    if src.kind == "ingested":
        sources.append(src.parquet)
    else:
        manifest = read_manifest(src.manifest) if src.manifest is not None else None
        sources += [r.path for r in find_records(src.path, manifest)]
        sources += [p for p in (src.manifest, src.aircraft, src.channel_map) if p is not None]
    res = write_evidence(
        data,
        out,
        model=args.model,
        sim_buffet=sim,
        campaign=src.path if src.kind == "campaign" else None,
        sources=sources,
        aft_stop_deg=aft_stop,
        power_on_ct=ct,
        longitudinal=not args.no_longitudinal,
        stall_form=args.stall_form,
        replay=not args.no_replay,
        overwrite=args.overwrite,
        command=_command(args),
        data_label=f"{src.describe()} ({data['maneuver_id'].n_unique()} maneuvers)",
    )
    if args.format == "json":
        print(json.dumps({"html": str(res.html), "matrix": res.matrix.to_dicts()}, indent=2))
    else:
        for i, r in enumerate(res.rows, start=1):
            print(f"{i:>2} {r.item}: {r.status}")
        print(f"wrote {res.html} ({len(res.figures)} figures)")
    sys.stdout.flush()
    return 0


def _command(args: argparse.Namespace) -> str:
    argv = sys.argv[1:] if sys.argv and Path(sys.argv[0]).name.startswith("aerodelta") else None
    if argv:
        return "aerodelta " + shlex.join(argv)
    parts = ["aerodelta", "evidence"]
    for opt, value in (
        ("--data", args.data or args.data_option),
        ("--model", args.model),
        ("--out", args.out),
        ("--sim-buffet", args.sim_buffet),
    ):
        if value is not None:
            parts += [opt, str(value)]
    return shlex.join(parts)
