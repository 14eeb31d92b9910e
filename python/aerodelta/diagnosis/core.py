"""The sim-to-real gap diagnosis: where the gap lies, which effect causes it, how far it shrinks.

See DESIGN.md ("The sim-to-real gap diagnosis") and issue 7. The diagnosis reads the flight
records and the simulator only; it never opens a campaign's ``truth/`` folder (enforced by
:func:`aerodelta.diagnosis.data.read_parquet_guarded`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from aerodelta._core import __version__
from aerodelta._groups import group_agg
from aerodelta.diagnosis.band import BAND_CHANNEL, band_cutoffs, band_match
from aerodelta.diagnosis.cv import (
    Design,
    FoldStats,
    HatGrid,
    build_design,
    fold_prediction,
    fold_solves,
    fold_stats,
    profile_out,
    row_prediction,
    total_solve,
)
from aerodelta.diagnosis.data import in_order, load_records, maneuver_codes, sorted_columns
from aerodelta.diagnosis.flaps import FlapLayout, choose_layout
from aerodelta.diagnosis.kinds import EntryKinds
from aerodelta.diagnosis.nested import effect_outer, outer_evaluation, outer_summary
from aerodelta.diagnosis.regressors import (
    delayed_controls,
    design_columns,
    measurement_columns,
)
from aerodelta.diagnosis.report import summary_text
from aerodelta.diagnosis.select import (
    PRACTICAL_FLOOR,
    Selection,
    SelectionConfig,
    columns_for,
    forward_select,
    regressors_of,
)
from aerodelta.diagnosis.simulator import load_simulator
from aerodelta.diagnosis.stochastic import DETECTOR_CHANNELS, event_columns, rolloff_finding
from aerodelta.diagnosis.vocabulary import (
    COEFFICIENTS,
    NEEDS_MODEL,
    Candidate,
    Vocabulary,
    default_vocabulary,
)
from aerodelta.diagnosis.where import (
    PHASES,
    REGIONS,
    gap_map,
    phase_codes,
    region_codes,
    stall_alphas,
    worst_segments,
)
from aerodelta.exceptions import DataError
from aerodelta.fit import theil_inequality

SCHEMA = "aerodelta.diagnosis/1"

#: Measurement regressors computed from the simulator's output (band-matched with it).
SIM_REGRESSORS = ("m_alpha_bias", "m_beta_bias", "m_control_lag", "m_time_skew")

#: The columns of the records the diagnosis holds sorted throughout (others are sorted when
#: they are read: the measured coefficients, the stall alpha's and the roll-off detector's).
FRAME_COLUMNS = ("maneuver_id", "t", "alpha_deg", "flap_deg", "kind")

#: The columns :func:`aerodelta.diagnosis.where.stall_alphas` reads.
STALL_COLUMNS = ("flap_deg", "alpha_deg", "CX_meas", "CZ_meas", "ct_left", "ct_right")


def _with_columns(
    frame: pl.DataFrame, records: pl.DataFrame, order: np.ndarray | None, columns: Sequence[str]
) -> pl.DataFrame:
    """``frame`` (the sorted :data:`FRAME_COLUMNS`) with the other ``columns`` of ``records``
    that it has, their rows put in ``order`` (``records`` itself when ``order`` is ``None``: it
    is sorted and has them all)."""
    if order is None:
        return records
    extra = [c for c in columns if c in records.columns and c not in frame.columns]
    return frame.with_columns([records[c].gather(order) for c in extra])


def _put_in_order(columns: dict[str, dict[str, np.ndarray]], order: np.ndarray) -> None:
    """Every array of ``columns`` (per regressor, per coefficient) replaced by its rows in
    ``order``, one at a time (an array shared by several entries is gathered once)."""
    done: dict[int, np.ndarray] = {}
    for per_coef in columns.values():
        for c, v in per_coef.items():
            if id(v) not in done:
                done[id(v)] = v[order]
            per_coef[c] = done[id(v)]


@dataclass(frozen=True)
class DiagnoseConfig:
    """Settings of :func:`diagnose` (defaults are the tested ones).

    Attributes
    ----------
    folds
        Cross-validation folds over maneuvers.
    knot_deg
        Spacing of the alpha knots of the aerodynamic candidates, deg.
    selection
        Thresholds of the greedy selection (:class:`SelectionConfig`).
    where_bin_deg
        Alpha bin width of the gap map, deg.
    where_alpha
        False-discovery rate of the gap map's tests (Benjamini-Hochberg over its cells).
    measurement
        Test the measurement effects (vane biases, control lag, time skew, accelerometer).
    per_flap
        ``None`` (default): one alpha curve per candidate shared by all flaps (five times the
        data per parameter), refitted per flap when the per-flap curves pass the selection's
        own test and effect-size floor (:mod:`aerodelta.diagnosis.flaps`), per coefficient.
        ``True``: always per flap; ``False``: always shared. The gap map is per flap either
        way.
    seed
        Seed of the fold assignment and of the randomization tests.
    band_match
        Pass the simulator's output through the band of the measured coefficients before the
        gap is formed (:mod:`aerodelta.diagnosis.band`).
    nested
        Also run the outer-fold evaluation (:mod:`aerodelta.diagnosis.nested`): the selection
        redone without each fold, scored on it; about ``folds`` times the selection's time.
    """

    folds: int = 5
    knot_deg: float = 1.0
    selection: SelectionConfig = field(default_factory=SelectionConfig)
    where_bin_deg: float = 2.0
    where_alpha: float = 0.05
    measurement: bool = True
    per_flap: bool | None = None
    seed: int = 0
    nested: bool = True
    band_match: bool = True


@dataclass
class Diagnosis:
    """The diagnosis (``to_dict()`` is the ``diagnosis.json`` contract).

    Attributes
    ----------
    result
        The JSON-ready dictionary (schema ``aerodelta.diagnosis/1``).
    predictions
        Per row: ``maneuver_id``, ``t``, ``alpha_deg``, ``flap_deg``, ``phase`` and per
        coefficient the gap and the held-out prediction of the selected effects.
    """

    result: dict[str, Any]
    predictions: pl.DataFrame

    def to_dict(self) -> dict[str, Any]:
        """The ``diagnosis.json`` content."""
        return self.result

    def verdict(self, coefficient: str) -> str:
        """The top effect for ``coefficient``, or ``"none"``."""
        return str(self.result["coefficients"][coefficient]["verdict"])

    def significant_effects(self, coefficient: str) -> list[str]:
        """Effects reported significant for ``coefficient``, in selection order."""
        return [
            e["effect"]
            for e in self.result["coefficients"][coefficient]["effects"]
            if e["significant"]
        ]

    def summary(self) -> str:
        """A plain-text summary (what ``aerodelta diagnose`` prints)."""
        return summary_text(self.result)


def _fold_ids(maneuvers: pl.DataFrame, n_folds: int, seed: int) -> np.ndarray:
    """Stratified fold per maneuver (by flap and kind), deterministic for a seed."""
    rng = np.random.default_rng(seed)
    keys = maneuvers.with_columns(pl.Series("__r", rng.random(maneuvers.height)))
    keys = keys.with_row_index("__i").sort(["flap_deg", "kind", "__r"])
    folds = np.zeros(maneuvers.height, dtype=np.int64)
    folds[keys["__i"].to_numpy()] = np.arange(maneuvers.height) % n_folds
    return folds


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def _run_around_peak(bins: np.ndarray, level: np.ndarray, threshold: float) -> list[float]:
    """The run of bins around the highest ``level`` that stay at or above ``threshold`` (a
    one-bin hole in the data does not break it), as ``[lo, hi]`` deg."""
    top = int(np.argmax(level))
    on = level >= threshold
    lo = hi = top
    while lo > 0 and on[lo - 1] and bins[lo] - bins[lo - 1] <= 2:
        lo -= 1
    while hi < bins.size - 1 and on[hi + 1] and bins[hi + 1] - bins[hi] <= 2:
        hi += 1
    return [float(bins[lo]), float(bins[hi]) + 1.0]


def _bin_means(alpha: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per 1-deg alpha bin with 20 points or more: the bins and the mean of ``value``, summed
    in row order (:mod:`aerodelta._groups`: a polars group-by mean splits its sums over the
    thread pool, and the last digits changed with the thread count and between calls)."""
    g = group_agg(
        pl.DataFrame({"b": np.floor(alpha).astype(np.int64), "v": value}),
        ["b"],
        {"v": ("v", "mean")},
        exact=[pl.len().alias("n")],
    ).filter(pl.col("n") >= 20)
    return g["b"].to_numpy(), g["v"].to_numpy()


