"""The distributed engine of the design studies: seeded tasks on Dask distributed.

A :class:`Job` is one seeded call; :func:`run_jobs` sends the jobs to a Dask cluster (a
``LocalCluster`` of worker processes with one thread each by default, or the scheduler at an
address), shows progress on stderr, retries a failed task (Dask ``retries``), hands each
finished result to the job's callback as it arrives (the caller saves it at once, so a rerun
resumes), and returns the failures with their errors: none is dropped. Results depend on the
job's arguments only, never on the worker that ran it, so a study gives the same bytes with
any number of workers (see ``docs/plan.md``).
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from tqdm import tqdm

from aerodelta.exceptions import InvalidInputError

#: Environment of the local workers: one engine thread per worker process, the front end's
#: thread pools included (``aerodelta._threads``; the cluster's parallelism is the tasks; an
#: engine pool per worker would oversubscribe the cores), and polars' pool too (session 30:
#: without it two workers on two cores ran four polars threads, and one worker borrowed the
#: second core).
WORKER_ENV: dict[str, str] = {
    "AERODELTA_NUM_THREADS": "1",
    "RAYON_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "POLARS_MAX_THREADS": "1",
}


#: Dask's configuration key of the variables a nanny sets before it spawns a worker.
_PRE_SPAWN = "distributed.nanny.pre-spawn-environ"


@dataclass(frozen=True)
class Job:
    """One seeded task.

    Attributes
    ----------
    key
        Unique task key (Dask key; names the task in messages).
    label
        What the task is, for progress lines and failures (e.g. ``"default seed 7"``).
    fn
        The function run on a worker (importable by the workers).
    args
        Its arguments (small, picklable).
    done
        Called on the client with the result as soon as it arrives.
    """

    key: str
    label: str
    fn: Callable[..., Any]
    args: tuple[Any, ...]
    done: Callable[[Any], None]


@dataclass(frozen=True)
class Failure:
    """A task that failed after its retries.

    Attributes
    ----------
    key
        The task key.
    label
        What the task was.
    error
        The exception's type and message (one line).
    """

    key: str
    label: str
    error: str


def _dask() -> Any:
    try:
        import distributed  # noqa: PLC0415  (optional dependency, imported when used)
    except ImportError:
        raise InvalidInputError(
            "the distributed engine needs Dask: pip install 'aerodelta[plan]' (dask[distributed])"
        ) from None
    return distributed


@contextmanager
def open_client(workers: int = 2, scheduler: str | None = None) -> Iterator[Any]:
    """A Dask client: on a ``LocalCluster`` of ``workers`` processes with one thread each, or
    on the scheduler at ``scheduler`` (``tcp://host:8786``).

    Parameters
    ----------
    workers
        Worker processes of the local cluster (ignored with ``scheduler``).
    scheduler
        Address of a running Dask scheduler.

    Raises
    ------
    InvalidInputError
        Dask missing, ``workers`` below 1, or a scheduler that does not answer.
    """
    distributed = _dask()
    if scheduler is None and workers < 1:
        raise InvalidInputError(f"--workers {workers}: give 1 or more worker processes")
    if scheduler is not None:
        try:
            client = distributed.Client(scheduler, timeout="10s")
        except OSError as e:
            raise InvalidInputError(
                f"--scheduler {scheduler}: no Dask scheduler answered ({e}); start one with "
                "`dask scheduler` and workers with `dask worker ADDRESS`, or drop --scheduler"
            ) from None
        try:
            yield client
        finally:
            client.close()
        return
    # Dask sets MALLOC_TRIM_THRESHOLD_=65536 in the workers' environment to hand freed memory
    # back to the OS at once. Setting it also fixes glibc's mmap threshold at 128 kB, so every
    # array of the fit and the diagnosis is a fresh mapping faulted in page by page: a
    # campaign task spent a quarter of its CPU in the kernel. The workers keep glibc's
    # adaptive thresholds (None unsets a pre-spawn variable) with at most 2 malloc arenas
    # (freed memory of one thread is reused by the others), and each task trims the heap when
    # it ends (:func:`aerodelta.plan.task.release_memory`).
    import dask  # noqa: PLC0415  (installed with distributed)

    malloc = {"MALLOC_TRIM_THRESHOLD_": None, "MALLOC_ARENA_MAX": 2}
    with dask.config.set({f"{_PRE_SPAWN}.{k}": v for k, v in malloc.items()}):
        cluster = distributed.LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",  # a free port: 8787 may be taken by another cluster
            silence_logs=logging.ERROR,
            env=dict(WORKER_ENV),
            local_directory=os.environ.get("AERODELTA_PLAN_SCRATCH"),
        )
    client = distributed.Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def run_jobs(
    client: Any, jobs: Sequence[Job], *, retries: int = 2, progress: bool = True
) -> list[Failure]:
    """Run ``jobs`` on the cluster of ``client``; each result goes to its job's ``done``.

    Parameters
    ----------
    client
        A Dask client (:func:`open_client`).
    jobs
        The tasks (keys unique).
    retries
        Retries of a task that raises (a task whose worker dies is moved to another worker by
        Dask itself).
    progress
        A progress bar on stderr, and one line per failed task.

    Returns
    -------
    list of Failure
        The tasks that still failed, in the order of ``jobs``.
    """
    distributed = _dask()
    if not jobs:
        return []
    futures = {
        client.submit(j.fn, *j.args, key=j.key, retries=retries, pure=False): j for j in jobs
    }
    failed: dict[str, Failure] = {}
    with tqdm(
        total=len(jobs), desc="plan", unit="task", file=sys.stderr, disable=not progress
    ) as bar:
        for fut in distributed.as_completed(futures):
            job = futures[fut]
            if fut.status == "finished":
                job.done(fut.result())
            else:
                exc = fut.exception()
                text = " ".join(f"{type(exc).__name__}: {exc}".split())
                failed[job.key] = Failure(job.key, job.label, text)
                if progress:
                    tqdm.write(
                        f"[plan] {job.label}: failed after {retries} retries: {text}",
                        file=sys.stderr,
                    )
            fut.release()
            bar.update(1)
    return [failed[j.key] for j in jobs if j.key in failed]
