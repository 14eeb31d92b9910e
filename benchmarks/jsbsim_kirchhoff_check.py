"""Issue 20 floor: output error on JSBSim aircraft (static tables: tau -> 0) agrees with
equation error.

For each aircraft (the F-15 ``f15`` and the DHC-6 ``DHC6``) and campaign seed: fly
``generate_jsbsim_campaign`` (default size: 6 repetitions of each flap x entry, sensor noise
scale 1, calm air), ingest it, and per flap fit on half of the maneuvers (sorted ids, even
positions), score on the other half (held out):

- **OE**: :func:`aerodelta.longitudinal.fit_kirchhoff` with ``known="none"``. JSBSim's
  control and rate terms are not the ADX-37's, and the campaign writes no longitudinal truth
  (its truth files hold the lateral terms only), so the measured C_L and C_m are fitted whole:
  the "static curve" of both fits is then the coefficient's mean at each alpha along the flown
  maneuvers (the elevator that trims each alpha included). Chosen over computing JSBSim's
  control and rate terms as the known part because the DHC-6's pitch terms cannot all be
  evaluated from the records (CmDe is a 3-D table, CmT reads the propulsion system's thrust
  coefficient).
- **EE-K** (equation error, the same model form): the static Kirchhoff curves (``x = x0(alpha)``,
  no lag) fitted by least squares to the same samples, C_L alone first
  (``scipy.optimize.least_squares``, from the engine's equation-error start), then C_m linear in
  ``(1, alpha, 1 - x0)``; covariance cluster-robust over maneuvers (sandwich).
- **EE-bins** (equation error, model-free): measured C_L, C_m averaged in 1-deg alpha bins,
  cluster-robust standard errors over maneuvers
  (:func:`aerodelta.longitudinal.binned_static_curve`).
- **Truth** (C_L only): JSBSim's lift, every LIFT term of the aircraft's XML evaluated at the
  recorded states (alpha, Mach, elevator, q, alpha-dot, flap; ground effect 1), averaged in the
  same bins. C_m has no truth here (the DHC-6's CmDe, CmT above).

Criteria, fixed before the report seeds were run (grid: the 1-deg bins of the fitted
maneuvers holding >= 20 samples of >= 2 maneuvers; 95 % band of a difference:
``1.96 sqrt(se_a^2 + se_b^2)``; OE bands from the coloured-residual covariance):

- **tau -> 0**: the fit reports the lags not identified (``FlapFit.tau_identified`` False:
  the free fit and its restart from the static solution put the total lag tau1 + tau2 under
  half a sample interval, and tau1, tau2 are held at the engine's lower bounds 1 ms, 0), or it
  identifies them and each is within 2 coloured-residual bounds of 0 or below 0.02 s (one
  50 Hz sample).
- **OE agrees with EE** (the floor): the OE static curves of C_L and of C_m lie within the 95 %
  band of the EE-K curves on >= 90 % of the grid.
- Reported beside it, not part of the floor: OE against EE-bins (does the Kirchhoff form follow
  the tables?) and against the truth (C_L within 1.96 OE bounds of JSBSim's binned lift), the
  breakpoint and C_L,max of OE and EE-K, and the held-out Theil coefficient
  ``rms(z - y) / (rms(z) + rms(y))`` of C_L and C_m for OE, EE-K and EE-bins.

Seeds: development 1, 2 (used while building the fallback of ``fit_kirchhoff`` and this
script); report 201, 202, 203 (run once, for docs/longitudinal.md). ``--seeds`` overrides.

Usage::

    PYTHONPATH=python python benchmarks/jsbsim_kirchhoff_check.py [--seeds 201 202 203]
        [--aircraft f15 DHC6] [--size 6] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("JSBSIM_DEBUG", "0")

import numpy as np
import polars as pl
from scipy.optimize import least_squares

from aerodelta import jsbsim_campaign as jc
from aerodelta.fit import model_frame
from aerodelta.ingest import ingest
from aerodelta.longitudinal import (
    PARAMS,
    TAU1_MIN_S,
    FlapFit,
    binned_static_curve,
    fit_kirchhoff,
    measured_lift,
    static_curves,
    theil,
)

DEV_SEEDS = (1, 2)
REPORT_SEEDS = (201, 202, 203)
CRITERIA = {"tau_bounds": 2.0, "tau_physical_s": 0.02, "band_z": 1.96, "grid_fraction": 0.90}
FT = 0.3048


def _x0(p: dict[str, float], a: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 - np.tanh(p["a1"] * (a - p["alpha_star"])))


def ee_static_fit(sub: pl.DataFrame, ee_start: dict[str, float]) -> tuple[dict[str, float], Any]:
    """Equation error of the static Kirchhoff curves on one flap's samples (engine units).

    Returns the nine parameters (no lag: tau1 = 1 ms, tau2 = 0) and their 9 x 9
    cluster-robust covariance.
    """
    a = np.radians(sub["alpha_deg"].to_numpy())
    cl = measured_lift(sub)
    cm = sub["Cm_meas"].to_numpy()
    mid = sub["maneuver_id"].to_numpy()
    names_l = ("CL_alpha", "alpha0", "alpha_star", "a1")

    def res_l(v: np.ndarray) -> np.ndarray:
        p = dict(zip(names_l, v, strict=True))
        x = _x0(p, a)
        return p["CL_alpha"] * (a - p["alpha0"]) * (0.5 * (1.0 + np.sqrt(x))) ** 2 - cl

    v0 = np.array([ee_start[n] for n in names_l])
    v0[3] = max(v0[3], 0.5)
    sol = least_squares(res_l, v0, method="trf", bounds=([-np.inf] * 3 + [0.1], np.inf))
    p = dict(zip(names_l, sol.x, strict=True))
    x = _x0(p, a)
    xm = np.column_stack([np.ones_like(a), a, 1.0 - x])
    bm, *_ = np.linalg.lstsq(xm, cm, rcond=None)
    p.update(Cm0=bm[0], Cm_alpha=bm[1], Cm_x=bm[2], tau1=TAU1_MIN_S, tau2=0.0)
    # cluster-robust sandwich per block (maneuvers are the clusters)
    cov = np.zeros((len(PARAMS), len(PARAMS)))
    for jac, r, names in (
        (sol.jac, sol.fun, names_l),
        (xm, xm @ bm - cm, ("Cm0", "Cm_alpha", "Cm_x")),
    ):
        bread = np.linalg.inv(jac.T @ jac)
        ids, inv = np.unique(mid, return_inverse=True)
        g = np.zeros((ids.size, jac.shape[1]))
        np.add.at(g, inv, jac * r[:, None])
        m = ids.size
        meat = g.T @ g * m / (m - 1)
        c = bread @ meat @ bread
        ix = [PARAMS.index(n) for n in names]
        cov[np.ix_(ix, ix)] = c
    return {k: float(v) for k, v in p.items()}, cov


def truth_lift(camp: Path, data: pl.DataFrame) -> np.ndarray:
    """JSBSim's lift coefficient at the recorded states: every LIFT term of the XML."""
    info = json.loads((camp / "truth" / "truth.json").read_text())
    aircraft = info["aircraft"]
    root = jc._root(None)
    cfg, xml = jc._resolve_aircraft(aircraft, root)
    terms = [t for t in jc._aero_terms(xml, root) if t.axis == "LIFT"]
    cbar_ft = float(_toml_value(camp / "aircraft.toml", "cbar_m")) / FT
    h = data["h_m"].to_numpy()
    v = data["tas_mps"].to_numpy()
    t_k = 288.15 - 0.0065 * np.minimum(h, 11000.0)
    mach = v / np.sqrt(1.4 * 287.053 * t_k)
    de = data["de_deg"].to_numpy() / float(info["control_signs"]["de"])
    env = {
        "aero/alpha-rad": np.radians(data["alpha_deg"].to_numpy()),
        "aero/alpha-deg": data["alpha_deg"].to_numpy(),
        "velocities/mach": mach,
        cfg.elevator_rad: np.radians(de),
        "aero/alphadot-rad_sec": np.radians(data["alphadot_dps"].to_numpy()),
        "velocities/q-aero-rad_sec": np.radians(data["q_dps"].to_numpy()),
        "fcs/flap-pos-deg": data["flap_deg"].to_numpy(),
        "fcs/speedbrake-pos-norm": np.zeros(data.height),
        **{k: np.full(data.height, val) for k, val in jc._REF_PROPS.items()},
    }
    env["aero/ci2vel"] = np.full(data.height, cbar_ft) / (2.0 * v / FT)
    total = np.zeros(data.height)
    for t in terms:
        if t.tree is None:
            raise SystemExit(f"{aircraft}: lift term {t.name} cannot be evaluated from the XML")
        missing = jc._props(t.tree) - set(env)
        if missing:
            raise SystemExit(f"{aircraft}: lift term {t.name} reads {sorted(missing)}")
        total += np.broadcast_to(jc._eval(t.tree, env.__getitem__), total.shape)
    return total


