"""The study's figure: band width against the target per parameter, flap and alpha range.

One panel per coefficient; a row per parameter and flap with an expected Δ, a column per alpha
range; the colour is the band width over the largest expected |Δ| (``band_relative``, capped at
3x the target), the text the probability of being identified, and the cells that miss a target
are outlined. Built without pyplot; :func:`aerodelta.rolloff_plots.save_figure` writes it.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
import polars as pl
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

COEFFICIENTS = ("Cl", "Cn", "CY")


def band_figure(
    params: pl.DataFrame, target: float, edges: Sequence[float], title: str = ""
) -> Figure:
    """Band width over the largest expected |Δ| per parameter, flap and alpha range.

    Parameters
    ----------
    params
        The study's table (:func:`aerodelta.plan.aggregate.param_table`).
    target
        ``relative_band_width`` of the matrix, -.
    edges
        ``alpha_edges_deg`` of the matrix, deg.
    title
        Figure title (the matrix's name).

    Returns
    -------
    matplotlib.figure.Figure
    """
    rows = params.filter(pl.col("truth_max") > 0)
    fig = Figure(figsize=(12.0, 0.9 + 0.28 * max(rows.height // 4, 8)), layout="constrained")
    axes = fig.subplots(1, len(COEFFICIENTS), squeeze=False)[0]
    edges = [float(e) for e in edges]
    im = None
    for ax, c in zip(axes, COEFFICIENTS, strict=True):
        g = rows.filter(pl.col("coefficient") == c)
        labels = sorted(
            {(p, f) for p, f in g.select("param", "flap_deg").iter_rows()},
            key=lambda k: (k[0], k[1]),
        )
        if not labels or len(edges) < 2:
            ax.set_title(f"{c}: no expected Δ")
            ax.set_axis_off()
            continue
        grid = np.full((len(labels), len(edges) - 1), np.nan)
        ident = np.full_like(grid, np.nan)
        miss = np.zeros(grid.shape, dtype=bool)
        for r in g.iter_rows(named=True):
            i = labels.index((r["param"], r["flap_deg"]))
            j = edges.index(r["alpha_lo_deg"])
            grid[i, j] = np.nan if r["band_relative"] is None else r["band_relative"]
            ident[i, j] = r["p_identified"]
            miss[i, j] = r["meets_target"] is False
        im = ax.imshow(
            np.minimum(grid, 3.0 * target),
            aspect="auto",
            origin="upper",
            cmap="viridis_r",
            vmin=0.0,
            vmax=3.0 * target,
        )
        for (i, j), p in np.ndenumerate(ident):
            if np.isfinite(p):
                dark = np.isfinite(grid[i, j]) and grid[i, j] > 1.5 * target
                ax.text(
                    j, i, f"{p:.0%}", ha="center", va="center", fontsize=6,
                    color="white" if dark else "black",
                )  # fmt: skip
            if miss[i, j]:
                ax.add_patch(
                    Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, edgecolor="red", lw=1.0)
                )
        ax.set_xticks(range(len(edges) - 1))
        ax.set_xticklabels([f"{a:g}-{b:g}" for a, b in itertools.pairwise(edges)])
        ax.set_yticks(range(len(labels)))
        ax.set_yticklabels([f"{p} @{f:g}" for p, f in labels], fontsize=6)
        ax.set_xlabel("alpha, deg")
        ax.set_title(c)
    if im is not None:
        cb = fig.colorbar(im, ax=list(axes), shrink=0.8)
        cb.set_label(f"band / largest expected |Δ| (target {target:g}; red: misses a target)")
    fig.suptitle(f"{title}: band width and P(identified) per parameter @ flap".lstrip(": "))
    return fig
