"""Which simulator is the qualified model: named by the user, never guessed.

The Δ is the gap between the aircraft and *a* simulator, so the simulator must be the user's.
It is one of

- ``"columns"``: the records carry the simulator's predictions along the flown states as
  ``Cl_sim``, ``Cn_sim``, ``CY_sim`` (a black-box simulator);
- a DAVE-ML file (``.dml``/``.xml``) with outputs ``Cl``, ``Cn``, ``CY`` and inputs named as
  the data's channels (``alpha_deg``, ``beta_deg`` or ``beta_rad``, ``phat``, ``rhat``,
  ``da_deg``, ... as ``aerodelta export-qualified`` writes them), evaluated along the records;
- ``"jsbsim:DIR"``: the qualified JSBSim aircraft of the JSBSim campaign ``DIR``
  (``aerodelta campaign --simulator jsbsim``), evaluated by JSBSim at every recorded state
  (:func:`jsbsim_predict`);
- ``"adx37"``: the built-in virtual aircraft's qualified model, for data flown on it.

``"auto"`` takes the columns when the records carry them, else the built-in model when the
data were flown on the virtual aircraft (ingest marks them, :data:`BUILTIN_COLUMN`, from the
campaign's ``aircraft.toml``), and otherwise refuses: a Δ against another aircraft's model
means nothing for the user's aircraft.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from aerodelta import _core
from aerodelta._threads import engine_threads
from aerodelta.aircraft import BUILTIN_COLUMN
from aerodelta.daveml import DaveModel
from aerodelta.exceptions import DataError

#: The lateral-directional coefficients a qualified model gives.
COEFFICIENTS = ("Cl", "Cn", "CY")

Predict = Callable[[pl.DataFrame], dict[str, np.ndarray]]

#: ``source`` -> what it is, in words (reports and summaries).
DESCRIPTIONS = {
    "columns": "the records' Cl_sim, Cn_sim, CY_sim columns",
    "adx37": "built-in ADX-37 qualified model",
}


@dataclass(frozen=True)
class Qualified:
    """A resolved qualified model.

    Attributes
    ----------
    source
        ``"columns"``, ``"adx37"`` or ``"daveml:<file name>"`` (recorded in the fitted
        model's provenance).
    predict
        ``predict(frame) -> {"Cl": array, "Cn": array, "CY": array}`` along a model frame.
    differentiable
        True when ``predict`` can be called at perturbed states (a loadable model).
    """

    source: str
    predict: Predict
    differentiable: bool

    @property
    def description(self) -> str:
        """What the model is, in words."""
        return describe(self.source)


#: Prefix of a JSBSim qualified model: ``"jsbsim:<campaign folder>"``.
JSBSIM = "jsbsim:"


def describe(source: str) -> str:
    """A qualified model's ``source`` (``"columns"``, ``"adx37"``, ``"daveml:NAME"``,
    ``"jsbsim:DIR"``) in words."""
    if source.startswith("daveml:"):
        return f"DAVE-ML model {source.split(':', 1)[1]}"
    if source.startswith(JSBSIM):
        return f"the qualified JSBSim aircraft of campaign {source[len(JSBSIM) :]}"
    return DESCRIPTIONS.get(source, source)


def recorded_source(spec: Mapping[str, Any], default: str) -> str:
    """The qualified model a fitted model's spec records (``provenance.qualified``), or
    ``default`` for a model fitted before it was recorded."""
    return str((spec.get("provenance") or {}).get("qualified", default))


def for_model(spec: Mapping[str, Any], qualified: str | Path, hint: str) -> str | Path:
    """The qualified model to evaluate a fitted model's spec against: ``qualified`` when named,
    for ``"auto"`` the one the fit recorded (``"auto"`` again for a model that recorded none).

    Raises
    ------
    DataError
        ``"auto"`` for a model fitted against a DAVE-ML file, which it records by name only:
        "the model was fitted against the DAVE-ML model NAME; ``hint``"; likewise for a
        JSBSim campaign (``"jsbsim:NAME"``), to be named again as ``jsbsim:DIR``.
    """
    if str(qualified) != "auto":
        return qualified
    recorded = recorded_source(spec, "auto")
    if recorded.startswith(JSBSIM):
        raise DataError(
            f"the model was fitted against the qualified JSBSim aircraft of campaign "
            f"{recorded[len(JSBSIM) :]}; name the campaign folder again (qualified="
            "'jsbsim:DIR', CLI --qualified jsbsim:DIR)"
        )
    if recorded.startswith("daveml:"):
        raise DataError(
            f"the model was fitted against the DAVE-ML model {recorded.split(':', 1)[1]}; {hint}"
        )
    return recorded


def has_columns(data: pl.DataFrame) -> bool:
    """Whether the records carry the simulator's ``Cl_sim``, ``Cn_sim``, ``CY_sim``."""
    return all(f"{c}_sim" in data.columns for c in COEFFICIENTS)


