"""The withheld-effect suite (issue 7, "the proof"): fly a virtual campaign whose truth aircraft
carries effects, give the diagnosis the qualified model without them, and score its answer
against the truth.

This harness reads the campaign's ``truth/`` files to score the answer; the diagnosis itself
never does (it refuses truth paths). Scoring rules:

- a coefficient is *affected* by a withheld aerodynamic effect when the effect's true
  contribution removes at least ``affect_share`` of that coefficient's gap energy (the oracle
  shrink); measurement effects affect the coefficients their physics reaches (beta vane bias,
  time skew and control lag: all three; accelerometer offset: C_Y; alpha vane bias: none
  measurably, since the lateral simulator barely depends on alpha) by default; when the case
  is run with its *twin* campaigns (:func:`run_case` flies, for each withheld measurement
  effect, the same seed without it: the flight is identical, only the sensors differ), the
  same gap-energy rule as for aerodynamic effects decides, on the gap the effect adds
  (:func:`measurement_shares`), so a quarter-size skew that moves no coefficient measurably
  is left out of the rates like an unmeasurable aerodynamic effect;
- a single is *found* when every affected coefficient's verdict is the effect, or names it
  as ambiguous with the verdict (the data could not tell them apart: not a confident wrong
  answer);
- in pairs and triples each withheld effect is *found* when it is among the significant
  effects (or their ambiguous rivals) of every coefficient it affects;
- a *false alarm* is a significant deterministic effect on a coefficient no withheld effect
  affects (nulls), or any significant effect of the vocabulary on C_l for an unlisted effect
  (misattribution);
- the *onset* error is the distance between the estimated and the true lower end of the alpha
  range, both by the same rule (1-deg bins whose RMS contribution reaches 20 % of the largest);
- the *shrink ratio* is the held-out shrink achieved over the shrink that subtracting the true
  contributions exactly achieves (aerodynamic effects).
"""

from __future__ import annotations

import json
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from aerodelta.campaign import effect_library, generate_campaign
from aerodelta.diagnosis.core import DiagnoseConfig, Diagnosis, _alpha_range, diagnose
from aerodelta.diagnosis.vocabulary import COEFFICIENTS
from aerodelta.fit import model_frame, qualified_coefficients
from aerodelta.ingest import ingest

#: Coefficients a measurement effect acts on (see the module doc).
MEASUREMENT_ACTS: dict[str, tuple[str, ...]] = {
    "beta_vane_bias": ("Cl", "Cn", "CY"),
    "alpha_vane_bias": (),
    "control_lag": ("Cl", "Cn", "CY"),
    "time_skew": ("Cl", "Cn", "CY"),
    "accelerometer_offset": ("CY",),
}


