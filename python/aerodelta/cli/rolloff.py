"""Stochastic roll-off from flight records (thesis Section 3.4.3): detect the events, estimate
the per-flap statistics (Table 3.2) with confidence intervals, derive the runtime model's
configuration, draw the figures, and optionally compare a Monte Carlo of the simulator
with that configuration against the records.

Writes into OUT (each file atomically):
  events.csv            every candidate (maneuver_id, t_onset, t_peak, alpha, peak, accepted,
                        reason): traceable to the maneuver and time
  statistics.csv/.json  per-flap statistics with intervals (Table 3.2)
  rolloff_config.json   the runtime configuration derived from them (aero_core::rolloff)
  max_roll.csv          maximum bank per straight stall against FAR 25.203
  figures/*.png         event time histories (Fig. 3.9-3.11), DRC (Fig. 3.12), maximum roll
                        (Fig. 3.13), Monte Carlo against the records
  monte_carlo.parquet, mc_comparison.csv/.json   with --monte-carlo N (N stalls per flap)
  summary.json          counts and the files written
Results go to stdout, progress to stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aerodelta._fsutil import write_atomic
from aerodelta.cli._data import (
    add_data_arguments,
    check_at_least,
    check_open_unit,
    check_outputs,
    created,
    existing_file,
    load_model,
    load_records,
    output_folder,
    resolve_data,
)

HELP = "detect roll-off events, per-flap statistics, runtime configuration, Monte Carlo"

#: Event figures drawn (the first accepted events, thesis Figures 3.9-3.11).
N_EVENT_FIGURES = 3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta rolloff``."""
    add_data_arguments(parser)
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument(
        "--model", help="fitted Δ model (JSON): its ΔC_l is removed from the residual too"
    )
    parser.add_argument(
        "--qualified",
        default="auto",
        choices=["auto", "columns", "adx37", "none"],
        help="qualified C_l removed from the measured one: the records' Cl_sim, the built-in "
        "ADX-37 model, or none (the detector's running median removes the trend)",
    )
    parser.add_argument(
        "--monte-carlo",
        type=int,
        default=0,
        metavar="N",
        help="fly N straight stalls per flap setting with the derived configuration",
    )
    parser.add_argument("--seed", type=int, help="Monte Carlo seed (default 0)")
    parser.add_argument("--level", type=float, default=0.95, help="confidence level")
    parser.add_argument("--threads", type=int, help="Monte Carlo threads (default: all cores)")
    parser.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.add_argument("--format", choices=("table", "json"), default="table")


def _json_safe(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_json_safe(v) for v in x]
    return x


