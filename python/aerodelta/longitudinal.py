"""The longitudinal stall: a Kirchhoff flow-separation model of lift and pitching moment,
identified by output error from flight records (``docs/longitudinal.md``).

The separation point ``x`` obeys ``tau1 x' + x = x0(alpha - tau2 alpha')`` with
``x0(alpha) = (1 - tanh(a1 (alpha - alpha*))) / 2`` (Fischenberg, AIAA 95-3438); lift is
``CL_alpha (alpha - alpha0) ((1 + sqrt(x)) / 2)**2`` and the pitching moment
``Cm0 + Cm_alpha alpha + Cm_x (1 - x)``; drag ``CD0 + CD_k CL(alpha, x)**2 + CD_x (1 - x)``
(the polar in the Kirchhoff lift plus the separated wake's drag, fitted by equation error along
the identified state: :class:`DragFit`). These replace the qualified model's static curves;
the qualified model's control, rate and thrust terms are known and taken off the measured
coefficients before the fit. The engine (``aero_core::output_error``) integrates the state from
the measured alpha and its rate, and fits all maneuvers of a flap setting at once by
Levenberg-Marquardt on the maximum-likelihood cost, starting from an equation-error fit; it
returns Cramér-Rao bounds and the bounds corrected for coloured residuals (Morelli & Klein,
SIDPAC ``m_colores``, auto-correlation of each output, biased estimate). Records without a
separation lag (static aerodynamics, e.g. JSBSim's tables) leave tau1, tau2 not identified: the
fit says so and holds them at the engine's lower bounds (:func:`fit_kirchhoff`, Notes).
:func:`static_curves` and :func:`binned_static_curve` give the static curves of a fit and the
model-free equation-error curves they are compared with.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta import _core
from aerodelta._groups import Groups, group_agg
from aerodelta.exceptions import AerodeltaError, DataError, InvalidInputError, NoConvergenceError
from aerodelta.lsq import ols

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

#: The engine's lower bound of tau1, s (tau2's is 0).
TAU1_MIN_S = 1e-3

#: Fraction of the records' sample interval (median over the flap's maneuvers) at or below
#: which the total lag ``tau1 + tau2`` counts as no lag: a lag under half a sample cannot be told
#: from sample timing (10 ms at 50 Hz, where the built-in aircraft's truth has 0.26-0.35 s).
STATIC_LAG_FRACTION = 0.5

#: Cost tolerance of the free restart from the static solution (the default fit's is 1e-9;
#: against the bounds the projected steps creep and need hundreds of iterations to meet it).
_PROBE_TOL = 1e-6

#: Iteration bound of the static refit and the free restart (at least; ``max_iter`` if larger):
#: from the equation-error start of records that never reach the stall (the JSBSim F-15) the
#: static fit took 105 iterations.
_FALLBACK_ITER = 300

_NEEDED = ("maneuver_id", "t", "alpha_deg", "alphadot_dps", "flap_deg", "CX_meas", "CZ_meas")

#: Drag parameter names (all dimensionless): ``C_D = CD0 + CD_k C_L(alpha, x)^2 + CD_x (1 - x)``.
DRAG_PARAMS: tuple[str, ...] = tuple(_core.kirchhoff_drag_names())


def _f64(frame: pl.DataFrame, name: str) -> FloatArray:
    return np.ascontiguousarray(frame[name].cast(pl.Float64).to_numpy(), dtype=np.float64)


def _body_force_coefficients(data: pl.DataFrame) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(alpha rad, C_X - C_T, C_Z)`` of the records: the measured body-axis force
    coefficients with the thrust coefficient ``C_T = ct_left + ct_right`` (along body x) taken
    off C_X where the records carry it."""
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
    return a, cx, _f64(data, "CZ_meas")


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
    a, cx, cz = _body_force_coefficients(data)
    return -cz * np.cos(a) + cx * np.sin(a)


def measured_drag(data: pl.DataFrame) -> FloatArray:
    """Measured aerodynamic drag coefficient along the records, -.

    ``C_D = -(C_X - C_T) cos(alpha) - C_Z sin(alpha)``, the wind-axis companion of
    :func:`measured_lift` (same channels, the thrust coefficient ``C_T = ct_left + ct_right``
    taken off C_X where the records carry it).

    Parameters
    ----------
    data
        Ingested records with ``alpha_deg``, ``CX_meas``, ``CZ_meas`` (and optionally
        ``ct_left``, ``ct_right``).

    Returns
    -------
    numpy.ndarray
        C_D per row.
    """
    a, cx, cz = _body_force_coefficients(data)
    return -cx * np.cos(a) - cz * np.sin(a)


