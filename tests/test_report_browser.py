"""The report in a real browser: headless Chromium opens it, logs no console error, renders the
summary and the plots, and takes a screenshot (kept beside the report for a look).

Skipped only when no Chromium is installed and the environment variable CI is unset; in CI
(``.ci/run`` installs Debian's ``chromium``) it always runs."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from matplotlib.image import imread

from _browser import CONSOLE_ERROR, chromium, needs_chromium
from _report_data import quick_report

pytestmark = needs_chromium


def _chromium(*args: str, tmp: Path) -> subprocess.CompletedProcess[str]:
    return chromium(*args, tmp=tmp, file_access=False)


@pytest.fixture(scope="module")
def report_html() -> Path:
    return quick_report().html


def test_report_renders_without_console_errors(report_html: Path, tmp_path: Path) -> None:
    dom = _chromium("--dump-dom", report_html.as_uri(), tmp=tmp_path)
    assert dom.returncode == 0, dom.stderr[-2000:]
    errors = [ln for ln in dom.stderr.splitlines() if CONSOLE_ERROR.search(ln)]
    assert not errors, errors
    assert '<section id="summary">' in dom.stdout
    assert dom.stdout.count("data:image/png;base64,") >= 10
    assert "4.1 Time-history matches" in dom.stdout


def test_screenshot_shows_the_summary_and_a_plot(report_html: Path, tmp_path: Path) -> None:
    shot = report_html.with_name("screenshot.png")
    r = _chromium(
        f"--screenshot={shot}", "--window-size=1280,2400", report_html.as_uri(), tmp=tmp_path
    )
    assert r.returncode == 0, r.stderr[-2000:]
    assert shot.exists() and shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = imread(shot)
    assert img.shape[0] == 2400 and img.shape[1] == 1280
    # the header bar (dark blue) is at the top, and the page is not blank below it: the summary
    # cards and at least the first plot (coloured lines) are drawn
    top = img[20, 640, :3]
    assert top[2] > top[0] + 0.1, top
    body = img[300:, :, :3]
    coloured = (abs(body[..., 0] - body[..., 2]) > 0.3).mean()
    assert coloured > 0.001, coloured
    errors = [ln for ln in r.stderr.splitlines() if CONSOLE_ERROR.search(ln)]
    assert not errors, errors
