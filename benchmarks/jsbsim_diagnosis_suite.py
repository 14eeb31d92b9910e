"""The withheld-effect suite on JSBSim aircraft (issue 17, item 5): campaigns flown on an
aircraft we did not build (``aerodelta.jsbsim_campaign``), the simulator given as the
campaign's ``Cl_sim``, ``Cn_sim``, ``CY_sim`` columns (JSBSim with chosen lateral terms frozen
past the withhold alpha: a black box), diagnosed with the default settings and scored against
the truth by the rules of the virtual suite (``aerodelta.diagnosis.withheld.score_jsbsim_case``).

Cases per seed set (case seed = 1000 x set + case index, so sets never share a campaign):

- singles: every withholdable lateral term (tabulated over alpha) at its full, half and quarter
  change (``withhold_scale`` 1, 0.5, 0.25), calm air; and at full change in light turbulence
  (Dryden severity 1);
- pairs and triples of terms (calm; one pair also in turbulence);
- nulls (nothing withheld): calm, turbulent, and with the rate gyros late by 2.5, 5, 10 and
  20 ms (the recorded p, q, r replaced by their values tau earlier, linearly interpolated
  between the 50 Hz samples; the measured moments, computed from the rates, lag with them).

Seed sets 1-3 are the DEVELOPMENT sets (used while building the suite); sets from 301 on are
the REPORT sets, never run before the report. Run:

    python benchmarks/jsbsim_diagnosis_suite.py --aircraft f15 --first-seed 301 --seeds 3 \
        [--size 10] [--only singles|multi|nulls] [--match LABEL] [--per-flap] [--out FILE] [--list]

Prints the table in the shape of ``docs/diagnosis.md`` (issue 17's floors) and the confusion of
singles; writes every case to JSON. The cases run as tasks on the distributed engine
(``aerodelta.plan.suite.run_cases``: ``--workers N`` local processes, default 2, or
``--scheduler ADDRESS``; ``--workers 0``: in this process); ``--resume DIR`` keeps each finished
case and a rerun skips it. The results do not depend on the number of workers.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from aerodelta.diagnosis import DiagnoseConfig, diagnose
from aerodelta.diagnosis.withheld import (
    JsbsimCaseResult,
    jsbsim_false_alarms,
    jsbsim_term_effects,
    score_jsbsim_case,
)
from aerodelta.exceptions import AerodeltaError
from aerodelta.ingest import ingest
from aerodelta.jsbsim_campaign import generate_jsbsim_campaign, lateral_terms
from aerodelta.plan.suite import run_cases

#: Seed sets below this are development sets; from it on, report sets.
REPORT_FROM = 300
MAGNITUDES = (1.0, 0.5, 0.25)
SKEWS_S = (0.0025, 0.005, 0.010, 0.020)
TURBULENCE = 1.0  # Dryden severity (light)
#: Pairs and triples per aircraft (at most one side-force term each).
MULTI: dict[str, list[tuple[str, ...]]] = {
    "f15": [
        ("Clb", "Cnb"),
        ("Clp", "Cndr"),
        ("ClDa", "Cnp"),
        ("CYb", "Clp"),
        ("Clb", "Clp", "Cnb"),
        ("ClDa", "Cnb", "Cnp"),
    ],
    "DHC6": [("Clb", "Cnb")],
}
#: The multi case also flown in turbulence.
MULTI_TURB = {"f15": ("Clb", "Clp", "Cnb"), "DHC6": ("Clb", "Cnb")}


@dataclass(frozen=True)
class Case:
    """One campaign of the suite."""

    part: str  # singles | multi | nulls
    terms: dict[str, float]
    seed: int
    turbulence: float = 0.0
    skew_s: float = 0.0
    label: str = field(default="")


def cases(aircraft: str, first_seed: int, seeds: int) -> list[Case]:
    """Every case of ``seeds`` seed sets from ``first_seed``."""
    terms = [t["name"] for t in lateral_terms(aircraft) if t["alpha_dependent"]]
    out: list[Case] = []
    for s in range(first_seed, first_seed + seeds):
        seq = iter(range(1000 * s + 1, 1000 * s + 1000))

        def nxt(seq: Any = seq) -> int:
            return int(next(seq))

        for t in terms:
            for m in MAGNITUDES:
                out.append(Case("singles", {t: m}, nxt(), label=f"{t} x{m:g}"))
            out.append(Case("singles", {t: 1.0}, nxt(), TURBULENCE, label=f"{t} x1 turb"))
        for grp in MULTI.get(aircraft, []):
            out.append(Case("multi", dict.fromkeys(grp, 1.0), nxt(), label="+".join(grp)))
        if aircraft in MULTI_TURB:
            g = MULTI_TURB[aircraft]
            out.append(
                Case("multi", dict.fromkeys(g, 1.0), nxt(), TURBULENCE, label="+".join(g) + " turb")
            )
        out.append(Case("nulls", {}, nxt(), label="null"))
        out.append(Case("nulls", {}, nxt(), TURBULENCE, label="null turb"))
        for tau in SKEWS_S:
            out.append(Case("nulls", {}, nxt(), skew_s=tau, label=f"null skew {tau * 1e3:g} ms"))
    return out


def skew_rates(campaign: Path, tau_s: float) -> None:
    """Make the recorded rate gyros late by ``tau_s``: p, q, r at t become their values at
    t - tau (linear interpolation between samples; the first samples hold the first value)."""
    for f in sorted((campaign / "records").glob("*.parquet")):
        df = pl.read_parquet(f)
        t = df["t"].to_numpy()
        df = df.with_columns(
            pl.Series(c, np.interp(t - tau_s, t, df[c].to_numpy()))
            for c in ("p_dps", "q_dps", "r_dps")
        )
        df.write_parquet(f, compression="zstd", statistics=False)


def run_case(
    aircraft: str,
    case: Case,
    size: int,
    workdir: str | None = None,
    config: DiagnoseConfig | None = None,
) -> JsbsimCaseResult:
    """Fly, ingest, diagnose (default settings, or ``config``) and score one case."""
    lat = lateral_terms(aircraft)
    effects = jsbsim_term_effects(lat)
    axes = {t["name"]: t["axis"] for t in lat}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        camp = Path(tmp) / "campaign"
        if case.terms:
            mags = set(case.terms.values())
            assert len(mags) == 1, "one magnitude per case"
            scale = mags.pop()
            withhold: str = ",".join(case.terms)
        else:
            scale, withhold = 1.0, "none"
        generate_jsbsim_campaign(
            camp, aircraft=aircraft, seed=case.seed, size=size, withhold=withhold,
            withhold_scale=scale, noise=1.0, turbulence=case.turbulence,
        )  # fmt: skip
        if case.skew_s:
            skew_rates(camp, case.skew_s)
        data = ingest(camp, compat=False, progress=False).data
        # the aircraft that flew them (before session 12 the diagnosis took the built-in
        # ADX-37's mass and geometry here without saying so)
        diag = diagnose(data, config=config, aircraft=camp / "aircraft.toml")
        out = score_jsbsim_case(diag, camp, case.terms, effects, axes, timing_lag=case.skew_s > 0.0)
    out.seconds = time.perf_counter() - t0
    out.settings = {
        "aircraft": aircraft, "part": case.part, "label": case.label, "seed": case.seed,
        "size": size, "turbulence": case.turbulence, "skew_s": case.skew_s, "noise": 1.0,
        "per_flap": "auto" if config is None or config.per_flap is None else config.per_flap,
    }  # fmt: skip
    return out


def one_case(aircraft: str, case: Case, size: int, per_flap: bool) -> JsbsimCaseResult | str:
    """One case (a task on the engine): its result, or the product's refusal (one line)."""
    cfg = DiagnoseConfig(per_flap=True) if per_flap else None
    try:
        return run_case(aircraft, case, size, config=cfg)
    except AerodeltaError as err:
        return str(err)


