"""The diagnosis's own held-out shrink against its outer-fold shrink (issue 17, item 1).

Flies virtual campaigns with one effect withheld at a small magnitude (near the selection's
floors, where choosing the winner among many candidates inflates the winner's numbers) and
null campaigns, diagnoses each, and prints per coefficient the effects the selection reports
with their in-sample held-out shrink beside the outer-fold shrink (the selection redone
without each fold and scored on it) and the folds that chose them; for nulls, what the outer
folds chose and removed.

    python benchmarks/nested_check.py [--first-seed 9001] [--magnitude 0.25] [--size default]
        [--effects dihedral,roll_damping,...] [--nulls 4]

Seeds 9001+ were not used to build any rule of the diagnosis.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from aerodelta.campaign import generate_campaign
from aerodelta.diagnosis import diagnose
from aerodelta.ingest import ingest

EFFECTS = (
    "dihedral",
    "roll_damping",
    "directional_stability",
    "rudder_effectiveness",
    "yaw_damping",
    "lateral_asymmetry",
)


def _case(effects: dict[str, float], seed: int, size: str) -> dict[str, object]:
    with tempfile.TemporaryDirectory() as tmp:
        camp = Path(tmp) / "campaign"
        generate_campaign(camp, effects=effects or "none", seed=seed, size=size, progress=False)
        data = ingest(camp, compat=False, progress=False).data
        t0 = time.perf_counter()
        d = diagnose(data)
        secs = time.perf_counter() - t0
    rows = []
    for coef, r in d.result["coefficients"].items():
        out = r["outer"]
        for e in r["effects"]:
            if e["significant"] and e.get("outer_chosen_folds") is not None:
                rows.append(
                    {
                        "coefficient": coef,
                        "effect": e["effect"],
                        "shrink": e["shrink_fraction"],
                        "outer_shrink": e["outer_shrink_fraction"],
                        "outer_folds": e["outer_chosen_folds"],
                        "outer_p": e["outer_p_value"],
                    }
                )
        sig = {e["effect"] for e in r["effects"] if e["significant"]}
        extra = {k: v for k, v in out["chosen_in_folds"].items() if k not in sig}
        if extra:
            rows.append(
                {
                    "coefficient": coef,
                    "effect": "(outer only) " + ",".join(f"{k}:{v}" for k, v in extra.items()),
                    "shrink": None,
                    "outer_shrink": out["shrink_fraction_effects"],
                    "outer_folds": None,
                    "outer_p": out["p_value_effects"],
                }
            )
    return {"effects": effects, "seed": seed, "seconds": secs, "rows": rows}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--first-seed", type=int, default=9001)
    ap.add_argument("--magnitude", type=float, default=0.25)
    ap.add_argument("--size", default="default")
    ap.add_argument("--effects", default=",".join(EFFECTS))
    ap.add_argument("--nulls", type=int, default=4)
    ap.add_argument("--out", default=None, help="write every case as JSON")
    a = ap.parse_args()
    cases: list[dict[str, float]] = [{e: a.magnitude} for e in a.effects.split(",") if e] + [
        {} for _ in range(a.nulls)
    ]
    results = []
    for i, eff in enumerate(cases):
        res = _case(eff, a.first_seed + i, a.size)
        results.append(res)
        name = ",".join(f"{k}={v:g}" for k, v in eff.items()) or "null"
        print(f"seed {res['seed']} {name} ({res['seconds']:.1f} s)")
        if not res["rows"]:
            print("    nothing reported, no outer fold chose anything")
        for r in res["rows"]:
            sh = "-" if r["shrink"] is None else f"{100 * r['shrink']:.2f} %"
            folds = "" if r["outer_folds"] is None else f", chosen {r['outer_folds']}/5"
            print(
                f"    {r['coefficient']:<3} {r['effect']:<32} selection {sh:>8}   "
                f"outer {100 * r['outer_shrink']:.2f} %{folds}, p {r['outer_p']:.2g}"
            )
    if a.out:
        Path(a.out).write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
