"""The characteristic-by-characteristic matrix of the evidence pack: each stall item of 14 CFR
Part 60 Appendix A (Attachment 7, Table A1A) as ``docs/stall.md`` reads it, assessed from the
records (and the Δ model when given) with the library's own detectors; nothing here invents a
number the data cannot give.

A row's status is ``PASS``/``FAIL`` where a tolerance can be checked from what exists,
``shown`` where the rule asks only to show it, or ``not assessed: <why>``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import polars as pl

from aerodelta._groups import group_agg
from aerodelta.buffet import FREQ_TOLERANCE_HZ, MIN_SPIKES, buffet_identification
from aerodelta.buffet import compare_frequencies as _compare
from aerodelta.evidence import figures
from aerodelta.exceptions import AerodeltaError, InvalidInputError
from aerodelta.model import DeltaModel
from aerodelta.preprocess import GAMMA, R_AIR
from aerodelta.stall import (
    CRITERIA,
    G0,
    MAX_TEST_DECEL_KT_S,
    MIN_MANEUVERS_COVERING,
    VALIDITY_MARGIN_DEG,
    stall_identification,
    stall_summary,
    validity_range,
)

PASS, FAIL, SHOWN = "PASS", "FAIL", "shown"
#: Prefix of a status that could not be assessed (followed by the reason).
NOT_ASSESSED = "not assessed: "
#: Stall speeds tolerance of the objective stall tests, kt (Part 60 Table A1A, issue 20).
SPEED_TOLERANCE_KT = 3.0
#: Power-on entry: the thrust coefficient summed over the engines at stall identification is
#: at least this (two engines at flight idle give about 0.012-0.02 near the stall speed of the
#: virtual ADX-37; set it for the aircraft, ``power_on_ct=`` / ``--power-on-ct``).
POWER_ON_CT = 0.03
#: Maneuver kinds that are wings-level and turning entries (manifest ``kind``).
WINGS_LEVEL_KINDS = ("straight",)
TURNING_KINDS = ("turning", "accelerated")
#: Window of the roll-off figure and metric after stall identification, s.
ROLL_WINDOW_S = 3.0
#: Reference bank limit drawn on the roll-off figure, deg (FAR 25.203(c)).
FAR25_203_BANK_DEG = 20.0
#: Half-width of the time window drawn around a g-break or pitch break, s.
BREAK_WINDOW_S = 3.0
#: Δ parameters of the degraded lateral-directional stability figure (those in the model).
LATERAL_TERMS = (("Cl", "dCl_beta"), ("Cn", "dCn_beta"), ("Cl", "dCl_p"), ("Cn", "dCn_r"))
#: Every n-th sample drawn in the longitudinal figure.
THIN = 4


@dataclass(frozen=True)
class MatrixRow:
    """One characteristic of the matrix.

    Attributes
    ----------
    key
        Anchor of the row (``row-<key>``).
    item
        The characteristic.
    rule
        Where the rule asks for it (as we read it).
    data
        The data used (counts).
    figure
        Anchor (``id``) of the figure that shows it, or None when there is none.
    tolerance
        The tolerance, or what the rule asks.
    status
        ``PASS``, ``FAIL``, ``shown`` or ``not assessed: <why>``.
    detail
        Per flap (or per item) findings, plain text.
    """

    key: str
    item: str
    rule: str
    data: str
    figure: str | None
    tolerance: str
    status: str
    detail: str = ""


@dataclass
class FigureSpec:
    """A figure to draw: its anchor, file stem, drawing function and arguments, caption."""

    anchor: str
    name: str
    draw: Callable[..., Any]
    kwargs: dict[str, Any]
    caption: str


@dataclass
class Assessment:
    """What :func:`assess` found: the rows, the figures to draw, the tables behind them and the
    facts the Statement of Compliance quotes."""

    rows: list[MatrixRow] = field(default_factory=list)
    figures: list[FigureSpec] = field(default_factory=list)
    tables: dict[str, pl.DataFrame] = field(default_factory=dict)
    facts: dict[str, Any] = field(default_factory=dict)

    def figure(self, spec: FigureSpec) -> str:
        """Register a figure; returns its anchor."""
        self.figures.append(spec)
        return spec.anchor


def _flaps_text(values: Mapping[float, str]) -> str:
    return "; ".join(f"flap {f:g}: {v}" for f, v in sorted(values.items()))


def _fmt(x: float | None, spec: str = ".1f") -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def assess(
    data: pl.DataFrame,
    *,
    model: DeltaModel | None = None,
    params: pl.DataFrame | None = None,
    sim_buffet: pl.DataFrame | None = None,
    sim_buffet_source: str = "",
    aft_stop_deg: float | None = None,
    power_on_ct: float = POWER_ON_CT,
    longitudinal: bool = True,
    buffet_model: Mapping[str, Any] | None = None,
    replay: bool = True,
    stall_form: str = "auto",
) -> Assessment:
    """Assess every characteristic of the matrix from ingested records.

    Parameters
    ----------
    data
        Ingested records (:func:`aerodelta.ingest` ``.data``).
    model
        The fitted Δ model (lateral-directional), or None.
    params
        Its per-bin estimates (``MODEL.params.parquet``), or None.
    sim_buffet
        The simulator's buffet frequencies (``flap_deg``, ``freq_hz``, optional ``axis``; Hz),
        or None.
    sim_buffet_source
        Where they come from (one phrase for the page).
    aft_stop_deg
        The elevator's aft stop, deg (None: the recorded extreme per maneuver).
    power_on_ct
        Thrust coefficient (sum over engines) at or above which an entry is power-on.
    longitudinal
        Fit the Kirchhoff stall (:func:`aerodelta.longitudinal.fit_kirchhoff`) where it applies.
    buffet_model
        The simulator's buffet model for the closed-loop replays (an ``aero_core`` BuffetSpec
        as a mapping), or None (the replayed simulator has no buffet).
    replay
        Fly the closed-loop replays of the stall maneuvers (rows 2-4,
        :func:`aerodelta.closed_loop.closed_loop_replay`) when a model is given.
    stall_form
        The form of the separation curve the pack fits: ``"kirchhoff"`` (the tanh,
        :func:`aerodelta.longitudinal.fit_kirchhoff`), ``"goman-khrabrov"`` (the table,
        :func:`aerodelta.goman_khrabrov.fit_goman_khrabrov`) or ``"auto"``: the form ``model``
        stores (:attr:`DeltaModel.stall_form`), else the tanh.

    Returns
    -------
    Assessment
    """
    form = stall_form_of(stall_form, model)
    out = Assessment()
    table = stall_identification(data, aft_stop_deg=aft_stop_deg)
    table = _with_state_at_id(data, table)
    flaps = sorted({float(f) for f in table["flap_deg"]})
    out.tables["stall"] = table
    out.tables["stall_summary"] = stall_summary(table)
    n_man = table.height
    ident = table.filter(pl.col("stall_id_by").is_not_null())
    out.facts.update(
        n_maneuvers=n_man,
        n_identified=ident.height,
        flaps=flaps,
        kinds=dict(table.group_by("kind").len().sort("kind").iter_rows()),
        by=dict(ident.group_by("stall_id_by").len().sort("stall_id_by").iter_rows()),
    )
    buffet = buffet_identification(data) if "az_mps2" in data.columns else None
    fits = fit_longitudinal(data, longitudinal, form)
    loop, why = _replay(
        data, table, model=model, fits=fits, buffet_model=buffet_model,
        aft_stop_deg=aft_stop_deg, enabled=replay,
    )  # fmt: skip
    if loop is not None:
        out.tables["closed_loop"] = loop.table
        out.tables["closed_loop_summary"] = loop.summary()
        out.facts["closed_loop_setup"] = loop.setup
    _stall_id_row(out, table, flaps)
    _speed_rows(out, table, flaps, buffet, loop=loop, why=why)
    _breaks_row(out, data, table)
    _rolloff_row(out, data, table)
    _buffet_rows(out, table, buffet, sim_buffet, sim_buffet_source)
    _validity_row(out, data, table)
    _envelope_row(out, data, model, loop)
    _entries_row(out, table, power_on_ct)
    _lateral_row(out, model, params)
    _longitudinal_row(out, fits)
    _prestall_row(out, data, model)
    _mach_row(out, data, table)
    return out


#: ISA sea-level temperature (K), lapse rate (K/m) to the tropopause (m), sea-level density
#: (kg/m³): ICAO Doc 7488 (the gas constant and ratio of specific heats: ingestion's).
ISA_T0_K, ISA_LAPSE_KPM, ISA_TROPOPAUSE_M, ISA_RHO0 = 288.15, 0.0065, 11000.0, 1.225


def static_temperature(data: pl.DataFrame) -> tuple[pl.Expr, str]:
    """The static air temperature (K) the records give, and where it comes from: the measured
    ``sat_k``; else the ISA temperature at the recorded altitude ``h_m`` (troposphere lapse,
    216.65 K above 11 km); else the ISA temperature of the recorded density (the density
    altitude: ``T = T0 (rho/rho0)^(1/(g/(L R) - 1))``)."""
    if "sat_k" in data.columns:
        return pl.col("sat_k").cast(pl.Float64), "the measured static temperature (sat_k)"
    if "h_m" in data.columns:
        h = pl.col("h_m").cast(pl.Float64).clip(upper_bound=ISA_TROPOPAUSE_M)
        return ISA_T0_K - ISA_LAPSE_KPM * h, "ISA at the recorded altitude (h_m)"
    n = 9.80665 / (ISA_LAPSE_KPM * R_AIR) - 1.0
    return (
        ISA_T0_K * (pl.col("rho_kgm3").cast(pl.Float64) / ISA_RHO0) ** (1.0 / n),
        "ISA at the recorded density (no sat_k or h_m channel)",
    )


def _with_state_at_id(data: pl.DataFrame, table: pl.DataFrame) -> pl.DataFrame:
    """The table with the bank angle ``phi_id_deg``, the thrust coefficient ``ct_id`` (sum
    over the engines) and the Mach number ``mach_id`` (:func:`static_temperature`) at stall
    identification (null without one)."""
    ct = (
        (pl.col("ct_left") + pl.col("ct_right"))
        if {"ct_left", "ct_right"} <= set(data.columns)
        else pl.lit(None, dtype=pl.Float64)
    )
    at = data.select(
        pl.col("maneuver_id").cast(pl.Utf8),
        pl.col("t").alias("stall_id_t_s"),
        pl.col("phi_deg").cast(pl.Float64).alias("phi_id_deg")
        if "phi_deg" in data.columns
        else pl.lit(None, dtype=pl.Float64).alias("phi_id_deg"),
        ct.cast(pl.Float64).alias("ct_id"),
        (
            pl.col("tas_mps").cast(pl.Float64)
            / (GAMMA * R_AIR * static_temperature(data)[0]).sqrt()
        ).alias("mach_id"),
    )
    return table.join(at, on=["maneuver_id", "stall_id_t_s"], how="left", maintain_order="left")


def _stall_id_row(out: Assessment, table: pl.DataFrame, flaps: Sequence[float]) -> None:
    ident = table.filter(pl.col("stall_id_by").is_not_null())
    counts = ", ".join(
        f"{c.replace('_', ' ')} {int((table['stall_id_by'] == c).sum())}" for c in CRITERIA
    )
    per = {
        float(r["flap_deg"]): (
            f"{r['n']} identified, α {_fmt(r['lo'])}-{_fmt(r['hi'])} deg"
            if r["n"]
            else "none identified"
        )
        for r in table.group_by("flap_deg")
        .agg(
            pl.col("stall_id_alpha_deg").is_not_null().sum().alias("n"),
            pl.col("stall_id_alpha_deg").min().alias("lo"),
            pl.col("stall_id_alpha_deg").max().alias("hi"),
        )
        .iter_rows(named=True)
    }
    note = str(table["not_assessed"][0] or "") if table.height else ""
    fig = out.figure(
        FigureSpec(
            "fig-stall-alpha",
            "stall_alpha",
            figures.stall_alpha,
            {"table": table, "flaps": list(flaps)},
            "Stall-identification alpha per maneuver by the criterion met first (left) and the "
            "alpha at every criterion met, the stall warning and the buffet onset (right); "
            "alphas at the CG, maneuvers offset by kind within each flap.",
        )
    )
    status = SHOWN if ident.height else NOT_ASSESSED + "no stall identified in the records"
    out.rows.append(
        MatrixRow(
            "stall_id",
            "Stall-identification angle of attack, per criterion",
            "Part 60 App. A, Attachment 7 (FSTD Directive 2): pusher, pitch break / g-break, "
            "deterrent buffet, 2 s at the aft stop, whichever first",
            f"{table.height} maneuvers, {ident.height} stalls identified (first criterion: "
            f"{counts})",
            fig,
            "identify by each criterion (no numeric tolerance)",
            status,
            _flaps_text(per) + (f". Not assessed in the records: {note}" if note else ""),
        )
    )


def _replay(
    data: pl.DataFrame,
    table: pl.DataFrame,
    *,
    model: DeltaModel | None,
    fits: LongitudinalFits,
    buffet_model: Mapping[str, Any] | None,
    aft_stop_deg: float | None,
    enabled: bool,
) -> tuple[Any, str]:
    """The closed-loop replays of the stall maneuvers with the extended model, or None and why
    not."""
    from aerodelta.closed_loop import closed_loop_replay  # noqa: PLC0415

    if not enabled:
        return None, "the closed-loop replays were switched off (replay=False, --no-replay)"
    if model is None:
        return None, (
            "no fitted Δ model given (--model model.json): the closed-loop replay flies the "
            "extended model"
        )
    # the stall the model carries flies where it has one (what the simulator will fly), the
    # pack's own fit elsewhere
    stored = set(model.adx37_stall_flaps)
    kp = {f: p for f, p in fits.params().items() if f not in stored}
    try:
        res = closed_loop_replay(
            data,
            model=model,
            kirchhoff=kp,
            buffet_model=buffet_model,
            aft_stop_deg=aft_stop_deg,
            table=table,
        )
    except AerodeltaError as e:
        return None, str(e).splitlines()[0]
    return res, ""


def _speed_rows(
    out: Assessment,
    table: pl.DataFrame,
    flaps: Sequence[float],
    buffet: Any,
    *,
    loop: Any,
    why: str,
) -> None:
    from aerodelta.closed_loop import QUANTITIES  # noqa: PLC0415

    lt = loop.table if loop is not None else None
    fig = out.figure(
        FigureSpec(
            "fig-speeds",
            "speeds",
            figures.speeds,
            {"table": table, "flaps": list(flaps), "replay": lt},
            "Flight-test stall-warning, buffet-onset and stall speeds (equivalent airspeed, kt) "
            "per maneuver, by flap and maneuver kind"
            + (
                "; open markers: the closed-loop replay with the extended model (same "
                "identification code), ±3 kt bars around the flight test."
                if lt is not None
                else "."
            ),
        )
    )
    note = str(table["not_assessed"][0] or "") if table.height else ""
    missing = {
        "v_warning": "no stall_warning channel in the records"
        if "stall warning" in note
        else "no stall warning recorded",
        "v_buffet_onset": "no raw az_mps2 channel in the records"
        if buffet is None
        else "no buffet onset found in the records",
        "v_stall": "no stall identified",
    }
    items = {
        "v_warning": "Stall-warning speed",
        "v_buffet_onset": "Buffet-onset speed",
        "v_stall": "Stall speed (at stall identification)",
    }
    setup = loop.setup if loop is not None else {}
    for key, col, _ in QUANTITIES:
        per_rec = {
            float(r["flap_deg"]): (r["n"], r["v"])
            for r in group_agg(  # the mean summed in row order (_groups)
                table,
                ["flap_deg"],
                {"v": (col, "mean")},
                exact=[pl.col(col).is_not_null().sum().alias("n")],
            ).iter_rows(named=True)
            if r["n"]
        }
        n = int(table[col].is_not_null().sum())
        data_text = f"{n} of {table.height} maneuvers with a flight-test value"
        if n == 0:
            status = NOT_ASSESSED + missing[key]
            per = {f: f"{k} maneuvers, mean {_fmt(v)} kt" for f, (k, v) in per_rec.items()}
        elif lt is None:
            status = NOT_ASSESSED + f"{why}; the flight-test speeds are shown"
            per = {f: f"{k} maneuvers, mean {_fmt(v)} kt" for f, (k, v) in per_rec.items()}
        elif key == "v_buffet_onset" and not setup.get("buffet_model"):
            status = NOT_ASSESSED + (
                "no simulator buffet model to fly in the closed-loop replay (a virtual "
                "campaign flown with --buffet carries one); the flight-test speeds are shown"
            )
            per = {f: f"{k} maneuvers, mean {_fmt(v)} kt" for f, (k, v) in per_rec.items()}
        else:
            replayed = lt.filter(pl.col(f"{key}_status").is_not_null())
            # the tolerance applies to the stall-speed test conditions (14 CFR 25.201(c):
            # entries up to 3 kt/s); faster entries are counted apart
            cmp = replayed.filter(pl.col("test_condition"))
            fast = replayed.filter(~pl.col("test_condition"))
            n_pass = int((cmp[f"{key}_status"] == "PASS").sum())
            status = PASS if n_pass == cmp.height else FAIL
            if not cmp.height:
                status = NOT_ASSESSED + (
                    f"no replayed entry within the stall-speed test conditions (at most "
                    f"{MAX_TEST_DECEL_KT_S:g} kt/s, 14 CFR 25.201(c))"
                )
            data_text += f"; {replayed.height} replayed in closed loop with the extended model"
            if fast.height:
                n_fast = int((fast[f"{key}_status"] == "PASS").sum())
                data_text += (
                    f"; {fast.height} entering faster than {MAX_TEST_DECEL_KT_S:g} kt/s "
                    f"(accelerated; outside the 14 CFR 25.201(c) stall-speed test conditions) "
                    f"shown, not judged: {n_fast} of them within ±{SPEED_TOLERANCE_KT:g} kt"
                )
            per = {}
            for r in group_agg(  # the mean summed in row order (_groups)
                cmp,
                ["flap_deg"],
                {"mean": (f"{key}_diff_kt", "mean")},
                exact=[
                    pl.len().alias("n"),
                    (pl.col(f"{key}_status") == "PASS").sum().alias("ok"),
                    pl.col(f"{key}_diff_kt").abs().max().alias("worst"),
                    pl.col(f"{key}_sim_keas").is_null().sum().alias("none"),
                ],
            ).iter_rows(named=True):
                per[float(r["flap_deg"])] = (
                    f"{r['ok']} of {r['n']} within ±{SPEED_TOLERANCE_KT:g} kt (simulator minus "
                    f"flight test: mean {_fmt(r['mean'], '+.1f')} kt, largest "
                    f"{_fmt(r['worst'])} kt"
                    + (f"; {r['none']} with none in the simulator" if r["none"] else "")
                    + ")"
                )
        out.rows.append(
            MatrixRow(
                key,
                items[key],
                "Part 60 App. A, Table A1A objective stall tests (full-stall, FSTD Directive 2)",
                data_text,
                fig,
                f"simulator within ±{SPEED_TOLERANCE_KT:g} kt of the aircraft",
                status,
                _flaps_text(per),
            )
        )


def _windows(
    data: pl.DataFrame, table: pl.DataFrame, tcol: str, value: pl.Expr
) -> list[dict[str, Any]]:
    """Lines ``t`` (from the event, s), ``y`` around each maneuver's event ``tcol``."""
    ev = table.filter(pl.col(tcol).is_not_null()).select("maneuver_id", "kind", tcol)
    if ev.height == 0:
        return []
    w = (
        data.select(pl.col("maneuver_id").cast(pl.Utf8), "t", value.alias("y"))
        .join(ev, on="maneuver_id", maintain_order="left")
        .with_columns((pl.col("t") - pl.col(tcol)).alias("dt"))
        .filter(pl.col("dt").abs() <= BREAK_WINDOW_S)
    )
    return [
        {"id": mid, "kind": g["kind"][0], "t": g["dt"].to_numpy(), "y": g["y"].to_numpy()}
        for (mid,), g in w.partition_by("maneuver_id", as_dict=True, maintain_order=True).items()
    ]


