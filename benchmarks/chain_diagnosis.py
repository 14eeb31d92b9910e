"""Where the Δ fit's zero-truth terms come from on a JSBSim campaign (issue 16, session 13).

Two analyses of one flown campaign (``generate_jsbsim_campaign``; its ``truth/`` folder):

1. **decompose**: hold out every fifth maneuver as ``jsbsim_identification_check.py`` does,
   run the default stepwise fit, then refit each flap's kept structure
   (``selection=None``) against three targets: the fit's own ``C_meas - C_sim``, the true Δ
   ``dC_true`` and the chain residual ``e = C_meas - C_sim - dC_true``. Least squares is
   linear, so each bin's estimate is exactly the sum of the last two; printed per zero-truth
   term: identified bins above alpha_l, the share with p < 0.05 against each target, and the
   median estimates.
2. **chain**: on the samples above the withhold alpha, how much of ``e`` the central
   difference's trapezoid ``¼ C(t-Δt) + ½ C(t) + ¼ C(t+Δt) - C(t)`` and the time derivative
   ``dC/dt`` of the aircraft's total coefficient (JSBSim aero + propulsion) explain, and
   the slopes (the trapezoid's coefficient is 0.5 for a pure central difference; ``dC/dt``'s
   is a time skew in s).

Run: ``python benchmarks/chain_diagnosis.py CAMPAIGN_DIR [--seed 1] [--no-smooth]
[--fit-setting chain_calibration=false]`` (development campaigns only: seeds 1-3).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import polars as pl

import aerodelta as ad
from aerodelta.fit import COEFFICIENTS, FitConfig

sys.path.insert(0, str(Path(__file__).resolve().parent))
import jsbsim_identification_check as jic

DT_COLS = [f"d{c}_true" for c in COEFFICIENTS]


def _truth(camp: Path) -> pl.DataFrame:
    return pl.concat(
        [
            pl.read_parquet(f).with_columns(pl.lit(f.stem).alias("maneuver_id"))
            for f in sorted((camp / "truth").glob("*.parquet"))
            if f.stem != "true_delta"
        ],
        how="diagonal_relaxed",
    )


def decompose(camp: Path, seed: int, settings: dict[str, object], smooth: bool) -> pl.DataFrame:
    """Per zero-truth term kept by the stepwise fit: significance and median estimate against
    the fit's target, the true Δ and the chain residual."""
    data = ad.ingest(camp, compat=False, progress=False, smooth=smooth).data
    truth = jic._truth_frame(camp)
    ids = data["maneuver_id"].unique().sort().to_list()
    train = data.filter(~pl.col("maneuver_id").is_in(set(ids[::5])))
    train = train.join(
        truth.select("maneuver_id", "t", *DT_COLS), on=["maneuver_id", "t"], how="left"
    )
    cfg = FitConfig(seed=seed, **settings)  # type: ignore[arg-type]
    r = ad.fit(train.drop(DT_COLS), qualified="columns", config=cfg)
    zero = jic._bin_rows(r, camp, cfg).filter(pl.col("zero_truth")).select("coefficient", "param")
    kept = r.structure.filter(pl.col("kept"))
    targets = {
        "total": lambda c: pl.col(f"{c}_sim"),
        "delta": lambda c: pl.col(f"{c}_meas") - pl.col(f"d{c}_true"),
        "chain": lambda c: pl.col(f"{c}_sim") + pl.col(f"d{c}_true"),
    }
    rows = []
    for flap in sorted(kept["flap_deg"].unique().to_list()):
        structs = {}
        for c in COEFFICIENTS:
            k = kept.filter((pl.col("coefficient") == c) & (pl.col("flap_deg") == flap))
            structs[c] = list(zip(k["param"].to_list(), k["regressor"].to_list(), strict=True))
        part = train.filter(pl.col("flap_deg") == flap)
        fits = {}
        for tag, sim in targets.items():
            d = part.with_columns(*[sim(c).alias(f"{c}_sim") for c in COEFFICIENTS]).drop(DT_COLS)
            one = FitConfig(seed=seed, selection=None, structures=structs, **settings)  # type: ignore[arg-type]
            p = ad.fit(d, qualified="columns", config=one).params
            fits[tag] = p.select(
                "coefficient",
                "param",
                "alpha_lo_deg",
                "identifiable",
                pl.col("estimate").alias(f"est_{tag}"),
                pl.col("p_value").alias(f"p_{tag}"),
            )
        j = fits["total"]
        for tag in ("delta", "chain"):
            j = j.join(fits[tag].drop("identifiable"), on=["coefficient", "param", "alpha_lo_deg"])
        rows.append(j.with_columns(pl.lit(flap).alias("flap_deg")))
    alpha_l = float(FitConfig().alpha_l_deg)  # type: ignore[arg-type]
    j = (
        pl.concat(rows)
        .join(zero.unique(), on=["coefficient", "param"])
        .filter(pl.col("identifiable") & (pl.col("alpha_lo_deg") >= alpha_l))
    )
    return (
        j.group_by("coefficient", "param", "flap_deg")
        .agg(
            pl.len().alias("bins"),
            *[(pl.col(f"p_{t}") < 0.05).mean().alias(f"sig_{t}") for t in targets],
            *[pl.col(f"est_{t}").median().alias(f"median_{t}") for t in targets],
        )
        .sort("coefficient", "param", "flap_deg")
    )


