"""Identified parameters against alpha (thesis Figures 3.7-3.8, 3.15-3.18): per-bin estimates
with 95 % error bars, the smoothed tables of the model, unidentified bins marked; and
error-vs-regressor plots for chosen bins (Figures 3.5-3.6)."""

from __future__ import annotations

import math

import numpy as np
import polars as pl
from matplotlib.ticker import MaxNLocator

from aerodelta.plots import COLORS, FigureSink, new_figure
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


FLAP_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")


def _param_figure(
    ctx: ReportContext, sink: FigureSink, coef: str, *, g: pl.DataFrame, tables: dict
) -> str:
    """One panel per parameter of ``coef``; the flap settings overlaid in colour."""
    names = list(dict.fromkeys(g["param"].to_list()))
    flaps = sorted(float(f) for f in g["flap_deg"].unique())
    ncol = 4
    nrow = math.ceil(len(names) / ncol)
    fig, ax = new_figure(nrow, ncol, width=10.5, height=2.0 * nrow + 0.5, sharex=True, layout=None)
    h = 2.0 * nrow + 0.5
    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.45 / h, top=1 - 0.5 / h, wspace=0.35,
                        hspace=0.45)  # fmt: skip
    for k, name in enumerate(names):
        a = ax[k // ncol, k % ncol]
        for fi, flap in enumerate(flaps):
            col = FLAP_COLORS[fi % len(FLAP_COLORS)]
            b = g.filter((pl.col("param") == name) & (pl.col("flap_deg") == flap))
            if b.height == 0:
                continue
            c = 0.5 * (b["alpha_lo_deg"].to_numpy() + b["alpha_hi_deg"].to_numpy())
            est = b["estimate"].to_numpy()
            # 95 % interval: cluster-robust (CR2) error with Bell-McCaffrey t
            half = b["ci95_upper"].to_numpy() - est
            ok = b["identifiable"].to_numpy() & np.isfinite(half)
            a.errorbar(
                c[ok], est[ok], yerr=half[ok], fmt="o", ms=2.0, color=col,
                elinewidth=0.5, capsize=0, alpha=0.8, label=f"flap {flap:g}",
            )  # fmt: skip
            tab = tables.get((coef, name))
            if tab is not None and flap in tab[1]:
                a.plot(tab[0], tab[1][flap], color=col, lw=1.2)
            if (~ok).any():
                a.plot(c[~ok], np.zeros(int((~ok).sum())), "x", color=col, ms=3.5, mew=0.8)
        a.set_title(f"{name}  [{g.filter(pl.col('param') == name)['regressor'][0]}]", fontsize=7.5)
        a.yaxis.set_major_locator(MaxNLocator(4))
    for k in range(len(names), nrow * ncol):
        ax[k // ncol, k % ncol].set_visible(False)
    for a in ax[-1, :]:
        a.set_xlabel("α [deg]")
    fig.legend(*ax[0, 0].get_legend_handles_labels(), loc="upper center", ncol=len(flaps),
               fontsize=7, frameon=False)  # fmt: skip
    return sink.add(
        fig,
        f"params_{coef}",
        f"Δ{coef} parameters against alpha, one colour per flap setting: identified bin "
        "estimates with 95 % error bars (coloured-residual standard errors), the smoothed and "
        "clipped table of the model (line), bins where the parameter is not identified (crosses "
        "drawn at zero, the value the fit keeps there). Cf. thesis Figures 3.7-3.8, 3.15-3.18.",
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
    fig, ax = new_figure(len(chosen), len(regs), width=10.0, height=2.0 * len(chosen) + 0.4)
    d = ctx.data.filter(pl.col("flap_deg") == flap)
    for i, (lo, hi) in enumerate(chosen):
        s = d.filter((pl.col("alpha_deg") >= lo) & (pl.col("alpha_deg") < hi))
        z = (s[f"{coef}_meas"] - s[f"{coef}_qual"]).to_numpy()
        pb = ctx.params.filter(
            (pl.col("coefficient") == coef)
            & (pl.col("flap_deg") == flap)
            & (pl.col("alpha_lo_deg") == lo)
        )
        for j, r in enumerate(regs):
            a = ax[i, j]
            x = s[r].to_numpy()
            step = max(1, x.size // MAX_SCATTER)
            a.plot(x[::step], z[::step], ".", ms=1.5, color="#555", alpha=0.5)
            row = pb.filter(pl.col("regressor") == r)
            if row.height and np.isfinite(x).any():
                slope = float(row["estimate"][0])
                xs = np.linspace(np.nanmin(x), np.nanmax(x), 2)
                a.plot(
                    xs,
                    np.nanmean(z) + slope * (xs - np.nanmean(x)),
                    color=COLORS["ext"],
                    lw=1.2,
                    label=f"bin slope {slope:.3g}",
                )
                a.legend(loc="best", fontsize=6)
            a.set_xlabel(r)
            if j == 0:
                a.set_ylabel(f"{coef} error, α {lo:.1f}-{hi:.1f}")
    return sink.add(
        fig,
        f"error_vs_regressor_{coef}_flap{flap:g}",
        f"Qualified-model error C_meas − C_qual of {coef} against candidate regressors in two "
        f"alpha bins (flap {flap:g}; one below and one past stall), with the bin's "
        "least-squares slope (cf. thesis Figures 3.5-3.6).",
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
    counts = ctx.data.group_by("flap_deg").len().sort("len", descending=True)
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
