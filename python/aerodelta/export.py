"""Export aero models to DAVE-ML (AIAA S-119): the qualified model and the extended model.

The ADX-37 qualified model is a sum of gridded tables times regressors (see
``aero_core::aircraft::qualified``); DAVE-ML expresses it directly: one gridded-table variable per
(table, inputs) pair, and each output ``CL, CD, CY, Cl, Cm, Cn`` as a sum of products of tables
and inputs. Check cases are generated from the model itself, so any DAVE-ML tool can verify the
file (``aerodelta check-daveml``).

The extended model (thesis Eq. 3.12) adds the blended Δ to a qualified DAVE-ML model without
rewriting it: :func:`export_extended_daveml` merges the Δ tables, regressors and blend weights
into the qualified file (the user's, or the built-in ADX-37 one), writes outputs ``dC``, ``w_C``
and ``C_ext = C + w_C dC`` per coefficient, and generates check cases at sampled states that
are verified against the engine (``aero_core::delta_model`` plus the qualified model) before the
file is written.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta import _core
from aerodelta._exportutil import (
    DERIVED_CHANNELS,
    check_states,
    columns,
    parse_regressor,
    units_of,
    write_atomic,
)
from aerodelta.campaign import qualified_model_tables
from aerodelta.daveml import DaveModel, daveml_text, write_daveml
from aerodelta.exceptions import DataError
from aerodelta.model import DeltaModel
from aerodelta.qualified import describe, recorded_source

#: Table inputs of the qualified model and their DAVE-ML variables.
_TABLE_INPUTS = {
    "AlphaDeg": "alpha_deg",
    "FlapDeg": "flap_deg",
    "DaDeg": "da_deg",
    "DrDeg": "dr_deg",
    "DslDeg": "dsl_deg",
    "DsrDeg": "dsr_deg",
}
#: Regressors and the input variables they multiply (CtSum/CtDiff: per engine).
_REGRESSORS: dict[str, list[tuple[float, list[str]]]] = {
    "One": [(1.0, [])],
    "Beta": [(1.0, ["beta_rad"])],
    "PHat": [(1.0, ["phat"])],
    "QHat": [(1.0, ["qhat"])],
    "RHat": [(1.0, ["rhat"])],
    "AlphaDotHat": [(1.0, ["alphadot_hat"])],
    "De": [(1.0, ["de_rad"])],
    "CtSum": [(1.0, ["ct_left"]), (1.0, ["ct_right"])],
    "CtDiff": [(1.0, ["ct_left"]), (-1.0, ["ct_right"])],
}
_BETA_MAX = math.radians(40.0)  # Table 3.1 static sideslip range; the model holds beyond
_CT_RANGE = (-0.1, 1.5)  # Table 3.1 static thrust-coefficient range, per engine

_INPUTS: list[dict[str, Any]] = [
    {"id": "alpha_deg", "units": "deg", "description": "angle of attack at the CG"},
    {"id": "beta_rad", "units": "rad", "description": "sideslip at the CG",
     "min": -_BETA_MAX, "max": _BETA_MAX},
    {"id": "phat", "units": "nd", "description": "p b / (2V)"},
    {"id": "qhat", "units": "nd", "description": "q cbar / (2V)"},
    {"id": "rhat", "units": "nd", "description": "r b / (2V)"},
    {"id": "alphadot_hat", "units": "nd", "description": "alphadot cbar / (2V)"},
    {"id": "de_rad", "units": "rad", "description": "elevator (positive nose down)"},
    {"id": "da_deg", "units": "deg", "description": "aileron (positive rolls left)"},
    {"id": "dr_deg", "units": "deg", "description": "rudder (positive yaws left)"},
    {"id": "dsl_deg", "units": "deg", "description": "left roll spoiler"},
    {"id": "dsr_deg", "units": "deg", "description": "right roll spoiler"},
    {"id": "flap_deg", "units": "deg", "description": "flap setting"},
    {"id": "ct_left", "units": "nd", "description": "left thrust coefficient T/(qbar S)",
     "min": _CT_RANGE[0], "max": _CT_RANGE[1]},
    {"id": "ct_right", "units": "nd", "description": "right thrust coefficient T/(qbar S)",
     "min": _CT_RANGE[0], "max": _CT_RANGE[1]},
]  # fmt: skip


def qualified_daveml_spec() -> dict[str, Any]:
    """The ADX-37 qualified model as a :func:`aerodelta.daveml.write_daveml` spec."""
    tables, terms = qualified_model_tables()
    by_name = {t["name"]: t for t in tables}
    table_vars: dict[tuple[str, tuple[str, ...]], str] = {}
    specs: list[dict[str, Any]] = []
    outputs: dict[str, list[dict[str, Any]]] = {c: [] for c in ("CL", "CD", "CY", "Cl", "Cm", "Cn")}
    for term in terms:
        args = tuple(_TABLE_INPUTS[i] for i in term["inputs"])
        key = (term["table"], args)
        if key not in table_vars:
            t = by_name[term["table"]]
            vid = (
                term["table"]
                if not any(k[0] == term["table"] for k in table_vars)
                else (f"{term['table']}_{'_'.join(args)}")
            )
            table_vars[key] = vid
            specs.append(
                {"id": vid, "units": "nd", "args": list(args), "breakpoints": t["breakpoints"],
                 "values": t["values"], "extrapolate": "neither"}
            )  # fmt: skip
        for coef, factors in _REGRESSORS[term["regressor"]]:
            outputs[term["coef"]].append(
                {"coef": coef * term["sign"], "factors": [table_vars[key], *factors]}
            )
    checks = [
        {"name": "cruise", "inputs": {"alpha_deg": 3.0, "flap_deg": 0.0, "ct_left": 0.05,
                                      "ct_right": 0.05}},
        {"name": "sideslip and rates", "inputs": {"alpha_deg": 8.0, "beta_rad": 0.05, "phat": 0.01,
                                                  "rhat": -0.01, "flap_deg": 10.0, "da_deg": 5.0,
                                                  "dr_deg": -3.0}},
        {"name": "stall, spoiler, asymmetric thrust",
         "inputs": {"alpha_deg": 17.0, "flap_deg": 15.0, "dsr_deg": 20.0, "ct_left": 0.3,
                    "ct_right": 0.1, "qhat": 0.005, "de_rad": -0.05}},
        {"name": "beyond the tables", "inputs": {"alpha_deg": 30.0, "beta_rad": 0.9,
                                                 "flap_deg": 35.0, "ct_left": 2.0}},
    ]  # fmt: skip
    return {
        "name": "ADX-37 qualified aerodynamic model",
        "description": "Representative twin turboprop of the aerodelta virtual flight test: the "
        "pre-stall qualified model (Table 3.1 ranges, holding the last value beyond). CL, CD "
        "wind axes; CY, Cl, Cm, Cn body axes; totals including thrust terms.",
        "inputs": [dict(i, initial=0.0) for i in _INPUTS],
        "tables": specs,
        "outputs": [
            {"id": c, "units": "nd", "description": f"{c} of the qualified model", "terms": t}
            for c, t in outputs.items()
        ],
        "checks": checks,
    }


def export_qualified_daveml(path: str | PathLike[str]) -> DaveModel:
    """Write the ADX-37 qualified model as DAVE-ML (atomic, with its own check cases)."""
    return write_daveml(path, qualified_daveml_spec())


# -- The extended model --------------------------------------------------------------------

_RAD2DEG = 180.0 / math.pi


def qualified_base(qualified: str | PathLike[str] | None) -> tuple[str, str, DaveModel]:
    """The qualified model's DAVE-ML text, its name for messages, and the model.

    ``None`` gives the built-in ADX-37 qualified model (:func:`qualified_daveml_spec`).
    """
    if qualified is None:
        text = daveml_text(qualified_daveml_spec())
        name = "built-in ADX-37 qualified model"
    else:
        try:
            text = Path(qualified).read_text(encoding="utf-8")
        except OSError as e:
            raise DataError(f"{qualified}: cannot read the qualified DAVE-ML file ({e})") from e
        name = str(qualified)
    return text, name, DaveModel.from_string(text, name)


#: Half width of the flap window of a stored stall in the DAVE-ML export, deg: the engine takes
#: a flap's stall at that flap setting exactly (``DeltaModel.kirchhoff``); the window only keeps
#: a NaN flap out.
STALL_FLAP_WINDOW_DEG = 1e-9
#: Variables of the qualified file the longitudinal stall replaces (the static curves).
STALL_BASE_VARIABLES = ("CL_basic", "Cm_basic")
#: The static drag curve a stall with a drag replaces too.
STALL_DRAG_VARIABLE = "CD_basic"


def _stall_replaces(model: DeltaModel) -> tuple[str, ...]:
    """The qualified file's static curves the model's stall replaces: those of
    :data:`STALL_BASE_VARIABLES` (and :data:`STALL_DRAG_VARIABLE` when a flap stores a drag)
    for a stall fitted on the ADX-37's known terms, none for one fitted with ``known="none"``
    (which adds its separation dynamics to the totals)."""
    if model.kirchhoff_known == "none":
        return ()
    return STALL_BASE_VARIABLES + ((STALL_DRAG_VARIABLE,) if model.kirchhoff_drag else ())


def _stall_totals(model: DeltaModel) -> tuple[str, ...]:
    """The coefficient totals the stall changes: C_L, C_m, and C_D with a stored drag."""
    return ("CL", "Cm", "CD") if model.kirchhoff_drag else ("CL", "Cm")


#: B-spline terms per calculation of a tabulated separation curve (each term some 25 nodes of
#: the expression tree; aero_core's parser takes 2048 nodes per expression).
SPLINE_TERMS_PER_CALC = 16


@dataclass(frozen=True)
class SplineLayout:
    """A stored separation table as the exports write it (``aero_core::goman_khrabrov::
    X0Table``): the knot coordinate ``s = (u - origin) / spacing`` held in ``[0, top]``, and
    ``x0 = Σ_k c_k B(s - k)`` over the nonzero ``(k, c_k)`` of ``terms``, ``k = -1 .. K`` (the
    end coefficients repeated beyond the ends), ``B(t) = (max(0, 2 - |t|)^3 - 4 max(0, 1 -
    |t|)^3) / 6`` the centred cubic B-spline (de Boor 2001, *A Practical Guide to Splines*,
    ch. IX). Zero coefficients are left out (they add exact zeros)."""

    origin: float
    spacing: float
    top: int
    terms: tuple[tuple[int, float], ...]

    @classmethod
    def of(cls, table: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]) -> SplineLayout:
        """The layout of ``(knots in rad, coefficients)`` (``DeltaModel.separation_tables``)."""
        knots, values = table
        n = len(knots)
        coef = [float(values[0]), *map(float, values), float(values[-1])]
        return cls(
            origin=float(knots[0]),
            spacing=(float(knots[-1]) - float(knots[0])) / (n - 1),
            top=n - 1,
            terms=tuple((k, c) for k, c in zip(range(-1, n + 1), coef, strict=True) if c != 0.0),
        )


def _x0_calcs(
    model: DeltaModel, f: float, u: str, name: str, what: str
) -> tuple[list[dict[str, Any]], str]:
    """Calculations giving the static separation point ``x0`` at the calculation ``u`` (rad)
    of the stored stall at flap ``f``, and the id of the last. The tanh form:
    ``x0(u) = (1 - tanh(a1 (u - alpha*))) / 2 = 1 / (1 + exp(2 a1 (u - alpha*)))``. The
    tabulated form: the engine's spline, exactly (:class:`SplineLayout`)."""
    p = (model.kirchhoff or {})[f]
    tables = model.separation_tables
    if f not in tables:
        expr = f"1 / (1 + exp(2 * {p['a1']!r} * ({u} - {p['alpha_star']!r})))"
        return [{"id": name, "units": "nd", "expr": expr, "description": what}], name
    lay = SplineLayout.of(tables[f])
    s_id = f"{name}_s"
    calcs: list[dict[str, Any]] = [
        {"id": s_id, "units": "nd",
         "expr": f"min({lay.top}, max(0, ({u} - {lay.origin!r}) / {lay.spacing!r}))",
         "description": f"{what}: knot coordinate of the separation table, held in "
         f"[0, {lay.top}]"},
    ]  # fmt: skip
    terms = [
        f"{c!r} * (max(0, 2 - abs({s_id} - ({k})))^3 - 4 * max(0, 1 - abs({s_id} - ({k})))^3)"
        for k, c in lay.terms
    ]
    parts = []
    for j in range(0, len(terms), SPLINE_TERMS_PER_CALC):
        pid = f"{name}_p{j // SPLINE_TERMS_PER_CALC}"
        calcs.append(
            {"id": pid, "units": "nd", "expr": " + ".join(terms[j : j + SPLINE_TERMS_PER_CALC]),
             "description": f"{what}: six times the B-spline's terms {j} to "
             f"{min(j + SPLINE_TERMS_PER_CALC, len(terms)) - 1}"}
        )  # fmt: skip
        parts.append(pid)
    total = " + ".join(parts) if parts else "0"
    calcs.append({"id": name, "units": "nd", "expr": f"({total}) / 6", "description": what})
    return calcs, name


