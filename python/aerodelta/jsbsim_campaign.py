"""Virtual flight test campaigns flown on JSBSim aircraft: an independent truth source.

``generate_jsbsim_campaign(out, aircraft="f15")`` flies a JSBSim model (the ``jsbsim`` Python
package, ``pip install 'aerodelta[jsbsim]'``) through the thesis's stall maneuvers with a
seeded pilot model and writes the campaign layout that ``aerodelta ingest`` reads, plus the
truth (see ``docs/jsbsim_campaign.md``)::

    DIR/manifest.csv              maneuver_id, flap_deg, kind, pusher, file, + metadata
    DIR/aircraft.toml             mass, inertias, geometry of the JSBSim model (SI)
    DIR/records/<id>.parquet      canonical channels (noisy sensors) + Cl_sim, Cn_sim, CY_sim
    DIR/truth/<id>.parquet        JSBSim's own Cl, Cn, CY (aero, about the CG), each lateral
                                  table term, the qualified model and the true Δ per sample
    DIR/truth/true_delta.parquet  the true Δ of every maneuver (full − qualified), per term
    DIR/truth/truth.json          withheld terms, their true Δ derivatives vs alpha, signs

The *qualified model* is JSBSim's own lateral aerodynamics with the withheld terms' alpha
dependence frozen at ``withhold_alpha_deg`` above it: each withheld term is re-evaluated from the
aircraft's XML with alpha replaced by ``min(alpha, withhold_alpha)``. The true Δ = full −
qualified is therefore known exactly per sample and per term. The XML evaluation is checked
against JSBSim's own ``aero/coefficient/*`` properties on every sample. ``withhold_scale=k``
withholds a fraction of that change: qualified = full − k·(full − frozen), so the true Δ is
k·(full − frozen) (k = 0.5, 0.25: an effect at half and a quarter of its size).

Every random draw derives from the campaign seed: the same seed gives byte-identical files.
"""

from __future__ import annotations

import importlib.metadata
import json
import math
import os
import shutil
import sys
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from aerodelta._fsutil import replace_dir
from aerodelta.exceptions import DataError, InvalidInputError, NoConvergenceError

__all__ = [
    "AIRCRAFT",
    "JsbsimAircraft",
    "JsbsimCampaignInfo",
    "generate_jsbsim_campaign",
    "lateral_terms",
    "true_delta_derivative",
]

FT = 0.3048
LBF = 4.44822
SLUG = 14.5939
SLUGFT2 = 1.35582
SLUGFT3 = 515.379
D2R = math.pi / 180.0
R2D = 180.0 / math.pi

#: Record rate (Hz) and integration step (s): the record is every 4th step.
RECORD_HZ = 50.0
DT = 1.0 / 200.0
_DECIM = 4

#: Sensor noise standard deviations at noise scale 1 (as the built-in virtual flight test).
NOISE = {
    "alpha_deg": 0.05,
    "beta_deg": 0.05,
    "p_dps": 0.03,
    "q_dps": 0.03,
    "r_dps": 0.03,
    "phi_deg": 0.03,
    "theta_deg": 0.03,
    "psi_deg": 0.03,
    "ax_mps2": 0.03,
    "ay_mps2": 0.03,
    "az_mps2": 0.03,
    "tas_mps": 0.15,
    "da_deg": 0.05,
    "de_deg": 0.05,
    "dr_deg": 0.05,
    "ct_left": 0.002,
    "ct_right": 0.002,
    "h_m": 0.5,
}

#: Maneuver kinds flown per flap setting (manifest ``kind``; sideslip entries are ``other``).
KINDS = ("straight", "turning", "sideslip")
SIZES = {"default": 6, "quick": 1}


@dataclass(frozen=True)
class JsbsimAircraft:
    """How to fly one JSBSim model (pilot gains, entry conditions, surfaces, defaults).

    Gains are in normalised stick per degree (per deg/s for rate gains); the pilot's sign
    conventions come from the aircraft's XML (see :func:`control_signs`).
    """

    model: str
    description: str
    h_ft: float
    entry_kts: tuple[float, ...]  # calibrated airspeed at the entry, per flap setting
    flaps_deg: tuple[float, ...] = (0.0,)
    flap_norm_per_deg: float = 0.0  # fcs/flap-cmd-norm per flap degree (0: no flaps)
    alpha_peak_deg: tuple[float, float] = (25.0, 35.0)  # the pilot's target past the stall
    withhold: tuple[str, ...] = ()
    withhold_alpha_deg: float = 15.0
    mach_ref: float = 0.3  # Mach for the truth derivatives of Mach-dependent tables
    aileron_rad: str = "fcs/left-aileron-pos-rad"
    elevator_rad: str = "fcs/elevator-pos-rad"
    rudder_rad: str = "fcs/rudder-pos-rad"
    flap_deg_prop: str = "fcs/flap-pos-deg"
    k_alpha: float = 0.06
    k_alpha_i: float = 0.03
    k_q: float = 0.03
    k_v: float = 0.25  # alpha command rate (deg/s) per kt of speed above the schedule
    k_phi: float = 0.03
    k_phi_i: float = 0.005
    k_p: float = 0.012
    k_beta: float = 0.06
    k_beta_i: float = 0.02
    k_r: float = 0.02
    doublet: tuple[float, float] = (0.3, 0.6)  # aileron/rudder doublet amplitude range
    abort_alpha_deg: float = 55.0
    #: signs fixed by hand where the XML cannot tell (e.g. a 3-D table): (("de", 1.0),)
    sign_overrides: tuple[tuple[str, float], ...] = ()
    notes: str = ""


#: Aircraft flown and checked here (``aerodelta campaign --simulator jsbsim --aircraft NAME``).
AIRCRAFT: dict[str, JsbsimAircraft] = {
    "f15": JsbsimAircraft(
        model="f15",
        description="JSBSim F-15 (twin turbofan, no flaps): Clb, Clp, ClDa, Cnb, Cnp, Cndr "
        "and CYb tabulated over alpha to 50 deg",
        h_ft=20000.0,
        entry_kts=(190.0,),
        alpha_peak_deg=(19.0, 24.0),  # the elevator stops the F-15 near 18-20 deg alpha
        withhold=("Clb", "Clp", "Cnb"),
        withhold_alpha_deg=12.0,
        mach_ref=0.35,
        notes="jet: ct_left/ct_right are the engines' net thrust T/(qbar S) (no propeller)",
    ),
    "DHC6": JsbsimAircraft(
        model="DHC6",
        description="JSBSim DHC-6 Twin Otter (twin turboprop, flaps 0-40 deg): Clb(beta, "
        "alpha) and Cnb(alpha, flap) tabulated into the stall",
        h_ft=6000.0,
        entry_kts=(90.0, 65.0, 60.0),
        flaps_deg=(0.0, 20.0, 40.0),
        flap_norm_per_deg=1.0 / 40.0,
        alpha_peak_deg=(16.0, 22.0),
        withhold=("Clb", "Cnb"),
        withhold_alpha_deg=10.0,
        sign_overrides=(("de", 1.0),),  # CmDe is a 3-D table: positive elevator pitches down
        mach_ref=0.12,
        k_alpha=0.08,
        k_alpha_i=0.04,
        k_q=0.04,
        k_v=0.3,
        k_phi=0.04,
        k_p=0.02,
        notes="turboprop: propeller torque and gyroscopic moments are propulsion, not aero "
        "(truth C*_prop_true); aircraft.toml sets prop_inertia_kgm2 = 0",
    ),
}


@dataclass(frozen=True)
class JsbsimCampaignInfo:
    """What :func:`generate_jsbsim_campaign` wrote.

    Attributes
    ----------
    path, n_maneuvers, seed, manifest
        As :class:`aerodelta.campaign.CampaignInfo`.
    aircraft
        JSBSim model name.
    withheld
        Withheld term names.
    withhold_alpha_deg
        Alpha above which the withheld terms are frozen in the qualified model.
    withhold_scale
        Fraction of the frozen terms' change withheld (``generate_jsbsim_campaign``).
    """

    path: Path
    n_maneuvers: int
    seed: int
    aircraft: str
    withheld: tuple[str, ...]
    withhold_alpha_deg: float
    manifest: pl.DataFrame
    effects: dict[str, float] = field(default_factory=dict)
    withhold_scale: float = 1.0


