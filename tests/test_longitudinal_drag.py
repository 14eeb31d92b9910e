"""The drag of the Kirchhoff stall (``C_D = CD0 + CD_k C_L(alpha, x)^2 + CD_x (1 - x)``), fitted
along the output-error state, against statsmodels (peer library) and a known truth.

The records are synthetic: the truth's separation state and Kirchhoff lift come from the
``scipy.signal.lfilter`` peer of the discretised ODE (``test_longitudinal.py``), the body-axis
coefficients from the wind-axis ones by the rotation through alpha; the peer regression uses
the separation state of the *fitted* output-error parameters, integrated by the same peer.
"""

from __future__ import annotations

import math

import numpy as np
import polars as pl
import statsmodels.api as sm
from scipy.signal import lfilter, lfilter_zi

from _stall_pulls import stall_pull
from aerodelta import _core
from aerodelta.longitudinal import DRAG_PARAMS, PARAMS, fit_kirchhoff, measured_drag, measured_lift

TRUTH_DRAG = {"CD0": 0.04, "CD_k": 0.045, "CD_x": 0.32}


def _peer_state(p: dict[str, float], t: np.ndarray, a: np.ndarray, ad: np.ndarray):
    """Separation point and Kirchhoff lift by ``lfilter`` (first-order hold, fixed step)."""
    h = t[1] - t[0]
    r = h / p["tau1"]
    e = math.exp(-r)
    g = 1.0 - (1.0 - e) / r
    u = 0.5 * (1.0 - np.tanh(p["a1"] * (a - p["tau2"] * ad - p["alpha_star"])))
    b, den = [g, 1.0 - e - g], [1.0, -e]
    x, _ = lfilter(b, den, u, zi=lfilter_zi(b, den) * u[0])
    cl = p["CL_alpha"] * (a - p["alpha0"]) * ((1.0 + np.sqrt(np.clip(x, 0.0, None))) / 2.0) ** 2
    cm = p["Cm0"] + p["Cm_alpha"] * a + p["Cm_x"] * (1.0 - x)
    return x, cl, cm


def _records(k: int, seed: int, noise: float) -> pl.DataFrame:
    """``k`` stall maneuvers at flap 10 with the truth's lift, pitch and drag, body axes."""
    rng = np.random.default_rng(seed)
    truth = _core.kirchhoff_truth_params(10.0)
    frames = []
    for m in range(k):
        t, a_deg, ad_deg = stall_pull(rng)
        n = t.size
        a, ad = np.radians(a_deg), np.radians(ad_deg)
        x, cl, cm = _peer_state(truth, t, a, ad)
        cd = TRUTH_DRAG["CD0"] + TRUTH_DRAG["CD_k"] * cl**2 + TRUTH_DRAG["CD_x"] * (1.0 - x)
        # coloured measurement noise per maneuver (AR(1), phi 0.9)
        e = lfilter([1.0], [1.0, -0.9], rng.standard_normal((3, n)), axis=1) * noise * 0.44
        cl, cd, cm = cl + e[0], cd + e[1], cm + 0.3 * e[2]
        ca, sa = np.cos(a), np.sin(a)
        frames.append(
            pl.DataFrame(
                {
                    "maneuver_id": f"m{m:02d}",
                    "t": t,
                    "alpha_deg": a_deg,
                    "alphadot_dps": ad_deg,
                    "flap_deg": 10.0,
                    "CX_meas": -cd * ca + cl * sa,
                    "CZ_meas": -cl * ca - cd * sa,
                    "Cm_meas": cm,
                }
            )
        )
    return pl.concat(frames)


