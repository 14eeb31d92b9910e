"""Time aerodelta.smoothing_spline against the Python csaps package on 10^5 points.

Standalone: ``python benchmarks/bench_spline.py``. Prints each timing (best of several
runs, fit and fit + evaluation at 10^5 points) and the ratio csaps / aerodelta measured in
this run, plus the largest difference between the two fits.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import csaps
import numpy as np

import aerodelta as ad

N = 100_000
REPEAT = 5


def _best(f: Callable[[], object]) -> float:
    times = []
    for _ in range(REPEAT):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    rng = np.random.default_rng(0)
    x = np.cumsum(0.05 + rng.random(N))
    y = np.sin(0.01 * x) + 0.1 * rng.standard_normal(N)
    w = 0.5 + rng.random(N)
    xe = np.sort(rng.uniform(x[0], x[-1], N))
    p = 0.4
    print(f"cubic smoothing spline, n = {N}, p = {p}, weighted; best of {REPEAT}")
    ours = _best(lambda: ad.smoothing_spline(x, y, p=p, weights=w))
    peer = _best(lambda: csaps.CubicSmoothingSpline(x, y, weights=w, smooth=p))
    print(
        f"  fit       aerodelta {ours * 1e3:9.2f} ms   csaps {peer * 1e3:9.2f} ms"
        f"   ratio {peer / ours:6.1f}x"
    )
    ours_e = _best(lambda: ad.smoothing_spline(x, y, p=p, weights=w)(xe))
    peer_e = _best(lambda: csaps.CubicSmoothingSpline(x, y, weights=w, smooth=p)(xe))
    print(
        f"  fit+eval  aerodelta {ours_e * 1e3:9.2f} ms   csaps {peer_e * 1e3:9.2f} ms"
        f"   ratio {peer_e / ours_e:6.1f}x"
    )
    diff = np.abs(
        ad.smoothing_spline(x, y, p=p, weights=w)(xe)
        - csaps.CubicSmoothingSpline(x, y, weights=w, smooth=p)(xe)
    ).max()
    print(f"  max |aerodelta - csaps| at {N} points: {diff:.2e}")


if __name__ == "__main__":
    main()
