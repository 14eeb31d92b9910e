"""Virtual flight test -> ingestion: the measured coefficients (thesis Eq. 3.2-3.4, computed from
recorded sensor channels with noise, offsets and turbulence) equal the truth model's to within
the noise, and with every effect off the truth is the qualified model (issue: campaign checks)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("camp") / "none"
    ad.generate_campaign(out, effects="none", seed=11, size="quick", rolloff=False, progress=False)
    return out


def _joined(campaign: Path) -> pl.DataFrame:
    data = ad.ingest(campaign, compat=False, progress=False).data
    truth = pl.concat(
        [
            pl.read_parquet(campaign / "truth" / f"{m}.parquet").with_columns(
                pl.lit(m).alias("maneuver_id")
            )
            for m in data["maneuver_id"].unique().sort()
        ]
    )
    return data.join(truth, on=["maneuver_id", "t"], how="inner")


@pytest.mark.parametrize("coef", ["Cl", "Cn", "CY"])
def test_measured_equals_qualified_within_noise(campaign: Path, coef: str) -> None:
    j = _joined(campaign)
    assert j.height > 50_000
    meas = j[f"{coef}_meas"].to_numpy()
    qual = j[f"{coef}_qual"].to_numpy()
    true = j[f"{coef}_true"].to_numpy()
    # effects off: the truth aircraft is the qualified model
    np.testing.assert_allclose(true, qual, rtol=0, atol=1e-12)
    err = meas - qual
    ok = np.isfinite(err)
    rms_err = np.sqrt(np.mean(err[ok] ** 2))
    rms_sig = np.sqrt(np.mean(qual[ok] ** 2))
    # sensor noise and smoothing leave a few percent of the signal, with no bias
    assert rms_err < 0.10 * rms_sig, (rms_err, rms_sig)
    assert abs(np.mean(err[ok])) < 0.02 * rms_sig