def _stall_spec(
    model: DeltaModel,
    bunits: Mapping[str, str],
    *,
    alpha: str,
    flap: str,
    alphadot: str,
    coefficients: Mapping[str, str],
) -> tuple[list[dict[str, Any]], list[dict[str, Any]], list[dict[str, Any]]]:
    """Inputs, calculations and outputs of the stored Kirchhoff stall (``model.kirchhoff``):
    the separation point as a state input ``x_sep`` the host integrates from ``x_sep_dot``
    (Fischenberg's ``τ₁ ẋ + x = x₀(α − τ₂ α̇)``), its static value ``x_sep_0`` (to start
    at), and ``CL_ext``, ``Cm_ext`` (and ``CD_ext`` when a flap stores the stall's drag) at
    each flap setting that has a stall. A stall fitted on the ADX-37's known terms replaces
    the qualified static curves ``CL_basic``, ``Cm_basic`` (``CD_basic``) of the ``CL``,
    ``Cm`` (``CD``) totals by the Kirchhoff curves (the engine's ``KirchhoffStall``);
    one fitted with ``known="none"`` (the whole measured coefficients, whose static curves
    the qualified file already holds) adds the separation dynamics alone: the Kirchhoff
    curves at ``x_sep`` less the same curves at the static ``x₀(α)``. Elsewhere the state
    derivative is 0 and the totals are the qualified ones."""
    stall = model.kirchhoff or {}
    drags = model.kirchhoff_drag
    dynamics_only = model.kirchhoff_known == "none"
    totals = _stall_totals(model)
    need = [*_stall_replaces(model), *(coefficients.get(c, c) for c in totals)]
    missing = [v for v in need if v not in bunits]
    if missing:
        names = " and ".join(", ".join(totals).rsplit(", ", 1))
        what = (
            f"the {names} totals the stall's separation dynamics are added to"
            if dynamics_only
            else f"the stall replaces the static curves {', '.join(_stall_replaces(model))} of "
            f"the {names} totals (the built-in ADX-37 file's variables)"
        )
        raise DataError(
            f"the qualified DAVE-ML model has no {', '.join(missing)}: {what}; name the totals "
            "(--coef CL=VARID --coef Cm=VARID --coef CD=VARID, coefficients=) or export "
            "without the stall (--no-longitudinal, longitudinal=False)"
        )
    d2r = math.pi / 180.0
    inputs = [
        {"id": "x_sep", "units": "nd", "initial": 1.0,
         "description": "separation point of the Kirchhoff stall (1 attached, 0 separated): a "
         "state the host integrates from x_sep_dot, started at x_sep_0"},
    ]  # fmt: skip
    calcs: list[dict[str, Any]] = [
        {"id": "ks_x", "units": "nd", "expr": "min(1, max(0, x_sep))",
         "description": "the separation point held in [0, 1]"},
        {"id": "ks_alpha", "units": "rad", "expr": f"{alpha} * {d2r!r}",
         "description": "angle of attack, rad"},
        {"id": "ks_alphadot", "units": "rad_s", "expr": f"{alphadot} * {d2r!r}",
         "description": "rate of the angle of attack, rad/s"},
    ]  # fmt: skip
    x0_terms, xd_terms, cl_terms, cm_terms, cd_terms = [], [], [], [], []
    w = STALL_FLAP_WINDOW_DEG
    for i, (f, p) in enumerate(sorted(stall.items())):
        g = {k: repr(float(v)) for k, v in p.items()}
        on, x0 = f"ks_on_{i}", f"ks_x0_{i}"
        calcs += [
            {"id": on, "units": "nd",
             "expr": f"step({flap} - {f!r} + {w!r}) * step({f!r} + {w!r} - {flap})",
             "description": f"1 at flap {f:g} deg (the stall stored for it), else 0"},
            {"id": f"ks_u_{i}", "units": "rad",
             "expr": f"ks_alpha - {g['tau2']} * ks_alphadot",
             "description": f"flap {f:g}: alpha - tau2 alphadot, rad"},
        ]  # fmt: skip
        calcs += _x0_calcs(
            model, f, f"ks_u_{i}", x0,
            f"flap {f:g}: static separation point at alpha - tau2 alphadot",
        )[0]  # fmt: skip
        calcs.append(
            {"id": f"ks_xdot_{i}", "units": "_s", "expr": f"({x0} - ks_x) / {g['tau1']}",
             "description": f"flap {f:g}: (x0 - x) / tau1, 1/s"}
        )  # fmt: skip
        lift = f"{g['CL_alpha']} * (ks_alpha - {g['alpha0']}) * ((1 + sqrt(ks_x)) / 2)^2"
        drag = {k: repr(float(v)) for k, v in drags.get(f, {}).items()}
        xs = f"ks_x0s_{i}"
        if dynamics_only:
            calcs += _x0_calcs(
                model, f, "ks_alpha", xs, f"flap {f:g}: static separation point x0(alpha)"
            )[0]
            calcs += [
                {"id": f"ks_dcl_{i}", "units": "nd",
                 "expr": f"{lift} - {g['CL_alpha']} * (ks_alpha - {g['alpha0']}) * "
                         f"((1 + sqrt({xs})) / 2)^2",
                 "description": f"flap {f:g}: Kirchhoff lift at x_sep minus at x0(alpha)"},
                {"id": f"ks_dcm_{i}", "units": "nd", "expr": f"{g['Cm_x']} * ({xs} - ks_x)",
                 "description": f"flap {f:g}: Kirchhoff pitching moment at x_sep minus at "
                 "x0(alpha)"},
            ]  # fmt: skip
        else:
            calcs += [
                {"id": f"ks_dcl_{i}", "units": "nd", "expr": f"{lift} - CL_basic",
                 "description": f"flap {f:g}: Kirchhoff lift minus the static curve it "
                 "replaces"},
                {"id": f"ks_dcm_{i}", "units": "nd",
                 "expr": f"{g['Cm0']} + {g['Cm_alpha']} * ks_alpha + {g['Cm_x']} * (1 - ks_x) "
                         "- Cm_basic",
                 "description": f"flap {f:g}: Kirchhoff pitching moment minus the static "
                 "curve"},
            ]  # fmt: skip
        if drag:
            if dynamics_only:  # the drag at x_sep less at x0(alpha)
                lift_s = f"{g['CL_alpha']} * (ks_alpha - {g['alpha0']}) * ((1 + sqrt({xs})) / 2)^2"
                expr = (
                    f"{drag['CD_k']} * (({lift})^2 - ({lift_s})^2) + {drag['CD_x']} * ({xs} - ks_x)"
                )
                what = "Kirchhoff drag at x_sep minus at x0(alpha)"
            else:
                expr = (
                    f"{drag['CD0']} + {drag['CD_k']} * ({lift})^2 + {drag['CD_x']} * (1 - ks_x)"
                    f" - {STALL_DRAG_VARIABLE}"
                )
                what = "Kirchhoff drag (CD0 + CD_k CL^2 + CD_x (1 - x)) minus the static curve"
            calcs.append(
                {"id": f"ks_dcd_{i}", "units": "nd", "expr": expr,
                 "description": f"flap {f:g}: {what}"}
            )  # fmt: skip
            cd_terms.append({"factors": [on, f"ks_dcd_{i}"]})
        x0_terms.append({"factors": [on, x0]})
        xd_terms.append({"factors": [on, f"ks_xdot_{i}"]})
        cl_terms.append({"factors": [on, f"ks_dcl_{i}"]})
        cm_terms.append({"factors": [on, f"ks_dcm_{i}"]})
    flaps = ", ".join(f"{f:g}" for f in sorted(stall))
    outputs = [
        {"id": "x_sep_dot", "units": "_s", "terms": xd_terms,
         "description": "rate of the separation point, 1/s (tau1 x_dot + x = x0(alpha - tau2 "
         f"alphadot), Fischenberg), at flaps {flaps} deg; 0 elsewhere"},
        {"id": "x_sep_0", "units": "nd", "terms": x0_terms,
         "description": "static separation point at the current alpha and alphadot: the state "
         f"to start from (trim), at flaps {flaps} deg; 0 elsewhere"},
        {"id": "CL_ext", "units": "nd",
         "terms": [{"factors": [coefficients.get("CL", "CL")]}, *cl_terms],
         "description": (
             "extended CL: the qualified CL plus the lift of the stall's separation dynamics "
             f"(Kirchhoff lift at x_sep less at x0(alpha)) at flaps {flaps} deg"
             if dynamics_only else
             "extended CL: the qualified CL with its static curve CL_basic replaced by the "
             f"Kirchhoff lift at flaps {flaps} deg")
         + " (the qualified CL elsewhere)"},
        {"id": "Cm_ext", "units": "nd",
         "terms": [{"factors": [coefficients.get("Cm", "Cm")]}, *cm_terms],
         "description": (
             "extended Cm: the qualified Cm plus the moment of the stall's separation "
             f"dynamics (Cm_x (x0(alpha) - x_sep)) at flaps {flaps} deg"
             if dynamics_only else
             "extended Cm: the qualified Cm with its static curve Cm_basic replaced by the "
             f"Kirchhoff moment at flaps {flaps} deg")
         + " (the qualified Cm elsewhere)"},
    ]  # fmt: skip
    if cd_terms:
        dflaps = ", ".join(f"{f:g}" for f in sorted(drags))
        outputs.append(
            {"id": "CD_ext", "units": "nd",
             "terms": [{"factors": [coefficients.get("CD", "CD")]}, *cd_terms],
             "description": (
                 "extended CD: the qualified CD plus the drag of the stall's separation "
                 f"dynamics at flaps {dflaps} deg"
                 if dynamics_only else
                 f"extended CD: the qualified CD with its static curve {STALL_DRAG_VARIABLE} "
                 f"replaced by the Kirchhoff drag at flaps {dflaps} deg")
             + " (the qualified CD elsewhere)"}
        )  # fmt: skip
    return inputs, calcs, outputs


