"""Monte Carlo of straight stalls with the stochastic roll-off (issue 6 benchmark).

Times ``aerodelta.rolloff.monte_carlo(n)`` (engine ``aero_core::rolloff_mc``: rayon over
stalls, summaries only) on all cores and, in the same run, on a one-thread pool
(``threads=1``); prints both, the scaling ratio, the process CPU time per stall (less
sensitive to other load on the machine) and the multi-threaded total against the 60 s
target. Each stall is a full campaign straight stall (trim, approach, stall, recovery;
about 40-60 s of flight at 100 Hz). The single-threaded run flies the first
``n_single`` stalls only (default n / 10) and is extrapolated linearly to ``n``; the
output says so. Same seed: the single-threaded stalls are checked equal to the
multi-threaded ones.

Usage: python benchmarks/bench_rolloff_mc.py [n_stalls=10000] [n_single=n/10]
"""

from __future__ import annotations

import os
import resource
import sys
import time

import numpy as np
import polars as pl

import aerodelta.rolloff as ro

TARGET_S = 60.0


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def timed(n: int, threads: int | None) -> tuple[float, float, pl.DataFrame]:
    """Wall time [s], process CPU time [s] and the result of ``n`` stalls."""
    c0, t0 = _cpu(), time.perf_counter()
    mc = ro.monte_carlo(n, seed=1, flap_deg=0.0, threads=threads)
    return time.perf_counter() - t0, _cpu() - c0, mc


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10_000
    n1 = int(sys.argv[2]) if len(sys.argv) > 2 else max(1, n // 10)
    cores = os.cpu_count() or 1
    ro.monte_carlo(2, seed=1)  # builds the qualified model once (static)
    t_multi, c_multi, mc = timed(n, None)
    bank = mc["max_bank_deg"].to_numpy()
    onset = mc["onset_alpha_deg"].to_numpy()
    print(
        f"{n} stalls: max bank median {np.median(bank):.1f} deg, p95 "
        f"{np.percentile(bank, 95):.1f} deg, > 20 deg {np.mean(bank > 20):.1%}; onset alpha "
        f"{np.nanmean(onset):.2f} +- {np.nanstd(onset):.2f} deg; mean flight "
        f"{mc['duration_s'].mean():.1f} s"
    )
    print(
        f"multi-threaded ({cores} cores): {t_multi:.2f} s ({n / t_multi:.0f} stalls/s), "
        f"CPU {1e3 * c_multi / n:.2f} ms/stall"
    )
    t_one, c_one, mc1 = timed(n1, 1)
    assert mc1.equals(mc.head(n1)), "one thread gave other stalls than all threads"
    t_single = t_one * n / n1
    how = "measured" if n1 == n else f"extrapolated from {n1} stalls x {n / n1:.0f}"
    print(
        f"single-threaded: {t_single:.2f} s ({how}; {n1} stalls took {t_one:.2f} s), "
        f"CPU {1e3 * c_one / n1:.2f} ms/stall; identical stalls: yes"
    )
    print(f"scaling {t_single / t_multi:.2f}x on {cores} cores (ideal {cores}x)")
    verdict = "meets" if t_multi < TARGET_S else "misses"
    print(f"total multi-threaded {t_multi:.1f} s vs target {TARGET_S:.0f} s: {verdict} it")
    load = os.getloadavg()[0]
    print(f"(load average at the end {load:.1f} on {cores} cores)")


if __name__ == "__main__":
    main()
