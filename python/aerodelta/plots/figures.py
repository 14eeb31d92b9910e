"""The figures of the validation report, one function each: ``draw(**data) -> Figure`` from
plain data (numpy arrays, numbers, strings, lists and dicts of them) computed by the report
sections (:mod:`aerodelta.report`). Nothing here computes a result: each function only places
what it is given, so it can run in a worker process that loads neither polars nor the engine
(:mod:`aerodelta.plots._pool`). Call them under :func:`aerodelta.plots.style` (as
:meth:`aerodelta.plots.FigureSink.plot` does). matplotlib is imported inside the functions, so
the sections can name them without loading it.

Units are those of the data given (angles in deg, time in s); sizes in inches.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from aerodelta.plots import COLORS, new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Colours of the flap settings (in order of the settings drawn).
FLAP_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b")

Panel = dict[str, Any]
Titles = list[tuple[Any, str, dict[str, Any]]]


def _legend(ax: Any, **kw: Any) -> None:
    """A legend inside ``ax``, left out of the constrained layout (it lies inside the axes, so
    the layout is the same without measuring it, which costs a 'best' placement per pass)."""
    ax.legend(**kw).set_in_layout(False)


def _pinned(lo: float, hi: float) -> bool:
    """Whether a y axis over ``[lo, hi]`` shows neither an offset nor an exponent above it:
    values between 1e-3 and 1e5 in magnitude (matplotlib writes 1e-5 to 1e6 in plain
    notation) spanning at least 1 % of it (an offset needs a span under 0.1 %)."""
    mag = max(abs(lo), abs(hi))
    return bool(np.isfinite(mag)) and 1e-3 <= mag < 1e5 and abs(hi - lo) >= 0.01 * mag


def _errorbars(
    ax: Any,
    x: np.ndarray,
    y: np.ndarray,
    half: np.ndarray,
    *,
    ms: float,
    color: str,
    elinewidth: float,
    alpha: float | None = None,
    label: str | None = None,
) -> None:
    """Points ``y`` at ``x`` with symmetric error bars ``y ± half``, drawn as ``errorbar`` does
    (bars below the markers, no caps) but all bars as one path: an SVG writes one element
    instead of one per bar. The legend entry is an empty ``errorbar`` (the same glyph)."""
    if len(x):
        n = len(x)
        xs = np.repeat(np.asarray(x, dtype=float), 3)
        xs[2::3] = np.nan
        ys = np.column_stack([y - half, y + half, np.full(n, np.nan)]).ravel()
        ax.plot(xs, ys, color=color, lw=elinewidth, alpha=alpha, solid_capstyle="butt", zorder=2)
        ax.plot(x, y, "o", ms=ms, color=color, alpha=alpha, zorder=2.1)
    ax.errorbar(
        [], [], yerr=[], fmt="o", ms=ms, color=color, elinewidth=elinewidth, capsize=0,
        alpha=alpha, label=label,
    )  # fmt: skip


#: Space around each panel's texts and at the figure's edges, points, and the extra space
#: between panels, fraction of the figure's width or height (the constrained layout's
#: defaults: 3/72 in and 0.02).
PAD_PT = 3.0
SPACE = 0.02
#: Gap between an axis and its offset text, points (matplotlib's ``Axis.OFFSETTEXTPAD``).
OFFSET_PAD_PT = 3.0


def _margins(ax: Any, r: Any) -> tuple[float, float, float, float]:
    """How far the decorations of ``ax`` reach beyond its box (left, right, bottom, top),
    pixels: tick marks, tick labels inside the view, the axis labels beside them, offset texts
    and the title. The axis labels and offset texts are placed by matplotlib only when drawn,
    so they are added by size."""
    import matplotlib as mpl  # noqa: PLC0415

    box = ax.get_window_extent(r)
    px = r.points_to_pixels(1.0)
    left = right = bottom = top = lifted = 0.0
    for axis, name in ((ax.xaxis, "x"), (ax.yaxis, "y")):
        axis.get_majorticklabels()  # places the ticks for the current view and size
        lo, hi = sorted(axis.get_view_interval())
        tol = 1e-9 * max(abs(lo), abs(hi), 1.0)
        ticks = [t for t in axis.get_major_ticks() if lo - tol <= t.get_loc() <= hi + tol]
        size = px * float(mpl.rcParams[f"{name}tick.major.size"])
        near = size if any(t.tick1line.get_visible() for t in ticks) else 0.0
        for t in (tk.label1 for tk in ticks):
            if t.get_visible() and t.get_text():
                b = t.get_window_extent(r)
                left, right = max(left, box.x0 - b.x0), max(right, b.x1 - box.x1)
                bottom, top = max(bottom, box.y0 - b.y0), max(top, b.y1 - box.y1)
                near = max(near, box.y0 - b.y0 if name == "x" else box.x0 - b.x0)
        label = axis.label
        if label.get_visible() and label.get_text():
            b = label.get_window_extent(r)
            pad = px * axis.labelpad
            if name == "x":
                bottom = max(bottom, near + pad + b.height)
            else:
                left = max(left, near + pad + b.width)
        off = axis.offsetText
        off.set_text(axis.get_major_formatter().get_offset())  # as drawing will
        if off.get_visible() and off.get_text():
            h = off.get_window_extent(r).height + px * OFFSET_PAD_PT
            if name == "x":  # under the tick labels
                bottom = max(bottom, near + h)
            else:  # above the axes, under a title lifted to clear it
                lifted = h
                top = max(top, h)
    if ax.title.get_text():  # above the axes; a long one reaches past its sides too
        b = ax.title.get_window_extent(r)
        top = max(top, b.y1 - box.y1 + lifted)
        left, right = max(left, box.x0 - b.x0), max(right, b.x1 - box.x1)
    return left, right, bottom, top


def _grid_layout(fig: Figure, ax: np.ndarray) -> None:
    """Place a grid of panels as the constrained layout would, for less: the margins and gaps
    are the extents of each panel's decorations beyond its axes (:func:`_margins`, measured,
    not drawn) plus :data:`PAD_PT` (and :data:`SPACE` between panels), placed again until
    no margin grows (the ticks of the placed axes may differ, and a title wider than its
    panel reaches further as the panel narrows). For figures whose decorations are ticks, axis
    labels (rotated ones too), offset texts and titles only (no colorbar, no figure legend);
    legends inside the axes do not count."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415

    fig.set_layout_engine("none")
    r = FigureCanvasAgg(fig).get_renderer()
    w_pt, h_pt = fig.get_size_inches() * 72.0
    pt = 72.0 / fig.dpi
    nrow, ncol = ax.shape
    used: np.ndarray | None = None
    for _ in range(4):  # until no margin grows (two passes unless a long title is squeezed)
        left, right = np.zeros(ncol), np.zeros(ncol)
        bottom, top = np.zeros(nrow), np.zeros(nrow)
        for (i, j), a in np.ndenumerate(ax):
            if a.get_visible():
                m = np.array(_margins(a, r)) * pt
                left[j], right[j] = max(left[j], m[0]), max(right[j], m[1])
                bottom[i], top[i] = max(bottom[i], m[2]), max(top[i], m[3])
        need = np.concatenate([left, right, bottom, top])
        if used is not None and np.all(need <= used + 0.5):
            return
        used = need if used is None else np.maximum(used, need)
        left, right = used[:ncol], used[ncol : 2 * ncol]
        bottom, top = used[2 * ncol : 2 * ncol + nrow], used[2 * ncol + nrow :]
        gap_w = (right[:-1] + left[1:]).max(initial=0.0) + 2 * PAD_PT + SPACE * w_pt
        gap_h = (bottom[:-1] + top[1:]).max(initial=0.0) + 2 * PAD_PT + SPACE * h_pt
        x0, x1 = left[0] + PAD_PT, w_pt - right[-1] - PAD_PT
        y0, y1 = bottom[-1] + PAD_PT, h_pt - top[0] - PAD_PT
        width = (x1 - x0 - (ncol - 1) * gap_w) / ncol
        height = (y1 - y0 - (nrow - 1) * gap_h) / nrow
        fig.subplots_adjust(
            left=x0 / w_pt,
            right=x1 / w_pt,
            bottom=y0 / h_pt,
            top=y1 / h_pt,
            wspace=gap_w / width if ncol > 1 else 0.0,
            hspace=gap_h / height if nrow > 1 else 0.0,
        )


