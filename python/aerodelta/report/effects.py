"""Section 4.2: effects of the extended aerodynamic database (thesis Figures 4.9-4.13):
stability and control derivatives against alpha per flap, qualified vs extended, with the
per-bin estimates and a 95 % confidence band."""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

import numpy as np
import polars as pl

from aerodelta.fit import qualified_coefficients
from aerodelta.plots import FigureSink, figures
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


#: One derivative to evaluate: (coefficient, channel, perturbation, flap [deg], alpha [deg]).
DerivativeSpec = tuple[str, str, float, float, np.ndarray]


def _grid_frame(ctx: ReportContext, specs: Sequence[DerivativeSpec]) -> pl.DataFrame:
    """Inputs of every spec at +h then -h, one block of rows each (zero other inputs)."""
    sizes = [2 * s[4].size for s in specs]
    n = sum(sizes)
    names = dict.fromkeys((*_QUAL_INPUTS, *ctx.model.input_columns, *(s[1] for s in specs)))
    cols = {c: np.zeros(n) for c in names}
    cols["tas_mps"] = np.full(n, 60.0)
    i = 0
    for (_, channel, h, flap, alpha), m in zip(specs, sizes, strict=True):
        k = m // 2
        cols["alpha_deg"][i : i + m] = np.concatenate([alpha, alpha])
        cols["flap_deg"][i : i + m] = flap
        cols[channel][i : i + k] = h
        cols[channel][i + k : i + m] = -h
        i += m
    return pl.DataFrame(cols)


def derivatives(
    ctx: ReportContext, specs: Sequence[DerivativeSpec]
) -> list[tuple[np.ndarray | None, np.ndarray]]:
    """:func:`derivative` of each spec, with one evaluation of the models for all of them
    (the models are evaluated row by row, so the batch changes no value)."""
    if not specs:
        return []
    f = _grid_frame(ctx, specs)
    ev = ctx.model.evaluate(f, coefficients=sorted({s[0] for s in specs}))
    q = qualified_coefficients(f, "adx37") if ctx.qualified == "adx37" else None
    out: list[tuple[np.ndarray | None, np.ndarray]] = []
    i = 0
    for coef, _, h, _, alpha in specs:
        k = alpha.size
        d = ev[f"d{coef}_blended"].to_numpy()[i : i + 2 * k]
        dd = (d[:k] - d[k:]) / (2 * h)
        dq = None
        if q is not None:
            qv = q[f"{coef}_qual"].to_numpy()[i : i + 2 * k]
            dq = (qv[:k] - qv[k:]) / (2 * h)
        out.append((dq, dd))
        i += 2 * k
    return out


def derivative(
    ctx: ReportContext, coef: str, channel: str, h: float, *, flap: float, alpha: np.ndarray
) -> tuple[np.ndarray | None, np.ndarray]:
    """Qualified (``None`` when the qualified model is only given as record columns) and Δ
    (blended) derivative of ``coef`` with respect to ``channel`` along ``alpha`` [deg] at
    ``flap`` [deg]: the central difference ``(C(+h) - C(-h)) / 2h`` (per unit of ``channel``)
    at zero other inputs and 60 m/s."""
    return derivatives(ctx, [(coef, channel, h, flap, np.asarray(alpha, dtype=float))])[0]


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


def _bin_marks(ctx: ReportContext, spec: DerivativeSpec, base: np.ndarray) -> dict[str, Any] | None:
    """The per-bin estimates of a derivative on the qualified value ``base`` along its alpha:
    identified bins with 95 % half-widths, the others, and the half-width of the band along
    ``alpha`` (drawn around the extended curve)."""
    coef, channel, h, flap, alpha = spec
    bins = _bins(ctx, coef, channel, flap)
    if bins is None:
        return None
    gain = _regressor_gain(str(bins["regressor"][0]), channel, h)
    if gain is None or gain <= 0:
        return None
    c = 0.5 * (bins["alpha_lo_deg"].to_numpy() + bins["alpha_hi_deg"].to_numpy())
    est = gain * bins["estimate"].to_numpy()
    # 95 % interval: cluster-robust (CR2) error with Bell-McCaffrey t
    half = gain * (bins["ci95_upper"].to_numpy() - bins["estimate"].to_numpy())
    ok = bins["identifiable"].to_numpy() & np.isfinite(half)
    qb = np.interp(c, alpha, base)
    band = inside = None
    if ok.sum() >= 2:
        inside = (alpha >= c[ok].min()) & (alpha <= c[ok].max())
        band = np.interp(alpha, c[ok], half[ok])
    return {
        "c": c[ok],
        "y": qb[ok] + est[ok],
        "half": half[ok],
        "c_bad": c[~ok],
        "y_bad": qb[~ok],
        "band": band,
        "inside": inside,
    }


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
    effects = [e for e in EFFECTS if e[1] in ctx.coefficients]
    grids = {}
    for flap in flaps:
        stall = ctx.stall_alpha_deg.get(flap)
        grids[flap] = np.linspace(-2.0, (stall + 12.0) if stall is not None else 30.0, 121)
    specs = [(coef, ch, h, flap, grids[flap]) for _, coef, ch, h, _ in effects for flap in flaps]
    values = iter(derivatives(ctx, specs))
    rows = []
    for name, coef, channel, h, unit in effects:
        panels = []
        for flap in flaps:
            stall = ctx.stall_alpha_deg.get(flap)
            alpha = grids[flap]
            hi = alpha[-1]
            dq, dd = next(values)
            base = dq if dq is not None else np.zeros_like(alpha)
            ext = base + dd
            panels.append(
                {
                    "flap": flap,
                    "alpha": alpha,
                    "dq": dq,
                    "ext": ext,
                    "stall": stall,
                    "bins": _bin_marks(ctx, (coef, channel, h, flap, alpha), base),
                }
            )
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
        sec.body.append(f"<h3>{name}</h3>")
        sec.body.append(
            sink.plot(
                figures.effect,
                f"effect_{name}",
                f"{name} against alpha per flap, qualified vs extended (cf. thesis Figures "
                "4.9-4.13).",
                panels=panels,
                ylabel=f"{name} [{unit}]",
                ext_label="extended" if ctx.qualified == "adx37" else "Δ (blended)",
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