def test_body_axes_back_to_lift_and_drag() -> None:
    data = _records(1, 3, noise=0.0)
    truth = _core.kirchhoff_truth_params(10.0)
    t = data["t"].to_numpy()
    a, ad = np.radians(data["alpha_deg"].to_numpy()), np.radians(data["alphadot_dps"].to_numpy())
    x, cl, _ = _peer_state(truth, t, a, ad)
    cd = TRUTH_DRAG["CD0"] + TRUTH_DRAG["CD_k"] * cl**2 + TRUTH_DRAG["CD_x"] * (1.0 - x)
    np.testing.assert_allclose(measured_lift(data), cl, atol=1e-12)
    np.testing.assert_allclose(measured_drag(data), cd, atol=1e-12)
    # thrust along body x is taken off C_X, as for the lift
    ct = 0.05
    thrusting = data.with_columns(
        (pl.col("CX_meas") + ct).alias("CX_meas"), ct_left=pl.lit(ct / 2), ct_right=pl.lit(ct / 2)
    )
    np.testing.assert_allclose(measured_drag(thrusting), cd, atol=1e-12)


def test_drag_fit_equals_statsmodels_along_the_fitted_state() -> None:
    data = _records(8, 11, noise=0.01)
    res = fit_kirchhoff(data, known="none")
    ff = res[10.0]
    d = ff.drag
    assert d is not None and d.n_maneuvers == 8 and d.n_samples == data.height
    # the peer: the fitted output-error parameters' state by lfilter, statsmodels OLS
    xs, zs, gs = [], [], []
    for k, (_, g) in enumerate(data.group_by("maneuver_id", maintain_order=True)):
        t = g["t"].to_numpy()
        a = np.radians(g["alpha_deg"].to_numpy())
        ad = np.radians(g["alphadot_dps"].to_numpy())
        x, cl, _ = _peer_state(ff.params, t, a, ad)
        xs.append(np.column_stack([np.ones(t.size), cl**2, 1.0 - x]))
        zs.append(measured_drag(g))
        gs.append(np.full(t.size, k))
    X, z, groups = np.concatenate(xs), np.concatenate(zs), np.concatenate(gs)
    peer = sm.OLS(z, X).fit()
    est = np.array([d.params[n] for n in DRAG_PARAMS])
    np.testing.assert_allclose(est, peer.params, rtol=0, atol=1e-9)
    conv = np.array([d.std_err_conventional[n] for n in DRAG_PARAMS])
    np.testing.assert_allclose(conv, peer.bse, rtol=1e-6)
    # cluster-robust: CR2 is CR1 (statsmodels' cluster) without G/(G-1), plus the leverage
    # correction; with 8 balanced maneuvers the two lie within 25 % of each other
    cr1 = peer.get_robustcov_results(cov_type="cluster", groups=groups).bse
    cr2 = np.array([d.std_err_cluster[n] for n in DRAG_PARAMS])
    np.testing.assert_allclose(cr2, cr1, rtol=0.25)

    assert all(0 < d.dof[n] <= 7 + 1e-9 for n in DRAG_PARAMS)
    # near the truth: within 4 cluster-robust errors
    for n in DRAG_PARAMS:
        assert abs(d.params[n] - TRUTH_DRAG[n]) < 4 * d.std_err[n], (n, d.params[n], d.std_err[n])
    assert "delta method" in d.note


def test_drag_rows_prediction_and_opting_out() -> None:
    data = _records(6, 5, noise=0.005)
    res = fit_kirchhoff(data, known="none")
    summ = res.summary()
    drag_rows = summ.filter(pl.col("parameter").is_in(list(DRAG_PARAMS)))
    assert drag_rows.height == 3 and drag_rows["std_err_cluster"].is_finite().all()
    d = res[10.0].drag
    assert d is not None
    np.testing.assert_array_equal(
        drag_rows["std_err_total"].to_numpy(), [d.std_err[n] for n in DRAG_PARAMS]
    )
    np.testing.assert_array_equal(
        drag_rows["std_err_cluster"].to_numpy(), [d.std_err_cluster[n] for n in DRAG_PARAMS]
    )
    assert summ.filter(pl.col("parameter") == "tau1")["std_err_cluster"].is_nan().all()
    assert summ.filter(pl.col("parameter") == "tau1")["std_err_total"].is_nan().all()
    pred = res.predict(data, known="none")
    ff = res[10.0]
    # the prediction is the drag model along the fitted state (no noise model): close to the
    # measured drag and exactly the fitted polar at the state it integrates
    cd_meas = measured_drag(data)
    resid = cd_meas - pred["CD_model"].to_numpy()
    assert float(np.sqrt(np.mean(resid**2))) < 3 * 0.005
    x = pred["x_sep"].to_numpy()
    cl = pred["CL_model"].to_numpy()
    p = ff.drag.params if ff.drag is not None else {}
    np.testing.assert_allclose(
        pred["CD_model"].to_numpy(), p["CD0"] + p["CD_k"] * cl**2 + p["CD_x"] * (1 - x), atol=1e-12
    )
    none = fit_kirchhoff(data, known="none", fit_cd=False)
    assert none[10.0].drag is None
    assert not none.summary()["parameter"].is_in(list(DRAG_PARAMS)).any()
    assert none.predict(data, known="none")["CD_model"].is_nan().all()
    # the output-error fit itself is the same with or without the drag
    assert none[10.0].params == ff.params
    assert set(PARAMS) <= set(ff.params)


