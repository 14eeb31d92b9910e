"""Stall identification per maneuver by each Part 60 Attachment 7 criterion (stick pusher, pitch
break, g-break, deterrent buffet, 2 s at the aft stop), the stall-warning, buffet-onset and stall
speeds, the buffet's onset alpha and predominant frequencies per flap, and the validity range the
records cover against stall identification + 10 deg (docs/stall.md).

Prints the per-flap-and-kind summary and one validity verdict line per flap to stdout (or
everything as JSON with --format json); --out FILE also writes the per-maneuver table as CSV
(FILE) with the summary, the alpha-band coverage, the verdicts and the buffet (per flap, its
predominant frequencies, amplitude against alpha) beside it (FILE's stem + .summary.csv,
.coverage.csv, .validity.csv, .buffet.csv, .buffet_freq.csv, .buffet_amplitude.csv).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from aerodelta._fsutil import write_atomic
from aerodelta.cli._data import (
    add_aft_stop_argument,
    add_data_arguments,
    aft_stop_deg,
    check_outputs,
    load_records,
    output_file,
    resolve_data,
)
from aerodelta.exceptions import InvalidInputError

HELP = "stall-identification alpha by each Attachment 7 criterion, stall speeds, validity range"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta stall-id``."""
    add_data_arguments(parser)
    parser.add_argument(
        "--out", metavar="FILE", help="write the per-maneuver table as CSV (and its companions)"
    )
    add_aft_stop_argument(parser)
    parser.add_argument(
        "--band", type=float, default=2.0, metavar="DEG", help="alpha band of the coverage table"
    )
    parser.add_argument("--format", choices=("table", "json"), default="table")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def _companions(out: Path) -> list[Path]:
    return [out.with_name(f"{out.stem}.{k}.csv") for k in _KINDS]


_KINDS = ("summary", "coverage", "validity", "buffet", "buffet_freq", "buffet_amplitude")


def _num(x: Any, fmt: str = ".1f") -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta stall-id``; returns the exit status."""
    from aerodelta.buffet import buffet_identification  # noqa: PLC0415  (CLI start-up light)
    from aerodelta.stall import (  # noqa: PLC0415  (CLI start-up light)
        stall_identification,
        stall_summary,
        validity_range,
    )

    if not (math.isfinite(args.band) and args.band > 0):
        raise InvalidInputError(f"--band {args.band:g}: give a positive band width, e.g. --band 2")
    aft_stop = aft_stop_deg(args)
    out = output_file(args.out, "--out", "stall_id.csv") if args.out else None
    src = resolve_data(args)
    if out is not None:
        check_outputs(src, "--out", files=[out, *_companions(out)])
    data = load_records(src, progress=not args.no_progress)
    table = stall_identification(data, aft_stop_deg=aft_stop)
    summary = stall_summary(table)
    coverage, verdict = validity_range(data, table, band_deg=args.band)
    buffet = buffet_identification(data) if "az_mps2" in data.columns else None
    frames = (table, summary, coverage, verdict)
    if buffet is not None:
        frames += (buffet.per_flap, buffet.frequencies, buffet.amplitude)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        for frame, path in zip(frames, (out, *_companions(out)), strict=False):
            write_atomic(path, frame.write_csv)
    if args.format == "json":
        print(
            json.dumps(
                {
                    "maneuvers": table.to_dicts(),
                    "summary": summary.to_dicts(),
                    "validity": verdict.to_dicts(),
                    "coverage": coverage.to_dicts(),
                    "buffet": None
                    if buffet is None
                    else {
                        "per_flap": buffet.per_flap.to_dicts(),
                        "frequencies": buffet.frequencies.to_dicts(),
                    },
                },
                indent=2,
            )
        )
    else:
        print(
            f"{'flap':>4} {'kind':<17} {'n':>3} {'id':>3} {'push':>4} {'pitch':>5} {'g':>3} "
            f"{'buf':>3} {'stop':>4} {'alpha id':>8} {'V warn':>7} {'V stall':>7} {'V min':>7}"
        )
        for r in summary.iter_rows(named=True):
            print(
                f"{r['flap_deg']:>4g} {r['kind']:<17} {r['n_maneuvers']:>3} "
                f"{r['n_identified']:>3} {r['by_pusher']:>4} {r['by_pitch_break']:>5} "
                f"{r['by_g_break']:>3} {r['by_buffet']:>3} {r['by_aft_stop']:>4} "
                f"{_num(r['stall_id_alpha_mean_deg']):>8} "
                f"{_num(r['v_warning_mean_keas']):>7} {_num(r['v_stall_mean_keas']):>7} "
                f"{_num(r['v_min_mean_keas']):>7}"
            )
        print("(alpha in deg at the CG; speeds KEAS, means per cell)")
        note = table["not_assessed"][0] if table.height else ""
        if note:
            print(note)
        for line in verdict["verdict"]:
            print(line)
        if buffet is not None:
            _print_buffet(buffet)
        if out is not None:
            for p in (out, *_companions(out)):
                print(f"wrote {p}")
    sys.stdout.flush()
    return 0


def _print_buffet(buffet: Any) -> None:
    """One line per flap: buffet onset alpha and speed, predominant frequencies per axis."""
    for r in buffet.per_flap.iter_rows(named=True):
        f = buffet.frequencies.filter(buffet.frequencies["flap_deg"] == r["flap_deg"])
        spikes = "; ".join(
            f"{axis} " + ", ".join(f"{v:.1f}" for v in f.filter(f["axis"] == axis)["freq_hz"])
            for axis in ("nz", "ny")
            if (f["axis"] == axis).any()
        )
        print(
            f"flap {r['flap_deg']:g}: buffet in {r['n_buffet']} of {r['n_maneuvers']} maneuvers, "
            f"onset alpha {_num(r['onset_alpha_deg'])} deg (median), "
            f"{_num(r['v_buffet_onset_mean_keas'])} KEAS; predominant frequencies, Hz: "
            f"{spikes or 'none (no buffet segment long enough for a spectrum)'}"
        )
