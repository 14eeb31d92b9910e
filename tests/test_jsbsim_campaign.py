"""JSBSim virtual flight tests: determinism, end-to-end reconstruction against JSBSim's own
coefficients, the exact true Δ, the CLI layout and the error messages."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import polars as pl
import pytest

pytest.importorskip("jsbsim", reason="needs the jsbsim package: pip install 'aerodelta[jsbsim]'")

import aerodelta
from aerodelta.cli import main
from aerodelta.exceptions import InvalidInputError
from aerodelta.jsbsim_campaign import (
    generate_jsbsim_campaign,
    true_delta_derivative,
)

D2R = math.pi / 180.0

# F-15 tables typed from jsbsim 1.3.3 aircraft/f15/f15.xml (an independent reference for the
# module's own XML evaluation): alpha in rad -> coefficient per rad of beta.
F15_CNB = ([-0.3490, 0.0000, 0.3490, 0.5240, 0.8730], [0.0745, 0.1776, 0.0057, -0.0974, -0.0286])
F15_CLB = (
    [-0.3490, -0.1750, 0.0000, 0.2090, 0.3140, 0.4190, 0.6980, 0.7850, 0.8730],
    [0.0286, -0.2292, -0.0573, -0.1719, -0.1146, -0.1719, -0.0745, -0.1146, -0.1203],
)
WALPHA = 12.0


@pytest.fixture(scope="module")
def f15_exact(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three F-15 maneuvers (straight, turning, sideslip), exact sensors."""
    out = tmp_path_factory.mktemp("jsb") / "f15"
    generate_jsbsim_campaign(out, aircraft="f15", seed=3, size="quick", noise=0.0)
    return out


