"""Outer-fold (nested) evaluation of the effect selection: held-out numbers that no choice saw.

The selection's own numbers are optimistic: the reported held-out shrink of an effect is that
of the *winner* among every candidate tried on the same folds (a statistics review found 3.7 %
reported where a fresh campaign gave 1.5 %), and its p-value is computed on the maneuvers that
chose it. Nested cross-validation (Stone 1974; Varma & Simon 2006, "Bias in error estimation
when using cross-validation for model selection") removes that bias: for each of the
diagnosis's ``K`` maneuver folds in turn, the whole selection (tests, floors, penalty scales,
all of :func:`~aerodelta.diagnosis.select.forward_select`) is run again on the other ``K - 1``
folds alone, with those as its inner folds; the effects it chooses are fitted on them and
scored on the left-out fold, which took no part in any choice. Over the ``K`` outer folds
every maneuver is scored exactly once, so the per-maneuver improvements are independent units
for a sign-flip test, as in the selection itself.

What is reported per coefficient (``outer`` in ``diagnosis.json``):

- the share of the gap's squared error the *procedure* removes on maneuvers it never saw:
  timing alignment plus the chosen effects, and the chosen effects beyond the timing terms,
  with the sign-flip p-value of the latter (:func:`~aerodelta.diagnosis.cv.improvement_test`,
  no Bonferroni factor: one test per coefficient);
- per effect: in how many outer folds the selection chose it, and its outer gain: on each
  left-out maneuver, what adding the effect removed in its fold's selection order (the error
  before minus after; a timing term, always in the model, by leaving it out of the final
  model), zero where its fold did not choose it, as a share of the gap's squared error, with
  its sign-flip p-value. The gains of a fold's effects other than timing terms add up to its
  effects' shrink.

The verdicts are not changed by these numbers (yet): they are reported beside the selection's
own so that a frozen rule can be built on them and scored on seed sets it was not built on.
Limits: the roll-off spike centres of C_l are found once on all the data (each event's moment
is profiled out of its own maneuver, with amplitudes estimated from that maneuver alone); the
alpha ranges are the full-data ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from aerodelta.diagnosis.cv import (
    Design,
    FloatArray,
    FoldStats,
    IntArray,
    fold_stats,
    improvement_test,
    model_sse,
    total_solve,
)
from aerodelta.diagnosis.flaps import FlapLayout, choose_layout, per_flap_design
from aerodelta.diagnosis.kinds import EntryKinds
from aerodelta.diagnosis.select import (
    SelectionConfig,
    columns_for,
    forward_select,
    material_change,
)
from aerodelta.diagnosis.vocabulary import Candidate

#: Seed offset of outer fold ``o``'s selection (its randomization tests differ from the
#: full-data selection's and from one another's).
_FOLD_SEED = 104729


@dataclass
class OuterEvaluation:
    """Per-maneuver held-out errors of the outer folds (see the module doc).

    Attributes
    ----------
    n_folds
        Outer folds (the diagnosis's folds).
    sse_gap
        Per maneuver, the gap's squared error (no model).
    sse_timing
        Per maneuver, the error after the timing nuisance terms fitted on its outer fold's
        complement (equal to ``sse_gap`` when there are none).
    sse_model
        Per maneuver, the error of its fold's chosen model (timing terms and effects).
    chosen
        Per outer fold, the names of the effects its selection chose.
    effect_gain
        Per effect chosen in at least one fold: per maneuver, the error its adding removed in
        its fold's selection order (0 where the fold did not choose it).
    """

    n_folds: int
    sse_gap: FloatArray
    sse_timing: FloatArray
    sse_model: FloatArray
    chosen: list[list[str]]
    effect_gain: dict[str, FloatArray] = field(default_factory=dict)
    per_flap: list[bool] = field(default_factory=list)  # per outer fold: curves split by flap


def _fit_and_score(
    inner: Design,
    stats: FoldStats,
    design: Design,
    outer: IntArray,
    model: Sequence[Candidate],
) -> FloatArray:
    """Error on the ``outer`` maneuvers of ``model`` fitted on all of ``inner`` (``stats``:
    the inner design's)."""
    if not model:
        return design.yty[outer].astype(float)
    cols = columns_for(inner, model)
    th = total_solve(inner, stats, cols)
    return model_sse(design, outer, th, cols)


def outer_evaluation(
    design: Design,
    folds: IntArray,
    candidates: Sequence[Candidate],
    cfg: SelectionConfig,
    layout: FlapLayout | None = None,
    *,
    kinds: EntryKinds | None = None,
) -> OuterEvaluation:
    """Run the selection once per outer fold on the other folds and score the left-out one.

    Parameters
    ----------
    design
        The coefficient's per-maneuver statistics (as the full-data selection used them).
    folds
        Fold per maneuver (``0..K-1``), the diagnosis's.
    candidates
        The candidate effects (as given to the full-data selection).
    cfg
        Thresholds of the selection (the same as the full-data selection's).
    layout
        Each maneuver's flap, when the full-data diagnosis chooses between one curve for all
        flaps and one per flap (:mod:`aerodelta.diagnosis.flaps`): each outer fold makes that
        choice again on its own inner folds. ``None``: ``design``'s layout, as given.
    kinds
        Each maneuver's entry kind, for the effects' entry-kind consistency check
        (:mod:`aerodelta.diagnosis.kinds`), which each outer fold's selection makes on its
        own inner maneuvers. ``None``: no check.
    """
    folds = np.asarray(folds, dtype=np.int64)
    n_q = int(folds.max()) + 1 if folds.size else 0
    m = design.n_maneuvers
    sse_gap = design.yty.astype(float).copy()
    sse_timing = sse_gap.copy()
    sse_model = sse_gap.copy()
    chosen: list[list[str]] = []
    gains: dict[str, FloatArray] = {}
    split: list[bool] = []
    for o in range(n_q):
        outer = np.flatnonzero(folds == o)
        inner_idx = np.flatnonzero(folds != o)
        if outer.size == 0 or inner_idx.size == 0:
            chosen.append([])
            split.append(False)
            continue
        inner = design.subset(inner_idx)
        # the inner folds: the other outer folds, renumbered 0..K-2
        inner_folds = np.searchsorted(np.unique(folds[inner_idx]), folds[inner_idx])
        stats = fold_stats(inner, inner_folds)
        fold_cfg = replace(cfg, seed=cfg.seed + _FOLD_SEED * (o + 1))
        kc = kinds.subset(inner_idx) if kinds is not None else None
        sel = forward_select(inner, stats, candidates, fold_cfg, report=False, kinds=kc)
        scored = design
        per_flap = False
        if layout is not None:
            inner_layout = FlapLayout(layout.man_flap[inner_idx], layout.n_flaps)
            ch = choose_layout(inner, stats, sel, candidates, inner_layout, fold_cfg, report=False)
            inner, stats, sel, per_flap = ch.design, ch.stats, ch.sel, ch.per_flap
            if per_flap:
                scored = per_flap_design(design, layout)
        split.append(per_flap)
        total = stats
        nuis = list(sel.nuisance)
        effects = [s.candidate for s in sel.selected if s.candidate not in nuis]
        model = nuis + effects
        sse_timing[outer] = _fit_and_score(inner, total, scored, outer, nuis)
        sse_model[outer] = with_all = _fit_and_score(inner, total, scored, outer, model)
        chosen.append([s.candidate.name for s in sel.selected])
        # each chosen effect's gain in its fold's selection order (the timing terms, always
        # in the model, by leaving each out of the final model), as the selection reports it
        prev, so_far = sse_timing[outer], list(nuis)
        for s in sel.selected:
            if s.candidate in nuis:
                rest = [c for c in model if c is not s.candidate]
                gain = _fit_and_score(inner, total, scored, outer, rest) - with_all
            else:
                so_far.append(s.candidate)
                now = _fit_and_score(inner, total, scored, outer, so_far)
                gain, prev = prev - now, now
            gains.setdefault(s.candidate.name, np.zeros(m))[outer] = gain
    return OuterEvaluation(n_q, sse_gap, sse_timing, sse_model, chosen, gains, split)


def outer_summary(ev: OuterEvaluation, n_perm: int, seed: int) -> dict[str, object]:
    """The ``outer`` block of a coefficient in ``diagnosis.json`` (module doc)."""
    total = float(ev.sse_gap.sum())

    def share(d: FloatArray) -> float:
        return float(d.sum()) / total if total > 0 else 0.0

    d_eff = material_change(ev.sse_timing, ev.sse_model)
    _, p_eff = improvement_test(d_eff, n_perm, seed)
    counts: dict[str, int] = {}
    for names in ev.chosen:
        for n in names:
            counts[n] = counts.get(n, 0) + 1
    return {
        "folds": ev.n_folds,
        "n_maneuvers": int(ev.sse_gap.size),
        "shrink_fraction": share(ev.sse_gap - ev.sse_model),
        "shrink_fraction_timing": share(ev.sse_gap - ev.sse_timing),
        "shrink_fraction_effects": share(ev.sse_timing - ev.sse_model),
        "p_value_effects": p_eff,
        "chosen_per_fold": [list(c) for c in ev.chosen],
        "chosen_in_folds": dict(sorted(counts.items())),
        "per_flap_folds": int(sum(ev.per_flap)),
    }


def effect_outer(
    ev: OuterEvaluation, name: str, n_perm: int, seed: int
) -> tuple[float, float, int]:
    """One effect's outer gain share, its sign-flip p-value and the folds that chose it."""
    folds_chosen = sum(1 for c in ev.chosen if name in c)
    g = ev.effect_gain.get(name)
    total = float(ev.sse_gap.sum())
    if g is None or folds_chosen == 0:
        return 0.0, 1.0, 0
    d = material_change(ev.sse_model + g, ev.sse_model)
    _, p = improvement_test(d, n_perm, seed)
    return (float(g.sum()) / total if total > 0 else 0.0), p, folds_chosen