# --------------------------------------------------------------------------------------------
# JSBSim access


def _jsbsim() -> Any:
    os.environ.setdefault("JSBSIM_DEBUG", "0")
    try:
        import jsbsim  # noqa: PLC0415
    except ImportError:
        raise InvalidInputError(
            "the JSBSim campaign needs the jsbsim package: pip install 'aerodelta[jsbsim]'"
        ) from None
    return jsbsim


def _root(root_dir: str | os.PathLike[str] | None) -> Path:
    return Path(root_dir) if root_dir is not None else Path(_jsbsim().get_default_root_dir())


def _model_xml(model: str, root: Path) -> Path:
    p = root / "aircraft" / model / f"{model}.xml"
    if not p.is_file():
        have = sorted(
            d.name for d in (root / "aircraft").glob("*") if (d / f"{d.name}.xml").is_file()
        )
        raise InvalidInputError(
            f"unknown JSBSim aircraft '{model}' (no {p}); aircraft flown here: "
            f"{', '.join(AIRCRAFT)}; models in that root: {', '.join(have)}"
        )
    return p


def _resolve_aircraft(aircraft: str | JsbsimAircraft, root: Path) -> tuple[JsbsimAircraft, Path]:
    if isinstance(aircraft, JsbsimAircraft):
        return aircraft, _model_xml(aircraft.model, root)
    key = {k.lower(): k for k in AIRCRAFT}.get(str(aircraft).lower())
    if key is None:
        _model_xml(str(aircraft), root)  # an unknown model: its own error
        raise InvalidInputError(
            f"JSBSim aircraft '{aircraft}' has no pilot configuration; use one of "
            f"{', '.join(AIRCRAFT)}, or pass aircraft=JsbsimAircraft(model='{aircraft}', ...) "
            "from Python"
        )
    cfg = AIRCRAFT[key]
    return cfg, _model_xml(cfg.model, root)


# --------------------------------------------------------------------------------------------
# The aircraft's aerodynamic terms, evaluated from its XML


_Node = tuple  # ("prop", name) | ("val", x) | ("table", vars, rows, cols, data) | (op, [children])
_OPS = ("product", "sum", "difference", "quotient", "abs", "max", "min")
#: Deepest function this evaluator reads (aircraft nest a handful of levels); a deeper one is
#: left to JSBSim like any other function it cannot evaluate, keeping the recursions here
#: (_parse_fn, _eval, _props) well inside Python's recursion limit.
_MAX_FN_DEPTH = 100


def _parse_fn(el: ET.Element, depth: int = 1) -> _Node | None:
    if depth > _MAX_FN_DEPTH:
        return None
    tag = el.tag
    if tag == "property":
        return ("prop", (el.text or "").strip())
    if tag == "value":
        return ("val", float((el.text or "").strip()))
    if tag == "table":
        ivs = el.findall("independentVar")
        td = el.find("tableData")
        if td is None or not ivs or len(ivs) > 2 or td.get("breakPoint") is not None:
            return None
        order = sorted(ivs, key=lambda v: {"row": 0, "column": 1}.get(v.get("lookup", "row"), 2))
        names = [(v.text or "").strip() for v in order]
        rows = [[float(x) for x in ln.split()] for ln in (td.text or "").strip().splitlines()]
        rows = [r for r in rows if r]
        if len(names) == 1:
            a = np.array(rows, dtype=float)
            return ("table", names, a[:, 0], None, a[:, 1])
        cols = np.array(rows[0], dtype=float)
        body = np.array(rows[1:], dtype=float)
        return ("table", names, body[:, 0], cols, body[:, 1:])
    if tag in _OPS:
        kids = [_parse_fn(c, depth + 1) for c in el if c.tag != "description"]
        if any(k is None for k in kids) or not kids:
            return None
        return (tag, kids)
    return None