def extended_daveml_spec(
    model: DeltaModel,
    base: DaveModel,
    *,
    channel_map: Mapping[str, str] | None = None,
    coefficients: Mapping[str, str] | None = None,
    seed: int = 0,
    longitudinal: bool = True,
) -> dict[str, Any]:
    """The Δ part of the extended model as a DAVE-ML spec to merge into ``base``.

    Parameters
    ----------
    model
        The fitted Δ model (``aerodelta fit``).
    base
        The qualified DAVE-ML model the Δ is added to.
    channel_map
        Δ-model channel -> expression over ``base`` variables (regressor language), for channels
        the base names differently, e.g. ``{"alpha_deg": "alpha"}``. Built in:
        ``ct_diff = ct_left - ct_right``, ``ds_deg = dsr_deg - dsl_deg`` and ``X_deg = X_rad *
        180/pi`` when the base has ``X_rad``. Channels neither in the base nor derivable become
        new inputs (default 0).
    coefficients
        Δ coefficient -> the base variable holding the qualified value (default the same name,
        e.g. ``Cl``).
    seed
        Seed of the sampled check states.
    longitudinal
        Carry the Kirchhoff stall the model stores (:meth:`DeltaModel.with_longitudinal`):
        the state input ``x_sep``, ``x_sep_dot``, ``x_sep_0``, ``CL_ext``, ``Cm_ext``
        (:func:`_stall_spec`). Without a stored stall nothing is added.

    Returns
    -------
    dict
        A spec for ``aerodelta._core.daveml_merge_xml`` (the writer's spec with calculations).

    Raises
    ------
    DataError
        A coefficient the base lacks; a stored stall the base cannot carry (no ``CL``, ``Cm``,
        or, for a stall fitted on the ADX-37's known terms, no ``CL_basic``, ``Cm_basic``),
        unless ``longitudinal=False``.
    """
    spec = model.to_spec()
    flaps = [float(f) for f in spec["flaps_deg"]]
    alpha_ch, flap_ch = spec.get("alpha_channel", "alpha_deg"), spec.get("flap_channel", "flap_deg")
    bvars = base.variables()
    bunits = dict(zip(bvars["id"].to_list(), bvars["units"].to_list(), strict=True))
    cmap = dict(channel_map or {})
    inputs: list[dict[str, Any]] = []
    calcs: list[dict[str, Any]] = []
    resolved: set[str] = set()

    def derivation(ch: str) -> str | None:
        if ch in cmap:
            return cmap[ch]
        if ch in DERIVED_CHANNELS:
            return DERIVED_CHANNELS[ch]
        if ch.endswith("_deg") and f"{ch[:-4]}_rad" in bunits:
            return f"{ch[:-4]}_rad * {_RAD2DEG!r}"
        return None

    def resolve(ch: str) -> None:
        if ch in resolved:
            return
        resolved.add(ch)
        if ch in bunits and ch not in cmap:
            inputs.append({"id": ch, "units": bunits[ch]})
            return
        expr = derivation(ch)
        if expr is None:
            inputs.append(
                {"id": ch, "units": units_of(ch), "initial": 0.0,
                 "description": f"Δ-model channel {ch} (not in the qualified model)"}
            )  # fmt: skip
            return
        for c in columns(parse_regressor(expr)):
            resolve(c)
        calcs.append(
            {"id": ch, "units": units_of(ch), "expr": expr,
             "description": f"Δ-model channel {ch} = {expr}"}
        )  # fmt: skip

    for ch in (alpha_ch, flap_ch):
        resolve(ch)
    tables: list[dict[str, Any]] = []
    outputs: list[dict[str, Any]] = []
    cnames = coefficients or {}
    for cname, c in spec["coefficients"].items():
        qual = cnames.get(cname, cname)
        if qual not in bunits:
            raise DataError(
                f"qualified model has no variable '{qual}' for coefficient {cname}; its outputs "
                f"are {base.outputs}: give the mapping (coefficients={{'{cname}': ...}}, CLI "
                f"--coef {cname}=ID)"
            )
        if qual not in resolved:
            resolved.add(qual)
            inputs.append({"id": qual, "units": bunits[qual]})
        terms = []
        for t in c["terms"]:
            node = parse_regressor(t["regressor"])
            table: dict[str, Any] = {
                "id": t["name"], "units": "nd",
                "description": f"Δ parameter of {cname} multiplying {t['regressor']} "
                               "(thesis Eq. 3.19), held beyond the last alpha",
                "args": [flap_ch, alpha_ch], "breakpoints": [flaps, t["alpha_deg"]],
                "values": [v for row in t["values"] for v in row],
            }  # fmt: skip
            band = t.get("band")
            if band is not None:
                table["uncertainty"] = {
                    "lower": [v for row in band["lower"] for v in row],
                    "upper": [v for row in band["upper"] for v in row],
                }
                table["description"] += (
                    f"; uncertainty: its {100 * band['level']:g} % confidence band (bootstrap "
                    "over maneuvers) as absolute bounds; DAVE-ML has no asymmetric "
                    "distribution, so it is written as uniformPDF: read the range, not the shape"
                )
            tables.append(table)
            for col in columns(node):
                resolve(col)
            if node.op == "const":
                terms.append({"coef": node.value, "factors": [t["name"]]})
            elif node.op == "col":
                terms.append({"factors": [t["name"], node.name]})
            else:
                xid = f"x_{t['name']}"
                calcs.append(
                    {"id": xid, "expr": t["regressor"],
                     "description": f"regressor of {t['name']}"}
                )  # fmt: skip
                terms.append({"factors": [t["name"], xid]})
        for side, key in (("l", "alpha_l_deg"), ("u", "alpha_u_deg")):
            tables.append(
                {"id": f"{cname}_alpha_{side}", "units": "deg",
                 "description": f"blend {'start' if side == 'l' else 'end'} of {cname} per "
                                "flap (thesis Eq. 3.12)",
                 "args": [flap_ch], "breakpoints": [flaps], "values": c[key]}
            )  # fmt: skip
        al, au = f"{cname}_alpha_l", f"{cname}_alpha_u"
        calcs.append(
            {"id": f"w_{cname}", "is_output": True,
             "expr": f"min(1, max(0, ({alpha_ch} - {al}) / max({au} - {al}, 1e-300)))",
             "description": f"blend weight of {cname}, 0 below alpha_l, 1 above alpha_u "
                            "(thesis Eq. 3.12)"}
        )  # fmt: skip
        outputs.append(
            {"id": f"d{cname}", "terms": terms,
             "description": f"Δ{cname} before blending (thesis Eq. 3.11)"}
        )  # fmt: skip
        outputs.append(
            {"id": f"{cname}_ext",
             "terms": [{"factors": [qual]}, {"factors": [f"w_{cname}", f"d{cname}"]}],
             "description": f"extended {cname} = {qual} + w_{cname} d{cname} (thesis Eq. 3.12)"}
        )  # fmt: skip
    if longitudinal and model.kirchhoff:
        resolve("alphadot_dps")
        s_inputs, s_calcs, s_outputs = _stall_spec(
            model, bunits, alpha=alpha_ch, flap=flap_ch, alphadot="alphadot_dps",
            coefficients=cnames,
        )  # fmt: skip
        for v in (*_stall_replaces(model), *(cnames.get(c, c) for c in _stall_totals(model))):
            if v not in resolved:
                resolved.add(v)
                inputs.append({"id": v, "units": bunits[v]})
        inputs += s_inputs
        calcs += s_calcs
        outputs += s_outputs
    env = spec.get("envelope")
    if env:  # the validated envelope's flag reads the sideslip (deg)
        resolve("beta_deg")
    alpha_max = max(max(t["alpha_deg"]) for c in spec["coefficients"].values() for t in c["terms"])
    blend = {k: (c["alpha_l_deg"], c["alpha_u_deg"]) for k, c in spec["coefficients"].items()}
    all_inputs = [*base.inputs, *(i["id"] for i in inputs if i["id"] not in bunits)]
    initial = dict(zip(bvars["id"].to_list(), bvars["initial_value"].to_list(), strict=True))
    checks = check_states(flaps, blend, alpha_max, all_inputs, seed=seed)
    for cp in checks:
        for i in base.inputs:
            if i not in cp["inputs"] and initial.get(i) is None:
                cp["inputs"][i] = 0.0
        cp["inputs"] = {k: v for k, v in cp["inputs"].items() if k in all_inputs}
    out: dict[str, Any] = {
        "name": "aerodelta extended model (qualified + blended Δ)",
        "provenance": _provenance(spec),
        "inputs": inputs,
        "calculations": calcs,
        "tables": tables,
        "outputs": outputs,
        "checks": checks,
        "check_tolerance": 1e-9,
    }
    if env:
        out["envelope_flag"] = {
            "id": "in_envelope", "flap": flap_ch, "alpha": alpha_ch, "beta": "beta_deg",
            "envelope": env,
            "description": "1 inside the validated envelope of the flight data (the alpha band "
            "of the nearest flap setting is covered and beta lies in its measured range), 0 "
            "outside: the indication a simulator shows its instructor",
        }  # fmt: skip
    return out


