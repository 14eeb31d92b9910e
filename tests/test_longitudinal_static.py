"""Output error on static aerodynamics (no flow-separation lag): the lags are reported not
identified and the static curves agree with equation error (issue 20; docs/longitudinal.md,
"Static tables: the JSBSim check").

Synthetic records carry the Kirchhoff static curves (``x = x0(alpha)``, no lag) plus seeded
noise; the same histories passed through the lagged model are the control that the lags are
still identified when present. A small JSBSim campaign (skipped without jsbsim) checks the
same on an aircraft with static tables.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from _stall_pulls import HZ, stall_pull
from aerodelta import _core
from aerodelta.cli import main
from aerodelta.longitudinal import (
    PARAMS,
    TAU1_MIN_S,
    binned_static_curve,
    fit_kirchhoff,
    static_curves,
)


def _frame(lagged: bool, seed: int, k: int = 8) -> tuple[pl.DataFrame, dict[str, float]]:
    """Stall-like pulls through the break (6 deg to 21-25 deg and back, with oscillations);
    C_L, C_m from the Kirchhoff model at flap 10 of the built-in truth, with its lags
    (``lagged``) or static (``x = x0(alpha)``), plus Gaussian noise (0.01 in C_L, 0.003 in
    C_m)."""
    truth = _core.kirchhoff_truth_params(10.0)
    rng = np.random.default_rng(seed)
    parts = []
    for i in range(k):
        t, a_deg, ad_deg = stall_pull(rng)
        n = t.size
        a = np.radians(a_deg)
        if lagged:
            _, cl, cm, _, _ = _core.kirchhoff_outputs(truth, t, a, np.radians(ad_deg))
        else:
            c = static_curves(truth, a_deg)
            cl, cm = c["CL"], c["Cm"]
        cl = cl + rng.normal(0.0, 0.01, n)
        cm = cm + rng.normal(0.0, 0.003, n)
        parts.append(
            pl.DataFrame(
                {
                    "maneuver_id": [f"m{i:02d}"] * n,
                    "t": t,
                    "alpha_deg": a_deg,
                    "alphadot_dps": ad_deg,
                    "flap_deg": np.full(n, 10.0),
                    # C_L = -C_Z cos(alpha) + C_X sin(alpha)
                    "CX_meas": cl * np.sin(a),
                    "CZ_meas": -cl * np.cos(a),
                    "Cm_meas": cm,
                }
            )
        )
    return pl.concat(parts), truth


def test_static_curves_against_the_engine_and_monte_carlo() -> None:
    p = _core.kirchhoff_truth_params(15.0)
    grid = np.linspace(0.0, 40.0, 40001)
    c = static_curves(p, grid)
    a_max, cl_max = _core.kirchhoff_cl_max(p)
    i = int(np.argmax(c["CL"]))
    assert grid[i] == pytest.approx(math.degrees(a_max), abs=2e-3)
    assert c["CL"][i] == pytest.approx(cl_max, rel=1e-8)  # grid step 1e-3 deg
    # the delta-method bands against draws from the covariance (seeded)
    rng = np.random.default_rng(7)
    th = np.array([p[n] for n in PARAMS])
    sd = np.array([0.0, 0.0, 0.002, 0.5, 0.05, 0.002, 0.002, 0.01, 0.005])
    corr = np.eye(9)
    corr[2, 3] = corr[3, 2] = 0.5
    cov = corr * np.outer(sd, sd)
    alpha = np.array([5.0, 15.0, 20.0, 25.0])
    c = static_curves(p, alpha, cov)
    draws = rng.multivariate_normal(th, cov, size=4000)
    mc = np.array([static_curves(dict(zip(PARAMS, d, strict=True)), alpha)["CL"] for d in draws])
    np.testing.assert_allclose(c["CL_se"], mc.std(axis=0), rtol=0.1)
    with pytest.raises(Exception, match="cov is"):
        static_curves(p, alpha, np.eye(3))


def test_binned_static_curve_is_the_cluster_robust_mean() -> None:
    # two maneuvers in one bin: means 1 (3 samples) and 2 (1 sample)
    f = pl.DataFrame(
        {
            "maneuver_id": ["a", "a", "a", "b"],
            "t": [0.0, 0.02, 0.04, 0.0],
            "alpha_deg": [10.1, 9.9, 10.2, 10.0],
            "alphadot_dps": [0.0] * 4,
            "flap_deg": [0.0] * 4,
            "CX_meas": [0.0] * 4,
            "CZ_meas": [-1.0, -1.0, -1.0, -2.0],
            "Cm_meas": [0.1, 0.2, 0.3, 0.0],
        }
    )
    b = binned_static_curve(f, min_samples=1)
    assert b.height == 1 and b["n"][0] == 4 and b["n_maneuvers"][0] == 2
    a = np.radians(f["alpha_deg"].to_numpy())
    cl = np.cos(a) * np.array([1.0, 1.0, 1.0, 2.0])
    mean = cl.mean()
    ma, mb = cl[:3].mean(), cl[3]
    se = math.sqrt(2.0 * ((3 * (ma - mean)) ** 2 + (mb - mean) ** 2)) / 4.0
    assert b["CL"][0] == pytest.approx(mean, rel=1e-12)
    assert b["CL_se"][0] == pytest.approx(se, rel=1e-12)
    assert b["Cm"][0] == pytest.approx(0.15, rel=1e-12)
    assert b["alpha_mean_deg"][0] == pytest.approx(10.05, rel=1e-12)
    assert binned_static_curve(f).height == 0  # under 20 samples
    with pytest.raises(Exception, match="bin_deg"):
        binned_static_curve(f, bin_deg=0.0)


def test_static_records_leave_the_lags_unidentified_and_agree_with_equation_error() -> None:
    data, truth = _frame(lagged=False, seed=31)
    ff = fit_kirchhoff(data, known="none")[10.0]
    assert not ff.tau_identified
    assert ff.note.startswith("tau1, tau2 not identified")
    assert ff.params["tau1"] == TAU1_MIN_S and ff.params["tau2"] == 0.0
    assert math.isnan(ff.std_err["tau1"]) and math.isnan(ff.std_err_colored["tau2"])
    assert ff.tau_free["tau1"] + ff.tau_free["tau2"] <= 0.5 / HZ  # half a sample
    # 0 inside the restart's bound of the lag sum (which the data do fix)
    assert ff.tau_free["tau_sum_se_colored"] < 0.05
    # the static curves against the truth and against the model-free equation error
    assert abs(ff.alpha_star_deg - math.degrees(truth["alpha_star"])) < 0.5
    bins = binned_static_curve(data)
    grid = bins["alpha_mean_deg"].to_numpy()
    oe = static_curves(ff.params, grid, ff.cov_colored)
    tr = static_curves(truth, grid)
    for c in ("CL", "Cm"):
        assert np.all(np.abs(oe[c] - tr[c]) <= 4.0 * oe[f"{c}_se"] + 1e-4), c
        band = 1.96 * np.hypot(oe[f"{c}_se"], bins[f"{c}_se"].to_numpy())
        inside = np.abs(oe[c] - bins[c].to_numpy()) <= band
        assert inside.mean() >= 0.9, (c, inside.mean())


def test_lagged_records_still_identify_the_lags() -> None:
    data, truth = _frame(lagged=True, seed=31)
    ff = fit_kirchhoff(data, known="none")[10.0]
    assert ff.tau_identified and ff.note == "" and ff.tau_free == {}
    for n in ("tau1", "tau2"):
        assert abs(ff.params[n] - truth[n]) < 0.15 * truth[n], n


def test_held_lags_keep_the_engine_error() -> None:
    # the fallback applies only with both lags free: held by the caller, no convergence
    # stays an error naming the flap
    data, _ = _frame(lagged=False, seed=32, k=4)
    with pytest.raises(Exception, match="flap 10 deg: output-error fit: did not converge"):
        fit_kirchhoff(data, known="none", fixed=["tau2"], max_iter=2)


def test_jsbsim_f15_static_tables(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip(
        "jsbsim", reason="jsbsim is not installed (pip install 'aerodelta[jsbsim]')"
    )
    os.environ.setdefault("JSBSIM_DEBUG", "0")
    from aerodelta.fit import model_frame  # noqa: PLC0415
    from aerodelta.ingest import ingest  # noqa: PLC0415
    from aerodelta.jsbsim_campaign import generate_jsbsim_campaign  # noqa: PLC0415

    camp = tmp_path / "f15"
    generate_jsbsim_campaign(camp, aircraft="f15", seed=1, size=2)
    data = model_frame(ingest(camp, progress=False).data)
    res = fit_kirchhoff(data, known="none")
    ff = res[0.0]
    assert not ff.tau_identified, ff
    assert res.notes[0.0] == ff.note
    bins = binned_static_curve(data)
    oe = static_curves(ff.params, bins["alpha_mean_deg"].to_numpy(), ff.cov_colored)
    band = 1.96 * np.hypot(oe["CL_se"], bins["CL_se"].to_numpy())
    inside = np.abs(oe["CL"] - bins["CL"].to_numpy()) <= band
    assert inside.mean() >= 0.9, inside
    # the command line prints the note after the table
    assert main(["longitudinal", str(camp), "--known", "none", "--no-progress"]) == 0
    assert "flap 0: tau1, tau2 not identified" in capsys.readouterr().out


def test_evidence_row_says_the_lags_are_not_identified(tmp_path: Path) -> None:
    # the built-in aircraft without its Kirchhoff stall has static longitudinal aerodynamics:
    # the evidence pack's longitudinal row gives the fit's "not identified" note per flap, not a
    # bound of NaN
    import aerodelta as ad  # noqa: PLC0415
    from aerodelta.evidence.matrix import assess  # noqa: PLC0415

    camp = tmp_path / "camp"
    ad.generate_campaign(camp, seed=41, size="quick", progress=False)
    data = ad.ingest(camp, compat=False, progress=False).data
    row = next(r for r in assess(data, replay=False).rows if r.key == "longitudinal")
    assert row.status == "shown"
    assert row.detail.count("tau1, tau2 not identified") == data["flap_deg"].n_unique()
    assert "nan" not in row.detail
