"""Issue 19's loading floor: with the CG moved over 10 % of the mean aerodynamic chord between
maneuvers (and mass, inertias varied), the fitted Δ is unchanged within its standard error.

For each seed, three campaigns of the same seed are fitted with the thesis structures
(``selection=None``: the same terms in every fit, so bins compare term by term):

- ``nominal``: every maneuver with the aircraft file's loading;
- ``varied``: each maneuver with its own CG (x over 10 % of c̄, y over 5 cm, z over 10 cm),
  mass and inertias (±5 %), the manifest's loading columns read by ingest (moments
  transferred to the moment reference centre, the datum);
- ``ignored``: the varied records ingested without the loading columns (the aircraft file's
  loading for all: what a user without the manifest columns would get).

Per fit, over the bins of the material true terms (|true Δ| at least 20 % of its largest, at
): the share of CR2 95 % intervals that hold the true Δ derivative,
the median |estimate − truth| / standard error, and the median relative error. The floor
holds when ``varied`` matches ``nominal`` (coverage and errors alike) and ``ignored`` shows
what the transfer removes.

Run: ``python benchmarks/loading_check.py [--seeds 501,502,503]`` (about a minute per seed on
2 cores). Seed 500 was used while writing this script; 501-503 are the report seeds.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import polars as pl
import tomllib

import aerodelta as ad
from aerodelta.fit import FitConfig
from aerodelta.loading import LOADING_COLUMNS
from aerodelta.truth import campaign_effects, true_parameter

MATERIAL = 0.2  # share of the largest |true Δ| a term's bin needs to count as material


def _score(result: ad.FitResult, effects: dict[str, float]) -> dict[str, float]:
    p = result.params.filter(pl.col("identifiable") & pl.col("std_err").is_finite())
    rows = []
    for (coef, flap, _param), g in p.group_by(["coefficient", "flap_deg", "param"]):
        reg = g["regressor"][0]
        centre = 0.5 * (g["alpha_lo_deg"] + g["alpha_hi_deg"]).to_numpy()
        truth = true_parameter(effects, str(coef), str(reg), float(flap), centre)
        rows.append(
            g.with_columns(pl.Series("truth", truth), pl.lit(np.abs(truth).max()).alias("peak"))
        )
    if not rows:
        return {}
    d = pl.concat(rows).filter(
        (pl.col("peak") > 0) & (pl.col("truth").abs() >= MATERIAL * pl.col("peak"))
    )
    est, se, tr = d["estimate"].to_numpy(), d["std_err"].to_numpy(), d["truth"].to_numpy()
    lo, hi = d["ci95_lower"].to_numpy(), d["ci95_upper"].to_numpy()
    return {
        "bins": float(d.height),
        "coverage": float(np.mean((lo <= tr) & (tr <= hi))),
        "median |z|": float(np.median(np.abs(est - tr) / se)),
        "median rel. error": float(np.median(np.abs(est - tr) / np.abs(tr))),
    }


def _fit(camp: Path, drop_loading: bool = False) -> ad.FitResult:
    manifest = pl.read_csv(camp / "manifest.csv")
    if drop_loading:
        manifest = manifest.drop([c for c in LOADING_COLUMNS if c in manifest.columns])
    data = ad.ingest(camp, manifest=manifest, compat=False, progress=False).data
    return ad.fit(data, config=FitConfig(selection=None))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="501,502,503")
    args = ap.parse_args()
    cbar = tomllib.loads(ad.campaign.aircraft_toml())["geometry"]["cbar_m"]
    ranges = {"cg_range_m": (0.10 * cbar, 0.05, 0.10), "mass_range": 0.10, "inertia_range": 0.10}
    print(f"CG ranges (total): x {0.10 * cbar:.3f} m (10 % of c̄ = {cbar} m), y 0.05 m, z 0.10 m; "
          "mass and inertias ±5 %")  # fmt: skip
    table = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in (int(s) for s in args.seeds.split(",")):
            nom, var = Path(tmp) / f"n{seed}", Path(tmp) / f"v{seed}"
            ad.generate_campaign(nom, seed=seed)
            ad.generate_campaign(var, seed=seed, **ranges)
            effects = campaign_effects(nom)
            for name, camp, drop in (("nominal", nom, False), ("varied", var, False),
                                     ("ignored", var, True)):  # fmt: skip
                s = _score(_fit(camp, drop), effects)
                table.append({"seed": seed, "campaign": name, **s})
                print(seed, name, {k: round(v, 3) for k, v in s.items()}, flush=True)
    df = pl.DataFrame(table)
    print(df.group_by("campaign", maintain_order=True).agg(pl.exclude("seed").mean()))


if __name__ == "__main__":
    main()
