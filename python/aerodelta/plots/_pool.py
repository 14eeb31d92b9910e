"""Worker processes that draw report figures (PNG and SVG bytes) for the calling process.

Each worker is a fresh interpreter (``sys.executable``, as the multiprocessing ``spawn``
start method) running :mod:`aerodelta.plots._worker` as a script. It is not a
multiprocessing pool because spawned multiprocessing workers re-run the caller's ``__main__``
script, which breaks scripts written without an ``if __name__ == "__main__"`` guard (fine
under Linux's default ``fork``). The caller never forks: it holds polars' thread pool and
hundreds of MB of records.

Protocol over the worker's stdin/stdout: length-prefixed pickles. First the caller's
``sys.path``; then per figure ``(module, function, kwargs, dpi, svg)``, answered by
``("ok", png, svg)`` or ``("error", traceback)``. One thread per worker in the caller sends a
figure and waits for its bytes; a figure whose worker failed comes back as ``None`` and is
drawn in the caller (:class:`aerodelta.plots.FigureSink`), so a report never depends on the
workers for its content.
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


def send(stream: IO[bytes], obj: object) -> None:
    """Write one length-prefixed pickle."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(data)))
    stream.write(data)
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


class _Worker:
    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, str(WORKER_SCRIPT)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env={**os.environ, "MPLBACKEND": "Agg"},
        )
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.stdin: IO[bytes] = self.proc.stdin
        self.stdout: IO[bytes] = self.proc.stdout
        send(self.stdin, [p for p in sys.path if p])

    def call(self, payload: bytes) -> tuple[bytes, bytes | None] | None:
        """Render one figure (``None``: the worker failed; it is stopped)."""
        try:
            self.stdin.write(_HEADER.pack(len(payload)))
            self.stdin.write(payload)
            self.stdin.flush()
            reply = receive(self.stdout)
        except (OSError, EOFError, pickle.UnpicklingError):
            self.stop()
            return None
        if reply[0] != "ok":
            return None  # the caller draws it again and raises the error itself
        return reply[1], reply[2]

    def stop(self) -> None:
        for s in (self.stdin, self.stdout):
            with contextlib.suppress(OSError):
                s.close()
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def _stop_all(workers: list[_Worker]) -> None:
    for w in workers:
        w.stop()


class RenderPool:
    """``size`` worker processes drawing figures; see the module docstring."""

    def __init__(self, size: int) -> None:
        if size < 1:
            raise ValueError(f"a render pool needs at least one worker, got {size}")
        self.size = size
        self._workers = [_Worker() for _ in range(size)]
        self._idle: queue.SimpleQueue[_Worker | None] = queue.SimpleQueue()
        for w in self._workers:
            self._idle.put(w)
        self._threads = ThreadPoolExecutor(max_workers=size, thread_name_prefix="aerodelta-render")
        self._finalizer = weakref.finalize(self, _stop_all, self._workers)

    def submit(
        self, draw: Callable[..., Any], kwargs: dict[str, Any], *, dpi: int, svg: bool
    ) -> Future[tuple[bytes, bytes | None] | None]:
        """Draw ``draw(**kwargs)`` in a worker; the future gives ``(png, svg)`` or ``None``."""
        payload = pickle.dumps(
            (draw.__module__, draw.__qualname__, kwargs, dpi, svg),
            protocol=pickle.HIGHEST_PROTOCOL,
        )
        return self._threads.submit(self._run, payload)

    def _run(self, payload: bytes) -> tuple[bytes, bytes | None] | None:
        w = self._idle.get()
        if w is None:  # a dead worker's slot: the caller draws it
            self._idle.put(None)
            return None
        out = w.call(payload)
        alive = w.proc.poll() is None
        self._idle.put(w if alive else None)
        return out

    def close(self) -> None:
        """Stop the workers (after the figures already submitted)."""
        self._threads.shutdown(wait=True, cancel_futures=True)
        self._finalizer()
