"""Export the blended Δ model (thesis Eq. 3.11-3.12) as a JSBSim ``<aerodynamics>`` file.

JSBSim sums every ``<function>`` of an ``<axis>``, so the export adds the extended model's
increments ``w(alpha) ΔC`` to an aircraft whose own aerodynamics already hold the qualified model:

- ``SIDE``: ``qbar S w_CY ΔCY`` (lbf; body-axis side force, as the Δ model's ``CY``),
- ``ROLL``: ``qbar S b w_Cl ΔCl`` (ft lbf), ``YAW``: ``qbar S b w_Cn ΔCn`` (ft lbf).

``ΔC = Σ θ(alpha, flap) x`` is a ``<sum>`` of ``<product>``\\s of a 2-D ``<table>`` (rows: angle
of attack, columns: flap; linear in both, ends held, as ``aero_core::table``) and the regressor
written as JSBSim function elements (``deadband(x, k)`` as ``max(x-k, 0) + min(x+k, 0)``,
thesis Eq. 3.15-3.16). The blend weight is ``min(1, max(0, (alpha - alpha_l(flap)) /
max(alpha_u(flap) - alpha_l(flap), 1e-300)))``, exactly the engine's Eq. 3.12 weight.

Each Δ-model channel reads a JSBSim property, or a product of properties and numbers
(:data:`DEFAULT_PROPERTIES`; override with ``properties=``). Channels whose sign convention
differs between aircraft (controls, thrust coefficients) default to ``aerodelta/...``
properties that the file declares (value 0) and the aircraft must drive, e.g. from a
``<system>``. Intermediate values are published as ``aero/aerodelta/<C>/...`` properties; a
model that carries its validated envelope also publishes ``aero/aerodelta/in-envelope`` (1
inside the flight data's alpha/beta envelope, 0 outside).

A model storing a Kirchhoff stall adds its lift and pitching-moment increments, and its drag
increment when it stores the stall's drag (``LIFT`` and ``DRAG`` or ``X``/``Z``, and
``PITCH``): over the ADX-37 qualified static curves for a stall fitted on the
ADX-37's known terms, over the identified static curves (the separation dynamics alone) for one
fitted with ``known="none"``; the separation state is stepped exactly each frame in the
aerodynamics and carried to the next frame by a ``<system>`` (:func:`jsbsim_stall_system_xml`;
``docs/export.md``).
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Mapping
from os import PathLike
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

import numpy as np
import numpy.typing as npt

from aerodelta._exportutil import DERIVED_CHANNELS, Node, parse_regressor, write_atomic
from aerodelta._fsutil import write_texts_atomic
from aerodelta.exceptions import DataError
from aerodelta.export import STALL_FLAP_WINDOW_DEG, SplineLayout, qualified_daveml_spec
from aerodelta.model import DeltaModel
from aerodelta.qualified import describe, recorded_source

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "DEFAULT_PROPERTIES",
    "export_jsbsim",
    "jsbsim_properties",
    "jsbsim_stall_system_xml",
    "jsbsim_xml",
]

_R2D = repr(180.0 / math.pi)

#: Tables of the built-in qualified model that are the thrust's own moment, not aerodynamics:
#: ``Cn_CTdiff`` is the engines' lever arm ``y/b`` times the thrust difference. The qualified
#: model holds the total coefficients the flight data measure (thrust included), but JSBSim's
#: ``<propulsion>`` applies each engine's thrust at its location, so with ``qualified=True``
#: these terms are left out of the ``<aerodynamics>`` (else an engine-out stall's thrust yaw
#: is counted twice: about 0.05 in C_n). The slipstream terms (``Cl_CTdiff``, ``C*_CT``) are
#: aerodynamic and stay.
PROPULSIVE_TERMS = frozenset({"Cn_CTdiff"})

#: Δ-model channel -> JSBSim property (or ``*``-separated product of properties and numbers).
#: Angles in deg, rates non-dimensional (``p b/(2V)`` = ``p [rad/s] * aero/bi2vel``).
#: Controls follow the project's convention (Etkin: positive aileron rolls left, positive
#: rudder yaws left), so they default to ``aerodelta/...`` properties the aircraft must set.
DEFAULT_PROPERTIES: dict[str, str] = {
    "alpha_deg": "aero/alpha-deg",
    "beta_deg": "aero/beta-deg",
    "beta_rad": "aero/beta-rad",
    "flap_deg": "fcs/flap-pos-deg",
    "phat": "velocities/p-aero-rad_sec * aero/bi2vel",
    "qhat": "velocities/q-aero-rad_sec * aero/ci2vel",
    "rhat": "velocities/r-aero-rad_sec * aero/bi2vel",
    "alphadot_dps": "aero/alphadot-deg_sec",
    "betadot_dps": "aero/betadot-deg_sec",
    "da_deg": "aerodelta/da-deg",
    "de_deg": "aerodelta/de-deg",
    "dr_deg": "aerodelta/dr-deg",
    "dsl_deg": "aerodelta/dsl-deg",
    "dsr_deg": "aerodelta/dsr-deg",
    "ct_left": "aerodelta/ct-left",
    "ct_right": "aerodelta/ct-right",
}

#: Coefficient -> (JSBSim axis, reference-length property or None for a force).
_AXES = {"CY": ("SIDE", None), "Cl": ("ROLL", "metrics/bw-ft"), "Cn": ("YAW", "metrics/bw-ft")}


def _num(x: float) -> str:
    return repr(float(x))


#: A JSBSim property path: components ``[A-Za-z_][A-Za-z0-9_.-]*`` with an optional ``[index]``
#: joined by ``/`` (SimGear's property names), optionally rooted at ``/``; a leading ``-``
#: negates it in a function (JSBSim's FGPropertyValue).
_PROPERTY = re.compile(
    r"-?/?[A-Za-z_][A-Za-z0-9_.\-]*(?:\[[0-9]+\])?(?:/[A-Za-z_][A-Za-z0-9_.\-]*(?:\[[0-9]+\])?)*"
)


def _property(name: str, what: str) -> str:
    """``name`` if it is a JSBSim property path (so it needs no XML escaping), else a
    ``DataError`` naming ``what`` it is for."""
    if _PROPERTY.fullmatch(name) is None:
        raise DataError(
            f"{what}: '{name}' is not a JSBSim property name; use letters, digits, _ - . and "
            "/ between the parts (e.g. fcs/left-aileron-pos-deg, propulsion/engine[1]/thrust-lbs)"
        )
    return name


def _factors(expr: str, channel: str = "") -> list[str]:
    what = f"JSBSim property mapping '{expr}'" + (f" of channel '{channel}'" if channel else "")
    out = [f.strip() for f in expr.split("*")]
    if not out or any(not f for f in out):
        raise DataError(f"{what}: give properties/numbers joined by '*'")
    for f in out:
        if _is_number(f):
            if not math.isfinite(float(f)):
                raise DataError(f"{what}: '{f}' is not a finite number")
        else:
            _property(f, what)
    return out


def _comment(text: str) -> str:
    """``text`` safe inside an XML comment: escaped, with no ``--`` and no trailing ``-``."""
    out = escape(text)
    while "--" in out:
        out = out.replace("--", "- -")
    return out + " " if out.endswith("-") else out


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


class _Writer:
    """Translates the model into JSBSim function elements, tracking the channels it reads."""

    def __init__(self, model: DeltaModel, properties: Mapping[str, str]) -> None:
        self.spec = model.to_spec()
        self.props = {**DEFAULT_PROPERTIES, **properties}
        self.channel_fns: list[str] = []  # functions defining channels (mapped or derived)
        self.channel_prop: dict[str, str] = {}
        self.declared: list[str] = []  # aerodelta/... properties the file declares
        flaps = [float(f) for f in self.spec["flaps_deg"]]
        # JSBSim tables need two breakpoints per axis: repeat a lone flap row (same values).
        self.flaps = flaps if len(flaps) > 1 else [flaps[0], flaps[0] + 1.0]
        self.pad = len(flaps) == 1

    def channel(self, ch: str) -> str:
        """The property holding channel ``ch`` (defining a function for it when needed)."""
        if ch in self.channel_prop:
            return self.channel_prop[ch]
        name = _property(
            f"aero/aerodelta/in/{ch}",
            f"Δ-model channel '{ch}' (the export names a property after it; rename the channel)",
        )
        if ch in self.props:
            fs = _factors(self.props[ch], ch)
            for f in fs:
                if f.startswith("aerodelta/") and f not in self.declared:
                    self.declared.append(f)
            if len(fs) == 1 and not _is_number(fs[0]):
                self.channel_prop[ch] = fs[0]
                return fs[0]
            body = "".join(
                f"<value>{_num(float(f))}</value>" if _is_number(f) else f"<property>{f}</property>"
                for f in fs
            )
            inner = body if len(fs) == 1 else f"<product>{body}</product>"
        elif ch in DERIVED_CHANNELS:
            inner = self.expr(parse_regressor(DERIVED_CHANNELS[ch]))
        else:
            raise DataError(
                f"Δ-model channel '{ch}' has no JSBSim property: map it with "
                f"properties={{'{ch}': 'some/property'}} (CLI --property {ch}=some/property)"
            )
        self.channel_fns.append(
            f'  <function name="{name}">\n    <description>Δ-model channel {escape(ch)}'
            f"</description>\n    {inner}\n  </function>"
        )
        self.channel_prop[ch] = name
        return name

    def expr(self, n: Node) -> str:
        """JSBSim function elements of a regressor expression."""
        zero = "<value>0</value>"
        a = [self.expr(x) for x in n.args]
        if n.op == "const":
            return f"<value>{_num(n.value)}</value>"
        if n.op == "col":
            return f"<property>{self.channel(n.name)}</property>"
        simple = {"+": "sum", "-": "difference", "*": "product", "/": "quotient", "^": "pow",
                  "abs": "abs", "sin": "sin", "cos": "cos", "exp": "exp", "min": "min",
                  "max": "max"}  # fmt: skip
        if n.op in simple:
            t = simple[n.op]
            return f"<{t}>{''.join(a)}</{t}>"
        if n.op == "minus":
            return f"<product><value>-1</value>{a[0]}</product>"
        if n.op == "pos":
            return f"<max>{a[0]}{zero}</max>"
        if n.op == "neg":
            return f"<min>{a[0]}{zero}</min>"
        if n.op == "deadband":
            x, k = a
            return (
                f"<sum><max><difference>{x}{k}</difference>{zero}</max>"
                f"<min><sum>{x}{k}</sum>{zero}</min></sum>"
            )
        if n.op == "step":
            return f"<ifthen><gt>{a[0]}{zero}</gt><value>1</value>{zero}</ifthen>"
        if n.op == "sqrt":
            return f"<pow>{a[0]}<value>0.5</value></pow>"
        raise DataError(f"regressor function '{n.op}' has no JSBSim form")

    def table2(self, term: dict[str, Any], alpha_p: str, flap_p: str) -> str:
        rows = term["values"] * 2 if self.pad else term["values"]
        lines = ["        " + " ".join(f"{_num(f):>10}" for f in self.flaps)]
        for j, a in enumerate(term["alpha_deg"]):
            vals = " ".join(_num(r[j]) for r in rows)
            lines.append(f"        {_num(a)} {vals}")
        body = "\n".join(lines)
        return (
            f'<table>\n      <independentVar lookup="row">{alpha_p}</independentVar>\n'
            f'      <independentVar lookup="column">{flap_p}</independentVar>\n'
            f"      <tableData>\n{body}\n      </tableData>\n    </table>"
        )

    def limited(self, ch: str, lo: float | None, hi: float | None) -> str:
        """The property of channel ``ch`` clamped to ``[lo, hi]`` (DAVE-ML min/maxValue)."""
        prop = self.channel(ch)
        if lo is None and hi is None:
            return prop
        name = f"aero/aerodelta/in/{ch}-limited"
        if name not in self.channel_prop.values():
            inner = f"<property>{prop}</property>"
            if lo is not None:
                inner = f"<max>{inner}<value>{_num(lo)}</value></max>"
            if hi is not None:
                inner = f"<min>{inner}<value>{_num(hi)}</value></min>"
            self.channel_fns.append(
                f'  <function name="{name}">\n    <description>{escape(ch)} within the qualified '
                f"model's limits</description>\n    {inner}\n  </function>"
            )
            self.channel_prop[f"{ch} (limited)"] = name
        return name

    def gridded(self, props: list[str], breakpoints: list[list[float]], values: list[float]) -> str:
        """A JSBSim table of 1-3 dimensions (row, column, table), values row-major with the
        last axis fastest as the DAVE-ML writer's."""
        bps = [list(map(float, b)) for b in breakpoints]
        v = np.asarray(values, dtype=np.float64).reshape([len(b) for b in bps])
        # JSBSim lookups: 1-D row; 2-D row, column; 3-D table, row, column.
        if v.ndim == 1:
            rows = "\n".join(f"        {_num(a)} {_num(x)}" for a, x in zip(bps[0], v, strict=True))
            return (
                f"<table>\n      <independentVar>{props[0]}</independentVar>\n"
                f"      <tableData>\n{rows}\n      </tableData>\n    </table>"
            )

        def block(m: np.ndarray, rb: list[float], cb: list[float]) -> str:
            lines = ["        " + " ".join(_num(c) for c in cb)]
            lines += [
                f"        {_num(r)} " + " ".join(_num(x) for x in row)
                for r, row in zip(rb, m, strict=True)
            ]
            return "\n".join(lines)

        if v.ndim == 2:
            return (
                f'<table>\n      <independentVar lookup="row">{props[0]}</independentVar>\n'
                f'      <independentVar lookup="column">{props[1]}</independentVar>\n'
                f"      <tableData>\n{block(v, bps[0], bps[1])}\n      </tableData>\n    </table>"
            )
        if v.ndim == 3:
            data = "\n".join(
                f'      <tableData breakPoint="{_num(t)}">\n{block(v[k], bps[1], bps[2])}\n'
                "      </tableData>"
                for k, t in enumerate(bps[0])
            )
            return (
                f'<table>\n      <independentVar lookup="row">{props[1]}</independentVar>\n'
                f'      <independentVar lookup="column">{props[2]}</independentVar>\n'
                f'      <independentVar lookup="table">{props[0]}</independentVar>\n'
                f"{data}\n    </table>"
            )
        raise DataError(f"a {v.ndim}-D table has no JSBSim form here (1-3 dimensions)")

    def table1(self, values: list[float], flap_p: str) -> str:
        vals = values * 2 if self.pad else values
        rows = "\n".join(
            f"        {_num(f)} {_num(v)}" for f, v in zip(self.flaps, vals, strict=True)
        )
        return (
            f"<table>\n      <independentVar>{flap_p}</independentVar>\n"
            f"      <tableData>\n{rows}\n      </tableData>\n    </table>"
        )