def _breaks_row(out: Assessment, data: pl.DataFrame, table: pl.DataFrame) -> None:
    zcol = next((c for c in ("az_cg_mps2", "az_mps2") if c in data.columns), None)
    ng = int(table["g_break_t_s"].is_not_null().sum())
    npb = int(table["pitch_break_t_s"].is_not_null().sum())
    fig = None
    if ng or npb:
        gb = _windows(data, table, "g_break_t_s", -pl.col(zcol) / G0) if zcol else []
        pb = _windows(data, table, "pitch_break_t_s", pl.col("theta_deg"))
        fig = out.figure(
            FigureSpec(
                "fig-breaks",
                "breaks",
                figures.breaks,
                {"gbreak": gb, "pitch": pb},
                f"Load factor around each g-break and pitch attitude around each pitch break "
                f"(±{BREAK_WINDOW_S:g} s), coloured by maneuver kind.",
            )
        )
    by_kind = table.group_by("kind").agg(
        pl.col("g_break_t_s").is_not_null().sum().alias("g"),
        pl.col("pitch_break_t_s").is_not_null().sum().alias("p"),
    )
    detail = "; ".join(
        f"{k}: g-break {g}, pitch break {p}" for k, g, p in by_kind.sort("kind").rows()
    )
    out.rows.append(
        MatrixRow(
            "breaks",
            "g-break and pitch break",
            "Part 60 App. A, Table A1A objective stall tests: g-break shown; Attachment 7 "
            "(uncommanded nose-down pitch)",
            f"g-break met in {ng}, pitch break in {npb} of {table.height} maneuvers",
            fig,
            "shown (no numeric tolerance)",
            SHOWN if fig else NOT_ASSESSED + "no g-break or pitch break in the records",
            detail,
        )
    )