def _alpha_range(alpha: np.ndarray, contrib: np.ndarray, frac: float = 0.2) -> list[float]:
    """Alpha interval where an effect acts: the run of 1-deg bins around the strongest one
    whose RMS contribution stays at least ``frac`` of that bin's (bins with 20 points or more;
    a one-bin hole in the data does not break the run). An isolated sparse bin far from the
    run, where a poorly excited coefficient is noisy, does not stretch the interval."""
    bins, ms = _bin_means(alpha, contrib * contrib)
    if bins.size == 0 or float(ms.max()) <= 0:
        return [float("nan"), float("nan")]
    rms = np.sqrt(ms)
    return _run_around_peak(bins, rms, frac * float(rms.max()))


def _gain_range(alpha: np.ndarray, gain: np.ndarray, frac: float = 0.2) -> list[float] | None:
    """Alpha interval where adding an effect lowers the *held-out* gap: the run of 1-deg bins
    around the largest mean held-out gain per point whose gain stays at least ``frac**2`` of it
    (an effect of RMS contribution ``c`` removes about ``c**2`` per point, so this matches the
    ``frac`` rule of :func:`_alpha_range` on the contribution). Where a flexible candidate
    only fits noise (its coefficients at alphas the effect never reaches) the held-out gain is
    nil, so that noise does not widen the interval. ``None`` when nothing gains."""
    bins, g = _bin_means(alpha, gain)
    if bins.size == 0 or float(g.max()) <= 0:
        return None
    return _run_around_peak(bins, g, frac * frac * float(g.max()))