@dataclass
class CaseResult:
    """The outcome of one withheld-effect case."""

    effects: dict[str, float]
    settings: dict[str, Any]
    verdicts: dict[str, str]
    significant: dict[str, list[str]]
    affected: dict[str, list[str]]  # effect -> coefficients it affects
    found: dict[str, bool]  # effect -> found (single: verdict; multiple: among significant)
    false_alarms: list[str]  # "coef:effect"
    onset_error_deg: dict[str, float] = field(default_factory=dict)
    shrink_ratio: dict[str, float] = field(default_factory=dict)  # coef -> ours / oracle
    ambiguous: dict[str, list[str]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return self.__dict__.copy()


def _kinds() -> dict[str, str]:
    return {e["name"]: e["kind"] for e in effect_library()}


def _gap(data: pl.DataFrame) -> pl.DataFrame:
    """``C_meas - C_qual`` of the built-in qualified model along the records, by (maneuver, t)."""
    mf = model_frame(data)
    q = qualified_coefficients(mf, "adx37")
    return mf.select("maneuver_id", "t").with_columns(
        (mf[f"{c}_meas"] - q[f"{c}_qual"]).alias(f"{c}_gap") for c in COEFFICIENTS
    )


def measurement_shares(data: pl.DataFrame, twin: pl.DataFrame) -> dict[str, float]:
    """Share of each coefficient's gap energy that a withheld measurement effect adds.

    Parameters
    ----------
    data
        The ingested campaign with the effect.
    twin
        The same campaign (seed, conditions, other effects) flown without it: same flight,
        only the sensors differ.

    Returns
    -------
    dict
        Coefficient -> ``sum(d^2) / sum(gap^2)``, ``d`` the gap with the effect minus the gap
        without it on the samples both campaigns keep.
    """
    j = _gap(data).join(_gap(twin), on=["maneuver_id", "t"], how="inner", suffix="_twin")
    out = {}
    for c in COEFFICIENTS:
        g = j[f"{c}_gap"].to_numpy()
        d = g - j[f"{c}_gap_twin"].to_numpy()
        ok = np.isfinite(d) & np.isfinite(g)
        den = float(np.sum(g[ok] ** 2))
        out[c] = float(np.sum(d[ok] ** 2)) / den if den > 0 else 0.0
    return out


def score_case(
    diag: Diagnosis,
    truth_dir: Path,
    effects: Mapping[str, float],
    affect_share: float = 0.03,
    shares: Mapping[str, Mapping[str, float]] | None = None,
) -> CaseResult:
    """Score a diagnosis against the campaign's truth files.

    ``shares`` (measurement effect -> coefficient -> gap-energy share, from
    :func:`measurement_shares` on the twin campaigns) makes a measurement effect affect the
    coefficients where it adds at least ``affect_share`` of the gap energy; without it, the
    fixed :data:`MEASUREMENT_ACTS` apply.
    """
    kinds = _kinds()
    preds = diag.predictions
    ids = sorted(set(preds["maneuver_id"].to_list()))
    truth = pl.concat(
        [
            pl.read_parquet(truth_dir / f"{m}.parquet").with_columns(pl.lit(m).alias("maneuver_id"))
            for m in ids
        ],
        how="diagonal_relaxed",
    )
    j = preds.join(truth, on=["maneuver_id", "t"], how="inner")
    res = diag.result["coefficients"]
    verdicts = {c: res[c]["verdict"] for c in COEFFICIENTS}
    significant = {
        c: [e["effect"] for e in res[c]["effects"] if e["significant"]] for c in COEFFICIENTS
    }
    ambiguous = {
        f"{c}:{e['effect']}": e["ambiguous_with"]
        for c in COEFFICIENTS
        for e in res[c]["effects"]
        if e["significant"] and e["ambiguous_with"]
    }
    affected: dict[str, list[str]] = {}
    oracle: dict[str, np.ndarray] = {c: np.zeros(j.height) for c in COEFFICIENTS}
    onset_err: dict[str, float] = {}
    for e in effects:
        k = kinds.get(e, "measurement")
        if k in ("aerodynamic", "unlisted"):
            acts = []
            for c in COEFFICIENTS:
                col = f"d{c}_{e}"
                if col not in j.columns:
                    continue
                contrib = j[col].to_numpy()
                gap = j[f"{c}_gap"].to_numpy()
                oracle[c] += contrib
                if float(np.sum(contrib**2)) >= affect_share * float(np.sum(gap**2)):
                    acts.append(c)
                    est = next((x for x in res[c]["effects"] if x["effect"] == e), None)
                    if est is not None and est["significant"]:
                        lo_t = _alpha_range(j["alpha_deg"].to_numpy(), contrib)[0]
                        lo_e = est["alpha_range_deg"][0]
                        if lo_e is not None and np.isfinite(lo_t):
                            onset_err[f"{c}:{e}"] = abs(float(lo_e) - lo_t)
            affected[e] = acts
        elif shares is not None and e in shares:
            affected[e] = [c for c in COEFFICIENTS if shares[e].get(c, 0.0) >= affect_share]
        else:
            affected[e] = list(MEASUREMENT_ACTS.get(e, ()))
    single = len(effects) == 1
    # an effect reported ambiguous with the one named is not a confident wrong answer
    named = {
        c: {
            e["effect"]: [e["effect"], *e["ambiguous_with"]]
            for e in res[c]["effects"]
            if e["significant"]
        }
        for c in COEFFICIENTS
    }

    def names(c: str, top_only: bool) -> set[str]:
        items = named[c].items()
        if top_only:
            items = [(k, v) for k, v in items if k == verdicts[c]]
        return {x for _, v in items for x in v}

    found = {}
    for e, acts in affected.items():
        if kinds.get(e) == "unlisted":
            continue
        if single:
            found[e] = bool(acts) and all(e in names(c, True) for c in acts)
        else:
            found[e] = bool(acts) and all(e in names(c, False) for c in acts)
        if not acts:
            found[e] = True  # nothing measurable to find (reported separately)
    touched = {c for acts in affected.values() for c in acts}
    det_kinds = {"aerodynamic", "measurement", "user"}
    false_alarms = []
    for c in COEFFICIENTS:
        for x in res[c]["effects"]:
            if not x["significant"] or x.get("kind") not in det_kinds:
                continue
            wrong = x["effect"] not in effects and not set(x["ambiguous_with"]) & set(effects)
            if wrong and (c not in touched or any(kinds.get(e) == "unlisted" for e in effects)):
                false_alarms.append(f"{c}:{x['effect']}")
    shrink = {}
    for c in touched:
        if not np.any(oracle[c]):
            continue
        # both shrinks from the timing-aligned gap (the timing nuisance is in every model)
        gap = j[f"{c}_gap"].to_numpy() - j[f"{c}_timing"].to_numpy()
        expl = j[f"{c}_explained"].to_numpy() - j[f"{c}_timing"].to_numpy()
        ours = 1.0 - float(np.sum((gap - expl) ** 2)) / float(np.sum(gap**2))
        orc = 1.0 - float(np.sum((gap - oracle[c]) ** 2)) / float(np.sum(gap**2))
        if orc > 0.02:
            shrink[c] = ours / orc
    return CaseResult(
        dict(effects), {}, verdicts, significant, affected, found, false_alarms, onset_err,
        shrink, ambiguous,
    )  # fmt: skip


def run_case(
    effects: Mapping[str, float],
    *,
    seed: int,
    size: str | int = "quick",
    noise: float = 1.0,
    turbulence: float = 0.5,
    rolloff: bool = False,
    config: DiagnoseConfig | None = None,
    workdir: str | Path | None = None,
    twins: bool = True,
) -> CaseResult:
    """Fly, ingest, diagnose and score one case (the campaign is written to a temporary
    folder, or ``workdir``). With ``twins``, each withheld measurement effect's reach is
    measured on a twin campaign flown without it (:func:`measurement_shares`)."""
    kinds = _kinds()

    def fly(folder: Path, eff: Mapping[str, float]) -> pl.DataFrame:
        generate_campaign(
            folder, effects=dict(eff) if eff else "none", seed=seed, size=size,
            noise=noise, turbulence=turbulence, rolloff=rolloff, overwrite=True,
        )  # fmt: skip
        return ingest(folder, compat=False, progress=False).data

    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        camp = Path(tmp) / "campaign"
        data = fly(camp, effects)
        shares: dict[str, dict[str, float]] | None = None
        if twins:
            shares = {}
            for e in effects:
                if kinds.get(e) == "measurement":
                    rest = {k: v for k, v in effects.items() if k != e}
                    shares[e] = measurement_shares(data, fly(Path(tmp) / f"twin_{e}", rest))
        diag = diagnose(data, config=config)
        out = score_case(diag, camp / "truth", effects, shares=shares)
    out.settings = {
        "seed": seed, "size": size, "noise": noise, "turbulence": turbulence, "rolloff": rolloff,
    }  # fmt: skip
    return out


def summarize(cases: list[CaseResult]) -> dict[str, Any]:
    """Rates of the suite (issue 7's floors) and the confusion matrix of singles."""
    kinds = _kinds()

    def rate(xs: list[bool]) -> float | None:
        return float(np.mean(xs)) if xs else None

    singles = [
        c for c in cases if len(c.effects) == 1 and kinds.get(next(iter(c.effects))) != "unlisted"
    ]
    by_mag: dict[str, list[bool]] = {}
    confusion: dict[str, dict[str, int]] = {}
    unmeasurable: dict[str, int] = {}
    for c in singles:
        ((e, m),) = c.effects.items()
        if not c.affected.get(e):
            # no coefficient moves measurably (e.g. an alpha vane bias on a lateral model):
            # not counted as found; listed apart
            unmeasurable[e] = unmeasurable.get(e, 0) + 1
            continue
        key = "design" if m >= 0.99 else ("half" if m >= 0.49 else "quarter")
        by_mag.setdefault(key, []).append(c.found.get(e, False))
        row = confusion.setdefault(e, {})
        for coef in c.affected.get(e, []) or ["-"]:
            v = c.verdicts.get(coef, "-") if coef != "-" else "n/a"
            row[v] = row.get(v, 0) + 1
    multi = [c for c in cases if len(c.effects) > 1]
    multi_found = [f for c in multi for f in c.found.values()]
    unlisted = [c for c in cases if any(kinds.get(e) == "unlisted" for e in c.effects)]
    nulls = [c for c in cases if not c.effects]
    onset = [v for c in cases for v in c.onset_error_deg.values()]
    # the oracle of an unlisted effect is not reachable by design: no candidate models it
    shrink = [v for c in cases if c not in unlisted for v in c.shrink_ratio.values()]
    return {
        "n_cases": len(cases),
        "singles_found": {k: rate(v) for k, v in by_mag.items()},
        "singles_n": {k: len(v) for k, v in by_mag.items()},
        "multi_found": rate(multi_found),
        "multi_n": len(multi_found),
        "unlisted_misattributed": rate([bool(c.false_alarms) for c in unlisted]),
        "unlisted_n": len(unlisted),
        "null_false_alarms": rate([bool(c.false_alarms) for c in nulls]),
        "null_n": len(nulls),
        "onset_within_1p5": rate([v <= 1.5 for v in onset]),
        "onset_n": len(onset),
        "shrink_ge_90pct_of_oracle": rate([v >= 0.9 for v in shrink]),
        "shrink_n": len(shrink),
        "confusion": confusion,
        "unmeasurable_singles": unmeasurable,
    }


def dumps(cases: list[CaseResult]) -> str:
    """All cases and the summary as JSON."""
    return json.dumps(
        {"summary": summarize(cases), "cases": [c.to_dict() for c in cases]}, indent=1, default=str
    )
