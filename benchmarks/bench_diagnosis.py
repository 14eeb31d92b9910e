"""Diagnosis speed (issue 7): a 200-maneuver campaign, the full vocabulary, 5-fold
cross-validation by maneuver, against a straightforward statsmodels loop over the same
candidate fits, in the same run.

The peer refits every candidate model of the greedy selection on the training maneuvers of
each fold with ``statsmodels.OLS`` on the dense design (the same hat-basis columns, per
coefficient) and predicts the held-out fold. Its first selection step is timed in full and
scaled to the number of candidate fits the aerodelta run made (printed), since the whole loop
would take many minutes.

    python benchmarks/bench_diagnosis.py [--size default|N]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import statsmodels.api as sm

from aerodelta.campaign import generate_campaign
from aerodelta.diagnosis import core, diagnose
from aerodelta.diagnosis.cv import HatGrid
from aerodelta.diagnosis.data import load_inputs
from aerodelta.diagnosis.regressors import design_columns, measurement_columns
from aerodelta.diagnosis.simulator import load_simulator
from aerodelta.diagnosis.vocabulary import default_vocabulary
from aerodelta.ingest import ingest


def _dense(alpha, aero, glob, grid):
    j, w1 = grid.locate(alpha)
    n, r_n = aero.shape
    x = np.zeros((n, grid.n * r_n))
    rows = np.arange(n)
    for r in range(r_n):
        x[rows, j * r_n + r] += (1 - w1) * aero[:, r]
        x[rows, (j + 1) * r_n + r] += w1 * aero[:, r]
    keep = np.abs(x).sum(axis=0) > 0
    return np.hstack([x[:, keep], glob])


def peer_first_step(data, folds_of_row, knot_deg):
    """statsmodels: every candidate of the first step, every fold, every coefficient."""
    frame, ac, _ = load_inputs(data, None)
    sim = load_simulator(None, frame, ac.cbar_m)
    sim_c = sim.predict(frame)
    meas = measurement_columns(frame, sim, ac)
    vocab = default_vocabulary()
    alpha = frame["alpha_deg"].to_numpy()
    grid = HatGrid.covering(alpha, knot_deg)
    fits = 0
    t0 = time.perf_counter()
    for coef in ("Cl", "Cn", "CY"):
        y = frame[f"{coef}_meas"].to_numpy() - sim_c[coef]
        for cand in vocab.for_coefficient(coef):
            aero = [r for r in cand.regressors if not cand.global_]
            glob = [r for r in cand.regressors if cand.global_]
            ax, gx = design_columns(
                frame, coef, aero_names=aero, glob_names=glob, vocab=vocab, meas=meas
            )
            x = _dense(alpha, ax, gx, grid)
            for q in range(5):
                tr = folds_of_row != q
                res = sm.OLS(y[tr], x[tr]).fit()
                _ = np.sum((y[~tr] - x[~tr] @ res.params) ** 2)
                fits += 1
    return time.perf_counter() - t0, fits


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--size", default="default")
    args = ap.parse_args()
    size = int(args.size) if args.size.isdigit() else args.size
    with tempfile.TemporaryDirectory() as tmp:
        camp = Path(tmp) / "c"
        generate_campaign(camp, effects="default", seed=7, size=size)
        data = ingest(camp, compat=False, progress=False).data
    n_fits = {"n": 0}
    orig = core.forward_select

    def counting(design, stats, cands, cfg):
        sel = orig(design, stats, cands, cfg)
        steps = len([s for s in sel.selected if s.candidate.kind != "measurement"]) + 1
        n_fits["n"] += 5 * (len(cands) * steps)
        return sel

    core.forward_select = counting
    t0 = time.perf_counter()
    d = diagnose(data)
    ours = time.perf_counter() - t0
    core.forward_select = orig
    man = sorted(set(data["maneuver_id"].to_list()))
    fold_of = {m: i % 5 for i, m in enumerate(man)}
    folds_of_row = np.array([fold_of[m] for m in d.predictions["maneuver_id"].to_list()])
    peer_t, peer_fits = peer_first_step(data, folds_of_row, core.DiagnoseConfig().knot_deg)
    peer_total = peer_t / peer_fits * n_fits["n"]
    print(f"campaign: {len(man)} maneuvers, {data.height} rows")
    print(
        f"aerodelta diagnose (everything, incl. the gap map and roll-off): {ours:.1f} s "
        f"(target < 30 s), about {n_fits['n']} candidate fits"
    )
    print(
        f"statsmodels loop: {peer_fits} candidate fits in {peer_t:.1f} s "
        f"({1000 * peer_t / peer_fits:.0f} ms per fit) -> {peer_total:.0f} s for the same "
        f"{n_fits['n']} fits"
    )
    print(f"ratio statsmodels / aerodelta: {peer_total / ours:.1f}x (floor >= 10x)")
    for c in ("Cl", "Cn", "CY"):
        print(f"  {c}: verdict {d.verdict(c)}; significant {d.significant_effects(c)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