def _cv_prediction(
    design: Design, stats: FoldStats, rows: dict[str, np.ndarray], model: Sequence[Candidate]
) -> np.ndarray:
    """Held-out prediction per row of a model (each row predicted by its fold's complement)."""
    thetas = fold_solves(design, stats, columns_for(design, model))
    return fold_prediction(
        design, thetas, rows["fold"], rows["flap"], rows["alpha"], rows["aero"], rows["glob"]
    )


def _effect_rows(
    sel: Selection,
    design: Design,
    stats: FoldStats,
    rows: dict[str, np.ndarray],
) -> tuple[list[dict[str, Any]], list[tuple[str, np.ndarray]]]:
    """The ranked effect list and the cumulative held-out predictions per step (a first
    ``timing_alignment`` step when the timing nuisance terms are in the model)."""
    total0 = float(sel.sse0.sum())
    n = float(design.n_rows.sum())
    out: list[dict[str, Any]] = []
    steps: list[tuple[str, np.ndarray]] = []
    base = list(sel.nuisance)
    if base:
        steps.append(("timing_alignment", _cv_prediction(design, stats, rows, base)))
    chosen: list[Candidate] = []
    full_model = base + [s.candidate for s in sel.selected if s.candidate not in base]
    theta_full = total_solve(design, stats, columns_for(design, full_model))
    y = rows["y"]
    for s in sel.selected:
        held_gain = None
        if s.candidate not in base:
            chosen.append(s.candidate)
            prev = steps[-1][1] if steps else np.zeros_like(y)
            pred = _cv_prediction(design, stats, rows, base + chosen)
            steps.append((s.candidate.name, pred))
            held_gain = (y - prev) ** 2 - (y - pred) ** 2
        # this effect's own contribution in the full-data fit of the final model
        ce = np.concatenate(columns_for(design, [s.candidate]))
        th_e = [np.zeros_like(t) for t in theta_full]
        for t_e, t_f in zip(th_e, theta_full, strict=True):
            t_e[ce] = t_f[ce]
        contrib = row_prediction(
            design, th_e, rows["flap"], rows["alpha"], rows["aero"], rows["glob"]
        )
        before, after = float(s.sse_before.sum()), float(s.sse_after.sum())
        out.append(
            {
                "effect": s.candidate.name,
                "kind": s.candidate.kind,
                "rank": s.rank,
                "significant": True,
                "ambiguous_with": list(s.ambiguous_with),
                "alpha_range_deg": (
                    _gain_range(rows["alpha"], held_gain)
                    if held_gain is not None and not s.candidate.global_
                    else None
                )
                or _alpha_range(rows["alpha"], contrib),
                "gap_rms_before": math.sqrt(before / n),
                "gap_rms_after": math.sqrt(after / n),
                "shrink_fraction": (before - after) / total0 if total0 > 0 else 0.0,
                "statistic": s.statistic,
                "p_value": s.p_value,
                "parameters": _global_params(design, theta_full, s.candidate),
            }
        )
    # the significant effects ranked by the share of the gap each removes (a timing effect
    # reported from the nuisance terms competes with the greedy steps on equal terms)
    out.sort(key=lambda e: -e["shrink_fraction"])
    for i, e in enumerate(out):
        e["rank"] = i + 1
    # every other candidate, ranked by what it would remove at the last step
    rest = sorted(sel.final_scores.values(), key=lambda st: -st.gain)
    if sel.selected:
        last = sel.selected[-1].sse_after
    else:
        last = sel.sse_nuisance if sel.sse_nuisance is not None else sel.sse0
    for i, st in enumerate(rest):
        base_sse = st.sse_before if st.sse_before is not None else last
        before, after = float(base_sse.sum()), float(st.sse.sum())
        out.append(
            {
                "effect": st.candidate.name,
                "kind": st.candidate.kind,
                "rank": len(sel.selected) + i + 1,
                "significant": False,
                "ambiguous_with": [],
                "alpha_range_deg": [float("nan"), float("nan")],
                "gap_rms_before": math.sqrt(before / n),
                "gap_rms_after": math.sqrt(after / n),
                "shrink_fraction": (before - after) / total0 if total0 > 0 else 0.0,
                "statistic": st.statistic,
                "p_value": st.p_value,
                "parameters": st.parameters,
                "note": "" if st.material else "significant or not, below its practical floor",
            }
        )
    return out, steps


