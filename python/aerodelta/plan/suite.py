"""Benchmark suites as seeded tasks on the distributed engine (issue 21).

The identification and withheld-effect suites of ``benchmarks/`` run each of their cases (a
campaign flown, fitted or diagnosed and scored) through :func:`run_cases`: the cases spread
over the workers of a Dask cluster (:func:`aerodelta.plan.engine.open_client`: a
``LocalCluster`` by default, ``scheduler`` for a cluster), a failed case is retried and then
reported (never dropped), each finished case is kept in a resume folder so an interrupted suite
goes on where it stopped, and the results come back in case order: a case depends on its
arguments only, so the suite's numbers are the same with any number of workers.

``workers=0`` runs the cases one after the other in the calling process (no Dask), as the
suites did before.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from aerodelta._fsutil import write_bytes_atomic
from aerodelta.exceptions import DataError, InvalidInputError
from aerodelta.plan.engine import Failure, Job, open_client, run_jobs


@dataclass
class SuiteRun:
    """What :func:`run_cases` returns.

    Attributes
    ----------
    results
        One result per case, in case order; ``None`` for a case that failed.
    failures
        The cases that failed after their retries, in case order.
    resumed
        Cases read back from the resume folder instead of being run.
    """

    results: list[Any] = field(default_factory=list)
    failures: list[Failure] = field(default_factory=list)
    resumed: int = 0


def case_key(fn: Callable[..., Any], args: Sequence[Any]) -> str:
    """A case's identity: SHA-256 (16 hex digits) of the function's qualified name and the
    ``repr`` of its arguments (a resumed result is only reused for the same call)."""
    ident = f"{getattr(fn, '__qualname__', repr(fn))}{tuple(args)!r}"
    return hashlib.sha256(ident.encode()).hexdigest()[:16]


def _resume_path(folder: Path, name: str, index: int, key: str) -> Path:
    return folder / f"{name}-{index:05d}-{key}.pkl"


def _load(path: Path) -> Any:
    try:
        return pickle.loads(path.read_bytes())
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError) as e:
        raise DataError(
            f"{path}: unreadable saved case ({type(e).__name__}: {e}); delete it to run the "
            "case again"
        ) from None


def run_cases(
    fn: Callable[..., Any],
    cases: Sequence[Sequence[Any]],
    *,
    labels: Sequence[str] | None = None,
    workers: int = 2,
    scheduler: str | None = None,
    retries: int = 2,
    resume: str | os.PathLike[str] | None = None,
    name: str = "case",
    progress: bool = True,
    client: Any = None,
) -> SuiteRun:
    """Run ``fn(*case)`` for every case, on the engine's workers or in this process.

    Parameters
    ----------
    fn
        The case function: module level (the workers receive it by reference, or by value
        from a script's ``__main__``), its result picklable and small (a summary, not records).
    cases
        The argument tuples, one per case; their ``repr`` names the case in the resume
        folder, so it must be the same from run to run (numbers, strings, paths, dicts built
        in a fixed order).
    labels
        One line per case for the progress bar and the failures (default ``name i``).
    workers
        Worker processes of the local cluster (one engine thread each); 0: one case after the
        other in this process, without Dask.
    scheduler
        Address of a running Dask scheduler (``tcp://host:8786``) instead of a local cluster.
    retries
        Retries of a failing case (on the engine; in this process a case runs once).
    resume
        Folder where each finished case is saved (``<name>-<index>-<key>.pkl``, written
        atomically) and from which a rerun reads the cases already done. It is yours: the
        files are Python pickles, read back without checks, so never point it at files you did
        not write.
    name
        Prefix of the saved files and the progress bar.
    progress
        A progress bar on stderr.
    client
        A Dask client to run on (its cluster; ``workers`` and ``scheduler`` are then unused).

    Returns
    -------
    SuiteRun

    Raises
    ------
    InvalidInputError
        Negative ``workers``, ``labels`` of another length, or Dask missing (``workers`` > 0).
    DataError
        A saved case that cannot be read (the message names the file).
    """
    if workers < 0:
        raise InvalidInputError(f"--workers {workers}: give 0 (this process) or more workers")
    if labels is not None and len(labels) != len(cases):
        raise InvalidInputError(f"{len(labels)} labels for {len(cases)} cases")
    names = list(labels) if labels is not None else [f"{name} {i}" for i in range(len(cases))]
    keys = [case_key(fn, c) for c in cases]
    folder = Path(resume) if resume is not None else None
    results: list[Any] = [None] * len(cases)
    done = [False] * len(cases)
    resumed = 0
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
        for i, k in enumerate(keys):
            p = _resume_path(folder, name, i, k)
            if p.is_file():
                results[i], done[i] = _load(p), True
                resumed += 1

    def keep(i: int) -> Callable[[Any], None]:
        def store(result: Any) -> None:
            results[i] = result
            if folder is not None:
                write_bytes_atomic(_resume_path(folder, name, i, keys[i]), pickle.dumps(result))

        return store

    todo = [i for i in range(len(cases)) if not done[i]]
    failures: list[Failure] = []
    jobs = [Job(f"{name}-{i:05d}-{keys[i]}", names[i], fn, tuple(cases[i]), keep(i)) for i in todo]
    if client is not None:
        failures = run_jobs(client, jobs, retries=retries, progress=progress)
    elif workers == 0 and scheduler is None:
        for i in tqdm(todo, desc=name, unit="case", file=sys.stderr, disable=not progress):
            keep(i)(fn(*cases[i]))
    elif todo:
        with open_client(workers=max(workers, 1), scheduler=scheduler) as own:
            failures = run_jobs(own, jobs, retries=retries, progress=progress)
    return SuiteRun(results=results, failures=failures, resumed=resumed)
