"""Identified parameters against alpha (thesis Figures 3.7-3.8, 3.15-3.18): per-bin estimates
with 95 % error bars, the smoothed tables of the model, unidentified bins marked; and
error-vs-regressor plots for chosen bins (Figures 3.5-3.6)."""

from __future__ import annotations

import numpy as np
import polars as pl

from aerodelta.plots import FigureSink, figures
from aerodelta.report.context import ReportContext
from aerodelta.report.html import Section, p, table

#: Channels shown in the error-vs-regressor plots (those present are drawn).
ERROR_REGRESSORS = ("beta_deg", "phat", "rhat", "da_deg", "dr_deg")
#: Most points drawn per scatter panel (evenly thinned beyond).
MAX_SCATTER = 1500


def _tables(
    ctx: ReportContext,
) -> dict[tuple[str, str], tuple[np.ndarray, dict[float, np.ndarray]]]:
    spec = ctx.model.to_spec()
    flaps = [float(f) for f in spec["flaps_deg"]]
    out = {}
    for coef, c in spec["coefficients"].items():
        for term in c["terms"]:
            grid = np.asarray(term["alpha_deg"], dtype=float)
            out[(coef, term["name"])] = (
                grid,
                {f: np.asarray(v, dtype=float) for f, v in zip(flaps, term["values"], strict=True)},
            )
    return out


def _param_figure(
    ctx: ReportContext, sink: FigureSink, coef: str, *, g: pl.DataFrame, tables: dict
) -> str:
    """One panel per parameter of ``coef``; the flap settings overlaid in colour."""
    names = list(dict.fromkeys(g["param"].to_list()))
    flaps = sorted(float(f) for f in g["flap_deg"].unique())
    parts = g.partition_by(["param", "flap_deg"], as_dict=True)
    panels = []
    for name in names:
        series = []
        for flap in flaps:
            b = parts.get((name, flap))
            if b is None or b.height == 0:
                continue
            c = 0.5 * (b["alpha_lo_deg"].to_numpy() + b["alpha_hi_deg"].to_numpy())
            est = b["estimate"].to_numpy()
            # 95 % interval: cluster-robust (CR2) error with Bell-McCaffrey t
            half = b["ci95_upper"].to_numpy() - est
            ok = b["identifiable"].to_numpy() & np.isfinite(half)
            tab = tables.get((coef, name))
            series.append(
                {
                    "flap": flap,
                    "c": c[ok],
                    "est": est[ok],
                    "half": half[ok],
                    "c_bad": c[~ok],
                    "table": (tab[0], tab[1][flap]) if tab is not None and flap in tab[1] else None,
                }
            )
        regressor = g.filter(pl.col("param") == name)["regressor"][0]
        panels.append({"title": f"{name}  [{regressor}]", "series": series})
    return sink.plot(
        figures.parameters,
        f"params_{coef}",
        f"Δ{coef} parameters against alpha, one colour per flap setting: identified bin "
        "estimates with 95 % error bars (coloured-residual standard errors), the smoothed and "
        "clipped table of the model (line), bins where the parameter is not identified (crosses "
        "drawn at zero, the value the fit keeps there). Cf. thesis Figures 3.7-3.8, 3.15-3.18.",
        panels=panels,
        flaps=flaps,
    )


