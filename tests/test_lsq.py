"""aerodelta.ols against independent references.

- estimates: ``numpy.linalg.lstsq`` (≤1e-10);
- standard errors, R², adjusted R², F, t, p, VIF: statsmodels OLS (≤1e-8 relative);
- NIST StRD Longley: certified parameters, standard errors, residual SD, R², F;
- PRESS: an explicit leave-one-out loop; PSE: its formula (Morelli);
- coloured-residual standard errors: a direct O(N²) numpy implementation of SIDPAC
  ``r_colores`` (Morelli & Klein Eq. 5.80), and a Monte-Carlo check with AR(1) noise;
- t and F distributions: scipy.stats.
"""

from __future__ import annotations

import inspect

import numpy as np
import polars as pl
import pytest
import scipy.stats
import statsmodels.api as sm
from scipy.special import betainc
from statsmodels.stats.outliers_influence import variance_inflation_factor

import aerodelta
from aerodelta import InvalidInputError, TooLittleDataError, _core


def _design(rng: np.random.Generator, n: int, p: int, const: bool) -> np.ndarray:
    x = rng.normal(size=(n, p)) * rng.uniform(0.1, 10.0, size=p) + rng.normal(size=p)
    if const:
        x[:, 0] = 1.0
    return x


def _vif(x: np.ndarray, j: int) -> float:
    """Classic VIF (no standardization; statsmodels >= 0.15 standardizes by default)."""
    if "standardize" in inspect.signature(variance_inflation_factor).parameters:
        return float(variance_inflation_factor(x, j, standardize=False))
    return float(variance_inflation_factor(x, j))


def _rel(a: np.ndarray | float, b: np.ndarray | float) -> float:
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300)))


