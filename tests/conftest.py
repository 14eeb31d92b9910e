"""Shared pytest configuration: the public DAVE-ML check models live in ../shared/data/daveml."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _shared_daveml() -> Path:
    env = os.environ.get("AERODELTA_SHARED_DAVEML")
    if env:
        return Path(env)
    # ../shared/data/daveml in the main checkout; further up from a nested worktree.
    for base in ROOT.parents:
        d = base / "shared" / "data" / "daveml"
        if d.is_dir():
            return d
    return ROOT.parent / "shared" / "data" / "daveml"


@pytest.fixture(scope="session")
def daveml_dir() -> Path:
    """Folder of the public DAVE-ML models with NASA check cases (not copied into the repo)."""
    d = _shared_daveml()
    if not d.is_dir():
        msg = f"public DAVE-ML models not found at {d}; set AERODELTA_SHARED_DAVEML to their folder"
        if os.environ.get("AERODELTA_REQUIRE_SHARED"):
            pytest.fail(f"{msg} (AERODELTA_REQUIRE_SHARED is set: CI runs the reference checks)")
        pytest.skip(msg)
    return d


@pytest.fixture(scope="session")
def stall_campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The quick virtual campaign of the stall evidence, seed 41, with buffet and the Kirchhoff
    stall, generated once for the session (read only)."""
    import aerodelta as ad  # noqa: PLC0415

    out = tmp_path_factory.mktemp("stall41") / "camp"
    ad.generate_campaign(
        out, seed=41, size="quick", buffet=True, longitudinal_stall="kirchhoff", progress=False
    )
    return out


@pytest.fixture(scope="session")
def quick_campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The quick virtual campaign, seed 5, generated once for the session (read only)."""
    import aerodelta as ad  # noqa: PLC0415  (the DAVE-ML checks above need no engine)

    out = tmp_path_factory.mktemp("quick5") / "camp"
    ad.generate_campaign(out, seed=5, size="quick", progress=False)
    return out
