"""Section 4.3: 6-DOF replay. The recorded controls of a maneuver are fed to the simulator from
the recorded initial state; its states (V, alpha, beta, theta, phi) are compared with the flight
record side by side, and checked for divergence."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import polars as pl

from aerodelta.aircraft import Aircraft
from aerodelta.campaign import record_state, replay
from aerodelta.daveml import DaveModel
from aerodelta.exceptions import AerodeltaError
from aerodelta.model import DeltaModel
from aerodelta.plots import COLORS, FigureSink, figures
from aerodelta.qualified import describe, flown_on_builtin
from aerodelta.report import jsbsim_section
from aerodelta.report.context import ReportContext
from aerodelta.report.daveml_replay import Fly, daveml_flyer
from aerodelta.report.html import Section, esc, p, table

#: Bounds of the divergence check: every state finite and inside these limits for the whole
#: replay (V relative to its initial value; angles in deg).
BOUNDS = {
    "V_ratio": (0.3, 2.0),
    "alpha_deg": (-45.0, 60.0),
    "beta_deg": (-60.0, 60.0),
    "theta_deg": (-85.0, 85.0),
}


def bounds_text() -> str:
    """The divergence bounds in words: ``V ∈ [..]·V₀, alpha ∈ [..] deg, ...``."""
    return f"V ∈ [{BOUNDS['V_ratio'][0]}, {BOUNDS['V_ratio'][1]}]·V₀, " + ", ".join(
        f"{k.replace('_deg', '')} ∈ [{lo:g}, {hi:g}] deg"
        for k, (lo, hi) in BOUNDS.items()
        if k != "V_ratio"
    )


STATES = ("V_mps", "alpha_deg", "beta_deg", "theta_deg", "phi_deg")
_REC = {
    "V_mps": "tas_mps",
    "alpha_deg": "alpha_deg",
    "beta_deg": "beta_deg",
    "theta_deg": "theta_deg",
    "phi_deg": "phi_deg",
}


def against_record(
    rec: pl.DataFrame,
    qual: pl.DataFrame,
    ext: pl.DataFrame,
    *,
    mid: str,
    held_out: bool,
    labels: tuple[str, str],
) -> tuple[dict[str, object], list[dict[str, object]]]:
    """A replayed maneuver against its record: the table row (divergence check of the
    extended replay and of the qualified one, largest bank angles in deg, RMS difference of
    each of :data:`STATES` from the record, interpolated to its times) and the figure's
    panels, the qualified and extended replays labelled ``labels``."""
    ok, why = divergence(ext)
    row: dict[str, object] = {
        "maneuver_id": mid,
        "flap_deg": float(rec["flap_deg"][0]),
        "held_out": held_out,
        "bounded": ok,
        "reason": why,
        "qualified_bounded": divergence(qual)[0],
        "max_bank_deg_flight": float(np.nanmax(np.abs(rec["phi_deg"].to_numpy()))),
        "max_bank_deg_ext": float(np.nanmax(np.abs(ext["phi_deg"].to_numpy()))),
    }
    tr = rec["t"].to_numpy()
    panels: list[dict[str, object]] = []
    for s in STATES:
        y = rec[_REC[s]].to_numpy()
        runs = []
        for name, run, col, lab in (
            ("qual", qual, COLORS["qual"], labels[0]),
            ("ext", ext, COLORS["ext"], labels[1]),
        ):
            ts, ys = run["t"].to_numpy(), run[s].to_numpy()
            runs.append((ts, ys, col, lab))
            err = np.interp(tr, ts, ys) - y
            row[f"rms_{s}_{name}"] = float(np.sqrt(np.nanmean(err**2)))
        panels.append({"title": s, "t": tr, "y": y, "runs": runs})
    return row, panels


def states_frame(x: np.ndarray, t: np.ndarray) -> pl.DataFrame:
    """Airspeed and angles (deg) from the simulator's 12-state history."""
    u, v, w = x[:, 0], x[:, 1], x[:, 2]
    vt = np.sqrt(u**2 + v**2 + w**2)
    with np.errstate(invalid="ignore", divide="ignore"):
        return pl.DataFrame(
            {
                "t": t,
                "V_mps": vt,
                "alpha_deg": np.degrees(np.arctan2(w, u)),
                "beta_deg": np.degrees(np.arcsin(np.clip(v / vt, -1, 1))),
                "theta_deg": np.degrees(x[:, 7]),
                "phi_deg": np.degrees(x[:, 6]),
            }
        )