def _rate(xs: list[bool]) -> str:
    return f"{sum(xs)}/{len(xs)}" if xs else "-"


def summarize(results: list[JsbsimCaseResult]) -> dict[str, Any]:
    """The suite's counts (issue 17's floors), per part."""
    part = {id(r): r.settings["part"] for r in results}
    singles = [r for r in results if part[id(r)] == "singles"]
    top: dict[str, list[bool]] = {}
    unmeasurable: dict[str, int] = {}
    confusion: dict[str, dict[str, int]] = {}
    for r in singles:
        ((t, m),) = r.terms.items()
        if "top" not in r.found:
            unmeasurable[f"{t} x{m:g}"] = unmeasurable.get(f"{t} x{m:g}", 0) + 1
            continue
        key = {1.0: "design", 0.5: "half", 0.25: "quarter"}[m]
        if r.settings["turbulence"] > 0:
            key = "design, turbulence"
        top.setdefault(key, []).append(r.found["top"])
        row = confusion.setdefault(f"{t} x{m:g}", {})
        for c, e in r.right_top.items():
            v = f"{c}: {r.verdicts[c]}" + ("" if r.verdicts[c] == e else f" (truth {e})")
            row[v] = row.get(v, 0) + 1
    multi = [r for r in results if part[id(r)] == "multi"]
    nulls = [r for r in results if part[id(r)] == "nulls"]
    null_rows: dict[str, list[bool]] = {}
    skew_named: list[bool] = []
    for r in nulls:
        k = f"skew {r.settings['skew_s'] * 1e3:g} ms" if r.settings["skew_s"] else "no skew"
        null_rows.setdefault(k, []).append(bool(r.false_alarms))
        if r.settings["skew_s"]:
            skew_named.append(any("time_skew" in v for v in r.significant.values()))
    non_null = singles + multi
    onset = [v for r in non_null for v in r.onset_error_deg.values()]
    shrink = [v for r in singles for v in r.shrink_ratio.values()]
    unl_coefs = [
        k
        for r in non_null
        for k in r.gap_shown  # one per (case, coefficient, unlisted part)
    ]
    return {
        "n_cases": len(results),
        "singles_top": {k: _rate(v) for k, v in top.items()},
        "multi_found": _rate([f for r in multi for f in r.found.values()]),
        "null_false_alarms": {k: _rate(v) for k, v in null_rows.items()},
        "null_false_alarms_all": _rate([bool(r.false_alarms) for r in nulls]),
        "skew_nulls_time_skew_named": _rate(skew_named),
        "spurious_untouched": _rate([bool(r.false_alarms_untouched) for r in non_null]),
        "spurious_below_share": _rate([bool(r.false_alarms) for r in non_null]),
        "unlisted_misattributed": _rate([bool(r.misattributed) for r in non_null if r.gap_shown]),
        "unlisted_gap_shown": _rate([v for r in non_null for v in r.gap_shown.values()]),
        "unlisted_n": len(unl_coefs),
        "onset_within_2": _rate([v <= 2.0 for v in onset]),
        "onset_within_1p5": _rate([v <= 1.5 for v in onset]),
        "onset_median_deg": float(np.median(onset)) if onset else None,
        "shrink_ge_90pct_of_oracle": _rate([v >= 0.9 for v in shrink]),
        "rolloff_called": _rate([r.rolloff_called for r in results]),
        "unmeasurable_singles": unmeasurable,
        "confusion": confusion,
        # singles whose right top effect was found only as an ambiguous rival of the verdict
        "top_through_ambiguity": sum(
            1
            for r in singles
            if r.found.get("top") and any(r.verdicts[c] != e for c, e in r.right_top.items())
        ),
        "cases_reporting_ambiguity": sum(1 for r in results if r.ambiguous),
        "seconds_median": float(np.median([r.seconds for r in results])) if results else None,
        "seconds_total": float(sum(r.seconds for r in results)),
    }


