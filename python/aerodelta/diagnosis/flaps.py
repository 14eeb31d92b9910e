"""One alpha curve for all flaps, or one per flap: chosen from the data by the selection's rule.

By default the diagnosis fits each candidate's alpha curve once for all flaps (five times the
data per parameter). When an effect differs between flaps (a sideslip derivative whose Δ at
flap 40 is not the one at flap 0), one shared curve fits their mean: the reported shrink is
understated and the onset lands where the flaps agree (on the JSBSim DHC-6, session 11: shrink
0.25-0.70 of the oracle's and the onset 4-6 deg late, where ``--per-flap`` gave 1.00-1.27 and
onsets within 1 deg).

The refinement is judged as one more candidate, by the rule every effect passes
(:mod:`aerodelta.diagnosis.select`, module doc; no threshold of its own): after the selection
on the shared layout, the chosen model (timing terms and effects) is fitted per flap on the
same folds; the per-flap curves are kept when the per-maneuver held-out improvement over the
shared ones passes the sign-flip test at ``alpha`` (one test) and removes at least
``min_shrink`` of the gap's squared error (or ``min_shrink_broad`` with the broad evidence).
Then the selection is run again on the per-flap layout, as ``per_flap=True`` would. Only a
model with an alpha-dependent (aerodynamic) effect is refined: the timing and measurement
terms are global and the same in both layouts. The outer folds of
:mod:`aerodelta.diagnosis.nested` make the same choice on their own inner folds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from aerodelta.diagnosis.cv import (
    Design,
    FoldStats,
    IntArray,
    fold_stats,
    heldout_sse,
    improvement_test,
    signed_rank_p,
)
from aerodelta.diagnosis.select import (
    Selection,
    SelectionConfig,
    columns_for,
    forward_select,
    material_change,
    regressors_of,
    robust_gain,
)
from aerodelta.diagnosis.vocabulary import Candidate

#: Seed offset of the refinement's randomization tests.
_SEED = 613


@dataclass(frozen=True)
class FlapLayout:
    """The flaps a refinement can split the curves by: each maneuver's flap index (into the
    sorted flaps of the data) and how many flaps there are."""

    man_flap: IntArray
    n_flaps: int


@dataclass
class LayoutChoice:
    """Outcome of :func:`choose_layout` (``design``/``stats``/``sel`` are the ones to use)."""

    design: Design
    stats: FoldStats
    sel: Selection
    per_flap: bool
    report: dict[str, Any]


def per_flap_design(design: Design, layout: FlapLayout) -> Design:
    """``design`` with each maneuver's local block counted under its own flap (the statistics
    are per maneuver; only the layout they are summed into changes)."""
    if design.man_flap.size != layout.man_flap.size:
        raise ValueError(
            f"flap layout of {layout.man_flap.size} maneuvers for a design of "
            f"{design.man_flap.size}"
        )
    return replace(design, n_flaps=layout.n_flaps, man_flap=np.asarray(layout.man_flap, np.int64))


def choose_layout(  # noqa: PLR0917 - the selection's state, all needed
    design: Design,
    stats: FoldStats,
    sel: Selection,
    candidates: Sequence[Candidate],
    layout: FlapLayout,
    cfg: SelectionConfig,
    report: bool = True,
) -> LayoutChoice:
    """Keep the shared curves, or refit per flap when the data ask for it (module doc).

    Parameters
    ----------
    design, stats, sel
        The coefficient's statistics on the shared layout, their fold sums and the
        selection made on them.
    candidates
        The candidates given to that selection (the per-flap selection gets the same).
    layout
        Each maneuver's flap (:class:`FlapLayout`).
    cfg
        The selection's thresholds, used unchanged.
    report
        Passed to the per-flap selection (``False`` in the outer folds).
    """
    model = list(sel.nuisance) + [
        s.candidate for s in sel.selected if s.candidate not in sel.nuisance
    ]
    aero = [c for c in model if not c.global_]
    keep = LayoutChoice(design, stats, sel, False, {"layout": "shared", "tested": False})
    if layout.n_flaps < 2:
        keep.report["reason"] = "one flap in the data"
        return keep
    if not aero:
        keep.report["reason"] = "no alpha-dependent effect selected"
        return keep
    # the shared model's held-out errors are the selection's own (memoised); the per-flap
    # ones are computed on the model's regressors only (Design.restrict: the same fits)
    sse_shared = heldout_sse(design, stats, columns_for(design, model))[0]
    small = per_flap_design(design.restrict(*regressors_of(model)), layout)
    sse_per = heldout_sse(small, fold_stats(small, stats.folds), columns_for(small, model))[0]
    d = material_change(sse_shared, sse_per)
    _, p = improvement_test(d, cfg.n_perm, cfg.seed + _SEED)
    total0 = float(sel.sse0.sum())
    gain = robust_gain(d)
    share = gain / total0 if total0 > 0 else 0.0
    passes = p < cfg.alpha and gain >= cfg.min_shrink * total0
    if not passes and p < cfg.alpha and gain >= cfg.min_shrink_broad * total0:
        rank_p = signed_rank_p(d, cfg.n_perm, cfg.seed + _SEED + 2)
        passes = rank_p < cfg.alpha * cfg.broad_alpha_factor
    info: dict[str, Any] = {
        "tested": True,
        "effects_refined": [c.name for c in aero],
        "shrink_fraction": share,
        "p_value": p,
    }
    if not passes:
        return LayoutChoice(design, stats, sel, False, {"layout": "shared", **info})
    per = per_flap_design(design, layout)
    pstats = fold_stats(per, stats.folds)
    psel = forward_select(per, pstats, candidates, cfg, report=report)
    return LayoutChoice(per, pstats, psel, True, {"layout": "per_flap", **info})