def _mach_row(out: Assessment, data: pl.DataFrame, table: pl.DataFrame) -> None:
    ident = table.filter(pl.col("mach_id").is_not_null())
    _, source = static_temperature(data)
    per = {
        float(f): (int(n), float(lo), float(hi))
        for f, n, lo, hi in ident.group_by("flap_deg")
        .agg(pl.len(), pl.col("mach_id").min().alias("lo"), pl.col("mach_id").max().alias("hi"))
        .sort("flap_deg")
        .rows()
    }
    out.facts["mach"] = {f: (lo, hi) for f, (_, lo, hi) in per.items()}
    fig = None
    if ident.height:
        fig = out.figure(
            FigureSpec(
                "fig-mach",
                "mach",
                figures.mach,
                {"table": ident, "flaps": sorted(per)},
                f"Mach number at stall identification of every identified stall, per flap and "
                f"maneuver kind (static temperature: {source}).",
            )
        )
    out.rows.append(
        MatrixRow(
            "mach",
            "Mach effects: the Mach range the stall data cover",
            "Part 60 App. A, Attachment 7 (the stall model covers Mach effects)",
            f"{ident.height} identified stalls; Mach from the true airspeed and {source}",
            fig,
            "shown: the Δ model has no Mach dependence, so it is validated over this range "
            "only; stalls at other Mach numbers need data there",
            SHOWN if fig else NOT_ASSESSED + "no stall identified in the records",
            _flaps_text(
                {f: f"Mach {lo:.3f}-{hi:.3f} ({n} stalls)" for f, (n, lo, hi) in per.items()}
            ),
        )
    )