def print_table(s: dict[str, Any], aircraft: str, sets: str) -> None:
    """The suite table (docs/diagnosis.md's shape) and the confusion of singles."""

    def row(check: str, result: str, floor: str) -> None:
        print(f"| {check} | {result} | {floor} |")

    print(f"\n{aircraft}, seed sets {sets}: {s['n_cases']} cases")
    print("| check | result | floor (issue 17) |")
    print("|---|---|---|")
    fl = {"design": "≥ 98 %", "half": "≥ 98 %", "quarter": "≥ 90 %", "design, turbulence": ""}
    for k in ("design", "half", "quarter", "design, turbulence"):
        if k in s["singles_top"]:
            row(f"right top effect, affected coefficients, {k}", s["singles_top"][k], fl[k])
    print(f"| each effect of pairs/triples among the significant | {s['multi_found']} | ≥ 95 % |")
    for k, v in s["null_false_alarms"].items():
        print(f"| nulls with a false alarm, {k} | {v} | ≤ 5 % |")
    if s.get("skew_nulls_time_skew_named"):
        row("nulls with late rates: time skew named", s["skew_nulls_time_skew_named"], "")
    row(
        "non-null cases with a spurious effect on a coefficient no withheld part moves",
        s["spurious_untouched"],
        "≤ 5 %",
    )
    row(
        "... or on one where the withheld parts remove < 3 % of its gap energy",
        s["spurious_below_share"],
        "",
    )
    print(
        f"| out-of-list part: coefficient misattributed | {s['unlisted_misattributed']} | ≤ 5 % |"
    )
    print(
        f"| out-of-list part: gap shown in its alpha range | {s['unlisted_gap_shown']} | ≥ 90 % |"
    )
    print(f"| onset within 2 deg (correct verdicts) | {s['onset_within_2']} | ≥ 90 % |")
    row("held-out shrink ≥ 0.9 of the oracle's (singles)", s["shrink_ge_90pct_of_oracle"], "≥ 90 %")
    print(f"| stochastic roll-off called (JSBSim has none) | {s['rolloff_called']} | |")
    print(
        f"singles whose right top effect is named only as an ambiguous rival: "
        f"{s['top_through_ambiguity']}; cases reporting an ambiguity: "
        f"{s['cases_reporting_ambiguity']} of {s['n_cases']}"
    )
    if s["unmeasurable_singles"]:
        print(
            "singles whose listed parts remove < 3 % of every coefficient's gap energy (left "
            "out of the rates): "
            + ", ".join(f"{k} ({v})" for k, v in s["unmeasurable_singles"].items())
        )
    print("confusion (single term -> verdict on each coefficient a listed part affects):")
    for t, row in sorted(s["confusion"].items()):
        print(f"  {t:<12} " + "; ".join(f"{v}: {n}" for v, n in sorted(row.items())))
    med, tot = s["seconds_median"], s["seconds_total"] / 60
    print(f"run time per case: median {med:.1f} s, total {tot:.1f} min")


