"""Campaign design studies: N seeded campaigns of a test matrix on the distributed engine.

``run_plan`` writes into ``DIR``::

    DIR/tasks/seed-000001.json   one small summary per finished seed (atomic; a rerun resumes)
    DIR/summary.json             the study (same seeds, same bytes with any number of workers)
    DIR/params.csv               per coefficient, flap, parameter and alpha range
    DIR/effects.csv              per expected effect (with the diagnosis on)
    DIR/coverage.csv             samples per maneuver per flap, kind and alpha range
    DIR/recommendation.txt       what to change, derived from the numbers
    DIR/band.png                 band width against the target per parameter, flap, alpha range
    DIR/run.json                 this run only: workers, seeds run and resumed, time, memory

``compare_plans`` runs two matrices on the same seeds and writes each study in
``DIR/<name>/``, ``DIR/compare.csv`` side by side and ``DIR/compare.png`` (the second's band
width over the first's, the probabilities of being identified).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import polars as pl

from aerodelta._fsutil import write_atomic, write_text_atomic
from aerodelta.exceptions import DataError, InvalidInputError
from aerodelta.plan.aggregate import (
    KEYS,
    coverage_table,
    effect_table,
    param_table,
    recommendation,
)
from aerodelta.plan.engine import Failure, Job, open_client, run_jobs
from aerodelta.plan.matrix import Matrix, load_matrix
from aerodelta.plan.plots import band_figure, compare_figure
from aerodelta.plan.task import TASK_SCHEMA, run_task
from aerodelta.rolloff_plots import save_figure

SCHEMA = "aerodelta.plan/1"


@dataclass(frozen=True)
class PlanResult:
    """The outcome of :func:`run_plan`.

    Attributes
    ----------
    path
        The study folder.
    matrix
        The matrix studied.
    seeds
        The study's seeds.
    params, effects, coverage
        The tables (as written to ``params.csv``, ``effects.csv``, ``coverage.csv``).
    recommendation
        The recommendation text.
    failures
        Seeds whose task failed after its retries, with the error (not in the tables).
    ran
        Seeds run by this call (the others were resumed from ``DIR/tasks``).
    peak_rss_mib
        Largest peak resident memory of a worker over the tasks run now, MiB (NaN if none).
    """

    path: Path
    matrix: Matrix
    seeds: list[int]
    params: pl.DataFrame
    effects: pl.DataFrame
    coverage: pl.DataFrame
    recommendation: str
    failures: list[dict[str, Any]] = field(default_factory=list)
    ran: list[int] = field(default_factory=list)
    peak_rss_mib: float = math.nan


def _clean(x: Any) -> Any:
    """JSON-ready: NaN and infinities as null."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    return x


def _dumps(doc: Any) -> str:
    return json.dumps(_clean(doc), indent=1, sort_keys=True, allow_nan=False) + "\n"


def _task_path(tasks: Path, seed: int) -> Path:
    return tasks / f"seed-{seed:06d}.json"


