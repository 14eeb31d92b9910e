"""OLS with all statistics on a 10⁶ x 12 design: aerodelta vs numpy lstsq vs statsmodels.

The design has a constant and 11 normal regressors; the rows are 500 maneuvers of 2000
samples (``--group-rows``) with AR(1) residuals (φ = 0.8) inside each maneuver, independent
between maneuvers. "All statistics" (issue 16) are the conventional ones plus the default
robust errors, the cluster-robust ones with each maneuver a cluster. Prints the best of 3
wall-clock times, all measured in this run, for

- ``aerodelta.ols(X, z, groups=maneuver, colored=False)``, all statistics: estimates,
  conventional covariance and standard errors, cluster-robust CR2 covariance and standard
  errors with Bell-McCaffrey dof, t, p, partial F, R², PRESS, PSE, singular values, VIFs;
- the same with the coloured-residual (SIDPAC ``r_colores``, FFT) errors as well;
- ``aerodelta.ols(X, z)`` (conventional and coloured, no clusters) and
  ``aerodelta.ols(X, z, colored=False)`` (conventional statistics only);
- bare ``numpy.linalg.lstsq`` (estimates only);
- ``statsmodels.OLS(z, X).fit()`` plus ``.bse`` (estimates and conventional errors);
- ``statsmodels.OLS(z, X).fit(cov_type='cluster', cov_kwds={'groups': maneuver})`` plus
  ``.bse``: statsmodels computing the same (its CR1 against aerodelta's CR2, which differ by
  O(p/G); the largest relative difference is printed, ~1e-5 here);

the time of the coloured and cluster-robust parts alone (differences of aerodelta runs), the
thread count, and the ratios against their floors, PASS or FAIL: the issue-16 floor,
statsmodels cluster / aerodelta all statistics >= 5; the same with the coloured errors too
(>= 5); and the earlier ones, lstsq / aerodelta with coloured errors >= 1 and statsmodels
conventional / aerodelta with coloured errors >= 5. Exit status 1 when the issue-16 floor
is not met.

Run: ``python benchmarks/bench_ols.py [--rows N] [--cols P] [--group-rows M]``.
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


def verdict(ratio: float, floor: float) -> str:
    return f"{ratio:6.2f}  (floor {floor:.2f}: {'PASS' if ratio >= floor else 'FAIL'})"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--cols", type=int, default=12)
    ap.add_argument("--group-rows", type=int, default=2000, help="samples per maneuver")
    ap.add_argument("--seed", type=int, default=20160601)
    args = ap.parse_args()
    n, p, m = args.rows, args.cols, args.group_rows

    rng = np.random.default_rng(args.seed)
    X = np.empty((n, p))
    X[:, 0] = 1.0
    X[:, 1:] = rng.normal(size=(n, p - 1))
    theta = rng.normal(size=p)
    # Maneuver id per row; AR(1) residuals (equation-error residuals in flight test data
    # are coloured) restarting at each maneuver: correlated inside, independent between.
    groups = np.arange(n, dtype=np.int64) // m
    e = rng.normal(size=n) * 0.1
    ar = np.empty(n)
    ar[0] = e[0]
    phi = 0.8
    for i in range(1, n):
        ar[i] = (phi * ar[i - 1] if i % m else 0.0) + e[i]
    z = X @ theta + ar
    threads = os.environ.get("RAYON_NUM_THREADS") or str(os.cpu_count())
    ng = int(groups[-1]) + 1
    print(
        f"design {n} x {p}, {ng} maneuvers of {m} rows, seed {args.seed}, "
        f"threads {threads} (rayon; RAYON_NUM_THREADS)"
    )

    cl = {"groups": groups}

    def timed(label: str, f: Callable[[], object]) -> float:
        t = best_of(f)
        print(f"{label:<60} {t * 1e3:9.1f} ms")
        return t

    t_all = timed(
        "aerodelta.ols all statistics (conventional + cluster CR2)",
        lambda: aerodelta.ols(X, z, groups=groups, colored=False),
    )
    t_allc = timed(
        "aerodelta.ols all statistics + coloured SE",
        lambda: aerodelta.ols(X, z, groups=groups),
    )
    t_ad = timed(
        "aerodelta.ols conventional + coloured SE (no clusters)", lambda: aerodelta.ols(X, z)
    )
    t_ad0 = timed(
        "aerodelta.ols conventional statistics only",
        lambda: aerodelta.ols(X, z, colored=False),
    )
    print(f"{'  cluster-SE part alone (difference)':<60} {(t_all - t_ad0) * 1e3:9.1f} ms")
    print(f"{'  coloured-SE part alone (difference)':<60} {(t_ad - t_ad0) * 1e3:9.1f} ms")
    t_np = timed("numpy.linalg.lstsq (estimates only)", lambda: np.linalg.lstsq(X, z, rcond=None))
    t_sm = timed("statsmodels OLS().fit() + .bse", lambda: sm.OLS(z, X).fit().bse)
    t_smc = timed(
        "statsmodels fit(cov_type='cluster') + .bse",
        lambda: sm.OLS(z, X).fit(cov_type="cluster", cov_kwds=cl).bse,
    )

    # Same quantity, two small-sample corrections (CR2 vs CR1): close with 500 maneuvers.
    se_ad = aerodelta.ols(X, z, groups=groups, colored=False).std_err_cluster
    se_sm = sm.OLS(z, X).fit(cov_type="cluster", cov_kwds=cl).bse
    assert se_ad is not None
    dev = float(np.max(np.abs(se_ad / se_sm - 1.0)))
    print(f"cluster SE, max |aerodelta CR2 / statsmodels CR1 - 1| = {dev:.2e}")

    r_cl = t_smc / t_all
    print(f"statsmodels cluster / aerodelta all statistics    = {verdict(r_cl, 5.0)}  [issue 16]")
    print(f"statsmodels cluster / aerodelta all + coloured SE = {verdict(t_smc / t_allc, 5.0)}")
    print(f"lstsq / aerodelta conventional + coloured         = {verdict(t_np / t_ad, 1.0)}")
    print(f"statsmodels / aerodelta conventional + coloured   = {verdict(t_sm / t_ad, 5.0)}")
    print(
        f"(conventional only: lstsq ratio {t_np / t_ad0:.2f}, statsmodels ratio {t_sm / t_ad0:.2f})"
    )
    return 0 if r_cl >= 5.0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