def _provenance(spec: Mapping[str, Any]) -> dict[str, Any]:
    """The DAVE-ML ``provenance`` of the Δ tables: what the fit recorded (library, data hash,
    qualified model, maneuvers, bands), in words."""
    prov = spec.get("provenance") or {}
    cfg = prov.get("config") or {}
    parts = [
        "Δ tables identified from flight test data by equation-error least squares per "
        "angle-of-attack bin and smoothed over alpha (thesis Sections 3.3-3.6)",
        f"by {prov.get('library', 'aerodelta')}",
    ]
    if prov.get("qualified"):
        parts.append(f"qualified model: {describe(str(prov['qualified']))}")
    if prov.get("maneuvers") is not None:
        parts.append(f"{prov['maneuvers']} maneuvers, {prov.get('rows', '?')} samples")
    if prov.get("data_sha256"):
        parts.append(f"data SHA-256 {prov['data_sha256']}")
    n_boot = int(cfg.get("bootstrap") or 0)
    if n_boot > 0:
        parts.append(
            f"uncertainty: {100 * float(cfg.get('band_level', 0.95)):g} % percentile bands of "
            f"a {n_boot}-replicate bootstrap over maneuvers (seed {cfg.get('seed', 0)}), "
            "widened by the smoothing spline's bias and holding the smoothed bins' bands "
            "(each at least the bin's CR2 t interval)"
        )
    else:
        parts.append("no bands: fitted without a bootstrap")
    return {"id": "aerodelta_fit", "description": "; ".join(parts)}


