"""Monte Carlo of straight stalls with the stochastic roll-off (issue 6 benchmark).

Times ``aerodelta.rolloff.monte_carlo(n)`` with all cores (rayon) and, in the same run, in a
subprocess with ``RAYON_NUM_THREADS=1``; prints both, the scaling ratio and the total against
the 60 s target. Each stall is a full campaign straight stall (trim, approach, stall, recovery;
about 40-60 s of flight at 100 Hz).

Usage: python benchmarks/bench_rolloff_mc.py [n_stalls=10000]
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import numpy as np

import aerodelta.rolloff as ro

TARGET_S = 60.0


def run(n: int) -> float:
    t0 = time.perf_counter()
    mc = ro.monte_carlo(n, seed=1, flap_deg=0.0)
    dt = time.perf_counter() - t0
    bank = mc["max_bank_deg"].to_numpy()
    onset = mc["onset_alpha_deg"].to_numpy()
    print(
        f"  {n} stalls: max bank median {np.median(bank):.1f} deg, "
        f"p95 {np.percentile(bank, 95):.1f} deg, > 20 deg {np.mean(bank > 20):.1%}; "
        f"onset alpha {np.nanmean(onset):.2f} +- {np.nanstd(onset):.2f} deg"
    )
    return dt


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10_000
    if os.environ.get("_BENCH_CHILD"):
        print(f"{run(n):.6f}")
        return
    cores = os.cpu_count() or 1
    t_multi = run(n)
    print(f"multi-threaded ({cores} cores): {t_multi:.2f} s ({n / t_multi:.0f} stalls/s)")
    env = dict(os.environ, RAYON_NUM_THREADS="1", _BENCH_CHILD="1")
    out = subprocess.run(
        [sys.executable, __file__, str(n)], env=env, capture_output=True, text=True, check=True
    )
    t_single = float(out.stdout.strip().splitlines()[-1])
    print(f"single-threaded: {t_single:.2f} s")
    print(f"scaling {t_single / t_multi:.2f}x on {cores} cores (ideal {cores}x)")
    print(f"total multi-threaded {t_multi:.1f} s vs target {TARGET_S:.0f} s")


if __name__ == "__main__":
    main()
