"""aerodelta.ols(..., groups=g): cluster-robust CR2 errors against independent references.

- a closed-form numpy CR2 (Bell & McCaffrey 2002; Imbens & Kolesár 2016 Eq. 6-8): the meat
  uses ``(I - H_gg)^(-1/2) e_g`` with the full hat matrix blocks and ``scipy.linalg.eigh``,
  and the Bell-McCaffrey dof from the ``n x G`` matrix ``G`` (≤1e-8 relative);
- statsmodels ``OLS(...).fit(cov_type='cluster')`` is CR1 (``G/(G-1) (N-1)/(N-k)`` times
  CR0): on a large balanced design with many clusters it agrees with CR2 within a few %;
- with one row per group CR2 is HC2 exactly: statsmodels ``cov_type='HC2'`` (≤1e-8);
- bad ``groups`` are refused naming the argument.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
import scipy.linalg
import scipy.stats
import statsmodels.api as sm
from threadpoolctl import threadpool_limits

import aerodelta
from aerodelta import InvalidInputError, TooLittleDataError


def _rel(a: np.ndarray | float, b: np.ndarray | float) -> float:
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300)))


def _clustered(
    rng: np.random.Generator,
    sizes: list[int],
    p: int,
    rho: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Design with a constant, slow AR(1) regressors at a per-cluster level and AR(1)
    residuals inside each cluster; ids are arbitrary (not 0..G-1, not sorted)."""
    xs, zs, gs = [], [], []
    theta = rng.normal(size=p)
    ids = rng.permutation(10 * len(sizes))[: len(sizes)] * 7 - 31
    for gid, m in zip(ids, sizes, strict=True):
        x = np.empty((m, p))
        x[:, 0] = 1.0
        lvl = rng.normal(size=p - 1)
        a = rng.normal(size=p - 1)
        e = np.empty(m)
        ei = rng.normal()
        for i in range(m):
            a = 0.9 * a + 0.44 * rng.normal(size=p - 1)
            x[i, 1:] = lvl + a
            ei = rho * ei + np.sqrt(1.0 - rho * rho) * rng.normal()
            e[i] = ei
        xs.append(x)
        zs.append(x @ theta + 0.3 * e)
        gs.append(np.full(m, gid))
    return np.vstack(xs), np.concatenate(zs), np.concatenate(gs)


