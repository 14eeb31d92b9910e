"""Regressor columns of the candidate effects (see :mod:`aerodelta.diagnosis.vocabulary`)."""

from __future__ import annotations

import numpy as np
import polars as pl

from aerodelta.aircraft import Aircraft
from aerodelta.diagnosis.simulator import Simulator, deg_step
from aerodelta.diagnosis.vocabulary import AERO_REGRESSORS, COEFFICIENTS, Vocabulary


def _rate(frame: pl.DataFrame, col: str) -> np.ndarray:
    """d(col)/dt per maneuver, unit/s: central differences of a 5-point moving average."""
    sm = pl.col(col).rolling_mean(5, center=True, min_samples=1)
    s = frame.select(
        ((sm.shift(-1) - sm.shift(1)) / (pl.col("t").shift(-1) - pl.col("t").shift(1)))
        .over("maneuver_id")
        .fill_null(0.0)
        .alias("d"),
    )
    d = s["d"].to_numpy()
    return np.where(np.isfinite(d), d, 0.0)


def _rate_of(frame: pl.DataFrame, values: np.ndarray) -> np.ndarray:
    """:func:`_rate` of an array aligned with ``frame``'s rows, per maneuver, unit/s."""
    tmp = frame.select("maneuver_id", "t").with_columns(pl.Series("__v", values))
    return _rate(tmp, "__v")


#: Time step of the directional differences of the lag and skew regressors, s.
_EPS_S = 0.02


def _directional(
    sim: Simulator, frame: pl.DataFrame, rates: dict[str, np.ndarray], eps: float
) -> dict[str, np.ndarray]:
    """``d/d(tau) C(x + tau * xdot)`` at ``tau = 0`` by central differences: the change of the
    simulator's output per second of delay of the channels in ``rates``."""
    cols = [c for c in rates if c in frame.columns]
    if not cols:
        return {c: np.zeros(frame.height) for c in COEFFICIENTS}
    up = sim.predict(frame.with_columns([(pl.col(c) + eps * rates[c]).alias(c) for c in cols]))
    dn = sim.predict(frame.with_columns([(pl.col(c) - eps * rates[c]).alias(c) for c in cols]))
    return {c: (up[c] - dn[c]) / (2.0 * eps) for c in COEFFICIENTS}


#: Control channels a control lag delays (the channels of the ``m_control_lag`` regressor).
LAG_CHANNELS = ("da_deg", "dr_deg", "dsl_deg", "dsr_deg")


def delayed_controls(frame: pl.DataFrame, tau_s: float) -> pl.DataFrame:
    """``frame`` with every control channel replaced by its value ``tau_s`` seconds earlier,
    per maneuver (linear interpolation in time, the end values held beyond the record): the
    exact delay of which ``m_control_lag`` is the first-order (rate) term."""
    cols = [c for c in LAG_CHANNELS if c in frame.columns]
    if not cols or tau_s == 0.0:
        return frame
    t = frame["t"].cast(pl.Float64).to_numpy()
    ids = frame["maneuver_id"].to_numpy()
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    ends = np.r_[starts[1:], ids.size]
    out = {}
    for c in cols:
        x = frame[c].cast(pl.Float64).to_numpy()
        y = x.copy()
        for s, e in zip(starts, ends, strict=True):
            y[s:e] = np.interp(t[s:e] - tau_s, t[s:e], x[s:e])
        out[c] = y
    return frame.with_columns([pl.Series(c, v) for c, v in out.items()])