def _global_params(design: Design, theta: list[np.ndarray], cand: Candidate) -> dict[str, float]:
    """Estimated global parameters of a measurement effect (bias deg, lag s, offset m)."""
    if not cand.global_:
        return {}
    base = design.grid.n * len(design.aero_names)
    return {r: float(theta[0][base + design.global_names.index(r)]) for r in cand.regressors}


def _shrink_table(
    y: np.ndarray,
    meas: np.ndarray,
    regions: dict[str, np.ndarray],
    steps: Sequence[tuple[str, np.ndarray]],
) -> list[dict[str, Any]]:
    """Held-out gap before and after each step (timing alignment, then each selected
    effect), cumulatively, over all rows and per alpha region (``regions``: each region's
    row indices)."""
    out = []
    prev = np.zeros_like(y)
    for k, (name, pred) in enumerate(steps):
        for reg in ("all", "pre_stall", "stall", "post_stall"):
            idx = regions.get(reg)
            if reg == "all":
                y_m, meas_m, prev_m, pred_m = y, meas, prev, pred
            elif idx is not None and idx.size:
                y_m, meas_m, prev_m, pred_m = y[idx], meas[idx], prev[idx], pred[idx]
            else:
                continue
            sim_b = meas_m - (y_m - prev_m)
            sim_a = meas_m - (y_m - pred_m)
            out.append(
                {
                    "step": k + 1,
                    "effect": name,
                    "region": reg,
                    "n_points": int(y_m.size),
                    "rms_before": _rms(y_m - prev_m),
                    "rms_after": _rms(y_m - pred_m),
                    "tic_before": theil_inequality(meas_m, sim_b),
                    "tic_after": theil_inequality(meas_m, sim_a),
                }
            )
        prev = pred
    return out


