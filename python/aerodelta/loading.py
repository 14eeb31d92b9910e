"""Per-maneuver loading: mass, inertia tensor and CG position from manifest columns.

A flight test campaign flies its maneuvers with different loadings (fuel burnt between
stalls, ballast moved to the forward and aft CG limits, crew changes), so the moments of
thesis Eq. 3.2-3.3 are about a CG that moves, with inertias that change. The manifest may
give, per maneuver, any of

====================  ======  ==========================================================
column                unit    meaning
====================  ======  ==========================================================
``mass_kg``           kg      mass
``Ixx_kgm2`` ...      kg m²   ``Ixx``, ``Iyy``, ``Izz``, ``Ixz``, ``Ixy``, ``Iyz`` about
                              that maneuver's CG (Etkin sign, as in ``aircraft.toml``)
``cg_x_m`` ...        m       ``cg_x_m``, ``cg_y_m``, ``cg_z_m``: CG from the aircraft
                              datum, body axes (x forward, y right, z down)
====================  ======  ==========================================================

the others taken from ``aircraft.toml``. The engine then transfers each maneuver's sensors
to its own CG and its moments to the moment reference centre ``[reference] moment_ref_m``
(``aero_core::preprocess::coefficients``), so the measured coefficients of all maneuvers
are about one point, as the simulator applies them. Mass changes within a maneuver (fuel
burnt over a one-minute stall, about 0.1 % of the mass) are not modelled.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from aerodelta.aircraft import Aircraft, inertia_definite
from aerodelta.exceptions import DataError
from aerodelta.readers import _rows, numeric_column

#: Manifest columns of the loading, in the order the engine takes them.
LOADING_COLUMNS = (
    "mass_kg",
    "Ixx_kgm2",
    "Iyy_kgm2",
    "Izz_kgm2",
    "Ixz_kgm2",
    "Ixy_kgm2",
    "Iyz_kgm2",
    "cg_x_m",
    "cg_y_m",
    "cg_z_m",
)

#: A CG further than this share of the mean aerodynamic chord (x, z) or of the span (y) from
#: the aircraft file's CG is reported: at these distances a unit slip (inches, % MAC) is
#: likelier than a loading (transport CG envelopes span some 20-30 % of the MAC).
CG_WARN_SHARE = 0.5


def _nominal(ac: Aircraft) -> list[float]:
    """The aircraft file's loading in the order of :data:`LOADING_COLUMNS`."""
    return [*ac.mass_geometry[3:], *ac.cg_m]


def manifest_loadings(man: pl.DataFrame | None, ac: Aircraft, source: str) -> pl.DataFrame | None:
    """Each manifest row's loading, or None when the manifest gives none of
    :data:`LOADING_COLUMNS`.

    Returns
    -------
    polars.DataFrame or None
        ``maneuver_id`` and every column of :data:`LOADING_COLUMNS` (kg, kg m², m), the
        aircraft file's value where the manifest has no such column.

    Raises
    ------
    DataError
        One line naming the manifest, column and rows: a cell that is empty or not a
        number, a mass that is not positive, an inertia tensor that is not positive definite.
    """
    if man is None:
        return None
    given = [c for c in LOADING_COLUMNS if c in man.columns]
    if not given:
        return None
    nominal = _nominal(ac)
    cols: dict[str, pl.Series] = {"maneuver_id": man["maneuver_id"].cast(pl.Utf8)}
    for c, v0 in zip(LOADING_COLUMNS, nominal, strict=True):
        if c not in man.columns:
            cols[c] = pl.Series(c, np.full(man.height, v0))
            continue
        what = (
            "a number; give the loading of every maneuver (or drop the column to use the "
            f"aircraft file's {v0:g})"
        )
        cols[c] = numeric_column(man, c, source, what).alias(c)
    out = pl.DataFrame(cols)
    m = out["mass_kg"].to_numpy()
    bad = np.flatnonzero(m <= 0.0)
    if bad.size:
        raise DataError(
            f"{source}: column 'mass_kg', rows {_rows(bad)}: the mass must be positive (kg)"
        )
    tensor = out.select(LOADING_COLUMNS[1:7]).to_numpy()
    bad = ~inertia_definite(tensor.T)
    if bad.any():
        named = ", ".join(c for c in LOADING_COLUMNS[1:7] if c in given) or "aircraft file"
        raise DataError(
            f"{source}: rows {_rows(np.flatnonzero(bad))}: the inertia tensor ({named}) is "
            "not positive definite; check the units (kg m²) and the products' signs (Etkin)"
        )
    return out


def cg_warnings(loadings: pl.DataFrame, ac: Aircraft) -> list[tuple[str, str]]:
    """``(maneuver_id, message)`` for CGs further than :data:`CG_WARN_SHARE` of the chord
    (x, z) or span (y) from the aircraft file's CG, and masses that differ from its mass
    by more than half."""
    limits = (CG_WARN_SHARE * ac.cbar_m, CG_WARN_SHARE * ac.b_m, CG_WARN_SHARE * ac.cbar_m)
    out: list[tuple[str, str]] = []
    ids = loadings["maneuver_id"].to_list()
    for axis, c0, lim in zip("xyz", ac.cg_m, limits, strict=True):
        off = loadings[f"cg_{axis}_m"].to_numpy() - c0
        for i in np.flatnonzero(np.abs(off) > lim):
            out.append(
                (
                    str(ids[i]),
                    f"manifest cg_{axis}_m is {off[i]:+.3g} m from the aircraft file's CG "
                    f"(more than {lim:.3g} m): check the units (m from the datum)",
                )
            )
    ratio = loadings["mass_kg"].to_numpy() / ac.mass_kg
    for i in np.flatnonzero((ratio < 0.5) | (ratio > 1.5)):
        out.append(
            (
                str(ids[i]),
                f"manifest mass_kg is {ratio[i]:.3g} times the aircraft file's: check the units",
            )
        )
    return out


def loading_array(loadings: pl.DataFrame | None, maneuver_ids: list[str]) -> np.ndarray | None:
    """The ``(n_maneuvers, 10)`` array of :data:`LOADING_COLUMNS` in the order of
    ``maneuver_ids``, as ``aerodelta._core.preprocess_batch`` takes it.

    Raises
    ------
    DataError
        A maneuver without a loading row.
    """
    if loadings is None:
        return None
    order = pl.DataFrame({"maneuver_id": maneuver_ids}).join(
        loadings, on="maneuver_id", how="left", maintain_order="left"
    )
    missing = order.filter(pl.col("mass_kg").is_null())["maneuver_id"].to_list()
    if missing:
        more = f" and {len(missing) - 5} more" if len(missing) > 5 else ""
        raise DataError(
            f"manifest: no loading for maneuver(s) {', '.join(missing[:5])}{more}; add their "
            "rows to the manifest"
        )
    return np.ascontiguousarray(order.select(LOADING_COLUMNS).to_numpy(), dtype=np.float64)
