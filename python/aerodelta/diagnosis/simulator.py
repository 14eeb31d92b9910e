"""The simulator whose gap to the flight data is diagnosed, and its sensitivities.

Three forms (issue 7, "Inputs"):

- a black box: the records carry its predictions as ``Cl_sim``, ``Cn_sim``, ``CY_sim``
  (no sensitivities: the measurement effects that need them are reported as not testable);
- a DAVE-ML file with outputs ``Cl``, ``Cn``, ``CY`` and inputs named as the data's channels
  (``alpha_deg``, ``beta_deg`` or ``beta_rad``, ``phat``, ``rhat``, ``da_deg``, ... as
  ``aerodelta export-qualified`` writes them), evaluated along the records;
- an aerodelta model file (``aerodelta fit``'s extended model): the built-in qualified model
  (or the ``*_sim`` columns) plus the model's blended Δ;
- nothing: the ``*_sim`` columns when present, else the built-in ADX-37 qualified model for
  data flown on the virtual aircraft, else refused (:mod:`aerodelta.qualified`).

Sensitivities ``dC/dx`` are central differences of the simulator in the channel ``x``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from aerodelta.diagnosis.vocabulary import COEFFICIENTS
from aerodelta.exceptions import DataError
from aerodelta.model import DeltaModel
from aerodelta.qualified import for_model, resolve

Predict = Callable[[pl.DataFrame], dict[str, np.ndarray]]


@dataclass(frozen=True)
class Simulator:
    """A simulator's lateral-directional coefficients along records.

    Attributes
    ----------
    name
        What it is (shown in the report).
    predict
        ``predict(frame) -> {"Cl": array, "Cn": array, "CY": array}``.
    differentiable
        True when ``predict`` can be called at perturbed states (a loadable model).
    """

    name: str
    predict: Predict
    differentiable: bool

    def sensitivity(self, frame: pl.DataFrame, column: str, step: float) -> dict[str, np.ndarray]:
        """Central difference ``dC/d(column)`` per coefficient, per unit of ``column``."""
        if column not in frame.columns:
            return {c: np.zeros(frame.height) for c in COEFFICIENTS}
        x = frame[column].cast(pl.Float64)
        up = self.predict(frame.with_columns((x + step).alias(column)))
        dn = self.predict(frame.with_columns((x - step).alias(column)))
        return {c: (up[c] - dn[c]) / (2.0 * step) for c in COEFFICIENTS}


def load_simulator(
    model: str | Path | None, data: pl.DataFrame, cbar_m: float | None = None
) -> Simulator:
    """The simulator to diagnose.

    Parameters
    ----------
    model
        A DAVE-ML file (``.dml``/``.xml``), an aerodelta model file (``.json``: the qualified
        model it was fitted against plus its blended Δ), or ``None``: the records' ``*_sim``
        columns, else the built-in ADX-37 qualified model for data flown on the virtual
        aircraft, else refused (:func:`aerodelta.qualified.resolve`).
    data
        A model frame (CG angles as ``alpha_deg``/``beta_deg``), to check the columns.
    cbar_m
        Mean aerodynamic chord, m, for ``alphadot_hat`` inputs of DAVE-ML models (None: the
        chord the data's ``qhat`` was formed with).
    """
    if model is None:
        q = resolve(data, "auto")
        return Simulator(q.description, q.predict, q.differentiable)
    path = Path(model)
    if not path.is_file():
        raise DataError(f"{path}: no such model file; pass a DAVE-ML (.dml) or aerodelta (.json)")
    if path.suffix.lower() in (".dml", ".xml"):
        q = resolve(data, path, cbar_m)
        return Simulator(q.description, q.predict, q.differentiable)
    if path.suffix.lower() == ".json":
        dm = DeltaModel.load(path)
        hint = (
            f"diagnose the extended DAVE-ML model instead ({path.name} exported with "
            "aerodelta export --qualified THAT.dml --daveml EXT.dml)"
        )
        base = resolve(data, for_model(dm.to_spec(), "auto", hint))

        def predict(frame: pl.DataFrame) -> dict[str, np.ndarray]:
            b = base.predict(frame)
            d = dm.evaluate(frame)
            return {
                c: b[c] + (d[f"d{c}_blended"].to_numpy() if f"d{c}_blended" in d.columns else 0.0)
                for c in COEFFICIENTS
            }

        return Simulator(f"extended model {path.name}", predict, base.differentiable)
    raise DataError(
        f"{path}: unknown model format '{path.suffix}'; use a DAVE-ML (.dml) or aerodelta (.json)"
    )


def deg_step() -> float:
    """Finite-difference step for angles, deg."""
    return 0.25
