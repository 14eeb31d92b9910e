"""The diagnosis without a sorted copy of the records (issue 17's memory floor): records whose
maneuvers come in flight order (``m1000_...`` after ``m999_...``) are diagnosed in their own
row order, only a permutation of the rows kept; the outer folds share the design's Gram
blocks; the solves are memoised; predictions and the band match work in pieces. Each is
checked against the straightforward computation it replaces: the same numbers, bit for bit."""

from __future__ import annotations

import json

import numpy as np
import polars as pl
import pytest

from _diagnosis_support import toy_rows
from aerodelta.campaign import generate_campaign
from aerodelta.diagnosis import cv, diagnose
from aerodelta.diagnosis.band import _lowpass_rows, lowpass
from aerodelta.diagnosis.data import _grouped_by_maneuver_in_time, load_inputs, load_records
from aerodelta.ingest import ingest


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> pl.DataFrame:
    """A quick virtual campaign (40 maneuvers, default effects and roll-offs), in
    ``maneuver_id`` order as the ingest writes it."""
    camp = tmp_path_factory.mktemp("order") / "campaign"
    generate_campaign(camp, seed=3, size="quick", overwrite=True)
    return ingest(camp, compat=False, progress=False).data


def _maneuvers_permuted(data: pl.DataFrame, seed: int) -> pl.DataFrame:
    """``data`` with its maneuvers (each kept whole, in time order) in a random order."""
    ids = data["maneuver_id"].unique(maintain_order=True).to_list()
    rank = {
        m: int(r)
        for m, r in zip(ids, np.random.default_rng(seed).permutation(len(ids)), strict=True)
    }
    key = pl.col("maneuver_id").replace_strict(rank, return_dtype=pl.Int64)
    return data.with_columns(key.alias("__k")).sort("__k", maintain_order=True).drop("__k")


def test_records_in_flight_order_give_the_sorted_records_diagnosis(quick: pl.DataFrame) -> None:
    shuffled = _maneuvers_permuted(quick, 5)
    frame, order, _, _ = load_records(shuffled, None)
    assert order is not None  # the records' own order is kept (no sorted copy)
    assert frame["maneuver_id"].to_list() == shuffled["maneuver_id"].to_list()
    ref, _, _ = load_inputs(quick, None)
    assert frame[order].equals(ref)  # the permutation is the sort
    a, b = diagnose(quick), diagnose(shuffled)
    assert json.dumps(b.result) == json.dumps(a.result)
    assert b.predictions.equals(a.predictions)


def test_a_user_regressor_reading_neighbouring_rows_sees_the_sorted_rows(
    quick: pl.DataFrame,
) -> None:
    """A user's regressor that reads the previous row without ``.over`` crosses from one
    maneuver into the one before it: in the records' own order that is another maneuver than
    in sorted order, so it is evaluated on its columns sorted; the diagnosis is the sorted
    records' one, and so are the regressor's columns."""
    from aerodelta.diagnosis.regressors import design_columns  # noqa: PLC0415
    from aerodelta.diagnosis.vocabulary import default_vocabulary  # noqa: PLC0415

    lagged = pl.col("rhat").shift(1).fill_null(0.0)
    vocab = default_vocabulary().with_user_effects({"lagged_yaw": {"Cn": [lagged, "beta_deg"]}})
    shuffled = _maneuvers_permuted(quick, 9)
    a = diagnose(quick, vocabulary=vocab)
    b = diagnose(shuffled, vocabulary=vocab)
    assert json.dumps(b.result) == json.dumps(a.result)
    names = ["user:lagged_yaw:Cn:0", "user:lagged_yaw:Cn:1", "beta"]
    ref, _, _ = load_inputs(quick, None)
    want, _ = design_columns(ref, "Cn", aero_names=names, glob_names=[], vocab=vocab, meas={})
    records, order, _, _ = load_records(shuffled, None)
    got, _ = design_columns(
        records, "Cn", aero_names=names, glob_names=[], vocab=vocab, meas={}, order=order
    )
    np.testing.assert_array_equal(got, want)
    # in the records' own order the lagged column differs at the maneuvers' first rows
    direct = records.select(lagged.alias("x"))["x"].to_numpy()[order]
    assert not np.array_equal(direct, want[:, 0])


def test_records_out_of_time_order_are_sorted(quick: pl.DataFrame) -> None:
    """A maneuver split in two runs, or two rows of one out of time order: the records are
    sorted as before (``order`` is ``None``), into the frame the sorted records give."""
    ref, _, _ = load_inputs(quick, None)
    first = quick["maneuver_id"][0]
    rows = np.flatnonzero(quick["maneuver_id"].to_numpy() == first)
    idx = np.arange(quick.height)
    split = np.r_[idx[rows[5] :], idx[: rows[5]]]  # its first 5 rows moved to the end
    swap = idx.copy()
    swap[[rows[3], rows[4]]] = swap[[rows[4], rows[3]]]
    for perm in (split, swap):
        frame, order, _, _ = load_records(quick[perm], None)
        assert order is None
        assert frame.equals(ref)
    assert not _grouped_by_maneuver_in_time(quick[split])
    assert _grouped_by_maneuver_in_time(_maneuvers_permuted(quick, 1))


def _design(n_man: int = 15):
    y, man, flap, alpha, aero, glob, grid = toy_rows(5, n_man, 50)
    return cv.build_design(y, man, flap, alpha, aero, glob, ["a", "b"], ["g"], grid, n_man, 2)


