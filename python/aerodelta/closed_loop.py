"""Closed-loop replays of the stall maneuvers: the objective stall tests of 14 CFR Part 60
Table A1A (stall-warning, buffet-onset and stall speeds within ±3 kt; ``docs/evidence.md``).

:func:`closed_loop_replay` flies each recorded stall maneuver again on the simulator
(``aero_core::sim::closed_loop``): from the record's first state, a pilot tracks the recorded
airspeed history (the entry's deceleration) through an alpha loop around the recorded alpha,
holds the recorded bank and sideslip, sets the recorded thrust, and past the record's stall
identification keeps pulling at the test pilot's alpha rate until the *simulator* stalls; the
simulator's pusher (at the aircraft's activation alpha read from the records), stall warning
(the aircraft's vane threshold read from the records) and buffet model act. The simulated time
history then goes through the same identification code as the records
(:func:`aerodelta.stall.stall_identification`), and the three speeds are compared, maneuver by
maneuver, against ±3 kt. The tolerance applies to the stall-speed test conditions: entries
decelerating at most :data:`aerodelta.stall.MAX_TEST_DECEL_KT_S` (3 kt/s; 14 CFR 25.201(c) flies
stalls at 1 kt/s and turning-flight stalls at up to 3 kt/s) over the 3 s before the record's
stall identification (``test_condition``); faster, accelerated entries are replayed and shown,
and the evidence pack's verdict counts them apart.

Supported: records flown on the built-in ADX-37 (ingest's ``builtin_simulator`` mark), whose
qualified model, mass, engines, actuators and pusher aerodelta carries. Other aircraft are
refused in one line.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import polars as pl

from aerodelta import _core
from aerodelta._groups import group_agg
from aerodelta.buffet import _band, detect_onset
from aerodelta.campaign import record_state
from aerodelta.exceptions import DataError, InvalidInputError
from aerodelta.model import DeltaModel
from aerodelta.stall import (
    DETERRENT_BUFFET_RMS_G,
    G0,
    MAX_TEST_DECEL_KT_S,
    stall_identification,
)

__all__ = [
    "QUANTITIES",
    "SPEED_TOLERANCE_KT",
    "ClosedLoopResult",
    "closed_loop_replay",
    "discrete_thresholds",
]

#: Part 60 Table A1A tolerance on the three speeds, kt.
SPEED_TOLERANCE_KT = 3.0
#: (key, column of the stall-identification table, label) of each compared speed.
QUANTITIES: tuple[tuple[str, str, str], ...] = (
    ("v_warning", "v_warning_keas", "stall-warning speed"),
    ("v_buffet_onset", "v_buffet_onset_keas", "buffet-onset speed"),
    ("v_stall", "v_stall_keas", "stall speed"),
)
#: Simulation rate of the replays, Hz.
SIM_HZ = 100.0

_RECORD_COLUMNS, _OUTPUT_COLUMNS = _core.sim_closed_loop_columns()
_KIRCHHOFF_NAMES = tuple(_core.kirchhoff_param_names())
_DRAG_NAMES = tuple(_core.kirchhoff_drag_names())
_CORE_NAMES = tuple(_core.goman_khrabrov_core_names())
#: The tabulated form's separation curve in a ``kirchhoff`` mapping: knots (rad), coefficients.
_TABLE_KEYS = ("x0_knots", "x0_values")

#: One flap's stall as the engine takes it: the tanh form's 9 parameters (or the tabulated
#: form's 7), the drag's 3 or None, and the table (knots in rad, coefficients) or None.
_Stall = tuple[list[float], list[float] | None, tuple[list[float], list[float]] | None]


@dataclass
class ClosedLoopResult:
    """What :func:`closed_loop_replay` found.

    Attributes
    ----------
    table
        One row per maneuver: ``maneuver_id``, ``flap_deg``, ``kind``, ``pusher_armed``,
        ``recognised_by`` (what made the simulated pilot recover: ``pusher``, ``g_break``,
        ``time``), ``alpha_correction_deg`` (the alpha the pilot's speed loop added to the
        recorded one up to the record's stall identification: model minus aircraft),
        ``stall_id_by`` and ``sim_stall_id_by``, ``entry_decel_kt_s`` (the record's, kt/s) and
        ``test_condition`` (the entry decelerates at most ``MAX_TEST_DECEL_KT_S``: a Part 60
        stall-speed test condition, or its deceleration is unknown), ``outside_envelope_s``
        (the time, s, the replayed state spent outside the model's validated envelope, where
        the Δ is extrapolated and a simulator shows its "outside the validated envelope"
        flag; null without a model or for a model with no envelope); per quantity
        ``<q>_rec_keas``, ``<q>_sim_keas``, ``<q>_diff_kt``
        (simulator minus aircraft) and ``<q>_status`` (``PASS``, ``FAIL`` or null when the
        record has no value) for ``v_warning``, ``v_buffet_onset``, ``v_stall``.
    runs
        The simulated time histories by maneuver (the columns the identification reads).
    setup
        The warning and pusher thresholds per flap (deg), the model, the flaps flying the
        Kirchhoff stall given (``kirchhoff_flaps``) and those flying the one ``model`` stores
        (``model_kirchhoff_flaps``), the buffet model, whether the envelope time was counted
        (``envelope``).
    """

    table: pl.DataFrame
    runs: dict[str, pl.DataFrame] = field(default_factory=dict)
    setup: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> pl.DataFrame:
        """Per quantity, flap and ``test_condition``: ``n`` compared, ``n_pass``,
        ``mean_diff_kt``, ``max_abs_diff_kt``."""
        rows = []
        for key, _, _ in QUANTITIES:
            # the mean summed in row order (_groups: a polars group-by mean splits its sums
            # over the thread pool)
            g = group_agg(
                self.table.filter(pl.col(f"{key}_status").is_not_null()),
                ["flap_deg", "test_condition"],
                {"mean_diff_kt": (f"{key}_diff_kt", "mean")},
                exact=[
                    pl.len().alias("n"),
                    (pl.col(f"{key}_status") == "PASS").sum().alias("n_pass"),
                    pl.col(f"{key}_diff_kt").abs().max().alias("max_abs_diff_kt"),
                ],
            ).with_columns(pl.lit(key).alias("quantity"))
            rows.append(g)
        return (
            pl.concat(rows)
            .select(
                "quantity",
                "flap_deg",
                "test_condition",
                "n",
                "n_pass",
                "mean_diff_kt",
                "max_abs_diff_kt",
            )
            .sort("quantity", "flap_deg", "test_condition", descending=[False, False, True])
        )


def _first_on(x: np.ndarray) -> int | None:
    on = np.flatnonzero(x > 0.5)
    return int(on[0]) if on.size else None


def discrete_thresholds(data: pl.DataFrame, discrete: str, alpha: str) -> dict[float, float]:
    """The alpha (deg) at which a discrete (``stall_warning``, ``pusher_active``) switches on,
    per flap, read from the records.

    Every sample before a maneuver's first activation lies below the threshold and the
    activation sample at or above it, so the threshold lies between the highest pre-activation
    alpha and the lowest activation alpha of the flap's maneuvers: the midpoint is taken. When
    noise makes the bracket empty, the median over the maneuvers of the midpoint of the last
    sample before and the first sample at activation.

    Parameters
    ----------
    data
        Ingested records with ``maneuver_id``, ``t``, ``flap_deg``, ``discrete`` and ``alpha``.
    discrete
        The discrete channel (1 on).
    alpha
        The alpha channel it is compared with, deg (the vane ``alpha_deg`` for the warning
        computer, ``alpha_cg_deg`` for the virtual aircraft's pusher).

    Returns
    -------
    dict
        flap (deg) -> threshold (deg); flaps without an activation are absent.
    """
    if discrete not in data.columns or alpha not in data.columns:
        return {}
    per: dict[float, list[tuple[float, float, float]]] = {}
    for (_,), g in data.sort("t").partition_by("maneuver_id", as_dict=True).items():
        a = g[alpha].cast(pl.Float64).to_numpy()
        k = _first_on(g[discrete].cast(pl.Float64).fill_null(0.0).to_numpy())
        if k is None or k == 0:
            continue
        per.setdefault(float(g["flap_deg"][0]), []).append(
            (float(np.max(a[:k])), float(a[k]), 0.5 * float(a[k - 1] + a[k]))
        )
    out = {}
    for flap, v in per.items():
        arr = np.asarray(v)
        lo, hi = float(arr[:, 0].max()), float(arr[:, 1].min())
        out[flap] = 0.5 * (lo + hi) if lo < hi else float(np.median(arr[:, 2]))
    return out


def _kirchhoff_array(params: Any) -> _Stall | None:
    """The stall's parameters, its 3 drag parameters when given, and its table for the
    tabulated form. ``params``: a mapping by name (the tanh form's 9 names; or the tabulated
    form's 7 core names with ``x0_knots`` in rad and ``x0_values``; the drag's names all or
    none), a sequence (9 or 12 values, the tanh form), or a tabulated fit of one flap
    (:class:`aerodelta.goman_khrabrov.GkFlapFit`, with its drag when fitted)."""
    from aerodelta.goman_khrabrov import GkFlapFit  # noqa: PLC0415

    if params is None:
        return None
    if isinstance(params, GkFlapFit):
        drag = params.drag
        params = {
            **params.params,
            "x0_knots": np.radians(np.asarray(params.knots_deg, dtype=np.float64)).tolist(),
            "x0_values": np.asarray(params.x0, dtype=np.float64).tolist(),
            **(dict(drag.params) if drag is not None else {}),
        }
    if isinstance(params, Mapping):
        tabulated = any(k in params for k in _TABLE_KEYS)
        names = _CORE_NAMES if tabulated else _KIRCHHOFF_NAMES
        missing = [n for n in (*names, *(_TABLE_KEYS if tabulated else ())) if n not in params]
        if missing:
            form = "the tabulated form's" if tabulated else "Kirchhoff"
            raise InvalidInputError(
                f"closed-loop replay: {form} parameters lack {', '.join(missing)}; give all "
                f"of {', '.join((*names, *(_TABLE_KEYS if tabulated else ())))}"
            )
        have = [n for n in _DRAG_NAMES if n in params]
        if have and len(have) < len(_DRAG_NAMES):
            lack = ", ".join(n for n in _DRAG_NAMES if n not in params)
            raise InvalidInputError(
                f"closed-loop replay: the Kirchhoff drag lacks {lack}; give all of "
                f"{', '.join(_DRAG_NAMES)} or none (the qualified drag)"
            )
        drag = [float(params[n]) for n in _DRAG_NAMES] if have else None
        table = (
            (
                [float(x) for x in params["x0_knots"]],
                [float(x) for x in params["x0_values"]],
            )
            if tabulated
            else None
        )
        return [float(params[n]) for n in names], drag, table
    v = [float(x) for x in params]
    k, d = len(_KIRCHHOFF_NAMES), len(_DRAG_NAMES)
    if len(v) not in (k, k + d):
        raise InvalidInputError(
            f"closed-loop replay: {len(v)} Kirchhoff parameters; give {k} "
            f"({', '.join(_KIRCHHOFF_NAMES)}), or {k + d} with the drag's "
            f"({', '.join(_DRAG_NAMES)})"
        )
    return v[:k], (v[k:] if len(v) > k else None), None


def _noise_std(t: np.ndarray, alpha: np.ndarray, az: np.ndarray) -> float:
    """White noise (m/s²) whose band-passed RMS is the record's buffet noise floor."""
    dt = float(np.median(np.diff(t)))
    lo, hi = _band(dt)
    floor = float(detect_onset(t, alpha, az)["floor_rms_mps2"])
    frac = max(hi - lo, 0.0) / (0.5 / dt)
    return floor / math.sqrt(frac) if frac > 0 else 0.0


def _time_outside(runs: pl.DataFrame, model: DeltaModel | None) -> dict[str, float]:
    """Per replayed maneuver, the time (s) its simulated state (CG alpha, sideslip, flap)
    spends outside the model's validated envelope (:meth:`DeltaModel.in_envelope`, the flag
    a simulator displays): each sample counts the interval to the next. Empty without a model
    or for a model that carries no envelope."""
    if model is None or model.envelope is None:
        return {}
    states = runs.select(
        "maneuver_id",
        "t",
        "flap_deg",
        pl.col("alpha_cg_deg").alias("alpha_deg"),
        "beta_deg",
    )
    inside = model.in_envelope(states)
    dt = (pl.col("t").shift(-1).over("maneuver_id") - pl.col("t")).fill_null(0.0)
    steps = states.with_columns(pl.when(inside).then(0.0).otherwise(dt).alias("dt_outside"))
    # summed in row order (_groups: a polars group-by sum splits over its thread pool)
    per = group_agg(steps, ["maneuver_id"], {"outside": ("dt_outside", "sum")})
    return {str(m): float(v) for m, v in per.select("maneuver_id", "outside").iter_rows()}


def _status(d: float | None) -> str:
    return "PASS" if d is not None and abs(d) <= SPEED_TOLERANCE_KT else "FAIL"


def closed_loop_replay(
    data: pl.DataFrame | Any,
    *,
    model: DeltaModel | None = None,
    kirchhoff: Mapping[float, Mapping[str, float] | Sequence[float]] | None = None,
    truth_effects: Sequence[str] | Mapping[str, float] | None = None,
    buffet_model: Mapping[str, Any] | None = None,
    maneuvers: Sequence[str] | None = None,
    resist_pusher: bool | None = None,
    aft_stop_deg: float | None = None,
    seed: int = 0,
    table: pl.DataFrame | None = None,
) -> ClosedLoopResult:
    """Fly each stall maneuver of ``data`` again on the ADX-37 simulator in closed loop and
    compare its stall-warning, buffet-onset and stall speeds with the records' (module docs).

    Parameters
    ----------
    data
        Ingested records (:func:`aerodelta.ingest` result or its ``data``) flown on the
        built-in ADX-37.
    model
        The fitted Δ model: the extended model (qualified + Δ) flies. None: the qualified
        model, with ``truth_effects`` when given (a virtual aircraft's truth, for checks).
    kirchhoff
        Per flap (deg), the Kirchhoff stall parameters (by name, engine units, or in
        ``_core.kirchhoff_param_names()`` order) replacing the qualified static C_L, C_m
        curves (e.g. :func:`aerodelta.longitudinal.fit_kirchhoff`'s), with the drag's
        ``CD0``, ``CD_k``, ``CD_x`` replacing the static C_D curve when given (by name, or as
        3 more values; without them the qualified drag flies); or the tabulated form: a
        :class:`aerodelta.goman_khrabrov.GkFlapFit` (with its drag), or a mapping of its core
        parameters with ``x0_knots`` (rad) and ``x0_values``; a flap absent flies the
        stall ``model`` stores for it (:meth:`DeltaModel.with_longitudinal`, when fitted with
        ``known="adx37"``), else the static curves.
    truth_effects
        Effects of the virtual aircraft's truth (names or name -> magnitude); only without
        ``model``.
    buffet_model
        The simulator's buffet model (an ``aero_core`` BuffetSpec as a mapping, e.g. a virtual
        campaign's ``truth/campaign.json`` ``spec.buffet``). None: the simulator has no buffet
        (no buffet onset, and no buffet criterion in its stall identification).
    maneuvers
        Only these maneuver ids (default: all).
    resist_pusher
        Whether the pilots resisted the pusher; None: the manifest's ``pusher_resisted``
        column when the records carry it, else False (the virtual ADX-37's pilots recover when
        the pusher fires).
    aft_stop_deg
        The elevator's aft stop for the identification, deg (None: the recorded extreme).
    seed
        Seed of the simulated buffet and accelerometer noise (the ``i``-th maneuver of the
        records uses ``seed + i``, whichever are replayed).
    table
        :func:`aerodelta.stall.stall_identification` of ``data`` when already computed.

    Returns
    -------
    ClosedLoopResult

    Raises
    ------
    InvalidInputError
        Records not flown on the ADX-37, or bad options: one line.
    DataError
        Records the identification cannot read.

    Examples
    --------
    >>> # res = closed_loop_replay(aerodelta.ingest("camp/").data, model=DeltaModel.load("m.json"))
    >>> # res.summary()
    """
    from aerodelta.qualified import flown_on_builtin  # noqa: PLC0415

    df: pl.DataFrame = getattr(data, "data", data)
    if not isinstance(df, pl.DataFrame) or "maneuver_id" not in df.columns:
        raise DataError("closed-loop replay: give ingested records (a frame with maneuver_id)")
    if not flown_on_builtin(df):
        raise InvalidInputError(
            "closed-loop replay: the records were not flown on the built-in ADX-37 (ingest's "
            "builtin_simulator mark); aerodelta flies closed-loop stall replays only on the "
            "ADX-37, whose qualified model, mass, engines, actuators and pusher it carries"
        )
    if model is not None and truth_effects:
        raise InvalidInputError(
            "closed-loop replay: give either model (the extended model) or truth_effects"
        )
    effects_json = None
    if truth_effects:
        eff = (
            dict(truth_effects)
            if isinstance(truth_effects, Mapping)
            else {str(n): 1.0 for n in truth_effects}
        )
        effects_json = json.dumps([{"name": n, "magnitude": float(m)} for n, m in eff.items()])
    need = [c for c in ("alpha_cg_deg", "beta_cg_deg", *_RECORD_COLUMNS[3:]) if c not in df]
    need = [c for c in need if c not in ("alpha_deg", "beta_deg")]
    if need:
        raise DataError(
            f"closed-loop replay: the records lack {', '.join(need)}; ingest them with "
            "aerodelta ingest (the canonical channels, docs/data.md)"
        )
    kp = {float(f): _kirchhoff_array(p) for f, p in (kirchhoff or {}).items()}
    rec_table = table if table is not None else stall_identification(df, aft_stop_deg=aft_stop_deg)
    warn = discrete_thresholds(df, "stall_warning", "alpha_deg")
    push = discrete_thresholds(df, "pusher_active", "alpha_cg_deg")
    ids = [str(m) for m in rec_table["maneuver_id"]]
    order = {m: i for i, m in enumerate(ids)}  # seeds follow the records' order, any subset
    if maneuvers is not None:
        unknown = sorted(set(maneuvers) - set(ids))
        if unknown:
            raise InvalidInputError(f"closed-loop replay: no maneuver {unknown[0]} in the records")
        ids = [m for m in ids if m in set(maneuvers)]
    groups = {
        str(k[0]): g.sort("t")
        for k, g in df.partition_by("maneuver_id", as_dict=True).items()
        if str(k[0]) in set(ids)
    }
    runs: dict[str, pl.DataFrame] = {}
    meta: dict[str, dict[str, Any]] = {}
    for mid in ids:
        g = groups[mid]
        r = rec_table.filter(pl.col("maneuver_id") == mid).row(0, named=True)
        flap = float(r["flap_deg"])
        t = g["t"].cast(pl.Float64).to_numpy()
        t_peak = float(t[int(np.argmax(g["alpha_cg_deg"].to_numpy()))])
        t_id = t_peak if r["stall_id_t_s"] is None else min(float(r["stall_id_t_s"]), t_peak)
        cols = {
            **{c: g[c] for c in _RECORD_COLUMNS},
            "alpha_deg": g["alpha_cg_deg"],
            "beta_deg": g["beta_cg_deg"],
        }
        rec = np.column_stack(
            [cols[c].cast(pl.Float64).fill_null(0.0).to_numpy() for c in _RECORD_COLUMNS]
        )
        x0 = record_state(g.row(0, named=True))
        resist = resist_pusher
        if resist is None:
            resist = bool(g["pusher_resisted"][0]) if "pusher_resisted" in g.columns else False
        armed = r["pusher_armed"]
        opts: dict[str, Any] = {
            "flap_deg": flap,
            "warning_alpha_deg": warn.get(flap),
            "pusher_alpha_deg": push.get(flap) if armed is not False else None,
            "resist_pusher": bool(resist),
            "t_id_s": t_id,
            "t_peak_s": t_peak,
            "deterrent_buffet_rms_mps2": DETERRENT_BUFFET_RMS_G * G0,
            "az_noise_mps2": _noise_std(t, g["alpha_cg_deg"].to_numpy(), g["az_mps2"].to_numpy())
            if "az_mps2" in g.columns and buffet_model is not None
            else 0.0,
            "seed": int(seed) + order[mid],
            "sim_hz": SIM_HZ,
        }
        if buffet_model is not None:
            opts["buffet"] = dict(buffet_model)
        x, info = _core.sim_closed_loop(
            np.ascontiguousarray(rec),
            x0,
            json.dumps(opts),
            model=model._m if model is not None else None,
            kirchhoff=stall[0] if (stall := kp.get(flap)) is not None else None,
            effects_json=effects_json,
            kirchhoff_drag=stall[1] if stall is not None else None,
            x0_knots=stall[2][0] if stall is not None and stall[2] is not None else None,
            x0_values=stall[2][1] if stall is not None and stall[2] is not None else None,
        )
        sim = pl.DataFrame(np.asarray(x), schema=list(_OUTPUT_COLUMNS), orient="row")
        runs[mid] = sim.with_columns(
            pl.lit(mid).alias("maneuver_id"),
            pl.lit(flap).alias("flap_deg"),
            pl.lit(r["kind"]).alias("kind"),
            pl.lit(armed, dtype=pl.Boolean).alias("pusher"),
        )
        meta[mid] = json.loads(info)
    if not runs:
        raise InvalidInputError("closed-loop replay: no maneuver to replay")
    sim_all = pl.concat(list(runs.values()))
    if buffet_model is None:
        sim_all = sim_all.drop("az_mps2")
    sim_table = stall_identification(sim_all, aft_stop_deg=aft_stop_deg)
    outside = _time_outside(sim_all, model)
    rows = []
    for mid in ids:
        r = rec_table.filter(pl.col("maneuver_id") == mid).row(0, named=True)
        s = sim_table.filter(pl.col("maneuver_id") == mid).row(0, named=True)
        row: dict[str, Any] = {
            "maneuver_id": mid,
            "flap_deg": float(r["flap_deg"]),
            "kind": r["kind"],
            "pusher_armed": r["pusher_armed"],
            "recognised_by": meta[mid]["recognised_by"],
            "alpha_correction_deg": meta[mid]["alpha_correction_deg"],
            "stall_id_by": r["stall_id_by"],
            "sim_stall_id_by": s["stall_id_by"],
            "entry_decel_kt_s": r["entry_decel_kt_s"],
            "test_condition": r["entry_decel_kt_s"] is None
            or r["entry_decel_kt_s"] <= MAX_TEST_DECEL_KT_S,
            "outside_envelope_s": outside.get(mid),
        }
        for key, col, _ in QUANTITIES:
            a, b = r[col], s[col]
            d = None if a is None or b is None else float(b) - float(a)
            row |= {
                f"{key}_rec_keas": a,
                f"{key}_sim_keas": b,
                f"{key}_diff_kt": d,
                f"{key}_status": None if a is None else _status(d),
            }
        rows.append(row)
    schema: dict[str, Any] = {
        "maneuver_id": pl.Utf8,
        "flap_deg": pl.Float64,
        "kind": pl.Utf8,
        "pusher_armed": pl.Boolean,
        "recognised_by": pl.Utf8,
        "alpha_correction_deg": pl.Float64,
        "stall_id_by": pl.Utf8,
        "sim_stall_id_by": pl.Utf8,
        "entry_decel_kt_s": pl.Float64,
        "test_condition": pl.Boolean,
        "outside_envelope_s": pl.Float64,
    }
    for key, _, _ in QUANTITIES:
        schema |= {
            f"{key}_rec_keas": pl.Float64,
            f"{key}_sim_keas": pl.Float64,
            f"{key}_diff_kt": pl.Float64,
            f"{key}_status": pl.Utf8,
        }
    setup = {
        "warning_alpha_deg": warn,
        "pusher_alpha_deg": push,
        "model": "extended (qualified + fitted Δ)" if model is not None else (
            "truth effects" if truth_effects else "qualified"),
        "kirchhoff_flaps": sorted(f for f, v in kp.items() if v is not None),
        "model_kirchhoff_flaps": sorted(
            set(model.adx37_stall_flaps) & {float(x) for x in sim_all["flap_deg"].unique()}
            - set(kp)
        ) if model is not None else [],
        "buffet_model": buffet_model is not None,
        "envelope": bool(outside),
    }  # fmt: skip
    return ClosedLoopResult(table=pl.DataFrame(rows, schema=schema), runs=runs, setup=setup)
