"""The built-in demonstration, with no data of the user's: fly the virtual flight test
campaign (ADX-37 truth aircraft with post-stall effects), ingest it, fit the Δ model on four
fifths of the maneuvers, and compare the qualified and extended models on the held-out fifth
(Theil inequality coefficient, thesis Chapter 4)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import polars as pl

from aerodelta.campaign import generate_campaign
from aerodelta.fit import fit, model_frame, validate_model
from aerodelta.ingest import ingest
from aerodelta.report import build_report

HELP = "run the whole method on the built-in virtual flight test campaign"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta demo``."""
    parser.add_argument("--out", default="aerodelta-demo", help="folder for the demo's outputs")
    parser.add_argument("--seed", type=int, default=0, help="campaign seed")
    parser.add_argument("--quick", action="store_true", help="40 maneuvers instead of 200")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta demo``."""
    out = Path(args.out)
    progress = not args.no_progress
    camp = out / "campaign"
    generate_campaign(
        camp, seed=args.seed, size="quick" if args.quick else "default",
        overwrite=True, progress=progress,
    )  # fmt: skip
    data = ingest(camp, compat=False, progress=progress).data
    ids = data["maneuver_id"].unique().sort().to_list()
    held = set(ids[::5])
    train = data.filter(~pl.col("maneuver_id").is_in(held))
    test = data.filter(pl.col("maneuver_id").is_in(held))
    result = fit(train, progress=progress)
    result.model.save(out / "model.json")
    result.summary().write_parquet(out / "model.params.parquet")
    v = validate_model(result.model, test)
    print(
        f"aerodelta demo: {len(ids)} maneuvers ({len(ids) - len(held)} fitted, {len(held)} held "
        f"out), stall alpha per flap {result.stall_alpha_deg}"
    )
    print("held-out maneuvers: qualified vs extended model (TIC: Theil inequality coefficient)")
    print(
        f"{'coef':<5} {'rms qual':>10} {'rms ext':>10} {'TIC qual':>9} {'TIC ext':>9} {'ratio':>6}"
    )
    for r in v.iter_rows(named=True):
        print(
            f"{r['coefficient']:<5} {r['rms_qualified']:>10.5f} {r['rms_extended']:>10.5f} "
            f"{r['tic_qualified']:>9.4f} {r['tic_extended']:>9.4f} {r['tic_ratio']:>6.2f}"
        )
    v.write_csv(out / "validation.csv")
    # What was recovered versus the truth (the demo harness reads the truth files; the fit
    # never does): the fitted, blended Δ against the truth aircraft's C_true - C_qual.
    truth = pl.concat(
        [
            pl.read_parquet(camp / "truth" / f"{m}.parquet").with_columns(
                pl.lit(m).alias("maneuver_id")
            )
            for m in sorted(held)
        ]
    )
    ev = result.model.evaluate(model_frame(test)).with_columns(test["maneuver_id"], test["t"])
    j = ev.join(truth, on=["maneuver_id", "t"], how="inner")
    print("held-out maneuvers: fitted Δ vs the truth aircraft's Δ (C_true - C_qual)")
    print(f"{'coef':<5} {'rms true Δ':>11} {'rms error':>10} {'explained':>10}")
    for c in ("Cl", "Cn", "CY"):
        d_true = (j[f"{c}_true"] - j[f"{c}_qual"]).to_numpy()
        err = d_true - j[f"d{c}_blended"].to_numpy()
        ok = np.isfinite(err)
        rms_t = float(np.sqrt(np.mean(d_true[ok] ** 2)))
        rms_e = float(np.sqrt(np.mean(err[ok] ** 2)))
        expl = 1.0 - (rms_e / rms_t) ** 2 if rms_t > 0 else float("nan")
        print(f"{c:<5} {rms_t:>11.5f} {rms_e:>10.5f} {100 * expl:>9.0f}%")
    rep = build_report(
        out / "model.json", data, out / "report", held_out=sorted(held), progress=progress
    )
    print(f"validation report: {rep.html}")
    print(
        f"outputs in {out}/ (campaign/, model.json, model.params.parquet, report/)", file=sys.stderr
    )
    return 0
