"""The sim-to-real diagnosis (``diagnosis.json``, schema ``aerodelta.diagnosis/1``): verdict per
coefficient, the gap map (alpha × coefficient per flap), the ranked effects and the shrink table.

Only the keys below are read; others are ignored and optional ones may be missing::

    coefficients.<C>.verdict                     effect name or "none"
    coefficients.<C>.gap                         {rms, bias, tic}
    coefficients.<C>.where[]                     {flap_deg, alpha_lo_deg, alpha_hi_deg, phase,
                                                  rms, bias, significant}
    coefficients.<C>.effects[]                   {effect, rank, significant, ambiguous_with,
                                                  alpha_range_deg, gap_rms_before,
                                                  gap_rms_after, shrink_fraction, statistic,
                                                  p_value}
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from aerodelta.exceptions import DataError
from aerodelta.plots import FigureSink, figures
from aerodelta.report.html import Section, esc, p, table

SCHEMA = "aerodelta.diagnosis/1"


def load_diagnosis(path: str | Path) -> dict[str, Any]:
    """Read and check a ``diagnosis.json``."""
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except UnicodeDecodeError as e:
        raise DataError(
            f"{path}: cannot read the diagnosis: not UTF-8 text (byte {e.start}); give the "
            "diagnosis.json written by aerodelta diagnose"
        ) from e
    except RecursionError as e:
        raise DataError(
            f"{path}: cannot read the diagnosis: nested too deep for a diagnosis.json"
        ) from e
    except (OSError, json.JSONDecodeError) as e:
        raise DataError(f"{path}: cannot read the diagnosis ({e})") from e
    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA:
        got = doc.get("schema") if isinstance(doc, dict) else type(doc).__name__
        raise DataError(f"{path}: schema is {got!r}, expected {SCHEMA!r}")
    return doc


def _num(x: Any) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def where_frame(doc: Mapping[str, Any]) -> pl.DataFrame:
    """All ``where`` entries as one frame (``coefficient`` added)."""
    rows = []
    for c, v in (doc.get("coefficients") or {}).items():
        for w in v.get("where") or []:
            rows.append(
                {
                    "coefficient": c,
                    "flap_deg": _num(w.get("flap_deg")),
                    "alpha_lo_deg": _num(w.get("alpha_lo_deg")),
                    "alpha_hi_deg": _num(w.get("alpha_hi_deg")),
                    "phase": str(w.get("phase", "")),
                    "rms": _num(w.get("rms")),
                    "bias": _num(w.get("bias")),
                    "significant": bool(w.get("significant", False)),
                }
            )
    return pl.DataFrame(
        rows,
        schema={
            "coefficient": pl.Utf8,
            "flap_deg": pl.Float64,
            "alpha_lo_deg": pl.Float64,
            "alpha_hi_deg": pl.Float64,
            "phase": pl.Utf8,
            "rms": pl.Float64,
            "bias": pl.Float64,
            "significant": pl.Boolean,
        },
    )


def effects_frame(doc: Mapping[str, Any]) -> pl.DataFrame:
    """All ranked effects as one frame (``coefficient`` added), sorted by coefficient, rank."""
    rows = []
    for c, v in (doc.get("coefficients") or {}).items():
        for k, e in enumerate(v.get("effects") or []):
            ar = e.get("alpha_range_deg") or [math.nan, math.nan]
            rows.append(
                {
                    "coefficient": c,
                    "rank": int(e.get("rank", k + 1)),
                    "effect": str(e.get("effect", "?")),
                    "significant": bool(e.get("significant", False)),
                    "ambiguous_with": ", ".join(map(str, e.get("ambiguous_with") or [])),
                    "alpha_lo_deg": _num(ar[0]),
                    "alpha_hi_deg": _num(ar[1] if len(ar) > 1 else None),
                    "gap_rms_before": _num(e.get("gap_rms_before")),
                    "gap_rms_after": _num(e.get("gap_rms_after")),
                    "shrink_fraction": _num(e.get("shrink_fraction")),
                    "statistic": _num(e.get("statistic")),
                    "p_value": _num(e.get("p_value")),
                }
            )
    schema = {
        "coefficient": pl.Utf8,
        "rank": pl.Int64,
        "effect": pl.Utf8,
        "significant": pl.Boolean,
        "ambiguous_with": pl.Utf8,
    }
    schema |= {
        k: pl.Float64
        for k in (
            "alpha_lo_deg",
            "alpha_hi_deg",
            "gap_rms_before",
            "gap_rms_after",
            "shrink_fraction",
            "statistic",
            "p_value",
        )
    }
    return pl.DataFrame(rows, schema=schema).sort(["coefficient", "rank"])


def _gap_map(sink: FigureSink, wf: pl.DataFrame) -> str | None:
    if wf.height == 0:
        return None
    keys = ["flap_deg", "coefficient", "alpha_lo_deg", "alpha_hi_deg"]
    # sorted: the bars are drawn in the same order every run (same figure bytes)
    g = wf.group_by(keys).agg(pl.col("rms").max(), pl.col("significant").any()).sort(keys)
    flaps = sorted(g["flap_deg"].unique().to_list())
    coefs = sorted(g["coefficient"].unique().to_list())
    top = {
        c: float(np.nanmax(g.filter(pl.col("coefficient") == c)["rms"].to_numpy())) for c in coefs
    }
    cells = []
    for k, flap in enumerate(flaps):
        for j, c in enumerate(coefs):
            s = g.filter((pl.col("flap_deg") == flap) & (pl.col("coefficient") == c))
            cells.append(
                {
                    "k": k,
                    "j": j,
                    "lo": s["alpha_lo_deg"].to_numpy(),
                    "hi": s["alpha_hi_deg"].to_numpy(),
                    "rms": s["rms"].to_numpy(),
                    "significant": s["significant"].to_list(),
                    "top": top[c],
                }
            )
    return sink.plot(
        figures.gap_map,
        "diagnosis_gap_map",
        "Gap map: RMS of measured − simulated per alpha region and coefficient, per flap "
        "(largest over flight phases, scaled per coefficient); outlined: significant against "
        "the noise floor.",
        flaps=flaps,
        coefs=coefs,
        cells=cells,
    )


def _shrink_plot(sink: FigureSink, ef: pl.DataFrame) -> str | None:
    if ef.height == 0:
        return None
    panels = []
    for c in sorted(ef["coefficient"].unique().to_list()):
        s = ef.filter(pl.col("coefficient") == c).sort("rank")
        y = np.concatenate([[s["gap_rms_before"][0]], s["gap_rms_after"].to_numpy()])
        panels.append({"coef": c, "y": y, "labels": ["qualified", *s["effect"].to_list()]})
    return sink.plot(
        figures.shrink,
        "diagnosis_shrink",
        "Held-out gap RMS before and after adding each ranked effect (greedy).",
        panels=panels,
    )


def section(doc: Mapping[str, Any] | None, sink: FigureSink) -> Section:
    """Build the diagnosis section (a note when there is no diagnosis)."""
    sec = Section("diagnosis", "Sim-to-real diagnosis")
    if doc is None:
        sec.body.append(
            p(
                "No diagnosis given (run <code>aerodelta diagnose</code> and pass its "
                "<code>diagnosis.json</code> with <code>--diagnosis</code>)."
            )
        )
        return sec
    coefs = doc.get("coefficients") or {}
    verdict = pl.DataFrame(
        [
            {
                "coefficient": c,
                "verdict": str(v.get("verdict", "?")),
                "gap_rms": _num((v.get("gap") or {}).get("rms")),
                "gap_bias": _num((v.get("gap") or {}).get("bias")),
                "gap_tic": _num((v.get("gap") or {}).get("tic")),
            }
            for c, v in coefs.items()
        ],
        schema={
            "coefficient": pl.Utf8,
            "verdict": pl.Utf8,
            "gap_rms": pl.Float64,
            "gap_bias": pl.Float64,
            "gap_tic": pl.Float64,
        },
    )
    sec.body.append(
        p(
            "Verdict per coefficient: the effect that best explains the gap between "
            "the flight data and the simulator, or <i>none</i>."
        )
    )
    sec.body.append(table(verdict))
    wf = where_frame(doc)
    fig = _gap_map(sink, wf)
    if fig:
        sec.body.append("<h3>Gap map</h3>")
        sec.body.append(fig)
    ef = effects_frame(doc)
    if ef.height:
        sec.body.append("<h3>Ranked effects</h3>")
        sec.body.append(
            table(
                ef.select(
                    "coefficient",
                    "rank",
                    "effect",
                    "significant",
                    "ambiguous_with",
                    "alpha_lo_deg",
                    "alpha_hi_deg",
                    "statistic",
                    "p_value",
                ),
                row_class=lambda r: "good" if r["significant"] else "",
            )
        )
        sec.body.append("<h3>Shrink table (held-out gap before and after each effect)</h3>")
        sec.body.append(
            table(
                ef.select(
                    "coefficient",
                    "rank",
                    "effect",
                    "gap_rms_before",
                    "gap_rms_after",
                    "shrink_fraction",
                ),
                formats={"shrink_fraction": ".1%"},
            )
        )
        fig2 = _shrink_plot(sink, ef)
        if fig2:
            sec.body.append(fig2)
    for r in verdict.iter_rows(named=True):
        sec.summary.append((f"{r['coefficient']} diagnosis", f"<b>{esc(r['verdict'])}</b>"))
    sec.tables.update({"verdict": verdict, "where": wf, "effects": ef})
    return sec
