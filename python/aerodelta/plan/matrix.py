"""The test matrix of a campaign design study (``aerodelta plan MATRIX.toml``).

A matrix says what one virtual campaign of the study flies and how it is fitted: the
maneuver counts per flap and kind (mapped onto :func:`aerodelta.campaign.generate_campaign`),
sensor noise and biases, turbulence, the effects to expect, the fit's bootstrap, the
diagnosis, and the targets the recommendation reads. Every key is checked: an unknown one is
refused with one line naming it and the allowed ones (``docs/plan.md`` lists them).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from aerodelta._toml import read_toml
from aerodelta.campaign import mass_variation, parse_effects, vane_calibration
from aerodelta.exceptions import AerodeltaError, DataError, InvalidInputError

#: The flap settings the virtual ADX-37 flies, deg.
FLAPS: tuple[float, ...] = (0.0, 5.0, 10.0, 15.0, 35.0)

#: Maneuver kinds the pilot model flies (thesis Section 3.2.1).
KINDS: tuple[str, ...] = ("straight", "turning", "accelerated", "asymmetric_thrust")

#: Maneuver kinds the JSBSim pilot flies (``aerodelta.jsbsim_campaign.KINDS``; a sideslip
#: entry's manifest kind is ``other``).
JSBSIM_KINDS: tuple[str, ...] = ("straight", "turning", "sideslip")

#: Simulators a matrix can fly: the built-in virtual ADX-37, or a JSBSim aircraft.
SIMULATORS: tuple[str, ...] = ("virtual", "jsbsim")

#: ``pusher`` values of a flap: both variants (alternating, the pusher on for the odd one),
#: the stick pusher on only, or off only.
PUSHER: tuple[str, ...] = ("both", "on", "off")

_TABLES: dict[str, tuple[str, ...]] = {
    "campaign": (
        "noise",
        "turbulence_mps",
        "excitation",
        "rolloff",
        "record_hz",
        "cg_range_m",
        "mass_range",
        "inertia_range",
        "vane_scale",
        "flank_vane",
    ),
    "fit": ("bootstrap", "selection", "band_level"),
    "diagnosis": ("enabled",),
    "targets": (
        "alpha_edges_deg",
        "relative_band_width",
        "identified_probability",
        "named_probability",
    ),
    "engine": ("retries", "fault_drill_seeds"),
    "aircraft": ("simulator", "name", "withhold", "withhold_scale", "turbulence"),
}
_TOP = ("campaign", "effects", "flaps", "fit", "diagnosis", "targets", "engine", "aircraft")
_FLAP_KEYS = (*KINDS, "pusher")
#: [campaign] keys a JSBSim matrix takes (the others set the virtual aircraft's generator).
_JSBSIM_CAMPAIGN = ("noise",)


@dataclass(frozen=True)
class FlapCounts:
    """Maneuvers flown at one flap setting.

    Attributes
    ----------
    flap_deg
        Flap setting, deg (one of :data:`FLAPS`).
    counts
        Maneuvers per kind (:data:`KINDS`), each >= 0.
    pusher
        ``"both"``, ``"on"`` or ``"off"`` (:data:`PUSHER`).
    """

    flap_deg: float
    counts: dict[str, int]
    pusher: str = "both"

    def per_variant(self) -> dict[tuple[str, bool], int]:
        """Maneuvers per (kind, stick pusher armed): with ``"both"`` the pusher-on variant
        takes the odd one (``ceil(n / 2)``)."""
        out: dict[tuple[str, bool], int] = {}
        for k, n in self.counts.items():
            if self.pusher == "both":
                out[(k, True)], out[(k, False)] = (n + 1) // 2, n // 2
            else:
                on = self.pusher == "on"
                out[(k, on)], out[(k, not on)] = n, 0
        return out


@dataclass(frozen=True)
class Matrix:
    """A parsed, checked test matrix.

    Attributes
    ----------
    name
        The matrix's name (its file stem), for tables and folders.
    flaps
        Maneuvers per flap (flaps not listed are not flown).
    effects
        Expected effects of the truth aircraft, name -> magnitude (1 = design).
    noise
        Sensor noise scale, - (0 = noise-free).
    turbulence_mps
        Dryden RMS gust intensity, m/s.
    excitation
        Pilot excitation scale (doublets, stick noise), - (one value for every maneuver).
    rolloff
        Fly the stochastic roll-off.
    record_hz
        Record rate, Hz.
    cg_range_m, mass_range, inertia_range, vane_scale, flank_vane
        As :func:`aerodelta.campaign.generate_campaign` (``None``: nominal, ideal vanes).
    bootstrap
        Bootstrap replicates over maneuvers per fit.
    selection
        ``"stepwise"``, ``"mof"`` or ``"none"`` (the thesis structures).
    band_level
        Confidence level of the bands, -.
    diagnose
        Diagnose each campaign (the per-effect probability of being named).
    alpha_edges_deg
        Alpha ranges the tables report, deg (ascending edges).
    relative_band_width
        Target: band width over the parameter's largest expected |Δ| at that flap, -.
    identified_probability
        Target: probability a parameter is identified in an alpha range, -.
    named_probability
        Target: probability the diagnosis names an expected effect, -.
    retries
        Retries of a failed task.
    fault_drill_seeds
        Seeds whose task raises on purpose (a drill of the retry and report path of a
        cluster before a long study); empty for a real study.
    simulator
        ``"virtual"`` (the built-in ADX-37) or ``"jsbsim"`` (:data:`SIMULATORS`).
    aircraft
        The JSBSim aircraft (a key of ``aerodelta.jsbsim_campaign.AIRCRAFT``); ``""`` for the
        virtual one.
    withhold, withhold_scale, jsbsim_turbulence
        The JSBSim campaign's withheld lateral terms (the effects the study expects; empty:
        the aircraft's default), the fraction of their change withheld, and the Dryden
        turbulence severity (``generate_jsbsim_campaign``'s ``turbulence``).
    """

    name: str
    flaps: tuple[FlapCounts, ...]
    effects: dict[str, float]
    noise: float = 1.0
    turbulence_mps: float = 0.5
    excitation: float = 1.0
    rolloff: bool = True
    record_hz: float = 50.0
    cg_range_m: tuple[float, float, float] | None = None
    mass_range: float | None = None
    inertia_range: float | None = None
    vane_scale: tuple[float, float] | None = None
    flank_vane: bool = False
    bootstrap: int = 50
    selection: str = "stepwise"
    band_level: float = 0.95
    diagnose: bool = False
    alpha_edges_deg: tuple[float, ...] = (8.0, 12.0, 16.0, 20.0, 24.0)
    relative_band_width: float = 0.2
    identified_probability: float = 0.8
    named_probability: float = 0.8
    retries: int = 2
    fault_drill_seeds: tuple[int, ...] = field(default_factory=tuple)
    simulator: str = "virtual"
    aircraft: str = ""
    withhold: tuple[str, ...] = ()
    withhold_scale: float = 1.0
    jsbsim_turbulence: float = 0.0

    def n_maneuvers(self) -> int:
        """Maneuvers used per campaign."""
        return sum(sum(f.counts.values()) for f in self.flaps)

    def kinds(self) -> tuple[str, ...]:
        """The maneuver kinds the matrix's pilot flies."""
        return JSBSIM_KINDS if self.simulator == "jsbsim" else KINDS

    def task_spec(self) -> dict[str, Any]:
        """What a task needs (JSON-ready): everything that shapes a campaign's summary, and
        nothing else (not the targets' thresholds, the retries or the drill)."""
        d = asdict(self)
        for k in (
            "name",
            "relative_band_width",
            "identified_probability",
            "named_probability",
            "retries",
            "fault_drill_seeds",
        ):
            d.pop(k)
        if self.simulator == "virtual":  # the virtual matrices' digests as before
            for k in ("simulator", "aircraft", "withhold", "withhold_scale", "jsbsim_turbulence"):
                d.pop(k)
        return d

    def digest(self) -> str:
        """SHA-256 (hex, 16 digits) of :meth:`task_spec`: the key a task file carries."""
        text = json.dumps(self.task_spec(), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _where(path: Path | str, table: str, key: str | None = None) -> str:
    return f"{path}: [{table}]" + (f" {key}" if key is not None else "")


def _check_keys(doc: Mapping[str, Any], allowed: tuple[str, ...], where: str) -> None:
    for k in doc:
        if k not in allowed:
            raise DataError(f"{where}: unknown key '{k}'; allowed: {', '.join(allowed)}")


def _number(v: Any, where: str, lo: float | None = None, hi: float | None = None) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise DataError(f"{where} = {v!r}: give a finite number")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise DataError(f"{where} = {v!r}: give a number {rng}")
    return float(v)


def _integer(v: Any, where: str, lo: int = 0) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise DataError(f"{where} = {v!r}: give an integer >= {lo}")
    return int(v)


def _flag(v: Any, where: str) -> bool:
    if not isinstance(v, bool):
        raise DataError(f"{where} = {v!r}: give true or false")
    return v


def _numbers(v: Any, n: int | None, where: str) -> tuple[float, ...]:
    if not isinstance(v, list) or (n is not None and len(v) != n):
        size = f"{n} numbers" if n is not None else "a list of numbers"
        raise DataError(f"{where} = {v!r}: give {size}")
    return tuple(_number(x, where) for x in v)


def _flap(
    key: str,
    body: Any,
    path: Path | str,
    *,
    flaps: tuple[float, ...] = FLAPS,
    kinds: tuple[str, ...] = KINDS,
    aircraft: str = "the virtual aircraft",
) -> FlapCounts:
    where = f"{path}: [flaps.{key}]"
    try:
        flap = float(key)
    except ValueError:
        raise DataError(
            f"{where}: '{key}' is not a flap setting; use one of "
            f"{', '.join(f'{f:g}' for f in flaps)}"
        ) from None
    if flap not in flaps:
        raise DataError(
            f"{where}: flap {flap:g} deg is not flown by {aircraft}; use one of "
            f"{', '.join(f'{f:g}' for f in flaps)}"
        )
    if not isinstance(body, Mapping):
        raise DataError(f"{where}: give a table of maneuver counts, e.g. straight = 4")
    jsbsim = kinds == JSBSIM_KINDS
    _check_keys(body, kinds if jsbsim else _FLAP_KEYS, where)
    counts = {k: _integer(body.get(k, 0), f"{where} {k}") for k in kinds}
    pusher = "off" if jsbsim else body.get("pusher", "both")
    if pusher not in PUSHER:
        raise DataError(f"{where} pusher = {pusher!r}: use one of {', '.join(PUSHER)}")
    return FlapCounts(flap, counts, str(pusher))


def _aircraft(doc: Mapping[str, Any], path: Path | str) -> dict[str, Any]:
    """The ``[aircraft]`` table: which simulator flies the campaigns (checked)."""
    a = doc.get("aircraft", {})
    sim = a.get("simulator", "virtual")
    if sim not in SIMULATORS:
        raise DataError(
            f"{_where(path, 'aircraft', 'simulator')} = {sim!r}: use one of {', '.join(SIMULATORS)}"
        )
    if sim == "virtual":
        extra = [k for k in a if k != "simulator"]
        if extra:
            raise DataError(
                f"{_where(path, 'aircraft', extra[0])}: applies to a JSBSim aircraft (simulator "
                '= "jsbsim"); the virtual ADX-37 takes its effects from [effects]'
            )
        return {}
    from aerodelta.jsbsim_campaign import AIRCRAFT, lateral_terms  # noqa: PLC0415

    name = a.get("name")
    if name not in AIRCRAFT:
        raise DataError(
            f"{_where(path, 'aircraft', 'name')} = {name!r}: give a JSBSim aircraft, one of "
            f"{', '.join(AIRCRAFT)}"
        )
    for t in ("effects",):
        if doc.get(t):
            raise DataError(
                f"{path}: [{t}] is the virtual aircraft's; a JSBSim aircraft's effects are the "
                "lateral terms it withholds ([aircraft] withhold)"
            )
    bad = [k for k in doc.get("campaign", {}) if k not in _JSBSIM_CAMPAIGN]
    if bad:
        raise DataError(
            f"{_where(path, 'campaign', bad[0])}: the virtual aircraft's; a JSBSim campaign takes "
            f"{', '.join(_JSBSIM_CAMPAIGN)} here and its turbulence as [aircraft] turbulence"
        )
    out: dict[str, Any] = {"simulator": "jsbsim", "aircraft": str(name)}
    w = a.get("withhold", [])
    where = _where(path, "aircraft", "withhold")
    if not isinstance(w, list) or not all(isinstance(x, str) for x in w):
        raise DataError(f"{where} = {w!r}: give a list of the aircraft's lateral terms, or omit it")
    try:  # reads the aircraft's XML from the jsbsim package
        known = [t["name"] for t in lateral_terms(str(name)) if t["alpha_dependent"]]
    except (AerodeltaError, ImportError) as e:
        raise DataError(f"{_where(path, 'aircraft', 'name')} = {name!r}: {e}") from None
    unknown = [x for x in w if x not in known]
    if unknown:
        raise DataError(
            f"{where}: '{unknown[0]}' is not a lateral term of {name} tabulated over alpha; use "
            f"some of {', '.join(known)}"
        )
    out["withhold"] = tuple(w) or tuple(AIRCRAFT[str(name)].withhold)
    if "withhold_scale" in a:
        out["withhold_scale"] = _number(
            a["withhold_scale"], _where(path, "aircraft", "withhold_scale"), 0.0, 1.0
        )
    if "turbulence" in a:
        out["jsbsim_turbulence"] = _number(
            a["turbulence"], _where(path, "aircraft", "turbulence"), 0.0, 7.0
        )
    return out


def parse_matrix(doc: Mapping[str, Any], path: Path | str, name: str) -> Matrix:
    """Check a matrix document (parsed TOML) and build the :class:`Matrix`.

    Parameters
    ----------
    doc
        The parsed TOML document.
    path
        Its file, for the messages.
    name
        The matrix's name.

    Raises
    ------
    DataError
        One line per problem: the file, the table, the key, what is allowed.

    Examples
    --------
    >>> m = parse_matrix({"flaps": {"15": {"turning": 3}}}, "m.toml", "m")
    >>> m.n_maneuvers(), m.flaps[0].per_variant()[("turning", True)]
    (3, 2)
    >>> parse_matrix({"flaps": {"15": {"turnings": 3}}}, "m.toml", "m")
    Traceback (most recent call last):
    ...
    aerodelta.exceptions.DataError: m.toml: [flaps.15]: unknown key 'turnings'; allowed: ...
    """
    _check_keys(doc, _TOP, f"{path}")
    for t, allowed in _TABLES.items():
        body = doc.get(t, {})
        if not isinstance(body, Mapping):
            raise DataError(f"{path}: '{t}' must be a table ([{t}])")
        _check_keys(body, allowed, _where(path, t))
    kw: dict[str, Any] = _aircraft(doc, path)
    jsbsim = kw.get("simulator") == "jsbsim"
    c = doc.get("campaign", {})
    w = lambda k: _where(path, "campaign", k)  # noqa: E731
    if "noise" in c:
        kw["noise"] = _number(c["noise"], w("noise"), 0.0)
    if "turbulence_mps" in c:
        kw["turbulence_mps"] = _number(c["turbulence_mps"], w("turbulence_mps"), 0.0)
    if "excitation" in c:
        kw["excitation"] = _number(c["excitation"], w("excitation"), 0.0)
    if "rolloff" in c:
        kw["rolloff"] = _flag(c["rolloff"], w("rolloff"))
    if "record_hz" in c:
        kw["record_hz"] = _number(c["record_hz"], w("record_hz"), 1.0, 100.0)
    if "cg_range_m" in c:
        kw["cg_range_m"] = _numbers(c["cg_range_m"], 3, w("cg_range_m"))
    for k in ("mass_range", "inertia_range"):
        if k in c:
            kw[k] = _number(c[k], w(k), 0.0)
    if "vane_scale" in c:
        kw["vane_scale"] = _numbers(c["vane_scale"], 2, w("vane_scale"))
    if "flank_vane" in c:
        kw["flank_vane"] = _flag(c["flank_vane"], w("flank_vane"))
    try:  # the generator's own checks of the ranges, before any task is sent
        mass_variation(kw.get("cg_range_m"), kw.get("mass_range"), kw.get("inertia_range"))
        vane_calibration(kw.get("vane_scale"), kw.get("flank_vane", False))
    except InvalidInputError as e:
        raise DataError(f"{path}: [campaign] {e}") from None
    eff = doc.get("effects", {})
    if not isinstance(eff, Mapping):
        raise DataError(f"{path}: 'effects' must be a table of name = magnitude ([effects])")
    for k, v in eff.items():
        _number(v, _where(path, "effects", k))
    try:
        effects = parse_effects({str(k): float(v) for k, v in eff.items()})
    except InvalidInputError as e:
        raise DataError(f"{path}: [effects] {e}") from None
    fl = doc.get("flaps", {})
    if not isinstance(fl, Mapping) or not fl:
        raise DataError(
            f"{path}: no [flaps.N] table; give the maneuver counts per flap, e.g. "
            "[flaps.0] straight = 4"
        )
    if jsbsim:
        from aerodelta.jsbsim_campaign import AIRCRAFT  # noqa: PLC0415

        ac = kw["aircraft"]
        fargs: dict[str, Any] = {
            "flaps": AIRCRAFT[ac].flaps_deg, "kinds": JSBSIM_KINDS, "aircraft": f"JSBSim's {ac}",
        }  # fmt: skip
    else:
        fargs = {}
    flaps = tuple(
        sorted((_flap(str(k), v, path, **fargs) for k, v in fl.items()), key=lambda f: f.flap_deg)
    )
    if len({f.flap_deg for f in flaps}) != len(flaps):
        raise DataError(f"{path}: [flaps] a flap setting is given twice (e.g. 15 and 15.0)")
    if sum(sum(f.counts.values()) for f in flaps) == 0:
        raise DataError(f"{path}: [flaps] every count is 0; give at least one maneuver")
    f = doc.get("fit", {})
    if "bootstrap" in f:
        kw["bootstrap"] = _integer(f["bootstrap"], _where(path, "fit", "bootstrap"), 2)
    if "selection" in f:
        if f["selection"] not in ("stepwise", "mof", "none"):
            raise DataError(
                f"{_where(path, 'fit', 'selection')} = {f['selection']!r}: use stepwise, mof "
                "or none"
            )
        kw["selection"] = f["selection"]
    if "band_level" in f:
        kw["band_level"] = _number(f["band_level"], _where(path, "fit", "band_level"), 0.5, 0.999)
    d = doc.get("diagnosis", {})
    if "enabled" in d:
        kw["diagnose"] = _flag(d["enabled"], _where(path, "diagnosis", "enabled"))
    t = doc.get("targets", {})
    if "alpha_edges_deg" in t:
        where = _where(path, "targets", "alpha_edges_deg")
        edges = _numbers(t["alpha_edges_deg"], None, where)
        if len(edges) < 2 or any(b <= a for a, b in itertools.pairwise(edges)):
            raise DataError(f"{where} = {list(edges)}: give two or more ascending edges, deg")
        kw["alpha_edges_deg"] = edges
    if "relative_band_width" in t:
        where = _where(path, "targets", "relative_band_width")
        kw["relative_band_width"] = _number(t["relative_band_width"], where, 1e-6)
    for k in ("identified_probability", "named_probability"):
        if k in t:
            kw[k] = _number(t[k], _where(path, "targets", k), 0.0, 1.0)
    e = doc.get("engine", {})
    if "retries" in e:
        kw["retries"] = _integer(e["retries"], _where(path, "engine", "retries"))
    if "fault_drill_seeds" in e:
        where = _where(path, "engine", "fault_drill_seeds")
        seeds = e["fault_drill_seeds"]
        if not isinstance(seeds, list):
            raise DataError(f"{where} = {seeds!r}: give a list of seeds")
        kw["fault_drill_seeds"] = tuple(_integer(s, where) for s in seeds)
    return Matrix(name=name, flaps=flaps, effects=effects, **kw)


def load_matrix(path: str | Path, name: str | None = None) -> Matrix:
    """Read and check a test matrix (TOML).

    Parameters
    ----------
    path
        The matrix file.
    name
        Name in tables and folders (default: the file stem).

    Raises
    ------
    DataError
        An unreadable file, invalid TOML, an unknown key (named, with the allowed ones) or a
        bad value (named, with what to give).
    """
    p = Path(path)
    doc, _ = read_toml(p, "test matrix")
    return parse_matrix(doc, p, name or p.stem)
