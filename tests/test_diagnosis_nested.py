"""Outer-fold (nested) evaluation of the diagnosis (issue 17, item 1): the outer errors are
those of refits without the fold (brute force on the dense design), an outer fold's choice
never depends on its own maneuvers, and the outer numbers reach diagnosis.json."""

from __future__ import annotations

import numpy as np
import pytest

from _diagnosis_support import dense_design, toy_rows
from aerodelta.diagnosis import cv, select
from aerodelta.diagnosis.nested import effect_outer, outer_evaluation, outer_summary
from aerodelta.diagnosis.select import SelectionConfig
from aerodelta.diagnosis.vocabulary import Candidate


@pytest.fixture(scope="module")
def toy():
    return toy_rows(5, 15, 50)


def test_outer_errors_are_those_of_refits_without_the_fold(toy):
    """``Design.subset`` + ``fold_stats`` + ``solve`` on the other folds, scored by
    ``model_sse`` on the left-out fold, equal penalised least squares on the dense rows of the
    other folds (with the subset's own penalty scale) and the squared error of its prediction
    on each left-out maneuver's rows."""
    y, man, flap, alpha, aero, glob, grid = toy
    design = cv.build_design(y, man, flap, alpha, aero, glob, ["a", "b"], ["g"], grid, 15, 2)
    folds = np.arange(15) % 5
    x = dense_design(y, man, flap, alpha, aero, glob, grid, 2)
    kr = grid.n * 2
    for o in range(5):
        inner_idx = np.flatnonzero(folds != o)
        outer = np.flatnonzero(folds == o)
        sub = design.subset(inner_idx)
        st = cv.fold_stats(sub, np.searchsorted(np.unique(folds[inner_idx]), folds[inner_idx]))
        for aero_names, glob_names in ((["a", "b"], ["g"]), (["a"], []), ([], ["g"])):
            cols = cv.local_columns(sub, aero_names, glob_names)
            th = cv.solve(sub, st.total_gram, st.total_xty, cols)
            got = cv.model_sse(design, outer, th, cols)
            # reference: dense penalised least squares on the inner rows, same columns
            keep = np.zeros(x.shape[1], dtype=bool)
            pen = np.zeros((x.shape[1], x.shape[1]))
            p_sub = cv.penalty(sub)
            for f in range(2):
                keep[f * kr + cols[0]] = True
                idx = f * kr + np.arange(kr)
                pen[np.ix_(idx, idx)] += p_sub[f][:kr, :kr]
            keep[2 * kr + (cols[1] - kr)] = True
            tr = np.isin(man, inner_idx)
            xk = x[:, keep]
            beta = np.linalg.solve(xk[tr].T @ xk[tr] + pen[np.ix_(keep, keep)], xk[tr].T @ y[tr])
            for i, m in enumerate(outer):
                rows = man == m
                ref = float(np.sum((y[rows] - xk[rows] @ beta) ** 2))
                assert got[i] == pytest.approx(ref, rel=1e-8, abs=1e-12)


def test_subset_of_a_profiled_design_scores_each_maneuver_on_its_own_nuisance(toy):
    """With per-maneuver nuisance columns profiled out (roll-off events), the error of a model
    on a left-out maneuver is its residual after that maneuver's own nuisance amplitudes are
    fitted: min over a of ||y - X theta - N a||^2 (closed form by least squares)."""
    y, man, flap, alpha, aero, glob, grid = toy
    rng = np.random.default_rng(2)
    centre = rng.uniform(3, 7, 15)
    u = (alpha - centre[man]) / 0.8
    nuis = np.column_stack([np.exp(-0.5 * u * u), u * np.exp(-0.5 * u * u)])
    nuis[man % 3 == 0] = 0.0
    y2 = y + rng.normal(0, 0.5, 15)[man] * nuis[:, 0]
    full = cv.build_design(
        y2, man, flap, alpha, aero, np.hstack([glob, nuis]), ["a", "b"], ["g", "n0", "n1"],
        grid, 15, 2,
    )  # fmt: skip
    prof = cv.profile_out(full, 2)
    inner_idx = np.flatnonzero(np.arange(15) % 5 != 1)
    outer = np.flatnonzero(np.arange(15) % 5 == 1)
    sub = prof.subset(inner_idx)
    assert sub.lowrank_of is not None and set(sub.lowrank_of) <= set(range(inner_idx.size))
    st = cv.fold_stats(sub, np.arange(inner_idx.size) % 4)
    cols = cv.local_columns(sub, ["a", "b"], ["g"])
    th = cv.solve(sub, st.total_gram, st.total_xty, cols)
    got = cv.model_sse(prof, outer, th, cols)
    x = dense_design(y2, man, flap, alpha, aero, glob, grid, 2)
    kr = grid.n * 2
    for i, m in enumerate(outer):
        rows = man == m
        f = int(flap[rows][0])
        beta = np.concatenate([th[f][:kr], th[f][kr:]])
        xm = np.hstack([x[rows][:, f * kr : (f + 1) * kr], x[rows][:, 2 * kr :]])
        r = y2[rows] - xm @ beta
        n_m = nuis[rows][:, np.abs(nuis[rows]).sum(axis=0) > 0]
        if n_m.size:
            r = r - n_m @ np.linalg.lstsq(n_m, r, rcond=None)[0]
        assert got[i] == pytest.approx(float(r @ r), rel=1e-8)


