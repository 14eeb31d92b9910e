"""The longitudinal stall with a tabulated static separation curve (the Goman-Khrabrov form),
identified by output error (``docs/longitudinal.md``, "The Goman-Khrabrov form").

The separation dynamics are those of :mod:`aerodelta.longitudinal`,
``tau1 x' + x = x0(alpha - tau2 alpha')``, with Kirchhoff's lift
``CL_alpha (alpha - alpha0) ((1 + sqrt(x)) / 2)**2`` and the pitching moment
``Cm0 + Cm_alpha alpha + Cm_x (1 - x)``; but ``x0(alpha)`` is a table, a uniform cubic
B-spline on knots every 1 deg, instead of Fischenberg's ``(1 - tanh(a1 (alpha - alpha*))) /
2`` (Goman & Khrabrov, J. Aircraft 31(5), 1994: the static separation curve is whatever the
static lift curve says). A lift curve the tanh cannot follow (a plateau, a second rise:
JSBSim's piecewise-linear tables) is followed coefficient by coefficient, and the state keeps
its lag and hysteresis.

:func:`fit_goman_khrabrov` starts from the tanh fit (:func:`aerodelta.longitudinal.
fit_kirchhoff`) of the same flap and records, holds a lift line (``CL_alpha``, ``alpha0``:
with every coefficient free, the line and the table trade off; of two candidates, the tanh
fit's and the equation-error start's attached-flow line, the one giving the lower cost), and
fits tau1, tau2, the table's coefficients and the pitching moment with the same engine
(``aero_core::output_error``: same cost, iterations, Cramér-Rao and coloured-residual bounds;
coefficients held at their bounds 0 or 1 while the data push them out).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta import _core
from aerodelta.exceptions import AerodeltaError, InvalidInputError, TooLittleDataError
from aerodelta.longitudinal import (
    DRAG_PARAMS,
    PARAMS,
    TAU1_MIN_S,
    DragFit,
    FlapFit,
    FloatArray,
    KirchhoffResult,
    _drag_regressors,
    _engine,
    _fit_drag,
    _flap_fit,
    _flap_records,
    _maneuver_name,
    _notes,
    _predict_along,
    _prepared,
    fit_kirchhoff,
    static_curves,
)

#: The scalar parameters in the engine's order (the node values ``x0[k]`` follow).
CORE_PARAMS: tuple[str, ...] = tuple(_core.goman_khrabrov_core_names())

#: Units of the scalar parameters (engine units).
CORE_UNITS: dict[str, str] = {
    "tau1": "s", "tau2": "s", "CL_alpha": "1/rad", "alpha0": "rad", "Cm0": "-",
    "Cm_alpha": "1/rad", "Cm_x": "-",
}  # fmt: skip

#: Held: the lift line (the tanh fit's or the equation-error start's, whichever gives the lower
#: cost; the table carries the rest).
HELD_LINE = ("CL_alpha", "alpha0")

#: The separation point of the tanh start at which the table ends when the records stop short
#: of it (the coefficients past the data are held at the tanh start's curve). Small, because
#: the lift goes as ``(1 + sqrt(x))^2``: at x = 1e-6 it is within 0.1 % of full separation's.
SEPARATED_X = 1e-6

#: The table ends at most this far past the highest alpha flown, deg.
EXTEND_DEG = 15.0

#: The separation point of the tanh start at which its flow is taken as attached (its lift
#: within 0.05 % of the line); the table begins BELOW_DEG under that alpha.
ATTACHED_X = 0.999

#: How far under the tanh start's attached alpha the table begins, deg: where the records
#: leave the line earlier than the tanh says (a plateau), the table must reach there too.
BELOW_DEG = 3.0


@dataclass(frozen=True)
class GkFlapFit:
    """The output-error fit of the tabulated form at one flap setting.

    Attributes
    ----------
    flap_deg
        Flap, deg.
    params, start
        Scalar estimates and their start (the held line's ``CL_alpha``, ``alpha0``, the tanh
        fit's others), by name (units: :data:`CORE_UNITS`).
    knots_deg
        The table's knots, deg (alpha of the static separation curve).
    x0, x0_start
        The spline's coefficients (separation point, 0-1) and their start (the tanh fit's
        static lift re-expressed on the held line, interpolated at the knots).
    std_err, std_err_colored
        Cramér-Rao bounds and the bounds corrected for coloured residuals of the scalar
        parameters (NaN: held, e.g. ``CL_alpha``, ``alpha0``; tau1, tau2 on static data).
    x0_std_err, x0_std_err_colored
        The same for the node values.
    cov, cov_colored
        Covariances over ``names`` (zeros where held).
    names
        ``CORE_PARAMS`` then ``x0[0]``, ``x0[1]``, ...
    iterations, converged, n_samples, n_maneuvers, cost
        As :class:`aerodelta.longitudinal.FlapFit`.
    residual_std
        Residual standard deviation of C_L and C_m (NaN when C_m was not fitted).
    maneuvers
        The maneuver ids fitted.
    tanh
        The tanh fit it started from (its ``cost`` against this one's says what the table
        gained on the same records).
    tau_identified, note
        As the tanh fit's: on static records tau1, tau2 stay held at the engine's bounds. The
        note also names the coefficients held for want of samples.
    line
        Which lift line was held: ``"lift line of the tanh fit"`` or ``"... of the
        equation-error start"`` (:func:`fit_goman_khrabrov`, Notes).
    drag
        The drag along this fit's state (:class:`aerodelta.longitudinal.DragFit`: ``CD0``,
        ``CD_k``, ``CD_x``, errors with the state's uncertainty); None with ``fit_cd=False``.
    """

    flap_deg: float
    params: dict[str, float]
    start: dict[str, float]
    knots_deg: FloatArray
    x0: FloatArray
    x0_start: FloatArray
    std_err: dict[str, float]
    std_err_colored: dict[str, float]
    x0_std_err: FloatArray
    x0_std_err_colored: FloatArray
    cov: FloatArray
    cov_colored: FloatArray
    names: tuple[str, ...]
    iterations: int
    converged: bool
    n_samples: int
    n_maneuvers: int
    cost: float
    residual_std: tuple[float, float]
    maneuvers: tuple[str, ...]
    tanh: FlapFit
    tau_identified: bool = True
    note: str = ""
    line: str = ""
    drag: DragFit | None = None

    def _table(self) -> tuple[dict[str, float], list[float], list[float]]:
        return self.params, np.radians(self.knots_deg).tolist(), self.x0.tolist()

    @property
    def cl_max(self) -> tuple[float, float]:
        """``(alpha at C_L,max [deg], C_L,max)`` of the static lift curve over the table. A
        maximum at the last knot means the curve still rises where the data end."""
        a, c = _core.goman_khrabrov_cl_max(*self._table())
        return math.degrees(a), c

    def static_curve(self, alpha_deg: Sequence[float] | FloatArray) -> pl.DataFrame:
        """The static curves (``x = x0(alpha)``) at ``alpha_deg`` (deg), with delta-method
        standard errors from the coloured-residual covariance.

        Returns
        -------
        polars.DataFrame
            ``alpha_deg``, ``x0``, ``CL``, ``Cm``, ``CL_se``, ``Cm_se`` (C_L and C_m the
            static-curve parts, as fitted).
        """
        a_deg = np.asarray(alpha_deg, dtype=np.float64)
        a = np.radians(a_deg)
        p, knots, values = self._table()
        x0, cl, cm = _core.goman_khrabrov_static(p, knots, values, a)
        # d x0 / d coefficient: the spline's weights at each alpha
        hat = _core.goman_khrabrov_weights(knots, a)
        sq = np.sqrt(np.maximum(x0, 1e-12))
        dcl_dx = p["CL_alpha"] * (a - p["alpha0"]) * (1.0 + sq) / (4.0 * sq)
        nc = len(CORE_PARAMS)
        g_cl = np.zeros((len(a), nc + len(knots)))
        g_cm = np.zeros_like(g_cl)
        g_cl[:, nc:] = dcl_dx[:, None] * hat
        ci = {n: k for k, n in enumerate(CORE_PARAMS)}
        g_cl[:, ci["CL_alpha"]] = (a - p["alpha0"]) * ((1.0 + sq) / 2.0) ** 2
        g_cl[:, ci["alpha0"]] = -p["CL_alpha"] * ((1.0 + sq) / 2.0) ** 2
        g_cm[:, ci["Cm0"]] = 1.0
        g_cm[:, ci["Cm_alpha"]] = a
        g_cm[:, ci["Cm_x"]] = 1.0 - x0
        g_cm[:, nc:] = -p["Cm_x"] * hat
        cov = self.cov_colored
        return pl.DataFrame(
            {
                "alpha_deg": a_deg,
                "x0": x0,
                "CL": cl,
                "Cm": cm,
                "CL_se": np.sqrt(np.maximum(((g_cl @ cov) * g_cl).sum(axis=1), 0.0)),
                "Cm_se": np.sqrt(np.maximum(((g_cm @ cov) * g_cm).sum(axis=1), 0.0)),
            }
        )


@dataclass(frozen=True)
class GomanKhrabrovResult:
    """What :func:`fit_goman_khrabrov` returns: one :class:`GkFlapFit` per flap, whether C_m
    was fitted, and ``known`` (the terms taken off the measured coefficients)."""

    fits: dict[float, GkFlapFit]
    fit_cm: bool
    known: str = "adx37"

    @property
    def notes(self) -> dict[float, str]:
        """flap (deg) -> the fit's note, for the flaps that have one."""
        return _notes(self.fits)

    def __getitem__(self, flap_deg: float) -> GkFlapFit:
        """The fit of one flap setting (deg)."""
        return _flap_fit(self.fits, flap_deg)

    def summary(self) -> pl.DataFrame:
        """One row per flap and parameter: ``flap_deg, parameter, unit, alpha_deg, estimate,
        std_err, std_err_colored, start`` (``alpha_deg`` the knot of a node ``x0[k]``, NaN for
        the scalars), the drag's ``CD0``, ``CD_k``, ``CD_x`` where fitted (``std_err`` the
        :class:`aerodelta.longitudinal.DragFit` one: CR2 with the state's uncertainty), then
        ``alpha_cl_max_deg`` and ``cl_max`` of the static curve and this fit's ``cost``.
        ``start``: the fit's start (the held line, the tanh fit's other scalars, the
        coefficients re-expressed on the held line); on the last three rows, the tanh fit's
        value."""
        rows: list[dict[str, Any]] = []
        nan = math.nan
        for f in sorted(self.fits):
            ff = self.fits[f]
            for n in CORE_PARAMS:
                rows.append(
                    {
                        "flap_deg": f, "parameter": n, "unit": CORE_UNITS[n], "alpha_deg": nan,
                        "estimate": ff.params[n], "std_err": ff.std_err[n],
                        "std_err_colored": ff.std_err_colored[n], "start": ff.start[n],
                    }
                )  # fmt: skip
            for k, a in enumerate(ff.knots_deg):
                rows.append(
                    {
                        "flap_deg": f, "parameter": f"x0[{k}]", "unit": "-",
                        "alpha_deg": float(a), "estimate": float(ff.x0[k]),
                        "std_err": float(ff.x0_std_err[k]),
                        "std_err_colored": float(ff.x0_std_err_colored[k]),
                        "start": float(ff.x0_start[k]),
                    }
                )  # fmt: skip
            if ff.drag is not None:
                rows.extend(
                    {
                        "flap_deg": f, "parameter": n, "unit": "-", "alpha_deg": nan,
                        "estimate": ff.drag.params[n], "std_err": ff.drag.std_err[n],
                        "std_err_colored": nan, "start": nan,
                    }
                    for n in DRAG_PARAMS
                )  # fmt: skip
            a_max, c_max = ff.cl_max
            t_a, t_c = ff.tanh.cl_max
            for name, unit, est, st in (
                ("alpha_cl_max_deg", "deg", a_max, t_a),
                ("cl_max", "-", c_max, t_c),
                ("cost", "-", ff.cost, ff.tanh.cost),
            ):
                rows.append(
                    {
                        "flap_deg": f, "parameter": name, "unit": unit, "alpha_deg": nan,
                        "estimate": est, "std_err": nan, "std_err_colored": nan, "start": st,
                    }
                )  # fmt: skip
        return pl.DataFrame(rows, infer_schema_length=None)

    def predict(self, data: pl.DataFrame, known: str | None = None) -> pl.DataFrame:
        """The model's C_L and C_m along records (each maneuver integrated from its start).

        Parameters
        ----------
        data
            A :func:`aerodelta.fit.model_frame` of ingested records at fitted flap settings.
        known
            ``"adx37"``: add the built-in qualified model's control, rate and thrust terms;
            ``"none"``: the static-curve parts alone. Default: the basis of the fit.

        Returns
        -------
        polars.DataFrame
            ``x_sep``, ``CL_model``, ``Cm_model``, ``CD_model`` (NaN at a flap whose drag was
            not fitted), one row per input row (in input order).
        """
        return _predict_along(
            data,
            self.known if known is None else known,
            self.__getitem__,
            lambda ff, t, a, ad: _core.goman_khrabrov_outputs(*ff._table(), t, a, ad),
        )


