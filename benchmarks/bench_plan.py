"""Campaign design study on the Dask engine (issue 21): speed-up and prediction floors.

``--speedup``: the same study (``--campaigns`` seeds) with 1 and then 2 local workers in one
run; prints both wall times, the ratio (floor: 1.8x on a 2-core machine) and whether the
summaries are byte-identical. Cold timings include the cluster's start (a few seconds); warm
ones run the study on a cluster already up, its workers having imported the engine.

``--floors``: a study of ``--campaigns`` seeds predicts, per parameter and alpha range with an
expected Δ, the standard error (RMS of the bootstrap standard errors), the band width and the
probability of being identified; ``--campaigns`` fresh campaigns of the same matrix (seeds
``--fresh-seed`` on) realise them: the standard deviation of the estimates over the fresh
campaigns, their median band width and their share identified. Floors (issue 21): predicted
SE and band width within 20 % of the realised ones, identification probability within 0.1.
With N campaigns the realised standard deviation alone scatters by about 1/√(2(N-1)) (16 % at
N = 20), so the share of rows within 20 % is also printed for a perfect prediction under that
sampling noise (simulated, seeded).

The matrix is ``--matrix`` (default: ``BENCH_MATRIX`` below, 80 maneuvers with the stepwise
selection active at every flap, 30 bootstrap replicates, no diagnosis: about 10 s per campaign
on one core). Studies are written under ``--out`` (default: a temporary folder) and resume.

Run: ``python benchmarks/bench_plan.py --speedup --campaigns 8``,
``python benchmarks/bench_plan.py --floors --campaigns 20``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import polars as pl

from aerodelta.plan import run_plan
from aerodelta.plan.aggregate import KEYS
from aerodelta.plan.engine import open_client

BENCH_MATRIX = """
[campaign]
noise = 1.0
turbulence_mps = 0.5

