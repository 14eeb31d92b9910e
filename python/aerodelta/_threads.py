"""How many threads aerodelta's own pools may use.

The engine (``aero_core``) parallelises with rayon, whose pool size ``RAYON_NUM_THREADS``
sets; the Python front end runs independent engine calls side by side on thread pools (the
engine releases the GIL). Both follow one setting, so a process given one core (a Dask worker
of ``aerodelta plan``, a batch job) uses one:

1. ``AERODELTA_NUM_THREADS``, else
2. ``RAYON_NUM_THREADS`` (0 meaning, as for rayon, the default), else
3. the CPUs this process may run on.
"""

from __future__ import annotations

import os

from aerodelta.exceptions import InvalidInputError

#: Environment variables read, in order.
THREAD_VARIABLES = ("AERODELTA_NUM_THREADS", "RAYON_NUM_THREADS")


def available_cpus() -> int:
    """CPUs this process may run on (its affinity mask where the platform has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def engine_threads(cap: int | None = None) -> int:
    """Threads for one of aerodelta's pools: the first of :data:`THREAD_VARIABLES` that is
    set (a positive integer), else :func:`available_cpus`; at most ``cap`` when given.

    Raises
    ------
    InvalidInputError
        When a variable is set to anything but a positive integer.
    """
    n = None
    for var in THREAD_VARIABLES:
        raw = os.environ.get(var, "").strip()
        if not raw:
            continue
        try:
            n = int(raw)
        except ValueError:
            n = -1
        if n == 0 and var == "RAYON_NUM_THREADS":  # rayon's own meaning: its default
            n = None
            continue
        if n < 1:
            raise InvalidInputError(
                f"{var}={raw!r}: give a positive whole number of threads (e.g. 1), or unset it"
            )
        break
    if n is None:
        n = available_cpus()
    return max(1, min(n, cap)) if cap is not None else n
