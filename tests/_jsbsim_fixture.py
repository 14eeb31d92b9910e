"""The JSBSim fixture aircraft of the export tests, loaded with exported aerodynamics and the
stall's ``<system>`` file (shared by ``test_export_extended.py`` and ``test_stall_forms.py``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import jsbsim

from aerodelta.jsbsim import DEFAULT_PROPERTIES

FIXTURE = Path(__file__).parent / "data" / "jsbsim" / "aircraft" / "aerodelta_fixture"
#: Every channel the export reads on a test property of its own (``test/<channel>``).
TEST_PROPS = {ch: f"test/{ch}" for ch in DEFAULT_PROPERTIES}


def load_with_stall(tmp: Path, aero: str, system: str) -> Any:
    """The fixture aircraft with the exported aerodynamics ``aero`` and the stall's
    ``<system>`` ``system``, under ``tmp``."""
    root = tmp / "jsbsim"
    dest = root / "aircraft" / "aerodelta_fixture"
    dest.mkdir(parents=True)
    text = (FIXTURE / "aerodelta_fixture.xml").read_text()
    loads = '<aerodynamics file="delta"/>'
    assert loads in text
    (dest / "aerodelta_fixture.xml").write_text(
        text.replace(loads, f'<system file="stall"/>\n  {loads}')
    )
    (dest / "delta.xml").write_text(aero)
    (dest / "stall.xml").write_text(system)
    fdm = jsbsim.FGFDMExec(str(root))
    fdm.set_debug_level(0)
    assert fdm.load_model("aerodelta_fixture")
    return fdm


def driven(tmp: Path, aero: str, system: str, peak_deg: float = 25.0) -> tuple[Any, float, Any]:
    """:func:`load_with_stall`, every channel on its test property (all 0, alpha 5 deg) after
    the initial conditions; JSBSim's dt, and a 5 s pull from 5 deg to ``peak_deg`` and back
    (deg per frame)."""
    import numpy as np  # noqa: PLC0415

    fdm = load_with_stall(tmp, aero, system)
    for ch in TEST_PROPS.values():
        fdm[ch] = 0.0
    fdm["test/alpha_deg"] = 5.0
    assert fdm.run_ic()
    dt = fdm["simulation/dt"]
    t = np.arange(600) * dt
    return fdm, dt, 5.0 + (peak_deg - 5.0) * np.sin(np.pi * t / t[-1]) ** 2
