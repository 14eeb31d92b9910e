"""The evidence pack's figures: plain functions of arrays and frames that return a matplotlib
``Figure`` (drawn under :func:`aerodelta.plots.style`, saved as PNG beside the page)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import polars as pl

from aerodelta.plots import new_figure

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: One colour per maneuver kind (and ``other``).
KIND_COLORS: dict[str, str] = {
    "straight": "#1f77b4",
    "turning": "#ff7f0e",
    "accelerated": "#2ca02c",
    "asymmetric_thrust": "#9467bd",
    "other": "#7f7f7f",
}
#: One colour per stall-identification criterion (Attachment 7) and the two speeds' events.
CRITERION_COLORS: dict[str, str] = {
    "pusher": "#d62728",
    "pitch_break": "#8c564b",
    "g_break": "#2ca02c",
    "buffet": "#ff7f0e",
    "aft_stop": "#17becf",
    "warning": "#bcbd22",
    "buffet_onset": "#e377c2",
}
#: Colours of the flap settings (cycled).
FLAP_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2")


def _legend(ax: Any, **kw: Any) -> None:
    """A legend when the axes have labelled artists (none: no legend, no warning)."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, frameon=False, **kw)


def _kind_color(kind: str) -> str:
    return KIND_COLORS.get(kind, KIND_COLORS["other"])


def _flap_axis(ax: Any, flaps: Sequence[float]) -> None:
    ax.set_xticks(range(len(flaps)))
    ax.set_xticklabels([f"{f:g}" for f in flaps])
    ax.set_xlabel("flap [deg]")
    ax.set_xlim(-0.6, len(flaps) - 0.4)


def _positions(table: pl.DataFrame, flaps: Sequence[float]) -> np.ndarray:
    """x of each maneuver: its flap's index, offset by kind so kinds sit side by side."""
    kinds = list(KIND_COLORS)
    idx = {f: i for i, f in enumerate(flaps)}
    fx = np.array([idx[float(f)] for f in table["flap_deg"]], dtype=float)
    kx = np.array([kinds.index(k) if k in kinds else len(kinds) - 1 for k in table["kind"]])
    return fx + (kx - (len(kinds) - 1) / 2.0) * 0.12


def _kind_legend(ax: Any, kinds: Sequence[str]) -> None:
    for k in kinds:
        ax.plot([], [], "o", color=_kind_color(k), label=k, ms=4)
    _legend(ax, loc="best")


def stall_alpha(*, table: pl.DataFrame, flaps: Sequence[float]) -> Figure:
    """Left: the stall-identification alpha per maneuver (colour: the criterion met first).
    Right: the alpha at every criterion met, and at the warning and buffet onset (deg)."""
    fig, ax = new_figure(1, 2, width=9.0, height=3.4, sharey=True)
    x = _positions(table, flaps)
    left, right = ax[0, 0], ax[0, 1]
    by = table["stall_id_by"].to_list()
    a = table["stall_id_alpha_deg"].to_numpy().astype(float)
    for crit in ("pusher", "pitch_break", "g_break", "buffet", "aft_stop"):
        m = np.array([b == crit for b in by], dtype=bool)
        if m.any():
            left.plot(x[m], a[m], "o", ms=5, color=CRITERION_COLORS[crit], label=crit)
    left.set_ylabel("α at stall identification [deg]")
    left.set_title("stall identification (first criterion met)")
    _legend(left, loc="best")
    _flap_axis(left, flaps)
    for k, crit in enumerate((*CRITERION_COLORS,)):
        col = f"{crit}_alpha_deg"
        if col not in table.columns:
            continue
        v = table[col].to_numpy().astype(float)
        ok = np.isfinite(v)
        if ok.any():
            right.plot(x[ok] + 0.02 * (k - 3), v[ok], "_", ms=9, mew=2,
                       color=CRITERION_COLORS[crit], label=crit)  # fmt: skip
    right.set_title("α at each criterion met, the warning and the buffet onset")
    _legend(right, loc="best", ncol=2)
    _flap_axis(right, flaps)
    return fig


