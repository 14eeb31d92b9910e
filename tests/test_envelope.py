"""The validated envelope stored with a fitted model (issue 20, item 4: the extended model's
"outside the validated envelope" indication): the data's alpha/beta coverage per flap,
checked point by point against a brute-force reading of the fitted data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta.fit import ENVELOPE_BAND_DEG, FitConfig


@pytest.fixture(scope="module")
def fitted(quick_campaign: Path) -> tuple[pl.DataFrame, ad.DeltaModel, int]:
    data = ad.ingest(quick_campaign, compat=False, progress=False).data
    cfg = FitConfig()
    return data, ad.fit(data, config=cfg).model, cfg.min_maneuvers_identified


def _brute_force(data: pl.DataFrame, flap: float, alpha: float, beta: float, need: int) -> bool:
    """Inside when the alpha band at the nearest flap holds samples of ``need`` maneuvers or
    more and ``beta`` lies within their sideslip range (loops over the rows' numpy arrays)."""
    flaps = np.unique(data["flap_deg"].to_numpy())
    f = flaps[np.argmin(np.abs(flaps - flap))]
    band = np.floor(alpha / ENVELOPE_BAND_DEG)
    rows = (data["flap_deg"].to_numpy() == f) & (
        np.floor(data["alpha_deg"].to_numpy() / ENVELOPE_BAND_DEG) == band
    )
    if len(set(data["maneuver_id"].to_numpy()[rows].tolist())) < need:
        return False
    b = data["beta_deg"].to_numpy()[rows]
    return bool(b.min() <= beta <= b.max())


def test_envelope_matches_the_data_point_by_point(fitted) -> None:
    data, model, need = fitted
    env = model.envelope
    assert env is not None and env.height > 0
    assert set(env["flap_deg"].unique().to_list()) <= set(data["flap_deg"].unique().to_list())
    assert (env["maneuvers"] >= need).all()
    rng = np.random.default_rng(8)
    # query points: around flown states (near the beta limits too) and far outside
    pick = rng.integers(0, data.height, 400)
    q = pl.DataFrame(
        {
            "flap_deg": data["flap_deg"].to_numpy()[pick] + rng.normal(0, 2.0, 400),
            "alpha_deg": data["alpha_deg"].to_numpy()[pick] + rng.normal(0, 3.0, 400),
            "beta_deg": data["beta_deg"].to_numpy()[pick] * rng.uniform(0.5, 4.0, 400),
        }
    )
    got = model.in_envelope(q).to_list()
    want = [
        _brute_force(data, *row, need)
        for row in q.select("flap_deg", "alpha_deg", "beta_deg").iter_rows()
    ]
    assert got == want
    assert 0.2 < np.mean(got) < 0.95  # both answers are exercised
    far = pl.DataFrame({"flap_deg": [0.0, 0.0], "alpha_deg": [89.0, 12.0], "beta_deg": [0.0, 80.0]})
    assert model.in_envelope(far).to_list() == [False, False]


def test_envelope_survives_the_model_file_and_refuses_what_it_cannot_answer(
    fitted, tmp_path: Path
) -> None:
    _, model, _ = fitted
    path = tmp_path / "model.json"
    model.save(path)
    back = ad.DeltaModel.load(path)
    assert back.envelope is not None and back.envelope.equals(model.envelope)
    with pytest.raises(ad.DataError, match="lacks beta_deg"):
        back.in_envelope(pl.DataFrame({"flap_deg": [0.0], "alpha_deg": [10.0]}))
    nulls = pl.DataFrame({"flap_deg": [0.0], "alpha_deg": [None], "beta_deg": [0.0]})
    assert back.in_envelope(nulls).to_list() == [False]
    spec = model.to_spec()
    del spec["envelope"]
    plain = ad.DeltaModel.from_spec(spec)
    assert plain.envelope is None
    with pytest.raises(ad.InvalidInputError, match="carries no validated envelope"):
        plain.in_envelope(pl.DataFrame({"flap_deg": [0.0], "alpha_deg": [10.0], "beta_deg": [0.0]}))
    spec["envelope"] = {"band_deg": -1.0, "flaps_deg": [0.0], "bands": [[]], "min_maneuvers": 2}
    with pytest.raises(ad.InvalidInputError, match="band_deg"):
        ad.DeltaModel.from_spec(spec)
