"""Structure selection, cross-validation over maneuvers and bootstrap bands, on a virtual
campaign whose truth (effects and their alpha shapes, ``aerodelta.truth``) is known."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta.exceptions import DataError
from aerodelta.fit import COEFFICIENTS, FitConfig, model_frame, qualified_coefficients
from aerodelta.fit import theil_inequality as tic
from aerodelta.truth import band_check, campaign_effects, true_parameter


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("select") / "camp"
    # the default campaign (200 maneuvers, default effects, realistic noise and turbulence)
    ad.generate_campaign(out, seed=2, progress=False)
    return out


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
    return ad.fit(split[0], config=FitConfig(bootstrap=40, seed=1))


def _kept(result: ad.FitResult, coef: str, flap: float) -> set[str]:
    s = result.structure.filter(
        (pl.col("coefficient") == coef) & (pl.col("flap_deg") == flap) & pl.col("kept")
    )
    return set(s["param"].to_list())


def test_selection_keeps_the_strong_true_effects_and_few_others(result: ad.FitResult) -> None:
    klein = []
    for flap in (0.0, 5.0, 10.0, 15.0, 35.0):
        # roll damping and the bias (lateral asymmetry) are large at every flap
        assert {"dCl_0", "dCl_p"} <= _kept(result, "Cl", flap)
        assert {"dCn_0", "dCn_dr"} <= _kept(result, "Cn", flap)
        assert {"dCY_0", "dCY_dr"} <= _kept(result, "CY", flap)
        for c in COEFFICIENTS:
            kept = _kept(result, c, flap)
            # parsimony: a handful of the 16 candidates
            assert len(kept) <= 7, (c, flap, kept)
            klein += sorted({f"d{c}_beta2", f"d{c}_beta3"} & kept)
    # the truth has no beta^2, beta^3 terms: Klein's trial regressors are kept in at most one
    # of the 15 structures (with C_T smoothed at ingestion the cleaner C_n data let the
    # cross-validated path keep dCn_beta2 at flap 15 on this seed, a likely proxy of the
    # thrust effect in the engine-out stalls, where beta is large and C_T low)
    assert len(klein) <= 1, klein
    # the selection data are per bin and per candidate, with the pool fit's flags
    sb = result.selection_bins
    assert {"correlation", "partial_f", "selected", "kappa", "identifiable_in_pool"} <= set(
        sb.columns
    )
    assert (sb.filter(pl.col("fitted"))["kappa"] >= 1.0).all()


def test_cross_validation_over_maneuvers_prefers_the_selected_structure(
    result: ad.FitResult,
) -> None:
    cv = result.cross_validation.pivot(
        on="structure", index=["coefficient", "flap_deg"], values="cv_rms"
    )
    assert cv.height == 15
    # held-out maneuvers: the selected structure predicts better than the full pool everywhere
    assert (cv["selected"] < cv["full"]).all(), cv
    # and at least as well as the thesis's default structures (within 5 %)
    assert (cv["selected"] <= 1.05 * cv["default"]).all(), cv


def test_held_out_tic_ratio_meets_the_floor_or_the_noise_limit(
    result: ad.FitResult, split: tuple[pl.DataFrame, pl.DataFrame], campaign: Path
) -> None:
    test = split[1]
    v = ad.validate_model(result.model, test)
    ratio = dict(zip(v["coefficient"], v["tic_ratio"], strict=True))
    assert ratio["Cl"] <= 0.5 and ratio["Cn"] <= 0.5, ratio
    # CY: even the true Δ cannot reach 0.5 here; the side-force measurement noise (accelerometer)
    # is as large as the Δ. The fit must come close to what the true Δ achieves.
    mf = model_frame(test)
    qual = qualified_coefficients(mf)
    truth = pl.concat(
        [
            pl.read_parquet(campaign / "truth" / f"{m}.parquet").with_columns(
                pl.lit(m).alias("maneuver_id")
            )
            for m in test["maneuver_id"].unique().to_list()
        ]
    )
    j = pl.concat(
        [test.select("maneuver_id", "t", "CY_meas"), qual.select("CY_qual")], how="horizontal"
    ).join(
        truth.select("maneuver_id", "t", "CY_true", pl.col("CY_qual").alias("q")),
        on=["maneuver_id", "t"],
    )
    meas, q = j["CY_meas"].to_numpy(), j["CY_qual"].to_numpy()
    oracle = tic(meas, q + (j["CY_true"] - j["q"]).to_numpy()) / tic(meas, q)
    assert oracle > 0.5  # the floor is out of reach for any Δ model on these data
    assert ratio["CY"] <= oracle + 0.05, (ratio, oracle)


def test_bootstrap_bands_are_stored_and_cover_the_truth(
    result: ad.FitResult, split: tuple[pl.DataFrame, pl.DataFrame], campaign: Path
) -> None:
    spec = result.model.to_spec()
    for c in spec["coefficients"].values():
        for t in c["terms"]:
            b = t["band"]
            lo, hi = np.asarray(b["lower"]), np.asarray(b["upper"])
            val = np.asarray(t["values"])
            assert b["level"] == 0.95 and lo.shape == val.shape == hi.shape
            assert (lo <= hi + 1e-15).all()
    # the smoothed table lies inside its own band almost everywhere
    s = result.smoothed.filter(pl.col("note") == "")
    inside = ((s["lower"] <= s["value"] + 1e-12) & (s["value"] <= s["upper"] + 1e-12)).mean()
    assert inside >= 0.9, inside
    # against the truth: bins marked identified, where the model applies (alpha >= alpha_l)
    bc = band_check(result, campaign_effects(campaign))
    n = bc["bins"].to_numpy()
    in_band = float(np.sum(n * bc["inside_band"].to_numpy()) / n.sum())
    in_bin = float(np.nansum(n * bc["inside_bin_band"].to_numpy()) / n.sum())
    # measured (seed 2, 40 replicates that select again): 0.81 for the smoothed bands, 0.91 for
    # the per-bin percentile bands (0.5 and 0.75 when the replicates refitted the chosen
    # structure: those bands lacked the selection's own uncertainty). The remaining misses are
    # systematic (measurement chain, roll-off; docs/identification.md)
    assert in_band >= 0.7 and in_bin >= 0.85, (in_band, in_bin)
    cy = bc.filter(pl.col("coefficient") == "CY")
    ncy = cy["bins"].to_numpy()
    assert float(np.sum(ncy * cy["inside_band"].to_numpy()) / ncy.sum()) >= 0.7
    # the band of the blended Δ along held-out records holds the model's own correction
    band = result.delta_band(split[1].filter(pl.col("flap_deg") == 10.0))
    for c in COEFFICIENTS:
        d, lo, hi = (band[f"d{c}_{k}"].to_numpy() for k in ("blended", "lower", "upper"))
        assert np.mean((lo <= d + 1e-12) & (d <= hi + 1e-12)) >= 0.9


def test_true_parameter_matches_the_effect_library() -> None:
    # dihedral: +0.06 per rad of beta at design, flap factor 0.9 at flaps 10, fully developed
    # between 19 and 24 deg; per degree of beta_deg in the fit's units
    v = true_parameter({"dihedral": 1.0}, "Cl", "beta_deg", 10.0, np.array([10.0, 21.0]))
    assert v[0] == 0.0
    assert math.isclose(v[1], 0.06 * 0.9 * math.pi / 180.0, rel_tol=1e-12)
    assert true_parameter({"dihedral": 1.0}, "Cn", "beta_deg", 10.0, np.array([21.0]))[0] == 0.0


def test_constant_regressor_is_unidentified_and_not_selected(
    split: tuple[pl.DataFrame, pl.DataFrame],
) -> None:
    # the rudder held still on every flaps-10 maneuver: no excitation
    d = split[0].filter(pl.col("flap_deg") == 10.0).with_columns(pl.lit(0.0).alias("dr_deg"))
    plain = ad.fit(d, config=FitConfig(selection=None))
    dr = plain.params.filter(pl.col("param") == "dCn_dr")
    assert dr.height > 0 and not dr["identifiable"].any()
    # a zero column: low excitation and an exact dependency, or a bin without enough data
    assert dr["note"].str.contains("low excitation|linearly dependent|not fitted").all()
    assert dr.filter(pl.col("note").str.contains("low excitation")).height > 0
    sel = ad.fit(d)
    assert "dCn_dr" not in _kept(sel, "Cn", 10.0)
    pool = sel.selection_bins.filter(pl.col("param") == "dCn_dr")
    assert not pool["identifiable_in_pool"].any() and not pool["selected"].any()


def test_a_control_held_still_through_its_sensor_is_low_excitation(
    split: tuple[pl.DataFrame, pl.DataFrame],
) -> None:
    # the rudder held at 1 deg on every flaps-10 maneuver and read through its sensor (white
    # noise of 0.05 deg, the virtual campaign's): its spread in a bin is its spread over the flap,
    # so the relative rule alone passes it; its noise floor does not
    d = split[0].filter(pl.col("flap_deg") == 10.0)
    rng = np.random.default_rng(3)
    d = d.with_columns(pl.Series("dr_deg", 1.0 + 0.05 * rng.standard_normal(d.height)))
    cfg = FitConfig(selection=None, structures={"Cn": [("dCn_0", "1"), ("dCn_dr", "dr_deg")]})
    dr = ad.fit(d, config=cfg).params.filter(
        (pl.col("param") == "dCn_dr") & ~pl.col("note").str.contains("not fitted")
    )
    assert dr.height > 20
    assert not dr["identifiable"].any()
    assert dr["note"].str.contains("noise floor").all()
    # std of white noise over its own floor: about 1
    snr = dr["excitation_snr"].to_numpy()
    assert np.all((snr > 0.6) & (snr < 1.5)), snr
    assert (dr["excitation"] > 0.5).all()  # what the relative rule saw
    relative_only = FitConfig(selection=None, structures=cfg.structures, min_excitation_snr=0.0)
    assert (
        ad.fit(d, config=relative_only)
        .params.filter(pl.col("param") == "dCn_dr")["identifiable"]
        .any()
    )
    # the rudder as flown is far above its floor (0.05 deg) wherever it is identified
    flown = ad.fit(split[0].filter(pl.col("flap_deg") == 10.0), config=cfg).params.filter(
        (pl.col("param") == "dCn_dr") & pl.col("identifiable")
    )
    assert flown.height > 20 and (flown["excitation_snr"] > 10.0).all()


def test_bins_of_few_maneuvers_are_not_identified(result: ad.FitResult) -> None:
    bins = result.bins.select("coefficient", "flap_deg", "alpha_lo_deg", "n_maneuvers")
    p = result.params.join(bins, on=["coefficient", "flap_deg", "alpha_lo_deg"])
    few = p.filter((pl.col("n_maneuvers") < 5) & ~pl.col("note").str.contains("not fitted"))
    assert few.height > 0  # the sparse ends of the alpha range
    assert not few["identifiable"].any()
    assert few["note"].str.contains("maneuvers in the bin").all()
    assert p.filter(pl.col("n_maneuvers") >= 5)["identifiable"].mean() > 0.9


def test_band_limited_fit_keeps_an_exact_linear_relation(
    split: tuple[pl.DataFrame, pl.DataFrame],
) -> None:
    # C_n = C_n,sim + 0.002 + 0.0005 dr exactly: one linear filter on both sides keeps the
    # relation, so every bin recovers it with the band limit as without
    d = split[0].filter(pl.col("flap_deg") == 5.0)
    sim = qualified_coefficients(model_frame(d))
    d = d.with_columns(
        sim["Cl_qual"].alias("Cl_sim"), sim["Cn_qual"].alias("Cn_sim"),
        sim["CY_qual"].alias("CY_sim"),
        (sim["Cn_qual"] + 0.002 + 0.0005 * pl.col("dr_deg")).alias("Cn_meas"),
    )  # fmt: skip
    structures = {"Cn": [("dCn_0", "1"), ("dCn_dr", "dr_deg")]}
    for band in (None, 2.0, {"Cn": 1.5}):
        # this C_n_meas never went through the ingestion's smoother, so the simulator's
        # output must not either (FitConfig.smoother_match off)
        cfg = FitConfig(selection=None, structures=structures, band_hz=band, smoother_match=False)
        p = ad.fit(d, qualified="columns", config=cfg).params
        p = p.filter(pl.col("estimate").is_not_nan())
        assert p.height > 40
        for name, want in (("dCn_0", 0.002), ("dCn_dr", 0.0005)):
            got = p.filter(pl.col("param") == name)["estimate"].to_numpy()
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    with pytest.raises(DataError, match=r"band_hz=2\.0 needs the time column 't'"):
        ad.fit(d.drop("t"), qualified="columns", config=FitConfig(band_hz=2.0))


def test_bootstrap_is_reproducible_for_a_seed(split: tuple[pl.DataFrame, pl.DataFrame]) -> None:
    d = split[0].filter(pl.col("flap_deg") == 5.0)
    cfg = FitConfig(bootstrap=10, seed=7, structures={"Cn": [("dCn_0", "1")]})
    a = ad.fit(d, config=cfg).smoothed
    b = ad.fit(d, config=cfg).smoothed
    assert a.equals(b)
    with pytest.raises(DataError, match="selection='best'"):
        ad.fit(d, config=FitConfig(selection="best"))


def test_mof_selection_and_config_file(tmp_path: Path) -> None:
    p = tmp_path / "fit.toml"
    p.write_text('selection = "mof"\nbootstrap = 20\n[candidates]\nCl = [["dCl_0", "1"]]\n')
    cfg = FitConfig.from_toml(p)
    assert cfg.selection == "mof" and cfg.bootstrap == 20
    assert cfg.candidates == {"Cl": [("dCl_0", "1")]}