# --------------------------------------------------------------------------------------
# numpy and statsmodels
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_params_match_numpy_lstsq(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n, p = int(rng.integers(30, 3000)), int(rng.integers(1, 9))
    x = _design(rng, n, p, const=seed % 2 == 0)
    z = x @ rng.normal(size=p) + rng.normal(size=n)
    ref = np.linalg.lstsq(x, z, rcond=None)[0]
    r = aerodelta.ols(x, z)
    np.testing.assert_allclose(r.params, ref, rtol=1e-10, atol=1e-10 * np.max(np.abs(ref)))


@pytest.mark.parametrize(("seed", "const"), [(10, True), (11, False), (12, True), (13, False)])
def test_statistics_match_statsmodels(seed: int, const: bool) -> None:
    rng = np.random.default_rng(seed)
    n, p = 500 + 700 * (seed % 2), 5
    x = _design(rng, n, p, const)
    z = x @ rng.normal(size=p) + rng.normal(size=n) * 0.7
    m = sm.OLS(z, x).fit()
    r = aerodelta.ols(x, z)
    assert r.const_column == (0 if const else None)
    assert _rel(r.params, m.params) < 1e-10
    assert _rel(r.std_err, m.bse) < 1e-8
    assert _rel(r.cov, m.cov_params()) < 1e-8
    assert _rel(r.tvalues, m.tvalues) < 1e-8
    assert _rel(r.pvalues, m.pvalues) < 1e-8
    assert _rel(r.r2, m.rsquared) < 1e-8
    assert _rel(r.r2_adj, m.rsquared_adj) < 1e-8
    assert _rel(r.fvalue, m.fvalue) < 1e-8
    assert _rel(r.f_pvalue, m.f_pvalue) < 1e-8 or m.f_pvalue < 1e-290
    assert _rel(r.s2, m.scale) < 1e-8
    assert _rel(r.ssr, m.ssr) < 1e-8
    assert r.df_resid == int(m.df_resid)
    assert r.df_model == int(m.df_model)
    assert r.nobs == n
    # Partial F, thesis Eq. 2.5, is the square of t.
    assert _rel(r.partial_f, m.tvalues**2) < 1e-8
    vif = [_vif(x, j) for j in range(p)]
    assert _rel(r.vif, vif) < 1e-8
    # Confidence intervals.
    ci = r.conf_int(0.1)
    assert _rel(ci["lower"].to_numpy(), m.conf_int(0.1)[:, 0]) < 1e-8
    assert _rel(ci["upper"].to_numpy(), m.conf_int(0.1)[:, 1]) < 1e-8


def test_singular_values_and_condition_number() -> None:
    rng = np.random.default_rng(5)
    x = _design(rng, 400, 4, const=True)
    z = rng.normal(size=400)
    r = aerodelta.ols(x, z)
    np.testing.assert_allclose(r.singular_values, np.linalg.svd(x, compute_uv=False), rtol=1e-10)
    xs = x / np.linalg.norm(x, axis=0)
    s = np.linalg.svd(xs, compute_uv=False)
    np.testing.assert_allclose(r.singular_values_scaled, s, rtol=1e-10)
    assert _rel(r.condition_number, s[0] / s[-1]) < 1e-9
    assert _rel(r.condition_number_unscaled, np.linalg.cond(x)) < 1e-9
    assert r.rank == 4


# --------------------------------------------------------------------------------------
# NIST StRD Longley (certified values, https://www.itl.nist.gov/div898/strd/lls/data/Longley.shtml)
# --------------------------------------------------------------------------------------
LONGLEY_B = [
    -3482258.63459582,
    15.0618722713733,
    -0.358191792925910e-01,
    -2.02022980381683,
    -1.03322686717359,
    -0.511041056535807e-01,
    1829.15146461355,
]
LONGLEY_SE = [
    890420.383607373,
    84.9149257747669,
    0.334910077722432e-01,
    0.488399681651699,
    0.214274163161675,
    0.226073200069370,
    455.478499142212,
]
LONGLEY_RSD = 304.854073561965
LONGLEY_R2 = 0.995479004577296
LONGLEY_F = 330.285339234588
LONGLEY_RSS = 836424.055505915


def test_longley_certified_values() -> None:
    data = sm.datasets.longley.load()
    exog = np.asarray(data.exog, dtype=float)
    x = np.column_stack([np.ones(len(exog)), exog])
    z = np.asarray(data.endog, dtype=float)
    names = ["const", *[str(c) for c in data.exog.columns]]
    r = aerodelta.ols(x, z, names=names)
    # Certified values carry 15 significant digits; QR reaches ~1e-9 on Longley.
    assert _rel(r.params, LONGLEY_B) < 1e-8
    assert _rel(r.std_err, LONGLEY_SE) < 1e-8
    assert _rel(np.sqrt(r.s2), LONGLEY_RSD) < 1e-9
    assert _rel(r.r2, LONGLEY_R2) < 1e-10
    assert _rel(r.fvalue, LONGLEY_F) < 1e-8
    assert _rel(r.ssr, LONGLEY_RSS) < 1e-9
    assert r.df_resid == 9
    # Longley is ill conditioned but identifiable at the default threshold.
    assert r.condition_number > 100
    assert r.identifiable.all()


# --------------------------------------------------------------------------------------
# PRESS, PSE, fit error
# --------------------------------------------------------------------------------------
def test_press_pse_fit_error_against_definitions() -> None:
    rng = np.random.default_rng(21)
    n, p = 80, 4
    x = _design(rng, n, p, const=True)
    z = x @ rng.normal(size=p) + rng.normal(size=n)
    r = aerodelta.ols(x, z)
    press = 0.0
    for i in range(n):
        keep = np.arange(n) != i
        th = np.linalg.lstsq(x[keep], z[keep], rcond=None)[0]
        press += (z[i] - x[i] @ th) ** 2
    assert _rel(r.press, press) < 1e-9
    resid = z - x @ np.linalg.lstsq(x, z, rcond=None)[0]
    sig2_max = np.mean((z - z.mean()) ** 2)
    pse = np.mean(resid**2) + sig2_max * p / n
    assert _rel(r.pse, pse) < 1e-10
    fe = 100.0 * np.sqrt(np.mean(resid**2)) / np.sqrt(np.mean(z**2))
    assert _rel(r.fit_error_pct, fe) < 1e-10
    assert abs(r.residual_mean) < 1e-12 * np.abs(z).max()


# --------------------------------------------------------------------------------------
# Coloured residuals (Morelli & Klein Eq. 5.80; SIDPAC r_colores)
# --------------------------------------------------------------------------------------
def _r_colores_direct(x: np.ndarray, z: np.ndarray, max_lag: int | None = None) -> np.ndarray:
    """Direct O(N²) transcription of the r_colores formula (biased xcorr, no mean removal)."""
    n = len(z)
    xtxi = np.linalg.inv(x.T @ x)
    v = z - x @ (xtxi @ x.T @ z)
    rvv = np.array([v[: n - k] @ v[k:] / n for k in range(n)])
    lag = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    t = rvv[lag]
    if max_lag is not None:
        t[lag > max_lag] = 0.0
    cov = xtxi @ x.T @ t @ x @ xtxi
    return np.sqrt(np.diag(cov))


def _ar1(rng: np.random.Generator, n: int, phi: float, sigma: float) -> np.ndarray:
    e = rng.normal(size=n) * sigma
    out = np.empty(n)
    out[0] = e[0] / np.sqrt(1 - phi**2)
    for i in range(1, n):
        out[i] = phi * out[i - 1] + e[i]
    return out


@pytest.mark.parametrize("max_lag", [None, 0, 7, 40])
def test_colored_std_err_matches_direct_double_sum(max_lag: int | None) -> None:
    rng = np.random.default_rng(31)
    n = 300
    t = np.arange(n) * 0.02
    x = np.column_stack([np.ones(n), np.sin(2.1 * t), np.cos(0.7 * t) + 0.1 * rng.normal(size=n)])
    z = x @ [0.1, -0.5, 0.3] + _ar1(rng, n, 0.9, 0.05)
    r = aerodelta.ols(x, z, max_lag=max_lag)
    ref = _r_colores_direct(x, z, max_lag)
    assert r.std_err_corrected is not None
    assert _rel(r.std_err_corrected, ref) < 1e-9


def test_colored_std_err_closer_to_monte_carlo_spread() -> None:
    """With AR(1) residuals the corrected SEs track the true scatter, conventional ones do not."""
    rng = np.random.default_rng(41)
    n, trials = 400, 150
    t = np.arange(n) * 0.05
    x = np.column_stack([np.ones(n), np.sin(0.9 * t), np.cos(0.35 * t)])
    theta = np.array([0.2, 1.0, -0.4])
    est, se_conv, se_corr = [], [], []
    for _ in range(trials):
        z = x @ theta + _ar1(rng, n, 0.95, 0.02)
        r = aerodelta.ols(x, z)
        est.append(r.params)
        se_conv.append(r.std_err)
        se_corr.append(r.std_err_corrected)
    spread = np.std(np.array(est), axis=0, ddof=1)
    conv = np.mean(np.array(se_conv), axis=0)
    corr = np.mean(np.array(se_corr), axis=0)
    # Slope parameters (the intercept's r_colores SE is known to collapse when the
    # residuals have zero mean, so it is not used here).
    for j in (1, 2):
        assert abs(np.log(corr[j] / spread[j])) < abs(np.log(conv[j] / spread[j]))
        assert conv[j] < 0.6 * spread[j]  # conventional SEs are optimistic here


def test_colored_can_be_turned_off() -> None:
    rng = np.random.default_rng(3)
    x = _design(rng, 50, 2, const=True)
    r = aerodelta.ols(x, rng.normal(size=50), colored=False)
    assert r.std_err_corrected is None
    assert r.summary()["std_err_corrected"].is_nan().all()


# --------------------------------------------------------------------------------------
# Rank deficiency, collinearity, NaN rows
# --------------------------------------------------------------------------------------
def test_duplicate_column_is_refused_with_its_names() -> None:
    rng = np.random.default_rng(51)
    x = _design(rng, 60, 3, const=True)
    x = np.column_stack([x, x[:, 1]])
    z = rng.normal(size=60)
    names = ["bias", "beta", "p_hat", "beta_copy"]
    with pytest.raises(TooLittleDataError) as ei:
        aerodelta.ols(x, z, names=names)
    msg = str(ei.value)
    assert "'beta'" in msg and "'beta_copy'" in msg and "'p_hat'" not in msg
    r = aerodelta.ols(x, z, names=names, min_norm=True)
    np.testing.assert_allclose(r.params, np.linalg.lstsq(x, z, rcond=None)[0], rtol=1e-9)
    assert r.rank == 3
    assert list(r.identifiable) == [True, False, True, False]
    assert "linearly dependent" in r.notes[1] and "'beta_copy'" in r.notes[1]


def test_sum_of_two_columns_is_refused_with_its_names() -> None:
    rng = np.random.default_rng(52)
    x = _design(rng, 60, 4, const=True)
    x[:, 3] = x[:, 1] + x[:, 2]
    with pytest.raises(TooLittleDataError) as ei:
        aerodelta.ols(x, rng.normal(size=60), names=["c", "a", "b", "a_plus_b"])
    msg = str(ei.value)
    assert all(f"'{c}'" in msg for c in ("a", "b", "a_plus_b")) and "'c'" not in msg


def test_near_collinear_reported_not_silent() -> None:
    rng = np.random.default_rng(53)
    n = 200
    x = _design(rng, n, 4, const=True)
    x[:, 3] = x[:, 1] - 2 * x[:, 2] + 1e-8 * rng.normal(size=n)
    z = x[:, :3] @ [1.0, 2.0, 3.0] + 0.01 * rng.normal(size=n)
    r = aerodelta.ols(x, z, names=["c", "alpha", "beta", "combo"])
    assert r.condition_number > 1e6
    assert not r.identifiable[1:].any()
    assert r.identifiable[0]
    deps = r.dependencies
    assert len(deps) == 1 and set(deps[0][1]) == {"alpha", "beta", "combo"}
    assert deps[0][0] > 1e6
    assert all("near-collinear" in r.notes[j] for j in (1, 2, 3))
    assert (r.vif[1:] > 1e10).all()
    # The coloured correction is computed through Q: no cancellation to zero.
    ratio = r.std_err_corrected / r.std_err
    assert np.all((ratio > 0.3) & (ratio < 3.0))
    # The summary carries the same verdict.
    s = r.summary()
    assert s["identifiable"].to_list() == [True, False, False, False]


def test_nan_rows_rejected_with_indices_or_dropped() -> None:
    rng = np.random.default_rng(61)
    n = 100
    x = _design(rng, n, 3, const=True)
    z = x @ [1.0, -1.0, 0.5] + 0.1 * rng.normal(size=n)
    x[5, 2] = np.nan
    z[42] = np.nan
    with pytest.raises(InvalidInputError) as ei:
        aerodelta.ols(x, z, names=["bias", "beta", "dr"])
    msg = str(ei.value)
    assert "row 5 (column 'dr')" in msg and "row 42 (z)" in msg and "drop_nan" in msg
    r = aerodelta.ols(x, z, drop_nan=True)
    assert r.dropped_rows == [5, 42]
    assert r.nobs == n - 2
    keep = np.isfinite(z) & np.isfinite(x).all(axis=1)
    np.testing.assert_allclose(r.params, np.linalg.lstsq(x[keep], z[keep], rcond=None)[0])


def test_too_few_rows_and_bad_shapes() -> None:
    with pytest.raises(TooLittleDataError):
        aerodelta.ols(np.ones((2, 2)), [1.0, 2.0])
    with pytest.raises(InvalidInputError):
        aerodelta.ols(np.ones((5, 2)), np.ones(4))
    with pytest.raises(InvalidInputError):
        aerodelta.ols(np.ones(5), np.ones(5))


# --------------------------------------------------------------------------------------
# Row subsets, polars input, result object
# --------------------------------------------------------------------------------------
def test_rows_subset_equals_fit_on_copy() -> None:
    rng = np.random.default_rng(71)
    x = _design(rng, 5000, 4, const=True)
    z = x @ rng.normal(size=4) + rng.normal(size=5000)
    rows = np.flatnonzero(x[:, 1] > 0.3)
    a = aerodelta.ols(x, z, rows=rows)
    b = aerodelta.ols(x[rows], z[rows])
    np.testing.assert_array_equal(a.params, b.params)
    np.testing.assert_array_equal(a.std_err_corrected, b.std_err_corrected)
    assert a.nobs == len(rows)


def test_polars_input_names_summary_and_immutability() -> None:
    rng = np.random.default_rng(81)
    n = 120
    df = pl.DataFrame({"bias": np.ones(n), "beta": rng.normal(size=n), "p_hat": rng.normal(size=n)})
    z = pl.Series("dCn", 0.1 + 0.2 * df["beta"].to_numpy() + 0.01 * rng.normal(size=n))
    r = aerodelta.ols(df, z)
    assert r.names == ["bias", "beta", "p_hat"]
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
    assert s.height == 3
    text = str(r)
    assert "R²" in text and "beta" in text and "PRESS" in text
    with pytest.raises(AttributeError):
        r.params = np.zeros(3)  # type: ignore[misc]
    with pytest.raises(TypeError):
        aerodelta.OLSResults()


# --------------------------------------------------------------------------------------
# Distributions vs scipy
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("df", [1.0, 2.5, 9.0, 30.0, 1000.0])
def test_student_t_against_scipy(df: float) -> None:
    for t in [-40.0, -3.0, -0.5, 0.0, 0.2, 1.7, 6.0, 25.0]:
        assert _rel(_core.student_t_cdf(t, df), scipy.stats.t.cdf(t, df)) < 1e-11
    for q in [0.001, 0.025, 0.3, 0.5, 0.9, 0.975, 0.9999]:
        ref = scipy.stats.t.ppf(q, df)
        assert abs(_core.student_t_ppf(q, df) - ref) <= 1e-9 * max(1.0, abs(ref))


@pytest.mark.parametrize(("d1", "d2"), [(1.0, 1.0), (3.0, 10.0), (12.0, 500.0), (0.5, 7.0)])
def test_f_against_scipy(d1: float, d2: float) -> None:
    for f in [1e-4, 0.3, 1.0, 2.5, 10.0, 200.0]:
        assert _rel(_core.f_cdf(f, d1, d2), scipy.stats.f.cdf(f, d1, d2)) < 1e-11
        assert _rel(_core.f_sf(f, d1, d2), scipy.stats.f.sf(f, d1, d2)) < 1e-10


def test_incomplete_beta_against_scipy() -> None:
    for a, b in [(0.5, 0.5), (2.0, 3.0), (10.0, 0.7), (150.0, 80.0)]:
        for x in [1e-3, 0.2, 0.5, 0.66, 0.97]:
            assert _rel(_core.beta_inc_reg(a, b, x), betainc(a, b, x)) < 1e-11 or (
                betainc(a, b, x) < 1e-280
            )


def test_min_norm_truncates_the_directions_the_rank_was_counted_on() -> None:
    # an exact dependency (x3 = 1e6 x1) beside a column at 1e-12 scale: the rank (3 of 4) is
    # counted on the column-normalized X, so the solution keeps the tiny column's direction and
    # drops the null one; truncating the unscaled SVD would do the opposite
    rng = np.random.default_rng(7)
    n = 200
    x1, x2 = rng.normal(size=n), rng.normal(size=n)
    x = np.column_stack([np.ones(n), x1, 1e-12 * x2, 1e6 * x1])
    z = 0.5 + 2.0 * x1 + 3.0 * x2 + 0.01 * rng.normal(size=n)
    r = aerodelta.ols(x, z, min_norm=True)
    norms = np.linalg.norm(x, axis=0)
    ref = np.linalg.lstsq(x / norms, z, rcond=None)[0] / norms
    np.testing.assert_allclose(r.params, ref, rtol=1e-7)
    assert r.rank == 3
    # the tiny column's parameter is the one the data determine: 3 per unit of x2 / 1e-12
    assert abs(r.params[2] * 1e-12 - 3.0) < 0.01
