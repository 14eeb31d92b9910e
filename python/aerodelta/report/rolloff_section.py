"""Roll-off (thesis Section 3.4.3): detected events and their Table 3.2 statistics, the dynamic
roll control (DRC) plot of aileron against dynamic roll φ' (Eq. 3.20, Figure 3.12), and the
maximum bank angle of each straight stall against the 20 deg requirement (FAR 25.203,
Figure 3.13)."""

from __future__ import annotations

import numpy as np
import polars as pl

from aerodelta.plots import FigureSink, figures
from aerodelta.report.context import ReportContext
from aerodelta.report.html import Section, details, p, table
from aerodelta.rolloff import (
    FAR25_203_MAX_ROLL_DEG,
    detect_rolloff,
    dynamic_roll,
    euler_roll_rate,
    max_roll_straight_stalls,
    rolloff_statistics,
)


def section(ctx: ReportContext, sink: FigureSink) -> Section:
    """Build the roll-off section."""
    sec = Section("rolloff", "Stochastic roll-off")
    d = ctx.data
    need = {"Cl_meas", "da_deg", "phi_deg", "p_dps"}
    if not need <= set(d.columns):
        sec.body.append(p(f"Roll-off skipped: the records lack {sorted(need - set(d.columns))}."))
        return sec
    res = d["Cl_meas"] - d["Cl_ext"] if "Cl_ext" in d.columns else None
    events = detect_rolloff(d, residual=None if res is None else res.to_numpy())
    acc = events.filter(pl.col("accepted"))
    sec.body.append(
        p(
            "Roll-off events are searched in the straight stalls as spikes of the extended model's "
            "rolling-moment residual <i>C</i><sub>l,meas</sub> − "
            "<i>C</i><sub>l,ext</sub> while the "
            "aileron, rudder and spoilers stay quiet (thesis Section 3.4.3 procedure). "
            f"{events.height} candidates, {acc.height} accepted; the Table 3.2 statistics "
            "need 3 or more accepted events per flap."
        )
    )
    # intervals need 3 or more events per flap (the chi-square quantile of 1 degree of freedom
    # is not defined by the Wilson-Hilferty approximation rolloff_statistics uses)
    counts = acc.group_by("flap_deg").len()
    enough = counts.filter(pl.col("len") >= 3)["flap_deg"].to_list()
    few = counts.filter(pl.col("len") < 3).sort("flap_deg")
    if few.height:
        sec.body.append(
            p(
                "Flaps with fewer than 3 accepted events (no statistics): "
                + ", ".join(
                    f"{r['flap_deg']:g} deg ({r['len']})" for r in few.iter_rows(named=True)
                )
                + "."
            )
        )
    if enough:
        st = rolloff_statistics(acc.filter(pl.col("flap_deg").is_in(enough)))
        cols = [
            "flap_deg",
            "n",
            "alpha_mean_deg",
            "alpha_mean_lo",
            "alpha_mean_hi",
            "alpha_std_deg",
            "magnitude_mean",
            "magnitude_cv",
            "n_right",
            "n_left",
            "p_right",
            "p_right_lo",
            "p_right_hi",
        ]
        sec.body.append("<h3>Statistics per flap (cf. thesis Table 3.2; 95 % intervals)</h3>")
        sec.body.append(table(st.select([c for c in cols if c in st.columns])))
        sec.tables["statistics"] = st
    if events.height:
        sec.body.append(details("Detected candidates", table(events.drop("noise_sigma"))))
    sec.tables["events"] = events

    straight = d.filter(pl.col("kind") == "straight") if "kind" in d.columns else d
    flaps = sorted(float(f) for f in straight["flap_deg"].unique())
    drc = []
    for flap in flaps:
        s = straight.filter(pl.col("flap_deg") == flap)
        th = s["theta_deg"].to_numpy() if "theta_deg" in s.columns else np.zeros(s.height)
        q = s["q_dps"].to_numpy() if "q_dps" in s.columns else np.zeros(s.height)
        r = s["r_dps"].to_numpy() if "r_dps" in s.columns else np.zeros(s.height)
        phid = euler_roll_rate(s["p_dps"].to_numpy(), q, r, s["phi_deg"].to_numpy(), th)
        dphi = dynamic_roll(s["phi_deg"].to_numpy(), phid)
        step = max(1, s.height // 4000)
        drc.append({"x": dphi[::step], "y": s["da_deg"].to_numpy()[::step]})
    mr = max_roll_straight_stalls(d)
    max_roll = []
    for k, flap in enumerate(flaps):
        g = mr.filter(pl.col("flap_deg") == flap)
        x = np.full(g.height, k) + np.linspace(-0.25, 0.25, max(g.height, 1))[: g.height]
        max_roll.append({"x": x, "y": g["max_roll_deg"].to_numpy()})
    sec.body.append(
        sink.plot(
            figures.rolloff_drc_maxroll,
            "rolloff_drc_maxroll",
            "Left: aileron against dynamic roll attitude φ' (thesis Eq. 3.20, Figure 3.12); the "
            "red dashed lines mark ±20 deg for scale (the QLC envelope itself is not drawn). "
            "Right: maximum bank angle of each straight stall against the 20 deg requirement "
            "(FAR 25.203, Figure 3.13).",
            drc=drc,
            max_roll=max_roll,
            flaps=flaps,
            limit_deg=FAR25_203_MAX_ROLL_DEG,
        )
    )
    if mr.height:
        npass = int(mr["passed"].sum())
        sec.body.append(
            table(
                mr.group_by("flap_deg")
                .agg(
                    pl.len().alias("stalls"),
                    pl.col("max_roll_deg").max().alias("worst_deg"),
                    pl.col("passed").mean().alias("within_20_deg"),
                )
                .sort("flap_deg"),
                formats={"within_20_deg": ".0%"},
            )
        )
        cls = "ok" if npass == mr.height else "fail"
        sec.summary.append(
            (
                "straight stalls within 20 deg bank",
                f'<span class="{cls}">{npass} / {mr.height}</span>',
            )
        )
        sec.tables["max_roll"] = mr
    sec.summary.append(("roll-off events accepted", f"{acc.height}"))
    return sec
