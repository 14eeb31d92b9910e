"""Section 4.1: time-history matches of Cl, Cn, CY (measured vs qualified vs extended), roll-off
off, with per-maneuver and overall metrics and the best, typical and worst fits (thesis
Figures 4.1-4.8)."""

from __future__ import annotations

import numpy as np
import polars as pl

from aerodelta.plots import FigureSink, figures
from aerodelta.report.context import ReportContext
from aerodelta.report.html import Section, details, esc, p, table
from aerodelta.report.metrics import maneuver_metrics, overall_metrics, rank_fits

_LABEL = {"Cl": "$C_l$", "Cn": "$C_n$", "CY": "$C_Y$"}


def _plot_maneuver(
    ctx: ReportContext,
    sink: FigureSink,
    g: pl.DataFrame,
    mid: str,
    coef: str,
    *,
    rank: str,
    row: dict[str, object],
) -> str:
    """Figure of one maneuver's records ``g`` (sorted by time)."""
    held = "held out" if row["held_out"] else "fitted"
    w = g[f"w_{coef}"].to_numpy() if f"w_{coef}" in g.columns else None
    return sink.plot(
        figures.time_history,
        f"th_{coef}_{rank}_{mid}",
        f"{coef} time history, {rank} fit ({mid}, {held}): measured, qualified and extended "
        "model (roll-off off); lower panel: angle of attack, shaded where the Δ model is blended "
        "in (cf. thesis Figures 4.1-4.8).",
        t=g["t"].to_numpy(),
        meas=g[f"{coef}_meas"].to_numpy(),
        qual=g[f"{coef}_qual"].to_numpy(),
        ext=g[f"{coef}_ext"].to_numpy(),
        alpha=g["alpha_deg"].to_numpy(),
        active=(w > 0) if w is not None and np.any(w > 0) else None,
        ylabel=_LABEL.get(coef, coef),
        title=f"{coef} {rank} fit: {mid} ({held})\nflap {row.get('flap_deg', '')}, "
        f"{row.get('kind', '')}, pusher {row.get('pusher', '')}; TIC qualified "
        f"{row['tic_qual']:.3f} → extended {row['tic_ext']:.3f}",
    )


def _scatter(ctx: ReportContext, sink: FigureSink, per: pl.DataFrame) -> str:
    panels = []
    for c in ctx.coefficients:
        g = per.filter(pl.col("coefficient") == c)
        pan: dict[str, object] = {"coef": c}
        for key, held in (("fitted", False), ("held", True)):
            s = g.filter(pl.col("held_out") == held)
            pan[key] = (s["tic_qual"].to_numpy(), s["tic_ext"].to_numpy()) if s.height else None
        pan["hi"] = float(np.nanmax(g["tic_qual"].to_numpy())) if g.height else 1.0
        panels.append(pan)
    return sink.plot(
        figures.tic_scatter,
        "th_tic_scatter",
        "Theil inequality coefficient per maneuver, qualified (x) vs extended (y); points below "
        "the dashed line are improved by the extended model.",
        panels=panels,
    )


def section(ctx: ReportContext, sink: FigureSink) -> Section:
    """Build the time-history section."""
    sec = Section("timehistory", "4.1 Time-history matches")
    per = maneuver_metrics(ctx.data, ctx.coefficients, ctx.held_out)
    overall = overall_metrics(ctx.data, ctx.coefficients, ctx.held_out)
    sec.body.append(
        p(
            "Measured coefficients (thesis Eq. 3.2-3.4) against the qualified "
            "model and the extended "
            "model <i>C</i><sub>ext</sub> = <i>C</i><sub>qual</sub> + <i>w</i>(α) Δ<i>C</i> "
            "(Eq. 3.12) with the stochastic roll-off <b>off</b>, as the thesis "
            "compares them to check "
            "the deterministic part. Metrics: RMS error, Theil inequality coefficient "
            "TIC = rms(y − ŷ)/(rms(y) + rms(ŷ)) (0 perfect, 1 no skill), peak |error|, and the RMS "
            "once the mean offset is removed (the standard deviation of the error)."
        )
    )
    cols = [
        "coefficient",
        "subset",
        "n",
        "rms_qual",
        "rms_ext",
        "tic_qual",
        "tic_ext",
        "peak_qual",
        "peak_ext",
        "rms_offset_removed_qual",
        "rms_offset_removed_ext",
    ]
    sec.body.append("<h3>Overall (pooled over samples)</h3>")
    sec.body.append(table(overall.select(cols)))
    sec.body.append(_scatter(ctx, sink, per))
    ranks = {c: rank_fits(per, c) for c in ctx.coefficients}
    chosen = sorted({mid for r in ranks.values() for mid in r.values()})
    records = {
        str(k[0]): g.sort("t")
        for k, g in ctx.data.filter(pl.col("maneuver_id").is_in(chosen)).group_by(
            ["maneuver_id"], maintain_order=True
        )
    }
    for c in ctx.coefficients:
        sec.body.append(f"<h3>{esc(c)}: best, typical and worst fit (ranked by extended TIC)</h3>")
        for rank, mid in ranks[c].items():
            row = per.filter((pl.col("coefficient") == c) & (pl.col("maneuver_id") == mid)).row(
                0, named=True
            )
            sec.body.append(_plot_maneuver(ctx, sink, records[mid], mid, c, rank=rank, row=row))
    show = (
        ["maneuver_id", "coefficient", "held_out"]
        + [x for x in ("flap_deg", "kind", "pusher") if x in per.columns]
        + [
            "rms_qual",
            "rms_ext",
            "tic_qual",
            "tic_ext",
            "peak_ext",
            "rms_offset_removed_ext",
            "offset_ext",
        ]
    )
    ranked = per.sort(["coefficient", "tic_ext"]).select(show)
    sec.body.append(
        details(
            f"Per-maneuver metrics ({per['maneuver_id'].n_unique()} maneuvers, sorted by extended "
            "TIC; held-out rows highlighted)",
            table(ranked, row_class=lambda r: "held" if r["held_out"] else ""),
        )
    )
    subset = "held out" if ctx.held_out else "all"
    for r in overall.filter(pl.col("subset") == subset).iter_rows(named=True):
        sec.summary.append(
            (
                f"{r['coefficient']} TIC ({subset})",
                f"{r['tic_qual']:.3f} → <b>{r['tic_ext']:.3f}</b>",
            )
        )
    sec.tables["per_maneuver"] = per
    sec.tables["overall"] = overall
    return sec
