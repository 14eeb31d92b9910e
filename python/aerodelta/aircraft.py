"""The aircraft reference (TOML): geometry, mass, inertias, propellers, sensor positions.

Schema (see ``docs/data.md``)::

    name = "..."
    [geometry]   S_m2, b_m, cbar_m
    [mass]       mass_kg, Ixx_kgm2, Iyy_kgm2, Izz_kgm2, Ixz_kgm2
    [propulsion] n_engines, prop_inertia_kgm2, prop_rotation = "same" | "opposite",
                 prop_rpm_channel = "prop_rpm" and/or prop_rpm_fixed = 1020.0
    [sensors]    accel_m, alpha_vane_m, beta_vane_m  (x fwd, y right, z down from the CG, m)
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aerodelta.exceptions import DataError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


@dataclass(frozen=True)
class Aircraft:
    """Reference data of the aircraft (SI units).

    ``prop_rotation = "same"`` means all propellers turn the same way (their angular momenta
    add, thesis Eq. 3.3 with :math:`h_p = n I_p \\Omega_p`); ``"opposite"`` means they cancel in
    pairs (:math:`h_p = (n \\bmod 2) I_p \\Omega_p`).
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
    prop_rotation: str = "same"
    prop_rpm_channel: str | None = None
    prop_rpm_fixed: float | None = None
    accel_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    alpha_vane_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    beta_vane_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    prop_efficiency: float = 0.8

    @property
    def mass_geometry(self) -> list[float]:
        """``[S, b, cbar, mass, Ixx, Iyy, Izz, Ixz]`` as the engine takes it."""
        return [
            self.S_m2,
            self.b_m,
            self.cbar_m,
            self.mass_kg,
            self.Ixx_kgm2,
            self.Iyy_kgm2,
            self.Izz_kgm2,
            self.Ixz_kgm2,
        ]

    @property
    def prop_h_per_rpm(self) -> float:
        """Propeller angular momentum per rpm, kg m²/s per rpm (thesis sign, Eq. 3.3)."""
        n_eff = self.n_engines if self.prop_rotation == "same" else self.n_engines % 2
        return n_eff * self.prop_inertia_kgm2 * 2.0 * math.pi / 60.0

    @classmethod
    def from_toml(cls, path: str | Path) -> Aircraft:
        """Read and validate an aircraft TOML file.

        Raises
        ------
        DataError
            Naming the file, the table and key at fault.
        """
        path = Path(path)
        try:
            with path.open("rb") as f:
                doc = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            raise DataError(f"{path}: not valid TOML: {e}") from e
        return cls.from_dict(doc, source=str(path))

    @classmethod
    def from_dict(cls, doc: dict[str, Any], source: str = "<dict>") -> Aircraft:
        """Build from the parsed TOML structure (same schema as :meth:`from_toml`)."""
        problems: list[str] = []

        def num(table: str, key: str, positive: bool = True, default: float | None = None) -> float:
            t = doc.get(table, {})
            if key not in t:
                if default is not None:
                    return default
                problems.append(f"[{table}] {key} is missing")
                return math.nan
            v = t[key]
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                problems.append(f"[{table}] {key} = {v!r} is not a finite number")
                return math.nan
            if positive and v <= 0:
                problems.append(f"[{table}] {key} = {v} must be positive")
            return float(v)

        def vec(key: str) -> tuple[float, float, float]:
            v = doc.get("sensors", {}).get(key, [0.0, 0.0, 0.0])
            if (
                not isinstance(v, list)
                or len(v) != 3
                or not all(isinstance(x, (int, float)) for x in v)
            ):
                problems.append(f"[sensors] {key} = {v!r} must be a list of 3 numbers (m)")
                return (0.0, 0.0, 0.0)
            return (float(v[0]), float(v[1]), float(v[2]))

        prop = doc.get("propulsion", {})
        rot = prop.get("prop_rotation", "same")
        if rot not in ("same", "opposite"):
            problems.append(f"[propulsion] prop_rotation = {rot!r} must be 'same' or 'opposite'")
        ac = cls(
            name=str(doc.get("name", "")),
            S_m2=num("geometry", "S_m2"),
            b_m=num("geometry", "b_m"),
            cbar_m=num("geometry", "cbar_m"),
            mass_kg=num("mass", "mass_kg"),
            Ixx_kgm2=num("mass", "Ixx_kgm2"),
            Iyy_kgm2=num("mass", "Iyy_kgm2"),
            Izz_kgm2=num("mass", "Izz_kgm2"),
            Ixz_kgm2=num("mass", "Ixz_kgm2", positive=False),
            n_engines=int(prop.get("n_engines", 2)),
            prop_inertia_kgm2=num("propulsion", "prop_inertia_kgm2", positive=False, default=0.0),
            prop_rotation=str(rot),
            prop_rpm_channel=prop.get("prop_rpm_channel"),
            prop_rpm_fixed=(float(prop["prop_rpm_fixed"]) if "prop_rpm_fixed" in prop else None),
            accel_m=vec("accel_m"),
            alpha_vane_m=vec("alpha_vane_m"),
            beta_vane_m=vec("beta_vane_m"),
            prop_efficiency=num("propulsion", "prop_efficiency", default=0.8),
        )
        if not problems and ac.Ixz_kgm2**2 >= ac.Ixx_kgm2 * ac.Izz_kgm2:
            problems.append(
                "[mass] Ixz_kgm2² >= Ixx·Izz: the inertia tensor is not positive definite"
            )
        if problems:
            raise DataError(f"{source}: invalid aircraft reference: " + "; ".join(problems))
        return ac
