"""Issue 19's reconstruction floor: with upwash and sidewash scale errors, vane biases and a
flank-angle yaw vane injected into the virtual flight test, the compatibility check
(``ingest(..., vane_scale=True)``) returns the scale factors within 1 % and the biases within
0.1 deg (campaign medians), and the Δ fitted after applying them (``apply_compat=True``)
equals the error-free campaign's within its error.

Per seed and turbulence level (calm, and the default 0.5 m/s Dryden gusts): the campaign
medians of k_alpha, k_beta, b_alpha, b_beta against the injected values (7 %, -8 %, 1.5 deg,
0.8 deg), with their standard errors from the spread between maneuvers; then the thesis
structures fitted on the corrected campaign and on the same seed flown with ideal vanes,
scored against the true Δ as in ``loading_check.py`` (95 % interval coverage, median
|error|/SE, median relative error).

Run: ``python benchmarks/vane_calibration_check.py [--seeds 701,702,703] [--compat-method
auto|output-error|innovations]`` (about a minute per seed and turbulence level on 2 cores).
Seeds 600 and 601 were used while building the check (they showed the turbulence bias
described in docs/data.md) and the innovations form (session 13); 701-703 were the report
seeds of the output-error check, 711-713 those of the innovations form.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import polars as pl

import aerodelta as ad
from aerodelta.fit import FitConfig
from aerodelta.truth import campaign_effects

sys.path.insert(0, str(Path(__file__).parent))
from loading_check import _score

K_ALPHA, K_BETA, B_ALPHA, B_BETA = 0.07, -0.08, 1.5, 0.8
EFFECTS = {"alpha_vane_bias": B_ALPHA, "beta_vane_bias": B_BETA}


def _medians(res: ad.IngestResult) -> dict[str, tuple[float, float]]:
    """Campaign median and its standard error (1.2533 x 1.4826 MAD / sqrt(n)) per parameter,
    in % for the scale factors and deg for the biases."""
    out = {}
    for name, unit in (("k_alpha", 100.0), ("k_beta", 100.0), ("b_alpha_rad", 180 / np.pi),
                       ("b_beta_rad", 180 / np.pi)):  # fmt: skip
        est = res.compat.filter(pl.col("parameter") == name)["estimate"].to_numpy() * unit
        med = float(np.median(est))
        se = 1.2533 * 1.4826 * float(np.median(np.abs(est - med))) / np.sqrt(est.size)
        out[name] = (med, se)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="701,702,703")
    ap.add_argument("--size", default="default")
    ap.add_argument(
        "--compat-method", default="auto", choices=["auto", "output-error", "innovations"],
        help="the compatibility check's reconstruction (auto: innovations, vane_scale is set)",
    )  # fmt: skip
    args = ap.parse_args()
    truth = {"k_alpha": 100 * K_ALPHA, "k_beta": 100 * K_BETA, "b_alpha_rad": B_ALPHA,
             "b_beta_rad": B_BETA}  # fmt: skip
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in (int(s) for s in args.seeds.split(",")):
            for turb in (0.0, 0.5):
                cal, ideal = Path(tmp) / f"c{seed}_{turb}", Path(tmp) / f"i{seed}_{turb}"
                kw = {"seed": seed, "size": args.size, "turbulence": turb}
                ad.generate_campaign(cal, effects={**EFFECTS, **dict.fromkeys(
                    ad.campaign.DEFAULT_EFFECTS, 1.0)}, vane_scale=(K_ALPHA, K_BETA),
                    flank_vane=True, **kw)  # fmt: skip
                ad.generate_campaign(ideal, effects="default", **kw)
                res = ad.ingest(
                    cal, vane_scale=True, apply_compat=True, progress=False,
                    compat_method=args.compat_method,
                )  # fmt: skip
                med = _medians(res)
                row: dict[str, object] = {"seed": seed, "turbulence": turb}
                for k, (m, se) in med.items():
                    row[f"{k} err"] = m - truth[k]
                    row[f"{k} se"] = se
                effects = campaign_effects(ideal)
                cfg = FitConfig(selection=None)
                s_cal = _score(ad.fit(res.data, config=cfg), effects)
                ideal_data = ad.ingest(ideal, compat=False, progress=False).data
                s_ideal = _score(ad.fit(ideal_data, config=cfg), effects)
                row |= {f"corrected {k}": v for k, v in s_cal.items() if k != "bins"}
                row |= {f"ideal {k}": v for k, v in s_ideal.items() if k != "bins"}
                rows.append(row)
                print({k: round(v, 3) if isinstance(v, float) else v for k, v in row.items()},
                      flush=True)  # fmt: skip
    df = pl.DataFrame(rows)
    with pl.Config(tbl_cols=-1, tbl_width_chars=200):
        print(df.group_by("turbulence", maintain_order=True).agg(pl.exclude("seed").mean()))


if __name__ == "__main__":
    main()
