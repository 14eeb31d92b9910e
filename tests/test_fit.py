"""Δ-model identification end to end on a virtual campaign with known truth effects."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta._fingerprint import data_sha256
from aerodelta.exceptions import DataError
from aerodelta.fit import DEFAULT_STRUCTURES, model_frame, stall_alpha


@pytest.fixture(scope="module")
def campaign(quick_campaign: Path) -> Path:
    return quick_campaign


@pytest.fixture(scope="module")
def split(campaign: Path) -> tuple[pl.DataFrame, pl.DataFrame]:
    d = ad.ingest(campaign, compat=False, progress=False).data
    ids = d["maneuver_id"].unique().sort().to_list()
    held = set(ids[::5])
    return (
        d.filter(~pl.col("maneuver_id").is_in(held)),
        d.filter(pl.col("maneuver_id").is_in(held)),
    )


@pytest.fixture(scope="module")
def result(split: tuple[pl.DataFrame, pl.DataFrame]) -> ad.FitResult:
    return ad.fit(split[0])


def test_extended_model_halves_rolling_moment_error_on_held_out_maneuvers(
    result: ad.FitResult, split: tuple[pl.DataFrame, pl.DataFrame]
) -> None:
    v = ad.validate_model(result.model, split[1]).filter(pl.col("coefficient") == "Cl")
    # the truth aircraft loses aileron power and roll damping past stall: the Δ model must
    # recover it on maneuvers it never saw
    assert v["tic_ratio"][0] < 0.5, v


def test_results_are_complete_and_honest(result: ad.FitResult) -> None:
    s = result.summary()
    assert {"estimate", "std_err", "std_err_colored", "identifiable", "note"} <= set(s.columns)
    ok = s.filter(pl.col("identifiable"))
    assert ok.height > 0
    assert (ok["std_err"] > 0).all()
    assert (ok["note"] == "").all()
    bad = s.filter(~pl.col("identifiable"))
    assert (bad["note"] != "").all(), "every unidentified parameter says why"
    assert set(result.stall_alpha_deg) == {0.0, 5.0, 10.0, 15.0, 35.0}
    for a in result.stall_alpha_deg.values():
        assert 12.0 < a < 24.0


def test_model_round_trip(result: ad.FitResult, split: tuple, tmp_path: Path) -> None:
    p = tmp_path / "model.json"
    result.model.save(p)
    back = ad.DeltaModel.load(p)
    data = model_frame(split[1])
    a = result.model.evaluate(data)
    b = back.evaluate(data)
    for c in a.columns:
        np.testing.assert_array_equal(a[c].to_numpy(), b[c].to_numpy())
    prov = back.to_spec()["provenance"]
    assert prov["library"].startswith("aerodelta ") and len(prov["data_sha256"]) == 64


def test_data_fingerprint_is_the_sha256_of_the_documented_bytes() -> None:
    """The provenance hash (``data_sha256``) written out by hand with hashlib: shape, then per
    column in name order its name and its float64 bytes (nulls as NaN), or its text joined
    by U+001F (nulls as "None", booleans as Python prints them)."""
    df = pl.DataFrame(
        {
            "b_f64": [1.5, None, -0.0],
            "a_i32": pl.Series([3, None, 7], dtype=pl.Int32),
            "c_f32": pl.Series([0.1, 2.0, None], dtype=pl.Float32),
            "d_id": ["m1", None, "m2"],
            "e_flag": [True, None, False],
            "f_enum": pl.Series(["x", "y", "x"], dtype=pl.Enum(["x", "y"])),
        }
    )
    h = hashlib.sha256(str(df.shape).encode())
    for name in sorted(df.columns):
        h.update(name.encode())
        values = df[name].to_list()
        if df[name].dtype.is_numeric():
            h.update(np.array([np.nan if v is None else v for v in values], dtype=float).tobytes())
        else:
            h.update("\x1f".join("None" if v is None else str(v) for v in values).encode())
    assert data_sha256(df) == h.hexdigest()


def test_fit_never_needs_the_truth_files(campaign: Path, tmp_path: Path) -> None:
    blind = tmp_path / "blind"
    shutil.copytree(campaign, blind, ignore=shutil.ignore_patterns("truth"))
    assert not (blind / "truth").exists()
    d = ad.ingest(blind, compat=False, progress=False).data
    r = ad.fit(d.filter(pl.col("flap_deg") == 10.0))
    assert r.model.coefficients == ["CY", "Cl", "Cn"]


def test_config_errors_name_file_and_key(tmp_path: Path) -> None:
    p = tmp_path / "fit.toml"
    p.write_text("width_deg = 0.5\nbogus = 1\n")
    with pytest.raises(DataError, match=r"fit.toml: unknown setting 'bogus'"):
        ad.FitConfig.from_toml(p)
    p.write_text('width_deg = 0.5\n[structures]\nCl = [["dCl_0", "1"], ["dCl_p", "phat"]]\n')
    cfg = ad.FitConfig.from_toml(p)
    assert cfg.width_deg == 0.5 and cfg.structures == {"Cl": [("dCl_0", "1"), ("dCl_p", "phat")]}


def test_example_config_is_the_documented_default() -> None:
    example = Path(__file__).resolve().parent.parent / "examples" / "fit.toml"
    assert ad.FitConfig.from_toml(example) == ad.FitConfig()


def test_too_few_maneuvers_per_flap_fit_the_given_structure_and_say_so(
    result: ad.FitResult, split: tuple[pl.DataFrame, pl.DataFrame]
) -> None:
    # the quick campaign has 8 maneuvers per flap (6-7 in the training split): below the 15
    # that cross-validated selection needs, so every flap fits the thesis structure
    n = split[0].group_by("flap_deg").agg(pl.col("maneuver_id").n_unique())["maneuver_id"]
    assert (n < 15).all()
    s = result.structure
    assert s.height > 0
    assert s["note"].str.contains("maneuvers at this flap, 15 needed").all(), s["note"][0]
    assert result.cross_validation.is_empty()
    # every term of the given structure is listed; the ones left out are left out for
    # collinearity (the virtual aircraft's roll spoiler is geared to its aileron), said so
    left = s.filter(~pl.col("kept"))
    assert left["note"].str.contains("left out: collinear with '").all(), left["note"].to_list()
    assert "dCl_ds" in left["param"].to_list()
    for c, terms in DEFAULT_STRUCTURES.items():
        listed = set(s.filter(pl.col("coefficient") == c)["param"].to_list())
        assert listed == {name for name, _ in terms}


def test_bootstrap_replicates_that_cannot_smooth_are_counted_not_zeros(
    split: tuple[pl.DataFrame, pl.DataFrame],
) -> None:
    """One flap with 6 maneuvers and 5 needed per bin (``min_maneuvers``): a replicate
    drawing 6 of them with replacement holds 5 distinct ones in a quarter of the draws, so
    most replicates refit too few bins to smooth. They are counted in a note and left out,
    never taken as a zero parameter; under half of them left, the smoothed band is NaN and the
    model carries no band there."""
    d = split[0].filter(pl.col("flap_deg") == 15.0)
    ids = d["maneuver_id"].unique().sort().to_list()[:6]
    cfg = ad.FitConfig(bootstrap=20, min_maneuvers=5)
    r = ad.fit(d.filter(pl.col("maneuver_id").is_in(ids)), config=cfg)
    notes = [n for n in r.notes if "bootstrap replicates could not smooth" in n]
    assert notes and all("of the 6 at this flap" in n for n in notes), r.notes
    for (coef, name, _), (_, reps) in r.replicates.items():
        failed = np.isnan(reps).all(axis=1)
        assert np.all(failed | np.isfinite(reps).all(axis=1))  # a replicate fails whole
        est = r.smoothed.filter((pl.col("coefficient") == coef) & (pl.col("param") == name))
        if (est["value"] != 0).any():
            assert not np.any((reps[~failed] == 0.0).all(axis=1)), (coef, name)
        if 2 * (~failed).sum() < len(failed):
            assert est["lower"].is_nan().all() and est["upper"].is_nan().all()
            assert f"{20 - int((~failed).sum())} of 20 bootstrap replicates" in " ".join(notes)
    spec = r.model.to_spec()
    banded = {t["name"] for c in spec["coefficients"].values() for t in c["terms"] if "band" in t}
    nan_band = set(r.smoothed.filter(pl.col("lower").is_nan())["param"].to_list())
    assert not banded & nan_band


def test_significance_and_the_bands_floor(
    split: tuple[pl.DataFrame, pl.DataFrame], result: ad.FitResult
) -> None:
    """``significant`` is the CR2 test at 5 % without a bootstrap; with a selecting bootstrap
    it is the band excluding zero, and every bin band holds the bin's CR2 95 % interval
    (``aero_core::bootstrap``'s floor), so a bin the band calls significant has p < 0.05, not
    always the reverse (a term some replicates drop reaches zero)."""
    p0 = result.params
    want = (p0["p_value"].is_finite() & (p0["p_value"] < 0.05)).fill_null(False)
    assert p0["significant"].equals(want, check_names=False)
    assert p0.columns.index("significant") == p0.columns.index("band_upper") + 1
    r = ad.fit(split[0], config=ad.FitConfig(bootstrap=20, seed=3))
    p = r.params.filter(pl.col("band_lower").is_finite() & pl.col("band_upper").is_finite())
    assert p.height > 100
    excl = (p["band_lower"] > 0) | (p["band_upper"] < 0)
    assert p["significant"].equals(excl, check_names=False)
    ci = p.filter(pl.col("ci95_lower").is_finite())
    tol = 1e-9 * (1.0 + ci["estimate"].abs())
    assert (
        (ci["band_lower"] <= ci["ci95_lower"] + tol) & (ci["ci95_upper"] - tol <= ci["band_upper"])
    ).all()
    assert ci.filter(pl.col("significant"))["p_value"].max() < 0.05 + 1e-9


def _no_thrust(d: pl.DataFrame) -> pl.DataFrame:
    """The records of a jet whose thrust is not recorded: ct channels all null."""
    cols = [c for c in ("ct_left", "ct_right", "ct_diff") if c in d.columns]
    return d.with_columns([pl.lit(None, dtype=pl.Float64).alias(c) for c in cols])


def test_terms_whose_channel_has_no_value_are_dropped_with_a_note(
    split: tuple[pl.DataFrame, pl.DataFrame],
) -> None:
    cfg = ad.FitConfig(selection=None)
    res = ad.fit(_no_thrust(split[0]), config=cfg)
    assert any("ct_left" in n and "dropped" in n for n in res.notes), res.notes
    assert not res.params.filter(pl.col("regressor").str.contains("ct_"))["param"].len()
    ok = res.params.filter(pl.col("identifiable"))
    # the other terms are fitted as before, not turned to NaN by the missing channel
    assert ok.height > 0.5 * res.params.height
    assert ok["estimate"].is_finite().all() and ok["std_err"].is_finite().all()
    full = ad.fit(split[0], config=cfg).params.filter(pl.col("identifiable"))
    assert set(ok["param"].unique()) == set(full["param"].unique()) - {
        p for p in full["param"].unique() if "ct" in p
    }


def test_a_term_the_user_named_is_refused_when_its_channel_is_missing(
    split: tuple[pl.DataFrame, pl.DataFrame],
) -> None:
    cfg = ad.FitConfig(
        selection=None,
        structures={"Cl": [("dCl_0", "1"), ("dCl_ct", "ct_left + ct_right")]},
    )
    with pytest.raises(DataError, match=r"dCl_ct.*'ct_left' \(no value\)"):
        ad.fit(_no_thrust(split[0]), config=cfg)


def test_rows_without_a_regressor_value_are_counted(
    split: tuple[pl.DataFrame, pl.DataFrame],
) -> None:
    d = split[0].with_row_index("_i")
    d = d.with_columns(
        pl.when(pl.col("_i") % 10 == 0).then(None).otherwise(pl.col("ct_left")).alias("ct_left")
    ).drop("_i")
    res = ad.fit(d, config=ad.FitConfig(selection=None))
    msgs = [n for n in res.notes if "no value of 'ct_left'" in n]
    assert msgs and all("left out" in n for n in msgs), res.notes


def test_too_few_maneuvers_is_an_error(split: tuple[pl.DataFrame, pl.DataFrame]) -> None:
    ids = split[0]["maneuver_id"].unique().sort().to_list()[:3]
    with pytest.raises(DataError, match="too little data"):
        ad.fit(split[0].filter(pl.col("maneuver_id").is_in(ids)))


@pytest.mark.parametrize(
    ("setting", "value", "message"),
    [
        ("bootstrap", "many", "bootstrap = 'many': give a whole number"),
        ("bootstrap", 2.5, "bootstrap = 2.5: give a whole number"),
        ("seed", -1, "seed = -1: give a whole number >= 0"),
        ("p", "0.4", "p = '0.4': give a finite number"),
        ("p", 0.0, "p = 0.0: the smoothing parameter"),
        ("max_vif", float("nan"), "max_vif = nan: give a finite number"),
        ("colored", "yes", "colored = 'yes': give true or false"),
        ("cv_folds", 1, "cv_folds = 1: cross-validation needs at least 2"),
        ("band_level", 95, "band_level = 95: give a confidence level in"),
        ("alpha_l_deg", "8", "alpha_l_deg = '8': give an alpha in deg"),
    ],
)
def test_a_setting_of_the_wrong_type_is_refused_in_one_line(
    setting: str, value: object, message: str, tmp_path: Path
) -> None:
    with pytest.raises(DataError, match=message.replace("(", r"\(")):
        ad.FitConfig(**{setting: value})  # type: ignore[arg-type]
    # the same from a configuration file, where a string is the usual slip
    if isinstance(value, str):
        p = tmp_path / "fit.toml"
        p.write_text(f'{setting} = "{value}"\n')
        with pytest.raises(DataError, match=f"fit setting {setting}"):
            ad.FitConfig.from_toml(p)


def test_stall_alpha_reads_past_wild_and_missing_alphas() -> None:
    """C_L = 1.5 - 0.004 (alpha - 16)^2 peaks at 16 deg; rows at 1e12 deg (a bin far from the
    others, too few points to count) or with no alpha do not move the 0.5-deg bin found."""
    alpha = np.repeat(np.arange(8.0, 24.0, 0.01), 3)
    a = np.radians(alpha)
    cl = 1.5 - 0.004 * (alpha - 16.0) ** 2
    d = pl.DataFrame({"alpha_deg": alpha, "CZ_meas": -cl * np.cos(a), "CX_meas": cl * np.sin(a)})
    wild = pl.DataFrame(
        {"alpha_deg": [1e12, None, np.nan], "CZ_meas": [-9.0, -9.0, -9.0], "CX_meas": [0.0] * 3}
    )
    plain = stall_alpha(d)
    assert abs(plain - 16.0) <= 0.25
    assert stall_alpha(pl.concat([wild, d])) == plain


def test_stall_alpha_is_the_wings_not_the_thrusts() -> None:
    """Closed form: an aerodynamic C_L peaking at 16 deg, a thrust coefficient 0.6 along body
    x. The total body force's lift-wise component C_L + C_T sin(alpha) peaks ~1.2 deg later;
    with the thrust channels the detection finds the wing's 16 deg."""
    alpha = np.repeat(np.arange(8.0, 24.0, 0.01), 3)
    a = np.radians(alpha)
    cl = 1.5 - 0.004 * (alpha - 16.0) ** 2
    cd = 0.05 + 0.002 * alpha**2 / 10
    ct = 0.3
    d = pl.DataFrame(
        {
            "alpha_deg": alpha,
            "CZ_meas": -(cl * np.cos(a) + cd * np.sin(a)),
            "CX_meas": cl * np.sin(a) - cd * np.cos(a) + 2 * ct,
            "ct_left": np.full(alpha.size, ct),
            "ct_right": np.full(alpha.size, ct),
        }
    )
    assert abs(stall_alpha(d) - 16.0) <= 0.25
    total = stall_alpha(d.drop("ct_left", "ct_right"))
    assert total >= 17.0, total
