"""Pre-stall regression: the extended model leaves the qualified model's results unchanged
where the Δ is blended out (issue 20 item 4; Part 60 asks that the stall model not change the
validated pre-stall behaviour on which the qualified model's tests were passed).

Three checks, per maneuver:

- **coefficients**: along the records, on every sample where the Δ's blend weight (thesis
  Eq. 3.12) is zero for all three lateral coefficients, the extended model's Δ added to the
  qualified model (``dC_blended``) must be exactly zero (a NaN or infinite Δ there would make
  ``0 · Δ`` non-zero: it is counted);
- **time histories** (records flown on the built-in ADX-37, whose qualified model aerodelta
  runs): the recorded controls replayed open loop from the record's first state on the
  extended model (``aero_core``'s runtime ``ExtendedAero``, the model a simulator embeds) and
  on the same model without its lateral Δ (the qualified model, or the qualified model with
  the model's stored longitudinal stall when it flies one); the 12 states must be identical,
  bit for bit, on every step before any replay's angle of attack first comes within
  :data:`MIN_MARGIN_DEG` (or two steps' change of alpha) of the flap's lowest blend start
  ``alpha_l``. After it the two may differ: that is the Δ at work.
- **the stored stall** (a model carrying a Kirchhoff stall fitted on the ADX-37's known terms,
  :meth:`aerodelta.model.DeltaModel.with_longitudinal`): the stall replaces the qualified
  static C_L, C_m curves everywhere, so below the blend start it is not bit-identical to the
  qualified model. Over the same steps, the replay with the stall and the qualified replay
  must stay within the tolerances of Part 60 Appendix A, Table A2A, tests 2.c.1-2.c.4
  (longitudinal dynamics, free response: ±3 kt airspeed, ±100 ft altitude, ±1.5 deg pitch
  angle; :data:`STALL_TOLERANCES`): a stall model may differ from the validated curves before
  the stall by what the qualified model's own tests tolerate, not more.

A maneuver passes when all that apply hold; the row passes when every maneuver does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import polars as pl

from aerodelta.campaign import record_state, replay
from aerodelta.exceptions import AerodeltaError
from aerodelta.fit import model_frame
from aerodelta.model import DeltaModel
from aerodelta.qualified import flown_on_builtin

#: Recorded controls (deg) and thrust coefficients the replays read.
CONTROLS = ("da_deg", "de_deg", "dr_deg", "dsl_deg", "dsr_deg")
THRUST = ("ct_left", "ct_right")
#: Smallest margin (deg) below ``alpha_l`` where the time-history comparison stops: the
#: integrator (RK4) evaluates the model at stage states between a step's end points, so a step
#: ending just below ``alpha_l`` may already have met a non-zero blend weight. The margin is
#: twice the largest one-step change of alpha in the replay, and at least this.
MIN_MARGIN_DEG = 0.05
#: The stored stall's largest allowed deviation from the qualified model before the blend
#: start: airspeed (kt), altitude (ft), pitch angle (deg); Part 60 App. A, Table A2A, tests
#: 2.c.1-2.c.4 (power, flap, spoiler and gear change dynamics, free response).
STALL_TOLERANCES = {"airspeed_kt": 3.0, "altitude_ft": 100.0, "pitch_deg": 1.5}
#: The table's stall-deviation columns, in :data:`STALL_TOLERANCES` order.
_STALL_COLUMNS = ("stall_dv_kt", "stall_dh_ft", "stall_dtheta_deg")
_KT_PER_MPS = 3600.0 / 1852.0
_FT_PER_M = 1.0 / 0.3048


@dataclass(frozen=True)
class PrestallCheck:
    """What :func:`prestall_regression` found.

    Attributes
    ----------
    table
        Per maneuver: ``maneuver_id``, ``flap_deg``, ``alpha_l_deg`` (the flap's lowest blend
        start, deg), ``samples_blended_out`` (record samples with a zero blend weight),
        ``max_abs_dC`` (largest |Δ added| there, over C_l, C_n, C_Y), ``nonfinite_dC`` (samples
        there whose Δ added is not finite), ``steps_compared`` (replay steps before the blend
        start; null: no replay), ``max_state_diff`` (largest |state difference| over them
        between the extended model and the same model without its lateral Δ, SI units and
        rad; null: no replay), ``stall_flown`` (the model's stored stall flew in this
        maneuver's replays),
        ``stall_dv_kt``, ``stall_dh_ft``, ``stall_dtheta_deg`` (with the stall: its largest
        deviation from the qualified replay over the same steps, in airspeed, altitude and
        pitch angle; null without) and ``status`` (``PASS``/``FAIL``).
    replay_note
        Why the time histories were not compared (empty when they were).
    runs
        Per maneuver with a replay: ``t`` (s), ``alpha_qual_deg``, ``alpha_ext_deg``,
        ``p_qual_dps``, ``p_ext_dps`` for the figure, and with the stall flown
        ``alpha_stall_deg``, ``p_stall_dps`` (the stall without the lateral Δ).
    """

    table: pl.DataFrame
    replay_note: str
    runs: dict[str, pl.DataFrame]

    @property
    def passed(self) -> bool:
        """Every maneuver passed."""
        return self.table.height > 0 and bool((self.table["status"] == "PASS").all())


def blend_start(model: DeltaModel, flap_deg: float) -> float:
    """The lowest ``alpha_l`` (deg) over the model's coefficients at ``flap_deg`` (linear in
    flap between the model's flap settings, held outside), deg."""
    spec = model.to_spec()
    flaps = np.asarray(spec["flaps_deg"], dtype=np.float64)
    starts = [
        float(np.interp(flap_deg, flaps, np.asarray(c["alpha_l_deg"], dtype=np.float64)))
        for c in spec["coefficients"].values()
    ]
    return min(starts)


def _alpha_deg(states: np.ndarray) -> np.ndarray:
    return np.degrees(np.arctan2(states[:, 2], states[:, 0]))


def _stall_deviation(qual: np.ndarray, stall: np.ndarray) -> tuple[float, float, float]:
    """Largest |difference| of airspeed (kt), altitude (ft) and pitch angle (deg) between two
    replays' states (rows: steps; u v w, p q r, φ θ ψ, x y h)."""
    if qual.shape[0] == 0:
        return 0.0, 0.0, 0.0
    dv = np.linalg.norm(stall[:, 0:3], axis=1) - np.linalg.norm(qual[:, 0:3], axis=1)
    dh = stall[:, 11] - qual[:, 11]
    dth = np.degrees(stall[:, 7] - qual[:, 7])
    return (
        float(np.max(np.abs(dv))) * _KT_PER_MPS,
        float(np.max(np.abs(dh))) * _FT_PER_M,
        float(np.max(np.abs(dth))),
    )


def prestall_regression(data: pl.DataFrame, model: DeltaModel) -> PrestallCheck:
    """Show that the extended model equals the qualified model where the Δ is blended out
    (module doc).

    Parameters
    ----------
    data
        Ingested records (:func:`aerodelta.ingest` ``.data``).
    model
        The fitted Δ model.

    Returns
    -------
    PrestallCheck
    """
    frame = model_frame(data)
    ev = model.evaluate(frame)
    coefs = [c for c in ("Cl", "Cn", "CY") if f"w_{c}" in ev.columns]
    out = frame.select("maneuver_id", "flap_deg").with_columns(
        out_of_blend=pl.all_horizontal([ev[f"w_{c}"] == 0.0 for c in coefs]),
        added=pl.max_horizontal([ev[f"d{c}_blended"].abs() for c in coefs]),
        finite=pl.all_horizontal([ev[f"d{c}_blended"].is_finite() for c in coefs]),
    )
    coef = (
        out.filter(pl.col("out_of_blend"))
        .group_by("maneuver_id", maintain_order=True)
        .agg(
            pl.len().alias("samples_blended_out"),
            pl.col("added").filter(pl.col("finite")).max().fill_null(0.0).alias("max_abs_dC"),
            (~pl.col("finite")).sum().alias("nonfinite_dC"),
        )
    )
    runs: dict[str, pl.DataFrame] = {}
    rows: list[dict[str, object]] = []
    can_replay = flown_on_builtin(data)
    missing = [c for c in (*CONTROLS, *THRUST, "tas_mps", "h_m") if c not in data.columns]
    note = ""
    if not can_replay:
        note = (
            "the records were not flown on the built-in ADX-37: aerodelta runs no qualified "
            "model of this aircraft to replay (the coefficient check stands alone)"
        )
    elif missing:
        note = f"the records lack {', '.join(missing)} for the replays"
    stall_flaps = set(model.adx37_stall_flaps)  # the ADX-37 replays fly the stall there
    for key, g in (
        data.sort("t").partition_by("maneuver_id", as_dict=True, maintain_order=True).items()
    ):
        mid = str(key[0])
        flap = float(g["flap_deg"][0])
        a_l = blend_start(model, flap)
        steps, diff = None, None
        flown = flap in stall_flaps
        dev: tuple[float, float, float] | None = None
        if not note:
            controls = np.column_stack([g[c].cast(pl.Float64).fill_null(0.0) for c in CONTROLS])
            ct = np.column_stack([g[c].cast(pl.Float64).fill_null(0.0) for c in THRUST])
            t = g["t"].cast(pl.Float64).to_numpy()
            dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
            x0 = record_state(g.row(0, named=True))
            try:
                qual = replay(flap, x0, dt, controls, ct)
                # the extended model without its lateral Δ: the qualified model, with the
                # model's stored stall when it flies one
                base = (
                    replay(flap, x0, dt, controls, ct, delta_model=model, lateral_delta=False)
                    if flown
                    else qual
                )
                ext = replay(flap, x0, dt, controls, ct, delta_model=model)
            except AerodeltaError as e:
                note = f"replay of {mid} failed: {str(e).splitlines()[0]}"
            else:
                aq, ab, ae = _alpha_deg(qual), _alpha_deg(base), _alpha_deg(ext)
                # the integrator's intermediate stages lie near a step's end points, not on
                # them: a step that comes within a margin of alpha_l may already add Δ
                step_max = float(np.nanmax(np.abs(np.diff(aq)))) if aq.size > 1 else 0.0
                margin = max(MIN_MARGIN_DEG, 2.0 * step_max)
                near = (
                    (aq >= a_l - margin) | (ab >= a_l - margin) | (ae >= a_l - margin)
                    | ~np.isfinite(aq + ab + ae)
                )  # fmt: skip
                reached = np.flatnonzero(near)
                steps = int(reached[0]) if reached.size else int(qual.shape[0])
                d = np.abs(base[:steps] - ext[:steps])
                diff = float(d.max()) if steps else 0.0
                if flown:
                    dev = _stall_deviation(qual[:steps], base[:steps])
                tt = t[0] + dt * np.arange(qual.shape[0])
                run = {
                    "t": tt,
                    "alpha_qual_deg": aq,
                    "alpha_ext_deg": ae,
                    "p_qual_dps": np.degrees(qual[:, 3]),
                    "p_ext_dps": np.degrees(ext[:, 3]),
                }
                if flown:
                    run["alpha_stall_deg"] = ab
                    run["p_stall_dps"] = np.degrees(base[:, 3])
                runs[mid] = pl.DataFrame(run)
        rows.append(
            {"maneuver_id": mid, "flap_deg": flap, "alpha_l_deg": a_l,
             "steps_compared": steps, "max_state_diff": diff,
             "stall_flown": flown and steps is not None,
             **dict(zip(_STALL_COLUMNS, dev if dev is not None else (None,) * 3, strict=True))}
        )  # fmt: skip
    table = (
        pl.DataFrame(
            rows,
            schema={
                "maneuver_id": pl.Utf8,
                "flap_deg": pl.Float64,
                "alpha_l_deg": pl.Float64,
                "steps_compared": pl.Int64,
                "max_state_diff": pl.Float64,
                "stall_flown": pl.Boolean,
                **dict.fromkeys(_STALL_COLUMNS, pl.Float64),
            },
        )
        .join(coef.with_columns(pl.col("maneuver_id").cast(pl.Utf8)), on="maneuver_id", how="left")
        .with_columns(
            pl.col("samples_blended_out").fill_null(0).cast(pl.Int64),
            pl.col("max_abs_dC").fill_null(0.0),
            pl.col("nonfinite_dC").fill_null(0).cast(pl.Int64),
        )
    )
    if note:  # a replay failed part-way: none of them is reported
        table = table.with_columns(
            pl.lit(None, pl.Int64).alias("steps_compared"),
            pl.lit(None, pl.Float64).alias("max_state_diff"),
            pl.lit(False).alias("stall_flown"),
            *(pl.lit(None, pl.Float64).alias(c) for c in _STALL_COLUMNS),
        )
        runs = {}
    within = [
        pl.col(c).is_null() | (pl.col(c) <= STALL_TOLERANCES[k])
        for c, k in zip(_STALL_COLUMNS, STALL_TOLERANCES, strict=True)
    ]
    ok = (
        (pl.col("max_abs_dC") == 0.0)
        & (pl.col("nonfinite_dC") == 0)
        & (pl.col("max_state_diff").is_null() | (pl.col("max_state_diff") == 0.0))
        & pl.all_horizontal(within)
    )
    table = table.with_columns(
        pl.when(ok).then(pl.lit("PASS")).otherwise(pl.lit("FAIL")).alias("status")
    )
    table = table.select(
        "maneuver_id", "flap_deg", "alpha_l_deg", "samples_blended_out", "max_abs_dC",
        "nonfinite_dC", "steps_compared", "max_state_diff", "stall_flown", *_STALL_COLUMNS,
        "status",
    )  # fmt: skip
    return PrestallCheck(table=table, replay_note=note, runs=runs)


def describe(check: PrestallCheck) -> str:
    """One paragraph on the check's result, for the matrix row."""
    t = check.table
    n = t.height
    n_pass = int((t["status"] == "PASS").sum())
    samples = int(t["samples_blended_out"].sum())
    parts = [
        f"{n_pass}/{n} maneuvers unchanged: Δ added on the {samples} samples with the blend "
        f"weight at zero, largest |ΔC| {float(t['max_abs_dC'].max() or 0.0):.3g}"
    ]
    bad = int(t["nonfinite_dC"].sum())
    if bad:
        parts.append(f"{bad} samples with a non-finite Δ there")
    if check.replay_note:
        parts.append(f"time histories not compared: {check.replay_note}")
    else:
        steps = int(t["steps_compared"].sum())
        diff = t["max_state_diff"].max()
        flown = t.filter(pl.col("stall_flown"))
        base = "the model without its lateral Δ" if flown.height else "qualified"
        parts.append(
            f"open-loop replays ({base} vs extended, recorded controls) identical over the "
            f"{steps} steps before the blend start (largest state difference "
            f"{0.0 if diff is None else float(diff):.3g})"
        )
        if flown.height:
            flaps = ", ".join(f"{f:g}" for f in flown["flap_deg"].unique().sort().to_list())
            tol = STALL_TOLERANCES
            parts.append(
                f"the stored stall (flap {flaps}) against the qualified model over those steps: "
                f"largest |ΔV| {float(flown['stall_dv_kt'].max() or 0.0):.3g} kt, |Δh| "
                f"{float(flown['stall_dh_ft'].max() or 0.0):.3g} ft, |Δθ| "
                f"{float(flown['stall_dtheta_deg'].max() or 0.0):.3g} deg (Part 60 Table A2A "
                f"2.c.1-2.c.4: ±{tol['airspeed_kt']:g} kt, ±{tol['altitude_ft']:g} ft, "
                f"±{tol['pitch_deg']:g} deg)"
            )
    return "; ".join(parts)


def first_divergence_s(run: pl.DataFrame) -> float:
    """Time (s) of the first step where the two replays' alpha differ (NaN: never)."""
    d = (run["alpha_qual_deg"] - run["alpha_ext_deg"]).abs().to_numpy()
    k = np.flatnonzero(d > 0.0)
    return float(run["t"][int(k[0])]) if k.size else math.nan
