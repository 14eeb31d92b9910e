"""Shared plotting helpers: matplotlib on the Agg backend (no display, no pyplot), one house
style, and a sink that writes each figure as PNG and SVG files and returns it as an HTML
``<figure>`` with the PNG embedded (base64), so a report is one self-contained file.

Figures are drawn by plain functions (``draw(**data) -> Figure``, :mod:`aerodelta.plots.figures`)
under :func:`style`, which starts from matplotlib's defaults: the bytes of a figure depend on its
data only, not on the caller's matplotlib settings, the clock or the process. A
:class:`FigureSink` with ``workers=2`` draws them in two worker processes
(:mod:`aerodelta.plots._pool`) while the caller goes on computing the next section; the files
are written by the caller, in figure order, with the same bytes as without workers.

matplotlib is imported on first use: a report drawn in worker processes never loads it in the
caller.
"""

from __future__ import annotations

import base64
import html
import io
import re
import threading
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from aerodelta._fsutil import write_bytes_atomic

if TYPE_CHECKING:
    from concurrent.futures import Future

    from matplotlib.figure import Figure

    from aerodelta.plots._pool import RenderPool

#: Colours of the three signals compared throughout the report.
COLORS = {"meas": "#222222", "qual": "#d62728", "ext": "#1f77b4", "band": "#9ecae1"}

#: The house style, on top of matplotlib's defaults. ``svg.hashsalt`` fixes the ids of the SVG
#: elements (random per process otherwise); the SVG date is left out at save time.
STYLE: dict[str, Any] = {
    "figure.dpi": 96,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "font.size": 9,
    "axes.titlesize": 9,
    "legend.fontsize": 8,
    "svg.fonttype": "none",
    "svg.hashsalt": "aerodelta",
    "path.simplify": True,
}

#: Resolution of the rasterized artists (dense point clouds) inside the SVG files, dpi.
SVG_RASTER_DPI = 150

_RC_LOCK = threading.RLock()


