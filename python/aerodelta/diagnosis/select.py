"""Greedy forward selection of candidate effects by held-out (cross-validated) gap reduction.

At each step every remaining candidate is added in turn to the effects already selected; the
one that lowers the held-out squared gap most is kept if

1. the improvement is real: sign-flip randomization tests over maneuvers of the per-maneuver
   held-out improvement (maneuvers are the independent units, so coloured residuals inside a
   maneuver do not inflate the evidence): Wilcoxon's signed ranks, for effects that help
   many maneuvers, and the plain sum, for effects that act in a minority of them (both
   combined by Bonferroni, :func:`~aerodelta.diagnosis.cv.improvement_test`), corrected
   for the candidates tried at that step, is below ``alpha``; and
2. it matters: the improvement is at least ``min_shrink`` of the held-out gap's squared error,
   and a measurement effect's parameter is above its practical floor (:data:`PRACTICAL_FLOOR`),
   so a statistically significant but negligible change, such as a few milliseconds of time
   skew, is not reported as an effect. A smaller improvement, down to ``min_shrink_broad``,
   counts only when it is broad: the signed-rank test alone (most maneuvers improve, not a
   few), exact and Bonferroni-corrected, passes at ``alpha * broad_alpha_factor``.

Candidates that were significant on their own at the step an effect was chosen, whose
held-out error cannot be told apart from the chosen one's (paired sign-flip test over
maneuvers, ``p > ambiguity_p``, or a difference under the effect-size floor ``min_shrink``;
:func:`_indistinct`) and that are not selected themselves, are reported as ambiguous with it.

A selected effect must not make the stalls of one entry kind worse (:func:`kind_consistency`,
:mod:`aerodelta.diagnosis.kinds`); the selection is made again without an effect that does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aerodelta.diagnosis.cv import (
    Design,
    FloatArray,
    FoldStats,
    IntArray,
    heldout_sse,
    improvement_test,
    improvement_tests,
    local_columns,
    sign_flip_pvalue,
    signed_rank_p,
    total_solve,
)
from aerodelta.diagnosis.kinds import EntryKinds
from aerodelta.diagnosis.vocabulary import Candidate

#: Practical floors of the measurement effects' parameters: below these an effect is
#: negligible however significant (0.1 deg of vane bias; 8 ms of lag or skew, under one frame
#: of a 100 Hz simulator and about the half-sample delay that zero-order-held controls and
#: numerically differentiated rates always carry; 3 cm of accelerometer displacement).
PRACTICAL_FLOOR: dict[str, float] = {
    "m_alpha_bias": 0.1,
    "m_beta_bias": 0.1,
    "m_control_lag": 0.008,
    "m_time_skew": 0.008,
    "m_acc_dx": 0.03,
    "m_acc_dz": 0.03,
}


@dataclass(frozen=True)
class SelectionConfig:
    """Thresholds of the selection.

    Attributes
    ----------
    alpha
        Familywise significance level per step (Bonferroni over the candidates tried).
    min_shrink
        Effect-size floor: the fraction of the held-out gap's squared error an effect must
        remove to be reported (robust gain, :func:`robust_gain`). Tried at 1.5 % (session 5):
        a C_Y sideslip-derivative loss at half magnitude that 2 % misses (2.3 % removed held
        out, under 2 % after the cap) was then found, but on a fresh seed set an unlisted
        beta*rhat effect was attributed to lateral asymmetry (2.05 %, p = 0.004): a confident
        wrong answer is worse than "none", so the floor stays at 2 %.
    min_shrink_broad
        Lower effect-size floor for broad effects (session 6). The two cases above are the
        same size (1.83 % and 1.77 % after the cap) but not the same evidence: the sideslip
        derivative improved 69 % of the maneuvers (exact signed-rank p ~ 1e-12), the misfit
        53 % (p = 0.013 before the Bonferroni factor; its sum test, which sees gains in a
        minority, carried it). So an effect between ``min_shrink_broad`` and ``min_shrink``
        is reported only when the signed-rank test alone passes at
        ``alpha * broad_alpha_factor``.
    broad_alpha_factor
        Factor on ``alpha`` of that signed-rank test.
    ambiguity_p
        A rival whose held-out error is not significantly worse than the chosen effect's at
        this level (paired test) is ambiguous with it.
    n_perm
        Sign-flip draws of the randomization tests.
    max_effects
        Most effects selected per coefficient.
    seed
        Seed of the randomization tests.
    """

    alpha: float = 0.01
    min_shrink: float = 0.02
    min_shrink_broad: float = 0.015
    broad_alpha_factor: float = 0.1
    ambiguity_p: float = 0.05
    n_perm: int = 4000
    max_effects: int = 6
    seed: int = 0


@dataclass
class Step:
    """One candidate's score at one step."""

    candidate: Candidate
    sse: FloatArray  # held-out SSE per maneuver with the candidate added
    gain: float  # total held-out SSE removed, each maneuver's share capped (robust_gain)
    statistic: float
    p_value: float  # Bonferroni-corrected
    thetas: list[list[FloatArray]]
    rank_p: float = 1.0  # exact signed-rank p alone, Bonferroni-corrected (broad evidence)
    parameters: dict[str, float] = field(default_factory=dict)  # global ones, full data
    material: bool = True  # parameters above their practical floors
    # held-out SSE per maneuver without the candidate, where that is not the model of the last
    # step (a timing nuisance term, always in the model, scored by leaving it out)
    sse_before: FloatArray | None = None


