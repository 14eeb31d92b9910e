"""Unit and sign plausibility of a campaign's channels, before fitting.

Kinematic consistency decides: each of az, ax, ay, airspeed, alpha, beta and altitude is
compared with what the other channels imply (``aero_core::preprocess::plausibility``: the
specific force against gravity and the motion, the changes of airspeed, the air angles and
altitude over 3 s windows against the integrals of their kinematic rates), pooled over the
campaign. A scale within 20 % of 1 is plausible; a scale far from it (by more than four
cluster-robust standard errors) is refused, and named when it is within 10 % of a unit mistake
or a sign flip of the declared unit (radians declared as degrees: 1/57.3; knots declared as
m/s: 1.944; ft declared as m: 3.281; g declared as m/s²: 1/9.807; an axis pointing the other
way: -1). See ``docs/data.md``, "Plausibility".
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import polars as pl

from aerodelta import _core
from aerodelta.channel_map import ChannelMap
from aerodelta.channels import CHANNELS
from aerodelta.units import _UNITS

#: check -> (canonical channel, what the kinematics give, dimension)
CHECKED = {
    "az": ("az_mps2", "kinematic normal specific force (gravity and motion)", "accel"),
    "ax": ("ax_mps2", "kinematic longitudinal specific force", "accel"),
    "ay": ("ay_mps2", "kinematic lateral specific force", "accel"),
    "tas": ("tas_mps", "airspeed change the accelerometers give", "speed"),
    "alpha": ("alpha_deg", "angle-of-attack change the rates and accelerations give", "angle"),
    "beta": ("beta_deg", "sideslip change the rates and accelerations give", "angle"),
    "h": ("h_m", "climb the airspeed and attitude give", "length"),
}

_UNIT_WORDS = {
    "deg": "degrees",
    "rad": "radians",
    "m/s2": "m/s²",
    "ft/s2": "ft/s²",
    "g": "g",
    "m/s": "m/s",
    "kt": "knots",
    "ft/s": "ft/s",
    "km/h": "km/h",
    "m": "m",
    "ft": "ft",
}


@dataclass(frozen=True)
class Cause:
    """A candidate mistake: the data read ``ratio`` times the truth in canonical units."""

    ratio: float
    actual_unit: str | None  # the unit the column is really in (None: the declared one)
    flipped: bool

    def describe(self, declared: str, scale: float) -> tuple[str, str]:
        """(likely cause, fix) in the channel map's terms."""
        parts = []
        fixes = []
        if self.actual_unit is not None:
            parts.append(
                f"{_UNIT_WORDS.get(self.actual_unit, self.actual_unit)} declared as "
                f"{_UNIT_WORDS.get(declared, declared)}"
            )
            fixes.append(f'set unit = "{self.actual_unit}"')
        if self.flipped:
            parts.append("the sensor axis points the other way (sign reversed)")
            fixes.append("remove scale = -1.0" if scale < 0 else "set scale = -1.0")
        return " and ".join(parts), " and ".join(fixes) + " in the channel map"


def candidates(declared: str, dimension: str) -> list[Cause]:
    """Every unit of ``dimension`` mistaken for ``declared``, each also with the sign flipped,
    and the sign flip alone."""
    fd = _UNITS[declared][1]
    out = [Cause(-1.0, None, True)]
    for u, (dim, f, _) in _UNITS.items():
        if dim != dimension or u == declared:
            continue
        r = fd / f
        out.append(Cause(r, u, False))
        out.append(Cause(-r, u, True))
    return out


def _declared(name: str, cmap: ChannelMap | None) -> tuple[str, str | None, float]:
    """(declared unit, user's column, scale) of canonical channel ``name``."""
    if cmap is not None:
        for e in cmap.entries:
            if e.name == name:
                return e.unit, e.source, e.scale
    return CHANNELS[name].unit, None, 1.0


def _files(ids: list[str], files: Mapping[str, str]) -> str:
    shown = sorted({files.get(m, m) for m in ids})
    head = ", ".join(shown[:3])
    return head + (f" and {len(shown) - 3} more" if len(shown) > 3 else "")