def diagnose(
    data: pl.DataFrame | str | Path,
    model: str | Path | None = None,
    *,
    vocabulary: Vocabulary | None = None,
    config: DiagnoseConfig | None = None,
    aircraft: str | Path | None = None,
    progress: bool = False,
) -> Diagnosis:
    """Diagnose the gap between a simulator and flight records.

    Parameters
    ----------
    data
        Ingested records (``aerodelta.ingest(...).data``), an ingest output folder
        (``data.parquet``) or a campaign folder (ingested on the fly). Needs
        ``maneuver_id``, ``t`` [s], ``flap_deg``, ``alpha_deg``/``beta_deg`` (or their CG
        versions), the Δ-model regressors and ``Cl_meas``, ``Cn_meas``, ``CY_meas``.
    model
        The simulator: a DAVE-ML file, an aerodelta model file, or ``None`` for the records'
        ``*_sim`` columns (else the built-in ADX-37 qualified model for data flown on the
        virtual aircraft, else refused: :mod:`aerodelta.qualified`).
    vocabulary
        Candidate effects (default: DESIGN.md's vocabulary); add your own with
        :meth:`Vocabulary.with_user_effects`.
    config
        Thresholds and cross-validation settings.
    aircraft
        Aircraft reference TOML (mass, wing area, chord); default ``DIR/aircraft.toml`` or the
        built-in ADX-37.
    progress
        Progress bars on stderr.

    Returns
    -------
    Diagnosis
    """
    # Thousands of small solves and quadratic forms: multi-threaded BLAS only adds thread
    # hand-offs at these sizes, and on a loaded machine its spinning threads made a 135 x 135
    # Cholesky factorisation 180 times slower (17 ms instead of 0.09 ms).
    with threadpool_limits(limits=1, user_api="blas"):
        return _diagnose(data, model, vocabulary, config, aircraft, progress)


