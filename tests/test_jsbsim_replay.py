"""The JSBSim replay aircraft and open-loop replay (issue 19 item 4, aerodelta.jsbsim_replay).

Independent references: the campaign's truth (JSBSim's own aero of the full aircraft and the
qualified model evaluated from the XML in Python, ``truth/<id>.parquet``), the records, and the
engine's ``DeltaModel.evaluate``. Noise-free quick campaigns keep the states exact.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest

pytest.importorskip("jsbsim", reason="needs the jsbsim package: pip install 'aerodelta[jsbsim]'")

from aerodelta.exceptions import AerodeltaError
from aerodelta.fit import theil_inequality
from aerodelta.jsbsim_campaign import generate_jsbsim_campaign
from aerodelta.jsbsim_replay import (
    CHANNELS,
    aero_at_states,
    load_setup,
    replay_campaign,
    replay_maneuver,
    score_window,
    write_replay_aircraft,
)
from aerodelta.model import DeltaModel

#: Maneuvers flown per aircraft: the F-15's three (straight, turning, sideslip); the DHC-6 at
#: flaps 0 (straight) and 20 (turning).
ONLY = {"f15": (), "DHC6": (0, 4)}


@pytest.fixture(scope="module", params=["f15", "DHC6"])
def campaign(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("camp") / request.param
    generate_jsbsim_campaign(
        out, aircraft=request.param, seed=1, size="quick", noise=0.0, only=ONLY[request.param]
    )
    return out


def _record(camp: Path, mid: str, kind: str = "records") -> pl.DataFrame:
    return pl.read_parquet(camp / kind / f"{mid}.parquet")


def test_qualified_aircraft_equals_campaign_sim(campaign: Path, tmp_path: Path) -> None:
    """The qualified JSBSim aircraft's aero at recorded states equals the campaign's qualified
    model C*_sim less its propulsion part (C*_sim = C*_true + C*_prop_true − dC*_true), and
    qualified − full equals −dC*_true to round-off (the same state in both aircraft: what the
    state setting cannot reproduce cancels). Absolute bounds: F-15 1e-12 (measured 1e-15);
    DHC-6 1e-5 (measured 2e-6 in CY, 1e-8 in Cl): its drag and lift, which enter the body-axis
    side force through sideslip (wind axes) and the roll moment through the CG's 1 cm lateral
    offset, differ slightly at a state set by initial conditions (engines, rates of change)."""
    setup = load_setup(campaign)
    qual = write_replay_aircraft(setup, tmp_path / "q", variant="qualified")
    full = write_replay_aircraft(setup, tmp_path / "f", variant="full")
    bound = 1e-12 if setup.cfg.model == "f15" else 1e-5
    checked_above = 0
    for mid in setup.manifest["maneuver_id"]:
        rec, tru = _record(campaign, mid), _record(campaign, mid, "truth")
        rows = np.linspace(0, rec.height - 1, 25).astype(int)
        q = aero_at_states(setup, qual, rec, rows)
        f = aero_at_states(setup, full, rec, rows)
        t = tru[rows]
        assert np.max(np.abs(q["alpha_deg"].to_numpy() - t["alpha_deg"].to_numpy())) < 1e-9
        for c in ("Cl", "Cn", "CY"):
            sim = (t[f"{c}_sim"] - t[f"{c}_prop_true"]).to_numpy()
            assert np.max(np.abs(q[f"{c}_aero"].to_numpy() - sim)) < bound, (mid, c)
            assert np.max(np.abs(f[f"{c}_aero"].to_numpy() - t[f"{c}_true"].to_numpy())) < bound
            dq = (q[f"{c}_aero"] - f[f"{c}_aero"]).to_numpy()
            assert np.max(np.abs(dq + t[f"d{c}_true"].to_numpy())) < 1e-13, (mid, c)
        above = t["alpha_deg"].to_numpy() > setup.withhold_alpha_deg
        d = np.abs(f["Cl_aero"].to_numpy() - q["Cl_aero"].to_numpy()) + np.abs(
            f["Cn_aero"].to_numpy() - q["Cn_aero"].to_numpy()
        )
        assert np.all(d[~above] == 0.0)  # below the withhold alpha: the same aircraft
        checked_above += int(np.sum(d[above] > 1e-5))
    assert checked_above >= 3  # the frozen terms differ where they should


def test_full_aircraft_replay_reproduces_the_record(campaign: Path, tmp_path: Path) -> None:
    """The full aircraft flown open loop with the recorded surfaces and the fitted throttle
    schedule reproduces the noise-free record. Measured (seed 1): F-15 TIC <= 0.01 on p, r, φ,
    β, DHC-6 <= 0.06 over nine maneuvers; the remainder is the 200 Hz surface motion between
    the 50 Hz samples (interpolated linearly) and, on the DHC-6, the propeller moments' sense
    of the fitted throttle schedule. Bounds: 0.02 (F-15) and 0.05 (DHC-6, two maneuvers,
    measured 0.002-0.02)."""
    setup = load_setup(campaign)
    root = write_replay_aircraft(setup, tmp_path / "f", variant="full")
    bound = 0.02 if setup.cfg.model == "f15" else 0.05
    for mid, seed in zip(setup.manifest["maneuver_id"], setup.manifest["seed"], strict=True):
        rec = _record(campaign, mid)
        rep = replay_maneuver(setup, root, rec, seed=int(seed))
        assert rep.height == rec.height
        assert np.allclose(rep["t"], rec["t"], atol=1e-9)
        # the surfaces at the record's samples are the recorded ones (the first sample is the
        # replay's own trim, within the trim's tolerance of the campaign's: 5e-3 deg)
        for k in ("da_deg", "de_deg", "dr_deg"):
            e = np.abs(rep[k].to_numpy() - rec[k].to_numpy())
            assert np.max(e[1:]) < 1e-6 and e[0] < 0.02, (mid, k)
        for ch in CHANNELS:
            tic = theil_inequality(rec[ch].to_numpy(), rep[ch].to_numpy())
            assert tic < bound, (mid, ch, tic)
        assert np.max(np.abs(rep["alpha_deg"].to_numpy() - rec["alpha_deg"].to_numpy())) < 1.0


def _synthetic_model(flaps: list[float]) -> DeltaModel:
    """Seeded Δ tables on every channel the replay maps (surfaces with their signs, thrust,
    spoilers, rates, sideslip, their rates of change: small, as JSBSim's alpha and beta rates
    lag a frame and a large gain on them oscillates), blended in from 8 to 12 deg."""
    rng = np.random.default_rng(3)
    regs = ["1", "beta_deg", "phat", "rhat", "deadband(da_deg, 2)", "dr_deg", "de_deg",
            "ct_left + ct_right", "ct_diff", "ds_deg", "ct_left", "betadot_dps",
            "alphadot_dps * beta_deg"]  # fmt: skip
    alpha = [-5.0, 5.0, 10.0, 15.0, 20.0, 30.0]
    coefs = {}
    for c in ("CY", "Cl", "Cn"):
        terms = [
            {"name": f"d{c}_{i}", "regressor": r, "alpha_deg": alpha,
             "values": ((1e-5 if "dot" in r else 1e-3)
                        * rng.normal(size=(len(flaps), len(alpha)))).tolist()}
            for i, r in enumerate(regs)
        ]  # fmt: skip
        coefs[c] = {"terms": terms, "alpha_l_deg": [8.0] * len(flaps),
                    "alpha_u_deg": [12.0] * len(flaps)}  # fmt: skip
    return DeltaModel.from_spec(
        {"schema": "aerodelta.model/1", "flaps_deg": flaps, "coefficients": coefs}
    )


def test_extended_increments_equal_engine(campaign: Path, tmp_path: Path) -> None:
    """The Δ the extended aircraft adds (aero/aerodelta/<C>/delta-blended) at the replayed
    states equals DeltaModel.evaluate on channels computed here: the record's surfaces, C_T from
    the replayed thrust / q̄S; p b/2V and r b/2V are the values the export's channel
    functions read (aero/aerodelta/in/phat = p-aero x bi2vel, docs/export.md), checked against
    the replayed body rates times b/2V (within 1e-3 of their range: JSBSim's air-relative rate
    as the aerodynamics read it during the frame differs from the one read after it by up to
    4e-4 relative). The
    first sample is the replay's own trim (its surfaces within the trim's tolerance of the
    record's), so the comparison starts at the second, where the recorded surfaces drive."""
    setup = load_setup(campaign)
    flaps = [0.0] if setup.cfg.model == "f15" else [0.0, 20.0, 40.0]
    model = _synthetic_model(flaps)
    root = write_replay_aircraft(setup, tmp_path / "x", variant="extended", model=model)
    mid = setup.manifest["maneuver_id"][-1]
    rec = _record(campaign, mid)
    props = [f"aero/aerodelta/{c}/delta-blended" for c in ("CY", "Cl", "Cn")]
    props += ["aero/aerodelta/in/phat", "aero/aerodelta/in/rhat"]
    props += ["aero/alphadot-deg_sec", "aero/betadot-deg_sec"]
    rep = replay_maneuver(setup, root, rec, throttle=(1.0, math.inf), extra=props)
    b = rep["b_ft"].to_numpy() * 0.3048
    v = rep["tas_mps"].to_numpy()
    qs = rep["qbar_psf"].to_numpy() * rep["S_sqft"].to_numpy()
    ctl, ctr = rep["thrust_left_lbs"].to_numpy() / qs, rep["thrust_right_lbs"].to_numpy() / qs
    frame = pl.DataFrame(
        {
            "alpha_deg": rep["alpha_deg"],
            "beta_deg": rep["beta_deg"],
            "flap_deg": rec["flap_deg"],
            "phat": rep["aero/aerodelta/in/phat"],
            "rhat": rep["aero/aerodelta/in/rhat"],
            "da_deg": rec["da_deg"],
            "de_deg": rec["de_deg"],
            "dr_deg": rec["dr_deg"],
            "ct_left": ctl,
            "ct_right": ctr,
            "ct_diff": ctl - ctr,
            "ds_deg": np.zeros(rec.height),
            "alphadot_dps": rep["aero/alphadot-deg_sec"],
            "betadot_dps": rep["aero/betadot-deg_sec"],
        }
    )
    # JSBSim's sideslip rate is the derivative of the replayed sideslip (sign and units)
    bdot = np.gradient(rep["beta_deg"].to_numpy(), rep["t"].to_numpy())
    assert np.corrcoef(bdot, rep["aero/betadot-deg_sec"].to_numpy())[0, 1] > 0.95
    for c in ("p", "r"):
        body = np.radians(rep[f"{c}_dps"].to_numpy()) * b / (2 * v)
        hat = rep[f"aero/aerodelta/in/{c}hat"].to_numpy()
        assert np.max(np.abs(hat - body)) < 1e-3 * np.ptp(body), c
    ev = model.evaluate(frame)
    for k in ("da_deg", "de_deg", "dr_deg"):
        assert np.max(np.abs(rep[k].to_numpy()[1:] - rec[k].to_numpy()[1:])) < 1e-6, k
    live = 0
    for c in ("CY", "Cl", "Cn"):
        jsb = rep[f"aero/aerodelta/{c}/delta-blended"].to_numpy()[1:]
        eng = ev[f"d{c}_blended"].to_numpy()[1:]
        scale = float(np.max(np.abs(eng)))
        assert scale > 1e-4  # the Δ acts in this maneuver
        assert np.max(np.abs(jsb - eng)) <= 1e-9 * scale, c
        live += int(np.sum(np.abs(eng) > 0))
    assert live > 100
    # the Δ reaches the moments: at recorded states extended − qualified = w ΔC, plus the Δ side
    # force's moment about the CG (JSBSim applies it at AERORP, on its wind-axis SIDE axis)
    qual = write_replay_aircraft(setup, tmp_path / "q", variant="qualified")
    rows = np.nonzero(rec["alpha_deg"].to_numpy() > 12.0)[0][::25]
    geo = [f"metrics/aero-rp-{a}-in" for a in "xyz"] + [f"inertia/cg-{a}-in" for a in "xyz"]
    geo += ["metrics/bw-ft"]
    ext_s = aero_at_states(setup, root, rec, rows, extra=[*props[:3], *geo])
    qual_s = aero_at_states(setup, qual, rec, rows)
    r = np.array(
        [
            (ext_s[f"metrics/aero-rp-{a}-in"] - ext_s[f"inertia/cg-{a}-in"]).to_numpy() * sg / 12
            for a, sg in zip("xyz", (-1.0, 1.0, -1.0), strict=True)
        ]
    )  # CG -> AERORP, body axes, ft
    al, be = np.radians(ext_s["alpha_deg"].to_numpy()), np.radians(ext_s["beta_deg"].to_numpy())
    wdy = ext_s["aero/aerodelta/CY/delta-blended"].to_numpy()
    fx, fy, fz = -np.cos(al) * np.sin(be) * wdy, np.cos(be) * wdy, -np.sin(al) * np.sin(be) * wdy
    bw = ext_s["metrics/bw-ft"].to_numpy()
    expect = {
        "Cl": ext_s["aero/aerodelta/Cl/delta-blended"].to_numpy() + (r[1] * fz - r[2] * fy) / bw,
        "Cn": ext_s["aero/aerodelta/Cn/delta-blended"].to_numpy() + (r[0] * fy - r[1] * fx) / bw,
        "CY": fy,
    }
    for c in ("Cl", "Cn", "CY"):
        d = (ext_s[f"{c}_aero"] - qual_s[f"{c}_aero"]).to_numpy()
        assert np.max(np.abs(d - expect[c])) <= 1e-9 * np.max(np.abs(expect[c])), c
    # and the dynamics: the extended replay leaves the full one past alpha_l
    full = write_replay_aircraft(setup, tmp_path / "f", variant="full")
    rf = replay_maneuver(setup, full, rec, throttle=(1.0, math.inf))
    assert theil_inequality(rf["p_dps"].to_numpy(), rep["p_dps"].to_numpy()) > 1e-3