[effects]
aileron_effectiveness = 1.0
roll_damping = 1.0
dihedral = 1.0
directional_stability = 1.0
rudder_effectiveness = 1.0
lateral_asymmetry = 1.0
"""
for _f in (0, 5, 10, 15, 35):
    BENCH_MATRIX += (
        f"\n[flaps.{_f}]\nstraight = 4\nturning = 4\naccelerated = 4\nasymmetric_thrust = 4\n"
    )
BENCH_MATRIX += "\n[fit]\nbootstrap = 30\n\n[targets]\nalpha_edges_deg = [8, 12, 16, 20, 24]\n"


def _warm(client: object) -> None:
    """Import the engine in every worker before timing (what a running cluster has done)."""

    def load() -> str:
        import aerodelta  # noqa: PLC0415

        return aerodelta.__version__

    client.run(load)  # type: ignore[attr-defined]


def speedup(matrix: Path, campaigns: int, root: Path) -> None:
    """Cold: the whole ``run_plan`` (the cluster started, its workers importing the engine).
    Warm: on a cluster already up and warmed, the study alone (the steady state of a long
    study, where the start-up is paid once)."""
    times, warm = {}, {}
    for w in (1, 2):
        t0 = time.perf_counter()
        run_plan(matrix, campaigns=campaigns, seed=1, out=root / f"w{w}", workers=w, progress=False)
        times[w] = time.perf_counter() - t0
        with open_client(w) as client:
            _warm(client)
            t0 = time.perf_counter()
            run_plan(matrix, campaigns=campaigns, seed=1, out=root / f"warm{w}", workers=w,
                     progress=False, client=client)  # fmt: skip
            warm[w] = time.perf_counter() - t0
        print(f"{w} worker(s): {times[w]:.1f} s for {campaigns} campaigns (cold), "
              f"{warm[w]:.1f} s on a warm cluster", flush=True)  # fmt: skip
    same = all(
        (root / a / "summary.json").read_bytes() == (root / "w1" / "summary.json").read_bytes()
        for a in ("w2", "warm1", "warm2")
    )
    print(f"speed-up 1 -> 2 workers: {times[1] / times[2]:.2f}x cold, {warm[1] / warm[2]:.2f}x "
          f"warm (floor 1.8x); summaries byte-identical: {same}")  # fmt: skip


def _noise_share(n: int, rng: np.random.Generator, trials: int = 20000) -> float:
    """Share of rows whose ratio of two standard deviations, each over n normal draws of the
    same law, is within 20 % of 1: the best a perfect prediction can show at this N."""
    sd = rng.standard_normal((2, trials, n)).std(axis=2, ddof=1)
    return float(np.mean(np.abs(sd[0] / sd[1] - 1.0) <= 0.2))


def _share(x: np.ndarray) -> str:
    return f"median {np.median(x):.2f}, within 20 %: {np.mean(np.abs(x - 1) <= 0.2):.0%}"


def floors(matrix: Path, campaigns: int, fresh_seed: int, root: Path) -> None:
    t0 = time.perf_counter()
    a = run_plan(matrix, campaigns=campaigns, seed=1, out=root / "study", progress=False)
    b = run_plan(matrix, campaigns=campaigns, seed=fresh_seed, out=root / "fresh", progress=False)
    print(f"study seeds 1..{campaigns}, fresh seeds {fresh_seed}..{fresh_seed + campaigns - 1}: "
          f"{time.perf_counter() - t0:.0f} s")  # fmt: skip
    cols = ["se_predicted", "se_bootstrap", "band_width", "p_identified"]
    pa = a.params.select(*KEYS, *cols, "truth_max")
    pb = b.params.select(*KEYS, *[pl.col(c).alias(f"{c}_fresh") for c in cols])
    j = pa.join(pb, on=list(KEYS), how="inner").filter(pl.col("truth_max") > 0)
    both = j.filter(
        (pl.col("p_identified") >= 0.5)
        & (pl.col("p_identified_fresh") >= 0.5)
        & (pl.col("se_predicted_fresh") > 0)
    ).with_columns(
        (pl.col("se_predicted") / pl.col("se_predicted_fresh")).alias("se_ratio"),
        (pl.col("se_bootstrap") / pl.col("se_bootstrap_fresh")).alias("boot_ratio"),
        (pl.col("band_width") / pl.col("band_width_fresh")).alias("band_ratio"),
        (pl.col("se_bootstrap") / pl.col("se_predicted")).alias("boot_over_sd"),
    )
    dp = (j["p_identified"] - j["p_identified_fresh"]).abs().to_numpy()
    noise = _noise_share(campaigns, np.random.default_rng(21))
    print(f"rows with an expected Δ: {j.height}; identified in >= half of both sets: {both.height}")
    print("predicted SE (spread of the study's estimates) / spread of the fresh estimates: "
          f"{_share(both['se_ratio'].to_numpy())} (a perfect prediction: {noise:.0%} within 20 % "
          f"from the sampling noise of two {campaigns}-campaign standard deviations)")  # fmt: skip
    print(f"bootstrap SE, study / fresh: {_share(both['boot_ratio'].to_numpy())}")
    print(f"band width, study / fresh: {_share(both['band_ratio'].to_numpy())}")
    print(f"identification probability |study - fresh|: median {np.median(dp):.3f}, "
          f"max {dp.max():.3f}, within 0.1: {np.mean(dp <= 0.1):.0%}")  # fmt: skip
    print("per coefficient (medians; boot/sd = the fits' bootstrap SE over the spread of the "
          "estimates, 1 = honest):")  # fmt: skip
    per_coef = both.group_by("coefficient").agg(
        pl.len().alias("rows"),
        pl.col("se_ratio").median(),
        pl.col("boot_ratio").median(),
        pl.col("band_ratio").median(),
        pl.col("boot_over_sd").median(),
    )
    print(per_coef.sort("coefficient"))
    print(f"worker peak memory: {max(a.peak_rss_mib, b.peak_rss_mib):.0f} MiB (NaN: all resumed)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speedup", action="store_true")
    ap.add_argument("--floors", action="store_true")
    ap.add_argument("--campaigns", type=int, default=8)
    ap.add_argument("--fresh-seed", type=int, default=1001)
    ap.add_argument("--matrix", type=Path)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        matrix = args.matrix
        if matrix is None:
            matrix = root / "bench_matrix.toml"
            matrix.write_text(BENCH_MATRIX)
        if args.speedup:
            speedup(matrix, args.campaigns, root)
        if args.floors:
            floors(matrix, args.campaigns, args.fresh_seed, root)


if __name__ == "__main__":
    main()
