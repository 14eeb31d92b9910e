"""Virtual flight test campaigns: determinism, the contract layout, consistency
of the recorded channels with the equations of motion (thesis Eq. 3.2-3.4), the
effect library and the roll-off statistics (thesis Table 3.2, Section 3.4.3)."""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta
from aerodelta.campaign import (
    _departure_row,
    campaign_plan,
    effect_library,
    generate_campaign,
    maneuver_index,
    parse_effects,
    qualified_model_tables,
    replay,
    rolloff_draws,
    simulate_campaign,
    trim,
)
from aerodelta.cli import main

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

CHANNELS = [
    "t", "alpha_deg", "beta_deg", "p_dps", "q_dps", "r_dps", "phi_deg", "theta_deg",
    "psi_deg", "ax_mps2", "ay_mps2", "az_mps2", "tas_mps", "rho_kgm3", "da_deg", "de_deg",
    "dr_deg", "dsl_deg", "dsr_deg", "flap_deg", "ct_left", "ct_right", "prop_rpm", "h_m",
    "pusher_active", "stall_warning",
]  # fmt: skip


def _digest(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("camp") / "quick"
    generate_campaign(out, effects="default", seed=11, size="quick")
    return out


def test_same_seed_identical_files_other_seed_differs(quick: Path, tmp_path: Path) -> None:
    again = tmp_path / "again"
    generate_campaign(again, effects="default", seed=11, size="quick")
    assert _digest(quick) == _digest(again)
    other = tmp_path / "other"
    generate_campaign(other, effects="default", seed=12, size="quick")
    a, b = _digest(quick), _digest(other)
    assert a.keys() == b.keys()
    assert a["records/m000_f00_straight_p.parquet"] != b["records/m000_f00_straight_p.parquet"]
    with pytest.raises(aerodelta.DataError, match="already exists"):
        generate_campaign(other, seed=1, size="quick")


def test_a_subset_flies_its_maneuvers_byte_for_byte_as_the_whole_campaign(
    quick: Path, tmp_path: Path
) -> None:
    """``only`` flies the chosen maneuvers of the campaign: their files are those of the whole
    campaign, their manifest rows too, and ``campaign_plan`` lists the whole campaign's
    maneuvers in its manifest's order before flying them."""
    whole = pl.read_csv(quick / "manifest.csv")
    plan = campaign_plan(seed=11, size="quick")
    assert plan["maneuver_index"].to_list() == list(range(whole.height))
    for col in ("flap_deg", "kind", "pusher", "seed"):
        assert plan[col].to_list() == whole[col].to_list(), col
    assert [maneuver_index(m) for m in whole["maneuver_id"]] == list(range(whole.height))
    # four digits from index 1000 on (stall.py read the first three until session 31)
    assert maneuver_index("m1000_f05_turning_n") == 1000
    with pytest.raises(aerodelta.InvalidInputError, match="not a virtual campaign's"):
        maneuver_index("DHC6_f00_straight_003")
    pick = [38, 0, 13, 7]
    sub = tmp_path / "sub"
    info = generate_campaign(sub, effects="default", seed=11, size="quick", only=pick)
    ids = whole["maneuver_id"].to_list()
    chosen = [ids[i] for i in sorted(pick)]
    assert info.manifest["maneuver_id"].to_list() == chosen
    assert pl.read_csv(sub / "manifest.csv").equals(
        whole.filter(pl.col("maneuver_id").is_in(chosen))
    )
    a, b = _digest(quick), _digest(sub)
    for mid in chosen:
        for part in ("records", "truth"):
            assert b[f"{part}/{mid}.parquet"] == a[f"{part}/{mid}.parquet"], (part, mid)
    assert len([k for k in b if k.startswith("records/")]) == len(pick)
    doc = json.loads((sub / "truth" / "campaign.json").read_text())
    assert doc["spec"]["only"] == sorted(pick)
    assert json.loads((quick / "truth" / "campaign.json").read_text())["spec"]["only"] == []
    seeds = dict(zip(ids, whole["seed"], strict=True))
    assert doc["maneuver_seeds"] == {m: seeds[m] for m in chosen}


@pytest.mark.parametrize(
    ("only", "match"),
    [
        ([40], r"only: maneuver index 40 is not in this campaign .*indices 0 to 39"),
        ([-1], r"only: maneuver index -1 is not in this campaign"),
        ([3, 5, 3], r"only: maneuver index 3 is given twice"),
        (["3"], r"only: '3' is not a maneuver index"),
        ("0,1", r"give a list of maneuver indices"),
    ],
)
def test_a_meaningless_subset_is_refused_in_one_line(
    only: object, match: str, tmp_path: Path
) -> None:
    with pytest.raises(aerodelta.InvalidInputError, match=match):
        generate_campaign(tmp_path / "c", seed=1, size="quick", only=only)  # type: ignore[arg-type]
    assert not (tmp_path / "c").exists()


def test_contract_layout_and_channels(quick: Path) -> None:
    man = pl.read_csv(quick / "manifest.csv")
    assert man.columns[:5] == ["maneuver_id", "flap_deg", "kind", "pusher", "file"]
    assert man.height == 40
    assert set(man["kind"]) == {"straight", "turning", "accelerated", "asymmetric_thrust"}
    assert set(man["flap_deg"]) == {0.0, 5.0, 10.0, 15.0, 35.0}
    assert man["pusher"].dtype == pl.Boolean and man["pusher"].sum() == 20
    # pusher maneuvers fire it; accelerated stalls reach n > 1.3 (Section 3.2.1)
    straight = pl.col("kind").is_in(["straight", "turning"])
    assert man.filter(pl.col("pusher") & straight)["pusher_fired"].all()
    assert not man.filter(~pl.col("pusher"))["pusher_fired"].any()
    assert (man.filter(pl.col("kind") == "accelerated")["load_factor_at_stall"] > 1.3).all()
    ac = tomllib.loads((quick / "aircraft.toml").read_text())
    assert {"geometry", "mass", "propulsion", "sensors"} <= ac.keys()
    assert len(ac["sensors"]["accel_m"]) == 3
    for row in man.iter_rows(named=True):
        rec = pl.read_parquet(quick / row["file"])
        assert rec.columns == CHANNELS
        assert all(dt == pl.Float64 for dt in rec.dtypes)
        t = rec["t"].to_numpy()
        assert np.all(np.diff(t) > 0)
        truth = pl.read_parquet(quick / "truth" / f"{row['maneuver_id']}.parquet")
        assert truth.height == rec.height
        for c in ["Cl_true", "Cn_true", "CY_true", "Cl_qual", "Cn_qual", "CY_qual"]:
            assert c in truth.columns
    info = json.loads((quick / "truth" / "campaign.json").read_text())
    assert "roll_damping" in info["effects"] and "stochastic_rolloff" in info["effects"]
    assert set(info["rolloff_draws"]) == set(man["maneuver_id"])


def _measured(rec: pl.DataFrame, ac: dict) -> dict[str, np.ndarray]:
    """Measured C_l, C_n, C_Y by thesis Eq. 3.2-3.4 with the accelerometer moved to the CG."""
    g, m, pr = ac["geometry"], ac["mass"], ac["propulsion"]
    s, b = g["S_m2"], g["b_m"]
    ixx, iyy, izz, ixz = m["Ixx_kgm2"], m["Iyy_kgm2"], m["Izz_kgm2"], m["Ixz_kgm2"]
    t = rec["t"].to_numpy()
    p, q, r = (np.radians(rec[c].to_numpy()) for c in ("p_dps", "q_dps", "r_dps"))
    pd, qd, rd = (np.gradient(x, t) for x in (p, q, r))
    qs = 0.5 * rec["rho_kgm3"].to_numpy() * rec["tas_mps"].to_numpy() ** 2 * s
    hp = 2 * pr["prop_inertia_kgm2"] * pr["prop_rpm_fixed"] * np.pi / 30
    cl = (ixx * pd - ixz * (rd + p * q) + (izz - iyy) * q * r) / (qs * b)
    cn = (izz * rd - ixz * (pd - q * r) + (iyy - ixx) * p * q + hp * q) / (qs * b)
    rx, ry, rz = ac["sensors"]["accel_m"]
    w = np.stack([p, q, r], 1)
    wd = np.stack([pd, qd, rd], 1)
    rv = np.array([rx, ry, rz])
    corr = np.cross(wd, rv) + np.cross(w, np.cross(w, rv))
    ay_cg = rec["ay_mps2"].to_numpy() - corr[:, 1]
    cy = m["mass_kg"] * ay_cg / qs
    return {"Cl": cl, "Cn": cn, "CY": cy}


def test_effects_off_recorded_coefficients_match_qualified_model() -> None:
    # Noise-free, calm air, no effects: Eq. 3.2-3.4 applied to the recorded channels
    # (an independent computation from the simulator's) give the qualified model's
    # coefficients; the residual is the finite-difference error of the rate derivatives.
    ms = simulate_campaign(
        effects="none", rolloff=False, noise=0.0, turbulence=0.0, size=1, only=[1, 3, 21, 38]
    )
    ac = tomllib.loads(aerodelta.campaign.aircraft_toml())
    for m in ms:
        truth = m["truth"]
        for c in ("Cl", "Cn", "CY"):
            assert np.array_equal(truth[f"{c}_true"].to_numpy(), truth[f"{c}_qual"].to_numpy())
        meas = _measured(m["record"], ac)
        for c in ("Cl", "Cn", "CY"):
            ref = truth[f"{c}_qual"].to_numpy()[2:-2]
            got = meas[c][2:-2]
            rms = np.sqrt(np.mean((got - ref) ** 2))
            assert rms < 0.05 * np.std(ref) + 2e-4, (m["id"], c, rms, np.std(ref))


def test_each_effect_changes_only_its_coefficients_and_alpha_range() -> None:
    lib = {e["name"]: e for e in effect_library() if e["kind"] == "aerodynamic"}
    ms = simulate_campaign(effects=dict.fromkeys(lib, 1.0), rolloff=False, size=1, only=range(8))
    for m in ms:
        tr = m["truth"]
        alpha = tr["alpha_true_deg"].to_numpy()
        for c in ("Cl", "Cn", "CY"):
            total = sum(tr[f"d{c}_{n}"].to_numpy() for n in lib)
            gap = tr[f"{c}_true"].to_numpy() - tr[f"{c}_qual"].to_numpy()
            np.testing.assert_allclose(gap, total, atol=1e-12)
        for name, e in lib.items():
            own = {t["coef"] for t in e["terms"]}
            lo, hi = e["alpha_range_deg"]
            for c in ("Cl", "Cn", "CY"):
                d = tr[f"d{c}_{name}"].to_numpy()
                if c not in own:
                    assert not d.any(), (name, c)
                else:
                    assert not d[(alpha <= lo) | (alpha >= hi)].any(), (name, c)
    # and the effects are actually exercised somewhere in these maneuvers
    hit = {
        n
        for m in ms
        for n in lib
        if any(m["truth"][f"d{c}_{n}"].abs().max() > 0 for c in ("Cl", "Cn", "CY"))
    }
    assert {"aileron_effectiveness", "roll_damping", "dihedral", "lateral_asymmetry"} <= hit


def test_rolloff_draw_statistics_match_table_3_2() -> None:
    # 20 000 draws: direction 58 % right, magnitude CV 22.5 %, alpha spread 1.31 deg
    # (thesis Section 3.4.3), within 5 standard errors.
    d = rolloff_draws(15.0, seed=4, n=20_000)
    n = d.height
    p = float((d["sign"] > 0).mean())
    assert abs(p - 0.58) < 5 * np.sqrt(0.58 * 0.42 / n)
    f = d["factor"].to_numpy()
    assert abs(f.mean() - 1) < 5 * 0.225 / np.sqrt(n)
    assert abs(f.std() - 0.225) < 0.01
    a = d["alpha_shift_deg"].to_numpy()
    assert abs(a.std() - 1.31) < 5 * 1.31 / np.sqrt(2 * n)
    np.testing.assert_allclose(d["center_deg"].to_numpy() - a, 18.04)
    np.testing.assert_allclose(np.abs(d["peak"].to_numpy()), 0.02315 * f)


def test_campaign_rolloff_draws_follow_configuration(quick: Path) -> None:
    info = json.loads((quick / "truth" / "campaign.json").read_text())
    cfg = {r["flap_deg"]: r for r in info["rolloff_config"]["flaps"]}
    man = pl.read_csv(quick / "manifest.csv")
    signs, shifts, factors = [], [], []
    for row in man.iter_rows(named=True):
        for dr in info["rolloff_draws"][row["maneuver_id"]]:
            signs.append(dr["sign"])
            shifts.append(dr["alpha_shift_deg"])
            factors.append(dr["factor"])
            mag = cfg[row["flap_deg"]]["magnitude"]
            assert abs(abs(dr["peak"]) - dr["factor"] * mag) < 1e-12
    n = len(signs)
    assert n >= 40
    p = np.mean(np.array(signs) > 0)
    assert abs(p - 0.58) < 4 * np.sqrt(0.58 * 0.42 / n)
    assert abs(np.std(shifts) - 1.31) < 4 * 1.31 / np.sqrt(2 * n)
    assert abs(np.std(factors) - 0.225) < 4 * 0.225 / np.sqrt(2 * n)


def test_replay_holds_trim_and_qualified_tables_export() -> None:
    tr = trim(10.0, 75.0, 3000.0)
    n = 500
    controls = np.tile(tr["controls_deg"], (n, 1))
    ct = np.full((n, 2), tr["ct"])
    states = replay(10.0, tr["state"], 0.01, controls, ct)
    assert states.shape == (n + 1, 12)
    np.testing.assert_allclose(states[-1, :9], states[0, :9], atol=1e-5)
    tables, terms = qualified_model_tables()
    names = {t["name"] for t in tables}
    assert {"CL_basic", "Cl_beta", "Cl_da", "Cn_dr"} <= names
    assert all(t["table"] in names for t in terms)
    for t in tables:
        assert t["values"].size == np.prod([len(b) for b in t["breakpoints"]])


def test_cli_list_effects_and_quick_run(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["campaign", "--list-effects"]) == 0
    out = capsys.readouterr().out
    for name in ("aileron_effectiveness", "stochastic_rolloff", "time_skew"):
        assert name in out
    assert parse_effects("roll_damping=0.5,default")["roll_damping"] == 1.0
    with pytest.raises(aerodelta.InvalidInputError, match="unknown effect"):
        parse_effects("nope")
    code = main(
        ["campaign", "--quick", "--seed", "3", "--effects", "none", "--no-rolloff",
         "--no-turbulence", "--out", str(tmp_path / "c")]
    )  # fmt: skip
    assert code == 0
    assert (tmp_path / "c" / "manifest.csv").exists()
    assert "wrote 40 maneuvers" in capsys.readouterr().out


def _warns_on_its_vane(rec: pl.DataFrame, on_deg: float) -> None:
    """The record's stall warning is the Schmitt trigger of its own alpha vane: on at
    ``on_deg``, off 0.5 deg below (``aero_core::sim::sensors::stall_warning``)."""
    a = rec["alpha_deg"].to_numpy()
    w = rec["stall_warning"].to_numpy()
    assert np.isin(w, (0.0, 1.0)).all() and w.any()
    prev = np.concatenate(([0.0], w[:-1]))
    assert (a[(w == 1.0) & (prev == 0.0)] >= on_deg).all()  # switched on at the threshold
    assert (a[(w == 0.0) & (prev == 1.0)] < on_deg - 0.5).all()  # off below the hysteresis
    assert (w[a >= on_deg] == 1.0).all() and (w[a < on_deg - 0.5] == 0.0).all()


def test_measurement_effects_act_on_their_channels_only() -> None:
    # Same seed: the flight is identical (sensors do not feed back), so each
    # measurement effect shows as its exact signature on its own channels.
    def rec(effects: str) -> pl.DataFrame:
        return simulate_campaign(effects=effects, seed=2, size=1, only=[5])[0]["record"]

    base = rec("none")
    bias = rec("alpha_vane_bias,beta_vane_bias=2")
    # design magnitudes of issue 7: 1 deg of vane bias (so magnitude 2 is 2 deg)
    np.testing.assert_allclose(bias["alpha_deg"] - base["alpha_deg"], 1.0, atol=1e-9)
    np.testing.assert_allclose(bias["beta_deg"] - base["beta_deg"], 2.0, atol=1e-9)
    # the stall warning reads the alpha vane (docs/stall.md): it follows the biased vane
    vane = ("alpha_deg", "beta_deg", "stall_warning")
    assert bias.drop(vane).equals(base.drop(vane))
    for r in (base, bias):
        _warns_on_its_vane(r, on_deg=19.5 - 5.0)  # maneuver 5 flies flap 0 (alpha_max 19.5)
    t_on = [float(r.filter(pl.col("stall_warning") == 1.0)["t"][0]) for r in (base, bias)]
    assert t_on[1] < t_on[0]  # 1 deg more on the vane: the warning comes earlier

    # A timing effect moves what the sensor sees; each sample keeps its own noise (same seed:
    # the same noise draws), so the shifted record differs from the base record shifted by
    # whole samples only by the difference of two independent noise samples (std sqrt(2) x
    # the channel's noise: 0.05 deg for controls and vanes), never by the signal; a record
    # shifted with its noise (the old sensor model) would give exactly zero.
    def same_signal(a: np.ndarray, b: np.ndarray, sd: float) -> None:
        d = a - b
        assert abs(float(d.mean())) < 0.1 * sd
        assert 0.85 < float(d.std()) / (np.sqrt(2.0) * sd) < 1.15

    lag = rec("control_lag")  # recorded controls lead by 0.10 s = 5 samples at 50 Hz
    for c in ("da_deg", "de_deg", "dr_deg"):
        same_signal(lag[c].to_numpy()[:-5], base[c].to_numpy()[5:], 0.05)
    skew = rec("time_skew")  # air data 0.04 s = 2 samples late
    same_signal(skew["alpha_deg"].to_numpy()[2:], base["alpha_deg"].to_numpy()[:-2], 0.05)
    assert skew.drop("alpha_deg", "beta_deg", "tas_mps", "stall_warning").equals(
        base.drop("alpha_deg", "beta_deg", "tas_mps", "stall_warning")
    )
    _warns_on_its_vane(skew, on_deg=19.5 - 5.0)
    acc = rec("accelerometer_offset")
    assert not np.allclose(acc["ay_mps2"], base["ay_mps2"])
    assert acc.drop("ax_mps2", "ay_mps2", "az_mps2").equals(
        base.drop("ax_mps2", "ay_mps2", "az_mps2")
    )


def _shape(alpha: np.ndarray, sh: dict) -> np.ndarray:
    def ss(x: np.ndarray) -> np.ndarray:
        x = np.clip(x, 0, 1)
        return x * x * (3 - 2 * x)

    up = ss((alpha - sh["onset_deg"]) / (sh["full_deg"] - sh["onset_deg"]))
    rec = sh["recover_full_deg"] - sh["recover_start_deg"]
    return up * (1 - sh["recovery"] * ss((alpha - sh["recover_start_deg"]) / rec))


def test_effect_contribution_follows_its_definition_and_magnitude() -> None:
    # dCl_roll_damping = m * g(alpha) * k_flap * C_design * p b / (2 V), recomputed here
    # from the library's published shape and the noise-free recorded p and V.
    lib = {e["name"]: e for e in effect_library()}["roll_damping"]
    b = tomllib.loads(aerodelta.campaign.aircraft_toml())["geometry"]["b_m"]
    for mag in (1.0, 2.5):
        m = simulate_campaign(
            effects={"roll_damping": mag}, rolloff=False, noise=0.0, size=1, only=[1]
        )[0]
        tr, rec = m["truth"], m["record"]
        p_hat = np.radians(rec["p_dps"].to_numpy()) * b / (2 * rec["tas_mps"].to_numpy())
        g = _shape(tr["alpha_true_deg"].to_numpy(), lib["shape"])
        expect = mag * g * lib["flap_factor"][0] * lib["terms"][0]["design"] * p_hat
        np.testing.assert_allclose(tr["dCl_roll_damping"].to_numpy(), expect, atol=1e-12)
        assert np.abs(expect).max() > 1e-4


def test_excitation_is_adjustable() -> None:
    quiet = simulate_campaign(effects="none", excitation=0.0, turbulence=0.0, size=1, only=[0])[0]
    busy = simulate_campaign(effects="none", excitation=2.0, turbulence=0.0, size=1, only=[0])[0]
    assert busy["record"]["dr_deg"].std() > 2 * quiet["record"]["dr_deg"].std()
    assert busy["record"]["p_dps"].std() > 2 * quiet["record"]["p_dps"].std()


def test_replay_of_recorded_controls_reproduces_the_flight() -> None:
    # Thesis Section 4.3: drive the simulator with the recorded control positions
    # and thrust coefficients from the recorded initial state. Recorded at the
    # simulation rate, noise-free, calm air, no roll-off: the replay is the flight.
    m = simulate_campaign(
        effects="default", rolloff=False, noise=0.0, turbulence=0.0, size=1, only=[9],
        record_hz=100.0,
    )[0]  # fmt: skip
    rec, tr = m["record"], m["truth"]
    a, b = np.radians(tr["alpha_true_deg"][0]), np.radians(tr["beta_true_deg"][0])
    v = rec["tas_mps"][0]
    x0 = [
        v * np.cos(a) * np.cos(b), v * np.sin(b), v * np.sin(a) * np.cos(b),
        *np.radians([rec["p_dps"][0], rec["q_dps"][0], rec["r_dps"][0]]),
        *np.radians([rec["phi_deg"][0], rec["theta_deg"][0], rec["psi_deg"][0]]),
        0.0, 0.0, rec["h_m"][0],
    ]  # fmt: skip
    # the surfaces move linearly from one recorded position to the next over each step
    controls = rec.select("da_deg", "de_deg", "dr_deg", "dsl_deg", "dsr_deg").to_numpy()
    ct = rec.select("ct_left", "ct_right").to_numpy()
    states = replay(rec["flap_deg"][0], x0, 0.01, controls, ct, effects="default")[:-1]
    alpha = np.degrees(np.arctan2(states[:, 2], states[:, 0]))
    np.testing.assert_allclose(alpha, tr["alpha_true_deg"].to_numpy(), atol=1e-6)
    np.testing.assert_allclose(np.degrees(states[:, 6]), rec["phi_deg"].to_numpy(), atol=1e-6)
    np.testing.assert_allclose(states[:, 11], rec["h_m"].to_numpy(), atol=1e-4)
    assert tr["alpha_true_deg"].max() > 18


def test_departed_maneuver_is_cut_one_second_before_leaving_the_physical_range() -> None:
    """A record whose alpha leaves [-45, 60] deg at t = 12.34 s (a spin entry) is cut at the
    last sample before 11.34 s; a record inside every range is kept whole."""
    t = np.arange(0.0, 20.0, 0.02)
    alpha = np.where(t < 12.34, 10.0, -70.0)
    beta = np.zeros_like(t)
    rec = pl.DataFrame({"t": t, "alpha_deg": alpha, "beta_deg": beta, "other": t * 1e9})
    cut = _departure_row(rec)
    assert cut is not None
    assert t[cut] >= 11.34 - 1e-9 and t[cut - 1] < 11.34
    assert _departure_row(rec.with_columns(pl.lit(10.0).alias("alpha_deg"))) is None
