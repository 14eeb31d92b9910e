"""Aggregate task summaries into a study's tables and recommendation (no Dask here).

Per coefficient, flap, parameter and alpha range: the predicted standard error (the spread of
the estimates over the campaigns), the bootstrap standard error and band width the fits
report, the probability of being identified, and the band width against the largest expected
|Δ|; per effect, the probability the diagnosis names
it. The recommendation is derived from these numbers only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import polars as pl

from aerodelta._groups import group_agg
from aerodelta.plan.matrix import Matrix

KEYS: tuple[str, ...] = (
    "coefficient",
    "flap_deg",
    "param",
    "regressor",
    "alpha_lo_deg",
    "alpha_hi_deg",
)

_PARAM_SCHEMA: dict[str, Any] = {
    "seed": pl.Int64,
    "coefficient": pl.String,
    "flap_deg": pl.Float64,
    "param": pl.String,
    "regressor": pl.String,
    "alpha_lo_deg": pl.Float64,
    "alpha_hi_deg": pl.Float64,
    "kept": pl.Boolean,
    "identified": pl.Boolean,
    "bins": pl.Int64,
    "estimate": pl.Float64,
    "se": pl.Float64,
    "band": pl.Float64,
    "truth": pl.Float64,
    "truth_max": pl.Float64,
}
#: Largest multiple of a flap's maneuvers the recommendation proposes; beyond it a miss is
#: reported as not fixable by the count alone.
MAX_FACTOR = 4.0

_COVERAGE_SCHEMA: dict[str, Any] = {
    "seed": pl.Int64,
    "flap_deg": pl.Float64,
    "kind": pl.String,
    "maneuvers": pl.Int64,
    "alpha_lo_deg": pl.Float64,
    "alpha_hi_deg": pl.Float64,
    "samples": pl.Int64,
}


def _rows(tasks: Sequence[Mapping[str, Any]], field: str) -> list[dict[str, Any]]:
    return [{"seed": t["seed"], **r} for t in tasks for r in t[field]]


def param_table(tasks: Sequence[Mapping[str, Any]], matrix: Matrix) -> pl.DataFrame:
    """The study's per-parameter table (one row per coefficient, flap, parameter, alpha range).

    Parameters
    ----------
    tasks
        Task summaries (:func:`aerodelta.plan.task.run_task`), in seed order.
    matrix
        The matrix (targets).

    Returns
    -------
    polars.DataFrame
        Key columns, ``campaigns`` (campaigns whose fit has the parameter), ``p_identified``,
        ``se_predicted`` (the standard deviation of the estimates over the campaigns where
        identified: the standard error of one campaign's estimate, by Monte Carlo; parameter
        unit), ``se_bootstrap`` (root mean square of the bootstrap standard errors the fits
        reported where identified), ``estimate_mean``, ``bias`` (``estimate_mean - truth``),
        ``band_width`` (median bootstrap band width where identified, parameter unit),
        ``truth`` (expected Δ, mean over the range), ``truth_max`` (largest expected |Δ| of
        the parameter at the flap), ``band_relative`` (``band_width / truth_max``; null without
        an expected Δ) and ``meets_target`` (null without an expected Δ).
    """
    n = len(tasks)
    d = pl.DataFrame(_rows(tasks, "params"), schema=_PARAM_SCHEMA)
    ok = pl.col("identified")
    t = matrix.relative_band_width
    # float sums in row order (_groups: a polars group-by splits them over the thread pool);
    # a filter(ok) inside the group is a null outside it (nulls are left out)
    out = (
        group_agg(
            d.with_columns(
                pl.when(ok).then(pl.col("estimate")).alias("_est"),
                pl.when(ok).then(pl.col("se").pow(2)).alias("_se2"),
            ),
            KEYS,
            {
                "se_predicted": ("_est", "std"),
                "se_bootstrap": ("_se2", "mean"),
                "estimate_mean": ("_est", "mean"),
            },
            exact=[
                pl.len().alias("campaigns"),
                (ok.sum() / max(n, 1)).alias("p_identified"),
                pl.col("band").filter(ok).median().alias("band_width"),
                pl.col("truth").first(),
                pl.col("truth_max").first(),
            ],
        )
        .select(
            *KEYS,
            "campaigns",
            "p_identified",
            "se_predicted",
            pl.col("se_bootstrap").sqrt(),
            "estimate_mean",
            "band_width",
            "truth",
            "truth_max",
        )
        .with_columns(
            (pl.col("estimate_mean") - pl.col("truth")).alias("bias"),
            pl.when(pl.col("truth_max") > 0)
            .then(pl.col("band_width") / pl.col("truth_max"))
            .alias("band_relative"),
        )
        .with_columns(
            pl.when(pl.col("truth_max") > 0)
            .then(
                (pl.col("band_relative") <= t).fill_null(False)
                & (pl.col("p_identified") >= matrix.identified_probability)
            )
            .alias("meets_target")
        )
        .sort(KEYS)
    )
    return out


def effect_table(tasks: Sequence[Mapping[str, Any]]) -> pl.DataFrame:
    """Per expected effect: campaigns diagnosed and the probability the diagnosis names it."""
    rows = [
        {"seed": t["seed"], "effect": e, "named": bool(v)}
        for t in tasks
        for e, v in t["effects"].items()
    ]
    d = pl.DataFrame(rows, schema={"seed": pl.Int64, "effect": pl.String, "named": pl.Boolean})
    return (
        d.group_by("effect")
        .agg(pl.len().alias("campaigns"), pl.col("named").mean().alias("p_named"))
        .sort("effect")
    )


def coverage_table(tasks: Sequence[Mapping[str, Any]]) -> pl.DataFrame:
    """Per flap, kind and alpha range: mean samples per maneuver over the campaigns (what one
    more maneuver of that kind adds there) and the maneuvers flown."""
    d = pl.DataFrame(_rows(tasks, "coverage"), schema=_COVERAGE_SCHEMA)
    keys = ["flap_deg", "kind", "alpha_lo_deg", "alpha_hi_deg"]
    return group_agg(
        d.with_columns((pl.col("samples") / pl.col("maneuvers")).alias("_spm")),
        keys,
        {"samples_per_maneuver": ("_spm", "mean")},  # summed in row order (_groups)
        exact=[pl.col("maneuvers").first()],
    ).sort(keys)


def _label(param: str, regressor: str) -> str:
    return f"{param} ({regressor})"


def recommendation(
    matrix: Matrix,
    params: pl.DataFrame,
    effects: pl.DataFrame,
    coverage: pl.DataFrame,
    n_campaigns: int,
) -> str:
    """The recommendation text, derived from the study's tables.

    For every parameter with an expected Δ that misses a target (band wider than
    ``relative_band_width`` of its largest expected |Δ|, or identified in fewer than
    ``identified_probability`` of the campaigns), per flap: the misses, how many maneuvers the
    flap would need and of which kind. Heuristic, stated as such: the band width scales as
    1/√(maneuvers at the flap) (the fit is per flap and the bootstrap resamples maneuvers), and
    the kind to add is the one that put the most samples per maneuver in the missed alpha
    ranges in this study. Misses needing more than :data:`MAX_FACTOR` times the flap's
    maneuvers are reported as not fixable by the count alone.
    """
    t, p_t = matrix.relative_band_width, matrix.identified_probability
    lines = [
        f"{matrix.name}: {n_campaigns} campaigns of {matrix.n_maneuvers()} maneuvers; targets: "
        f"band <= {t:.0%} of the largest expected |Δ|, identified in >= {p_t:.0%} of campaigns"
    ]
    miss = params.filter(pl.col("meets_target").not_())
    if n_campaigns == 0:
        lines.append("No campaign finished: nothing to recommend (see the failures).")
    elif params.filter(pl.col("meets_target").is_not_null()).height == 0:
        lines.append("No parameter has an expected Δ (no effect in [effects]): no band target.")
    elif miss.height == 0:
        lines.append(
            "Every parameter with an expected Δ meets both targets in every alpha range reported."
        )
    counts = {f.flap_deg: f.counts for f in matrix.flaps}
    order = (
        miss.group_by("flap_deg")
        .agg(pl.len().alias("k"))
        .sort(["k", "flap_deg"], descending=[True, False])
    )
    for flap, k in order.iter_rows():
        m = miss.filter(pl.col("flap_deg") == flap).sort(
            "band_relative", descending=True, nulls_last=True
        )
        n_flap = sum(counts.get(flap, {}).values())
        lines.append(
            f"flap {flap:g}: {k} parameter/alpha ranges miss a target ({n_flap} maneuvers flown)"
        )
        for r in m.head(6).iter_rows(named=True):
            if r["band_relative"] is not None:
                band = f"band {r['band_relative']:.0%} of its largest expected |Δ|"
            elif not r["p_identified"]:
                band = "no band (never identified)"
            else:  # identified, but the replicates could not smooth it (fit notes)
                band = "no band (too few maneuvers for the bootstrap to smooth it)"
            lines.append(
                f"  {r['coefficient']} {_label(r['param'], r['regressor'])}, alpha "
                f"{r['alpha_lo_deg']:g}-{r['alpha_hi_deg']:g} deg: {band}, identified in "
                f"{r['p_identified']:.0%} of campaigns"
            )
        if m.height > 6:
            lines.append(f"  ... and {m.height - 6} more (params.csv, meets_target = false)")
        if n_flap == 0:
            lines.append(f"  -> flap {flap:g} flew no maneuver; add some")
            continue
        # maneuvers each miss needs (identification-only misses: twice the flap's, assumed)
        need = m.with_columns(
            pl.when(pl.col("band_relative").is_not_null())
            .then((pl.col("band_relative") / t).pow(2) * n_flap)
            .otherwise(2.0 * n_flap)
            .ceil()
            .cast(pl.Int64)
            .alias("need")
        )
        fix = need.filter(pl.col("need") <= MAX_FACTOR * n_flap)
        hard = need.filter(pl.col("need") > MAX_FACTOR * n_flap)
        if fix.height:
            ranges = fix.select("alpha_lo_deg", "alpha_hi_deg").unique()
            # summed in a fixed row order (_groups; the join's row order is not promised)
            per_kind = group_agg(
                coverage.filter(pl.col("flap_deg") == flap)
                .join(ranges, on=["alpha_lo_deg", "alpha_hi_deg"], how="inner")
                .sort("kind", "alpha_lo_deg", "alpha_hi_deg"),
                ["kind"],
                {"samples_per_maneuver": ("samples_per_maneuver", "sum")},
            ).sort(["samples_per_maneuver", "kind"], descending=[True, False])
            n_need = int(fix["need"].max())  # type: ignore[arg-type]
            what = f"{fix.height} of these"
            if per_kind.height:
                best, spm = per_kind.row(0)
                nxt = (
                    f", against {per_kind.row(1)[1]:.0f} for {per_kind.row(1)[0]}"
                    if per_kind.height > 1
                    else ""
                )
                how = (
                    f"as {best} stalls: they put the most samples in those alpha ranges "
                    f"({spm:.0f} per maneuver{nxt})"
                )
            else:
                how = "as stalls reaching those alpha ranges (none flown reached them)"
            lines.append(
                f"  -> raise flap {flap:g} from {n_flap} to about {n_need} maneuvers "
                f"(+{n_need - n_flap}) for {what}, {how}. Heuristic: band width ∝ "
                "1/√(maneuvers at the flap), so a band r times the target needs r² times the "
                "maneuvers; an identification miss alone is given twice the maneuvers."
            )
            unflown = [k for k in matrix.kinds() if counts.get(flap, {}).get(k, 0) == 0]
            if unflown:
                lines.append(
                    f"     (kinds not flown at this flap, so not measured: {', '.join(unflown)})"
                )
        if hard.height:
            worst = hard.sort("need", descending=True).row(0, named=True)
            lines.append(
                f"  -> {hard.height} of these need more than {MAX_FACTOR:g}x the flap's "
                f"maneuvers (up to {worst['need']} for {worst['param']} at alpha "
                f"{worst['alpha_lo_deg']:g}-{worst['alpha_hi_deg']:g} deg): count alone will not "
                "get there; raise the excitation, or accept the wider band there"
            )
    low = effects.filter(pl.col("p_named") < matrix.named_probability)
    for e, camps, p in low.iter_rows():
        lines.append(
            f"the diagnosis names {e} in {p:.0%} of {camps} campaigns (target "
            f"{matrix.named_probability:.0%})"
        )
    return "\n".join(lines) + "\n"
