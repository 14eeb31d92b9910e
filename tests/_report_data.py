"""A quick campaign, ingested and fitted, and its report: built once per test process and
shared by the report tests (tests/test_report.py, tests/test_report_browser.py)."""

from __future__ import annotations

import atexit
import functools
import shutil
import tempfile
from pathlib import Path
from typing import Any

import polars as pl

from aerodelta.campaign import generate_campaign
from aerodelta.fit import FitResult, fit
from aerodelta.ingest import ingest
from aerodelta.report import ReportResult, build_report


@functools.lru_cache(maxsize=1)
def quick_fit() -> tuple[Path, pl.DataFrame, FitResult, list[str]]:
    """(folder, ingested data, fit result, held-out ids) of the quick campaign (seed 3).

    The model is saved as ``folder/model.json`` with its per-bin estimates beside it.
    """
    root = Path(tempfile.mkdtemp(prefix="aerodelta-report-"))
    atexit.register(shutil.rmtree, root, ignore_errors=True)
    generate_campaign(root / "campaign", seed=3, size="quick")
    data = ingest(root / "campaign", compat=False).data
    ids = data["maneuver_id"].unique().sort().to_list()
    held = ids[::5]
    res = fit(data.filter(~pl.col("maneuver_id").is_in(held)))
    res.model.save(root / "model.json")
    res.summary().write_parquet(root / "model.params.parquet")
    return root, data, res, held


@functools.lru_cache(maxsize=1)
def quick_report() -> ReportResult:
    """The report of :func:`quick_fit` with the hand-made diagnosis, two replays, PNG + SVG."""
    root, data, _, held = quick_fit()
    return build_report(
        root / "model.json",
        data,
        root / "report",
        held_out=held,
        diagnosis_doc=diagnosis_fixture(),
        replay_count=2,
    )


def diagnosis_fixture() -> dict[str, Any]:
    """A hand-made diagnosis following schema aerodelta.diagnosis/1 (with unknown keys and a
    coefficient missing optional ones)."""

    def eff(name: str, rank: int, before: float, after: float, sig: bool) -> dict[str, Any]:
        return {
            "effect": name,
            "rank": rank,
            "significant": sig,
            "ambiguous_with": ["time_skew"],
            "alpha_range_deg": [12.0, 20.0],
            "gap_rms_before": before,
            "gap_rms_after": after,
            "shrink_fraction": 1 - after / before,
            "statistic": 12.5,
            "p_value": 1e-4,
            "extra_key": "ignored",
        }

    where = [
        {
            "flap_deg": f,
            "alpha_lo_deg": lo,
            "alpha_hi_deg": lo + 2.0,
            "phase": ph,
            "rms": 0.001 * lo,
            "bias": 0.0002,
            "significant": lo > 12,
        }
        for f in (0.0, 10.0)
        for lo in (8.0, 10.0, 12.0, 14.0)
        for ph in ("stall", "recovery")
    ]
    return {
        "schema": "aerodelta.diagnosis/1",
        "coefficients": {
            "Cl": {
                "verdict": "aileron_reversal",
                "gap": {"rms": 0.004, "bias": 0.0, "tic": 0.3},
                "where": where,
                "effects": [
                    eff("aileron_reversal", 1, 0.004, 0.002, True),
                    eff("roll_damping_loss", 2, 0.002, 0.0019, False),
                ],
            },
            "Cn": {"verdict": "none", "gap": {"rms": 0.001}, "where": [], "effects": []},
        },
        "future_key": {"anything": 1},
    }