def test_the_state_uncertainty_is_carried_by_the_delta_method() -> None:
    """``DragFit.cov`` is the CR2 covariance plus ``J V J'``: ``V`` the output-error fit's
    coloured covariance, ``J`` the derivative of the drag's least squares in the output-error
    parameters, here by a peer (statsmodels OLS on ``lfilter`` regressors, central differences
    of 1e-4 of each parameter's error)."""
    data = _records(8, 21, noise=0.01)
    ff = fit_kirchhoff(data, known="none")[10.0]
    d = ff.drag
    assert d is not None
    groups = list(data.group_by("maneuver_id", maintain_order=True))
    z = np.concatenate([measured_drag(g) for _, g in groups])

    def beta(p: dict[str, float]) -> np.ndarray:
        xs = []
        for _, g in groups:
            t = g["t"].to_numpy()
            a = np.radians(g["alpha_deg"].to_numpy())
            ad = np.radians(g["alphadot_dps"].to_numpy())
            x, cl, _ = _peer_state(p, t, a, ad)
            xs.append(np.column_stack([np.ones(t.size), cl**2, 1.0 - x]))
        return sm.OLS(z, np.concatenate(xs)).fit().params

    v = np.asarray(ff.cov_colored)
    jac = np.zeros((3, len(PARAMS)))
    for j, name in enumerate(PARAMS):
        se = math.sqrt(v[j, j])
        if se == 0.0:
            continue
        h = 1e-4 * se
        up, dn = dict(ff.params), dict(ff.params)
        up[name] += h
        dn[name] -= h
        jac[:, j] = (beta(up) - beta(dn)) / (2.0 * h)
    expected = d.cov_cluster + jac @ v @ jac.T
    np.testing.assert_allclose(d.cov, expected, rtol=1e-3)
    # the state's share is material for the wake's drag, whose regressor 1 - x is the state
    share = 1.0 - np.diag(d.cov_cluster) / np.diag(d.cov)
    assert share[2] > 0.01, share


def test_drag_intervals_cover_over_noise_seeds() -> None:
    """Over 30 noise seeds (AR(1) noise, 8 maneuvers), the 95 % t intervals of the total errors
    hold the truth in at least 26 for every parameter, and the standardised errors spread by
    0.7-1.5 (neither liberal nor far too wide)."""
    from scipy import stats  # noqa: PLC0415

    z: dict[str, list[float]] = {n: [] for n in DRAG_PARAMS}
    cover = dict.fromkeys(DRAG_PARAMS, 0)
    for seed in range(300, 330):
        d = fit_kirchhoff(_records(8, seed, noise=0.01), known="none")[10.0].drag
        assert d is not None
        for n in DRAG_PARAMS:
            e = d.params[n] - TRUTH_DRAG[n]
            z[n].append(e / d.std_err[n])
            cover[n] += abs(e) <= stats.t.ppf(0.975, d.dof[n]) * d.std_err[n]
    for n in DRAG_PARAMS:
        assert cover[n] >= 26, (n, cover[n])
        assert 0.7 < float(np.std(z[n])) < 1.5, (n, np.std(z[n]))
