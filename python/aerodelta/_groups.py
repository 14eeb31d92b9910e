"""Grouped float aggregations that give the same bits for any thread count.

A polars ``group_by(...).agg(pl.col(x).sum())`` (or ``mean``, ``std``, ``var``, and the same
inside ``.over(...)``) on a float column splits its sums over the polars thread pool, so the
last digits of the result can change with ``POLARS_MAX_THREADS`` and even between two calls
on the same data (float addition is not associative; pola-rs/polars#6157, #25163). This module
takes those sums with numpy instead, in row order: :func:`numpy.unique` numbers the groups and
:func:`numpy.bincount` with weights adds each group's values in the order of the rows. The
result depends on the rows and their order only.

Semantics follow polars' defaults: nulls are ignored (a group with no value gives a null mean,
standard deviation and variance and a zero sum); NaN is a value and propagates (a group holding
a NaN has a NaN sum, mean, standard deviation and variance). ``std`` and ``var`` take
``ddof = 1`` unless told and are null when a group has ``ddof`` values or fewer; they are two
passes (the group means first, then the sum of squared deviations from them). Results are in
the unit of the input column (its square for ``var``), ``Float64`` (``Float32`` for a
``Float32`` column, as polars).

Groups come out sorted by the keys, in polars' sort order (nulls first, NaN after every number,
``-0.0`` and ``0.0`` one group). Order-free aggregations (``len``, ``min``, ``max``,
``n_unique``, ``median``, ``quantile``, ``first``/``last`` in row order, counts and sums of
booleans or integers) are exact in polars: pass them as ``exact`` expressions; they are
evaluated by polars per group and aligned with the same groups.

Examples
--------
>>> df = pl.DataFrame({"f": [0.0, 0.0, 5.0], "x": [1.0, 2.0, None]})
>>> group_agg(df, ["f"], {"x_mean": ("x", "mean")}, exact=[pl.len().alias("n")]).rows()
[(0.0, 2, 1.5), (5.0, 1, None)]
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import polars as pl

Agg = Literal["sum", "mean", "std", "var"]
"""A float aggregation: ``sum``, ``mean``, ``std`` or ``var``."""

_AGGS = ("sum", "mean", "std", "var")
_INDEX = "__aerodelta_group__"
#: Mixed-radix key codes up to this many (or 4x the rows) are compacted by a table, not a sort.
_TABLE_MIN = 1 << 16


@dataclass(frozen=True)
class Groups:
    """The groups of a frame's rows by key columns.

    Attributes
    ----------
    keys : polars.DataFrame
        One row per group: the key columns (their dtypes), sorted by the keys.
    index : numpy.ndarray
        Per row of the frame, its group: a row number of ``keys`` (int64).
    first : numpy.ndarray
        Per group, the row of the frame where it first occurs (int64).
    """

    keys: pl.DataFrame
    index: np.ndarray
    first: np.ndarray

    @classmethod
    def of(cls, df: pl.DataFrame, keys: Sequence[str]) -> Groups:
        """The groups of ``df``'s rows by the columns ``keys`` (at least one)."""
        keys = list(keys)
        if not keys:
            raise ValueError("group by at least one key column")
        n = df.height
        # the rows' key tuples as one integer whose order is the keys' sort order: per key its
        # dense rank (0 for null), mixed radix; compacted by a sort only past the table bound
        code = np.zeros(n, dtype=np.int64)
        size = 1
        bound = max(_TABLE_MIN, 4 * n)
        for k in keys:
            r, m = _dense_rank(df[k])
            if size * (m + 1) > bound and n:
                code = np.unique(code, return_inverse=True)[1].astype(np.int64).reshape(-1)
                size = int(code.max()) + 1
            code = code * (m + 1) + r
            size *= m + 1
        if n and size <= bound:
            present = np.zeros(size, dtype=bool)
            present[code] = True
            index = (np.cumsum(present) - 1)[code].astype(np.int64)
            first = np.full(int(present.sum()), n, dtype=np.int64)
            np.minimum.at(first, index, np.arange(n, dtype=np.int64))
        else:
            _, first, index = np.unique(code, return_index=True, return_inverse=True)
            first = first.astype(np.int64)
            index = index.astype(np.int64).reshape(-1)
        return cls(df.select(keys)[first], index, first)

    @property
    def size(self) -> int:
        """The number of groups."""
        return self.keys.height

    def reduce(self, values: pl.Series | np.ndarray, how: Agg, *, ddof: int = 1) -> pl.Series:
        """Per group, ``how`` of ``values`` (one per row of the frame), summed in row order.

        Returns a ``Float64`` series (``Float32`` for ``Float32`` values) in the groups'
        order, named after ``values`` (``""`` for an array); null where polars gives null."""
        if how not in _AGGS:
            raise ValueError(f"aggregation {how!r}: use one of {', '.join(_AGGS)}")
        s = values if isinstance(values, pl.Series) else pl.Series("", values)
        if s.len() != self.index.size:
            raise ValueError(f"{s.len()} values for {self.index.size} rows")
        if not (s.dtype.is_float() or s.dtype.is_integer() or s.dtype == pl.Boolean):
            raise TypeError(f"{s.name!r} is {s.dtype}: aggregate numbers")
        valid = s.is_not_null().to_numpy()
        x = np.where(valid, s.cast(pl.Float64).fill_null(0.0).to_numpy(), 0.0)
        m = self.size
        n = np.bincount(self.index, weights=valid.astype(np.float64), minlength=m)
        total = np.bincount(self.index, weights=x, minlength=m)
        out: np.ndarray
        missing: np.ndarray
        if how == "sum":
            out, missing = total, np.zeros(m, dtype=bool)
        else:
            with np.errstate(invalid="ignore", divide="ignore"):
                mean = total / n
            if how == "mean":
                out, missing = mean, n == 0
            else:
                dev = np.where(valid, x - mean[self.index], 0.0)
                ss = np.bincount(self.index, weights=dev * dev, minlength=m)
                with np.errstate(invalid="ignore", divide="ignore"):
                    out = ss / (n - ddof)
                if how == "std":
                    out = np.sqrt(out)
                missing = n <= ddof
        dtype = pl.Float32 if s.dtype == pl.Float32 else pl.Float64
        res = pl.Series(s.name, out, dtype=pl.Float64).scatter(np.flatnonzero(missing), None)
        return res.cast(dtype)

    def over(self, values: pl.Series | np.ndarray, how: Agg, *, ddof: int = 1) -> pl.Series:
        """:meth:`reduce` broadcast back to the frame's rows (polars ``.over(keys)``)."""
        return self.reduce(values, how, ddof=ddof).gather(self.index)

    def agg(
        self,
        df: pl.DataFrame,
        floats: Mapping[str, tuple[str, Agg]] | None = None,
        *,
        exact: Sequence[pl.Expr] = (),
        ddof: int = 1,
    ) -> pl.DataFrame:
        """Per group of ``df`` (the frame these groups were made from): the key columns, the
        ``exact`` expressions (evaluated by polars per group), then for each ``name: (column,
        how)`` of ``floats`` a column ``name``, ``how`` of ``column``. Sorted by the keys."""
        out = self.keys
        if exact:
            ex = (
                df.with_columns(pl.Series(_INDEX, self.index))
                .group_by(_INDEX)
                .agg(*exact)
                .sort(_INDEX)
                .drop(_INDEX)
            )
            out = out.hstack(ex)
        cols = [
            self.reduce(df[col], how, ddof=ddof).alias(name)
            for name, (col, how) in (floats or {}).items()
        ]
        return out.hstack(cols) if cols else out


