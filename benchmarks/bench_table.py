"""4-D batch table lookup on 10^6 points: aerodelta.Table vs scipy RegularGridInterpolator.

Floor (issue 2): aerodelta at least 20x faster than scipy, measured in the same run.
Run: python benchmarks/bench_table.py
"""

from __future__ import annotations

import time

import numpy as np
from scipy.interpolate import RegularGridInterpolator

import aerodelta as ad

FLOOR = 20.0


def best_of(f, repeat: int = 5) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    rng = np.random.default_rng(0)
    bps = [
        np.linspace(-10, 35, 30),  # alpha, deg
        np.linspace(-30, 30, 13),  # beta, deg
        np.array([0.0, 5.0, 10.0, 15.0, 35.0]),  # flap, deg
        np.linspace(-20, 20, 9),  # aileron, deg
    ]
    vals = rng.normal(size=[len(b) for b in bps])
    n = 1_000_000
    pts = np.column_stack([rng.uniform(b[0], b[-1], n) for b in bps])
    cols = [np.ascontiguousarray(pts[:, k]) for k in range(4)]

    ours = ad.Table(bps, vals)
    peer = RegularGridInterpolator(bps, vals)
    np.testing.assert_allclose(ours(*cols), peer(pts), atol=1e-12)

    t_cols = best_of(lambda: ours(*cols))
    t_rows = best_of(lambda: ours.eval_rows(pts))
    t_peer = best_of(lambda: peer(pts), repeat=3)
    print(f"4-D lookup, {n:,} points")
    print(f"  scipy RegularGridInterpolator   {t_peer * 1e3:9.2f} ms")
    print(f"  aerodelta Table (columns)       {t_cols * 1e3:9.2f} ms   {t_peer / t_cols:6.1f}x")
    print(f"  aerodelta Table (rows, N x 4)   {t_rows * 1e3:9.2f} ms   {t_peer / t_rows:6.1f}x")
    ok = t_peer / max(t_cols, t_rows) >= FLOOR
    print(f"  floor {FLOOR:.0f}x faster: {'met' if ok else 'NOT MET'}")


if __name__ == "__main__":
    main()