@pytest.fixture(scope="module")
def dhc6_exact(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two DHC-6 maneuvers (flaps 0 and 20 deg), exact sensors."""
    out = tmp_path_factory.mktemp("jsb") / "dhc6"
    generate_jsbsim_campaign(out, aircraft="DHC6", seed=5, size="quick", only=[0, 4], noise=0.0)
    return out


def _files(d: Path) -> dict[str, bytes]:
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def test_same_seed_same_bytes(tmp_path: Path) -> None:
    kw = {"aircraft": "f15", "size": "quick", "only": [1, 2], "turbulence": 1.0}
    generate_jsbsim_campaign(tmp_path / "a", seed=11, **kw)
    generate_jsbsim_campaign(tmp_path / "b", seed=11, **kw)
    generate_jsbsim_campaign(tmp_path / "c", seed=12, **kw)
    a, b, c = _files(tmp_path / "a"), _files(tmp_path / "b"), _files(tmp_path / "c")
    assert set(a) == set(b) and len(a) >= 8
    assert a == b
    assert a["records/f15_001.parquet"] != c["records/f15_001.parquet"]
    # nothing left behind by the atomic write
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b", "c"]


def _reconstruction(campaign: Path) -> dict[tuple[str, str], tuple[float, float]]:
    """rms(measured - JSBSim) / range, for aero only and aero + propulsion."""
    res = aerodelta.ingest(campaign, compat=False, smooth=False)
    out = {}
    for (mid,), g in res.data.group_by("maneuver_id", maintain_order=True):
        tr = pl.read_parquet(campaign / "truth" / f"{mid}.parquet")
        assert tr.height == g.height
        k = slice(3, -3)  # central differences of the rates need both neighbours
        for c in ("Cl", "Cn", "CY"):
            meas = g[f"{c}_meas"].to_numpy()[k]
            aero = tr[f"{c}_true"].to_numpy()[k]
            total = aero + tr[f"{c}_prop_true"].to_numpy()[k]
            rng = float(np.ptp(aero))
            out[(str(mid), c)] = (
                float(np.sqrt(np.mean((meas - aero) ** 2)) / rng),
                float(np.sqrt(np.mean((meas - total) ** 2)) / rng),
            )
    return out


def test_reconstruction_f15(f15_exact: Path) -> None:
    """aerodelta's measured Cl, Cn, CY from the exact sensors (Eq. 3.2-3.4 with the
    aircraft.toml inertias) against JSBSim's own aero coefficients about the CG: units, signs,
    inertias (Ixz sign), specific force and frames end to end. A jet: no propulsion moments."""
    rec = _reconstruction(f15_exact)
    assert len(rec) == 9
    for (mid, c), (aero, _) in rec.items():
        tol = 1e-5 if c == "CY" else 0.01  # measured 0.3 % for Cl, Cn (50 Hz differences)
        assert aero <= tol, (mid, c, aero)


def test_reconstruction_dhc6_with_propulsion(dhc6_exact: Path) -> None:
    """The DHC-6's propellers add roll and yaw moments: the inertial measurement agrees with
    JSBSim's aero + propulsion moments (1 %), and differs from aero alone by the truth's
    C*_prop_true (Cl: several % of the range)."""
    rec = _reconstruction(dhc6_exact)
    for (mid, c), (aero, total) in rec.items():
        assert total <= (1e-5 if c == "CY" else 0.02), (mid, c, total)
        if c == "Cl":
            assert aero > 2 * total, (mid, aero, total)


def test_true_delta_exact(f15_exact: Path) -> None:
    info = json.loads((f15_exact / "truth" / "truth.json").read_text())
    assert info["withhold_alpha_deg"] == WALPHA
    assert [w["name"] for w in info["withheld"]] == ["Clb", "Clp", "Cnb"]
    assert info["terms_not_evaluated"] == []
    all_delta = pl.read_parquet(f15_exact / "truth" / "true_delta.parquet")
    above = 0
    for f in sorted((f15_exact / "records").glob("*.parquet")):
        rec = pl.read_parquet(f)
        tr = pl.read_parquet(f15_exact / "truth" / f.name)
        a = tr["alpha_deg"].to_numpy()
        b = tr["beta_deg"].to_numpy() * D2R
        for c in ("Cl", "Cn", "CY"):
            d = tr[f"d{c}_true"].to_numpy()
            # full - qualified, the qualified model is what the records carry
            full_minus_sim = tr[f"{c}_true"].to_numpy() - rec[f"{c}_sim"].to_numpy()
            np.testing.assert_allclose(d, full_minus_sim, rtol=0, atol=1e-15)
            assert np.all(d[a <= WALPHA] == 0.0)
        assert np.all(tr["dCY_true"].to_numpy() == 0.0)
        dcl = tr["dterm_Clb"].to_numpy() + tr["dterm_Clp"].to_numpy()
        np.testing.assert_allclose(tr["dCl_true"].to_numpy(), dcl, rtol=0, atol=1e-15)
        # JSBSim's own term values and the true Δ against the XML tables typed in above
        cnb = np.interp(a * D2R, *F15_CNB)
        cnb_q = np.interp(np.minimum(a, WALPHA) * D2R, *F15_CNB)
        np.testing.assert_allclose(tr["term_Cnb"].to_numpy(), cnb * b, rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            tr["dterm_Cnb"].to_numpy(), (cnb - cnb_q) * b, rtol=0, atol=1e-12
        )
        clb = np.interp(a * D2R, *F15_CLB) - np.interp(np.minimum(a, WALPHA) * D2R, *F15_CLB)
        np.testing.assert_allclose(tr["dterm_Clb"].to_numpy(), clb * b, rtol=0, atol=1e-12)
        above += int(np.sum(np.abs(tr["dCn_true"].to_numpy()) > 1e-4))
        sub = all_delta.filter(pl.col("maneuver_id") == f.stem)
        assert np.array_equal(sub["dCn_true"].to_numpy(), tr["dCn_true"].to_numpy())
    assert above > 50  # the maneuvers reach past the withhold alpha with sideslip
    # the per-term derivative in the fit's units (per deg of beta)
    grid = np.array([5.0, 12.0, 15.0, 18.0, 20.0, 30.0])
    want = np.interp(grid * D2R, *F15_CNB) - np.interp(np.minimum(grid, WALPHA) * D2R, *F15_CNB)
    got = true_delta_derivative(f15_exact, "Cn", "beta_deg", 0.0, grid)
    np.testing.assert_allclose(got, want * D2R, rtol=1e-6, atol=1e-12)
    assert np.all(true_delta_derivative(f15_exact, "Cn", "rhat", 0.0, grid) == 0.0)


def test_sideslip_short_of_its_command_is_noted(tmp_path: Path, f15_exact: Path) -> None:
    """The JSBSim DHC-6 cannot hold its commanded sideslip at flap 20 (Cn_beta 1.0-2.5 per rad
    against Cn_dr -0.125 per rad and 0.28 rad of rudder: about 1 deg at full rudder); the
    manifest says so, with the sideslip the records hold. The F-15's entry gets no note."""
    info = generate_jsbsim_campaign(
        tmp_path / "d", aircraft="DHC6", seed=5, size="quick", only=[5], noise=0.0
    )
    row = info.manifest.row(0, named=True)
    assert row["entry"] == "sideslip" and row["flap_deg"] == 20.0
    m = re.search(r"sideslip entry held ([0-9.]+) deg of sideslip against ([0-9.]+) deg "
                  r"commanded, the rudder at ([0-9]+) % of its travel", row["notes"])  # fmt: skip
    assert m is not None, row["notes"]
    held, cmd, rudder = float(m[1]), float(m[2]), float(m[3])
    assert 5.0 <= cmd <= 9.0 and held < 0.5 * cmd
    assert rudder >= 70.0  # the pilot uses the rudder; the aircraft does not follow
    # the records: median |beta| from the deceleration's start (4 s) to the stall
    tr = pl.read_parquet(tmp_path / "d" / "truth" / f"{row['maneuver_id']}.parquet")
    t = tr["t"].to_numpy()
    beta = np.abs(tr["beta_deg"].to_numpy()[(t >= 4.0) & (t <= row["t_stall_s"])])
    assert abs(float(np.median(beta)) - held) <= 0.3 and held < 2.0
    man = pl.read_csv(f15_exact / "manifest.csv")
    assert not man["notes"].str.contains("sideslip entry held").any()