def measurement_columns(
    frame: pl.DataFrame, sim: Simulator, aircraft: Aircraft
) -> dict[str, dict[str, np.ndarray]]:
    """The measurement regressors per coefficient (computed once: nine simulator calls).

    ``m_alpha_bias``/``m_beta_bias``: ``-dC/d(angle)`` per deg of vane bias; ``m_control_lag``:
    ``-dC/dtau`` with every control delayed by tau (s); ``m_time_skew``: ``+dC/dtau`` with the
    air data (alpha, beta) delayed, or with a black-box simulator (``*_sim`` columns) every
    input delayed, ``+dC_sim/dt`` (with the accelerometer offset, the measurement effects
    such a simulator can test); ``m_acc_dx``/``m_acc_dz``: the side-force coefficient picked up
    per metre of accelerometer displacement (``m/(qbar S) rdot`` and ``-m/(qbar S) pdot``;
    C_Y only, zero for C_l and C_n).
    """
    out: dict[str, dict[str, np.ndarray]] = {}
    if not sim.differentiable:
        # A black-box simulator (the records' *_sim columns) cannot be evaluated at perturbed
        # states, but a timing skew acts on its whole output: with the simulator's inputs
        # tau seconds late (or the measured coefficients tau early), C_sim(t) = C(t - tau)
        # and the gap gains +tau dC_sim/dt, the sign of the model-based skew above. Measured
        # rate gyros 10 ms late give tau = -0.01 s.
        pred = sim.predict(frame)
        out["m_time_skew"] = {c: _rate_of(frame, pred[c]) for c in COEFFICIENTS}
    if sim.differentiable:
        sa = sim.sensitivity(frame, "alpha_deg", deg_step())
        sb = sim.sensitivity(frame, "beta_deg", deg_step())
        out["m_alpha_bias"] = {c: -v for c, v in sa.items()}
        out["m_beta_bias"] = {c: -v for c, v in sb.items()}
        air = {
            "alpha_deg": frame["alphadot_dps"].to_numpy(),
            "beta_deg": frame["betadot_dps"].to_numpy(),
        }
        skew = _directional(sim, frame, air, _EPS_S)
        out["m_time_skew"] = skew
        ctrl = {ch: _rate(frame, ch) for ch in LAG_CHANNELS if ch in frame.columns}
        lag = _directional(sim, frame, ctrl, _EPS_S)
        out["m_control_lag"] = {c: -v for c, v in lag.items()}
    qs = np.maximum(frame["qbar_pa"].to_numpy(), 1.0) * aircraft.S_m2
    k = aircraft.mass_kg / qs
    zero = np.zeros(frame.height)
    dx = k * np.radians(frame["rdot_dps2"].to_numpy())
    dz = -k * np.radians(frame["pdot_dps2"].to_numpy())
    out["m_acc_dx"] = {"Cl": zero, "Cn": zero, "CY": dx}
    out["m_acc_dz"] = {"Cl": zero, "Cn": zero, "CY": dz}
    return out


def _sorted_for(frame: pl.DataFrame, expr: pl.Expr) -> pl.DataFrame:
    """The columns of ``frame`` that ``expr`` reads (with ``maneuver_id`` and ``t``; all of them
    if polars cannot tell), sorted by maneuver and time."""
    try:
        roots = expr.meta.root_names()
    except pl.exceptions.PolarsError:  # an expression polars cannot introspect: every column
        roots = frame.columns
    keep = [c for c in dict.fromkeys(["maneuver_id", "t", *roots]) if c in frame.columns]
    return frame.select(keep).sort(["maneuver_id", "t"])


def design_columns(
    frame: pl.DataFrame,
    coef: str,
    *,
    aero_names: list[str],
    glob_names: list[str],
    vocab: Vocabulary,
    meas: dict[str, dict[str, np.ndarray]],
    order: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The aerodynamic (``n x R``) and global (``n x Gn``) regressor matrices of ``coef``.

    ``order`` (a permutation of ``frame``'s rows, or ``None``) puts the aerodynamic regressors'
    rows in that order as they are filled in; ``meas`` must be in the same order already."""
    exprs = {**AERO_REGRESSORS, **vocab.user_regressors}
    # filled column by column into one row-major array (no intermediate copies)
    aero_x = np.empty((frame.height, len(aero_names)))
    for i, a in enumerate(aero_names):
        expr = exprs[a].cast(pl.Float64).alias("__reg")
        if order is not None and a not in AERO_REGRESSORS:
            # a user's expression may read neighbouring rows (a shift, a rolling mean, across
            # maneuvers unless it says .over): evaluated on its columns sorted, the rows a
            # sorted copy of the records gave it
            aero_x[:, i] = _sorted_for(frame, exprs[a]).with_columns(expr)["__reg"].to_numpy()
            continue
        # with_columns broadcasts a literal (the constant regressor) to the frame's height
        col = frame.with_columns(expr)["__reg"].to_numpy()
        aero_x[:, i] = col if order is None else col[order]
        del col
    aero_x[~np.isfinite(aero_x)] = 0.0
    glob_x = np.empty((frame.height, len(glob_names)))
    for i, g in enumerate(glob_names):
        glob_x[:, i] = meas[g][coef]
    glob_x[~np.isfinite(glob_x)] = 0.0
    return aero_x, glob_x
