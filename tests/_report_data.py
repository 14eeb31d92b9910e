"""A quick campaign, ingested and fitted once per test process, for the report tests."""

from __future__ import annotations

import functools
import tempfile
from pathlib import Path

import polars as pl

from aerodelta.campaign import generate_campaign
from aerodelta.fit import FitResult, fit
from aerodelta.ingest import ingest


@functools.lru_cache(maxsize=1)
def quick_fit() -> tuple[Path, pl.DataFrame, FitResult, list[str]]:
    """(folder, ingested data, fit result, held-out ids) of the quick campaign (seed 3).

    The model is saved as ``folder/model.json`` with its per-bin estimates beside it.
    """
    root = Path(tempfile.mkdtemp(prefix="aerodelta-report-"))
    generate_campaign(root / "campaign", seed=3, size="quick")
    data = ingest(root / "campaign", compat=False).data
    ids = data["maneuver_id"].unique().sort().to_list()
    held = ids[::5]
    res = fit(data.filter(~pl.col("maneuver_id").is_in(held)))
    res.model.save(root / "model.json")
    res.summary().write_parquet(root / "model.params.parquet")
    return root, data, res, held
