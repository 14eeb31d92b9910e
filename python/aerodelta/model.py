"""The Δ part of the extended model: load, save, evaluate (engine: ``aero_core::delta_model``).

The extended coefficient is ``C_ext = C_qualified + w(alpha) * dC`` (thesis Eq. 3.11-3.12):
``dC`` sums parameter tables in (flap, alpha) times regressors (Eq. 3.19), ``w`` blends the
correction in linearly between ``alpha_l`` and ``alpha_u`` per flap.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta import _core
from aerodelta.exceptions import DataError, InvalidInputError

FloatArray = npt.NDArray[np.float64]

SCHEMA = "aerodelta.model/1"


class DeltaModel:
    """A validated Δ model, as saved by ``aerodelta fit`` and read by ``aero_core``.

    Build one from a spec dictionary (the JSON document, schema ``aerodelta.model/1``)
    with :meth:`from_spec`, or load a file with :meth:`load`.

    Examples
    --------
    >>> spec = {
    ...     "schema": "aerodelta.model/1",
    ...     "flaps_deg": [0.0],
    ...     "coefficients": {"Cl": {
    ...         "terms": [{"name": "dCl_0", "regressor": "1",
    ...                    "alpha_deg": [10.0, 20.0], "values": [[0.0, 0.02]]}],
    ...         "alpha_l_deg": [10.0], "alpha_u_deg": [12.0]}},
    ... }
    >>> m = DeltaModel.from_spec(spec)
    >>> out = m.evaluate(pl.DataFrame({"alpha_deg": [11.0, 15.0], "flap_deg": [0.0, 0.0]}))
    >>> [round(v, 6) for v in out["dCl_blended"]]
    [0.001, 0.01]
    """

    __slots__ = ("_m",)

    def __init__(self) -> None:
        raise TypeError("use DeltaModel.load(path) or DeltaModel.from_spec(dict)")

    @classmethod
    def _from_core(cls, m: _core.DeltaModel) -> DeltaModel:
        obj = object.__new__(cls)
        obj._m = m
        return obj

    @classmethod
    def from_spec(cls, spec: Mapping[str, Any], source: str = "<spec>") -> DeltaModel:
        """Validate a spec dictionary (see the module docstring for its meaning)."""
        return cls._from_core(_core.DeltaModel.from_json(json.dumps(spec), source))

    @classmethod
    def load(cls, path: str | Path) -> DeltaModel:
        """Load a model file (JSON, schema ``aerodelta.model/1``)."""
        return cls._from_core(_core.DeltaModel.load(str(path)))

    def save(self, path: str | Path) -> None:
        """Write the model atomically (temporary file, then rename)."""
        self._m.save(str(path))

    def to_spec(self) -> dict[str, Any]:
        """The stored document as a dictionary."""
        return json.loads(self._m.to_json())

    @property
    def coefficients(self) -> list[str]:
        """Coefficient names (e.g. ``["CY", "Cl", "Cn"]``)."""
        return self._m.coefficient_names

    @property
    def input_columns(self) -> list[str]:
        """Data columns the model reads: alpha (deg), flap (deg) and the regressors' columns."""
        return self._m.input_columns

    def parameter(self, coefficient: str, term: str, flap_deg: float, alpha_deg: float) -> float:
        """Value of one parameter table at a flap setting and angle of attack (deg)."""
        return self._m.parameter(coefficient, term, float(flap_deg), float(alpha_deg))

    def evaluate(
        self,
        data: pl.DataFrame,
        *,
        coefficients: list[str] | None = None,
        terms: bool = False,
    ) -> pl.DataFrame:
        """Evaluate the corrections along records.

        Parameters
        ----------
        data
            Columns named as :attr:`input_columns` (angles in deg as named).
        coefficients
            Subset to evaluate (default all).
        terms
            Also return each term's (unblended) contribution as ``<term>`` columns.

        Returns
        -------
        polars.DataFrame
            Per coefficient ``C``: ``dC`` (unblended Δ), ``w_C`` (blend weight, Eq. 3.12) and
            ``dC_blended`` = ``w_C * dC``, the amount to add to the qualified model.
        """
        n = data.height
        needed = set(self.input_columns)
        missing = sorted(needed - set(data.columns))
        if missing:
            raise _core.InvalidInputError(
                f"columns {missing} are required by the model but missing from the data"
            )
        cols = {
            c: np.ascontiguousarray(data[c].cast(pl.Float64).to_numpy()) for c in sorted(needed)
        }
        out: dict[str, np.ndarray] = {}
        for c in coefficients or self.coefficients:
            delta, weight, contribs = self._m.eval_columns(c, cols, n)
            out[f"d{c}"] = delta
            out[f"w_{c}"] = weight
            out[f"d{c}_blended"] = weight * delta
            if terms:
                out.update(contribs)
        return pl.DataFrame(out)

    @property
    def envelope(self) -> pl.DataFrame | None:
        """The flight data's validated envelope stored with the model: per flap and alpha
        band, the band's alpha limits and the measured sideslip range (deg) and its
        maneuvers; ``None`` for a model without one (an older model file, or one written by
        hand)."""
        env = self.to_spec().get("envelope")
        if env is None:
            return None
        w = float(env["band_deg"])
        rows = [
            {
                "flap_deg": float(f),
                "alpha_lo_deg": b["band"] * w,
                "alpha_hi_deg": (b["band"] + 1) * w,
                "beta_min_deg": b["beta_min_deg"],
                "beta_max_deg": b["beta_max_deg"],
                "maneuvers": b["maneuvers"],
            }
            for f, bands in zip(env["flaps_deg"], env["bands"], strict=True)
            for b in bands
        ]
        schema = {
            "flap_deg": pl.Float64, "alpha_lo_deg": pl.Float64, "alpha_hi_deg": pl.Float64,
            "beta_min_deg": pl.Float64, "beta_max_deg": pl.Float64, "maneuvers": pl.Int64,
        }  # fmt: skip
        return pl.DataFrame(rows, schema=schema)

    def in_envelope(self, frame: pl.DataFrame) -> pl.Series:
        """Per row of ``frame`` (``flap_deg``, ``alpha_deg``, ``beta_deg``, deg): whether the
        state lies inside the validated envelope of the flight data (a covered alpha band of
        the nearest flap setting, within its measured sideslip range) — the "outside the
        validated envelope" indication of 14 CFR Part 60 a simulator shows. A missing value is
        outside.

        Raises
        ------
        DataError
            When a column is missing.
        InvalidInputError
            When the model carries no envelope.
        """
        missing = [c for c in ("flap_deg", "alpha_deg", "beta_deg") if c not in frame.columns]
        if missing:
            raise DataError(
                f"in_envelope: the frame lacks {', '.join(missing)} (deg); it needs flap_deg, "
                "alpha_deg and beta_deg"
            )
        cols = [
            np.ascontiguousarray(frame[c].cast(pl.Float64).fill_null(np.nan).to_numpy())
            for c in ("flap_deg", "alpha_deg", "beta_deg")
        ]
        out = self._m.in_envelope(*cols)
        if out is None:
            raise InvalidInputError(
                "in_envelope: this model carries no validated envelope (an older model file, "
                "or one written by hand); fit it again to store the data's alpha/beta coverage"
            )
        return pl.Series("in_envelope", out)

    @property
    def kirchhoff(self) -> dict[float, dict[str, float]] | None:
        """The longitudinal stall stored with the model: per flap (deg), the stall's scalar
        parameters by name (engine units s, rad, 1/rad): ``aerodelta.longitudinal.PARAMS`` for
        the tanh form, ``aerodelta.goman_khrabrov.CORE_PARAMS`` for the tabulated one, whose
        separation curve :attr:`separation_tables` holds (:attr:`stall_form` says which);
        ``None`` for a model without one. :attr:`kirchhoff_known` says what the fit took off
        the measured coefficients."""
        lon = self.to_spec().get("longitudinal")
        if lon is None:
            return None
        return {float(f["flap_deg"]): dict(f["params"]) for f in lon["flaps"]}

    @property
    def stall_form(self) -> str | None:
        """The form of the stored stall's static separation curve: ``"kirchhoff"`` (the tanh
        curve, :func:`aerodelta.longitudinal.fit_kirchhoff`), ``"goman-khrabrov"`` (the
        tabulated curve, :func:`aerodelta.goman_khrabrov.fit_goman_khrabrov`) or ``None``
        without a stored stall."""
        lon = self.to_spec().get("longitudinal")
        return None if lon is None else str(lon["model"])

    @property
    def separation_tables(self) -> dict[float, tuple[FloatArray, FloatArray]]:
        """The tabulated form's static separation curves: per flap (deg), the knots (rad,
        equally spaced) and the cubic B-spline's coefficients (0-1, one per knot); empty for
        the tanh form or without a stored stall."""
        lon = self.to_spec().get("longitudinal")
        if lon is None or lon["model"] != "goman-khrabrov":
            return {}
        return {
            float(f["flap_deg"]): (
                np.asarray(f["x0_knots"], dtype=np.float64),
                np.asarray(f["x0_values"], dtype=np.float64),
            )
            for f in lon["flaps"]
        }

    @property
    def kirchhoff_drag(self) -> dict[float, dict[str, float]]:
        """The drag of the stored stall: per flap (deg) that carries one, ``CD0``, ``CD_k``,
        ``CD_x`` (``aerodelta.longitudinal.DRAG_PARAMS``, dimensionless); empty without."""
        lon = self.to_spec().get("longitudinal")
        if lon is None:
            return {}
        return {float(f["flap_deg"]): dict(f["drag"]) for f in lon["flaps"] if f.get("drag")}

    @property
    def kirchhoff_known(self) -> str | None:
        """``adx37`` (the stall replaces the built-in aircraft's qualified static C_L, C_m
        curves), ``none`` (the curves are the whole measured coefficients) or ``None`` without
        a stored stall."""
        lon = self.to_spec().get("longitudinal")
        return None if lon is None else str(lon["known"])

    @property
    def adx37_stall_flaps(self) -> list[float]:
        """The flap settings (deg, sorted) at which replays on the built-in ADX-37 fly the
        stored stall in place of the qualified static curves: those of a stall fitted on its
        known terms (``kirchhoff_known == "adx37"``); empty otherwise. The engine's rule,
        ``aero_core``'s ``DeltaModel::adx37_stall`` (flaps matched exactly)."""
        k = self.kirchhoff
        return sorted(k) if k is not None and self.kirchhoff_known == "adx37" else []

    def with_longitudinal(self, result: Any) -> DeltaModel:
        """A copy of the model carrying the longitudinal stall of
        :func:`aerodelta.longitudinal.fit_kirchhoff` (the tanh separation curve) or
        :func:`aerodelta.goman_khrabrov.fit_goman_khrabrov` (the tabulated curve), every flap
        fitted, with its note and its drag when fitted, so a simulator that loads the model
        (``aero_core``'s replays, the exports, the evidence pack) flies the identified lift and
        pitch break and the drag of the separated flow. A stall already stored is replaced.

        Raises
        ------
        InvalidInputError
            When the fit left C_m out (``fit_cm=False``: a simulator flies both curves) or
            fitted no flap.
        """
        from aerodelta.goman_khrabrov import GomanKhrabrovResult  # noqa: PLC0415
        from aerodelta.longitudinal import KirchhoffResult  # noqa: PLC0415

        if not isinstance(result, KirchhoffResult | GomanKhrabrovResult):
            raise InvalidInputError(
                f"with_longitudinal: a {type(result).__name__}; give the result of "
                "aerodelta.longitudinal.fit_kirchhoff or aerodelta.goman_khrabrov."
                "fit_goman_khrabrov"
            )
        if not result.fit_cm:
            raise InvalidInputError(
                "with_longitudinal: the stall fit left C_m out (fit_cm=False); fit both "
                "curves to store the stall a simulator flies"
            )
        if not result.fits:
            raise InvalidInputError("with_longitudinal: the stall fit has no flap")
        tabulated = isinstance(result, GomanKhrabrovResult)

        def table(ff: Any) -> dict[str, Any]:
            if not tabulated:
                return {}
            return {
                "x0_knots": np.radians(np.asarray(ff.knots_deg, dtype=np.float64)).tolist(),
                "x0_values": np.asarray(ff.x0, dtype=np.float64).tolist(),
            }

        spec = self.to_spec()
        spec["longitudinal"] = {
            "model": "goman-khrabrov" if tabulated else "kirchhoff",
            "known": result.known,
            "flaps": [
                {
                    "flap_deg": float(f),
                    "params": dict(ff.params),
                    **table(ff),
                    **({"drag": dict(ff.drag.params)} if ff.drag is not None else {}),
                    "note": ff.note,
                }
                for f, ff in sorted(result.fits.items())
            ],
        }
        return DeltaModel.from_spec(spec, "model with its longitudinal stall")

    def __repr__(self) -> str:
        return f"DeltaModel({', '.join(self.coefficients)})"