def _sum(items: list[str], sep: str) -> str:
    """``<sum>`` of the items; one item alone stands for itself (JSBSim warns that a one-argument
    ``<sum>`` is a no-op) and none is zero."""
    if not items:
        return "<value>0</value>"
    if len(items) == 1:
        return items[0].strip()
    return f"<sum>{sep}" + sep.join(items) + "\n    </sum>"


def _qualified_table(
    w: _Writer, vid: str, qspec: dict[str, Any], done: set[str], fns: list[str]
) -> str:
    """``aero/aerodelta/qualified/<vid>``: a table of a writer spec (its inputs clamped to the
    spec's limits) as a JSBSim function, appended to ``fns`` the first time (``done``)."""
    name = f"aero/aerodelta/qualified/{vid}"
    if vid not in done:
        done.add(vid)
        inputs = {i["id"]: i for i in qspec["inputs"]}
        t = next(t for t in qspec["tables"] if t["id"] == vid)
        args = [w.limited(a, inputs[a].get("min"), inputs[a].get("max")) for a in t["args"]]
        fns.append(
            f'  <function name="{name}">\n    '
            f"{w.gridded(args, t['breakpoints'], t['values'])}\n  </function>"
        )
    return name


def _qualified_functions(w: _Writer, cname: str, qspec: dict[str, Any], done: set[str]) -> str:
    """``aero/aerodelta/<C>/qualified``: a coefficient of a writer spec (sum of products of
    tables and inputs, e.g. the built-in ADX-37 qualified model) as JSBSim functions."""
    inputs = {i["id"]: i for i in qspec["inputs"]}
    tables = {t["id"]: t for t in qspec["tables"]}
    out = {o["id"]: o for o in qspec["outputs"]}
    if cname not in out:
        raise DataError(f"the qualified model has no output '{cname}'")
    fns: list[str] = []

    def prop(vid: str) -> str:
        if vid in tables:
            return _qualified_table(w, vid, qspec, done, fns)
        if vid in inputs:
            return w.limited(vid, inputs[vid].get("min"), inputs[vid].get("max"))
        raise DataError(f"qualified output {cname}: factor '{vid}' has no JSBSim form")

    prods = []
    for term in out[cname]["terms"]:
        if any(f in PROPULSIVE_TERMS for f in term["factors"]):
            continue  # JSBSim's propulsion applies the thrust at the engines
        facs = [f"<property>{prop(f)}</property>" for f in term["factors"]]
        if term.get("coef", 1.0) != 1.0 or not facs:
            facs.insert(0, f"<value>{_num(term.get('coef', 1.0))}</value>")
        prods.append(facs[0] if len(facs) == 1 else f"<product>{''.join(facs)}</product>")
    fns.append(
        f'  <function name="aero/aerodelta/{cname}/qualified">\n    <description>qualified '
        f"{cname}</description>\n    " + _sum(prods, "\n      ") + "\n  </function>"
    )
    return "\n".join(fns)


