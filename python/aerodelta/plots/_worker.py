"""Figure workers of :class:`aerodelta.plots._pool.RenderPool`, run as a script
(``python .../aerodelta/plots/_worker.py``): this interpreter serves figure jobs on its
stdin/stdout and forks the other workers, each serving its own pair of pipes, until their input
closes.

The ``aerodelta`` package is registered without running its ``__init__`` (which loads the Rust
engine and polars, 0.4 s and 30 MB a worker that drawing never uses); the figure modules import
only numpy, matplotlib and :mod:`aerodelta.plots`. Before forking, a small figure is drawn so
the workers share loaded fonts and the mathtext parser.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
import traceback
import types
from pathlib import Path
from typing import IO, Any


def _register_package() -> None:
    pkg = Path(__file__).resolve().parent.parent
    if "aerodelta" not in sys.modules:
        mod = types.ModuleType("aerodelta")
        mod.__path__ = [str(pkg)]
        mod.__file__ = str(pkg / "__init__.py")
        sys.modules["aerodelta"] = mod


def _warm_up() -> None:
    """Draw and save a small figure with ticks, a legend and mathtext (fonts, parser)."""
    from aerodelta.plots import draw_and_render  # noqa: PLC0415
    from aerodelta.plots.figures import time_history  # noqa: PLC0415

    t = [0.0, 1.0, 2.0]
    draw_and_render(
        time_history,
        {
            "t": t, "meas": t, "qual": t, "ext": t, "alpha": t, "active": None,
            "ylabel": "$C_l$", "title": "warm-up",
        },
        dpi=20,
        svg=True,
    )  # fmt: skip


def _serve(inp: IO[bytes], out: IO[bytes]) -> None:
    from aerodelta.plots import draw_and_render  # noqa: PLC0415
    from aerodelta.plots._pool import receive, send  # noqa: PLC0415

    while True:
        try:
            module, name, kwargs, dpi, svg = receive(inp)
        except EOFError:
            return
        try:
            draw = getattr(importlib.import_module(module), name)
            png, svg_bytes = draw_and_render(draw, kwargs, dpi=dpi, svg=svg)
            reply: tuple[Any, ...] = ("ok", png, svg_bytes)
        except Exception:  # the caller draws the figure again and raises it there
            reply = ("error", traceback.format_exc())
        try:
            send(out, reply)
        except OSError:  # the caller is gone
            return


def main() -> int:
    """Serve figure jobs (this process and its forks) until the inputs close."""
    inp: IO[bytes] = sys.stdin.buffer
    out: IO[bytes] = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # stray prints go to stderr, never into the byte stream
    here = str(Path(__file__).resolve().parent)
    sys.path[:] = [p for p in sys.path if p and p != here]
    _register_package()
    from aerodelta.plots._pool import receive  # noqa: PLC0415

    try:
        setup = receive(inp)
    except EOFError:
        return 0
    sys.path[:] = [*setup["path"], *(p for p in sys.path if p not in setup["path"])]
    channels: list[tuple[int, int]] = setup["channels"]
    with contextlib.suppress(Exception):  # only a speed-up: the jobs report their own errors
        _warm_up()
    children = []
    for k, (r, w) in enumerate(channels):
        pid = os.fork()
        if pid == 0:  # a worker on its own pipes: drop the later workers' (earlier ones closed)
            try:
                inp.close()
                out.close()
                for r2, w2 in channels[k + 1 :]:
                    os.close(r2)
                    os.close(w2)
                _serve(os.fdopen(r, "rb"), os.fdopen(w, "wb"))
            finally:
                os._exit(0)
        children.append(pid)
        os.close(r)
        os.close(w)
    _serve(inp, out)
    for pid in children:
        os.waitpid(pid, 0)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:  # Ctrl-C reaches the whole process group
        sys.exit(130)
