"""Shared plotting helpers: matplotlib on the Agg backend (no display), one house style, and a
sink that writes each figure as PNG and SVG files and returns it as an HTML ``<figure>`` with the
PNG embedded (base64), so a report is one self-contained file."""

from __future__ import annotations

import base64
import html
import io
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.figure import Figure

from aerodelta._fsutil import write_bytes_atomic

#: Colours of the three signals compared throughout the report.
COLORS = {"meas": "#222222", "qual": "#d62728", "ext": "#1f77b4", "band": "#9ecae1"}

plt.rcParams.update(
    {
        "figure.dpi": 96,
        "axes.grid": True,
        "grid.alpha": 0.3,
        "axes.spines.top": False,
        "axes.spines.right": False,
        "font.size": 9,
        "axes.titlesize": 9,
        "legend.fontsize": 8,
        "svg.fonttype": "none",
        "path.simplify": True,
    }
)


def new_figure(
    nrows: int = 1,
    ncols: int = 1,
    *,
    width: float = 7.5,
    height: float = 3.0,
    layout: str | None = "constrained",
    **kw: Any,
) -> tuple[Figure, Any]:
    """A figure with a grid of axes (inches). ``layout=None`` skips the (slow) constrained
    layout: the caller places the axes with ``fig.subplots_adjust``."""
    fig = Figure(figsize=(width, height), layout=layout)
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig, axes


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "figure"


@dataclass
class FigureSink:
    """Collects report figures.

    Parameters
    ----------
    out_dir
        Folder for the PNG/SVG files (``None``: embed only).
    svg
        Also write an SVG file of each figure.
    dpi
        Resolution of the PNG files and of the embedded image.
    """

    out_dir: Path | None = None
    svg: bool = True
    dpi: int = 110
    written: list[Path] = field(default_factory=list)
    count: int = 0

    def add(self, fig: Figure, name: str, caption: str) -> str:
        """Write ``fig`` and return its HTML ``<figure>`` (PNG as a ``data:`` URI)."""
        self.count += 1
        slug = f"{self.count:03d}_{_slug(name)}"
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=self.dpi)
        png = buf.getvalue()
        # the layout is computed once (for the PNG) and kept for the SVG
        fig.set_layout_engine("none")
        if self.out_dir is not None:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            self._write(self.out_dir / f"{slug}.png", png)
            if self.svg:
                sbuf = io.BytesIO()
                fig.savefig(sbuf, format="svg")
                self._write(self.out_dir / f"{slug}.svg", sbuf.getvalue())
        b64 = base64.b64encode(png).decode("ascii")
        cap = html.escape(caption)
        return (
            f'<figure id="fig-{slug}"><img alt="{html.escape(name)}" '
            f'src="data:image/png;base64,{b64}"><figcaption>{cap}</figcaption></figure>'
        )

    def _write(self, path: Path, data: bytes) -> None:
        self.written.append(write_bytes_atomic(path, data))


__all__ = ["COLORS", "FigureSink", "new_figure"]