def _toml_value(path: Path, key: str) -> str:
    for line in path.read_text().splitlines():
        k, _, v = line.partition("=")
        if k.strip() == key:
            return v.split("#")[0].strip()
    raise SystemExit(f"{path}: no {key}")


def _compare(
    a: np.ndarray, a_se: np.ndarray, b: np.ndarray, b_se: np.ndarray
) -> tuple[float, float, float]:
    """max |a - b|, rms (a - b), the fraction of the grid within the 95 % band."""
    d = a - b
    band = CRITERIA["band_z"] * np.sqrt(a_se**2 + b_se**2)
    return (
        float(np.max(np.abs(d))),
        float(np.sqrt(np.mean(d**2))),
        float(np.mean(np.abs(d) <= band)),
    )


def _tau_ok(ff: FlapFit) -> tuple[bool, str]:
    if not ff.tau_identified:
        return True, "not identified: at the lower bounds"
    ok = all(
        ff.params[n] <= CRITERIA["tau_bounds"] * ff.std_err_colored[n]
        or ff.params[n] <= CRITERIA["tau_physical_s"]
        for n in ("tau1", "tau2")
    )
    return ok, "identified"


def check_seed(aircraft: str, seed: int, size: int, work: Path) -> list[dict[str, object]]:
    """Fly, ingest, fit and compare one campaign; one row per flap."""
    t0 = time.perf_counter()
    camp = work / f"{aircraft}_{seed}"
    jc.generate_jsbsim_campaign(camp, aircraft=aircraft, seed=seed, size=size, overwrite=True)
    t_fly = time.perf_counter() - t0
    data = model_frame(ingest(camp, progress=False).data)
    t_ing = time.perf_counter() - t0 - t_fly
    data = data.with_columns(
        pl.Series("_cl_meas", measured_lift(data)), pl.Series("_cl_true", truth_lift(camp, data))
    )
    ids = sorted(data["maneuver_id"].unique().to_list())
    train_ids, test_ids = ids[0::2], ids[1::2]
    train = data.filter(pl.col("maneuver_id").is_in(train_ids))
    held = data.filter(pl.col("maneuver_id").is_in(test_ids))
    t1 = time.perf_counter()
    res = fit_kirchhoff(data, maneuvers=train_ids, known="none")
    t_fit = time.perf_counter() - t1
    bins = binned_static_curve(train)
    truth_bins = (
        train.with_columns(pl.Series("alpha_bin", np.round(train["alpha_deg"].to_numpy())))
        .group_by("flap_deg", "alpha_bin")
        .agg(pl.col("_cl_true").mean().alias("CL_true"))
    )
    pred = res.predict(held, known="none")
    rows: list[dict[str, object]] = []
    for flap, ff in sorted(res.fits.items()):
        sub = train.filter(pl.col("flap_deg") == flap)
        ee, ee_cov = ee_static_fit(sub, ff.start)
        grid = bins.filter(pl.col("flap_deg") == flap).join(
            truth_bins.filter(pl.col("flap_deg") == flap).select(
                pl.col("alpha_bin").alias("alpha_deg"), "CL_true"
            ),
            on="alpha_deg",
            how="left",
        )
        ag = grid["alpha_mean_deg"].to_numpy()
        oe_c = static_curves(ff.params, ag, ff.cov_colored)
        ee_c = static_curves(ee, ag, ee_cov)
        row: dict[str, Any] = {
            "aircraft": aircraft,
            "seed": seed,
            "flap_deg": flap,
            "maneuvers_fit": ff.n_maneuvers,
            "samples_fit": ff.n_samples,
            "alpha_min_deg": float(sub["alpha_deg"].min()),
            "alpha_max_deg": float(sub["alpha_deg"].max()),
            "grid_bins": int(ag.size),
            "iterations": ff.iterations,
            "tau_identified": ff.tau_identified,
            "note": ff.note,
            "tau1": ff.params["tau1"],
            "tau2": ff.params["tau2"],
            "tau1_se_col": ff.std_err_colored["tau1"],
            "tau2_se_col": ff.std_err_colored["tau2"],
            "free_tau1": ff.tau_free.get("tau1", math.nan),
            "free_tau2": ff.tau_free.get("tau2", math.nan),
            "free_tau1_se_col": ff.tau_free.get("tau1_se_colored", math.nan),
            "free_tau2_se_col": ff.tau_free.get("tau2_se_colored", math.nan),
            "free_tau_sum_se_col": ff.tau_free.get("tau_sum_se_colored", math.nan),
            "alpha_star_oe_deg": ff.alpha_star_deg,
            "alpha_star_oe_se_deg": math.degrees(ff.std_err_colored["alpha_star"]),
            "alpha_star_ee_deg": math.degrees(ee["alpha_star"]),
            "alpha_star_ee_se_deg": math.degrees(math.sqrt(ee_cov[2, 2])),
            "alpha_cl_max_oe_deg": ff.cl_max[0],
            "cl_max_oe": ff.cl_max[1],
        }
        from aerodelta import _core  # noqa: PLC0415

        a_ee, c_ee = _core.kirchhoff_cl_max(ee)
        row.update(alpha_cl_max_ee_deg=math.degrees(a_ee), cl_max_ee=c_ee)
        row.update(
            cl_max_bins=float(grid["CL"].max()),
            cl_max_truth_bins=float(grid["CL_true"].max()),
        )
        tau_ok, tau_how = _tau_ok(ff)
        row.update(tau_ok=tau_ok, tau_how=tau_how)
        for c in ("CL", "Cm"):
            m, r, f = _compare(oe_c[c], oe_c[f"{c}_se"], ee_c[c], ee_c[f"{c}_se"])
            row.update({f"{c}_oe_ee_max": m, f"{c}_oe_ee_rms": r, f"{c}_oe_ee_frac": f})
            gb, gb_se = grid[c].to_numpy(), grid[f"{c}_se"].to_numpy()
            m, r, f = _compare(oe_c[c], oe_c[f"{c}_se"], gb, gb_se)
            row.update({f"{c}_oe_bins_max": m, f"{c}_oe_bins_rms": r, f"{c}_oe_bins_frac": f})
            row[f"{c}_band_median"] = float(
                np.median(CRITERIA["band_z"] * np.hypot(oe_c[f"{c}_se"], ee_c[f"{c}_se"]))
            )
        tr = grid["CL_true"].to_numpy()
        m, r, f = _compare(oe_c["CL"], oe_c["CL_se"], tr, np.zeros_like(tr))
        row.update(CL_oe_truth_max=m, CL_oe_truth_rms=r, CL_oe_truth_frac=f)
        m, r, f = _compare(grid["CL"].to_numpy(), grid["CL_se"].to_numpy(), tr, np.zeros_like(tr))
        row.update(CL_bins_truth_max=m, CL_bins_truth_rms=r, CL_bins_truth_frac=f)
        sel = held["flap_deg"].to_numpy() == flap
        ha = held["alpha_deg"].to_numpy()[sel]
        ee_h = static_curves(ee, ha)
        for c, z in (
            ("CL", held["_cl_meas"].to_numpy()[sel]),
            ("Cm", held["Cm_meas"].to_numpy()[sel]),
        ):
            y_oe = pred[f"{c}_model"].to_numpy()[sel]
            y_bins = np.interp(ha, ag, grid[c].to_numpy())
            row[f"theil_{c}_oe"] = theil(z, y_oe)
            row[f"theil_{c}_ee"] = theil(z, ee_h[c])
            row[f"theil_{c}_bins"] = theil(z, y_bins)
        row["held_out_samples"] = int(sel.sum())
        row["floor_ok"] = bool(
            tau_ok
            and row["CL_oe_ee_frac"] >= CRITERIA["grid_fraction"]
            and row["Cm_oe_ee_frac"] >= CRITERIA["grid_fraction"]
        )
        row["meas_vs_truth_cl_rms"] = float(
            np.sqrt(np.mean((data["_cl_meas"].to_numpy() - data["_cl_true"].to_numpy()) ** 2))
        )
        rows.append(row)
    print(
        f"{aircraft} seed {seed}: flew {t_fly:.0f} s, ingested {t_ing:.0f} s, fitted "
        f"{t_fit:.1f} s ({len(res.fits)} flaps, {len(train_ids)} maneuvers)",
        file=sys.stderr,
    )
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(REPORT_SEEDS))
    ap.add_argument("--aircraft", nargs="+", default=["f15", "DHC6"])
    ap.add_argument("--size", type=int, default=6, help="repetitions per (flap, entry)")
    ap.add_argument("--json", type=Path, help="write the rows here")
    args = ap.parse_args(argv)
    rows: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for ac in args.aircraft:
            for s in args.seeds:
                rows += check_seed(ac, s, args.size, Path(tmp))
    df = pl.DataFrame(rows, infer_schema_length=None)
    with pl.Config(tbl_rows=100, tbl_cols=40, tbl_width_chars=300, float_precision=4):
        print(
            df.select(
                "aircraft", "seed", "flap_deg", "alpha_min_deg", "alpha_max_deg", "tau_identified",
                "free_tau1", "free_tau2", "free_tau_sum_se_col", "alpha_star_oe_deg",
                "alpha_star_ee_deg", "alpha_cl_max_oe_deg", "alpha_cl_max_ee_deg", "cl_max_oe",
                "cl_max_ee", "cl_max_bins", "cl_max_truth_bins",
            )
        )  # fmt: skip
        print(
            df.select(
                "aircraft", "seed", "flap_deg", "grid_bins", "CL_band_median", "CL_oe_ee_max",
                "CL_oe_ee_frac", "Cm_band_median",
                "Cm_oe_ee_max", "Cm_oe_ee_frac", "CL_oe_bins_max", "CL_oe_bins_frac",
                "Cm_oe_bins_max", "Cm_oe_bins_frac", "CL_oe_truth_max", "CL_oe_truth_frac",
                "CL_bins_truth_frac", "floor_ok",
            )
        )  # fmt: skip
        print(
            df.select(
                "aircraft", "seed", "flap_deg", "held_out_samples", "theil_CL_oe", "theil_CL_ee",
                "theil_CL_bins", "theil_Cm_oe", "theil_Cm_ee", "theil_Cm_bins",
            )
        )  # fmt: skip
    n = df.height
    met = int(df["floor_ok"].sum())
    print(
        f"floor (tau -> 0 and OE within the EE-K band on >= 90 % of the grid, C_L and C_m): "
        f"{met}/{n} (aircraft, seed, flap) fits; tau -> 0 {int(df['tau_ok'].sum())}/{n}"
    )
    if args.json:
        args.json.write_text(
            json.dumps({"criteria": CRITERIA, "seeds": args.seeds, "rows": rows}, indent=1,
                       default=float)
        )  # fmt: skip
    return 0 if met == n else 1


if __name__ == "__main__":
    sys.exit(main())