def test_score_window_and_campaign_table(campaign: Path) -> None:
    """score_window ends where the recorded alpha is back at the withhold alpha after its
    peak; replay_campaign scores every variant, and a perfect model (the full aircraft)
    scores lower than the qualified one."""
    setup = load_setup(campaign)
    mid = setup.manifest["maneuver_id"][0]
    rec = _record(campaign, mid)
    t_end = score_window(rec, setup.withhold_alpha_deg)
    a, t = rec["alpha_deg"].to_numpy(), rec["t"].to_numpy()
    k = int(np.argmax(a))
    assert a.max() > setup.withhold_alpha_deg
    assert np.all(a[(t > t[k]) & (t < t_end)] > setup.withhold_alpha_deg)
    assert a[t == t_end][0] <= setup.withhold_alpha_deg
    model = _synthetic_model([0.0] if setup.cfg.model == "f15" else [0.0, 20.0, 40.0])
    scores = replay_campaign(campaign, model, maneuvers=[mid])
    assert set(scores["channel"]) == set(CHANNELS)
    assert set(scores["maneuver_id"]) == {mid, "pooled"}
    d = scores.filter((pl.col("window") == "delta") & (pl.col("maneuver_id") == mid))
    assert np.allclose(d["ratio"], d["tic_extended"] / d["tic_qualified"])
    assert (d["tic_full"] < d["tic_qualified"]).all()


