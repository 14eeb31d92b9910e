"""One task of a campaign design study: fly one seeded campaign of a test matrix, fit it with
bootstrap bands, optionally diagnose it, and return a small summary (never the records).

The function runs on a Dask worker (:mod:`aerodelta.plan.engine`); it depends on its
arguments only, so the same seed gives the same summary on any worker.
"""

from __future__ import annotations

import ctypes
import itertools
import math
import resource
import sys
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from aerodelta.campaign import campaign_plan, generate_campaign
from aerodelta.exceptions import AerodeltaError
from aerodelta.fit import FitConfig, fit
from aerodelta.ingest import ingest
from aerodelta.truth import true_parameter

#: Version of the task summary's layout (a task file of another version is run again).
TASK_SCHEMA = "aerodelta.plan.task/1"


class FaultDrillError(AerodeltaError):
    """Raised on purpose by a seed listed in ``[engine] fault_drill_seeds``."""


def _flap_rows(spec: Mapping[str, Any]) -> pl.DataFrame:
    """Maneuvers wanted per (flap, kind, pusher) cell of the matrix."""
    rows = []
    for f in spec["flaps"]:
        counts: Mapping[str, int] = f["counts"]
        for kind, n in counts.items():
            if f["pusher"] == "both":
                split = {True: (n + 1) // 2, False: n // 2}
            else:
                on = f["pusher"] == "on"
                split = {on: n, not on: 0}
            for pusher, k in split.items():
                if k > 0:
                    rows.append(
                        {
                            "flap_deg": float(f["flap_deg"]),
                            "kind": kind,
                            "pusher": pusher,
                            "want": k,
                        }
                    )
    return pl.DataFrame(
        rows,
        schema={"flap_deg": pl.Float64, "kind": pl.String, "pusher": pl.Boolean, "want": pl.Int64},
    )


def _first_in_cells(table: pl.DataFrame, order: str, spec: Mapping[str, Any]) -> pl.DataFrame:
    """The rows of ``table`` (manifest or plan) the matrix uses: in each (flap, kind, pusher)
    cell, the first ``want`` rows in the order of column ``order``, returned in that order."""
    cells = ["flap_deg", "kind", "pusher"]
    m = table.sort(order).with_columns(pl.int_range(pl.len()).over(cells).alias("_rank"))
    return (
        m.join(_flap_rows(spec), on=cells, how="inner")
        .filter(pl.col("_rank") < pl.col("want"))
        .drop("_rank", "want")
        .sort(order)
    )


def select_maneuvers(manifest: pl.DataFrame, spec: Mapping[str, Any]) -> pl.DataFrame:
    """The manifest rows the matrix uses: in each (flap, kind, pusher) cell, the first
    ``want`` maneuvers in maneuver order (each maneuver has its own seeded streams, so the
    subset is a campaign of the matrix's counts).

    Returns
    -------
    polars.DataFrame
        The selected manifest rows, in maneuver order.
    """
    return _first_in_cells(manifest, "maneuver_id", spec)


def maneuvers_to_fly(seed: int, spec: Mapping[str, Any]) -> list[int]:
    """Indices (``generate_campaign(only=...)``) of the maneuvers the matrix uses, in a campaign
    of ``seed`` whose size is the matrix's largest cell: in each (flap, kind, pusher) cell the
    first ``want`` in the campaign's order, the maneuvers :func:`select_maneuvers` takes from
    the whole campaign. Only those are flown (until session 31 the whole campaign was flown and
    the rest thrown away: all but 16 of 120 maneuvers for the tests' tiny matrix)."""
    plan = campaign_plan(seed=int(seed), size=_campaign_size(spec))
    return _first_in_cells(plan, "maneuver_index", spec)["maneuver_index"].to_list()


def _campaign_size(spec: Mapping[str, Any]) -> int:
    """Repetitions of the campaign a task flies: the matrix's largest cell."""
    return int(max([1, *(_flap_rows(spec)["want"].to_list())]))


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


#: The true Δ of one parameter along alpha: ``(coefficient, regressor, flap_deg, alpha_deg)``
#: -> values.
Truth = Callable[[str, str, float, np.ndarray], np.ndarray]


def _range_rows(result: Any, spec: Mapping[str, Any], truth: Truth) -> list[dict[str, Any]]:
    """Per coefficient, flap, parameter and alpha range of the matrix: the smoothed
    parameter's mean over the range (``estimate``), its bootstrap standard error (the standard
    deviation over the replicates of the same mean), the band width (mean of upper - lower over
    the range), the identified bins there, and the expected (true) Δ (``truth``)."""
    edges = np.asarray(spec["alpha_edges_deg"], dtype=float)
    sm: pl.DataFrame = result.smoothed
    params: pl.DataFrame = result.params
    ident = (
        params.filter(pl.col("identifiable"))
        .with_columns(((pl.col("alpha_lo_deg") + pl.col("alpha_hi_deg")) / 2).alias("centre"))
        .select("coefficient", "flap_deg", "param", "centre")
    )
    rows: list[dict[str, Any]] = []
    keys = sm.select("coefficient", "flap_deg", "param").unique(maintain_order=True)
    for coef, flap, name in keys.sort(["coefficient", "flap_deg", "param"]).iter_rows():
        g = sm.filter(
            (pl.col("coefficient") == coef)
            & (pl.col("flap_deg") == flap)
            & (pl.col("param") == name)
        ).sort("alpha_deg")
        kept = g["note"][0] == ""
        grid = g["alpha_deg"].to_numpy()
        reg = params.filter((pl.col("coefficient") == coef) & (pl.col("param") == name))[
            "regressor"
        ]
        regressor = str(reg[0]) if reg.len() else ""
        truth_grid = truth(str(coef), regressor, float(flap), grid)
        truth_max = float(np.max(np.abs(truth_grid))) if grid.size else 0.0
        rep = result.replicates.get((coef, name, flap))
        centres = ident.filter(
            (pl.col("coefficient") == coef)
            & (pl.col("flap_deg") == flap)
            & (pl.col("param") == name)
        )["centre"].to_numpy()
        value, lower, upper = (g[c].to_numpy() for c in ("value", "lower", "upper"))
        for lo, hi in itertools.pairwise(edges):
            sel = (grid >= lo) & (grid < hi)
            if not sel.any():
                continue
            se = math.nan
            if rep is not None and kept:
                rg, rv = rep
                rsel = (rg >= lo) & (rg < hi)
                means = rv[:, rsel].mean(axis=1) if rsel.any() else np.array([])
                means = means[np.isfinite(means)]  # replicates that could not smooth it: out
                if means.size > 1 and 2 * means.size >= rv.shape[0]:
                    se = float(np.std(means, ddof=1))
            n_bins = int(np.count_nonzero((centres >= lo) & (centres < hi)))
            rows.append(
                {
                    "coefficient": str(coef),
                    "flap_deg": float(flap),
                    "param": str(name),
                    "regressor": regressor,
                    "alpha_lo_deg": float(lo),
                    "alpha_hi_deg": float(hi),
                    "kept": bool(kept),
                    "identified": bool(kept and n_bins > 0),
                    "bins": n_bins,
                    "estimate": _finite(float(value[sel].mean())),
                    "se": _finite(se),
                    "band": _finite(float((upper[sel] - lower[sel]).mean())) if kept else None,
                    "truth": float(truth_grid[sel].mean()),
                    "truth_max": truth_max,
                }
            )
    return rows


def _coverage(data: pl.DataFrame, edges: list[float]) -> list[dict[str, Any]]:
    """Samples and maneuvers per flap, kind and alpha range (what each kind contributes)."""
    # the range index: how many edges lie at or below alpha (ranges closed on the left), what
    # `Expr.cut(edges, left_closed=True)` labels, which polars 2 deprecates
    at_or_above = [(pl.col("alpha_deg") >= e).cast(pl.Int32) for e in edges]
    d = data.select("maneuver_id", "flap_deg", "kind", "alpha_deg").with_columns(
        pl.sum_horizontal(at_or_above).cast(pl.String).alias("r")
    )
    maneuvers = d.group_by("flap_deg", "kind").agg(pl.col("maneuver_id").n_unique().alias("n"))
    counts = d.group_by("flap_deg", "kind", "r").agg(pl.len().alias("samples"))
    out = []
    for flap, kind, n in maneuvers.sort("flap_deg", "kind").iter_rows():
        for i, (lo, hi) in enumerate(itertools.pairwise(edges)):
            s = counts.filter(
                (pl.col("flap_deg") == flap)
                & (pl.col("kind") == kind)
                & (pl.col("r") == str(i + 1))
            )["samples"]
            out.append(
                {
                    "flap_deg": float(flap),
                    "kind": str(kind),
                    "maneuvers": int(n),
                    "alpha_lo_deg": float(lo),
                    "alpha_hi_deg": float(hi),
                    "samples": int(s[0]) if s.len() else 0,
                }
            )
    return out


def _effects_named(camp: Path, data: pl.DataFrame, effects: Mapping[str, float]) -> dict[str, bool]:
    """Per expected effect: whether the diagnosis names it (scored against the campaign's truth
    as the withheld-effect suite does, :func:`aerodelta.diagnosis.withheld.score_case`)."""
    from aerodelta.diagnosis import diagnose  # noqa: PLC0415  (only with the diagnosis on)
    from aerodelta.diagnosis.withheld import score_case  # noqa: PLC0415

    diag = diagnose(data)
    case = score_case(diag, camp / "truth", effects)
    return {str(k): bool(v) for k, v in sorted(case.found.items())}


def _scratch() -> str | None:
    """Where a task's campaign is flown: the Dask worker's own folder when the task runs on a
    worker (a worker killed mid-task leaves its campaign there, and Dask deletes the folders
    of dead workers), else the system's temporary folder."""
    try:
        from distributed import get_worker  # noqa: PLC0415  (only on a worker)

        return str(get_worker().local_directory)
    except (ImportError, ValueError):  # no Dask, or not inside a worker
        return None


def release_memory() -> None:
    """Hand the heap's free memory back to the OS (glibc ``malloc_trim``; elsewhere nothing).

    The workers keep glibc's adaptive allocation thresholds (:func:`aerodelta.plan.engine.
    open_client`), under which freed arrays stay in the process for reuse; trimming once per
    task keeps a worker's memory from creeping up over the tasks it runs."""
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.malloc_trim(0)
    except (OSError, AttributeError):  # not glibc (musl): nothing to trim
        return


def peak_rss_mib() -> float:
    """Peak resident memory of this process, MiB (``getrusage``)."""
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb / (1024.0 * 1024.0) if sys.platform == "darwin" else kb / 1024.0


def _fit_config(spec: Mapping[str, Any], seed: int) -> FitConfig:
    """The matrix's fit settings, bootstrapped with the campaign's seed."""
    selection = None if spec["selection"] == "none" else spec["selection"]
    return FitConfig(
        bootstrap=int(spec["bootstrap"]),
        seed=int(seed),
        selection=selection,
        band_level=float(spec["band_level"]),
    )


def _summary(
    seed: int, n: int, rows: list[dict[str, Any]], coverage: list[dict[str, Any]],
    named: Mapping[str, bool],
) -> dict[str, Any]:  # fmt: skip
    """A task's summary (:func:`run_task`), once its campaign is gone and memory trimmed."""
    release_memory()
    return {
        "schema": TASK_SCHEMA,
        "seed": int(seed),
        "maneuvers": int(n),
        "params": rows,
        "coverage": coverage,
        "effects": dict(named),
        "peak_rss_mib": peak_rss_mib(),
    }


def run_task(spec: Mapping[str, Any], seed: int, drill: bool = False) -> dict[str, Any]:
    """Fly, fit and (optionally) diagnose one campaign of a matrix; return its summary.

    Parameters
    ----------
    spec
        :meth:`aerodelta.plan.matrix.Matrix.task_spec`.
    seed
        Campaign seed (also the fit's bootstrap seed).
    drill
        Raise :class:`FaultDrillError` instead (``[engine] fault_drill_seeds``).

    Returns
    -------
    dict
        ``schema``, ``seed``, ``maneuvers`` (used), ``params`` (per coefficient, flap,
        parameter and alpha range: ``estimate``, ``se``, ``band`` in the parameter's unit,
        ``identified``, ``bins``, ``truth``), ``coverage`` (samples per flap, kind and alpha
        range), ``effects`` (expected effect -> named by the diagnosis; empty without it) and
        ``peak_rss_mib`` (memory of the worker, not part of the study's result).

    Raises
    ------
    FaultDrillError
        With ``drill``.
    """
    if drill:
        raise FaultDrillError(f"seed {seed}: fault drill ([engine] fault_drill_seeds)")
    if spec.get("simulator") == "jsbsim":
        return _run_jsbsim_task(spec, seed)
    effects: dict[str, float] = dict(spec["effects"])
    with tempfile.TemporaryDirectory(prefix="aerodelta-plan-", dir=_scratch()) as tmp:
        camp = Path(tmp) / "campaign"
        info = generate_campaign(
            camp,
            effects=effects or "none",
            seed=int(seed),
            size=_campaign_size(spec),
            noise=float(spec["noise"]),
            turbulence=float(spec["turbulence_mps"]),
            rolloff=bool(spec["rolloff"]),
            excitation=float(spec["excitation"]),
            cg_range_m=spec["cg_range_m"],
            mass_range=spec["mass_range"],
            inertia_range=spec["inertia_range"],
            vane_scale=spec["vane_scale"],
            flank_vane=bool(spec["flank_vane"]),
            only=maneuvers_to_fly(seed, spec),
        )
        manifest = select_maneuvers(info.manifest, spec)
        data = ingest(camp, manifest=manifest, compat=False, progress=False).data
        truth_effects = dict(info.effects)
        result = fit(data, config=_fit_config(spec, seed))
        rows = _range_rows(
            result,
            spec,
            lambda c, r, f, a: true_parameter(truth_effects, c, r, f, a),
        )
        named = _effects_named(camp, data, truth_effects) if spec["diagnose"] else {}
        coverage = _coverage(data, list(spec["alpha_edges_deg"]))
        n = manifest.height
    del info, manifest, data, result
    return _summary(seed, n, rows, coverage, named)


def _run_jsbsim_task(spec: Mapping[str, Any], seed: int) -> dict[str, Any]:
    """:func:`run_task` on a JSBSim aircraft: fly the matrix's maneuvers of :func:`aerodelta.
    jsbsim_campaign.generate_jsbsim_campaign` (in each flap and kind the first ones of the
    campaign whose cells are the matrix's largest, as :func:`maneuvers_to_fly`), fit against
    the campaign's qualified columns (``qualified="columns"``), take the true Δ from the
    aircraft's XML (``true_delta_derivative``: zero for regressors other than beta, p̂, r̂, δa,
    δr) and, with the diagnosis on, score it as the JSBSim withheld-effect suite does
    (``score_jsbsim_case``: per vocabulary effect of the withheld terms, named or not)."""
    from aerodelta.jsbsim_campaign import (  # noqa: PLC0415  (jsbsim is optional)
        generate_jsbsim_campaign,
        jsbsim_campaign_plan,
        lateral_terms,
        true_delta_derivative,
    )

    terms = {str(t): float(spec["withhold_scale"]) for t in spec["withhold"]}
    # the JSBSim manifest calls a sideslip entry "other"; the matrix calls it sideslip
    kinds = pl.col("kind").replace({"other": "sideslip"})
    plan = jsbsim_campaign_plan(str(spec["aircraft"]), seed=int(seed), size=_campaign_size(spec))
    only = _first_in_cells(plan.with_columns(kinds), "maneuver_index", spec)["maneuver_index"]
    with tempfile.TemporaryDirectory(prefix="aerodelta-plan-", dir=_scratch()) as tmp:
        camp = Path(tmp) / "campaign"
        info = generate_jsbsim_campaign(
            camp,
            aircraft=str(spec["aircraft"]),
            seed=int(seed),
            size=_campaign_size(spec),
            withhold=list(terms),
            withhold_scale=float(spec["withhold_scale"]),
            noise=float(spec["noise"]),
            turbulence=float(spec["jsbsim_turbulence"]),
            only=only.to_list(),
        )
        man = info.manifest.with_columns(kinds, pl.col("pusher").cast(pl.Boolean))
        manifest = select_maneuvers(man, spec)
        keep = info.manifest.filter(pl.col("maneuver_id").is_in(manifest["maneuver_id"].to_list()))
        data = ingest(camp, manifest=keep, compat=False, progress=False).data
        data = data.with_columns(kinds)
        result = fit(data, qualified="columns", config=_fit_config(spec, seed))
        rows = _range_rows(result, spec, lambda c, r, f, a: true_delta_derivative(camp, c, r, f, a))
        named: dict[str, bool] = {}
        if spec["diagnose"]:
            from aerodelta.diagnosis import diagnose  # noqa: PLC0415
            from aerodelta.diagnosis.withheld import (  # noqa: PLC0415
                jsbsim_term_effects,
                score_jsbsim_case,
            )

            lat = lateral_terms(str(spec["aircraft"]))
            diag = diagnose(data, aircraft=camp / "aircraft.toml")
            case = score_jsbsim_case(
                diag, camp, terms, jsbsim_term_effects(lat), {t["name"]: t["axis"] for t in lat}
            )
            named = {str(k): bool(v) for k, v in sorted(case.found.items())}
        coverage = _coverage(data, list(spec["alpha_edges_deg"]))
        n = manifest.height
    del info, manifest, data, result
    return _summary(seed, n, rows, coverage, named)
