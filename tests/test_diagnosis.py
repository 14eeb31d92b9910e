"""The sim-to-real gap diagnosis (issue 7): the cross-validation algebra against brute force,
the randomization test against scipy, and withheld-effect cases on virtual campaigns whose
truth is known (the harness reads the truth; the diagnosis must not)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import polars as pl
import pytest
from scipy import stats

import aerodelta
from _diagnosis_support import dense_design, toy_rows
from aerodelta.campaign import generate_campaign
from aerodelta.cli import main
from aerodelta.diagnosis import band, cv, select, write_outputs
from aerodelta.diagnosis.core import DiagnoseConfig
from aerodelta.diagnosis.kinds import EntryKinds
from aerodelta.diagnosis.select import SelectionConfig, forward_select
from aerodelta.diagnosis.stochastic import event_columns, event_regressors, refine_centres
from aerodelta.diagnosis.vocabulary import Candidate
from aerodelta.diagnosis.withheld import score_case
from aerodelta.exceptions import DataError
from aerodelta.fit import model_frame, qualified_coefficients
from aerodelta.ingest import ingest


@pytest.fixture(scope="module")
def toy():
    return toy_rows(3, 12, 60)


def test_cross_validation_matches_brute_force_refits(toy):
    y, man, flap, alpha, aero, glob, grid = toy
    design = cv.build_design(y, man, flap, alpha, aero, glob, ["a", "b"], ["g"], grid, 12, 2)
    folds = np.arange(12) % 3
    st = cv.fold_stats(design, folds)
    cols = cv.local_columns(design, ["a", "b"], ["g"])
    sse, _ = cv.heldout_sse(design, st, cols)
    # reference: penalised least squares on the dense design, refitted without each fold
    x = dense_design(y, man, flap, alpha, aero, glob, grid, 2)
    pen = np.zeros((x.shape[1], x.shape[1]))
    p_local = cv.penalty(design)
    kr = grid.n * 2
    for f in range(2):
        idx = np.r_[f * kr + np.arange(kr)]
        pen[np.ix_(idx, idx)] += p_local[f][:kr, :kr]
    for q in range(3):
        tr = folds[man] != q
        beta = np.linalg.solve(x[tr].T @ x[tr] + pen, x[tr].T @ y[tr])
        for m in np.flatnonzero(folds == q):
            rows = man == m
            ref = float(np.sum((y[rows] - x[rows] @ beta) ** 2))
            assert sse[m] == pytest.approx(ref, rel=1e-8, abs=1e-12)


def test_signed_rank_randomization_agrees_with_scipy_wilcoxon():
    rng = np.random.default_rng(5)
    for shift in (0.0, 0.3, 0.6):
        d = rng.normal(shift, 1.0, 30)
        _, p = cv.sign_flip_pvalue(d, 20000, 1)
        ref = stats.wilcoxon(d, alternative="greater", method="exact").pvalue
        assert p == pytest.approx(ref, abs=0.01)


def test_exact_signed_rank_p_matches_scipy_and_full_enumeration():
    """The exact signed-rank p against scipy's exact Wilcoxon (n <= 50) and, for n = 14,
    against all 2^14 sign patterns; far in the tail it goes below any randomization floor."""
    import itertools  # noqa: PLC0415

    rng = np.random.default_rng(12)
    for n, shift in ((9, 0.0), (25, 0.4), (50, 0.7)):
        d = rng.normal(shift, 1.0, n)
        ref = stats.wilcoxon(d, alternative="greater", method="exact").pvalue
        assert cv.signed_rank_p(d, 4000, 1) == pytest.approx(ref, rel=1e-10)
    d = rng.normal(0.2, 1.0, 14)
    ranks = np.empty(14)
    ranks[np.argsort(np.abs(d))] = np.arange(1, 15)
    w = ranks @ np.sign(d)
    exact = np.mean([s @ ranks >= w - 1e-9 for s in itertools.product((-1, 1), repeat=14)])
    assert cv.signed_rank_p(d, 4000, 1) == pytest.approx(exact, rel=1e-12)
    # 200 maneuvers all improving: p = 2^-200, resolved (a randomization floor is 1/(draws+1))
    assert cv.signed_rank_p(np.abs(rng.normal(size=200)) + 0.1, 4000, 1) == pytest.approx(
        2.0**-200, rel=1e-9
    )


def test_small_effect_counts_only_when_most_maneuvers_improve():
    """Between the broad floor (1.5 %) and the effect-size floor (2 %) of the gap, an effect
    passes only if the signed ranks alone pass at alpha/10: the same total gain spread over
    most maneuvers passes, carried by a minority it does not (its sum test alone would)."""
    rng = np.random.default_rng(4)
    cfg = select.SelectionConfig()
    total0 = 1.0

    def step(d: np.ndarray) -> select.Step:
        d = d * (0.018 / d.sum())  # 1.8 % of the gap, under min_shrink, over the broad floor
        t, p = cv.improvement_test(d, cfg.n_perm, 1)
        rank_p = cv.signed_rank_p(d, cfg.n_perm, 3) * 12
        return select.Step(
            None,
            np.zeros(1),
            select.robust_gain(d),
            t,
            min(1.0, 12 * p),
            [],
            rank_p,  # type: ignore[arg-type]
        )

    broad = step(rng.gamma(2.0, 1.0, 200) - 0.4)
    minority = step(np.concatenate([rng.uniform(3.0, 6.0, 30), rng.normal(-0.02, 0.3, 170)]))
    assert broad.p_value < cfg.alpha and minority.p_value < cfg.alpha
    assert broad.gain >= cfg.min_shrink_broad and minority.gain >= cfg.min_shrink_broad
    assert select._passes(broad, cfg, total0)
    assert not select._passes(minority, cfg, total0)
    # the same minority effect at 2.5 % of the gap is reported: the broad rule only covers
    # the band under the effect-size floor
    big = select.Step(None, np.zeros(1), 0.025, minority.statistic, minority.p_value, [], 1.0)  # type: ignore[arg-type]
    assert select._passes(big, cfg, total0)


def test_delayed_controls_are_the_records_shifted_in_time_per_maneuver():
    """The exact delay behind the control-lag regressor: each control channel's value tau
    earlier, within its own maneuver (the first value held before the start); other channels
    untouched; and the rate term the regressor uses is its first-order expansion."""
    from aerodelta.diagnosis.regressors import delayed_controls  # noqa: PLC0415

    t = np.r_[np.arange(0.0, 2.0, 0.02), np.arange(0.0, 1.0, 0.02)]
    man = np.r_[np.zeros(100, dtype=int), np.ones(50, dtype=int)].astype(str)
    da = np.sin(2.0 * t) + (man == "1") * 3.0
    frame = pl.DataFrame({"maneuver_id": man, "t": t, "da_deg": da, "dr_deg": t**2, "p": t})
    out = delayed_controls(frame, 0.1)
    first = man == "0"
    tt = np.maximum(t - 0.1, 0.0)
    np.testing.assert_allclose(out["dr_deg"].to_numpy(), tt**2, atol=2e-4)  # linear interp
    np.testing.assert_allclose(
        out["da_deg"].to_numpy(), np.sin(2.0 * tt) + (~first) * 3.0, atol=1e-3
    )
    assert out["p"].to_list() == frame["p"].to_list()
    assert frame["da_deg"].to_list() == da.tolist()  # the input is not modified
    # the first-order term: x(t - tau) - x(t) ~ -tau * xdot away from the start
    mid = first & (t > 0.5) & (t < 1.9)
    lin = -0.01 * 2.0 * np.cos(2.0 * t[mid])
    got = delayed_controls(frame, 0.01)["da_deg"].to_numpy()[mid] - da[mid]
    # to the second-order term of interpolating between samples, h^2 |x''| / 4 = 4e-4 here
    np.testing.assert_allclose(got, lin, atol=4.5e-4)


def test_profiling_out_per_maneuver_nuisance_matches_ols_with_per_maneuver_columns(toy):
    """Frisch-Waugh-Lovell: the shared parameters fitted on statistics with each maneuver's
    nuisance columns profiled out equal those of one OLS (statsmodels) over the dense design
    with a separate copy of the nuisance columns per maneuver."""
    import statsmodels.api as sm  # noqa: PLC0415

    y, man, flap, alpha, aero, glob, grid = toy
    rng = np.random.default_rng(11)
    # a bump in alpha with a random amplitude per maneuver (a roll-off), only in some
    centre = rng.uniform(3, 7, 12)
    amp = rng.normal(0, 0.5, 12) * (np.arange(12) % 3 != 0)
    u = (alpha - centre[man]) / 0.8
    nuis = np.column_stack([np.exp(-0.5 * u * u), u * np.exp(-0.5 * u * u)])
    nuis[np.arange(12)[man] % 3 == 0] = 0.0  # maneuvers without an event: no columns
    y2 = y + amp[man] * nuis[:, 0]
    full = cv.build_design(
        y2, man, flap, alpha, aero, np.hstack([glob, nuis]), ["a", "b"], ["g", "n0", "n1"],
        grid, 12, 2,
    )  # fmt: skip
    prof = cv.profile_out(full, 2)
    assert prof.global_names == ["g"]
    pen0 = [np.zeros_like(g) for g in cv.penalty(prof)]
    grams = [sum(prof.gram[m] for m in range(12) if prof.man_flap[m] == f) for f in range(2)]
    xtys = [sum(prof.xty[m] for m in range(12) if prof.man_flap[m] == f) for f in range(2)]
    cols = cv.local_columns(prof, ["a", "b"], ["g"])
    th = cv.solve(prof, [g + p for g, p in zip(grams, pen0, strict=True)], xtys, cols)
    # reference: dense design, nuisance columns copied per maneuver
    x = dense_design(y2, man, flap, alpha, aero, glob, grid, 2)
    blocks = np.zeros((y.size, 24))
    for m in range(12):
        rows = man == m
        blocks[rows, 2 * m : 2 * m + 2] = nuis[rows]
    live = np.abs(blocks).sum(axis=0) > 0
    keep = np.abs(x).sum(axis=0) > 0
    res = sm.OLS(y2, np.hstack([x[:, keep], blocks[:, live]])).fit()
    kr = grid.n * 2
    ours = np.concatenate([th[0][:kr], th[1][:kr], th[0][kr:]])[keep]
    np.testing.assert_allclose(ours, res.params[: keep.sum()], rtol=1e-7, atol=1e-9)
    # and the profiled y'y is each maneuver's residual sum of squares on its nuisance alone
    for m in range(12):
        rows = man == m
        n_m = nuis[rows][:, np.abs(nuis[rows]).sum(axis=0) > 0]
        r = y2[rows] - (n_m @ np.linalg.lstsq(n_m, y2[rows], rcond=None)[0] if n_m.size else 0)
        assert prof.yty[m] == pytest.approx(float(r @ r), rel=1e-9)


def test_sum_sign_flip_test_is_exact_and_sees_sparse_improvements():
    """The sum test against its exact distribution (all 2^n sign patterns), and on a sparse
    improvement (a quarter of the maneuvers gain a lot, the rest lose a little) where the
    signed ranks are blind and the combined test is not."""
    import itertools  # noqa: PLC0415

    rng = np.random.default_rng(8)
    d = rng.normal(0.4, 1.0, 12)
    exact = np.mean(
        [float(np.dot(s, d)) >= d.sum() - 1e-12 for s in itertools.product((-1, 1), repeat=12)]
    )
    _, p = cv.sign_flip_sum_pvalue(d, 40000, 3)
    assert p == pytest.approx(exact, abs=0.01)
    sparse = np.concatenate([rng.uniform(0.5, 1.0, 50), -rng.uniform(0.001, 0.01, 150)])
    assert cv.sign_flip_pvalue(sparse, 4000, 1)[1] > 0.5
    z, p_comb = cv.improvement_test(sparse, 4000, 1)
    assert p_comb < 1e-3 and z > 0
    # a clear effect stays significant after a Bonferroni factor of 24 candidates (the far
    # tail is refined with more draws instead of stopping at the 1/4001 floor of the estimate)
    strong = rng.normal(1.0, 1.0, 200)
    assert cv.improvement_test(strong, 4000, 2)[1] * 24 < 0.01
    # under the null both stay calibrated: about 5 % of symmetric samples fall below 0.05
    hits = [cv.improvement_test(rng.normal(0, 1, 40), 1000, i)[1] < 0.05 for i in range(300)]
    assert 0.01 <= np.mean(hits) <= 0.09


def test_alpha_range_is_the_run_around_the_strongest_bin():
    """The interval where an effect acts is the contiguous run of strong bins (a ramp from
    12 deg), not stretched to a distant sparse bin where a noisy fit happens to be large."""
    from aerodelta.diagnosis.core import _alpha_range  # noqa: PLC0415

    alpha = np.concatenate([np.linspace(-4, 22, 26000), np.full(30, -15.5)])
    contrib = np.clip((alpha - 12.0) / 8.0, 0.0, 1.0)
    contrib[-30:] = 0.8  # an isolated bin far below the ramp
    lo, hi = _alpha_range(alpha, contrib)
    # bin [13, 14) holds (alpha - 12)/8 from 0.125 to 0.25: RMS 0.19, under 20 % of the
    # peak bin's 0.94 ([21, 22)); [14, 15) is the first above; 22 deg has a single point
    assert (lo, hi) == (14.0, 22.0)


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    """Quick virtual campaigns (40 maneuvers): null, one aerodynamic and one measurement
    effect withheld from the simulator (the built-in qualified model lacks them)."""
    out = {}
    for name, eff, seed in (
        ("null", "none", 101),
        ("dihedral", "dihedral", 1),
        ("beta_vane_bias", "beta_vane_bias", 2),
    ):
        d = tmp_path_factory.mktemp(name) / "campaign"
        generate_campaign(d, effects=eff, seed=seed, size="quick", rolloff=False)
        out[name] = (d, ingest(d, compat=False, progress=False).data)
    return out


@pytest.fixture(scope="module")
def diagnoses(campaigns):
    return {k: aerodelta.diagnose(data) for k, (_, data) in campaigns.items()}


def test_withheld_aerodynamic_effect_is_the_verdict_where_it_acts(campaigns, diagnoses):
    d = diagnoses["dihedral"]
    assert d.verdict("Cl") == "dihedral"
    assert d.verdict("Cn") == "none" and d.verdict("CY") == "none"
    case = score_case(d, campaigns["dihedral"][0] / "truth", {"dihedral": 1.0})
    assert case.found == {"dihedral": True}
    assert case.false_alarms == []
    # the alpha range where it acts starts where the truth's does (issue floor: 1.5 deg)
    assert case.onset_error_deg["Cl:dihedral"] <= 1.5
    # the held-out gap shrinks nearly as much as adding the true effect exactly would
    assert case.shrink_ratio["Cl"] >= 0.85
    eff = d.result["coefficients"]["Cl"]["effects"][0]
    assert eff["gap_rms_after"] < eff["gap_rms_before"]


def test_withheld_vane_bias_is_named_on_every_coefficient_with_its_size(diagnoses):
    d = diagnoses["beta_vane_bias"]
    for c in ("Cl", "Cn", "CY"):
        assert d.verdict(c) == "beta_vane_bias"
    est = next(e for e in d.result["coefficients"]["CY"]["effects"] if e["rank"] == 1)
    # the campaign's vane reads 1 deg high (design magnitude); the estimate is in deg
    assert est["parameters"]["m_beta_bias"] == pytest.approx(1.0, abs=0.15)


def test_null_campaign_reports_no_significant_effect(diagnoses):
    d = diagnoses["null"]
    for c in ("Cl", "Cn", "CY"):
        assert d.verdict(c) == "none", d.summary()


def test_json_contract_keys(diagnoses, tmp_path):
    d = diagnoses["dihedral"]
    write_outputs(d.result, d.predictions, tmp_path)
    doc = json.loads((tmp_path / "diagnosis.json").read_text())
    assert doc["schema"] == "aerodelta.diagnosis/1"
    for c in ("Cl", "Cn", "CY"):
        r = doc["coefficients"][c]
        assert set(r["gap"]) >= {"rms", "bias", "tic"}
        assert r["where"] and set(r["where"][0]) >= {
            "flap_deg", "alpha_lo_deg", "alpha_hi_deg", "phase", "rms", "bias", "significant",
        }  # fmt: skip
        assert set(r["effects"][0]) >= {
            "effect", "rank", "significant", "ambiguous_with", "alpha_range_deg",
            "gap_rms_before", "gap_rms_after", "shrink_fraction", "statistic", "p_value",
            "outer_shrink_fraction", "outer_p_value", "outer_chosen_folds",
        }  # fmt: skip
        assert set(r["outer"]) >= {
            "folds", "n_maneuvers", "shrink_fraction", "shrink_fraction_timing",
            "shrink_fraction_effects", "p_value_effects", "chosen_per_fold", "chosen_in_folds",
        }  # fmt: skip
        assert r["outer"]["n_maneuvers"] == doc["data"]["n_maneuvers"]
        assert r["flap_curves"]["layout"] in {"shared", "per_flap"}
        assert 0 <= r["outer"]["per_flap_folds"] <= r["outer"]["folds"]
    # the withheld dihedral effect holds out of sample: chosen in every outer fold, most of
    # its in-sample shrink kept on maneuvers no choice saw
    top = doc["coefficients"]["Cl"]["effects"][0]
    assert top["effect"] == "dihedral" and top["outer_chosen_folds"] == 5
    assert top["outer_shrink_fraction"] >= 0.8 * top["shrink_fraction"]
    assert doc["coefficients"]["Cl"]["outer"]["p_value_effects"] < 0.01
    # every selected effect passed the entry-kind consistency check; nothing was rejected
    assert doc["coefficients"]["Cl"]["entry_kind_check"]["checked"][0] == "dihedral"
    assert doc["coefficients"]["Cl"]["entry_kind_check"]["rejected"] == []
    assert "outer folds" in (tmp_path / "diagnosis.txt").read_text()
    assert doc["settings"]["per_flap"] == "auto"


def test_gap_numbers_match_a_direct_computation(campaigns, diagnoses):
    """The gap is C_meas minus the simulator's output low-passed per maneuver at the cut-off
    ingest's smoother chose for the coefficient's channel (the cut-offs taken here from
    ingest's own smoothing report, not recomputed)."""
    camp, data = campaigns["dihedral"]
    frame = model_frame(data).sort(["maneuver_id", "t"])
    q = qualified_coefficients(frame)
    report = ingest(camp, compat=False, progress=False).smoothing
    cut = {(r["maneuver_id"], r["channel"]): r["cutoff_hz"] for r in report.iter_rows(named=True)}
    ids, t = frame["maneuver_id"].to_numpy(), frame["t"].to_numpy()
    for coef, ch in (("Cl", "p_dps"), ("Cn", "r_dps"), ("CY", "ay_mps2")):
        sim = q[f"{coef}_qual"].to_numpy().copy()
        for m in np.unique(ids):
            i = np.flatnonzero(ids == m)
            sim[i] = band.lowpass(sim[i], float(np.median(np.diff(t[i]))), cut[(m, ch)])
        gap = frame[f"{coef}_meas"].to_numpy() - sim
        g = diagnoses["dihedral"].result["coefficients"][coef]["gap"]
        assert g["rms"] == pytest.approx(float(np.sqrt(np.mean(gap**2))), rel=1e-9)
        assert g["bias"] == pytest.approx(float(gap.mean()), rel=1e-9, abs=1e-12)


def test_band_match_lowpass_passes_the_band_and_removes_what_is_above_without_delay():
    """Closed forms: a sine at half the cut-off comes out unchanged (no gain, no phase), one at
    twice the cut-off is removed, the end points and a straight line are kept."""
    dt, n, fc = 0.02, 1500, 3.0
    t = np.arange(n) * dt
    slow = np.sin(2 * np.pi * 0.5 * fc * t)
    fast = np.sin(2 * np.pi * 2.0 * fc * t)
    ramp = 0.3 + 0.01 * t
    out = band.lowpass(slow + fast + ramp, dt, fc)
    inner = slice(100, n - 100)  # away from the ends' reflection
    np.testing.assert_allclose(out[inner], (slow + ramp)[inner], atol=2e-3)
    ends = (slow + fast + ramp)[[0, -1]]  # kept (to the periodic extension's 1e-5)
    np.testing.assert_allclose(out[[0, -1]], ends, atol=1e-5)
    np.testing.assert_allclose(band.lowpass(ramp, dt, fc), ramp, atol=1e-12)


def test_band_match_without_the_channel_says_so(campaigns):
    """Records without the raw lateral accelerometer: C_Y cannot take the measured band, and
    the report says the comparison is at full band instead of quietly doing it."""
    _, data = campaigns["null"]
    d = aerodelta.diagnose(data.drop("ay_mps2"), config=DiagnoseConfig(nested=False))
    notes = d.result["data"]["notes"]
    assert any(n.startswith("CY: the simulator's output is compared at full band") for n in notes)
    assert not any(n.startswith(("Cl:", "Cn:")) for n in notes)
    assert "note: CY: the simulator's output is compared at full band" in d.summary()


def test_gap_without_band_match_is_the_raw_difference(campaigns):
    _, data = campaigns["dihedral"]
    frame = model_frame(data).sort(["maneuver_id", "t"])
    q = qualified_coefficients(frame)
    gap = frame["Cl_meas"].to_numpy() - q["Cl_qual"].to_numpy()
    d = aerodelta.diagnose(data, config=DiagnoseConfig(band_match=False, nested=False))
    g = d.result["coefficients"]["Cl"]["gap"]
    assert d.result["settings"]["band_match"] is False
    assert g["rms"] == pytest.approx(float(np.sqrt(np.mean(gap**2))), rel=1e-9)
    assert g["bias"] == pytest.approx(float(gap.mean()), rel=1e-9, abs=1e-12)


def test_black_box_sim_columns_skip_the_sensitivity_effects(campaigns):
    _, data = campaigns["dihedral"]
    frame = model_frame(data)
    q = qualified_coefficients(frame)
    boxed = data.with_columns(
        q["Cl_qual"].alias("Cl_sim"), q["Cn_qual"].alias("Cn_sim"), q["CY_qual"].alias("CY_sim")
    )
    d = aerodelta.diagnose(boxed)
    assert d.result["simulator"].startswith("the records'")
    assert set(d.result["not_testable"]) >= {"beta_vane_bias", "control_lag"}
    assert d.verdict("Cl") == "dihedral"


@pytest.mark.parametrize("tau_s", [0.03, -0.03])
def test_black_box_time_skew_is_estimated_from_the_sim_columns(campaigns, tau_s):
    """A black-box simulator whose inputs are ``tau`` late: its *_sim columns are the built-in
    qualified model's outputs ``tau`` seconds earlier along each maneuver (exact, by
    interpolation). The skew is testable from the columns alone (``+tau dC_sim/dt``): it is
    reported with its size and sign, and the withheld dihedral is still found on C_l."""
    _, data = campaigns["dihedral"]
    frame = model_frame(data)
    q = qualified_coefficients(frame)
    t = frame["t"].to_numpy()
    ids = frame["maneuver_id"].to_numpy()
    cols = {}
    for c in ("Cl", "Cn", "CY"):
        v = q[f"{c}_qual"].to_numpy()
        late = v.copy()
        for m in np.unique(ids):
            i = np.flatnonzero(ids == m)
            late[i] = np.interp(t[i] - tau_s, t[i], v[i])
        cols[f"{c}_sim"] = late
    d = aerodelta.diagnose(data.with_columns(pl.Series(k, v) for k, v in cols.items()))
    assert "time_skew" not in d.result["not_testable"]
    assert "dihedral" in d.significant_effects("Cl"), d.summary()
    for c in ("Cl", "Cn"):
        skew = [e for e in d.result["coefficients"][c]["effects"] if e["effect"] == "time_skew"]
        assert skew and skew[0]["significant"], d.summary()
        assert skew[0]["parameters"]["m_time_skew"] == pytest.approx(tau_s, rel=0.2)


def test_the_diagnosis_never_reads_truth_files(campaigns, monkeypatch, tmp_path):
    camp, _ = campaigns["dihedral"]
    seen: list[str] = []
    real_read, real_scan = pl.read_parquet, pl.scan_parquet
    real_open = Path.open

    def read(p, *a, **k):
        seen.append(str(p))
        return real_read(p, *a, **k)

    def scan(p, *a, **k):
        seen.append(str(p))
        return real_scan(p, *a, **k)

    def popen(self, *a, **k):
        seen.append(str(self))
        return real_open(self, *a, **k)

    monkeypatch.setattr(pl, "read_parquet", read)
    monkeypatch.setattr(pl, "scan_parquet", scan)
    monkeypatch.setattr(Path, "open", popen)
    d = aerodelta.diagnose(camp)
    assert d.verdict("Cl") == "dihedral"
    assert seen and not [p for p in seen if "truth" in Path(p).parts]
    with pytest.raises(DataError, match="truth"):
        aerodelta.diagnose(camp / "truth")


def test_cli_writes_the_report(campaigns, tmp_path, capsys):
    camp, _ = campaigns["null"]
    rc = main(["diagnose", "--data", str(camp), "--out", str(tmp_path), "--no-progress"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "no significant unmodelled effect" in out
    doc = json.loads((tmp_path / "diagnosis.json").read_text())
    assert doc["coefficients"]["Cl"]["verdict"] == "none"
    for f in ("diagnosis.txt", "gap_map.csv", "effects.csv", "shrink.csv", "predictions.parquet"):
        assert (tmp_path / f).is_file()


def test_bad_input_names_what_is_missing(campaigns):
    _, data = campaigns["null"]
    with pytest.raises(DataError, match="Cl_meas"):
        aerodelta.diagnose(data.drop("Cl_meas"))
    with pytest.raises(DataError, match="maneuvers"):
        few = data.filter(
            pl.col("maneuver_id").is_in(data["maneuver_id"].unique().head(3).to_list())
        )
        aerodelta.diagnose(few)


def test_user_defined_effect_is_scored_and_can_explain_what_it_models(campaigns, tmp_path):
    # an effect of the user's, as the CLI reads it from TOML: the withheld dihedral written
    # as a user regressor is found under the user's name (it and the vocabulary's dihedral
    # are then the same model, so one of them wins and the other is ambiguous or unselected)
    camp, _ = campaigns["dihedral"]
    toml = tmp_path / "effects.toml"
    toml.write_text('[my_beta]\nCl = ["beta_deg"]\n[my_noise]\nCn = ["beta_deg * rhat * 0"]\n')
    out = tmp_path / "out"
    rc = main(
        ["diagnose", "--data", str(camp), "--effects", str(toml), "--out", str(out),
         "--no-progress"]
    )  # fmt: skip
    assert rc == 0
    doc = json.loads((out / "diagnosis.json").read_text())
    cl = doc["coefficients"]["Cl"]
    names = {e["effect"] for e in cl["effects"]}
    assert {"my_beta", "dihedral"} <= names
    top = cl["effects"][0]
    assert top["significant"]
    assert {top["effect"], *top["ambiguous_with"]} & {"my_beta", "dihedral"}
    # a regressor that is identically zero explains nothing and is never significant
    cn = {e["effect"]: e for e in doc["coefficients"]["Cn"]["effects"]}
    assert not cn["my_noise"]["significant"]


def test_rolloff_nuisance_columns_follow_the_runtime_spike_along_the_record(tmp_path):
    """The per-event nuisance columns of the roll-off moment have the runtime model's shape
    along the flown alpha history (drawn at the armed 15-deg crossing, decaying with the
    alpha travelled past the centre, spent after four widths; a flank-only spike's centre
    found above its peak): on a virtual campaign, each maneuver's injected truth spike is
    reproduced by least-squares amplitudes on its two columns to a few per cent RMS, where a
    Gaussian of alpha alone at the peak alpha (the spike met again on the way down) leaves
    about a third of it."""
    d = tmp_path / "campaign"
    generate_campaign(d, effects="none", seed=5, size="quick", rolloff=True)
    new, old = [], []
    for f in sorted((d / "truth").glob("m*.parquet")):
        tr = pl.read_parquet(f).with_columns(pl.lit(f.stem).alias("maneuver_id"))
        spike = tr["dCl_stochastic_rolloff"].to_numpy()
        on = np.abs(spike) > 1e-7
        if np.abs(spike).max() < 1e-4 or int(np.sum(on[1:] & ~on[:-1])) > 1:
            continue  # no roll-off, or more than one draw in the maneuver
        a, t = tr["alpha_true_deg"].to_numpy(), tr["t"].to_numpy()
        k = int(np.argmax(np.abs(spike)))
        frame = tr.select("maneuver_id", "t", pl.col("alpha_true_deg").alias("alpha_deg"))
        centres = refine_centres(frame, spike, [(f.stem, float(a[k]), float(t[k]))])
        u = (a - a[k]) / 0.5  # the former column: a Gaussian of alpha at the peak alpha
        gauss = np.exp(-0.5 * u * u)
        for out, cols in (
            (new, event_regressors(frame, centres)),
            (old, np.column_stack([gauss, u * gauss])),
        ):
            amp, *_ = np.linalg.lstsq(cols, spike, rcond=None)
            out.append(np.sqrt(np.mean((cols @ amp - spike) ** 2) / np.mean(spike**2)))
    new_a, old_a = np.array(new), np.array(old)
    assert new_a.size >= 20
    assert np.median(new_a) < 0.03, np.sort(new_a)
    assert np.mean(new_a < 0.05) >= 0.8, np.sort(new_a)
    assert np.median(old_a) > 5 * np.median(new_a)


# The numpy implementation the engine's roll-off event columns replaced
# (aero_core::rolloff_events), kept here as the reference.


def _np_travelled_alpha(alpha, centre):
    top = np.maximum.accumulate(alpha)
    return np.where(top >= centre, 2.0 * top - alpha, alpha)


def _np_draw_index(a_m, t_m, tp):
    up = np.flatnonzero((a_m[1:] >= 15.0) & (a_m[:-1] < 15.0)) + 1
    low = a_m < 15.0 - 2.0
    start, armed, prev = 0, True, 0
    for i in up:
        if t_m[i] > tp:
            break
        if not armed and low[prev:i].any():
            armed = True
        if armed:
            start, armed, prev = int(i), False, int(i)
    return start


def _np_spike_columns(a_m, start, ac, sigma_deg, with_u=False):
    g = np.zeros(a_m.size)
    ug = np.zeros(a_m.size)
    u_m = np.zeros(a_m.size)
    eff = _np_travelled_alpha(a_m[start:], ac)
    live = ~np.maximum.accumulate(eff >= ac + 4.0 * sigma_deg)
    u = (eff[live] - ac) / sigma_deg
    idx = np.flatnonzero(live) + start
    g[idx] = np.exp(-0.5 * u * u)
    ug[idx] = u * g[idx]
    u_m[idx] = u  # not in the numpy code: the test checks u g against the engine's g with it
    return (g, ug, u_m) if with_u else (g, ug)


def _np_by_maneuver(frame):
    names = sorted(set(frame["maneuver_id"].to_list()))
    code = np.array([names.index(m) for m in frame["maneuver_id"].to_list()])
    t = frame["t"].to_numpy()
    order = np.lexsort((t, code))
    bounds = np.searchsorted(code[order], np.arange(len(names) + 1))
    rows = {m: order[bounds[i] : bounds[i + 1]] for i, m in enumerate(names)}
    return rows, frame["alpha_deg"].to_numpy(), t


def _np_event_columns(frame, centres, sigma_deg=0.5):
    rows_of, alpha, t = _np_by_maneuver(frame)
    per = {}
    for m, ac, tp in centres:
        if m in rows_of:
            per.setdefault(m, []).append((float(ac), float(tp)))
    k = max((len(v) for v in per.values()), default=0)
    rows = [[] for _ in range(2 * k)]
    vals = [[] for _ in range(2 * k)]
    u_of = np.zeros((frame.height, k))
    for m, cs in per.items():
        r_m = rows_of[m]
        for j, (ac, tp) in enumerate(sorted(cs, key=lambda x: x[0])):
            start = _np_draw_index(alpha[r_m], t[r_m], tp)
            g, ug, u = _np_spike_columns(alpha[r_m], start, ac, sigma_deg, with_u=True)
            u_of[r_m, j] = u
            for c, v in ((2 * j, g), (2 * j + 1, ug)):
                nz = np.flatnonzero(v)
                rows[c].append(r_m[nz])
                vals[c].append(v[nz])
    return [np.concatenate(r) for r in rows], [np.concatenate(v) for v in vals], u_of


def _np_refine_centres(frame, residual, centres, sigma_deg=0.5):
    rows_of, alpha, t = _np_by_maneuver(frame)
    out = []
    for m, ac, tp in centres:
        rows = rows_of.get(m)
        if rows is None:
            out.append((m, ac, tp))
            continue
        r = residual[rows]
        start = _np_draw_index(alpha[rows], t[rows], tp)
        best, best_c = -1.0, ac
        for dc in (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5):
            g, ug = _np_spike_columns(alpha[rows], start, ac + dc, sigma_deg)
            x = np.column_stack([g, ug])
            nz = np.flatnonzero(np.any(x != 0.0, axis=1))
            if nz.size < 3:
                continue
            coef, *_ = np.linalg.lstsq(x[nz], r[nz], rcond=None)
            explained = float(np.sum((x[nz] @ coef) ** 2))
            if explained > best:
                best, best_c = explained, ac + dc
        out.append((m, best_c, tp))
    return out


def _ramps(a0, knots, dt=0.02):
    """Alpha from ``a0`` through ``(alpha, seconds to reach it)`` knots, one sample per dt."""
    out, prev = [np.array([a0])], a0
    for a, dur in knots:
        n = round(dur / dt)
        out.append(prev + (a - prev) * np.arange(1, n + 1) / n)
        prev = a
    return np.concatenate(out)


def test_rolloff_event_columns_and_centres_match_the_numpy_reference():
    """The engine's event columns and centre search (``aero_core::rolloff_events``) against
    the numpy code they replaced, on records of five maneuvers whose rows are shuffled: a
    stall that passes its centre; chatter about 15 deg, then a stall that turns back 0.75 deg
    before its roll-off's centre (the centre must be found above the peak); two stalls with a
    recovery below 13 deg between them (re-armed: a second draw); a record that starts above
    15 deg; a maneuver without an event. The centres are the same; the columns' rows are the
    same, ``g`` equal to the last bit or one (numpy's vectorised exp and the C library's differ
    by one ulp on a few per cent of arguments) and ``u g`` exactly ``u`` times the engine's
    ``g``."""
    rng = np.random.default_rng(3)
    alphas = {
        "m_pass": _ramps(10.0, [(18.6, 4.0), (9.0, 2.0)]),
        "m_flank": _ramps(12.0, [(15.4, 1.0), (14.3, 0.3), (15.3, 0.3), (16.8, 1.0), (11.0, 1.5)]),
        "m_twice": _ramps(10.0, [(17.5, 3.0), (11.0, 1.5), (19.2, 3.0), (10.0, 2.0)]),
        "m_above": _ramps(16.0, [(18.0, 1.0), (12.0, 1.5)]),
        "m_none": _ramps(5.0, [(12.0, 2.0)]),
    }
    parts = []
    for i, (m, a_m) in enumerate(alphas.items()):
        t = 100.0 * i + 0.02 * np.arange(a_m.size)
        wiggle = 0.03 * np.sin(np.arange(a_m.size) * 0.07)
        parts.append(pl.DataFrame({"maneuver_id": m, "t": t, "alpha_deg": a_m + wiggle}))
    frame = pl.concat(parts)
    frame = frame[rng.permutation(frame.height)]  # rows in no order at all
    a, t, ids = frame["alpha_deg"].to_numpy(), frame["t"].to_numpy(), frame["maneuver_id"]

    def peak(m, t0, t1):
        on = np.flatnonzero((ids == m).to_numpy() & (t >= t0) & (t <= t1))
        k = on[np.argmax(a[on])]
        return float(a[k]), float(t[k])

    (a_p, t_p), (a_f, t_f) = peak("m_pass", 0, 100), peak("m_flank", 100, 200)
    (a_1, t_1), (a_2, t_2) = peak("m_twice", 200, 203.5), peak("m_twice", 204, 300)
    a_a, t_a = peak("m_above", 300, 400)
    centres = [
        ("m_flank", a_f, t_f),  # the spike's peak alpha; its centre is 0.75 deg above
        ("m_twice", a_2 - 0.3, t_2),  # the second stall's event first, a lower centre second
        ("m_pass", a_p - 1.2, t_p - 0.6),
        ("m_gone", 17.0, 5.0),  # a maneuver the frame does not have
        ("m_twice", a_1 - 0.2, t_1),
        ("m_above", a_a, t_a),
    ]
    truth = {0: (0.75, 0.02), 1: (0.25, -0.015), 2: (0.0, 0.01), 4: (0.5, 0.012), 5: (0.0, 0.02)}
    residual = 2e-4 * rng.standard_normal(frame.height)
    rows_of, _, _ = _np_by_maneuver(frame)
    for i, (dc, amp) in truth.items():
        m, ac, tp = centres[i]
        r = rows_of[m]
        g, _ = _np_spike_columns(a[r], _np_draw_index(a[r], t[r], tp), ac + dc, 0.5)
        residual[r] += amp * g
    ref_centres = _np_refine_centres(frame, residual, centres)
    got = refine_centres(frame, residual, centres)
    assert got == ref_centres
    assert got[0][1] == a_f + 0.75  # the flank-only stall's centre, found above its peak
    assert got[3] == centres[3]
    # the re-armed second stall draws at its own crossing, after a recovery below 13 deg
    r = rows_of["m_twice"]
    d1, d2 = (_np_draw_index(a[r], t[r], tp) for tp in (t_1, t_2))
    assert 0 < d1 < d2 and (a[r][d1:d2] < 13.0).any()
    # the flank-only stall chattered about 15 deg before it: its draw is the first crossing
    r = rows_of["m_flank"]
    assert _np_draw_index(a[r], t[r], t_f) == int(np.argmax(a[r] >= 15.0))

    cols = event_columns(frame, got)
    want_rows, want_vals, u = _np_event_columns(frame, got)
    assert cols.shape == (frame.height, 4)
    for j in range(4):
        np.testing.assert_array_equal(cols.rows[j], want_rows[j])
        assert cols.rows[j].size > 20
    for j in (0, 2):
        np.testing.assert_array_max_ulp(cols.values[j], want_vals[j], maxulp=1)
    dense = event_regressors(frame, got)
    want = np.zeros_like(dense)
    for j in range(4):
        want[want_rows[j], j] = want_vals[j]
    np.testing.assert_array_max_ulp(dense[:, 0::2], want[:, 0::2], maxulp=1)
    np.testing.assert_array_equal(dense[:, 1::2], u * dense[:, 0::2])
    assert (dense[:, 1::2] != 0).sum() == sum(want_rows[j].size for j in (1, 3))


@pytest.mark.parametrize("true_skew", [0.0, 0.02])
def test_timing_nuisance_is_judged_again_once_the_aerodynamic_effects_are_in(true_skew):
    """A timing term is kept at the nuisance stage, before any aerodynamic effect is in the
    model, when it absorbs part of an unmodelled effect's gap; it is reported only if it still
    passes its tests and practical floor in the final model. Truth: a roll-damping-like term
    above 15 deg, a timing regressor that is half made of it, and a real skew of
    ``true_skew`` s on an independent part of the timing regressor."""
    rng = np.random.default_rng(11)
    n_man, per = 60, 200
    man = np.repeat(np.arange(n_man), per)
    alpha = rng.uniform(0.0, 30.0, man.size)
    phat = rng.normal(size=man.size)
    own = rng.normal(size=man.size)
    stall = (alpha > 15.0).astype(float)
    timing = 25.0 * stall * phat + 25.0 * own  # half the unmodelled effect's shape
    y = 1.0 * stall * phat + true_skew * 25.0 * own + 0.3 * rng.normal(size=man.size)
    grid = cv.HatGrid.covering(alpha, 1.0)
    flap = np.zeros(man.size, dtype=np.int64)
    design = cv.build_design(
        y, man, flap, alpha, phat[:, None], timing[:, None], ["phat"], ["m_time_skew"],
        grid, n_man, 1,
    )  # fmt: skip
    stats_ = cv.fold_stats(design, np.arange(n_man) % 5)
    cands = [
        Candidate("time_skew", "measurement", ("m_time_skew",)),
        Candidate("roll_damping", "aerodynamic", ("phat",)),
    ]
    sel = forward_select(design, stats_, cands, SelectionConfig(n_perm=400))
    names = [s.candidate.name for s in sel.selected]
    assert "roll_damping" in names
    if true_skew:
        assert "time_skew" in names
    else:
        # alone, the timing term took about 0.02 s (over the 8 ms floor) of the damping gap
        assert "time_skew" not in names
        st = sel.final_scores["time_skew"]
        assert st.sse_before is not None  # scored by leaving it out of the final model
        assert abs(st.parameters["m_time_skew"]) < 0.008


@pytest.mark.parametrize("means", [(0.3, 0.3, 0.3, 0.0), (0.2, 0.2, 0.2, 0.2)])
def test_an_effect_that_makes_one_entry_kind_worse_is_rejected(means):
    """Entry-kind consistency (diagnosis/kinds.py): above 15 deg the gap is an offset per
    entry kind, ``means``. Unequal, it is an unlisted effect whose mean depends on the entry:
    the constant of ``lateral_asymmetry`` passes the selection's tests, but it makes the
    stalls of the kind with no offset worse held out, so it is rejected with that kind named,
    and the selection made again without it keeps nothing. Equal, it is an asymmetry of the
    aircraft: it helps every kind and stays."""
    rng = np.random.default_rng(17)
    n_man, per = 80, 200
    man = np.repeat(np.arange(n_man), per)
    kind_of_man = np.arange(n_man) % 4
    alpha = rng.uniform(0.0, 30.0, man.size)
    phat = rng.normal(size=man.size)
    stall = (alpha > 15.0).astype(float)
    y = stall * np.asarray(means)[kind_of_man[man]] + 0.3 * rng.normal(size=man.size)
    grid = cv.HatGrid.covering(alpha, 2.0)
    flap = np.zeros(man.size, dtype=np.int64)
    design = cv.build_design(
        y, man, flap, alpha, np.column_stack([np.ones(man.size), phat]), np.zeros((man.size, 0)),
        ["one", "phat"], [], grid, n_man, 1,
    )  # fmt: skip
    stats_ = cv.fold_stats(design, np.arange(n_man) % 5)
    cands = [
        Candidate("lateral_asymmetry", "aerodynamic", ("one",)),
        Candidate("roll_damping", "aerodynamic", ("phat",)),
    ]
    cfg = SelectionConfig(n_perm=1000)
    labels = pl.Series("kind", ["straight", "turning", "accelerated", "asymmetric_thrust"])
    kinds = EntryKinds.of(labels.gather(kind_of_man))
    assert kinds is not None
    plain = forward_select(design, stats_, cands, cfg)
    assert [s.candidate.name for s in plain.selected] == ["lateral_asymmetry"]
    assert plain.kind_check is None  # not asked for
    sel = forward_select(design, stats_, cands, cfg, kinds=kinds)
    assert sel.kind_check is not None
    if len(set(means)) > 1:
        assert sel.selected == []
        (rej,) = sel.kind_check["rejected"]
        assert rej["effect"] == "lateral_asymmetry"
        worse = {k for k, v in rej["per_kind"].items() if v["p_worse"] < cfg.alpha}
        assert worse == {"asymmetric_thrust"}  # the kind with no offset
        assert rej["per_kind"]["asymmetric_thrust"]["shrink_fraction"] < 0
        assert rej["per_kind"]["asymmetric_thrust"]["kind_worse_fraction"] >= cfg.min_shrink
    else:
        assert [s.candidate.name for s in sel.selected] == ["lateral_asymmetry"]
        assert sel.kind_check == {"checked": ["lateral_asymmetry"], "rejected": []}


def test_a_real_effect_that_barely_touches_other_kinds_is_kept():
    """The check's materiality floor: a thrust-asymmetry-like term acts through a regressor
    that is zero but in one entry kind (its truth differs by flap, factors 1 and 2, the model
    sharing one curve), recorded with noise (0.5 % of its size): in the other kinds the
    fitted term turns that noise into a small, consistent error, significant over their
    maneuvers (as a thrust-asymmetry term on a virtual campaign made 44 of 50 wings-level
    stalls worse, p = 0.0002), yet under ``min_shrink`` of their gap: the effect is kept."""
    rng = np.random.default_rng(23)
    n_man, per = 80, 200
    man = np.repeat(np.arange(n_man), per)
    kind_of_man = np.arange(n_man) % 4
    flap_of_man = (np.arange(n_man) // 4) % 2
    alpha = rng.uniform(0.0, 30.0, man.size)
    x = np.where(kind_of_man[man] == 3, 1.0 + 0.2 * rng.normal(size=man.size), 0.0)
    x_meas = x + 0.005 * rng.normal(size=man.size)  # the recorded channel's noise
    stall = (alpha > 12.0).astype(float)
    y = stall * (1.0 + flap_of_man[man]) * x + 0.05 * rng.normal(size=man.size)
    x = x_meas
    grid = cv.HatGrid.covering(alpha, 2.0)
    design = cv.build_design(
        y, man, np.zeros(man.size, dtype=np.int64), alpha, np.column_stack([np.ones(man.size), x]),
        np.zeros((man.size, 0)), ["ct_diff", "one"][::-1], [], grid, n_man, 1,
    )  # fmt: skip
    stats_ = cv.fold_stats(design, np.arange(n_man) % 5)
    cands = [
        Candidate("lateral_asymmetry", "aerodynamic", ("one",)),
        Candidate("thrust_asymmetry", "aerodynamic", ("ct_diff",)),
    ]
    cfg = SelectionConfig(n_perm=1000)
    labels = pl.Series("kind", ["straight", "turning", "accelerated", "asymmetric_thrust"])
    kinds = EntryKinds.of(labels.gather(kind_of_man))
    assert kinds is not None
    sel = forward_select(design, stats_, cands, cfg, kinds=kinds)
    assert [s.candidate.name for s in sel.selected] == ["thrust_asymmetry"]
    assert sel.kind_check is not None and sel.kind_check["rejected"] == []
    check = select.kind_consistency(
        design, stats_, [*sel.nuisance, sel.selected[0].candidate],
        sel.selected[0].candidate, kinds, cfg,
    )  # fmt: skip
    small = [v for k, v in check["per_kind"].items() if k != "asymmetric_thrust"]
    assert any(v["p_worse"] < cfg.alpha for v in small)  # significant...
    assert all(v["kind_worse_fraction"] < cfg.min_shrink for v in small)  # ...not material


def test_rivals_apart_by_less_than_the_effect_size_floor_are_ambiguous():
    """Two explanations whose held-out errors differ consistently (every maneuver, so the
    paired test is significant) but by less than ``min_shrink`` of the gap cannot be chosen
    between: ambiguous. The same consistent difference above the floor is a choice."""
    cfg = SelectionConfig(n_perm=2000)
    rng = np.random.default_rng(5)
    chosen = rng.uniform(0.5, 1.5, 200)
    total0 = 10.0 * float(chosen.sum())  # the gap: chosen removes 90 % of it
    tiny = chosen * 1.01  # 0.1 % of the gap, on every maneuver
    big = chosen * 1.5  # 5 % of the gap, on every maneuver
    for d in (tiny, big):
        _, p = cv.sign_flip_pvalue(select.material_change(d, chosen), cfg.n_perm, 1)
        assert p < cfg.ambiguity_p
    assert select._indistinct(tiny, chosen, cfg, total0, 1)
    assert not select._indistinct(big, chosen, cfg, total0, 1)


def test_user_effects_refused_in_one_line_and_a_lone_regressor_accepted() -> None:
    """Vocabulary.with_user_effects: an unknown coefficient, a regressor that is not SQL, or a
    value of the wrong type is an InvalidInputError naming the effect; one regressor given as
    a string (not a list) is one regressor, not one per character."""
    from aerodelta.diagnosis.vocabulary import default_vocabulary  # noqa: PLC0415
    from aerodelta.exceptions import InvalidInputError  # noqa: PLC0415

    v = default_vocabulary()
    with pytest.raises(InvalidInputError, match="user effect 'x': unknown coefficient 'Cm'"):
        v.with_user_effects({"x": {"Cm": ["beta_deg"]}})
    with pytest.raises(InvalidInputError, match="is not a SQL expression") as e:
        v.with_user_effects({"x": {"Cl": ["beta_deg * * rhat"]}})
    assert "\n" not in str(e.value)
    with pytest.raises(InvalidInputError, match="neither a SQL expression"):
        v.with_user_effects({"x": {"Cl": [3.0]}})  # type: ignore[list-item]
    with pytest.raises(InvalidInputError, match="coefficient: \\[regressor"):
        v.with_user_effects({"x": ["beta_deg"]})  # type: ignore[dict-item]
    lone = v.with_user_effects({"x": {"Cl": "beta_deg * rhat"}})  # type: ignore[dict-item]
    user = [c for c in lone.candidates["Cl"] if c.name == "x"]
    assert len(user) == 1 and len(user[0].regressors) == 1


def test_rolloff_search_that_cannot_run_says_why(monkeypatch):
    """Fail loudly: records without the aileron channel, or data the detector refuses, give a
    visible note ('roll-off not searched: ...', printed in the report), and an unexpected
    error inside the detector propagates instead of reading as 'no roll-off'."""
    from aerodelta.diagnosis import stochastic  # noqa: PLC0415
    from aerodelta.diagnosis.report import summary_text  # noqa: PLC0415

    n = 50
    f = pl.DataFrame(
        {
            "maneuver_id": ["a"] * n, "t": np.arange(n) * 0.02,
            "alpha_deg": np.linspace(0, 20, n), "da_deg": np.zeros(n), "Cl_meas": np.zeros(n),
        }
    )  # fmt: skip
    r = stochastic.rolloff_finding(f.drop("da_deg"), np.zeros(n))
    assert r["note"] == "roll-off not searched: the records lack ['da_deg']"
    assert not r["detected"]
    r = stochastic.rolloff_finding(f, np.zeros(7))
    assert r["note"].startswith("roll-off not searched: roll-off detection: residual has shape")
    assert "note" not in stochastic.rolloff_finding(f, np.zeros(n))

    def broken(*_a, **_k):
        raise RuntimeError("bug in the detector")

    monkeypatch.setattr(stochastic, "detect_rolloff", broken)
    with pytest.raises(RuntimeError, match="bug in the detector"):
        stochastic.rolloff_finding(f, np.zeros(n))
    empty = {
        "verdict": "none", "gap": {"rms": 0.0, "bias": 0.0, "tic": 0.0},
        "remaining_gap": {"rms": 0.0, "tic": 0.0},
        "effects": [], "where": [], "rolloff": {"note": "roll-off not searched: x"},
    }  # fmt: skip
    doc = {
        "simulator": "s", "data": {"n_maneuvers": 1, "n_points": n, "flaps_deg": [0.0], "folds": 5},
        "coefficients": {c: empty for c in ("Cl", "Cn", "CY")},
    }  # fmt: skip
    assert "  roll-off not searched: x" in summary_text(doc).splitlines()


def test_scoring_shows_an_unlisted_gap_only_in_its_alpha_range(tmp_path):
    # hand-built truth: an unlisted effect (beta_rhat_coupling) moves C_l only between 14 and
    # 18 deg of alpha; a diagnosis that names nothing and whose gap map has one significant
    # cell shows the gap when that cell overlaps 14-18 deg, not when it lies at 8-9 deg
    t = np.arange(0.0, 40.0, 0.05)
    alpha = 5.0 + 0.5 * t  # 5 to 25 deg
    contrib = np.where((alpha >= 14.0) & (alpha < 18.0), 0.01, 0.0)
    truth = tmp_path / "truth"
    truth.mkdir()
    pl.DataFrame({"t": t, "dCl_beta_rhat_coupling": contrib}).write_parquet(truth / "m000.parquet")
    zero = np.zeros_like(t)
    preds = pl.DataFrame(
        {"maneuver_id": ["m000"] * t.size, "t": t, "alpha_deg": alpha}
        | {f"{c}_{k}": zero for c in ("Cl", "Cn", "CY") for k in ("explained", "timing")}
        | {"Cl_gap": contrib, "Cn_gap": zero + 1e-3, "CY_gap": zero + 1e-3}
    )

    def diag(lo: float) -> SimpleNamespace:
        cell = {"significant": True, "alpha_lo_deg": lo, "alpha_hi_deg": lo + 1.0}
        res = {c: {"verdict": "none", "effects": [], "where": [cell]} for c in ("Cl", "Cn", "CY")}
        return SimpleNamespace(predictions=preds, result={"coefficients": res})

    shown = score_case(diag(15.0), truth, {"beta_rhat_coupling": 1.0})
    assert shown.affected == {"beta_rhat_coupling": ["Cl"]}
    assert shown.gap_shown == {"Cl:beta_rhat_coupling": True}
    assert score_case(diag(8.0), truth, {"beta_rhat_coupling": 1.0}).gap_shown == {
        "Cl:beta_rhat_coupling": False
    }


def test_rolloff_call_counts_the_wings_level_stalls(monkeypatch):
    """The binomial call (events in more maneuvers than the detector's 10 % false-event rate
    explains, p < 0.01) counts the wings-level stalls when the records name kinds: events in 7
    of 20 cross-controlled stalls are no roll-off, the same in 7 of 20 wings-level stalls are
    (7 is the least count with P(X >= k | 20, 0.1) < 0.01, from scipy's binomial); with no kind
    column every maneuver counts. Events of every kind are reported."""
    from scipy.stats import binom  # noqa: PLC0415

    from aerodelta.diagnosis import stochastic  # noqa: PLC0415

    n = 40
    ids = [f"m{i:02d}" for i in range(40)]
    frame = pl.DataFrame(
        {
            "maneuver_id": [m for m in ids for _ in range(n)],
            "t": np.tile(np.arange(n) * 0.02, 40),
            "alpha_deg": np.tile(np.linspace(5, 20, n), 40),
            "da_deg": np.zeros(40 * n),
            "Cl_meas": np.zeros(40 * n),
            "kind": [("straight" if i < 20 else "other") for i in range(40) for _ in range(n)],
        }
    )

    def events(with_events: list[str]):
        def fake(*_a, **_k):
            k = len(with_events)
            return pl.DataFrame(
                {
                    "maneuver_id": with_events, "accepted": [True] * k,
                    "alpha_onset_deg": [15.0] * k, "alpha_peak_deg": [15.5] * k,
                    "t_peak": [0.5] * k, "t_onset": [0.4] * k, "peak": [0.01] * k,
                }
            )  # fmt: skip

        return fake

    # the smallest count the call accepts among 20 counted maneuvers (closed form)
    need = next(k for k in range(21) if binom.sf(k - 1, 20, 0.1) < 0.01)
    assert need == 7
    for who, counted in ((ids[20 : 20 + need], False), (ids[:need], True)):
        monkeypatch.setattr(stochastic, "detect_rolloff", events(who))
        r = stochastic.rolloff_finding(frame, np.zeros(frame.height))
        assert r["detected"] is counted, (who, r)
        assert r["call_kinds"] == ["straight"] and r["call_maneuvers"] == 20
        assert r["n_maneuvers_with_events"] == need and r["n_searched"] == 40
    # no kinds named: all 40 maneuvers count (7 of 40 is not enough, 9 is)
    need40 = next(k for k in range(41) if binom.sf(k - 1, 40, 0.1) < 0.01)
    monkeypatch.setattr(stochastic, "detect_rolloff", events(ids[20 : 20 + need40]))
    r = stochastic.rolloff_finding(frame.drop("kind"), np.zeros(frame.height))
    assert r["detected"] and r["call_kinds"] == [] and r["call_maneuvers"] == 40


def test_a_virtual_rolloff_campaign_is_called_stochastic_rolloff(tmp_path, campaigns, diagnoses):
    # the truth draws a roll-off at every stall (thesis Table 3.2, aero_core::rolloff); the
    # wings-level stalls the call counts are enough on a 40-maneuver campaign, and the null
    # campaign of the same size (no roll-off in its truth) is not called
    d = tmp_path / "campaign"
    generate_campaign(d, effects="none", seed=7, size="quick", rolloff=True)
    truth = pl.concat(
        pl.read_parquet(f, columns=["dCl_stochastic_rolloff"]).with_columns(
            pl.lit(f.stem).alias("maneuver_id")
        )
        for f in sorted((d / "truth").glob("m*.parquet"))
    )
    with_spike = truth.filter(pl.col("dCl_stochastic_rolloff").abs() > 1e-4)["maneuver_id"]
    assert with_spike.n_unique() >= 20
    res = aerodelta.diagnose(ingest(d, compat=False, progress=False).data).result
    ro = res["coefficients"]["Cl"]["rolloff"]
    assert ro["detected"] and res["coefficients"]["Cl"]["verdict"] == "stochastic_rolloff"
    assert ro["call_kinds"] == ["straight"] and ro["call_maneuvers"] == 10
    assert not diagnoses["null"].result["coefficients"]["Cl"]["rolloff"]["detected"]
