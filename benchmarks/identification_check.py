"""Check the Δ-model identification against the truth over independent virtual campaigns.

For each seed: fly the default campaign (default effects, realistic noise and turbulence),
ingest it, fit four fifths of the maneuvers with a bootstrap over maneuvers, and hold the
rest out. Reported, per coefficient:

- **coverage**: the share of identified bins (alpha >= alpha_l, where the model applies) whose
  95 % bootstrap percentile band holds the true Δ derivative at the bin centre, per bin and
  for the smoothed parameter there (``aerodelta.truth.band_check``); with the
  stepwise-selected structure and a bootstrap that selects again in each replicate (the
  default), the same without reselection, and the thesis structures (``selection=None``);
- **band width**: median width of the smoothed bands against the largest |truth|;
- **calibration**: per bin fitted in every campaign, the root-mean-square bootstrap standard
  error over the standard deviation of the estimates across campaigns (1 = honest), and the
  same for the coloured-residual standard error;
- **held-out TIC ratio**: Theil inequality of the extended model over the qualified model's on
  the held-out maneuvers, and the same for qualified + the true Δ (the best any Δ model can do
  against the noisy measurements).

Run: ``python benchmarks/identification_check.py [--seeds 20] [--first-seed 1]
[--workers 2] [--scheduler ADDRESS] [--resume DIR]`` (about 40 s of 2 cores per seed). The seeds
run as tasks on the distributed engine (``aerodelta.plan.suite.run_cases``: a local Dask cluster
of ``--workers`` processes, or the cluster at ``--scheduler``; ``--workers 0``: in this
process); ``--resume DIR`` keeps each finished seed and a rerun skips it. The numbers do not
depend on the number of workers.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

import aerodelta as ad
from aerodelta.fit import COEFFICIENTS, FitConfig, model_frame, qualified_coefficients
from aerodelta.fit import theil_inequality as tic
from aerodelta.plan.suite import run_cases
from aerodelta.truth import band_summary, campaign_effects

CONFIGS = {
    "selected": FitConfig(),
    "no reselection": FitConfig(bootstrap_selection=False),
    "thesis": FitConfig(selection=None),
}


def _tic_ratios(
    result: ad.FitResult, test: pl.DataFrame, camp: Path
) -> dict[str, tuple[float, float]]:
    """Per coefficient: held-out TIC ratio of the extended model, and of qualified + true Δ."""
    mf = model_frame(test)
    qual = qualified_coefficients(mf)
    ev = pl.concat(
        [result.model.evaluate(mf), qual, test.select("maneuver_id", "t", *[
            f"{c}_meas" for c in COEFFICIENTS])],
        how="horizontal",
    )  # fmt: skip
    truth = pl.concat(
        [
            pl.read_parquet(camp / "truth" / f"{m}.parquet")
            .select("t", *[f"{c}_true" for c in COEFFICIENTS], *[f"{c}_qual" for c in COEFFICIENTS])
            .rename({f"{c}_qual": f"{c}_tq" for c in COEFFICIENTS})
            .with_columns(pl.lit(m).alias("maneuver_id"))
            for m in test["maneuver_id"].unique().to_list()
        ]
    )
    j = ev.join(truth, on=["maneuver_id", "t"], how="inner")
    out = {}
    for c in COEFFICIENTS:
        meas, q = j[f"{c}_meas"].to_numpy(), j[f"{c}_qual"].to_numpy()
        ext = q + j[f"d{c}_blended"].to_numpy()
        oracle = q + (j[f"{c}_true"] - j[f"{c}_tq"]).to_numpy()
        out[c] = (tic(meas, ext) / tic(meas, q), tic(meas, oracle) / tic(meas, q))
    return out


def one_seed(seed: int, bootstrap: int) -> dict[str, Any]:
    """One campaign (a task on the engine): per configuration the band summary, the held-out
    TIC ratios of the selected fit and the thesis fit's parameter table."""
    out: dict[str, Any] = {"bands": {}}
    with tempfile.TemporaryDirectory() as tmp:
        camp = Path(tmp) / f"c{seed}"
        ad.generate_campaign(camp, seed=seed, progress=False)
        effects = campaign_effects(camp)
        data = ad.ingest(camp, compat=False, progress=False).data
        ids = data["maneuver_id"].unique().sort().to_list()
        held = set(ids[::5])
        train = data.filter(~pl.col("maneuver_id").is_in(held))
        test = data.filter(pl.col("maneuver_id").is_in(held))
        for name, base in CONFIGS.items():
            cfg = FitConfig(**{**base.__dict__, "bootstrap": bootstrap, "seed": seed})
            r = ad.fit(train, config=cfg)
            out["bands"][name] = band_summary(r, effects)
            if name == "selected":
                out["tics"] = _tic_ratios(r, test, camp)
            elif name == "thesis":
                out["params"] = r.params.with_columns(pl.lit(seed).alias("seed"))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--bootstrap", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2, help="engine workers (0: this process)")
    ap.add_argument("--scheduler", default=None, help="a Dask scheduler's address")
    ap.add_argument("--resume", default=None, help="keep finished seeds here and skip them")
    args = ap.parse_args()
    configs = CONFIGS
    cov = {k: {c: [0.0, 0.0, 0.0] for c in COEFFICIENTS} for k in configs}
    widths: dict[str, dict[str, list[float]]] = {k: {c: [] for c in COEFFICIENTS} for k in configs}
    tics: dict[str, list[tuple[float, float]]] = {c: [] for c in COEFFICIENTS}
    params: list[pl.DataFrame] = []
    t_start = time.perf_counter()
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    run = run_cases(
        one_seed,
        [(seed, args.bootstrap) for seed in seeds],
        labels=[f"seed {seed}" for seed in seeds],
        workers=args.workers,
        scheduler=args.scheduler,
        resume=args.resume,
        name="identification",
    )
    for f in run.failures:
        print(f"FAILED {f.label}: {f.error}")
    for res in run.results:
        if res is None:
            continue
        for name in configs:
            for row in res["bands"][name].iter_rows(named=True):
                c, n = row["coefficient"], row["bins"]
                cov[name][c][0] += n
                cov[name][c][1] += n * row["inside_bin_band"]
                cov[name][c][2] += n * row["inside_band"]
                widths[name][c].append(row["width_ratio"])
        for c, v in res["tics"].items():
            tics[c].append(v)
        params.append(res["params"])
    print(
        f"{len(params)} seeds done in {time.perf_counter() - t_start:.0f} s "
        f"({run.resumed} read back from --resume, {len(run.failures)} failed)"
    )
    print(f"\n{args.seeds} campaigns (seeds {args.first_seed}..{args.first_seed + args.seeds - 1}),"
          f" {args.bootstrap} bootstrap replicates each")  # fmt: skip
    print("truth inside the 95 % bands (identified bins, alpha >= alpha_l): per bin / smoothed;"
          " floor 90 %")  # fmt: skip
    print(f"{'coef':<5} " + " ".join(f"{k:>26}" for k in configs) + f" {'width/|truth|':>14}")
    for c in COEFFICIENTS:
        cells = []
        for k in configs:
            n, kb, ks = cov[k][c]
            cells.append(
                f"{100 * kb / max(n, 1):>6.1f} / {100 * ks / max(n, 1):>5.1f} % of {n:>6.0f}"
            )
        print(f"{c:<5} " + " ".join(f"{x:>26}" for x in cells) + (
            f" {float(np.median(widths['selected'][c])):>14.3f}"))  # fmt: skip
    _print_tic(tics)
    if len(params) < 2:
        return
    # calibration: bins fitted in every campaign with the thesis structure (same structure,
    # same edges), alpha >= 8 deg
    p = pl.concat(params).filter(pl.col("identifiable") & (pl.col("alpha_lo_deg") >= 8.0))
    g = (
        p.group_by(["coefficient", "flap_deg", "param", "alpha_lo_deg"])
        .agg(
            pl.col("estimate").std().alias("sd"),
            pl.col("std_err_bootstrap").pow(2).mean().sqrt().alias("boot"),
            pl.col("std_err_colored").pow(2).mean().sqrt().alias("colored"),
            pl.len().alias("k"),
        )
        .filter(pl.col("k") == len(params))
    )
    print("\nstandard errors against the spread of the estimates over the campaigns "
          "(thesis structure, median over bins; 1 = honest)")  # fmt: skip
    print(f"{'coef':<5} {'bins':>6} {'bootstrap':>10} {'coloured':>10}")
    for c in COEFFICIENTS:
        h = g.filter(pl.col("coefficient") == c)
        rb = float((h["boot"] / h["sd"]).median())  # type: ignore[arg-type]
        rc = float((h["colored"] / h["sd"]).median())  # type: ignore[arg-type]
        print(f"{c:<5} {h.height:>6} {rb:>10.2f} {rc:>10.2f}")


def _print_tic(tics: dict[str, list[tuple[float, float]]]) -> None:
    print("\nheld-out TIC ratio, extended / qualified (floor 0.5), and qualified + true Δ")
    for c in COEFFICIENTS:
        a = np.asarray(tics[c])
        print(f"{c:<5} median {np.median(a[:, 0]):.2f} (max {a[:, 0].max():.2f})   "
              f"true Δ: median {np.median(a[:, 1]):.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
