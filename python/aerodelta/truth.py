"""The virtual aircraft's true Δ parameters, to check an identification against them.

The truth aircraft adds effects ``ΔC = m · g(alpha) · k_flap · C_design · regressor`` to the
qualified model (``docs/aircraft.md``, ``aero_core::aircraft::effects``). This module turns
the effect library and a campaign's magnitudes into the Δ derivative of each regressor of the
fit, in the fit's units (per degree of ``beta_deg``, ``da_deg``, ``dr_deg``, ``ds_deg``; per
deg/s of ``betadot_dps``; per unit of ``phat``, ``rhat``, thrust coefficients), and checks a
bootstrap :class:`~aerodelta.fit.FitResult` against them. Only tests and the demo read the
truth; the fit never does.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from statistics import NormalDist

import numpy as np
import polars as pl

from aerodelta import _core
from aerodelta.exceptions import DataError

_D = math.pi / 180.0

#: Effect regressor (library name) -> (fit regressor expression, factor from the library's
#: radian units to the fit's degree units).
_REGRESSORS: dict[str, tuple[str, float]] = {
    "One": ("1", 1.0),
    "Beta": ("beta_deg", _D),
    "PHat": ("phat", 1.0),
    "RHat": ("rhat", 1.0),
    "AileronDeadband": ("deadband(da_deg, 2)", _D),
    "Rudder": ("dr_deg", _D),
    "Spoiler": ("ds_deg", _D),
    "AlphaDotSpoiler": ("alphadot_dps * ds_deg", _D * _D),
    "CtSum": ("ct_left + ct_right", 1.0),
    "CtDiff": ("ct_diff", 1.0),
    "BetaDot": ("betadot_dps", _D),
}
_FLAPS = (0.0, 5.0, 10.0, 15.0, 35.0)


def _key(expr: str) -> str:
    return expr.replace(" ", "")


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _shape(shape: Mapping[str, float], alpha: np.ndarray) -> np.ndarray:
    up = _smoothstep(
        (alpha - shape["onset_deg"]) / max(shape["full_deg"] - shape["onset_deg"], 1e-9)
    )
    if shape["recovery"] == 0.0:
        return up
    span = max(shape["recover_full_deg"] - shape["recover_start_deg"], 1e-9)
    return up * (1.0 - shape["recovery"] * _smoothstep((alpha - shape["recover_start_deg"]) / span))


def campaign_effects(campaign_dir: str | Path) -> dict[str, float]:
    """Effects and magnitudes of a campaign, from ``truth/campaign.json``."""
    p = Path(campaign_dir) / "truth" / "campaign.json"
    try:
        doc = json.loads(p.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise DataError(f"{p}: cannot read the campaign truth: {e}") from e
    eff = doc.get("effects", doc.get("spec", {}).get("effects"))
    if eff is None:
        raise DataError(f"{p}: no 'effects' entry")
    if isinstance(eff, Mapping):
        return {
            str(k): float(v["magnitude"] if isinstance(v, Mapping) else v) for k, v in eff.items()
        }
    return {str(e["name"]): float(e.get("magnitude", 1.0)) for e in eff}


def true_parameter(
    effects: Mapping[str, float],
    coefficient: str,
    regressor: str,
    flap_deg: float,
    alpha_deg: np.ndarray,
) -> np.ndarray:
    """True Δ derivative of ``coefficient`` with respect to a fit regressor, vs alpha.

    Parameters
    ----------
    effects
        Effect name -> magnitude (1 = design), e.g. from :func:`campaign_effects`.
    coefficient
        ``"Cl"``, ``"Cn"`` or ``"CY"``.
    regressor
        The fit's regressor expression (e.g. ``"beta_deg"``); zero for one no effect uses.
    flap_deg
        Flap setting, deg (the nearest of 0, 5, 10, 15, 35 gives the flap factor).
    alpha_deg
        Angles of attack, deg.
    """
    a = np.asarray(alpha_deg, dtype=float)
    out = np.zeros_like(a)
    fi = int(np.argmin([abs(f - flap_deg) for f in _FLAPS]))
    for item in json.loads(_core.sim_effect_library()):
        name = item["name"]
        if item.get("kind") != "aerodynamic" or name not in effects:
            continue
        for t in item["terms"]:
            expr, unit = _REGRESSORS.get(t["regressor"], ("", 0.0))
            if t["coef"] != coefficient or _key(expr) != _key(regressor):
                continue
            k = effects[name] * item["flap_factor"][fi] * t["design"] * unit
            out = out + k * _shape(item["shape"], a)
    return out


def band_check(result: object, effects: Mapping[str, float]) -> pl.DataFrame:
    """Check a bootstrap fit's bands against the true parameters, per coefficient and flap.

    For every parameter of the final structures and every bin where it is marked identified
    and the model applies (bin centre between the blending start ``alpha_l`` of Eq. 3.12 and
    the end of the tables), the truth at the bin centre is compared with the
    smoothed parameter's band there (``inside_band``) and with the bin estimate's percentile
    band ``band_lower``..``band_upper`` (``inside_bin_band``; from a model without them,
    ``estimate ± z · std_err_bootstrap``, z of the band level).

    Returns
    -------
    polars.DataFrame
        One row per coefficient, flap and parameter: identified bins, the fractions inside,
        the median band width and the largest |truth| of the parameter.
    """
    smoothed: pl.DataFrame = result.smoothed  # type: ignore[attr-defined]
    params: pl.DataFrame = result.params  # type: ignore[attr-defined]
    if "lower" not in smoothed.columns or smoothed["lower"].is_nan().all():
        raise DataError("band_check: the fit has no bootstrap; fit with FitConfig(bootstrap=...)")
    level = 0.95
    spec = result.model.to_spec()  # type: ignore[attr-defined]
    flaps = list(spec["flaps_deg"])
    for c in spec["coefficients"].values():
        for t in c["terms"]:
            if "band" in t:
                level = float(t["band"]["level"])
    zq = NormalDist().inv_cdf(0.5 + level / 2.0)
    rows = []
    for (coef, flap, name), g in smoothed.group_by(["coefficient", "flap_deg", "param"]):
        if g["note"][0] != "":
            continue  # parameter set to zero: no band to check
        grid = g["alpha_deg"].to_numpy()
        p = params.filter(
            (pl.col("coefficient") == coef)
            & (pl.col("flap_deg") == flap)
            & (pl.col("param") == name)
            & pl.col("identifiable")
        )
        centre = 0.5 * (p["alpha_lo_deg"].to_numpy() + p["alpha_hi_deg"].to_numpy())
        alpha_l = spec["coefficients"][coef]["alpha_l_deg"][flaps.index(flap)]
        inrange = (centre >= alpha_l) & (centre <= grid.max())
        centre = centre[inrange]
        if centre.size == 0:
            continue
        reg = p["regressor"][0]
        truth = true_parameter(effects, str(coef), reg, float(flap), centre)
        lo = np.interp(centre, grid, g["lower"].to_numpy())
        hi = np.interp(centre, grid, g["upper"].to_numpy())
        est = p["estimate"].to_numpy()[inrange]
        sb = p["std_err_bootstrap"].to_numpy()[inrange]
        if "band_lower" in p.columns:
            blo = p["band_lower"].to_numpy()[inrange]
            bhi = p["band_upper"].to_numpy()[inrange]
        else:
            blo, bhi = est - zq * sb, est + zq * sb
        ok_b = np.isfinite(blo) & np.isfinite(bhi)
        rows.append(
            {
                "coefficient": coef, "flap_deg": flap, "param": name, "regressor": reg,
                "bins": int(centre.size),
                "inside_band": float(np.mean((lo <= truth) & (truth <= hi))),
                "inside_bin_band": float(np.mean((blo <= truth)[ok_b] & (truth <= bhi)[ok_b]))
                if ok_b.any()
                else math.nan,
                "median_width": float(np.median(hi - lo)),
                "max_abs_truth": float(np.max(np.abs(true_parameter(
                    effects, str(coef), reg, float(flap), grid)))),
            }
        )  # fmt: skip
    return pl.DataFrame(rows).sort(["coefficient", "flap_deg", "param"])


def band_summary(result: object, effects: Mapping[str, float]) -> pl.DataFrame:
    """:func:`band_check` pooled per coefficient.

    Returns
    -------
    polars.DataFrame
        One row per coefficient (``Cl``, ``Cn``, ``CY``): identified bins checked (``bins``),
        the bin-weighted shares inside the smoothed band (``inside_band``) and inside the
        per-bin band (``inside_bin_band``), and the median over parameters with a nonzero truth
        of the smoothed band's median width over the parameter's largest |truth|
        (``width_ratio``).
    """
    bc = band_check(result, effects)
    rows = []
    for c in ("Cl", "Cn", "CY"):
        g = bc.filter(pl.col("coefficient") == c)
        n = g["bins"].to_numpy()
        t = g.filter(pl.col("max_abs_truth") > 0)
        rows.append(
            {
                "coefficient": c,
                "bins": int(n.sum()),
                "inside_band": float(np.sum(n * g["inside_band"].to_numpy()) / n.sum()),
                "inside_bin_band": float(np.nansum(n * g["inside_bin_band"].to_numpy()) / n.sum()),
                "width_ratio": float(
                    np.median(t["median_width"].to_numpy() / t["max_abs_truth"].to_numpy())
                ),
            }
        )
    return pl.DataFrame(rows)