#: Property prefix of the stall's separation state (``aero/aerodelta/stall/...`` in the
#: aerodynamics, ``aerodelta/stall/...`` in the ``<system>`` holding the previous frame).
STALL_PREFIX = "aerodelta/stall"


def _stall_flaps(model: DeltaModel) -> list[tuple[float, dict[str, float]]]:
    """The stored stall's scalar parameters per flap setting, in either form of its separation
    curve (``DeltaModel.stall_form``; the table's curve is ``DeltaModel.separation_tables``),
    fitted with ``known`` ``"adx37"`` or ``"none"`` (the two variants of
    :func:`_stall_functions`; the model file allows no other basis)."""
    return sorted((float(f), dict(p)) for f, p in (model.kirchhoff or {}).items())


def _logistic(k: float, u: str, centre: float) -> str:
    """``1 / (1 + exp(k (u - centre)))`` as JSBSim function elements (``u`` one element).
    With ``k = 2 a1`` it is ``x0(u) = (1 - tanh(a1 (u - alpha*))) / 2``, with ``k = -2 a1``
    the separated fraction ``1 - x0(u)``."""
    return (
        "<quotient><value>1</value><sum><value>1</value><exp><product>"
        f"<value>{_num(k)}</value><difference>{u}<value>{_num(centre)}</value></difference>"
        "</product></exp></sum></quotient>"
    )


def _spline_x0(table: tuple[FloatArray, FloatArray], s_prop: str) -> str:
    """The tabulated separation curve ``x0`` at the knot coordinate held in the property
    ``s_prop`` (:func:`_spline_coordinate`), as JSBSim function elements: the sum of
    :class:`aerodelta.export.SplineLayout`, ``aero_core::goman_khrabrov::X0Table`` exactly."""
    sp = f"<property>{s_prop}</property>"

    def cube(reach: int, k: int) -> str:
        return (
            f"<pow><max><value>0</value><difference><value>{reach}</value><abs><difference>{sp}"
            f"<value>{k}</value></difference></abs></difference></max><value>3</value></pow>"
        )

    terms = [
        f"<product><value>{_num(c)}</value><difference>{cube(2, k)}<product><value>4</value>"
        f"{cube(1, k)}</product></difference></product>"
        for k, c in SplineLayout.of(table).terms
    ]
    return f"<quotient>{_sum(terms, '')}<value>6</value></quotient>"


def _spline_coordinate(table: tuple[FloatArray, FloatArray], u: str) -> str:
    """The knot coordinate of ``u`` (rad, one element) held in ``[0, K - 1]``
    (:class:`aerodelta.export.SplineLayout`); the curve is constant beyond the end knots."""
    lay = SplineLayout.of(table)
    return (
        f"<min><value>{lay.top}</value><max><value>0</value><quotient><difference>{u}"
        f"<value>{_num(lay.origin)}</value></difference><value>{_num(lay.spacing)}</value>"
        "</quotient></max></min>"
    )


