"""Stall identification on virtual campaigns against the truth (issue 20 item 1, docs/stall.md).

For each seed: generate a virtual campaign (default effects, nominal noise and 0.5 m/s
turbulence) in a temporary folder, ingest it, identify the stalls
(``aerodelta.stall_identification``) and compare with the truth's
(``aerodelta.stall.virtual_truth``: the same definitions on the simulator's noise-free signals,
the simulator's own pusher firing time). Prints per seed and pooled: the maneuvers identified
by the records and by the truth, how many by a different criterion (and whether the truth meets
that one within 0.5 s: a near tie), the error of the stall-identification alpha (floor 0.5 deg),
of the stall speed and of the stall-warning speed (floor 1 kt), and the criteria counts; then
the validity verdict lines of the first seed. Misses are listed with their times.

Usage: python benchmarks/stall_id_check.py [seeds=21-30] [size=quick]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import polars as pl

import aerodelta as ad
from aerodelta.stall import stall_identification, validity_range, virtual_truth


def _seeds(text: str) -> list[int]:
    if "-" in text:
        lo, hi = text.split("-")
        return list(range(int(lo), int(hi) + 1))
    return [int(s) for s in text.split(",")]


def main() -> None:
    """Run the check; see the module docstring."""
    seeds = _seeds(sys.argv[1] if len(sys.argv) > 1 else "21-30")
    size = sys.argv[2] if len(sys.argv) > 2 else "quick"
    frames = []
    first_verdict = None
    for seed in seeds:
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            camp = Path(tmp) / "camp"
            ad.generate_campaign(camp, seed=seed, size=size if size == "quick" else int(size))
            data = ad.ingest(camp, progress=False, compat=False).data
            table = stall_identification(data)
            j = virtual_truth(camp, table).with_columns(pl.lit(seed).alias("seed"))
            if first_verdict is None:
                first_verdict = validity_range(data, table)[1]
        frames.append(j)
        _report(f"seed {seed}", j, time.perf_counter() - t0)
    _report("pooled", pl.concat(frames), None)
    pooled = pl.concat(frames)
    bad = pooled.filter(
        ((pl.col("stall_id_alpha_deg") - pl.col("truth_alpha_deg")).abs() >= 0.5)
        | ((pl.col("v_stall_keas") - pl.col("truth_v_stall_keas")).abs() >= 1.0)
        | (pl.col("truth_by").is_null() != pl.col("stall_id_by").is_null())
    )
    for r in bad.iter_rows(named=True):
        print(
            f"  seed {r['seed']} {r['maneuver_id']}: records {r['stall_id_by']} at "
            f"{r['stall_id_t_s']} s, alpha {r['stall_id_alpha_deg']}, {r['v_stall_keas']} KEAS; "
            f"truth {r['truth_by']} at {r['truth_t_s']} s, alpha {r['truth_alpha_deg']}, "
            f"{r['truth_v_stall_keas']} KEAS"
        )
    by = pl.concat(frames).group_by("stall_id_by").len().sort("stall_id_by", nulls_last=True)
    print("criteria (records):", dict(by.iter_rows()))
    if first_verdict is not None:
        for line in first_verdict["verdict"]:
            print(line)


def _report(name: str, j: pl.DataFrame, seconds: float | None) -> None:
    both = j.filter(pl.col("truth_by").is_not_null() & pl.col("stall_id_by").is_not_null())
    only_one = int((j["truth_by"].is_null() != j["stall_id_by"].is_null()).sum())
    other = both.filter(pl.col("truth_by") != pl.col("stall_id_by"))
    ties = sum(
        1
        for r in other.iter_rows(named=True)
        if r[f"truth_{r['stall_id_by']}_t_s"] is not None
        and r[f"truth_{r['stall_id_by']}_t_s"] - r["truth_t_s"] < 0.5
    )
    da = (both["stall_id_alpha_deg"] - both["truth_alpha_deg"]).abs().to_numpy()
    dv = (both["v_stall_keas"] - both["truth_v_stall_keas"]).abs().to_numpy()
    dw = (j["v_warning_keas"] - j["truth_v_warning_keas"]).abs().drop_nulls().to_numpy()

    def stat(x: np.ndarray) -> str:
        if not x.size:
            return "-"
        return f"max {x.max():.2f} p95 {np.percentile(x, 95):.2f} mean {x.mean():.3f}"

    took = "" if seconds is None else f" ({seconds:.0f} s)"
    print(
        f"{name}: {j.height} maneuvers, identified {both.height} (records and truth), "
        f"{only_one} by one only, {other.height} by another criterion ({ties} near ties); "
        f"alpha within 0.5 deg {int((da < 0.5).sum())}/{da.size}, stall speed within 1 kt "
        f"{int((dv < 1.0).sum())}/{dv.size}, warning speed within 1 kt "
        f"{int((dw < 1.0).sum())}/{dw.size}; |d alpha| deg {stat(da)}; |d V stall| kt "
        f"{stat(dv)}; |d V warning| kt {stat(dw)}{took}"
    )


if __name__ == "__main__":
    main()
