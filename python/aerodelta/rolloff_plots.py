"""Roll-off figures (thesis Section 3.4.3): event time histories (Figures 3.9-3.11), the
dynamic roll-control plot (Figure 3.12), maximum bank per straight stall against FAR
25.203 (Figure 3.13), and the Monte Carlo against the flight records.

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot (no
display, no global state; PNG through the Agg canvas). :func:`save_figure` writes one
atomically.

>>> import polars as pl
>>> from aerodelta.rolloff_plots import max_roll_figure
>>> fig = max_roll_figure(pl.DataFrame({"maneuver_id": ["a", "b"], "flap_deg": [0.0, 0.0],
...                                     "max_roll_deg": [12.0, 25.0]}))
>>> len(fig.axes)
1
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from aerodelta._fsutil import write_atomic
from aerodelta.exceptions import DataError
from aerodelta.rolloff import FAR25_203_MAX_ROLL_DEG, dynamic_roll, euler_roll_rate

#: Default |φ'| bound of the dynamic roll-control envelope, deg (QLC dynamic roll
#: attitude bound, Wilborn & Foster 2004); a parameter of :func:`drc_figure`.
DRC_PHI_LIMIT_DEG = 60.0
#: Aileron travel of the representative aircraft, deg (the envelope's vertical extent).
AILERON_LIMIT_DEG = 20.0


def _figure(width: float = 7.0, height: float = 4.0) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _need(data: pl.DataFrame, cols: list[str], what: str) -> None:
    missing = [c for c in cols if c not in data.columns]
    if missing:
        raise DataError(f"{what}: channels {missing} are missing from the data")


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: int = 120) -> Path:
    """Write ``fig`` as PNG at ``path`` atomically (``path.tmp-<pid>``, then rename)."""
    return write_atomic(path, lambda p: fig.savefig(p, dpi=dpi, format="png"))


def event_figure(
    record: pl.DataFrame,
    event: Mapping[str, Any] | None = None,
    *,
    model_column: str | None = None,
    title: str | None = None,
) -> Figure:
    """C_l and aileron against time with the roll-off marked (thesis Figures 3.9-3.11).

    Parameters
    ----------
    record
        One maneuver: ``t`` [s], ``Cl_meas``, ``da_deg`` [deg]; ``alpha_deg`` when present
        (third panel).
    event
        A row of :func:`aerodelta.rolloff.detect_rolloff` (``t_onset``, ``t_peak`` [s],
        ``alpha_onset_deg``, ``peak``, ``accepted``), or ``None``.
    model_column
        A model C_l column (e.g. ``Cl_qual``) drawn beside the measured one.
    title
        Figure title (default: the maneuver id when present).
    """
    _need(record, ["t", "Cl_meas", "da_deg"], "event figure")
    t = record["t"].to_numpy()
    has_alpha = "alpha_deg" in record.columns
    fig = _figure(8.0, 5.5 if has_alpha else 4.0)
    axes = fig.subplots(2 if has_alpha else 1, 1, sharex=True, squeeze=False)[:, 0]
    ax = axes[0]
    ax.plot(t, record["Cl_meas"].to_numpy(), color="tab:blue", lw=1.0, label="$C_l$ measured")
    if model_column is not None:
        _need(record, [model_column], "event figure")
        ax.plot(t, record[model_column].to_numpy(), color="tab:gray", lw=1.0, label=model_column)
    ax.set_ylabel("$C_l$")
    ax2 = ax.twinx()
    ax2.plot(t, record["da_deg"].to_numpy(), color="tab:orange", lw=1.0, label=r"$\delta_a$")
    ax2.set_ylabel(r"$\delta_a$ [deg] (positive rolls left)")
    if has_alpha:
        axes[1].plot(t, record["alpha_deg"].to_numpy(), color="tab:green", lw=1.0)
        axes[1].set_ylabel(r"$\alpha$ [deg]")
    axes[-1].set_xlabel("t [s]")
    if event is not None:
        color = "tab:red" if event.get("accepted", True) else "tab:purple"
        for a in axes:
            a.axvline(float(event["t_onset"]), color=color, lw=1.2)
            a.axvline(float(event["t_peak"]), color=color, lw=1.0, ls="--")
        ax.annotate(
            f"roll-off: onset t = {float(event['t_onset']):.2f} s, "
            f"α = {float(event['alpha_onset_deg']):.2f}°, ΔC_l = {float(event['peak']):+.4f}"
            + ("" if event.get("accepted", True) else f" (rejected: {event.get('reason', '')})"),
            xy=(0.01, 0.97),
            xycoords="axes fraction",
            va="top",
            fontsize=8,
            color=color,
        )
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="lower left", fontsize=8)
    if title is None and "maneuver_id" in record.columns and record.height:
        title = str(record["maneuver_id"][0])
    if title:
        fig.suptitle(title)
    return fig


def drc_figure(
    data: pl.DataFrame,
    *,
    phi_limit_deg: float = DRC_PHI_LIMIT_DEG,
    aileron_limit_deg: float = AILERON_LIMIT_DEG,
    kinds: tuple[str, ...] | None = ("straight",),
) -> Figure:
    """Aileron against dynamic roll attitude φ' = φ + φ̇ · 1 s (thesis Eq. 3.20, Figure 3.12).

    One line per maneuver. The envelope is the box ``|φ'| <= phi_limit_deg`` over the
    aileron travel ``|δa| <= aileron_limit_deg``; leaving it marks a loss of roll control.
    Positive aileron rolls left, so quadrants I and III are corrective inputs and II and
    IV inputs that augment the roll.

    Parameters
    ----------
    data
        Records: ``maneuver_id``, ``phi_deg``, ``p_dps``, ``da_deg``; with ``q_dps``,
        ``r_dps``, ``theta_deg`` the Euler roll rate is used, else ``p``.
    phi_limit_deg, aileron_limit_deg
        Envelope, deg.
    kinds
        Maneuver kinds drawn when a ``kind`` column is present (``None``: all).
    """
    _need(data, ["maneuver_id", "phi_deg", "p_dps", "da_deg"], "DRC figure")
    d = data
    if kinds is not None and "kind" in d.columns:
        d = d.filter(pl.col("kind").is_in(list(kinds)))
    fig = _figure(6.5, 5.5)
    ax = fig.subplots()
    euler = all(c in d.columns for c in ("q_dps", "r_dps", "theta_deg"))
    top = phi_limit_deg
    for (_,), g in d.group_by(["maneuver_id"], maintain_order=True):
        phidot = (
            euler_roll_rate(g["p_dps"], g["q_dps"], g["r_dps"], g["phi_deg"], g["theta_deg"])
            if euler
            else g["p_dps"].to_numpy()
        )
        phi1 = dynamic_roll(g["phi_deg"], phidot)
        top = max(top, float(np.nanmax(np.abs(phi1))) if phi1.size else top)
        ax.plot(phi1, g["da_deg"].to_numpy(), lw=0.6, alpha=0.6)
    box_x = [-phi_limit_deg, phi_limit_deg, phi_limit_deg, -phi_limit_deg, -phi_limit_deg]
    box_y = [-aileron_limit_deg, -aileron_limit_deg, aileron_limit_deg, aileron_limit_deg]
    ax.plot(box_x, [*box_y, -aileron_limit_deg], color="black", lw=1.5, label="DRC envelope")
    ax.axhline(0.0, color="gray", lw=0.5)
    ax.axvline(0.0, color="gray", lw=0.5)
    ax.set_xlim(-1.1 * top, 1.1 * top)
    ax.set_xlabel(r"dynamic roll attitude $\phi' = \phi + \dot\phi \cdot 1\,$s [deg]")
    ax.set_ylabel(r"aileron $\delta_a$ [deg]")
    ax.set_title("Dynamic roll control")
    ax.legend(loc="upper right", fontsize=8)
    return fig


def max_roll_figure(max_roll: pl.DataFrame, *, limit_deg: float = FAR25_203_MAX_ROLL_DEG) -> Figure:
    """Maximum roll angle per straight stall against the FAR 25.203 line (thesis Figure 3.13).

    Parameters
    ----------
    max_roll
        :func:`aerodelta.rolloff.max_roll_straight_stalls` output (``maneuver_id``,
        ``max_roll_deg``, optional ``flap_deg``); stalls whose id ends in ``_p`` are drawn
        as pusher stalls, ``_n`` as non-pusher stalls.
    limit_deg
        The bank limit, deg.
    """
    _need(max_roll, ["maneuver_id", "max_roll_deg"], "maximum-roll figure")
    fig = _figure(8.0, 4.0)
    ax = fig.subplots()
    ids = max_roll["maneuver_id"].to_list()
    y = max_roll["max_roll_deg"].to_numpy()
    x = np.arange(y.size)
    pusher = np.array([str(i).endswith("_p") for i in ids], dtype=bool)
    ax.scatter(x[pusher], y[pusher], s=18, marker="o", label="stick pusher")
    ax.scatter(x[~pusher], y[~pusher], s=18, marker="^", label="no pusher")
    ax.axhline(limit_deg, color="tab:red", lw=1.2, label=f"FAR 25.203: {limit_deg:g}°")
    if "flap_deg" in max_roll.columns:
        flaps = max_roll["flap_deg"].to_numpy()
        for k in np.nonzero(np.diff(flaps) != 0)[0]:
            ax.axvline(k + 0.5, color="gray", lw=0.5, ls=":")
    ax.set_xlabel("straight stall")
    ax.set_ylabel("maximum |φ| [deg]")
    n_over = int((y > limit_deg).sum())
    ax.set_title(f"Maximum roll in straight stalls: {n_over} of {y.size} above {limit_deg:g}°")
    ax.legend(fontsize=8)
    return fig


def mc_histograms(
    mc: pl.DataFrame,
    events: pl.DataFrame | None = None,
    max_roll: pl.DataFrame | None = None,
    *,
    limit_deg: float = FAR25_203_MAX_ROLL_DEG,
    bins: int = 30,
) -> Figure:
    """Monte Carlo distributions of onset alpha and maximum bank against the records'.

    Densities (so samples of different sizes compare): the Monte Carlo's
    ``onset_alpha_deg`` and ``max_bank_deg`` (:func:`aerodelta.rolloff.monte_carlo`)
    against the accepted events' ``alpha_onset_deg`` and the straight stalls'
    ``max_roll_deg``, with the FAR 25.203 line.
    """
    _need(mc, ["onset_alpha_deg", "max_bank_deg"], "Monte Carlo histograms")
    fig = _figure(9.0, 3.8)
    ax1, ax2 = fig.subplots(1, 2)
    a = mc["onset_alpha_deg"].drop_nans().drop_nulls().to_numpy()
    b = mc["max_bank_deg"].to_numpy()
    ax1.hist(a, bins=bins, density=True, alpha=0.5, label=f"Monte Carlo (n={a.size})")
    ax2.hist(b, bins=bins, density=True, alpha=0.5, label=f"Monte Carlo (n={b.size})")
    if events is not None and events.height:
        ev = events.filter(pl.col("accepted")) if "accepted" in events.columns else events
        r = ev["alpha_onset_deg"].to_numpy()
        ax1.hist(r, bins=max(5, bins // 3), density=True, histtype="step", lw=1.5,
                 label=f"records (n={r.size})")  # fmt: skip
    if max_roll is not None and max_roll.height:
        r = max_roll["max_roll_deg"].to_numpy()
        ax2.hist(r, bins=max(5, bins // 3), density=True, histtype="step", lw=1.5,
                 label=f"records (n={r.size})")  # fmt: skip
    ax2.axvline(limit_deg, color="tab:red", lw=1.2, label=f"FAR 25.203: {limit_deg:g}°")
    ax1.set_xlabel("roll-off onset alpha [deg]")
    ax2.set_xlabel("maximum |φ| [deg]")
    for ax in (ax1, ax2):
        ax.set_ylabel("density")
        ax.legend(fontsize=8)
    fig.suptitle("Monte Carlo against the flight records")
    return fig


__all__ = [
    "AILERON_LIMIT_DEG",
    "DRC_PHI_LIMIT_DEG",
    "drc_figure",
    "event_figure",
    "max_roll_figure",
    "mc_histograms",
    "save_figure",
]
