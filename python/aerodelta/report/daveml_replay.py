"""The 6-DOF replay of a user's DAVE-ML qualified model (issue 19 item 5).

aerodelta's simulator (``aero_core::sim``) flies the user's aircraft: its mass, inertias and
geometry from the aircraft file, its aerodynamics from the DAVE-ML model
(``aero_core::sim::dave_aero::DaveAero``: the inputs bound by name to aerodelta's channels,
``CY``, ``Cl``, ``Cm``, ``Cn`` and ``CX``, ``CZ`` or lift and drag ``CL``, ``CD``), with the
fitted Δ on top for the extended model (``ExtendedAero``, Eq. 3.12).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from aerodelta import _core
from aerodelta.aircraft import Aircraft
from aerodelta.daveml import DaveModel
from aerodelta.exceptions import DataError
from aerodelta.model import DeltaModel

#: ``fly(flap_deg, state0, dt, controls_deg (n, 5), ct (n, 2), delta)`` -> ``(n + 1, 12)``
#: states, as :func:`aerodelta.campaign.replay`.
Fly = Callable[
    [float, Sequence[float], float, npt.NDArray[np.float64], npt.NDArray[np.float64],
     DeltaModel | None],
    npt.NDArray[np.float64],
]  # fmt: skip


def aircraft_values(aircraft: Aircraft) -> list[float]:
    """The engine's aircraft row: S (m²), b, c̄ (m), mass (kg), Ixx, Iyy, Izz, Ixz (kg m²),
    engines, propeller polar inertia (kg m²), propeller speed (rpm), and the CG from the
    moment reference centre (``cg_m − moment_ref_m``, body axes, m): the DAVE-ML model's
    moments are about that centre (the fitted Δ's too: it was fitted about
    ``moment_ref_m``) and the simulator transfers them to the CG.

    The simulator counts one propeller angular momentum ``n I Ω`` with the aircraft file's
    sense (``prop_rotation``: ccw +, cw −, opposite 0; thesis Eq. 3.3), so it is given as one
    engine of inertia ``± n I``; the speed is ``prop_rpm_fixed`` (0 when the file gives only
    an rpm channel: no gyroscopic moment in the replay).
    """
    rpm = aircraft.prop_rpm_fixed or 0.0
    h_per_rpm_inertia = aircraft.prop_h_per_rpm * 60.0 / (2.0 * np.pi)  # ± n I, kg m²
    return [
        aircraft.S_m2, aircraft.b_m, aircraft.cbar_m, aircraft.mass_kg, aircraft.Ixx_kgm2,
        aircraft.Iyy_kgm2, aircraft.Izz_kgm2, aircraft.Ixz_kgm2, 1.0, h_per_rpm_inertia, rpm,
        *np.subtract(aircraft.cg_m, aircraft.reference_m).tolist(),
    ]  # fmt: skip


def daveml_flyer(path: str | os.PathLike[str], aircraft: Aircraft | str | os.PathLike[str]) -> Fly:
    """A replay function flying ``aircraft`` with the DAVE-ML model ``path`` (plus a Δ).

    Raises
    ------
    InvalidInputError
        The model cannot be flown: outputs missing (CY, Cl, Cm, Cn, and CX, CZ or CL, CD), or
        inputs that are not aerodelta channels and have no default (the engine's message
        names them), or aircraft values the simulator refuses.
    DataError
        The aircraft file is missing or invalid.
    """
    ac = aircraft if isinstance(aircraft, Aircraft) else Aircraft.from_toml(Path(aircraft))
    model = DaveModel(path)
    row = aircraft_values(ac)
    # bind once now (an unflyable model is refused before any replay): a one-step replay
    probe = _core.sim_replay_daveml(
        model._m, row, 0.0, [50.0, 0, 2.0, 0, 0, 0, 0, 0.03, 0, 0, 0, 1000.0], 0.01,
        np.zeros((1, 5)), np.zeros((1, 2)),
    )  # fmt: skip
    if probe.shape != (2, 12):
        raise DataError(f"{path}: the DAVE-ML replay returned {probe.shape} states for one step")

    def fly(  # noqa: PLR0917  (the Fly signature, as aerodelta.campaign.replay)
        flap_deg: float,
        state0: Sequence[float],
        dt: float,
        controls_deg: npt.NDArray[np.float64],
        ct: npt.NDArray[np.float64],
        delta: DeltaModel | None,
    ) -> npt.NDArray[np.float64]:
        c = np.ascontiguousarray(controls_deg, dtype=np.float64)
        k = np.ascontiguousarray(ct, dtype=np.float64)
        return np.asarray(
            _core.sim_replay_daveml(
                model._m, row, float(flap_deg), list(state0), float(dt), c, k,
                None if delta is None else delta._m,
            )
        )  # fmt: skip

    return fly