def speeds(
    *, table: pl.DataFrame, flaps: Sequence[float], replay: pl.DataFrame | None = None
) -> Figure:
    """Stall-warning, buffet-onset and stall speeds (KEAS) per maneuver, by flap and kind; with
    ``replay`` (:attr:`aerodelta.closed_loop.ClosedLoopResult.table`), the simulator's speeds as
    open markers beside them and ±3 kt bars around the flight test."""
    fig, ax = new_figure(1, 3, width=10.0, height=3.2, sharey=True)
    x = _positions(table, flaps)
    kinds = table["kind"].to_list()
    cols = (
        ("v_warning_keas", "v_warning", "stall warning"),
        ("v_buffet_onset_keas", "v_buffet_onset", "buffet onset"),
        ("v_stall_keas", "v_stall", "stall (at identification)"),
    )
    sim = None
    if replay is not None:
        sim = table.select("maneuver_id").join(replay, on="maneuver_id", how="left")
    for a, (col, key, title) in zip(ax[0], cols, strict=True):
        v = table[col].to_numpy().astype(float)
        for kind in dict.fromkeys(kinds):
            m = np.array([k == kind for k in kinds]) & np.isfinite(v)
            if m.any():
                a.plot(x[m], v[m], "o", ms=4, color=_kind_color(kind))
                if sim is not None:
                    a.errorbar(x[m], v[m], yerr=3.0, fmt="none", ecolor="#999", lw=0.6)
                    s = sim[f"{key}_sim_keas"].to_numpy().astype(float)
                    ms = m & np.isfinite(s)
                    a.plot(x[ms] + 0.05, s[ms], "o", ms=4, mfc="none", color=_kind_color(kind))
        a.set_title(f"{title}: {int(np.isfinite(v).sum())} maneuvers")
        _flap_axis(a, flaps)
    ax[0, 0].set_ylabel("equivalent airspeed [kt]")
    _kind_legend(ax[0, 2], list(dict.fromkeys(kinds)))
    return fig


def breaks(*, gbreak: Sequence[Mapping[str, Any]], pitch: Sequence[Mapping[str, Any]]) -> Figure:
    """Load factor around each g-break and pitch attitude around each pitch break, against
    time from the break (s); one line per maneuver (``t``, ``y``, ``kind``, ``id``)."""
    fig, ax = new_figure(1, 2, width=9.0, height=3.2)
    for a, lines, ylabel, title in (
        (ax[0, 0], gbreak, "load factor n [-]", f"g-break: {len(gbreak)} maneuvers"),
        (ax[0, 1], pitch, "pitch attitude θ [deg]", f"pitch break: {len(pitch)} maneuvers"),
    ):
        for ln in lines:
            a.plot(ln["t"], ln["y"], lw=0.9, color=_kind_color(str(ln["kind"])))
        if not lines:
            a.text(0.5, 0.5, "none in the records", transform=a.transAxes, ha="center",
                   va="center", color="#666")  # fmt: skip
            a.set_xlim(-3.0, 3.0)
        a.axvline(0.0, color="#444", lw=0.8, ls="--")
        a.set_xlabel("time from the break [s]")
        a.set_ylabel(ylabel)
        a.set_title(title)
    _kind_legend(ax[0, 0], list(dict.fromkeys(str(ln["kind"]) for ln in [*gbreak, *pitch])))
    return fig


def rolloff(*, lines: Sequence[Mapping[str, Any]], limit_deg: float) -> Figure:
    """Bank angle of the wings-level stalls against time from stall identification (s), with
    the ±``limit_deg`` lines of FAR 25.203(c) for scale; roll-off events marked."""
    fig, ax = new_figure(1, 1, width=7.0, height=3.2)
    a = ax[0, 0]
    for i, ln in enumerate(lines):
        color = FLAP_COLORS[i % len(FLAP_COLORS)]
        a.plot(ln["t"], ln["y"], lw=0.9, color=color, label=str(ln["id"]))
        ev = np.asarray(ln.get("events", []), dtype=float)
        if ev.size:
            a.plot(ev, np.interp(ev, ln["t"], ln["y"]), "v", color=color, ms=6)
    for s in (-1.0, 1.0):
        a.axhline(s * limit_deg, color="#b42318", lw=0.8, ls="--")
    a.axvline(0.0, color="#444", lw=0.8, ls=":")
    a.set_xlabel("time from stall identification [s]")
    a.set_ylabel("bank angle φ [deg]")
    a.set_title("wings-level stalls (▼: roll-off events detected)")
    if len(lines) <= 10:
        a.legend(loc="best", fontsize=6, frameon=False)
    return fig