def _diagnose(  # noqa: PLR0917 - the arguments of diagnose(), passed through
    data: pl.DataFrame | str | Path,
    model: str | Path | None,
    vocabulary: Vocabulary | None,
    config: DiagnoseConfig | None,
    aircraft: str | Path | None,
    progress: bool,
) -> Diagnosis:
    cfg = config or DiagnoseConfig()
    vocab = vocabulary or default_vocabulary(cfg.measurement)
    # ``records``: every column, in the records' own row order where that spares a sorted
    # copy of them (``order`` then sorts their rows, data.load_records); what is computed from
    # them row by row or maneuver by maneuver (the simulator, the regressors, the band) is
    # computed there and put in (maneuver_id, t) order, the order of ``frame``: the columns
    # read below, sorted, and all that follows sees exactly what a sorted copy would give
    records, order, ac, notes = load_records(data, aircraft, progress=progress)
    frame = sorted_columns(records, order, FRAME_COLUMNS)
    sim = load_simulator(model, records, ac.cbar_m)
    sim_c = sim.predict(records)
    meas_cols = measurement_columns(records, sim, ac)
    cutoffs: dict[str, np.ndarray] = {}
    if cfg.band_match:
        # the simulator's output (and what is computed from it) in the band of the measured
        # coefficients, which come from smoothed rates and accelerations (band.py)
        cutoffs = band_cutoffs(records)
        for c, fc in cutoffs.items():
            if not np.isfinite(fc).any():
                notes.append(
                    f"{c}: the simulator's output is compared at full band (no '{BAND_CHANNEL[c]}' "
                    "channel to take the measured coefficient's band from)"
                )
        sim_c = band_match(records, sim_c, cutoffs)
        for name in SIM_REGRESSORS:
            if name in meas_cols:
                meas_cols[name] = band_match(records, meas_cols[name], cutoffs)
    if order is not None:
        sim_c = {c: v[order] for c, v in sim_c.items()}
        _put_in_order(meas_cols, order)
    man = (
        frame.group_by("maneuver_id", maintain_order=True)
        .agg(pl.col("flap_deg").first(), pl.col("kind").first())
        .sort("maneuver_id")
    )
    if man.height < cfg.folds:
        raise DataError(
            f"the diagnosis needs at least {cfg.folds} maneuvers for {cfg.folds}-fold "
            f"cross-validation by maneuver; the data hold {man.height}"
        )
    mcode = maneuver_codes(frame)[1]  # index in ``man`` (sorted by maneuver_id)
    kinds = EntryKinds.of(man["kind"])  # for the effects' entry-kind check
    flaps = sorted(set(man["flap_deg"].to_list()))
    fidx = np.searchsorted(np.array(flaps), frame["flap_deg"].to_numpy())
    folds_m = _fold_ids(man, cfg.folds, cfg.seed)
    alpha = frame["alpha_deg"].to_numpy()
    stall = stall_alphas(_with_columns(frame, records, order, STALL_COLUMNS))
    # polars string columns built from codes (a conversion of 400,000 numpy strings took 0.1 s)
    phase = pl.Series("phase", PHASES).gather(phase_codes(frame, stall))
    rcode = region_codes(alpha, frame["flap_deg"].to_numpy(), stall)
    region_rows = {r: np.flatnonzero(rcode == i) for i, r in enumerate(REGIONS)}
    region = pl.Series("region", REGIONS).gather(rcode)
    del rcode
    grid = HatGrid.covering(alpha, cfg.knot_deg)
    dflap = fidx if cfg.per_flap else np.zeros_like(fidx)
    n_dflaps = len(flaps) if cfg.per_flap else 1
    # each maneuver's flap, for the per-flap refinement (default ``per_flap=None``)
    layout = (
        FlapLayout(np.searchsorted(np.array(flaps), man["flap_deg"].to_numpy()), len(flaps))
        if cfg.per_flap is None
        else None
    )
    steps = tqdm(COEFFICIENTS, desc="diagnose", disable=not progress, file=None)
    coefs: dict[str, Any] = {}
    pred_cols: dict[str, np.ndarray] = {}
    not_testable: list[str] = []
    # Roll-off spikes are stochastic, not deterministic (thesis Section 3.4.3). They are searched
    # for in the C_l gap left by the deterministic effects selected on all the data (the thesis's
    # "residual of the fitted deterministic model"), so a deterministic transient the vocabulary
    # explains (spoiler, aileron reversal) is not taken for a spike; each event's moment is then
    # profiled out of its maneuver, the selection is redone, and the spikes are reported apart.
    ro: dict[str, Any] = {"detected": False, "centres": []}
    for coef in steps:
        cands = vocab.for_coefficient(coef)
        if not sim.differentiable:
            skip = [c.name for c in cands if c.name in NEEDS_MODEL]
            not_testable += [s for s in skip if s not in not_testable]
            cands = [c for c in cands if c.name not in NEEDS_MODEL]
        aero_names, glob_names = regressors_of(cands)
        aero_x, glob_x = design_columns(
            records, coef, aero_names=aero_names, glob_names=glob_names, vocab=vocab,
            meas=meas_cols, order=order,
        )  # fmt: skip
        # a global regressor that cannot move the coefficient by 1e-7 at its practical floor
        # is untestable for this coefficient (e.g. dC_Y/dalpha of a lateral model is ~0)
        for gi, g in enumerate(glob_names):
            if _rms(glob_x[:, gi]) * PRACTICAL_FLOOR.get(g, 1.0) < 1e-7:
                glob_x[:, gi] = 0.0
        # this coefficient's measurement regressors are in glob_x now
        for per_coef in meas_cols.values():
            per_coef.pop(coef, None)
        meas = in_order(records[f"{coef}_meas"].to_numpy(), order)
        y = meas - sim_c[coef]
        design = build_design(
            y, mcode, dflap, alpha, aero_x, glob_x, aero_names, glob_names, grid, man.height,
            n_dflaps,
        )  # fmt: skip
        stats = fold_stats(design, folds_m)
        sel = forward_select(design, stats, cands, cfg.selection, kinds=kinds)
        if coef == "Cl":
            model = list(sel.nuisance) + [
                s.candidate for s in sel.selected if s.candidate not in sel.nuisance
            ]
            fitted = np.zeros_like(y)
            if model:
                th = total_solve(design, stats, columns_for(design, model))
                fitted = row_prediction(design, th, dflap, alpha, aero_x, glob_x)
            resid = y - fitted
            if sim.differentiable and any(s.candidate.name == "control_lag" for s in sel.selected):
                # a control lag reported as an effect is put back exactly before the spikes are
                # searched for: its regressor is the first-order (rate) term of the delay, and
                # at 50-100 ms the rest, where the pilot's recovery inputs are fast, looked like
                # roll-off spikes in campaigns that had none
                g = design.global_names.index("m_control_lag")
                tau = float(th[0][design.grid.n * len(design.aero_names) + g])
                late = sim.predict(delayed_controls(records, tau))
                if cfg.band_match:
                    late = band_match(records, {"Cl": late["Cl"]}, cutoffs)
                exact = in_order(late["Cl"], order) - sim_c["Cl"]
                resid = resid + tau * glob_x[:, g] - exact
            ro = rolloff_finding(_with_columns(frame, records, order, DETECTOR_CHANNELS), resid)
            if ro["detected"]:
                # each event's moment, with its own random amplitude, profiled out of its
                # maneuver (Frisch-Waugh); the deterministic effects are then selected again
                del design, stats, sel, fitted, resid  # before the next design is built
                nuis = event_columns(frame, ro["centres"])
                design = profile_out(
                    build_design(
                        y, mcode, dflap, alpha, aero_x, (glob_x, nuis),
                        aero_names, [*glob_names, *(f"__rolloff{j}" for j in range(nuis.shape[1]))],
                        grid, man.height, n_dflaps,
                    ),
                    nuis.shape[1],
                )  # fmt: skip
                del nuis
                stats = fold_stats(design, folds_m)
                sel = forward_select(design, stats, cands, cfg.selection, kinds=kinds)
        kind_report = sel.kind_check
        if kind_report is not None and kind_report["rejected"]:
            # the layout choice and the outer folds select without the rejected effects
            out = {r["effect"] for r in kind_report["rejected"]}
            cands = [c for c in cands if c.name not in out]
        flap_rows = dflap
        shared = design  # the outer folds choose the layout on their own inner folds
        layout_report: dict[str, Any] = {"layout": "per_flap" if cfg.per_flap else "shared"}
        if layout is not None:
            ch = choose_layout(design, stats, sel, cands, layout, cfg.selection)
            design, stats, sel, layout_report = ch.design, ch.stats, ch.sel, ch.report
            if ch.per_flap:
                flap_rows = fidx
        rows = {
            "y": y, "fold": folds_m[mcode], "flap": flap_rows, "alpha": alpha,
            "aero": aero_x, "glob": glob_x,
        }  # fmt: skip
        effects, steps_ = _effect_rows(sel, design, stats, rows)
        # the rows' regressors are not read again (the outer folds need only the statistics)
        del aero_x, glob_x, rows
        outer = None
        if cfg.nested:
            ev = outer_evaluation(shared, folds_m, cands, cfg.selection, layout, kinds=kinds)
            outer = outer_summary(ev, cfg.selection.n_perm, cfg.seed + 17)
            for i, e in enumerate(effects):
                share, p_out, k = effect_outer(
                    ev, e["effect"], cfg.selection.n_perm, cfg.seed + 29 + 2 * i
                )
                e["outer_shrink_fraction"] = share
                e["outer_p_value"] = p_out
                e["outer_chosen_folds"] = k
            del ev
        final_pred = steps_[-1][1] if steps_ else np.zeros_like(y)
        pred_cols[f"{coef}_gap"] = y
        pred_cols[f"{coef}_explained"] = final_pred
        pred_cols[f"{coef}_timing"] = (
            steps_[0][1] if steps_ and steps_[0][0] == "timing_alignment" else np.zeros_like(y)
        )
        sig = [e for e in effects if e["significant"]]
        coefs[coef] = {
            "verdict": sig[0]["effect"] if sig else "none",
            "gap": {
                "rms": _rms(y),
                "bias": float(np.mean(y)),
                "tic": theil_inequality(meas, sim_c[coef]),
                "n_points": int(y.size),
            },
            "remaining_gap": {
                "rms": _rms(y - final_pred),
                "tic": theil_inequality(meas, sim_c[coef] + final_pred),
            },
            "where": gap_map(frame, y, phase, cfg.where_bin_deg, cfg.where_alpha),
            "worst_segments": worst_segments(frame, y),
            "effects": effects,
            "flap_curves": layout_report,
            "entry_kind_check": kind_report,
            "shrink": _shrink_table(y, meas, region_rows, steps_),
        }
        if outer is not None:
            coefs[coef]["outer"] = outer
        # this coefficient's rows and statistics go before the next one's are built
        del design, shared, stats, sel, steps_
        sim_c.pop(coef)
    coefs["Cl"]["rolloff"] = {k: v for k, v in ro.items() if k != "centres"}
    coefs["Cl"]["rolloff"]["events_profiled_out"] = len(ro["centres"]) if ro["detected"] else 0
    if ro["detected"]:
        n_sig = sum(1 for e in coefs["Cl"]["effects"] if e["significant"])
        for e in coefs["Cl"]["effects"][n_sig:]:
            e["rank"] += 1
        coefs["Cl"]["effects"].insert(
            n_sig,
            {
                "effect": "stochastic_rolloff",
                "kind": "stochastic",
                "rank": n_sig + 1,
                "significant": True,
                "ambiguous_with": [],
                "alpha_range_deg": ro["alpha_range_deg"],
                "gap_rms_before": coefs["Cl"]["remaining_gap"]["rms"],
                "gap_rms_after": coefs["Cl"]["remaining_gap"]["rms"],
                "shrink_fraction": 0.0,
                "statistic": float(ro["n_events"]),
                "p_value": ro["p_value"],
                **(
                    {
                        "outer_shrink_fraction": None,
                        "outer_p_value": None,
                        "outer_chosen_folds": None,
                    }
                    if cfg.nested
                    else {}
                ),
            },
        )
        if coefs["Cl"]["verdict"] == "none":
            coefs["Cl"]["verdict"] = "stochastic_rolloff"
    result = {
        "schema": SCHEMA,
        "aerodelta_version": __version__,
        "simulator": sim.name,
        "data": {
            "n_points": int(frame.height),
            "n_maneuvers": int(man.height),
            "flaps_deg": [float(f) for f in flaps],
            "folds": cfg.folds,
            "notes": notes,
        },
        "settings": {
            "knot_deg": cfg.knot_deg,
            "per_flap": "auto" if cfg.per_flap is None else cfg.per_flap,
            "alpha": cfg.selection.alpha,
            "min_shrink": cfg.selection.min_shrink,
            "min_shrink_broad": cfg.selection.min_shrink_broad,
            "broad_alpha_factor": cfg.selection.broad_alpha_factor,
            "ambiguity_p": cfg.selection.ambiguity_p,
            "n_perm": cfg.selection.n_perm,
            "seed": cfg.seed,
            "nested": cfg.nested,
            "band_match": cfg.band_match,
        },
        "stall_alpha_deg": {str(k): v for k, v in stall.items()},
        "not_testable": not_testable,
        "coefficients": coefs,
    }
    preds = frame.select("maneuver_id", "t", "alpha_deg", "flap_deg").with_columns(
        phase,
        region,
        *[pl.Series(k, v) for k, v in pred_cols.items()],
    )
    return Diagnosis(result, preds)