def _flown(model: DeltaModel, inputs: Mapping[str, float]) -> bool:
    """Whether a state lies inside the model's flaps and the alphas its tables cover (the
    flight test's envelope): a published check case stays there."""
    spec = model.to_spec()
    flaps = [float(f) for f in spec["flaps_deg"]]
    alpha_max = max(max(t["alpha_deg"]) for c in spec["coefficients"].values() for t in c["terms"])
    flap = float(inputs.get(spec.get("flap_channel", "flap_deg"), np.nan))
    alpha = float(inputs.get(spec.get("alpha_channel", "alpha_deg"), np.nan))
    return bool(min(flaps) <= flap <= max(flaps) and alpha <= alpha_max)


@dataclass(frozen=True)
class ExtendedExport:
    """What :func:`extended_daveml_text` produced: the text, the model read back, and the
    largest relative difference between the file's check values and the engine's."""

    text: str
    model: DaveModel
    n_checks: int
    max_rel_error: float


def _engine_reference(
    model: DeltaModel,
    base: DaveModel,
    merged: DaveModel,
    states: list[dict[str, Any]],
    coefficients: Mapping[str, str],
    *,
    stall: bool = False,
) -> dict[str, np.ndarray]:
    """``C_ext`` by the engine: the base model's ``C`` plus ``w dC`` from ``aero_core``'s
    Δ model, at the states (Δ channels derived in the merged file read back by varID); with
    ``stall``, the Kirchhoff stall's outputs too (:func:`_stall_reference`)."""
    ids = merged.variables()["id"].to_list()
    keys = sorted({k for s in states for k in s["inputs"]})
    data = {k: [s["inputs"].get(k, np.nan) for s in states] for k in keys}
    frame = merged.evaluate(data, outputs=[c for c in model.input_columns if c in ids])
    delta = model.evaluate(frame)
    binputs = set(base.inputs)
    qual = base.evaluate(
        {k: v for k, v in data.items() if k in binputs}, outputs=list(coefficients.values())
    )
    out = {
        f"{c}_ext": qual[coefficients[c]].to_numpy() + delta[f"d{c}_blended"].to_numpy()
        for c in model.coefficients
    } | {f"d{c}": delta[f"d{c}"].to_numpy() for c in model.coefficients}
    if stall:
        out |= _stall_reference(model, base, data, coefficients)
    return out