def replay_maneuver(
    rec: pl.DataFrame,
    *,
    controls: str = "elevator",
    rolloff_seed: int | None = 7,
    model: DeltaModel | None = None,
    fly: Fly | None = None,
) -> pl.DataFrame:
    """Replay one record (``model_frame`` rows of one maneuver, sorted by time).

    Parameters
    ----------
    controls
        ``"all"``: every recorded control (aileron, elevator, rudder, spoilers, thrust);
        ``"elevator"``: the recorded elevator and thrust only, lateral controls held at zero
        (the thesis's validation case).
    rolloff_seed
        Seed of the stochastic roll-off (``None``: off).
    model
        The fitted Δ model (the extended model in the loop); ``None``: the qualified model.
    fly
        The simulator (:func:`aerodelta.report.daveml_replay.daveml_flyer`: the user's
        aircraft and DAVE-ML model; no roll-off); ``None``: the built-in ADX-37.
    """
    t = rec["t"].to_numpy()
    n = rec.height - 1
    dt = float(np.median(np.diff(t)))

    def col(c: str) -> np.ndarray:
        return rec[c].fill_null(0.0).to_numpy()[:n] if c in rec.columns else np.zeros(n)

    names = ("da_deg", "de_deg", "dr_deg", "dsl_deg", "dsr_deg")
    ctl = np.column_stack([col(c) for c in names])
    if controls == "elevator":
        ctl[:, [0, 2, 3, 4]] = 0.0
    ct = np.column_stack([col("ct_left"), col("ct_right")])
    if fly is not None:
        x = fly(float(rec["flap_deg"][0]), record_state(rec.row(0, named=True)), dt, ctl, ct, model)
        return states_frame(np.asarray(x), t[0] + dt * np.arange(n + 1))
    x = replay(
        float(rec["flap_deg"][0]), record_state(rec.row(0, named=True)), dt, ctl, ct,
        rolloff_seed=rolloff_seed, delta_model=model,
    )  # fmt: skip
    return states_frame(np.asarray(x), t[0] + dt * np.arange(n + 1))


def divergence(sim: pl.DataFrame) -> tuple[bool, str]:
    """``(bounded, reason)``: every state finite and V, alpha, beta, theta inside
    :data:`BOUNDS` (the bank angle is free: an uncontrolled roll-off may roll the aircraft far,
    as in the thesis's replays, without the integration blowing up)."""
    v0 = float(sim["V_mps"][0])
    for s in STATES:
        x = sim[s].to_numpy()
        if not np.isfinite(x).all():
            return False, f"{s} not finite"
        if s == "V_mps":
            lo, hi = BOUNDS["V_ratio"]
            if x.min() < lo * v0 or x.max() > hi * v0:
                return False, f"V left [{lo}, {hi}] × V0"
        elif s in BOUNDS:
            lo, hi = BOUNDS[s]
            if x.min() < lo or x.max() > hi:
                return False, f"{s} left [{lo:g}, {hi:g}] deg"
    return True, "bounded"


#: The moment and side-force coefficients a 6-DOF simulation needs from an aerodynamic model,
#: besides the longitudinal forces (:data:`FORCE_PAIRS`).
MOMENTS_AND_SIDE = ("CY", "Cl", "Cm", "Cn")
#: Either pair gives the longitudinal forces: body axes (CX, CZ) or lift and drag (CL, CD).
FORCE_PAIRS = (("CX", "CZ"), ("CL", "CD"))


def daveml_outputs_note(qualified: str) -> str:
    """For a DAVE-ML qualified model (its path) replayed without an aircraft file, a sentence
    saying whether it gives the six coefficients a 6-DOF replay needs (:data:`MOMENTS_AND_SIDE`
    and one of :data:`FORCE_PAIRS`) and which it lacks; ``""`` for another qualified model."""
    if not qualified.lower().endswith((".dml", ".xml")):
        return ""
    path = Path(qualified)
    outs = set(DaveModel(path).outputs)
    lack = [c for c in MOMENTS_AND_SIDE if c not in outs]
    if not any(set(pair) <= outs for pair in FORCE_PAIRS):
        lack.append("CX and CZ (or lift and drag, CL and CD)")
    have = [c for c in ("CX", "CZ", "CL", "CD", *MOMENTS_AND_SIDE) if c in outs]
    if lack:
        return (
            f" The DAVE-ML model {esc(path.name)} gives {', '.join(have) or 'none'} of the "
            f"coefficients a 6-DOF replay needs; missing: {', '.join(lack)}."
        )
    return (
        f" The DAVE-ML model {esc(path.name)} gives all six coefficients ({', '.join(have)}): "
        "name your aircraft file (--aircraft FILE, default DATA/aircraft.toml; build_report("
        "aircraft=...)) and this section flies your aircraft with it."
    )