def _error_vs_regressor(ctx: ReportContext, sink: FigureSink, coef: str, flap: float) -> str | None:
    if ctx.params is None:
        return None
    bins = (
        ctx.params.filter((pl.col("coefficient") == coef) & (pl.col("flap_deg") == flap))
        .select("alpha_lo_deg", "alpha_hi_deg")
        .unique()
        .sort("alpha_lo_deg")
    )
    stall = ctx.stall_alpha_deg.get(flap)
    if bins.height == 0 or stall is None:
        return None
    chosen = []
    for target in (stall - 4.0, stall + 2.0):
        lo = bins["alpha_lo_deg"].to_numpy()
        hi = bins["alpha_hi_deg"].to_numpy()
        k = int(np.argmin(np.abs(0.5 * (lo + hi) - target)))
        chosen.append((float(lo[k]), float(hi[k])))
    regs = [r for r in ERROR_REGRESSORS if r in ctx.data.columns]
    d = ctx.data.filter(pl.col("flap_deg") == flap)
    rows = []
    for lo, hi in chosen:
        s = d.filter((pl.col("alpha_deg") >= lo) & (pl.col("alpha_deg") < hi))
        z = (s[f"{coef}_meas"] - s[f"{coef}_qual"]).to_numpy()
        pb = ctx.params.filter(
            (pl.col("coefficient") == coef)
            & (pl.col("flap_deg") == flap)
            & (pl.col("alpha_lo_deg") == lo)
        )
        panels = []
        for r in regs:
            x = s[r].to_numpy()
            step = max(1, x.size // MAX_SCATTER)
            fit = None
            row = pb.filter(pl.col("regressor") == r)
            if row.height and np.isfinite(x).any():
                slope = float(row["estimate"][0])
                xs = np.linspace(np.nanmin(x), np.nanmax(x), 2)
                fit = (xs, np.nanmean(z) + slope * (xs - np.nanmean(x)), f"bin slope {slope:.3g}")
            panels.append({"xlabel": r, "x": x[::step], "z": z[::step], "fit": fit})
        rows.append({"ylabel": f"{coef} error, α {lo:.1f}-{hi:.1f}", "panels": panels})
    return sink.plot(
        figures.error_vs_regressor,
        f"error_vs_regressor_{coef}_flap{flap:g}",
        f"Qualified-model error C_meas − C_qual of {coef} against candidate regressors in two "
        f"alpha bins (flap {flap:g}; one below and one past stall), with the bin's "
        "least-squares slope (cf. thesis Figures 3.5-3.6).",
        rows=rows,
    )


def section(ctx: ReportContext, sink: FigureSink) -> Section:
    """Build the parameter section."""
    sec = Section("params", "Identified parameters against alpha")
    if ctx.params is None:
        sec.body.append(
            p(
                "No per-bin estimates were found beside the model "
                "(<code>MODEL.params.parquet</code>, "
                "written by <code>aerodelta fit</code>); only the smoothed tables are available."
            )
        )
        return sec
    pr = ctx.params
    tables = _tables(ctx)
    sec.body.append(
        p(
            "Each alpha bin is fitted by equation-error least squares (thesis Eq. 3.10); a "
            "parameter is marked not identified where its regressor lacks excitation, is "
            "collinear with others or the bin has too few points. Identified bins are smoothed "
            "against alpha (Eq. 3.13, p = 0.4) and clipped 10 deg past stall."
        )
    )
    ident = (
        pr.group_by(["coefficient", "flap_deg"])
        .agg(
            pl.len().alias("estimates"),
            pl.col("identifiable").mean().alias("identified"),
            pl.col("alpha_lo_deg").n_unique().alias("bins"),
        )
        .sort(["coefficient", "flap_deg"])
    )
    sec.body.append(table(ident, formats={"identified": ".0%"}))
    for coef in ctx.coefficients:
        g = pr.filter(pl.col("coefficient") == coef)
        if g.height:
            sec.body.append(f"<h3>Δ{coef}</h3>")
            sec.body.append(_param_figure(ctx, sink, coef, g=g, tables=tables))
    # the flap with the most samples; equal counts: the lowest flap (not the hash order)
    counts = ctx.data.group_by("flap_deg").len().sort(["len", "flap_deg"], descending=[True, False])
    if counts.height:
        flap = float(counts["flap_deg"][0])
        sec.body.append("<h3>Error against regressor in chosen bins</h3>")
        for coef in ctx.coefficients[:2]:
            f = _error_vs_regressor(ctx, sink, coef, flap)
            if f:
                sec.body.append(f)
    total = float(pr["identifiable"].mean() or 0.0)
    sec.summary.append(("parameters identified", f"{100 * total:.0f}% of bin estimates"))
    sec.tables["identified"] = ident
    return sec