def _stall_reference(
    model: DeltaModel,
    base: DaveModel,
    data: Mapping[str, list[Any]],
    coefficients: Mapping[str, str],
) -> dict[str, np.ndarray]:
    """``x_sep_dot``, ``x_sep_0``, ``CL_ext``, ``Cm_ext`` (and ``CD_ext`` with a stored drag)
    by the engine at the states: the stored stall's ``KirchhoffParams``
    (``_core.kirchhoff_point``) and ``KirchhoffDrag`` (``_core.kirchhoff_drag_point``) at the
    flap settings that have one (exactly), replacing the base file's ``CL_basic``, ``Cm_basic``
    (``CD_basic``) in its ``CL``, ``Cm`` (``CD``) (the base's own values, as the Δ's reference
    takes the base's coefficients)."""
    n = len(data["alpha_deg"])

    def col(name: str, default: float) -> np.ndarray:
        v = data.get(name)
        return np.full(n, default) if v is None else np.asarray(v, dtype=float)

    alpha, flap = col("alpha_deg", np.nan), col("flap_deg", np.nan)
    rates = np.radians(col("alphadot_dps", 0.0))
    x = np.clip(col("x_sep", 1.0), 0.0, 1.0)
    totals = [coefficients.get(c, c) for c in _stall_totals(model)]
    binputs = set(base.inputs)
    dynamics_only = model.kirchhoff_known == "none"
    drags = model.kirchhoff_drag
    qual = base.evaluate(
        {k: v for k, v in data.items() if k in binputs},
        outputs=[*totals, *_stall_replaces(model)],
    )
    xdot, x0 = np.zeros(n), np.zeros(n)
    cl, cm = qual[totals[0]].to_numpy().copy(), qual[totals[1]].to_numpy().copy()
    cd = qual[totals[2]].to_numpy().copy() if drags else None
    tables = model.separation_tables
    for f, p in (model.kirchhoff or {}).items():
        on = flap == f
        a_on = np.radians(alpha[on])
        table = (
            {"knots": tables[f][0].tolist(), "values": tables[f][1].tolist()} if f in tables else {}
        )
        s_x0, s_xd, s_cl, s_cm = _core.kirchhoff_point(p, a_on, rates[on], x[on], **table)
        x0[on], xdot[on] = s_x0, s_xd
        d = drags.get(f)
        if dynamics_only:  # less the same curves at the static state x0(alpha)
            still = np.zeros_like(a_on)
            xs = _core.kirchhoff_point(p, a_on, still, x[on], **table)[0]
            _, _, st_cl, st_cm = _core.kirchhoff_point(p, a_on, still, xs, **table)
            cl[on] += s_cl - st_cl
            cm[on] += s_cm - st_cm
            if d is not None and cd is not None:
                cd[on] += _core.kirchhoff_drag_point(d, s_cl, x[on]) - _core.kirchhoff_drag_point(
                    d, st_cl, xs
                )
        else:
            cl[on] += s_cl - qual["CL_basic"].to_numpy()[on]
            cm[on] += s_cm - qual["Cm_basic"].to_numpy()[on]
            if d is not None and cd is not None:
                cd[on] += (
                    _core.kirchhoff_drag_point(d, s_cl, x[on])
                    - qual[STALL_DRAG_VARIABLE].to_numpy()[on]
                )
    out = {"x_sep_dot": xdot, "x_sep_0": x0, "CL_ext": cl, "Cm_ext": cm}
    return out | ({"CD_ext": cd} if cd is not None else {})


