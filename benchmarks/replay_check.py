"""Closed-loop replays of held-out stall maneuvers with the stored stall in either form.

Issue 20's floor: closed-loop replays of held-out stall maneuvers within the ±3 kt stall-speed
tolerance in ≥ 90 % of them (Part 60's stall-speed test conditions: entries decelerating at
most ``closed_loop.MAX_TEST_DECEL_KT_S``; all entries reported beside them). The Δ model is
fitted on one virtual campaign (buffet and the Kirchhoff stall on, ``aerodelta.fit``
defaults), and carries the longitudinal stall fitted on the same records by output error in
the tanh form (``fit_kirchhoff``) or the tabulated form (``fit_goman_khrabrov``), stored with
``DeltaModel.with_longitudinal``; each model replays the maneuvers of other campaigns (never
used in the fit), and so does the truth (the campaign's effects and its Kirchhoff stall).

Floors, fixed before the report seeds ran: for each stored form, ≥ 90 % of the held-out
test-condition stall speeds within ±3 kt; the table (whose tanh truth it can only
approximate) within one maneuver of the tanh's count.

Run: ``python benchmarks/replay_check.py [--fit-seed 961] [--seeds 962 ... 971]``
(quick campaigns; a few seconds per held-out campaign). Development: fit seed 41, held-out
42-45. Report (run once): fit seed 961, held-out 962-971.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import polars as pl

import aerodelta as ad
from aerodelta import _core
from aerodelta.campaign import spec_effects
from aerodelta.closed_loop import closed_loop_replay
from aerodelta.fit import model_frame
from aerodelta.goman_khrabrov import fit_goman_khrabrov
from aerodelta.longitudinal import fit_kirchhoff


def _campaign(root: Path, seed: int) -> tuple[pl.DataFrame, dict[str, Any]]:
    camp = root / f"c{seed}"
    ad.generate_campaign(
        camp, seed=seed, size="quick", buffet=True, longitudinal_stall="kirchhoff",
        progress=False,
    )  # fmt: skip
    data = ad.ingest(camp, compat=False, progress=False).data
    spec = json.loads((camp / "truth" / "campaign.json").read_text())["spec"]
    return data, spec


def _truth_stall(flaps: list[float]) -> dict[float, dict[str, float]]:
    """The campaign's own Kirchhoff stall and drag per flap (engine units)."""
    out = {}
    for f in flaps:
        p = dict(_core.kirchhoff_truth_params(f))
        p |= dict(_core.kirchhoff_truth_drag(f))
        out[f] = p
    return out


def _count(table: pl.DataFrame) -> dict[str, tuple[int, int]]:
    """(within ±3 kt, with a value) of the stall speed, test conditions and all entries."""
    t = table.filter(pl.col("v_stall_status").is_not_null())
    tc = t.filter(pl.col("test_condition"))
    return {
        "test": (int((tc["v_stall_status"] == "PASS").sum()), tc.height),
        "all": (int((t["v_stall_status"] == "PASS").sum()), t.height),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fit-seed", type=int, default=961)
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(962, 972)))
    args = ap.parse_args()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        data, _ = _campaign(root, args.fit_seed)
        base = ad.fit(data).model
        mf = model_frame(data)
        tanh = fit_kirchhoff(mf, known="adx37")
        table = fit_goman_khrabrov(mf, known="adx37", start=tanh)
        models = {
            "tanh": base.with_longitudinal(tanh),
            "table": base.with_longitudinal(table),
        }
        for name, res in (("tanh", tanh), ("table", table)):
            for f, ff in sorted(res.fits.items()):
                print(f"fit seed {args.fit_seed}, {name}, flap {f:g}: cost {ff.cost:.4g}"
                      + (f", note: {ff.note}" if ff.note else ""))  # fmt: skip
        totals: dict[str, dict[str, list[int]]] = {}
        gaps: list[float] = []  # |table - tanh| of the simulated stall speeds, kt
        for seed in args.seeds:
            held, spec = _campaign(root, seed)
            buffet = spec.get("buffet")
            flaps = sorted(float(f) for f in held["flap_deg"].unique())
            runs = {
                name: closed_loop_replay(held, model=m, buffet_model=buffet, seed=seed)
                for name, m in models.items()
            }
            runs["truth"] = closed_loop_replay(
                held, kirchhoff=_truth_stall(flaps), truth_effects=spec_effects(spec),
                buffet_model=buffet, seed=seed,
            )  # fmt: skip
            both = (
                runs["tanh"].table.select("maneuver_id", pl.col("v_stall_sim_keas").alias("a"))
                .join(runs["table"].table.select("maneuver_id", pl.col("v_stall_sim_keas")
                                                 .alias("b")), on="maneuver_id")
                .drop_nulls()
            )  # fmt: skip
            gaps += (both["b"] - both["a"]).abs().to_list()
            for name, res in runs.items():
                c = _count(res.table)
                tot = totals.setdefault(name, {"test": [0, 0], "all": [0, 0]})
                for k, (ok, n) in c.items():
                    tot[k][0] += ok
                    tot[k][1] += n
                print(
                    f"seed {seed} {name:>5}: stall speed within ±3 kt: test conditions "
                    f"{c['test'][0]} of {c['test'][1]}, all entries {c['all'][0]} of "
                    f"{c['all'][1]}"
                )
        print()
        print("| model | test conditions within ±3 kt | all entries |")
        print("|---|---|---|")
        for name, tot in totals.items():
            (a, n), (b, m) = tot["test"], tot["all"]
            print(f"| {name} | {a} of {n} ({100 * a / max(n, 1):.0f} %) | "
                  f"{b} of {m} ({100 * b / max(m, 1):.0f} %) |")  # fmt: skip
        if gaps:
            g = sorted(gaps)
            print(
                f"simulated stall speed, table - tanh: median |diff| {g[len(g) // 2]:.2f} kt, "
                f"largest {g[-1]:.2f} kt over {len(g)} maneuvers"
            )
        for name in ("tanh", "table"):
            a, n = totals[name]["test"]
            ok = n > 0 and a >= 0.9 * n
            print(f"floor {name}: >= 90 % of test-condition stall speeds: "
                  f"{'PASS' if ok else 'FAIL'}")  # fmt: skip
        gap = totals["tanh"]["test"][0] - totals["table"]["test"][0]
        print(f"floor table within one maneuver of tanh ({gap:+d}): "
              f"{'PASS' if gap <= 1 else 'FAIL'}")  # fmt: skip
    print(f"took {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