def flown_on_builtin(data: pl.DataFrame) -> bool:
    """Whether every row was flown on the built-in virtual aircraft (ingest's mark)."""
    if BUILTIN_COLUMN not in data.columns or data.height == 0:
        return False
    col = data[BUILTIN_COLUMN].cast(pl.Utf8)
    return bool((col == "adx37").all())


def _columns(frame: pl.DataFrame) -> dict[str, np.ndarray]:
    return {c: frame[f"{c}_sim"].cast(pl.Float64).to_numpy() for c in COEFFICIENTS}


_ADX37_INPUTS = (
    "alpha_deg", "beta_deg", "phat", "qhat", "rhat", "alphadot_dps", "betadot_dps",
    "da_deg", "de_deg", "dr_deg", "dsl_deg", "dsr_deg", "flap_deg", "ct_left", "ct_right",
    "tas_mps",
)  # fmt: skip


def _adx37(frame: pl.DataFrame) -> dict[str, np.ndarray]:
    cols = {}
    for n in _ADX37_INPUTS:
        if n in frame.columns:
            cols[n] = np.ascontiguousarray(frame[n].cast(pl.Float64).fill_null(0.0).to_numpy())
        elif n in ("dsl_deg", "dsr_deg", "de_deg"):
            cols[n] = np.zeros(frame.height)
    # row chunks side by side (the engine releases the GIL; row-wise, so chunking is exact)
    n = frame.height
    step = max(50_000, -(-n // engine_threads(cap=4)))
    chunks = [{k: v[i : i + step] for k, v in cols.items()} for i in range(0, max(n, 1), step)]
    with ThreadPoolExecutor(max_workers=len(chunks)) as ex:
        parts = list(ex.map(_core.qualified_lateral_adx37, chunks))
    return {c: np.concatenate([p[k] for p in parts]) for k, c in enumerate(COEFFICIENTS)}


def chord_of(frame: pl.DataFrame) -> float:
    """The mean aerodynamic chord (m) the data's ``qhat = q c̄ / 2V`` was formed with (ingest
    computes it from the smoothed pitch rate ``q_s_dps``), NaN when no row pitches."""
    need = ("qhat", "q_s_dps", "tas_mps")
    if any(c not in frame.columns for c in need):
        return float("nan")
    q = np.radians(frame["q_s_dps"].cast(pl.Float64).to_numpy())
    qhat = frame["qhat"].cast(pl.Float64).to_numpy()
    v = frame["tas_mps"].cast(pl.Float64).to_numpy()
    ok = np.isfinite(q) & np.isfinite(qhat) & np.isfinite(v) & (np.abs(q) > np.radians(0.5))
    if not ok.any():
        return float("nan")
    return float(np.median(2.0 * v[ok] * qhat[ok] / q[ok]))


def daveml_predict(path: Path, cbar_m: float | None = None) -> Predict:
    """Evaluate a DAVE-ML qualified model along model frames.

    ``cbar_m`` (m) forms ``alphadot_hat`` when the model takes it; None: the chord the data's
    ``qhat`` was formed with (:func:`chord_of`).

    Raises
    ------
    DataError
        The file lacks an output ``Cl``, ``Cn`` or ``CY``.
    """
    model = DaveModel(path)
    missing = [c for c in COEFFICIENTS if c not in model.outputs]
    if missing:
        raise DataError(
            f"{path}: the DAVE-ML model has no output(s) {missing} (outputs: {model.outputs}); "
            "a qualified model needs Cl, Cn and CY"
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
            c = chord_of(frame) if cbar_m is None else cbar_m
            if not np.isfinite(c):
                raise DataError(
                    f"{path}: the model takes alphadot_hat, and the data give no chord to "
                    "form it with (no qhat, q_s_dps or pitch motion)"
                )
            ad = np.radians(frame["alphadot_dps"].cast(pl.Float64).to_numpy())
            cols["alphadot_hat"] = ad * c / (2.0 * np.maximum(v, 1.0))
        out = model.evaluate(cols, list(COEFFICIENTS))
        return {c: out[c].to_numpy() for c in COEFFICIENTS}

    return predict


def jsbsim_predict(campaign: Path) -> Predict:
    """The qualified JSBSim aircraft of a JSBSim campaign evaluated along model frames.

    The aircraft is the campaign's own with its withheld terms frozen above the withhold alpha
    (:func:`aerodelta.jsbsim_replay.write_replay_aircraft`, ``variant="qualified"``); at every
    sample JSBSim's initial conditions are set to the recorded altitude, airspeed, alpha, beta,
    Euler angles, body rates, surfaces and flaps and its aerodynamic moments and side force
    read back (:func:`aerodelta.jsbsim_replay.aero_along`: ``Cl``, ``Cn`` about the CG over
    q̄Sb, ``CY`` over q̄S). The samples' states must be finite: the model frame's
    ``alpha_deg``/``beta_deg`` (CG angles), SI and degrees as ingested.

    Raises
    ------
    DataError
        Not a JSBSim campaign (no ``truth/truth.json``), or an aircraft with propellers:
        JSBSim computes their torque and gyroscopic moments from its engines' state, which a
        recorded state does not set, while the measured coefficients hold them; a Δ against
        the aerodynamics alone would absorb them (give the simulator's total as ``*_sim``
        columns instead).
    InvalidInputError
        The ``jsbsim`` package is not installed.
    """
    from aerodelta import jsbsim_replay as jr  # noqa: PLC0415  (jsbsim is optional)

    setup = jr.load_setup(campaign)
    props = jr.propellers(setup)
    if props:
        raise DataError(
            f"{campaign}: the JSBSim {setup.cfg.model} has propellers ({', '.join(props)}), "
            "whose torque and gyroscopic moments JSBSim computes from its engines' state, not "
            "from a recorded state; the qualified model 'jsbsim:' gives the aerodynamics only "
            "and the Δ would absorb them: give the simulator's total as Cl_sim, Cn_sim, CY_sim "
            "columns (qualified='columns')"
        )

    def predict(frame: pl.DataFrame) -> dict[str, np.ndarray]:
        return jr.aero_along(setup, frame)

    return predict


NO_SIMULATOR = (
    "no qualified model for these records: they carry no Cl_sim, Cn_sim, CY_sim columns (your "
    "simulator's predictions along the flown states) and were not flown on the built-in "
    "virtual aircraft; add the columns, give your simulator as a DAVE-ML file (qualified="
    "'model.dml', CLI --model model.dml), or choose the built-in ADX-37 on purpose "
    "(qualified='adx37')"
)


def resolve(
    data: pl.DataFrame, qualified: str | Path = "auto", cbar_m: float | None = None
) -> Qualified:
    """The qualified model named by ``qualified`` for the model frame ``data``.

    Parameters
    ----------
    data
        A model frame (CG angles as ``alpha_deg``/``beta_deg``).
    qualified
        ``"auto"``, ``"columns"``, ``"adx37"``, ``"jsbsim:DIR"`` (a JSBSim campaign folder)
        or the path of a DAVE-ML file.
    cbar_m
        Mean aerodynamic chord for a DAVE-ML model's ``alphadot_hat``, m (None: the data's).

    Raises
    ------
    DataError
        ``"auto"`` with neither columns nor the virtual aircraft's mark; ``"columns"`` without
        them; a DAVE-ML file that does not exist or lacks an output; an unknown name.
    """
    q = str(qualified)
    if q == "auto":
        if has_columns(data):
            q = "columns"
        elif flown_on_builtin(data):
            q = "adx37"
        else:
            raise DataError(NO_SIMULATOR)
    if q == "columns":
        missing = [f"{c}_sim" for c in COEFFICIENTS if f"{c}_sim" not in data.columns]
        if missing:
            raise DataError(
                f"qualified='columns' but the records lack {missing}; add the simulator's "
                "predictions or name the simulator (a DAVE-ML file, or 'adx37')"
            )
        return Qualified("columns", _columns, False)
    if q == "adx37":
        return Qualified("adx37", _adx37, True)
    if q.startswith(JSBSIM):
        camp = Path(q[len(JSBSIM) :])
        if not q[len(JSBSIM) :] or not camp.is_dir():
            raise DataError(
                f"qualified={q!r}: no such JSBSim campaign folder; name the folder written by "
                "aerodelta campaign --simulator jsbsim (qualified='jsbsim:DIR')"
            )
        # not differentiable: JSBSim reads the states (p, r in deg/s), not the fit's regressors
        return Qualified(f"{JSBSIM}{camp.resolve().name}", jsbsim_predict(camp), False)
    path = Path(q)
    if path.suffix.lower() in (".dml", ".xml"):
        if not path.is_file():
            raise DataError(f"{path}: no such DAVE-ML file (the qualified model)")
        return Qualified(f"daveml:{path.name}", daveml_predict(path, cbar_m), True)
    raise DataError(
        f"qualified={q!r}: use 'auto', 'columns', 'adx37', 'jsbsim:DIR' (a JSBSim campaign) "
        "or the path of a DAVE-ML file (.dml)"
    )
