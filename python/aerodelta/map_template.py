"""A channel-map skeleton from one flight record: each column's canonical channel guessed from
its name, its unit from its name and its values, every guess marked for review.

The skeleton (``MapTemplate.to_toml()``, CLI ``aerodelta map-template RECORD -o map.toml``) is
a channel map in the format :class:`aerodelta.ChannelMap` reads, with a ``# REVIEW`` comment
on every guessed line saying why it was guessed. The loader refuses a map that still holds
such a mark (naming the lines), so nothing guessed is used unchecked: review each line (the
channel, the unit, the sign of ``scale``), fix what is wrong, delete the mark.

How units are guessed, per canonical channel (``docs/data.md``):

- a unit in the column's name (``aoa_rad``, ``Time_ms``, ``KTAS``, ``alt_ft``) when the values
  are plausible in it;
- otherwise the unit of the channel's dimension whose converted values lie inside the
  channel's physical range and whose typical size (99th percentile of ``|value|``, or the
  median for airspeed, density, pressure, altitude, normal acceleration and propeller speed)
  is nearest, on a log scale, to a typical flight test value (alpha 15 deg, rates 15 deg/s,
  airspeed 70 m/s, ...); the air angles and attitudes, the body rates and the three
  accelerations each share the unit most of their members favour. So angles whose
  ``|value|`` stays below ~1.6 read as radians, a normal acceleration near 1 as g and near 32
  as ft/s², airspeeds near 130 as knots;
- time: ``ms`` when the median step is above 0.25 (a 4 Hz record in seconds is implausible),
  else ``s``;
- temperature: K above 150, degC up to 60, else degF;
- a normal acceleration whose median is positive (load factor, z up) gets ``scale = -1.0``:
  the canonical ``az_mps2`` is the specific force along body z down, -9.81 m/s² in level
  flight.

Ambiguities are written into the review comment (e.g. airspeeds of 60-100 are plausible as
m/s and as knots).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from aerodelta.channels import ALTERNATIVES, CHANNELS, REQUIRED
from aerodelta.exceptions import DataError
from aerodelta.readers import scan_record
from aerodelta.units import ALIASES, dimension, factor_offset, known_units

#: Rows read to guess the units (the head of the record).
MAX_ROWS = 200_000

#: Column names (lower case, separators and unit suffixes removed) per canonical channel.
NAMES: dict[str, tuple[str, ...]] = {
    "t": ("t", "time", "tsec", "elapsed", "elapsedtime", "reltime", "timestamp"),
    "alpha_deg": ("alpha", "aoa", "alfa", "angleofattack", "alphavane", "aoavane", "alphav"),
    "beta_deg": ("beta", "aos", "sideslip", "angleofsideslip", "betavane", "betav", "ss"),
    "p_dps": ("p", "rollrate", "prate", "pbody", "pb"),
    "q_dps": ("q", "pitchrate", "qrate", "qbody", "qb"),
    "r_dps": ("r", "yawrate", "rrate", "rbody", "rb"),
    "phi_deg": ("phi", "roll", "bank", "rollangle", "bankangle", "rollattitude"),
    "theta_deg": ("theta", "pitch", "pitchangle", "pitchattitude", "tht"),
    "psi_deg": ("psi", "heading", "hdg", "yaw", "yawangle", "trueheading", "magheading"),
    "ax_mps2": ("ax", "nx", "accx", "accelx", "axb", "longaccel", "longitudinalaccel"),
    "ay_mps2": ("ay", "ny", "accy", "accely", "ayb", "lataccel", "lateralaccel"),
    "az_mps2": ("az", "nz", "accz", "accelz", "azb", "normaccel", "normalaccel", "loadfactor"),
    "tas_mps": ("tas", "ktas", "vtas", "vt", "truespeed", "trueairspeed", "airspeed", "vtrue"),
    "rho_kgm3": ("rho", "density", "airdensity"),
    "ps_pa": ("ps", "pstatic", "staticpressure", "pstat"),
    "pt_pa": ("pt", "ptotal", "totalpressure", "ptot"),
    "sat_k": ("sat", "oat", "tstatic", "statictemp", "statictemperature", "temperature"),
    "h_m": ("h", "alt", "altitude", "hp", "height", "palt", "pressurealtitude"),
    "da_deg": ("da", "aileron", "ail", "dail", "deltaa", "ailpos"),
    "de_deg": ("de", "elevator", "elev", "delev", "deltae", "elevpos"),
    "dr_deg": ("dr", "rudder", "rud", "drud", "deltar", "rudpos"),
    "dsl_deg": ("dsl", "spoilerl", "spoilerleft", "lspoiler", "leftspoiler", "dspl"),
    "dsr_deg": ("dsr", "spoilerr", "spoilerright", "rspoiler", "rightspoiler", "dspr"),
    "flap_deg": ("flap", "flaps", "df", "dflap", "flappos"),
    "ct_left": ("ctleft", "ctl", "ct1", "ctlh"),
    "ct_right": ("ctright", "ctr", "ct2", "ctrh"),
    "torque_left_nm": ("torqueleft", "tql", "tq1", "torque1", "torquel"),
    "torque_right_nm": ("torqueright", "tqr", "tq2", "torque2", "torquer"),
    "rpm_left": ("rpmleft", "rpml", "npl", "np1", "rpm1"),
    "rpm_right": ("rpmright", "rpmr", "npr", "np2", "rpm2"),
    "prop_rpm": ("proprpm", "prop", "np", "nprop", "propspeed"),
    "Cl_sim": ("clsim",),
    "Cn_sim": ("cnsim",),
    "CY_sim": ("cysim",),
}

#: Names that imply a unit (checked against the values like a unit suffix).
NAME_UNITS: dict[str, str] = {"ktas": "kt", "kias": "kt", "kcas": "kt"}

#: The statistic of a channel's values compared with its typical value (canonical unit):
#: ``p99`` (99th percentile of |value|) or ``median`` (median of |value|).
TYPICAL: dict[str, tuple[str, float]] = {
    "alpha_deg": ("p99", 15.0),
    "beta_deg": ("p99", 5.0),
    "p_dps": ("p99", 15.0),
    "q_dps": ("p99", 10.0),
    "r_dps": ("p99", 10.0),
    "phi_deg": ("p99", 25.0),
    "theta_deg": ("p99", 15.0),
    "psi_deg": ("p99", 180.0),
    "ax_mps2": ("p99", 3.0),
    "ay_mps2": ("p99", 2.0),
    "az_mps2": ("median", 9.8),
    "tas_mps": ("median", 70.0),
    "rho_kgm3": ("median", 1.0),
    "ps_pa": ("median", 80000.0),
    "pt_pa": ("median", 85000.0),
    "h_m": ("median", 3000.0),
    "da_deg": ("p99", 8.0),
    "de_deg": ("p99", 8.0),
    "dr_deg": ("p99", 8.0),
    "dsl_deg": ("p99", 10.0),
    "dsr_deg": ("p99", 10.0),
    "flap_deg": ("p99", 15.0),
    "torque_left_nm": ("p99", 5000.0),
    "torque_right_nm": ("p99", 5000.0),
    "rpm_left": ("median", 1200.0),
    "rpm_right": ("median", 1200.0),
    "prop_rpm": ("median", 1200.0),
}

#: Channels that share one unit (the members' guesses are pooled).
GROUPS = (
    ("alpha_deg", "beta_deg", "phi_deg", "theta_deg", "psi_deg"),
    ("p_dps", "q_dps", "r_dps"),
    ("ax_mps2", "ay_mps2", "az_mps2"),
)

#: Units never proposed (duplicates of another of the same dimension and factor).
_SKIP_UNITS = {"mbar"}

_UNIT_TOKENS = {u.lower(): u for u in known_units()} | {
    a.lower(): ALIASES[a] for a in ALIASES if a.strip() and a not in ("1", "C", "F")
}
_UNIT_TOKENS |= {
    "degrees": "deg", "radians": "rad", "rads": "rad/s", "degs": "deg/s", "sec": "s",
    "secs": "s", "msec": "ms", "kn": "kt", "mps2": "m/s2", "fps2": "ft/s2", "ftps2": "ft/s2",
    "ftps": "ft/s", "ms2": "m/s2", "kgm3": "kg/m3",
    "slugft3": "slug/ft3", "nm": "N*m", "ftlbf": "ft*lbf", "degc": "degC", "degf": "degF",
    "k": "K", "pa": "Pa", "hpa": "hPa", "inhg": "inHg", "gs": "g",
}  # fmt: skip


def _tokens(name: str) -> list[str]:
    """``rollRate_rad_s`` -> ``['roll', 'rate', 'rad', 's']``."""
    spaced = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", " ", name)
    return [t.lower() for t in re.split(r"[^A-Za-z0-9]+", spaced) if t]


def _split_name(name: str) -> tuple[str, str | None]:
    """The name without unit suffixes (joined, lower case) and the unit the suffix names."""
    toks = _tokens(name)
    for k in range(min(3, len(toks) - 1), 0, -1):
        tail = toks[-k:]
        for cand in ("/".join(tail), "".join(tail)):
            if cand in _UNIT_TOKENS:
                return "".join(toks[:-k]), _UNIT_TOKENS[cand]
    return "".join(toks), None


def guess_channel(name: str) -> tuple[str | None, str | None]:
    """The canonical channel a column name suggests (or None) and the unit its name states.

    >>> guess_channel("aoa_rad")
    ('alpha_deg', 'rad')
    >>> guess_channel("Time_ms")
    ('t', 'ms')
    >>> guess_channel("KTAS")
    ('tas_mps', 'kt')
    >>> guess_channel("whatever")
    (None, None)
    """
    if name in CHANNELS:
        return name, CHANNELS[name].unit
    key, unit = _split_name(name)
    whole = "".join(_tokens(name))
    for cand, u in ((key, unit), (whole, None)):
        for ch, names in NAMES.items():
            if cand in names:
                return ch, u or NAME_UNITS.get(cand)
    return None, None


@dataclass
class Guess:
    """One column of the record and what was guessed for it."""

    column: str
    channel: str | None
    unit: str | None = None
    scale: float = 1.0
    why: str = ""
    note: str = ""  # why a column is left out (not numeric, unknown name, duplicate)


@dataclass
class MapTemplate:
    """The guesses for one record; ``to_toml()`` writes the skeleton."""

    record: Path
    rows: int
    guesses: list[Guess] = field(default_factory=list)

    @property
    def mapped(self) -> list[Guess]:
        """The columns written as channel entries."""
        return [g for g in self.guesses if g.channel and not g.note]

    def missing_required(self) -> list[str]:
        """Required channels no column was matched to (nor their alternatives)."""
        have = {g.channel for g in self.mapped}
        out = [c for c in REQUIRED if c not in have]
        out += [
            c
            for c, alts in ALTERNATIVES.items()
            if c not in have and not all(a in have for a in alts)
        ]
        return out

    def to_toml(self) -> str:
        """The channel-map skeleton (TOML)."""
        lines = [
            f"# Channel map skeleton written by aerodelta map-template from {self.record.name}",
            f"# ({self.rows} rows read). Canonical channels and units: docs/data.md.",
            "# Every guessed line ends with a REVIEW comment saying why: check the channel, the",
            "# unit and the sign (scale = -1.0 flips it) against your data, fix what is wrong,",
            "# then delete the mark. The map is refused while any mark is left.",
            "# canonical = convert(raw * scale + offset, unit -> canonical unit)",
            "",
            "[channels]",
        ]
        for g in self.mapped:
            spec = f"source = {json.dumps(g.column)}, unit = {json.dumps(g.unit)}"
            if g.scale != 1.0:
                spec += f", scale = {g.scale:.1f}"
            lines.append(f"{g.channel} = {{ {spec} }}  # REVIEW: {g.why}")
        missing = self.missing_required()
        if missing:
            lines += ["", "# Required channels no column was recognised as (map them by hand):"]
            for c in missing:
                lines.append(f'# {c} = {{ source = "?", unit = "{CHANNELS[c].unit}" }}')
        left = [g for g in self.guesses if g.note]
        if left:
            lines += ["", "# Columns left out (map them by hand if they are channels):"]
            for g in left:
                lines.append(f"# {json.dumps(g.column)}: {g.note}")
        return "\n".join(lines) + "\n"


def _fmt(x: float) -> str:
    return f"{x:.3g}"


def _stat(values: np.ndarray, kind: str) -> float:
    a = np.abs(values)
    return float(np.median(a) if kind == "median" else np.quantile(a, 0.99))


def _candidates(channel: str) -> list[str]:
    dim = dimension(CHANNELS[channel].unit)
    return [u for u in known_units() if dimension(u) == dim and u not in _SKIP_UNITS]


def _plausible(channel: str, unit: str, lo: float, hi: float, scale: float = 1.0) -> bool:
    spec = CHANNELS[channel]
    k, o = factor_offset(unit, spec.unit)
    a, b = sorted((lo * scale * k + o, hi * scale * k + o))
    return spec.lo <= a and b <= spec.hi


def _score(channel: str, unit: str, stat: float) -> float:
    """Distance (log scale) of the statistic, converted to the canonical unit, from typical."""
    k, _ = factor_offset(unit, CHANNELS[channel].unit)
    return abs(math.log(stat * k / TYPICAL[channel][1]))


@dataclass
class _Col:
    guess: Guess
    values: np.ndarray
    hint: str | None
    stat: float = 0.0
    scores: dict[str, float] = field(default_factory=dict)


def _time_unit(col: _Col) -> None:
    v = col.values
    steps = np.diff(v)
    steps = steps[steps > 0]
    dt = float(np.median(steps)) if steps.size else math.nan
    g = col.guess
    by_values = "ms" if dt > 0.25 else "s"
    shown = f"median step {_fmt(dt)}"
    if col.hint in ("s", "ms"):
        g.unit = col.hint
        agree = "agrees" if col.hint == by_values else f"suggests {by_values}"
        g.why = f"unit {col.hint} from the name ({shown} {agree})"
    else:
        g.unit = by_values
        hz = 1.0 / (dt * (1e-3 if by_values == "ms" else 1.0)) if dt > 0 else math.nan
        g.why = f"{shown}: {by_values} guessed ({_fmt(hz)} Hz)"


def _temperature_unit(col: _Col) -> None:
    v = col.values
    med, top = float(np.median(v)), float(np.max(v))
    unit = "K" if med > 150 else ("degC" if top <= 60 else "degF")
    g = col.guess
    if (
        col.hint
        and dimension(col.hint) == "temperature"
        and _plausible(g.channel or "sat_k", col.hint, float(v.min()), float(v.max()))
    ):
        g.unit, g.why = col.hint, f"unit {col.hint} from the name (median {_fmt(med)})"
    else:
        g.unit, g.why = unit, f"median {_fmt(med)}, max {_fmt(top)}: {unit} guessed"


def _dimensionless(col: _Col) -> None:
    v = col.values
    col.guess.unit = "-"
    col.guess.why = f"dimensionless (values {_fmt(float(v.min()))} to {_fmt(float(v.max()))})"


def _score_units(col: _Col) -> None:
    ch = col.guess.channel or ""
    v = col.values
    kind, _ = TYPICAL[ch]
    col.stat = _stat(v, kind)
    lo, hi = float(v.min()), float(v.max())
    scale = -1.0 if ch == "az_mps2" and float(np.median(v)) > 0 else 1.0
    for u in _candidates(ch):
        if _plausible(ch, u, lo, hi, scale):
            col.scores[u] = _score(ch, u, col.stat) if col.stat > 0 else 0.0


def _describe(col: _Col, unit: str) -> str:
    ch = col.guess.channel or ""
    kind, _ = TYPICAL[ch]
    what = "median |value|" if kind == "median" else "99% of |value| <="
    canon = CHANNELS[ch].unit
    k, o = factor_offset(unit, canon)
    text = f"{what} {_fmt(col.stat)}"
    if unit != canon:
        text += f" = {_fmt(col.stat * k + o)} {canon}"
    return text


def _choose(col: _Col, group_unit: str | None) -> None:
    g = col.guess
    ch = g.channel or ""
    v = col.values
    if ch == "az_mps2" and float(np.median(v)) > 0:
        g.scale = -1.0
    flip = (
        "; median > 0 (z up, load factor): scale = -1.0 flips it to body z down"
        if g.scale < 0
        else ""
    )
    plausible = sorted(col.scores, key=col.scores.__getitem__)
    if not plausible:
        g.unit = col.hint if col.hint in _candidates(ch) else CHANNELS[ch].unit
        g.why = (
            f"values {_fmt(float(v.min()))} to {_fmt(float(v.max()))} are outside the physical "
            f"range of {ch} in every unit; {g.unit} written, check the column"
        )
        return
    if col.stat == 0:
        g.unit = col.hint if col.hint in plausible else CHANNELS[ch].unit
        g.why = f"all values 0: the unit cannot be told from them; {g.unit} written" + flip
        return
    if col.hint in plausible:
        unit, how = col.hint, "from the name"
    elif group_unit in plausible:
        unit, how = group_unit, "guessed from the values (shared with its group)"
    else:
        unit, how = plausible[0], "guessed from the values"
    why = f"unit {unit} {how}: {_describe(col, unit)}"
    if col.hint and col.hint not in plausible and dimension(col.hint) == dimension(unit):
        why += f"; the name says {col.hint}, implausible for these values"
    others = [u for u in plausible if u != unit and col.scores[u] < col.scores[unit] + 1.0]
    if others:
        why += f"; also plausible: {', '.join(others)}"
    g.unit, g.why = unit, why + flip


def _group_unit(cols: list[_Col]) -> str | None:
    totals: dict[str, float] = {}
    counts: dict[str, int] = {}
    scored = [c for c in cols if c.stat > 0 and c.scores]
    for c in scored:
        for u, s in c.scores.items():
            totals[u] = totals.get(u, 0.0) + s
            counts[u] = counts.get(u, 0) + 1
    full = [u for u in totals if counts[u] == len(scored)]
    if not full:
        return None
    return min(full, key=totals.__getitem__)


def _not_numeric(s: pl.Series) -> str:
    """Why a text column is left out: the first cell that is not a number, by row."""
    text = s.cast(pl.Utf8)
    bad = text.is_not_null() & text.str.strip_chars().cast(pl.Float64, strict=False).is_null()
    rows = np.flatnonzero(bad.to_numpy())
    if rows.size == 0:
        return "not numeric"
    r = int(rows[0])
    cell = json.dumps(str(text[r]))[:40]
    if rows.size < len(s):
        return f"not numeric: row {r} holds {cell} ({rows.size} of {len(s)} cells are text)"
    return f"not numeric (text such as {cell})"


def map_template(record: str | Path) -> MapTemplate:
    """Guess a channel map for ``record`` (CSV, Parquet or ``.mat``): see the module text.

    Raises
    ------
    DataError
        The record cannot be read or holds no data rows.
    """
    path = Path(record)
    try:
        df = scan_record(path).head(MAX_ROWS).collect()
    except DataError:
        raise
    except Exception as e:  # polars raises several kinds for unreadable files
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        raise DataError(f"{path}: cannot read the record ({first})") from e
    if df.width == 0 or df.height == 0:
        raise DataError(
            f"{path}: no data rows; the units are guessed from the values, give a record with data"
        )
    out = MapTemplate(path, df.height)
    cols: list[_Col] = []
    taken: dict[str, str] = {}
    for name in df.columns:
        s = df[name]
        if name == "maneuver_id":
            out.guesses.append(Guess(name, None, note="maneuver ids: split the file (kept as is)"))
            continue
        channel, hint = guess_channel(name)
        if not s.dtype.is_numeric():
            note = _not_numeric(s)
            if channel:
                note += f"; its name suggests {channel}: fix the file's values to map it"
            out.guesses.append(Guess(name, channel, note=note))
            continue
        v = s.cast(pl.Float64).to_numpy()
        v = v[np.isfinite(v)]
        if channel is None:
            rng = f"values {_fmt(float(v.min()))} to {_fmt(float(v.max()))}" if v.size else ""
            out.guesses.append(Guess(name, None, note=f"name not recognised ({rng})"))
            continue
        if channel in taken:
            out.guesses.append(
                Guess(
                    name, channel, note=f"also looks like {channel} (mapped from {taken[channel]})"
                )
            )
            continue
        if v.size == 0:
            out.guesses.append(Guess(name, channel, note=f"no finite value; looks like {channel}"))
            continue
        taken[channel] = name
        g = Guess(name, channel, why="")
        out.guesses.append(g)
        cols.append(_Col(g, v, hint))
    by_channel = {c.guess.channel: c for c in cols}
    for c in cols:
        ch = c.guess.channel or ""
        if ch == "t":
            _time_unit(c)
        elif ch == "sat_k":
            _temperature_unit(c)
        elif CHANNELS[ch].unit == "-":
            _dimensionless(c)
        else:
            _score_units(c)
    group_of: dict[str, str | None] = {}
    for members in GROUPS:
        present = [by_channel[m] for m in members if m in by_channel]
        unit = _group_unit(present)
        for m in members:
            group_of[m] = unit
    for c in cols:
        ch = c.guess.channel or ""
        if ch in TYPICAL:
            _choose(c, group_of.get(ch))
    return out
