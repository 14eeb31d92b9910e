"""The Δ-model file: evaluation against hand-computed Eq. 3.11-3.12/3.19 values, round trip."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad


def _spec() -> dict:
    return {
        "schema": "aerodelta.model/1",
        "flaps_deg": [0.0, 10.0],
        "coefficients": {
            "Cl": {
                "terms": [
                    {
                        "name": "dCl_0",
                        "regressor": "1",
                        "alpha_deg": [10.0, 20.0],
                        "values": [[0.0, 0.01], [0.0, 0.03]],
                    },
                    {
                        "name": "dCl_da",
                        "regressor": "deadband(da_deg, 2)",
                        "alpha_deg": [10.0, 15.0, 20.0],
                        "values": [[0.0, 0.001, 0.002], [0.0, 0.002, 0.004]],
                    },
                ],
                "alpha_l_deg": [8.0, 10.0],
                "alpha_u_deg": [12.0, 14.0],
            }
        },
        "provenance": {"note": "test"},
    }


def _reference(alpha: np.ndarray, flap: np.ndarray, da: np.ndarray) -> np.ndarray:
    """Independent numpy evaluation of w(alpha) * sum theta_j(flap, alpha) x_j."""

    def table(alphas: list[float], rows: list[list[float]], a: float, f: float) -> float:
        r0 = np.interp(a, alphas, rows[0])
        r1 = np.interp(a, alphas, rows[1])
        return float(np.interp(f, [0.0, 10.0], [r0, r1]))

    spec = _spec()["coefficients"]["Cl"]
    out = []
    for a, f, d in zip(alpha, flap, da, strict=True):
        x_da = max(d - 2.0, 0.0) + min(d + 2.0, 0.0)
        t0, t1 = spec["terms"]
        delta = (
            table(t0["alpha_deg"], t0["values"], a, f)
            + table(t1["alpha_deg"], t1["values"], a, f) * x_da
        )
        lo = np.interp(f, [0.0, 10.0], spec["alpha_l_deg"])
        hi = np.interp(f, [0.0, 10.0], spec["alpha_u_deg"])
        w = float(np.clip((a - lo) / (hi - lo), 0.0, 1.0))
        out.append(w * delta)
    return np.array(out)


def test_evaluate_matches_independent_reference() -> None:
    rng = np.random.default_rng(3)
    n = 2000
    df = pl.DataFrame(
        {
            "alpha_deg": rng.uniform(0, 30, n),
            "flap_deg": rng.uniform(-5, 15, n),
            "da_deg": rng.uniform(-20, 20, n),
        }
    )
    m = ad.DeltaModel.from_spec(_spec())
    out = m.evaluate(df, terms=True)
    ref = _reference(df["alpha_deg"].to_numpy(), df["flap_deg"].to_numpy(), df["da_deg"].to_numpy())
    np.testing.assert_allclose(out["dCl_blended"].to_numpy(), ref, rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        out["dCl"].to_numpy(), (out["dCl_0"] + out["dCl_da"]).to_numpy(), atol=1e-15
    )


def test_round_trip_and_atomic_save(tmp_path: Path) -> None:
    m = ad.DeltaModel.from_spec(_spec())
    p = tmp_path / "m.json"
    m.save(p)
    assert [q.name for q in tmp_path.iterdir()] == ["m.json"]
    back = ad.DeltaModel.load(p)
    assert back.to_spec() == m.to_spec()
    assert back.coefficients == ["Cl"]
    assert back.input_columns == ["alpha_deg", "flap_deg", "da_deg"]
    assert back.parameter("Cl", "dCl_da", 5.0, 15.0) == pytest.approx(0.0015, abs=1e-16)


def test_bad_models_are_refused_with_place(tmp_path: Path) -> None:
    s = _spec()
    s["coefficients"]["Cl"]["terms"][1]["regressor"] = "deadband(da_deg)"
    with pytest.raises(ad.InvalidInputError, match=r"term 'dCl_da'.*takes 2 argument"):
        ad.DeltaModel.from_spec(s)
    p = tmp_path / "broken.json"
    p.write_text(json.dumps(_spec())[:-5])
    with pytest.raises(ad.ParseError, match=r"broken.json:1:"):
        ad.DeltaModel.load(p)
    m = ad.DeltaModel.from_spec(_spec())
    with pytest.raises(ad.InvalidInputError, match=r"da_deg"):
        m.evaluate(pl.DataFrame({"alpha_deg": [1.0], "flap_deg": [0.0]}))
