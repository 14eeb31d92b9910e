"""Units of flight test channels and their explicit conversion to the canonical units.

Every channel of a channel map declares its unit; :func:`factor_offset` gives the affine map
``canonical = raw * factor + offset`` onto the canonical unit of the same dimension, and
refuses to convert between dimensions (deg to m/s, say). Canonical units: deg, deg/s, m/s²,
m/s, m, Pa, K, kg/m³, N, N·m, rpm, s and ``-`` (dimensionless).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from aerodelta.exceptions import DataError

# unit -> (dimension, factor to canonical, offset to canonical)
_UNITS: dict[str, tuple[str, float, float]] = {
    # angle
    "deg": ("angle", 1.0, 0.0),
    "rad": ("angle", 180.0 / math.pi, 0.0),
    # angular rate
    "deg/s": ("rate", 1.0, 0.0),
    "rad/s": ("rate", 180.0 / math.pi, 0.0),
    # angular acceleration
    "deg/s2": ("angacc", 1.0, 0.0),
    "rad/s2": ("angacc", 180.0 / math.pi, 0.0),
    # linear acceleration
    "m/s2": ("accel", 1.0, 0.0),
    "ft/s2": ("accel", 0.3048, 0.0),
    "g": ("accel", 9.80665, 0.0),
    # speed
    "m/s": ("speed", 1.0, 0.0),
    "kt": ("speed", 1852.0 / 3600.0, 0.0),
    "ft/s": ("speed", 0.3048, 0.0),
    "km/h": ("speed", 1.0 / 3.6, 0.0),
    # length
    "m": ("length", 1.0, 0.0),
    "ft": ("length", 0.3048, 0.0),
    # pressure
    "Pa": ("pressure", 1.0, 0.0),
    "hPa": ("pressure", 100.0, 0.0),
    "mbar": ("pressure", 100.0, 0.0),
    "psf": ("pressure", 47.88025898033584, 0.0),
    "psi": ("pressure", 6894.757293168361, 0.0),
    "inHg": ("pressure", 3386.389, 0.0),
    # temperature
    "K": ("temperature", 1.0, 0.0),
    "degC": ("temperature", 1.0, 273.15),
    "degF": ("temperature", 5.0 / 9.0, 273.15 - 32.0 * 5.0 / 9.0),
    # density
    "kg/m3": ("density", 1.0, 0.0),
    "slug/ft3": ("density", 515.3788183931961, 0.0),
    # force and torque
    "N": ("force", 1.0, 0.0),
    "lbf": ("force", 4.4482216152605, 0.0),
    "N*m": ("torque", 1.0, 0.0),
    "ft*lbf": ("torque", 1.3558179483314004, 0.0),
    # rotational speed of engines and propellers
    "rpm": ("rotspeed", 1.0, 0.0),
    "rev/s": ("rotspeed", 60.0, 0.0),
    # time and dimensionless
    "s": ("time", 1.0, 0.0),
    "ms": ("time", 1e-3, 0.0),
    "-": ("none", 1.0, 0.0),
}

#: Aliases accepted in channel maps.
ALIASES: dict[str, str] = {
    "degrees": "deg",
    "radians": "rad",
    "dps": "deg/s",
    "rps": "rad/s",
    "m/s^2": "m/s2",
    "ft/s^2": "ft/s2",
    "knots": "kt",
    "kts": "kt",
    "mps": "m/s",
    "fps": "ft/s",
    "lb/ft2": "psf",
    "C": "degC",
    "F": "degF",
    "Nm": "N*m",
    "ftlbf": "ft*lbf",
    "kg/m^3": "kg/m3",
    "1": "-",
    "": "-",
}


def known_units() -> list[str]:
    """Every unit name accepted (aliases excluded), sorted."""
    return sorted(_UNITS)


def canonical_name(unit: str) -> str:
    """Resolve an alias to the registry's unit name.

    Raises
    ------
    DataError
        When the unit is unknown; the message lists the known units.
    """
    u = ALIASES.get(unit.strip(), unit.strip())
    if u not in _UNITS:
        raise DataError(f"unknown unit '{unit}'; known units: {', '.join(known_units())}")
    return u


def dimension(unit: str) -> str:
    """The physical dimension of ``unit`` (``angle``, ``rate``, ``speed``, ...)."""
    return _UNITS[canonical_name(unit)][0]


def factor_offset(from_unit: str, to_unit: str) -> tuple[float, float]:
    """Affine map ``y = x * factor + offset`` converting ``from_unit`` to ``to_unit``.

    Raises
    ------
    DataError
        When the units are unknown or of different dimensions.

    Examples
    --------
    >>> factor_offset("kt", "m/s")[0]
    0.5144444444444445
    """
    fa, fb = canonical_name(from_unit), canonical_name(to_unit)
    da, ka, oa = _UNITS[fa]
    db, kb, ob = _UNITS[fb]
    if da != db:
        raise DataError(f"cannot convert '{from_unit}' ({da}) to '{to_unit}' ({db})")
    # to canonical: c = x*ka + oa; from canonical: y = (c - ob)/kb
    return ka / kb, (oa - ob) / kb


def convert(values: npt.ArrayLike, from_unit: str, to_unit: str) -> npt.NDArray[np.float64]:
    """Convert ``values`` from one unit to another of the same dimension.

    Examples
    --------
    >>> round(float(convert(100.0, "degC", "degF")), 9)
    212.0
    """
    k, o = factor_offset(from_unit, to_unit)
    return np.asarray(values, dtype=np.float64) * k + o
