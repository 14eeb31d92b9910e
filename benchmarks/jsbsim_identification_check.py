"""Check the Δ-model identification against the truth on JSBSim aircraft (issue 16).

For each aircraft (``f15``, ``DHC6``) and seed: fly a JSBSim campaign
(``aerodelta.jsbsim_campaign.generate_jsbsim_campaign``, the aircraft's default withheld terms
and withhold alpha, sensor noise scale 1, no turbulence unless ``--turbulence``), ingest it,
hold out every fifth maneuver, fit the rest against the campaign's qualified model
(``qualified="columns"``: ``Cl_sim``, ``Cn_sim``, ``CY_sim``) with the thesis structures
(``selection=None``) and with the default stepwise selection (optionally with a bootstrap over
maneuvers), and compare every identified bin with the true Δ derivative at the bin centre
(``true_delta_derivative``, from the aircraft's XML). Reported per aircraft, structure and
coefficient:

- **consistency**: rms over the samples above the withhold alpha of
  ``C_meas - C_sim - dC_true`` (what the fit would have to explain that is not the true Δ:
  sensor noise, the 50 Hz rate differences, anything the qualified columns leave out) over the
  rms of ``dC_true``;
- **material terms**: a (parameter, flap, bin) is material where |true Δ derivative| at the bin
  centre is at least 20 % of its largest value over the flap's fitted bin centres
  (alpha >= alpha_l); per identified material bin: relative error |estimate - truth| / |truth|
  (median and 90th percentile), the share whose 95 % CR2 interval (``ci95_lower``..
  ``ci95_upper``) holds the truth, the same for the bootstrap band (``band_lower``..
  ``band_upper``) when run, and for the smoothed parameter's band at the bin centre
  (``smoothed``); the share of material bins identified; for the selection, the
  (seed, flap) cases where a material term is not kept;
- **zero-truth terms**: share of identified bins (alpha >= alpha_l) of parameters whose
  truth is zero that the fit calls ``significant`` (its band excludes zero), and in brackets
  with ``p_value < 0.05`` (CR2 alone) (``beta_deg^2``, ``beta_deg^3`` are left out: the
  truth gives the slope at beta = 0 only, and the DHC-6's Clb(beta, alpha) is nonlinear in
  beta);
- **held-out TIC ratio**: Theil inequality of the extended model over the qualified model's on
  the held-out maneuvers, and of qualified + the true Δ.

Run: ``python benchmarks/jsbsim_identification_check.py --aircraft f15 --seeds 20
--first-seed 101 [--size 10] [--bootstrap 100] [--out rows.parquet]``; ``--summarize
rows_a.parquet rows_b.parquet`` prints the table of saved rows. About 12-15 s per campaign to
fly (size 10) and 1-10 s per fit on 2 cores. ``--campaigns DIR`` keeps the flown campaigns
and reuses them on the next run (to compare two versions of the fit on the same flights:
run the script twice with each version on ``PYTHONPATH``); ``--structures stepwise`` runs
only the selecting fit. The seeds run as tasks on the distributed engine
(``aerodelta.plan.suite.run_cases``: ``--workers N`` local processes, default 2, or
``--scheduler ADDRESS``; ``--workers 0``: in this process); ``--resume DIR`` keeps each finished
seed and a rerun skips it. The rows do not depend on the number of workers (the ``fly_s`` and
``fit_s`` timings do).
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

import aerodelta as ad
from aerodelta import jsbsim_campaign as jc
from aerodelta.fit import COEFFICIENTS, FitConfig, model_frame, qualified_coefficients
from aerodelta.fit import theil_inequality as tic
from aerodelta.jsbsim_campaign import generate_jsbsim_campaign, true_delta_derivative
from aerodelta.plan.suite import run_cases

#: Fit regressor -> truth regressor of ``truth.json`` (others have zero truth).
_TRUTH_REG = {
    "beta_deg": "beta_deg",
    "phat": "phat",
    "rhat": "rhat",
    "deadband(da_deg, 2)": "da_deg",
    "da_deg": "da_deg",
    "dr_deg": "dr_deg",
}
#: Regressors whose truth the campaign does not give (higher orders of a beta table).
_UNKNOWN_TRUTH = {"beta_deg^2", "beta_deg^3", "abs(beta_deg)"}
MATERIAL = 0.2


def _true_intercept(camp: Path, coefficient: str, flap_deg: float, alpha_deg: float) -> float:
    """True Δ at zero regressors (the ``1`` regressor), which ``truth.json`` does not give:
    the withheld terms (full - qualified) evaluated from the XML at beta = p = r = controls =
    0. Nonzero where a table holds the coefficient itself rather than a derivative (the
    DHC-6's Clb(beta, alpha) is -0.01 at beta = 0, alpha = 10 deg and +0.02 at 14 deg)."""
    doc = json.loads((camp / "truth" / "truth.json").read_text())
    key = (doc["aircraft"], doc["withhold_alpha_deg"], coefficient, flap_deg)
    if key not in _INTERCEPTS:
        cfg, xml = jc._resolve_aircraft(doc["aircraft"], jc._root(None))
        names = {w["name"] for w in doc["withheld"] if w["coefficient"] == coefficient}
        terms = [t for t in jc._aero_terms(xml, jc._root(None)) if t.name in names]
        grid = np.asarray(doc["alpha_grid_deg"], dtype=float)
        walpha = float(doc["withhold_alpha_deg"])
        total = np.zeros_like(grid)
        for t in terms:
            for a, sign in ((grid, 1.0), (np.minimum(grid, walpha), -1.0)):
                base = {
                    **jc._REF_PROPS,
                    "aero/alpha-rad": a * jc.D2R,
                    "aero/alpha-deg": a,
                    cfg.flap_deg_prop: np.full_like(a, flap_deg),
                    "fcs/flap-pos-norm": np.full_like(a, flap_deg * cfg.flap_norm_per_deg),
                    "velocities/mach": np.full_like(a, cfg.mach_ref),
                }
                val = jc._eval(t.tree, lambda prop, base=base: base.get(prop, 0.0))
                total = total + sign * np.broadcast_to(val, a.shape)
        _INTERCEPTS[key] = (grid, total)
    grid, total = _INTERCEPTS[key]
    return float(np.interp(alpha_deg, grid, total))


_INTERCEPTS: dict[tuple[str, float, str, float], tuple[np.ndarray, np.ndarray]] = {}


def _truth_frame(camp: Path) -> pl.DataFrame:
    return pl.concat(
        [
            pl.read_parquet(f)
            .select(
                "t",
                "alpha_deg",
                *[f"{c}_sim" for c in COEFFICIENTS],
                *[f"d{c}_true" for c in COEFFICIENTS],
            )
            .rename({"alpha_deg": "alpha_true_deg"})
            .with_columns(pl.lit(f.stem).alias("maneuver_id"))
            for f in sorted((camp / "truth").glob("*.parquet"))
            if f.stem != "true_delta"
        ]
    )


def _consistency(data: pl.DataFrame, truth: pl.DataFrame, walpha: float) -> dict[str, float]:
    """Per coefficient: rms(C_meas - C_sim - dC_true) / rms(dC_true) above the withhold alpha."""
    j = data.select("maneuver_id", "t", *[f"{c}_meas" for c in COEFFICIENTS]).join(
        truth, on=["maneuver_id", "t"], how="inner"
    )
    j = j.filter(pl.col("alpha_true_deg") > walpha)
    out = {}
    for c in COEFFICIENTS:
        d = j[f"d{c}_true"].to_numpy()
        res = j[f"{c}_meas"].to_numpy() - j[f"{c}_sim"].to_numpy() - d
        rd = float(np.sqrt(np.mean(d**2)))
        out[c] = float(np.sqrt(np.mean(res**2))) / rd if rd > 0 else math.inf
        out[f"{c}_abs"] = float(np.sqrt(np.mean(res**2)))
    return out


def _tic_ratios(result: ad.FitResult, test: pl.DataFrame, truth: pl.DataFrame) -> dict[str, float]:
    mf = model_frame(test)
    qual = qualified_coefficients(mf, "columns")
    ev = pl.concat(
        [
            result.model.evaluate(mf),
            qual,
            test.select("maneuver_id", "t", *[f"{c}_meas" for c in COEFFICIENTS]),
        ],
        how="horizontal",
    )
    j = ev.join(truth, on=["maneuver_id", "t"], how="inner")
    out = {}
    for c in COEFFICIENTS:
        meas, q = j[f"{c}_meas"].to_numpy(), j[f"{c}_qual"].to_numpy()
        t0 = tic(meas, q)
        out[f"tic_{c}"] = tic(meas, q + j[f"d{c}_blended"].to_numpy()) / t0
        out[f"tic_true_{c}"] = tic(meas, q + j[f"d{c}_true"].to_numpy()) / t0
    return out


def _bin_rows(result: ad.FitResult, camp: Path, config: FitConfig) -> pl.DataFrame:
    """One row per fitted (coefficient, flap, parameter, bin) with its truth."""
    p = result.params
    spec = result.model.to_spec()
    flaps = list(spec["flaps_deg"])
    centre = 0.5 * (p["alpha_lo_deg"].to_numpy() + p["alpha_hi_deg"].to_numpy())
    truth = np.zeros(p.height)
    known = np.ones(p.height, dtype=bool)
    alpha_l = np.zeros(p.height)
    for i, (coef, flap, reg) in enumerate(
        zip(p["coefficient"], p["flap_deg"], p["regressor"], strict=True)
    ):
        alpha_l[i] = spec["coefficients"][coef]["alpha_l_deg"][flaps.index(flap)]
        if reg in _UNKNOWN_TRUTH:
            known[i] = False
        elif reg in _TRUTH_REG:
            truth[i] = float(true_delta_derivative(camp, coef, _TRUTH_REG[reg], flap, centre[i]))
        elif reg == "1":
            truth[i] = _true_intercept(camp, coef, flap, centre[i])
    has_band = "band_lower" in p.columns and config.bootstrap > 0
    # the smoothed parameter's band at the bin centre (the table the simulator flies)
    s_lo, s_hi = np.full(p.height, math.nan), np.full(p.height, math.nan)
    if has_band:
        sm = result.smoothed
        for (coef, flap, name), g in sm.group_by(["coefficient", "flap_deg", "param"]):
            if g["note"][0] != "":
                continue  # set to zero: no band
            rows = np.flatnonzero(
                (p["coefficient"] == coef).to_numpy()
                & (p["flap_deg"] == flap).to_numpy()
                & (p["param"] == name).to_numpy()
            )
            gs = g.sort("alpha_deg")
            grid = gs["alpha_deg"].to_numpy()
            s_lo[rows] = np.interp(centre[rows], grid, gs["lower"].to_numpy())
            s_hi[rows] = np.interp(centre[rows], grid, gs["upper"].to_numpy())
    out = p.select(
        "coefficient",
        "flap_deg",
        "param",
        "regressor",
        "estimate",
        "ci95_lower",
        "ci95_upper",
        "p_value",
        *(["significant"] if "significant" in p.columns else []),
        "identifiable",
        *([] if not has_band else ["band_lower", "band_upper"]),
    ).with_columns(
        pl.Series("centre_deg", centre),
        pl.Series("truth", truth),
        pl.Series("truth_known", known),
        pl.Series("alpha_l_deg", alpha_l),
        pl.Series("smooth_lower", s_lo),
        pl.Series("smooth_upper", s_hi),
    )
    if not has_band:
        out = out.with_columns(
            pl.lit(math.nan).alias("band_lower"), pl.lit(math.nan).alias("band_upper")
        )
    out = out.filter(pl.col("centre_deg") >= pl.col("alpha_l_deg"))
    # material: |truth| >= 20 % of the term's largest |truth| over the flap's bins
    out = out.with_columns(
        pl.col("truth").abs().max().over("coefficient", "flap_deg", "param").alias("truth_max")
    ).with_columns(
        (
            (pl.col("truth").abs() >= MATERIAL * pl.col("truth_max")) & (pl.col("truth_max") > 0)
        ).alias("material"),
        ((pl.col("truth_max") == 0) & pl.col("truth_known")).alias("zero_truth"),
    )
    return out


def _dropped(result: ad.FitResult, camp: Path) -> pl.DataFrame:
    """Per (coefficient, flap, parameter) of the selection: whether a term with nonzero truth
    on the fitted range is kept."""
    s = result.structure
    rows = []
    for row in s.iter_rows(named=True):
        reg = row["regressor"]
        grid = np.arange(0.0, 60.0, 0.5)
        if reg == "1":
            t = np.array(
                [_true_intercept(camp, row["coefficient"], row["flap_deg"], a) for a in grid]
            )
        elif reg in _TRUTH_REG:
            t = true_delta_derivative(
                camp, row["coefficient"], _TRUTH_REG[reg], row["flap_deg"], grid
            )
        else:
            continue
        if np.any(t != 0):
            rows.append(
                {
                    "coefficient": row["coefficient"],
                    "flap_deg": row["flap_deg"],
                    "param": row["param"],
                    "kept": bool(row["kept"]),
                    "note": str(row["note"]),
                }
            )
    return pl.DataFrame(rows)


def one_seed(
    seed: int, opts: dict[str, Any]
) -> tuple[list[pl.DataFrame], list[dict[str, Any]], list[pl.DataFrame]]:
    """One campaign (a task on the engine): its bin rows, campaign row per structure and the
    selection's dropped terms. ``opts``: ``aircraft``, ``size``, ``turbulence``,
    ``bootstrap``, ``structures``, ``campaigns`` (the command line's)."""
    aircraft, size, turbulence = opts["aircraft"], opts["size"], opts["turbulence"]
    bootstrap, structures, campaigns = opts["bootstrap"], opts["structures"], opts["campaigns"]
    configs = {
        "thesis": FitConfig(selection=None, bootstrap=bootstrap),
        "stepwise": FitConfig(bootstrap=bootstrap),
        # the default fit with the qualified model compared at full band (before session 27)
        "stepwise_full_band": FitConfig(bootstrap=bootstrap, smoother_match=False),
        # the default fit without |beta| riding with beta (before session 27)
        "stepwise_no_kink": FitConfig(bootstrap=bootstrap, beta_kink=False),
    }
    configs = {k: v for k, v in configs.items() if k in structures}
    bins: list[pl.DataFrame] = []
    camps: list[dict[str, Any]] = []
    drops: list[pl.DataFrame] = []
    with tempfile.TemporaryDirectory() as tmp:
        keep = campaigns is not None
        root = campaigns if campaigns is not None else Path(tmp)
        camp = root / f"{aircraft}_{seed}_size{size}_turb{turbulence:g}"
        t0 = time.perf_counter()
        if keep and (camp / "truth" / "truth.json").is_file():
            # flown before with the same seed, size and turbulence: reused
            walpha = float(
                json.loads((camp / "truth" / "truth.json").read_text())["withhold_alpha_deg"]
            )
        else:
            info = generate_jsbsim_campaign(
                camp, aircraft=aircraft, seed=seed, size=size, turbulence=turbulence
            )
            walpha = info.withhold_alpha_deg
        t_fly = time.perf_counter() - t0
        data = ad.ingest(camp, compat=False, progress=False).data
        truth = _truth_frame(camp)
        cons = _consistency(data, truth, walpha)
        ids = data["maneuver_id"].unique().sort().to_list()
        held = set(ids[::5])
        train = data.filter(~pl.col("maneuver_id").is_in(held))
        test = data.filter(pl.col("maneuver_id").is_in(held))
        for name, base in configs.items():
            cfg = FitConfig(**{**base.__dict__, "seed": seed})
            t1 = time.perf_counter()
            r = ad.fit(train, qualified="columns", config=cfg)
            t_fit = time.perf_counter() - t1
            tag = {"aircraft": aircraft, "seed": seed, "structure": name}
            b = _bin_rows(r, camp, cfg)
            bins.append(b.with_columns(*[pl.lit(v).alias(k) for k, v in tag.items()]))
            camps.append(
                {
                    **tag,
                    "maneuvers": len(ids),
                    "fly_s": t_fly,
                    "fit_s": t_fit,
                    **{f"cons_{k}": v for k, v in cons.items()},
                    **_tic_ratios(r, test, truth),
                }
            )
            if name.startswith("stepwise"):
                d = _dropped(r, camp)
                if d.height:
                    drops.append(d.with_columns(*[pl.lit(v).alias(k) for k, v in tag.items()]))
    return bins, camps, drops


def run(args: argparse.Namespace) -> tuple[pl.DataFrame, pl.DataFrame, pl.DataFrame]:
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    opts = {
        "aircraft": args.aircraft,
        "size": args.size,
        "turbulence": args.turbulence,
        "bootstrap": args.bootstrap,
        "structures": tuple(args.structures.split(",")),
        "campaigns": args.campaigns,
    }
    t_start = time.perf_counter()
    res = run_cases(
        one_seed,
        [(seed, opts) for seed in seeds],
        labels=[f"{args.aircraft} seed {seed}" for seed in seeds],
        workers=args.workers,
        scheduler=args.scheduler,
        resume=args.resume,
        name=f"jsbsim-identification-{args.aircraft}",
    )
    for f in res.failures:
        print(f"FAILED {f.label}: {f.error}")
    bins: list[pl.DataFrame] = []
    camps: list[dict[str, Any]] = []
    drops: list[pl.DataFrame] = []
    for r in res.results:
        if r is not None:
            bins += r[0]
            camps += r[1]
            drops += r[2]
    print(
        f"{args.aircraft}: {len(seeds) - len(res.failures)} campaigns in "
        f"{time.perf_counter() - t_start:.0f} s ({res.resumed} read back from --resume, "
        f"{len(res.failures)} failed)",
        flush=True,
    )
    bins_df = pl.concat(bins, how="diagonal_relaxed")
    drops_df = pl.concat(drops) if drops else pl.DataFrame()
    return bins_df, pl.DataFrame(camps), drops_df


def _q(x: np.ndarray, q: float) -> float:
    return float(np.quantile(x, q)) if x.size else math.nan


def summarize(bins: pl.DataFrame, camps: pl.DataFrame, drops: pl.DataFrame) -> str:
    """The markdown table of the check (one row per aircraft, structure, coefficient)."""
    lines = [
        "| aircraft | structure | coef | consistency | material terms | bins (ident.) | "
        "rel. err median / p90 | CR2 95 % holds truth | bootstrap band holds truth | "
        "material term dropped | zero-truth significant (the fit's `significant`; p < 0.05) | "
        "TIC ext/qual | "
        "TIC (qual + true Δ)/qual |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for (ac, st), g in bins.group_by(["aircraft", "structure"], maintain_order=True):
        cg = camps.filter((pl.col("aircraft") == ac) & (pl.col("structure") == st))
        for c in COEFFICIENTS:
            h = g.filter(pl.col("coefficient") == c)
            mat = h.filter(pl.col("material"))
            mid = mat.filter(pl.col("identifiable"))
            terms = ", ".join(sorted(set(mat["param"].to_list()))) or "-"
            est, tr = mid["estimate"].to_numpy(), mid["truth"].to_numpy()
            rel = np.abs(est - tr) / np.abs(tr)
            inside = (mid["ci95_lower"].to_numpy() <= tr) & (tr <= mid["ci95_upper"].to_numpy())
            blo, bhi = mid["band_lower"].to_numpy(), mid["band_upper"].to_numpy()
            okb = np.isfinite(blo) & np.isfinite(bhi)
            band = (
                f"{100 * np.mean(((blo <= tr) & (tr <= bhi))[okb]):.0f} % of {okb.sum()}"
                if okb.any()
                else "-"
            )
            if "smooth_lower" in mid.columns:
                slo, shi = mid["smooth_lower"].to_numpy(), mid["smooth_upper"].to_numpy()
                oks = np.isfinite(slo) & np.isfinite(shi)
                if oks.any():
                    inside_s = ((slo <= tr) & (tr <= shi))[oks]
                    band += f"; smoothed {100 * np.mean(inside_s):.0f} %"
            zero = h.filter(pl.col("zero_truth") & pl.col("identifiable"))
            zsig = zero["p_value"].to_numpy() < 0.05
            # the fit's own verdict (band excludes zero; rows saved before it: p < 0.05 only)
            zsig_fit = zero["significant"].to_numpy() if "significant" in zero.columns else None
            if st.startswith("stepwise") and drops.height:
                dg = drops.filter(
                    (pl.col("aircraft") == ac)
                    & (pl.col("coefficient") == c)
                    & (pl.col("structure") == st)
                )
                nd = dg.filter(~pl.col("kept"))
                dropped = (
                    f"{nd.height} of {dg.height} ("
                    + ", ".join(f"{k} {v}x" for k, v in nd["param"].value_counts().iter_rows())
                    + ")"
                    if nd.height
                    else f"0 of {dg.height}"
                )
            else:
                dropped = "n/a (fixed)"
            cons = cg[f"cons_{c}"].to_numpy()
            cons_txt = (
                f"{np.median(cons):.2f}"
                if np.all(np.isfinite(cons))
                else f"no Δ (rms {np.median(cg[f'cons_{c}_abs'].to_numpy()):.4f})"
            )
            lines.append(
                f"| {ac} | {st} | {c} | {cons_txt} | {terms} | "
                f"{mat.height} ({mid.height}) | "
                + (
                    f"{100 * np.median(rel):.0f} % / {100 * _q(rel, 0.9):.0f} % | "
                    f"{100 * np.mean(inside):.0f} % | "
                    if mid.height
                    else "- | - | "
                )
                + f"{band} | {dropped} | "
                + (
                    f"{100 * np.mean(zsig_fit) if zsig_fit.size else math.nan:.1f} % (p < 0.05: "
                    if zsig_fit is not None
                    else ""
                )
                + f"{100 * np.mean(zsig) if zsig.size else math.nan:.1f} %"
                + (")" if zsig_fit is not None else "")
                + f" of {zsig.size} | "
                f"{np.median(cg[f'tic_{c}']):.2f} (max {cg[f'tic_{c}'].max():.2f}) | "
                f"{np.median(cg[f'tic_true_{c}']):.2f} |"
            )
    return "\n".join(lines)


def per_term(bins: pl.DataFrame) -> str:
    """Per material parameter: identified share, relative error and CR2 coverage."""
    lines = [
        "| aircraft | structure | param | flap | material bins (ident.) | rel. err median / p90 | "
        "CR2 95 % holds truth | median estimate / truth |",
        "|---|---|---|---|---|---|---|---|",
    ]
    m = bins.filter(pl.col("material"))
    for (ac, st, par, fl), g in m.group_by(
        ["aircraft", "structure", "param", "flap_deg"], maintain_order=True
    ):
        mid = g.filter(pl.col("identifiable"))
        tr, est = mid["truth"].to_numpy(), mid["estimate"].to_numpy()
        if tr.size:
            rel = np.abs(est - tr) / np.abs(tr)
            ins = (mid["ci95_lower"].to_numpy() <= tr) & (tr <= mid["ci95_upper"].to_numpy())
            cells = (
                f"{100 * np.median(rel):.0f} % / {100 * _q(rel, 0.9):.0f} % | "
                f"{100 * np.mean(ins):.0f} % | {np.median(est / tr):.2f}"
            )
        else:
            cells = "- | - | -"
        lines.append(f"| {ac} | {st} | {par} | {fl:g} | {g.height} ({mid.height}) | {cells} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--aircraft", default="f15", choices=["f15", "DHC6"])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=101)
    ap.add_argument("--size", type=int, default=10, help="repetitions per flap and entry kind")
    ap.add_argument("--bootstrap", type=int, default=0)
    ap.add_argument("--turbulence", type=float, default=0.0)
    ap.add_argument("--out", type=Path, default=None, help="save the rows (prefix)")
    ap.add_argument(
        "--campaigns",
        type=Path,
        default=None,
        help="keep the flown campaigns in this folder and reuse them when run again "
        "(default: a temporary folder)",
    )
    ap.add_argument(
        "--structures",
        default="thesis,stepwise",
        help="comma list of the fits to run: thesis, stepwise, stepwise_full_band (the default "
        "fit without FitConfig.smoother_match), stepwise_no_kink (without FitConfig.beta_kink)",
    )
    ap.add_argument("--summarize", type=Path, nargs="+", default=None, help="saved prefixes")
    ap.add_argument("--workers", type=int, default=2, help="engine workers (0: this process)")
    ap.add_argument("--scheduler", default=None, help="a Dask scheduler's address")
    ap.add_argument("--resume", default=None, help="keep finished seeds here and skip them")
    args = ap.parse_args()
    if args.summarize:
        bins = pl.concat(
            [pl.read_parquet(f"{p}_bins.parquet") for p in args.summarize], how="diagonal_relaxed"
        )
        camps = pl.concat([pl.read_parquet(f"{p}_camps.parquet") for p in args.summarize])
        drops = pl.concat(
            [
                pl.read_parquet(f"{p}_drops.parquet")
                for p in args.summarize
                if Path(f"{p}_drops.parquet").exists()
            ],
            how="diagonal_relaxed",
        )
    else:
        bins, camps, drops = run(args)
        if args.out is not None:
            bins.write_parquet(f"{args.out}_bins.parquet")
            camps.write_parquet(f"{args.out}_camps.parquet")
            if drops.height:
                drops.write_parquet(f"{args.out}_drops.parquet")
    seeds = sorted(set(camps["seed"].to_list()))
    print(f"\nseeds {seeds[0]}..{seeds[-1]} ({len(seeds)} campaigns per aircraft)")
    timing = camps.group_by("aircraft", "structure").agg(
        pl.col("maneuvers").median(), pl.col("fly_s").median(), pl.col("fit_s").median()
    )
    print(timing)
    print(summarize(bins, camps, drops))
    print()
    print(per_term(bins))


if __name__ == "__main__":
    main()
