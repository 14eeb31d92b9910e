"""The built-in demonstration, with no data of the user's: fly the virtual flight test
campaign (ADX-37 truth aircraft with post-stall effects), ingest it, fit the Δ model on four
fifths of the maneuvers, and compare the qualified and extended models on the held-out fifth
(Theil inequality coefficient, thesis Chapter 4)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from aerodelta._fsutil import write_atomic
from aerodelta._groups import group_agg
from aerodelta.campaign import generate_campaign
from aerodelta.cli._data import check_at_least, created, output_folder
from aerodelta.diagnosis import diagnose, write_outputs
from aerodelta.fit import (
    COEFFICIENTS,
    FitConfig,
    fit,
    model_frame,
    qualified_coefficients,
    theil_inequality,
    validate_model,
)
from aerodelta.ingest import ingest
from aerodelta.model import with_params_hash
from aerodelta.truth import band_summary, campaign_effects

HELP = "run the whole method on the built-in virtual flight test campaign"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta demo``."""
    parser.add_argument("--out", default="aerodelta-demo", help="folder for the demo's outputs")
    parser.add_argument("--seed", type=int, default=0, help="campaign seed")
    parser.add_argument("--quick", action="store_true", help="40 maneuvers instead of 200")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.add_argument(
        "--bootstrap", type=int, default=100, help="bootstrap replicates for the bands (0: none)"
    )


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta demo``."""
    from aerodelta.report import build_report  # noqa: PLC0415  (matplotlib: CLI start-up light)

    check_at_least(args.seed, "--seed", 0)
    check_at_least(args.bootstrap, "--bootstrap", 0)
    out = output_folder(args.out)
    with created(out):  # a demo stopped part way leaves no folder it made
        return _demo(args, out, build_report)


def _demo(args: argparse.Namespace, out: Path, build_report: Any) -> int:
    """The demo's steps, writing into ``out``."""
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
    result = fit(train, config=FitConfig(bootstrap=args.bootstrap), progress=progress)
    # the params table first, the model last recording its hash (committed together)
    write_atomic(out / "model.params.parquet", result.summary().write_parquet)
    with_params_hash(result.model, out / "model.params.parquet").save(out / "model.json")
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
    meas_cols = [f"{c}_meas" for c in COEFFICIENTS]
    mf = model_frame(test)
    qual = qualified_coefficients(mf).rename({f"{c}_qual": f"{c}_fitqual" for c in COEFFICIENTS})
    ev = pl.concat(
        [result.model.evaluate(mf), qual, test.select("maneuver_id", "t", *meas_cols)],
        how="horizontal",
    )
    j = ev.join(truth, on=["maneuver_id", "t"], how="inner")
    print("held-out maneuvers: fitted Δ vs the truth aircraft's Δ (C_true - C_qual)")
    print(
        f"{'coef':<5} {'rms true Δ':>11} {'rms error':>10} {'explained':>10} "
        f"{'TIC ratio of the true Δ':>24}"
    )
    for c in ("Cl", "Cn", "CY"):
        d_true = (j[f"{c}_true"] - j[f"{c}_qual"]).to_numpy()
        err = d_true - j[f"d{c}_blended"].to_numpy()
        ok = np.isfinite(err)
        rms_t = float(np.sqrt(np.mean(d_true[ok] ** 2)))
        rms_e = float(np.sqrt(np.mean(err[ok] ** 2)))
        expl = 1.0 - (rms_e / rms_t) ** 2 if rms_t > 0 else float("nan")
        # the best any Δ model can do against the noisy measurements: qualified + true Δ
        meas, qual = j[f"{c}_meas"].to_numpy(), j[f"{c}_fitqual"].to_numpy()
        oracle = theil_inequality(meas, qual + d_true) / theil_inequality(meas, qual)
        print(f"{c:<5} {rms_t:>11.5f} {rms_e:>10.5f} {100 * expl:>9.0f}% {oracle:>24.2f}")
    # the thesis structures with the same bootstrap: the per-bin bands without the selection
    # step (a band on a selected structure does not carry the selection's own uncertainty)
    thesis = (
        fit(train, config=FitConfig(selection=None, bootstrap=args.bootstrap))
        if args.bootstrap
        else None
    )
    _print_identification(result, camp, thesis)
    # the sim-to-real gap of the qualified model on the whole campaign (issue 7), then the
    # validation report with it (issue 8)
    diag = diagnose(data, progress=progress)
    write_outputs(diag.result, diag.predictions, out / "diagnosis")
    print(diag.summary())
    rep = build_report(
        out / "model.json",
        data,
        out / "report",
        held_out=sorted(held),
        diagnosis_doc=diag.result,
        progress=progress,
    )
    print(f"validation report: {rep.html}")
    print(
        f"outputs in {out}/ (campaign/, model.json, model.params.parquet, diagnosis/, report/)",
        file=sys.stderr,
    )
    return 0