def _rolloff_row(out: Assessment, data: pl.DataFrame, table: pl.DataFrame) -> None:
    from aerodelta.rolloff import detect_rolloff  # noqa: PLC0415  (imports the campaign engine)

    wl = table.filter(
        pl.col("kind").is_in(list(WINGS_LEVEL_KINDS)) & pl.col("stall_id_t_s").is_not_null()
    )
    if wl.height == 0 or "phi_deg" not in data.columns:
        why = (
            "no phi_deg channel"
            if "phi_deg" not in data.columns
            else "no wings-level stall (manifest kind straight) identified"
        )
        out.rows.append(
            MatrixRow(
                "rolloff", "Roll-off (uncommanded roll at the stall), apparent randomness",
                "Part 60 App. A, Table A1A objective stall tests: roll-off shown",
                "0 wings-level stalls identified", None, "shown (no numeric tolerance)",
                NOT_ASSESSED + why,
            )
        )  # fmt: skip
        return
    win = (
        data.select(pl.col("maneuver_id").cast(pl.Utf8), "t", "phi_deg")
        .join(
            wl.select("maneuver_id", "stall_id_t_s", "phi_id_deg"),
            on="maneuver_id",
            maintain_order="left",
        )
        .with_columns((pl.col("t") - pl.col("stall_id_t_s")).alias("dt"))
    )
    bank = (
        win.filter((pl.col("dt") >= 0) & (pl.col("dt") <= ROLL_WINDOW_S))
        .group_by("maneuver_id")
        .agg((pl.col("phi_deg") - pl.col("phi_id_deg")).abs().max().alias("bank_change_deg"))
    )
    events_note = ""
    try:
        ev = detect_rolloff(data, kinds=list(WINGS_LEVEL_KINDS)).filter(pl.col("accepted"))
    except (AerodeltaError, pl.exceptions.PolarsError) as e:
        ev = None
        events_note = f" (roll-off events not detected: {str(e).splitlines()[0]})"
    events: dict[str, np.ndarray] = {}
    n_all = 0
    if ev is not None and ev.height:
        rel = ev.join(
            wl.select("maneuver_id", "stall_id_t_s"), on="maneuver_id", maintain_order="left"
        ).with_columns((pl.col("t_onset") - pl.col("stall_id_t_s")).alias("dt"))
        events = {
            str(m): g["dt"].to_numpy()
            for (m,), g in rel.filter(
                (pl.col("dt") >= -2.0) & (pl.col("dt") <= 3.0 * ROLL_WINDOW_S)
            )
            .partition_by("maneuver_id", as_dict=True)
            .items()
        }
        n_all = ev.filter(pl.col("maneuver_id").is_in(wl["maneuver_id"].to_list())).height
    shown = win.filter((pl.col("dt") >= -2.0) & (pl.col("dt") <= 3.0 * ROLL_WINDOW_S))
    lines = [
        {
            "id": m,
            "t": g["dt"].to_numpy(),
            "y": g["phi_deg"].to_numpy(),
            "events": events.get(m, []),
        }
        for (m,), g in shown.partition_by("maneuver_id", as_dict=True, maintain_order=True).items()
    ]
    out.tables["rolloff"] = wl.select("maneuver_id", "flap_deg", "stall_id_t_s").join(
        bank, on="maneuver_id", how="left", maintain_order="left"
    )
    fig = out.figure(
        FigureSpec(
            "fig-rolloff",
            "rolloff",
            figures.rolloff,
            {"lines": lines, "limit_deg": FAR25_203_BANK_DEG},
            "Bank angle of the wings-level stalls from 2 s before to "
            f"{3 * ROLL_WINDOW_S:g} s after stall identification; dashed: ±"
            f"{FAR25_203_BANK_DEG:g} deg (FAR 25.203(c), for scale); ▼ roll-off events "
            "detected in the rolling-moment residual (docs/rolloff.md).",
        )
    )
    b = out.tables["rolloff"]["bank_change_deg"]
    n_ev = sum(len(v) for v in events.values())  # those in the window drawn
    out.rows.append(
        MatrixRow(
            "rolloff",
            "Roll-off (uncommanded roll at the stall), apparent randomness",
            "Part 60 App. A, Table A1A objective stall tests: roll-off shown; Attachment 7 "
            "(uncommanded roll-off, apparent randomness)",
            f"{wl.height} wings-level stalls identified, {n_all} roll-off events detected in "
            f"them ({n_ev} from 2 s before to {3 * ROLL_WINDOW_S:g} s after stall identification)",
            fig,
            "shown (no numeric tolerance)",
            SHOWN,
            f"bank change within {ROLL_WINDOW_S:g} s of stall identification: median "
            f"{_fmt(b.median())}, max {_fmt(b.max())} deg" + events_note,  # type: ignore[arg-type]
        )
    )