def qualified_longitudinal(data: pl.DataFrame) -> pl.DataFrame:
    """The built-in aircraft's qualified C_L, C_m and C_D along the records, and their static
    parts.

    Parameters
    ----------
    data
        A :func:`aerodelta.fit.model_frame` of records flown on the virtual aircraft.

    Returns
    -------
    polars.DataFrame
        ``CL_qual``, ``Cm_qual``, ``CD_qual`` (totals; C_L and C_D in wind axes) and
        ``CL_basic``, ``Cm_basic``, ``CD_basic`` (the static curves of alpha and flap the
        Kirchhoff model replaces), one row per record row.
    """
    cols: dict[str, FloatArray] = {}
    for n in _QUAL_INPUTS:
        if n in data.columns:
            cols[n] = np.ascontiguousarray(
                data[n].cast(pl.Float64).fill_null(0.0).to_numpy(), dtype=np.float64
            )
        elif n in ("dsl_deg", "dsr_deg", "de_deg", "ct_left", "ct_right"):
            cols[n] = np.zeros(data.height)
    cl, cm, clb, cmb, cd, cdb = _core.qualified_longitudinal_adx37(cols)
    return pl.DataFrame(
        {
            "CL_qual": cl, "Cm_qual": cm, "CD_qual": cd,
            "CL_basic": clb, "Cm_basic": cmb, "CD_basic": cdb,
        }
    )  # fmt: skip


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