def _set_titles(titles: Titles) -> None:
    """Set the panel titles once the data are drawn. A title is pinned just above its axes
    (``y=1``, where matplotlib puts it anyway) when no offset text can sit there; else
    matplotlib places it, measuring the axis at every draw to clear the offset text."""
    for ax, text, kw in titles:
        lo, hi = ax.get_ylim()
        ax.set_title(text, y=1.0 if _pinned(lo, hi) else None, **kw)


def tic_scatter(*, panels: Sequence[Panel]) -> Figure:
    """Theil inequality coefficient per maneuver, qualified (x) against extended (y), one panel
    per coefficient.

    Each panel: ``coef``; ``fitted`` and ``held`` as ``(tic_qual, tic_ext)`` arrays (``None``:
    none); ``hi``, the end of the dashed identity line.
    """
    fig, ax = new_figure(1, len(panels), height=2.9, layout=None)
    titles: Titles = []
    for k, pan in enumerate(panels):
        a = ax[0, k]
        for key, mk, col, lab in (
            ("fitted", "o", "#1f77b4", "fitted"),
            ("held", "^", "#ff7f0e", "held out"),
        ):
            if pan[key] is not None:
                x, y = pan[key]
                a.scatter(x, y, s=12, marker=mk, color=col, label=lab)
        a.plot([0, pan["hi"]], [0, pan["hi"]], color="#999", lw=0.8, ls="--")
        titles.append((a, f"{pan['coef']}: TIC per maneuver", {}))
        a.set_xlabel("TIC qualified")
        a.set_ylabel("TIC extended")
        _legend(a, loc="upper left")
    _set_titles(titles)
    _grid_layout(fig, ax)
    return fig


