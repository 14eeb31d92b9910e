"""DAVE-ML (AIAA S-119) models: load, evaluate, check and write (engine: ``aero_core::daveml``).

A DAVE-ML file declares variables (with units), gridded tables and MathML
calculations, plus static check cases published with the model. This module
loads such a file, evaluates it on arrays or polars DataFrames, runs its check
cases, and writes models of gridded tables combined by sums of products with
check cases generated from the model itself.

The project's own example, :func:`example_model`, is a small lateral-directional
aero model of a twin turboprop; ``aerodelta write-example-model`` writes it and
``aerodelta check-daveml`` verifies it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from os import PathLike
from typing import Any

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta import _core

__all__ = [
    "DaveModel",
    "check_daveml",
    "daveml_text",
    "example_model",
    "load_daveml",
    "write_daveml",
    "write_example_model",
]

_CHECK_COLUMNS = [
    "shot",
    "variable",
    "name",
    "units",
    "kind",
    "expected",
    "actual",
    "tolerance",
    "pass",
]


class DaveModel:
    """A DAVE-ML model compiled for evaluation.

    Parameters
    ----------
    path
        DAVE-ML file (``.dml`` / ``.xml``).

    Raises
    ------
    aerodelta.ParseError
        Malformed file: the message names the file, line and element (unknown
        varID, table size, non-increasing breakpoints, dependency cycle, unit
        mismatch in a check case, ...).
    aerodelta.AeroIOError
        The file cannot be read.
    """

    __slots__ = ("_m",)

    def __init__(self, path: str | PathLike[str]) -> None:
        self._m = _core.DaveModel(str(path))

    @classmethod
    def _from_core(cls, m: _core.DaveModel) -> DaveModel:
        obj = cls.__new__(cls)
        obj._m = m
        return obj

    @classmethod
    def from_string(cls, text: str, name: str = "<string>") -> DaveModel:
        """Compile DAVE-ML text; ``name`` names it in error messages."""
        return cls._from_core(_core.DaveModel.from_string(text, name))

    @property
    def name(self) -> str:
        """Model name (``fileHeader name``, else the file name)."""
        return self._m.name

    @property
    def inputs(self) -> list[str]:
        """varIDs of the inputs (``isInput``, or free with no initial value)."""
        return self._m.inputs

    @property
    def outputs(self) -> list[str]:
        """varIDs of the variables flagged ``isOutput``."""
        return self._m.outputs

    @property
    def n_shots(self) -> int:
        """Number of static check cases in the file."""
        return self._m.n_shots

    def variables(self) -> pl.DataFrame:
        """Every variable: ``id, name, units, is_input, is_output, initial_value, min_value,
        max_value``, in file order."""
        rows = self._m.variables()
        return pl.DataFrame(
            rows,
            schema={
                "id": pl.String,
                "name": pl.String,
                "units": pl.String,
                "is_input": pl.Boolean,
                "is_output": pl.Boolean,
                "initial_value": pl.Float64,
                "min_value": pl.Float64,
                "max_value": pl.Float64,
            },
            orient="row",
        )

    def uncertainty(self) -> pl.DataFrame:
        """The ``uncertainty`` elements of the file's variables and tables (DAVE-ML 2.0),
        each checked when the file was read (bounds bracketing an absolute nominal value, a
        ``dataTable`` bound shaped as its table).

        Returns
        -------
        polars.DataFrame
            One row per uncertainty: ``variable`` (varID; a table's: the variable its function
            defines), ``effect`` (``additive``, ``multiplicative``, ``percentage``,
            ``absolute``), ``distribution`` (``normal``, ``uniform``), ``num_sigmas`` (null
            for uniform), ``bounds`` (one list per ``bounds`` element, in the variable's units
            for ``additive``/``absolute``: a number, or a table's values in its row-major
            order; empty for a ``variableRef``), ``bound_variables`` (the varID of a
            ``variableRef`` bound, else ""), ``line``.
        """
        rows = [
            (v, e, d, None if math.isnan(s) else s, b, r, line)
            for v, e, d, s, b, r, line in self._m.uncertainties()
        ]
        return pl.DataFrame(
            rows,
            schema={
                "variable": pl.String,
                "effect": pl.String,
                "distribution": pl.String,
                "num_sigmas": pl.Float64,
                "bounds": pl.List(pl.List(pl.Float64)),
                "bound_variables": pl.List(pl.String),
                "line": pl.Int64,
            },
            orient="row",
        )

    def evaluate(
        self,
        data: pl.DataFrame | Mapping[str, npt.ArrayLike],
        outputs: Sequence[str] | None = None,
        *,
        ignore_extra: bool = False,
    ) -> pl.DataFrame:
        """Evaluate the model at many points.

        Parameters
        ----------
        data
            Input values by varID, in the variables' own units (e.g. ``deg``):
            a polars DataFrame or a mapping of arrays/scalars (broadcast to a
            common length). Inputs not given take their ``initialValue``.
        outputs
            varIDs to return (default: the model's outputs). Any variable,
            internal ones included, may be asked for.
        ignore_extra
            Skip columns that are not variables of the model (e.g. other flight
            data channels) instead of raising.

        Returns
        -------
        polars.DataFrame
            One column per requested output, one row per point.

        Raises
        ------
        aerodelta.InvalidInputError
            Unknown or computed varID given as input, a missing input without an
            initial value, or columns of different lengths.

        Examples
        --------
        >>> m = DaveModel.from_string(
        ...     '<DAVEfunc><variableDef name="a" varID="a" units="deg"><isInput/></variableDef>'
        ...     '<variableDef name="y" varID="y" units="nd"><isOutput/></variableDef>'
        ...     '<function name="f"><independentVarPts varID="a">0, 10</independentVarPts>'
        ...     '<dependentVarPts varID="y">0, 1</dependentVarPts></function></DAVEfunc>')
        >>> m.evaluate({"a": [2.5, 5.0]})["y"].to_list()
        [0.25, 0.5]
        """
        if isinstance(data, pl.DataFrame):
            items: list[tuple[str, Any]] = [(c, data[c].to_numpy()) for c in data.columns]
        else:
            items = list(data.items())
        if ignore_extra:
            known = set(self.variables()["id"].to_list())
            items = [(k, v) for k, v in items if k in known]
        arrays = [np.asarray(v, dtype=np.float64) for _, v in items]
        if arrays:
            arrays = list(np.broadcast_arrays(*arrays))
        cols = {
            str(k): np.ascontiguousarray(a.ravel()) for (k, _), a in zip(items, arrays, strict=True)
        }
        outs = list(outputs) if outputs is not None else self.outputs
        values = self._m.evaluate(cols, outs)
        return pl.DataFrame(values, schema=dict.fromkeys(outs, pl.Float64))

    def run_checks(self) -> pl.DataFrame:
        """Run the file's static check cases.

        Returns
        -------
        polars.DataFrame
            One row per shot and checked variable: ``shot, variable, name, units,
            kind`` (``output`` or ``internal``), ``expected, actual, tolerance,
            pass``. Outputs use their own ``<tol>``; internal values the largest
            output tolerance of their shot.
        """
        return _checks_frame(self._m.run_checks())

    def __repr__(self) -> str:
        return (
            f"DaveModel({self.name!r}; {len(self.inputs)} inputs, {len(self.outputs)} outputs, "
            f"{self.n_shots} check cases)"
        )


def _checks_frame(
    rows: list[tuple[str, str, str, str, str, float, float, float, bool]],
) -> pl.DataFrame:
    schema = {
        "shot": pl.String,
        "variable": pl.String,
        "name": pl.String,
        "units": pl.String,
        "kind": pl.String,
        "expected": pl.Float64,
        "actual": pl.Float64,
        "tolerance": pl.Float64,
        "pass": pl.Boolean,
    }
    return pl.DataFrame(rows, schema=schema, orient="row")


def load_daveml(path: str | PathLike[str]) -> DaveModel:
    """Load a DAVE-ML file (see :class:`DaveModel`)."""
    return DaveModel(path)


def check_daveml(path: str | PathLike[str]) -> pl.DataFrame:
    """Load a DAVE-ML file and run its check cases (see :meth:`DaveModel.run_checks`)."""
    return DaveModel(path).run_checks()


def _plain(x: Any) -> Any:
    """Convert numpy arrays/scalars inside dicts and lists to plain Python for JSON."""
    if isinstance(x, Mapping):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        return x.astype(np.float64).ravel().tolist() if x.dtype.kind in "fiu" else x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, list | tuple):
        return [_plain(v) for v in x]
    return x


def _spec_json(spec: Mapping[str, Any]) -> str:
    return json.dumps(_plain(spec), allow_nan=True)


def daveml_text(spec: Mapping[str, Any]) -> str:
    """The DAVE-ML text of a model spec (see :func:`write_daveml`), check cases included."""
    return _core.daveml_to_xml(_spec_json(spec))


def write_daveml(path: str | PathLike[str], spec: Mapping[str, Any]) -> DaveModel:
    """Write a model spec as a DAVE-ML file, atomically, with generated check cases.

    Parameters
    ----------
    path
        Output file; written as ``path.tmp-<pid>`` in the same folder, then renamed.
    spec
        Plain Python (lists, dicts, numpy arrays) with keys:

        - ``name`` (str), optional ``description``, ``author``, ``date`` (ISO);
        - ``inputs``: list of ``{"id", "name"?, "units"?, "description"?, "min"?,
          "max"?, "initial"?}`` (``min``/``max`` become ``minValue``/``maxValue``
          and the tables' ``independentVarRef`` limits);
        - ``tables``: list of ``{"id", "name"?, "units"?, "description"?, "args":
          [varID, ...], "breakpoints": [[...], ...], "values": array (row-major,
          last axis fastest, or shaped), "extrapolate"?: "neither"|"min"|"max"|"both",
          "is_output"?: bool}``;
        - ``outputs``: list of ``{"id", "name"?, "units"?, "description"?, "terms":
          [{"coef"?: float, "factors": [varID, ...]}, ...]}``, the output being
          the sum over terms of ``coef * prod(factors)``;
        - ``checks``: list of ``{"name", "inputs": {varID: value}}`` where check
          cases are generated by evaluating the model;
        - ``check_tolerance`` (default 1e-9), written on every check output.

    Returns
    -------
    DaveModel
        The model read back from the written text (its checks verified).

    Raises
    ------
    aerodelta.InvalidInputError
        A malformed spec: the message names the table, input or output at fault.
    aerodelta.AeroIOError
        The file cannot be written.
    """
    return DaveModel._from_core(_core.daveml_write(str(path), _spec_json(spec)))


# -- The project's example model ------------------------------------------------------------

#: Angle-of-attack breakpoints of the example tables, deg.
_ALPHA = [-4.0, 0.0, 4.0, 8.0, 10.0, 12.0, 14.0, 16.0, 18.0, 20.0, 24.0]


def _schedule(nominal: float, points: Mapping[float, float]) -> list[float]:
    """Values over ``_ALPHA``: ``nominal`` up to 10 deg, then the given knots (linear between)."""
    xs = [10.0, *sorted(points)]
    ys = [nominal, *(points[k] for k in sorted(points))]
    return [float(nominal if a <= 10.0 else np.interp(a, xs, ys)) for a in _ALPHA]


def example_model() -> dict[str, Any]:
    """The project's own example: a lateral-directional aero model of a twin turboprop.

    Inputs ``alpha_deg``, ``beta_deg`` (deg), ``p_hat = p b/(2V)``, ``r_hat = r b/(2V)``
    (non-dimensional), ``da_deg``, ``dr_deg`` (deg; positive aileron rolls left, positive
    rudder yaws left, Etkin). Stability and control derivatives are tables in alpha with
    plausible linear-range values (per rad: Cl_beta -0.1, Cl_p -0.5, Cl_r 0.12, Cl_da
    -0.15, Cn_beta 0.1, Cn_p -0.05, Cn_r -0.15, Cn_dr -0.1, CY_beta -0.8, CY_dr 0.15)
    that degrade between 12 and 16 deg as the wing stalls (dihedral effect and roll
    damping are lost, roll damping turns slightly unstable near 18 deg). Outputs:

    - ``Cl = (Cl_beta beta + Cl_da da) pi/180 + Cl_p p_hat + Cl_r r_hat``
    - ``Cn = (Cn_beta beta + Cn_dr dr) pi/180 + Cn_p p_hat + Cn_r r_hat``
    - ``CY = (CY_beta beta + CY_dr dr) pi/180``

    Returns
    -------
    dict
        A spec for :func:`write_daveml`, with check points spanning the linear range,
        the stall break and beyond the tables.
    """
    d2r = math.pi / 180.0
    tables = {
        "Cl_beta": (-0.10, {12.0: -0.085, 14.0: -0.05, 16.0: -0.02, 18.0: 0.0, 24.0: 0.01}),
        "Cl_p": (-0.50, {12.0: -0.45, 14.0: -0.30, 16.0: -0.10, 18.0: 0.05, 24.0: -0.02}),
        "Cl_r": (0.12, {12.0: 0.14, 14.0: 0.16, 16.0: 0.15, 24.0: 0.10}),
        "Cl_da": (-0.15, {12.0: -0.135, 14.0: -0.11, 16.0: -0.07, 24.0: -0.05}),
        "Cn_beta": (0.10, {12.0: 0.095, 14.0: 0.075, 16.0: 0.04, 24.0: 0.02}),
        "Cn_p": (-0.05, {12.0: -0.06, 14.0: -0.07, 16.0: -0.05, 24.0: -0.02}),
        "Cn_r": (-0.15, {12.0: -0.145, 14.0: -0.13, 16.0: -0.10, 24.0: -0.08}),
        "Cn_dr": (-0.10, {12.0: -0.097, 14.0: -0.09, 16.0: -0.08, 24.0: -0.07}),
        "CY_beta": (-0.80, {12.0: -0.78, 14.0: -0.72, 16.0: -0.65, 24.0: -0.60}),
        "CY_dr": (0.15, {12.0: 0.148, 14.0: 0.14, 16.0: 0.13, 24.0: 0.12}),
    }
    per_rad = {"Cl_beta", "Cl_da", "Cn_beta", "Cn_dr", "CY_beta", "CY_dr"}

    def inp(id_: str, units: str, lo: float, hi: float, desc: str) -> dict[str, Any]:
        return {
            "id": id_,
            "units": units,
            "min": lo,
            "max": hi,
            "initial": 0.0,
            "description": desc,
        }

    def term(table: str, var: str) -> dict[str, Any]:
        return {"coef": d2r if table in per_rad else 1.0, "factors": [table, var]}

    checks = [
        {"name": "trim, alpha 4", "inputs": {"alpha_deg": 4.0}},
        {"name": "sideslip 5 deg, alpha 8", "inputs": {"alpha_deg": 8.0, "beta_deg": 5.0}},
        {"name": "roll rate, alpha 6", "inputs": {"alpha_deg": 6.0, "p_hat": 0.05}},
        {"name": "yaw rate, alpha 6", "inputs": {"alpha_deg": 6.0, "r_hat": -0.03}},
        {"name": "aileron 10 deg, alpha 2", "inputs": {"alpha_deg": 2.0, "da_deg": 10.0}},
        {"name": "rudder -15 deg, alpha 9", "inputs": {"alpha_deg": 9.0, "dr_deg": -15.0}},
        {
            "name": "combined, stall break alpha 13.3",
            "inputs": {
                "alpha_deg": 13.3,
                "beta_deg": -3.7,
                "p_hat": 0.021,
                "r_hat": 0.012,
                "da_deg": -6.5,
                "dr_deg": 4.2,
            },
        },
        {
            "name": "post-stall alpha 17",
            "inputs": {"alpha_deg": 17.0, "beta_deg": 2.0, "p_hat": -0.04, "da_deg": 12.0},
        },
        {
            "name": "beyond tables, alpha 28",
            "inputs": {"alpha_deg": 28.0, "beta_deg": 4.0, "dr_deg": -10.0},
        },
    ]
    return {
        "name": "ADX-72 lateral-directional aero (aerodelta example)",
        "description": (
            "Representative twin turboprop lateral-directional aerodynamics: stability and "
            "control derivatives tabulated in angle of attack, degrading through the stall "
            "(12-16 deg). Body axes, Etkin sign conventions: positive aileron rolls left, "
            "positive rudder yaws left. Check cases generated by aerodelta from the model."
        ),
        "inputs": [
            inp("alpha_deg", "deg", -10.0, 30.0, "angle of attack"),
            inp("beta_deg", "deg", -25.0, 25.0, "angle of sideslip"),
            inp("p_hat", "nd", -0.3, 0.3, "non-dimensional roll rate p b/(2V)"),
            inp("r_hat", "nd", -0.3, 0.3, "non-dimensional yaw rate r b/(2V)"),
            inp("da_deg", "deg", -25.0, 25.0, "aileron deflection, positive rolls left"),
            inp("dr_deg", "deg", -30.0, 30.0, "rudder deflection, positive yaws left"),
        ],
        "tables": [
            {
                "id": name,
                "units": "_rad" if name in per_rad else "nd",
                "description": f"{name} versus angle of attack",
                "args": ["alpha_deg"],
                "breakpoints": [_ALPHA],
                "values": _schedule(nominal, knots),
                "extrapolate": "neither",
            }
            for name, (nominal, knots) in tables.items()
        ],
        "outputs": [
            {
                "id": "Cl",
                "description": "rolling moment coefficient (body axes)",
                "terms": [
                    term("Cl_beta", "beta_deg"),
                    term("Cl_p", "p_hat"),
                    term("Cl_r", "r_hat"),
                    term("Cl_da", "da_deg"),
                ],
            },
            {
                "id": "Cn",
                "description": "yawing moment coefficient (body axes)",
                "terms": [
                    term("Cn_beta", "beta_deg"),
                    term("Cn_p", "p_hat"),
                    term("Cn_r", "r_hat"),
                    term("Cn_dr", "dr_deg"),
                ],
            },
            {
                "id": "CY",
                "description": "side force coefficient (body axes)",
                "terms": [term("CY_beta", "beta_deg"), term("CY_dr", "dr_deg")],
            },
        ],
        "checks": checks,
        "check_tolerance": 1e-9,
    }


def write_example_model(path: str | PathLike[str]) -> DaveModel:
    """Write :func:`example_model` as DAVE-ML at ``path`` (atomic) and return it read back."""
    return write_daveml(path, example_model())
