"""Measurement-chain calibration of the qualified model (``aerodelta.fit.calibrate_chain``).

The reference is analytic: a measured coefficient that is the true one shifted in time by τ
(``C(t + τ)``) or seen through the central difference's trapezoid ``¼, ½, ¼`` has a known skew
and second-order smoothing, which the calibration must recover from the samples below
``alpha_l`` alone.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import polars as pl
import pytest

from aerodelta.fit import CHAIN_MIN_SAMPLES, FitConfig, calibrate_chain

DT = 0.02  # s, 50 Hz


def _signal(t: np.ndarray, phase: float) -> np.ndarray:
    """A qualified coefficient with fast content (doublet-like harmonics), per unit."""
    return (
        0.02 * np.sin(2.1 * t + phase)
        + 0.008 * np.sin(7.3 * t + 2 * phase)
        + 0.004 * np.sin(13.0 * t - phase)
    )


def _frame(
    measured: Callable[[np.ndarray, float], np.ndarray],
    n_man: int = 8,
    seconds: float = 20.0,
    seed: int = 0,
) -> pl.DataFrame:
    """Maneuvers whose alpha ramps 2 -> 20 deg; Cl_meas = measured(t, phase) + a Δ above
    10 deg (0.01 per deg past 10, slow) + white noise; Cl_q the qualified model."""
    rng = np.random.default_rng(seed)
    parts = []
    for m in range(n_man):
        t = np.arange(0.0, seconds, DT)
        phase = 0.7 * m
        alpha = 2.0 + 18.0 * t / seconds
        delta = 0.001 * np.clip(alpha - 10.0, 0.0, None)
        parts.append(
            pl.DataFrame(
                {
                    "t": t,
                    "alpha_deg": alpha,
                    "flap_deg": np.zeros_like(t),
                    "maneuver_id": [f"m{m:02d}"] * t.size,
                    "Cl_meas": measured(t, phase) + delta + 1e-5 * rng.standard_normal(t.size),
                    "Cl_q": _signal(t, phase),
                }
            )
        )
    return pl.concat(parts)


def test_recovers_a_time_skew() -> None:
    tau = 0.006  # s
    df = _frame(lambda t, ph: _signal(t + tau, ph))
    q, cal = calibrate_chain(df, {"Cl": df["Cl_q"].to_numpy()}, ["Cl"], FitConfig(), [0.0])
    assert cal.skipped == {}
    assert cal.skew_s["Cl"] == pytest.approx(tau, rel=0.03)
    # C(t + tau) = C + tau C' + tau^2/2 C'' + ...
    assert cal.curvature_s2["Cl"] == pytest.approx(tau**2 / 2, rel=0.2)
    # the calibrated model matches the measurement to the noise below alpha_l (away from a
    # maneuver's first and last sample, where no three-point derivative exists)
    t = df["t"].to_numpy()
    inner = (df["alpha_deg"] < 8.0).to_numpy() & (t > 0.0) & (t < t.max())
    z = df["Cl_meas"].to_numpy() - q["Cl"]
    z0 = df["Cl_meas"].to_numpy() - df["Cl_q"].to_numpy()
    assert np.std(z[inner]) < 0.05 * np.std(z0[inner])


def test_recovers_the_central_difference_kernel() -> None:
    """A rate differenced over two samples averages its derivative over [t - Δt, t + Δt]:
    at the samples, the trapezoid ¼, ½, ¼, i.e. C + (Δt²/4) C'' to second order."""
    df = _frame(
        lambda t, ph: 0.25 * _signal(t - DT, ph) + 0.5 * _signal(t, ph) + 0.25 * _signal(t + DT, ph)
    )
    _, cal = calibrate_chain(df, {"Cl": df["Cl_q"].to_numpy()}, ["Cl"], FitConfig(), [0.0])
    assert abs(cal.skew_s["Cl"]) < 1e-5
    assert cal.curvature_s2["Cl"] == pytest.approx(DT**2 / 4, rel=0.02)
    assert abs(cal.t_curvature["Cl"]) > 10


def test_leaves_a_consistent_chain_alone() -> None:
    """No chain effect: the estimates are zero within their clustered standard errors."""
    df = _frame(_signal, seed=3)
    q, cal = calibrate_chain(df, {"Cl": df["Cl_q"].to_numpy()}, ["Cl"], FitConfig(), [0.0])
    assert abs(cal.t_skew["Cl"]) < 4 and abs(cal.t_curvature["Cl"]) < 4
    assert np.max(np.abs(q["Cl"] - df["Cl_q"].to_numpy())) < 1e-5


def test_per_flap_alpha_l_and_gaps() -> None:
    """Only rows below their own flap's alpha_l calibrate; no derivative across a gap or
    between maneuvers (the correction is zero there)."""
    tau = 0.006
    df = _frame(lambda t, ph: _signal(t + tau, ph))
    # a second flap whose rows are all above its alpha_l: they must not enter the estimate,
    # although their measurement is wildly off
    other = df.with_columns(
        pl.lit(20.0).alias("flap_deg"),
        (pl.col("maneuver_id") + "_f20").alias("maneuver_id"),
        (pl.col("Cl_meas") + 5.0 * pl.col("Cl_q")).alias("Cl_meas"),
    )
    both = pl.concat([df, other])
    cfg = FitConfig(alpha_l_deg={0.0: 8.0, 20.0: 1.0})
    q, cal = calibrate_chain(both, {"Cl": both["Cl_q"].to_numpy()}, ["Cl"], cfg, [0.0, 20.0])
    assert cal.skew_s["Cl"] == pytest.approx(tau, rel=0.03)
    assert cal.maneuvers["Cl"] == 8
    first = both.with_row_index().group_by("maneuver_id").agg(pl.col("index").min())["index"]
    corr = q["Cl"] - both["Cl_q"].to_numpy()
    assert np.all(corr[first.to_numpy()] == 0.0)
    # a gap of 1 s inside a maneuver: the samples beside it keep the model as it is
    gapped = df.with_columns(
        pl.when(pl.col("t") > 10.0).then(pl.col("t") + 1.0).otherwise(pl.col("t")).alias("t")
    )
    q2, _ = calibrate_chain(gapped, {"Cl": gapped["Cl_q"].to_numpy()}, ["Cl"], FitConfig(), [0.0])
    beside = ((gapped["t"] - 10.0).abs() < 1e-9) | ((gapped["t"] - 11.02).abs() < 1e-9)
    assert beside.sum() == 16
    assert np.all((q2["Cl"] - gapped["Cl_q"].to_numpy())[beside.to_numpy()] == 0.0)


def test_skipped_with_a_reason() -> None:
    df = _frame(_signal)
    q, cal = calibrate_chain(
        df.drop("t"), {"Cl": df["Cl_q"].to_numpy()}, ["Cl"], FitConfig(), [0.0]
    )
    assert "no time column 't'" in cal.note("Cl")
    assert np.array_equal(q["Cl"], df["Cl_q"].to_numpy())
    few = _frame(_signal, n_man=2, seconds=3.0)
    _, cal = calibrate_chain(few, {"Cl": few["Cl_q"].to_numpy()}, ["Cl"], FitConfig(), [0.0])
    assert "not calibrated" in cal.note("Cl") and f"{CHAIN_MIN_SAMPLES} samples" in cal.note("Cl")


def test_setting_is_checked() -> None:
    from aerodelta.exceptions import DataError  # noqa: PLC0415

    with pytest.raises(DataError, match="chain_calibration"):
        FitConfig(chain_calibration="yes")  # type: ignore[arg-type]


def test_a_given_structure_is_estimated_with_the_chain() -> None:
    """A Δ the fit is told exists (a fixed structure) and that is present below alpha_l, in
    phase with the model's derivative, is estimated beside the chain instead of being read
    as a time skew."""
    tau = 0.004
    df = _frame(lambda t, ph: _signal(t + tau, ph))
    da = np.cos(7.3 * df["t"].to_numpy() + 2 * 0.7 * _maneuver_index(df))
    df = df.with_columns(
        pl.Series("da_deg", da), (pl.col("Cl_meas") + 0.0005 * pl.Series(da)).alias("Cl_meas")
    )
    q = {"Cl": df["Cl_q"].to_numpy()}
    _, alone = calibrate_chain(df, q, ["Cl"], FitConfig(), [0.0])
    _, joint = calibrate_chain(
        df, q, ["Cl"], FitConfig(), [0.0], structures={"Cl": [("dCl_0", "1"), ("dCl_da", "da_deg")]}
    )
    assert joint.skew_s["Cl"] == pytest.approx(tau, rel=0.03)
    assert abs(alone.skew_s["Cl"] - tau) > 0.5 * tau  # the omitted Δ taken for a skew
    # a structure term on a channel the data lack is left out, not an error
    _, missing = calibrate_chain(
        df, q, ["Cl"], FitConfig(), [0.0], structures={"Cl": [("dCl_ct", "ct_left + ct_right")]}
    )
    assert missing.skew_s["Cl"] == pytest.approx(alone.skew_s["Cl"], rel=1e-9)


def test_dependent_structure_terms_are_a_note_not_a_crash() -> None:
    """Two given structure terms that are one below alpha_l (the second twice the first):
    the chain is not calibrated and the note names them (this used to raise out of fit)."""
    df = _frame(_signal)
    da = np.cos(7.3 * df["t"].to_numpy())
    df = df.with_columns(pl.Series("da_deg", da), pl.Series("dr_deg", 2.0 * da))
    q = {"Cl": df["Cl_q"].to_numpy()}
    out, cal = calibrate_chain(
        df, q, ["Cl"], FitConfig(), [0.0],
        structures={"Cl": [("dCl_da", "da_deg"), ("dCl_dr", "dr_deg")]},
    )  # fmt: skip
    note = cal.note("Cl")
    assert "not calibrated" in note and "'dCl_da', 'dCl_dr'" in note, note
    assert np.array_equal(out["Cl"], q["Cl"])


def _maneuver_index(df: pl.DataFrame) -> np.ndarray:
    return df["maneuver_id"].str.slice(1).cast(pl.Int64).to_numpy().astype(float)
