"""Simulator validation envelope: where in alpha and beta, per flap, the extended model is
backed by flight data and with what confidence (high / moderate / low), as 14 CFR Part 60
(FSTD qualification, stall-model evaluation) asks the model's validity range to be declared.

Confidence rule (per 1 deg × 1 deg alpha-beta cell; documented in ``docs/report.md``):

- **high**: at least ``HIGH_SAMPLES`` samples from at least ``HIGH_MANEUVERS`` maneuvers, and
  at least ``HIGH_IDENTIFIED`` of the Δ-model parameters identified in the alpha bin(s) of the
  cell (pooled over Cl, Cn, CY);
- **moderate**: at least ``MODERATE_SAMPLES`` samples from at least ``MODERATE_MANEUVERS``
  maneuvers and ``MODERATE_IDENTIFIED`` of the parameters identified;
- **low**: some flight data in the cell, but less than the above (or past the end of the
  model's tables, 10 deg beyond stall, where the tables are held);
- **none**: no flight data: the model there is an extrapolation.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from aerodelta.plots import FigureSink, figures
from aerodelta.report.context import ReportContext
from aerodelta.report.html import Section, p, table

HIGH_SAMPLES, HIGH_MANEUVERS, HIGH_IDENTIFIED = 50, 3, 0.7
MODERATE_SAMPLES, MODERATE_MANEUVERS, MODERATE_IDENTIFIED = 10, 2, 0.4
LEVELS = ("none", "low", "moderate", "high")
BETA_LIMIT_DEG = 15.0


def identified_by_alpha(params: pl.DataFrame | None, flap: float, alpha: np.ndarray) -> np.ndarray:
    """Share of Δ parameters identified at each alpha (deg), pooled over the coefficients:
    every coefficient contributes the parameters of its own fit bin containing that alpha
    (the coefficients' bins need not share edges). NaN where no coefficient has a bin.

    Counts are summed, so the result does not depend on the row order of ``params``.
    """
    out = np.full(alpha.shape, np.nan)
    if params is None:
        return out
    g = (
        params.filter(pl.col("flap_deg") == flap)
        .group_by(["coefficient", "alpha_lo_deg", "alpha_hi_deg"])
        .agg(
            pl.col("identifiable").cast(pl.Float64).sum().alias("ident"),
            pl.col("identifiable").count().cast(pl.Float64).alias("total"),
        )
    )
    if g.height == 0:
        return out
    lo = g["alpha_lo_deg"].to_numpy()[:, None]
    hi = g["alpha_hi_deg"].to_numpy()[:, None]
    inside = ((alpha[None, :] >= lo) & (alpha[None, :] < hi)).astype(float)
    total = g["total"].to_numpy() @ inside
    ident = g["ident"].to_numpy() @ inside
    has = total > 0
    out[has] = ident[has] / total[has]
    return out


def classify(
    n: np.ndarray, maneuvers: np.ndarray, identified: np.ndarray, beyond_tables: np.ndarray
) -> np.ndarray:
    """Confidence level index into :data:`LEVELS` per cell (see the module docstring).

    A NaN ``identified`` (no per-bin estimates) counts as fully identified, so the level then
    rests on data density alone.
    """
    f = np.where(np.isfinite(identified), identified, 1.0)
    lvl = np.where(n > 0, 1, 0)
    mod = (n >= MODERATE_SAMPLES) & (maneuvers >= MODERATE_MANEUVERS) & (f >= MODERATE_IDENTIFIED)
    high = (n >= HIGH_SAMPLES) & (maneuvers >= HIGH_MANEUVERS) & (f >= HIGH_IDENTIFIED)
    lvl = np.where(mod & ~beyond_tables, 2, lvl)
    lvl = np.where(high & ~beyond_tables, 3, lvl)
    return lvl


def coverage(ctx: ReportContext, flap: float) -> tuple[np.ndarray, np.ndarray, pl.DataFrame]:
    """Alpha and beta cell edges (deg) and one row per cell: counts and confidence level."""
    d = (
        ctx.data.filter(pl.col("flap_deg") == flap)
        .select("alpha_deg", "beta_deg", "maneuver_id")
        .drop_nans()
    )
    a = d["alpha_deg"].to_numpy()
    a_edges = np.arange(
        np.floor(a.min()) if a.size else 0.0, (np.ceil(a.max()) if a.size else 1.0) + 1.0, 1.0
    )
    b_edges = np.arange(-BETA_LIMIT_DEG, BETA_LIMIT_DEG + 1.0, 1.0)
    cells = (
        d.with_columns(
            ((pl.col("alpha_deg") - a_edges[0]).floor()).cast(pl.Int64).alias("i"),
            ((pl.col("beta_deg") - b_edges[0]).floor()).cast(pl.Int64).alias("j"),
        )
        .filter((pl.col("j") >= 0) & (pl.col("j") < len(b_edges) - 1))
        .group_by(["i", "j"])
        .agg(pl.len().alias("n"), pl.col("maneuver_id").n_unique().alias("maneuvers"))
    )
    na, nb = len(a_edges) - 1, len(b_edges) - 1
    ii, jj = np.meshgrid(np.arange(na), np.arange(nb), indexing="ij")
    n = np.zeros((na, nb))
    m = np.zeros((na, nb))
    n[cells["i"].to_numpy(), cells["j"].to_numpy()] = cells["n"].to_numpy()
    m[cells["i"].to_numpy(), cells["j"].to_numpy()] = cells["maneuvers"].to_numpy()
    ac = 0.5 * (a_edges[:-1] + a_edges[1:])
    ident = identified_by_alpha(ctx.params, flap, ac)[:, None] * np.ones((1, nb))
    stall = ctx.stall_alpha_deg.get(flap)
    beyond = (ac > stall + 10.0) if stall is not None else np.zeros(na, dtype=bool)
    lvl = classify(n, m, ident, beyond[:, None] * np.ones((1, nb), dtype=bool))
    frame = pl.DataFrame(
        {
            "alpha_lo_deg": a_edges[ii.ravel()],
            "beta_lo_deg": b_edges[jj.ravel()],
            "n": n.ravel().astype(np.int64),
            "maneuvers": m.ravel().astype(np.int64),
            "identified": ident.ravel(),
            "level": [LEVELS[k] for k in lvl.ravel()],
        }
    )
    return a_edges, b_edges, frame


def section(ctx: ReportContext, sink: FigureSink) -> Section:
    """Build the validation-envelope section."""
    sec = Section("envelope", "Simulator validation envelope")
    sec.body.append(
        p(
            "Where the extended model is backed by flight data, per flap, in 1 deg "
            "× 1 deg cells of "
            "alpha and beta (14 CFR Part 60 asks a stall model to declare its validated range). "
            f"<b>High</b>: ≥ {HIGH_SAMPLES} samples from ≥ {HIGH_MANEUVERS} maneuvers and ≥ "
            f"{HIGH_IDENTIFIED:.0%} of the Δ parameters identified in that alpha bin; "
            f"<b>moderate</b>: ≥ {MODERATE_SAMPLES} samples, ≥ {MODERATE_MANEUVERS} maneuvers, ≥ "
            f"{MODERATE_IDENTIFIED:.0%} identified; <b>low</b>: any data (or past the end of the "
            "tables, 10 deg beyond stall); <b>none</b>: no data, the model is extrapolated there."
        )
    )
    flaps = ctx.flaps
    rows = []
    panels = []
    for flap in flaps:
        a_edges, b_edges, cells = coverage(ctx, flap)
        lvl = np.array([LEVELS.index(x) for x in cells["level"]]).reshape(
            len(a_edges) - 1, len(b_edges) - 1
        )
        stall = ctx.stall_alpha_deg.get(flap)
        panels.append(
            {"flap": flap, "a_edges": a_edges, "b_edges": b_edges, "level": lvl, "stall": stall}
        )
        hi = cells.filter(pl.col("level") == "high")
        row = {"flap_deg": flap}
        for lev in LEVELS[1:]:
            row[f"cells_{lev}"] = int((cells["level"] == lev).sum())
        row["alpha_max_high_deg"] = (
            float(hi["alpha_lo_deg"].max()) + 1.0 if hi.height else float("nan")  # type: ignore[operator]
        )
        dat = cells.filter(pl.col("n") > 0)
        row["alpha_max_data_deg"] = (
            float(dat["alpha_lo_deg"].max()) + 1.0 if dat.height else float("nan")
        )  # type: ignore[operator]
        row["stall_alpha_deg"] = stall if stall is not None else float("nan")
        rows.append(row)
    sec.body.append(
        sink.plot(
            figures.envelope,
            "envelope",
            "Validation envelope per flap: confidence of the extended model in "
            "each alpha-beta cell "
            "(grey: no data; orange: low; light blue: moderate; dark blue: high); dashed: stall.",
            panels=panels,
            levels=list(LEVELS),
        )
    )
    t = pl.DataFrame(rows)
    sec.body.append(table(t))
    sec.tables["envelope"] = t
    best = t["alpha_max_high_deg"].drop_nans()
    if best.len():
        sec.summary.append(
            (
                "high-confidence alpha reach",
                " · ".join(
                    f"flap {r['flap_deg']:g}: {r['alpha_max_high_deg']:.0f}°"
                    for r in t.iter_rows(named=True)
                ),
            )
        )
    return sec