def maneuver_keys(frame: pl.DataFrame) -> np.ndarray:
    """Each row's maneuver as an integer for the engine: the dense rank (1, 2, ...) of
    ``maneuver_id`` as text, a contiguous ``uint64`` array (the engine compares and groups
    integers; comparing and grouping 10^5 strings costs a quarter second)."""
    return np.ascontiguousarray(
        frame["maneuver_id"].cast(pl.Utf8).rank("dense").cast(pl.UInt64).to_numpy()
    )


def _dense_rank(col: pl.Series) -> tuple[np.ndarray, int]:
    """Per row of ``col``, the dense rank of its value among the column's distinct values in
    polars' sort order (1, 2, ...; null 0, first as in a polars sort), and the number of
    distinct non-null values: polars' ``rank("dense")`` (NaN with NaN after every number,
    ``-0.0`` with ``0.0``).

    Without a sort where it can: whole numbers spanning at most a few times the row count
    (alpha bins, flap settings in whole degrees) index a table over the span; strings are
    coded by their sorted distinct values (a hash lookup). Anything else takes the rank."""
    n = col.len()
    valid = col.is_not_null().to_numpy()
    nonnull = int(np.count_nonzero(valid))
    if nonnull == 0:
        return np.zeros(n, dtype=np.int64), 0
    offset: np.ndarray | None = None
    span = 0
    if col.dtype.is_integer():
        lo, hi = col.min(), col.max()
        if isinstance(lo, int) and isinstance(hi, int) and hi - lo < 4 * n:
            span = hi - lo + 1
            c = col.drop_nulls()
            # in a dtype that holds both the values and their offset from the smallest
            c = c if c.dtype == pl.UInt64 else c.cast(pl.Int64)
            offset = (c - lo).cast(pl.Int64).to_numpy()
    elif col.dtype.is_float():
        v = col.drop_nulls().cast(pl.Float64).to_numpy()
        if np.isfinite(v).all() and (v == np.floor(v)).all():
            lo_f = float(v.min())
            if v.max() - lo_f < 4 * n:
                span = int(v.max() - lo_f) + 1
                offset = (v - lo_f).astype(np.int64)
    elif col.dtype == pl.String:
        cats = col.drop_nulls().unique().sort()
        r = col.cast(pl.Enum(cats)).to_physical().cast(pl.Int64).fill_null(-1).to_numpy()
        out = np.zeros(n, dtype=np.int64)
        out[valid] = r[valid] + 1
        return out, cats.len()
    if offset is None:
        r = col.rank("dense").fill_null(0).cast(pl.Int64).to_numpy()
        return r, int(r.max(initial=0))
    present = np.zeros(span, dtype=bool)
    present[offset] = True
    out = np.zeros(n, dtype=np.int64)
    out[valid] = np.cumsum(present)[offset]
    return out, int(present.sum())