def test_bad_input_is_one_line(tmp_path: Path, campaign: Path) -> None:
    with pytest.raises(AerodeltaError, match="missing; give a folder written by"):
        load_setup(tmp_path)
    setup = load_setup(campaign)
    with pytest.raises(AerodeltaError, match="variant 'half'"):
        write_replay_aircraft(setup, tmp_path / "r", variant="half")
    with pytest.raises(AerodeltaError, match=r"not in .*manifest\.csv"):
        replay_campaign(campaign, _synthetic_model([0.0]), maneuvers=["nope"])
    with pytest.raises(AerodeltaError, match="no such Δ model file"):
        replay_campaign(campaign, tmp_path / "missing.json")


def test_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``aerodelta jsbsim-replay`` prints both windows and writes replay_campaign's table;
    refused input is one error line."""
    from aerodelta.cli import main  # noqa: PLC0415

    campaign = tmp_path / "camp"
    generate_jsbsim_campaign(campaign, aircraft="DHC6", seed=1, size="quick", noise=0.0, only=(4,))
    _synthetic_model([0.0, 20.0, 40.0]).save(tmp_path / "model.json")
    mid = "DHC6_004"
    out = tmp_path / "scores.csv"
    argv = ["jsbsim-replay", "--campaign", str(campaign), "--model", str(tmp_path / "model.json")]
    assert main([*argv, "--held-out", mid, "--out", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "window 'predictable'" in text and "window 'delta'" in text and mid in text
    table = pl.read_csv(out)
    assert set(table["window"]) == {"predictable", "delta", "record"}
    assert table.filter(pl.col("maneuver_id") == mid).height == 3 * len(CHANNELS)
    assert main(["jsbsim-replay", "--campaign", str(tmp_path / "nope"), "--model", "m.json"]) == 1
    err = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert err == [
        f"aerodelta jsbsim-replay: error: --campaign {tmp_path / 'nope'}: folder not found"
    ]