def _stall_static_separated(
    g: Mapping[str, float],
    alpha_p: str,
    alphadot_p: str,
    table: tuple[FloatArray, FloatArray] | None = None,
    s_prop: str = "",
) -> str:
    """``1 - x0(alpha - tau2 alphadot)`` (alpha in deg, alphadot in deg/s read from the
    properties); for the tabulated form (``table``) from the knot coordinate of the lagged
    alpha in the property ``s_prop`` (:func:`_spline_coordinate`)."""
    if table is not None:
        return f"<difference><value>1</value>{_spline_x0(table, s_prop)}</difference>"
    return _logistic(-2.0 * g["a1"], _lagged_alpha(g, alpha_p, alphadot_p), g["alpha_star"])


def _lagged_alpha(g: Mapping[str, float], alpha_p: str, alphadot_p: str) -> str:
    """``alpha - tau2 alphadot``, rad, from the properties (deg, deg/s)."""
    d2r = math.pi / 180.0
    return (
        f"<difference><product><property>{alpha_p}</property><value>{_num(d2r)}</value>"
        f"</product><product><property>{alphadot_p}</property>"
        f"<value>{_num(g['tau2'] * d2r)}</value></product></difference>"
    )


def _stall_on(flap_p: str, f: float) -> str:
    """1 at flap setting ``f`` (within the engine's exact match), else 0."""
    lo, hi = _num(f - STALL_FLAP_WINDOW_DEG), _num(f + STALL_FLAP_WINDOW_DEG)
    return (
        f"<and><ge><property>{flap_p}</property><value>{lo}</value></ge>"
        f"<le><property>{flap_p}</property><value>{hi}</value></le></and>"
    )


def jsbsim_stall_system_xml(model: DeltaModel) -> str:
    """The JSBSim ``<system>`` that carries the stored Kirchhoff stall's separation state from
    one frame to the next.

    JSBSim runs its systems before it computes alpha and the aerodynamics, so the state is
    stepped in the aerodynamics (:func:`jsbsim_xml`), with the frame's own alpha and alphadot,
    and this system only hands each frame's result to the next: per stored flap setting ``i``
    two ``<fcs_function>`` copies, ``aerodelta/stall/flap-<i>/separated-previous`` (the
    separated fraction ``1 - x`` after the previous frame) and ``.../separated-static-previous``
    (the previous frame's ``1 - x0(alpha - tau2 alphadot)``). Both start at 0, attached flow.
    Load it with the aircraft (``<system file="..."/>``) beside the aerodynamics.

    Raises
    ------
    DataError
        The model stores no stall, or one fitted with ``known="none"``.
    """
    if not model.kirchhoff:
        raise DataError(
            "the model stores no longitudinal stall (aerodelta longitudinal --model M "
            "--out-model M2 adds one): there is no separation state to carry"
        )
    parts = []
    for i, (f, _) in enumerate(_stall_flaps(model)):
        for what, desc in (("separated", "1 - x"), ("separated-static", "1 - x0")):
            parts.append(
                f'    <fcs_function name="{STALL_PREFIX}/flap-{i}/{what}-previous">\n'
                f"      <description>flap {f:g} deg: {desc} of the previous frame</description>\n"
                f"      <function><property>aero/{STALL_PREFIX}/flap-{i}/{what}</property>"
                "</function>\n    </fcs_function>"
            )
    prov = model.to_spec().get("provenance") or {}
    header = (
        '<?xml version="1.0"?>\n<!--\n  aerodelta Kirchhoff stall: the separation state of the '
        f"model's longitudinal stall carried between frames, written by "
        f"{_comment(str(prov.get('library', 'aerodelta')))}; model data sha256 "
        f"{_comment(str(prov.get('data_sha256', '?')))}.\n  Load it with the aircraft beside "
        "the exported aerodynamics, which step the state and read these copies.\n-->\n"
    )
    return (
        header + '<system name="aerodelta-stall">\n  <channel name="separation">\n'
        + "\n".join(parts) + "\n  </channel>\n</system>\n"
    )  # fmt: skip


#: The force axes of the stall's lift and drag increments per JSBSim axis system: wind
#: (``LIFT``, ``DRAG``), body ``AXIAL``/``NORMAL`` (with ``SIDE``), body ``X``/``Z`` (with ``Y``).
STALL_AXES = ("LIFT", "AXIAL", "X")


def stall_axes_for(side_axis: str, stall_axes: str | None) -> str:
    """The stall's force axes for ``side_axis`` (:data:`STALL_AXES`; default ``LIFT`` with
    ``SIDE``, ``X`` with ``Y``); a pair JSBSim's axis systems do not hold is refused."""
    axes = stall_axes or ("X" if side_axis == "Y" else "LIFT")
    if axes not in STALL_AXES:
        raise DataError(
            f"stall_axes '{axes}': use 'LIFT' (DRAG/SIDE/LIFT aircraft), 'AXIAL' "
            "(AXIAL/SIDE/NORMAL aircraft) or 'X' (X/Y/Z aircraft)"
        )
    if (axes == "X") != (side_axis == "Y"):
        raise DataError(
            f"stall_axes '{axes}' with side_axis '{side_axis}': JSBSim's axis systems are "
            "DRAG/SIDE/LIFT, AXIAL/SIDE/NORMAL and X/Y/Z; give LIFT or AXIAL with SIDE, X with Y"
        )
    return axes


