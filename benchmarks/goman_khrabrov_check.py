"""Issue 20, the Goman-Khrabrov alternative: the tabulated separation curve against the tanh.

Two checks, each fitting on half of the maneuvers of a flap (sorted ids, even positions) and
scoring on the other half (held out), as ``kirchhoff_check.py`` and
``jsbsim_kirchhoff_check.py`` do:

- **Virtual aircraft, Kirchhoff truth** (``--virtual``; the default campaign, 200 maneuvers,
  ``longitudinal_stall="kirchhoff"``): the truth *is* the tanh form, so the table must lose
  nothing. Floors, fixed before the report seeds were run: tau1, tau2 within 15 % of the
  truth; the static C_L,max within 2 %; the held-out Theil coefficient of C_L and of C_m above
  the stall (alpha above the truth's alpha of C_L,max) at most half the qualified model's
  (issue 20's floors, now for the table); and the table's held-out Theil coefficient of C_L at
  most 1.10 times the tanh's on the same samples.
- **JSBSim aircraft, static tables** (``--jsbsim``; F-15 ``f15`` and DHC-6 ``DHC6``, 6
  repetitions of each flap x entry, ``known="none"``): the lift tables are piecewise linear
  (the DHC-6's has a plateau the tanh cannot follow: its static curve lay inside the binned
  curve's band on 39-64 % of the grid, ``docs/longitudinal.md``). Floors, fixed before the
  report seeds were run: the table's static C_L within the 95 % band
  ``1.96 sqrt(se_table^2 + se_bins^2)`` of the model-free binned curve
  (``binned_static_curve``; grid: its 1-deg bins of at least 20 samples from 2 maneuvers) on
  at least 90 % of the grid; and the table's held-out Theil coefficient of C_L no larger than
  the tanh's. Reported beside them: the tanh's fraction on the same grid, the table against
  JSBSim's own lift (every LIFT term of the XML at the recorded states), the lags, and the
  same comparisons for C_m. C_m is not floored: its form (``Cm0 + Cm_alpha alpha + Cm_x
  (1 - x)``) is the tanh fit's, the table changes only ``x0``, and with ``known="none"`` the
  measured C_m is the elevator's trim residual, which neither form follows (on development
  seeds 1, 2 both lay within the bins' band on 50-92 % of the grid; a first version of this
  floor asked 90 % of C_m too, dropped on those seeds before any report seed was run).

Seeds: development Kirchhoff 1, 2 and JSBSim 1, 2 (used while building the tabulated form and
this script); report Kirchhoff 107, 108, 109 and JSBSim 881, 882, 883 (run once, for
docs/longitudinal.md). ``--seeds`` overrides both.

Usage::

    PYTHONPATH=python python benchmarks/goman_khrabrov_check.py [--virtual] [--jsbsim]
        [--seeds 107 108 109] [--jsbsim-seeds 881 882 883] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("JSBSIM_DEBUG", "0")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
import polars as pl

from aerodelta.campaign import generate_campaign
from aerodelta.exceptions import AerodeltaError
from aerodelta.fit import model_frame
from aerodelta.goman_khrabrov import fit_goman_khrabrov
from aerodelta.ingest import ingest
from aerodelta.longitudinal import (
    binned_static_curve,
    fit_kirchhoff,
    measured_lift,
    qualified_longitudinal,
    static_curves,
    theil,
)

DEV_SEEDS = (1, 2)
REPORT_SEEDS = (107, 108, 109)
JSBSIM_DEV_SEEDS = (1, 2)
JSBSIM_REPORT_SEEDS = (881, 882, 883)
FLOORS = {
    "tau_rel": 0.15,
    "cl_max_rel": 0.02,
    "theil_ratio": 0.5,
    "theil_vs_tanh": 1.10,
    "band_z": 1.96,
    "grid_fraction": 0.90,
}


def _split(data: pl.DataFrame) -> tuple[list[str], pl.DataFrame, pl.DataFrame]:
    ids = sorted(data["maneuver_id"].unique().to_list())
    train, test = ids[0::2], ids[1::2]
    return (
        train,
        data.filter(pl.col("maneuver_id").is_in(train)),
        data.filter(pl.col("maneuver_id").is_in(test)),
    )


def check_virtual(seed: int, work: Path) -> list[dict[str, Any]]:
    """One virtual campaign with the Kirchhoff truth; one row per flap."""
    t0 = time.perf_counter()
    camp = work / f"kirchhoff_{seed}"
    generate_campaign(camp, seed=seed, longitudinal_stall="kirchhoff", overwrite=True)
    truth = json.loads((camp / "truth" / "campaign.json").read_text())["longitudinal_stall"]
    data = model_frame(ingest(camp, progress=False).data)
    train, _, held = _split(data)
    t1 = time.perf_counter()
    tanh = fit_kirchhoff(data, maneuvers=train, fit_cd=False)
    gk = fit_goman_khrabrov(data, start=tanh, maneuvers=train)
    t_fit = time.perf_counter() - t1
    p_t, p_g = tanh.predict(held), gk.predict(held)
    qual = qualified_longitudinal(held)
    z_l, z_m = measured_lift(held), held["Cm_meas"].to_numpy()
    rows = []
    for flap, gf in sorted(gk.fits.items()):
        tr = truth["params_by_flap"][f"{flap:g}"]
        sel = (held["flap_deg"].to_numpy() == flap) & (
            held["alpha_deg"].to_numpy() > tr["alpha_cl_max_deg"]
        )
        th = {
            (c, m): theil(z[sel], y[sel])
            for c, z in (("CL", z_l), ("Cm", z_m))
            for m, y in (
                ("gk", p_g[f"{c}_model"].to_numpy()),
                ("tanh", p_t[f"{c}_model"].to_numpy()),
                ("qual", qual[f"{c}_qual"].to_numpy()),
            )
        }
        e1 = abs(gf.params["tau1"] / tr["tau1"] - 1.0)
        e2 = abs(gf.params["tau2"] / tr["tau2"] - 1.0)
        ecl = abs(gf.cl_max[1] / tr["cl_max"] - 1.0)
        r_l, r_m = th["CL", "gk"] / th["CL", "qual"], th["Cm", "gk"] / th["Cm", "qual"]
        vs_tanh = th["CL", "gk"] / th["CL", "tanh"]
        rows.append(
            {
                "seed": seed, "flap_deg": flap, "knots": gf.knots_deg.size,
                "free_nodes": int(np.isfinite(gf.x0_std_err).sum()),
                "iterations": gf.iterations, "tau1": gf.params["tau1"], "tau1_true": tr["tau1"],
                "tau1_tanh": gf.tanh.params["tau1"], "tau2": gf.params["tau2"],
                "tau2_true": tr["tau2"], "tau2_tanh": gf.tanh.params["tau2"],
                "tau1_err": e1, "tau2_err": e2, "cl_max": gf.cl_max[1],
                "cl_max_true": tr["cl_max"], "cl_max_err": ecl,
                "theil_CL_gk": th["CL", "gk"], "theil_CL_tanh": th["CL", "tanh"],
                "theil_CL_qual": th["CL", "qual"], "theil_Cm_gk": th["Cm", "gk"],
                "theil_Cm_tanh": th["Cm", "tanh"], "theil_Cm_qual": th["Cm", "qual"],
                "theil_ratio_CL": r_l, "theil_ratio_Cm": r_m, "theil_CL_vs_tanh": vs_tanh,
                "cost_gk": gf.cost, "cost_tanh": gf.tanh.cost, "held_out": int(sel.sum()),
                "line": gf.line.removeprefix("lift line of the "),
                "floor_ok": bool(
                    e1 <= FLOORS["tau_rel"] and e2 <= FLOORS["tau_rel"]
                    and ecl <= FLOORS["cl_max_rel"] and r_l <= FLOORS["theil_ratio"]
                    and r_m <= FLOORS["theil_ratio"] and vs_tanh <= FLOORS["theil_vs_tanh"]
                ),
            }
        )  # fmt: skip
    print(
        f"virtual seed {seed}: {time.perf_counter() - t0:.0f} s (fit {t_fit:.1f} s)",
        file=sys.stderr,
    )
    return rows


def _in_band(a: np.ndarray, a_se: np.ndarray, b: np.ndarray, b_se: np.ndarray) -> float:
    return float(np.mean(np.abs(a - b) <= FLOORS["band_z"] * np.hypot(a_se, b_se)))


def check_jsbsim(aircraft: str, seed: int, work: Path) -> list[dict[str, Any]]:
    """One JSBSim campaign (static tables); one row per flap."""
    from aerodelta import jsbsim_campaign as jc  # noqa: PLC0415
    from jsbsim_kirchhoff_check import truth_lift  # noqa: PLC0415

    t0 = time.perf_counter()
    camp = work / f"{aircraft}_{seed}"
    jc.generate_jsbsim_campaign(camp, aircraft=aircraft, seed=seed, size=6, overwrite=True)
    data = model_frame(ingest(camp, progress=False).data)
    data = data.with_columns(pl.Series("_cl_true", truth_lift(camp, data)))
    train, fit_rows, held = _split(data)
    t1 = time.perf_counter()
    try:
        tanh = fit_kirchhoff(data, maneuvers=train, known="none", fit_cd=False)
        gk = fit_goman_khrabrov(data, start=tanh, maneuvers=train, known="none")
    except AerodeltaError as e:
        # a failed fit is a row that does not meet the floor, with the reason
        print(f"{aircraft} seed {seed}: no fit: {e}", file=sys.stderr)
        return [{"aircraft": aircraft, "seed": seed, "error": str(e), "floor_ok": False}]
    t_fit = time.perf_counter() - t1
    bins = binned_static_curve(fit_rows)
    truth_bins = (
        fit_rows.with_columns(pl.col("alpha_deg").round().alias("alpha_bin"))
        .group_by("flap_deg", "alpha_bin")
        .agg(pl.col("_cl_true").mean().alias("CL_true"))
    )
    p_t = tanh.predict(held, known="none")
    p_g = gk.predict(held, known="none")
    z_l, z_m = measured_lift(held), held["Cm_meas"].to_numpy()
    rows = []
    for flap, gf in sorted(gk.fits.items()):
        grid = bins.filter(pl.col("flap_deg") == flap).join(
            truth_bins.filter(pl.col("flap_deg") == flap).select(
                pl.col("alpha_bin").alias("alpha_deg"), "CL_true"
            ),
            on="alpha_deg",
            how="left",
        )
        ag = grid["alpha_mean_deg"].to_numpy()
        g_c = gf.static_curve(ag)
        t_c = static_curves(gf.tanh.params, ag, gf.tanh.cov_colored)
        row: dict[str, Any] = {
            "aircraft": aircraft, "seed": seed, "flap_deg": flap, "grid_bins": int(ag.size),
            "knots": gf.knots_deg.size, "free_nodes": int(np.isfinite(gf.x0_std_err).sum()),
            "table_deg": f"{gf.knots_deg[0]:g}-{gf.knots_deg[-1]:g}",
            "tau_identified": gf.tau_identified, "tau1": gf.params["tau1"],
            "tau2": gf.params["tau2"], "iterations": gf.iterations,
            "line": gf.line.removeprefix("lift line of the "),
        }  # fmt: skip
        for c in ("CL", "Cm"):
            b, b_se = grid[c].to_numpy(), grid[f"{c}_se"].to_numpy()
            row[f"{c}_gk_bins_frac"] = _in_band(
                g_c[c].to_numpy(), g_c[f"{c}_se"].to_numpy(), b, b_se
            )
            row[f"{c}_tanh_bins_frac"] = _in_band(t_c[c], t_c[f"{c}_se"], b, b_se)
            row[f"{c}_gk_bins_max"] = float(np.max(np.abs(g_c[c].to_numpy() - b)))
            row[f"{c}_tanh_bins_max"] = float(np.max(np.abs(t_c[c] - b)))
        tr = grid["CL_true"].to_numpy()
        row["CL_gk_truth_max"] = float(np.nanmax(np.abs(g_c["CL"].to_numpy() - tr)))
        row["CL_tanh_truth_max"] = float(np.nanmax(np.abs(t_c["CL"] - tr)))
        sel = held["flap_deg"].to_numpy() == flap
        for c, z in (("CL", z_l), ("Cm", z_m)):
            row[f"theil_{c}_gk"] = theil(z[sel], p_g[f"{c}_model"].to_numpy()[sel])
            row[f"theil_{c}_tanh"] = theil(z[sel], p_t[f"{c}_model"].to_numpy()[sel])
        row["floor_ok"] = bool(
            row["CL_gk_bins_frac"] >= FLOORS["grid_fraction"]
            and row["theil_CL_gk"] <= row["theil_CL_tanh"]
        )
        rows.append(row)
    print(
        f"{aircraft} seed {seed}: {time.perf_counter() - t0:.0f} s (fit {t_fit:.1f} s)",
        file=sys.stderr,
    )
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--virtual", action="store_true", help="only the virtual aircraft")
    ap.add_argument("--jsbsim", action="store_true", help="only the JSBSim aircraft")
    ap.add_argument("--seeds", type=int, nargs="+", default=list(REPORT_SEEDS))
    ap.add_argument("--jsbsim-seeds", type=int, nargs="+", default=list(JSBSIM_REPORT_SEEDS))
    ap.add_argument("--aircraft", nargs="+", default=["f15", "DHC6"])
    ap.add_argument("--json", type=Path, help="write the rows here")
    args = ap.parse_args(argv)
    both = not (args.virtual or args.jsbsim)
    virt: list[dict[str, Any]] = []
    jsb: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        if both or args.virtual:
            for s in args.seeds:
                virt += check_virtual(s, Path(tmp))
        if both or args.jsbsim:
            for ac in args.aircraft:
                for s in args.jsbsim_seeds:
                    jsb += check_jsbsim(ac, s, Path(tmp))
    ok = True
    with pl.Config(tbl_rows=100, tbl_cols=40, tbl_width_chars=300, float_precision=4):
        if virt:
            df = pl.DataFrame(virt)
            print(df.drop("cost_gk", "cost_tanh"))
            met = int(df["floor_ok"].sum())
            print(
                f"virtual floors (tau 15 %, C_L,max 2 %, Theil <= 0.5 qualified, <= 1.10 tanh): "
                f"{met}/{df.height}; worst tau1 {df['tau1_err'].max():.3f}, tau2 "
                f"{df['tau2_err'].max():.3f}, C_L,max {df['cl_max_err'].max():.4f}, Theil "
                f"ratio C_L {df['theil_ratio_CL'].max():.3f}, C_m {df['theil_ratio_Cm'].max():.3f},"
                f" vs tanh {df['theil_CL_vs_tanh'].max():.3f}"
            )
            ok &= met == df.height
        if jsb:
            dj = pl.DataFrame(jsb, infer_schema_length=None)
            print(dj)
            met = int(dj["floor_ok"].sum())
            print(
                f"JSBSim floors (table's C_L within the bins' band on >= 90 % of the grid; "
                f"held-out Theil C_L <= the tanh's): {met}/{dj.height}"
            )
            ok &= met == dj.height
    if args.json:
        args.json.write_text(
            json.dumps({"floors": FLOORS, "virtual": virt, "jsbsim": jsb}, indent=1, default=str)
        )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
