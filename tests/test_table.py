"""aerodelta.Table against scipy's RegularGridInterpolator and closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

import aerodelta as ad


def _random_grid(rng: np.random.Generator, ndim: int) -> tuple[list[np.ndarray], np.ndarray]:
    bps = [
        np.sort(rng.choice(np.linspace(-10, 10, 400), size=rng.integers(2, 7), replace=False))
        for _ in range(ndim)
    ]
    vals = rng.normal(size=[len(b) for b in bps])
    return bps, vals


@pytest.mark.parametrize("ndim", [1, 2, 3, 4, 5])
@pytest.mark.parametrize("seed", range(4))
def test_matches_scipy_inside_grid(ndim: int, seed: int) -> None:
    rng = np.random.default_rng(1000 * ndim + seed)
    bps, vals = _random_grid(rng, ndim)
    pts = np.column_stack([rng.uniform(b[0], b[-1], 5000) for b in bps])
    ref = RegularGridInterpolator(bps, vals, method="linear")(pts)
    t = ad.Table(bps, vals)
    np.testing.assert_allclose(t.eval_rows(pts), ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(t(*pts.T), ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_linear_extrapolation_matches_scipy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    bps, vals = _random_grid(rng, 3)
    pts = np.column_stack([rng.uniform(b[0] - 5, b[-1] + 5, 5000) for b in bps])
    ref = RegularGridInterpolator(bps, vals, bounds_error=False, fill_value=None)(pts)
    t = ad.Table(bps, vals, below="linear", above="linear")
    np.testing.assert_allclose(t.eval_rows(pts), ref, rtol=0, atol=1e-11)


@pytest.mark.parametrize("seed", range(3))
def test_hold_equals_scipy_on_clipped_points(seed: int) -> None:
    rng = np.random.default_rng(50 + seed)
    bps, vals = _random_grid(rng, 4)
    pts = np.column_stack([rng.uniform(b[0] - 5, b[-1] + 5, 5000) for b in bps])
    clipped = np.column_stack([np.clip(pts[:, k], b[0], b[-1]) for k, b in enumerate(bps)])
    ref = RegularGridInterpolator(bps, vals)(clipped)
    np.testing.assert_allclose(ad.Table(bps, vals).eval_rows(pts), ref, rtol=0, atol=1e-12)


def test_exact_at_every_node() -> None:
    rng = np.random.default_rng(7)
    bps, vals = _random_grid(rng, 3)
    mesh = np.meshgrid(*bps, indexing="ij")
    out = ad.Table(bps, vals)(*mesh)
    assert np.array_equal(out, vals)


def test_mixed_policies_per_side() -> None:
    t = ad.Table([[0.0, 1.0]], [0.0, 2.0], below="hold", above="linear")
    assert t.eval_point([-1.0]) == 0.0
    assert t.eval_point([2.0]) == 4.0
    t = ad.Table([[0.0, 1.0]], [0.0, 2.0], below="linear", above="hold", mins=-0.5)
    assert t.eval_point([-3.0]) == -1.0
    assert t.eval_point([3.0]) == 2.0


def test_nan_gives_nan() -> None:
    t = ad.Table([[0.0, 1.0], [0.0, 1.0]], [[0.0, 1.0], [2.0, 3.0]])
    out = t([np.nan, 0.5], [0.5, np.nan])
    assert np.isnan(out).all()
    assert np.isnan(t.eval_point([0.5, float("nan")]))


def test_bad_breakpoints_name_axis_and_index() -> None:
    with pytest.raises(ad.InvalidInputError, match=r"axis 'beta', breakpoint 2"):
        ad.Table([[0.0, 1.0], [0.0, 1.0, 0.5]], np.zeros(6), names=["alpha", "beta"])
    with pytest.raises(ad.InvalidInputError, match=r"has 5 values.*need 6"):
        ad.Table([[0.0, 1.0], [0.0, 1.0, 2.0]], np.zeros(5))
    with pytest.raises(ad.InvalidInputError, match=r"argument 'below'.*'hold' and 'linear'"):
        ad.Table([[0.0, 1.0]], [0.0, 1.0], below="clamp")  # type: ignore[arg-type]
    with pytest.raises(ad.InvalidInputError, match=r"got 1 input columns for a 2-D table"):
        ad.Table([[0.0, 1.0], [0.0, 1.0]], np.zeros(4))([0.5])
