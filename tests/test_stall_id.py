"""Stall identification (Part 60 Attachment 7 criteria) against the virtual aircraft's truth.

The truth of each criterion (``aerodelta.stall.virtual_truth``) is the same definition applied to
the simulator's noise-free signals (``truth/<id>.parquet``: true alpha at the CG, pitch attitude,
acting elevator, load factor, airspeed) and, for the pusher, the time the simulator's own pusher
fired; the records carry noise, sensor offsets, biases and turbulence-driven vane errors. The
detector itself is checked on analytic signals, the pusher against its activation alpha.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta.cli import main
from aerodelta.stall import (
    AFT_STOP_HOLD_S,
    KT,
    RHO0,
    detect_criteria,
    stall_identification,
    stall_summary,
    validity_range,
    virtual_truth,
)

#: The ADX-37's C_L,max alpha per flap (crates/aero_core/src/aircraft/qualified.rs FLAP_STALL,
#: docs/aircraft.md): its pusher fires 1 deg below, its stall warning 5 deg below.
ALPHA_MAX = {0.0: 19.5, 5.0: 19.0, 10.0: 18.5, 15.0: 18.5, 35.0: 18.0}


@pytest.fixture(scope="module")
def ingested(quick_campaign: Path) -> pl.DataFrame:
    return ad.ingest(quick_campaign, progress=False, compat=False).data


@pytest.fixture(scope="module")
def table(ingested: pl.DataFrame) -> pl.DataFrame:
    return stall_identification(ingested)


def test_identified_alpha_and_speeds_match_the_truth(
    quick_campaign: Path, table: pl.DataFrame
) -> None:
    j = virtual_truth(quick_campaign, table)
    # every maneuver the truth identifies is identified, by the same criterion
    assert (j["truth_by"].is_null() == j["stall_id_by"].is_null()).all(), j.filter(
        j["truth_by"].is_null() != j["stall_id_by"].is_null()
    ).select("maneuver_id", "truth_by", "stall_id_by")
    both = j.filter(pl.col("truth_by").is_not_null())
    assert both.height >= 20, both.height  # the floor is measured on most of the campaign
    # by the same criterion, or by one the truth meets within 0.5 s of its first (a near tie)
    for r in both.filter(pl.col("truth_by") != pl.col("stall_id_by")).iter_rows(named=True):
        other = r[f"truth_{r['stall_id_by']}_t_s"]
        assert other is not None and other - r["truth_t_s"] < 0.5, r
    d_alpha = (both["stall_id_alpha_deg"] - both["truth_alpha_deg"]).abs()
    d_v = (both["v_stall_keas"] - both["truth_v_stall_keas"]).abs()
    assert d_alpha.max() < 0.5, both.select("maneuver_id", "stall_id_alpha_deg", "truth_alpha_deg")
    assert d_v.max() < 1.0, both.select("maneuver_id", "v_stall_keas", "truth_v_stall_keas")
    d_w = (j["v_warning_keas"] - j["truth_v_warning_keas"]).abs()
    assert j["v_warning_keas"].is_not_null().all() and d_w.max() < 1.0
    # the pusher criterion: at the pusher's activation alpha (C_L,max alpha - 1 deg)
    push = j.filter(pl.col("stall_id_by") == "pusher")
    assert push.height >= 8
    on = push["flap_deg"].replace_strict(ALPHA_MAX) - 1.0
    assert ((push["pusher_alpha_deg"] - on).abs() < 0.5).all()
    assert ((push["pusher_t_s"] - push["truth_t_s"]).abs() <= 0.02 + 1e-9).all()
    # the warning comes before the stall (its speed need not be higher: the alpha-only warning
    # has no alpha-rate lead, and the entries are not all 1-g decelerations; docs/stall.md)
    assert (j["warning_t_s"] < j["stall_id_t_s"]).drop_nulls().all()


def test_without_the_optional_channels(ingested: pl.DataFrame, table: pl.DataFrame) -> None:
    bare = stall_identification(ingested.drop("pusher_active", "stall_warning"))
    for c in ("pusher_t_s", "pusher_alpha_deg", "warning_t_s", "v_warning_keas"):
        assert bare[c].is_null().all(), c
    note = bare["not_assessed"][0]
    assert "pusher: no pusher_active channel" in note and "stall_warning" in note
    # the buffet is assessed from the raw normal accelerometer (docs/stall.md, "Buffet")
    assert "buffet" not in note
    # the criteria it can assess are those of the full record
    for c in ("pitch_break_alpha_deg", "g_break_alpha_deg", "aft_stop_alpha_deg"):
        assert bare[c].to_list() == table[c].to_list(), c
    assert "pusher" not in table["not_assessed"][0].split(";")[1:]


def test_summary_and_validity(ingested: pl.DataFrame, table: pl.DataFrame) -> None:
    s = stall_summary(table)
    assert s["n_maneuvers"].sum() == table.height == 40
    counts = table.group_by("stall_id_by").len().drop_nulls()
    for r in counts.iter_rows(named=True):
        assert s[f"by_{r['stall_id_by']}"].sum() == r["len"]
    coverage, verdict = validity_range(ingested, table, band_deg=2.0)
    # coverage against a direct count
    a = ingested["alpha_cg_deg"].to_numpy()
    f = ingested["flap_deg"].to_numpy()
    sel = (f == 10.0) & (a >= 16.0) & (a < 18.0)
    row = coverage.filter((pl.col("flap_deg") == 10.0) & (pl.col("alpha_lo_deg") == 16.0))
    assert row["n_samples"][0] == sel.sum()
    assert row["n_maneuvers"][0] == len(set(ingested["maneuver_id"].to_numpy()[sel]))
    assert verdict.height == 5
    for r in verdict.iter_rows(named=True):
        flap = r["flap_deg"]
        want = table.filter(pl.col("flap_deg") == flap)["stall_id_alpha_deg"].max()
        assert r["required_deg"] == pytest.approx(want + 10.0)
        assert r["alpha_reached_deg"] == pytest.approx(a[f == flap].max())
        # the virtual campaign flies to a few deg past the stall: +10 deg is not covered
        assert not r["covered"] and "not covered" in r["verdict"]
        assert r["verdict"].startswith(f"flap {flap:g}: data to ")


def test_validity_covered_on_data_that_reach_it() -> None:
    t = np.arange(0.0, 40.0, 0.05)
    alpha = 2.0 + 0.8 * t  # 2 .. 34 deg
    frames = [
        pl.DataFrame({"maneuver_id": f"m{i}", "t": t, "alpha_deg": alpha + i, "flap_deg": 10.0})
        for i in range(3)
    ]
    data = pl.concat(frames)
    table = pl.DataFrame({"flap_deg": [10.0] * 3, "stall_id_alpha_deg": [16.0, 17.0, 16.5]})
    base = pl.DataFrame({c: [0.0] for c in ("theta_deg", "de_deg", "tas_mps", "rho_kgm3")})
    data = data.join(base, how="cross")
    _, verdict = validity_range(data, table)
    r = verdict.row(0, named=True)
    assert r["required_deg"] == 27.0 and r["covered"] and r["n_maneuvers_beyond"] == 3
    assert r["n_samples_beyond"] == int(sum(((alpha + i) >= 27.0).sum() for i in range(3)))
    assert "covered by 3 maneuvers" in r["verdict"]


def test_detectors_on_known_signals() -> None:
    t = np.arange(0.0, 12.0, 0.02)
    alpha = np.minimum(8.0 + t, 17.0)
    # aft stop: the elevator reaches -20 deg at t = 4 s and stays, pitch flat from there
    de = np.where(t < 4.0, -20.0 * t / 4.0, -20.0)
    theta = np.where(t < 4.0, t, 4.0)
    got = detect_criteria(t, alpha, theta, de, aft_stop_deg=-20.0)
    assert t[got["aft_stop"]] == pytest.approx(4.0 + AFT_STOP_HOLD_S, abs=0.03)
    # still pitching up at the stop: not met
    assert detect_criteria(t, alpha, t, de, aft_stop_deg=-20.0)["aft_stop"] is None
    # a pitch break at 9 s (theta falls 5 deg/s) with the elevator held: met there
    theta = np.where(t < 9.0, 5.0, 5.0 - 5.0 * (t - 9.0))
    de = np.full_like(t, -5.0)
    k = detect_criteria(t, alpha, theta, de)["pitch_break"]
    assert k is not None and abs(t[k] - 9.0) < 0.2
    # the same nose-down pitch commanded (elevator 3 deg nose down just before): not met
    de_push = np.where(t < 8.8, -5.0, -2.0)
    assert detect_criteria(t, alpha, theta, de_push)["pitch_break"] is None
    # a g-break: n falls 0.2 g at constant alpha from t = 10 s
    nz = np.where(t < 10.0, 1.0, 1.0 - 0.2 * (t - 10.0))
    k = detect_criteria(t, alpha, np.full_like(t, 5.0), de, nz=nz)["g_break"]
    assert k is not None and abs(t[k] - 10.5) < 0.1
    # the same loss with alpha falling (a pushover): not a g-break
    a_down = np.where(t < 10.0, alpha, 17.0 - 3.0 * (t - 10.0))
    assert detect_criteria(t, a_down, np.full_like(t, 5.0), de, nz=nz)["g_break"] is None


def test_bad_input_is_one_line(ingested: pl.DataFrame) -> None:
    one = ingested.filter(pl.col("maneuver_id") == "m003_f00_turning_n")
    bad = one.with_columns(
        pl.when(pl.int_range(pl.len()) == 7).then(float("nan")).otherwise(pl.col("theta_deg"))
        .alias("theta_deg")
    )  # fmt: skip
    with pytest.raises(ad.DataError) as e:
        stall_identification(bad)
    msg = str(e.value)
    assert "\n" not in msg and "m003_f00_turning_n" in msg and "theta_deg" in msg
    assert "row 7" in msg
    with pytest.raises(ad.DataError, match=r"no flap_deg column") as e:
        stall_identification(one.drop("flap_deg"))
    assert "\n" not in str(e.value)
    no_flap = one.with_columns(pl.lit(None, dtype=pl.Float64).alias("flap_deg"))
    with pytest.raises(ad.DataError, match=r"m003_f00_turning_n: flap_deg has no flap setting"):
        stall_identification(no_flap)
    with pytest.raises(ad.DataError, match=r"no de_deg"):
        stall_identification(one.drop("de_deg"))


def test_cli(quick_campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "res" / "stall.csv"
    code = main(["stall-id", "--data", str(quick_campaign), "--out", str(out), "--no-progress"])
    text = capsys.readouterr().out
    assert code == 0
    got = pl.read_csv(out)
    assert got.height == 40 and "stall_id_alpha_deg" in got.columns
    for k in ("summary", "coverage", "validity"):
        assert (out.parent / f"stall.{k}.csv").is_file()
    assert "flap 10: data to " in text and "flap 10: buffet in 0 of 8 maneuvers" in text
    code = main(["stall-id", str(quick_campaign), "--band", "0"])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and "--band 0" in err


def test_g_break_reads_lift_not_the_load_factor_s_decay_with_speed() -> None:
    # an accelerated entry: 2 g at constant lift coefficient while the speed falls 8 kt/s from
    # 140 kt (closed form n = 2 (V/V0)^2); alpha creeps up. The load factor falls 0.1 g in
    # under 0.5 s, which the load factor alone calls a g-break, lift per dynamic pressure not
    t = np.arange(0.0, 6.0, 0.02)
    v = (140.0 - 8.0 * t) * KT
    qbar = 0.5 * RHO0 * v**2
    nz = 2.0 * (v / v[0]) ** 2
    alpha = 15.0 + 0.2 * t
    de = np.full_like(t, -8.0)
    theta = np.full_like(t, 20.0)
    assert detect_criteria(t, alpha, theta, de, nz=nz)["g_break"] is not None
    assert detect_criteria(t, alpha, theta, de, nz=nz, qbar=qbar)["g_break"] is None
    # lift lost at t = 4 s (n 20 % below the constant-C_L value by 4.5 s): a g-break, where
    # the loss at the current dynamic pressure first reaches 0.1 g (the closed form's time)
    loss = np.clip((t - 4.0) / 0.5, 0.0, 1.0) * 0.2
    nz_b = nz * (1.0 - loss)
    k = detect_criteria(t, alpha, theta, de, nz=nz_b, qbar=qbar)["g_break"]
    t_expect = t[np.flatnonzero(nz * loss >= 0.1)[0]]
    assert k is not None and abs(t[k] - t_expect) < 0.1, (t[k], t_expect)


def test_entry_deceleration_is_the_eas_slope_before_identification(
    ingested: pl.DataFrame, table: pl.DataFrame
) -> None:
    # recomputed from the records' equivalent airspeed: (V(t_id - 3 s) - V(t_id)) / 3 s
    for r in table.filter(pl.col("stall_id_by").is_not_null()).head(8).iter_rows(named=True):
        g = ingested.filter(pl.col("maneuver_id") == r["maneuver_id"]).sort("t")
        t = g["t"].to_numpy()
        eas = g["tas_s_mps"].to_numpy() * np.sqrt(g["rho_kgm3"].to_numpy() / RHO0) / KT
        t1 = r["stall_id_t_s"]
        want = (np.interp(t1 - 3.0, t, eas) - np.interp(t1, t, eas)) / 3.0
        assert r["entry_decel_kt_s"] == pytest.approx(want, abs=1e-9)
    # 1 kt/s wings-level entries and the accelerated ones are told apart at 3 kt/s
    # (14 CFR 25.201(c): turning-flight stalls up to 3 kt/s)
    k = table.filter(pl.col("entry_decel_kt_s").is_not_null())
    assert (k.filter(pl.col("kind") == "straight")["entry_decel_kt_s"] < 3.0).all()
    acc = k.filter(pl.col("kind") == "accelerated")["entry_decel_kt_s"]
    assert acc.len() and (acc > 3.0).mean() >= 0.5, acc.to_list()


def test_speeds_are_equivalent_airspeed(ingested: pl.DataFrame, table: pl.DataFrame) -> None:
    r = table.filter(pl.col("stall_id_by").is_not_null()).row(0, named=True)
    g = ingested.filter(pl.col("maneuver_id") == r["maneuver_id"])
    k = int(np.argmin(np.abs(g["t"].to_numpy() - r["stall_id_t_s"])))
    tas, rho = g["tas_s_mps"][k], g["rho_kgm3"][k]
    assert r["v_stall_ktas"] == pytest.approx(tas / KT)
    assert r["v_stall_keas"] == pytest.approx(tas * np.sqrt(rho / RHO0) / KT)
