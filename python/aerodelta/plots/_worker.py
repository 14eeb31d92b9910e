"""Figure worker of :class:`aerodelta.plots._pool.RenderPool`, run as a script
(``python .../aerodelta/plots/_worker.py``): reads figure jobs on stdin, answers PNG and SVG
bytes on stdout, until stdin closes.

The ``aerodelta`` package is registered without running its ``__init__`` (which loads the Rust
engine and polars, 0.4 s and 30 MB a worker that drawing never uses); the figure modules import
only numpy, matplotlib and :mod:`aerodelta.plots`.
"""

from __future__ import annotations

import importlib
import os
import sys
import traceback
import types
from pathlib import Path


def _register_package() -> None:
    pkg = Path(__file__).resolve().parent.parent
    if "aerodelta" not in sys.modules:
        mod = types.ModuleType("aerodelta")
        mod.__path__ = [str(pkg)]
        mod.__file__ = str(pkg / "__init__.py")
        sys.modules["aerodelta"] = mod


def main() -> int:
    """Serve figure jobs until stdin closes."""
    inp = sys.stdin.buffer
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # stray prints go to stderr, never into the byte stream
    here = str(Path(__file__).resolve().parent)
    sys.path[:] = [p for p in sys.path if p and p != here]
    _register_package()
    from aerodelta.plots._pool import receive, send  # noqa: PLC0415

    try:
        paths = receive(inp)
    except EOFError:
        return 0
    sys.path[:] = [*paths, *(p for p in sys.path if p not in paths)]
    from aerodelta.plots import draw_and_render  # noqa: PLC0415

    while True:
        try:
            module, name, kwargs, dpi, svg = receive(inp)
        except EOFError:
            return 0
        try:
            draw = getattr(importlib.import_module(module), name)
            png, svg_bytes = draw_and_render(draw, kwargs, dpi=dpi, svg=svg)
            reply: tuple[object, ...] = ("ok", png, svg_bytes)
        except Exception:  # the caller draws the figure again and raises it there
            reply = ("error", traceback.format_exc())
        send(out, reply)


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:  # Ctrl-C reaches the whole process group
        sys.exit(130)