def knots_for(
    alpha_deg: FloatArray,
    spacing_deg: float,
    first_deg: float,
    min_samples: int,
    last_deg: float = -math.inf,
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """The table's knots (deg) and which coefficients are free.

    Knots are the multiples of ``spacing_deg`` from ``first_deg`` (rounded down; or from the
    lowest flown alpha, rounded down, when that is higher) to the first at or above the largest
    flown alpha or ``last_deg``, whichever is higher, so the table spans the data (and, past
    them, the start's curve up to ``last_deg``). A coefficient is free when its effective sample
    count, the sum of its spline weight over the samples (``aero_core``'s
    ``X0Table::weights``), is at least ``min_samples``; the others stay at their start (a
    coefficient at the table's end that few samples reach extrapolates: held, it keeps the
    tanh start's trend).

    Raises
    ------
    TooLittleDataError
        Fewer than three knots, or fewer than two free coefficients.
    """
    a = np.sort(np.asarray(alpha_deg, dtype=np.float64))
    lo = math.floor(max(first_deg, a[0]) / spacing_deg) * spacing_deg
    top = math.ceil(max(a[-1], last_deg) / spacing_deg) * spacing_deg
    if top - lo < 2 * spacing_deg - 1e-9:
        raise TooLittleDataError(
            f"the records reach alpha {a[-1]:.1f} deg, less than two {spacing_deg:g}-deg "
            f"knots past {lo:g} deg (where the tanh fit's separation begins): fly through the "
            "stall, or narrow the spacing"
        )
    grid = lo + spacing_deg * np.arange(round((top - lo) / spacing_deg) + 1)
    weight = _core.goman_khrabrov_weights(np.radians(grid).tolist(), np.radians(a)).sum(axis=0)
    free = weight >= min_samples
    if int(free.sum()) < 2:
        raise TooLittleDataError(
            f"{int(free.sum())} of {grid.size} knots from {lo:g} deg have an effective sample "
            f"count of {min_samples}; the table needs at least 2 free: fly deeper into the "
            "stall, widen the spacing or lower min_knot_samples"
        )
    return np.asarray(grid, dtype=np.float64), free


def fit_goman_khrabrov(
    data: pl.DataFrame,
    *,
    start: KirchhoffResult | None = None,
    flaps: Sequence[float] | None = None,
    maneuvers: Sequence[str] | None = None,
    fit_cm: bool = True,
    fit_cd: bool = True,
    known: str = "adx37",
    knot_spacing_deg: float = 1.0,
    min_knot_samples: int = 50,
    max_iter: int = 100,
    max_lag: int | None = None,
) -> GomanKhrabrovResult:
    """Fit the tabulated (Goman-Khrabrov) form by output error, one flap setting at a time.

    Parameters
    ----------
    data
        A :func:`aerodelta.fit.model_frame` of ingested records, as
        :func:`aerodelta.longitudinal.fit_kirchhoff`.
    start
        The tanh fit of the same records (``fit_kirchhoff(data, flaps=..., maneuvers=...,
        known=...)``) to start from; default: fitted here (without drag). Refused when it was
        fitted on other maneuvers or another ``known``.
    flaps, maneuvers, fit_cm, fit_cd, known, max_lag
        As :func:`aerodelta.longitudinal.fit_kirchhoff` (the drag along this fit's state).
    knot_spacing_deg
        Spacing of the table's knots, deg (:func:`knots_for`).
    min_knot_samples
        Effective samples (the sum of a coefficient's spline weight over the samples) a
        coefficient needs to be estimated; the others are held at the tanh start
        (:func:`knots_for`).
    max_iter
        Iteration bound of the Levenberg-Marquardt loop.

    Returns
    -------
    GomanKhrabrovResult

    Notes
    -----
    A lift line ``CL_alpha``, ``alpha0`` is held (:data:`HELD_LINE`): with every coefficient
    free the line and the table trade off. Two candidates are fitted and the lower cost kept
    (:attr:`GkFlapFit.line`): the tanh fit's line, and the equation-error start's attached-flow
    line (its margin under the peak 5 deg, or 3 or 1.5 when needed); the tanh fit's own line
    bends to the break where the tanh cannot follow it, the attached line clips coefficients at
    1 where the lift rises above it again. The table's knots
    run from :data:`BELOW_DEG` under the tanh start's attached alpha (or the lowest alpha
    flown) to past the data on the tanh start's curve (:func:`knots_for`); its start is the
    separation point whose lift on the held line is the tanh fit's static lift. tau1, tau2, the
    coefficients with enough samples (bounded to [0, 1]) and ``Cm0``, ``Cm_alpha``, ``Cm_x``
    are estimated; the others are held and the note names them. Where the tanh fit found no
    separation lag (``tau_identified`` False: static records) tau1, tau2 stay held at the
    engine's bounds and the note says so.

    Raises
    ------
    InvalidInputError
        A ``start`` fitted on other maneuvers, flaps or basis.
    TooLittleDataError, NoConvergenceError
        Too few knots with data, or from the engine, with the flap named.
    """
    if knot_spacing_deg <= 0 or not math.isfinite(knot_spacing_deg):
        raise InvalidInputError(f"knot_spacing_deg is {knot_spacing_deg}; give a spacing > 0 deg")
    if start is not None and (start.known != known or (fit_cm and not start.fit_cm)):
        raise InvalidInputError(
            f"start was fitted with known='{start.known}', fit_cm={start.fit_cm}; "
            f"this fit asks known='{known}', fit_cm={fit_cm}: fit the start the same way"
        )
    frame = _prepared(data, maneuvers, known, fit_cm)
    all_flaps = sorted({float(f) for f in frame["flap_deg"].unique().to_list()})
    wanted = all_flaps if flaps is None else [float(f) for f in flaps]
    if start is None:
        start = fit_kirchhoff(
            data, flaps=wanted, maneuvers=maneuvers, fit_cm=fit_cm, fit_cd=False, known=known,
            max_lag=max_lag,
        )  # fmt: skip
    fits: dict[float, GkFlapFit] = {}
    for flap in wanted:
        ts, al, ad, ls, ms, ds, ids = _flap_records(frame, flap, all_flaps)
        tanh = start[flap]
        if tuple(sorted(tanh.maneuvers)) != tuple(sorted(ids)):
            raise InvalidInputError(
                f"flap {flap:g} deg: start was fitted on {len(tanh.maneuvers)} maneuvers, these "
                f"records hold {len(ids)} others; fit the start on the same maneuvers"
            )
        ff = _fit_flap(
            tanh, ts, al, ad, ls, ms if fit_cm else None, tuple(ids), flap,
            knot_spacing_deg, min_knot_samples, max_iter, max_lag,
        )  # fmt: skip
        if fit_cd:
            ff = dataclasses.replace(ff, drag=_table_drag(ff, ts, al, ad, ds))
        fits[flap] = ff
    return GomanKhrabrovResult(fits=fits, fit_cm=fit_cm, known=known)


def _held_note(knots_deg: FloatArray, free: npt.NDArray[np.bool_]) -> str:
    """``"x0 not identified at 19-25 deg ..."`` for the held coefficients (empty when none is
    held)."""
    held = np.flatnonzero(~free)
    if held.size == 0:
        return ""
    runs = np.split(held, np.flatnonzero(np.diff(held) > 1) + 1)
    where = ", ".join(
        f"{knots_deg[r[0]]:g}" if r.size == 1 else f"{knots_deg[r[0]]:g}-{knots_deg[r[-1]]:g}"
        for r in runs
    )
    return f"x0 not identified at {where} deg (too few samples there), held at the tanh fit's curve"


def _fit_flap(  # noqa: PLR0917
    tanh: FlapFit,
    ts: list[FloatArray],
    al: list[FloatArray],
    ad: list[FloatArray],
    ls: list[FloatArray],
    ms: list[FloatArray] | None,
    ids: tuple[str, ...],
    flap: float,
    spacing: float,
    min_samples: int,
    max_iter: int,
    max_lag: int | None,
) -> GkFlapFit:
    tp = tanh.params
    # the table starts BELOW_DEG under where the tanh start leaves attached flow (x0 = 0.999:
    # its lift within 0.05 % of its line), at a multiple of the spacing
    a_att = math.degrees(tp["alpha_star"] + math.atanh(1.0 - 2.0 * ATTACHED_X) / tp["a1"])
    # past the data the table follows the tanh start's curve (held coefficients) until it is
    # separated (x0 = SEPARATED_X), at most EXTEND_DEG past the highest alpha flown
    a_all = np.degrees(np.concatenate(al))
    a_sep = math.degrees(tp["alpha_star"] + math.atanh(1.0 - 2.0 * SEPARATED_X) / tp["a1"])
    last = min(a_sep, float(a_all.max()) + EXTEND_DEG)
    try:
        knots_deg, free = knots_for(a_all, spacing, a_att - BELOW_DEG, min_samples, last)
    except TooLittleDataError as e:
        raise TooLittleDataError(f"flap {flap:g} deg: {e}") from e
    knots = np.radians(knots_deg)
    fixed = [*HELD_LINE, *(f"x0[{k}]" for k in np.flatnonzero(~free))]
    held_note = _held_note(knots_deg, free)
    if held_note:
        held_note += f" (an effective sample count under {min_samples})"
    if not tanh.tau_identified:
        fixed += ["tau1", "tau2"]
    # Two candidate lift lines, the one of lower cost kept (same free parameters, so the costs
    # compare): the tanh fit's, fitted to every sample, and the attached-flow line of the
    # equation-error start (least squares below the largest binned C_L less 5 deg). Where the
    # tanh cannot follow the lift curve it bends its line to fit the break, and the lags read
    # that as dynamics (a plateau's tau2 came out 15 % low on the tanh's line); where the lift
    # rises above the attached line again (JSBSim's F-15, DHC-6) that line clips coefficients
    # at 1 (the table left the binned curve's band on 15-25 % of the grid).
    candidates: list[tuple[str, Mapping[str, float]]] = [("tanh fit", tp)]
    errors: list[AerodeltaError] = []
    try:
        ee = _engine(ts, al, ad, ls, ms, ids, flap, max_lag, None, list(PARAMS), 1)["start"]
        candidates.append(("equation-error start", ee))
    except AerodeltaError as e:  # a user-given tanh start on records the start refuses
        errors.append(e)
    fits: list[tuple[float, str, dict[str, Any]]] = []
    for source, line_p in candidates:
        try:
            r = _fit_on_line(
                tanh, line_p, knots, knots_deg, ts, al, ad, ls, ms, fixed, max_iter, max_lag
            )
        except AerodeltaError as e:
            msg = re.sub(r"maneuver (\d+)", functools.partial(_maneuver_name, ids), str(e))
            errors.append(type(e)(f"flap {flap:g} deg (Goman-Khrabrov, {source}'s line): {msg}"))
            continue
        fits.append((float(r["cost"]), source, r))
    if not fits:
        raise errors[0]
    _, source, r = min(fits, key=lambda f: f[0])
    line_note = f"lift line of the {source}"
    names = tuple(r["names"])
    nc = len(CORE_PARAMS)
    se = [float(v) for v in r["std_err"]]
    sec = [float(v) for v in r["std_err_colored"]]
    var = [float(v) for v in r["residual_var"]]
    return GkFlapFit(
        flap_deg=flap,
        params={k: float(v) for k, v in r["params"].items()},
        start={k: float(v) for k, v in r["start"].items()},
        knots_deg=knots_deg,
        x0=np.asarray(r["values"], dtype=np.float64),
        x0_start=np.asarray(r["start_values"], dtype=np.float64),
        std_err=dict(zip(CORE_PARAMS, se[:nc], strict=True)),
        std_err_colored=dict(zip(CORE_PARAMS, sec[:nc], strict=True)),
        x0_std_err=np.asarray(se[nc:]),
        x0_std_err_colored=np.asarray(sec[nc:]),
        cov=np.asarray(r["cov"]),
        cov_colored=np.asarray(r["cov_colored"]),
        names=names,
        iterations=int(r["iterations"]),
        converged=bool(r["converged"]),
        n_samples=int(r["n_samples"]),
        n_maneuvers=int(r["n_maneuvers"]),
        cost=float(r["cost"]),
        residual_std=(math.sqrt(var[0]), math.sqrt(var[1]) if ms is not None else math.nan),
        maneuvers=ids,
        tanh=tanh,
        tau_identified=tanh.tau_identified,
        note="; ".join(n for n in (tanh.note, held_note) if n),
        line=line_note,
    )


def _fit_on_line(  # noqa: PLR0917
    tanh: FlapFit,
    line_p: Mapping[str, float],
    knots: FloatArray,
    knots_deg: FloatArray,
    ts: list[FloatArray],
    al: list[FloatArray],
    ad: list[FloatArray],
    ls: list[FloatArray],
    ms: list[FloatArray] | None,
    fixed: list[str],
    max_iter: int,
    max_lag: int | None,
) -> dict[str, Any]:
    """One engine fit of the table on the lift line of ``line_p`` (held). The start is the
    separation point whose lift on that line is the tanh fit's static lift, interpolated by
    the spline at the knots (coefficients equal to the curve's values miss it by
    ``h^2 x0''/6``, and near full separation the lift's ``1/sqrt(x)`` sensitivity turns that
    into 0.02 of C_L)."""
    tp = tanh.params
    basis = _core.goman_khrabrov_weights(knots.tolist(), knots)
    line = float(line_p["CL_alpha"]) * (knots - float(line_p["alpha0"]))
    ratio = np.ones_like(knots)
    up = line > 0.0
    ratio[up] = np.clip(static_curves(tp, knots_deg[up])["CL"] / line[up], 0.25, 1.0)
    values = np.clip(np.linalg.solve(basis, (2.0 * np.sqrt(ratio) - 1.0) ** 2), 0.0, 1.0)
    core = {n: float(tp[n]) for n in CORE_PARAMS}
    core.update(CL_alpha=float(line_p["CL_alpha"]), alpha0=float(line_p["alpha0"]))
    if not tanh.tau_identified:
        core.update(tau1=TAU1_MIN_S, tau2=0.0)
    return dict(
        _core.output_error_goman_khrabrov(
            ts, al, ad, ls, ms, core, knots.tolist(), values.tolist(), fixed=fixed,
            max_iter=int(max_iter), max_lag=max_lag,
        )
    )  # fmt: skip


def _table_drag(
    ff: GkFlapFit,
    ts: list[FloatArray],
    al: list[FloatArray],
    ad: list[FloatArray],
    ds: list[FloatArray],
) -> DragFit:
    """The drag along the table's state (:func:`aerodelta.longitudinal._fit_drag`), its errors
    with the table's coloured covariance carried."""
    nc = len(CORE_PARAMS)
    knots = np.radians(ff.knots_deg).tolist()

    def design(p: Mapping[str, float]) -> FloatArray:
        core = {n: p[n] for n in CORE_PARAMS}
        values = [p[n] for n in ff.names[nc:]]
        xs: list[FloatArray] = []
        for t, a, adot in zip(ts, al, ad, strict=True):
            x, cl, _ = _core.goman_khrabrov_outputs(core, knots, values, t, a, adot)
            xs.append(_drag_regressors(cl, x))
        return np.concatenate(xs)

    theta = {**ff.params, **dict(zip(ff.names[nc:], map(float, ff.x0), strict=True))}
    theta = {n: theta[n] for n in ff.names}
    bounds = {
        "tau1": (TAU1_MIN_S, math.inf),
        "tau2": (0.0, math.inf),
        **dict.fromkeys(ff.names[nc:], (0.0, 1.0)),
    }
    d = _fit_drag(design, theta, ff.cov_colored, bounds, ds, ff.maneuvers, ff.flap_deg)
    return dataclasses.replace(
        d,
        note=d.note + "; the held lift line (CL_alpha, alpha0) carries no uncertainty here",
    )