def time_history(
    *,
    t: np.ndarray,
    meas: np.ndarray,
    qual: np.ndarray,
    ext: np.ndarray,
    alpha: np.ndarray,
    active: np.ndarray | None,
    ylabel: str,
    title: str,
) -> Figure:
    """Measured, qualified and extended coefficient against time ``t`` [s], with alpha [deg]
    below, shaded where ``active`` (the Δ model blended in; ``None``: nowhere)."""
    fig, ax = new_figure(
        2, 1, height=3.6, sharex=True, gridspec_kw={"height_ratios": [3, 1]}, layout=None
    )
    titles: Titles = []
    a0, a1 = ax[0, 0], ax[1, 0]
    a0.plot(t, meas, color=COLORS["meas"], lw=0.8, label="measured")
    a0.plot(t, qual, color=COLORS["qual"], lw=1.0, label="qualified")
    a0.plot(t, ext, color=COLORS["ext"], lw=1.2, label="extended")
    a0.set_ylabel(ylabel)
    _legend(a0, loc="best", ncol=3)
    titles.append((a0, title, {"fontsize": 8.5}))
    a1.plot(t, alpha, color="#555", lw=0.9)
    if active is not None:
        a1.fill_between(
            t,
            0,
            1,
            where=active,
            transform=a1.get_xaxis_transform(),
            color=COLORS["band"],
            alpha=0.35,
            lw=0,
            label="Δ model active",
        )
        _legend(a1, loc="upper right")
    a1.set_ylabel("α [deg]")
    a1.set_xlabel("t [s]")
    _set_titles(titles)
    _grid_layout(fig, ax)
    return fig


def effect(*, panels: Sequence[Panel], ylabel: str, ext_label: str) -> Figure:
    """One derivative against alpha, one panel per flap setting.

    Each panel: ``flap``, ``alpha`` [deg], ``dq`` (qualified, or ``None``), ``ext`` (extended),
    ``stall`` [deg] or ``None``, and ``bins`` (``None`` or ``c``, ``y``, ``half`` arrays of the
    identified bins: centre [deg], value and 95 % half-width; ``c_bad``, ``y_bad`` of the
    others; ``band``: the half-width along ``alpha`` and ``inside``, where it is drawn).
    """
    n = len(panels)
    fig, ax = new_figure(1, n, width=min(2.3 * n + 0.6, 12.0), height=2.6, sharey=True, layout=None)
    titles: Titles = []
    for k, pan in enumerate(panels):
        a = ax[0, k]
        alpha, ext = pan["alpha"], pan["ext"]
        if pan["dq"] is not None:
            a.plot(alpha, pan["dq"], color=COLORS["qual"], lw=1.1, label="qualified")
        a.plot(alpha, ext, color=COLORS["ext"], lw=1.4, label=ext_label)
        b = pan["bins"]
        if b is not None:
            _errorbars(
                a, b["c"], b["y"], b["half"], ms=2.5, color="#444", elinewidth=0.6, label="bins"
            )
            if len(b["c_bad"]):
                a.plot(b["c_bad"], b["y_bad"], "x", color="#999", ms=4, label="not identified")
            if b["band"] is not None:
                a.fill_between(
                    alpha,
                    ext - b["band"],
                    ext + b["band"],
                    where=b["inside"],
                    color=COLORS["band"],
                    alpha=0.5,
                    lw=0,
                    label="95 % band",
                )
        if pan["stall"] is not None:
            a.axvline(pan["stall"], color="#777", ls="--", lw=0.8)
        titles.append((a, f"flap {pan['flap']:g}", {}))
        a.set_xlabel("α [deg]")
    ax[0, 0].set_ylabel(ylabel)
    _legend(ax[0, 0], loc="best", fontsize=6.5)
    _set_titles(titles)
    _grid_layout(fig, ax)
    return fig


