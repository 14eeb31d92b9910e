"""The diagnosis's memory and speed (issues 17 and 18): per-maneuver statistics held as the
Gram matrix's non-zero blocks, checked against the dense algebra written out row by row; the
held-out errors of a design with per-maneuver nuisance columns profiled out against refits
on the dense design; the sign-flip draws against numpy's own calls; and the traced peak of a
whole diagnosis per row of data."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from aerodelta.campaign import generate_campaign
from aerodelta.diagnosis import cv, diagnose
from aerodelta.diagnosis.stochastic import DETECTOR_CHANNELS
from aerodelta.fit import model_frame, qualified_coefficients
from aerodelta.ingest import ingest
from aerodelta.rolloff import detect_rolloff


def _local_rows(alpha, aero, glob, grid):
    """Each row on a flap's local layout (``k*R + r``, then the globals), written out."""
    k_n, r_n = grid.n, aero.shape[1]
    j, w1 = grid.locate(alpha)
    x = np.zeros((alpha.size, k_n * r_n + glob.shape[1]))
    for i in range(alpha.size):
        for r in range(r_n):
            x[i, j[i] * r_n + r] += (1.0 - w1[i]) * aero[i, r]
            x[i, (j[i] + 1) * r_n + r] += w1[i] * aero[i, r]
        x[i, k_n * r_n :] = glob[i]
    return x


def _toy(n_man=15, per=80, r_n=3, g_n=2, seed=7):
    rng = np.random.default_rng(seed)
    man = np.repeat(np.arange(n_man), per)
    flap = (man % 2).astype(np.int64)
    alpha = np.concatenate([np.sort(rng.uniform(0, 12, per)) for _ in range(n_man)])
    aero = rng.normal(size=(man.size, r_n))
    glob = rng.normal(size=(man.size, g_n))
    y = np.sin(alpha / 3) * aero[:, 0] + 0.2 * glob[:, 0] + 0.05 * rng.normal(size=man.size)
    grid = cv.HatGrid.covering(alpha, 1.5)
    return y, man, flap, alpha, aero, glob, grid


