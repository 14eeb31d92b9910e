"""Cubic smoothing splines with MATLAB ``csaps`` semantics (engine: ``aero_core::spline``).

The spline :math:`f` minimises (thesis Eq. 3.13)

.. math::

    p \\sum_j w_j \\, (y_j - f(x_j))^2 + (1 - p) \\int (f''(t))^2 \\, dt,

with :math:`p = 0` the weighted least-squares straight line and :math:`p = 1` the
natural cubic interpolant. The thesis smooths the per-alpha-bin Δ-model parameters
with ``p = 0.4`` (Section 3.4). Results agree with the Python ``csaps`` package
(``csaps.CubicSmoothingSpline(x, y, weights, smooth=p)``) to rounding.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import numpy.typing as npt

from aerodelta import _core
from aerodelta.table import Table

SplineExtrapolation = Literal["polynomial", "hold"]


def _vector(name: str, v: npt.ArrayLike) -> npt.NDArray[np.float64]:
    a = np.ascontiguousarray(np.asarray(v, dtype=np.float64))
    if a.ndim != 1:
        raise _core.InvalidInputError(f"argument '{name}': expected a 1-D array, got {a.ndim}-D")
    return a


class SmoothingSpline:
    """A cubic spline in piecewise-polynomial form, as fitted by :func:`smoothing_spline`.

    Piece ``i`` covers ``[breaks[i], breaks[i+1])`` (the last piece is closed) and is
    ``c[0, i] t**3 + c[1, i] t**2 + c[2, i] t + c[3, i]`` with ``t = x - breaks[i]``,
    the layout of MATLAB ``ppform``, scipy ``PPoly`` and ``csaps.SplinePPForm``.
    """

    __slots__ = ("_breaks", "_coefs", "_s")

    def __init__(self) -> None:
        raise TypeError("build a SmoothingSpline with aerodelta.smoothing_spline(...)")

    @classmethod
    def _from_core(cls, s: _core.SmoothingSpline) -> SmoothingSpline:
        obj = cls.__new__(cls)
        obj._s = s
        obj._breaks = s.breaks()
        obj._coefs = s.coefs().reshape(-1, 4).T.copy()
        obj._breaks.flags.writeable = False
        obj._coefs.flags.writeable = False
        return obj

    @property
    def breaks(self) -> npt.NDArray[np.float64]:
        """Breaks (the data sites), strictly increasing, in the unit of ``x``."""
        return self._breaks

    @property
    def coefs(self) -> npt.NDArray[np.float64]:
        """Coefficients, shape ``(4, len(breaks) - 1)``, highest power first."""
        return self._coefs

    @property
    def p(self) -> float:
        """Smoothing parameter used (the automatic one when none was given)."""
        return self._s.p

    def __call__(
        self,
        x: npt.ArrayLike,
        nu: int = 0,
        *,
        extrapolate: SplineExtrapolation = "polynomial",
    ) -> npt.NDArray[np.float64]:
        """Values (``nu = 0``) or derivatives of order ``nu`` at ``x``.

        Parameters
        ----------
        x
            Points, any shape, in the unit of the data sites (e.g. deg).
        nu
            Derivative order (per unit of ``x``); orders above 3 are zero.
        extrapolate
            Outside the breaks: ``"polynomial"`` continues the end pieces (as
            ``csaps``/MATLAB do), ``"hold"`` keeps the end values (derivatives 0).

        Returns
        -------
        numpy.ndarray
            Same shape as ``x``; NaN where ``x`` is NaN.
        """
        if int(nu) != nu or nu < 0:
            raise _core.InvalidInputError(f"argument 'nu': {nu} is not a non-negative integer")
        xa = np.asarray(x, dtype=np.float64)
        flat = np.ascontiguousarray(xa.ravel())
        return self._s.eval(flat, int(nu), extrapolate).reshape(xa.shape)

    def to_table(
        self,
        grid: npt.ArrayLike,
        *,
        name: str = "alpha_deg",
        extrapolate: SplineExtrapolation = "hold",
    ) -> Table:
        """Resample onto a strictly increasing ``grid`` as a 1-D :class:`~aerodelta.Table`.

        Grid points beyond the data use ``extrapolate``; the table itself holds its
        end values beyond the grid (thesis Section 3.4: clipped tables).
        """
        g = [float(v) for v in _vector("grid", grid)]
        return Table._from_core(self._s.to_table(name, g, extrapolate))

    def __repr__(self) -> str:
        b = self._breaks
        return f"SmoothingSpline(p={self.p:.6g}, {b.size} breaks on [{b[0]:g}, {b[-1]:g}])"


def smoothing_spline(
    x: npt.ArrayLike,
    y: npt.ArrayLike,
    p: float | Literal["auto"] | None = 0.4,
    weights: npt.ArrayLike | None = None,
    *,
    normalized: bool = False,
    merge_duplicates: bool = False,
) -> SmoothingSpline:
    """Fit the cubic smoothing spline of thesis Eq. 3.13 (MATLAB / Python ``csaps``).

    Parameters
    ----------
    x
        Data sites, 1-D, finite and strictly increasing (e.g. alpha-bin centres, deg);
        unsorted or repeated sites are refused unless ``merge_duplicates``.
    y
        Values at the sites, 1-D (one series; call once per series).
    p
        Smoothing parameter in [0, 1]: 0 gives the weighted least-squares line, 1 the
        natural cubic interpolant; the thesis uses 0.4. ``None`` or ``"auto"`` picks
        ``csaps``'s automatic value ``1 / (1 + trace(R) / (6 trace(Q' W^-1 Q)))``.
    weights
        Positive weights ``w_j`` (default 1), e.g. ``1 / std_err**2`` per bin.
    normalized
        Use ``csaps``'s ``normalizedsmooth``: ``p`` (default 0.5) is a scale-free
        smoothing value mapped to the actual parameter (see ``.p``).
    merge_duplicates
        Sort the data and replace repeated sites by one site with the weighted mean
        value and the summed weight, as MATLAB ``csaps`` does (the minimiser of
        Eq. 3.13 is unchanged). ``breaks`` are then the distinct sites.

    Returns
    -------
    SmoothingSpline

    Raises
    ------
    TooLittleDataError
        Fewer than 2 points.
    InvalidInputError
        Non-finite or unsorted data, or arrays of different lengths (index named).
    OutOfRangeError
        ``p`` outside [0, 1] or a weight <= 0 (index named).

    Examples
    --------
    >>> s = smoothing_spline([0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 0.0, 1.0], p=1.0)
    >>> float(s(2.0))
    0.0
    >>> s0 = smoothing_spline([0.0, 1.0, 2.0], [0.0, 2.0, 1.0], p=0.0)
    >>> round(float(s0(4.0)), 12)
    2.5
    """
    xa = _vector("x", x)
    ya = _vector("y", y)
    wa = None if weights is None else _vector("weights", weights)
    if isinstance(p, str):
        if p != "auto":
            raise _core.InvalidInputError(f"argument 'p': '{p}' is not a number or 'auto'")
        p = None
    pv = None if p is None else float(p)
    if merge_duplicates:
        xa, ya, wa = _core.merge_sites(xa, ya, wa)
    return SmoothingSpline._from_core(_core.smoothing_spline(xa, ya, wa, pv, normalized))


__all__ = ["SmoothingSpline", "SplineExtrapolation", "smoothing_spline"]
