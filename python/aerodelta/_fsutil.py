"""Atomic file writes (nothing is lost): the content goes to ``<path>.tmp-<pid>`` in the same
folder, then is renamed over ``path``; the temporary file never survives a failure."""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path


def write_atomic(path: str | os.PathLike[str], write: Callable[[Path], object]) -> Path:
    """Call ``write(tmp)`` on a temporary path beside ``path``, then rename it to ``path``.

    An ``OSError`` names ``path``, never the temporary file (which the user never asked for).
    """
    out = Path(path)
    tmp = _temporary(out)
    try:
        write(tmp)
        os.replace(tmp, out)
    except OSError as e:
        raise _naming(e, tmp, out) from e
    finally:
        tmp.unlink(missing_ok=True)
    return out


def _temporary(out: Path) -> Path:
    """The temporary file beside ``out`` that is renamed to it: ``<name>.tmp-<pid>``."""
    return out.with_name(f"{out.name}.tmp-{os.getpid()}")


def _naming(e: OSError, tmp: Path, out: Path) -> OSError:
    """``e`` with ``out`` in place of ``tmp`` (same class and errno)."""
    if e.errno is not None and e.strerror:
        return type(e)(e.errno, e.strerror, str(out))
    # polars shortens long paths ('...-of-root/x/data.csv.tmp-123'): drop the temporary suffix
    # wherever the name appears, whole or shortened
    text = str(e).replace(str(tmp), str(out)).replace(tmp.name[len(out.name) :], "")
    return type(e)(f"{text}" if str(out) in text else f"{out}: {text}")


def write_text_atomic(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return write_atomic(path, lambda p: p.write_text(text, encoding="utf-8"))


def write_texts_atomic(items: list[tuple[str | os.PathLike[str], str]]) -> list[Path]:
    """Write several UTF-8 files as one output: each to ``<path>.tmp-<pid>`` beside it, and
    only when all are written are they renamed into place (a failure while writing leaves
    every earlier file as it was, and no temporary file)."""
    outs = [Path(p) for p, _ in items]
    tmps = [_temporary(o) for o in outs]
    try:
        for (_, text), tmp, out in zip(items, tmps, outs, strict=True):
            try:
                tmp.write_text(text, encoding="utf-8")
            except OSError as e:
                raise _naming(e, tmp, out) from e
        for tmp, out in zip(tmps, outs, strict=True):
            try:
                os.replace(tmp, out)
            except OSError as e:
                raise _naming(e, tmp, out) from e
    finally:
        for tmp in tmps:
            tmp.unlink(missing_ok=True)
    return outs


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    return write_atomic(path, lambda p: p.write_bytes(data))


def replace_dir(tmp: Path, out: Path) -> None:
    """Commit a folder written at ``tmp`` as ``out`` with renames: an existing ``out`` is moved
    aside, ``tmp`` renamed into place, then the old one removed (readers never see a half-written
    folder)."""
    if out.exists():
        old = out.parent / f".{out.name}.old-{os.getpid()}"
        out.rename(old)
        tmp.rename(out)
        shutil.rmtree(old, ignore_errors=True)
    else:
        tmp.rename(out)