def _cr2_reference(x: np.ndarray, z: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Textbook CR2 covariance and Bell-McCaffrey dof with the full ``n x n`` hat matrix."""
    n, p = x.shape
    m = np.linalg.inv(x.T @ x)
    e = z - x @ np.linalg.lstsq(x, z, rcond=None)[0]
    h = x @ m @ x.T
    meat = np.zeros((p, p))
    blocks = []
    for c in np.unique(g):
        idx = np.flatnonzero(g == c)
        w, v = scipy.linalg.eigh(np.eye(idx.size) - h[np.ix_(idx, idx)])
        a = (v / np.sqrt(w)) @ v.T  # (I - H_gg)^(-1/2)
        u = x[idx].T @ (a @ e[idx])
        meat += np.outer(u, u)
        blocks.append((idx, a))
    cov = m @ meat @ m
    ih = np.eye(n) - h
    dof = np.empty(p)
    for j in range(p):
        gm = np.column_stack([ih[:, idx] @ (a @ (x[idx] @ m[:, j])) for idx, a in blocks])
        lam = np.linalg.eigvalsh(gm.T @ gm)
        dof[j] = lam.sum() ** 2 / (lam**2).sum()
    return cov, dof


@pytest.mark.parametrize(("seed", "rho"), [(1, 0.9), (2, 0.0), (3, 0.5)])
def test_cr2_and_dof_equal_the_closed_form(seed: int, rho: float) -> None:
    rng = np.random.default_rng(seed)
    sizes = [int(v) for v in rng.integers(15, 60, size=7)]
    x, z, g = _clustered(rng, sizes, 4, rho)
    # Rows of a cluster need not be contiguous: shuffle them.
    perm = rng.permutation(len(z))
    x, z, g = x[perm], z[perm], g[perm]
    cov_ref, dof_ref = _cr2_reference(x, z, g)
    r = aerodelta.ols(x, z, groups=g)
    assert r.n_groups == 7
    assert r.cov_cluster is not None and r.std_err_cluster is not None
    assert r.dof_cluster is not None
    assert _rel(r.cov_cluster, cov_ref) < 1e-8
    assert _rel(r.std_err_cluster, np.sqrt(np.diag(cov_ref))) < 1e-8
    assert _rel(r.dof_cluster, dof_ref) < 1e-8
    assert np.all((r.dof_cluster > 1.0) & (r.dof_cluster <= 6.0 + 1e-9))
    assert r.notes_cluster == ["", "", "", ""]
    # The conventional statistics are those of the fit without groups.
    r0 = aerodelta.ols(x, z)
    np.testing.assert_array_equal(r.params, r0.params)
    np.testing.assert_array_equal(r.std_err, r0.std_err)
    assert r0.std_err_cluster is None and r0.dof_cluster is None and r0.n_groups is None


@pytest.mark.slow
def test_a_cluster_longer_than_one_block_equals_the_closed_form() -> None:
    """The engine accumulates a cluster's Gram in blocks of 2048 rows: a cluster of 2100
    rows spread over the record (not contiguous) against the closed form (a 2100 x 2100
    eigh; one BLAS thread, which is ~5x faster than several on a loaded 2-core machine)."""
    rng = np.random.default_rng(4)
    x, z, g = _clustered(rng, [2100, 150, 120, 90], 3, 0.6)
    perm = rng.permutation(len(z))
    x, z, g = x[perm], z[perm], g[perm]
    with threadpool_limits(limits=1):
        cov_ref, dof_ref = _cr2_reference(x, z, g)
    r = aerodelta.ols(x, z, groups=g, colored=False)
    assert _rel(r.cov_cluster, cov_ref) < 1e-8
    assert _rel(r.dof_cluster, dof_ref) < 1e-8


def test_large_balanced_cr2_agrees_with_statsmodels_cr1() -> None:
    """CR1 and CR2 differ by O(p/G) (the clusters' leverage): with G = 200 balanced clusters
    of 100 rows they agree within a few %; they are not the same estimator."""
    rng = np.random.default_rng(7)
    x, z, g = _clustered(rng, [100] * 200, 4, 0.8)
    r = aerodelta.ols(x, z, groups=g)
    # statsmodels passes integer ids straight to numpy.bincount (negative ids raise): give
    # it 0..G-1.
    gi = np.unique(g, return_inverse=True)[1]
    m = sm.OLS(z, x).fit(cov_type="cluster", cov_kwds={"groups": gi, "use_correction": True})
    assert r.std_err_cluster is not None
    rel = np.abs(r.std_err_cluster / m.bse - 1.0)
    assert rel.max() < 0.03, rel
    # Both are far from the conventional errors under AR(1) residuals (the test bites).
    assert np.all(r.std_err_cluster > 1.5 * r.std_err)
    # CR0 (no correction) times G/(G-1) (N-1)/(N-k) is statsmodels' CR1: check our reading.
    m0 = sm.OLS(z, x).fit(cov_type="cluster", cov_kwds={"groups": gi, "use_correction": False})
    n, k, ng = len(z), x.shape[1], 200
    assert _rel(m.bse**2, m0.bse**2 * ng / (ng - 1) * (n - 1) / (n - k)) < 1e-10


@pytest.mark.parametrize("seed", [11, 12])
def test_singleton_groups_equal_statsmodels_hc2(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n, p = 300, 5
    x = rng.normal(size=(n, p)) * rng.uniform(0.5, 5.0, size=p)
    x[:, 0] = 1.0
    x[:5, 1] *= 8.0  # a few high-leverage rows, so HC2 differs from HC0/HC1
    z = x @ rng.normal(size=p) + rng.normal(size=n) * (0.2 + np.abs(x[:, 2]))
    g = rng.permutation(n) - 100  # one row per group, arbitrary ids
    r = aerodelta.ols(x, z, groups=g)
    m = sm.OLS(z, x).fit(cov_type="HC2")
    assert r.n_groups == n
    assert _rel(r.cov_cluster, m.cov_params()) < 1e-8
    assert _rel(r.std_err_cluster, m.bse) < 1e-8
    # And not HC0/HC1 (the comparison can tell them apart).
    assert _rel(r.std_err_cluster, sm.OLS(z, x).fit(cov_type="HC1").bse) > 1e-4


def test_id_labels_rows_subset_and_dropped_rows() -> None:
    rng = np.random.default_rng(21)
    x, z, g = _clustered(rng, [40] * 9, 3, 0.7)
    r = aerodelta.ols(x, z, groups=g)
    # Other labels (float ids, a polars Series, unsigned, another order) change nothing
    # but the order of summation over clusters.
    relabel = {v: i for i, v in enumerate(rng.permutation(np.unique(g)))}
    for gg in (
        g.astype(float),
        pl.Series("maneuver", g),
        (g - g.min()).astype(np.uint32),
        np.array([relabel[v] for v in g]),
    ):
        rr = aerodelta.ols(x, z, groups=gg)
        assert _rel(rr.cov_cluster, r.cov_cluster) < 1e-12
        assert _rel(rr.dof_cluster, r.dof_cluster) < 1e-12
    # A row subset equals the fit on the copy, the groups taken on the subset.
    rows = np.flatnonzero(rng.uniform(size=len(z)) < 0.6)
    a = aerodelta.ols(x, z, rows=rows, groups=g)
    b = aerodelta.ols(x[rows], z[rows], groups=g[rows])
    assert a.std_err_cluster is not None and b.std_err_cluster is not None
    assert _rel(a.std_err_cluster, b.std_err_cluster) < 1e-12
    # drop_nan: the dropped rows do not count, a cluster emptied by it disappears.
    xn = x.copy()
    xn[g == g[0], 1] = np.nan
    c = aerodelta.ols(xn, z, groups=g, drop_nan=True)
    keep = g != g[0]
    d = aerodelta.ols(x[keep], z[keep], groups=g[keep])
    assert c.n_groups == 8
    assert _rel(c.std_err_cluster, d.std_err_cluster) < 1e-12
    assert _rel(c.cov_cluster, _cr2_reference(x[keep], z[keep], g[keep])[0]) < 1e-8


def test_summary_str_and_cluster_intervals() -> None:
    rng = np.random.default_rng(31)
    x, z, g = _clustered(rng, [50] * 10, 3, 0.8)
    r = aerodelta.ols(x, z, names=["bias", "alpha", "q_hat"], groups=g)
    s = r.summary()
    assert s.columns == [
        "name",
        "estimate",
        "std_err",
        "std_err_corrected",
        "std_err_cluster",
        "dof_cluster",
        "t",
        "p",
        "ci_lo",
        "ci_hi",
        "partial_f",
        "vif",
        "identifiable",
        "note",
    ]
    assert r.std_err_cluster is not None and r.dof_cluster is not None
    np.testing.assert_array_equal(s["std_err_cluster"].to_numpy(), r.std_err_cluster)
    np.testing.assert_array_equal(s["dof_cluster"].to_numpy(), r.dof_cluster)
    text = str(r)
    assert "10 groups" in text and "se_clust" in text and "dof_cl" in text
    ci = r.conf_int(0.1, cluster=True)
    q = scipy.stats.t.ppf(0.95, r.dof_cluster)
    assert _rel(ci["lower"].to_numpy(), r.params - q * r.std_err_cluster) < 1e-10
    assert _rel(ci["upper"].to_numpy(), r.params + q * r.std_err_cluster) < 1e-10
    # Without groups the columns are NaN and the cluster interval is refused.
    r0 = aerodelta.ols(x, z)
    assert r0.summary()["std_err_cluster"].is_nan().all()
    assert "se_clust" not in str(r0)
    with pytest.raises(InvalidInputError, match="without groups"):
        r0.conf_int(cluster=True)
    with pytest.raises(InvalidInputError, match="not both"):
        r.conf_int(corrected=True, cluster=True)


def test_one_cluster_carrying_a_regressor_is_nan_with_its_reason() -> None:
    rng = np.random.default_rng(41)
    g = np.repeat(np.arange(5), 30)
    x = np.column_stack([np.ones(150), np.zeros(150), rng.normal(size=150)])
    x[g == 0, 1] = np.sin(0.3 * np.arange(30))
    z = 0.1 + x[:, 1] + 0.5 * x[:, 2] + 0.1 * rng.normal(size=150)
    r = aerodelta.ols(x, z, names=["bias", "dl", "beta"], groups=g)
    assert r.std_err_cluster is not None and r.cov_cluster is not None
    assert r.notes_cluster is not None
    assert np.isnan(r.std_err_cluster[1]) and np.isnan(r.cov_cluster[1]).all()
    assert np.isfinite(r.std_err_cluster[2])
    assert "one maneuver" in r.notes_cluster[1]
    assert "one maneuver" in r.summary()["note"][1]
    assert np.isnan(r.conf_int(cluster=True)["lower"][1])


# --------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------
def _small() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(51)
    x = np.column_stack([np.ones(40), rng.normal(size=40)])
    z = x @ [1.0, 2.0] + rng.normal(size=40)
    return x, z, np.repeat(np.arange(4), 10)


def test_groups_of_the_wrong_length_or_shape_are_refused() -> None:
    x, z, g = _small()
    with pytest.raises(InvalidInputError, match=r"argument 'groups': has 39 values but X has 40"):
        aerodelta.ols(x, z, groups=g[:-1])
    with pytest.raises(InvalidInputError, match=r"argument 'groups': must be 1-D"):
        aerodelta.ols(x, z, groups=g.reshape(20, 2))
    with pytest.raises(InvalidInputError, match=r"argument 'groups': must be 1-D"):
        aerodelta.ols(x, z, groups=3)


def test_nan_non_integer_and_non_numeric_groups_are_refused() -> None:
    x, z, g = _small()
    gf = g.astype(float)
    gf[[3, 17]] = np.nan
    with pytest.raises(InvalidInputError, match=r"argument 'groups': 2 NaN/inf .*\[3, 17\]"):
        aerodelta.ols(x, z, groups=gf)
    # A polars integer column with a null arrives as NaN: refused the same way.
    with pytest.raises(InvalidInputError, match=r"argument 'groups': 1 NaN/inf"):
        aerodelta.ols(x, z, groups=pl.Series("m", [*g[:-1].tolist(), None]))
    with pytest.raises(InvalidInputError, match=r"argument 'groups': not integer"):
        aerodelta.ols(x, z, groups=g + 0.5)
    with pytest.raises(InvalidInputError, match=r"argument 'groups': must be integer"):
        aerodelta.ols(x, z, groups=np.array([f"m{v}" for v in g]))
    with pytest.raises(InvalidInputError, match=r"argument 'groups': must be integer"):
        aerodelta.ols(x, z, groups=g > 1)


def test_fewer_than_two_groups_are_refused() -> None:
    x, z, g = _small()
    with pytest.raises(TooLittleDataError, match=r"argument 'groups': .* in 1 group"):
        aerodelta.ols(x, z, groups=np.zeros(40, dtype=int))
    # Also when only the fitted rows fall in one group (row subset, dropped rows).
    with pytest.raises(TooLittleDataError, match=r"argument 'groups': the 10 fitted rows"):
        aerodelta.ols(x, z, rows=np.arange(10), groups=g)
    xn = x.copy()
    xn[10:, 1] = np.nan
    with pytest.raises(TooLittleDataError, match=r"argument 'groups'"):
        aerodelta.ols(xn, z, groups=g, drop_nan=True)
