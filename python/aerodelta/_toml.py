"""One reader for the TOML files a user writes (channel map, aircraft reference, fit settings,
user effects): every way such a file can fail to be read is one :class:`DataError` line naming
the file and, where there is one, the line."""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

from aerodelta.exceptions import DataError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

_AT = re.compile(r"\(at line (\d+), column \d+\)")


def read_toml(path: str | Path, what: str) -> tuple[dict[str, Any], str]:
    """Read and parse a TOML file; returns the document and its text.

    Parameters
    ----------
    path
        The file.
    what
        What the file is, for the messages (e.g. ``"channel map"``).

    Raises
    ------
    DataError
        A missing file, a folder, unreadable bytes, text that is not UTF-8 (a UTF-8 byte-order
        mark is accepted), invalid TOML (with the line) or nesting too deep to parse.
    """
    p = Path(path)
    if p.is_dir():
        raise DataError(f"{p}: is a folder; give the {what} file (TOML)")
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise DataError(f"{p}: {what} not found") from None
    except OSError as e:
        raise DataError(f"{p}: cannot read the {what}: {e.strerror or e}") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[: e.start].count(b"\n") + 1
        raise DataError(
            f"{p}: line {line}: byte 0x{raw[e.start]:02x} is not UTF-8 text; save the {what} "
            "as UTF-8 (TOML)"
        ) from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        msg = str(e).splitlines()[0] if str(e) else "invalid TOML"
        m = _AT.search(msg)
        hint = ""
        if m and ("overwrite" in msg or "declare" in msg):
            lines = text.splitlines()
            n = int(m.group(1))
            key = lines[n - 1].split("=")[0].strip() if 0 < n <= len(lines) else ""
            hint = f": '{key}' is given twice" if key else ": a key or table is given twice"
        raise DataError(f"{p}: not valid TOML: {msg}{hint}") from None
    except RecursionError:
        raise DataError(
            f"{p}: arrays or tables nested too deeply to read; this is not a {what}"
        ) from None
    return doc, text