def _stall_functions(
    w: _Writer, model: DeltaModel, stall_axes: str, done: set[str]
) -> tuple[list[str], dict[str, list[str]]]:
    """The aerodynamics' part of the stored stall: ``aero/aerodelta/stall/x`` (1 attached,
    0 separated; 1 at a flap setting without a stall), the increments ``CL-delta``,
    ``Cm-delta`` (and ``CD-delta`` when a flap stores the stall's drag) at each flap setting
    with a stall (0 elsewhere) and the axis functions (``stall_axes``): ``LIFT`` (and
    ``DRAG``; wind axes), ``AXIAL``, ``NORMAL`` (body axes: ``D cos(alpha) - L sin(alpha)``,
    ``L cos(alpha) + D sin(alpha)``) or ``X``, ``Z`` (body axes: ``L sin(alpha) - D cos(alpha)``,
    ``-L cos(alpha) - D sin(alpha)``), and ``PITCH``.

    The increments of a stall fitted with ``known="adx37"`` are the Kirchhoff curves less the
    ADX-37 qualified static curves ``CL_basic``, ``Cm_basic`` they replace. One fitted with
    ``known="none"`` describes the whole measured coefficients, whose static curves the
    aircraft's own tables already hold: its increments are the separation dynamics alone, the
    Kirchhoff curves at the state ``x`` less the same curves at the static state ``x0(alpha)``
    (0 in steady flight; ``aero/aerodelta/stall/flap-<i>/x-static``)."""
    flaps = _stall_flaps(model)
    dynamics_only = model.kirchhoff_known == "none"
    spec = w.spec
    alpha_p = w.channel(spec.get("alpha_channel", "alpha_deg"))
    flap_p = w.channel(spec.get("flap_channel", "flap_deg"))
    fns: list[str] = []
    drags = model.kirchhoff_drag
    if not dynamics_only:
        qspec = qualified_daveml_spec()
        cl_basic = _qualified_table(w, "CL_basic", qspec, done, fns)
        cm_basic = _qualified_table(w, "Cm_basic", qspec, done, fns)
        cd_basic = _qualified_table(w, "CD_basic", qspec, done, fns) if drags else ""
    alphadot_p = w.channel("alphadot_dps")
    tables = model.separation_tables
    # the exact step of the ODE for an input linear over the frame (first-order hold, as
    # aero_core::kirchhoff::step): r = dt / tau1, e = exp(-r), g = 1 - (1 - e) / r,
    # s = e s_prev + (1 - e - g) v_prev + g v on the separated fraction s = 1 - x, v = 1 - x0
    # (a frame of dt = 0, as JSBSim's initial conditions run, keeps the state; r is floored
    # so that e and g stay finite there)
    for i, (f, g) in enumerate(flaps):
        base, prev = f"aero/{STALL_PREFIX}/flap-{i}", f"{STALL_PREFIX}/flap-{i}"
        r = (
            f"<quotient><max><property>simulation/dt</property><value>1e-12</value></max>"
            f"<value>{_num(g['tau1'])}</value></quotient>"
        )
        e_fn = f"<exp><product><value>-1</value>{r}</product></exp>"
        g_fn = (
            f"<difference><value>1</value><quotient><difference><value>1</value>{e_fn}"
            f"</difference>{r}</quotient></difference>"
        )
        e, gg = f"<property>{base}/e</property>", f"<property>{base}/g</property>"
        fns.append(
            f'  <function name="{base}/e">\n    <description>flap {f:g} deg: exp(-dt/tau1)'
            f'</description>\n    {e_fn}\n  </function>\n  <function name="{base}/g">\n'
            f"    <description>flap {f:g} deg: 1 - (1 - e) tau1/dt</description>\n    {g_fn}\n"
            "  </function>"
        )
        table = tables.get(f)
        if table is not None:
            fns.append(
                f'  <function name="{base}/knot-lagged">\n    <description>flap {f:g} deg: '
                "the separation table's knot coordinate of alpha - tau2 alphadot</description>"
                f"\n    {_spline_coordinate(table, _lagged_alpha(g, alpha_p, alphadot_p))}\n"
                "  </function>"
            )
        fns.append(
            f'  <function name="{base}/separated-static">\n    <description>flap {f:g} deg: '
            "1 - x0(alpha - tau2 alphadot), the separated fraction the flow tends to"
            f"</description>\n    "
            f"{_stall_static_separated(g, alpha_p, alphadot_p, table, f'{base}/knot-lagged')}"
            "\n  </function>"
        )
        fns.append(
            f'  <function name="{base}/separated">\n    <description>flap {f:g} deg: 1 - x, '
            f"tau1 {_num(g['tau1'])} s (Fischenberg: tau1 x' + x = x0(alpha - tau2 alphadot)), "
            "stepped exactly over the frame; held in a frame of dt = 0</description>\n    "
            "<ifthen><gt><property>simulation/dt</property><value>0</value></gt>"
            "<min><value>1</value><max><value>0</value><sum>"
            f"<product>{e}<property>{prev}/separated-previous</property></product>"
            f"<product><difference><difference><value>1</value>{e}</difference>{gg}</difference>"
            f"<property>{prev}/separated-static-previous</property></product>"
            f"<product>{gg}<property>{base}/separated-static</property></product>"
            f"</sum></max></min><property>{prev}/separated-previous</property></ifthen>\n"
            "  </function>"
        )
    sep = _sum(
        [
            f"<product>{_stall_on(flap_p, f)}<property>aero/{STALL_PREFIX}/flap-{i}/separated"
            "</property></product>"
            for i, (f, _) in enumerate(flaps)
        ],
        "",
    )
    x = "aero/aerodelta/stall/x"
    fns.append(
        f'  <function name="{x}">\n    <description>separation point of the Kirchhoff stall '
        "(1 attached, 0 separated); 1 at a flap setting without a stall</description>\n"
        f"    <difference><value>1</value>{sep}</difference>\n  </function>"
    )
    xp = f"<property>{x}</property>"
    a_rad = (
        f"<product><property>{alpha_p}</property><value>{_num(math.pi / 180.0)}</value></product>"
    )
    cl_terms, cm_terms, cd_terms = [], [], []

    def lift(g: Mapping[str, float], x: str) -> str:
        """``C_La (alpha - alpha0) ((1 + sqrt(x)) / 2)^2``"""
        return (
            f"<product><value>{_num(g['CL_alpha'])}</value><difference>{a_rad}"
            f"<value>{_num(g['alpha0'])}</value></difference><pow><product><value>0.5</value>"
            f"<sum><value>1</value><pow>{x}<value>0.5</value></pow></sum></product>"
            "<value>2</value></pow></product>"
        )

    for i, (f, g) in enumerate(flaps):
        on = _stall_on(flap_p, f)
        if dynamics_only:
            xs = f"aero/{STALL_PREFIX}/flap-{i}/x-static"
            table = tables.get(f)
            if table is None:
                static = _logistic(2.0 * g["a1"], a_rad, g["alpha_star"])
                form = "1 / (1 + exp(2 a1 (alpha - alpha*)))"
            else:
                ks = f"aero/{STALL_PREFIX}/flap-{i}/knot-static"
                fns.append(
                    f'  <function name="{ks}">\n    <description>flap {f:g} deg: the '
                    "separation table's knot coordinate of alpha</description>\n    "
                    f"{_spline_coordinate(table, a_rad)}\n  </function>"
                )
                static = _spline_x0(table, ks)
                form = "the separation table's cubic B-spline"
            fns.append(
                f'  <function name="{xs}">\n    <description>flap {f:g} deg: the static '
                f"separation point x0(alpha), {form}</description>"
                f"\n    {static}\n  </function>"
            )
            dcl = f"<difference>{lift(g, xp)}{lift(g, f'<property>{xs}</property>')}</difference>"
            dcm = (
                f"<product><value>{_num(g['Cm_x'])}</value><difference><property>{xs}"
                f"</property>{xp}</difference></product>"
            )
        else:
            moment = (
                f"<sum><value>{_num(g['Cm0'])}</value><product><value>{_num(g['Cm_alpha'])}"
                f"</value>{a_rad}</product><product><value>{_num(g['Cm_x'])}</value><difference>"
                f"<value>1</value>{xp}</difference></product></sum>"
            )
            dcl = f"<difference>{lift(g, xp)}<property>{cl_basic}</property></difference>"
            dcm = f"<difference>{moment}<property>{cm_basic}</property></difference>"
        cl_terms.append(f"<product>{on}{dcl}</product>")
        cm_terms.append(f"<product>{on}{dcm}</product>")
        d = drags.get(f)
        if d is not None:
            # C_D = CD0 + CD_k C_L(alpha, x)^2 + CD_x (1 - x) (aero_core KirchhoffDrag)
            def polar(x: str, lift_at: str, d: Mapping[str, float] = d) -> str:
                return (
                    f"<sum><value>{_num(d['CD0'])}</value><product><value>{_num(d['CD_k'])}"
                    f"</value><pow>{lift_at}<value>2</value></pow></product><product>"
                    f"<value>{_num(d['CD_x'])}</value><difference><value>1</value>{x}"
                    "</difference></product></sum>"
                )

            here = polar(xp, lift(g, xp))
            if dynamics_only:
                xsp = f"<property>aero/{STALL_PREFIX}/flap-{i}/x-static</property>"
                dcd = f"<difference>{here}{polar(xsp, lift(g, xsp))}</difference>"
            else:
                dcd = f"<difference>{here}<property>{cd_basic}</property></difference>"
            cd_terms.append(f"<product>{on}{dcd}</product>")
    flaps_txt = ", ".join(f"{f:g}" for f, _ in flaps)
    less = (
        "the same curve at the static separation point (the separation dynamics over the "
        "aircraft's own static curve)"
        if dynamics_only
        else "the qualified static curve it replaces"
    )
    incs = [("CL", cl_terms, "lift"), ("Cm", cm_terms, "pitching moment")]
    if cd_terms:
        incs.append(("CD", cd_terms, "drag"))
    for c, terms, what in incs:
        fns.append(
            f'  <function name="aero/aerodelta/stall/{c}-delta">\n    <description>Kirchhoff '
            f"{what} less {less}, at flaps {flaps_txt} deg; 0 elsewhere</description>\n    "
            f"{_sum(terms, '')}\n  </function>"
        )
    qs = "<property>aero/qbar-psf</property><property>metrics/Sw-sqft</property>"
    cl = "<property>aero/aerodelta/stall/CL-delta</property>"
    axes: dict[str, list[str]] = {}

    def force(axis: str, name: str, what: str, body: str) -> None:
        axes.setdefault(axis, []).append(
            f'    <function name="aero/force/aerodelta-{name}">\n      <description>{what} '
            f"(lbf)</description>\n      {body}\n    </function>"
        )

    cd = "<property>aero/aerodelta/stall/CD-delta</property>"
    if stall_axes == "AXIAL":
        force(
            "AXIAL",
            "CA-stall",
            "body axial force (positive aft) of the stall's lift increment, -L sin(alpha)",
            f"<product><value>-1</value>{qs}{cl}<sin>{a_rad}</sin></product>",
        )
        force(
            "NORMAL",
            "CN-stall",
            "body normal force (positive up) of the stall's lift increment, L cos(alpha)",
            f"<product>{qs}{cl}<cos>{a_rad}</cos></product>",
        )
        if cd_terms:
            force(
                "AXIAL",
                "CA-stall-drag",
                "body axial force of the stall's drag increment, D cos(alpha)",
                f"<product>{qs}{cd}<cos>{a_rad}</cos></product>",
            )
            force(
                "NORMAL",
                "CN-stall-drag",
                "body normal force of the stall's drag increment, D sin(alpha)",
                f"<product>{qs}{cd}<sin>{a_rad}</sin></product>",
            )
    elif stall_axes == "X":
        force(
            "X",
            "CX-stall",
            "body x force of the stall's lift increment, L sin(alpha)",
            f"<product>{qs}{cl}<sin>{a_rad}</sin></product>",
        )
        force(
            "Z",
            "CZ-stall",
            "body z force of the stall's lift increment, -L cos(alpha)",
            f"<product><value>-1</value>{qs}{cl}<cos>{a_rad}</cos></product>",
        )
        if cd_terms:
            force(
                "X",
                "CX-stall-drag",
                "body x force of the stall's drag increment, -D cos(alpha)",
                f"<product><value>-1</value>{qs}{cd}<cos>{a_rad}</cos></product>",
            )
            force(
                "Z",
                "CZ-stall-drag",
                "body z force of the stall's drag increment, -D sin(alpha)",
                f"<product><value>-1</value>{qs}{cd}<sin>{a_rad}</sin></product>",
            )
    else:
        force("LIFT", "CL-stall", "lift increment of the stall", f"<product>{qs}{cl}</product>")
        if cd_terms:
            force("DRAG", "CD-stall", "drag increment of the stall", f"<product>{qs}{cd}</product>")
    axes["PITCH"] = [
        '    <function name="aero/moment/aerodelta-Cm-stall">\n      <description>pitching '
        "moment increment of the stall (ft lbf)</description>\n      <product>"
        f"{qs}<property>metrics/cbarw-ft</property><property>aero/aerodelta/stall/Cm-delta"
        "</property></product>\n    </function>"
    ]  # fmt: skip
    return fns, axes


