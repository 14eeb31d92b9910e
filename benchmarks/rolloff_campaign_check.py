"""Per-flap roll-off statistics on a default-size campaign against the configured ones (issue 6).

Generates a default-size virtual campaign (200 maneuvers, thesis Table 3.2 roll-off, nominal
noise and gusts) in a temporary folder, ingests it, detects the roll-off events in the
straight stalls (residual: measured C_l less the qualified model), estimates the per-flap
statistics with 95 % intervals and prints, per flap and quantity, the configured value, the
estimate, its interval and whether the interval holds the configured value, with the time
of each stage.

Effects: none but the roll-off by default. With the default post-stall effects the residual
also holds their ΔC_l, which the detected peaks pick up (magnitude and its spread inflated)
unless a fitted Δ model is removed first, as ``aerodelta rolloff --model`` does.

How the statistics account for what a flight test hides (``docs/rolloff.md``): a spike whose
onset lies below the 15 deg re-arm alpha starts at the crossing (its onset is censored there),
and a stick-pusher stall that turns back before the spike's centre meets its rising flank only
(such events are left out of the onset fit by truncation and out of the magnitude statistics).
The onset alphas are read on the CG-corrected alpha. 10 straight stalls per flap (the pilot
holds the controls in the last 6 deg before the stall: no doublets, stick noise only) give
wide intervals; a flap with too few events reports the plain sample statistics
(``alpha_method``/``magnitude_method`` flags) or no interval (counted outside).

Detection is scored against the injected truth (``aerodelta.rolloff.score_detection``: found of
injected, floor 90 %; false of accepted, ceiling 10 %), with the missed events and the
detector's reasons.

Usage: python benchmarks/rolloff_campaign_check.py [seed=0] [size=default] [effects=none]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import polars as pl

import aerodelta as ad
import aerodelta.rolloff as ro
from aerodelta.fit import model_frame, qualified_coefficients


def main() -> None:
    seed = int(sys.argv[1]) if len(sys.argv) > 1 else 0
    size: str | int = sys.argv[2] if len(sys.argv) > 2 else "default"
    size = int(size) if str(size).isdigit() else size
    effects = sys.argv[3] if len(sys.argv) > 3 else "none"
    with tempfile.TemporaryDirectory() as tmp:
        camp = Path(tmp) / "campaign"
        t0 = time.perf_counter()
        info = ad.generate_campaign(camp, seed=seed, size=size, effects=effects, progress=True)
        t1 = time.perf_counter()
        print(
            f"campaign: {info.n_maneuvers} maneuvers, seed {seed}, effects {info.effects} "
            f"({t1 - t0:.1f} s)"
        )
        data = ad.ingest(camp, compat=False, progress=True).data
        t2 = time.perf_counter()
        print(
            f"ingest: {data['maneuver_id'].n_unique()} maneuvers, {data.height} rows "
            f"({t2 - t1:.1f} s)"
        )
        qual = qualified_coefficients(model_frame(data))["Cl_qual"].to_numpy()
        events = ro.detect_rolloff(data, residual=data["Cl_meas"].to_numpy() - qual)
        t3 = time.perf_counter()
        n_straight = data.filter(pl.col("kind") == "straight")["maneuver_id"].n_unique()
        print(
            f"detection: {int(events['accepted'].sum())} accepted of {events.height} candidates "
            f"in {n_straight} straight stalls ({t3 - t2:.1f} s)"
        )
        sc = ro.score_detection(events, camp)
        print(
            f"against the injected truth: found {sc['found']} of {sc['injected']} injected "
            f"({100 * sc['recall']:.1f} %, floor 90 %), {sc['false']} false of {sc['accepted']} "
            f"accepted ({100 * sc['false_rate']:.1f} %, ceiling 10 %)"
        )
        if sc["missed"].height:
            with pl.Config(fmt_str_lengths=200, tbl_width_chars=200):
                print(sc["missed"])
    stats = ro.rolloff_statistics(events)
    chk = ro.check_statistics(stats, ro.default_config())
    with pl.Config(tbl_rows=100, tbl_cols=20, float_precision=4, tbl_width_chars=160):
        print(stats.select("flap_deg", "n", "n_onset", "n_complete", "alpha_mean_deg",
                           "alpha_std_deg", "alpha_method", "magnitude_mean", "magnitude_cv",
                           "magnitude_method", "p_right"))  # fmt: skip
        print(chk)
        print(
            chk.group_by("quantity", maintain_order=True).agg(
                pl.col("inside").sum().alias("inside"),
                pl.len().alias("of"),
                (pl.col("lo").is_nan() | pl.col("hi").is_nan()).sum().alias("no_interval"),
            )
        )
    print(
        f"{int(chk['inside'].sum())} of {chk.height} configured values inside their 95 % interval"
    )


if __name__ == "__main__":
    main()