def pick_maneuvers(ctx: ReportContext, count: int) -> list[str]:
    """Up to ``count`` maneuvers to replay: straight stalls first, held-out ones first, one per
    flap setting in turn."""
    m = (
        ctx.data.group_by("maneuver_id", maintain_order=True)
        .agg(
            pl.col("flap_deg").first(),
            (pl.col("kind").first() if "kind" in ctx.data.columns else pl.lit("")).alias("kind"),
        )
        .with_columns(
            pl.col("maneuver_id").is_in(ctx.held_out).alias("held"),
            (pl.col("kind") == "straight").alias("straight"),
        )
        .sort(["straight", "held", "maneuver_id"], descending=[True, True, False])
    )
    out: list[str] = []
    seen: set[float] = set()
    for r in m.iter_rows(named=True):
        if len(out) >= count:
            break
        if r["flap_deg"] not in seen:
            out.append(r["maneuver_id"])
            seen.add(r["flap_deg"])
    return out


def section(
    ctx: ReportContext,
    sink: FigureSink,
    *,
    count: int = 3,
    controls: str = "elevator",
    ids: Sequence[str] | None = None,
    jsbsim_campaign: str | os.PathLike[str] | None = None,
    aircraft: Aircraft | str | os.PathLike[str] | None = None,
) -> Section:
    """Build the replay section.

    ``jsbsim_campaign``: the JSBSim campaign folder the records come from (or the qualified
    model named ``"jsbsim:DIR"``): its JSBSim aircraft are flown instead of the built-in ADX-37
    (:mod:`aerodelta.report.jsbsim_section`); ``controls`` then does not apply (every recorded
    surface drives the replay).

    ``aircraft``: the aircraft file (or :class:`aerodelta.aircraft.Aircraft`) of records fitted
    against a DAVE-ML qualified model that gives the six coefficients: the replay then flies
    that aircraft with that model (:mod:`aerodelta.report.daveml_replay`), without roll-off.
    """
    sec = Section("replay", "4.3 6-DOF replay")
    campaign = jsbsim_section.campaign_of(ctx, jsbsim_campaign)
    if campaign is not None:
        return jsbsim_section.section(ctx, sink, sec, campaign, count=count, ids=ids)
    if aircraft is not None and _is_daveml(ctx.qualified):
        fly = _daveml_intro(ctx, sec, controls, aircraft)
        if fly is None:
            return sec
        return _replays(ctx, sink, sec, count=count, controls=controls, ids=ids, fly=fly)
    sec.body.append(
        p(
            (
                "The recorded elevator and thrust of each maneuver (aileron, rudder and spoilers "
                "held at zero, as the thesis's Section 4.3 validation) are"
                if controls == "elevator"
                else "All recorded controls of each maneuver are"
            )
            + " fed to the 6-DOF simulator of the built-in ADX-37 from the recorded initial "
            "state, with the stochastic roll-off on (seed 7), twice: with the <b>extended "
            "model</b> (the qualified aerodynamics plus the fitted Δ model, Eq. 3.12, in the "
            "loop) and, for reference, with the qualified model alone. The replay runs open "
            "loop: the recorded pilot flew the real aircraft (and countered its roll-off), so "
            "the lateral states part from the record once the stall is reached; the check is "
            "that the simulation behaves qualitatively like the flight and nothing blows up. "
            "Divergence check: every state finite and inside "
            + bounds_text()
            + " (the bank angle is free; its maximum is reported against the 20 deg of "
            "FAR 25.203)."
        )
    )
    if ctx.qualified != "adx37" or not flown_on_builtin(ctx.data):
        sec.body.append(
            p(
                "Replay not run: aerodelta's 6-DOF simulator flies the built-in ADX-37, and "
                "these records were not flown on it (qualified model: "
                f"{describe(ctx.qualified)}). Replaying them needs your aircraft's own 6-DOF "
                "model with the Δ added (e.g. JSBSim with the exported increments, "
                "docs/export.md); flying another aircraft from your initial states would "
                "prove nothing. For the records of a JSBSim campaign, name the campaign "
                "(--jsbsim-campaign DIR, or the qualified model 'jsbsim:DIR') and this section "
                "flies its JSBSim aircraft." + daveml_outputs_note(ctx.qualified)
            )
        )
        return sec
    return _replays(ctx, sink, sec, count=count, controls=controls, ids=ids, fly=None)


