"""Alpha partitioning into bins (thesis Section 3.3.1; engine: ``aero_core::partition``).

The data of one flap setting are split by angle of attack into contiguous bins, each
fitted separately by equation-error least squares. Bins are 0.2 deg wide where the data
allow and wider where data are sparse (high alpha), so that every bin holds at least
``min_points_per_param * n_params`` samples (thesis: about 10 per parameter) and,
optionally, samples from at least ``min_maneuvers`` distinct maneuvers.

Algorithm: start from the fine grid (interior edges on multiples of ``width_deg`` more
than half a width inside the range, outer edges at the range ends), then repeatedly
merge the under-filled bin with the fewest samples into its lighter neighbour (ties:
fewer maneuvers, then narrower, then lower alpha) until every bin is filled. With
``max_width_deg`` a merge past the cap is not made and the bin is reported in
``underfilled``, as is a single bin when the data hold too few samples overall.
Samples are assigned as :func:`numpy.histogram` assigns them on ``edges``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta import _core


class AlphaBins:
    """Bins of one alpha partition, built by :func:`partition_alpha`.

    Attributes are read-only numpy arrays: ``edges`` (deg, ``len + 1``), ``counts``,
    ``centres`` and ``widths`` (deg), ``index`` (bin of each sample, -1 outside the
    range), ``maneuvers`` (distinct maneuvers per bin, or None), ``underfilled``.
    """

    __slots__ = (
        "_b",
        "centres",
        "counts",
        "edges",
        "index",
        "maneuvers",
        "underfilled",
        "widths",
    )

    def __init__(self) -> None:
        raise TypeError("build AlphaBins with aerodelta.partition_alpha(...)")

    @classmethod
    def _from_core(cls, b: _core.AlphaBins) -> AlphaBins:
        obj = cls.__new__(cls)
        obj._b = b
        obj.edges = b.edges()
        obj.counts = b.counts().astype(np.int64)
        m = b.maneuvers()
        obj.maneuvers = None if m is None else m.astype(np.int64)
        obj.index = b.index()
        obj.underfilled = b.underfilled()
        obj.centres = 0.5 * (obj.edges[:-1] + obj.edges[1:])
        obj.widths = np.diff(obj.edges)
        for a in (obj.edges, obj.counts, obj.index, obj.underfilled, obj.centres, obj.widths):
            a.flags.writeable = False
        if obj.maneuvers is not None:
            obj.maneuvers.flags.writeable = False
        return obj

    @property
    def required_points(self) -> int:
        """Samples each bin must hold (``min_points_per_param * n_params``)."""
        return self._b.required_points

    @property
    def required_maneuvers(self) -> int:
        """Distinct maneuvers each bin must hold (0 without maneuver ids)."""
        return self._b.required_maneuvers

    @property
    def ok(self) -> bool:
        """Whether every bin meets the requirement."""
        return not bool(self.underfilled.any())

    def __len__(self) -> int:
        return int(self.counts.size)

    def to_frame(self) -> pl.DataFrame:
        """One row per bin: ``bin, alpha_lo_deg, alpha_hi_deg, alpha_centre_deg,
        width_deg, count, maneuvers`` (null without ids) ``, underfilled``."""
        n = len(self)
        return pl.DataFrame(
            {
                "bin": np.arange(n, dtype=np.int64),
                "alpha_lo_deg": self.edges[:-1],
                "alpha_hi_deg": self.edges[1:],
                "alpha_centre_deg": self.centres,
                "width_deg": self.widths,
                "count": self.counts,
                "maneuvers": pl.Series(
                    "maneuvers",
                    [None] * n if self.maneuvers is None else self.maneuvers,
                    dtype=pl.Int64,
                ),
                "underfilled": self.underfilled,
            }
        )

    def __repr__(self) -> str:
        e = self.edges
        return (
            f"AlphaBins({len(self)} bins on [{e[0]:g}, {e[-1]:g}] deg, "
            f">= {self.required_points} points each, {int(self.underfilled.sum())} underfilled)"
        )


def partition_alpha(
    alpha_deg: npt.ArrayLike,
    n_params: int,
    *,
    width_deg: float = 0.2,
    min_points_per_param: int = 10,
    maneuver_id: npt.ArrayLike | None = None,
    min_maneuvers: int = 1,
    alpha_range: tuple[float, float] | None = None,
    max_width_deg: float | None = None,
    anchor_deg: float = 0.0,
) -> AlphaBins:
    """Partition alpha samples of one flap setting into bins (thesis Section 3.3.1).

    Parameters
    ----------
    alpha_deg
        Angle of attack per sample, deg, 1-D (e.g. a polars column).
    n_params
        Parameters each bin's regression identifies.
    width_deg
        Nominal (finest) bin width, deg (thesis: 0.2).
    min_points_per_param
        Samples required per parameter (thesis: about 10).
    maneuver_id
        Maneuver of each sample (any hashable values, e.g. strings), for
        ``min_maneuvers``.
    min_maneuvers
        Distinct maneuvers each bin must hold (samples of one maneuver are correlated).
    alpha_range
        ``(lo, hi)`` in deg to partition; default the data's min and max. Samples
        outside get index -1.
    max_width_deg
        Largest bin width, deg; bins that would need more are left under-filled.
    anchor_deg
        Interior edges lie on ``anchor_deg + k * width_deg`` (default: multiples of
        the width, e.g. 12.0, 12.2 deg).

    Returns
    -------
    AlphaBins

    Raises
    ------
    TooLittleDataError
        No samples (or none in ``alpha_range``).
    InvalidInputError
        A non-finite alpha (its row named), ``n_params`` 0, bad range or lengths.
    OutOfRangeError
        A width that is not positive, or a cap below the width.

    Examples
    --------
    >>> import numpy as np
    >>> bins = partition_alpha(np.linspace(6.0, 8.0, 201), 2)
    >>> len(bins), int(bins.counts.min()) >= 20
    (10, True)
    """
    a = np.ascontiguousarray(np.asarray(alpha_deg, dtype=np.float64))
    if a.ndim != 1:
        raise _core.InvalidInputError(f"argument 'alpha_deg': expected a 1-D array, got {a.ndim}-D")
    if int(n_params) != n_params or n_params < 0:
        raise _core.InvalidInputError(f"argument 'n_params': {n_params} is not a count")
    ids = None
    if maneuver_id is not None:
        m = np.asarray(maneuver_id)
        if m.ndim != 1:
            raise _core.InvalidInputError(
                f"argument 'maneuver_id': expected a 1-D array, got {m.ndim}-D"
            )
        _, inverse = np.unique(m, return_inverse=True)
        ids = np.ascontiguousarray(inverse.ravel().astype(np.uint64))
    rng = None if alpha_range is None else (float(alpha_range[0]), float(alpha_range[1]))
    b = _core.partition_alpha(
        a,
        int(n_params),
        float(width_deg),
        int(min_points_per_param),
        ids,
        int(min_maneuvers),
        rng,
        None if max_width_deg is None else float(max_width_deg),
        float(anchor_deg),
    )
    return AlphaBins._from_core(b)


__all__ = ["AlphaBins", "partition_alpha"]