def _sha256(path: Path) -> str:
    import hashlib  # noqa: PLC0415

    h = hashlib.sha256()
    with path.open("rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def with_params_hash(model: DeltaModel, params_path: str | Path) -> DeltaModel:
    """The model with the SHA-256 of its per-bin estimates file recorded in its provenance
    (``provenance.params_sha256``): writing that file first and the model last commits the
    pair, and :func:`check_params` tells a table from another fit."""
    spec = model.to_spec()
    prov = dict(spec.get("provenance") or {})
    prov["params_sha256"] = _sha256(Path(params_path))
    spec["provenance"] = prov
    return DeltaModel.from_spec(spec, str(params_path))


def check_params(model_path: str | Path, params_path: str | Path) -> None:
    """Refuse a per-bin estimates file that is not the one the model file records (a fit
    killed between its two renames, or files copied from different fits). Models without the
    record (older files, the Python API's ``save``) are not checked.

    Raises
    ------
    DataError
        Naming both files.
    """
    from aerodelta.exceptions import DataError  # noqa: PLC0415

    try:
        prov = json.loads(Path(model_path).read_text()).get("provenance") or {}
    except (OSError, ValueError):
        return  # the model loader reports an unreadable model file
    want = prov.get("params_sha256") if isinstance(prov, dict) else None
    if want and _sha256(Path(params_path)) != want:
        raise DataError(
            f"{params_path}: these per-bin estimates are not the ones {Path(model_path).name} "
            "was fitted with (another fit wrote one of the two files, or it was stopped "
            "between them); run aerodelta fit again"
        )