def _selection_case(corrupt_fold: int | None):
    """60 maneuvers: a roll-damping-like term above 15 deg and a dihedral-like candidate with
    zero truth; with ``corrupt_fold`` set, that fold's maneuvers carry a large dihedral-like
    gap too."""
    rng = np.random.default_rng(21)
    n_man, per = 60, 150
    man = np.repeat(np.arange(n_man), per)
    alpha = rng.uniform(0.0, 30.0, man.size)
    phat = rng.normal(size=man.size)
    beta = rng.normal(size=man.size)
    folds = np.arange(n_man) % 5
    y = (alpha > 15.0) * phat + 0.3 * rng.normal(size=man.size)
    if corrupt_fold is not None:
        y = y + 2.0 * beta * (folds[man] == corrupt_fold)
    grid = cv.HatGrid.covering(alpha, 1.0)
    design = cv.build_design(
        y, man, np.zeros(man.size, dtype=np.int64), alpha, np.column_stack([phat, beta]),
        np.zeros((man.size, 0)), ["phat", "beta"], [], grid, n_man, 1,
    )  # fmt: skip
    cands = [
        Candidate("roll_damping", "aerodynamic", ("phat",)),
        Candidate("dihedral", "aerodynamic", ("beta",)),
    ]
    return design, folds, cands


def test_an_outer_fold_choice_never_depends_on_its_own_maneuvers():
    """Fold 0's maneuvers carry a large spurious dihedral gap. Fold 0's own selection and fit
    must not see it: it chooses what it chooses on the clean data, and its outer error is that
    of the clean data's fold-0 model (fitted on folds 1-4, which are the same in both) applied
    to the corrupted maneuvers: a fit that had included them would have reduced it."""
    cfg = SelectionConfig(n_perm=400)
    design_c, folds, cands = _selection_case(None)
    design_b, _, _ = _selection_case(0)
    clean = outer_evaluation(design_c, folds, cands, cfg)
    bad = outer_evaluation(design_b, folds, cands, cfg)
    assert clean.chosen == [["roll_damping"]] * 5
    assert bad.chosen[0] == clean.chosen[0]
    f0 = np.flatnonzero(folds == 0)
    inner = design_c.subset(np.flatnonzero(folds != 0))
    st = cv.fold_stats(inner, np.searchsorted([1, 2, 3, 4], folds[folds != 0]))
    cols = cv.local_columns(inner, ["phat"], [])
    th = cv.solve(inner, st.total_gram, st.total_xty, cols)
    np.testing.assert_allclose(bad.sse_model[f0], cv.model_sse(design_b, f0, th, cols), rtol=1e-10)
    assert bad.sse_model[f0].sum() > 5 * clean.sse_model[f0].sum()
    # the other folds' selections see fold 0 as one inner fold: an effect in one fold only
    # cannot be validated across folds, and none of them takes dihedral either
    summary = outer_summary(bad, 400, 0)
    assert summary["chosen_in_folds"] == {"roll_damping": 5}
    share, p, k = effect_outer(clean, "roll_damping", 400, 1)
    assert k == 5 and p < 0.01 and share > 0.5
    assert effect_outer(clean, "dihedral", 400, 1) == (0.0, 1.0, 0)
    # the gains of each fold's effects add up to its effects' shrink (selection order)
    total = sum(clean.effect_gain[n] for n in clean.effect_gain)
    np.testing.assert_allclose(total, clean.sse_timing - clean.sse_model, rtol=1e-9, atol=1e-9)
    s_clean = outer_summary(clean, 400, 0)
    assert s_clean["shrink_fraction_effects"] == pytest.approx(
        float((clean.sse_timing - clean.sse_model).sum() / clean.sse_gap.sum())
    )
    assert s_clean["p_value_effects"] < 0.01


@pytest.mark.parametrize("true_skew", [0.0, 0.02])
def test_choices_without_the_report_are_the_same_choices(true_skew):
    """``forward_select(report=False)`` (tests for the largest gain only, no rivals) keeps the
    same effects, in the same order, with the same p-values, as the full selection."""
    rng = np.random.default_rng(12)
    n_man, per = 60, 150
    man = np.repeat(np.arange(n_man), per)
    alpha = rng.uniform(0.0, 30.0, man.size)
    phat, beta, own = rng.normal(size=(3, man.size))
    stall = (alpha > 15.0).astype(float)
    timing = 25.0 * stall * phat + 25.0 * own
    y = stall * phat + 0.2 * beta + true_skew * 25.0 * own + 0.3 * rng.normal(size=man.size)
    grid = cv.HatGrid.covering(alpha, 1.0)
    design = cv.build_design(
        y, man, np.zeros(man.size, dtype=np.int64), alpha, np.column_stack([phat, beta]),
        timing[:, None], ["phat", "beta"], ["m_time_skew"], grid, n_man, 1,
    )  # fmt: skip
    stats = cv.fold_stats(design, np.arange(n_man) % 5)
    cands = [
        Candidate("time_skew", "measurement", ("m_time_skew",)),
        Candidate("roll_damping", "aerodynamic", ("phat",)),
        Candidate("dihedral", "aerodynamic", ("beta",)),
    ]
    cfg = SelectionConfig(n_perm=400)
    full = select.forward_select(design, stats, cands, cfg)
    lean = select.forward_select(design, stats, cands, cfg, report=False)
    got = [(s.candidate.name, s.p_value, s.rank) for s in lean.selected]
    assert got == [(s.candidate.name, s.p_value, s.rank) for s in full.selected]
    assert {"roll_damping", "dihedral"} <= {n for n, _, _ in got}
    for a, b in zip(lean.selected, full.selected, strict=True):
        np.testing.assert_array_equal(a.sse_after, b.sse_after)