#: Sideslip limits of an alpha band the flight data do not cover (a hole between covered
#: bands): no sideslip lies inside.
_NO_BETA = 1e30


def _envelope_function(env: Mapping[str, Any], alpha_p: str, beta_p: str, flap_p: str) -> str:
    """``aero/aerodelta/in-envelope``: 1 when the state lies inside the validated envelope
    stored with the model, else 0, by the rule of ``aero_core::envelope``: the alpha band
    ``floor(alpha / band_deg)`` of the nearest flap setting (the lower one on a tie) is covered
    and beta lies in its measured range. JSBSim's ``<switch>`` picks the flap and the band (its
    index is kept inside the list: JSBSim stops on an index out of range)."""
    band_deg = float(env["band_deg"])
    flaps = [float(f) for f in env["flaps_deg"]]
    alpha = f"<property>{alpha_p}</property>"
    beta = f"<property>{beta_p}</property>"
    band = f"<floor><quotient>{alpha}<value>{_num(band_deg)}</value></quotient></floor>"

    def switch(index: str, values: list[str]) -> str:
        return values[0] if len(values) == 1 else f"<switch>{index}{''.join(values)}</switch>"

    per_flap = []
    for bands in env["bands"]:
        if not bands:
            per_flap.append("<value>0</value>")
            continue
        b0, b1 = int(bands[0]["band"]), int(bands[-1]["band"])
        lo = [_NO_BETA] * (b1 - b0 + 1)
        hi = [-_NO_BETA] * (b1 - b0 + 1)
        for b in bands:
            lo[int(b["band"]) - b0] = float(b["beta_min_deg"])
            hi[int(b["band"]) - b0] = float(b["beta_max_deg"])
        index = (
            f"<min><max><difference>{band}<value>{b0}</value></difference><value>0</value></max>"
            f"<value>{b1 - b0}</value></min>"
        )
        lo_v = switch(index, [f"<value>{_num(v)}</value>" for v in lo])
        hi_v = switch(index, [f"<value>{_num(v)}</value>" for v in hi])
        per_flap.append(
            f"<and><ge>{band}<value>{b0}</value></ge><le>{band}<value>{b1}</value></le>"
            f"<ge>{beta}{lo_v}</ge><le>{beta}{hi_v}</le></and>"
        )
    nearest = _sum(
        [
            f"<gt><property>{flap_p}</property><value>{_num(0.5 * (a + b))}</value></gt>"
            for a, b in itertools.pairwise(flaps)
        ],
        "",
    )
    body = switch(nearest, per_flap)
    return (
        '  <function name="aero/aerodelta/in-envelope">\n    <description>1 inside the '
        "validated envelope of the flight data (the alpha band of the nearest flap setting "
        "is covered and beta lies in its measured range), 0 outside: the indication a "
        f"simulator shows its instructor</description>\n    {body}\n  </function>"
    )


