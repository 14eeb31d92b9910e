"""Figures of the diagnosis: the gap map (alpha x flap per coefficient, the cells' RMS with
the significant ones marked) and the shrink plot (held-out gap RMS after each step, per alpha
region). Built without pyplot; :func:`aerodelta.rolloff_plots.save_figure` writes them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure

from aerodelta.diagnosis.vocabulary import COEFFICIENTS


def gap_map_figure(result: dict[str, Any], phase: str | None = None) -> Figure:
    """Heat map of the gap RMS per flap (rows) and alpha bin (columns), one panel per
    coefficient; significant cells carry a dot. ``phase`` keeps one flight phase (default:
    the largest RMS over the phases of each cell)."""
    fig = Figure(figsize=(10.0, 3.4), layout="constrained")
    axes = fig.subplots(1, len(COEFFICIENTS))
    for ax, c in zip(axes, COEFFICIENTS, strict=True):
        cells = [w for w in result["coefficients"][c]["where"] if phase in (None, w["phase"])]
        if not cells:
            ax.set_title(f"{c}: no data")
            continue
        flaps = sorted({w["flap_deg"] for w in cells})
        los = sorted({w["alpha_lo_deg"] for w in cells})
        grid = np.full((len(flaps), len(los)), np.nan)
        sig = np.zeros_like(grid, dtype=bool)
        for w in cells:
            i, j = flaps.index(w["flap_deg"]), los.index(w["alpha_lo_deg"])
            if not np.isfinite(grid[i, j]) or w["rms"] > grid[i, j]:
                grid[i, j] = w["rms"]
            sig[i, j] |= bool(w["significant"])
        width = cells[0]["alpha_hi_deg"] - cells[0]["alpha_lo_deg"]
        extent = (los[0], los[-1] + width, -0.5, len(flaps) - 0.5)
        im = ax.imshow(grid, aspect="auto", origin="lower", extent=extent, cmap="viridis")
        ii, jj = np.nonzero(sig)
        ax.scatter(np.asarray(los)[jj] + width / 2, ii, s=10, c="red", marker="o", lw=0)
        ax.set_yticks(range(len(flaps)), [f"{f:g}" for f in flaps])
        ax.set_xlabel("alpha, deg")
        ax.set_ylabel("flap, deg")
        ax.set_title(f"{c} gap RMS (verdict: {result['coefficients'][c]['verdict']})", fontsize=9)
        fig.colorbar(im, ax=ax, shrink=0.8)
    return fig


def shrink_figure(result: dict[str, Any]) -> Figure:
    """Held-out gap RMS before any effect and after each step, per alpha region and
    coefficient (bars), the "how far" of the diagnosis."""
    fig = Figure(figsize=(10.0, 3.4), layout="constrained")
    axes = fig.subplots(1, len(COEFFICIENTS))
    regions = ("all", "pre_stall", "stall", "post_stall")
    for ax, c in zip(axes, COEFFICIENTS, strict=True):
        rows = result["coefficients"][c]["shrink"]
        if not rows:
            ax.set_title(f"{c}: nothing added")
            ax.set_axis_off()
            continue
        steps = sorted({(r["step"], r["effect"]) for r in rows})
        labels = ["gap"] + [name for _, name in steps]
        x = np.arange(len(regions))
        width = 0.8 / len(labels)
        for k, lab in enumerate(labels):
            vals = []
            for reg in regions:
                if k == 0:
                    v = [r["rms_before"] for r in rows if r["step"] == 1 and r["region"] == reg]
                else:
                    v = [r["rms_after"] for r in rows if r["step"] == k and r["region"] == reg]
                vals.append(v[0] if v else np.nan)
            ax.bar(x + k * width, vals, width, label=lab)
        ax.set_xticks(x + 0.4 - width / 2, regions, fontsize=8)
        ax.set_ylabel("held-out gap RMS")
        ax.set_title(c)
        ax.legend(fontsize=7)
    return fig