@dataclass
class Selected:
    """An effect kept by the selection."""

    candidate: Candidate
    rank: int
    sse_before: FloatArray
    sse_after: FloatArray
    statistic: float
    p_value: float
    ambiguous_with: list[str] = field(default_factory=list)


@dataclass
class Selection:
    """Outcome of :func:`forward_select`."""

    selected: list[Selected]
    final_scores: dict[str, Step]  # every unselected candidate scored at the last step
    sse0: FloatArray
    nuisance: list[Candidate] = field(default_factory=list)  # always in the model
    sse_nuisance: FloatArray | None = None
    # the entry-kind consistency checks (kind_consistency): the effects checked, and those
    # rejected, without which this selection was made
    kind_check: dict[str, Any] | None = None


#: Timing candidates kept in every model as nuisance terms: data always carry a small lag
#: between channels (zero-order-held controls, differentiated rates); they are reported as
#: effects only when their estimate passes the practical floor and the tests.
NUISANCE = frozenset({"control_lag", "time_skew"})


def regressors_of(cands: Sequence[Candidate]) -> tuple[list[str], list[str]]:
    """The aerodynamic (alpha-dependent) and the global regressors of a set of candidates,
    each sorted and without repeats."""
    aero = {r for c in cands if not c.global_ for r in c.regressors}
    glob = {r for c in cands if c.global_ for r in c.regressors}
    return sorted(aero), sorted(glob)


def _cols(design: Design, cands: Sequence[Candidate]) -> tuple[IntArray, IntArray]:
    return local_columns(design, *regressors_of(cands))


#: Quantile of the per-maneuver absolute improvements at which :func:`robust_gain` caps each
#: maneuver's share (the top 5 %: 10 of a 200-maneuver campaign).
GAIN_CAP_QUANTILE = 0.95


def robust_gain(d: FloatArray) -> float:
    """Total held-out improvement with each maneuver's share capped at the
    :data:`GAIN_CAP_QUANTILE` of the absolute improvements: an effect must help many
    maneuvers, not one or two whose gap holds an unmasked transient (a roll-off spike the
    detector rejected). The cap was the 90th percentile until session 4: a real effect past
    the stall lives in the stalls that reach it (a sideslip-rate term in C_Y: 2.5 % of the gap
    removed held-out, 1.9 % after capping the top 20 of 200 maneuvers, under the 2 % floor)."""
    nz = np.abs(d[d != 0.0])
    if nz.size == 0:
        return 0.0
    q = float(np.quantile(nz, GAIN_CAP_QUANTILE))
    return float(np.clip(d, -np.inf, q).sum())


def material_change(sse_before: FloatArray, sse_after: FloatArray) -> FloatArray:
    """Per-maneuver held-out improvement, with changes under 0.1 % of the maneuver's own
    squared gap set to zero: a candidate whose regressor is zero in a maneuver (thrust
    difference in a symmetric-thrust stall) moves that maneuver's error only through the
    refit of the other terms, which is no evidence either way (a tie, left out of the ranks)."""
    d = sse_before - sse_after
    return np.where(np.abs(d) < 1e-3 * np.maximum(sse_before, 1e-300), 0.0, d)