def static_curves(
    params: Mapping[str, float],
    alpha_deg: npt.ArrayLike,
    cov: npt.ArrayLike | None = None,
) -> dict[str, FloatArray]:
    """The static curves of Kirchhoff parameters (``x = x0(alpha)``) and their standard errors.

    Parameters
    ----------
    params
        The nine parameters by name (engine units: :data:`UNITS`).
    alpha_deg
        Angles of attack, deg.
    cov
        Their 9 x 9 covariance in :data:`PARAMS` order (e.g. :attr:`FlapFit.cov_colored`;
        zero rows for held parameters), or None.

    Returns
    -------
    dict
        ``CL``, ``Cm`` (-) and, with ``cov``, ``CL_se``, ``Cm_se`` (-): the delta-method
        standard errors (central differences of the curves in each parameter).
    """
    a = np.radians(np.asarray(alpha_deg, dtype=np.float64))
    th = np.array([float(params[n]) for n in PARAMS])

    def curves(v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Curves of parameter rows ``v`` (k x 9) over alpha: two k x n arrays."""
        p = {n: v[:, k, None] for k, n in enumerate(PARAMS)}
        x = 0.5 * (1.0 - np.tanh(p["a1"] * (a - p["alpha_star"])))
        cl = p["CL_alpha"] * (a - p["alpha0"]) * (0.5 * (1.0 + np.sqrt(x))) ** 2
        return cl, p["Cm0"] + p["Cm_alpha"] * a + p["Cm_x"] * (1.0 - x)

    cl, cm = curves(th[None, :])
    out = {"CL": cl[0], "Cm": cm[0]}
    if cov is None:
        return out
    c = np.asarray(cov, dtype=np.float64)
    if c.shape != (len(PARAMS), len(PARAMS)):
        raise InvalidInputError(f"static_curves: cov is {c.shape}, expected 9 x 9 ({PARAMS})")
    # central differences in each parameter at once: rows th + h_j e_j, then th - h_j e_j
    h = 1e-6 * np.maximum(np.abs(th), 1e-3)
    step = np.diag(h)
    lp, mp = curves(th + step)
    lm, mm = curves(th - step)
    g_l, g_m = (lp - lm) / (2 * h[:, None]), (mp - mm) / (2 * h[:, None])
    out["CL_se"] = np.sqrt(np.maximum(np.einsum("ia,ij,ja->a", g_l, c, g_l), 0.0))
    out["Cm_se"] = np.sqrt(np.maximum(np.einsum("ia,ij,ja->a", g_m, c, g_m), 0.0))
    return out


def binned_static_curve(
    data: pl.DataFrame,
    *,
    bin_deg: float = 1.0,
    known: str = "none",
    min_samples: int = 20,
    min_maneuvers: int = 2,
) -> pl.DataFrame:
    """The equation-error static curves: measured C_L and C_m averaged in alpha bins, per flap.

    Model-free: each bin's value is the mean of all its samples; its standard error is the
    cluster-robust one over maneuvers (``sqrt(M/(M-1) sum_m n_m^2 (ybar_m - ybar)^2) / N``,
    ``M`` maneuvers with ``n_m`` samples in the bin, ``N`` in all), since samples within a
    maneuver are correlated.

    Parameters
    ----------
    data
        A :func:`aerodelta.fit.model_frame` of ingested records (as for :func:`fit_kirchhoff`).
    bin_deg
        Bin width, deg (bins centred on multiples of it).
    known
        As :func:`fit_kirchhoff`: ``"none"`` or ``"adx37"``.
    min_samples, min_maneuvers
        Bins with fewer samples or maneuvers are left out.

    Returns
    -------
    polars.DataFrame
        ``flap_deg``, ``alpha_deg`` (bin centre, deg), ``alpha_mean_deg`` (the mean alpha of
        the bin's samples, deg: compare a curve there, not at the centre, where a slope of
        0.09 per deg turns a 0.1 deg offset into 0.009 of C_L), ``n``, ``n_maneuvers``,
        ``CL``, ``CL_se``, ``Cm``, ``Cm_se`` (-; C_m NaN without ``Cm_meas``), sorted.
    """
    _check(data)
    if not (math.isfinite(bin_deg) and bin_deg > 0):
        raise InvalidInputError(f"bin_deg {bin_deg!r}: give a positive width in deg")
    rest_l, rest_m, _ = _known(data, known)
    cm = (
        _f64(data, "Cm_meas") - rest_m
        if "Cm_meas" in data.columns
        else np.full(data.height, np.nan)
    )
    f = pl.DataFrame(
        {
            "flap_deg": _f64(data, "flap_deg"),
            "maneuver_id": data["maneuver_id"].cast(pl.String),
            "bin": np.round(_f64(data, "alpha_deg") / bin_deg),
            "alpha": _f64(data, "alpha_deg"),
            "CL": measured_lift(data) - rest_l,
            "Cm": cm,
        }
    ).filter(pl.col("CL").is_finite() & pl.col("bin").is_finite())
    # sorted: the sums over a bin's maneuvers below run in maneuver order (in the hash
    # grouping's random order they changed in the last digits from run to run); every float
    # sum (the maneuvers' means, the bin's n-weighted sums) in row order (_groups: a polars
    # group-by or window sum splits its float sums over the thread pool)
    per = group_agg(
        f,
        ["flap_deg", "bin", "maneuver_id"],
        {"alpha_m": ("alpha", "mean"), "CL_m": ("CL", "mean"), "Cm_m": ("Cm", "mean")},
        exact=[pl.len().alias("n_m")],
    ).sort("flap_deg", "bin", "maneuver_id")
    bins = Groups.of(per, ["flap_deg", "bin"])
    weighted = per.select((pl.col("n_m") * pl.col(f"{c}_m")).alias(c) for c in ("CL", "Cm"))
    per = per.with_columns(
        *(bins.over(weighted[c], "sum").alias(f"_s{c}") for c in ("CL", "Cm")),
        pl.col("n_m").sum().over("flap_deg", "bin").alias("n"),  # integers: exact
    )
    per = per.with_columns((pl.col(f"_s{c}") / pl.col("n")).alias(c) for c in ("CL", "Cm"))
    per = per.with_columns(
        (pl.col("n_m") * pl.col("alpha_m")).alias("_a"),
        *(
            ((pl.col("n_m") * (pl.col(f"{c}_m") - pl.col(c))) ** 2).alias(f"_d{c}")
            for c in ("CL", "Cm")
        ),
    )
    out = (
        bins.agg(
            per,
            {"_sa": ("_a", "sum"), "_vCL": ("_dCL", "sum"), "_vCm": ("_dCm", "sum")},
            exact=[
                pl.col("n").first(),
                pl.len().alias("n_maneuvers"),
                pl.col("n_m").sum().alias("_n"),
                pl.col("CL").first(),
                pl.col("Cm").first(),
            ],
        )
        .with_columns((pl.col("_sa") / pl.col("_n")).alias("alpha_mean_deg"))
        .filter((pl.col("n") >= min_samples) & (pl.col("n_maneuvers") >= min_maneuvers))
        .with_columns(
            (
                (pl.col(f"_v{c}") * pl.col("n_maneuvers") / (pl.col("n_maneuvers") - 1)).sqrt()
                / pl.col("n")
            ).alias(f"{c}_se")
            for c in ("CL", "Cm")
        )
        .with_columns((pl.col("bin") * bin_deg).alias("alpha_deg"))
        .select(
            "flap_deg",
            "alpha_deg",
            "alpha_mean_deg",
            "n",
            "n_maneuvers",
            "CL",
            "CL_se",
            "Cm",
            "Cm_se",
        )
        .sort("flap_deg", "alpha_deg")
    )
    return out


@dataclass(frozen=True)
class DragFit:
    """The drag of one flap setting, fitted by equation error along the identified state.

    ``C_D = CD0 + CD_k C_L(alpha, x)^2 + CD_x (1 - x)`` with ``x`` and the Kirchhoff lift
    ``C_L`` integrated from the output-error estimates over each maneuver (as
    :meth:`KirchhoffResult.predict`), least squares on the measured drag less its known terms
    (``aero_core::lsq``).

    Attributes
    ----------
    params
        ``CD0``, ``CD_k``, ``CD_x`` (-).
    std_err
        Standard errors: the cluster-robust ones (CR2, maneuvers as clusters, the default of the
        identification, ``docs/identification.md``) with the separation state's uncertainty
        added by the delta method (``cov`` below); NaN where a maneuver alone determines a
        parameter.
    dof
        The Bell-McCaffrey degrees of freedom of the CR2 part (Student t).
    std_err_conventional, std_err_colored
        White-residual and coloured-residual (SIDPAC ``r_colores``, within the concatenated
        records) standard errors, beside them.
    cov
        ``cov_cluster + J V J'``, 3 x 3 in :data:`DRAG_PARAMS` order: ``V`` the output-error
        fit's coloured-residual covariance, ``J`` the derivative of the drag's least squares in
        those parameters (the regressors ``C_L^2``, ``1 - x`` move with the state).
    residual_std
        Residual standard deviation of C_D.
    n_samples, n_maneuvers
        Samples and maneuvers fitted.
    note
        What the errors include and leave out.
    std_err_cluster, cov_cluster
        The CR2 errors and covariance conditional on the state (as if it were known).
    """

    params: dict[str, float]
    std_err: dict[str, float]
    dof: dict[str, float]
    std_err_conventional: dict[str, float]
    std_err_colored: dict[str, float]
    cov: FloatArray
    residual_std: float
    n_samples: int
    n_maneuvers: int
    note: str = ""
    std_err_cluster: dict[str, float] = field(default_factory=dict)
    cov_cluster: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))


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
    cost
        Final maximum-likelihood cost ``sum_o ln(mean v_o^2)``.
    tau_identified
        False when the lags were not identified (:func:`fit_kirchhoff`, static data): tau1,
        tau2 are then held at the engine's lower bounds (1 ms, 0) and ``note`` says why.
    note
        Empty, or ``"tau1, tau2 not identified: ..."``.
    tau_free
        With ``tau_identified`` False: the free restart from the static solution (``tau1``,
        ``tau2`` s, their coloured-residual bounds ``tau1_se_colored``, ``tau2_se_colored``
        and that of the sum ``tau_sum_se_colored`` s, all NaN when it did not converge;
        ``cost_drop``, the static fit's cost minus the restart's; ``iterations``).
    drag
        The drag along the identified state (:class:`DragFit`); None when not fitted
        (``fit_cd=False``).
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
    cost: float = math.nan
    tau_identified: bool = True
    note: str = ""
    tau_free: dict[str, float] = field(default_factory=dict)
    drag: DragFit | None = None

    @property
    def alpha_star_deg(self) -> float:
        """Breakpoint alpha* (x0 = 1/2), deg."""
        return math.degrees(self.params["alpha_star"])

    @property
    def cl_max(self) -> tuple[float, float]:
        """``(alpha at C_L,max [deg], C_L,max)`` of the static lift curve of the estimates."""
        a, c = _core.kirchhoff_cl_max(self.params)
        return math.degrees(a), c


class _Noted(Protocol):
    note: str


_Fit = TypeVar("_Fit", bound=_Noted)


def _notes(fits: Mapping[float, _Noted]) -> dict[float, str]:
    """flap (deg) -> the fit's note, for the flaps that have one."""
    return {f: ff.note for f, ff in sorted(fits.items()) if ff.note}


def _flap_fit(fits: Mapping[float, _Fit], flap_deg: float) -> _Fit:
    """The fit of one flap setting (deg), or a clear refusal naming the fitted flaps."""
    try:
        return fits[float(flap_deg)]
    except KeyError:
        have = ", ".join(f"{f:g}" for f in sorted(fits))
        raise InvalidInputError(f"no fit at flap {flap_deg:g} deg; fitted: {have}") from None


@dataclass(frozen=True)
class KirchhoffResult:
    """What :func:`fit_kirchhoff` returns: one :class:`FlapFit` per flap setting, whether
    C_m was fitted, and ``known`` (the terms taken off the measured coefficients: ``adx37`` or
    ``none``)."""

    fits: dict[float, FlapFit]
    fit_cm: bool
    known: str = "adx37"

    @property
    def notes(self) -> dict[float, str]:
        """flap (deg) -> the fit's note, for the flaps that have one (lags not identified)."""
        return _notes(self.fits)

    def __getitem__(self, flap_deg: float) -> FlapFit:
        """The fit of one flap setting (deg)."""
        return _flap_fit(self.fits, flap_deg)

    def summary(self) -> pl.DataFrame:
        """One row per flap and parameter: ``flap_deg, parameter, unit, estimate, std_err,
        std_err_colored, std_err_cluster, std_err_total, start``, plus the derived
        ``alpha_star_deg``, ``alpha_cl_max_deg`` and ``cl_max`` (their errors NaN, except
        alpha*'s in deg), then the drag's ``CD0``, ``CD_k``, ``CD_x`` where fitted (``std_err``
        conventional, ``std_err_colored`` coloured-residual, ``std_err_cluster`` CR2 given the
        state, ``std_err_total`` CR2 with the state's uncertainty: :attr:`DragFit.std_err`; no
        start). ``std_err_cluster`` and ``std_err_total`` are NaN on the output-error rows."""
        rows: list[dict[str, Any]] = []
        nan = math.nan
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
                        "std_err_cluster": nan,
                        "std_err_total": nan,
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
                        "std_err_cluster": nan,
                        "std_err_total": nan,
                        "start": st,
                    }
                )
            if ff.drag is not None:
                rows.extend(
                    {
                        "flap_deg": f, "parameter": n, "unit": "-",
                        "estimate": ff.drag.params[n],
                        "std_err": ff.drag.std_err_conventional[n],
                        "std_err_colored": ff.drag.std_err_colored[n],
                        "std_err_cluster": ff.drag.std_err_cluster[n],
                        "std_err_total": ff.drag.std_err[n],
                        "start": nan,
                    }
                    for n in DRAG_PARAMS
                )  # fmt: skip
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
            ``x_sep``, ``CL_model``, ``Cm_model``, ``CD_model`` (NaN at a flap whose drag was
            not fitted), one row per input row (in input order).
        """
        return _predict_along(
            data,
            known,
            self.__getitem__,
            lambda ff, t, a, ad: _core.kirchhoff_outputs(ff.params, t, a, ad)[:3],
        )


#: One flap fit's separation state, lift and pitching moment along one maneuver (time in s,
#: alpha in rad, its rate in rad/s).
_States = Callable[[Any, FloatArray, FloatArray, FloatArray], tuple[Any, Any, Any]]


def _predict_along(
    data: pl.DataFrame, known: str, fit_of: Callable[[float], Any], states: _States
) -> pl.DataFrame:
    """The ``predict`` of both forms of the stall: each maneuver integrated from its start by
    ``states`` with the fit of its flap (``fit_of``), the drag along the state where fitted,
    plus the known terms of ``known`` (:func:`_known`)."""
    _check(data)
    rest_l, rest_m, rest_d = _known(data, known)
    n = data.height
    x, cl, cm = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    cd = np.full(n, np.nan)
    idx = data.with_row_index("_row")
    for _, g in idx.group_by("maneuver_id", maintain_order=True):
        ff = fit_of(float(g["flap_deg"][0]))
        rows = g["_row"].to_numpy()
        xs, ls, ms = states(
            ff,
            _f64(g, "t"),
            np.radians(_f64(g, "alpha_deg")),
            np.radians(_f64(g, "alphadot_dps")),
        )
        x[rows], cl[rows], cm[rows] = xs, ls, ms
        if ff.drag is not None:
            cd[rows] = _core.kirchhoff_drag_point(ff.drag.params, ls, xs)
    return pl.DataFrame(
        {
            "x_sep": x,
            "CL_model": cl + rest_l,
            "Cm_model": cm + rest_m,
            "CD_model": cd + rest_d,
        }
    )


def _drag_regressors(cl: FloatArray, x: FloatArray) -> FloatArray:
    """``[1, C_L^2, 1 - x]`` per sample (``aero_core::kirchhoff::KirchhoffDrag::regressors``)."""
    return np.column_stack([np.ones(len(cl)), cl * cl, 1.0 - x])


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


def _known(data: pl.DataFrame, known: str) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The coefficients' known (non-static-curve) parts along the records: C_L, C_m, C_D."""
    if known == "none":
        return np.zeros(data.height), np.zeros(data.height), np.zeros(data.height)
    if known == "adx37":
        q = qualified_longitudinal(data)
        return (
            (q["CL_qual"] - q["CL_basic"]).to_numpy(),
            (q["Cm_qual"] - q["Cm_basic"]).to_numpy(),
            (q["CD_qual"] - q["CD_basic"]).to_numpy(),
        )
    raise InvalidInputError(f"known '{known}': use 'adx37' (the built-in aircraft) or 'none'")


