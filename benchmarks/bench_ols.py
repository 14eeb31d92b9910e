"""OLS with all statistics on a 10⁶ x 12 design: aerodelta vs numpy lstsq vs statsmodels.

Prints the best of 3 wall-clock times for

- ``aerodelta.ols`` (estimates, covariance, standard errors corrected for coloured
  residuals by FFT, t, p, partial F, R², PRESS, PSE, singular values, VIFs);
- bare ``numpy.linalg.lstsq`` (estimates only);
- ``statsmodels.OLS(z, X).fit()`` plus ``.bse`` access (estimates and standard errors);

the time of the coloured-SE part alone (difference of the two aerodelta runs), the
thread count, and the two ratios against their floors: aerodelta no slower than lstsq,
and at least 5x faster than statsmodels.

Run: ``python benchmarks/bench_ols.py [--rows N] [--cols P]``.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

import numpy as np
import statsmodels.api as sm

import aerodelta


def best_of(f: Callable[[], object], repeat: int = 3) -> float:
    """Best wall-clock time of ``repeat`` calls, seconds."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--cols", type=int, default=12)
    ap.add_argument("--seed", type=int, default=20160601)
    args = ap.parse_args()
    n, p = args.rows, args.cols

    rng = np.random.default_rng(args.seed)
    X = np.empty((n, p))
    X[:, 0] = 1.0
    X[:, 1:] = rng.normal(size=(n, p - 1))
    theta = rng.normal(size=p)
    # AR(1) residuals, as equation-error residuals in flight test data are coloured.
    e = rng.normal(size=n) * 0.1
    ar = np.empty(n)
    ar[0] = e[0]
    phi = 0.8
    for i in range(1, n):
        ar[i] = phi * ar[i - 1] + e[i]
    z = X @ theta + ar
    threads = os.environ.get("RAYON_NUM_THREADS") or str(os.cpu_count())
    print(f"design {n} x {p}, seed {args.seed}, threads {threads} (rayon; RAYON_NUM_THREADS)")

    t_ad = best_of(lambda: aerodelta.ols(X, z))
    print(f"aerodelta.ols (all statistics, coloured SE): {t_ad * 1e3:9.1f} ms")
    t_ad0 = best_of(lambda: aerodelta.ols(X, z, colored=False))
    print(f"aerodelta.ols (all but coloured SE):         {t_ad0 * 1e3:9.1f} ms")
    print(f"  coloured-SE part alone (difference):       {(t_ad - t_ad0) * 1e3:9.1f} ms")
    t_np = best_of(lambda: np.linalg.lstsq(X, z, rcond=None))
    print(f"numpy.linalg.lstsq (estimates only):         {t_np * 1e3:9.1f} ms")
    t_sm = best_of(lambda: sm.OLS(z, X).fit().bse)
    print(f"statsmodels OLS().fit() + .bse:              {t_sm * 1e3:9.1f} ms")

    r_np = t_np / t_ad
    r_sm = t_sm / t_ad
    ok_np = "met" if r_np >= 1 else "NOT met"
    ok_sm = "met" if r_sm >= 5 else "NOT met"
    print(f"lstsq / aerodelta       = {r_np:6.2f}  (floor 1.00: {ok_np})")
    print(f"statsmodels / aerodelta = {r_sm:6.2f}  (floor 5.00: {ok_sm})")
    print(
        f"(without coloured SE: lstsq ratio {t_np / t_ad0:.2f}, "
        f"statsmodels ratio {t_sm / t_ad0:.2f})"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