def _buffet_rows(
    out: Assessment,
    table: pl.DataFrame,
    buffet: Any,
    sim: pl.DataFrame | None,
    sim_source: str,
) -> None:
    rule_f = (
        "Part 60 App. A, Table A1A test 3.f.5 (buffet at approach to stall; full stall under "
        "FSTD Directive 2)"
    )
    tol_f = f"at least {MIN_SPIKES} predominant spikes within ±{FREQ_TOLERANCE_HZ:g} Hz"
    if buffet is None:
        why = NOT_ASSESSED + "the records have no raw az_mps2 accelerometer channel"
        out.rows.append(MatrixRow("buffet_freq", "Stall buffet: predominant frequencies", rule_f,
                                  "no raw accelerometer", None, tol_f, why))  # fmt: skip
        out.rows.append(MatrixRow("buffet_onset", "Stall buffet: onset and amplitude against α",
                                  "Attachment 7 (stall buffet in the model)",
                                  "no raw accelerometer", None, "shown", why))  # fmt: skip
        return
    out.tables["buffet_per_flap"] = buffet.per_flap
    out.tables["buffet_frequencies"] = buffet.frequencies
    n_buf = int(buffet.per_flap["n_buffet"].sum())
    onsets = {
        float(f): float(a)
        for f, a in buffet.per_flap.select("flap_deg", "onset_alpha_deg").rows()
        if a is not None
    }
    fig_amp = out.figure(
        FigureSpec(
            "fig-buffet-amplitude",
            "buffet_amplitude",
            figures.buffet_amplitude,
            {"amplitude": buffet.amplitude, "onsets": onsets},
            "Buffet amplitude (4-20 Hz band-passed RMS of the raw accelerometers) against alpha "
            "per flap (bands with at least 25 samples); dashed: the flap's median buffet-onset "
            "alpha.",
        )
    )
    out.rows.append(
        MatrixRow(
            "buffet_onset",
            "Stall buffet: onset and amplitude against α",
            "Attachment 7 (the model covers stall buffet)",
            f"buffet found in {n_buf} of {buffet.per_flap['n_maneuvers'].sum()} maneuvers",
            fig_amp,
            "shown (onset speed: see the buffet-onset speed row)",
            SHOWN if n_buf else NOT_ASSESSED + "no buffet found in the records",
            _flaps_text(
                {
                    float(r["flap_deg"]): f"{r['n_buffet']} with buffet, onset α "
                    f"{_fmt(r['onset_alpha_deg'])} deg (median)"
                    for r in buffet.per_flap.iter_rows(named=True)
                }
            ),
        )
    )
    freqs = buffet.frequencies
    fig = None
    if buffet.spectra.height:
        fig = out.figure(
            FigureSpec(
                "fig-buffet-spectra",
                "buffet_spectra",
                figures.buffet_spectra,
                {"spectra": buffet.spectra, "peaks": freqs, "simulated": sim,
                 "tol_hz": FREQ_TOLERANCE_HZ},
                "Averaged Welch PSD of the buffet segments per flap (normal nz, lateral ny), "
                "the identified predominant spikes (dots)"
                + (
                    f" and the simulator's frequencies ({sim_source}) with their "
                    f"±{FREQ_TOLERANCE_HZ:g} Hz band (green)."
                    if sim is not None
                    else "."
                ),
            )
        )  # fmt: skip
    spikes = {
        float(f): ", ".join(f"{v:.2f}" for v in g["freq_hz"].sort())
        for (f,), g in freqs.partition_by("flap_deg", as_dict=True).items()
    }
    data_text = (
        f"{freqs.height} spikes identified in {freqs['flap_deg'].n_unique()} flap settings "
        f"({int(buffet.per_flap['n_spectrum_segments'].fill_null(0).sum())} Welch segments)"
    )
    if freqs.height == 0:
        status = NOT_ASSESSED + "no buffet segment long enough for a spectrum in the records"
        detail = ""
    elif sim is None:
        status = NOT_ASSESSED + (
            "no simulator buffet frequencies to compare (give sim_buffet= / --sim-buffet FILE); "
            "the flight-test spikes are shown"
        )
        detail = _flaps_text({f: f"{v} Hz" for f, v in spikes.items()})
    else:
        cmp = _compare(sim, freqs, tolerance_hz=FREQ_TOLERANCE_HZ, min_spikes=MIN_SPIKES)
        out.tables["buffet_comparison"] = cmp
        per = cmp.group_by("flap_deg").agg(
            pl.col("flap_pass").first(), pl.col("n_present").first(), pl.col("n_required").first()
        )
        ok = bool(per["flap_pass"].all())
        status = PASS if ok else FAIL
        detail = (
            _flaps_text(
                {
                    float(r["flap_deg"]): f"{'PASS' if r['flap_pass'] else 'FAIL'} "
                    f"({r['n_present']} of {r['n_required']} required spikes within "
                    f"±{FREQ_TOLERANCE_HZ:g} Hz; flight test "
                    f"{spikes.get(float(r['flap_deg']), '')} Hz)"
                    for r in per.iter_rows(named=True)
                }
            )
            + f". Simulator: {sim_source}"
        )
    out.facts["buffet_status"] = status
    out.rows.append(
        MatrixRow("buffet_freq", "Stall buffet: predominant frequencies", rule_f, data_text, fig,
                  tol_f, status, detail)
    )  # fmt: skip


def _validity_row(out: Assessment, data: pl.DataFrame, table: pl.DataFrame) -> None:
    coverage, verdict = validity_range(data, table)
    out.tables["validity"] = verdict
    out.tables["coverage"] = coverage
    fig = out.figure(
        FigureSpec(
            "fig-validity",
            "validity",
            figures.validity,
            {"verdict": verdict, "coverage": coverage},
            "Flight-test samples per 2 deg alpha band per flap (log scale) against the highest "
            "stall-identification alpha (dashed) and the alpha "
            f"{VALIDITY_MARGIN_DEG:g} deg beyond it (red) to which the model must be valid.",
        )
    )
    judged = verdict.filter(pl.col("stall_id_alpha_deg").is_not_null())
    if judged.height == 0:
        status = NOT_ASSESSED + "no stall identified, so no validity range can be set"
    else:
        status = PASS if bool(judged["covered"].all()) else FAIL
    out.facts["validity_status"] = status
    out.facts["validity_lines"] = verdict["verdict"].to_list()
    out.rows.append(
        MatrixRow(
            "validity",
            f"Validity range ≥ {VALIDITY_MARGIN_DEG:g} deg of α beyond stall identification",
            "Part 60 App. A, Attachment 7 (FSTD Directive 2)",
            f"{int(coverage['n_samples'].sum())} samples in {coverage['flap_deg'].n_unique()} "
            "flap settings",
            fig,
            f"flight data reach stall identification + {VALIDITY_MARGIN_DEG:g} deg in at least "
            f"{MIN_MANEUVERS_COVERING} maneuvers per flap (else other data must be declared)",
            status,
            "; ".join(verdict["verdict"].to_list()),
        )
    )


