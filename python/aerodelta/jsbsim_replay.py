"""Closed-loop check of an exported Δ: fly JSBSim with it through held-out maneuvers (issue 19).

A JSBSim campaign (:mod:`aerodelta.jsbsim_campaign`) records maneuvers flown on a JSBSim
aircraft (the *full* aircraft, the truth) and defines a *qualified* model: the withheld lateral
terms re-evaluated with alpha replaced by ``min(alpha, withhold_alpha)``. This module

1. writes that qualified model as a JSBSim aircraft (:func:`write_replay_aircraft`,
   ``variant="qualified"``): a copy of the aircraft folder under a new JSBSim root whose withheld
   ``aero/coefficient/*`` functions read ``aero/aerodelta/alpha-frozen-deg`` (``-rad``) =
   ``min(alpha, withhold_alpha)`` instead of alpha (``withhold_scale`` k: the function is
   ``(1 - k) full + k frozen``, the campaign's ``full - k (full - frozen)``);
2. adds the Δ exported by :func:`aerodelta.jsbsim.export_jsbsim` to it (``variant="extended"``),
   its channels mapped onto the aircraft's own properties (:func:`replay_properties`: surfaces
   with the campaign's control signs, Etkin; thrust coefficients from engine thrust over q̄S);
3. replays recorded maneuvers open loop (:func:`replay_maneuver`): JSBSim is trimmed at the
   record's initial airspeed and altitude as the campaign trims, then the recorded surface
   positions drive the surfaces (an FCS channel appended to every replay aircraft overrides the
   surface positions while ``aerodelta/replay/active`` is 1); the campaign records no throttle,
   so the campaign pilot's schedule (one setting, then full throttle at the recovery) is fitted
   to the recorded thrust (``ct_left``, ``ct_right`` times the record's q̄S);
4. scores the replays against the records (:func:`replay_campaign`): Theil inequality
   coefficient (``aerodelta.fit.theil_inequality``) on p, r, φ and β per maneuver and pooled.

Every replay aircraft also carries the replay channel; with ``aerodelta/replay/active`` = 0
(the default) its FCS is the aircraft's own. Units: SI and degrees in the returned frames, as the
campaign's records.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from aerodelta import jsbsim_campaign as jc
from aerodelta.exceptions import DataError, InvalidInputError
from aerodelta.fit import theil_inequality
from aerodelta.jsbsim import export_jsbsim
from aerodelta.model import DeltaModel

__all__ = [
    "CHANNELS",
    "DIVERGED",
    "SMOOTHED",
    "STATE_CHANNELS",
    "VARIANTS",
    "CampaignSetup",
    "aero_along",
    "aero_at_states",
    "load_setup",
    "predictable_until",
    "propellers",
    "read_record",
    "replay_campaign",
    "replay_maneuver",
    "replay_properties",
    "score_window",
    "write_replay_aircraft",
]

#: Aircraft variants a replay flies: the campaign's own (truth), its qualified model, and the
#: qualified model plus the exported Δ.
VARIANTS = ("full", "qualified", "extended")
#: Channels scored (record column names): roll rate, yaw rate (deg/s), bank, sideslip (deg).
CHANNELS = ("p_dps", "r_dps", "phi_deg", "beta_deg")

_ACTIVE = "aerodelta/replay/active"
_SURF = {"da": "aerodelta/replay/da-rad", "de": "aerodelta/replay/de-rad",
         "dr": "aerodelta/replay/dr-rad"}  # fmt: skip
_ALPHA_FROZEN = "aero/aerodelta/alpha-frozen"
_CT = {"ct_left": "aero/aerodelta/thrust/ct-left", "ct_right": "aero/aerodelta/thrust/ct-right"}

#: JSBSim properties recorded by a replay (50 Hz), with the record column they become.
_REPLAY_PROPS = {
    "aero/alpha-deg": "alpha_deg",
    "aero/beta-deg": "beta_deg",
    "velocities/p-rad_sec": "p_dps",
    "velocities/q-rad_sec": "q_dps",
    "velocities/r-rad_sec": "r_dps",
    "attitude/phi-rad": "phi_deg",
    "attitude/theta-rad": "theta_deg",
    "attitude/psi-rad": "psi_deg",
    "velocities/vt-fps": "tas_mps",
    "position/h-sl-ft": "h_m",
    "aero/qbar-psf": "qbar_psf",
    "moments/l-aero-lbsft": "l_aero_lbsft",
    "moments/n-aero-lbsft": "n_aero_lbsft",
    "forces/fby-aero-lbs": "fy_aero_lbs",
    "velocities/p-aero-rad_sec": "p_aero_rad_sec",
    "velocities/r-aero-rad_sec": "r_aero_rad_sec",
    "aero/bi2vel": "bi2vel",
    "metrics/Sw-sqft": "S_sqft",
    "metrics/bw-ft": "b_ft",
}


@dataclass(frozen=True)
class CampaignSetup:
    """A JSBSim campaign's aircraft and qualified-model definition (``truth/truth.json``).

    Attributes
    ----------
    path
        Campaign folder.
    cfg
        The aircraft configuration the campaign flew.
    jsbsim_root
        JSBSim root holding the original aircraft (``aircraft/<model>/``, ``engine/``,
        ``systems/``).
    withheld
        Withheld term names (``aero/coefficient/<name>``).
    withhold_alpha_deg
        Alpha (deg) above which the withheld terms are frozen.
    withhold_scale
        Fraction of the frozen change withheld (qualified = full − k (full − frozen)).
    signs
        Control signs: ``da_deg = signs["da"] * deg(aileron position)``, likewise de, dr.
    turbulence
        The campaign's Dryden severity (0 calm).
    manifest
        ``manifest.csv``.
    """

    path: Path
    cfg: jc.JsbsimAircraft
    jsbsim_root: Path
    withheld: tuple[str, ...]
    withhold_alpha_deg: float
    withhold_scale: float
    signs: dict[str, float]
    turbulence: float
    manifest: pl.DataFrame


def _tuples(v: Any) -> Any:
    return tuple(_tuples(x) for x in v) if isinstance(v, list) else v


def load_setup(
    campaign_dir: str | os.PathLike[str], root_dir: str | os.PathLike[str] | None = None
) -> CampaignSetup:
    """Read a JSBSim campaign's truth (aircraft, withheld terms, signs) and manifest.

    ``root_dir``: the JSBSim root the campaign flew (default: the ``jsbsim`` package's).
    Raises ``DataError`` naming the file when the folder is not a JSBSim campaign.
    """
    d = Path(campaign_dir)
    tj = d / "truth" / "truth.json"
    try:
        doc = json.loads(tj.read_text())
    except FileNotFoundError:
        raise DataError(
            f"{tj}: missing; give a folder written by aerodelta campaign --simulator jsbsim"
        ) from None
    except (OSError, json.JSONDecodeError) as e:
        raise DataError(f"{tj}: cannot read the JSBSim campaign truth: {e}") from None
    if doc.get("simulator") != "jsbsim" or "config" not in doc:
        raise DataError(f"{tj}: not a JSBSim campaign's truth (no simulator 'jsbsim', config)")
    known = set(jc.JsbsimAircraft.__dataclass_fields__)
    cfg = jc.JsbsimAircraft(
        **{k: _tuples(v) for k, v in doc["config"].items() if k in known}  # type: ignore[arg-type]
    )
    root = jc._root(root_dir)
    jc._model_xml(cfg.model, root)
    try:
        manifest = pl.read_csv(d / "manifest.csv")
    except (OSError, pl.exceptions.PolarsError) as e:
        raise DataError(f"{d / 'manifest.csv'}: cannot read the manifest: {e}") from None
    return CampaignSetup(
        path=d,
        cfg=cfg,
        jsbsim_root=root,
        withheld=tuple(w["name"] for w in doc["withheld"]),
        withhold_alpha_deg=float(doc["withhold_alpha_deg"]),
        withhold_scale=float(doc.get("withhold_scale", 1.0)),
        signs={k: float(v) for k, v in doc["control_signs"].items()},
        turbulence=float(doc.get("turbulence", 0.0)),
        manifest=manifest,
    )


# --------------------------------------------------------------------------------------------
# Aircraft files


def replay_properties(setup: CampaignSetup) -> dict[str, str]:
    """Δ-model channel -> JSBSim property of the campaign's aircraft, for
    :func:`aerodelta.jsbsim.export_jsbsim`: the surfaces as the campaign records them
    (``da_deg = signs["da"] * left-aileron-pos-rad * 180/π``, Etkin), the thrust coefficients
    as functions this module adds (engine thrust by side over q̄S, as the records' ``ct_*``),
    the roll spoilers 0 (the campaign's aircraft have none)."""
    r2d = repr(180.0 / math.pi)
    cfg, s = setup.cfg, setup.signs
    return {
        "da_deg": f"{s['da']!r} * {cfg.aileron_rad} * {r2d}",
        "de_deg": f"{s['de']!r} * {cfg.elevator_rad} * {r2d}",
        "dr_deg": f"{s['dr']!r} * {cfg.rudder_rad} * {r2d}",
        "flap_deg": cfg.flap_deg_prop if cfg.flap_norm_per_deg else "fcs/flap-pos-deg",
        # no roll spoilers: the records carry none and the ingestion sets ds_deg = 0
        "dsl_deg": "0",
        "dsr_deg": "0",
        **_CT,
    }


def _sub(parent: ET.Element, tag: str, text: str | None = None, **attrib: str) -> ET.Element:
    el = ET.SubElement(parent, tag, attrib)
    if text is not None:
        el.text = text
    return el


def _replay_channel(fcs: ET.Element, cfg: jc.JsbsimAircraft) -> None:
    """Append the channel that sets the surfaces from ``aerodelta/replay/*`` while active."""
    for p in (_ACTIVE, *_SURF.values()):
        _sub(fcs, "property", p, value="0")
    ch = _sub(fcs, "channel", name="aerodelta replay")
    for key, prop in (("da", cfg.aileron_rad), ("de", cfg.elevator_rad), ("dr", cfg.rudder_rad)):
        sw = _sub(ch, "switch", name=f"aerodelta-replay-{key}")
        _sub(sw, "default", value=prop)
        _sub(sw, "test", f"{_ACTIVE} EQ 1", value=_SURF[key])
        _sub(sw, "output", prop)


def _freeze(fn: ET.Element, k: float) -> None:
    """Make an ``aero/coefficient`` function the campaign's qualified term."""
    body = [c for c in fn if c.tag != "description"]
    if len(body) != 1:
        raise DataError(f"{fn.get('name')}: expected one function body to freeze")
    orig = body[0]
    frozen = ET.fromstring(ET.tostring(orig))
    for el in frozen.iter():
        t = (el.text or "").strip()
        if el.tag in ("property", "independentVar") and t in ("aero/alpha-deg", "aero/alpha-rad"):
            el.text = f"{_ALPHA_FROZEN}-{t.rsplit('-', 1)[1]}"
    fn.remove(orig)
    if k == 1.0:
        fn.append(frozen)
        return
    s = _sub(fn, "sum")
    for w, el in ((1.0 - k, orig), (k, frozen)):
        pr = _sub(s, "product")
        _sub(pr, "value", repr(w))
        pr.append(el)


def _alpha_frozen_functions(walpha: float) -> list[ET.Element]:
    out = []
    for unit, lim in (("deg", walpha), ("rad", walpha * jc.D2R)):
        fn = ET.Element("function", name=f"{_ALPHA_FROZEN}-{unit}")
        _sub(fn, "description", f"alpha frozen above the campaign's withhold alpha ({unit})")
        mn = _sub(fn, "min")
        _sub(mn, "property", f"aero/alpha-{unit}")
        _sub(mn, "value", repr(lim))
        out.append(fn)
    return out


def _thrust_functions(setup: CampaignSetup, xml: Path, n_eng: int) -> list[ET.Element]:
    """``ct_left``/``ct_right`` as the campaign records them: thrust by engine side / q̄S."""
    sides = jc._engine_sides(xml, n_eng)
    out = []
    for ch, prop in _CT.items():
        fn = ET.Element("function", name=prop)
        _sub(fn, "description", f"{ch}: engine thrust over qbar S, as the campaign's records")
        q = _sub(fn, "quotient")
        s = _sub(q, "sum")
        _sub(s, "value", "0")
        for i, w in enumerate(sides):
            share = w if ch == "ct_left" else 1.0 - w
            if share:
                pr = _sub(s, "product")
                _sub(pr, "value", repr(share))
                _sub(pr, "property", f"propulsion/engine[{i}]/thrust-lbs")
        mx = _sub(q, "max")
        pr = _sub(mx, "product")
        _sub(pr, "property", "aero/qbar-psf")
        _sub(pr, "property", "metrics/Sw-sqft")
        _sub(mx, "value", "1e-9")
        out.append(fn)
    return out


def _n_engines_xml(xml: Path) -> int:
    return len(ET.parse(xml).getroot().findall("propulsion/engine"))


def write_replay_aircraft(
    setup: CampaignSetup,
    out_root: str | os.PathLike[str],
    *,
    variant: str = "qualified",
    model: DeltaModel | None = None,
) -> Path:
    """Write a JSBSim root holding the campaign's aircraft as ``variant``.

    Parameters
    ----------
    setup
        :func:`load_setup` of the campaign.
    out_root
        New JSBSim root (created; ``engine/`` and ``systems/`` link to the original root's).
    variant
        ``"full"`` (the aircraft as flown), ``"qualified"`` (withheld terms frozen above the
        withhold alpha, the campaign's ``C*_sim``) or ``"extended"`` (qualified + the Δ of
        ``model`` exported by :func:`aerodelta.jsbsim.export_jsbsim` with
        :func:`replay_properties`; the lateral Δ only: a stored Kirchhoff stall is not
        flown).
    model
        The fitted Δ model (``"extended"`` only).

    Returns
    -------
    Path
        ``out_root``; load the aircraft with ``FGFDMExec(str(out_root)).load_model(model)``.
    """
    if variant not in VARIANTS:
        raise InvalidInputError(f"variant '{variant}': use one of {', '.join(VARIANTS)}")
    if (variant == "extended") != (model is not None):
        raise InvalidInputError("a Δ model is needed for variant 'extended' and only there")
    cfg, src_root = setup.cfg, setup.jsbsim_root
    root = Path(out_root)
    src = src_root / "aircraft" / cfg.model
    dst = root / "aircraft" / cfg.model
    if dst.exists():
        shutil.rmtree(dst)
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copytree(src, dst)
    for sub in ("engine", "systems"):
        link = root / sub
        if not link.exists() and (src_root / sub).exists():
            link.symlink_to((src_root / sub).resolve(), target_is_directory=True)
    xml = dst / f"{cfg.model}.xml"
    tree = ET.parse(xml)
    doc = tree.getroot()
    fcs = doc.find("flight_control")
    if fcs is None:
        fcs = ET.SubElement(doc, "flight_control", name="aerodelta replay")
    _replay_channel(fcs, cfg)
    aero = doc.find("aerodynamics")
    aero_tree, aero_path = tree, xml
    if aero is not None and aero.get("file"):
        aero_path = dst / f"{aero.get('file')}.xml"
        aero_tree = ET.parse(aero_path)
        aero = aero_tree.getroot()
    if aero is None:
        raise DataError(f"{xml}: no <aerodynamics> section")
    if variant != "full":
        found = set()
        for ax in aero.findall("axis"):
            for fn in ax.findall("function"):
                name = fn.get("name", "").rsplit("/", 1)[-1]
                if fn.get("name", "").startswith("aero/coefficient/") and name in setup.withheld:
                    _freeze(fn, setup.withhold_scale)
                    found.add(name)
        missing = sorted(set(setup.withheld) - found)
        if missing:
            raise DataError(f"{xml}: withheld terms {', '.join(missing)} not found in its axes")
        first = next((i for i, c in enumerate(aero) if c.tag == "axis"), len(aero))
        for j, fn in enumerate(_alpha_frozen_functions(setup.withhold_alpha_deg)):
            aero.insert(first + j, fn)
    if model is not None:
        _merge_delta(setup, aero, model, xml)
    ET.indent(aero_tree)
    aero_tree.write(aero_path, encoding="utf-8", xml_declaration=True)
    if aero_tree is not tree:
        tree.write(xml, encoding="utf-8", xml_declaration=True)
    return root


def _merge_delta(setup: CampaignSetup, aero: ET.Element, model: DeltaModel, xml: Path) -> None:
    """Add the exported Δ (increments w ΔC on SIDE/ROLL/YAW) to the aircraft's aerodynamics.
    A Kirchhoff stall the model stores is not added: the replay checks the lateral Δ."""
    with tempfile.TemporaryDirectory() as tmp:
        text = export_jsbsim(
            Path(tmp) / "delta.xml", model, replay_properties(setup), longitudinal=False
        )
    ex = ET.fromstring(text)
    declared = [c.text for c in ex.findall("property")]
    if declared:
        raise DataError(
            f"the Δ model reads {', '.join(str(d) for d in declared)}, which the JSBSim "
            f"{setup.cfg.model} does not drive; the replay maps only surfaces, flaps and thrust"
        )
    first = next((i for i, c in enumerate(aero) if c.tag == "axis"), len(aero))
    pre = _thrust_functions(setup, xml, _n_engines_xml(xml)) + ex.findall("function")
    for j, fn in enumerate(pre):
        aero.insert(first + j, fn)
    axes = {a.get("name", "").upper(): a for a in aero.findall("axis")}
    for ax in ex.findall("axis"):
        name = ax.get("name", "").upper()
        if name not in axes:
            raise DataError(
                f"{xml}: no <axis name='{name}'> to add the Δ to (axes: {', '.join(axes)})"
            )
        for fn in ax.findall("function"):
            axes[name].append(fn)


# --------------------------------------------------------------------------------------------
# Replay


def _initial(col: np.ndarray, t: np.ndarray, span_s: float = 0.5) -> float:
    """Value at t[0] of a straight line fitted over the first ``span_s`` (averages the sensor
    noise without the bias of a mean on a trend)."""
    m = t <= t[0] + span_s
    if int(m.sum()) < 3:
        return float(col[0])
    c = np.polyfit(t[m] - t[0], col[m], 1)
    return float(c[1])


def _trim(fdm: Any, setup: CampaignSetup, rec: pl.DataFrame, seed: int) -> None:
    """Trim as the campaign does, at the record's initial true airspeed and altitude."""
    cfg = setup.cfg
    t = rec["t"].to_numpy()
    flap = float(rec["flap_deg"][0])
    fdm["ic/h-sl-ft"] = _initial(rec["h_m"].to_numpy(), t) / jc.FT
    fdm["ic/vt-fps"] = _initial(rec["tas_mps"].to_numpy(), t) / jc.FT
    fdm["ic/psi-true-deg"] = _initial(rec["psi_deg"].to_numpy(), t)
    jc.trim_at_ic(
        fdm,
        cfg,
        flap,
        seed,
        f"JSBSim trim failed for {cfg.model} at the record's initial state "
        f"({float(rec['tas_mps'][0]):.1f} m/s, {float(rec['h_m'][0]):.0f} m)",
    )


def _golden(f: Any, lo: float, hi: float, tol: float) -> float:
    """Minimiser of a unimodal ``f`` on [lo, hi] (golden section, to ``tol``)."""
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo, hi
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    while b - a > tol:
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    return (a + b) / 2.0


@dataclass
class _Inputs:
    """A maneuver's replay inputs at every 200 Hz frame after the trim."""

    times: np.ndarray  # s, frame times (record clock)
    surf: dict[str, np.ndarray]  # da, de, dr: JSBSim surface positions (rad)


class _Flight:
    """One replay from the trim: the surfaces from the record, the throttle from a schedule."""

    def __init__(self, setup: CampaignSetup, root: Path, record: pl.DataFrame, seed: int) -> None:
        self.setup, self.root, self.record, self.seed = setup, root, record, seed
        cfg = setup.cfg
        t = record["t"].to_numpy()
        self.t = t
        fdm = self.start()
        self.n_eng = jc._n_engines(fdm)
        self.thr0 = np.array([fdm[f"fcs/throttle-cmd-norm[{i}]"] for i in range(self.n_eng)])
        xml = setup.jsbsim_root / "aircraft" / cfg.model / f"{cfg.model}.xml"
        self.sides = jc._engine_sides(xml, self.n_eng)
        n = round((t[-1] - t[0]) / jc.DT)
        ts = t[0] + jc.DT * np.arange(1, n + 1)
        surf = {
            k: np.interp(ts, t, record[f"{k}_deg"].to_numpy()) / setup.signs[k] * jc.D2R
            for k in ("da", "de", "dr")
        }
        qs = (
            0.5
            * record["rho_kgm3"].to_numpy()
            / jc.SLUGFT3
            * (record["tas_mps"].to_numpy() / jc.FT) ** 2
            * fdm["metrics/Sw-sqft"]
        )
        wl = np.array(self.sides)
        share_l = wl / max(float(wl.sum()), 1e-12)
        share_r = (1 - wl) / max(float((1 - wl).sum()), 1e-12)
        tl, tr = record["ct_left"].to_numpy() * qs, record["ct_right"].to_numpy() * qs
        self.rec_thrust = share_l[:, None] * tl[None, :] + share_r[:, None] * tr[None, :]
        self.inputs = _Inputs(ts, surf)

    def start(self) -> Any:
        fdm = jc.new_fdm(self.root, self.setup.cfg.model)
        _trim(fdm, self.setup, self.record, self.seed)
        if self.setup.turbulence > 0:
            fdm["atmosphere/turb-type"] = 3
            fdm["atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"] = 15.0 / jc.FT * 0.514
            fdm["atmosphere/turbulence/milspec/severity"] = self.setup.turbulence
        return fdm

    def fly(
        self, factor: float, t_full: float, n_frames: int | None = None, props: Sequence[str] = ()
    ) -> dict[str, np.ndarray]:
        """Fly ``n_frames`` 200 Hz frames with throttle ``factor`` x trim throttle until
        ``t_full`` (s, record clock), full throttle after; record ``props`` and the engines'
        thrust at 50 Hz (the record's samples)."""
        fdm = self.start()
        fdm[_ACTIVE] = 1.0
        inp = self.inputs
        n = len(inp.times) if n_frames is None else min(n_frames, len(inp.times))
        thrust_p = [f"propulsion/engine[{i}]/thrust-lbs" for i in range(self.n_eng)]
        allp = list(dict.fromkeys([*props, *thrust_p]))
        rec: dict[str, list[float]] = {p: [fdm[p]] for p in allp}
        low = np.clip(self.thr0 * factor, 0.0, 1.0)
        thr_p = [f"fcs/throttle-cmd-norm[{i}]" for i in range(self.n_eng)]
        da, de, dr = inp.surf["da"], inp.surf["de"], inp.surf["dr"]
        sda, sde, sdr = _SURF["da"], _SURF["de"], _SURF["dr"]
        for k in range(n):
            fdm[sda] = da[k]
            fdm[sde] = de[k]
            fdm[sdr] = dr[k]
            full = inp.times[k] > t_full
            for i in range(self.n_eng):
                fdm[thr_p[i]] = 1.0 if full else low[i]
            fdm.run()
            if (k + 1) % jc._DECIM == 0:
                for p in allp:
                    rec[p].append(fdm[p])
        out = {p: np.asarray(v, dtype=float) for p, v in rec.items()}
        out["_thrust"] = np.stack([out[p] for p in thrust_p])
        return out

    def thrust_error(self, thrust: np.ndarray, lo: float, hi: float) -> float:
        """Sum of squared thrust errors (lbf²) over record times in [lo, hi] (s)."""
        m = len(thrust[0])
        t = self.t[:m]
        w = (t >= lo) & (t <= hi)
        return float(np.sum((thrust[:, w] - self.rec_thrust[:, :m][:, w]) ** 2))

    def throttle_schedule(self) -> tuple[float, float]:
        """The campaign pilot's throttle, fitted to the recorded thrust: one setting (a factor
        on the trim throttle) then full throttle from the recovery. The factor is fitted over
        the first 2 s, the recovery located at the first sustained excess of the recorded
        thrust over the held setting's (5 % of the largest recorded thrust, 5 samples), the
        factor refitted over the whole held part (from the start to 3 s before that excess:
        the sensor noise averages out over it) and the recovery time fitted over the 3 s
        before and 2 s after it (golden sections, least squares on the thrust)."""
        hi_f = 1.0 / max(float(np.max(self.thr0)), 1e-3)

        def err_f(f: float, span: float) -> float:
            nf = round(span / jc.DT)
            return self.thrust_error(self.fly(f, math.inf, nf)["_thrust"], 0.0, span)

        factor = _golden(lambda f: err_f(f, 2.0), 0.0, hi_f, 1e-3)
        held = self.fly(factor, math.inf)["_thrust"]
        m = held.shape[1]
        excess = (self.rec_thrust[:, :m] - held).sum(axis=0) / np.max(self.rec_thrust.sum(axis=0))
        run = np.convolve((excess > 0.05).astype(float), np.ones(5), mode="valid") >= 5
        t_exc = float(self.t[int(np.argmax(run))]) if run.any() else math.inf
        span = max(2.0, min(t_exc, float(self.t[-1])) - 3.0)
        if span > 2.0:
            w = 0.05 * hi_f
            factor = _golden(lambda f: err_f(f, span), max(factor - w, 0.0), factor + w, 1e-5)
        if not math.isfinite(t_exc):
            return factor, math.inf
        lo, hi = max(t_exc - 3.0, 0.0), t_exc
        n_to = round((min(t_exc + 2.0, float(self.t[-1])) - self.t[0]) / jc.DT)

        def err_t(tf: float) -> float:
            return self.thrust_error(self.fly(factor, tf, n_to)["_thrust"], lo, t_exc + 2.0)

        return factor, _golden(err_t, lo, hi, jc.DT)


def replay_maneuver(
    setup: CampaignSetup,
    aircraft_root: str | os.PathLike[str],
    record: pl.DataFrame,
    *,
    seed: int = 0,
    throttle: tuple[float, float] | None = None,
    extra: Sequence[str] = (),
) -> pl.DataFrame:
    """Fly one recorded maneuver open loop on a replay aircraft (:func:`write_replay_aircraft`).

    JSBSim is trimmed at the record's initial true airspeed and altitude (a line fitted over
    its first 0.5 s), wings level, flaps as recorded, as the campaign trims; turbulence as the
    campaign (``seed``: the manifest's maneuver seed, JSBSim's generator seed). Then at every
    200 Hz frame the surfaces are set to the recorded ``da_deg``, ``de_deg``, ``dr_deg``
    (converted with the control signs, interpolated linearly between the 50 Hz samples). The
    campaign records no throttle: the throttle is the campaign pilot's schedule (a factor on
    the trim throttle, full throttle after a recovery time), ``throttle=(factor, t_full_s)``, or
    fitted to the recorded thrust (``ct_left``/``ct_right`` times the record's q̄S) when None.

    Returns
    -------
    polars.DataFrame
        50 Hz at the record's times: ``t`` (s), ``alpha_deg``, ``beta_deg``, ``p_dps``,
        ``q_dps``, ``r_dps``, ``phi_deg``, ``theta_deg``, ``psi_deg`` (unwrapped), ``tas_mps``,
        ``h_m``, ``qbar_psf`` (lbf/ft²), ``Cl_aero``, ``Cn_aero``, ``CY_aero`` (JSBSim's aero
        moments about the CG over q̄Sb, side force over q̄S), ``phat``, ``rhat``, ``da_deg``,
        ``de_deg``, ``dr_deg`` (as flown, Etkin), ``thrust_left_lbs``, ``thrust_right_lbs``,
        ``throttle_factor``, ``t_full_throttle_s``, and each property of ``extra`` under its
        own name.
    """
    flight = _Flight(setup, Path(aircraft_root), record, seed)
    factor, t_full = flight.throttle_schedule() if throttle is None else throttle
    cfg = setup.cfg
    props = [*_REPLAY_PROPS, cfg.aileron_rad, cfg.elevator_rad, cfg.rudder_rad, *extra]
    rec = flight.fly(factor, t_full, props=list(dict.fromkeys(props)))
    out = _frame(setup, rec, flight.t, flight.sides, flight.n_eng, extra)
    return out.with_columns(
        pl.lit(factor).alias("throttle_factor"), pl.lit(t_full).alias("t_full_throttle_s")
    )


def _frame(  # noqa: PLR0917
    setup: CampaignSetup,
    rec: Mapping[str, list[float]],
    t: np.ndarray,
    sides: Sequence[float],
    n_eng: int,
    extra: Sequence[str],
) -> pl.DataFrame:
    a = {p: np.asarray(v, dtype=float) for p, v in rec.items() if not p.startswith("_")}
    n = min(len(t), len(a["aero/alpha-deg"]))
    a = {p: v[:n] for p, v in a.items()}
    cfg, s = setup.cfg, setup.signs
    qs = a["aero/qbar-psf"] * a["metrics/Sw-sqft"]
    qsb = qs * a["metrics/bw-ft"]
    out: dict[str, np.ndarray] = {"t": t[:n]}
    for p, c in _REPLAY_PROPS.items():
        v = a[p]
        if c.endswith("_dps") or c in ("phi_deg", "theta_deg"):
            v = v * jc.R2D
        elif c == "psi_deg":
            v = np.unwrap(v) * jc.R2D
        elif c in ("tas_mps", "h_m"):
            v = v * jc.FT
        out[c] = v
    out["Cl_aero"] = a["moments/l-aero-lbsft"] / qsb
    out["Cn_aero"] = a["moments/n-aero-lbsft"] / qsb
    out["CY_aero"] = a["forces/fby-aero-lbs"] / qs
    out["phat"] = a["velocities/p-aero-rad_sec"] * a["aero/bi2vel"]
    out["rhat"] = a["velocities/r-aero-rad_sec"] * a["aero/bi2vel"]
    out["da_deg"] = s["da"] * a[cfg.aileron_rad] * jc.R2D
    out["de_deg"] = s["de"] * a[cfg.elevator_rad] * jc.R2D
    out["dr_deg"] = s["dr"] * a[cfg.rudder_rad] * jc.R2D
    thrust = [a[f"propulsion/engine[{i}]/thrust-lbs"] for i in range(n_eng)]
    out["thrust_left_lbs"] = sum((w * th for w, th in zip(sides, thrust, strict=True)), 0 * t[:n])
    out["thrust_right_lbs"] = sum(
        ((1 - w) * th for w, th in zip(sides, thrust, strict=True)), 0 * t[:n]
    )
    for p in extra:
        out[p] = a[p]
    return pl.DataFrame(out)


def aero_at_states(
    setup: CampaignSetup,
    aircraft_root: str | os.PathLike[str],
    record: pl.DataFrame,
    rows: Sequence[int],
    *,
    extra: Sequence[str] = (),
) -> pl.DataFrame:
    """A replay aircraft's aerodynamics at recorded states (no integration).

    For each row of ``record``: JSBSim's initial conditions are set to the recorded altitude,
    true airspeed, alpha, beta, Euler angles and body rates, the surfaces to the recorded
    ``da_deg``/``de_deg``/``dr_deg`` (replay channel active), the flaps to ``flap_deg``, and
    ``run_ic`` evaluates every model once with the integration suspended.

    Returns
    -------
    polars.DataFrame
        ``row``, ``alpha_deg``, ``beta_deg`` (as JSBSim computed them back), ``Cl_aero``,
        ``Cn_aero`` (aero moments about the CG / q̄Sb), ``CY_aero`` (body side force / q̄S)
        and each property of ``extra``.
    """
    cfg = setup.cfg
    fdm = jc.new_fdm(Path(aircraft_root), cfg.model)
    _trim(fdm, setup, record, 0)
    fdm[_ACTIVE] = 1.0
    out: dict[str, list[float]] = {
        k: [] for k in ("row", "alpha_deg", "beta_deg", "Cl_aero", "Cn_aero", "CY_aero", *extra)
    }
    for i in rows:
        r = record.row(int(i), named=True)
        fdm["ic/h-sl-ft"] = r["h_m"] / jc.FT
        fdm["ic/vt-fps"] = r["tas_mps"] / jc.FT
        fdm["ic/alpha-deg"] = r["alpha_deg"]
        fdm["ic/beta-deg"] = r["beta_deg"]
        fdm["ic/phi-deg"] = r["phi_deg"]
        fdm["ic/theta-deg"] = r["theta_deg"]
        fdm["ic/psi-true-deg"] = r["psi_deg"]
        for a in "pqr":
            fdm[f"ic/{a}-rad_sec"] = r[f"{a}_dps"] * jc.D2R
        for k in ("da", "de", "dr"):
            fdm[_SURF[k]] = r[f"{k}_deg"] / setup.signs[k] * jc.D2R
        fdm.run_ic()
        if cfg.flap_norm_per_deg and abs(fdm[cfg.flap_deg_prop] - r["flap_deg"]) > 1e-6:
            raise DataError(
                f"row {i}: flap {r['flap_deg']:g} deg differs from the record's first sample; "
                "evaluate one flap setting per call"
            )
        qs = fdm["aero/qbar-psf"] * fdm["metrics/Sw-sqft"]
        out["row"].append(int(i))
        out["alpha_deg"].append(fdm["aero/alpha-deg"])
        out["beta_deg"].append(fdm["aero/beta-deg"])
        out["Cl_aero"].append(fdm["moments/l-aero-lbsft"] / (qs * fdm["metrics/bw-ft"]))
        out["Cn_aero"].append(fdm["moments/n-aero-lbsft"] / (qs * fdm["metrics/bw-ft"]))
        out["CY_aero"].append(fdm["forces/fby-aero-lbs"] / qs)
        for p in extra:
            out[p].append(fdm[p])
    return pl.DataFrame(out)


def propellers(setup: CampaignSetup) -> list[str]:
    """The thruster files of the campaign's aircraft that are propellers (root element
    ``<propeller>``, looked up as JSBSim does: the aircraft's ``Engines/``, then the root's
    ``engine/``)."""
    xml = _model_xml_of(setup)
    out = []
    for th in ET.parse(xml).getroot().findall("propulsion/engine/thruster"):
        name = th.get("file", "")
        for d in (xml.parent / "Engines", xml.parent / "engine", setup.jsbsim_root / "engine"):
            f = d / f"{name}.xml"
            if f.is_file():
                if ET.parse(f).getroot().tag == "propeller":
                    out.append(name)
                break
    return list(dict.fromkeys(out))


def _model_xml_of(setup: CampaignSetup) -> Path:
    return setup.jsbsim_root / "aircraft" / setup.cfg.model / f"{setup.cfg.model}.xml"


#: Channels :func:`aero_along` reads from each row (a model frame of ingested records).
STATE_CHANNELS = ("maneuver_id", "t", "h_m", "tas_mps", "alpha_deg", "beta_deg", "phi_deg",
                  "theta_deg", "psi_deg", "p_dps", "q_dps", "r_dps", "da_deg", "de_deg",
                  "dr_deg", "flap_deg")  # fmt: skip


#: State channel -> the ingestion's smoothed channel that :func:`aero_along` reads instead
#: when the frame has it.
SMOOTHED = {"p_dps": "p_s_dps", "q_dps": "q_s_dps", "r_dps": "r_s_dps", "tas_mps": "tas_s_mps"}


def aero_along(
    setup: CampaignSetup, frame: pl.DataFrame, *, variant: str = "qualified"
) -> dict[str, np.ndarray]:
    """A replay aircraft's aerodynamic ``Cl``, ``Cn`` (about the CG, over q̄Sb) and ``CY``
    (over q̄S) at every row of ``frame``: :func:`aero_at_states` maneuver by maneuver (each
    sorted by time, trimmed at its first sample), in the frame's row order.

    ``frame`` needs :data:`STATE_CHANNELS` (SI and degrees, as ingested), finite, one flap
    setting per maneuver. The body rates and airspeed are the smoothed ones of
    :data:`SMOOTHED` when the frame has them (an ingested model frame does): the states the
    fit's regressors (p̂, r̂, alpha, beta at the CG) are formed from, so the qualified model and
    the Δ see the same sample. Raises ``DataError`` naming the missing channel, or the channel and
    row of a value that is not finite.
    """
    missing = [c for c in STATE_CHANNELS if c not in frame.columns]
    if missing:
        raise DataError(
            f"the JSBSim qualified model ({setup.path}) sets the recorded state of each sample "
            f"and the records lack {', '.join(missing)}"
        )
    for c in STATE_CHANNELS[1:]:
        x = frame[c].cast(pl.Float64).fill_null(math.nan).to_numpy()
        bad = np.nonzero(~np.isfinite(x))[0]
        if bad.size:
            raise DataError(
                f"channel {c}, row {int(bad[0])}: not a finite number; the JSBSim qualified "
                "model needs every state of every sample (drop or fill the sample)"
            )
    # the smoothed states the ingestion forms the fit's regressors from (p̂ = p_s b / 2 V_s)
    smooth = {c: s for c, s in SMOOTHED.items() if s in frame.columns}
    idx = frame.with_columns(pl.col(s).alias(c) for c, s in smooth.items()).with_row_index("_row")
    out = {c: np.full(frame.height, math.nan) for c in ("Cl", "Cn", "CY")}
    with tempfile.TemporaryDirectory(prefix="aerodelta-qualified-") as tmp:
        root = write_replay_aircraft(setup, tmp, variant=variant)
        for group in idx.partition_by("maneuver_id", maintain_order=True):
            part = group.sort("t")
            res = aero_at_states(setup, root, part, range(part.height))
            rows = part["_row"].to_numpy()
            for c, v in out.items():
                v[rows] = res[f"{c}_aero"].to_numpy()
    return out


# --------------------------------------------------------------------------------------------
# Scoring


def score_window(record: pl.DataFrame, withhold_alpha_deg: float) -> float:
    """End (s, record clock) of the scored window: the first sample after the record's largest
    alpha at which the recorded alpha is back at or below the withhold alpha, i.e. where the Δ
    stops acting (the recovery); the record's end when it never is. The window starts at the
    record's start: below the withhold alpha the qualified and extended aircraft are the full
    one, so the early part scores the replay itself."""
    a = record["alpha_deg"].to_numpy()
    t = record["t"].to_numpy()
    k = int(np.argmax(a))
    back = np.nonzero(a[k:] <= withhold_alpha_deg)[0]
    return float(t[k + back[0]]) if back.size else float(t[-1])


#: The full aircraft's replay error, as a fraction of a channel's recorded range, that ends
#: the ``"predictable"`` window (:func:`predictable_until`).
DIVERGED = 0.1


def predictable_until(record: pl.DataFrame, full: pl.DataFrame, t_end: float) -> float:
    """Time (s) the full aircraft's replay (the truth flown with the recorded inputs) stops
    reproducing the record: the first sample where its error on any of p, r, φ, β exceeds
    :data:`DIVERGED` times that channel's recorded range up to ``t_end``; ``inf`` if never.
    Past it the open-loop motion (a stall's chaotic part) no longer follows the inputs, and
    no aerodynamic model can be scored against the record there."""
    t = record["t"].to_numpy()
    n = min(len(t), full.height)
    m = t[:n] <= t_end
    bad = np.zeros(n, dtype=bool)
    for ch in CHANNELS:
        y = record[ch].to_numpy()[:n]
        rng = float(np.ptp(y[m])) if m.any() else 0.0
        bad |= np.abs(full[ch].to_numpy()[:n] - y) > DIVERGED * max(rng, 1e-12)
    k = np.nonzero(bad)[0]
    return float(t[k[0]]) if k.size else math.inf


def replay_campaign(
    campaign_dir: str | os.PathLike[str],
    model: str | os.PathLike[str] | DeltaModel,
    *,
    maneuvers: Sequence[str] | None = None,
    variants: Sequence[str] = VARIANTS,
    root_dir: str | os.PathLike[str] | None = None,
    keep_replays: bool = False,
    progress: bool = False,
) -> pl.DataFrame | tuple[pl.DataFrame, pl.DataFrame]:
    """Fly held-out maneuvers of a JSBSim campaign on the full, qualified and extended aircraft
    and score each replay against the record (Theil inequality coefficient, TIC).

    Parameters
    ----------
    campaign_dir
        A folder written by :func:`aerodelta.jsbsim_campaign.generate_jsbsim_campaign`.
    model
        The Δ model fitted on the campaign (``aerodelta.fit(..., qualified="columns")``), or
        its file.
    maneuvers
        Maneuver ids to replay (those held out of the fit); default every maneuver.
    variants
        Aircraft to fly, of :data:`VARIANTS`.
    root_dir
        The JSBSim root the campaign flew (default: the ``jsbsim`` package's).
    keep_replays
        Also return the replayed time histories (``(scores, replays)``).
    progress
        One line per maneuver on stderr.

    Returns
    -------
    polars.DataFrame
        One row per maneuver (``maneuver_id``, and ``"pooled"``: all maneuvers' windows
        concatenated), ``window`` (``"delta"``: from the start to :func:`score_window`;
        ``"predictable"``: that window ended where the full aircraft's own replay leaves the
        record, :func:`predictable_until`, when ``"full"`` is flown; ``"record"``: the whole
        record) and ``channel`` of
        :data:`CHANNELS`: ``tic_<variant>`` (0 perfect, 1 useless), ``ratio`` =
        ``tic_extended / tic_qualified``, ``t_end_s``, ``n_samples``. With ``keep_replays``,
        also the replays (``maneuver_id``, ``variant`` and :func:`replay_maneuver`'s columns).

    The throttle schedule (:func:`replay_maneuver`) is fitted once per maneuver on the
    qualified aircraft (what a user has) and flown by every variant.
    """
    bad = [v for v in variants if v not in VARIANTS]
    if bad or not variants:
        raise InvalidInputError(f"variants {bad or '[]'}: use some of {', '.join(VARIANTS)}")
    setup = load_setup(campaign_dir, root_dir)
    dm = model if isinstance(model, DeltaModel) else _load_model(model)
    ids = setup.manifest["maneuver_id"].to_list()
    chosen = list(ids) if maneuvers is None else list(maneuvers)
    unknown = [m for m in chosen if m not in ids]
    if unknown:
        raise InvalidInputError(
            f"maneuvers {', '.join(unknown)} are not in {setup.path / 'manifest.csv'}"
        )
    seeds = dict(zip(ids, setup.manifest["seed"].to_list(), strict=True))
    rows: list[dict[str, Any]] = []
    pooled: dict[tuple[str, str, str], list[np.ndarray]] = {}
    replays: list[pl.DataFrame] = []
    with tempfile.TemporaryDirectory(prefix="aerodelta-replay-") as tmp:
        roots = {
            v: write_replay_aircraft(
                setup, Path(tmp) / v, variant=v, model=dm if v == "extended" else None
            )
            for v in dict.fromkeys([*variants, "qualified"])
        }
        for mid in chosen:
            rec = read_record(setup, mid)
            seed = int(seeds[mid])
            sched = _Flight(setup, roots["qualified"], rec, seed).throttle_schedule()
            t_end = score_window(rec, setup.withhold_alpha_deg)
            reps = {
                v: replay_maneuver(setup, roots[v], rec, seed=seed, throttle=sched)
                for v in variants
            }
            if keep_replays:
                replays += [
                    r.with_columns(pl.lit(mid).alias("maneuver_id"), pl.lit(v).alias("variant"))
                    for v, r in reps.items()
                ]
            windows = {"delta": t_end, "record": math.inf}
            if "full" in reps:
                windows["predictable"] = min(t_end, predictable_until(rec, reps["full"], t_end))
            for window, end in windows.items():
                m = rec["t"].to_numpy() <= end
                for ch in CHANNELS:
                    y = rec[ch].to_numpy()[m]
                    row: dict[str, Any] = {"maneuver_id": mid, "window": window, "channel": ch}
                    pooled.setdefault((window, ch, "_y"), []).append(y)
                    for v, r in reps.items():
                        yh = r[ch].to_numpy()[m]
                        row[f"tic_{v}"] = theil_inequality(y, yh)
                        pooled.setdefault((window, ch, v), []).append(yh)
                    row["t_end_s"] = float(min(end, rec["t"][-1]))
                    row["n_samples"] = int(m.sum())
                    rows.append(row)
            if progress:
                print(
                    f"[replay] {mid}: windows to {', '.join(f'{v:.1f}' for v in windows.values())}"
                    f" s, throttle x{sched[0]:.3f}, full from {sched[1]:.2f} s",
                    file=sys.stderr,
                )
    for window in sorted({k[0] for k in pooled}):
        for ch in CHANNELS:
            y = np.concatenate(pooled[(window, ch, "_y")])
            row = {"maneuver_id": "pooled", "window": window, "channel": ch}
            for v in variants:
                row[f"tic_{v}"] = theil_inequality(y, np.concatenate(pooled[(window, ch, v)]))
            row["t_end_s"] = math.nan
            row["n_samples"] = int(y.size)
            rows.append(row)
    out = pl.DataFrame(rows)
    if "extended" in variants and "qualified" in variants:
        out = out.with_columns((pl.col("tic_extended") / pl.col("tic_qualified")).alias("ratio"))
    if keep_replays:
        return out, pl.concat(replays, how="diagonal_relaxed")
    return out


def _load_model(path: str | os.PathLike[str]) -> DeltaModel:
    p = Path(path)
    if not p.is_file():
        raise InvalidInputError(f"{p}: no such Δ model file; give the file aerodelta fit wrote")
    return DeltaModel.load(p)


def read_record(setup: CampaignSetup, mid: str) -> pl.DataFrame:
    """The campaign's record of maneuver ``mid`` (``records/<id>.parquet`` as the manifest
    names it), checked for the channels a replay reads; ``DataError`` naming the file
    otherwise."""
    row = setup.manifest.filter(pl.col("maneuver_id") == mid)
    if row.height == 0:
        raise DataError(f"{setup.path / 'manifest.csv'}: no maneuver {mid}")
    p = setup.path / str(row["file"][0])
    try:
        rec = pl.read_parquet(p)
    except (OSError, pl.exceptions.PolarsError) as e:
        raise DataError(f"{p}: cannot read the record of maneuver {mid}: {e}") from None
    need = {"t", "alpha_deg", "tas_mps", "h_m", "rho_kgm3", "flap_deg", "psi_deg", "ct_left",
            "ct_right", "da_deg", "de_deg", "dr_deg", *CHANNELS}  # fmt: skip
    missing = sorted(need - set(rec.columns))
    if missing:
        raise DataError(f"{p}: channels {', '.join(missing)} missing; the replay needs them")
    return rec
