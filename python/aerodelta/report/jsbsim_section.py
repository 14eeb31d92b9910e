"""Section 4.3 for the records of a JSBSim campaign: the user's own aircraft replayed.

When the report is told that its records come from a JSBSim campaign (``build_report(...,
jsbsim_campaign=DIR)``, CLI ``--jsbsim-campaign DIR``, or the qualified model named as
``"jsbsim:DIR"``), the replay section flies the campaign's JSBSim aircraft instead of the
built-in ADX-37: the qualified aircraft and the qualified aircraft with the fitted Δ exported into
it, exactly as :func:`aerodelta.jsbsim_replay.replay_campaign` flies them (the same aircraft
files, trim, surfaces, throttle schedule, windows and Theil inequality coefficients). Nothing is
guessed: without the campaign named, the section keeps the built-in aircraft's behaviour.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import polars as pl

from aerodelta.exceptions import AerodeltaError
from aerodelta.plots import FigureSink, figures
from aerodelta.report.context import ReportContext
from aerodelta.report.html import Section, esc, p, table

#: Windows of :func:`aerodelta.jsbsim_replay.replay_campaign` shown in the TIC table.
WINDOWS = ("delta", "predictable")
#: The issue-19 floor on the pooled TIC ratio (extended / qualified).
RATIO_FLOOR = 0.5
_PREFIX = "jsbsim:"


def campaign_of(ctx: ReportContext, jsbsim_campaign: str | os.PathLike[str] | None) -> Path | None:
    """The JSBSim campaign the records come from, as the user named it: ``jsbsim_campaign``,
    else the qualified model when it is ``"jsbsim:DIR"``; ``None`` when neither names one."""
    if jsbsim_campaign is not None:
        return Path(jsbsim_campaign)
    if ctx.qualified.startswith(_PREFIX):
        return Path(ctx.qualified[len(_PREFIX) :])
    return None


def _not_run(sec: Section, why: str) -> Section:
    sec.body.append(p(f"JSBSim replay not run: {esc(why)}"))
    return sec


def _record_mismatch(ctx: ReportContext, rec: pl.DataFrame, mid: str) -> bool:
    """Whether the report's samples of ``mid`` are not the campaign record's (time, airspeed)."""
    mine = ctx.data.filter(pl.col("maneuver_id") == mid).sort("t")
    if mine.height != rec.height:
        return True
    return any(
        not np.allclose(
            mine[c].cast(pl.Float64).to_numpy(), rec[c].cast(pl.Float64).to_numpy(),
            rtol=0.0, atol=1e-6, equal_nan=True,
        )
        for c in ("t", "tas_mps")
    )  # fmt: skip


def section(
    ctx: ReportContext,
    sink: FigureSink,
    sec: Section,
    campaign: Path,
    *,
    count: int = 3,
    ids: Sequence[str] | None = None,
) -> Section:
    """Fill the replay section ``sec`` with the JSBSim replays of the campaign ``campaign``.

    Up to ``count`` maneuvers (:func:`aerodelta.report.replay.pick_maneuvers`) or ``ids`` are
    flown by :func:`aerodelta.jsbsim_replay.replay_campaign` on the campaign's full, qualified
    and extended (qualified + Δ) aircraft. Tables: ``"replay"`` (one row per maneuver: the
    divergence check, maximum bank, RMS differences of V [m/s], α, β, θ, φ [deg] from the
    record for the qualified and extended replays, as the built-in aircraft's section) and
    ``"jsbsim_tic"`` (``replay_campaign``'s rows of the ``delta`` and ``predictable`` windows:
    TIC of each aircraft on p, r, φ, β and ``ratio`` = extended / qualified). When the replay
    cannot be flown (no ``jsbsim`` package, not a JSBSim campaign, records not the campaign's)
    the section says why in one sentence.
    """
    from aerodelta.report.replay import (  # noqa: PLC0415
        STATES,
        against_record,
        bounds_text,
        pick_maneuvers,
    )

    sec.body.append(
        p(
            f"The records come from the JSBSim campaign <code>{esc(campaign)}</code> (named "
            "for the report), so its own JSBSim aircraft is flown, as "
            "<code>aerodelta jsbsim-replay</code> flies it (docs/jsbsim_campaign.md): the "
            "<b>qualified</b> aircraft (the campaign's "
            "withheld terms frozen above its withhold alpha: the simulator the Δ was fitted "
            "against) and the <b>extended</b> aircraft (the qualified one with the fitted Δ "
            "model exported into its aerodynamics). Each is trimmed at the record's initial "
            "airspeed and altitude and driven open loop by every recorded surface (aileron, "
            "elevator, rudder: the replay-controls option applies to the built-in aircraft only) "
            "and the campaign pilot's throttle schedule fitted to the recorded thrust. The "
            "campaign's full aircraft (the truth the records were flown on) is flown as well: "
            "how far an open-loop replay can follow the record at all. Theil inequality "
            "coefficients (TIC, 0 perfect, 1 no skill) on p, r, φ, β in the windows of "
            "jsbsim-replay: <i>delta</i>, from the start to where alpha is back at the withhold "
            "alpha after its peak, and <i>predictable</i>, that window ended where the full "
            "aircraft's own replay leaves the record by 10 % of a channel's range; "
            f"ratio = TIC extended / TIC qualified (issue 19's floor: ≤ {RATIO_FLOOR:g}). "
            "Divergence check (extended replay) as for the built-in aircraft: "
            + bounds_text()
            + "."
        )
    )
    try:
        import jsbsim  # noqa: F401, PLC0415
    except ImportError:
        return _not_run(
            sec,
            "the jsbsim package is not installed (pip install 'aerodelta[jsbsim]'); it flies "
            "the campaign's aircraft.",
        )
    from aerodelta import jsbsim_replay as jr  # noqa: PLC0415

    try:
        setup = jr.load_setup(campaign)
    except AerodeltaError as e:
        return _not_run(sec, f"{e}.")
    chosen = list(ids) if ids is not None else pick_maneuvers(ctx, count)
    known = set(setup.manifest["maneuver_id"].to_list())
    alien = [m for m in chosen if m not in known]
    if alien:
        return _not_run(
            sec,
            f"maneuvers {', '.join(alien[:5])} of these records are not in "
            f"{setup.path / 'manifest.csv'}; name the campaign the records were ingested from.",
        )
    if not chosen:
        return _not_run(sec, "no maneuver to replay.")
    try:
        records = {mid: jr.read_record(setup, mid) for mid in chosen}
    except AerodeltaError as e:
        return _not_run(sec, f"{e}.")
    differ = [mid for mid, rec in records.items() if _record_mismatch(ctx, rec, mid)]
    if differ:
        return _not_run(
            sec,
            f"the report's samples of {', '.join(differ[:5])} differ from the campaign's "
            f"records (time or airspeed) in {setup.path / 'records'}; name the campaign the "
            "records were ingested from.",
        )
    try:
        scores, reps = jr.replay_campaign(
            setup.path, ctx.model, maneuvers=chosen, variants=jr.VARIANTS, keep_replays=True
        )
    except AerodeltaError as e:
        return _not_run(sec, f"the replay failed: {e}.")
    rows = []
    for mid in chosen:
        rec = records[mid]
        run = {
            v: reps.filter((pl.col("maneuver_id") == mid) & (pl.col("variant") == v))
            .rename({"tas_mps": "V_mps"})
            .select("t", *STATES)
            for v in jr.VARIANTS
        }
        row, panels = against_record(
            rec, run["qualified"], run["extended"], mid=mid, held_out=mid in ctx.held_out,
            labels=("JSBSim, qualified", "JSBSim, extended + Δ"),
        )  # fmt: skip
        why = row["reason"]
        sec.body.append(
            sink.plot(
                figures.replay,
                f"replay_jsbsim_{mid}",
                f"JSBSim replay of {mid} (flap {row['flap_deg']:g}) on the campaign's "
                f"{setup.cfg.model}: flight record vs the qualified JSBSim aircraft and the "
                "qualified aircraft with the fitted Δ; divergence check of the extended "
                f"replay: {why}.",
                panels=panels,
            )
        )
        rows.append(row)
    t = pl.DataFrame(rows, strict=False)
    sec.body.append(table(t, row_class=lambda r: "" if r["bounded"] else "bad"))
    nb = int(t["bounded"].sum())
    cls = "ok" if nb == t.height else "fail"
    sec.summary.append(("replays bounded", f'<span class="{cls}">{nb} / {t.height}</span>'))
    sec.tables["replay"] = t
    tic = scores.filter(pl.col("window").is_in(WINDOWS)).select(
        "maneuver_id", "window", "channel", "tic_qualified", "tic_extended", "ratio",
        "tic_full", "t_end_s", "n_samples",
    )  # fmt: skip
    sec.body.append(
        p(
            "Theil inequality coefficients of the JSBSim replays against the record (rows "
            "<i>pooled</i>: the chosen maneuvers' windows concatenated)."
        )
    )
    sec.body.append(
        table(
            tic,
            row_class=lambda r: "bad" if (r["ratio"] or 0.0) > RATIO_FLOOR else "",
        )
    )
    sec.tables["jsbsim_tic"] = tic
    pooled = tic.filter((pl.col("maneuver_id") == "pooled") & (pl.col("window") == "delta"))
    ratios = pooled["ratio"].to_numpy()
    if ratios.size and np.isfinite(ratios).all():
        cls = "ok" if float(ratios.max()) <= RATIO_FLOOR else "fail"
        text = ", ".join(
            f"{ch.split('_')[0]} {r:.2f}"
            for ch, r in zip(pooled["channel"].to_list(), ratios, strict=True)
        )
        sec.summary.append(
            ("JSBSim TIC ext/qual (delta)", f'<span class="{cls}">{esc(text)}</span>')
        )
    return sec