def check_plausibility(
    out: pl.DataFrame, cmap: ChannelMap | None, files: Mapping[str, str]
) -> tuple[list[str], pl.DataFrame]:
    """Run the checks on preprocessed maneuvers stored back to back.

    Returns
    -------
    (list[str], polars.DataFrame)
        One refusal line per channel at fault (empty: plausible), and the estimates
        (``check, channel, k, std_err, blocks, verdict``).
    """
    d2r = np.pi / 180.0
    runs = out.select(pl.col("maneuver_id").rle()).unnest("maneuver_id")
    ids = [str(v) for v in runs["value"].to_list()]
    offsets = [0, *np.cumsum(runs["len"].to_numpy()).tolist()]

    def a(c: str, k: float = 1.0) -> np.ndarray:
        return np.ascontiguousarray(out[c].cast(pl.Float64).to_numpy() * k, dtype=np.float64)

    h = None
    if "h_m" in out.columns:
        hh = a("h_m")
        if np.isfinite(hh).all():
            h = hh
    declared = {chk: _declared(ch, cmap) for chk, (ch, _, _) in CHECKED.items()}
    causes = {chk: candidates(declared[chk][0], dim) for chk, (_, _, dim) in CHECKED.items()}
    res = _core.plausibility_check(
        [int(o) for o in offsets],
        a("t"),
        [a("ax_cg_mps2"), a("ay_cg_mps2"), a("az_cg_mps2")],
        [a("p_s_dps", d2r), a("q_s_dps", d2r), a("r_s_dps", d2r)],
        a("tas_s_mps"),
        a("alpha_cg_deg", d2r),
        a("beta_cg_deg", d2r),
        [a("phi_deg", d2r), a("theta_deg", d2r)],
        [a("alpha_deg", d2r) - a("alpha_cg_deg", d2r), a("beta_deg", d2r) - a("beta_cg_deg", d2r)],
        h,
        [[c.ratio for c in causes[chk]] for chk in CHECKED],
    )
    lines: list[str] = []
    rows = []
    for r in res:
        chk = str(r["channel"])
        name, what, _ = CHECKED[chk]
        unit, source, scale = declared[chk]
        rows.append((chk, name, float(r["k"]), float(r["se"]), int(r["blocks"]), r["verdict"]))
        col = f" (column '{source}')" if source else ""
        if r["verdict"] in ("mistake", "far"):
            where = f"{len(ids)} maneuver(s): {_files(ids, files)}"
            lines.append(
                _line(name, col, where, r["k"], r["se"], what, r, causes[chk], unit, scale)
            )
            continue
        # the campaign is plausible, but some maneuvers hold a named mistake (mixed files)
        bad: dict[int, list[str]] = {}
        for mid, v, c in zip(ids, r["verdict_m"], r["candidate_m"], strict=True):
            if v == "mistake" and c is not None:
                bad.setdefault(int(c), []).append(mid)
        for c, mids in bad.items():
            km = np.median([k for m, k in zip(ids, r["k_m"], strict=True) if m in set(mids)])
            cause, fix = causes[chk][c].describe(unit, scale)
            lines.append(
                f"channel '{name}'{col} in {len(mids)} of {len(ids)} maneuvers "
                f"({_files(mids, files)}): reads {km:.3g}x the {what}: likely {cause}; "
                f"{fix} for those files"
            )
    est = pl.DataFrame(
        rows,
        schema={
            "check": pl.Utf8,
            "channel": pl.Utf8,
            "k": pl.Float64,
            "std_err": pl.Float64,
            "blocks": pl.Int64,
            "verdict": pl.Utf8,
        },
        orient="row",
    )
    return lines, est


def _line(  # noqa: PLR0917
    name: str,
    col: str,
    where: str,
    k: float,
    se: float,
    what: str,
    r: Mapping[str, object],
    causes: list[Cause],
    unit: str,
    scale: float,
) -> str:
    head = f"channel '{name}'{col} over {where}: reads {k:.3g}x (± {se:.2g}) the {what}"
    cand = r["candidate"]
    if r["verdict"] == "mistake" and isinstance(cand, int):
        cause, fix = causes[cand].describe(unit, scale)
        return f"{head}: likely {cause}; {fix}"
    return (
        f"{head}, far from 1 (0.8-1.25 is physical): check its unit, scale and sign in the "
        "channel map"
    )
