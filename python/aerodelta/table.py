"""Gridded N-D lookup tables with multilinear interpolation (engine: ``aero_core::table``)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import numpy.typing as npt

from aerodelta import _core

Extrapolation = Literal["hold", "linear"]


def _per_axis(value: object, n: int, name: str) -> list:
    if isinstance(value, str) or value is None or np.isscalar(value):
        return [value] * n
    seq = list(value)  # type: ignore[call-overload]
    if len(seq) != n:
        raise _core.InvalidInputError(f"argument '{name}': has {len(seq)} entries for {n} axes")
    return seq


class Table:
    """A gridded table of 1 to 8 dimensions, as simulator aero databases store them.

    Parameters
    ----------
    breakpoints
        One strictly increasing sequence per axis, in the axis's own unit.
    values
        Array of shape ``tuple(len(b) for b in breakpoints)`` (or flat, row-major
        with the last axis fastest).
    names
        Axis names, for messages and exports (default ``x0, x1, ...``).
    below, above
        Out-of-range policy per axis (or one for all): ``"hold"`` keeps the end
        value (default, as qualified models do), ``"linear"`` extrapolates the
        end segment.
    mins, maxs
        Optional input limits per axis, applied before interpolation.

    Examples
    --------
    >>> t = Table([[0.0, 10.0], [-5.0, 5.0]], [[0.0, 1.0], [2.0, 3.0]], names=["alpha", "beta"])
    >>> float(t([5.0], [0.0])[0])
    1.5
    >>> t.eval_point([20.0, 5.0])
    3.0
    """

    __slots__ = ("_t",)

    def __init__(
        self,
        breakpoints: Sequence[Sequence[float]],
        values: npt.ArrayLike,
        *,
        names: Sequence[str] | None = None,
        below: Extrapolation | Sequence[Extrapolation] = "hold",
        above: Extrapolation | Sequence[Extrapolation] = "hold",
        mins: float | Sequence[float | None] | None = None,
        maxs: float | Sequence[float | None] | None = None,
    ) -> None:
        bps = [[float(b) for b in axis] for axis in breakpoints]
        n = len(bps)
        names_ = list(names) if names is not None else [f"x{k}" for k in range(n)]
        vals = np.ascontiguousarray(np.asarray(values, dtype=np.float64).ravel())
        self._t = _core.Table(
            names_,
            bps,
            vals,
            _per_axis(below, n, "below"),
            _per_axis(above, n, "above"),
            _per_axis(mins, n, "mins"),
            _per_axis(maxs, n, "maxs"),
        )

    @classmethod
    def _from_core(cls, t: _core.Table) -> Table:
        obj = cls.__new__(cls)
        obj._t = t
        return obj

    @property
    def ndim(self) -> int:
        """Number of axes."""
        return self._t.ndim

    @property
    def names(self) -> list[str]:
        """Axis names."""
        return self._t.names

    @property
    def breakpoints(self) -> list[list[float]]:
        """Breakpoints per axis."""
        return self._t.breakpoints

    @property
    def values(self) -> npt.NDArray[np.float64]:
        """Values with the table's shape."""
        return self._t.values().reshape([len(b) for b in self.breakpoints])

    def eval_point(self, x: Sequence[float]) -> float:
        """Value at one point (one coordinate per axis); NaN if any coordinate is NaN."""
        return self._t.eval_point([float(v) for v in x])

    def __call__(self, *columns: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Values at many points, one array per axis (broadcast to a common shape).

        The work runs in Rust with the GIL released, in parallel over points.
        """
        arrays = np.broadcast_arrays(*[np.asarray(c, dtype=np.float64) for c in columns])
        shape = arrays[0].shape if arrays else ()
        flat = [np.ascontiguousarray(a.ravel()) for a in arrays]
        return self._t.eval_columns(flat).reshape(shape)

    def eval_rows(self, points: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Values at an ``(npoints, ndim)`` array of points (scipy's layout)."""
        pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64))
        if pts.ndim != 2:
            raise _core.InvalidInputError(
                f"argument 'points': expected a 2-D (npoints, ndim) array, got {pts.ndim}-D"
            )
        return self._t.eval_rows(pts)

    def __repr__(self) -> str:
        shape = "x".join(str(len(b)) for b in self.breakpoints)
        return f"Table({', '.join(self.names)}; {shape})"
