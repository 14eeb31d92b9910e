"""Preprocessing of validated canonical records: air data, propulsion, and the Rust pipeline
(smoothing, derivatives, CG transfers, measured coefficients).

Formulas (body axes, Etkin: x forward, y right wing, z down):

- air data when ``tas_mps``/``rho_kgm3`` are absent: :math:`\\rho = p_s/(R T_s)`,
  :math:`M = \\sqrt{5[(q_c/p_s + 1)^{2/7} - 1]}` with :math:`q_c = p_t - p_s` (subsonic
  isentropic pitot), :math:`V = M\\sqrt{\\gamma R T_s}`, R = 287.05287 J/(kg K), γ = 1.4;
- thrust coefficient per engine when ``ct_*`` are absent: :math:`C_T = \\eta Q\\Omega/(V\\bar q S)`
  from shaft torque Q (N m) and propeller speed Ω (rad/s), η = ``Aircraft.prop_efficiency``;
- :math:`C_{T,diff} = C_{T,left} - C_{T,right}` (thesis Eq. 3.17), from per-engine C_T
  smoothed like the air data (optimal Fourier smoothing per maneuver, :func:`_smooth_thrust`);
  the signed combined spoiler :math:`\\delta_s = \\delta_{s,right} - \\delta_{s,left}`
  (Eq. 3.18 with signed sides, see ``docs/data.md``);
- the engine (``aero_core::preprocess::maneuver``): smoothing (SIDPAC ``smoo``), ṗ, q̇, ṙ,
  accelerometer and vane transfers to the CG, α̇, β̇, :math:`\\bar q = \\rho V^2/2`,
  :math:`\\hat p = pb/2V`, :math:`\\hat q = q\\bar c/2V`, :math:`\\hat r = rb/2V`, and
  Cl, Cn, CY (Eq. 3.2-3.4, gyroscopic term :math:`I_p\\Omega_p q`), CX, CZ, Cm.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import polars as pl

from aerodelta import _core
from aerodelta.aircraft import Aircraft
from aerodelta.loading import loading_array

R_AIR = 287.05287
GAMMA = 1.4


def add_air_data(df: pl.DataFrame) -> pl.DataFrame:
    """Add ``tas_mps`` and ``rho_kgm3`` from ``ps_pa``, ``pt_pa``, ``sat_k`` where absent."""
    exprs = []
    if "rho_kgm3" not in df.columns:
        exprs.append((pl.col("ps_pa") / (R_AIR * pl.col("sat_k"))).alias("rho_kgm3"))
    if "tas_mps" not in df.columns:
        qc_ps = (pl.col("pt_pa") - pl.col("ps_pa")) / pl.col("ps_pa")
        mach = (5.0 * ((qc_ps + 1.0) ** (2.0 / 7.0) - 1.0)).clip(lower_bound=0.0).sqrt()
        exprs.append((mach * (GAMMA * R_AIR * pl.col("sat_k")).sqrt()).alias("tas_mps"))
    return df.with_columns(exprs) if exprs else df


def _prop_rpm(df: pl.DataFrame, ac: Aircraft) -> np.ndarray:
    if ac.prop_rpm_channel and ac.prop_rpm_channel in df.columns:
        return df[ac.prop_rpm_channel].cast(pl.Float64).to_numpy()
    if ac.prop_rpm_fixed is not None:
        return np.full(df.height, ac.prop_rpm_fixed)
    return np.zeros(df.height)


def preprocess_frame(
    df: pl.DataFrame,
    aircraft: Aircraft,
    smooth: bool = True,
    loadings: pl.DataFrame | None = None,
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """Preprocess validated maneuvers stored back to back (a ``maneuver_id`` column separates
    them; each maneuver's rows contiguous and in time order).

    ``loadings`` (from :func:`aerodelta.loading.manifest_loadings`) gives each maneuver its
    own mass, inertia tensor and CG; without it every maneuver has the aircraft file's. The
    moment coefficients are about the aircraft's moment reference centre
    (:attr:`Aircraft.reference_m`).

    Returns
    -------
    (polars.DataFrame, polars.DataFrame)
        The input with the derived columns of :data:`aerodelta.channels.DERIVED` (plus the
        smoothed ``p_s_dps``, ``q_s_dps``, ``r_s_dps``, ``tas_s_mps``), and the smoother
        report: one row per maneuver and channel with ``cutoff_hz`` and ``noise_std``.
    """
    df = add_air_data(df)
    # maneuver boundaries from the run lengths of maneuver_id (no per-row Python objects)
    runs = df.select(pl.col("maneuver_id").rle()).unnest("maneuver_id")
    lengths = runs["len"].to_numpy()
    starts = np.concatenate(([0], np.cumsum(lengths)[:-1])).astype(np.int64)
    offsets = [*starts.tolist(), df.height]
    inputs, smoothed, outputs = _core.preprocess_columns()
    cols = []
    for c in inputs:
        if c == "prop_rpm":
            cols.append(np.ascontiguousarray(_prop_rpm(df, aircraft), dtype=np.float64))
        else:
            cols.append(np.ascontiguousarray(df[c].cast(pl.Float64).to_numpy(), dtype=np.float64))
    arrays, cut, noise = _core.preprocess_batch(
        cols,
        offsets,
        aircraft.mass_geometry,
        aircraft.prop_h_per_rpm,
        list(aircraft.accel_m),
        list(aircraft.alpha_vane_m),
        list(aircraft.beta_vane_m),
        smooth,
        cg_m=list(aircraft.cg_m),
        moment_ref_m=list(aircraft.reference_m),
        masses=loading_array(loadings, [str(v) for v in runs["value"].to_list()]),
        beta_flank=aircraft.beta_vane_type == "flank",
    )
    out = df.with_columns(pl.Series(name, a) for name, a in zip(outputs, arrays, strict=False))
    qs = pl.col("qbar_pa") * aircraft.S_m2
    extra = []
    for side in ("left", "right"):
        ct = f"ct_{side}"
        tq, rpm = f"torque_{side}_nm", f"rpm_{side}"
        if ct not in out.columns:
            if tq in out.columns and rpm in out.columns:
                omega = pl.col(rpm) * (2.0 * math.pi / 60.0)
                thrust = aircraft.prop_efficiency * pl.col(tq) * omega / pl.col("tas_mps")
                extra.append((thrust / qs).alias(ct))
            else:
                extra.append(pl.lit(None, dtype=pl.Float64).alias(ct))
    if extra:
        out = out.with_columns(extra)
    ct_report: list[tuple[str, str, float, float]] = []
    if smooth:
        out, ct_report = _smooth_thrust(out, offsets, [str(v) for v in runs["value"].to_list()])
    # Combined roll spoiler (thesis Eq. 3.18 with signed sides): the spoilers deploy one side
    # at a time, so ds = dsr - dsl keeps the roll direction (positive: right spoiler up,
    # right wing down, positive Cl), as the virtual flight test's truth model uses it.
    dsr = pl.col("dsr_deg") if "dsr_deg" in out.columns else pl.lit(0.0)
    dsl = pl.col("dsl_deg") if "dsl_deg" in out.columns else pl.lit(0.0)
    ds = dsr - dsl
    out = out.with_columns(
        (pl.col("ct_left") - pl.col("ct_right")).alias("ct_diff"),
        ds.cast(pl.Float64).alias("ds_deg"),
    )
    nm = len(offsets) - 1
    first_ids = [str(v) for v in runs["value"].to_list()]
    report = pl.DataFrame(
        {
            "maneuver_id": [m for m in first_ids for _ in smoothed],
            "channel": smoothed * nm,
            "cutoff_hz": np.asarray(cut),
            "noise_std": np.asarray(noise),
        }
    )
    if ct_report:
        report = pl.concat(
            [report, pl.DataFrame(ct_report, schema=report.columns, orient="row")]
        ).sort("maneuver_id", maintain_order=True)
    return out, report


#: Per-engine thrust coefficient channels smoothed like the air data and rates.
THRUST_CHANNELS = ("ct_left", "ct_right")


def _smooth_thrust(
    df: pl.DataFrame, offsets: list[int], ids: list[str]
) -> tuple[pl.DataFrame, list[tuple[str, str, float, float]]]:
    """Optimal Fourier smoothing (SIDPAC ``smoo``, the engine's smoother) of the thrust
    coefficients, per maneuver, with a data-chosen cut-off.

    C_T enters the simulator's lateral model (``C_n,CTdiff = y_engine / b``) and the Δ
    regressors ``ct_sum``, ``ct_diff``; used raw, its measurement noise passes straight into
    the simulator's C_n (0.158 x sqrt(2) x 0.002 = 4.5e-4 rms at the virtual flight test's
    noise, the size of the whole C_n gap of a well-modelled campaign) and biases the
    thrust-asymmetry terms toward zero (errors in variables). Maneuvers whose channel has
    missing values are left as they are.
    """
    t = df["t"].to_numpy()
    cols: dict[str, np.ndarray] = {}
    report: list[tuple[str, str, float, float]] = []
    for ch in THRUST_CHANNELS:
        if ch not in df.columns or df[ch].null_count() == df.height:
            continue
        x = df[ch].cast(pl.Float64).fill_null(float("nan")).to_numpy().copy()
        for k, (a, b) in enumerate(itertools.pairwise(offsets)):
            seg = x[a:b]
            if b - a < 8 or not np.all(np.isfinite(seg)):
                continue
            dt = float(t[b - 1] - t[a]) / (b - a - 1)  # the engine's step (uniform rate)
            sm, cutoff, noise = _core.smooth(np.ascontiguousarray(seg), dt)
            x[a:b] = sm
            report.append((ids[k], ch, float(cutoff), float(noise)))
        cols[ch] = x
    if not cols:
        return df, report
    # missing samples stay missing (null), not NaN
    return df.with_columns(
        pl.when(pl.col(k).is_null()).then(None).otherwise(pl.Series(k, v)).alias(k)
        for k, v in cols.items()
    ), report
