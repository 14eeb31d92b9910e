"""The roll-off Monte Carlo (:func:`aerodelta.rolloff.monte_carlo`) on the distributed engine.

The stalls ``0 .. n - 1`` of one seed are split into chunks of fixed size; chunk ``k`` flies
stalls ``k * chunk .. (k + 1) * chunk - 1`` (``first=``), so each stall is the same flight
whatever chunk or worker runs it, and the chunks concatenated equal one
``monte_carlo(n, seed)`` call. Each finished chunk is written as one Parquet file
(``DIR/chunks/chunk-000000000.parquet``, atomically; a rerun resumes), and the summary is
computed from a lazy scan of that folder (one pass, the stalls never all in memory at once)::

    DIR/rolloff.json     the study's settings (a rerun with other settings is refused)
    DIR/chunks/          one Parquet file per chunk of stalls
    DIR/summary.json     counts, FAR 25.203 pass rate, bank and onset statistics
    DIR/run.json         this run only: workers, chunks run and resumed, time
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import polars as pl

from aerodelta._fsutil import write_atomic, write_text_atomic
from aerodelta.exceptions import DataError, InvalidInputError
from aerodelta.plan.engine import Job, open_client, run_jobs
from aerodelta.rolloff import monte_carlo

SCHEMA = "aerodelta.plan.rolloff/1"


@dataclass(frozen=True)
class RolloffStudy:
    """The outcome of :func:`run_rolloff_study`.

    Attributes
    ----------
    path
        The study folder.
    summary
        The ``summary.json`` content.
    ran
        First stall index of each chunk run by this call (others were resumed).
    failures
        Chunks that failed after their retries: ``first`` stall and error.
    """

    path: Path
    summary: dict[str, Any]
    ran: list[int] = field(default_factory=list)
    failures: list[dict[str, Any]] = field(default_factory=list)


def mc_chunk(settings: Mapping[str, Any], first: int, n: int) -> pl.DataFrame:
    """Stalls ``first .. first + n - 1`` of the study (runs on a worker, one engine thread).

    Parameters
    ----------
    settings
        ``seed``, ``flap_deg`` (deg), ``turbulence_mps`` (m/s), ``excitation`` (-),
        ``config`` (roll-off configuration or ``None`` for thesis Table 3.2).
    first
        Index of the first stall.
    n
        Number of stalls.

    Returns
    -------
    polars.DataFrame
        As :func:`aerodelta.rolloff.monte_carlo`.
    """
    return monte_carlo(
        n,
        int(settings["seed"]),
        flap_deg=float(settings["flap_deg"]),
        config=settings["config"],
        turbulence=float(settings["turbulence_mps"]),
        excitation=float(settings["excitation"]),
        first=first,
        threads=1,
    )


def _chunk_path(folder: Path, first: int) -> Path:
    return folder / f"chunk-{first:09d}.parquet"


def rolloff_summary(chunks: Path) -> dict[str, Any]:
    """Statistics of every stall in ``chunks`` (lazy scan of the Parquet files).

    Returns
    -------
    dict
        ``stalls``, ``far25_203_pass`` (share with max |φ| <= 20 deg), ``pusher_fired``
        (share), ``rolloff_met`` (share with a roll-off, ``direction != 0``), ``right_share``
        (of those), ``max_bank_deg`` and ``max_dynamic_roll_deg`` quantiles (p50, p95, p99,
        deg), ``onset_alpha_deg`` mean and standard deviation (deg, stalls that met it).
    """
    files = sorted(chunks.glob("chunk-*.parquet"))
    if not files:
        return {"stalls": 0}
    lf = pl.scan_parquet(files)
    met = pl.col("direction") != 0
    onset = pl.col("onset_alpha_deg").filter(pl.col("onset_alpha_deg").is_not_nan())
    q = lf.select(
        pl.len().alias("stalls"),
        pl.col("far25_203_pass").mean().alias("far25_203_pass"),
        pl.col("pusher_fired").mean().alias("pusher_fired"),
        met.mean().alias("rolloff_met"),
        (pl.col("direction") > 0).filter(met).mean().alias("right_share"),
        *[
            pl.col(c).quantile(p, interpolation="linear").alias(f"{c}_p{int(p * 100)}")
            for c in ("max_bank_deg", "max_dynamic_roll_deg")
            for p in (0.5, 0.95, 0.99)
        ],
        onset.mean().alias("onset_alpha_deg_mean"),
        onset.std().alias("onset_alpha_deg_sd"),
    ).collect()
    return {
        k: (None if isinstance(v, float) and math.isnan(v) else v)
        for k, v in q.row(0, named=True).items()
    }


def run_rolloff_study(
    stalls: int,
    *,
    seed: int,
    out: str | os.PathLike[str],
    flap_deg: float = 0.0,
    chunk: int = 5000,
    turbulence: float = 0.5,
    excitation: float = 1.0,
    config: Mapping[str, Any] | None = None,
    workers: int = 2,
    scheduler: str | None = None,
    retries: int = 2,
    progress: bool = True,
    client: Any = None,
) -> RolloffStudy:
    """Run ``stalls`` straight stalls of the roll-off Monte Carlo in seeded chunks on the
    distributed engine.

    Parameters
    ----------
    stalls
        Number of stalls (half with the stick pusher).
    seed
        Seed (the campaign seed of :func:`aerodelta.rolloff.monte_carlo`).
    out
        Study folder; finished chunks in ``out/chunks`` are not run again.
    flap_deg
        Flap setting, deg (0, 5, 10, 15 or 35).
    chunk
        Stalls per task (the split does not change any stall).
    turbulence
        Dryden gust RMS, m/s.
    excitation
        Pilot excitation scale, -.
    config
        Roll-off configuration (``None``: thesis Table 3.2).
    workers, scheduler, retries, progress, client
        As :func:`aerodelta.plan.run_plan`.

    Returns
    -------
    RolloffStudy

    Raises
    ------
    InvalidInputError
        Fewer than 1 stall or chunk, a flap the aircraft does not fly.
    DataError
        ``out`` holding a study with other settings.
    """
    if stalls < 1 or chunk < 1:
        raise InvalidInputError(f"stalls ({stalls}) and chunk ({chunk}) must be >= 1")
    if flap_deg not in (0.0, 5.0, 10.0, 15.0, 35.0):
        raise InvalidInputError(f"--flap {flap_deg:g}: use one of 0, 5, 10, 15, 35")
    settings = {
        "schema": SCHEMA,
        "seed": int(seed),
        "stalls": int(stalls),
        "flap_deg": float(flap_deg),
        "chunk": int(chunk),
        "turbulence_mps": float(turbulence),
        "excitation": float(excitation),
        "config": None if config is None else dict(config),
    }
    root = Path(out)
    chunks = root / "chunks"
    chunks.mkdir(parents=True, exist_ok=True)
    stored = root / "rolloff.json"
    text = json.dumps(settings, indent=1, sort_keys=True) + "\n"
    if stored.exists() and stored.read_text(encoding="utf-8") != text:
        raise DataError(
            f"{stored}: this folder holds a Monte Carlo with other settings (stalls, seed, "
            "flap, chunk, turbulence, excitation or configuration); give another --out or delete it"
        )
    write_text_atomic(stored, text)
    firsts = list(range(0, stalls, chunk))
    ran: list[int] = []

    def saver(first: int) -> Any:
        def save(df: pl.DataFrame) -> None:
            write_atomic(
                _chunk_path(chunks, first), lambda p: df.write_parquet(p, statistics=False)
            )
            ran.append(first)

        return save

    jobs = [
        Job(
            key=f"rolloff-{seed}-{flap_deg:g}-{first}-{chunk}",
            label=f"roll-off stalls {first}-{min(first + chunk, stalls) - 1}",
            fn=mc_chunk,
            args=(settings, first, min(chunk, stalls - first)),
            done=saver(first),
        )
        for first in firsts
        if not _chunk_path(chunks, first).exists()
    ]
    t0 = time.perf_counter()
    if client is not None:
        failures = run_jobs(client, jobs, retries=retries, progress=progress)
    elif jobs:
        with open_client(workers, scheduler) as c:
            failures = run_jobs(c, jobs, retries=retries, progress=progress)
    else:
        failures = []
    fails = [{"first": int(f.key.split("-")[-2]), "error": f.error} for f in failures]
    summary = {"schema": SCHEMA, "settings": settings, "failures": fails,
               **rolloff_summary(chunks)}  # fmt: skip
    write_text_atomic(root / "summary.json", json.dumps(summary, indent=1, sort_keys=True) + "\n")
    run = {
        "workers": scheduler or f"local:{workers}",
        "ran": sorted(ran),
        "resumed": sorted(set(firsts) - set(ran) - {f["first"] for f in fails}),
        "seconds": round(time.perf_counter() - t0, 3),
    }
    write_text_atomic(root / "run.json", json.dumps(run, indent=1, sort_keys=True) + "\n")
    return RolloffStudy(root, summary, sorted(ran), fails)
