"""The study's figure: band width against the target per parameter, flap and alpha range.

One panel per coefficient; a row per parameter and flap with an expected Δ, a column per alpha
range; the colour is the band width over the largest expected |Δ| (``band_relative``, capped at
3x the target), the text the probability of being identified, and the cells that miss a target
are outlined. Built without pyplot; :func:`aerodelta.rolloff_plots.save_figure` writes it.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np
import polars as pl
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

COEFFICIENTS = ("Cl", "Cn", "CY")


def _label_axes(ax: Any, coef: str, labels: list[tuple[str, float]], edges: list[float]) -> None:
    """Alpha ranges across, ``param @flap`` down, the coefficient on top."""
    ax.set_xticks(range(len(edges) - 1))
    ax.set_xticklabels([f"{a:g}-{b:g}" for a, b in itertools.pairwise(edges)])
    ax.set_yticks(range(len(labels)))
    ax.set_yticklabels([f"{p} @{f:g}" for p, f in labels], fontsize=6)
    ax.set_xlabel("alpha, deg")
    ax.set_title(coef)


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
        _label_axes(ax, c, labels, edges)
    if im is not None:
        cb = fig.colorbar(im, ax=list(axes), shrink=0.8)
        cb.set_label(f"band / largest expected |Δ| (target {target:g}; red: misses a target)")
    fig.suptitle(f"{title}: band width and P(identified) per parameter @ flap".lstrip(": "))
    return fig


def compare_figure(
    table: pl.DataFrame, names: tuple[str, str], target: float, edges: Sequence[float]
) -> Figure:
    """Two matrices side by side: per parameter, flap and alpha range, the band width of the
    second over the first's (log scale: blue, the second's band is narrower), the probability
    of being identified of each as text (``first→second``), and the cells where only one of
    them meets the band target outlined (green: only the second, red: only the first).

    Parameters
    ----------
    table
        :func:`aerodelta.plan.study.compare_table` (columns suffixed with ``names``).
    names
        The two matrices' column suffixes, in order.
    target
        ``relative_band_width`` of the first matrix, -.
    edges
        ``alpha_edges_deg`` of the first matrix, deg.

    Returns
    -------
    matplotlib.figure.Figure
    """
    na, nb = names
    finite = pl.col(f"band_relative_{na}").is_finite() | pl.col(f"band_relative_{nb}").is_finite()
    rows = table.filter(finite.fill_null(False))
    edges = [float(e) for e in edges]
    fig = Figure(figsize=(12.0, 0.9 + 0.28 * max(rows.height // 4, 8)), layout="constrained")
    axes = fig.subplots(1, len(COEFFICIENTS), squeeze=False)[0]
    im = None
    for ax, c in zip(axes, COEFFICIENTS, strict=True):
        g = rows.filter(pl.col("coefficient") == c)
        labels = sorted({(p, f) for p, f in g.select("param", "flap_deg").iter_rows()})
        if not labels or len(edges) < 2:
            ax.set_title(f"{c}: no expected Δ")
            ax.set_axis_off()
            continue
        ratio = np.full((len(labels), len(edges) - 1), np.nan)
        for r in g.iter_rows(named=True):
            if r["alpha_lo_deg"] not in edges[:-1]:
                continue
            i, j = labels.index((r["param"], r["flap_deg"])), edges.index(r["alpha_lo_deg"])
            a, b = r[f"band_width_{na}"], r[f"band_width_{nb}"]
            if a is not None and b is not None and a > 0 and b > 0:
                ratio[i, j] = np.log2(b / a)
            pa, pb = r[f"p_identified_{na}"], r[f"p_identified_{nb}"]
            ax.text(
                j, i, f"{'-' if pa is None else f'{pa:.0%}'}→{'-' if pb is None else f'{pb:.0%}'}",
                ha="center", va="center", fontsize=5,
            )  # fmt: skip
            ma, mb = r[f"meets_target_{na}"] is True, r[f"meets_target_{nb}"] is True
            if ma != mb:
                edge = "green" if mb else "red"
                box = Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, lw=1.2, edgecolor=edge)
                ax.add_patch(box)
        im = ax.imshow(ratio, aspect="auto", origin="upper", cmap="coolwarm", vmin=-2, vmax=2)
        _label_axes(ax, c, labels, edges)
    if im is not None:
        cb = fig.colorbar(im, ax=list(axes), shrink=0.8)
        cb.set_label(f"log2(band {nb} / band {na})")
    fig.suptitle(
        f"{nb} against {na}: band width ratio per parameter @ flap; text: P(identified) "
        f"{na}→{nb}\noutlined: only one meets the band target {target:g} (green: {nb}, red: {na})"
    )
    return fig