def test_block_statistics_are_the_dense_gram_matrices_and_far_smaller():
    y, man, flap, alpha, aero, glob, grid = _toy()
    n_man, r_n, g_n = 15, aero.shape[1], glob.shape[1]
    names_a, names_g = [f"a{i}" for i in range(r_n)], [f"g{i}" for i in range(g_n)]
    design = cv.build_design(y, man, flap, alpha, aero, glob, names_a, names_g, grid, n_man, 2)
    x = _local_rows(alpha, aero, glob, grid)
    for m in range(n_man):
        rows = man == m
        g_ref = x[rows].T @ x[rows]
        np.testing.assert_allclose(design.dense_gram(m), g_ref, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(design.xty[m], x[rows].T @ y[rows], rtol=1e-12, atol=1e-12)
        assert design.yty[m] == pytest.approx(float(y[rows] @ y[rows]), rel=1e-13)
        assert design.man_flap[m] == m % 2 and design.n_rows[m] == rows.sum()
    np.testing.assert_allclose(
        design.gram_diagonals(), [np.diag(design.dense_gram(m)) for m in range(n_man)], rtol=1e-13
    )
    # the bytes per maneuver are those of the blocks, not of a dense matrix: on a 1-deg grid
    # over 45 deg with C_l's 13 regressors and 4 globals, 1/20 of the dense size
    k_n, r13, g4 = 46, 13, 4
    rng = np.random.default_rng(1)
    man2 = np.repeat(np.arange(30), 50)
    a2 = rng.uniform(-5, 40, man2.size)
    big = cv.build_design(
        rng.normal(size=man2.size), man2, np.zeros(man2.size, dtype=np.int64), a2,
        rng.normal(size=(man2.size, r13)), rng.normal(size=(man2.size, g4)),
        [f"a{i}" for i in range(r13)], [f"g{i}" for i in range(g4)],
        cv.HatGrid.covering(a2, 1.0), 30, 1,
    )  # fmt: skip
    assert big.grid.n == k_n
    dense = (k_n * r13 + g4) ** 2 * 8
    assert big.nbytes / 30 < dense / 15


def test_heldout_errors_of_a_profiled_design_match_dense_refits():
    """Per-maneuver nuisance columns (a roll-off's random amplitude) profiled out: each fold's
    parameters are the penalised least squares on the training maneuvers' data projected off
    their own nuisance columns, and each held-out maneuver's error is its residual projected
    off its own nuisance columns; both computed here on the dense design, row by row."""
    y, man, flap, alpha, aero, glob, grid = _toy(seed=3)
    n_man, r_n, g_n, n_f = 15, aero.shape[1], glob.shape[1], 2
    rng = np.random.default_rng(5)
    centre = rng.uniform(3, 9, n_man)
    u = (alpha - centre[man]) / 0.8
    nuis = np.column_stack([np.exp(-0.5 * u * u), u * np.exp(-0.5 * u * u)])
    nuis[man % 4 == 0] = 0.0  # maneuvers without an event
    y = y + rng.normal(0, 0.5, n_man)[man] * nuis[:, 0]
    names_a = [f"a{i}" for i in range(r_n)]
    names_g = [f"g{i}" for i in range(g_n)]
    full = cv.build_design(
        y, man, flap, alpha, aero, (glob, nuis), names_a, [*names_g, "n0", "n1"], grid, n_man, n_f
    )
    prof = cv.profile_out(full, 2)
    folds = np.arange(n_man) % 3
    stats = cv.fold_stats(prof, folds)
    cols = cv.local_columns(prof, names_a[:2], names_g[1:])
    sse, _ = cv.heldout_sse(prof, stats, cols)

    # reference: dense rows projected off each maneuver's own nuisance columns
    x_loc = _local_rows(alpha, aero, glob, grid)
    kr = grid.n * r_n
    proj_x, proj_y = np.zeros_like(x_loc), np.zeros_like(y)
    for m in range(n_man):
        rows = np.flatnonzero(man == m)
        n_m = nuis[rows][:, np.abs(nuis[rows]).sum(axis=0) > 0]
        p_m = np.eye(rows.size) - (n_m @ np.linalg.pinv(n_m) if n_m.size else 0.0)
        proj_x[rows], proj_y[rows] = p_m @ x_loc[rows], p_m @ y[rows]
    # the penalty, from the projected data's diagonal per flap and regressor
    d2 = np.diff(np.eye(grid.n), n=2, axis=0)
    pens = []
    for f in range(n_f):
        diag = np.sum(proj_x[flap == f] ** 2, axis=0)
        pen = np.zeros((kr + g_n, kr + g_n))
        for r in range(r_n):
            idx = np.arange(grid.n) * r_n + r
            pen[np.ix_(idx, idx)] = diag[idx].mean() * (
                cv.RIDGE_REL * np.eye(grid.n) + cv.SMOOTH_REL * d2.T @ d2
            )
        pens.append(pen)
    # the model's columns: regressors a0, a1 at every knot of each flap, and global g1
    keep = np.r_[[k * r_n + r for k in range(grid.n) for r in (0, 1)], kr + 1]
    for q in range(3):
        blocks, rhs, pen_all = [], [], []
        for f in range(n_f):
            tr = (folds[man] != q) & (flap == f)
            blocks.append(proj_x[tr][:, keep])
            rhs.append(proj_y[tr])
            pen_all.append(pens[f][np.ix_(keep, keep)])
        # both flaps' alpha columns side by side, the global column shared
        na = keep.size - 1
        a_mat = np.zeros((2 * na + 1, 2 * na + 1))
        b_vec = np.zeros(2 * na + 1)
        for f in range(n_f):
            sl = np.r_[f * na + np.arange(na), 2 * na]
            a_mat[np.ix_(sl, sl)] += blocks[f].T @ blocks[f] + pen_all[f]
            b_vec[sl] += blocks[f].T @ rhs[f]
        theta = np.linalg.solve(a_mat, b_vec)
        for m in np.flatnonzero(folds == q):
            rows = man == m
            f = m % 2
            th = theta[np.r_[f * na + np.arange(na), 2 * na]]
            ref = float(np.sum((proj_y[rows] - proj_x[rows][:, keep] @ th) ** 2))
            assert sse[m] == pytest.approx(ref, rel=1e-8, abs=1e-12)


def test_sparse_nuisance_columns_give_the_dense_statistics():
    """Roll-off nuisance columns passed by their non-zero entries (SparseColumns, not an
    n x 2K matrix of zeros) give the same statistics, number for number."""
    y, man, flap, alpha, aero, glob, grid = _toy(seed=9)
    rng = np.random.default_rng(4)
    rows, vals = [], []
    for j in range(3):  # a column lives on a few rows of a few maneuvers
        r = np.sort(rng.choice(man.size, 60 + 20 * j, replace=False))
        rows.append(r)
        vals.append(rng.normal(size=r.size))
    sparse = cv.SparseColumns(man.size, rows, vals)
    names = ([f"a{i}" for i in range(3)], ["g0", "g1", "n0", "n1", "n2"])
    args = (y, man, flap, alpha, aero)
    d_sparse = cv.build_design(*args, (glob, sparse), *names, grid, 15, 2)
    d_dense = cv.build_design(*args, np.hstack([glob, sparse.dense()]), *names, grid, 15, 2)
    for f in ("diag", "off", "cross", "glob", "xty", "yty"):
        np.testing.assert_array_equal(getattr(d_sparse, f), getattr(d_dense, f))
    assert np.count_nonzero(d_sparse.glob[:, 2:, 2:]) > 0


def _flip_p_numpy(weights, w, n_perm, seed):
    """The sign-flip estimate drawn as numpy draws it (the reference of the fast path)."""
    rng = np.random.default_rng(seed)
    n, hits, draws, total = weights.size, 0, 0, n_perm
    while draws < total:
        k = min(total - draws, 50_000)
        signs = rng.integers(0, 2, size=(k, n), dtype=np.int8) * 2 - 1
        hits += int(np.sum(signs @ weights >= w))
        draws += k
        if draws == n_perm and hits < 20:
            total = n_perm * cv.TAIL_DRAWS
    return (1.0 + hits) / (draws + 1.0)


@pytest.mark.parametrize("n", [1, 5, 8, 13, 64, 203])
def test_sign_flip_draws_are_numpys(n):
    """The bytes read from the bit generator give numpy's ``integers`` signs, for any number
    of maneuvers (groups of 8 and a remainder) and of draws (calls ending inside a 32-bit
    word), in the tail extension and out of it; ranks (integer weights) and plain sums."""
    assert cv._sign_bytes_match(), "numpy draws its int8 signs otherwise: the fast path is off"
    rng = np.random.default_rng(n)
    d = rng.normal(0.2, 1.0, n)
    for weights in (cv._abs_ranks(d), d):
        scale = float(np.sqrt(np.sum(weights**2)))
        for thr in (0.0, 1.5 * scale, 4.0 * scale):
            for n_perm in (1000, 1001):
                want = _flip_p_numpy(weights, thr, n_perm, 9)
                assert cv._flip_p(weights, thr, n_perm, 9) == want


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """A quick virtual campaign (40 maneuvers) with the default effects and roll-offs."""
    camp = tmp_path_factory.mktemp("memory") / "campaign"
    generate_campaign(camp, seed=0, size="quick", overwrite=True)
    return ingest(camp, compat=False, progress=False).data


def test_roll_off_detector_is_given_every_channel_it_reads(quick):
    """The diagnosis hands the roll-off detector only :data:`DETECTOR_CHANNELS` (it copies
    every column it is given, maneuver by maneuver): the events are those found on all the
    records' columns."""
    frame = model_frame(quick)
    # the qualified model's C_l error: the roll-off spikes are in it
    residual = (
        frame["Cl_meas"].to_numpy() - qualified_coefficients(frame, "adx37")["Cl_qual"].to_numpy()
    )
    full = detect_rolloff(frame, residual=residual, kinds=None, alpha="alpha_deg")
    few = detect_rolloff(
        frame.select([c for c in DETECTOR_CHANNELS if c in frame.columns]),
        residual=residual,
        kinds=None,
        alpha="alpha_deg",
    )
    assert full.height > 0
    assert few.equals(full)


def test_diagnosis_traced_memory_per_row(quick):
    """A whole diagnosis (roll-off search and profiling included) on a quick campaign: the
    peak of the arrays it allocates stays under 1.5 kB per row of data. Holding a dense Gram
    matrix per maneuver took 4.3 kB per row here (350 MB for 40 maneuvers) and grew with the
    maneuvers; the rows' own regressor columns take about 0.9 kB."""
    data = quick
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        d = diagnose(data)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert d.result["coefficients"]["Cl"]["rolloff"]["events_profiled_out"] > 0
    assert peak / data.height < 1500, f"{peak / data.height:.0f} B per row"
