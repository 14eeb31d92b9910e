"""The Kirchhoff stall model and its output-error fit against scipy (peer library).

The peer integrates the same discretised separation ODE with ``scipy.signal.lfilter`` (the
first-order-hold recursion is a linear filter for a fixed step) and fits it with
``scipy.optimize.least_squares``; the engine uses its own recursion and Levenberg-Marquardt.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from scipy.optimize import least_squares
from scipy.signal import lfilter, lfilter_zi

from aerodelta import _core
from aerodelta.campaign import generate_campaign, simulate_campaign
from aerodelta.cli import main
from aerodelta.exceptions import DataError, InvalidInputError, TooLittleDataError
from aerodelta.fit import model_frame
from aerodelta.ingest import ingest
from aerodelta.longitudinal import PARAMS, fit_kirchhoff, measured_drag, measured_lift, theil

HZ = 50.0


def _truth() -> dict[str, float]:
    return _core.kirchhoff_truth_params(10.0)


def _maneuvers(k: int, seed: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Stall-like alpha histories: a pull through the break and back, with oscillations."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(k):
        n = 1200
        t = np.arange(n) / HZ
        top, f1, amp = rng.uniform(21.0, 25.0), rng.uniform(1.0, 2.5), rng.uniform(0.5, 2.0)
        dur = n / HZ
        s = np.sin(np.pi * t / dur)
        a_deg = 6.0 + (top - 6.0) * s**2 + amp * np.sin(f1 * t)
        ad_deg = (top - 6.0) * 2 * s * np.cos(np.pi * t / dur) * np.pi / dur + amp * f1 * np.cos(
            f1 * t
        )
        out.append((t, np.radians(a_deg), np.radians(ad_deg)))
    return out


def _peer_outputs(
    th: np.ndarray, t: np.ndarray, a: np.ndarray, ad: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    tau1, tau2, a_star, a1, cla, a0, cm0, cma, cmx = th
    h = t[1] - t[0]
    r = h / tau1
    e = math.exp(-r)
    g = 1.0 - (1.0 - e) / r
    u = 0.5 * (1.0 - np.tanh(a1 * (a - tau2 * ad - a_star)))
    b, den = [g, 1.0 - e - g], [1.0, -e]
    x, _ = lfilter(b, den, u, zi=lfilter_zi(b, den) * u[0])
    cl = cla * (a - a0) * ((1.0 + np.sqrt(np.clip(x, 0.0, None))) / 2.0) ** 2
    cm = cm0 + cma * a + cmx * (1.0 - x)
    return cl, cm


def _data(
    truth: dict[str, float], ms: list, noise: float, seed: int
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    rng = np.random.default_rng(seed)
    cls, cms = [], []
    for t, a, ad in ms:
        _, cl, cm, _, _ = _core.kirchhoff_outputs(truth, t, a, ad)
        cls.append(cl + noise * rng.standard_normal(cl.size))
        cms.append(cm + 0.3 * noise * rng.standard_normal(cm.size))
    return cls, cms


def test_engine_outputs_equal_the_lfilter_recursion() -> None:
    truth = _truth()
    th = np.array([truth[n] for n in PARAMS])
    for t, a, ad in _maneuvers(3, 4):
        x, cl, cm, dcl, dcm = _core.kirchhoff_outputs(truth, t, a, ad, sensitivities=True)
        pcl, pcm = _peer_outputs(th, t, a, ad)
        np.testing.assert_allclose(cl, pcl, rtol=0, atol=1e-12)
        np.testing.assert_allclose(cm, pcm, rtol=0, atol=1e-12)
        assert dcl.shape == (t.size, 9) and dcm.shape == (t.size, 9)
        # the static solution at the first sample
        assert (
            abs(
                x[0]
                - 0.5
                * (
                    1
                    - math.tanh(truth["a1"] * (a[0] - truth["tau2"] * ad[0] - truth["alpha_star"]))
                )
            )
            < 1e-15
        )


def test_output_error_matches_scipy_least_squares() -> None:
    truth = _truth()
    ms = _maneuvers(6, 21)
    cls, cms = _data(truth, ms, noise=0.02, seed=5)
    r = _core.output_error_kirchhoff(
        [m[0] for m in ms], [m[1] for m in ms], [m[2] for m in ms], cls, cms
    )
    assert r["converged"]
    est = np.array([r["params"][n] for n in PARAMS])
    # the ML estimate with R estimated is the weighted least-squares estimate with R fixed at
    # the final residual variances: the peer fits that problem from the engine's own start
    w = 1.0 / np.sqrt(np.asarray(r["residual_var"]))

    def resid(th: np.ndarray) -> np.ndarray:
        parts = []
        for (t, a, ad), zl, zm in zip(ms, cls, cms, strict=True):
            pl_, pm = _peer_outputs(th, t, a, ad)
            parts += [(zl - pl_) * w[0], (zm - pm) * w[1]]
        return np.concatenate(parts)

    x0 = np.array([r["start"][n] for n in PARAMS])
    peer = least_squares(resid, x0, method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    assert peer.success
    se = np.asarray(r["std_err"])
    # same optimum to a small fraction of the Cramér-Rao bound
    np.testing.assert_array_less(np.abs(peer.x - est), 0.01 * se)
    # same Cramér-Rao bounds: (J^T J)^-1 of the peer's weighted Jacobian
    jac = peer.jac
    se_peer = np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)))
    np.testing.assert_allclose(se, se_peer, rtol=0.02)
    # and both sit near the truth (noise 0.02 in C_L)
    tru = np.array([truth[n] for n in PARAMS])
    np.testing.assert_array_less(np.abs(est - tru), 4.0 * se)


def test_bounds_cover_the_truth_in_monte_carlo() -> None:
    """Coverage of the conventional Cramér-Rao bounds on white noise (seeds 100-139)."""
    truth = _truth()
    tru = np.array([truth[n] for n in PARAMS])
    ms = _maneuvers(3, 77)
    z = []
    for seed in range(100, 140):
        cls, cms = _data(truth, ms, noise=0.03, seed=seed)
        r = _core.output_error_kirchhoff(
            [m[0] for m in ms], [m[1] for m in ms], [m[2] for m in ms], cls, cms, start=truth
        )
        z.append((np.array([r["params"][n] for n in PARAMS]) - tru) / np.asarray(r["std_err"]))
    zz = np.asarray(z)
    inside = np.mean(np.abs(zz) < 1.96, axis=0)
    # 95 % nominal; with 40 draws a parameter's coverage below 0.8 would be a 4-sigma miss
    assert np.all(inside >= 0.8), dict(zip(PARAMS, inside, strict=True))
    assert np.all(np.abs(zz.std(axis=0) - 1.0) < 0.4), zz.std(axis=0)


def test_bad_inputs_name_the_problem() -> None:
    truth = _truth()
    (t, a, ad), *_ = _maneuvers(1, 3)
    bad = truth | {"tau1": -1.0}
    with pytest.raises(Exception, match="tau1"):
        _core.kirchhoff_outputs(bad, t, a, ad)
    cl = np.full(t.size, 0.5)
    cl[9] = np.nan
    with pytest.raises(Exception, match="maneuver 0: CL row 9"):
        _core.output_error_kirchhoff([t], [a], [ad], [cl])
    with pytest.raises(Exception, match="unknown parameter 'tau3'"):
        _core.output_error_kirchhoff([t], [a], [ad], [cl], fixed=["tau3"])
    pre = np.radians(np.linspace(2.0, 8.0, t.size))
    with pytest.raises(TooLittleDataError):
        _core.output_error_kirchhoff([t], [pre], [ad * 0], [5.2 * pre])


def test_fit_kirchhoff_names_the_maneuver_and_the_flap() -> None:
    n = 300
    a = np.linspace(2.0, 22.0, n)
    frame = pl.DataFrame(
        {
            "maneuver_id": ["m007"] * n,
            "t": np.arange(n) * 0.02,
            "alpha_deg": a,
            "alphadot_dps": np.full(n, 1.0),
            "flap_deg": np.full(n, 5.0),
            "CX_meas": np.zeros(n),
            "CZ_meas": np.where(np.arange(n) == 40, np.nan, -0.09 * a),
            "Cm_meas": np.zeros(n),
        }
    )
    with pytest.raises(InvalidInputError, match=r"flap 5 deg: .*maneuver m007: CL row 40"):
        fit_kirchhoff(frame, known="none")
    with pytest.raises(DataError, match="lack CZ_meas"):
        fit_kirchhoff(frame.drop("CZ_meas"))
    with pytest.raises(DataError, match="no records at flap 10"):
        fit_kirchhoff(frame, flaps=[10.0], known="none")


def test_theil() -> None:
    z = np.array([1.0, 2.0, 3.0])
    assert theil(z, z) == 0.0
    assert theil(z, -z) == pytest.approx(1.0)
    assert math.isnan(theil([], []))
    with pytest.raises(InvalidInputError):
        theil(z, z[:2])


def test_kirchhoff_campaign_truth_and_default_unchanged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plain = simulate_campaign(seed=3, size="quick", only=[0, 1])
    again = simulate_campaign(seed=3, size="quick", only=[0, 1], longitudinal_stall="static")
    for x, y in zip(plain, again, strict=True):
        assert x["record"].equals(y["record"]) and x["truth"].equals(y["truth"])
        assert "x_sep_true" not in x["truth"].columns
    k = simulate_campaign(seed=3, size="quick", only=[0, 1], longitudinal_stall="kirchhoff")
    for m in k:
        tr = m["truth"]
        assert {"x_sep_true", "CL_true", "Cm_true", "CD_true"} <= set(tr.columns)
        x = tr["x_sep_true"].to_numpy()
        assert np.all((x >= 0) & (x <= 1)) and x[0] > 0.99
    # the stall separates the flow (maneuver 1 flies without the pusher, past alpha*)
    assert k[1]["truth"]["x_sep_true"].min() < 0.5
    assert not k[0]["record"].equals(plain[0]["record"])
    with pytest.raises(InvalidInputError, match="longitudinal_stall"):
        simulate_campaign(seed=3, size="quick", only=[0], longitudinal_stall="goman")
    info = generate_campaign(
        tmp_path / "k", seed=3, size="quick", longitudinal_stall="kirchhoff", overwrite=True
    )
    meta = json.loads((info.path / "truth" / "campaign.json").read_text())
    p10 = meta["longitudinal_stall"]["params_by_flap"]["10"]
    assert p10["tau1"] == pytest.approx(_core.kirchhoff_truth_params(10.0)["tau1"])
    assert p10["CD_x"] == pytest.approx(_core.kirchhoff_truth_drag(10.0)["CD_x"])
    # the measured drag of the ingested records (wind axes, thrust off C_X) is the truth's
    # drag (the engine's lift/drag to body-axis rotation) to within the sensors' noise
    data = model_frame(ingest(info.path, progress=False).data)
    truth = pl.concat(
        pl.read_parquet(f).with_columns(pl.lit(f.stem).alias("maneuver_id"))
        for f in sorted((info.path / "truth").glob("*.parquet"))
    ).select("maneuver_id", pl.col("t").round(6), "CD_true", "CL_true")
    both = data.with_columns(
        pl.Series("_cd", measured_drag(data)),
        pl.Series("_cl", measured_lift(data)),
        pl.col("t").round(6),
    ).join(truth, on=["maneuver_id", "t"])
    assert both.height > 0.9 * data.height
    err_d = (both["_cd"] - both["CD_true"]).to_numpy()
    err_l = (both["_cl"] - both["CL_true"]).to_numpy()
    assert abs(float(np.median(err_d))) < 2e-3 and float(np.std(err_d)) < 0.02
    assert abs(float(np.median(err_l))) < 2e-3 and float(np.std(err_l)) < 0.02
    assert meta["spec"]["longitudinal_stall"] == "kirchhoff"
    assert pl.read_csv(info.path / "manifest.csv").height == info.n_maneuvers
    # the command line fits it (all 8 maneuvers of flap 10)
    assert main(["longitudinal", str(info.path), "--flaps", "10", "--format", "json",
                 "--no-progress"]) == 0  # fmt: skip
    rows = {r["parameter"]: r for r in json.loads(capsys.readouterr().out)}
    truth10 = _core.kirchhoff_truth_params(10.0)
    assert rows["tau1"]["estimate"] == pytest.approx(truth10["tau1"], rel=0.3)
    assert rows["alpha_star_deg"]["estimate"] == pytest.approx(
        math.degrees(truth10["alpha_star"]), abs=0.5
    )
    assert rows["tau1"]["std_err_colored"] > 0
    # the drag along the identified state: the separated wake's drag near the truth's
    drag10 = _core.kirchhoff_truth_drag(10.0)
    assert rows["CD_x"]["estimate"] == pytest.approx(drag10["CD_x"], rel=0.3)
    assert rows["CD_x"]["std_err_cluster"] > 0 and math.isnan(rows["tau1"]["std_err_cluster"])
    assert main(["longitudinal", str(info.path), "--flaps", "10", "--no-cd",
                 "--no-progress"]) == 0  # fmt: skip
    text = capsys.readouterr().out
    assert "CD_x" not in text and "tau1" in text
    assert main(["longitudinal", str(info.path), "--flaps", "12", "--no-progress"]) == 1
    assert "no records at flap 12" in capsys.readouterr().err
    # the default campaign is the one before the option: test_campaign_mass.py's stored
    # content digest of generate_campaign(seed=11, size="quick") (NOMINAL_QUICK_11) covers it
