"""Writing the diagnosis: ``diagnosis.json`` (stable keys), a plain-text report, CSV tables."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import polars as pl

from aerodelta._fsutil import write_atomic, write_text_atomic
from aerodelta.diagnosis.vocabulary import COEFFICIENTS

_LIST_KEYS = ("ambiguous_with", "alpha_range_deg", "parameters")


def _clean(x: Any) -> Any:
    """JSON-safe: NaN/inf become null."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    return x


def summary_text(result: dict[str, Any]) -> str:
    """Human-readable report of a diagnosis dictionary."""
    lines = [
        "aerodelta diagnosis: the sim-to-real gap",
        f"simulator: {result['simulator']}",
        f"data: {result['data']['n_maneuvers']} maneuvers, {result['data']['n_points']} points, "
        f"flaps {result['data']['flaps_deg']}; {result['data']['folds']}-fold cross-validation "
        "by maneuver",
    ]
    for note in result["data"].get("notes", []):
        lines.append(f"note: {note}")
    if result.get("not_testable"):
        lines.append("not testable without a loadable model: " + ", ".join(result["not_testable"]))
    for c in COEFFICIENTS:
        r = result["coefficients"][c]
        g = r["gap"]
        lines.append("")
        lines.append(
            f"{c}: verdict {r['verdict']}   gap rms {g['rms']:.5f}  bias {g['bias']:+.5f}  "
            f"TIC {g['tic']:.3f}  ->  remaining rms {r['remaining_gap']['rms']:.5f}  "
            f"TIC {r['remaining_gap']['tic']:.3f}"
        )
        ro = r.get("rolloff") or {}
        if ro.get("note"):
            lines.append(f"  {ro['note']}")
        if ro.get("detected"):
            counted = (
                f"{ro['call_maneuvers_with_events']} of the {ro['call_maneuvers']} "
                f"{'/'.join(ro['call_kinds'])} stalls counted"
                if ro.get("call_kinds")
                else "all kinds counted: the records name no wings-level stall"
            )
            lines.append(
                f"  roll-off spikes in {ro['n_maneuvers_with_events']} of {ro['n_searched']} "
                f"maneuvers ({counted}; p = {ro['p_value']:.2g}): stochastic, not a "
                "deterministic effect; "
                f"the moment of each of the {ro['events_profiled_out']} events (a Gaussian in "
                "alpha, amplitude free per event) is profiled out of the effect fits"
            )
        kc = r.get("entry_kind_check") or {}
        for rej in kc.get("rejected", []):
            worse = [
                f"{k} {100 * v['kind_worse_fraction']:+.1f}% (p = {v['p_worse']:.2g})"
                for k, v in rej["per_kind"].items()
                if v["p_worse"] < 1.0 and v["kind_worse_fraction"] > 0
            ]
            lines.append(
                f"  {rej['effect']} rejected: it makes the held-out gap of some entry kind's "
                "stalls worse (" + ", ".join(worse) + "), which an effect of the aircraft "
                "cannot; an unmodelled effect whose mean depends on how the stall was entered"
            )
        sig = [e for e in r["effects"] if e["significant"] and e.get("kind") != "stochastic"]
        if not sig:
            lines.append("  no significant unmodelled effect")
        fc = r.get("flap_curves") or {}
        if fc.get("tested"):
            how = (
                "one per flap (the flaps differ)"
                if fc["layout"] == "per_flap"
                else "one for all flaps (per-flap curves not better)"
            )
            lines.append(
                f"  alpha curves: {how}; per flap they remove "
                f"{100 * fc['shrink_fraction']:+.1f}% of the gap held out (p = {fc['p_value']:.2g})"
            )
        elif fc.get("layout") == "per_flap":
            lines.append("  alpha curves: one per flap (--per-flap)")
        outer = r.get("outer")
        if outer:
            lines.append(
                f"  outer folds (the selection redone without each of the {outer['folds']} "
                f"folds and scored on it; {outer['n_maneuvers']} maneuvers): the chosen effects "
                f"remove {100 * outer['shrink_fraction_effects']:.1f}% of the gap "
                f"(p = {outer['p_value_effects']:.2g}), timing alignment "
                f"{100 * outer['shrink_fraction_timing']:.1f}%"
            )
            others = {
                k: v
                for k, v in outer["chosen_in_folds"].items()
                if k not in {e["effect"] for e in sig}
            }
            if others:
                lines.append(
                    "  chosen in some outer folds only: "
                    + ", ".join(f"{k} {v}/{outer['folds']}" for k, v in others.items())
                )
        for e in sig:
            lo, hi = e["alpha_range_deg"]
            amb = (
                f"  (ambiguous with {', '.join(e['ambiguous_with'])})"
                if e["ambiguous_with"]
                else ""
            )
            ok = lo is not None and math.isfinite(lo)
            rng = f"alpha {lo:.0f}..{hi:.0f} deg" if ok else "alpha ?"
            out = (
                f"; outer: chosen {e['outer_chosen_folds']}/{outer['folds']}, "
                f"shrink {100 * e['outer_shrink_fraction']:.0f}%"
                if outer and e.get("outer_chosen_folds") is not None
                else ""
            )
            lines.append(
                f"  {e['rank']}. {e['effect']:<24} {rng:<18} held-out rms "
                f"{e['gap_rms_before']:.5f} -> {e['gap_rms_after']:.5f} "
                f"(shrink {100 * e['shrink_fraction']:.0f}% of the gap), "
                f"p = {e['p_value']:.2g}{out}{amb}"
            )
        cells = [w for w in r["where"] if w["significant"]]
        if cells:
            spans = sorted({(w["flap_deg"], w["alpha_lo_deg"], w["phase"]) for w in cells})
            lines.append(
                f"  significant gap in {len(cells)} of {len(r['where'])} cells (flap, alpha, "
                "phase): "
                + ", ".join(f"{f:g}/{a:g}/{p}" for f, a, p in spans[:12])
                + (" ..." if len(spans) > 12 else "")
            )
    return "\n".join(lines)