def score(  # noqa: PLR0917 - internal scoring step
    design: Design,
    stats: FoldStats,
    base: Sequence[Candidate],
    cand: Candidate,
    sse_before: FloatArray,
    cfg: SelectionConfig,
    n_tests: int,
    seed: int,
    tests: bool = True,
) -> Step:
    """Held-out score of adding ``cand`` to ``base`` (with ``tests=False`` the randomization
    tests are skipped: statistic 0, p-values 1; :func:`with_tests` adds them later)."""
    sse, thetas = heldout_sse(design, stats, _cols(design, [*base, cand]))
    params: dict[str, float] = {}
    material = True
    if cand.global_:
        cols = _cols(design, [*base, cand])
        th = total_solve(design, stats, cols)[0]
        k0 = design.grid.n * len(design.aero_names)
        params = {r: float(th[k0 + design.global_names.index(r)]) for r in cand.regressors}
        size = float(np.sqrt(sum(v * v for v in params.values())))
        floor = max(PRACTICAL_FLOOR.get(r, 0.0) for r in cand.regressors)
        material = size >= floor
    gain = robust_gain(sse_before - sse)
    st = Step(cand, sse, gain, 0.0, 1.0, thetas, 1.0, params, material)
    return with_tests(st, sse_before, cfg, n_tests, seed) if tests else st


def with_tests(
    st: Step, sse_before: FloatArray, cfg: SelectionConfig, n_tests: int, seed: int
) -> Step:
    """``st`` (scored against ``sse_before``) with its randomization tests, Bonferroni-corrected
    over ``n_tests`` candidates: the combined test, and the signed-rank test alone (the
    broad-effect evidence) when the combined one passes."""
    with_tests_many([st], sse_before, cfg, n_tests, [seed])
    return st


def with_tests_many(
    steps: Sequence[Step],
    sse_before: FloatArray,
    cfg: SelectionConfig,
    n_tests: int,
    seeds: Sequence[int],
) -> None:
    """The randomization tests of each of ``steps`` (its seed in ``seeds``; see
    :func:`with_tests`), the draws of all of them counted at once
    (:func:`~aerodelta.diagnosis.cv.improvement_tests`): the same numbers as one call each.
    The broad-effect test is run only for an effect that passes the main test (:func:`_passes`
    needs it only then)."""
    ds = [material_change(sse_before, st.sse) for st in steps]
    for st, d, seed, (z, p) in zip(
        steps, ds, seeds, improvement_tests(ds, cfg.n_perm, seeds), strict=True
    ):
        st.statistic, st.p_value = z, min(1.0, p * n_tests)
        if st.p_value < cfg.alpha:
            st.rank_p = min(1.0, signed_rank_p(d, cfg.n_perm, seed + 2) * n_tests)


def _passes(st: Step, cfg: SelectionConfig, total0: float) -> bool:
    """The tests and floors an effect must pass to be reported (module doc, 1 and 2)."""
    if not (st.material and st.p_value < cfg.alpha):
        return False
    if st.gain >= cfg.min_shrink * total0:
        return True
    broad = st.rank_p < cfg.alpha * cfg.broad_alpha_factor
    return broad and st.gain >= cfg.min_shrink_broad * total0


def _left_out(  # noqa: PLR0917 - internal scoring step
    design: Design,
    stats: FoldStats,
    model: Sequence[Candidate],
    cand: Candidate,
    cfg: SelectionConfig,
    n_tests: int,
    seed: int,
    sse_empty: FloatArray,
) -> Step:
    """Score of ``cand``, a term of ``model`` (a timing nuisance term, always in the model),
    against ``model`` without it; ``sse_empty`` is the held-out SSE of the empty model."""
    rest = [x for x in model if x is not cand]
    sse_wo = heldout_sse(design, stats, _cols(design, rest))[0] if rest else sse_empty
    st = score(design, stats, rest, cand, sse_wo, cfg, n_tests, seed)
    st.sse_before = sse_wo
    return st


#: Seed offset of the entry-kind consistency test (from the selection's seed).
_KIND_SEED = 4409