def _load_done(tasks: Path, digest: str, seeds: Sequence[int]) -> dict[int, dict[str, Any]]:
    """Finished tasks of this matrix in ``tasks`` (a file of another matrix is refused)."""
    done: dict[int, dict[str, Any]] = {}
    if not tasks.is_dir():
        return done
    wanted = set(seeds)
    for p in sorted(tasks.glob("seed-*.json")):
        try:
            doc = json.loads(p.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as e:
            raise DataError(
                f"{p}: unreadable task file ({e}); delete it to run that seed again"
            ) from None
        if doc.get("digest") != digest:
            raise DataError(
                f"{p}: a task of another matrix (digest {doc.get('digest')}, this one {digest}); "
                "give another --out or delete its tasks/ folder"
            )
        s = doc.get("summary", {})
        if s.get("schema") == TASK_SCHEMA and s.get("seed") in wanted:
            done[int(s["seed"])] = s
    return done


@dataclass
class _Study:
    """One matrix's study in progress (results arrive in any order; kept by seed)."""

    matrix: Matrix
    out: Path
    seeds: list[int]
    done: dict[int, dict[str, Any]]
    ran: list[int] = field(default_factory=list)
    rss: list[float] = field(default_factory=list)

    @property
    def tasks(self) -> Path:
        return self.out / "tasks"

    def save(self, summary: dict[str, Any]) -> None:
        seed = int(summary["seed"])
        self.rss.append(float(summary.pop("peak_rss_mib", math.nan)))
        doc = {"digest": self.matrix.digest(), "summary": summary}
        write_text_atomic(_task_path(self.tasks, seed), _dumps(doc))
        self.done[seed] = summary
        self.ran.append(seed)

    def jobs(self) -> list[Job]:
        spec = self.matrix.task_spec()
        digest = self.matrix.digest()
        drill = set(self.matrix.fault_drill_seeds)
        return [
            Job(
                key=f"plan-{digest}-{s}",
                label=f"{self.matrix.name} seed {s}",
                fn=run_task,
                args=(spec, s, s in drill),
                done=self.save,
            )
            for s in self.seeds
            if s not in self.done
        ]


def _study(matrix: Matrix, out: Path, seeds: list[int]) -> _Study:
    if out.exists() and not out.is_dir():
        raise InvalidInputError(
            f"--out {out}: is a file; give a folder (it is created when absent)"
        )
    (out / "tasks").mkdir(parents=True, exist_ok=True)
    return _Study(matrix, out, seeds, _load_done(out / "tasks", matrix.digest(), seeds))


def _finish(st: _Study, failures: Sequence[Failure], seconds: float, workers: str) -> PlanResult:
    """Aggregate in seed order and write the study's files."""
    m = st.matrix
    tasks = [st.done[s] for s in st.seeds if s in st.done]
    fails = [
        {"seed": int(f.key.rsplit("-", 1)[1]), "error": f.error}
        for f in failures
        if f.key.startswith(f"plan-{m.digest()}-")
    ]
    params = param_table(tasks, m)
    effects = effect_table(tasks)
    coverage = coverage_table(tasks)
    text = recommendation(m, params, effects, coverage, len(tasks))
    if fails:
        text += "".join(f"seed {f['seed']} failed: {f['error']}\n" for f in fails)
    summary = {
        "schema": SCHEMA,
        "matrix": m.name,
        "digest": m.digest(),
        "task_spec": m.task_spec(),
        "targets": {
            "relative_band_width": m.relative_band_width,
            "identified_probability": m.identified_probability,
            "named_probability": m.named_probability,
        },
        "seeds": st.seeds,
        "campaigns": len(tasks),
        "failures": fails,
        "params": params.to_dicts(),
        "effects": effects.to_dicts(),
        "coverage": coverage.to_dicts(),
        "recommendation": text,
    }
    write_text_atomic(st.out / "summary.json", _dumps(summary))
    write_atomic(st.out / "params.csv", params.write_csv)
    write_atomic(st.out / "effects.csv", effects.write_csv)
    write_atomic(st.out / "coverage.csv", coverage.write_csv)
    write_text_atomic(st.out / "recommendation.txt", text)
    if params.height:
        fig = band_figure(params, m.relative_band_width, m.alpha_edges_deg, m.name)
        save_figure(fig, st.out / "band.png")
    rss = [r for r in st.rss if math.isfinite(r)]
    run = {
        "workers": workers,
        "ran": sorted(st.ran),
        "resumed": sorted(set(st.done) - set(st.ran)),
        "failed": [f["seed"] for f in fails],
        "seconds": round(seconds, 3),
        "worker_peak_rss_mib": max(rss) if rss else None,
    }
    write_text_atomic(st.out / "run.json", _dumps(run))
    return PlanResult(
        path=st.out,
        matrix=m,
        seeds=st.seeds,
        params=params,
        effects=effects,
        coverage=coverage,
        recommendation=text,
        failures=fails,
        ran=sorted(st.ran),
        peak_rss_mib=max(rss) if rss else math.nan,
    )


def _matrix(m: Matrix | str | os.PathLike[str]) -> Matrix:
    return m if isinstance(m, Matrix) else load_matrix(m)


def _seeds(campaigns: int, seed: int) -> list[int]:
    if campaigns < 1:
        raise InvalidInputError(f"--campaigns {campaigns}: give 1 or more campaigns")
    if seed < 0:
        raise InvalidInputError(f"--seed {seed}: give a seed >= 0")
    return list(range(seed, seed + campaigns))


def _run(
    studies: Sequence[_Study],
    *,
    workers: int,
    scheduler: str | None,
    progress: bool,
    client: Any,
) -> list[PlanResult]:
    t0 = time.perf_counter()
    jobs = [j for st in studies for j in st.jobs()]
    retries = max(st.matrix.retries for st in studies)
    where = scheduler or f"local:{workers}"
    failures: list[Failure] = []
    if jobs:
        if client is not None:
            failures = run_jobs(client, jobs, retries=retries, progress=progress)
        else:
            with open_client(workers, scheduler) as c:
                failures = run_jobs(c, jobs, retries=retries, progress=progress)
    dt = time.perf_counter() - t0
    return [_finish(st, failures, dt, where) for st in studies]


def run_plan(
    matrix: Matrix | str | os.PathLike[str],
    *,
    campaigns: int,
    seed: int,
    out: str | os.PathLike[str],
    workers: int = 2,
    scheduler: str | None = None,
    progress: bool = True,
    client: Any = None,
) -> PlanResult:
    """Fly, fit and (optionally) diagnose ``campaigns`` seeded campaigns of a test matrix.

    Parameters
    ----------
    matrix
        A :class:`~aerodelta.plan.matrix.Matrix` or the matrix file (TOML).
    campaigns
        Number of campaigns; seeds ``seed .. seed + campaigns - 1``.
    seed
        First seed.
    out
        Study folder; finished seeds in ``out/tasks`` are not run again.
    workers
        Worker processes of the local Dask cluster (one thread each).
    scheduler
        Address of a Dask scheduler to use instead (``tcp://host:8786``).
    progress
        Progress bar and failed-task lines on stderr.
    client
        An open Dask client to use instead of ``workers``/``scheduler``.

    Returns
    -------
    PlanResult

    Raises
    ------
    DataError
        A bad matrix, or ``out/tasks`` holding another matrix's tasks.
    InvalidInputError
        Fewer than one campaign, a negative seed, Dask missing, no scheduler at the address.
    """
    m = _matrix(matrix)
    st = _study(m, Path(out), _seeds(campaigns, seed))
    return _run([st], workers=workers, scheduler=scheduler, progress=progress, client=client)[0]


def compare_table(a: PlanResult, b: PlanResult) -> pl.DataFrame:
    """Two studies side by side per coefficient, flap, parameter and alpha range (columns
    suffixed with the matrices' names; a parameter one study never fitted has nulls there)."""
    cols = [
        "p_identified",
        "se_predicted",
        "se_bootstrap",
        "band_width",
        "band_relative",
        "meets_target",
    ]
    na, nb = a.matrix.name, b.matrix.name
    if na == nb:
        na, nb = f"{na}_a", f"{nb}_b"
    left = a.params.select(*KEYS, *cols).rename({c: f"{c}_{na}" for c in cols})
    right = b.params.select(*KEYS, *cols).rename({c: f"{c}_{nb}" for c in cols})
    return left.join(right, on=list(KEYS), how="full", coalesce=True, nulls_equal=True).sort(KEYS)


def compare_plans(
    a: Matrix | str | os.PathLike[str],
    b: Matrix | str | os.PathLike[str],
    *,
    campaigns: int,
    seed: int,
    out: str | os.PathLike[str],
    workers: int = 2,
    scheduler: str | None = None,
    progress: bool = True,
    client: Any = None,
) -> tuple[PlanResult, PlanResult, pl.DataFrame]:
    """Study two matrices on the same seeds (one cluster) and put them side by side.

    Parameters
    ----------
    a, b
        The matrices (or their files); studied in ``out/<name>/`` each.
    campaigns, seed, out, workers, scheduler, progress, client
        As :func:`run_plan`.

    Returns
    -------
    tuple
        Both results and the side-by-side table (also ``out/compare.csv``, and the figure
        ``out/compare.png``: :func:`aerodelta.plan.plots.compare_figure`).
    """
    ma, mb = _matrix(a), _matrix(b)
    if ma.digest() == mb.digest():
        raise InvalidInputError(
            f"--compare: {ma.name} and {mb.name} fly and fit the same campaigns (only targets, "
            "retries or drills differ); compare matrices that differ in what is flown or fitted"
        )
    seeds = _seeds(campaigns, seed)
    root = Path(out)
    na, nb = (ma.name, mb.name) if ma.name != mb.name else (f"{ma.name}_a", f"{mb.name}_b")
    sa, sb = _study(ma, root / na, seeds), _study(mb, root / nb, seeds)
    ra, rb = _run([sa, sb], workers=workers, scheduler=scheduler, progress=progress, client=client)
    table = compare_table(ra, rb)
    write_atomic(root / "compare.csv", table.write_csv)
    fig = compare_figure(table, (na, nb), ma.relative_band_width, ma.alpha_edges_deg)
    save_figure(fig, root / "compare.png")
    return ra, rb, table


def read_summary(path: str | os.PathLike[str]) -> Mapping[str, Any]:
    """A study's ``summary.json``."""
    p = Path(path)
    p = p / "summary.json" if p.is_dir() else p
    try:
        return dict(json.loads(p.read_text(encoding="utf-8")))
    except (OSError, json.JSONDecodeError) as e:
        raise DataError(f"{p}: cannot read the study summary: {e}") from None