@contextmanager
def style() -> Iterator[None]:
    """matplotlib's default settings plus :data:`STYLE` for the duration of the block (the
    caller's settings are restored after it). Not thread-safe across threads drawing at once,
    as matplotlib's settings are global: the block holds a lock."""
    import matplotlib as mpl  # noqa: PLC0415  (heavy; only where figures are drawn)

    with _RC_LOCK, mpl.rc_context():
        mpl.rcdefaults()
        mpl.rcParams.update(STYLE)
        yield


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
    layout: the caller places the axes with ``fig.subplots_adjust``. Call it inside
    :func:`style` for the house style."""
    from matplotlib.figure import Figure  # noqa: PLC0415

    fig = Figure(figsize=(width, height), layout=layout)
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig, axes


def render(fig: Figure, *, dpi: int = 110, svg: bool = True) -> tuple[bytes, bytes | None]:
    """PNG (at ``dpi``) and SVG bytes of ``fig``; the layout is computed once (for the PNG) and
    kept for the SVG. No date is written, so the bytes depend on the figure only."""
    with style():
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        fig.set_layout_engine("none")
        if not svg:
            return buf.getvalue(), None
        sbuf = io.BytesIO()
        fig.savefig(sbuf, format="svg", dpi=SVG_RASTER_DPI, metadata={"Date": None})
        return buf.getvalue(), sbuf.getvalue()


def draw_and_render(
    draw: Callable[..., Figure], kwargs: dict[str, Any], *, dpi: int, svg: bool
) -> tuple[bytes, bytes | None]:
    """``render(draw(**kwargs))`` with the figure drawn under :func:`style` too."""
    with style():
        fig = draw(**kwargs)
        return render(fig, dpi=dpi, svg=svg)


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "figure"


_TOKEN = re.compile(r"<!--aerodelta-figure:(\d+)-->")


@dataclass
class _Pending:
    number: int
    slug: str
    name: str
    caption: str
    future: Future[tuple[bytes, bytes | None] | None]
    draw: Callable[..., Figure]
    kwargs: dict[str, Any]


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
    workers
        Worker processes drawing the figures of :meth:`plot` (0: draw in this process). With
        workers, :meth:`plot` returns a placeholder that :meth:`fill` replaces once
        :meth:`finish` has run; use the sink as a context manager (or call :meth:`close`) so
        the workers stop.
    """

    out_dir: Path | None = None
    svg: bool = True
    dpi: int = 110
    workers: int = 0
    written: list[Path] = field(default_factory=list)
    count: int = 0
    _pool: RenderPool | None = field(default=None, init=False, repr=False)
    _pending: deque[_Pending] = field(default_factory=deque, init=False, repr=False)
    _done: dict[int, str] = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.workers > 0:
            from aerodelta.plots._pool import RenderPool  # noqa: PLC0415

            try:
                self._pool = RenderPool(self.workers)
            except OSError:  # no interpreter to start: draw here
                self._pool = None

    def __enter__(self) -> FigureSink:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Stop the worker processes (pending figures are dropped)."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None

    def _next_slug(self, name: str) -> str:
        self.count += 1
        return f"{self.count:03d}_{_slug(name)}"

    def add(self, fig: Figure, name: str, caption: str) -> str:
        """Write ``fig`` now and return its HTML ``<figure>`` (PNG as a ``data:`` URI)."""
        slug = self._next_slug(name)
        png, svg = render(fig, dpi=self.dpi, svg=self.svg)
        return self._emit(slug, name, caption, png, svg)

    def plot(self, draw: Callable[..., Figure], name: str, caption: str, **data: Any) -> str:
        """Figure ``draw(**data)`` (``draw`` a module-level function, ``data`` picklable:
        arrays, numbers, strings, lists and dicts of them).

        Returns its HTML ``<figure>``, or with workers a placeholder for :meth:`fill`.
        """
        slug = self._next_slug(name)
        if self._pool is None:
            png, svg = draw_and_render(draw, data, dpi=self.dpi, svg=self.svg)
            return self._emit(slug, name, caption, png, svg)
        # bounded memory: at most two figures waiting per worker
        while len(self._pending) >= 2 * self._pool.size:
            self._drain(block_first=True)
        fut = self._pool.submit(draw, data, dpi=self.dpi, svg=self.svg)
        self._pending.append(_Pending(self.count, slug, name, caption, fut, draw, data))
        self._drain(block_first=False)
        return f"<!--aerodelta-figure:{self.count}-->"

    def _drain(self, *, block_first: bool) -> None:
        """Write the finished figures at the head of the queue, in order."""
        while self._pending and (block_first or self._pending[0].future.done()):
            block_first = False
            job = self._pending.popleft()
            out = job.future.result()
            if out is None:  # the worker is gone: draw it here (same bytes)
                out = draw_and_render(job.draw, job.kwargs, dpi=self.dpi, svg=self.svg)
            self._done[job.number] = self._emit(job.slug, job.name, job.caption, *out)

    def finish(self) -> None:
        """Wait for the figures drawn in workers and write them (in figure order)."""
        while self._pending:
            self._drain(block_first=True)

    def fill(self, fragment: str) -> str:
        """``fragment`` with the placeholders of :meth:`plot` replaced by the figures."""
        if "<!--aerodelta-figure:" not in fragment:
            return fragment
        self.finish()
        return _TOKEN.sub(lambda m: self._done[int(m.group(1))], fragment)

    def _emit(self, slug: str, name: str, caption: str, png: bytes, svg: bytes | None) -> str:
        if self.out_dir is not None:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            self._write(self.out_dir / f"{slug}.png", png)
            if svg is not None:
                self._write(self.out_dir / f"{slug}.svg", svg)
        b64 = base64.b64encode(png).decode("ascii")
        cap = html.escape(caption)
        return (
            f'<figure id="fig-{slug}"><img alt="{html.escape(name)}" '
            f'src="data:image/png;base64,{b64}"><figcaption>{cap}</figcaption></figure>'
        )

    def _write(self, path: Path, data: bytes) -> None:
        self.written.append(write_bytes_atomic(path, data))


__all__ = ["COLORS", "STYLE", "FigureSink", "draw_and_render", "new_figure", "render", "style"]
