"""Diagnosis speed and memory (issues 7, 17 and 18): a 200-maneuver campaign, the full
vocabulary, 5-fold cross-validation by maneuver, against a straightforward statsmodels loop
over the same candidate fits, in the same run; then the time and the peak memory of the
diagnosis per maneuver at several campaign sizes.

The peer refits every candidate model of the greedy selection on the training maneuvers of
each fold with ``statsmodels.OLS`` on the dense design (the same hat-basis columns, per
coefficient) and predicts the held-out fold. Its first selection step is timed in full and
scaled to the number of candidate fits the aerodelta run made (printed), since the whole loop
would take many minutes.

Memory is the process's peak resident set during ``diagnose`` above its resident set just
before (the peak is reset first where Linux allows, ``/proc/self/clear_refs``), the peak
itself (the records, held by the caller, included), and the peak of the arrays numpy
allocates (tracemalloc, in a second run: it slows numpy down; ``--no-traced`` skips it).
Time is wall and CPU seconds of the process (on a shared machine the CPU seconds are the
steadier measure; the selection runs single-threaded, the simulator's evaluation in threads).

    python benchmarks/bench_diagnosis.py [--size default|N] [--scaling 2,5,10] [--no-peer]
        [--no-traced]

``--scaling`` takes repetitions per (flap, kind, pusher) cell of the virtual campaign (40
maneuvers each): ``--scaling 50`` is issue 17's 2,000-maneuver floor. The campaigns come out
of the ingest in flight order (``m1000_...`` after ``m999_...``), as a user's records would.
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import polars as pl
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


def _status_mb(key: str) -> float | None:
    """``VmRSS``/``VmHWM`` of this process from ``/proc/self/status``, MB (None elsewhere)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def _reset_peak() -> bool:
    """Reset the kernel's peak resident set of this process (Linux); False if not possible."""
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as fh:
            fh.write("5")
    except OSError:
        return False
    return True


def measure(data: pl.DataFrame, traced: bool = True) -> dict[str, float]:
    """Wall and CPU time of ``diagnose(data)``, the peak resident set it adds and the peak
    itself, MB, and (second run, unless ``traced`` is false: NaN) the peak of numpy's
    allocations, MB."""
    before = _status_mb("VmRSS")
    reset = _reset_peak()
    max_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    t0, c0 = time.perf_counter(), time.process_time()
    diagnose(data)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    peak = _status_mb("VmHWM") if reset else None
    if peak is None or before is None:
        # no reset: the lifetime peaks after and before (understates if ingest peaked higher)
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        before = max_before
    out = {"wall": wall, "cpu": cpu, "rss_added": peak - before, "peak": peak, "traced": np.nan}
    if traced:
        tracemalloc.start()
        diagnose(data)
        out["traced"] = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()
    return out


def _campaign(size: str | int, tmp: str) -> pl.DataFrame:
    camp = Path(tmp) / f"c{size}"
    generate_campaign(camp, effects="default", seed=7, size=size)
    return ingest(camp, compat=False, progress=False).data


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--size", default="default")
    ap.add_argument("--scaling", default="2,5,10", help="repetitions per cell ('' for none)")
    ap.add_argument("--no-peer", action="store_true", help="skip the statsmodels comparison")
    ap.add_argument(
        "--no-traced", action="store_true", help="skip the tracemalloc run of each campaign size"
    )
    args = ap.parse_args()
    size = int(args.size) if args.size.isdigit() else args.size
    with tempfile.TemporaryDirectory() as tmp:
        data = _campaign(size, tmp)
    n_fits = {"n": 0}
    orig = core.forward_select

    def counting(design, stats, cands, cfg, **kw):
        sel = orig(design, stats, cands, cfg, **kw)
        steps = len([s for s in sel.selected if s.candidate.kind != "measurement"]) + 1
        n_fits["n"] += 5 * (len(cands) * steps)
        return sel

    core.forward_select = counting
    t0, c0 = time.perf_counter(), time.process_time()
    d = diagnose(data)
    ours, ours_cpu = time.perf_counter() - t0, time.process_time() - c0
    core.forward_select = orig
    man = sorted(set(data["maneuver_id"].to_list()))
    print(f"campaign: {len(man)} maneuvers, {data.height} rows")
    print(
        f"aerodelta diagnose (everything, incl. the gap map and roll-off): {ours:.1f} s "
        f"({ours_cpu:.1f} s of CPU; issue 17 floor: <= 5 s for 200 maneuvers), about "
        f"{n_fits['n']} candidate fits"
    )
    if not args.no_peer:
        fold_of = {m: i % 5 for i, m in enumerate(man)}
        folds_of_row = np.array([fold_of[m] for m in d.predictions["maneuver_id"].to_list()])
        peer_t, peer_fits = peer_first_step(data, folds_of_row, core.DiagnoseConfig().knot_deg)
        peer_total = peer_t / peer_fits * n_fits["n"]
        print(
            f"statsmodels loop: {peer_fits} candidate fits in {peer_t:.1f} s "
            f"({1000 * peer_t / peer_fits:.0f} ms per fit) -> {peer_total:.0f} s for the same "
            f"{n_fits['n']} fits"
        )
        print(f"ratio statsmodels / aerodelta: {peer_total / ours:.1f}x (floor >= 10x)")
    for c in ("Cl", "Cn", "CY"):
        print(f"  {c}: verdict {d.verdict(c)}; significant {d.significant_effects(c)}")
    del d, data
    reps = [int(x) for x in args.scaling.split(",") if x.strip()]
    if reps:
        print(
            "\ntime and peak memory per maneuver (peak resident set added by diagnose; numpy's "
            "own peak, tracemalloc)"
        )
        print(
            f"{'maneuvers':>9} {'rows':>9} {'wall s':>7} {'cpu s':>6} {'ms/man':>7} "
            f"{'RSS+ MB':>8} {'MB/man':>7} {'peak MB':>8} {'numpy MB':>9} {'kB/man':>7}"
        )
    for r in reps:
        with tempfile.TemporaryDirectory() as tmp:
            data = _campaign(r, tmp)
        n_man = int(data["maneuver_id"].n_unique())
        m = measure(data, traced=not args.no_traced)
        print(
            f"{n_man:>9} {data.height:>9} {m['wall']:>7.1f} {m['cpu']:>6.1f} "
            f"{1000 * m['wall'] / n_man:>7.1f} {m['rss_added']:>8.0f} "
            f"{m['rss_added'] / n_man:>7.2f} {m['peak']:>8.0f} {m['traced']:>9.0f} "
            f"{1000 * m['traced'] / n_man:>7.0f}"
        )
        del data
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