def jsbsim_xml(
    model: DeltaModel,
    properties: Mapping[str, str] | None = None,
    *,
    side_axis: str = "SIDE",
    qualified: bool = False,
    longitudinal: bool = True,
    stall_axes: str | None = None,
) -> str:
    """The JSBSim ``<aerodynamics>`` text of the blended Δ model (see the module docstring).

    Parameters
    ----------
    model
        The fitted Δ model.
    properties
        Overrides of :data:`DEFAULT_PROPERTIES`: channel -> property, or a ``*``-separated
        product of properties and numbers (e.g. ``{"da_deg": "-1 * fcs/left-aileron-pos-deg"}``).
    side_axis
        Axis of the side force: ``"SIDE"`` (aircraft using AXIAL/SIDE/NORMAL body axes, where
        it is exactly the body-axis ``CY``, or DRAG/SIDE/LIFT wind axes, where JSBSim takes it
        as the wind-axis side force: a difference of order ``1 - cos(beta)``) or ``"Y"``
        (aircraft using X/Y/Z body axes).
    qualified
        Also write the built-in ADX-37 qualified model's CY, Cl, Cn
        (``aero/aerodelta/<C>/qualified``, ``.../extended`` = qualified + w ΔC) and put the
        extended coefficients on the axes: the file is then the aircraft's whole
        lateral-directional aerodynamics, without the thrust's own moment
        (:data:`PROPULSIVE_TERMS`), which JSBSim's propulsion applies.
    longitudinal
        Carry the Kirchhoff stall the model stores (:meth:`DeltaModel.with_longitudinal`):
        the lift and pitching-moment increments (and the drag's, where the model stores the
        stall's drag) of the Kirchhoff curves over the ADX-37 qualified static curves
        ``CL_basic``, ``Cm_basic``, ``CD_basic`` (fitted with ``known="adx37"``) or, fitted with
        ``known="none"``, over the same curves at the static separation point (the separation
        dynamics alone, over the aircraft's own static curves; non-dimensional:
        ``aero/aerodelta/stall/CL-delta``, ``.../Cm-delta``, ``.../CD-delta``), on the ``LIFT``
        and ``DRAG`` axes (``side_axis="SIDE"``: wind axes) or the ``X`` and ``Z`` axes
        (``side_axis="Y"``), and ``PITCH`` (``qbar S cbar``, ft lbf). The separation state
        is stepped here, with the frame's alpha and alphadot, from the previous frame's that
        :func:`jsbsim_stall_system_xml`'s ``<system>`` hands on; load both.
    stall_axes
        The axes of the stall's lift and drag increments (:data:`STALL_AXES`): ``"LIFT"``
        (``LIFT``, ``DRAG``; the default with ``side_axis="SIDE"``), ``"AXIAL"`` (``AXIAL``,
        ``NORMAL``, for an aircraft whose aerodynamics use AXIAL/SIDE/NORMAL: a file's
        functions join the aircraft's own axis system) or ``"X"`` (``X``, ``Z``; the default
        and only choice with ``side_axis="Y"``).

    Raises
    ------
    DataError
        A channel without a property, a coefficient other than ``CY``, ``Cl``, ``Cn``,
        or ``qualified`` for a Δ fitted against another simulator than the built-in ADX-37.
    """
    if side_axis not in ("SIDE", "Y"):
        raise DataError(f"side_axis '{side_axis}': use 'SIDE' or 'Y' (JSBSim axis names)")
    st_axes = stall_axes_for(side_axis, stall_axes)
    w = _Writer(model, properties or {})
    spec = w.spec
    recorded = recorded_source(spec, "adx37")
    if qualified and recorded != "adx37":
        raise DataError(
            f"the Δ was fitted against {describe(recorded)}, not the built-in ADX-37: its "
            "qualified model (--jsbsim-qualified) belongs to another aircraft; export the Δ "
            "alone and add it to your aircraft's own lateral aerodynamics"
        )
    qspec = qualified_daveml_spec() if qualified else None
    done: set[str] = set()
    alpha_p = w.channel(spec.get("alpha_channel", "alpha_deg"))
    flap_p = w.channel(spec.get("flap_channel", "flap_deg"))
    fns: list[str] = []
    axes: dict[str, list[str]] = {}
    for cname, c in spec["coefficients"].items():
        if cname not in _AXES:
            raise DataError(f"coefficient '{cname}': the JSBSim export knows CY, Cl and Cn")
        base = f"aero/aerodelta/{cname}"
        prods = []
        for t in c["terms"]:
            node = parse_regressor(t["regressor"])
            tab = w.table2(t, alpha_p, flap_p)
            if node.op == "const" and node.value == 1.0:
                prods.append(f"    <!-- {_comment(t['name'])} * 1 -->\n    {tab}")
            else:
                prods.append(
                    f"    <!-- {_comment(t['name'])} * {_comment(t['regressor'])} -->\n"
                    f"    <product>{tab}\n      {w.expr(node)}</product>"
                )
        fns.append(
            f'  <function name="{base}/delta">\n    <description>Δ{cname} before blending '
            f"(thesis Eq. 3.11)</description>\n" + _sum(prods, "\n") + "\n  </function>"
        )
        fns.append(
            f'  <function name="{base}/alpha_l">\n    {w.table1(c["alpha_l_deg"], flap_p)}\n'
            f'  </function>\n  <function name="{base}/alpha_u">\n'
            f"    {w.table1(c['alpha_u_deg'], flap_p)}\n  </function>"
        )
        la, ua = f"<property>{base}/alpha_l</property>", f"<property>{base}/alpha_u</property>"
        fns.append(
            f'  <function name="{base}/w">\n    <description>blend weight (thesis Eq. 3.12)'
            "</description>\n    <min><value>1</value><max><value>0</value><quotient>"
            f"<difference><property>{alpha_p}</property>{la}</difference>"
            f"<max><difference>{ua}{la}</difference><value>1e-300</value></max>"
            "</quotient></max></min>\n  </function>"
        )
        fns.append(
            f'  <function name="{base}/delta-blended">\n    <description>w Δ{cname}: the '
            f"increment to add to the qualified {cname}</description>\n    <product>"
            f"<property>{base}/w</property><property>{base}/delta</property></product>\n"
            "  </function>"
        )
        total = "delta-blended"
        if qspec is not None:
            fns.append(_qualified_functions(w, cname, qspec, done))
            fns.append(
                f'  <function name="{base}/extended">\n    <description>extended {cname} '
                f"(thesis Eq. 3.12)</description>\n    <sum><property>{base}/qualified</property>"
                f"<property>{base}/delta-blended</property></sum>\n  </function>"
            )
            total = "extended"
        axis, length = _AXES[cname]
        axis = side_axis if axis == "SIDE" else axis
        ref = "<property>aero/qbar-psf</property><property>metrics/Sw-sqft</property>"
        if length:
            ref += f"<property>{length}</property>"
        kind = "moment" if length else "force"
        unit = "ft lbf" if length else "lbf"
        axes.setdefault(axis, []).append(
            f'    <function name="aero/{kind}/aerodelta-{cname}">\n'
            f"      <description>{'extended' if qspec else 'extended-model increment of'} "
            f"{cname} ({unit})</description>\n"
            f"      <product>{ref}<property>{base}/{total}</property></product>\n"
            "    </function>"
        )
    stall = longitudinal and bool(model.kirchhoff)
    if stall:
        sfns, saxes = _stall_functions(w, model, st_axes, done)
        fns.extend(sfns)
        for a, fs in saxes.items():
            axes.setdefault(a, []).extend(fs)
    env = spec.get("envelope")
    if env:
        beta_p = w.channel("beta_deg")
        fns.append(_envelope_function(env, alpha_p, beta_p, flap_p))
    mapping = "\n".join(
        f"    {ch:<14} {p}"
        for ch, p in jsbsim_properties(model, properties, longitudinal=stall).items()
    )
    decl = "\n".join(f'  <property value="0">{p}</property>' for p in w.declared)
    prov = spec.get("provenance") or {}
    header = (
        '<?xml version="1.0"?>\n<!--\n  aerodelta extended-model increments (thesis Eq. 3.12), '
        f"written by {_comment(str(prov.get('library', 'aerodelta')))}; model data sha256 "
        f"{_comment(str(prov.get('data_sha256', '?')))}.\n  Add these functions to the aircraft's "
        "own aerodynamics (the qualified model)"
        + (
            "; the Kirchhoff stall's functions read the\n  separation state of the stall "
            "<system> exported with them (load both)"
            if stall
            else ""
        )
        + ".\n  Channels and the JSBSim properties they "
        "read (aerodelta/... ones are declared here with value 0:\n  drive them from the "
        "aircraft, signs as in the Etkin convention):\n" + _comment(mapping) + "\n-->\n"
    )
    axes_xml = "\n".join(
        f'  <axis name="{a}">\n' + "\n".join(fs) + "\n  </axis>" for a, fs in axes.items()
    )
    parts = [decl, *w.channel_fns, *fns, axes_xml]
    return header + "<aerodynamics>\n" + "\n".join(p for p in parts if p) + "\n</aerodynamics>\n"