def test_cli_counts_the_short_sideslips(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    args = ["campaign", "--simulator", "jsbsim", "--aircraft", "DHC6", "--quick", "--seed", "5"]
    assert main([*args, "--no-progress", "--out", str(tmp_path / "c")]) == 0
    out = capsys.readouterr().out
    m = re.search(r"note: (\d) of 3 sideslip entries held less than half their commanded "
                  r"sideslip \(flaps ([0-9, ]+) deg", out)  # fmt: skip
    assert m is not None, out
    man = pl.read_csv(tmp_path / "c" / "manifest.csv")
    short = man.filter(pl.col("notes").str.contains("sideslip entry held", literal=True))
    assert int(m[1]) == short.height >= 2
    assert m[2] == ", ".join(f"{f:g}" for f in sorted(set(short["flap_deg"])))


def test_control_signs_follow_etkin(f15_exact: Path) -> None:
    """Positive da, dr give negative Cl, Cn in JSBSim's own moment terms (aerodelta's
    convention), checked on the recorded surface positions."""
    for f in sorted((f15_exact / "records").glob("*.parquet")):
        rec = pl.read_parquet(f)
        tr = pl.read_parquet(f15_exact / "truth" / f.name)
        da, dr = rec["da_deg"].to_numpy(), rec["dr_deg"].to_numpy()
        big_a, big_r = np.abs(da) > 0.5, np.abs(dr) > 0.5
        assert big_a.sum() > 20 and big_r.sum() > 20
        assert np.all(tr["term_ClDa"].to_numpy()[big_a] * da[big_a] < 0)
        assert np.all(tr["term_Cndr"].to_numpy()[big_r] * dr[big_r] < 0)


def test_cli_writes_an_ingestable_campaign(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "camp"
    args = ["campaign", "--simulator", "jsbsim", "--aircraft", "f15", "--quick", "--seed", "2"]
    rc = main([*args, "--withhold", "Cnb,Cnp", "--withhold-alpha", "14", "--out", str(out)])
    assert rc == 0
    assert "wrote 3 maneuvers of JSBSim f15" in capsys.readouterr().out
    man = pl.read_csv(out / "manifest.csv")
    assert man.columns[:5] == ["maneuver_id", "flap_deg", "kind", "pusher", "file"]
    assert set(man["kind"]) == {"straight", "turning", "other"}
    info = json.loads((out / "truth" / "truth.json").read_text())
    assert [w["name"] for w in info["withheld"]] == ["Cnb", "Cnp"]
    assert info["withhold_alpha_deg"] == 14.0
    rc = main(["ingest", "--data", str(out), "--out", str(tmp_path / "ing"), "--quiet"])
    assert rc == 0
    data = pl.read_parquet(tmp_path / "ing" / "data.parquet")
    assert data.height == sum(
        pl.read_parquet(out / "records" / f"{m}.parquet").height for m in man["maneuver_id"]
    )
    assert data["Cl_meas"].is_finite().all() and data["ct_diff"].is_finite().all()


@pytest.mark.parametrize(
    ("kw", "needle"),
    [
        ({"aircraft": "no_such_plane"}, "unknown JSBSim aircraft 'no_such_plane'"),
        ({"aircraft": "f15", "withhold": "Clx"}, "unknown withheld term 'Clx'"),
        ({"aircraft": "f15", "withhold": "Clr"}, "'Clr' of JSBSim f15 does not depend on alpha"),
        ({"aircraft": "f16"}, "has no pilot configuration"),
    ],
)
def test_bad_input_names_the_thing(tmp_path: Path, kw: dict, needle: str) -> None:
    with pytest.raises(InvalidInputError, match=needle):
        generate_jsbsim_campaign(tmp_path / "x", **kw)
    assert not (tmp_path / "x").exists()


def test_cli_error_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    args = ["campaign", "--simulator", "jsbsim", "--aircraft", "f15", "--withhold", "Clx"]
    rc = main([*args, "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert rc == 1
    assert err.count("\n") == 1 and "unknown withheld term 'Clx'" in err