def kind_consistency(  # noqa: PLR0917 - the selection's state, all needed
    design: Design,
    stats: FoldStats,
    model: Sequence[Candidate],
    effect: Candidate,
    kinds: EntryKinds,
    cfg: SelectionConfig,
) -> dict[str, Any]:
    """The entry-kind consistency check of ``effect``, a term of the selected ``model``
    (timing terms included; :mod:`aerodelta.diagnosis.kinds`): the held-out change each
    maneuver owes to the effect in the model, tested per entry kind for a worsening
    (:func:`~aerodelta.diagnosis.cv.improvement_test` of the negated changes over the kind's
    maneuvers, Bonferroni over the kinds). Rejected when some kind is worse, significantly at
    ``cfg.alpha`` and materially: by at least ``cfg.min_shrink`` of that kind's own held-out
    squared gap (the effect-size floor an effect must clear to be reported, applied to the
    harm it does).

    Returns, per kind, its maneuvers, the fraction by which the effect raises the kind's
    held-out squared gap (``kind_worse_fraction``, negative: lowers), the share of the whole
    gap's squared error it removes in the kind, the fraction of the kind's maneuvers it
    improves and the corrected p-value of the worsening; and ``rejected``."""
    rest = [c for c in model if c is not effect]
    sse_m = heldout_sse(design, stats, _cols(design, model))[0]
    sse_wo = heldout_sse(design, stats, _cols(design, rest))[0] if rest else design.yty
    d = material_change(sse_wo, sse_m)
    total0 = float(design.yty.sum())
    n_k = len(kinds.kinds)
    per: dict[str, dict[str, float]] = {}
    rejected = False
    for i, k in enumerate(kinds.kinds):
        mask = kinds.man_kind == i
        dk = d[mask]
        p = 1.0
        if np.count_nonzero(dk) > 0:
            _, p = improvement_test(-dk, cfg.n_perm, cfg.seed + _KIND_SEED + i)
            p = min(1.0, p * n_k)
        own = float(sse_wo[mask].sum())
        worse = -float(dk.sum()) / own if own > 0 else 0.0
        rejected = rejected or (p < cfg.alpha and worse >= cfg.min_shrink)
        per[k] = {
            "n_maneuvers": int(dk.size),
            "kind_worse_fraction": worse,
            "shrink_fraction": float(dk.sum()) / total0 if total0 > 0 else 0.0,
            "improved_fraction": float(np.mean(dk > 0)) if dk.size else 0.0,
            "p_worse": float(p),
        }
    return {"effect": effect.name, "per_kind": per, "rejected": rejected}


def forward_select(  # noqa: PLR0917 - the selection's inputs
    design: Design,
    stats: FoldStats,
    candidates: Sequence[Candidate],
    cfg: SelectionConfig,
    report: bool = True,
    kinds: EntryKinds | None = None,
) -> Selection:
    """Greedy forward selection (see the module doc).

    With ``report=False`` only the choices are made, as the outer folds of
    :mod:`aerodelta.diagnosis.nested` need them: at each step the randomization tests run for
    the candidate of largest gain only (the one the step keeps or stops at; the same seeds,
    so the same decisions), ambiguous rivals are not looked for, and the unselected
    candidates' scores carry no p-values.

    ``kinds`` (each maneuver's entry kind, :mod:`aerodelta.diagnosis.kinds`) makes every
    selected effect (the timing terms aside) pass :func:`kind_consistency`; the selection is
    made again without the effects that fail, until none does, and the checks are kept in
    :attr:`Selection.kind_check`. ``None``: no check.
    """
    cands = list(candidates)
    rejected: list[dict[str, Any]] = []
    while True:
        sel = _forward_select(design, stats, cands, cfg, report)
        if kinds is None:
            return sel
        effects = [s.candidate for s in sel.selected if s.candidate not in sel.nuisance]
        model = [*sel.nuisance, *effects]
        checks = [kind_consistency(design, stats, model, e, kinds, cfg) for e in effects]
        failed = [c for c in checks if c["rejected"]]
        if not failed:  # bounded: each pass removes at least one candidate
            sel.kind_check = {"checked": [c["effect"] for c in checks], "rejected": rejected}
            return sel
        rejected += failed
        out = {c["effect"] for c in failed}
        cands = [c for c in cands if c.name not in out]


def _indistinct(
    sse_rival: FloatArray, sse_chosen: FloatArray, cfg: SelectionConfig, total0: float, seed: int
) -> bool:
    """Whether the data cannot tell a rival from the chosen effect: the chosen one's held-out
    error is not significantly lower (paired sign-flip test over maneuvers,
    ``p > ambiguity_p``), or lower by less than the effect-size floor (``min_shrink`` of the
    gap's squared error, each maneuver's share capped as in :func:`robust_gain`): a difference
    too small to report as an effect is too small to choose between two explanations by.
    On the virtual aircraft, whose spoilers are slaved to the wheel, a withheld aileron
    effectiveness loss (with a control lag and a directional-stability loss, development case
    8505) was named ``spoiler_effect``: the aileron in its place left 0.19 % more of the gap,
    significant over the maneuvers (p < 0.05) but far under the floor."""
    d = material_change(sse_rival, sse_chosen)
    if robust_gain(d) < cfg.min_shrink * total0:
        return True
    _, p_pair = sign_flip_pvalue(d, cfg.n_perm, seed)
    return p_pair > cfg.ambiguity_p


