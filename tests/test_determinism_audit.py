"""Run-to-run determinism of outputs that went through an unordered step: a polars hash
``group_by`` (its groups come out in a random order on every call), a sort whose key leaves
ties, or a Python set of strings (iterated in a per-process hash-seed order)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from typing import Any

import numpy as np
import polars as pl
import pytest

from aerodelta.fit import stall_alpha
from aerodelta.longitudinal import binned_static_curve
from aerodelta.report import params as report_params
from aerodelta.report.context import ReportContext

RUNS = 24


def _tied_lift_frame(seed: int) -> pl.DataFrame:
    """Records whose two alpha bins (0.5 deg) at 12.25 and 14.25 deg have the very same lift
    coefficient, bit for bit, above every other bin; rows in a shuffled order."""
    c_max = 1.3
    a_lo, a_hi = np.radians(12.25), np.radians(14.25)
    cz_lo = -c_max / np.cos(a_lo)
    cl_lo = -cz_lo * np.cos(a_lo)
    cz_hi = -cl_lo / np.cos(a_hi)
    while -cz_hi * np.cos(a_hi) != cl_lo:  # a few ulps to the exact tie
        cz_hi = np.nextafter(cz_hi, -np.inf if -cz_hi * np.cos(a_hi) < cl_lo else np.inf)
    alpha = np.concatenate([np.full(60, 12.25), np.full(60, 14.25), np.full(60, 10.25)])
    cz = np.concatenate([np.full(60, cz_lo), np.full(60, cz_hi), np.full(60, -1.0)])
    order = np.random.default_rng(seed).permutation(alpha.size)
    return pl.DataFrame(
        {"alpha_deg": alpha[order], "CX_meas": np.zeros(alpha.size), "CZ_meas": cz[order]}
    )


def test_stall_alpha_of_equal_bins_is_the_lowest_every_run() -> None:
    # the hash grouping put the two tied bins in a random order, and the sort on the mean
    # alone kept it: the stall alpha was either bin's from one call to the next
    for seed in range(RUNS):
        assert stall_alpha(_tied_lift_frame(seed)) == 12.25


def _fan_frame(order: np.ndarray) -> pl.DataFrame:
    """Twelve maneuvers in one 1-deg bin (25 samples each) whose mean C_L spread over sixteen
    orders of magnitude: their n-weighted sum depends on the order it is taken in. Maneuvers
    concatenated in ``order``."""
    parts = []
    for k in order:
        scale = 10.0 ** (int(k) - 6) * (-1.0) ** int(k)
        alpha = 10.0 + np.linspace(-0.3, 0.3, 25)
        cl = scale * (1.0 + 0.01 * np.arange(25))
        parts.append(
            pl.DataFrame(
                {
                    "maneuver_id": f"m{int(k):02d}",
                    "t": 0.02 * np.arange(25),
                    "alpha_deg": alpha,
                    "alphadot_dps": np.zeros(25),
                    "flap_deg": 0.0,
                    "CX_meas": np.zeros(25),
                    "CZ_meas": -cl / np.cos(np.radians(alpha)),
                    "Cm_meas": -0.5 * scale * np.ones(25),
                }
            )
        )
    return pl.concat(parts)


def test_binned_static_curve_is_bit_identical_across_runs_and_maneuver_order() -> None:
    # the per-maneuver means came out of a hash grouping in a random order, and the bin's
    # n-weighted sums over them (and the standard errors) were taken in that order
    ref = binned_static_curve(_fan_frame(np.arange(12)), min_samples=1)
    assert ref.height == 1 and ref["n_maneuvers"][0] == 12
    rng = np.random.default_rng(3)
    for run in range(RUNS):
        order = np.arange(12) if run % 2 == 0 else rng.permutation(12)
        b = binned_static_curve(_fan_frame(order), min_samples=1)
        assert b.write_csv() == ref.write_csv(), f"run {run}, maneuvers in order {order}"
    # and the same values as a row-order-free reference (to rounding)
    f = _fan_frame(np.arange(12))
    a = np.radians(f["alpha_deg"].to_numpy())
    cl = -f["CZ_meas"].to_numpy() * np.cos(a)
    assert ref["CL"][0] == pytest.approx(float(np.mean(cl)), rel=1e-9, abs=1e-12)


def test_params_section_picks_the_lowest_of_equally_sampled_flaps(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # the error-against-regressor figures are drawn for the flap with the most samples: with
    # equal counts the hash grouping's order chose one, and the report's figures changed
    chosen: list[float] = []

    def record(ctx: Any, sink: Any, coef: str, flap: float) -> None:
        chosen.append(flap)

    monkeypatch.setattr(report_params, "_error_vs_regressor", record)
    monkeypatch.setattr(report_params, "_tables", lambda ctx: {})
    monkeypatch.setattr(report_params, "_param_figure", lambda *a, **k: "")
    params = pl.DataFrame(
        {
            "coefficient": ["Cl"] * 4,
            "flap_deg": [0.0, 0.0, 20.0, 20.0],
            "alpha_lo_deg": [0.0, 1.0, 0.0, 1.0],
            "identifiable": [True, False, True, True],
        }
    )
    rng = np.random.default_rng(5)
    for _ in range(RUNS):
        flaps = np.repeat([0.0, 20.0, 40.0], [7, 7, 3])
        data = pl.DataFrame({"flap_deg": flaps[rng.permutation(flaps.size)]})
        ctx = ReportContext(None, data, params, ["Cl"], [], "columns")  # type: ignore[arg-type]
        chosen.clear()
        report_params.section(ctx, None)  # type: ignore[arg-type]
        assert chosen == [0.0]


_SCORE_CASE = textwrap.dedent(
    """
    import json, sys, tempfile
    from pathlib import Path
    from types import SimpleNamespace
    import numpy as np
    import polars as pl
    from aerodelta.diagnosis.withheld import score_case

    n = 200
    rng = np.random.default_rng(0)
    t = 0.02 * np.arange(n)
    alpha = np.linspace(0.0, 19.9, n)
    contrib = {c: (k + 1.0) * np.sin(t * (k + 1.0)) for k, c in enumerate(("Cl", "Cn", "CY"))}
    preds = {"maneuver_id": ["m0"] * n, "t": t, "alpha_deg": alpha}
    for c, v in contrib.items():
        gap = v + 0.01 * rng.standard_normal(n)
        preds |= {f"{c}_gap": gap, f"{c}_explained": 0.9 * gap, f"{c}_timing": np.zeros(n)}
    with tempfile.TemporaryDirectory() as d:
        pl.DataFrame({"t": t, **{f"d{c}_dihedral": v for c, v in contrib.items()}}).write_parquet(
            Path(d) / "m0.parquet"
        )
        res = {c: {"verdict": "dihedral", "effects": [], "where": []} for c in contrib}
        diag = SimpleNamespace(predictions=pl.DataFrame(preds), result={"coefficients": res})
        case = score_case(diag, Path(d), {"dihedral": 0.01})
    print(json.dumps(list(case.shrink_ratio)))
    """
)


def test_withheld_case_shrink_ratio_in_coefficient_order_for_any_hash_seed() -> None:
    # the coefficients an effect touches were a set of strings, iterated in the process's
    # hash-seed order: the case's JSON listed them in a different order per process
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    seen = set()
    for seed in range(8):
        env["PYTHONHASHSEED"] = str(seed)
        out = subprocess.run(
            [sys.executable, "-c", _SCORE_CASE], env=env, capture_output=True, text=True, check=True
        )
        seen.add(out.stdout.strip().splitlines()[-1])
    assert seen == {'["Cl", "Cn", "CY"]'}


_BIN_MEANS = textwrap.dedent(
    """
    import hashlib
    import numpy as np
    from aerodelta.diagnosis.core import _bin_means

    rng = np.random.default_rng(0)
    n = 300_000
    alpha = rng.uniform(0.0, 20.0, n)
    value = rng.standard_normal(n) ** 2 * 10.0 ** rng.integers(-6, 6, n)
    for _ in range(4):
        b, m = _bin_means(alpha, value)
        print(hashlib.sha256(b.tobytes() + m.tobytes()).hexdigest())
    """
)


def test_diagnosis_bin_means_are_the_same_bytes_for_any_polars_thread_count() -> None:
    # a polars group_by mean of floats splits its sums over the thread pool: the per-bin
    # means (hence an effect's alpha range in diagnosis.json) changed with the thread count
    # and from one call to the next
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    seen = set()
    for threads in (1, 2, 3):
        env["POLARS_MAX_THREADS"] = str(threads)
        out = subprocess.run(
            [sys.executable, "-c", _BIN_MEANS], env=env, capture_output=True, text=True, check=True
        )
        seen |= set(out.stdout.split())
    assert len(seen) == 1


def test_diagnosis_bin_means_are_the_per_bin_means() -> None:
    from aerodelta.diagnosis.core import _bin_means  # noqa: PLC0415

    rng = np.random.default_rng(1)
    alpha = rng.uniform(-2.0, 6.0, 500)
    value = rng.standard_normal(500)
    alpha[:30] = 5.5  # bin 5 holds at least 30 points; bins with fewer than 20 are left out
    bins, means = _bin_means(alpha, value)
    floor = np.floor(alpha)
    want = [b for b in np.unique(floor) if np.count_nonzero(floor == b) >= 20]
    np.testing.assert_array_equal(bins, want)
    np.testing.assert_allclose(
        means, [value[floor == b].mean() for b in want], rtol=1e-12, atol=1e-15
    )
