"""Worker processes that draw report figures (PNG and SVG bytes) for the calling process.

The workers descend from one fresh interpreter (``sys.executable`` running
:mod:`aerodelta.plots._worker` as a script, as the multiprocessing ``spawn`` start method):
it imports matplotlib once, draws a small figure to load the fonts and the mathtext parser,
then forks the other workers, which start warm. Forking that interpreter is safe: it runs a
single thread (BLAS and OpenMP pools are set to one thread) and holds no data. The caller itself
never forks: it holds polars' thread pool and hundreds of MB of records.

Not a multiprocessing pool: its spawned workers re-run the caller's ``__main__`` script, which
breaks scripts written without an ``if __name__ == "__main__"`` guard (fine under Linux's
default ``fork``).

Protocol per worker over a pair of pipes: length-prefixed pickles. The first interpreter gets
``{"path": sys.path, "channels": [(read_fd, write_fd), ...]}`` (the pipes of the workers it
forks); then per figure ``(module, function, kwargs, dpi, svg)``, answered by
``("ok", png, svg)`` or ``("error", traceback)``. One thread per worker in the caller sends a
figure and waits for its bytes; a figure whose worker failed comes back as ``None`` and is
drawn in the caller (:class:`aerodelta.plots.FigureSink`), so a report never depends on the
workers for its content. A worker exits when its input pipe closes.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import queue
import struct
import subprocess
import sys
import weakref
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import IO, Any

_HEADER = struct.Struct("<Q")
WORKER_SCRIPT = Path(__file__).with_name("_worker.py")
#: Environment of the workers: the Agg backend, single-threaded numerical libraries.
WORKER_ENV = {
    "MPLBACKEND": "Agg",
    "OPENBLAS_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}

Rendered = tuple[bytes, bytes | None]


def send(stream: IO[bytes], obj: object) -> None:
    """Write one length-prefixed pickle."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(data)) + data)
    stream.flush()


def receive(stream: IO[bytes]) -> Any:
    """Read one length-prefixed pickle (``EOFError`` when the stream ends)."""
    head = stream.read(_HEADER.size)
    if len(head) < _HEADER.size:
        raise EOFError("worker stream closed")
    n = _HEADER.unpack(head)[0]
    data = stream.read(n)
    if len(data) < n:
        raise EOFError("worker stream closed")
    return pickle.loads(data)


class _Channel:
    """The caller's ends of one worker's pipes."""

    def __init__(self, to_worker: IO[bytes], from_worker: IO[bytes]) -> None:
        self.to_worker = to_worker
        self.from_worker = from_worker
        self.alive = True

    def call(self, payload: bytes) -> Rendered | None:
        """Render one figure (``None``: the worker failed, or is gone and the channel closed)."""
        try:
            self.to_worker.write(_HEADER.pack(len(payload)) + payload)
            self.to_worker.flush()
            reply = receive(self.from_worker)
        except (OSError, EOFError, pickle.UnpicklingError):
            self.close()
            return None
        if reply[0] != "ok":
            return None  # the caller draws it again and raises the error itself
        return reply[1], reply[2]

    def close(self) -> None:
        self.alive = False
        for s in (self.to_worker, self.from_worker):
            with contextlib.suppress(OSError):
                s.close()


def _stop(channels: list[_Channel], proc: subprocess.Popen[bytes]) -> None:
    for c in channels:
        c.close()  # each worker exits on the end of its input
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


class RenderPool:
    """``size`` worker processes drawing figures; see the module docstring."""

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f"a render pool needs at least one worker, got {size}")
        self.size = size
        pipes = [(os.pipe(), os.pipe()) for _ in range(size - 1)]
        # the forked workers' ends: they read jobs from the first pipe, answer on the second
        theirs = [(jobs[0], answers[1]) for jobs, answers in pipes]
        try:
            self._proc = subprocess.Popen(
                [sys.executable, str(WORKER_SCRIPT)],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                pass_fds=[fd for pair in theirs for fd in pair],
                env={**os.environ, **WORKER_ENV},
            )
        finally:
            for fd in (fd for pair in theirs for fd in pair):
                os.close(fd)
        assert self._proc.stdin is not None and self._proc.stdout is not None
        self._channels = [_Channel(self._proc.stdin, self._proc.stdout)]
        self._channels += [
            _Channel(os.fdopen(jobs[1], "wb"), os.fdopen(answers[0], "rb"))
            for jobs, answers in pipes
        ]
        self._finalizer = weakref.finalize(self, _stop, self._channels, self._proc)
        try:
            send(self._proc.stdin, {"path": [p for p in sys.path if p], "channels": theirs})
        except OSError:
            self._finalizer()
            raise
        self._idle: queue.SimpleQueue[_Channel] = queue.SimpleQueue()
        for c in self._channels:
            self._idle.put(c)
        self._threads = ThreadPoolExecutor(max_workers=size, thread_name_prefix="aerodelta-render")

    def submit(
        self, draw: Callable[..., Any], kwargs: dict[str, Any], *, dpi: int, svg: bool
    ) -> Future[Rendered | None]:
        """Draw ``draw(**kwargs)`` in a worker; the future gives ``(png, svg)`` or ``None``."""
        payload = pickle.dumps(
            (draw.__module__, draw.__qualname__, kwargs, dpi, svg),
            protocol=pickle.HIGHEST_PROTOCOL,
        )
        return self._threads.submit(self._run, payload)

    def _run(self, payload: bytes) -> Rendered | None:
        c = self._idle.get()
        try:
            # a dead worker's channel stays in the queue and answers None: the caller draws
            return c.call(payload) if c.alive else None
        finally:
            self._idle.put(c)

    def close(self) -> None:
        """Stop the workers (after the figures already submitted)."""
        self._threads.shutdown(wait=True, cancel_futures=True)
        self._finalizer()
