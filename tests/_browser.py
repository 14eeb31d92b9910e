"""Headless Chromium for the browser tests of the report and the evidence pack.

The tests are skipped only when no Chromium is installed and the environment variable CI is
unset; in CI (``.ci/run`` installs Debian's ``chromium``) they always run."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

CHROMIUM = next(
    (p for p in (shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")) if p),
    None,
)

#: Skip marker of a browser test module.
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None and not os.environ.get("CI"),
    reason="headless Chromium not installed (apt-get install chromium); runs whenever CI is set",
)

#: Console-error markers in Chromium's ``--enable-logging=stderr`` output. (Chromium does not
#: log a missing local image: the tests check figure files exist themselves.)
CONSOLE_ERROR = re.compile(r"Uncaught|CONSOLE\(\d+\).*(error|Error)|:ERROR:CONSOLE", re.I)


def chromium(*args: str, tmp: Path, file_access: bool = False) -> subprocess.CompletedProcess[str]:
    """Run headless Chromium with ``args`` (a profile in ``tmp``, console logged to stderr);
    ``file_access`` lets a local page read the files beside it."""
    assert CHROMIUM is not None, "CI is set but no chromium is installed (see .ci/run)"
    cmd = [
        CHROMIUM,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--no-first-run",
        "--hide-scrollbars",
        *(["--allow-file-access-from-files"] if file_access else []),
        f"--user-data-dir={tmp / 'profile'}",
        "--enable-logging=stderr",
        "--v=0",
        *args,
    ]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