def test_a_subset_shares_the_blocks_and_gives_what_a_copy_gives() -> None:
    design = _design()
    folds = np.arange(15) % 5
    inner_idx = np.flatnonzero(folds != 2)
    sub = design.subset(inner_idx)
    own = sub.owning()
    assert np.shares_memory(sub.diag, design.diag) and sub.block_rows is not None
    assert not np.shares_memory(own.diag, design.diag) and own.block_rows is None
    assert sub.nbytes == own.nbytes + sub.block_rows.nbytes
    assert own.nbytes < design.nbytes
    np.testing.assert_array_equal(sub.gram_diagonals(), own.gram_diagonals())
    for ms in (np.arange(sub.n_maneuvers), np.array([0, 3, 7]), np.array([5])):
        np.testing.assert_array_equal(sub.gram_sum(ms), own.gram_sum(ms))
    # a subset of a subset reads the original rows
    sub2 = sub.subset(np.array([1, 4, 6]))
    np.testing.assert_array_equal(sub2.dense_gram(2), design.dense_gram(inner_idx[6]))
    inner_folds = np.searchsorted(np.unique(folds[inner_idx]), folds[inner_idx])
    st_sub, st_own = cv.fold_stats(sub, inner_folds), cv.fold_stats(own, inner_folds)
    for aero, glob in ((["a", "b"], ["g"]), (["b"], []), ([], ["g"])):
        cols = cv.local_columns(sub, aero, glob)
        sse_s, th_s = cv.heldout_sse(sub, st_sub, cols)
        sse_o, th_o = cv.heldout_sse(own, st_own, cols)
        np.testing.assert_array_equal(sse_s, sse_o)
        for a, b in zip(th_s, th_o, strict=True):
            for x, z in zip(a, b, strict=True):
                np.testing.assert_array_equal(x, z)


def test_memoised_solves_are_the_solves() -> None:
    design = _design()
    stats = cv.fold_stats(design, np.arange(15) % 5)
    cols = cv.local_columns(design, ["a"], ["g"])
    sse, thetas = cv.heldout_sse(design, stats, cols)
    sse[:] = -1.0  # the caller's copy: the memo is not touched
    again, thetas2 = cv.heldout_sse(design, stats, cols)
    assert np.all(again >= 0.0)
    for q in range(5):
        fresh = cv.solve(design, stats.train_gram[q], stats.train_xty[q], cols)
        for a, b, c in zip(thetas[q], thetas2[q], fresh, strict=True):
            np.testing.assert_array_equal(a, c)
            np.testing.assert_array_equal(b, c)
    tot = cv.solve(design, stats.total_gram, stats.total_xty, cols)
    for a, b in zip(cv.total_solve(design, stats, cols), tot, strict=True):
        np.testing.assert_array_equal(a, b)
    # the memo serves only the design it was filled for
    other = _design()
    other.xty[:] *= 2.0
    st2 = cv.fold_stats(other, np.arange(15) % 5)
    st2.memo.update(stats.memo)
    fresh_other = cv.heldout_sse(other, cv.fold_stats(other, np.arange(15) % 5), cols)[0]
    np.testing.assert_array_equal(cv.heldout_sse(other, st2, cols)[0], fresh_other)
    assert not np.array_equal(fresh_other, again)


def test_predictions_in_pieces_are_the_whole_predictions(monkeypatch: pytest.MonkeyPatch) -> None:
    y, man, flap, alpha, aero, glob, grid = toy_rows(5, 15, 50)
    design = cv.build_design(y, man, flap, alpha, aero, glob, ["a", "b"], ["g"], grid, 15, 2)
    stats = cv.fold_stats(design, np.arange(15) % 5)
    cols = cv.local_columns(design, ["a", "b"], ["g"])
    thetas = cv.fold_solves(design, stats, cols)
    fold = (np.arange(15) % 5)[man]
    whole = cv.fold_prediction(design, thetas, fold, flap, alpha, aero, glob)
    one = cv.row_prediction(design, thetas[0], flap, alpha, aero, glob)
    # reference: each row's hat-basis interpolation of its fold's parameters, written out
    kr = grid.n * 2
    j, w1 = grid.locate(alpha)
    ref = np.empty(alpha.size)
    for i in range(alpha.size):
        th = thetas[fold[i]][flap[i]]
        a = th[:kr].reshape(grid.n, 2)
        ref[i] = ((1 - w1[i]) * a[j[i]] + w1[i] * a[j[i] + 1]) @ aero[i] + glob[i] @ th[kr:]
    np.testing.assert_allclose(whole, ref, rtol=1e-12, atol=1e-15)
    monkeypatch.setattr(cv, "PREDICT_ROWS", 7)
    np.testing.assert_array_equal(
        cv.fold_prediction(design, thetas, fold, flap, alpha, aero, glob), whole
    )
    np.testing.assert_array_equal(
        cv.row_prediction(design, thetas[0], flap, alpha, aero, glob), one
    )


@pytest.mark.parametrize("n", [8, 9, 130, 1001])
def test_band_rows_filtered_together_are_each_rows_lowpass(n: int) -> None:
    rng = np.random.default_rng(n)
    x = rng.normal(size=(3, n)).cumsum(axis=1)
    fcs = np.array([0.7, 2.5, 9.0])
    got = _lowpass_rows(x, 0.02, fcs)
    for r in range(3):
        np.testing.assert_array_equal(got[r], lowpass(x[r], 0.02, float(fcs[r])))