def buffet_spectra(
    *, spectra: pl.DataFrame, peaks: pl.DataFrame, simulated: pl.DataFrame | None, tol_hz: float
) -> Figure:
    """Averaged buffet PSD per flap (normal and lateral accelerometer), the identified spikes
    (dots) and the simulator's frequencies with their ±``tol_hz`` band (shaded)."""
    flaps = sorted({float(f) for f in spectra["flap_deg"]})
    n = len(flaps)
    fig, ax = new_figure(1, n, width=min(2.3 * n + 1.0, 12.5), height=3.0, sharey=True)
    for k, flap in enumerate(flaps):
        a = ax[0, k]
        for axis, color in (("nz", "#1f77b4"), ("ny", "#ff7f0e")):
            s = spectra.filter((pl.col("flap_deg") == flap) & (pl.col("axis") == axis))
            if s.height == 0:
                continue
            f, p = s["freq_hz"].to_numpy(), s["psd_m2s4_hz"].to_numpy()
            keep = (f >= 2.0) & (f <= 22.0) & (p > 0)
            a.semilogy(f[keep], p[keep], color=color, lw=0.9, label=axis)
            pk = peaks.filter((pl.col("flap_deg") == flap) & (pl.col("axis") == axis))
            a.plot(pk["freq_hz"], pk["psd_m2s4_hz"], "o", color=color, ms=4)
        if simulated is not None:
            for fq in simulated.filter(pl.col("flap_deg") == flap)["freq_hz"].to_numpy():
                a.axvspan(fq - tol_hz, fq + tol_hz, color="#2ca02c", alpha=0.08, lw=0)
                a.axvline(fq, color="#2ca02c", lw=0.8, ls="--")
        a.set_title(f"flap {flap:g}")
        a.set_xlabel("frequency [Hz]")
    ax[0, 0].set_ylabel("PSD [(m/s²)²/Hz]")
    _legend(ax[0, 0], loc="best")
    return fig


def buffet_amplitude(*, amplitude: pl.DataFrame, onsets: Mapping[float, float]) -> Figure:
    """Band-passed (4-20 Hz) normal and lateral acceleration RMS against alpha per flap, with
    the median buffet-onset alpha of each flap (dashed)."""
    fig, ax = new_figure(1, 2, width=9.0, height=3.2, sharey=True)
    flaps = sorted({float(f) for f in amplitude["flap_deg"]})
    for i, flap in enumerate(flaps):
        color = FLAP_COLORS[i % len(FLAP_COLORS)]
        g = amplitude.filter((pl.col("flap_deg") == flap) & (pl.col("n_samples") >= 25))
        c = 0.5 * (g["alpha_lo_deg"].to_numpy() + g["alpha_hi_deg"].to_numpy())
        for a, col in ((ax[0, 0], "nz_rms_mps2"), (ax[0, 1], "ny_rms_mps2")):
            a.plot(c, g[col].to_numpy(), "-o", ms=2.5, lw=0.9, color=color, label=f"flap {flap:g}")
            on = onsets.get(flap)
            if on is not None:
                a.axvline(on, color=color, lw=0.7, ls="--")
    ax[0, 0].set_title("normal accelerometer")
    ax[0, 1].set_title("lateral accelerometer")
    for a in ax[0]:
        a.set_xlabel("α at the CG [deg]")
    ax[0, 0].set_ylabel("buffet RMS [m/s²]")
    _legend(ax[0, 0], loc="best")
    return fig


def validity(*, verdict: pl.DataFrame, coverage: pl.DataFrame) -> Figure:
    """Per flap: samples per alpha band (grey bars, log scale), the highest stall-
    identification alpha (dashed) and the alpha 10 deg beyond it (solid red) that the model must
    reach."""
    flaps = verdict["flap_deg"].to_list()
    n = len(flaps)
    fig, ax = new_figure(1, n, width=min(2.2 * n + 1.0, 12.5), height=3.2, sharey=True)
    for k, r in enumerate(verdict.iter_rows(named=True)):
        a = ax[0, k]
        c = coverage.filter(pl.col("flap_deg") == r["flap_deg"])
        lo, hi = c["alpha_lo_deg"].to_numpy(), c["alpha_hi_deg"].to_numpy()
        a.barh(lo, c["n_samples"].to_numpy(), height=hi - lo, align="edge", color="#bbb")
        a.set_xscale("log")
        if r["stall_id_alpha_deg"] is not None:
            a.axhline(r["stall_id_alpha_deg"], color="#444", ls="--", lw=0.9, label="stall id")
            a.axhline(r["required_deg"], color="#b42318", lw=1.2, label="stall id + 10")
        a.set_title(f"flap {r['flap_deg']:g}: {'covered' if r['covered'] else 'not covered'}")
        a.set_xlabel("samples per band")
    ax[0, 0].set_ylabel("α at the CG [deg]")
    _legend(ax[0, 0], loc="lower right")
    return fig