def _outlines(env: pl.DataFrame) -> dict[float, list[tuple[np.ndarray, np.ndarray]]]:
    """Closed (β, α) polygons of the validated envelope per flap, one per run of adjacent
    alpha bands."""
    out: dict[float, list[tuple[np.ndarray, np.ndarray]]] = {}
    for (flap,), g in (
        env.sort("flap_deg", "alpha_lo_deg")
        .partition_by("flap_deg", as_dict=True, maintain_order=True)
        .items()
    ):
        lo, hi = g["alpha_lo_deg"].to_numpy(), g["alpha_hi_deg"].to_numpy()
        bmin, bmax = g["beta_min_deg"].to_numpy(), g["beta_max_deg"].to_numpy()
        cuts = np.flatnonzero(lo[1:] != hi[:-1]) + 1
        polys = []
        for idx in np.split(np.arange(lo.size), cuts):
            a_right = np.column_stack([lo[idx], hi[idx]]).ravel()
            b_right = np.repeat(bmax[idx], 2)
            b = np.concatenate([b_right, np.repeat(bmin[idx], 2)[::-1], b_right[:1]])
            a = np.concatenate([a_right, a_right[::-1], a_right[:1]])
            polys.append((b, a))
        out[float(flap)] = polys
    return out


def _replay_outside(replays: pl.DataFrame) -> str:
    """The closed-loop replays' time outside the validated envelope, one sentence."""
    t = replays.filter(pl.col("outside_envelope_s").is_not_null())
    out = t.filter(pl.col("outside_envelope_s") > 0.0).sort(
        "outside_envelope_s", "maneuver_id", descending=[True, False]
    )
    if not out.height:
        return (
            f". The {t.height} closed-loop replays with the extended model stay inside it "
            "throughout"
        )
    worst = out.row(0, named=True)
    return (
        f". {out.height} of the {t.height} closed-loop replays with the extended model leave it "
        f"(the Δ extrapolated there): {_fmt(float(out['outside_envelope_s'].sum()), '.1f')} s "
        f"in all, the longest {_fmt(worst['outside_envelope_s'], '.1f')} s "
        f"({worst['maneuver_id']})"
    )


def _envelope_row(
    out: Assessment, data: pl.DataFrame, model: DeltaModel | None, loop: Any = None
) -> None:
    acol = "alpha_cg_deg" if "alpha_cg_deg" in data.columns else "alpha_deg"
    bcol = "beta_cg_deg" if "beta_cg_deg" in data.columns else "beta_deg"
    kind = pl.col("kind").cast(pl.Utf8) if "kind" in data.columns else pl.lit("other")
    pts = data.select(
        pl.col("flap_deg").cast(pl.Float64),
        kind.fill_null("other").alias("kind"),
        pl.col(acol).cast(pl.Float64).alias("alpha_deg"),
        pl.col(bcol).cast(pl.Float64).alias("beta_deg"),
        pl.col("maneuver_id"),
    )
    points = [
        {"flap": f, "kind": k, "alpha": g["alpha_deg"].to_numpy(), "beta": g["beta_deg"].to_numpy()}
        for (f, k), g in pts.partition_by(["flap_deg", "kind"], as_dict=True).items()
    ]
    counts = (
        pts.group_by("flap_deg", "kind")
        .agg(pl.col("maneuver_id").n_unique().alias("maneuvers"), pl.len().alias("samples"))
        .sort("flap_deg", "kind")
    )
    out.tables["envelope_counts"] = counts
    outlines = None
    detail = "; ".join(
        f"flap {f:g} {k}: {m} maneuvers, {s} samples" for f, k, m, s in counts.rows()
    )
    status = SHOWN
    env = model.envelope if model is not None else None
    if model is not None and env is None:
        detail += ". The model carries no validated envelope (an older model file): refit it"
    elif env is not None:
        outlines = _outlines(env)
        inside = pts.with_columns(model.in_envelope(pts).alias("inside"))  # type: ignore[union-attr]
        share = inside.group_by("flap_deg").agg(pl.col("inside").mean()).sort("flap_deg")
        out.tables["envelope_inside"] = share
        detail += ". Share of the samples inside the model's validated envelope (the simulator's " \
            "'outside the validated envelope' flag, DeltaModel.in_envelope): " + ", ".join(
                f"flap {f:g} {100 * s:.0f} %" for f, s in share.rows()
            )  # fmt: skip
        if loop is not None and loop.setup.get("envelope"):
            detail += _replay_outside(loop.table)
    fig = out.figure(
        FigureSpec(
            "fig-envelope",
            "envelope",
            figures.envelope,
            {"points": points, "outlines": outlines},
            "α against β (at the CG) of every flight-test sample per flap, coloured by maneuver "
            "kind" + ("; black: the model's validated envelope (DeltaModel.envelope)." if outlines
                      else "."),
        )
    )  # fmt: skip
    out.rows.append(
        MatrixRow(
            "envelope",
            "α/β envelope of the flight-test points per flap and maneuver kind",
            "Part 60 App. A, Attachment 7 (FSTD Directive 2): α/β envelope plots with the "
            "maneuver types; the simulator flags flight outside the validated envelope",
            f"{pts.height} samples of {pts['maneuver_id'].n_unique()} maneuvers",
            fig,
            "shown (no numeric tolerance)",
            status,
            detail,
        )
    )


def _entries_row(out: Assessment, table: pl.DataFrame, power_on_ct: float) -> None:
    ident = table.filter(pl.col("stall_id_t_s").is_not_null())
    wl = int(ident["kind"].is_in(list(WINGS_LEVEL_KINDS)).sum())
    turn = int(ident["kind"].is_in(list(TURNING_KINDS)).sum())
    has_ct = bool(ident["ct_id"].is_not_null().any()) if ident.height else False
    pw = int((ident["ct_id"] >= power_on_ct).sum()) if has_ct else 0
    out.facts["entries"] = {"wings_level": wl, "turning": turn, "power_on": pw}
    missing = [n for n, c in (("wings-level", wl), ("turning", turn), ("power-on", pw)) if c == 0]
    fig = None
    if ident.height and has_ct and "phi_id_deg" in ident.columns:
        fig = out.figure(
            FigureSpec(
                "fig-entries",
                "entries",
                figures.entries,
                {"table": ident, "power_on_ct": power_on_ct},
                "Bank angle and thrust coefficient (sum over the engines) at stall "
                "identification of every identified stall, by maneuver kind; dashed: the "
                f"power-on threshold C_T = {power_on_ct:g}.",
            )
        )
    known_kinds = set(WINGS_LEVEL_KINDS) | set(TURNING_KINDS)
    if ident.height == 0:
        status = NOT_ASSESSED + "no stall identified in the records"
    elif not has_ct:
        status = NOT_ASSESSED + "no ct_left/ct_right channels, so power-on cannot be told"
    elif ident.height and not ident["kind"].is_in(list(known_kinds | {"asymmetric_thrust"})).any():
        status = NOT_ASSESSED + (
            "no maneuver kind in the manifest (straight, turning, accelerated), so wings-level "
            "and turning entries cannot be told; give --manifest"
        )
    else:
        status = PASS if not missing else FAIL
    out.rows.append(
        MatrixRow(
            "entries",
            "Wings-level, turning and power-on stall entries",
            "Part 60 App. A, Table A1A objective stall tests (FSTD Directive 2)",
            f"{ident.height} identified stalls: {wl} wings-level "
            f"(kind {', '.join(WINGS_LEVEL_KINDS)}), {turn} turning "
            f"(kind {', '.join(TURNING_KINDS)}), {pw} power-on (C_T ≥ {power_on_ct:g})",
            fig,
            "each entry present with at least one identified stall",
            status,
            ("missing: " + ", ".join(missing)) if missing else "all three entries present",
        )
    )


