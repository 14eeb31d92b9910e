"""Per-maneuver loadings and the moment reference centre, end to end through ingest.

The reference is tests/_ingest_synth.py's closed-form rigid-body motion flown with two
loadings (mass, full inertia tensor, CG), its truth the full Euler equations about each CG
transferred to the moment reference centre in numpy: independent of aero_core.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta
from _ingest_synth import AIRCRAFT_TOML, canonical_frame, motion
from aerodelta.aircraft import Aircraft
from aerodelta.exceptions import DataError

T = np.arange(0.0, 40.0, 0.02)
REF = (-0.4, 0.0, 0.05)
# two loadings 0.55 m (24 % of the 2.3 m chord) apart in x, with products of inertia
LOADS = {
    "m1": {
        "m": 18500.0,
        "I": (2.9e5, 4.6e5, 7.0e5, 1.4e4, 800.0, -1200.0),
        "cg": (0.35, 0.02, 0.12),
    },
    "m2": {"m": 21500.0, "I": (3.1e5, 4.4e5, 7.2e5, 1.6e4, 0.0, 0.0), "cg": (-0.2, -0.05, 0.05)},
}
COLS = ("mass_kg", "Ixx_kgm2", "Iyy_kgm2", "Izz_kgm2", "Ixz_kgm2", "Ixy_kgm2", "Iyz_kgm2")


def _manifest(loads: dict[str, dict], with_loading: bool = True) -> str:
    head = "maneuver_id,flap_deg,kind,pusher,file"
    if with_loading:
        head += "," + ",".join(COLS) + ",cg_x_m,cg_y_m,cg_z_m"
    rows = [head]
    for mid, ld in loads.items():
        row = f"{mid},0,straight,false,records/{mid}.parquet"
        if with_loading:
            row += "," + ",".join(repr(v) for v in (ld["m"], *ld["I"], *ld["cg"]))
        rows.append(row)
    return "\n".join(rows) + "\n"


@pytest.fixture(scope="module")
def truths() -> dict[str, dict[str, np.ndarray]]:
    return {
        mid: motion(T, seed=k + 1, loading={**ld, "ref": REF})
        for k, (mid, ld) in enumerate(LOADS.items())
    }


@pytest.fixture
def campaign(tmp_path: Path, truths: dict) -> Path:
    (tmp_path / "records").mkdir()
    for mid, tr in truths.items():
        canonical_frame(tr).write_parquet(tmp_path / "records" / f"{mid}.parquet")
    (tmp_path / "aircraft.toml").write_text(
        AIRCRAFT_TOML + f"[reference]\nmoment_ref_m = {list(REF)}\n"
    )
    (tmp_path / "manifest.csv").write_text(_manifest(LOADS))
    return tmp_path


def _err(got: np.ndarray, want: np.ndarray) -> float:
    return float(np.max(np.abs(got - want)) / np.max(np.abs(want)))


def test_each_maneuver_about_the_reference_with_its_own_loading(
    campaign: Path, truths: dict
) -> None:
    res = aerodelta.ingest(campaign, smooth=False, compat=False, progress=False)
    for mid, tr in truths.items():
        d = res.data.filter(pl.col("maneuver_id") == mid)
        # only the O(dt²) central-difference error remains, as for the nominal loading
        for col, ref in [
            ("Cl_meas", "Cl_true"),
            ("Cn_meas", "Cn_true"),
            ("CY_meas", "CY_true"),
            ("Cm_meas", "Cm_true"),
        ]:
            assert _err(d[col].to_numpy(), tr[ref]) < 1e-3, (mid, col)
        # the vanes are transferred to this maneuver's CG
        np.testing.assert_allclose(d["alpha_cg_deg"].to_numpy(), tr["alpha_cg_true"], atol=1e-9)
        np.testing.assert_allclose(d["beta_cg_deg"].to_numpy(), tr["beta_cg_true"], atol=1e-9)


def test_ignoring_the_loading_is_visibly_wrong(campaign: Path, truths: dict) -> None:
    # the same records with the aircraft file's loading for both: the errors the transfer
    # removes are two orders of magnitude above the differentiation error
    (campaign / "manifest.csv").write_text(_manifest(LOADS, with_loading=False))
    res = aerodelta.ingest(campaign, smooth=False, compat=False, progress=False)
    d = res.data.filter(pl.col("maneuver_id") == "m1")
    assert _err(d["Cl_meas"].to_numpy(), truths["m1"]["Cl_true"]) > 0.05
    assert _err(d["Cm_meas"].to_numpy(), truths["m1"]["Cm_true"]) > 0.05


def test_a_partial_loading_takes_the_rest_from_the_aircraft_file(campaign: Path) -> None:
    (campaign / "manifest.csv").write_text(
        "maneuver_id,flap_deg,kind,pusher,file,cg_x_m\n"
        "m1,0,straight,false,records/m1.parquet,0.3\n"
        "m2,0,straight,false,records/m2.parquet,0.0\n"
    )
    res = aerodelta.ingest(campaign, smooth=False, compat=False, progress=False)
    full = (
        "maneuver_id,flap_deg,kind,pusher,file," + ",".join(COLS) + ",cg_x_m,cg_y_m,cg_z_m\n"
        "m1,0,straight,false,records/m1.parquet,20000,3e5,4.5e5,7.1e5,1.5e4,0,0,0.3,0,0\n"
        "m2,0,straight,false,records/m2.parquet,20000,3e5,4.5e5,7.1e5,1.5e4,0,0,0.0,0,0\n"
    )
    (campaign / "manifest.csv").write_text(full)
    res_full = aerodelta.ingest(campaign, smooth=False, compat=False, progress=False)
    assert res.data["Cl_meas"].equals(res_full.data["Cl_meas"])


@pytest.mark.parametrize(
    ("column", "value", "expect"),
    [
        ("mass_kg", "heavy", "column 'mass_kg', rows 1: heavy is not a number"),
        ("mass_kg", "", "column 'mass_kg', rows 1"),
        ("mass_kg", "-5", "mass must be positive"),
        ("Ixz_kgm2", "9e5", "not positive definite"),
    ],
)
def test_bad_loadings_are_refused_naming_column_and_row(
    campaign: Path, column: str, value: str, expect: str
) -> None:
    man = pl.read_csv(campaign / "manifest.csv", infer_schema_length=0)
    man = man.with_columns(
        pl.when(pl.col("maneuver_id") == "m2")
        .then(pl.lit(value))
        .otherwise(pl.col(column))
        .alias(column)
    )
    man.write_csv(campaign / "manifest.csv")
    with pytest.raises(DataError, match="manifest") as e:
        aerodelta.ingest(campaign, smooth=False, compat=False, progress=False)
    assert expect in str(e.value), str(e.value)
    assert "\n" not in str(e.value)


def test_a_cg_in_inches_is_warned(campaign: Path) -> None:
    man = pl.read_csv(campaign / "manifest.csv").with_columns(
        (pl.col("cg_x_m") / 0.0254).alias("cg_x_m")
    )
    man.write_csv(campaign / "manifest.csv")
    res = aerodelta.ingest(campaign, smooth=False, compat=False, progress=False)
    warned = [f.message for r in res.reports for f in r.findings if "cg_x_m" in f.message]
    assert len(warned) == 2 and "check the units" in warned[0], warned


def test_aircraft_file_reference_and_full_tensor() -> None:
    base = {
        "geometry": {"S_m2": 61.0, "b_m": 27.05, "cbar_m": 2.3},
        "mass": {"mass_kg": 2e4, "Ixx_kgm2": 3e5, "Iyy_kgm2": 4.5e5, "Izz_kgm2": 7.1e5,
                 "Ixz_kgm2": 1.5e4},
    }  # fmt: skip
    ac = Aircraft.from_dict(base)
    assert ac.reference_m == (0.0, 0.0, 0.0) and ac.mass_geometry[8:] == [0.0, 0.0]
    ac = Aircraft.from_dict(
        {**base, "mass": {**base["mass"], "cg_m": [0.3, 0.0, 0.1], "Ixy_kgm2": 500.0}}
    )
    assert ac.reference_m == (0.3, 0.0, 0.1)  # no [reference]: moments about the CG
    ac = Aircraft.from_dict({**base, "reference": {"moment_ref_m": [1.0, 0.0, 0.0]}})
    assert ac.reference_m == (1.0, 0.0, 0.0)
    # Ixx Iyy < Ixy²: positive diagonal and Ixz, but not definite (Sylvester's 2x2 minor)
    with pytest.raises(DataError, match="not positive definite"):
        Aircraft.from_dict({**base, "mass": {**base["mass"], "Ixy_kgm2": 4e5}})
    with pytest.raises(DataError, match=r"\[reference\] moment_ref_m"):
        Aircraft.from_dict({**base, "reference": {"moment_ref_m": [1.0, 0.0]}})
    with pytest.raises(DataError, match=r"\[reference\] has unknown key"):
        Aircraft.from_dict({**base, "reference": {"aerorp": [1.0, 0.0, 0.0]}})


def test_propeller_sense_follows_the_right_hand_rule(campaign: Path) -> None:
    """A rotor turning clockwise viewed from behind (looking forward) has its angular
    momentum along +x by the right-hand rule, counter-clockwise along -x. The measured
    (aerodynamic) moments differ between the two by omega x (h_cw - h_ccw), computed here
    with numpy's cross product from those vectors alone."""
    res = {}
    for sense in ("cw", "ccw"):
        text = (campaign / "aircraft.toml").read_text()
        (campaign / "aircraft.toml").write_text(
            text.replace('prop_rotation = "ccw"', f'prop_rotation = "{sense}"').replace(
                'prop_rotation = "cw"', f'prop_rotation = "{sense}"'
            )
        )
        res[sense] = aerodelta.ingest(campaign, smooth=False, compat=False, progress=False).data
    ac = Aircraft.from_toml(campaign / "aircraft.toml")
    d = res["cw"].filter(pl.col("maneuver_id") == "m1")
    e = res["ccw"].filter(pl.col("maneuver_id") == "m1")
    rpm = d["prop_rpm"].to_numpy()
    h = ac.n_engines * ac.prop_inertia_kgm2 * rpm * 2.0 * np.pi / 60.0  # |h|, kg m²/s
    dh = np.zeros((d.height, 3))
    dh[:, 0] = 2.0 * h  # h_cw - h_ccw = (+h) - (-h) along x
    om = np.radians(d.select("p_s_dps", "q_s_dps", "r_s_dps").to_numpy())
    dm = np.cross(om, dh)
    qs = d["qbar_pa"].to_numpy() * ac.S_m2
    np.testing.assert_allclose(
        (d["Cn_meas"] - e["Cn_meas"]).to_numpy(), dm[:, 2] / (qs * ac.b_m), rtol=1e-9, atol=1e-15
    )
    np.testing.assert_allclose(
        (d["Cm_meas"] - e["Cm_meas"]).to_numpy(),
        dm[:, 1] / (qs * ac.cbar_m),
        rtol=1e-9,
        atol=1e-15,
    )
    assert np.abs(dm[:, 2]).max() > 0  # the motion pitches: the test can fail
