"""The evidence pack in a real browser: headless Chromium opens it (figures as PNG files beside
the page), logs no console error, renders the matrix and the figures, and prints it to PDF.

Skipped only when no Chromium is installed and the environment variable CI is unset; in CI
(``.ci/run`` installs Debian's ``chromium``) it always runs."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
from matplotlib.image import imread

import aerodelta as ad
from _browser import CONSOLE_ERROR, chromium, needs_chromium
from aerodelta.evidence import write_evidence

pytestmark = needs_chromium


def _chromium(*args: str, tmp: Path) -> subprocess.CompletedProcess[str]:
    return chromium(*args, tmp=tmp, file_access=True)


@pytest.fixture(scope="module")
def pack_html(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("evidence_browser")
    ad.generate_campaign(root / "camp", seed=41, size="quick", buffet=True, progress=False)
    res = write_evidence(root / "camp", root / "pack", longitudinal=False)
    return res.html


def test_pack_renders_without_console_errors(pack_html: Path, tmp_path: Path) -> None:
    dom = _chromium("--dump-dom", pack_html.as_uri(), tmp=tmp_path)
    assert dom.returncode == 0, dom.stderr[-2000:]
    errors = [ln for ln in dom.stderr.splitlines() if CONSOLE_ERROR.search(ln)]
    assert not errors, errors
    assert '<section id="matrix">' in dom.stdout
    assert dom.stdout.count('<tr id="row-') >= 12
    assert dom.stdout.count("<figure id=") >= 8


def test_screenshot_shows_the_matrix_and_print_to_pdf(pack_html: Path, tmp_path: Path) -> None:
    shot = tmp_path / "shot.png"
    r = _chromium(
        f"--screenshot={shot}", "--window-size=1280,2400", pack_html.as_uri(), tmp=tmp_path
    )
    assert r.returncode == 0, r.stderr[-2000:]
    img = imread(shot)
    assert img.shape[0] == 2400 and img.shape[1] == 1280
    top = img[20, 640, :3]
    assert top[2] > top[0] + 0.1, top  # the dark-blue header bar
    body = img[300:, :, :3]
    # the matrix's status cells are tinted (green PASS, red FAIL, blue shown) below the header
    tinted = (abs(body[..., 0] - body[..., 2]) > 0.05).mean()
    assert tinted > 0.001, tinted
    errors = [ln for ln in r.stderr.splitlines() if CONSOLE_ERROR.search(ln)]
    assert not errors, errors
    pdf = tmp_path / "pack.pdf"
    r = _chromium(f"--print-to-pdf={pdf}", "--no-pdf-header-footer", pack_html.as_uri(),
                  tmp=tmp_path)  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    head = pdf.read_bytes()
    assert head[:5] == b"%PDF-"
    # several A4 pages: the print CSS puts the envelope plots, figures, statement and
    # provenance on pages of their own
    assert len(re.findall(rb"/Type\s*/Page[^s]", head)) >= 4