def _prepared(
    data: pl.DataFrame, maneuvers: Sequence[str] | None, known: str, fit_cm: bool
) -> pl.DataFrame:
    """The records to fit with the outputs less their known terms: ``_cl``, ``_cm``, ``_cd``."""
    _check(data)
    if fit_cm and "Cm_meas" not in data.columns:
        raise DataError("records lack Cm_meas; run aerodelta.ingest, or pass fit_cm=False")
    frame = data
    if maneuvers is not None:
        frame = frame.filter(pl.col("maneuver_id").is_in(list(maneuvers)))
    rest_l, rest_m, rest_d = _known(frame, known)
    cl = measured_lift(frame) - rest_l
    cm = (_f64(frame, "Cm_meas") - rest_m) if fit_cm else np.zeros(frame.height)
    return frame.with_columns(
        pl.Series("_cl", cl),
        pl.Series("_cm", cm),
        pl.Series("_cd", measured_drag(frame) - rest_d),
    )


_Arrays = list[FloatArray]


def _flap_records(
    frame: pl.DataFrame, flap: float, all_flaps: Sequence[float]
) -> tuple[_Arrays, _Arrays, _Arrays, _Arrays, _Arrays, _Arrays, list[str]]:
    """Per maneuver of one flap (time order): t (s), alpha (rad), alpha-dot (rad/s), the
    outputs ``_cl``, ``_cm``, ``_cd`` of :func:`_prepared`, and the ids (as a list)."""
    sub = frame.filter(pl.col("flap_deg") == flap)
    if sub.height == 0:
        have = ", ".join(f"{f:g}" for f in all_flaps)
        raise DataError(f"no records at flap {flap:g} deg; the data hold flaps {have}")
    ts: _Arrays = []
    al: _Arrays = []
    ad: _Arrays = []
    ls: _Arrays = []
    ms: _Arrays = []
    ds: _Arrays = []
    ids: list[str] = []
    for (mid,), grp in sub.group_by("maneuver_id", maintain_order=True):
        g = grp.sort("t")
        ts.append(_f64(g, "t"))
        al.append(np.radians(_f64(g, "alpha_deg")))
        ad.append(np.radians(_f64(g, "alphadot_dps")))
        ls.append(_f64(g, "_cl"))
        ms.append(_f64(g, "_cm"))
        ds.append(_f64(g, "_cd"))
        ids.append(str(mid))
    return ts, al, ad, ls, ms, ds, ids


