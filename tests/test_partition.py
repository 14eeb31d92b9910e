"""aerodelta.partition_alpha (thesis Section 3.3.1): bins checked against numpy.histogram on
the returned edges, independent per-bin counts of maneuvers, and closed-form grids."""

from __future__ import annotations

import doctest

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
import aerodelta.partition


def _stall_like(seed: int, n_dense: int = 6000, n_tail: int = 700) -> np.ndarray:
    """Dense data 4-16 deg, density falling off towards 28 deg (as in thesis Fig. 3.4)."""
    rng = np.random.default_rng(seed)
    dense = rng.uniform(4.0, 16.0, n_dense)
    tail = 16.0 + 12.0 * rng.random(n_tail) ** 3
    return rng.permutation(np.concatenate([dense, tail]))


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("k", [1, 3, 6])
def test_counts_match_histogram_and_every_bin_is_filled(seed: int, k: int) -> None:
    a = _stall_like(seed)
    bins = ad.partition_alpha(a, k)
    hist, _ = np.histogram(a, bins=bins.edges)
    np.testing.assert_array_equal(bins.counts, hist)
    assert bins.required_points == 10 * k
    assert np.all(bins.counts >= 10 * k)
    assert bins.ok and not bins.underfilled.any()
    assert bins.edges[0] == a.min() and bins.edges[-1] == a.max()
    # Per-sample index: numpy's assignment (left-closed, last bin closed).
    ref = np.clip(np.searchsorted(bins.edges, a, side="right") - 1, 0, len(bins) - 1)
    np.testing.assert_array_equal(bins.index, ref)
    np.testing.assert_allclose(bins.centres, 0.5 * (bins.edges[1:] + bins.edges[:-1]))


def test_dense_uniform_data_gives_the_nominal_grid() -> None:
    a = np.arange(6.0025, 20.0, 0.005)  # 40 samples per 0.2 deg cell
    bins = ad.partition_alpha(a, 4, alpha_range=(6.0, 20.0))
    np.testing.assert_allclose(bins.edges, np.linspace(6.0, 20.0, 71), rtol=0, atol=1e-12)
    assert np.all(bins.counts == 40)
    # Without a range: same interior grid, outer edges at the data's ends.
    rng = np.random.default_rng(5)
    b = ad.partition_alpha(rng.uniform(6.0, 20.0, 50_000), 2)
    np.testing.assert_allclose(b.edges[1:-1], np.linspace(6.2, 19.8, 69), rtol=0, atol=1e-12)
    assert np.all(np.abs(b.widths[1:-1] - 0.2) < 1e-12)


def test_sparse_high_alpha_tail_gets_wider_bins() -> None:
    a = _stall_like(11)
    bins = ad.partition_alpha(a, 5)
    low = bins.centres < 15.0
    assert np.all(np.abs(bins.widths[low][1:] - 0.2) < 1e-12)
    assert bins.widths[-1] > 1.0
    # Widths grow towards the sparse end.
    tail = bins.widths[bins.centres > 17.0]
    assert tail.size >= 2 and tail[-1] >= tail[0]


def test_deterministic_and_order_independent() -> None:
    a = _stall_like(2)
    b1 = ad.partition_alpha(a, 4)
    b2 = ad.partition_alpha(a, 4)
    perm = np.random.default_rng(0).permutation(a.size)
    b3 = ad.partition_alpha(a[perm], 4)
    np.testing.assert_array_equal(b1.edges, b2.edges)
    np.testing.assert_array_equal(b1.edges, b3.edges)
    np.testing.assert_array_equal(b1.index[perm], b3.index)


def test_min_maneuvers_counts_distinct_maneuvers() -> None:
    rng = np.random.default_rng(4)
    # 12 maneuvers, two per 2-deg slice: a 0.2 deg bin sees two maneuvers, so asking for
    # three forces bins across slice boundaries.
    man = np.repeat([f"m{j:02d}" for j in range(12)], 500)
    a = 4.0 + 2.0 * (np.arange(man.size) // 500 % 6) + 2.0 * rng.random(man.size)
    bins = ad.partition_alpha(a, 2, maneuver_id=man, min_maneuvers=3)
    assert bins.maneuvers is not None
    frame = pl.DataFrame({"bin": bins.index, "m": man})
    distinct = frame.group_by("bin").agg(pl.col("m").n_unique()).sort("bin")["m"].to_numpy()
    np.testing.assert_array_equal(bins.maneuvers, distinct)
    assert np.all(bins.maneuvers >= 3) and bins.ok
    single = ad.partition_alpha(a, 2, maneuver_id=man, min_maneuvers=1)
    assert len(single) > len(bins)


def test_width_cap_reports_underfilled_bins() -> None:
    a = _stall_like(3)
    bins = ad.partition_alpha(a, 5, max_width_deg=1.0)
    assert np.all(bins.widths <= 1.0 + 1e-9)
    assert bins.underfilled.any() and not bins.ok
    np.testing.assert_array_equal(bins.underfilled, bins.counts < 50)
    hist, _ = np.histogram(a, bins=bins.edges)
    np.testing.assert_array_equal(bins.counts, hist)


def test_alpha_range_and_frame() -> None:
    a = _stall_like(6)
    bins = ad.partition_alpha(a, 3, alpha_range=(8.0, 14.0))
    inside = (a >= 8.0) & (a <= 14.0)
    assert np.all((bins.index == -1) == ~inside)
    assert bins.counts.sum() == inside.sum()
    df = bins.to_frame()
    assert isinstance(df, pl.DataFrame)
    assert df.columns == [
        "bin",
        "alpha_lo_deg",
        "alpha_hi_deg",
        "alpha_centre_deg",
        "width_deg",
        "count",
        "maneuvers",
        "underfilled",
    ]
    assert df.height == len(bins)
    assert df["count"].sum() == inside.sum()
    assert df["maneuvers"].null_count() == len(bins)


def test_too_few_points_give_one_underfilled_bin() -> None:
    bins = ad.partition_alpha([5.0, 5.5, 6.0], 2)
    assert len(bins) == 1 and not bins.ok
    np.testing.assert_array_equal(bins.edges, [5.0, 6.0])


def test_errors_name_the_row() -> None:
    with pytest.raises(ad.TooLittleDataError, match="no alpha samples"):
        ad.partition_alpha([], 2)
    with pytest.raises(ad.InvalidInputError, match="row 5"):
        ad.partition_alpha([1, 2, 3, 4, 5, np.nan, 7], 2)
    with pytest.raises(ad.InvalidInputError, match="n_params"):
        ad.partition_alpha([1.0, 2.0], 0)
    with pytest.raises(ad.InvalidInputError, match="maneuver"):
        ad.partition_alpha([1.0, 2.0], 1, min_maneuvers=2)
    with pytest.raises(ad.InvalidInputError, match="maneuver_id"):
        ad.partition_alpha([1.0, 2.0], 1, maneuver_id=["a"])
    with pytest.raises(ad.OutOfRangeError, match="width_deg"):
        ad.partition_alpha([1.0, 2.0], 1, width_deg=0.0)
    with pytest.raises(ad.InvalidInputError, match="alpha_range"):
        ad.partition_alpha([1.0, 2.0], 1, alpha_range=(3.0, 2.0))
    with pytest.raises(ad.TooLittleDataError, match="no alpha sample"):
        ad.partition_alpha([1.0, 2.0], 1, alpha_range=(3.0, 4.0))


def test_docstring_examples() -> None:
    assert doctest.testmod(aerodelta.partition).failed == 0