def jsbsim_properties(
    model: DeltaModel,
    properties: Mapping[str, str] | None = None,
    *,
    longitudinal: bool | None = None,
) -> dict[str, str]:
    """Channel -> the JSBSim property the export of ``model`` reads for it, followed by
    ``= definition`` when the export defines that property as a function (a product of
    mapped properties, or a derived channel such as ``ct_diff``). ``longitudinal`` (default:
    whether the model stores a stall) adds the channels the stall reads (``alpha_deg``,
    ``alphadot_dps``, ``flap_deg``)."""
    w = _Writer(model, properties or {})
    chans = list(model.input_columns)
    if longitudinal if longitudinal is not None else bool(model.kirchhoff):
        chans += [c for c in ("alpha_deg", "alphadot_dps", "flap_deg") if c not in chans]
    for ch in chans:
        w.channel(ch)
    out = {}
    for ch, prop in w.channel_prop.items():
        if prop.startswith("aero/aerodelta/in/"):
            defn = w.props.get(ch) or DERIVED_CHANNELS.get(ch, "")
            out[ch] = f"{prop} = {defn}"
        else:
            out[ch] = prop
    return out


def stall_system_problem(
    model: DeltaModel, longitudinal: bool, system_path: str | PathLike[str] | None
) -> str | None:
    """Why the JSBSim export of ``model`` cannot go ahead with this stall system file (a stall
    carried without one, or one given with no stall to carry), or ``None``. One rule for
    :func:`export_jsbsim` and the CLI, which asks before it writes anything."""
    if longitudinal and model.kirchhoff:
        if system_path is None:
            flaps = ", ".join(f"{f:g}" for f in sorted(model.kirchhoff))
            return (
                f"the model stores a Kirchhoff stall (flaps {flaps} deg): JSBSim needs a "
                "<system> file to carry its separation state between frames; give one "
                "(--jsbsim-system FILE, system_path=) or leave the stall out "
                "(--no-longitudinal, longitudinal=False)"
            )
        return None
    if system_path is None:
        return None
    why = (
        "the model stores no Kirchhoff stall (aerodelta longitudinal --model M --out-model M2 "
        "adds one)"
        if not model.kirchhoff
        else "the export leaves its stall out (--no-longitudinal, longitudinal=False)"
    )
    return f"the JSBSim stall system {system_path}: {why}; drop --jsbsim-system / system_path"


def export_jsbsim(
    path: str | PathLike[str],
    model: DeltaModel,
    properties: Mapping[str, str] | None = None,
    *,
    side_axis: str = "SIDE",
    qualified: bool = False,
    longitudinal: bool = True,
    system_path: str | PathLike[str] | None = None,
    stall_axes: str | None = None,
) -> str:
    """Write :func:`jsbsim_xml` to ``path``; returns its text. A model storing a Kirchhoff
    stall (with ``longitudinal``) also needs ``system_path``, where
    :func:`jsbsim_stall_system_xml` goes: both files are written in full before either
    replaces what was there (``<name>.tmp-<pid>`` beside each, then renamed).

    Raises
    ------
    DataError
        As :func:`jsbsim_xml`; a stall without ``system_path``, ``system_path`` without a
        stall to carry, or ``system_path`` naming ``path``.
    """
    problem = stall_system_problem(model, longitudinal, system_path)
    if problem is not None:
        raise DataError(problem)
    text = jsbsim_xml(
        model,
        properties,
        side_axis=side_axis,
        qualified=qualified,
        longitudinal=longitudinal,
        stall_axes=stall_axes,
    )
    if system_path is None:
        write_atomic(path, text)
        return text
    if Path(system_path).resolve() == Path(path).resolve():
        raise DataError(
            f"the JSBSim aerodynamics and stall system both name {path}; give two files"
        )
    write_texts_atomic([(path, text), (system_path, jsbsim_stall_system_xml(model))])
    return text