def _interp_idx(x: np.ndarray, bp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    xc = np.clip(x, bp[0], bp[-1])
    i = np.clip(np.searchsorted(bp, xc, side="right") - 1, 0, len(bp) - 2)
    w = (xc - bp[i]) / (bp[i + 1] - bp[i])
    return i, w


def _eval(node: _Node, env: Callable[[str], np.ndarray]) -> np.ndarray:
    kind = node[0]
    if kind == "prop":
        return env(node[1])
    if kind == "val":
        return np.asarray(node[1])
    if kind == "table":
        _, names, rk, ck, data = node
        r = np.asarray(env(names[0]), dtype=float)
        if ck is None:
            if len(rk) == 1:
                return np.full_like(r, data[0])
            i, w = _interp_idx(r, rk)
            return data[i] * (1 - w) + data[i + 1] * w
        c = np.asarray(env(names[1]), dtype=float)
        r, c = np.broadcast_arrays(r, c)
        i, wi = _interp_idx(r, rk) if len(rk) > 1 else (np.zeros(r.shape, int), np.zeros(r.shape))
        j, wj = _interp_idx(c, ck) if len(ck) > 1 else (np.zeros(c.shape, int), np.zeros(c.shape))
        i1 = np.minimum(i + 1, len(rk) - 1)
        j1 = np.minimum(j + 1, len(ck) - 1)
        return (
            data[i, j] * (1 - wi) * (1 - wj)
            + data[i1, j] * wi * (1 - wj)
            + data[i, j1] * (1 - wi) * wj
            + data[i1, j1] * wi * wj
        )
    kids = [_eval(k, env) for k in node[1]]
    if kind == "product":
        out = kids[0]
        for k in kids[1:]:
            out = out * k
        return out
    if kind == "sum":
        return sum(kids[1:], kids[0])
    if kind == "difference":
        out = kids[0]
        for k in kids[1:]:
            out = out - k
        return out
    if kind == "quotient":
        return kids[0] / kids[1]
    if kind == "abs":
        return np.abs(kids[0])
    if kind == "max":
        return np.maximum.reduce(np.broadcast_arrays(*kids))
    return np.minimum.reduce(np.broadcast_arrays(*kids))


def _props(node: _Node) -> set[str]:
    if node[0] == "prop":
        return {node[1]}
    if node[0] == "val":
        return set()
    if node[0] == "table":
        return set(node[1])
    return set().union(*(_props(k) for k in node[1]))


@dataclass(frozen=True)
class Term:
    """One ``aero/coefficient/*`` function of the aircraft's XML."""

    name: str  # short name, e.g. "Clp"
    prop: str  # aero/coefficient/Clp
    axis: str  # ROLL, YAW, SIDE, PITCH, ...
    tree: _Node | None  # None: not evaluable here (reported from JSBSim only)

    @property
    def coefficient(self) -> str | None:
        return {"ROLL": "Cl", "YAW": "Cn", "SIDE": "CY", "PITCH": "Cm"}.get(self.axis)

    @property
    def alpha_dependent(self) -> bool:
        return self.tree is not None and bool(
            _props(self.tree) & {"aero/alpha-rad", "aero/alpha-deg"}
        )


def _aero_terms(xml: Path, root: Path) -> list[Term]:
    try:
        doc = ET.parse(xml).getroot()
    except ET.ParseError as e:
        raise DataError(f"{xml}: not valid XML: {e}") from e
    aero = doc.find("aerodynamics")
    if aero is not None and aero.get("file"):
        sub = xml.parent / f"{aero.get('file')}.xml"
        aero = ET.parse(sub).getroot()
    if aero is None:
        raise DataError(f"{xml}: no <aerodynamics> section")
    out = []
    for ax in aero.findall("axis"):
        for fn in ax.findall("function"):
            name = fn.get("name", "")
            if not name.startswith("aero/coefficient/"):
                continue
            kids = [c for c in fn if c.tag != "description"]
            tree = _parse_fn(kids[0]) if len(kids) == 1 else None
            out.append(Term(name.rsplit("/", 1)[1], name, ax.get("name", "").upper(), tree))
    return out


def lateral_terms(
    aircraft: str = "f15", root_dir: str | os.PathLike[str] | None = None
) -> list[dict[str, Any]]:
    """The roll, yaw and side-force terms of a JSBSim model's XML.

    Returns
    -------
    list of dict
        ``name``, ``coefficient`` (Cl, Cn, CY), ``axis``, ``alpha_dependent`` (can be
        withheld), ``properties`` the term reads.
    """
    root = _root(root_dir)
    name = aircraft.model if isinstance(aircraft, JsbsimAircraft) else str(aircraft)
    key = {k.lower(): k for k in AIRCRAFT}.get(name.lower())
    xml = _model_xml(AIRCRAFT[key].model if key else name, root)
    return [
        {
            "name": t.name,
            "coefficient": t.coefficient,
            "axis": t.axis,
            "alpha_dependent": t.alpha_dependent,
            "properties": sorted(_props(t.tree)) if t.tree is not None else None,
        }
        for t in _aero_terms(xml, root)
        if t.axis in ("ROLL", "YAW", "SIDE")
    ]


# Reference quantities that make a term nondimensional (set to 1 for derivatives).
_REF_PROPS = {
    "aero/qbar-psf": 1.0,
    "aero/qbar-area": 1.0,
    "metrics/Sw-sqft": 1.0,
    "metrics/bw-ft": 1.0,
    "metrics/cbarw-ft": 1.0,
    "aero/bi2vel": 1.0,
    "aero/ci2vel": 1.0,
    "aero/function/kCLge": 1.0,
    "aero/function/kCDge": 1.0,
    "aero/function/kCmge": 1.0,
}


def _regressor_env(
    cfg: JsbsimAircraft, signs: Mapping[str, float]
) -> dict[str, Callable[[float], dict[str, float]]]:
    """Fit regressor -> JSBSim properties at regressor value x (fit units)."""
    sa, sr = signs["da"], signs["dr"]
    return {
        "beta_deg": lambda x: {"aero/beta-rad": x * D2R, "aero/beta-deg": x},
        "phat": lambda x: {"velocities/p-aero-rad_sec": x},
        "rhat": lambda x: {"velocities/r-aero-rad_sec": x},
        "da_deg": lambda x: {
            cfg.aileron_rad: x * D2R / sa,
            cfg.aileron_rad.replace("-rad", "-deg"): x / sa,
        },
        "dr_deg": lambda x: {
            cfg.rudder_rad: x * D2R / sr,
            cfg.rudder_rad.replace("-rad", "-deg"): x / sr,
        },
    }


def _nondim(term: Term, values: Mapping[str, np.ndarray | float]) -> np.ndarray:
    """A term's value over q̄S (force) or q̄Sb (moment), q̄ S b from ``values``."""
    qs = np.asarray(values["aero/qbar-psf"]) * np.asarray(values["metrics/Sw-sqft"])
    if term.axis in ("ROLL", "YAW"):
        return 1.0 / (qs * np.asarray(values["metrics/bw-ft"]))
    if term.axis == "PITCH":
        return 1.0 / (qs * np.asarray(values["metrics/cbarw-ft"]))
    return 1.0 / qs


def _term_derivatives(  # noqa: PLR0917
    term: Term,
    cfg: JsbsimAircraft,
    signs: Mapping[str, float],
    alpha_deg: np.ndarray,
    flap_deg: float,
    withhold_alpha_deg: float,
    withhold_scale: float = 1.0,
) -> dict[str, dict[str, list[float]]]:
    """Per fit regressor: the term's derivative (full and qualified) vs alpha, fit units; the
    qualified one is ``full - withhold_scale * (full - frozen)``."""
    assert term.tree is not None
    regs = _regressor_env(cfg, signs)
    out: dict[str, dict[str, list[float]]] = {}
    h = 1e-3
    for reg, setter in regs.items():
        curves = []
        for frozen in (False, True):
            a = np.minimum(alpha_deg, withhold_alpha_deg) if frozen else alpha_deg
            vals = []
            for sgn in (1.0, -1.0):
                base: dict[str, Any] = {
                    **_REF_PROPS,
                    "aero/alpha-rad": a * D2R,
                    "aero/alpha-deg": a,
                    cfg.flap_deg_prop: np.full_like(a, flap_deg),
                    "fcs/flap-pos-norm": np.full_like(
                        a, flap_deg * cfg.flap_norm_per_deg if cfg.flap_norm_per_deg else 0.0
                    ),
                    "velocities/mach": np.full_like(a, cfg.mach_ref),
                    **setter(sgn * h),
                }

                def env(p: str, base: dict[str, Any] = base) -> Any:
                    return base.get(p, 0.0)

                vals.append(np.broadcast_to(_eval(term.tree, env), a.shape))
            curves.append((vals[0] - vals[1]) / (2 * h))
        full, frozen_ = curves
        delta = withhold_scale * (full - frozen_)
        if np.max(np.abs(full)) > 1e-12:
            out[reg] = {
                "full": full.tolist(),
                "qualified": (full - delta).tolist(),
                "delta": delta.tolist(),
            }
    return out


def control_signs(cfg: JsbsimAircraft, terms: Sequence[Term]) -> dict[str, float]:
    """Signs mapping the aircraft's surface positions onto aerodelta's convention (Etkin:
    a positive deflection gives a negative moment), from the XML's own moment derivatives
    at 5 deg alpha: ``da_deg = s_a * deg(aileron)``, likewise ``de``, ``dr``."""
    out = dict(cfg.sign_overrides)
    a = np.array([5.0])
    for key, prop, axis in (
        ("da", cfg.aileron_rad, "ROLL"),
        ("de", cfg.elevator_rad, "PITCH"),
        ("dr", cfg.rudder_rad, "YAW"),
    ):
        if key in out:
            continue
        total = 0.0
        for t in terms:
            if t.axis != axis or t.tree is None or prop not in _props(t.tree):
                continue
            vals = []
            for x in (0.01, -0.01):
                base = {
                    **_REF_PROPS,
                    "aero/alpha-rad": a * D2R,
                    "aero/alpha-deg": a,
                    "velocities/mach": np.array([cfg.mach_ref]),
                    prop: np.array([x]),
                    prop.replace("-rad", "-deg"): np.array([x * R2D]),
                }
                vals.append(float(np.ravel(_eval(t.tree, lambda p, b=base: b.get(p, 0.0)))[0]))
            total += (vals[0] - vals[1]) / 0.02
        if total == 0.0:
            raise DataError(
                f"{cfg.model}: cannot tell the sign of {prop} from the {axis} terms of its XML; "
                "name the surface property in JsbsimAircraft"
            )
        out[key] = -1.0 if total > 0 else 1.0
    return out


# --------------------------------------------------------------------------------------------
# Flying


_REC_PROPS = [
    "simulation/sim-time-sec",
    "aero/alpha-deg",
    "aero/beta-deg",
    "velocities/p-rad_sec",
    "velocities/q-rad_sec",
    "velocities/r-rad_sec",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "attitude/psi-rad",
    "forces/fbx-total-lbs",
    "forces/fby-total-lbs",
    "forces/fbz-total-lbs",
    "inertia/mass-slugs",
    "velocities/vt-fps",
    "atmosphere/rho-slugs_ft3",
    "position/h-sl-ft",
    "aero/qbar-psf",
    "metrics/Sw-sqft",
    "metrics/bw-ft",
    "metrics/cbarw-ft",
    "moments/l-aero-lbsft",
    "moments/n-aero-lbsft",
    "forces/fby-aero-lbs",
    "moments/l-prop-lbsft",
    "moments/n-prop-lbsft",
    "forces/fby-prop-lbs",
    "velocities/p-aero-rad_sec",
    "velocities/r-aero-rad_sec",
    "aero/bi2vel",
    "velocities/mach",
    "aero/alpha-rad",
]


def new_fdm(root: Path, model: str) -> Any:
    """A quiet JSBSim executive with aircraft ``model`` of the root folder ``root`` loaded,
    stepping at :data:`DT`.

    Raises
    ------
    DataError
        JSBSim cannot load the aircraft.
    """
    jsbsim = _jsbsim()
    fdm = jsbsim.FGFDMExec(str(root))
    fdm.set_debug_level(0)
    if not fdm.load_model(model):
        raise DataError(f"JSBSim could not load aircraft '{model}' from {root}")
    fdm.set_dt(DT)
    return fdm


def quiet_trim(fdm: Any, failure: str) -> None:
    """JSBSim's ``do_simple_trim`` with its diagnostics (printed on C stdout) kept out of ours.

    Raises
    ------
    NoConvergenceError
        With ``failure`` as the message, when JSBSim cannot trim.
    """
    jsbsim = _jsbsim()
    fd = os.dup(1)
    try:
        sys.stdout.flush()
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            try:
                fdm["simulation/do_simple_trim"] = 1
            finally:
                os.dup2(fd, 1)
    except jsbsim.TrimFailureError:
        raise NoConvergenceError(failure) from None
    finally:
        os.close(fd)


def trim_at_ic(fdm: Any, cfg: JsbsimAircraft, flap_deg: float, seed: int, failure: str) -> None:
    """Trim at the initial conditions already set (speed, altitude, heading): level flight,
    the flap at ``flap_deg`` (deg), gear up, engines running, turbulence seeded with ``seed``,
    then the fuel frozen so the mass properties stay those of ``aircraft.toml``.

    Raises
    ------
    NoConvergenceError
        With ``failure`` as the message, when JSBSim cannot trim.
    """
    fdm["ic/gamma-deg"] = 0.0
    fdm["simulation/randomseed"] = seed % 2_000_000_000
    if cfg.flap_norm_per_deg:
        fdm["fcs/flap-cmd-norm"] = flap_deg * cfg.flap_norm_per_deg
    fdm["gear/gear-cmd-norm"] = 0.0
    fdm["propulsion/set-running"] = -1
    fdm.run_ic()
    quiet_trim(fdm, failure)
    fdm["propulsion/fuel_freeze"] = 1


def _trim(fdm: Any, cfg: JsbsimAircraft, flap_deg: float, kts: float, seed: int) -> None:
    fdm["ic/h-sl-ft"] = cfg.h_ft
    fdm["ic/vc-kts"] = kts
    fdm["ic/psi-true-deg"] = 0.0
    trim_at_ic(
        fdm,
        cfg,
        flap_deg,
        seed,
        f"JSBSim trim failed for {cfg.model} at {kts:g} kt, {cfg.h_ft:g} ft, flap "
        f"{flap_deg:g} deg; choose another entry speed/altitude (JsbsimAircraft)",
    )


@dataclass
class _Plan:
    index: int
    flap_deg: float
    kind: str
    seed: int


def _plan(cfg: JsbsimAircraft, seed: int, reps: int) -> list[_Plan]:
    ss = np.random.SeedSequence(seed)
    plans = []
    i = 0
    for flap in cfg.flaps_deg:
        for kind in KINDS:
            for _ in range(reps):
                plans.append(_Plan(i, float(flap), kind, 0))
                i += 1
    for p, child in zip(plans, ss.spawn(len(plans)), strict=True):
        p.seed = int(child.generate_state(1, dtype=np.uint32)[0])
    return plans


def jsbsim_campaign_plan(
    aircraft: str | JsbsimAircraft = "f15",
    *,
    seed: int = 0,
    size: str | int = "default",
    root_dir: str | os.PathLike[str] | None = None,
) -> pl.DataFrame:
    """The maneuvers :func:`generate_jsbsim_campaign` flies, in order, before flying them.

    Parameters
    ----------
    aircraft, seed, size, root_dir
        As :func:`generate_jsbsim_campaign` (the other options do not change the plan).

    Returns
    -------
    polars.DataFrame
        One row per maneuver: ``maneuver_index`` (what ``only`` takes), ``flap_deg`` (deg),
        ``kind`` and ``pusher`` as the manifest writes them (a sideslip entry is ``"other"``;
        no pusher) and ``seed`` (the maneuver's own stream: a maneuver flies the same in a
        subset as in the whole campaign).

    Raises
    ------
    InvalidInputError
        Unknown aircraft, or a size that is not ``"default"``, ``"quick"`` or a positive count.
    """
    cfg, _ = _resolve_aircraft(aircraft, _root(root_dir))
    reps = SIZES.get(size, 0) if isinstance(size, str) else int(size)
    if reps <= 0:
        raise InvalidInputError(f"size '{size}': use 'default', 'quick' or a positive integer")
    plans = _plan(cfg, int(seed), reps)
    return pl.DataFrame(
        {
            "maneuver_index": [p.index for p in plans],
            "flap_deg": [p.flap_deg for p in plans],
            "kind": ["other" if p.kind == "sideslip" else p.kind for p in plans],
            "pusher": [False] * len(plans),
            "seed": [p.seed for p in plans],
        },
        schema={
            "maneuver_index": pl.Int64,
            "flap_deg": pl.Float64,
            "kind": pl.String,
            "pusher": pl.Boolean,
            "seed": pl.Int64,
        },
    )


def _entry_kts(cfg: JsbsimAircraft, flap_deg: float) -> float:
    i = int(np.argmin([abs(f - flap_deg) for f in cfg.flaps_deg]))
    return float(cfg.entry_kts[min(i, len(cfg.entry_kts) - 1)])


def _doublet(t: float, t0: float, half: float, amp: float) -> float:
    if t0 <= t < t0 + half:
        return amp
    if t0 + half <= t < t0 + 2 * half:
        return -amp
    return 0.0


def _fly(  # noqa: PLR0917
    cfg: JsbsimAircraft,
    root: Path,
    plan: _Plan,
    signs: Mapping[str, float],
    props: Sequence[str],
    decel_kts: float,
    turbulence: float,
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Fly one maneuver; return the recorded properties (50 Hz) and metadata."""
    rng = np.random.default_rng(plan.seed)
    side = 1.0 if rng.random() < 0.5 else -1.0
    entry = _entry_kts(cfg, plan.flap_deg) * rng.uniform(0.98, 1.02)
    decel = decel_kts * rng.uniform(0.8, 1.2)
    peak = rng.uniform(*cfg.alpha_peak_deg)
    hold = rng.uniform(3.0, 5.0)
    bank = side * rng.uniform(27.0, 33.0) if plan.kind == "turning" else 0.0
    beta_cmd = side * rng.uniform(5.0, 9.0) if plan.kind == "sideslip" else 0.0
    amp_a = rng.uniform(*cfg.doublet)
    amp_r = rng.uniform(*cfg.doublet)
    half_a = rng.uniform(0.4, 0.8)
    half_r = rng.uniform(0.5, 0.9)
    gain = rng.uniform(0.9, 1.1, size=4)
    noise_tau = 0.5
    fdm = new_fdm(root, cfg.model)
    _trim(fdm, cfg, plan.flap_deg, entry, plan.seed)
    if turbulence > 0:
        fdm["atmosphere/turb-type"] = 3
        fdm["atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"] = 15.0 / FT * 0.514
        fdm["atmosphere/turbulence/milspec/severity"] = float(turbulence)
    # the trim's pitch trim moves into the elevator command (full travel for the pilot)
    e0 = fdm["fcs/pitch-trim-cmd-norm"] + fdm["fcs/elevator-cmd-norm"]
    fdm["fcs/pitch-trim-cmd-norm"] = 0.0
    a0, r0 = fdm["fcs/aileron-cmd-norm"], fdm["fcs/rudder-cmd-norm"]
    thr0 = [fdm[f"fcs/throttle-cmd-norm[{i}]"] for i in range(_n_engines(fdm))]
    alpha_trim = fdm["aero/alpha-deg"]
    v0 = fdm["velocities/vc-kts"]
    thr_factor = rng.uniform(0.4, 0.9)
    alpha_cmd = alpha_trim
    # integrators, in the pilot's units (+ nose down, + right wing down, + nose right),
    # starting at the trim's commands
    ie, ia, ir = signs["de"] * e0, -signs["da"] * a0, -signs["dr"] * r0
    na = nr = 0.0  # stick noise (AR(1))
    phase, t_phase = "entry", 0.0
    t_stall = math.nan
    rec: dict[str, list[float]] = {p: [] for p in props}
    max_alpha = -1e9
    max_bank = 0.0
    held: list[float] = []  # |beta| while the sideslip command is held (decel and stall)
    rudder_use: list[float] = []  # |rudder command| (share of full travel) over those samples
    step = 0
    phi_cmd = 0.0
    ks = math.exp(-DT / noise_tau)
    while True:
        t = step * DT
        if step % _DECIM == 0:
            for p in props:
                rec[p].append(fdm[p])
        alpha = fdm["aero/alpha-deg"]
        beta = fdm["aero/beta-deg"]
        phi = fdm["attitude/phi-deg"]
        p_dps = fdm["velocities/p-rad_sec"] * R2D
        q_dps = fdm["velocities/q-rad_sec"] * R2D
        r_dps = fdm["velocities/r-rad_sec"] * R2D
        vc = fdm["velocities/vc-kts"]
        max_alpha = max(max_alpha, alpha)
        max_bank = max(max_bank, abs(phi))
        # ---- phases
        if phase == "entry":
            phi_cmd = bank * min(1.0, t / 3.0)
            if t >= 4.0:
                phase, t_phase = "decel", t
        elif phase == "decel":
            v_sched = v0 - decel * (t - t_phase)
            alpha_cmd += max(cfg.k_v * (vc - v_sched), 0.2) * DT
            if alpha_cmd >= peak:
                alpha_cmd = peak
                phase, t_phase, t_stall = "stall", t, t
        elif phase == "stall":
            if t - t_phase >= hold:
                phase, t_phase = "recovery", t
        elif phase == "recovery":
            alpha_cmd = alpha_trim
            phi_cmd = 0.0
            if t - t_phase >= 5.0 and alpha < alpha_trim + 5.0:
                break
        if phase != "recovery" and (
            alpha > cfg.abort_alpha_deg or abs(phi) > 75.0 or abs(beta) > 25.0
        ):
            phase, t_phase = "recovery", t
        if t > 240.0:
            break
        # ---- pilot: pitch (alpha), roll (bank), yaw (sideslip)
        ea = alpha - alpha_cmd
        ie += cfg.k_alpha_i * gain[0] * ea * DT
        ie = float(np.clip(ie, -1.0, 1.0))
        u_pitch = ie + cfg.k_alpha * gain[0] * ea + cfg.k_q * q_dps  # + = nose down
        ia += cfg.k_phi_i * (phi_cmd - phi) * DT
        ia = float(np.clip(ia, -0.5, 0.5))
        u_roll = cfg.k_phi * gain[1] * (phi_cmd - phi) - cfg.k_p * p_dps  # + = right wing down
        b_cmd = beta_cmd if phase in ("decel", "stall") or phase == "entry" else 0.0
        if phase == "entry":
            b_cmd = beta_cmd * min(1.0, t / 3.0)
        eb = beta - b_cmd
        ir += cfg.k_beta_i * gain[2] * eb * DT
        ir = float(np.clip(ir, -0.5, 0.5))
        u_yaw = ir + cfg.k_beta * gain[2] * eb - cfg.k_r * r_dps  # + = nose right
        na = ks * na + math.sqrt(1 - ks * ks) * 0.03 * rng.standard_normal()
        nr = ks * nr + math.sqrt(1 - ks * ks) * 0.03 * rng.standard_normal()
        u_roll += na
        u_yaw += nr
        if phase == "stall":
            u_roll += _doublet(t, t_stall + 0.5, half_a, amp_a * side)
            u_yaw += _doublet(t, t_stall + 0.7 + 2 * half_a, half_r, amp_r * side)
            u_roll += _doublet(t, t_stall + 1.2 + 2 * half_a + 2 * half_r, half_a, -amp_a * side)
        fdm["fcs/elevator-cmd-norm"] = float(np.clip(signs["de"] * u_pitch, -1, 1))
        fdm["fcs/aileron-cmd-norm"] = float(np.clip(-signs["da"] * (ia + u_roll), -1, 1))
        fdm["fcs/rudder-cmd-norm"] = float(np.clip(-signs["dr"] * u_yaw, -1, 1))
        if beta_cmd != 0.0 and phase in ("decel", "stall"):
            held.append(abs(beta))
            rudder_use.append(min(abs(u_yaw), 1.0))
        for i, th in enumerate(thr0):
            fdm[f"fcs/throttle-cmd-norm[{i}]"] = 1.0 if phase == "recovery" else th * thr_factor
        fdm.run()
        step += 1
    meta = {
        "side": side,
        "entry_kts": entry,
        "decel_kts_per_s": decel,
        "alpha_peak_cmd_deg": peak,
        "max_alpha_deg": max_alpha,
        "max_bank_deg": max_bank,
        "t_stall_s": t_stall,
        "aileron_trim_cmd": a0,
        "rudder_trim_cmd": r0,
        "n_engines": len(thr0),
        "beta_cmd_deg": abs(beta_cmd),
        "beta_held_deg": float(np.median(held)) if held else math.nan,
        "rudder_use": float(np.median(rudder_use)) if rudder_use else math.nan,
    }
    return {p: np.asarray(v, dtype=float) for p, v in rec.items()}, meta


#: A sideslip entry whose median |beta| while the command is held is below this share of the
#: command gets a note in the manifest (the aircraft could not be sideslipped that far).
SIDESLIP_SHORT = 0.5
#: How that note begins (``aerodelta campaign`` counts the notes that do).
SIDESLIP_NOTE = "sideslip entry held"


def _sideslip_note(meta: Mapping[str, Any]) -> str:
    """The manifest note of a sideslip entry that held less than :data:`SIDESLIP_SHORT` of its
    commanded sideslip (medians over the entry's deceleration and stall, while the command is
    held), with the rudder command's median share of its travel. The rudder's authority
    against the directional stability bounds the sideslip (at full rudder beta is about
    -Cn_dr dr_max / Cn_beta): the JSBSim DHC-6, Cn_beta 1.0-2.5 per rad at flap 20 and 2.4-3.2
    at flap 40 (alpha 0-15 deg) against Cn_dr -0.125 per rad and 16 deg of rudder, holds about
    1 deg. Such an entry
    excites beta less than its name says. Empty otherwise."""
    cmd, got, use = meta["beta_cmd_deg"], meta["beta_held_deg"], meta["rudder_use"]
    if cmd <= 0.0 or not math.isfinite(got) or got >= SIDESLIP_SHORT * cmd:
        return ""
    return (
        f"{SIDESLIP_NOTE} {got:.1f} deg of sideslip against {cmd:.1f} deg commanded, "
        f"the rudder at {100 * use:.0f} % of its travel (medians while the command is held): "
        "this maneuver excites sideslip less than its name says"
    )


def _n_engines(fdm: Any) -> int:
    n = 0
    while True:
        try:
            fdm[f"propulsion/engine[{n}]/thrust-lbs"]
        except KeyError:
            return n
        n += 1
        if n > 16:
            return n


def _engine_sides(xml: Path, n: int) -> list[float]:
    """Per engine: 1 left, 0 right, 0.5 on the centreline (from the XML's y positions)."""
    doc = ET.parse(xml).getroot()
    ys = []
    for eng in doc.findall("propulsion/engine"):
        loc = eng.find("thruster/location")
        if loc is None:
            loc = eng.find("location")
        y = float((loc.findtext("y") or "0").strip()) if loc is not None else 0.0
        ys.append(y)
    ys = (ys + [0.0] * n)[:n]
    return [1.0 if y < 0 else 0.0 if y > 0 else 0.5 for y in ys]


# --------------------------------------------------------------------------------------------
# Turning the recorded properties into the campaign's records and truth


def _coefficients(
    rec: Mapping[str, np.ndarray],
    terms: Sequence[Term],
    withheld: Sequence[Term],
    walpha: float,
    r_body: np.ndarray,
    *,
    withhold_scale: float = 1.0,
) -> tuple[dict[str, np.ndarray], list[str]]:
    """Truth columns of one maneuver: JSBSim's aero and propulsion coefficients about the CG,
    each lateral term (nondimensional), the qualified model and the true Δ
    (``withhold_scale`` times the withheld terms' change when frozen)."""
    qs = rec["aero/qbar-psf"] * rec["metrics/Sw-sqft"]
    qsb = qs * rec["metrics/bw-ft"]
    out: dict[str, np.ndarray] = {
        "Cl_true": rec["moments/l-aero-lbsft"] / qsb,
        "Cn_true": rec["moments/n-aero-lbsft"] / qsb,
        "CY_true": rec["forces/fby-aero-lbs"] / qs,
        "Cl_prop_true": rec["moments/l-prop-lbsft"] / qsb,
        "Cn_prop_true": rec["moments/n-prop-lbsft"] / qsb,
        "CY_prop_true": rec["forces/fby-prop-lbs"] / qs,
    }
    problems = []
    # frozen above the withhold alpha; below it the inputs are JSBSim's own, bit for bit
    above = rec["aero/alpha-deg"] > walpha
    frozen = {
        "aero/alpha-deg": np.where(above, walpha, rec["aero/alpha-deg"]),
        "aero/alpha-rad": np.where(above, walpha * D2R, rec.get("aero/alpha-rad", 0.0)),
    }

    def env_full(p: str) -> np.ndarray:
        return rec[p]

    def env_frozen(p: str) -> np.ndarray:
        return frozen[p] if p in frozen else rec[p]

    d = {"Cl": np.zeros_like(qs), "Cn": np.zeros_like(qs), "CY": np.zeros_like(qs)}
    wnames = {t.name for t in withheld}
    for t in terms:
        if t.axis not in ("ROLL", "YAW", "SIDE"):
            continue
        val = rec[t.prop]
        nd = _nondim(t, rec)
        out[f"term_{t.name}"] = val * nd
        if t.tree is None:
            continue
        full = np.broadcast_to(_eval(t.tree, env_full), val.shape)
        scale = max(float(np.max(np.abs(val))), 1e-9)
        if float(np.max(np.abs(full - val))) > 1e-7 * scale:
            problems.append(t.name)
            continue
        if t.name not in wnames:
            continue
        # full - qualified, both from the XML (bit-identical below the withhold alpha)
        dv = withhold_scale * (full - np.broadcast_to(_eval(t.tree, env_frozen), val.shape))
        if t.axis == "SIDE":
            # wind-axis side force -> body force; its moment about the CG through r x F
            a = rec["aero/alpha-deg"] * D2R
            b = rec["aero/beta-deg"] * D2R
            fx = -np.cos(a) * np.sin(b) * dv
            fy = np.cos(b) * dv
            fz = -np.sin(a) * np.sin(b) * dv
            dl = r_body[1] * fz - r_body[2] * fy
            dn = r_body[0] * fy - r_body[1] * fx
            d["CY"] += fy / qs
            d["Cl"] += dl / qsb
            d["Cn"] += dn / qsb
            out[f"dterm_{t.name}"] = fy / qs
        else:
            c = t.coefficient or ""
            d[c] += dv * nd
            out[f"dterm_{t.name}"] = dv * nd
    for c in ("Cl", "Cn", "CY"):
        out[f"d{c}_true"] = d[c]
        # the simulator's total: aero + propulsion (the inertial measurement holds both), so
        # the measured minus the qualified coefficient is the withheld aero Δ alone
        out[f"{c}_sim"] = out[f"{c}_true"] + out[f"{c}_prop_true"] - d[c]
    return out, problems


def _record_frame(  # noqa: PLR0917
    rec: Mapping[str, np.ndarray],
    cfg: JsbsimAircraft,
    signs: Mapping[str, float],
    engine_left: Sequence[float],
    truth: Mapping[str, np.ndarray],
    flap_deg: float,
) -> dict[str, np.ndarray]:
    n = len(rec["simulation/sim-time-sec"])
    m = rec["inertia/mass-slugs"]
    qs = rec["aero/qbar-psf"] * rec["metrics/Sw-sqft"]
    thrust = [rec[f"propulsion/engine[{i}]/thrust-lbs"] for i in range(len(engine_left))]
    ct_l = sum((w * th for w, th in zip(engine_left, thrust, strict=True)), np.zeros(n)) / qs
    ct_r = (
        sum(((1.0 - w) * th for w, th in zip(engine_left, thrust, strict=True)), np.zeros(n)) / qs
    )
    t = rec["simulation/sim-time-sec"]
    return {
        "t": t - t[0],
        "alpha_deg": rec["aero/alpha-deg"],
        "beta_deg": rec["aero/beta-deg"],
        "p_dps": rec["velocities/p-rad_sec"] * R2D,
        "q_dps": rec["velocities/q-rad_sec"] * R2D,
        "r_dps": rec["velocities/r-rad_sec"] * R2D,
        "phi_deg": rec["attitude/phi-rad"] * R2D,
        "theta_deg": rec["attitude/theta-rad"] * R2D,
        "psi_deg": np.unwrap(rec["attitude/psi-rad"]) * R2D,
        "ax_mps2": rec["forces/fbx-total-lbs"] / m * FT,
        "ay_mps2": rec["forces/fby-total-lbs"] / m * FT,
        "az_mps2": rec["forces/fbz-total-lbs"] / m * FT,
        "tas_mps": rec["velocities/vt-fps"] * FT,
        "rho_kgm3": rec["atmosphere/rho-slugs_ft3"] * SLUGFT3,
        "h_m": rec["position/h-sl-ft"] * FT,
        "da_deg": signs["da"] * rec[cfg.aileron_rad] * R2D,
        "de_deg": signs["de"] * rec[cfg.elevator_rad] * R2D,
        "dr_deg": signs["dr"] * rec[cfg.rudder_rad] * R2D,
        "flap_deg": rec[cfg.flap_deg_prop] if cfg.flap_norm_per_deg else np.full(n, flap_deg),
        "ct_left": ct_l,
        "ct_right": ct_r,
        "Cl_sim": truth["Cl_sim"],
        "Cn_sim": truth["Cn_sim"],
        "CY_sim": truth["CY_sim"],
    }


def _aircraft_toml(cfg: JsbsimAircraft, fdm: Any, n_engines: int) -> str:
    ixz_elem = fdm["inertia/ixz-slugs_ft2"]
    return "\n".join(
        [
            f'name = "JSBSim {cfg.model} (jsbsim {_jsbsim_version()}): {cfg.description}"',
            f"# {cfg.notes}" if cfg.notes else "#",
            "# Inertias at the campaign's (frozen) fuel state. JSBSim's inertia/ixz-slugs_ft2 is",
            f"# the inertia-matrix element J13 = -Ixz ({ixz_elem:.6g} slug ft2); Ixz here is the",
            "# product of inertia of Etkin's equations, L = Ixx pdot - Ixz (rdot + pq) + ...",
            "[geometry]",
            f"S_m2 = {fdm['metrics/Sw-sqft'] * FT**2!r}",
            f"b_m = {fdm['metrics/bw-ft'] * FT!r}",
            f"cbar_m = {fdm['metrics/cbarw-ft'] * FT!r}",
            "[mass]",
            f"mass_kg = {fdm['inertia/mass-slugs'] * SLUG!r}",
            f"Ixx_kgm2 = {fdm['inertia/ixx-slugs_ft2'] * SLUGFT2!r}",
            f"Iyy_kgm2 = {fdm['inertia/iyy-slugs_ft2'] * SLUGFT2!r}",
            f"Izz_kgm2 = {fdm['inertia/izz-slugs_ft2'] * SLUGFT2!r}",
            f"Ixz_kgm2 = {-ixz_elem * SLUGFT2!r}",
            "# inertia/ixy- and iyz-slugs_ft2 are the products themselves (element -Ixy, -Iyz)",
            f"Ixy_kgm2 = {fdm['inertia/ixy-slugs_ft2'] * SLUGFT2 + 0.0!r}",
            f"Iyz_kgm2 = {fdm['inertia/iyz-slugs_ft2'] * SLUGFT2 + 0.0!r}",
            "[propulsion]",
            f"n_engines = {n_engines}",
            "prop_inertia_kgm2 = 0.0  # JSBSim's propulsion moments are truth, not modelled",
            'prop_rotation = "ccw"  # inert: prop_inertia_kgm2 = 0',
            "[sensors]  # JSBSim's alpha, beta and specific force are at the CG",
            "accel_m = [0.0, 0.0, 0.0]",
            "alpha_vane_m = [0.0, 0.0, 0.0]",
            "beta_vane_m = [0.0, 0.0, 0.0]",
            "",
        ]
    )


def _jsbsim_version() -> str:
    try:
        return importlib.metadata.version("jsbsim")
    except importlib.metadata.PackageNotFoundError:  # pragma: no cover
        return "unknown"


def _write_parquet(df: pl.DataFrame, path: Path) -> None:
    df.write_parquet(path, compression="zstd", statistics=False)


def _select_withheld(
    terms: Sequence[Term], withhold: str | Sequence[str] | None, cfg: JsbsimAircraft
) -> list[Term]:
    if withhold is None or withhold == "default":
        names = list(cfg.withhold)
    elif isinstance(withhold, str):
        names = [w.strip() for w in withhold.split(",") if w.strip() and w.strip() != "none"]
    else:
        names = [str(w) for w in withhold]
    by = {t.name: t for t in terms if t.axis in ("ROLL", "YAW", "SIDE")}
    out = []
    for n in names:
        t = by.get(n)
        if t is None:
            raise InvalidInputError(
                f"unknown withheld term '{n}' for JSBSim {cfg.model}; its lateral terms: "
                f"{', '.join(by)}"
            )
        if not t.alpha_dependent:
            ok = ", ".join(k for k, v in by.items() if v.alpha_dependent)
            raise InvalidInputError(
                f"withheld term '{n}' of JSBSim {cfg.model} does not depend on alpha (or is "
                f"not a product/sum of properties and tables); choose from: {ok}"
            )
        out.append(t)
    return out


def generate_jsbsim_campaign(
    out_dir: str | os.PathLike[str],
    *,
    aircraft: str | JsbsimAircraft = "f15",
    seed: int = 0,
    size: str | int = "default",
    withhold: str | Sequence[str] | None = "default",
    withhold_alpha_deg: float | None = None,
    withhold_scale: float = 1.0,
    noise: float = 1.0,
    turbulence: float = 0.0,
    decel_kts_per_s: float = 1.0,
    only: Sequence[int] = (),
    root_dir: str | os.PathLike[str] | None = None,
    overwrite: bool = False,
    progress: bool = False,
) -> JsbsimCampaignInfo:
    """Fly a JSBSim aircraft through the thesis's stall maneuvers and write the campaign.

    Parameters
    ----------
    out_dir
        Campaign folder to create (written into a temporary sibling, then renamed).
    aircraft
        A key of :data:`AIRCRAFT` (``"f15"``, ``"DHC6"``) or a :class:`JsbsimAircraft` for
        another model.
    seed
        Campaign seed; the same seed gives byte-identical files.
    size
        ``"default"`` (6 repetitions of each flap x kind), ``"quick"`` (1) or a count.
    withhold
        Lateral terms whose alpha dependence the qualified model freezes: ``"default"`` (the
        aircraft's), ``"none"``, a comma list or a sequence of term names (``lateral_terms``).
    withhold_alpha_deg
        Alpha above which the withheld terms are frozen (default: the aircraft's, 15 deg for
        the F-15).
    withhold_scale
        Fraction ``k`` of the withheld terms' change that the qualified model lacks:
        qualified = full − k·(full − frozen), true Δ = k·(full − frozen); 1 (default) withholds
        the whole change, 0.5 and 0.25 half and a quarter of it. Finite and >= 0.
    noise
        Sensor noise scale (0 = exact sensors).
    turbulence
        0 (calm) or JSBSim's MIL-spec Dryden severity (1 light, 3 moderate, 4 severe);
        JSBSim's turbulence generator is seeded from the maneuver seed.
    decel_kts_per_s
        The entry's deceleration schedule (thesis: about 1 kt/s).
    only
        Fly only these maneuver indices (:func:`jsbsim_campaign_plan` lists them; empty: all).
    root_dir
        JSBSim root (``aircraft/``, ``engine/``, ``systems/``); default: the package's.
    overwrite
        Replace an existing folder.
    progress
        Print one line per maneuver on stderr.

    Raises
    ------
    InvalidInputError
        Unknown aircraft or withheld term, jsbsim missing.
    NoConvergenceError
        JSBSim cannot trim the aircraft at the entry condition.
    DataError
        ``out_dir`` exists (without ``overwrite``); the XML evaluation disagrees with JSBSim.
    """
    out = Path(out_dir)
    if out.exists() and not overwrite:
        raise DataError(f"{out}: already exists; choose another folder or pass overwrite=True")
    jsbsim = _jsbsim()
    del jsbsim
    root = _root(root_dir)
    cfg, xml = _resolve_aircraft(aircraft, root)
    walpha = cfg.withhold_alpha_deg if withhold_alpha_deg is None else float(withhold_alpha_deg)
    if not math.isfinite(walpha):
        raise InvalidInputError("withhold_alpha_deg must be finite")
    k_scale = float(withhold_scale)
    if not math.isfinite(k_scale) or k_scale < 0:
        raise InvalidInputError(
            f"withhold_scale {withhold_scale!r}: give a finite fraction >= 0 (1 = the whole "
            "withheld change, 0.5 = half of it)"
        )
    reps = SIZES.get(size, 0) if isinstance(size, str) else int(size)
    if reps <= 0:
        raise InvalidInputError(f"size '{size}': use 'default', 'quick' or a positive integer")
    if noise < 0 or turbulence < 0:
        raise InvalidInputError("noise and turbulence must be >= 0")
    terms = _aero_terms(xml, root)
    withheld = _select_withheld(terms, withhold, cfg)
    signs = control_signs(cfg, terms)
    plans = _plan(cfg, int(seed), reps)
    if only:
        plans = [p for p in plans if p.index in set(only)]
    # properties recorded: channels, truth, every input of the lateral terms
    fdm0 = new_fdm(root, cfg.model)
    _trim(fdm0, cfg, cfg.flaps_deg[0], _entry_kts(cfg, cfg.flaps_deg[0]), int(seed))
    n_eng = _n_engines(fdm0)
    lat = [t for t in terms if t.axis in ("ROLL", "YAW", "SIDE")]
    props = list(_REC_PROPS)
    extra = [cfg.aileron_rad, cfg.elevator_rad, cfg.rudder_rad, cfg.flap_deg_prop]
    extra += [f"propulsion/engine[{i}]/thrust-lbs" for i in range(n_eng)]
    extra += [t.prop for t in lat]
    for t in lat:
        if t.tree is not None:
            extra += sorted(_props(t.tree))
    for p in extra:
        if p not in props:
            props.append(p)
    rp = np.array([fdm0[f"metrics/aero-rp-{a}-in"] for a in "xyz"])
    cg = np.array([fdm0[f"inertia/cg-{a}-in"] for a in "xyz"])
    r_body = (rp - cg) * np.array([-1.0, 1.0, -1.0]) / 12.0  # structural -> body, ft
    toml = _aircraft_toml(cfg, fdm0, n_eng)
    sides = _engine_sides(xml, n_eng)
    del fdm0

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.tmp-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    (tmp / "records").mkdir(parents=True)
    (tmp / "truth").mkdir()
    rows: list[dict[str, Any]] = []
    deltas: list[pl.DataFrame] = []
    unevaluated: set[str] = set()
    try:
        from aerodelta.campaign import _departure_row  # noqa: PLC0415

        for p in plans:
            rec, meta = _fly(cfg, root, p, signs, props, decel_kts_per_s, turbulence)
            tru, problems = _coefficients(
                rec, terms, withheld, walpha, r_body, withhold_scale=k_scale
            )
            bad = sorted(set(problems) & {t.name for t in withheld})
            if bad:
                raise DataError(
                    f"JSBSim {cfg.model}: the XML evaluation of {', '.join(bad)} disagrees "
                    "with JSBSim's own aero/coefficient values; these terms cannot be withheld"
                )
            unevaluated.update(problems)
            chans = _record_frame(rec, cfg, signs, sides, tru, p.flap_deg)
            clean = pl.DataFrame(chans)
            noisy = _add_noise(chans, noise, p.seed)
            mid = f"{cfg.model}_{p.index:03d}"
            truth_cols = {
                "t": chans["t"],
                "alpha_deg": chans["alpha_deg"],
                "beta_deg": chans["beta_deg"],
                "phat": rec["velocities/p-aero-rad_sec"] * rec["aero/bi2vel"],
                "rhat": rec["velocities/r-aero-rad_sec"] * rec["aero/bi2vel"],
                **tru,
            }
            recdf = pl.DataFrame(noisy)
            trudf = pl.DataFrame(truth_cols)
            cut = _departure_row(clean)
            departed = None
            if cut is not None:
                departed = float(clean["t"][cut])
                recdf, trudf = recdf.head(cut), trudf.head(cut)
            _write_parquet(recdf, tmp / "records" / f"{mid}.parquet")
            _write_parquet(trudf, tmp / "truth" / f"{mid}.parquet")
            dcols = ["t", "alpha_deg", "dCl_true", "dCn_true", "dCY_true"]
            dcols += sorted(c for c in trudf.columns if c.startswith("dterm_"))
            deltas.append(
                trudf.select(dcols).with_columns(
                    pl.lit(mid).alias("maneuver_id"), pl.lit(p.flap_deg).alias("flap_deg")
                )
            )
            rows.append(
                {
                    "maneuver_id": mid,
                    "flap_deg": p.flap_deg,
                    "kind": "other" if p.kind == "sideslip" else p.kind,
                    "pusher": False,
                    "file": f"records/{mid}.parquet",
                    "entry": p.kind,
                    "seed": p.seed,
                    "simulator": f"jsbsim {_jsbsim_version()}",
                    "aircraft": cfg.model,
                    "max_alpha_deg": round(float(meta["max_alpha_deg"]), 6),
                    "max_bank_deg": round(float(meta["max_bank_deg"]), 6),
                    "t_stall_s": round(float(meta["t_stall_s"]), 6),
                    "departed_at_s": departed,
                    "notes": "; ".join(n for n in (cfg.notes, _sideslip_note(meta)) if n),
                }
            )
            if progress:
                print(
                    f"[jsbsim] {mid}: {p.kind}, flap {p.flap_deg:g}, max alpha "
                    f"{meta['max_alpha_deg']:.1f} deg, {recdf.height} samples",
                    file=sys.stderr,
                )
        manifest = pl.DataFrame(rows, infer_schema_length=None)
        manifest.write_csv(tmp / "manifest.csv")
        (tmp / "aircraft.toml").write_text(toml)
        if deltas:
            _write_parquet(
                pl.concat(deltas, how="diagonal_relaxed").select(
                    "maneuver_id", "flap_deg", pl.exclude("maneuver_id", "flap_deg")
                ),
                tmp / "truth" / "true_delta.parquet",
            )
        info = _truth_json(
            cfg, withheld, walpha, signs, seed, noise, turbulence, sorted(unevaluated), k_scale
        )
        (tmp / "truth" / "truth.json").write_text(json.dumps(info, indent=1, sort_keys=True))
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    replace_dir(tmp, out)
    return JsbsimCampaignInfo(
        path=out,
        n_maneuvers=len(rows),
        seed=int(seed),
        aircraft=cfg.model,
        withheld=tuple(t.name for t in withheld),
        withhold_alpha_deg=walpha,
        manifest=manifest,
        withhold_scale=k_scale,
    )


def _add_noise(chans: Mapping[str, np.ndarray], scale: float, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng([seed, 0x5E45])
    out = {}
    for k, v in chans.items():
        sd = NOISE.get(k, 0.0) * scale
        out[k] = v + sd * rng.standard_normal(v.shape) if sd > 0 else v.copy()
    return out


def _truth_json(  # noqa: PLR0917
    cfg: JsbsimAircraft,
    withheld: Sequence[Term],
    walpha: float,
    signs: Mapping[str, float],
    seed: int,
    noise: float,
    turbulence: float,
    unevaluated: Sequence[str],
    withhold_scale: float = 1.0,
) -> dict[str, Any]:
    grid = np.round(np.arange(-5.0, 60.0 + 1e-9, 0.5), 6)
    wt = []
    for t in withheld:
        per_flap = {
            f"{f:g}": _term_derivatives(t, cfg, signs, grid, f, walpha, withhold_scale)
            for f in cfg.flaps_deg
        }
        wt.append(
            {
                "name": t.name,
                "property": t.prop,
                "axis": t.axis,
                "coefficient": t.coefficient,
                "inputs": sorted(_props(t.tree)) if t.tree is not None else [],
                "derivatives": per_flap,
            }
        )
    cfg_d = {k: (list(v) if isinstance(v, tuple) else v) for k, v in cfg.__dict__.items()}
    return {
        "simulator": "jsbsim",
        "jsbsim_version": _jsbsim_version(),
        "aircraft": cfg.model,
        "config": cfg_d,
        "seed": int(seed),
        "noise_scale": float(noise),
        "turbulence": float(turbulence),
        "withhold_alpha_deg": walpha,
        "withhold_scale": float(withhold_scale),
        "alpha_grid_deg": grid.tolist(),
        "withheld": wt,
        "control_signs": dict(signs),
        "terms_not_evaluated": list(unevaluated),
        "units": {
            "beta_deg": "per deg of sideslip",
            "phat": "per unit of p b/2V (JSBSim's p relative to the air)",
            "rhat": "per unit of r b/2V",
            "da_deg": "per deg of aerodelta's aileron (positive rolls left)",
            "dr_deg": "per deg of aerodelta's rudder (positive yaws left)",
        },
        "notes": [
            "Cl_true, Cn_true, CY_true: JSBSim's aero moments/force about the CG (body axes) "
            "over qbar S b (qbar S); term_* are each aero/coefficient/* value nondimensional "
            "(moments about the aero reference point, SIDE in wind axes).",
            "dC*_true = full - qualified: withhold_scale times the withheld terms' change "
            "when their alpha dependence is frozen at withhold_alpha_deg above it; "
            "C*_sim = C*_true + C*_prop_true - dC*_true (the simulator's total, as measured).",
            "derivatives: d(term)/d(regressor) at regressor 0 vs alpha_grid_deg, full, "
            "qualified and delta; tables nonlinear in beta give the slope at beta = 0.",
            "C*_prop_true: propulsion moments (not aero); the inertial measurement includes them.",
            cfg.notes,
        ],
    }


def true_delta_derivative(
    campaign_dir: str | os.PathLike[str],
    coefficient: str,
    regressor: str,
    flap_deg: float,
    alpha_deg: np.ndarray | Sequence[float] | float,
) -> np.ndarray:
    """True Δ derivative (full − qualified) of ``coefficient`` w.r.t. a fit regressor
    (``beta_deg``, ``phat``, ``rhat``, ``da_deg``, ``dr_deg``) vs alpha, summed over the
    withheld terms of a JSBSim campaign (``truth/truth.json``); zero where none applies.
    The nearest flap setting's curve is used."""
    p = Path(campaign_dir) / "truth" / "truth.json"
    try:
        doc = json.loads(p.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise DataError(f"{p}: cannot read the JSBSim campaign truth: {e}") from e
    grid = np.asarray(doc["alpha_grid_deg"], dtype=float)
    a = np.asarray(alpha_deg, dtype=float)
    out = np.zeros_like(a)
    for t in doc["withheld"]:
        if t["coefficient"] != coefficient:
            continue
        flaps = list(t["derivatives"])
        f = min(flaps, key=lambda k: abs(float(k) - flap_deg))
        d = t["derivatives"][f].get(regressor)
        if d is not None:
            out = out + np.interp(a, grid, np.asarray(d["delta"], dtype=float))
    return out


def with_overrides(cfg: JsbsimAircraft, **kw: Any) -> JsbsimAircraft:
    """A copy of an aircraft configuration with some fields changed."""
    return replace(cfg, **kw)
