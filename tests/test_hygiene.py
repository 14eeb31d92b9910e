"""Project hygiene that must not regress: ruff-clean Python, rustfmt-clean Rust."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

from conftest import ROOT


def test_ruff_clean() -> None:
    r = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "python", "tests", "benchmarks"],
        cwd=ROOT,
        capture_output=True,
        check=False,
        text=True,
    )
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.skipif(shutil.which("cargo") is None, reason="cargo not on PATH")
def test_rustfmt_clean() -> None:
    r = subprocess.run(
        ["cargo", "fmt", "--all", "--", "--check"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    assert r.returncode == 0, r.stdout + r.stderr