def group_agg(
    df: pl.DataFrame,
    keys: Sequence[str],
    floats: Mapping[str, tuple[str, Agg]] | None = None,
    *,
    exact: Sequence[pl.Expr] = (),
    ddof: int = 1,
) -> pl.DataFrame:
    """``df.group_by(keys).agg(...)`` with the float aggregations summed in row order.

    Parameters
    ----------
    df
        The rows.
    keys
        Key columns (any sortable dtype; nulls and NaN form groups of their own).
    floats
        Output column -> (input column, ``"sum"`` | ``"mean"`` | ``"std"`` | ``"var"``); the
        input is a float (or integer, boolean) column, the output ``Float64`` (``Float32`` for
        ``Float32``) in the input's unit (squared for ``var``).
    exact
        Polars expressions whose result does not depend on the order of the additions
        (``pl.len()``, ``min``, ``max``, ``median``, ``first``, integer sums...), evaluated per
        group by polars.
    ddof
        Delta degrees of freedom of ``std`` and ``var`` (polars' default 1).

    Returns
    -------
    polars.DataFrame
        One row per group, sorted by the keys: the keys, the ``exact`` columns, the ``floats``
        columns in the order given.
    """
    return Groups.of(df, keys).agg(df, floats, exact=exact, ddof=ddof)
