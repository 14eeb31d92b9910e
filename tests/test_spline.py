"""aerodelta.smoothing_spline against the Python ``csaps`` package (MATLAB csaps semantics,
thesis Eq. 3.13) and against closed forms (p = 0: weighted least-squares line; p = 1:
interpolation)."""

from __future__ import annotations

import doctest

import csaps
import numpy as np
import pytest

import aerodelta as ad
import aerodelta.spline

RTOL = 1e-10


def _data(seed: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = 4.0 + np.cumsum(0.05 + rng.random(n))
    y = np.sin(x) + 0.2 * rng.standard_normal(n)
    w = 0.2 + 2.0 * rng.random(n)
    return x, y, w


def _close(a: np.ndarray, ref: np.ndarray, rtol: float = RTOL) -> None:
    scale = max(1.0, float(np.abs(ref).max()))
    np.testing.assert_allclose(a, ref, rtol=0, atol=rtol * scale)


@pytest.mark.parametrize("n", [3, 4, 11, 60])
@pytest.mark.parametrize("p", [0.0, 0.05, 0.4, 0.9, 1.0, None])
@pytest.mark.parametrize("weighted", [False, True])
def test_matches_csaps(n: int, p: float | None, weighted: bool) -> None:
    x, y, w = _data(n + 7, n)
    wt = w if weighted else None
    ref = csaps.CubicSmoothingSpline(x, y, weights=wt, smooth=p)
    s = ad.smoothing_spline(x, y, p=p, weights=wt)
    assert s.p == pytest.approx(ref.smooth, rel=1e-14, abs=1e-15)
    np.testing.assert_array_equal(s.breaks, ref.spline.breaks)
    assert s.coefs.shape == ref.spline.coeffs.shape
    for row in range(4):
        _close(s.coefs[row], ref.spline.coeffs[row])
    # Inside, at the sites, and outside on both sides (csaps extrapolates the end pieces).
    xe = np.concatenate([np.linspace(x[0] - 3.0, x[-1] + 3.0, 301), x])
    for nu in range(4):
        _close(s(xe, nu), ref(xe, nu=nu))


@pytest.mark.parametrize("s_norm", [None, 0.3, 0.8])
def test_normalized_smooth_matches_csaps(s_norm: float | None) -> None:
    x, y, w = _data(3, 40)
    ref = csaps.CubicSmoothingSpline(x, y, weights=w, smooth=s_norm, normalizedsmooth=True)
    s = ad.smoothing_spline(x, y, p=s_norm, weights=w, normalized=True)
    assert s.p == pytest.approx(ref.smooth, rel=1e-13)
    xe = np.linspace(x[0] - 1.0, x[-1] + 1.0, 200)
    _close(s(xe), ref(xe))


def test_two_points_is_the_line_like_csaps() -> None:
    x, y = np.array([1.0, 3.0]), np.array([2.0, -1.0])
    ref = csaps.CubicSmoothingSpline(x, y, smooth=0.4)
    s = ad.smoothing_spline(x, y, p=0.4)
    assert s.p == ref.smooth == 1.0
    xe = np.linspace(-1.0, 5.0, 13)
    _close(s(xe), ref(xe))
    _close(s(xe, 1), np.full(xe.shape, -1.5))


@pytest.mark.parametrize("n", [5, 200, 3000])
def test_p0_is_weighted_least_squares_line(n: int) -> None:
    x, y, w = _data(n, n)
    slope, intercept = np.polyfit(x, y, 1, w=np.sqrt(w))  # minimises sum w (y - f)^2
    s = ad.smoothing_spline(x, y, p=0.0, weights=w)
    xe = np.linspace(x[0] - 5.0, x[-1] + 5.0, 101)
    _close(s(xe), intercept + slope * xe, 1e-9)
    _close(s(xe, 1), np.full(xe.shape, slope), 1e-9)
    assert np.all(s.coefs[:2] == 0.0)


@pytest.mark.parametrize("seed", range(5))
def test_p1_interpolates(seed: int) -> None:
    x, y, w = _data(seed, 25)
    s = ad.smoothing_spline(x, y, p=1.0, weights=w)
    _close(s(x), y, 1e-12)
    assert s(x[0], 2) == pytest.approx(0.0, abs=1e-12)  # natural end condition


def test_hold_extrapolation_and_shapes() -> None:
    x, y, _ = _data(1, 12)
    s = ad.smoothing_spline(x, y)
    assert s.p == 0.4
    xe = np.linspace(x[0] - 2.0, x[-1] + 2.0, 60).reshape(3, 20)
    held = s(xe, extrapolate="hold")
    assert held.shape == (3, 20)
    np.testing.assert_array_equal(held, s(np.clip(xe, x[0], x[-1])))
    d1 = s(xe, 1, extrapolate="hold")
    outside = (xe < x[0]) | (xe > x[-1])
    assert np.all(d1[outside] == 0.0)
    assert np.isnan(s(np.nan))
    assert s(xe, 4).max() == 0.0


def test_to_table_resamples_on_grid() -> None:
    x, y, _ = _data(2, 15)
    s = ad.smoothing_spline(x, y, p=0.4)
    grid = np.arange(np.floor(x[0]) - 1.0, np.ceil(x[-1]) + 1.5, 0.5)
    t = s.to_table(grid, name="alpha_deg")
    assert t.names == ["alpha_deg"]
    np.testing.assert_array_equal(t.values, s(grid, extrapolate="hold"))
    assert t.eval_point([grid[-1] + 10.0]) == t.values[-1]


def test_merge_duplicates_equals_csaps_on_merged_data() -> None:
    rng = np.random.default_rng(9)
    x, y, _ = _data(9, 20)
    # Every site appears 1-3 times with its own value and weight, shuffled.
    rep = rng.integers(1, 4, x.size)
    xd = np.repeat(x, rep)
    yd = np.repeat(y, rep) + 0.1 * rng.standard_normal(xd.size)
    wd = 0.5 + rng.random(xd.size)
    perm = rng.permutation(xd.size)
    s = ad.smoothing_spline(xd[perm], yd[perm], p=0.4, weights=wd[perm], merge_duplicates=True)
    site = np.repeat(np.arange(x.size), rep)
    wsum = np.bincount(site, weights=wd)
    ymean = np.bincount(site, weights=wd * yd) / wsum
    ref = csaps.CubicSmoothingSpline(x, ymean, weights=wsum, smooth=0.4)
    np.testing.assert_array_equal(s.breaks, x)
    xe = np.linspace(x[0] - 1.0, x[-1] + 1.0, 200)
    _close(s(xe), ref(xe))
    with pytest.raises(ad.InvalidInputError, match=r"x\[\d+\].*strictly increasing"):
        ad.smoothing_spline(xd[perm], yd[perm])


def test_errors_name_the_index() -> None:
    with pytest.raises(ad.TooLittleDataError, match="at least 2"):
        ad.smoothing_spline([1.0], [1.0])
    with pytest.raises(ad.InvalidInputError, match=r"y\[3\]"):
        ad.smoothing_spline([0, 1, 2, 3, 4], [0, 1, 2, np.nan, 4])
    with pytest.raises(ad.InvalidInputError, match=r"x\[2\]"):
        ad.smoothing_spline([0, 1, 1, 3], [0, 1, 2, 3])
    with pytest.raises(ad.InvalidInputError, match=r"x\[1\]"):
        ad.smoothing_spline([0, np.inf, 2], [0, 1, 2])
    with pytest.raises(ad.OutOfRangeError, match=r"weights\[1\]"):
        ad.smoothing_spline([0, 1, 2], [0, 1, 2], weights=[1.0, 0.0, 1.0])
    with pytest.raises(ad.OutOfRangeError, match="smoothing parameter"):
        ad.smoothing_spline([0, 1, 2], [0, 1, 2], p=1.5)
    with pytest.raises(ad.InvalidInputError):
        ad.smoothing_spline([0, 1, 2], [0, 1])
    with pytest.raises(ad.InvalidInputError):
        ad.smoothing_spline([0, 1, 2], [[0, 1, 2]])
    with pytest.raises(ad.InvalidInputError, match="'p'"):
        ad.smoothing_spline([0, 1, 2], [0, 1, 2], p="smooth")  # type: ignore[arg-type]
    s = ad.smoothing_spline([0, 1, 2], [0, 1, 2])
    with pytest.raises(ad.InvalidInputError, match="'nu'"):
        s([1.0], -1)
    with pytest.raises(ad.InvalidInputError, match="extrapolate"):
        s([1.0], extrapolate="linear")  # type: ignore[arg-type]


def test_docstring_examples() -> None:
    assert doctest.testmod(aerodelta.spline).failed == 0