def _lateral_row(out: Assessment, model: DeltaModel | None, params: pl.DataFrame | None) -> None:
    rule = (
        "Part 60 App. A, Attachment 7 (FSTD Directive 2): the model covers degraded "
        "lateral-directional stability and control"
    )
    if model is None:
        out.rows.append(
            MatrixRow("lateral", "Degraded lateral-directional stability (fitted Δ)", rule,
                      "no model", None, "shown with its uncertainty",
                      NOT_ASSESSED + "no fitted Δ model given (--model model.json)")
        )  # fmt: skip
        return
    spec = model.to_spec()
    flaps = [float(f) for f in spec["flaps_deg"]]
    cols = set(model.input_columns)
    panels = []
    n_ident = 0
    for coef, name in LATERAL_TERMS:
        terms = {t["name"]: t for t in spec["coefficients"].get(coef, {}).get("terms", [])}
        term = terms.get(name)
        if term is None or term["regressor"] not in cols:
            continue
        grid = np.linspace(min(term["alpha_deg"]), max(term["alpha_deg"]), 61)
        series = []
        for flap in flaps:
            frame = pl.DataFrame(
                {c: np.zeros(grid.size) for c in cols}
            ).with_columns(
                pl.Series("alpha_deg", grid),
                pl.lit(flap).alias("flap_deg"),
                pl.lit(1.0).alias(term["regressor"]),
            )  # fmt: skip
            tab = model.evaluate(frame, coefficients=[coef], terms=True)[name].to_numpy()
            s: dict[str, Any] = {"flap": flap, "grid": grid, "table": tab, "c": [], "est": [],
                                 "lo": [], "hi": []}  # fmt: skip
            if params is not None:
                b = params.filter(
                    (pl.col("param") == name)
                    & (pl.col("flap_deg") == flap)
                    & pl.col("identifiable")
                    & pl.col("ci95_lower").is_finite()
                )
                n_ident += b.height
                s.update(
                    c=0.5 * (b["alpha_lo_deg"].to_numpy() + b["alpha_hi_deg"].to_numpy()),
                    est=b["estimate"].to_numpy(),
                    lo=b["ci95_lower"].to_numpy(),
                    hi=b["ci95_upper"].to_numpy(),
                )
            series.append(s)
        panels.append({"name": name, "series": series})
    if not panels:
        out.rows.append(
            MatrixRow("lateral", "Degraded lateral-directional stability (fitted Δ)", rule,
                      "model without those terms", None, "shown with its uncertainty",
                      NOT_ASSESSED + "the model has none of "
                      + ", ".join(n for _, n in LATERAL_TERMS))
        )  # fmt: skip
        return
    fig = out.figure(
        FigureSpec(
            "fig-lateral",
            "lateral",
            figures.lateral,
            {"panels": panels},
            "Fitted Δ stability derivatives against alpha per flap: the model's smoothed table "
            "(line, unblended) and the identified per-bin estimates with their 95 % intervals "
            "(cluster-robust CR2, Bell-McCaffrey t; MODEL.params.parquet)."
            + ("" if params is not None else " No per-bin estimates beside the model: no bars."),
        )
    )
    out.rows.append(
        MatrixRow(
            "lateral",
            "Degraded lateral-directional stability (fitted Δ)",
            rule,
            f"{len(panels)} Δ derivatives ({', '.join(str(p['name']) for p in panels)}) in "
            f"{len(flaps)} flap settings; {n_ident} identified bins",
            fig,
            "shown with its uncertainty",
            SHOWN,
            "per-bin 95 % intervals from the fit"
            if params is not None
            else "no per-bin estimates (MODEL.params.parquet) beside the model: tables only",
        )
    )


@dataclass
class LongitudinalFits:
    """The output-error stall fits of the records per flap (:func:`fit_longitudinal`), in the
    form ``form`` of the separation curve."""

    fitted: dict[float, Any] = field(default_factory=dict)
    notes: dict[float, str] = field(default_factory=dict)
    known: str = "none"
    frame: pl.DataFrame | None = None
    why: str | None = None
    form: str = "kirchhoff"

    def params(self) -> dict[float, Any]:
        """flap -> what the closed-loop replays fly (``closed_loop_replay(kirchhoff=)``): the
        tanh form's fitted parameters (engine units, by name) with the drag's where fitted, or
        the tabulated form's fit of the flap (:class:`aerodelta.goman_khrabrov.GkFlapFit`,
        with its drag)."""
        out: dict[float, Any] = {}
        for f, r in self.fitted.items():
            if self.form == "goman-khrabrov":
                out[f] = r[f]
                continue
            drag = r[f].drag
            out[f] = {**r[f].params, **(drag.params if drag is not None else {})}
        return out


#: The forms of the separation curve the pack can fit (``stall_form``), and ``"auto"``.
STALL_FORMS = ("auto", "kirchhoff", "goman-khrabrov")


def stall_form_of(stall_form: str, model: DeltaModel | None) -> str:
    """The form the pack fits: ``stall_form``, or for ``"auto"`` the one ``model`` stores
    (else the tanh). Anything else is refused."""
    if stall_form not in STALL_FORMS:
        raise InvalidInputError(
            f"stall_form '{stall_form}': use {', '.join(repr(f) for f in STALL_FORMS)}"
        )
    if stall_form != "auto":
        return stall_form
    stored = model.stall_form if model is not None else None
    return stored or "kirchhoff"


def fit_longitudinal(
    data: pl.DataFrame, enabled: bool, form: str = "kirchhoff"
) -> LongitudinalFits:
    """Fit the stall by output error per flap where it applies, in the form ``form``
    (``"kirchhoff"``: the tanh separation curve; ``"goman-khrabrov"``: the table, started from
    the tanh fit of the same flap); ``why`` says why not when it does not."""
    from aerodelta.fit import model_frame  # noqa: PLC0415
    from aerodelta.goman_khrabrov import fit_goman_khrabrov  # noqa: PLC0415
    from aerodelta.longitudinal import fit_kirchhoff  # noqa: PLC0415
    from aerodelta.qualified import flown_on_builtin  # noqa: PLC0415

    need = ("CX_meas", "CZ_meas", "Cm_meas", "alphadot_dps")
    missing = [c for c in need if c not in data.columns]
    if not enabled or missing:
        why = "switched off (longitudinal=False)" if not enabled else (
            f"the records lack {', '.join(missing)} (ingest them with aerodelta ingest)"
        )  # fmt: skip
        return LongitudinalFits(why=why, form=form)
    mf = model_frame(data)
    known = "adx37" if flown_on_builtin(mf) else "none"
    out = LongitudinalFits(known=known, frame=mf, form=form)
    for flap in sorted({float(f) for f in mf["flap_deg"]}):
        try:
            if form == "goman-khrabrov":
                out.fitted[flap] = fit_goman_khrabrov(mf, flaps=[flap], known=known)
            else:
                out.fitted[flap] = fit_kirchhoff(mf, flaps=[flap], known=known)
        except AerodeltaError as e:
            out.notes[flap] = "not fitted: " + str(e).splitlines()[0]
    return out