def fit_kirchhoff(
    data: pl.DataFrame,
    *,
    flaps: Sequence[float] | None = None,
    maneuvers: Sequence[str] | None = None,
    fit_cm: bool = True,
    fit_cd: bool = True,
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
    fit_cd
        Fit the drag along the identified state too (:class:`DragFit`: ``CD0``, ``CD_k``,
        ``CD_x`` by least squares once the output-error fit of the flap is done).
    known
        ``"adx37"``: take the built-in qualified model's control, rate and thrust terms off the
        measured C_L, C_m and C_D; ``"none"``: fit the measured coefficients as they are.
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

    Notes
    -----
    **Lags not identified (static data).** When tau1 and tau2 are both free and the fit does not
    converge within ``max_iter``, or converges with a total lag ``tau1 + tau2`` of at most
    :data:`STATIC_LAG_FRACTION` of the sample interval (half a sample), the flap is refitted
    with tau1, tau2 held at the engine's lower bounds ``tau1 = 1 ms``, ``tau2 = 0`` (the static
    model: ``x = x0(alpha)`` within a millisecond) from the equation-error start, and restarted
    free from that solution (cost tolerance 1e-6; both with at least 300 iterations). If the
    free restart lowers the cost with a total lag over half a sample, the lags are identified
    after all (the equation-error start was in another basin): the fit is rerun from it as
    usual. Otherwise the static fit is returned with ``tau_identified=False``, a
    ``note`` saying why, and the restart in ``tau_free``; the Cramér-Rao bounds of tau1, tau2
    are then NaN (held: a bound at a constraint is not a confidence interval). Found on JSBSim
    aircraft, whose lift and pitch tables are static (``docs/longitudinal.md``).

    Raises
    ------
    DataError
        Records without the needed channels, or a flap without data.
    TooLittleDataError, NoConvergenceError
        From the engine, with the flap named (no convergence with tau1 or tau2 held by the
        caller, or of the static fit).
    """
    frame = _prepared(data, maneuvers, known, fit_cm)
    all_flaps = sorted({float(f) for f in frame["flap_deg"].unique().to_list()})
    wanted = all_flaps if flaps is None else [float(f) for f in flaps]
    fits: dict[float, FlapFit] = {}
    for flap in wanted:
        ts, al, ad, ls, ms, ds, ids = _flap_records(frame, flap, all_flaps)
        engine = functools.partial(
            _engine, ts, al, ad, ls, ms if fit_cm else None, tuple(ids), flap, max_lag
        )
        user_start = None if start is None or flap not in start else dict(start[flap])
        taus_free = "tau1" not in fixed and "tau2" not in fixed
        r: dict[str, Any] | None
        try:
            r, why = engine(user_start, list(fixed), int(max_iter)), ""
        except NoConvergenceError:
            if not taus_free:
                raise
            r, why = None, f"the free fit did not converge in {int(max_iter)} iterations"
        note, tau_free = "", {}
        h_half = STATIC_LAG_FRACTION * float(np.median(np.concatenate([np.diff(x) for x in ts])))
        if r is not None:
            lag = float(r["params"]["tau1"]) + float(r["params"]["tau2"])
            why = (
                f"the free fit put the total lag tau1 + tau2 at {lag * 1e3:.3g} ms, under half "
                f"the sample interval ({h_half * 1e3:.3g} ms)"
            )
        if taus_free and (r is None or _static_lags(r["params"], h_half)):
            budget = max(int(max_iter), _FALLBACK_ITER)
            r, note, tau_free = _static_fit(
                engine, user_start, list(fixed), budget, why, h_half=h_half
            )
        assert r is not None
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
            cost=float(r["cost"]),
            tau_identified=not note,
            note=note,
            tau_free=tau_free,
            drag=(
                _fit_drag(
                    _tanh_design(ts, al, ad),
                    {n: float(r["params"][n]) for n in PARAMS},
                    np.asarray(r["cov_colored"]),
                    _BOUNDS,
                    ds,
                    ids,
                    flap,
                )
                if fit_cd
                else None
            ),
        )
    return KirchhoffResult(fits=fits, fit_cm=fit_cm, known=known)


#: Bounds of the output-error parameters a difference step must respect (others: none).
_BOUNDS = {"tau1": (TAU1_MIN_S, math.inf), "tau2": (0.0, math.inf), "a1": (0.1, math.inf)}

Design = Callable[[Mapping[str, float]], FloatArray]


def _state_jacobian(  # noqa: PLR0917
    design_of: Design,
    p: Mapping[str, float],
    names: Sequence[str],
    cov: FloatArray,
    x0: FloatArray,
    z: FloatArray,
    beta: FloatArray,
    bounds: Mapping[str, tuple[float, float]],
) -> FloatArray:
    """``d beta / d theta`` (3 x len(names)): how the drag's least squares moves with the
    output-error parameters ``theta`` (``names``, covariance ``cov``) that make its regressors
    ``design_of(theta)``: ``(X'X)^-1 (dX' r - X' dX beta)``, the regressors' derivative ``dX``
    by central differences of 1e-3 of each parameter's error (one-sided at a bound; zero for a
    parameter without error: held)."""
    xtx = x0.T @ x0
    resid = z - x0 @ beta
    jac = np.zeros((len(DRAG_PARAMS), len(names)))
    for j, name in enumerate(names):
        se = math.sqrt(max(float(cov[j, j]), 0.0))
        if not se > 0.0:
            continue
        h = 1e-3 * se
        lo, hi = bounds.get(name, (-math.inf, math.inf))
        up_ok, dn_ok = p[name] + h <= hi, p[name] - h >= lo
        x_up = _design_at(design_of, p, name, h) if up_ok else x0
        x_dn = _design_at(design_of, p, name, -h) if dn_ok else x0
        dx = (x_up - x_dn) / (h * (int(up_ok) + int(dn_ok)))
        jac[:, j] = np.linalg.solve(xtx, dx.T @ resid - x0.T @ (dx @ beta))
    return jac


def _design_at(design_of: Design, p: Mapping[str, float], name: str, h: float) -> FloatArray:
    return design_of({**p, name: p[name] + h})


def _tanh_design(ts: list[FloatArray], al: list[FloatArray], ad: list[FloatArray]) -> Design:
    """The drag's regressors ``[1, C_L^2, 1 - x]`` along the tanh form's state, all maneuvers,
    as a function of its parameters."""

    def design(p: Mapping[str, float]) -> FloatArray:
        xs: list[FloatArray] = []
        for t, a, adot in zip(ts, al, ad, strict=True):
            x, cl, _, _, _ = _core.kirchhoff_outputs(dict(p), t, a, adot)
            xs.append(_drag_regressors(cl, x))
        return np.concatenate(xs)

    return design


def _fit_drag(  # noqa: PLR0917
    design_of: Design,
    params: Mapping[str, float],
    cov_state: FloatArray,
    bounds: Mapping[str, tuple[float, float]],
    ds: list[FloatArray],
    ids: tuple[str, ...] | list[str],
    flap: float,
) -> DragFit:
    """The drag of one flap by least squares along the state of ``params`` (:class:`DragFit`),
    its errors with the state's (``cov_state``, the output-error fit's covariance over
    ``params`` in their order) carried by the delta method."""
    p = {k: float(v) for k, v in params.items()}
    design = design_of(p)
    z = np.concatenate(ds)
    groups = np.repeat(np.arange(len(ds), dtype=np.uint64), [len(d) for d in ds])
    try:
        f = ols(design, z, list(DRAG_PARAMS), groups=groups, colored=True)
    except AerodeltaError as e:
        raise type(e)(f"flap {flap:g} deg, drag: {e}") from e
    assert f.std_err_cluster is not None and f.dof_cluster is not None
    assert f.cov_cluster is not None and f.std_err_corrected is not None
    beta = np.asarray(f.params)
    jac = _state_jacobian(design_of, p, list(p), cov_state, design, z, beta, bounds)
    cov_cr2 = np.asarray(f.cov_cluster)
    cov = cov_cr2 + jac @ cov_state @ jac.T

    def named(v: FloatArray) -> dict[str, float]:
        return {n: float(x) for n, x in zip(DRAG_PARAMS, v, strict=True)}

    return DragFit(
        params=named(f.params),
        std_err=named(np.sqrt(np.maximum(np.diag(cov), 0.0))),
        dof=named(f.dof_cluster),
        std_err_conventional=named(f.std_err),
        std_err_colored=named(f.std_err_corrected),
        cov=cov,
        residual_std=float(np.sqrt(f.s2)),
        n_samples=int(z.size),
        n_maneuvers=len(ids),
        note="the separation state's uncertainty (the output-error fit's coloured-residual "
        "covariance of its parameters) is carried into the errors by the delta method; the "
        "correlation of the lift and drag residuals is not",
        std_err_cluster=named(f.std_err_cluster),
        cov_cluster=cov_cr2,
    )


def _engine(  # noqa: PLR0917
    ts: list[FloatArray],
    al: list[FloatArray],
    ad: list[FloatArray],
    ls: list[FloatArray],
    ms: list[FloatArray] | None,
    ids: tuple[str, ...],
    flap: float,
    max_lag: int | None,
    start: dict[str, float] | None,
    fixed: list[str],
    max_iter: int,
    tol: float = 1e-9,
) -> dict[str, Any]:
    """One engine fit of one flap; the engine's maneuver numbers renamed to the ids."""
    try:
        return dict(
            _core.output_error_kirchhoff(
                ts,
                al,
                ad,
                ls,
                ms,
                start=start,
                fixed=fixed,
                max_iter=max_iter,
                tol=tol,
                max_lag=max_lag,
            )
        )
    except AerodeltaError as e:
        # the engine numbers the maneuvers it was given: name them
        msg = re.sub(r"maneuver (\d+)", functools.partial(_maneuver_name, ids), str(e))
        raise type(e)(f"flap {flap:g} deg: {msg}") from e


