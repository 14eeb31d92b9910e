"""Export the representative aircraft's qualified model to DAVE-ML (AIAA S-119).

The ADX-37 qualified model is a sum of gridded tables times regressors (see
``aero_core::aircraft::qualified``); DAVE-ML expresses it directly: one gridded-table variable per
(table, inputs) pair, and each output ``CL, CD, CY, Cl, Cm, Cn`` as a sum of products of tables
and inputs. Check cases are generated from the model itself, so any DAVE-ML tool can verify the
file (``aerodelta check-daveml``).
"""

from __future__ import annotations

import math
from os import PathLike
from typing import Any

from aerodelta.campaign import qualified_model_tables
from aerodelta.daveml import DaveModel, write_daveml

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
