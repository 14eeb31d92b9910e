"""Issue 20 floors of the longitudinal stall on virtual campaigns with a known Kirchhoff stall.

For each campaign seed: fly ``generate_campaign(..., longitudinal_stall="kirchhoff")``, ingest
it, fit :func:`aerodelta.longitudinal.fit_kirchhoff` per flap on half of the maneuvers (sorted
ids, even positions) and score on the other half (held out). Floors (fixed before scoring):

- tau1, tau2 within 15 % of the truth; the breakpoint alpha* within 0.5 deg;
  C_L,max of the static lift curve within 2 %;
- held-out Theil coefficient of C_L and of C_m above the stall (alpha above the truth's alpha of
  C_L,max) at most 0.5 of the qualified model's (the built-in qualified model: static curves).

The drag (session 28, fixed before its first scoring): C_Dx, the drag of the separated flow,
within 15 % of the truth; the held-out Theil coefficient of C_D above the stall at most 0.5 of
the qualified model's. Reported beside them: C_D0 and C_Dk against the truth, and whether each
drag parameter's truth lies in its 95 % cluster-robust interval (t with the Bell-McCaffrey dof).

Seeds: development seeds 1, 2 (used while building the model and the fit); report seeds
101, 102, 103 (run once, for the report of the lift and pitch floors) and 104, 105, 106 (run
once, for the drag's). ``--seeds`` overrides.

Usage::

    PYTHONPATH=python python benchmarks/kirchhoff_check.py [--seeds 101 102 103] [--size 2]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import polars as pl
from scipy import stats

from aerodelta.campaign import generate_campaign
from aerodelta.fit import model_frame
from aerodelta.ingest import ingest
from aerodelta.longitudinal import (
    DRAG_PARAMS,
    fit_kirchhoff,
    measured_drag,
    measured_lift,
    qualified_longitudinal,
    theil,
)

DEV_SEEDS = (1, 2)
REPORT_SEEDS = (104, 105, 106)
FLOORS = {
    "tau_rel": 0.15, "alpha_star_deg": 0.5, "cl_max_rel": 0.02, "theil_ratio": 0.5,
    "cd_x_rel": 0.15,
}  # fmt: skip


def check_seed(seed: int, size: int, work: Path) -> list[dict[str, object]]:
    """Fly, ingest, fit and score one campaign; one row per flap."""
    t0 = time.perf_counter()
    camp = work / f"kirchhoff_{seed}"
    generate_campaign(camp, seed=seed, size=size, longitudinal_stall="kirchhoff", overwrite=True)
    t_fly = time.perf_counter() - t0
    truth = json.loads((camp / "truth" / "campaign.json").read_text())["longitudinal_stall"]
    data = model_frame(ingest(camp, progress=False).data)
    t_ing = time.perf_counter() - t0 - t_fly
    ids = sorted(data["maneuver_id"].unique().to_list())
    train, test = ids[0::2], ids[1::2]
    t1 = time.perf_counter()
    res = fit_kirchhoff(data, maneuvers=train)
    t_fit = time.perf_counter() - t1
    held = data.filter(pl.col("maneuver_id").is_in(test))
    pred = res.predict(held)
    qual = qualified_longitudinal(held)
    cl_meas = measured_lift(held)
    cd_meas = measured_drag(held)
    cm_meas = held["Cm_meas"].to_numpy()
    rows = []
    for flap, ff in sorted(res.fits.items()):
        tr = truth["params_by_flap"][f"{flap:g}"]
        a_max, cl_max = ff.cl_max
        sel = (held["flap_deg"].to_numpy() == flap) & (
            held["alpha_deg"].to_numpy() > tr["alpha_cl_max_deg"]
        )
        tic = {}
        for name, z, y_m, y_q in (
            ("CL", cl_meas, pred["CL_model"].to_numpy(), qual["CL_qual"].to_numpy()),
            ("Cm", cm_meas, pred["Cm_model"].to_numpy(), qual["Cm_qual"].to_numpy()),
            ("CD", cd_meas, pred["CD_model"].to_numpy(), qual["CD_qual"].to_numpy()),
        ):
            ok = sel & np.isfinite(z) & np.isfinite(y_m)
            tic[name] = (theil(z[ok], y_m[ok]), theil(z[ok], y_q[ok]), int(ok.sum()))
        row: dict[str, object] = {
            "seed": seed,
            "flap_deg": flap,
            "maneuvers_fit": ff.n_maneuvers,
            "iterations": ff.iterations,
            "tau1": ff.params["tau1"],
            "tau1_true": tr["tau1"],
            "tau1_se_col": ff.std_err_colored["tau1"],
            "tau2": ff.params["tau2"],
            "tau2_true": tr["tau2"],
            "tau2_se_col": ff.std_err_colored["tau2"],
            "alpha_star_deg": ff.alpha_star_deg,
            "alpha_star_true_deg": tr["alpha_star_deg"],
            "a1": ff.params["a1"],
            "a1_true": tr["a1"],
            "cl_max": cl_max,
            "cl_max_true": tr["cl_max"],
            "alpha_cl_max_deg": a_max,
            "theil_CL": tic["CL"][0],
            "theil_CL_qual": tic["CL"][1],
            "theil_Cm": tic["Cm"][0],
            "theil_Cm_qual": tic["Cm"][1],
            "held_out_points": tic["CL"][2],
        }
        drag = ff.drag
        assert drag is not None
        for n in DRAG_PARAMS:
            half = stats.t.ppf(0.975, drag.dof[n]) * drag.std_err[n]
            row[n] = drag.params[n]
            row[f"{n}_true"] = tr[n]
            row[f"{n}_se"] = drag.std_err[n]
            row[f"{n}_in_band"] = bool(abs(drag.params[n] - tr[n]) <= half)
            half_c = stats.t.ppf(0.975, drag.dof[n]) * drag.std_err_cluster[n]
            row[f"{n}_in_band_given_state"] = bool(abs(drag.params[n] - tr[n]) <= half_c)
        row.update(theil_CD=tic["CD"][0], theil_CD_qual=tic["CD"][1])
        e_cdx = abs(drag.params["CD_x"] / tr["CD_x"] - 1.0)
        r_d = tic["CD"][0] / tic["CD"][1]
        e_t1 = abs(ff.params["tau1"] / tr["tau1"] - 1.0)
        e_t2 = abs(ff.params["tau2"] / tr["tau2"] - 1.0)
        e_as = abs(ff.alpha_star_deg - tr["alpha_star_deg"])
        e_cl = abs(cl_max / tr["cl_max"] - 1.0)
        r_l = tic["CL"][0] / tic["CL"][1]
        r_m = tic["Cm"][0] / tic["Cm"][1]
        row.update(
            tau1_err=e_t1,
            tau2_err=e_t2,
            alpha_star_err_deg=e_as,
            cl_max_err=e_cl,
            theil_ratio_CL=r_l,
            theil_ratio_Cm=r_m,
            pass_tau=e_t1 <= FLOORS["tau_rel"] and e_t2 <= FLOORS["tau_rel"],
            pass_alpha_star=e_as <= FLOORS["alpha_star_deg"],
            pass_cl_max=e_cl <= FLOORS["cl_max_rel"],
            pass_theil=r_l <= FLOORS["theil_ratio"] and r_m <= FLOORS["theil_ratio"],
            cd_x_err=e_cdx,
            theil_ratio_CD=r_d,
            pass_cd_x=e_cdx <= FLOORS["cd_x_rel"],
            pass_theil_CD=r_d <= FLOORS["theil_ratio"],
        )
        rows.append(row)
    print(
        f"seed {seed}: flew {t_fly:.0f} s, ingested {t_ing:.0f} s, fitted {t_fit:.1f} s "
        f"(5 flaps, {len(train)} maneuvers)",
        file=sys.stderr,
    )
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(REPORT_SEEDS))
    ap.add_argument(
        "--size", type=int, default=5, help="repetitions per (flap, kind, pusher); 5: 200 maneuvers"
    )
    ap.add_argument("--json", type=Path, help="write the rows here")
    args = ap.parse_args(argv)
    rows: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for s in args.seeds:
            rows += check_seed(s, args.size, Path(tmp))
    df = pl.DataFrame(rows)
    with pl.Config(tbl_rows=100, tbl_cols=30, tbl_width_chars=250, float_precision=3):
        print(
            df.select(
                "seed",
                "flap_deg",
                "tau1",
                "tau1_true",
                "tau2",
                "tau2_true",
                "alpha_star_deg",
                "alpha_star_true_deg",
                "cl_max",
                "cl_max_true",
                "theil_ratio_CL",
                "theil_ratio_Cm",
                "pass_tau",
                "pass_alpha_star",
                "pass_cl_max",
                "pass_theil",
            )
        )
        print(
            df.select(
                "seed",
                "flap_deg",
                *(c for n in DRAG_PARAMS for c in (n, f"{n}_true", f"{n}_se")),
                "theil_ratio_CD",
                "pass_cd_x",
                "pass_theil_CD",
            )
        )
    cover = {n: int(df[f"{n}_in_band"].sum()) for n in DRAG_PARAMS}
    given = {n: int(df[f"{n}_in_band_given_state"].sum()) for n in DRAG_PARAMS}
    print(
        "drag truth inside its 95 % interval (CR2 with the state's uncertainty): "
        + ", ".join(f"{n} {v}/{df.height}" for n, v in cover.items())
        + "; given the state (CR2 alone): "
        + ", ".join(f"{n} {v}/{df.height}" for n, v in given.items())
    )
    passes = {
        k: int(df[k].sum())
        for k in (
            "pass_tau", "pass_alpha_star", "pass_cl_max", "pass_theil", "pass_cd_x",
            "pass_theil_CD",
        )
    }  # fmt: skip
    n = df.height
    print(
        f"floors met over {n} (seed, flap) fits: "
        + ", ".join(f"{k} {v}/{n}" for k, v in passes.items())
    )
    worst = {
        "tau1_err": float(df["tau1_err"].max()),
        "tau2_err": float(df["tau2_err"].max()),
        "alpha_star_err_deg": float(df["alpha_star_err_deg"].max()),
        "cl_max_err": float(df["cl_max_err"].max()),
        "theil_ratio_CL": float(df["theil_ratio_CL"].max()),
        "theil_ratio_Cm": float(df["theil_ratio_Cm"].max()),
        "cd_x_err": float(df["cd_x_err"].max()),
        "theil_ratio_CD": float(df["theil_ratio_CD"].max()),
    }
    print("worst: " + ", ".join(f"{k} {v:.3g}" for k, v in worst.items()))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1, default=float))
    all_ok = all(v == n for v in passes.values()) and all(math.isfinite(v) for v in worst.values())
    return 0 if all_ok else 1


if __name__ == "__main__":
    sys.exit(main())