def _static_lags(params: Mapping[str, float], h_half: float) -> bool:
    """True when the total lag is at most ``h_half`` (s), half the sample interval."""
    return float(params["tau1"]) + float(params["tau2"]) <= h_half


def _static_fit(
    engine: Any,
    user_start: dict[str, float] | None,
    fixed: list[str],
    max_iter: int,
    why: str,
    *,
    h_half: float,
) -> tuple[dict[str, Any], str, dict[str, float]]:
    """The fit with tau1, tau2 held at their lower bounds, and the free restart from it.

    Returns the engine result to report, the note (empty when the restart identifies the lags)
    and the restart's numbers.
    """
    # the equation-error start: every parameter held, one iteration
    base = user_start if user_start is not None else engine(None, list(PARAMS), 1)["start"]
    st = {k: float(v) for k, v in base.items()}
    st.update(tau1=TAU1_MIN_S, tau2=0.0)
    held = engine(st, [*fixed, "tau1", "tau2"], max_iter)
    try:
        probe: dict[str, Any] | None = engine(
            {k: float(v) for k, v in held["params"].items()}, fixed, max_iter, _PROBE_TOL
        )
    except NoConvergenceError:
        probe = None
    if (
        probe is not None
        and not _static_lags(probe["params"], h_half)
        and probe["cost"] < held["cost"]
    ):
        # the lags leave the bounds from the static solution: identified after all
        return engine(dict(probe["params"]), fixed, max_iter), "", {}
    nan = math.nan
    tau_free = {
        "tau1": nan, "tau2": nan, "tau1_se_colored": nan, "tau2_se_colored": nan,
        "tau_sum_se_colored": nan, "cost_drop": nan, "iterations": nan,
    }  # fmt: skip
    if probe is None:
        restart = "a free restart from that static solution did not converge either"
    else:
        names = list(probe["names"])
        i1, i2 = names.index("tau1"), names.index("tau2")
        cov = np.asarray(probe["cov_colored"])
        se = [float(v) for v in probe["std_err_colored"]]
        tau_free.update(
            tau1=float(probe["params"]["tau1"]),
            tau2=float(probe["params"]["tau2"]),
            tau1_se_colored=se[i1],
            tau2_se_colored=se[i2],
            tau_sum_se_colored=math.sqrt(
                max(float(cov[i1, i1] + cov[i2, i2] + 2.0 * cov[i1, i2]), 0.0)
            ),
            cost_drop=float(held["cost"] - probe["cost"]),
            iterations=float(probe["iterations"]),
        )
        where = (
            "stays under half a sample"
            if _static_lags(probe["params"], h_half)
            else "does not lower the cost"
        )
        restart = (
            f"restarted free from there the total lag {where} (tau1 = "
            f"{tau_free['tau1'] * 1e3:.3g} ms, tau2 = {tau_free['tau2'] * 1e3:.3g} ms; cost lower "
            f"by {tau_free['cost_drop']:.2g})"
        )
    note = (
        f"tau1, tau2 not identified: {why}; fitted with the lags at the engine's lower bounds "
        f"(tau1 = 1 ms, tau2 = 0), {restart}: the records show no flow-separation lag (static "
        "aerodynamics). Reported with tau1, tau2 held at those bounds; the static curves are "
        "estimated as usual"
    )
    return held, note, tau_free