def _write_json(path: Path, obj: Any) -> Path:
    text = json.dumps(_json_safe(obj), indent=2)
    return write_atomic(path, lambda p: p.write_text(text + "\n"))


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta rolloff``; returns the exit status."""
    from aerodelta.exceptions import InvalidInputError  # noqa: PLC0415  (CLI start-up light)

    check_open_unit(args.level, "--level", "0.95")
    check_at_least(args.monte_carlo, "--monte-carlo", 0)
    for value, option in ((args.threads, "--threads"), (args.seed, "--seed")):
        if value is not None and not args.monte_carlo:
            raise InvalidInputError(
                f"{option} {value}: applies to the Monte Carlo; give --monte-carlo N too, or "
                "drop it"
            )
    args.seed = 0 if args.seed is None else args.seed
    check_at_least(args.seed, "--seed", 0)
    if args.threads is not None:
        check_at_least(args.threads, "--threads", 1)
    model_file = existing_file(args.model, "--model")
    progress = not args.no_progress
    out = output_folder(args.out)
    src = resolve_data(args)
    check_outputs(src, "--out", folder=out, inputs=[model_file])
    m = load_model(model_file) if model_file is not None else None
    data = load_records(src, progress=progress)
    with created(out):
        return _run(args, data, m, out, progress)


def _run(args: argparse.Namespace, data: Any, m: Any, out: Path, progress: bool) -> int:
    """The computation and the files of ``aerodelta rolloff`` (``m``: the Δ model or None)."""
    import numpy as np  # noqa: PLC0415  (keeps CLI start-up light)
    import polars as pl  # noqa: PLC0415
    from tqdm import tqdm  # noqa: PLC0415

    import aerodelta.rolloff as ro  # noqa: PLC0415
    from aerodelta.exceptions import InvalidInputError  # noqa: PLC0415
    from aerodelta.fit import model_frame, qualified_coefficients  # noqa: PLC0415

    written: list[Path] = []
    residual = data["Cl_meas"].to_numpy().astype(np.float64)
    frame = model_frame(data)
    if args.qualified != "none":
        residual = residual - qualified_coefficients(frame, args.qualified)["Cl_qual"].to_numpy()
    if m is not None and "Cl" in m.coefficients:
        residual = residual - m.evaluate(frame, coefficients=["Cl"])["dCl_blended"].to_numpy()
    model_col = None
    if args.qualified != "none" or m is not None:
        model_col = "Cl_model"  # what the residual removed: drawn beside the measured C_l
        data = data.with_columns(pl.Series(model_col, data["Cl_meas"].to_numpy() - residual))
    events = ro.detect_rolloff(data, residual=residual)
    written.append(write_atomic(out / "events.csv", events.write_csv))
    stats = ro.rolloff_statistics(events, level=args.level)
    if stats.height:
        written.append(write_atomic(out / "statistics.csv", stats.write_csv))
    written.append(_write_json(out / "statistics.json", stats.to_dicts()))
    try:
        config = ro.config_from_statistics(stats)
        config_source = "records"
    except InvalidInputError as e:
        print(f"aerodelta rolloff: {e}; using the thesis Table 3.2 configuration", file=sys.stderr)
        config = ro.default_config()
        config_source = "default (too few events)"
    written.append(_write_json(out / "rolloff_config.json", config))
    max_roll = ro.max_roll_straight_stalls(data)
    written.append(write_atomic(out / "max_roll.csv", max_roll.write_csv))

    comparison = None
    mc = None
    if args.monte_carlo:
        flaps = sorted(set(data.filter(pl.col("kind") == "straight")["flap_deg"].to_list()))
        runs = []
        for flap in flaps:
            if float(flap) not in (0.0, 5.0, 10.0, 15.0, 35.0):
                print(f"aerodelta rolloff: no Monte Carlo at flap {flap} deg", file=sys.stderr)
                continue
            runs.append(
                ro.monte_carlo(
                    args.monte_carlo,
                    seed=args.seed,
                    flap_deg=float(flap),
                    config=config,
                    threads=args.threads,
                    progress=progress,
                )
            )
        if runs:
            mc = pl.concat(runs)
            written.append(write_atomic(out / "monte_carlo.parquet", mc.write_parquet))
            comparison = ro.compare_with_records(mc, events, max_roll)
            written.append(write_atomic(out / "mc_comparison.csv", comparison.write_csv))
            written.append(_write_json(out / "mc_comparison.json", comparison.to_dicts()))

    if not args.no_figures:
        from aerodelta import rolloff_plots as rp  # noqa: PLC0415  (matplotlib is heavy)

        figs = out / "figures"
        figs.mkdir(exist_ok=True)
        acc = events.filter(pl.col("accepted")).head(N_EVENT_FIGURES)
        jobs: list[tuple[str, Callable[[], Any]]] = []
        for ev in acc.iter_rows(named=True):
            rec = data.filter(pl.col("maneuver_id") == ev["maneuver_id"]).sort("t")
            jobs.append(
                (
                    f"event_{ev['maneuver_id']}.png",
                    lambda r=rec, e=ev: rp.event_figure(r, e, model_column=model_col),
                )
            )
        jobs.append(("drc.png", lambda: rp.drc_figure(data)))
        jobs.append(("max_roll.png", lambda: rp.max_roll_figure(max_roll)))
        if mc is not None:
            for flap in sorted(set(mc["flap_deg"].to_list())):
                jobs.append(
                    (
                        f"mc_histograms_f{int(flap):02d}.png",
                        lambda f=flap: rp.mc_histograms(
                            mc.filter(pl.col("flap_deg") == f),
                            events.filter(pl.col("flap_deg") == f),
                            max_roll.filter(pl.col("flap_deg") == f),
                        ),
                    )
                )
        for name, make in tqdm(jobs, desc="figures", unit="fig", disable=not progress):
            written.append(rp.save_figure(make(), figs / name))

    n_acc = int(events["accepted"].sum()) if events.height else 0
    summary = {
        "maneuvers": int(data["maneuver_id"].n_unique()),
        "straight_stalls": int(max_roll.height),
        "candidates": int(events.height),
        "accepted": n_acc,
        "far25_203_exceeded": int((~max_roll["passed"]).sum()) if max_roll.height else 0,
        "config_source": config_source,
        "monte_carlo_per_flap": int(args.monte_carlo),
        "seed": int(args.seed),
        "files": [str(p) for p in written],
    }
    written.append(out / "summary.json")
    summary["files"].append(str(out / "summary.json"))
    _write_json(out / "summary.json", summary)
    if args.format == "json":
        print(json.dumps(_json_safe(summary), indent=2))
    else:
        print(
            f"{summary['accepted']} roll-off events accepted of {summary['candidates']} "
            f"candidates in {summary['straight_stalls']} straight stalls "
            f"({summary['far25_203_exceeded']} above 20 deg bank)"
        )
        for r in stats.iter_rows(named=True):
            print(
                f"flap {r['flap_deg']:>4g}: n={r['n']:<3d} onset alpha "
                f"{r['alpha_mean_deg']:.2f} [{r['alpha_mean_lo']:.2f}, {r['alpha_mean_hi']:.2f}]"
                f" deg, sd {r['alpha_std_deg']:.2f}, |ΔCl| {r['magnitude_mean']:.4f} "
                f"[{r['magnitude_lo']:.4f}, {r['magnitude_hi']:.4f}], right "
                f"{r['p_right']:.2f} [{r['p_right_lo']:.2f}, {r['p_right_hi']:.2f}]"
            )
        if comparison is not None:
            for r in comparison.iter_rows(named=True):
                print(
                    f"flap {r['flap_deg']:>4g} {r['quantity']}: median MC {r['q50_mc']:.2f} "
                    f"records {r['q50_records']:.2f}; KS D={r['ks_statistic']:.3f} "
                    f"p={r['ks_pvalue']:.3g} (n {r['n_mc']} / {r['n_records']})"
                )
        print(f"wrote {len(summary['files'])} files into {out}")
    sys.stdout.flush()
    return 0