def write_outputs(result: dict[str, Any], predictions: pl.DataFrame, out: str | Path) -> list[Path]:
    """Write ``diagnosis.json``, ``diagnosis.txt``, ``gap_map.csv``, ``effects.csv``,
    ``shrink.csv``, the figures ``gap_map.png`` and ``shrink.png`` and ``predictions.parquet``
    into ``out`` (atomically, file by file)."""
    d = Path(out)
    d.mkdir(parents=True, exist_ok=True)
    paths = []
    p = d / "diagnosis.json"
    write_text_atomic(p, json.dumps(_clean(result), indent=2))
    paths.append(p)
    p = d / "diagnosis.txt"
    write_text_atomic(p, summary_text(result) + "\n")
    paths.append(p)
    tables: dict[str, list[dict[str, Any]]] = {"gap_map": [], "effects": [], "shrink": []}
    for c in COEFFICIENTS:
        r = result["coefficients"][c]
        tables["gap_map"] += [{"coefficient": c, **w} for w in r["where"]]
        tables["effects"] += [
            {
                "coefficient": c,
                **{
                    k: v
                    for k, v in e.items()
                    if k not in ("ambiguous_with", "alpha_range_deg", "parameters")
                },
                "ambiguous_with": ";".join(e["ambiguous_with"]),
                "alpha_lo_deg": e["alpha_range_deg"][0],
                "alpha_hi_deg": e["alpha_range_deg"][1],
            }
            for e in r["effects"]
        ]
        tables["shrink"] += [{"coefficient": c, **s} for s in r["shrink"]]
    for name, rows in tables.items():
        table = pl.DataFrame(rows, infer_schema_length=None)
        paths.append(write_atomic(d / f"{name}.csv", table.write_csv))
    from aerodelta.diagnosis.plots import gap_map_figure, shrink_figure  # noqa: PLC0415
    from aerodelta.rolloff_plots import save_figure  # noqa: PLC0415 - matplotlib on demand

    paths.append(save_figure(gap_map_figure(result), d / "gap_map.png"))
    paths.append(save_figure(shrink_figure(result), d / "shrink.png"))
    paths.append(write_atomic(d / "predictions.parquet", predictions.write_parquet))
    return paths
