"""Section 4.2: effects of the extended aerodynamic database (thesis Figures 4.9-4.13):
stability and control derivatives against alpha per flap, qualified vs extended, with the
per-bin estimates and a 95 % confidence band."""

from __future__ import annotations

import re

import numpy as np
import polars as pl

from aerodelta.fit import qualified_coefficients
from aerodelta.plots import COLORS, FigureSink, new_figure
from aerodelta.report.context import ReportContext
from aerodelta.report.html import Section, p, table

#: (name, coefficient, channel, perturbation, unit) of each effect plot. The derivative is the
#: central difference ``(C(+h) - C(-h)) / 2h`` at zero other inputs; the aileron uses ±5 deg
#: (outside the ±2 deg dead band of Eq. 3.15-3.16), as the thesis plots Figure 4.10.
EFFECTS: tuple[tuple[str, str, str, float, str], ...] = (
    ("Cl_beta", "Cl", "beta_deg", 1.0, "1/deg"),
    ("Cl_da", "Cl", "da_deg", 5.0, "1/deg (±5 deg)"),
    ("Cl_p", "Cl", "phat", 0.01, "1/rad (p̂)"),
    ("Cn_beta", "Cn", "beta_deg", 1.0, "1/deg"),
    ("Cn_dr", "Cn", "dr_deg", 5.0, "1/deg (±5 deg)"),
    ("CY_beta", "CY", "beta_deg", 1.0, "1/deg"),
)

_QUAL_INPUTS = (
    "alpha_deg",
    "beta_deg",
    "phat",
    "qhat",
    "rhat",
    "alphadot_dps",
    "betadot_dps",
    "da_deg",
    "de_deg",
    "dr_deg",
    "dsl_deg",
    "dsr_deg",
    "ct_left",
    "ct_right",
    "ds_deg",
    "ct_diff",
)


def _grid_frame(
    ctx: ReportContext, flap: float, alpha: np.ndarray, channel: str, value: float
) -> pl.DataFrame:
    cols = {c: np.zeros_like(alpha) for c in (*_QUAL_INPUTS, *ctx.model.input_columns)}
    cols["alpha_deg"] = alpha
    cols["flap_deg"] = np.full_like(alpha, flap)
    cols["tas_mps"] = np.full_like(alpha, 60.0)
    cols[channel] = np.full_like(alpha, value)
    return pl.DataFrame(cols)


def derivative(
    ctx: ReportContext, coef: str, channel: str, h: float, *, flap: float, alpha: np.ndarray
) -> tuple[np.ndarray | None, np.ndarray]:
    """Qualified (``None`` when the qualified model is only given as record columns) and Δ
    (blended) derivative of ``coef`` with respect to ``channel`` along ``alpha`` at ``flap``."""
    out = []
    for sign in (1.0, -1.0):
        f = _grid_frame(ctx, flap, alpha, channel, sign * h)
        d = ctx.model.evaluate(f, coefficients=[coef])[f"d{coef}_blended"].to_numpy()
        q = (
            qualified_coefficients(f, "adx37")[f"{coef}_qual"].to_numpy()
            if ctx.qualified == "adx37"
            else None
        )
        out.append((q, d))
    (qp, dp), (qm, dm) = out
    dq = None if qp is None or qm is None else (qp - qm) / (2 * h)
    return dq, (dp - dm) / (2 * h)


def _regressor_gain(regressor: str, channel: str, h: float) -> float | None:
    """d(regressor)/d(channel) over ±h for the regressors of a single channel, else ``None``."""
    if regressor.strip() == channel:
        return 1.0
    m = re.fullmatch(rf"\s*deadband\(\s*{re.escape(channel)}\s*,\s*([0-9.]+)\s*\)\s*", regressor)
    if m:
        return max(h - float(m.group(1)), 0.0) / h
    return None


def _bins(ctx: ReportContext, coef: str, channel: str, flap: float) -> pl.DataFrame | None:
    if ctx.params is None:
        return None
    g = ctx.params.filter(
        (pl.col("coefficient") == coef)
        & (pl.col("flap_deg") == flap)
        & pl.col("regressor").str.contains(channel, literal=True)
    )
    return g if g.height else None


