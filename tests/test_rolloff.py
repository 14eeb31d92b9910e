"""Stochastic roll-off (thesis Section 3.4.3): runtime draws against their configuration
(scipy tests), interval formulas against scipy, Eq. 3.20, and detection on a virtual campaign
against the injected truth events (issue 6 checks)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from scipy import stats

import aerodelta as ad
import aerodelta.rolloff as ro
from aerodelta.fit import model_frame, qualified_coefficients


def test_python_draws_equal_engine_draws_for_the_same_seed() -> None:
    a = ro.sample_draws(None, 10.0, seed=7, n=500, stream=4)
    b = ad.rolloff_draws(10.0, seed=7, n=500, stream=4)
    assert a.equals(b)
    c = ro.sample_draws(None, 10.0, seed=8, n=500, stream=4)
    assert not a.equals(c)


def test_1e5_draws_reproduce_the_configuration() -> None:
    cfg = ro.default_config()
    cfg["flaps"][2]["p_right"] = 0.63
    cfg["alpha_std_deg"] = 0.9
    cfg["magnitude_cv"] = 0.3
    d = ro.sample_draws(cfg, 10.0, seed=1234, n=100_000)
    right = int((d["sign"] > 0).sum())
    assert stats.binomtest(right, 100_000, 0.63).pvalue > 0.001
    # magnitude factor ~ N(1, cv^2) (the clip at 0 is 4 sigma away): chi-square variance test
    k = d["factor"].to_numpy()
    n = k.size
    chi = (n - 1) * k.var(ddof=1) / 0.3**2
    p_var = 2 * min(stats.chi2.cdf(chi, n - 1), stats.chi2.sf(chi, n - 1))
    assert p_var > 0.001, k.std()
    s = d["alpha_shift_deg"].to_numpy()
    chi = (n - 1) * s.var(ddof=1) / 0.9**2
    p_a = 2 * min(stats.chi2.cdf(chi, n - 1), stats.chi2.sf(chi, n - 1))
    assert p_a > 0.001, s.std()
    assert stats.kstest(s / 0.9, "norm").pvalue > 0.001
    expected_peak = d["sign"] * d["factor"] * cfg["flaps"][2]["magnitude"]
    np.testing.assert_allclose(d["peak"].to_numpy(), expected_peak.to_numpy(), rtol=1e-14)


def test_interval_formulas_match_scipy() -> None:
    for p in (0.025, 0.5, 0.975):
        assert ro.normal_ppf(p) == pytest.approx(stats.norm.ppf(p), abs=1e-6)
    for df in (13, 20, 60):
        for p in (0.025, 0.975):
            assert ro.chi2_ppf(p, df) == pytest.approx(stats.chi2.ppf(p, df), rel=5e-3)
    lo, hi = ro.wilson_interval(9, 16)
    ref = stats.binomtest(9, 16).proportion_ci(0.95, method="wilson")
    assert (lo, hi) == pytest.approx((ref.low, ref.high), abs=1e-6)
    rng = np.random.default_rng(3)
    a = rng.normal(17.5, 1.3, 17)
    ev = pl.DataFrame(
        {
            "flap_deg": [5.0] * 17,
            "alpha_onset_deg": a,
            "alpha_peak_deg": a + 0.9,
            "peak": rng.normal(0.015, 0.003, 17) * np.where(np.arange(17) % 3 == 0, -1, 1),
            "direction": np.where(np.arange(17) % 3 == 0, -1, 1).astype(np.int8),
            "accepted": [True] * 17,
        }
    )
    s = ro.rolloff_statistics(ev).row(0, named=True)
    t = stats.t.interval(0.95, 16, loc=a.mean(), scale=a.std(ddof=1) / math.sqrt(17))
    assert (s["alpha_mean_lo"], s["alpha_mean_hi"]) == pytest.approx(t, rel=1e-9)
    v = a.var(ddof=1)
    ref_sd = (
        math.sqrt(16 * v / stats.chi2.ppf(0.975, 16)),
        math.sqrt(16 * v / stats.chi2.ppf(0.025, 16)),
    )
    assert (s["alpha_std_lo"], s["alpha_std_hi"]) == pytest.approx(ref_sd, rel=5e-3)
    assert (s["n_right"], s["n_left"]) == (11, 6)
    cfg = ro.config_from_statistics(ro.rolloff_statistics(ev))
    assert cfg["flaps"][0]["mean_alpha_deg"] == pytest.approx(a.mean() + 0.9)
    assert cfg["alpha_std_deg"] == pytest.approx(a.std(ddof=1))
    ro.sample_draws(cfg, 5.0, seed=1, n=10)  # the engine accepts it


def test_dynamic_roll_closed_form() -> None:
    # level (theta = 0): phidot = p; phi' = phi + phidot (Eq. 3.20)
    phidot = ro.euler_roll_rate([10.0], [5.0], [3.0], [30.0], [0.0])
    assert phidot[0] == pytest.approx(10.0)
    th = 10.0
    phidot = ro.euler_roll_rate([10.0], [5.0], [3.0], [30.0], [th])
    ref = 10.0 + (5 * 0.5 + 3 * math.sqrt(3) / 2) * math.tan(math.radians(th))
    assert phidot[0] == pytest.approx(ref)
    assert ro.dynamic_roll([5.0], [-12.0])[0] == pytest.approx(-7.0)
    d = pl.DataFrame(
        {
            "maneuver_id": ["a"] * 3 + ["b"] * 3,
            "kind": ["straight"] * 6,
            "flap_deg": [0.0] * 6,
            "phi_deg": [1.0, -25.0, 3.0, 2.0, 4.0, -19.0],
            "p_dps": [0.0] * 6,
        }
    )
    m = ro.max_roll_straight_stalls(d)
    assert m["max_roll_deg"].to_list() == [25.0, 19.0]
    assert m["passed"].to_list() == [False, True]


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("rolloff")
    out = {}
    for name, on in (("on", True), ("off", False)):
        out[name] = base / name
        # nominal pilot excitation: stick noise throughout, doublets except in a straight
        # stall's last 6 deg before the stall (the pilot holds the controls there)
        ad.generate_campaign(out[name], effects="none", seed=21, size=2, rolloff=on)
    return out


def test_detection_recall_and_false_rate_on_a_virtual_campaign(
    campaigns: dict[str, Path],
) -> None:
    data = ad.ingest(campaigns["on"], compat=False, progress=False).data
    # the residual of the qualified model, as the issue prescribes where a model exists: on
    # the raw C_l the roll-damping moment that follows a small roll-off (|ΔC_l| 0.005-0.007)
    # can outweigh it and be reported with the opposite direction (2 of 19 here)
    qual = qualified_coefficients(model_frame(data))["Cl_qual"].to_numpy()
    ev = ro.detect_rolloff(data, residual=data["Cl_meas"].to_numpy() - qual)
    sc = ro.score_detection(ev, campaigns["on"])
    n_inj, found, false, matched = sc["injected"], sc["found"], sc["false"], sc["matched"]
    print(f"injected {n_inj}, found {found}, accepted {sc['accepted']}, false {false}")
    print(sc["missed"])
    assert n_inj >= 10
    assert found >= 0.9 * n_inj
    assert sc["false_rate"] <= 0.1
    # the estimates agree with the injected spike (one draw per stall, so one spike: its
    # largest value): direction always, size within noise
    inj_a = matched["peak_true"].to_numpy()
    assert (np.sign(matched["peak"].to_numpy()) == np.sign(inj_a)).all()
    rel = np.abs(matched["peak"].to_numpy()) / np.abs(inj_a)
    print("detected / injected peak:", np.round(rel, 3))
    # statistics: the right-roll probability's Wilson interval holds the configured 0.58, and
    # the t-interval of the detected/injected magnitude ratio holds 1
    st = ro.rolloff_statistics(ev.with_columns(pl.lit(0.0).alias("flap_deg")))
    row = st.row(0, named=True)
    print(row)
    assert row["p_right_lo"] <= 0.58 <= row["p_right_hi"], row
    # pooled over flaps (means differ by < 1 deg) the alpha spread's interval holds 1.31 deg
    assert row["alpha_std_lo"] <= 1.31 <= row["alpha_std_hi"], row
    ratio = pl.DataFrame(
        {
            "flap_deg": np.zeros(rel.size),
            "alpha_onset_deg": rel,
            "peak": rel,
            "direction": np.ones(rel.size, np.int8),
        }
    )
    r = ro.rolloff_statistics(ratio).row(0, named=True)
    assert r["alpha_mean_lo"] <= 1.0 <= r["alpha_mean_hi"], r


def test_no_rolloff_no_events_beyond_the_false_rate(campaigns: dict[str, Path]) -> None:
    data = ad.ingest(campaigns["off"], compat=False, progress=False).data
    # the qualified model's residual, as with the roll-off on (on the raw C_l the pilot's stick
    # noise, up to the allowed 4 deg of aileron, moves C_l by as much as a roll-off)
    qual = qualified_coefficients(model_frame(data))["Cl_qual"].to_numpy()
    ev = ro.detect_rolloff(data, residual=data["Cl_meas"].to_numpy() - qual)
    n_stalls = data.filter(pl.col("kind") == "straight")["maneuver_id"].n_unique()
    assert ev["accepted"].sum() <= 0.1 * n_stalls, ev.filter(pl.col("accepted"))
    m = ro.max_roll_straight_stalls(data)
    assert m.height == n_stalls


def test_monte_carlo_draws_roll_offs_of_the_configured_size() -> None:
    mc = ro.monte_carlo(4, seed=3, flap_deg=15.0)
    assert mc.height == 4
    assert mc["maneuver_id"].str.contains("_f15_straight_").all()
    # every peak is a draw of s k A_f with A_f = 0.02315 (Table 3.2, 15 deg flap), k ~ N(1, 0.225)
    big = mc["peak"].abs().to_numpy()
    assert (big < 0.02315 * (1 + 5 * 0.225)).all(), big
    assert (mc["max_bank_deg"] >= 0).all()


def test_truncated_normal_fit_reduces_to_t_and_chi2_and_covers_under_censoring() -> None:
    # no censoring nor truncation: the Student t and chi-square intervals (scipy)
    rng = np.random.default_rng(11)
    x = rng.normal(17.0, 1.3, 12)
    f = ro.truncated_normal_fit(x, -np.inf, np.inf)
    t = stats.t.interval(0.95, 11, loc=x.mean(), scale=x.std(ddof=1) / math.sqrt(12))
    assert (f["mean_lo"], f["mean_hi"]) == pytest.approx(t, rel=1e-6)
    sd = x.std(ddof=1)
    assert f["std"] == pytest.approx(sd, rel=1e-5)
    ref = (
        sd * math.sqrt(11 / stats.chi2.ppf(0.975, 11)),
        sd * math.sqrt(11 / stats.chi2.ppf(0.025, 11)),
    )
    assert (f["std_lo"], f["std_hi"]) == pytest.approx(ref, rel=5e-3)
    # the campaign's structure: onsets N(16.2, 1.31^2) censored below 15.5 deg (the draw at
    # the 15 deg crossing), truncated above at 17.1 deg for half the stalls (stick pusher) and
    # 21 deg for the others; 10 stalls kept: the 95 % intervals hold the truth about 95 % of
    # the time, where the plain sample statistics are biased
    cover_m = cover_s = 0
    naive = []
    reps = 120
    for _ in range(reps):
        y = rng.normal(16.2, 1.31, 60)
        up = np.where(rng.random(60) < 0.5, 17.1, 21.0)
        keep = y <= up
        y, up = y[keep][:10], up[keep][:10]
        obs = np.where(y < 15.5, 15.0 + 0.5 * rng.random(10), y)  # censored: read near 15
        f = ro.truncated_normal_fit(obs, 15.5, up, censor_lower=True)
        cover_m += f["mean_lo"] <= 16.2 <= f["mean_hi"]
        cover_s += f["std_lo"] <= 1.31 <= f["std_hi"]
        naive.append((obs.mean(), obs.std(ddof=1)))
    print("coverage", cover_m / reps, cover_s / reps, "naive", np.mean(naive, axis=0))
    assert cover_m >= 0.88 * reps and cover_s >= 0.88 * reps
    assert np.mean(naive, axis=0)[1] < 1.1  # the censored sample's spread is too small


def test_statistics_of_detected_events_use_complete_spikes() -> None:
    # two flaps of hand-made detected events: partial spikes (the stall turned back at the
    # peak, alpha_max - alpha_peak < 0.5 deg) and cut ones (onset below 15.5 deg) are left out
    # of the magnitude; every event counts for the direction
    ev = pl.DataFrame(
        {
            "flap_deg": [0.0] * 6,
            "alpha_onset_deg": [16.0, 16.5, 17.0, 16.8, 15.1, 16.2],
            "alpha_peak_deg": [16.9, 17.4, 17.9, 17.7, 15.6, 17.1],
            "alpha_max_deg": [21.0, 22.0, 18.8, 21.5, 18.5, 17.2],
            "peak": [0.010, -0.012, 0.011, 0.009, 0.004, 0.003],
            "direction": [1, -1, 1, 1, 1, 1],
            "accepted": [True] * 6,
        }
    )
    s = ro.rolloff_statistics(ev).row(0, named=True)
    assert (s["n"], s["n_onset"], s["n_complete"]) == (6, 5, 4)
    assert s["magnitude_mean"] == pytest.approx(np.mean([0.010, 0.012, 0.011, 0.009]))
    assert (s["n_right"], s["n_left"]) == (5, 1)
    assert s["alpha_method"] == "censored_fit"
    plain = ro.rolloff_statistics(ev, truncation=False).row(0, named=True)
    assert plain["magnitude_mean"] == pytest.approx(np.mean(np.abs(ev["peak"].to_numpy())))
