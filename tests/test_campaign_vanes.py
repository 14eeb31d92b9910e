"""Vane calibration errors in the virtual flight test and their recovery by the compatibility
check (issue 19 item 2): upwash and sidewash scale errors, vane biases and a flank-angle yaw
vane, injected by the sensor model with known values."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta.aircraft import Aircraft
from aerodelta.exceptions import InvalidInputError

K_ALPHA, K_BETA, B_ALPHA, B_BETA = 0.07, -0.08, 1.5, 0.8


@pytest.fixture(scope="module")
def calm(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("vanes") / "calm"
    ad.generate_campaign(
        out, seed=17, size="quick", turbulence=0.0,
        effects={"alpha_vane_bias": B_ALPHA, "beta_vane_bias": B_BETA, "roll_damping": 1.0},
        vane_scale=(K_ALPHA, K_BETA), flank_vane=True,
    )  # fmt: skip
    return out


def test_calm_air_campaign_medians_recover_scale_factors_and_biases(calm: Path) -> None:
    """Calm air: the campaign medians are within issue 19's 1 % and 0.1 deg (measured on the
    development seed 600: 0.08-0.1 % and 0.02 deg)."""
    assert Aircraft.from_toml(calm / "aircraft.toml").beta_vane_type == "flank"
    res = ad.ingest(calm, vane_scale=True, progress=False)
    med = dict(res.compat.group_by("parameter").agg(pl.col("estimate").median()).iter_rows())
    assert abs(med["k_alpha"] - K_ALPHA) < 0.01, med["k_alpha"]
    assert abs(med["k_beta"] - K_BETA) < 0.01, med["k_beta"]
    assert abs(np.degrees(med["b_alpha_rad"]) - B_ALPHA) < 0.1
    assert abs(np.degrees(med["b_beta_rad"]) - B_BETA) < 0.1
    said = {f.message.split(" (median")[0] for r in res.reports for f in r.findings}
    assert any("alpha vane scale error (upwash) 7" in m for m in said), said


def test_gusts_bias_output_error_not_the_innovations_form(tmp_path: Path) -> None:
    """0.5 m/s Dryden turbulence (quick campaign, seed 602): the aircraft answers the gusts,
    so output error's reconstructed sideslip carries part of the gust angle and k_beta comes
    out low by more than issue 19's 1 % (-1.6 % here); the innovations form
    (``compat_method="innovations"``, the default with ``vane_scale``) follows the gusts and
    holds both scale factors within 1 % and the biases within 0.2 deg (the median's spread
    over 40 maneuvers is 0.1-0.2 deg)."""
    out = tmp_path / "gusty"
    ad.generate_campaign(
        out, seed=602, size="quick", turbulence=0.5,
        effects={"alpha_vane_bias": B_ALPHA, "beta_vane_bias": B_BETA},
        vane_scale=(K_ALPHA, K_BETA), flank_vane=True,
    )  # fmt: skip

    def medians(method: str) -> dict[str, float]:
        res = ad.ingest(out, vane_scale=True, progress=False, compat_method=method)
        return dict(res.compat.group_by("parameter").agg(pl.col("estimate").median()).iter_rows())

    oe = medians("output-error")
    assert oe["k_beta"] - K_BETA < -0.01, oe["k_beta"]
    inn = medians("auto")
    assert abs(inn["k_alpha"] - K_ALPHA) < 0.01, inn["k_alpha"]
    assert abs(inn["k_beta"] - K_BETA) < 0.01, inn["k_beta"]
    assert abs(np.degrees(inn["b_alpha_rad"]) - B_ALPHA) < 0.2
    assert abs(np.degrees(inn["b_beta_rad"]) - B_BETA) < 0.2
    assert 0.3 < inn["gain_beta"] < 1.0  # the predictor follows the gusts
    with pytest.raises(ad.DataError, match="compat_method='filter'"):
        ad.ingest(out, compat_method="filter", progress=False)
    with pytest.raises(ad.DataError, match="needs the compatibility check"):
        ad.ingest(out, compat=False, compat_method="innovations", progress=False)


def test_scale_errors_multiply_what_the_vane_reads(tmp_path: Path) -> None:
    """Noise-free, one maneuver: the recorded alpha with a 7 % scale error is 1.07 times the
    ideal vane's (both biases off), the same flight otherwise."""
    kw = {"seed": 3, "size": 1, "noise": 0.0, "turbulence": 0.0, "effects": "none", "only": [0]}
    ideal = ad.campaign.simulate_campaign(**kw)[0]["record"]
    with_k = ad.campaign.simulate_campaign(**kw, vane_scale=(0.07, 0.0))[0]["record"]
    np.testing.assert_allclose(
        with_k["alpha_deg"].to_numpy(), 1.07 * ideal["alpha_deg"].to_numpy(), rtol=1e-12
    )
    assert with_k["beta_deg"].equals(ideal["beta_deg"])
    with pytest.raises(InvalidInputError, match="vane"):
        ad.generate_campaign(tmp_path / "bad", size="quick", vane_scale=(0.7, 0.0))
    with pytest.raises(InvalidInputError, match="vane_scale"):
        ad.generate_campaign(tmp_path / "bad", size="quick", vane_scale=(0.1,))