def envelope(
    *,
    points: Sequence[Mapping[str, Any]],
    outlines: Mapping[float, Sequence[tuple[np.ndarray, np.ndarray]]] | None,
) -> Figure:
    """α against β of every flight-test sample, one panel per flap (``flap``, ``kind``,
    ``beta``, ``alpha`` arrays per kind), coloured by maneuver kind; the model's validated
    envelope outlined (closed polygons ``(beta, alpha)``) when given."""
    flaps = sorted({float(p["flap"]) for p in points})
    n = len(flaps)
    ncol = min(n, 3)
    nrow = (n + ncol - 1) // ncol
    fig, ax = new_figure(nrow, ncol, width=3.2 * ncol + 0.6, height=3.0 * nrow)
    kinds: list[str] = []
    for k, flap in enumerate(flaps):
        a = ax[k // ncol, k % ncol]
        for p in points:
            if float(p["flap"]) != flap:
                continue
            kinds.append(str(p["kind"]))
            a.plot(p["beta"], p["alpha"], ",", color=_kind_color(str(p["kind"])), alpha=0.6,
                   rasterized=True)  # fmt: skip
        for b, al in (outlines or {}).get(flap, ()):
            a.plot(b, al, color="#222", lw=1.0)
        a.set_title(f"flap {flap:g}")
        a.set_xlabel("β [deg]")
        a.set_ylabel("α [deg]")
    for k in range(n, nrow * ncol):
        ax[k // ncol, k % ncol].set_visible(False)
    leg = ax[0, 0]
    for kd in dict.fromkeys(kinds):
        leg.plot([], [], "s", color=_kind_color(kd), label=kd, ms=5)
    if outlines:
        leg.plot([], [], color="#222", lw=1.0, label="validated envelope (model)")
    _legend(leg, loc="best")
    return fig


def entries(*, table: pl.DataFrame, power_on_ct: float) -> Figure:
    """Per identified stall: the bank angle and the thrust coefficient (sum over engines) at
    stall identification, coloured by maneuver kind, with the power-on threshold (dashed)."""
    fig, ax = new_figure(1, 1, width=6.5, height=3.2)
    a = ax[0, 0]
    kinds = table["kind"].to_list()
    phi = table["phi_id_deg"].to_numpy().astype(float)
    ct = table["ct_id"].to_numpy().astype(float)
    for kind in dict.fromkeys(kinds):
        m = np.array([k == kind for k in kinds])
        a.plot(phi[m], ct[m], "o", ms=5, color=_kind_color(kind), label=kind)
    a.axhline(power_on_ct, color="#b42318", lw=0.9, ls="--", label="power-on threshold")
    a.set_xlabel("bank angle at stall identification [deg]")
    a.set_ylabel("thrust coefficient C_T (sum) [-]")
    _legend(a, loc="best")
    return fig


def mach(*, table: pl.DataFrame, flaps: Sequence[float]) -> Figure:
    """Per identified stall: the Mach number at stall identification against the flap setting,
    coloured by maneuver kind."""
    fig, ax = new_figure(1, 1, width=6.5, height=3.2)
    a = ax[0, 0]
    x = _positions(table, flaps)
    kinds = table["kind"].to_list()
    m_id = table["mach_id"].to_numpy().astype(float)
    for kind in dict.fromkeys(kinds):
        k = np.array([c == kind for c in kinds])
        a.plot(x[k], m_id[k], "o", ms=5, color=_kind_color(kind), label=kind)
    _flap_axis(a, flaps)
    a.set_ylabel("Mach at stall identification [-]")
    _legend(a, loc="best")
    return fig


def lateral(*, panels: Sequence[Mapping[str, Any]]) -> Figure:
    """Fitted Δ parameters against alpha (one panel each: ``name``; per flap ``series`` with
    the model table ``grid``/``table`` and the per-bin ``c``, ``est``, ``lo``, ``hi`` 95 %
    intervals)."""
    n = len(panels)
    fig, ax = new_figure(1, n, width=min(2.6 * n + 0.8, 12.5), height=3.0)
    for k, pan in enumerate(panels):
        a = ax[0, k]
        for i, s in enumerate(pan["series"]):
            color = FLAP_COLORS[i % len(FLAP_COLORS)]
            a.plot(s["grid"], s["table"], color=color, lw=1.0, label=f"flap {s['flap']:g}")
            if len(s["c"]):
                est = np.asarray(s["est"])
                err = np.vstack([est - np.asarray(s["lo"]), np.asarray(s["hi"]) - est])
                a.errorbar(s["c"], est, yerr=err, fmt="o", ms=2.5, lw=0.7, color=color)
        a.axhline(0.0, color="#444", lw=0.6)
        # scale to the tables and the estimates: a wide interval past the stall runs off the
        # panel rather than flattening every curve
        vals = np.concatenate(
            [
                np.ravel(np.asarray(s[k], dtype=float))
                for s in pan["series"]
                for k in ("table", "est")
            ]
        )
        vals = vals[np.isfinite(vals)]
        if vals.size:
            lo, hi = float(vals.min()), float(vals.max())
            pad = 0.15 * (hi - lo) if hi > lo else max(abs(hi), 1e-6)
            a.set_ylim(lo - pad, hi + pad)
        a.set_title(str(pan["name"]))
        a.set_xlabel("α [deg]")
    _legend(ax[0, 0], loc="best")
    return fig


def longitudinal(*, panels: Sequence[Mapping[str, Any]]) -> Figure:
    """Measured (grey) and Kirchhoff-model (colour) C_L and C_m against alpha per fitted flap
    (``flap``, ``alpha``, ``cl``, ``cl_model``, ``cm``, ``cm_model``; every nth sample)."""
    fig, ax = new_figure(1, 2, width=9.0, height=3.2)
    for i, pan in enumerate(panels):
        color = FLAP_COLORS[i % len(FLAP_COLORS)]
        for a, meas, mod in ((ax[0, 0], "cl", "cl_model"), (ax[0, 1], "cm", "cm_model")):
            a.plot(pan["alpha"], pan[meas], ",", color="#999", rasterized=True)
            a.plot(pan["alpha"], pan[mod], ".", ms=1.0, color=color, label=f"flap {pan['flap']:g}",
                   rasterized=True)  # fmt: skip
    ax[0, 0].set_ylabel("C_L [-]")
    ax[0, 1].set_ylabel("C_m [-]")
    for a in ax[0]:
        a.set_xlabel("α [deg]")
    ax[0, 0].set_title("lift: measured (grey) and Kirchhoff model")
    ax[0, 1].set_title("pitching moment: measured (grey) and model")
    _legend(ax[0, 0], loc="best", markerscale=6)
    return fig


def prestall(*, panels: Sequence[Mapping[str, Any]]) -> Figure:
    """Per flap, one maneuver replayed open loop on the qualified and on the extended model
    (and on the model's stored stall without its lateral Δ, when it flies one): angle of
    attack and roll rate against time, the blend start ``alpha_l`` and the end of the
    bit-for-bit comparison marked (``panels``: ``flap``, ``id``, ``run`` frame of
    :func:`aerodelta.evidence.prestall.prestall_regression`, ``alpha_l``, ``t_end``)."""
    n = max(1, len(panels))
    fig, ax = new_figure(n, 2, width=8.0, height=2.0 * n + 0.6)
    for i, pn in enumerate(panels):
        run = pn["run"]
        t = run["t"].to_numpy()
        pairs = (
            ("alpha_qual_deg", "alpha_ext_deg", "α [deg]"),
            ("p_qual_dps", "p_ext_dps", "p [deg/s]"),
        )
        for j, (q, e, label) in enumerate(pairs):
            a = ax[i, j]
            a.plot(t, run[q].to_numpy(), color="#1f77b4", lw=1.6, label="qualified")
            stall = q.replace("qual", "stall")
            if stall in run.columns:  # the model's stored stall, without the lateral Δ
                a.plot(t, run[stall].to_numpy(), color="#9467bd", lw=1.1, ls=":",
                       label="stored stall, no lateral Δ")  # fmt: skip
            a.plot(t, run[e].to_numpy(), color="#d62728", lw=0.9, ls="--", label="extended")
            if j == 0:
                a.axhline(pn["alpha_l"], color="#444", lw=0.8, ls=":", label="blend start α_l")
            if pn["t_end"] is not None:
                a.axvline(pn["t_end"], color="#2ca02c", lw=0.8, label="end of comparison")
            a.set_ylabel(label)
            a.set_title(f"flap {pn['flap']:g}: {pn['id']}", fontsize=8)
            if i == n - 1:
                a.set_xlabel("time [s]")
            if i == 0:
                _legend(a, loc="best")
    return fig