def _is_daveml(qualified: str) -> bool:
    return qualified.lower().endswith((".dml", ".xml"))


def _daveml_intro(
    ctx: ReportContext, sec: Section, controls: str, aircraft: Aircraft | str | os.PathLike[str]
) -> Fly | None:
    """The DAVE-ML replay's paragraph, and its simulator (``None``, with the reason, when the
    model cannot be flown)."""
    name = esc(Path(ctx.qualified).name)
    sec.body.append(
        p(
            (
                "The recorded elevator and thrust of each maneuver (aileron, rudder and spoilers "
                "held at zero, as the thesis's Section 4.3 validation) are"
                if controls == "elevator"
                else "All recorded controls of each maneuver are"
            )
            + " fed to aerodelta's 6-DOF simulator flying <b>your aircraft</b> (mass, inertias "
            f"and geometry from its aircraft file) with <b>your DAVE-ML model</b> {name} from "
            "the recorded initial state, twice: with the extended model (the DAVE-ML "
            "coefficients plus the fitted Δ model, Eq. 3.12, in the loop) and, for "
            "reference, with the DAVE-ML model alone; no stochastic roll-off. The replay runs "
            "open loop, so the lateral states part from the record once the stall is "
            "reached; the check is that the simulation behaves qualitatively like the "
            "flight and nothing blows up. Divergence check: every state finite and inside "
            + bounds_text()
            + " (the bank angle is free; its maximum is reported against the 20 deg of "
            "FAR 25.203)."
        )
    )
    try:
        return daveml_flyer(ctx.qualified, aircraft)
    except AerodeltaError as e:
        sec.body.append(p(f"Replay not run: {esc(e)}"))
        return None


def _replays(
    ctx: ReportContext,
    sink: FigureSink,
    sec: Section,
    *,
    count: int,
    controls: str,
    ids: Sequence[str] | None,
    fly: Fly | None,
) -> Section:
    """The replays, their figures and table (the built-in aircraft, or ``fly``'s)."""
    need = {"tas_mps", "p_dps", "q_dps", "r_dps", "phi_deg", "theta_deg", "de_deg"}
    if not need <= set(ctx.data.columns):
        sec.body.append(
            p(f"Replay skipped: the records lack {sorted(need - set(ctx.data.columns))}.")
        )
        return sec
    rows = []
    for mid in ids if ids is not None else pick_maneuvers(ctx, count):
        rec = ctx.data.filter(pl.col("maneuver_id") == mid).sort("t")
        try:
            sim = replay_maneuver(rec, controls=controls, model=ctx.model, fly=fly)
            qual = replay_maneuver(rec, controls=controls, fly=fly)
        except AerodeltaError as e:  # the engine's own message names the cause
            rows.append({"maneuver_id": mid, "bounded": False, "reason": f"replay failed: {e}"})
            continue
        row, panels = against_record(
            rec, qual, sim, mid=mid, held_out=mid in ctx.held_out,
            labels=("replay, qualified", "replay, extended"),
        )  # fmt: skip
        why = row["reason"]
        sec.body.append(
            sink.plot(
                figures.replay,
                f"replay_{mid}",
                f"6-DOF replay of {mid} (flap {row['flap_deg']:g}): flight record vs the "
                f"simulator with the extended and the qualified model; divergence check of the "
                f"extended replay: {why}.",
                panels=panels,
            )
        )
        rows.append(row)
    if rows:
        t = pl.DataFrame(rows, strict=False)
        sec.body.append(table(t, row_class=lambda r: "" if r["bounded"] else "bad"))
        nb = int(t["bounded"].sum())
        cls = "ok" if nb == t.height else "fail"
        sec.summary.append(("replays bounded", f'<span class="{cls}">{nb} / {t.height}</span>'))
        sec.tables["replay"] = t
    return sec