def _forward_select(
    design: Design,
    stats: FoldStats,
    candidates: Sequence[Candidate],
    cfg: SelectionConfig,
    report: bool,
) -> Selection:
    """:func:`forward_select` without the entry-kind checks."""
    sse0 = design.yty.copy()
    total0 = float(sse0.sum())
    nuis = [c for c in candidates if c.name in NUISANCE]
    current: list[Candidate] = list(nuis)
    sse_cur = sse0
    selected: list[Selected] = []
    nuis_scores: dict[str, Step] = {}
    if nuis:
        sse_cur = heldout_sse(design, stats, _cols(design, nuis))[0]
        for i, c in enumerate(nuis):
            st = _left_out(design, stats, nuis, c, cfg, len(candidates), cfg.seed + 101 + i, sse0)
            if _passes(st, cfg, total0):
                selected.append(
                    Selected(c, len(selected) + 1, st.sse_before, st.sse, st.statistic, st.p_value)
                )
            else:
                nuis_scores[c.name] = st
    sse_nuis = sse_cur.copy() if nuis else None
    remaining = [c for c in candidates if c.name not in NUISANCE]
    scores: dict[str, Step] = {}
    step_i = 0
    while remaining:
        n_tests = len(remaining)
        seeds = {c.name: cfg.seed + 7919 * step_i + i for i, c in enumerate(remaining)}
        scores = {
            c.name: score(design, stats, current, c, sse_cur, cfg, n_tests, seeds[c.name], False)
            for c in remaining
        }
        if report:
            with_tests_many(
                list(scores.values()), sse_cur, cfg, n_tests, [seeds[n] for n in scores]
            )
        eligible = [s for s in scores.values() if s.material]
        if not eligible:
            break
        best = max(eligible, key=lambda s: s.gain)
        if not report:
            with_tests(best, sse_cur, cfg, n_tests, seeds[best.candidate.name])
        if not (_passes(best, cfg, total0) and len(selected) < cfg.max_effects):
            break
        rivals = []
        for name, s in scores.items():
            if name == best.candidate.name or not report:
                continue
            if _passes(s, cfg, total0) and _indistinct(
                s.sse, best.sse, cfg, total0, cfg.seed + 31 + step_i
            ):
                rivals.append(name)
        selected.append(
            Selected(
                best.candidate,
                len(selected) + 1,
                sse_cur,
                best.sse,
                best.statistic,
                best.p_value,
                rivals,
            )
        )
        current.append(best.candidate)
        sse_cur = best.sse
        remaining = [c for c in remaining if c.name != best.candidate.name]
        step_i += 1
    # A timing term kept at the nuisance stage was judged before any aerodynamic effect was in
    # the model, where it could absorb part of an unmodelled effect's gap (on a campaign with
    # roll damping withheld and no timing error, a time skew passed its tests and floor there,
    # and came out at -5.5 ms in the final model): it is judged again in the final model, by
    # the same tests and floors, and reported only if it still passes.
    # The timing terms left out are scored in the final model too, for the effect list.
    if nuis and len(current) > len(nuis):
        was = {s.candidate.name: s for s in selected}
        kept = [s for s in selected if s.candidate.name not in NUISANCE]
        for i, c in enumerate(nuis):
            st = _left_out(
                design, stats, current, c, cfg, len(candidates), cfg.seed + 211 + i, sse0
            )
            if c.name in was and _passes(st, cfg, total0):
                kept.append(
                    Selected(c, was[c.name].rank, st.sse_before, st.sse, st.statistic, st.p_value)
                )
                nuis_scores.pop(c.name, None)
            else:
                nuis_scores[c.name] = st
        selected = sorted(kept, key=lambda x: x.rank)
    # A rival that was itself selected later is not ambiguous: both are real.
    chosen = {s.candidate.name for s in selected}
    for s in selected:
        s.ambiguous_with = [r for r in s.ambiguous_with if r not in chosen]
    final = {**nuis_scores, **{k: v for k, v in scores.items() if k not in chosen}}
    return Selection(selected, final, sse0, nuis, sse_nuis)


def columns_for(design: Design, cands: Sequence[Candidate]) -> tuple[IntArray, IntArray]:
    """Full-layout columns of a set of candidates."""
    return _cols(design, cands)