def section(ctx: ReportContext, sink: FigureSink) -> Section:
    """Build the effect-plot section."""
    sec = Section("effects", "4.2 Effects of the extended database")
    sec.body.append(
        p(
            "Each derivative is the central difference of the coefficient with "
            "respect to one input "
            "at zero sideslip, rates and controls, along alpha, for each flap "
            "setting: the qualified "
            "model (red), the extended model qualified + <i>w</i>(α) ΔC (blue), the per-bin "
            "least-squares estimates added to the qualified value (dots: identified, with 95 % "
            "error bars from the coloured-residual standard errors; crosses: not identified) and a "
            "95 % band around the extended curve from the bin standard errors interpolated in "
            "alpha (an approximation of the smoothing spline's band). Dashed: stall alpha."
            + (
                ""
                if ctx.qualified == "adx37"
                else " The qualified model is given only as record columns here, so only the Δ "
                "derivative is drawn."
            )
        )
    )
    flaps = ctx.flaps
    rows = []
    for name, coef, channel, h, unit in EFFECTS:
        if coef not in ctx.coefficients:
            continue
        fig, ax = new_figure(
            1, len(flaps), width=min(2.3 * len(flaps) + 0.6, 12.0), height=2.6, sharey=True
        )
        for k, flap in enumerate(flaps):
            a = ax[0, k]
            stall = ctx.stall_alpha_deg.get(flap)
            hi = (stall + 12.0) if stall is not None else 30.0
            alpha = np.linspace(-2.0, hi, 121)
            dq, dd = derivative(ctx, coef, channel, h, flap=flap, alpha=alpha)
            base = dq if dq is not None else np.zeros_like(alpha)
            ext = base + dd
            if dq is not None:
                a.plot(alpha, dq, color=COLORS["qual"], lw=1.1, label="qualified")
            a.plot(
                alpha,
                ext,
                color=COLORS["ext"],
                lw=1.4,
                label="extended" if dq is not None else "Δ (blended)",
            )
            bins = _bins(ctx, coef, channel, flap)
            if bins is not None:
                gain = _regressor_gain(str(bins["regressor"][0]), channel, h)
                if gain is not None and gain > 0:
                    c = 0.5 * (bins["alpha_lo_deg"].to_numpy() + bins["alpha_hi_deg"].to_numpy())
                    est = gain * bins["estimate"].to_numpy()
                    # 95 % interval: cluster-robust (CR2) error with Bell-McCaffrey t
                    half = gain * (bins["ci95_upper"].to_numpy() - bins["estimate"].to_numpy())
                    ok = bins["identifiable"].to_numpy() & np.isfinite(half)
                    qb = np.interp(c, alpha, base)
                    a.errorbar(
                        c[ok],
                        qb[ok] + est[ok],
                        yerr=half[ok],
                        fmt="o",
                        ms=2.5,
                        color="#444",
                        elinewidth=0.6,
                        capsize=0,
                        label="bins",
                    )
                    if (~ok).any():
                        a.plot(c[~ok], qb[~ok], "x", color="#999", ms=4, label="not identified")
                    if ok.sum() >= 2:
                        inside = (alpha >= c[ok].min()) & (alpha <= c[ok].max())
                        band = np.interp(alpha, c[ok], half[ok])
                        a.fill_between(
                            alpha,
                            ext - band,
                            ext + band,
                            where=inside,
                            color=COLORS["band"],
                            alpha=0.5,
                            lw=0,
                            label="95 % band",
                        )
            if stall is not None:
                a.axvline(stall, color="#777", ls="--", lw=0.8)
            a.set_title(f"flap {flap:g}")
            a.set_xlabel("α [deg]")
            sel = alpha <= (stall + 10.0 if stall is not None else hi)
            i = int(np.argmax(sel * alpha))
            rows.append(
                {
                    "effect": name,
                    "flap_deg": flap,
                    "qualified_at_max": float(dq[i]) if dq is not None else float("nan"),
                    "extended_at_max": float(ext[i]),
                    "alpha_deg": float(alpha[i]),
                }
            )
        ax[0, 0].set_ylabel(f"{name} [{unit}]")
        ax[0, 0].legend(loc="best", fontsize=6.5)
        sec.body.append(f"<h3>{name}</h3>")
        sec.body.append(
            sink.add(
                fig,
                f"effect_{name}",
                f"{name} against alpha per flap, qualified vs extended (cf. thesis Figures "
                "4.9-4.13).",
            )
        )
    if rows:
        t = pl.DataFrame(rows)
        sec.body.append("<h3>Value 10 deg past stall (end of the tables)</h3>")
        sec.body.append(table(t))
        sec.tables["derivatives"] = t
        sec.summary.append(
            ("derivatives plotted", f"{t['effect'].n_unique()} × {len(flaps)} flaps")
        )
    return sec