def parameters(*, panels: Sequence[Panel], flaps: Sequence[float], ncol: int = 4) -> Figure:
    """Δ parameters against alpha, one panel per parameter, the flap settings in colour.

    Each panel: ``title`` and ``series``, one per flap drawn: ``flap``, ``c``, ``est``, ``half``
    (identified bins: centre [deg], estimate, 95 % half-width), ``c_bad`` (bins not
    identified, drawn at zero) and ``table`` (``(alpha, values)`` of the model, or ``None``).
    """
    from matplotlib.ticker import MaxNLocator  # noqa: PLC0415

    nrow = max(1, -(-len(panels) // ncol))
    h = 2.0 * nrow + 0.5
    fig, ax = new_figure(nrow, ncol, width=10.5, height=h, sharex=True, layout=None)
    titles: Titles = []
    fig.subplots_adjust(left=0.07, right=0.99, bottom=0.45 / h, top=1 - 0.5 / h, wspace=0.35,
                        hspace=0.45)  # fmt: skip
    index = {f: i for i, f in enumerate(flaps)}
    for k, pan in enumerate(panels):
        a = ax[k // ncol, k % ncol]
        for s in pan["series"]:
            col = FLAP_COLORS[index[s["flap"]] % len(FLAP_COLORS)]
            _errorbars(
                a, s["c"], s["est"], s["half"], ms=2.0, color=col, elinewidth=0.5, alpha=0.8,
                label=f"flap {s['flap']:g}",
            )  # fmt: skip
            if s["table"] is not None:
                a.plot(s["table"][0], s["table"][1], color=col, lw=1.2)
            if len(s["c_bad"]):
                a.plot(s["c_bad"], np.zeros(len(s["c_bad"])), "x", color=col, ms=3.5, mew=0.8)
        titles.append((a, pan["title"], {"fontsize": 7.5}))
        a.yaxis.set_major_locator(MaxNLocator(4))
    for k in range(len(panels), nrow * ncol):
        ax[k // ncol, k % ncol].set_visible(False)
    for a in ax[-1, :]:
        a.set_xlabel("α [deg]")
    fig.legend(*ax[0, 0].get_legend_handles_labels(), loc="upper center", ncol=len(flaps),
               fontsize=7, frameon=False)  # fmt: skip
    _set_titles(titles)
    return fig


def error_vs_regressor(*, rows: Sequence[Panel]) -> Figure:
    """Model error against candidate regressors, one row of panels per alpha bin.

    Each row: ``ylabel`` and ``panels``: ``xlabel``, ``x``, ``z`` (the points, thinned by the
    caller; drawn rasterized in the SVG) and ``fit`` (``None`` or ``(xs, ys, label)``, the bin's
    least-squares line).
    """
    ncol = max(len(r["panels"]) for r in rows)
    fig, ax = new_figure(len(rows), ncol, width=10.0, height=2.0 * len(rows) + 0.4, layout=None)
    titles: Titles = []
    for i, row in enumerate(rows):
        for j, pan in enumerate(row["panels"]):
            a = ax[i, j]
            (pts,) = a.plot(pan["x"], pan["z"], ".", ms=1.5, color="#555", alpha=0.5)
            pts.set_rasterized(True)
            if pan["fit"] is not None:
                xs, ys, label = pan["fit"]
                a.plot(xs, ys, color=COLORS["ext"], lw=1.2, label=label)
                _legend(a, loc="best", fontsize=6)
            a.set_xlabel(pan["xlabel"])
            if j == 0:
                a.set_ylabel(row["ylabel"])
    _set_titles(titles)
    _grid_layout(fig, ax)
    return fig


def replay(*, panels: Sequence[Panel]) -> Figure:
    """Flight record against the 6-DOF replays, one panel per state.

    Each panel: ``title``, ``t`` and ``y`` of the record and ``runs``: ``(t, y, colour,
    label)`` per replay.
    """
    fig, ax = new_figure(1, len(panels), width=11.0, height=2.4, layout=None)
    titles: Titles = []
    for k, pan in enumerate(panels):
        a = ax[0, k]
        a.plot(pan["t"], pan["y"], color=COLORS["meas"], lw=0.9, label="flight record")
        for ts, ys, col, lab in pan["runs"]:
            a.plot(ts, ys, color=col, lw=1.0, label=lab)
        titles.append((a, pan["title"], {}))
        a.set_xlabel("t [s]")
    _legend(ax[0, 0], loc="best", fontsize=6.5)
    _set_titles(titles)
    _grid_layout(fig, ax)
    return fig


def rolloff_drc_maxroll(
    *, drc: Sequence[Panel], max_roll: Sequence[Panel], flaps: Sequence[float], limit_deg: float
) -> Figure:
    """Left: aileron [deg] against dynamic roll φ' [deg] per flap (``drc``: ``x``, ``y``
    thinned by the caller, drawn rasterized in the SVG). Right: maximum bank [deg] per straight
    stall per flap (``max_roll``: ``x``, ``y``) against ``limit_deg``."""
    fig, ax = new_figure(1, 2, width=10.0, height=3.4, layout=None)
    titles: Titles = []
    a = ax[0, 0]
    for k, (pan, flap) in enumerate(zip(drc, flaps, strict=True)):
        (pts,) = a.plot(
            pan["x"], pan["y"], ".", ms=1.0, color=FLAP_COLORS[k % len(FLAP_COLORS)],
            alpha=0.5, label=f"flap {flap:g}",
        )  # fmt: skip
        pts.set_rasterized(True)
    a.axhline(0, color="#666", lw=0.6)
    a.axvline(0, color="#666", lw=0.6)
    for x in (-limit_deg, limit_deg):
        a.axvline(x, color="#b42318", lw=0.8, ls="--")
    a.set_xlabel("dynamic roll φ' = φ + φ̇·1 s [deg]")
    a.set_ylabel("aileron δa [deg] (+ rolls left)")
    titles.append((a, "Dynamic roll control, straight stalls (quadrants I/III: recovering)", {}))
    _legend(a, loc="best", markerscale=6, fontsize=6.5)
    b = ax[0, 1]
    for k, pan in enumerate(max_roll):
        b.scatter(pan["x"], pan["y"], s=12, color=FLAP_COLORS[k % len(FLAP_COLORS)])
    b.axhline(limit_deg, color="#b42318", ls="--", lw=1.0, label=f"{limit_deg:g} deg (FAR 25.203)")
    b.set_xticks(range(len(flaps)), [f"flap {f:g}" for f in flaps])
    b.set_ylabel("max |φ| [deg]")
    titles.append((b, "Maximum bank angle per straight stall", {}))
    _legend(b, loc="best")
    _set_titles(titles)
    _grid_layout(fig, ax)
    return fig


#: Colours of the envelope's confidence levels (none, low, moderate, high).
ENVELOPE_COLORS = ("#f2f2f2", "#fdd49e", "#9ecae1", "#2171b5")


def envelope(*, panels: Sequence[Panel], levels: Sequence[str]) -> Figure:
    """Confidence level per alpha-beta cell, one panel per flap.

    Each panel: ``flap``, ``a_edges`` and ``b_edges`` (cell edges, deg), ``level`` (index into
    ``levels`` per cell, alpha × beta) and ``stall`` [deg] or ``None``.
    """
    from matplotlib.colors import BoundaryNorm, ListedColormap  # noqa: PLC0415

    cmap = ListedColormap(list(ENVELOPE_COLORS))
    norm = BoundaryNorm([-0.5, 0.5, 1.5, 2.5, 3.5], cmap.N)
    n = len(panels)
    fig, ax = new_figure(1, n, width=min(2.4 * n + 1.0, 12.5), height=3.4, sharey=True)
    titles: Titles = []
    im = None
    for k, pan in enumerate(panels):
        a = ax[0, k]
        be, ae = pan["b_edges"], pan["a_edges"]
        # the cells are a regular 1 deg grid: an image, one pixel per cell (in the SVG too,
        # drawn unsmoothed), instead of one path per cell
        im = a.imshow(
            pan["level"], cmap=cmap, norm=norm, origin="lower", aspect="auto",
            interpolation="none", extent=(be[0], be[-1], ae[0], ae[-1]),
        )  # fmt: skip
        a.set_xlim(be[0], be[-1])
        if pan["stall"] is not None:
            a.axhline(pan["stall"], color="#b42318", ls="--", lw=0.8)
        titles.append((a, f"flap {pan['flap']:g}", {}))
        a.set_xlabel("β [deg]")
    if panels:  # the axes share alpha: the union of the panels' ranges (and stall lines)
        ends = [v for p in panels for v in (p["a_edges"][0], p["a_edges"][-1], p["stall"])]
        ax[0, 0].set_ylim(min(v for v in ends if v is not None),
                          max(v for v in ends if v is not None))  # fmt: skip
    ax[0, 0].set_ylabel("α [deg]")
    if im is not None:
        cb = fig.colorbar(im, ax=ax[0, -1], ticks=[0, 1, 2, 3])
        cb.ax.set_yticklabels(list(levels))
    _set_titles(titles)
    return fig


def gap_map(*, flaps: Sequence[float], coefs: Sequence[str], cells: Sequence[Panel]) -> Figure:
    """Gap RMS per alpha region (bars from ``lo`` to ``hi`` deg) and coefficient, one panel per
    flap; colour: ``rms`` over ``top`` (the coefficient's largest); outlined where
    ``significant``.

    ``cells``: one per (flap index ``k``, coefficient index ``j``) with ``lo``, ``hi``, ``rms``,
    ``significant`` arrays and ``top``.
    """
    from matplotlib import colormaps  # noqa: PLC0415
    from matplotlib.cm import ScalarMappable  # noqa: PLC0415
    from matplotlib.colors import Normalize  # noqa: PLC0415

    n = len(flaps)
    fig, ax = new_figure(1, n, width=min(2.2 * n + 1.2, 12.0), height=3.2, sharey=True)
    titles: Titles = []
    cmap = colormaps["YlOrRd"]
    for c in cells:
        a = ax[0, c["k"]]
        top = c["top"]
        norm = Normalize(0.0, top if np.isfinite(top) and top > 0 else 1.0)
        a.bar(
            np.full(len(c["lo"]), c["j"]),
            c["hi"] - c["lo"],
            bottom=c["lo"],
            width=0.9,
            color=cmap(norm(np.nan_to_num(c["rms"]))),
            edgecolor=["#000" if x else "none" for x in c["significant"]],
            linewidth=0.8,
        )
    for k, flap in enumerate(flaps):
        ax[0, k].set_xticks(range(len(coefs)), list(coefs))
        titles.append((ax[0, k], f"flap {flap:g}", {}))
    ax[0, 0].set_ylabel("α [deg]")
    fig.colorbar(
        ScalarMappable(Normalize(0, 1), cmap),
        ax=ax[0, -1],
        label="gap RMS / largest of the coefficient",
    )
    _set_titles(titles)
    return fig


def shrink(*, panels: Sequence[Panel]) -> Figure:
    """Held-out gap RMS as the ranked effects are added, one panel per coefficient (``coef``,
    ``y``: the gap before and after each effect, ``labels``)."""
    n = len(panels)
    fig, ax = new_figure(1, n, width=min(3.4 * n, 12.0), height=2.8, layout=None)
    titles: Titles = []
    for k, pan in enumerate(panels):
        a = ax[0, k]
        y = pan["y"]
        a.plot(range(len(y)), y, "o-", color="#1f77b4")
        a.set_xticks(range(len(y)), pan["labels"], rotation=35, ha="right", fontsize=7)
        titles.append((a, f"{pan['coef']}: held-out gap RMS as effects are added", {}))
        a.set_ylim(bottom=0)
    _set_titles(titles)
    _grid_layout(fig, ax)
    return fig


__all__ = [
    "ENVELOPE_COLORS",
    "FLAP_COLORS",
    "effect",
    "envelope",
    "error_vs_regressor",
    "gap_map",
    "parameters",
    "replay",
    "rolloff_drc_maxroll",
    "shrink",
    "tic_scatter",
    "time_history",
]
