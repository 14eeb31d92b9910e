"""The simulator whose gap to the flight data is diagnosed, and its sensitivities.

Three forms (issue 7, "Inputs"):

- a black box: the records carry its predictions as ``Cl_sim``, ``Cn_sim``, ``CY_sim``
  (no sensitivities: the measurement effects that need them are reported as not testable);
- a DAVE-ML file with outputs ``Cl``, ``Cn``, ``CY`` and inputs named as the data's channels
  (``alpha_deg``, ``beta_deg`` or ``beta_rad``, ``phat``, ``rhat``, ``da_deg``, ... as
  ``aerodelta export-qualified`` writes them), evaluated along the records;
- an aerodelta model file (``aerodelta fit``'s extended model): the built-in qualified model
  (or the ``*_sim`` columns) plus the model's blended Δ;
- nothing: the ``*_sim`` columns when present, else the built-in ADX-37 qualified model.

Sensitivities ``dC/dx`` are central differences of the simulator in the channel ``x``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from aerodelta.daveml import DaveModel
from aerodelta.diagnosis.vocabulary import COEFFICIENTS
from aerodelta.exceptions import DataError
from aerodelta.fit import qualified_coefficients
from aerodelta.model import DeltaModel

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


def _columns_sim(frame: pl.DataFrame) -> dict[str, np.ndarray]:
    return {c: frame[f"{c}_sim"].cast(pl.Float64).to_numpy() for c in COEFFICIENTS}


def _builtin(frame: pl.DataFrame) -> dict[str, np.ndarray]:
    q = qualified_coefficients(frame, "adx37")
    return {c: q[f"{c}_qual"].to_numpy() for c in COEFFICIENTS}


def _daveml(path: Path, cbar_m: float) -> Predict:
    model = DaveModel(path)
    missing = [c for c in COEFFICIENTS if c not in model.outputs]
    if missing:
        raise DataError(
            f"{path}: the DAVE-ML model has no output(s) {missing} (outputs: {model.outputs}); "
            "the diagnosis needs Cl, Cn and CY"
        )
    known = set(model.inputs)

    def predict(frame: pl.DataFrame) -> dict[str, np.ndarray]:
        v = frame["tas_mps"].cast(pl.Float64).to_numpy()
        cols: dict[str, np.ndarray] = {}
        for c in frame.columns:
            if c in known and frame[c].dtype.is_numeric():
                cols[c] = frame[c].cast(pl.Float64).fill_null(0.0).to_numpy()
        if "beta_rad" in known and "beta_deg" in frame.columns:
            cols["beta_rad"] = np.radians(frame["beta_deg"].cast(pl.Float64).to_numpy())
        if "de_rad" in known and "de_deg" in frame.columns:
            cols["de_rad"] = np.radians(frame["de_deg"].cast(pl.Float64).to_numpy())
        if "alphadot_hat" in known and "alphadot_dps" in frame.columns:
            ad = np.radians(frame["alphadot_dps"].cast(pl.Float64).to_numpy())
            cols["alphadot_hat"] = ad * cbar_m / (2.0 * np.maximum(v, 1.0))
        out = model.evaluate(cols, list(COEFFICIENTS))
        return {c: out[c].to_numpy() for c in COEFFICIENTS}

    return predict


def load_simulator(model: str | Path | None, data: pl.DataFrame, cbar_m: float = 2.0) -> Simulator:
    """The simulator to diagnose.

    Parameters
    ----------
    model
        A DAVE-ML file (``.dml``/``.xml``), an aerodelta model file (``.json``), or ``None``
        (the records' ``*_sim`` columns when present, else the built-in ADX-37 qualified model).
    data
        A model frame (CG angles as ``alpha_deg``/``beta_deg``), to check the columns.
    cbar_m
        Mean aerodynamic chord, m (for ``alphadot_hat`` inputs of DAVE-ML models).
    """
    has_cols = all(f"{c}_sim" in data.columns for c in COEFFICIENTS)
    if model is None:
        if has_cols:
            return Simulator("the records' Cl_sim, Cn_sim, CY_sim columns", _columns_sim, False)
        return Simulator("built-in ADX-37 qualified model", _builtin, True)
    path = Path(model)
    if not path.is_file():
        raise DataError(f"{path}: no such model file; pass a DAVE-ML (.dml) or aerodelta (.json)")
    if path.suffix.lower() in (".dml", ".xml"):
        return Simulator(f"DAVE-ML model {path.name}", _daveml(path, cbar_m), True)
    if path.suffix.lower() == ".json":
        dm = DeltaModel.load(path)
        base: Predict = _columns_sim if has_cols else _builtin

        def predict(frame: pl.DataFrame) -> dict[str, np.ndarray]:
            b = base(frame)
            d = dm.evaluate(frame)
            return {
                c: b[c] + (d[f"d{c}_blended"].to_numpy() if f"d{c}_blended" in d.columns else 0.0)
                for c in COEFFICIENTS
            }

        return Simulator(f"extended model {path.name}", predict, not has_cols)
    raise DataError(
        f"{path}: unknown model format '{path.suffix}'; use a DAVE-ML (.dml) or aerodelta (.json)"
    )


def deg_step() -> float:
    """Finite-difference step for angles, deg."""
    return 0.25