def _longitudinal_row(out: Assessment, fits: LongitudinalFits) -> None:
    from aerodelta.longitudinal import measured_lift  # noqa: PLC0415

    item = "Longitudinal stall: lift break, pitch break, hysteresis (Kirchhoff)"
    rule = (
        "Part 60 App. A, Attachment 7 (FSTD Directive 2): the model covers changes in pitch "
        "stability and the stall's lift loss"
    )
    if fits.why is not None or fits.frame is None:
        out.rows.append(MatrixRow("longitudinal", item, rule, "-", None, "shown",
                                  NOT_ASSESSED + str(fits.why)))  # fmt: skip
        return
    mf, known, fitted = fits.frame, fits.known, fits.fitted
    notes = dict(fits.notes)
    panels = []
    rows = []
    for flap, res in fitted.items():
        ff = res[flap]
        sub = mf.filter(pl.col("flap_deg") == flap)
        pred = res.predict(sub, known=known)
        panels.append(
            {
                "flap": flap,
                "alpha": sub["alpha_deg"].to_numpy()[::THIN],
                "cl": measured_lift(sub)[::THIN],
                "cl_model": pred["CL_model"].to_numpy()[::THIN],
                "cm": sub["Cm_meas"].to_numpy()[::THIN],
                "cm_model": pred["Cm_model"].to_numpy()[::THIN],
            }
        )
        a_max, cl_max = ff.cl_max
        sec = ff.std_err_colored
        lags = (
            f"tau1 {ff.params['tau1']:.3f} ± {sec['tau1']:.3f} s, tau2 {ff.params['tau2']:.3f} ± "
            f"{sec['tau2']:.3f} s"
            if ff.tau_identified
            else ff.note  # static records: "tau1, tau2 not identified: why ..."
        )
        drag = (
            f", separated-flow drag C_Dx {ff.drag.params['CD_x']:.3f} ± "
            f"{ff.drag.std_err['CD_x']:.3f}"
            if ff.drag is not None
            else ""
        )
        if fits.form == "goman-khrabrov":
            knots = ff.knots_deg
            curve = (
                f"separation table on {len(knots)} knots, {knots[0]:.0f}-{knots[-1]:.0f} deg"
                + (f" ({ff.note})" if ff.note and ff.tau_identified else "")
            )
        else:
            curve = f"α* {ff.alpha_star_deg:.2f} deg"
        notes[flap] = (
            f"{lags}, {curve}, C_L,max {cl_max:.3f} at "
            f"{a_max:.1f} deg{drag} ({ff.n_maneuvers} maneuvers, {ff.iterations} iterations)"
        )
        rows.append(res.summary())
    if rows:
        out.tables["kirchhoff"] = pl.concat(rows)
    fig = None
    if panels:
        fig = out.figure(
            FigureSpec(
                "fig-longitudinal",
                "longitudinal",
                figures.longitudinal,
                {"panels": panels},
                "Measured lift and pitching-moment coefficients (grey) and the Kirchhoff "
                "flow-separation model fitted by output error (colour; separation curve: "
                + (
                    "a cubic B-spline table, Goman-Khrabrov"
                    if fits.form == "goman-khrabrov"
                    else "tanh, Fischenberg"
                )
                + f") against alpha, per flap fitted (every {THIN}th sample; "
                "docs/longitudinal.md).",
            )
        )
    out.rows.append(
        MatrixRow(
            "longitudinal",
            item,
            rule,
            f"{len(fitted)} of {len(notes)} flap settings fitted (known terms: {known})",
            fig,
            "shown with Cramér-Rao bounds corrected for coloured residuals",
            SHOWN if fitted else NOT_ASSESSED + "the output-error fit applied to no flap setting",
            _flaps_text(notes),
        )
    )


def _prestall_row(out: Assessment, data: pl.DataFrame, model: DeltaModel | None) -> None:
    """Pre-stall regression: the extended model equals the qualified model where the Δ is
    blended out (:mod:`aerodelta.evidence.prestall`)."""
    from aerodelta.evidence import prestall  # noqa: PLC0415

    item = "Pre-stall regression: the qualified model's behaviour unchanged below the Δ"
    rule = (
        "Part 60 App. A, Attachment 7 (FSTD Directive 2): the stall model extends the validated "
        "model without changing the pre-stall behaviour its tests were passed on"
    )
    tol = (
        "identical (bit for bit) where the blend weight is zero; a stored longitudinal stall "
        f"within ±{prestall.STALL_TOLERANCES['airspeed_kt']:g} kt, "
        f"±{prestall.STALL_TOLERANCES['altitude_ft']:g} ft, "
        f"±{prestall.STALL_TOLERANCES['pitch_deg']:g} deg pitch of the qualified model there "
        "(Part 60 App. A, Table A2A tests 2.c.1-2.c.4)"
    )
    if model is None:
        out.rows.append(
            MatrixRow("prestall", item, rule, "-", None, tol,
                      NOT_ASSESSED + "no fitted Δ model given (--model model.json)")
        )  # fmt: skip
        return
    chk = prestall.prestall_regression(data, model)
    out.tables["prestall"] = chk.table
    out.facts["prestall_passed"] = chk.passed
    fig = None
    if chk.runs:
        panels = []
        replayed = chk.table.filter(pl.col("maneuver_id").is_in(list(chk.runs)))
        for flap, g in replayed.partition_by("flap_deg", as_dict=True, maintain_order=True).items():
            # the maneuver of the flap compared over the most steps
            r = g.sort("steps_compared", descending=True, nulls_last=True).row(0, named=True)
            run = chk.runs[r["maneuver_id"]]
            steps = r["steps_compared"]
            t_end = float(run["t"][steps - 1]) if steps else None
            panels.append(
                {"flap": float(flap[0]), "id": r["maneuver_id"], "run": run,
                 "alpha_l": r["alpha_l_deg"], "t_end": t_end}
            )  # fmt: skip
        fig = out.figure(
            FigureSpec(
                "fig-prestall",
                "prestall",
                figures.prestall,
                {"panels": panels},
                "Recorded controls replayed open loop on the qualified (blue) and the extended "
                "(red, dashed) model, one maneuver per flap: identical until the blend start "
                "(green line: end of the bit-for-bit comparison), then the Δ acts. A model "
                "storing a longitudinal stall also flies it alone (purple, dotted): the "
                "extended model equals it bit for bit until the blend start, and it stays "
                "within the table's tolerances of the qualified model there.",
            )
        )
    out.rows.append(
        MatrixRow(
            "prestall",
            item,
            rule,
            f"{chk.table.height} maneuvers, {int(chk.table['samples_blended_out'].sum())} "
            "samples with the blend weight at zero",
            fig,
            tol,
            PASS if chk.passed else FAIL,
            prestall.describe(chk),
        )
    )
