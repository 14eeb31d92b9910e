"""Closed-loop check of the exported Δ on JSBSim aircraft (issue 19 item 4).

For each aircraft and seed: fly a JSBSim campaign (``generate_jsbsim_campaign``, the aircraft's
default withheld terms and withhold alpha, sensor noise scale 1, calm air), ingest it, hold
out every fifth maneuver (as ``benchmarks/jsbsim_identification_check.py``), fit the rest
(``aerodelta.fit(..., qualified="columns")``, default configuration with the campaign's seed, or
the thesis structures without selection with ``--thesis``),
then replay every held-out maneuver open loop with its recorded surfaces and the throttle
schedule fitted to its recorded thrust on the full aircraft (the truth), the qualified aircraft
(withheld terms frozen, the campaign's ``C*_sim``) and the extended aircraft (qualified + the Δ
exported by ``aerodelta.jsbsim.export_jsbsim``), ``aerodelta.jsbsim_replay.replay_campaign``.

Scored: Theil inequality coefficient on p, r, φ, β against the record, over the window fixed
before any extended-vs-qualified result was seen (``score_window``: from the start to the
first sample after the largest alpha at which the recorded alpha is back at the withhold
alpha), pooled over the held-out maneuvers of a campaign, and per maneuver. The floor:
``tic_extended / tic_qualified <= 0.5`` on every channel, on two aircraft.

Run: ``python benchmarks/jsbsim_replay_check.py --aircraft f15 DHC6 --seeds 11 12 13
[--size 6] [--thesis] [--out rows.parquet]``. About 20-60 s per campaign on 2 shared cores.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import polars as pl

import aerodelta as ad
from aerodelta.fit import FitConfig
from aerodelta.jsbsim_campaign import generate_jsbsim_campaign
from aerodelta.jsbsim_replay import replay_campaign


def one(aircraft: str, seed: int, size: int, tmp: Path, thesis: bool = False) -> pl.DataFrame:
    """Fly, fit and replay one campaign; the score rows tagged with aircraft and seed."""
    camp = tmp / f"{aircraft}_{seed}"
    t0 = time.perf_counter()
    generate_jsbsim_campaign(camp, aircraft=aircraft, seed=seed, size=size)
    data = ad.ingest(camp, compat=False, progress=False).data
    ids = data["maneuver_id"].unique().sort().to_list()
    held = ids[::5]
    train = data.filter(~pl.col("maneuver_id").is_in(held))
    config = FitConfig(seed=seed, selection=None) if thesis else FitConfig(seed=seed)
    fit = ad.fit(train, qualified="columns", config=config)
    t1 = time.perf_counter()
    scores = replay_campaign(camp, fit.model, maneuvers=held, progress=True)
    t2 = time.perf_counter()
    print(
        f"{aircraft} seed {seed}: {len(ids)} maneuvers, {len(held)} held out; fly+fit "
        f"{t1 - t0:.0f} s, replay {t2 - t1:.0f} s",
        flush=True,
    )
    return scores.with_columns(pl.lit(aircraft).alias("aircraft"), pl.lit(seed).alias("seed"))


def summarize(rows: pl.DataFrame) -> str:
    """The pooled and per-maneuver tables of the scored window."""
    cols = ["aircraft", "seed", "channel", "tic_full", "tic_qualified", "tic_extended", "ratio"]
    out = []
    for window in ("predictable", "delta", "record"):
        w = rows.filter(pl.col("window") == window)
        pooled = w.filter(pl.col("maneuver_id") == "pooled").select(cols).sort(cols[:3])
        out.append(f"== window '{window}', pooled over the held-out maneuvers of each campaign")
        out.append(str(pooled))
        agg = (
            w.filter(pl.col("maneuver_id") != "pooled")
            .group_by("aircraft", "channel")
            .agg(
                pl.len().alias("maneuvers"),
                pl.col("ratio").median().alias("median_ratio"),
                (pl.col("ratio") <= 0.5).mean().alias("share_ratio_le_0.5"),
                pl.col("tic_full").median().alias("median_tic_full"),
            )
            .sort("aircraft", "channel")
        )
        out.append(f"== window '{window}', per maneuver")
        out.append(str(agg))
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--aircraft", nargs="+", default=["f15", "DHC6"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[11, 12, 13])
    ap.add_argument("--size", type=int, default=6)
    ap.add_argument("--out", type=Path)
    ap.add_argument(
        "--thesis", action="store_true", help="fit the thesis structures (selection=None)"
    )
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for aircraft in args.aircraft:
            for seed in args.seeds:
                rows.append(one(aircraft, seed, args.size, Path(tmp), args.thesis))
    df = pl.concat(rows, how="diagonal_relaxed")
    if args.out:
        df.write_parquet(args.out)
    with pl.Config(tbl_rows=200, tbl_cols=20, float_precision=4, tbl_width_chars=200):
        print(summarize(df))
        print("== per maneuver, window 'delta'")
        print(
            df.filter((pl.col("window") == "delta") & (pl.col("maneuver_id") != "pooled"))
            .select(
                "aircraft",
                "seed",
                "maneuver_id",
                "channel",
                "t_end_s",
                "tic_full",
                "tic_qualified",
                "tic_extended",
                "ratio",
            )
            .sort("aircraft", "seed", "maneuver_id", "channel")
        )


if __name__ == "__main__":
    main()
