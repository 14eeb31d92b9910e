"""Every refusal and warning of validation, fed a bad file, checked on its message."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta
from _ingest_synth import AIRCRAFT_TOML, canonical_frame, motion
from aerodelta import DataError
from aerodelta.validate import az_medians, screen_many, unit_checks_only, validate

T = np.arange(0.0, 20.0, 0.02)
BASE = motion(T, seed=11)


def _write(tmp_path: Path, df: pl.DataFrame, name: str = "bad.csv") -> Path:
    (tmp_path / "aircraft.toml").write_text(AIRCRAFT_TOML)
    p = tmp_path / name
    df.write_csv(p)
    return p


def _refused(tmp_path: Path, df: pl.DataFrame, **kw: object) -> str:
    p = _write(tmp_path, df)
    with pytest.raises(DataError) as e:
        aerodelta.ingest(p, aircraft=tmp_path / "aircraft.toml", progress=False, **kw)
    msg = str(e.value)
    assert "bad.csv" in msg
    return msg


def test_missing_required_channel(tmp_path: Path) -> None:
    msg = _refused(tmp_path, canonical_frame(BASE).drop("beta_deg", "tas_mps"))
    assert "'beta_deg'" in msg and "required channel missing" in msg
    assert "'tas_mps'" in msg and "ps_pa" in msg  # says what could replace it


def test_duplicated_and_non_increasing_time(tmp_path: Path) -> None:
    t = T.copy()
    t[100] = t[99]
    msg = _refused(tmp_path, canonical_frame({**BASE, "t": t}))
    assert "'t', rows 99-100" in msg and "duplicated" in msg
    t = T.copy()
    t[200], t[201] = t[201], t[200]
    msg = _refused(tmp_path, canonical_frame({**BASE, "t": t}))
    assert "'t', rows" in msg and "non-increasing" in msg and "200" in msg


def test_nan_run_is_refused_unless_interpolation_is_allowed(tmp_path: Path) -> None:
    q = BASE["q_dps"].copy()
    q[300:304] = np.nan
    df = canonical_frame({**BASE, "q_dps": q})
    msg = _refused(tmp_path, df)
    assert "'q_dps', rows 300-303" in msg and "4 NaN/inf" in msg and "allow_interpolation" in msg
    res = aerodelta.ingest(
        tmp_path / "bad.csv",
        aircraft=tmp_path / "aircraft.toml",
        allow_interpolation=True,
        compat=False,
        progress=False,
    )
    w = [f for f in res.reports[0].findings if f.channel == "q_dps"]
    assert w and w[0].severity == "warning" and w[0].rows == "300-303"
    assert "interpolated" in w[0].message
    assert np.isfinite(res.data["q_dps"].to_numpy()).all()
    # a long run is refused even when interpolation is allowed
    q[300:340] = np.nan
    msg = _refused(tmp_path, canonical_frame({**BASE, "q_dps": q}), allow_interpolation=True)
    assert "'q_dps', rows 300-339" in msg


def test_sample_rate_change(tmp_path: Path) -> None:
    t = np.concatenate((T[:500], T[499] + 0.01 * np.arange(1, len(T) - 499)))
    msg = _refused(tmp_path, canonical_frame({**BASE, "t": t}))
    assert (
        "sample rate changes" in msg and "rows 499-500" in msg and "0.01 s at rows 499-500" in msg
    )


def test_alpha_in_radians_declared_as_degrees(tmp_path: Path) -> None:
    msg = _refused(tmp_path, canonical_frame({**BASE, "alpha_deg": np.radians(BASE["alpha_deg"])}))
    assert "'alpha_deg'" in msg and "radians" in msg


def _low_alpha_cruise(seed: int = 3) -> dict[str, np.ndarray]:
    """A legitimate, kinematically exact cruise record with alpha within ±0.4 deg (degrees):
    V = 80 m/s, wings level, gentle pitch and alpha oscillations; specific forces from thesis
    Eq. 3.1a, 3.1c (u = V cos α, w = V sin α, a = V̇ + ω×V − g_body), small sensor noise."""
    rng = np.random.default_rng(seed)
    t = T
    vt = 80.0
    al = np.radians(0.1 + 0.3 * np.sin(0.5 * t))
    ald = np.radians(0.3 * 0.5 * np.cos(0.5 * t))
    th = np.radians(2.0 + 1.0 * np.sin(0.3 * t))
    q = np.radians(1.0 * 0.3 * np.cos(0.3 * t))
    u, w = vt * np.cos(al), vt * np.sin(al)
    ud, wd = -vt * np.sin(al) * ald, vt * np.cos(al) * ald
    ax = ud + q * w + 9.80665 * np.sin(th)
    az = wd - q * u - 9.80665 * np.cos(th)
    zero = np.zeros_like(t)
    m = dict(BASE)
    m.update(
        alpha_deg=np.degrees(al) + 0.01 * rng.standard_normal(len(t)),
        beta_deg=zero + 0.01 * rng.standard_normal(len(t)),
        p_dps=zero + 0.05 * rng.standard_normal(len(t)),
        q_dps=np.degrees(q) + 0.05 * rng.standard_normal(len(t)),
        r_dps=zero + 0.05 * rng.standard_normal(len(t)),
        phi_deg=zero,
        theta_deg=np.degrees(th),
        psi_deg=zero + 30.0,
        ax_mps2=ax + 0.02 * rng.standard_normal(len(t)),
        ay_mps2=zero + 0.02 * rng.standard_normal(len(t)),
        az_mps2=az + 0.02 * rng.standard_normal(len(t)),
        tas_mps=np.full_like(t, vt) + 0.1 * rng.standard_normal(len(t)),
    )
    return m


def test_low_alpha_cruise_in_degrees_is_accepted(tmp_path: Path) -> None:
    m = _low_alpha_cruise()
    assert np.abs(m["alpha_deg"]).max() < 0.6  # the old value-only detector refused this
    p = _write(tmp_path, canonical_frame(m), name="cruise.csv")
    res = aerodelta.ingest(p, aircraft=tmp_path / "aircraft.toml", compat=False, progress=False)
    assert [f for f in res.reports[0].findings if f.channel == "alpha_deg"] == []
    # the same cruise with alpha in radians declared as degrees is refused
    msg = _refused(tmp_path, canonical_frame({**m, "alpha_deg": np.radians(m["alpha_deg"])}))
    assert "'alpha_deg'" in msg and "radians" in msg


def test_rates_in_rad_per_s_declared_as_deg_per_s(tmp_path: Path) -> None:
    m = {**BASE, **{c: np.radians(BASE[c]) for c in ("p_dps", "q_dps", "r_dps")}}
    msg = _refused(tmp_path, canonical_frame(m))
    assert "p_dps, q_dps, r_dps" in msg and "rad/s" in msg


def test_acceleration_in_g_and_out_of_range_values(tmp_path: Path) -> None:
    msg = _refused(tmp_path, canonical_frame({**BASE, "az_mps2": BASE["az_mps2"] / 9.80665}))
    assert "'az_mps2'" in msg and "g declared" in msg
    beta = BASE["beta_deg"].copy()
    beta[50:53] = 120.0
    msg = _refused(tmp_path, canonical_frame({**BASE, "beta_deg": beta}))
    assert "'beta_deg', rows 50-52" in msg and "physical range" in msg


def test_all_problems_reported_at_once(tmp_path: Path) -> None:
    q = BASE["q_dps"].copy()
    q[10] = np.inf
    msg = _refused(tmp_path, canonical_frame({**BASE, "q_dps": q}).drop("da_deg"))
    assert "2 problem(s)" in msg and "'da_deg'" in msg and "'q_dps', rows 10" in msg


def test_stuck_and_clipped_sensors_warn(tmp_path: Path) -> None:
    ay = BASE["ay_mps2"].copy()
    top = np.quantile(ay, 0.9)
    ay = np.minimum(ay, top)  # clipped sensor
    df = canonical_frame({**BASE, "ay_mps2": ay, "beta_deg": np.full(len(T), 1.5)})
    out, rep = validate(df, "f.csv", "m")
    assert rep.ok
    by = {f.channel: f for f in rep.findings}
    assert by["beta_deg"].severity == "warning" and "stuck" in by["beta_deg"].message
    assert by["ay_mps2"].severity == "warning" and "clipped" in by["ay_mps2"].message
    frame = rep.to_frame()
    assert frame.columns == ["severity", "file", "maneuver_id", "channel", "rows", "message"]
    assert frame.height == len(rep.findings)
    js = json.loads(rep.to_json())
    assert js["ok"] is True and len(js["findings"]) == len(rep.findings)
    assert out.height == len(T)


def test_channel_map_errors_name_the_entry(tmp_path: Path) -> None:
    bad = tmp_path / "map.toml"
    bad.write_text(
        '[channels]\nalpha_deg = { source = "AOA", unit = "kt" }\n'
        'foo = { source = "X", unit = "deg" }\n'
    )
    with pytest.raises(DataError) as e:
        aerodelta.ChannelMap.from_toml(bad)
    assert "'alpha_deg'" in str(e.value) and "speed" in str(e.value)
    assert "'foo' is not a canonical channel" in str(e.value)
    ok = tmp_path / "ok.toml"
    ok.write_text('[channels]\nalpha_deg = { source = "AOA", unit = "rad" }\n')
    p = _write(tmp_path, canonical_frame(BASE))
    with pytest.raises(DataError, match=r"bad.csv: channel map .* 'AOA' \(for alpha_deg\)"):
        aerodelta.ingest(p, aircraft=tmp_path / "aircraft.toml", channel_map=ok, progress=False)


def test_aircraft_and_manifest_errors(tmp_path: Path) -> None:
    a = tmp_path / "a.toml"
    a.write_text(AIRCRAFT_TOML.replace("b_m = 27.05", "b_m = -1").replace("S_m2 = 61.0\n", ""))
    with pytest.raises(DataError) as e:
        aerodelta.Aircraft.from_toml(a)
    assert "[geometry] S_m2 is missing" in str(e.value) and "b_m = -1 must be positive" in str(
        e.value
    )
    m = tmp_path / "manifest.csv"
    m.write_text("maneuver_id,flap_deg,kind,pusher\nx,0,straight,true\ny,0,spin,maybe\n")
    from aerodelta.readers import read_manifest  # noqa: PLC0415

    with pytest.raises(DataError, match=r"column 'kind', rows 1: unknown kind"):
        read_manifest(m)


def test_vectorised_screen_agrees_with_validate() -> None:
    """The campaign fast path (screen_many + unit checks) flags every record that validate
    finds anything wrong with, and gives exactly validate's findings for the ones it passes."""
    q_nan = BASE["q_dps"].copy()
    q_nan[300] = np.nan
    p_stuck = BASE["p_dps"].copy()
    p_stuck[400:460] = p_stuck[400]
    t_jump = T.copy()
    t_jump[600:] += 0.005
    variants = {
        "good": BASE,
        "nan": {**BASE, "q_dps": q_nan},
        "stuck": {**BASE, "p_dps": p_stuck},
        "time": {**BASE, "t": t_jump},
        "alpha_rad": {**BASE, "alpha_deg": np.radians(BASE["alpha_deg"])},
        "rates_rad": {**BASE, **{c: np.radians(BASE[c]) for c in ("p_dps", "q_dps", "r_dps")}},
        "good2": motion(T, seed=12),
    }
    frames = [canonical_frame(m) for m in variants.values()]
    big = pl.concat(frames, rechunk=True)
    cols = {c: big[c].to_numpy() for c in big.columns}
    offsets = np.concatenate(([0], np.cumsum([f.height for f in frames])))
    clean, views = screen_many(cols, offsets)
    med = az_medians(cols, offsets)
    assert med is not None
    for i, (name, f) in enumerate(zip(variants, frames, strict=True)):
        _, rep = validate(f, "x.csv", name)
        if clean[i]:
            fast = unit_checks_only(views[i], "x.csv", name, float(med[i]))
            assert fast.findings == rep.findings, name
        else:
            assert rep.findings, name
    assert clean.tolist() == [True, False, False, False, False, True, True]
