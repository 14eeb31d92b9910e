"""The qualified model exported to DAVE-ML equals the engine's qualified model and passes its
own check cases in an independent read."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta import _core
from aerodelta.cli import main
from aerodelta.export import export_qualified_daveml


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("export") / "adx37.dml"
    export_qualified_daveml(p)
    return p


def test_exported_checks_pass(exported: Path) -> None:
    res = ad.check_daveml(exported)
    assert res.height > 0 and res["pass"].all()


def test_exported_equals_engine_at_random_states(exported: Path) -> None:
    rng = np.random.default_rng(0)
    n = 3000
    s = {
        "alpha_deg": rng.uniform(-20, 40, n),
        "beta_deg": rng.uniform(-50, 50, n),
        "phat": rng.normal(0, 0.02, n),
        "qhat": rng.normal(0, 0.01, n),
        "rhat": rng.normal(0, 0.02, n),
        "alphadot_dps": np.zeros(n),
        "betadot_dps": np.zeros(n),
        "da_deg": rng.uniform(-25, 25, n),
        "de_deg": rng.uniform(-15, 15, n),
        "dr_deg": rng.uniform(-25, 25, n),
        "dsl_deg": np.where(rng.random(n) < 0.5, rng.uniform(0, 40, n), 0.0),
        "dsr_deg": np.where(rng.random(n) < 0.5, rng.uniform(0, 40, n), 0.0),
        "flap_deg": rng.choice([0.0, 5.0, 10.0, 15.0, 35.0, 7.5], n),
        "ct_left": rng.uniform(-0.2, 1.8, n),
        "ct_right": rng.uniform(-0.2, 1.8, n),
        "tas_mps": rng.uniform(45, 120, n),
    }
    cl, cn, cy = _core.qualified_lateral_adx37({k: np.ascontiguousarray(v) for k, v in s.items()})
    dave = ad.load_daveml(exported).evaluate(
        pl.DataFrame(
            {
                "alpha_deg": s["alpha_deg"],
                "beta_rad": np.radians(s["beta_deg"]),
                "phat": s["phat"],
                "qhat": s["qhat"],
                "rhat": s["rhat"],
                "alphadot_hat": np.zeros(n),
                "de_rad": np.radians(s["de_deg"]),
                "da_deg": s["da_deg"],
                "dr_deg": s["dr_deg"],
                "dsl_deg": s["dsl_deg"],
                "dsr_deg": s["dsr_deg"],
                "flap_deg": s["flap_deg"],
                "ct_left": s["ct_left"],
                "ct_right": s["ct_right"],
            }
        )
    )
    np.testing.assert_allclose(dave["Cl"].to_numpy(), cl, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dave["Cn"].to_numpy(), cn, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dave["CY"].to_numpy(), cy, rtol=0, atol=1e-12)


def test_cli_export(tmp_path: Path) -> None:
    out = tmp_path / "q.dml"
    assert main(["export-qualified", str(out)]) == 0
    assert main(["check-daveml", str(out)]) == 0
