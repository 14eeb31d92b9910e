"""The aircraft reference (TOML): geometry, mass, inertias, propellers, sensor positions.

Schema (see ``docs/data.md``)::

    name = "..."
    [geometry]   S_m2, b_m, cbar_m
    [mass]       mass_kg, Ixx_kgm2, Iyy_kgm2, Izz_kgm2, Ixz_kgm2, Ixy_kgm2 = 0, Iyz_kgm2 = 0
                 (about the CG, Etkin sign), cg_m = [0, 0, 0]
    [reference]  moment_ref_m (default: cg_m)
    [propulsion] n_engines, prop_inertia_kgm2, prop_rotation = "cw" | "ccw" | "opposite",
                 prop_rpm_channel = "prop_rpm" and/or prop_rpm_fixed = 1020.0
    [sensors]    accel_m, alpha_vane_m, beta_vane_m, beta_vane_type = "sideslip" | "flank"
    [simulator]  builtin = "adx37" (only the virtual flight test's campaigns: their
                 qualified model is the built-in one)

Positions (``cg_m``, ``moment_ref_m``, sensors) are body axes (x forward, y right wing,
z down), metres, from one fixed aircraft datum; without ``cg_m`` the datum is the CG.
The measured moment coefficients are about ``moment_ref_m`` (the simulator's moment
reference centre: JSBSim's AERORP, DAVE-ML's MRC); per-maneuver loadings come from the
manifest (:mod:`aerodelta.loading`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aerodelta._toml import read_toml
from aerodelta.channels import CHANNELS
from aerodelta.exceptions import DataError

#: The tables of the aircraft file and their keys.
_KEYS = {
    "geometry": ("S_m2", "b_m", "cbar_m"),
    "mass": (
        "mass_kg", "Ixx_kgm2", "Iyy_kgm2", "Izz_kgm2", "Ixz_kgm2", "Ixy_kgm2", "Iyz_kgm2", "cg_m",
    ),
    "reference": ("moment_ref_m",),
    "propulsion": (
        "n_engines", "prop_inertia_kgm2", "prop_rotation", "prop_rpm_channel", "prop_rpm_fixed",
        "prop_efficiency",
    ),
    "sensors": ("accel_m", "alpha_vane_m", "beta_vane_m", "beta_vane_type"),
    "simulator": ("builtin",),
}  # fmt: skip

#: Built-in simulators an aircraft file may declare its data were flown on.
BUILTINS = ("adx37",)
#: Column ingest adds to data flown on a built-in simulator (the aircraft file's
#: ``[simulator] builtin``): the only data the built-in qualified model is used for unnamed.
BUILTIN_COLUMN = "builtin_simulator"


def inertia_definite(tensor: Sequence[Any]) -> Any:
    """Whether the inertia tensor ``(Ixx, Iyy, Izz, Ixz, Ixy, Iyz)`` (kg m², Etkin sign: -Ixy,
    -Ixz, -Iyz off the diagonal) is positive definite, by Sylvester's leading minors;
    elementwise when the six are numpy arrays."""
    ixx, iyy, izz, ixz, ixy, iyz = tensor
    m2 = ixx * iyy - ixy * ixy
    det = (
        ixx * (iyy * izz - iyz * iyz)
        - ixy * (ixy * izz + iyz * ixz)
        - ixz * (ixy * iyz + iyy * ixz)
    )
    return (ixx > 0.0) & (m2 > 0.0) & (det > 0.0)


@dataclass(frozen=True)
class Aircraft:
    """Reference data of the aircraft (SI units).

    ``prop_rotation`` is the propellers' sense viewed from behind (looking forward):
    ``"ccw"`` (counter-clockwise) or ``"cw"`` (clockwise, most engines of US and UK design),
    every engine turning that way, their angular momenta adding (thesis Eq. 3.3 with
    :math:`h_p = \\pm n I_p \\Omega_p`); ``"opposite"`` for counter-rotating pairs, whose
    momenta cancel. The thesis's sign (:math:`+I_p\\Omega_p q` in :math:`C_n`) is a spin
    angular momentum pointing aft: counter-clockwise from behind, so ``"cw"`` gives
    :math:`h_p = -n I_p \\Omega_p` (a nose-up pitch rate then yaws the nose right, the
    gyroscopic rule of a clockwise propeller). Needed only when ``prop_inertia_kgm2 > 0``.
    """

    name: str
    S_m2: float
    b_m: float
    cbar_m: float
    mass_kg: float
    Ixx_kgm2: float
    Iyy_kgm2: float
    Izz_kgm2: float
    Ixz_kgm2: float
    n_engines: int = 2
    prop_inertia_kgm2: float = 0.0
    prop_rotation: str | None = None
    prop_rpm_channel: str | None = None
    prop_rpm_fixed: float | None = None
    accel_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    alpha_vane_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    beta_vane_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    prop_efficiency: float = 0.8
    Ixy_kgm2: float = 0.0
    Iyz_kgm2: float = 0.0
    cg_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    moment_ref_m: tuple[float, float, float] | None = None
    builtin: str | None = None
    beta_vane_type: str = "sideslip"

    @property
    def mass_geometry(self) -> list[float]:
        """``[S, b, cbar, mass, Ixx, Iyy, Izz, Ixz, Ixy, Iyz]`` as the engine takes it."""
        return [
            self.S_m2,
            self.b_m,
            self.cbar_m,
            self.mass_kg,
            self.Ixx_kgm2,
            self.Iyy_kgm2,
            self.Izz_kgm2,
            self.Ixz_kgm2,
            self.Ixy_kgm2,
            self.Iyz_kgm2,
        ]

    @property
    def reference_m(self) -> tuple[float, float, float]:
        """The moment reference centre from the datum, m (``moment_ref_m``, else the CG)."""
        return self.cg_m if self.moment_ref_m is None else self.moment_ref_m

    @property
    def prop_h_per_rpm(self) -> float:
        """Propeller angular momentum per rpm, kg m²/s per rpm (thesis sign, Eq. 3.3)."""
        sense = {"ccw": 1.0, "cw": -1.0}.get(self.prop_rotation or "", 0.0)
        return sense * self.n_engines * self.prop_inertia_kgm2 * 2.0 * math.pi / 60.0

    @classmethod
    def from_toml(cls, path: str | Path) -> Aircraft:
        """Read and validate an aircraft TOML file.

        Raises
        ------
        DataError
            Naming the file, the table and key at fault.
        """
        doc, _ = read_toml(path, "aircraft reference")
        return cls.from_dict(doc, source=str(path))

    @classmethod
    def from_dict(cls, doc: dict[str, Any], source: str = "<dict>") -> Aircraft:
        """Build from the parsed TOML structure (same schema as :meth:`from_toml`)."""
        problems: list[str] = []
        for k, v in doc.items():
            if k in _KEYS:
                if not isinstance(v, dict):
                    problems.append(f"{k} = {v!r} must be a table [{k}]")
                    continue
                unknown = sorted(set(v) - set(_KEYS[k]))
                if unknown:
                    problems.append(
                        f"[{k}] has unknown key(s) {', '.join(unknown)} (known: "
                        f"{', '.join(_KEYS[k])})"
                    )
            elif k != "name":
                problems.append(f"unknown key or table '{k}' (known: name, {', '.join(_KEYS)})")

        def table(name: str) -> dict[str, Any]:
            t = doc.get(name, {})
            return t if isinstance(t, dict) else {}

        def num(
            table_: str, key: str, positive: bool = True, default: float | None = None
        ) -> float:
            t = table(table_)
            if key not in t:
                if default is not None:
                    return default
                problems.append(f"[{table_}] {key} is missing")
                return math.nan
            v = t[key]
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                problems.append(f"[{table_}] {key} = {v!r} is not a finite number")
                return math.nan
            if positive and v <= 0:
                problems.append(f"[{table_}] {key} = {v} must be positive")
            return float(v)

        def vec(key: str, table_: str = "sensors") -> tuple[float, float, float]:
            v = table(table_).get(key, [0.0, 0.0, 0.0])
            if (
                not isinstance(v, list)
                or len(v) != 3
                or not all(
                    isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                    for x in v
                )
            ):
                problems.append(f"[{table_}] {key} = {v!r} must be a list of 3 finite numbers (m)")
                return (0.0, 0.0, 0.0)
            return (float(v[0]), float(v[1]), float(v[2]))

        prop = table("propulsion")
        rot = prop.get("prop_rotation")
        if rot == "same":
            problems.append(
                "[propulsion] prop_rotation = 'same' does not say which way: give 'cw' or "
                "'ccw' (viewed from behind, looking forward; 'same' used to mean 'ccw', the "
                "thesis's sign) or 'opposite' (counter-rotating pairs)"
            )
        elif rot is not None and rot not in ("cw", "ccw", "opposite"):
            problems.append(
                f"[propulsion] prop_rotation = {rot!r} must be 'cw' or 'ccw' (viewed from "
                "behind, looking forward) or 'opposite' (counter-rotating pairs)"
            )
        n_eng = prop.get("n_engines", 2)
        if isinstance(n_eng, bool) or not isinstance(n_eng, int) or n_eng < 0:
            problems.append(f"[propulsion] n_engines = {n_eng!r} must be a whole number >= 0")
            n_eng = 0
        rpm_channel = prop.get("prop_rpm_channel")
        if rpm_channel is not None and (
            not isinstance(rpm_channel, str) or rpm_channel not in CHANNELS
        ):
            problems.append(
                f"[propulsion] prop_rpm_channel = {rpm_channel!r} must name a canonical channel "
                '(e.g. "prop_rpm"; map the record\'s column onto it in the channel map)'
            )
            rpm_channel = None
        rpm_fixed = (
            num("propulsion", "prop_rpm_fixed", positive=True) if "prop_rpm_fixed" in prop else None
        )
        efficiency = num("propulsion", "prop_efficiency", default=0.8)
        if efficiency > 1.0:
            problems.append(
                f"[propulsion] prop_efficiency = {efficiency} must lie in (0, 1] (e.g. 0.8)"
            )
        inertia = num("propulsion", "prop_inertia_kgm2", positive=False, default=0.0)
        if inertia < 0.0:
            problems.append(f"[propulsion] prop_inertia_kgm2 = {inertia} must be >= 0")
        if inertia > 0.0 and rot is None:
            problems.append(
                "[propulsion] prop_rotation is missing: with prop_inertia_kgm2 > 0 the "
                "gyroscopic moment's sign needs it ('cw' or 'ccw' viewed from behind, or "
                "'opposite')"
            )
        if inertia > 0.0 and rot == "opposite" and isinstance(n_eng, int) and n_eng % 2:
            problems.append(
                f"[propulsion] prop_rotation = 'opposite' with {n_eng} engines: an odd engine "
                "has no partner to cancel; give 'cw' or 'ccw'"
            )
        vane_type = table("sensors").get("beta_vane_type", "sideslip")
        if vane_type not in ("sideslip", "flank"):
            problems.append(
                f"[sensors] beta_vane_type = {vane_type!r} must be 'sideslip' (the vane reads "
                "asin(v/V)) or 'flank' (a boom yaw vane reads atan(v/u))"
            )
            vane_type = "sideslip"
        builtin = table("simulator").get("builtin")
        if builtin is not None and builtin not in BUILTINS:
            problems.append(
                f"[simulator] builtin = {builtin!r} must be one of {', '.join(BUILTINS)} (only "
                "for data flown on aerodelta's virtual aircraft; drop it for your own aircraft)"
            )
            builtin = None
        name = doc.get("name", "")
        if not isinstance(name, str):
            problems.append(f"name = {name!r} must be a string")
        ac = cls(
            name=str(name),
            S_m2=num("geometry", "S_m2"),
            b_m=num("geometry", "b_m"),
            cbar_m=num("geometry", "cbar_m"),
            mass_kg=num("mass", "mass_kg"),
            Ixx_kgm2=num("mass", "Ixx_kgm2"),
            Iyy_kgm2=num("mass", "Iyy_kgm2"),
            Izz_kgm2=num("mass", "Izz_kgm2"),
            Ixz_kgm2=num("mass", "Ixz_kgm2", positive=False),
            n_engines=int(n_eng),
            prop_inertia_kgm2=inertia,
            prop_rotation=None if rot is None else str(rot),
            prop_rpm_channel=rpm_channel,
            prop_rpm_fixed=rpm_fixed,
            accel_m=vec("accel_m"),
            alpha_vane_m=vec("alpha_vane_m"),
            beta_vane_m=vec("beta_vane_m"),
            prop_efficiency=efficiency,
            Ixy_kgm2=num("mass", "Ixy_kgm2", positive=False, default=0.0),
            Iyz_kgm2=num("mass", "Iyz_kgm2", positive=False, default=0.0),
            cg_m=vec("cg_m", "mass"),
            moment_ref_m=(
                vec("moment_ref_m", "reference") if "moment_ref_m" in table("reference") else None
            ),
            builtin=builtin,
            beta_vane_type=str(vane_type),
        )
        if not problems and not inertia_definite(ac.mass_geometry[4:]):
            problems.append(
                f"[mass] Ixz_kgm2 = {ac.Ixz_kgm2:g}, Ixy_kgm2 = {ac.Ixy_kgm2:g}, Iyz_kgm2 = "
                f"{ac.Iyz_kgm2:g}: the inertia tensor is not positive definite (a product of "
                "inertia too large for the moments of inertia; Etkin sign, kg m²)"
            )
        if problems:
            raise DataError(f"{source}: invalid aircraft reference: " + "; ".join(problems))
        return ac