def rescore(path: str) -> list[JsbsimCaseResult]:
    """The cases of a JSON written by this script, their false alarms recomputed from the
    saved verdicts, ambiguities and gap-energy shares (``jsbsim_false_alarms``)."""
    out = []
    for d in json.loads(Path(path).read_text())["cases"]:
        d.setdefault("shares", {})
        d.setdefault("false_alarms_untouched", [])
        r = JsbsimCaseResult(**d)
        det = {c: [e for e in v if e != "stochastic_rolloff"] for c, v in r.significant.items()}
        r.false_alarms, r.false_alarms_untouched, r.misattributed = jsbsim_false_alarms(
            det, r.ambiguous, r.shares, timing_lag=r.settings.get("skew_s", 0.0) > 0.0
        )
        out.append(r)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--aircraft", choices=("f15", "DHC6"), required=True)
    ap.add_argument(
        "--first-seed", type=int, default=1, help="first seed set (1-3 development, 301+ report)"
    )
    ap.add_argument("--seeds", type=int, default=1, help="seed sets")
    ap.add_argument("--size", type=int, default=10, help="repetitions per flap x entry kind")
    ap.add_argument("--only", choices=("singles", "multi", "nulls"))
    ap.add_argument("--match", default=None, help="only cases whose label contains this")
    ap.add_argument("--list", action="store_true", help="print the cases and stop")
    ap.add_argument(
        "--per-flap", action="store_true", help="diagnose with one alpha curve per flap always"
    )
    ap.add_argument(
        "--rescore",
        default=None,
        help="print the table of a saved JSON (false alarms recomputed) instead of running",
    )
    ap.add_argument(
        "--out",
        default=None,
        help="JSON of every case (default jsbsim_suite_<aircraft>_<sets>.json)",
    )
    ap.add_argument("--workers", type=int, default=2, help="engine workers (0: this process)")
    ap.add_argument("--scheduler", default=None, help="a Dask scheduler's address")
    ap.add_argument("--resume", default=None, help="keep finished cases here and skip them")
    args = ap.parse_args()
    if args.rescore:
        res = rescore(args.rescore)
        seeds = sorted({r.settings["seed"] // 1000 for r in res})
        sets = f"{seeds[0]}-{seeds[-1]}" if len(seeds) > 1 else f"{seeds[0]}"
        kind = "REPORT" if seeds[0] >= REPORT_FROM else "DEVELOPMENT"
        print_table(summarize(res), args.aircraft, f"{sets} ({kind}), rescored {args.rescore}")
        return 0
    last = args.first_seed + args.seeds - 1
    if args.first_seed < REPORT_FROM <= last:
        print(
            "error: --first-seed/--seeds mix development (< 300) and report (>= 300) sets",
            file=sys.stderr,
        )
        return 2
    kind = "REPORT" if args.first_seed >= REPORT_FROM else "DEVELOPMENT"
    sets = f"{args.first_seed}-{last}" if args.seeds > 1 else f"{args.first_seed}"
    todo = cases(args.aircraft, args.first_seed, args.seeds)
    if args.only:
        todo = [c for c in todo if c.part == args.only]
    if args.match:
        todo = [c for c in todo if args.match in c.label]
    seeds_used = [c.seed for c in todo]
    print(
        f"{kind} seed sets {sets} ({args.aircraft}, size {args.size}): {len(todo)} cases, "
        f"case seeds {min(seeds_used)}..{max(seeds_used)}"
        if todo
        else f"{kind}: no cases"
    )
    if args.list:
        for c in todo:
            print(f"  {c.seed:>7} {c.part:<8} {c.label}")
        return 0
    run = run_cases(
        one_case,
        [(args.aircraft, c, args.size, args.per_flap) for c in todo],
        labels=[f"{c.seed} {c.label}" for c in todo],
        workers=args.workers,
        scheduler=args.scheduler,
        resume=args.resume,
        name=f"jsbsim-withheld-{args.aircraft}",
    )
    results: list[JsbsimCaseResult] = []
    failed: list[dict[str, str]] = []
    for c, r in zip(todo, run.results, strict=True):
        if isinstance(r, JsbsimCaseResult):
            results.append(r)
        elif isinstance(r, str):
            # a case the product refuses is a result, reported, never dropped or fatal to the
            # rest of the set (set 351 lost its last five cases to one refused maneuver)
            failed.append({"seed": str(c.seed), "label": c.label, "error": r})
            print(f"case {c.seed} ({c.label}) refused: {r}", file=sys.stderr)
    for f in run.failures:
        failed.append({"seed": f.label.split()[0], "label": f.label, "error": f.error})
        print(f"case {f.label} failed after its retries: {f.error}", file=sys.stderr)
    s = summarize(results)
    s["failed_cases"] = failed
    print_table(s, args.aircraft, f"{sets} ({kind})")
    if failed:
        print(f"cases that did not run ({len(failed)}; not in the rates above):")
        for f in failed:
            print(f"  {f['seed']} {f['label']}: {f['error'].splitlines()[0]}")
    out = args.out or f"jsbsim_suite_{args.aircraft}_{sets}.json"
    Path(out).write_text(
        json.dumps({"summary": s, "cases": [r.to_dict() for r in results]}, indent=1, default=str)
    )
    print(f"wrote {out}")
    return 1 if run.failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