def chain(camp: Path, smooth: bool) -> pl.DataFrame:
    """The chain residual against the trapezoid and the time derivative of the total."""
    walpha = float(json.loads((camp / "truth" / "truth.json").read_text())["withhold_alpha_deg"])
    data = ad.ingest(camp, compat=False, progress=False, smooth=smooth).data
    t = _truth(camp)
    j = data.select("maneuver_id", "t", *[f"{c}_meas" for c in ("Cl", "Cn")]).join(
        t.select(
            "maneuver_id",
            "t",
            pl.col("alpha_deg").alias("alpha_true_deg"),
            *[
                (pl.col(f"{c}_true") + pl.col(f"{c}_prop_true")).alias(f"{c}_tot")
                for c in ("Cl", "Cn")
            ],
        ),
        on=["maneuver_id", "t"],
    )
    j = j.sort("maneuver_id", "t")
    dt = float(np.median(np.diff(j["t"].to_numpy()[:50])))
    out = []
    for c in ("Cl", "Cn"):
        x = pl.col(f"{c}_tot")
        k = j.with_columns(
            ((x.shift(1) + x.shift(-1)) / 2 - x).over("maneuver_id").alias("trap"),
            ((x.shift(-1) - x.shift(1)) / (2 * dt)).over("maneuver_id").alias("rate"),
        ).filter(pl.col("alpha_true_deg") > walpha)
        k = k.drop_nulls(["trap", "rate"])
        e = (k[f"{c}_meas"] - k[f"{c}_tot"]).to_numpy()
        for name, cols in (("trapezoid", ["trap"]), ("rate", ["rate"]), ("both", ["trap", "rate"])):
            xm = np.column_stack([np.ones(k.height)] + [k[n].to_numpy() for n in cols])
            th, *_ = np.linalg.lstsq(xm, e, rcond=None)
            res = e - xm @ th
            out.append(
                {
                    "coefficient": c,
                    "regressors": name,
                    "rms_e": float(np.std(e)),
                    "r2": float(1 - res.var() / e.var()),
                    "slopes": ", ".join(f"{n} {v:.4g}" for n, v in zip(cols, th[1:], strict=True)),
                }
            )
    return pl.DataFrame(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", type=Path)
    ap.add_argument("--seed", type=int, default=1, help="fold and bootstrap seed of the fit")
    ap.add_argument("--no-smooth", action="store_true", help="ingest without smoothing")
    ap.add_argument(
        "--fit-setting",
        action="append",
        default=[],
        help="NAME=JSON FitConfig setting, e.g. chain_calibration=false (repeatable)",
    )
    args = ap.parse_args()
    settings = {k: json.loads(v) for k, v in (s.split("=", 1) for s in args.fit_setting)}
    pl.Config.set_tbl_rows(200)
    pl.Config.set_tbl_width_chars(250)
    pl.Config.set_tbl_cols(-1)
    smooth = not args.no_smooth
    print(chain(args.campaign, smooth))
    print(decompose(args.campaign, args.seed, settings, smooth))


if __name__ == "__main__":
    main()
