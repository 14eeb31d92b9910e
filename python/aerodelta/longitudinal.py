"""The longitudinal stall: a Kirchhoff flow-separation model of lift and pitching moment,
identified by output error from flight records (``docs/longitudinal.md``).

The separation point ``x`` obeys ``tau1 x' + x = x0(alpha - tau2 alpha')`` with
``x0(alpha) = (1 - tanh(a1 (alpha - alpha*))) / 2`` (Fischenberg, AIAA 95-3438); lift is
``CL_alpha (alpha - alpha0) ((1 + sqrt(x)) / 2)**2`` and the pitching moment
``Cm0 + Cm_alpha alpha + Cm_x (1 - x)``. These replace the qualified model's static curves;
the qualified model's control, rate and thrust terms are known and taken off the measured
coefficients before the fit. The engine (``aero_core::output_error``) integrates the state from
the measured alpha and its rate, and fits all maneuvers of a flap setting at once by
Levenberg-Marquardt on the maximum-likelihood cost, starting from an equation-error fit; it
returns Cramér-Rao bounds and the bounds corrected for coloured residuals (Morelli & Klein,
SIDPAC ``m_colores``, auto-correlation of each output, biased estimate).
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta import _core
from aerodelta.exceptions import AerodeltaError, DataError, InvalidInputError

FloatArray = npt.NDArray[np.float64]

#: Parameter names in the engine's order.
PARAMS: tuple[str, ...] = tuple(_core.kirchhoff_param_names())

#: Units of each parameter (the engine works in radians and seconds).
UNITS: dict[str, str] = {
    "tau1": "s", "tau2": "s", "alpha_star": "rad", "a1": "1/rad", "CL_alpha": "1/rad",
    "alpha0": "rad", "Cm0": "-", "Cm_alpha": "1/rad", "Cm_x": "-",
}  # fmt: skip

_QUAL_INPUTS = (
    "alpha_deg", "beta_deg", "phat", "qhat", "rhat", "alphadot_dps", "betadot_dps",
    "da_deg", "de_deg", "dr_deg", "dsl_deg", "dsr_deg", "flap_deg", "ct_left", "ct_right",
    "tas_mps",
)  # fmt: skip

_NEEDED = ("maneuver_id", "t", "alpha_deg", "alphadot_dps", "flap_deg", "CX_meas", "CZ_meas")


def _f64(frame: pl.DataFrame, name: str) -> FloatArray:
    return np.ascontiguousarray(frame[name].cast(pl.Float64).to_numpy(), dtype=np.float64)


def measured_lift(data: pl.DataFrame) -> FloatArray:
    """Measured aerodynamic lift coefficient along the records, -.

    ``C_L = -C_Z cos(alpha) + (C_X - C_T) sin(alpha)`` from the measured body-axis
    ``CX_meas``, ``CZ_meas`` (ingestion, thesis Eq. 3.2-3.4 and the force equations) and
    ``alpha_deg`` (deg, at the CG in a :func:`aerodelta.fit.model_frame`), with the thrust
    coefficient ``C_T = ct_left + ct_right`` (thrust along body x) taken off C_X where the
    records carry it.

    Parameters
    ----------
    data
        Ingested records with ``alpha_deg``, ``CX_meas``, ``CZ_meas`` (and optionally
        ``ct_left``, ``ct_right``).

    Returns
    -------
    numpy.ndarray
        C_L per row.
    """
    missing = [c for c in ("alpha_deg", "CX_meas", "CZ_meas") if c not in data.columns]
    if missing:
        raise DataError(
            f"records lack {', '.join(missing)}; run aerodelta.ingest on them first "
            "(it derives the measured coefficients)"
        )
    a = np.radians(_f64(data, "alpha_deg"))
    cx = _f64(data, "CX_meas")
    if all(c in data.columns for c in ("ct_left", "ct_right")):
        ct = _f64(data, "ct_left") + _f64(data, "ct_right")
        cx = cx - np.where(np.isfinite(ct), ct, 0.0)
    return -_f64(data, "CZ_meas") * np.cos(a) + cx * np.sin(a)


def qualified_longitudinal(data: pl.DataFrame) -> pl.DataFrame:
    """The built-in aircraft's qualified C_L and C_m along the records, and their static parts.

    Parameters
    ----------
    data
        A :func:`aerodelta.fit.model_frame` of records flown on the virtual aircraft.

    Returns
    -------
    polars.DataFrame
        ``CL_qual``, ``Cm_qual`` (totals) and ``CL_basic``, ``Cm_basic`` (the static
        curves of alpha and flap the Kirchhoff model replaces), one row per record row.
    """
    cols: dict[str, FloatArray] = {}
    for n in _QUAL_INPUTS:
        if n in data.columns:
            cols[n] = np.ascontiguousarray(
                data[n].cast(pl.Float64).fill_null(0.0).to_numpy(), dtype=np.float64
            )
        elif n in ("dsl_deg", "dsr_deg", "de_deg", "ct_left", "ct_right"):
            cols[n] = np.zeros(data.height)
    cl, cm, clb, cmb = _core.qualified_longitudinal_adx37(cols)
    return pl.DataFrame({"CL_qual": cl, "Cm_qual": cm, "CL_basic": clb, "Cm_basic": cmb})


def theil(measured: npt.ArrayLike, predicted: npt.ArrayLike) -> float:
    """Theil inequality coefficient ``rms(z - y) / (rms(z) + rms(y))`` (0 perfect, 1 worst).

    Parameters
    ----------
    measured, predicted
        Equal-length series (any unit, the same for both).

    Returns
    -------
    float
        The coefficient; NaN for empty or all-zero input.
    """
    z = np.asarray(measured, dtype=np.float64)
    y = np.asarray(predicted, dtype=np.float64)
    if z.shape != y.shape:
        raise InvalidInputError(f"theil: {z.shape} measured values but {y.shape} predicted")
    if z.size == 0:
        return float("nan")
    den = math.sqrt(float(np.mean(z * z))) + math.sqrt(float(np.mean(y * y)))
    if den == 0.0:
        return float("nan")
    return math.sqrt(float(np.mean((z - y) ** 2))) / den


@dataclass(frozen=True)
class FlapFit:
    """The output-error fit of one flap setting.

    Attributes
    ----------
    flap_deg
        Flap, deg.
    params, start
        Estimates and the equation-error start, by name (engine units: :data:`UNITS`).
    std_err, std_err_colored
        Cramér-Rao bounds and the bounds corrected for coloured residuals (NaN: held).
    cov, cov_colored
        The 9 x 9 covariances in :data:`PARAMS` order.
    iterations, converged, n_samples, n_maneuvers
        Iterations taken, convergence, samples and maneuvers used.
    residual_std
        Residual standard deviation of C_L and C_m (NaN when C_m was not fitted).
    maneuvers
        The maneuver ids fitted.
    """

    flap_deg: float
    params: dict[str, float]
    start: dict[str, float]
    std_err: dict[str, float]
    std_err_colored: dict[str, float]
    cov: FloatArray
    cov_colored: FloatArray
    iterations: int
    converged: bool
    n_samples: int
    n_maneuvers: int
    residual_std: tuple[float, float]
    maneuvers: tuple[str, ...] = field(default=())

    @property
    def alpha_star_deg(self) -> float:
        """Breakpoint alpha* (x0 = 1/2), deg."""
        return math.degrees(self.params["alpha_star"])

    @property
    def cl_max(self) -> tuple[float, float]:
        """``(alpha at C_L,max [deg], C_L,max)`` of the static lift curve of the estimates."""
        a, c = _core.kirchhoff_cl_max(self.params)
        return math.degrees(a), c


@dataclass(frozen=True)
class KirchhoffResult:
    """What :func:`fit_kirchhoff` returns: one :class:`FlapFit` per flap setting."""

    fits: dict[float, FlapFit]
    fit_cm: bool

    def __getitem__(self, flap_deg: float) -> FlapFit:
        """The fit of one flap setting (deg)."""
        try:
            return self.fits[float(flap_deg)]
        except KeyError:
            have = ", ".join(f"{f:g}" for f in sorted(self.fits))
            raise InvalidInputError(f"no fit at flap {flap_deg:g} deg; fitted: {have}") from None

    def summary(self) -> pl.DataFrame:
        """One row per flap and parameter: ``flap_deg, parameter, unit, estimate, std_err,
        std_err_colored, start``, plus the derived ``alpha_star_deg``, ``alpha_cl_max_deg``
        and ``cl_max`` (their errors NaN, except alpha*'s in deg)."""
        rows: list[dict[str, Any]] = []
        for f in sorted(self.fits):
            ff = self.fits[f]
            for n in PARAMS:
                rows.append(
                    {
                        "flap_deg": f,
                        "parameter": n,
                        "unit": UNITS[n],
                        "estimate": ff.params[n],
                        "std_err": ff.std_err[n],
                        "std_err_colored": ff.std_err_colored[n],
                        "start": ff.start[n],
                    }
                )
            a_max, cl_max = ff.cl_max
            d = math.degrees
            for name, unit, est, se, sec, st in (
                (
                    "alpha_star_deg",
                    "deg",
                    ff.alpha_star_deg,
                    d(ff.std_err["alpha_star"]),
                    d(ff.std_err_colored["alpha_star"]),
                    d(ff.start["alpha_star"]),
                ),
                ("alpha_cl_max_deg", "deg", a_max, math.nan, math.nan, math.nan),
                ("cl_max", "-", cl_max, math.nan, math.nan, math.nan),
            ):
                rows.append(
                    {
                        "flap_deg": f,
                        "parameter": name,
                        "unit": unit,
                        "estimate": est,
                        "std_err": se,
                        "std_err_colored": sec,
                        "start": st,
                    }
                )
        return pl.DataFrame(rows, infer_schema_length=None)

    def predict(self, data: pl.DataFrame, known: str = "adx37") -> pl.DataFrame:
        """The model's C_L and C_m along records (each maneuver integrated from its start).

        Parameters
        ----------
        data
            A :func:`aerodelta.fit.model_frame` of ingested records at fitted flap settings.
        known
            ``"adx37"``: add the built-in qualified model's control, rate and thrust terms (the
            records' total coefficients); ``"none"``: the static-curve parts alone.

        Returns
        -------
        polars.DataFrame
            ``x_sep``, ``CL_model``, ``Cm_model``, one row per input row (in input order).
        """
        _check(data)
        rest_l, rest_m = _known(data, known)
        n = data.height
        x, cl, cm = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
        idx = data.with_row_index("_row")
        for _, g in idx.group_by("maneuver_id", maintain_order=True):
            flap = float(g["flap_deg"][0])
            ff = self[flap]
            rows = g["_row"].to_numpy()
            xs, ls, ms, _, _ = _core.kirchhoff_outputs(
                ff.params,
                _f64(g, "t"),
                np.radians(_f64(g, "alpha_deg")),
                np.radians(_f64(g, "alphadot_dps")),
            )
            x[rows], cl[rows], cm[rows] = xs, ls, ms
        return pl.DataFrame({"x_sep": x, "CL_model": cl + rest_l, "Cm_model": cm + rest_m})


def _maneuver_name(ids: tuple[str, ...], m: re.Match[str]) -> str:
    """``maneuver <index>`` of an engine message as ``maneuver <id>``."""
    k = int(m.group(1))
    return f"maneuver {ids[k]}" if k < len(ids) else m.group(0)


def _check(data: pl.DataFrame) -> None:
    missing = [c for c in _NEEDED if c not in data.columns]
    if missing:
        raise DataError(
            f"records lack {', '.join(missing)}; pass aerodelta.fit.model_frame(ingest(...).data)"
        )


def _known(data: pl.DataFrame, known: str) -> tuple[FloatArray, FloatArray]:
    """The coefficients' known (non-static-curve) parts along the records."""
    if known == "none":
        return np.zeros(data.height), np.zeros(data.height)
    if known == "adx37":
        q = qualified_longitudinal(data)
        return (
            (q["CL_qual"] - q["CL_basic"]).to_numpy(),
            (q["Cm_qual"] - q["Cm_basic"]).to_numpy(),
        )
    raise InvalidInputError(f"known '{known}': use 'adx37' (the built-in aircraft) or 'none'")


def fit_kirchhoff(
    data: pl.DataFrame,
    *,
    flaps: Sequence[float] | None = None,
    maneuvers: Sequence[str] | None = None,
    fit_cm: bool = True,
    known: str = "adx37",
    start: Mapping[float, Mapping[str, float]] | None = None,
    fixed: Sequence[str] = (),
    max_iter: int = 60,
    max_lag: int | None = None,
) -> KirchhoffResult:
    """Fit the Kirchhoff stall model by output error, one flap setting at a time.

    Parameters
    ----------
    data
        A :func:`aerodelta.fit.model_frame` of ingested records (``maneuver_id``, ``t`` s,
        ``alpha_deg`` deg, ``alphadot_dps`` deg/s, ``flap_deg``, ``CX_meas``, ``CZ_meas``,
        ``Cm_meas``); each maneuver should start below the stall.
    flaps
        Flap settings to fit, deg (default: all in the data).
    maneuvers
        Maneuver ids to fit on (default: all); the others stay out (held out).
    fit_cm
        Fit the pitching moment too (C_m0, C_malpha, C_mx); else C_L alone.
    known
        ``"adx37"``: take the built-in qualified model's control, rate and thrust terms off the
        measured C_L and C_m; ``"none"``: fit the measured coefficients as they are.
    start
        Start values per flap (all nine parameters, engine units); default: equation error.
    fixed
        Parameter names held at their start.
    max_iter
        Iteration bound of the Levenberg-Marquardt loop.
    max_lag
        Truncate the residual autocorrelation of the coloured-residual bounds (samples).

    Returns
    -------
    KirchhoffResult

    Raises
    ------
    DataError
        Records without the needed channels, or a flap without data.
    TooLittleDataError, NoConvergenceError
        From the engine, with the flap named.
    """
    _check(data)
    if fit_cm and "Cm_meas" not in data.columns:
        raise DataError("records lack Cm_meas; run aerodelta.ingest, or pass fit_cm=False")
    frame = data
    if maneuvers is not None:
        frame = frame.filter(pl.col("maneuver_id").is_in(list(maneuvers)))
    rest_l, rest_m = _known(frame, known)
    cl = measured_lift(frame) - rest_l
    cm = (_f64(frame, "Cm_meas") - rest_m) if fit_cm else None
    frame = frame.with_columns(
        pl.Series("_cl", cl), pl.Series("_cm", cm if cm is not None else np.zeros(frame.height))
    )
    all_flaps = sorted({float(f) for f in frame["flap_deg"].unique().to_list()})
    wanted = all_flaps if flaps is None else [float(f) for f in flaps]
    fits: dict[float, FlapFit] = {}
    for flap in wanted:
        sub = frame.filter(pl.col("flap_deg") == flap)
        if sub.height == 0:
            have = ", ".join(f"{f:g}" for f in all_flaps)
            raise DataError(f"no records at flap {flap:g} deg; the data hold flaps {have}")
        ts, al, ad, ls, ms, ids = [], [], [], [], [], []
        for (mid,), grp in sub.group_by("maneuver_id", maintain_order=True):
            g = grp.sort("t")
            ts.append(_f64(g, "t"))
            al.append(np.radians(_f64(g, "alpha_deg")))
            ad.append(np.radians(_f64(g, "alphadot_dps")))
            ls.append(_f64(g, "_cl"))
            ms.append(_f64(g, "_cm"))
            ids.append(str(mid))
        try:
            r = _core.output_error_kirchhoff(
                ts,
                al,
                ad,
                ls,
                ms if fit_cm else None,
                start=None if start is None or flap not in start else dict(start[flap]),
                fixed=list(fixed),
                max_iter=int(max_iter),
                max_lag=max_lag,
            )
        except AerodeltaError as e:
            # the engine numbers the maneuvers it was given: name them
            msg = re.sub(r"maneuver (\d+)", functools.partial(_maneuver_name, tuple(ids)), str(e))
            raise type(e)(f"flap {flap:g} deg: {msg}") from e
        names = list(r["names"])
        fits[flap] = FlapFit(
            flap_deg=flap,
            params={k: float(v) for k, v in r["params"].items()},
            start={k: float(v) for k, v in r["start"].items()},
            std_err=dict(zip(names, map(float, r["std_err"]), strict=True)),
            std_err_colored=dict(zip(names, map(float, r["std_err_colored"]), strict=True)),
            cov=np.asarray(r["cov"]),
            cov_colored=np.asarray(r["cov_colored"]),
            iterations=int(r["iterations"]),
            converged=bool(r["converged"]),
            n_samples=int(r["n_samples"]),
            n_maneuvers=int(r["n_maneuvers"]),
            residual_std=(
                math.sqrt(float(r["residual_var"][0])),
                math.sqrt(float(r["residual_var"][1])) if fit_cm else math.nan,
            ),
            maneuvers=tuple(ids),
        )
    return KirchhoffResult(fits=fits, fit_cm=fit_cm)
