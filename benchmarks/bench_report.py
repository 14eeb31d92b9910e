"""Time the validation report for the 200-maneuver default campaign against the 60 s target.

Generates the campaign (seed 0), ingests it and fits the Δ model on four fifths (as
``aerodelta demo``) outside the timing, then times ``build_report`` (PNG + SVG figures, three
6-DOF replays) and prints the share of each section. Peer: the fit itself, timed in the same run.

Run: ``python benchmarks/bench_report.py [--size quick|default]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import polars as pl

from aerodelta.campaign import generate_campaign
from aerodelta.fit import fit
from aerodelta.ingest import ingest
from aerodelta.report import build_report

TARGET_S = 60.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--size", default="default", choices=["quick", "default"])
    ap.add_argument("--no-svg", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        t = time.perf_counter()
        generate_campaign(root / "campaign", seed=0, size=args.size)
        data = ingest(root / "campaign", compat=False).data
        print(
            f"campaign + ingest: {time.perf_counter() - t:.1f} s, "
            f"{data['maneuver_id'].n_unique()} maneuvers, {data.height} samples"
        )
        ids = data["maneuver_id"].unique().sort().to_list()
        held = ids[::5]
        t = time.perf_counter()
        res = fit(data.filter(~pl.col("maneuver_id").is_in(held)))
        t_fit = time.perf_counter() - t
        res.model.save(root / "model.json")
        res.summary().write_parquet(root / "model.params.parquet")
        print(f"fit (peer): {t_fit:.1f} s")
        rep = build_report(
            root / "model.json", data, root / "report", held_out=held, svg=not args.no_svg
        )
        size = rep.html.stat().st_size / 1e6
        print(
            f"report: {rep.seconds:.1f} s (target {TARGET_S:.0f} s: "
            f"{'met' if rep.seconds < TARGET_S else 'MISSED'}), "
            f"{rep.seconds / t_fit:.2f}x the fit, {len(rep.figures)} figure files, "
            f"HTML {size:.1f} MB"
        )
        for k, v in rep.timings().items():
            print(f"  {k:<12} {v:6.2f} s  {100 * v / rep.seconds:5.1f} %")


if __name__ == "__main__":
    main()