def extended_daveml_text(
    model: DeltaModel,
    qualified: str | PathLike[str] | None = None,
    *,
    channel_map: Mapping[str, str] | None = None,
    coefficients: Mapping[str, str] | None = None,
    seed: int = 0,
    rtol: float = 1e-12,
    longitudinal: bool = True,
) -> ExtendedExport:
    """The extended model as DAVE-ML text, verified against the engine.

    Parameters are those of :func:`extended_daveml_spec`; ``qualified`` is a DAVE-ML file
    (default: the built-in ADX-37 qualified model). Every check output ``dC`` and ``C_ext`` of
    the generated file is compared with the engine (``DeltaModel.evaluate`` plus the qualified
    model) to relative tolerance ``rtol``.

    Raises
    ------
    DataError
        The qualified model lacks a coefficient or a mapping refers to unknown variables.
    RuntimeError
        The file disagrees with the engine (a bug: please report it).
    """
    recorded = recorded_source(model.to_spec(), "adx37")
    if qualified is None and recorded != "adx37":
        raise DataError(
            f"the Δ was fitted against {describe(recorded)}, not the built-in ADX-37: give "
            "that simulator's DAVE-ML file to merge it into (--qualified FILE.dml, "
            "qualified=...); added to another aircraft's model it means nothing"
        )
    text, name, base = qualified_base(qualified)
    spec = extended_daveml_spec(
        model, base, channel_map=channel_map, coefficients=coefficients, seed=seed,
        longitudinal=longitudinal,
    )  # fmt: skip
    stall = longitudinal and bool(model.kirchhoff)
    # every sampled state verifies the file against the engine; only those inside the flown
    # flaps and alphas are published as its check cases (beyond them the file holds the edge
    # values, which no flight test supports)
    states = spec["checks"]
    spec["checks"] = [c for c in states if _flown(model, c["inputs"])]
    merged_text = _core.daveml_merge_xml(text, name, json.dumps(spec))
    merged = DaveModel.from_string(merged_text, name)
    cmap = {c: (coefficients or {}).get(c, c) for c in model.coefficients}
    if stall:
        cmap |= {c: (coefficients or {}).get(c, c) for c in _stall_totals(model)}
    ref = _engine_reference(model, base, merged, states, cmap, stall=stall)
    keys = sorted({k for s in states for k in s["inputs"]})
    data = {k: [s["inputs"].get(k, np.nan) for s in states] for k in keys}
    got = merged.evaluate(data, outputs=list(ref))
    worst = 0.0
    for k, want in ref.items():
        err = np.abs(got[k].to_numpy() - want) / np.maximum(np.abs(want), 1e-3)
        worst = max(worst, float(err.max()))
        if not np.all(err <= rtol):
            raise RuntimeError(
                f"extended DAVE-ML output {k} differs from the engine by {err.max():.3e} "
                f"(relative) at check '{states[int(err.argmax())]['name']}'"
            )
    checks = merged.run_checks()
    if not checks["pass"].all():
        bad = checks.filter(~pl.col("pass")).row(0, named=True)
        raise RuntimeError(f"extended DAVE-ML fails its own check: {bad}")
    return ExtendedExport(merged_text, merged, len(spec["checks"]), worst)


def export_extended_daveml(
    path: str | PathLike[str],
    model: DeltaModel,
    qualified: str | PathLike[str] | None = None,
    **kwargs: Any,
) -> ExtendedExport:
    """Write the extended model (qualified + blended Δ, thesis Eq. 3.12) as DAVE-ML, atomically.

    See :func:`extended_daveml_text` for the parameters and the verification done before
    writing; verify the file with ``aerodelta check-daveml``.
    """
    out = extended_daveml_text(model, qualified, **kwargs)
    write_atomic(path, out.text)
    return out
