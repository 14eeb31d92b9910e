"""Draw functions for the figure-worker tests (tests/test_report_figures.py). Importable in a
worker: they import only the standard library and aerodelta.plots, never polars."""

from __future__ import annotations

import sys
from typing import Any

from aerodelta.plots import new_figure


def modules() -> Any:
    """A figure whose title names the heavy modules loaded in the drawing process."""
    fig, ax = new_figure()
    loaded = [m for m in ("polars", "aerodelta._core", "aerodelta.report") if m in sys.modules]
    ax[0, 0].set_title(f"loaded: {','.join(loaded) or 'none'}")
    return fig


def failing(message: str) -> Any:
    """Raise ``ValueError(message)`` (in whichever process draws it)."""
    raise ValueError(message)