def _print_identification(result: object, camp: Path, thesis: object | None = None) -> None:
    """Structure selection, its cross-validation and the bootstrap bands against the truth."""
    r = result
    print("structure selection (stepwise, partial F >= 4, CV over maneuvers): kept per flap")
    kept = (
        r.structure.filter(pl.col("kept"))  # type: ignore[attr-defined]
        .group_by(["coefficient", "flap_deg"], maintain_order=True)
        .agg(pl.col("param"))
        .sort(["coefficient", "flap_deg"])
    )
    for row in kept.iter_rows(named=True):
        names = ", ".join(p.split("_", 1)[1] for p in row["param"])
        print(f"  {row['coefficient']:<3} flap {row['flap_deg']:>4g}: {names}")
    skipped = r.structure.filter(pl.col("note") != "")  # type: ignore[attr-defined]
    if skipped.height:
        print(f"  (flaps {sorted(set(skipped['flap_deg'].to_list()))}: {skipped['note'][0]})")
    if r.cross_validation.is_empty():  # type: ignore[attr-defined]
        print("no cross-validated selection: too few maneuvers per flap")
        cv = None
    else:
        cv = group_agg(  # the means summed in row order (_groups)
            r.cross_validation,  # type: ignore[attr-defined]
            ["coefficient", "structure"],
            {c: (c, "mean") for c in ("cv_rms", "cv_tic", "n_params")},
        ).sort(["coefficient", "structure"])
    if cv is not None:
        print(
            "cross-validated per-bin Δ fit (mean over flaps): selected vs full pool vs thesis "
            "default"
        )
        print(f"{'coef':<5} {'structure':<9} {'params':>6} {'CV rms':>10} {'CV TIC':>7}")
        for row in cv.iter_rows(named=True):
            print(
                f"{row['coefficient']:<5} {row['structure']:<9} {row['n_params']:>6.1f} "
                f"{row['cv_rms']:>10.5f} {row['cv_tic']:>7.3f}"
            )
    if not r.replicates:  # type: ignore[attr-defined]
        return
    effects = campaign_effects(camp)
    sel = band_summary(r, effects)
    th = band_summary(thesis, effects) if thesis is not None else None
    print("bootstrap 95% bands vs the true Δ derivatives (identified bins, alpha >= alpha_l)")
    head = f"{'coef':<5} {'bins':>6} {'smoothed':>9} {'per bin':>8} {'width/max|truth|':>17}"
    print(head + (f" {'thesis structure, per bin':>26}" if th is not None else ""))
    for i, row in enumerate(sel.iter_rows(named=True)):
        line = (
            f"{row['coefficient']:<5} {row['bins']:>6} {100 * row['inside_band']:>8.0f}% "
            f"{100 * row['inside_bin_band']:>7.0f}% {row['width_ratio']:>17.3f}"
        )
        if th is not None:
            t = th.row(i, named=True)
            line += f" {100 * t['inside_bin_band']:>17.0f}% of {t['bins']:>5}"
        print(line)
