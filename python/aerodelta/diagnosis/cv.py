"""Cross-validated least squares over candidate effects, from per-maneuver sufficient statistics.

The gap ``y = C_meas - C_sim`` of one coefficient is modelled as a sum of candidate effects.
An alpha-dependent (aerodynamic) regressor ``x_r`` enters as ``theta_{f,k,r} h_k(alpha) x_r``
with ``h_k`` the piecewise-linear hat functions on a knot grid in alpha (per flap ``f``): the
continuous counterpart of the thesis's per-bin Δ parameters (Section 3.3, Eq. 3.10); a global
(measurement) regressor enters with one parameter. Every fit is equation-error least squares.

Each maneuver's rows are reduced once to ``G_m = D_m' D_m``, ``b_m = D_m' y_m`` and
``y_m' y_m`` over its flap's columns. A fold's training normal equations are then the total
minus the fold's, and the held-out squared error of maneuver ``m`` under parameters ``theta``
is ``y_m'y_m - 2 theta' b_m + theta' G_m theta``: cross-validation by maneuver (never by
sample: neighbouring samples are correlated) costs one small solve per fold.

``G_m`` is never held dense. A row touches only two neighbouring knots (the hat basis), so
``G_m`` is block-tridiagonal in the knots: per knot an ``R x R`` block, per pair of
neighbouring knots one more, per knot an ``R x Gn`` block against the global columns, and
the ``Gn x Gn`` global block (:class:`Design`), ``2 K R^2 + K R Gn + Gn^2`` numbers per
maneuver instead of ``(K R + Gn)^2`` (about 150 kB instead of 2.9 MB for C_l on a 1-deg
grid). Profiling out per-maneuver nuisance columns (:func:`profile_out`) adds a low-rank
term, ``G_m = band_m - F_m F_m'``. The quadratic forms of the held-out errors are evaluated
on these blocks directly, for all maneuvers of a fold at once.

The numerics run in the engine, ``aero_core::hatcv``: the reduction of the rows to the blocks
(:func:`build_design`), the penalised solves (:func:`solve`), the folds' fits and held-out
errors (:func:`heldout_sse`) and the quadratic forms (:func:`model_sse`); the sign-flip tests'
draws in ``aero_core::signflip``. This module holds the layout and drives them.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from aerodelta import _core

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True)
class HatGrid:
    """Knots in alpha, deg: ``k0 + step * [0, 1, ..., n-1]``."""

    k0: float
    step: float
    n: int

    @classmethod
    def covering(cls, alpha_deg: FloatArray, step: float) -> HatGrid:
        """The grid of spacing ``step`` covering ``alpha_deg``."""
        lo = float(np.floor(np.nanmin(alpha_deg) / step) * step)
        hi = float(np.ceil(np.nanmax(alpha_deg) / step) * step)
        n = max(2, round((hi - lo) / step) + 1)
        return cls(lo, step, n)

    def locate(self, alpha_deg: FloatArray) -> tuple[IntArray, FloatArray]:
        """Interval index ``j`` (knots ``j, j+1``) and the weight of knot ``j+1``."""
        u = (alpha_deg - self.k0) / self.step
        j = np.clip(np.floor(u), 0, self.n - 2).astype(np.int64)
        w1 = np.clip(u - j, 0.0, 1.0)
        return j, w1

    @property
    def knots(self) -> FloatArray:
        """Knot positions, deg."""
        return self.k0 + self.step * np.arange(self.n)


@dataclass
class Design:
    """Per-maneuver sufficient statistics of one coefficient's gap over all candidate columns.

    Local layout (one per flap; a maneuver has one flap): alpha-dependent columns ``k*R + r``
    (``K`` knots, ``R`` aerodynamic regressors), then the ``Gn`` global columns, which are
    shared by every flap.

    ``G_m``, the Gram matrix of maneuver ``m`` on the local layout, is held as its non-zero
    blocks (the hat basis makes it block-tridiagonal in the knots), regressor-pair major so
    that a model's regressors are contiguous runs over the knots:

    - ``diag[m, r, s, k]``: ``G_m[k*R + r, k*R + s]``;
    - ``off[m, r, s, k]``: ``G_m[k*R + r, (k+1)*R + s]`` (its transpose below the diagonal);
    - ``cross[m, r, g, k]``: ``G_m[k*R + r, K*R + g]``;
    - ``glob[m, g, h]``: ``G_m[K*R + g, K*R + h]``;
    - ``lowrank`` (``n_local x r``, or ``None``) and ``lowrank_of`` (``r``): the columns of
      every maneuver's ``F_m`` side by side and the maneuver of each, ``G_m = blocks - F_m F_m'``
      (the per-maneuver nuisance profiled out, :func:`profile_out`).
    - ``block_rows`` (or ``None``): the row of each maneuver in ``diag``, ``off``, ``cross``
      and ``glob``; a :meth:`subset` shares those four with the design it is taken from (they
      are most of its memory) and reads its maneuvers' rows through it.

    :meth:`dense_gram` (and the ``gram`` view) writes one out in full.
    """

    grid: HatGrid
    n_flaps: int
    aero_names: list[str]
    global_names: list[str]
    man_flap: IntArray  # flap index per maneuver
    diag: FloatArray  # (M, R, R, K)
    off: FloatArray  # (M, R, R, K-1)
    cross: FloatArray  # (M, R, Gn, K)
    glob: FloatArray  # (M, Gn, Gn)
    xty: FloatArray  # (M, n_local), local layout
    yty: FloatArray
    n_rows: IntArray
    lowrank: FloatArray | None = None  # (n_local, r): F_m of every maneuver, side by side
    lowrank_of: IntArray | None = None  # (r,): the maneuver of each column, ascending
    block_rows: IntArray | None = None  # (M,): each maneuver's row in diag/off/cross/glob

    def block_index(self, maneuvers: IntArray) -> IntArray:
        """The rows of ``maneuvers`` (indices of this design's) in the block arrays."""
        return maneuvers if self.block_rows is None else self.block_rows[maneuvers]

    @property
    def n_local(self) -> int:
        """Columns of one flap's local layout."""
        return self.grid.n * len(self.aero_names) + len(self.global_names)

    @property
    def n_maneuvers(self) -> int:
        """Maneuvers (rows of the per-maneuver statistics)."""
        return int(self.yty.size)

    @property
    def nbytes(self) -> int:
        """Bytes of the per-maneuver statistics (of a :meth:`subset`, its maneuvers' blocks
        count, which the design it was taken from holds)."""
        arrays = [self.xty, self.yty, self.n_rows]
        if self.lowrank is not None and self.lowrank_of is not None:
            arrays += [self.lowrank, self.lowrank_of]
        blocks = [self.diag, self.off, self.cross, self.glob]
        if self.block_rows is None:
            arrays += blocks
        else:
            arrays.append(self.block_rows)
        own = sum(a.nbytes for a in arrays)
        if self.block_rows is not None:
            own += self.n_maneuvers * sum(a[:1].nbytes for a in blocks)
        return int(own)

    def gram_sum(self, maneuvers: IntArray) -> FloatArray:
        """``sum_m G_m`` over ``maneuvers`` (indices), dense on the local layout
        (``aero_core::hatcv::gram_sum``)."""
        g, _ = _core.hat_gram_sum(
            _block_args(self), _layout(self), np.asarray(maneuvers, dtype=np.int64).ravel()
        )
        return g.reshape(self.n_local, self.n_local)

    def dense_gram(self, m: int) -> FloatArray:
        """``G_m`` written out on the local layout (``n_local x n_local``)."""
        return self.gram_sum(np.array([m], dtype=np.int64))

    def gram_diagonals(self) -> FloatArray:
        """``diag(G_m)`` per maneuver, ``(M, n_local)``."""
        r_n, g_n = len(self.aero_names), len(self.global_names)
        ar, ag = np.arange(r_n), np.arange(g_n)
        if self.block_rows is None:
            aero = self.diag[:, ar, ar, :]  # (M, R, K)
            glob = self.glob[:, ag, ag]
        else:
            br = self.block_rows[:, None]
            aero = self.diag[br, ar, ar]  # (M, R, K): the same values, the same layout
            glob = self.glob[br, ag, ag]
        out = np.concatenate([aero.transpose(0, 2, 1).reshape(self.n_maneuvers, -1), glob], axis=1)
        if self.lowrank is not None and self.lowrank_of is not None:
            np.subtract.at(out, self.lowrank_of, (self.lowrank * self.lowrank).T)
        return out

    def subset(self, maneuvers: IntArray) -> Design:
        """The statistics of ``maneuvers`` only (ascending indices), renumbered ``0..``: the
        design an outer fold's selection sees (:mod:`aerodelta.diagnosis.nested`). It shares
        the Gram blocks with this design (``block_rows``: no copy of them)."""
        idx = np.asarray(maneuvers, dtype=np.int64)
        if idx.size > 1 and np.any(np.diff(idx) <= 0):
            raise ValueError("Design.subset: maneuver indices must be ascending and distinct")
        lowrank, lowrank_of = None, None
        if self.lowrank is not None and self.lowrank_of is not None:
            keep = np.isin(self.lowrank_of, idx)
            if keep.any():
                lowrank = np.ascontiguousarray(self.lowrank[:, keep])
                lowrank_of = np.searchsorted(idx, self.lowrank_of[keep]).astype(np.int64)
        return Design(
            self.grid,
            self.n_flaps,
            list(self.aero_names),
            list(self.global_names),
            self.man_flap[idx],
            self.diag,
            self.off,
            self.cross,
            self.glob,
            self.xty[idx],
            self.yty[idx],
            self.n_rows[idx],
            lowrank,
            lowrank_of,
            self.block_index(idx),
        )

    def restrict(self, aero: Sequence[str], glob: Sequence[str]) -> Design:
        """This design on the regressors ``aero`` and ``glob`` only (kept in this design's
        order; its own copy of their blocks). A model on those regressors has the same fits
        and errors here as in the full design (each regressor's penalty is scaled by its own
        Gram diagonal), at the cost of its columns only: the per-flap test of
        :mod:`aerodelta.diagnosis.flaps` sums the statistics of one model, not of the pool."""
        ra = np.array(sorted(self.aero_names.index(a) for a in aero), dtype=np.int64)
        rg = np.array(sorted(self.global_names.index(g) for g in glob), dtype=np.int64)
        k_n, r_n = self.grid.n, len(self.aero_names)
        old = np.concatenate(
            [(np.arange(k_n)[:, None] * r_n + ra[None, :]).ravel(), k_n * r_n + rg]
        )
        rows = self.block_index(np.arange(self.n_maneuvers))
        lowrank = None if self.lowrank is None else np.ascontiguousarray(self.lowrank[old])
        return Design(
            self.grid,
            self.n_flaps,
            [self.aero_names[i] for i in ra],
            [self.global_names[i] for i in rg],
            self.man_flap.copy(),
            self.diag[rows][:, ra][:, :, ra],
            self.off[rows][:, ra][:, :, ra],
            self.cross[rows][:, ra][:, :, rg],
            self.glob[rows][:, rg][:, :, rg],
            self.xty[:, old],
            self.yty.copy(),
            self.n_rows.copy(),
            lowrank,
            None if self.lowrank_of is None else self.lowrank_of.copy(),
        )

    def owning(self) -> Design:
        """This design with its own copy of its maneuvers' Gram blocks (itself if it has
        them)."""
        if self.block_rows is None:
            return self
        br = self.block_rows
        return replace(
            self, diag=self.diag[br], off=self.off[br], cross=self.cross[br],
            glob=self.glob[br], block_rows=None,
        )  # fmt: skip

    @property
    def gram(self) -> Sequence[FloatArray]:
        """``G_m`` per maneuver, each written out dense when it is read (for checks)."""
        return _DenseGrams(self)


class _DenseGrams(Sequence[FloatArray]):
    """Read-only sequence of a design's per-maneuver Gram matrices, built on access."""

    def __init__(self, design: Design) -> None:
        self._d = design

    def __len__(self) -> int:
        return self._d.n_maneuvers

    def __getitem__(self, m: int) -> FloatArray:  # type: ignore[override]
        if not -len(self) <= m < len(self):
            raise IndexError(m)
        return self._d.dense_gram(m % len(self))

    def __iter__(self) -> Iterator[FloatArray]:
        return (self._d.dense_gram(m) for m in range(len(self)))


@dataclass(frozen=True)
class SparseColumns:
    """Columns that are zero but on a few rows (a roll-off event's nuisance columns live on
    its maneuver's rows near the spike): per column, the rows and the values there."""

    n_rows: int
    rows: list[IntArray]
    values: list[FloatArray]

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, columns)`` of the matrix they stand for."""
        return self.n_rows, len(self.rows)

    def dense(self) -> FloatArray:
        """The columns written out, ``n_rows x columns``."""
        out = np.zeros(self.shape)
        for j, (r, v) in enumerate(zip(self.rows, self.values, strict=True)):
            out[r, j] = v
        return out


def build_design(  # noqa: PLR0917 - the reduction's inputs, all positional by design
    y: FloatArray,
    maneuver: IntArray,
    flap: IntArray,
    alpha_deg: FloatArray,
    aero: FloatArray,
    glob: FloatArray | Sequence[FloatArray | SparseColumns],
    aero_names: list[str],
    global_names: list[str],
    grid: HatGrid,
    n_maneuvers: int,
    n_flaps: int,
) -> Design:
    """Reduce the rows to per-maneuver ``G_m``, ``b_m``, ``y_m'y_m`` (block form, see
    :class:`Design`) in the engine (``aero_core::hatcv::build_blocks``: rows grouped by
    maneuver and knot interval, maneuvers reduced in parallel, no dense design formed).

    Parameters
    ----------
    y
        Gap per row.
    maneuver, flap
        Maneuver code (``0..n_maneuvers-1``) and flap index per row; a maneuver has one flap.
    alpha_deg
        Angle of attack per row, deg.
    aero, glob
        Aerodynamic (``n x R``) and global (``n x Gn``) regressor columns; ``glob`` may be
        given as blocks of columns side by side (not copied into one matrix), dense or
        :class:`SparseColumns`.
    """
    blocks = [glob] if isinstance(glob, np.ndarray) else list(glob)
    parts: list[Any] = []
    for b in blocks:
        if isinstance(b, SparseColumns):
            parts += [
                (np.asarray(r, dtype=np.int64), np.ascontiguousarray(v, dtype=np.float64))
                for r, v in zip(b.rows, b.values, strict=True)
            ]
        else:
            parts.append(np.ascontiguousarray(np.asarray(b, dtype=np.float64).reshape(len(y), -1)))
    r_n, g_n = aero.shape[1], sum(b.shape[1] for b in blocks)
    k_n, m_n = grid.n, n_maneuvers
    maneuver = np.asarray(maneuver, dtype=np.int64)
    diag, off, cross, gl, xty, yty = _core.hat_build(
        np.ascontiguousarray(y, dtype=np.float64),
        maneuver,
        np.ascontiguousarray(alpha_deg, dtype=np.float64),
        np.ascontiguousarray(aero, dtype=np.float64),
        parts,
        (float(grid.k0), float(grid.step), int(k_n)),
        int(m_n),
    )
    man_flap = np.zeros(m_n, dtype=np.int64)
    man_flap[maneuver] = flap  # a maneuver has one flap
    n_rows = np.bincount(maneuver, minlength=m_n)[:m_n].astype(np.int64)
    return Design(
        grid, n_flaps, list(aero_names), list(global_names), man_flap,
        diag.reshape(m_n, r_n, r_n, k_n), off.reshape(m_n, r_n, r_n, k_n - 1),
        cross.reshape(m_n, r_n, g_n, k_n), gl.reshape(m_n, g_n, g_n),
        xty.reshape(m_n, k_n * r_n + g_n), yty, n_rows,
    )  # fmt: skip


def profile_out(design: Design, n_nuisance: int) -> Design:
    """Remove per-maneuver nuisance columns from the statistics (Frisch-Waugh-Lovell).

    The last ``n_nuisance`` global columns of ``design`` are nuisance regressors whose
    amplitudes are free *per maneuver* (a roll-off event's moment: a random draw, Section
    3.4.3). Each maneuver's ``G``, ``b``, ``y'y`` are replaced by those of its data projected
    off its own nuisance columns, ``G_DD - G_DN G_NN^+ G_ND`` and so on: every later fit,
    held-out or not, is then the fit with each maneuver's nuisance amplitudes estimated from
    that maneuver alone. Columns a maneuver does not use (all zero) drop out of ``G_NN^+``.

    ``G_DN G_NN^+ G_ND`` is kept as ``F F'`` with ``F = G_DN V L^{-1/2}`` (``V L V'`` the
    eigendecomposition of ``G_NN`` over the eigenvalues ``G_NN^+`` keeps: those above
    ``1e-10`` of the largest; a Gram matrix has no negative ones beyond rounding). Computed in
    the engine (``aero_core::hatcv::profile_out``).
    """
    if n_nuisance <= 0:
        return design
    if design.lowrank is not None:
        raise ValueError("profile_out: this design's nuisance columns were profiled out already")
    design = design.owning()
    k_n, r_n = design.grid.n, len(design.aero_names)
    g_keep = len(design.global_names) - n_nuisance
    p_keep = k_n * r_n + g_keep
    xty_f, yty, fac, owner = _core.hat_profile_out(_block_args(design), _layout(design), n_nuisance)
    xty = xty_f.reshape(design.n_maneuvers, p_keep)
    lowrank, lowrank_of = None, None
    if owner.size:
        lowrank = fac.reshape(p_keep, owner.size)
        lowrank_of = owner
    return Design(
        design.grid,
        design.n_flaps,
        list(design.aero_names),
        list(design.global_names[:g_keep]),
        design.man_flap.copy(),
        design.diag,  # shared: the nuisance columns are global ones
        design.off,
        np.ascontiguousarray(design.cross[:, :, :g_keep, :]),
        np.ascontiguousarray(design.glob[:, :g_keep, :g_keep]),
        xty,
        yty,
        design.n_rows.copy(),
        lowrank,
        lowrank_of,
    )


#: Ridge on each alpha-dependent parameter, relative to its regressor's mean excitation in the
#: flap: a knot the data barely reach is pulled to zero (no correction) instead of extrapolated.
RIDGE_REL = 0.01
#: Second-difference (roughness) penalty along the knots, relative to the same scale: the
#: per-bin parameters of the thesis are smoothed in alpha (Eq. 3.13); this is its analogue.
SMOOTH_REL = 0.1


def penalty(design: Design) -> list[FloatArray]:
    """Per flap, the penalty matrix on its local layout (ridge + roughness along alpha, each
    regressor scaled by its mean diagonal over the flap's data; none on global columns)."""
    k_n, r_n = design.grid.n, len(design.aero_names)
    d2 = np.diff(np.eye(k_n), n=2, axis=0)
    rough = d2.T @ d2
    diags = design.gram_diagonals()
    out = []
    for f in range(design.n_flaps):
        diag = diags[design.man_flap == f].sum(axis=0)
        pen = np.zeros((design.n_local, design.n_local))
        for r in range(r_n):
            idx = np.arange(k_n) * r_n + r
            scale = float(diag[idx].mean())
            if scale <= 0:
                continue
            pen[np.ix_(idx, idx)] += scale * (RIDGE_REL * np.eye(k_n) + SMOOTH_REL * rough)
        out.append(pen)
    return out


@dataclass
class FoldStats:
    """Per fold and flap, the normal equations on the flap's local layout (training = total
    minus the fold's), with the penalty added to the training ones; stacked, C order, as
    the engine (``aero_core::hatcv``) reads them.

    ``memo`` keeps the solves already made on these statistics, by model columns
    (:func:`fold_solves`, :func:`total_solve`, :func:`heldout_sse`): the selection meets the
    same model several times (a timing term scored by leaving it out of the model of the last
    step, the held-out predictions of the chosen models, the outer folds' scoring), and a
    solve repeated on the same numbers gives the same numbers."""

    folds: IntArray  # fold per maneuver
    train_gram: FloatArray  # (Q, F, p, p): per fold and flap, penalised
    train_xty: FloatArray  # (Q, F, p)
    total_gram: FloatArray  # (F, p, p), penalised
    total_xty: FloatArray  # (F, p)
    memo: dict[tuple[str, bytes, bytes], tuple[Design, object]] = field(
        default_factory=dict, repr=False, compare=False
    )


def _memoised(
    design: Design, stats: FoldStats, what: str, cols: tuple[IntArray, IntArray], make: Any
) -> Any:
    """``make()`` for ``what`` on ``cols`` of ``design``, computed once per ``stats``."""
    key = (
        what,
        np.asarray(cols[0], dtype=np.int64).tobytes(),
        np.asarray(cols[1], dtype=np.int64).tobytes(),
    )
    hit = stats.memo.get(key)
    if hit is not None and hit[0] is design:
        return hit[1]
    value = make()
    stats.memo[key] = (design, value)
    return value


def fold_solves(
    design: Design, stats: FoldStats, cols: tuple[IntArray, IntArray]
) -> list[list[FloatArray]]:
    """Per fold, the per-flap parameters of the model on ``cols`` fitted on the fold's
    complement (penalised least squares on the training statistics, computed with the
    held-out errors by :func:`heldout_sse`; shared, do not modify)."""
    return list(_memoised(design, stats, "heldout", cols, lambda: _heldout(design, stats, cols))[1])


def total_solve(
    design: Design, stats: FoldStats, cols: tuple[IntArray, IntArray]
) -> list[FloatArray]:
    """The per-flap parameters of the model on ``cols`` fitted on all the maneuvers
    (:func:`solve` on the penalised totals; shared, do not modify)."""
    return _memoised(
        design, stats, "total", cols,
        lambda: _solve_stacked(design, stats.total_gram, stats.total_xty, cols),
    )  # fmt: skip


def fold_stats(design: Design, folds: IntArray) -> FoldStats:
    """Sum the maneuvers' statistics per fold and flap."""
    n_q = int(folds.max()) + 1 if folds.size else 1
    n_f, p = design.n_flaps, design.n_local
    g_flat, x_flat = _core.hat_fold_sums(
        _block_args(design), _layout(design), np.asarray(folds, dtype=np.int64),
        np.asarray(design.man_flap, dtype=np.int64), n_q, n_f,
    )  # fmt: skip
    g = g_flat.reshape(n_q, n_f, p, p)
    x = x_flat.reshape(n_q, n_f, p)
    pen = np.stack(penalty(design)) if n_f else np.zeros((0, p, p))
    tg = g.sum(axis=0)
    tx = x.sum(axis=0)
    # training = total - the fold's (+ the penalty), in place over the fold sums
    np.subtract(tg[None], g, out=g)
    g += pen[None]
    np.subtract(tx[None], x, out=x)
    return FoldStats(folds, g, x, tg + pen, tx)


def local_columns(
    design: Design, aero: Sequence[str], glob: Sequence[str]
) -> tuple[IntArray, IntArray]:
    """Local-layout columns (alpha-dependent, global) of the given regressors."""
    k, r = design.grid.n, len(design.aero_names)
    ridx = sorted(design.aero_names.index(a) for a in aero)
    a_cols = np.array([kk * r + ri for kk in range(k) for ri in ridx], dtype=np.int64)
    g_cols = np.array(sorted(k * r + design.global_names.index(x) for x in glob), dtype=np.int64)
    return a_cols, g_cols


def _layout(design: Design) -> tuple[int, int, int]:
    """``(knots, aerodynamic regressors, global regressors)`` of the local layout."""
    return design.grid.n, len(design.aero_names), len(design.global_names)


def _block_args(design: Design) -> tuple[Any, ...]:
    """The design's per-maneuver statistics as the engine reads them (C-contiguous; no copy
    when they already are)."""

    def c(a: Any, dtype: Any = np.float64) -> Any:
        return None if a is None else np.ascontiguousarray(a, dtype=dtype)

    return (
        c(design.diag), c(design.off), c(design.cross), c(design.glob), c(design.xty),
        c(design.yty), c(design.block_rows, np.int64), c(design.lowrank),
        c(design.lowrank_of, np.int64),
    )  # fmt: skip


def _cols64(cols: tuple[IntArray, IntArray]) -> tuple[IntArray, IntArray]:
    return np.asarray(cols[0], dtype=np.int64), np.asarray(cols[1], dtype=np.int64)


def _solve_stacked(
    design: Design, grams: FloatArray, xtys: FloatArray, cols: tuple[IntArray, IntArray]
) -> list[FloatArray]:
    """:func:`solve` on stacked per-flap statistics (``(F, p, p)``, ``(F, p)``)."""
    out = _core.hat_solve(
        np.ascontiguousarray(grams), np.ascontiguousarray(xtys), _layout(design), *_cols64(cols)
    )
    return list(out.reshape(grams.shape[0], design.n_local))


def solve(
    design: Design,
    grams: Sequence[FloatArray],
    xtys: Sequence[FloatArray],
    cols: tuple[IntArray, IntArray],
) -> list[FloatArray]:
    """Penalised least squares on the columns ``cols``; per flap, the local parameter vector.

    The flaps' alpha-dependent blocks are independent given the global parameters, so the
    system is solved by the Schur complement of the global block (per flap a Cholesky solve
    of its alpha-dependent block, then one small least-squares solve for the global
    parameters): ``aero_core::hatcv::penalised_solve``.
    """
    return _solve_stacked(design, np.stack(list(grams)), np.stack(list(xtys)), cols)


def _quadratic_forms(
    design: Design, ms: IntArray, theta: FloatArray, cols: tuple[IntArray, IntArray]
) -> FloatArray:
    """``theta' G_m theta - 2 theta' b_m`` for each maneuver in ``ms`` (one flap's local
    ``theta``, zero off ``cols``), from the blocks of :class:`Design`
    (``aero_core::hatcv::quadratic_forms``)."""
    return _core.hat_quadratic_forms(
        _block_args(design),
        _layout(design),
        np.asarray(ms, dtype=np.int64),
        np.ascontiguousarray(theta, dtype=np.float64),
        *_cols64(cols),
    )


def model_sse(
    design: Design,
    maneuvers: IntArray,
    thetas: Sequence[FloatArray],
    cols: tuple[IntArray, IntArray],
) -> FloatArray:
    """Squared error of the model ``thetas`` (per flap, on ``cols``) on each of ``maneuvers``
    (indices into ``design``), in their order: ``y'y - 2 theta'b + theta'G theta``."""
    ms = np.asarray(maneuvers, dtype=np.int64)
    out = design.yty[ms].astype(float)
    if sum(c.size for c in cols) == 0:
        return out
    for f in range(design.n_flaps):
        sel = np.flatnonzero(design.man_flap[ms] == f)
        if sel.size:
            order = np.argsort(ms[sel], kind="stable")
            mf = ms[sel][order]
            out[sel[order]] += _quadratic_forms(design, mf, thetas[f], cols)
    return out


def heldout_sse(
    design: Design, stats: FoldStats, cols: tuple[IntArray, IntArray]
) -> tuple[FloatArray, list[list[FloatArray]]]:
    """Held-out squared error per maneuver of the model on ``cols`` (each maneuver predicted by
    the fit on the other folds), and each fold's per-flap parameters (shared, do not modify)."""
    sse, thetas = _memoised(design, stats, "heldout", cols, lambda: _heldout(design, stats, cols))
    return sse.copy(), list(thetas)


def _heldout(
    design: Design, stats: FoldStats, cols: tuple[IntArray, IntArray]
) -> tuple[FloatArray, list[list[FloatArray]]]:
    """Each fold's fit and its maneuvers' held-out errors, in the engine
    (``aero_core::hatcv::held_out``)."""
    sse, th = _core.hat_held_out(
        _block_args(design),
        _layout(design),
        stats.train_gram,
        stats.train_xty,
        np.asarray(stats.folds, dtype=np.int64),
        np.asarray(design.man_flap, dtype=np.int64),
        design.n_flaps,
        *_cols64(cols),
    )
    th = th.reshape(stats.train_xty.shape)
    return sse, [list(tq) for tq in th]


def fold_prediction(  # noqa: PLR0917 - rows' columns, positional by design
    design: Design,
    thetas: Sequence[Sequence[FloatArray]],
    fold: IntArray,
    flap: IntArray,
    alpha_deg: FloatArray,
    aero: FloatArray,
    glob: FloatArray,
) -> FloatArray:
    """:func:`row_prediction` of each row with its fold's parameters (``thetas[fold][flap]``),
    :data:`PREDICT_ROWS` rows at a time."""
    k_n, r_n = design.grid.n, len(design.aero_names)
    kr = k_n * r_n
    th = np.stack([np.stack([t[:kr].reshape(k_n, r_n) for t in tq]) for tq in thetas])
    used = np.flatnonzero(np.any(th != 0.0, axis=(0, 1, 2)))
    tu = th[..., used]
    out = np.zeros(alpha_deg.size)
    for sl in _row_chunks(alpha_deg.size):
        fo, fl = fold[sl], flap[sl]
        o = out[sl]
        if used.size:
            j, w1 = design.grid.locate(alpha_deg[sl])
            coef = tu[fo, fl, j] * (1.0 - w1)[:, None] + tu[fo, fl, j + 1] * w1[:, None]
            o[:] = np.einsum("nr,nr->n", coef, aero[sl][:, used])
        if glob.shape[1]:
            g = glob[sl]
            for q, tq in enumerate(thetas):
                m = fo == q
                o[m] += g[m] @ tq[0][kr:]
    return out


def row_prediction(  # noqa: PLR0917 - rows' columns, positional by design
    design: Design,
    thetas: Sequence[FloatArray],
    flap: IntArray,
    alpha_deg: FloatArray,
    aero: FloatArray,
    glob: FloatArray,
) -> FloatArray:
    """The model ``sum theta * column`` at each row (``thetas``: per-flap local vectors),
    :data:`PREDICT_ROWS` rows at a time."""
    k_n, r_n = design.grid.n, len(design.aero_names)
    th = np.stack([t[: k_n * r_n].reshape(k_n, r_n) for t in thetas])
    # only the regressors the model uses (the others' parameters are all zero)
    used = np.flatnonzero(np.any(th != 0.0, axis=(0, 1)))
    tu = th[:, :, used]
    out = np.zeros(alpha_deg.size)
    for sl in _row_chunks(alpha_deg.size):
        o = out[sl]
        if used.size:
            fl = flap[sl]
            j, w1 = design.grid.locate(alpha_deg[sl])
            coef = tu[fl, j] * (1.0 - w1)[:, None] + tu[fl, j + 1] * w1[:, None]
            o[:] = np.einsum("nr,nr->n", coef, aero[sl][:, used])
        if glob.shape[1]:
            o[:] = o + glob[sl] @ thetas[0][k_n * r_n :]
    return out


#: Rows predicted at once by :func:`fold_prediction` and :func:`row_prediction` (bounds their
#: temporaries, a few arrays of this many rows by the model's regressors).
PREDICT_ROWS = 1 << 17


def _row_chunks(n: int) -> Iterator[slice]:
    """Consecutive slices of at most :data:`PREDICT_ROWS` of ``n`` rows."""
    return (slice(lo, min(lo + PREDICT_ROWS, n)) for lo in range(0, n, PREDICT_ROWS))


def _abs_ranks(d: FloatArray) -> FloatArray:
    """Ranks 1..n of ``|d|`` (ties broken by order), the weights of the signed-rank tests."""
    ranks = np.empty(d.size)
    ranks[np.argsort(np.abs(d), kind="stable")] = np.arange(1, d.size + 1)
    return ranks


def sign_flip_pvalue(d: FloatArray, n_perm: int, seed: int) -> tuple[float, float]:
    """One-sided signed-rank randomization test that the per-maneuver improvements ``d`` are
    shifted above zero (Wilcoxon's signed-rank statistic, null by random sign flips).

    Under the null the held-out improvements of independent maneuvers are symmetric about
    zero (or below it: a useless regressor adds variance); ranks keep a few long or noisy
    maneuvers from dominating. Returns ``(z, p)``, ``z`` the statistic's normal score.
    """
    d = _nonzero(d)
    if d.size < 2:
        return 0.0, 1.0
    weights, w, z = _rank_statistic(d)
    return z, _flip_p(weights, w, n_perm, seed)


def _nonzero(d: FloatArray) -> FloatArray:
    """The non-zero improvements (ties with zero carry no sign)."""
    d = np.asarray(d, dtype=np.float64)
    return d[d != 0.0]


def _rank_statistic(d: FloatArray) -> tuple[FloatArray, float, float]:
    """``(weights, w, z)`` of the signed-rank test of non-zero ``d``: the ranks of ``|d|``,
    the signed rank sum and its normal score."""
    ranks = _abs_ranks(d)
    w = float(np.sum(ranks[d > 0]) - np.sum(ranks[d < 0]))
    return ranks, w, w / float(np.sqrt(np.sum(ranks**2)))


def _sum_statistic(d: FloatArray) -> tuple[FloatArray, float, float]:
    """``(weights, w, z)`` of the sum test of non-zero ``d``: ``d`` itself, its sum and the sum
    over its sign-flip standard deviation ``sqrt(sum d^2)``."""
    w = float(d.sum())
    sd = float(np.sqrt(np.sum(d * d)))
    return d, w, (w / sd if sd > 0 else 0.0)


#: Most maneuvers for which :func:`signed_rank_p` computes the exact null distribution (its
#: work grows as n^3: 1.5 ms at 200, 14 ms at 400); beyond, the randomization estimate is used.
EXACT_RANK_MAX_N = 400


def signed_rank_p(d: FloatArray, n_perm: int, seed: int) -> float:
    """One-sided p-value of the statistic of :func:`sign_flip_pvalue` (Wilcoxon's signed
    ranks of the nonzero ``d``), from its exact null distribution under random sign flips.

    With ranks 1..n (no ties: ``d`` is continuous, ties broken by order), the sum W+ of the
    positive ranks has the distribution of a sum of independent terms 0 or k with probability
    1/2 each, built by the recursion ``P_k(w) = (P_{k-1}(w) + P_{k-1}(w - k)) / 2`` (Wilcoxon
    1945; scipy's ``wilcoxon(method="exact")`` for n <= 50). Unlike the randomization estimate
    it has no floor ``1/(draws + 1)``, so p-values far in the tail are resolved. For more
    than :data:`EXACT_RANK_MAX_N` maneuvers the randomization estimate is returned."""
    d = np.asarray(d, dtype=np.float64)
    d = d[d != 0.0]
    n = d.size
    if n < 2:
        return 1.0
    if n > EXACT_RANK_MAX_N:
        return sign_flip_pvalue(d, n_perm, seed)[1]
    w_plus = int(_abs_ranks(d)[d > 0].sum())
    dist = np.zeros(n * (n + 1) // 2 + 1)
    dist[0] = 1.0
    for k in range(1, n + 1):
        # in place on the entries that can be non-zero after k terms (sums up to k(k+1)/2)
        top = k * (k + 1) // 2 + 1
        dist[k:top] += dist[: top - k]  # numpy reads overlapping inputs as if copied first
        dist[:top] *= 0.5
    return float(min(1.0, dist[w_plus:].sum()))


def sign_flip_sum_pvalue(d: FloatArray, n_perm: int, seed: int) -> tuple[float, float]:
    """One-sided sign-flip randomization test on the *sum* of the per-maneuver improvements.

    Exact under the same null as :func:`sign_flip_pvalue` (improvements symmetric about zero),
    but it weighs each maneuver by its improvement instead of its rank, so it sees an effect
    that acts in a minority of maneuvers (a thrust asymmetry present in a quarter of the
    stalls: large gains there, tiny refit losses elsewhere), which the signed ranks miss.
    It stays robust to one dominant maneuver: flipping that maneuver's sign flips the sum, so
    a gain carried by one or two maneuvers cannot reach a small p. Returns ``(z, p)``, ``z``
    the sum over its sign-flip standard deviation ``sqrt(sum d^2)``.
    """
    d = _nonzero(d)
    if d.size < 2:
        return 0.0, 1.0
    weights, w, z = _sum_statistic(d)
    return z, _flip_p(weights, w, n_perm, seed)


def improvement_test(d: FloatArray, n_perm: int, seed: int) -> tuple[float, float]:
    """The selection's test of a held-out improvement: the signed-rank and the sum sign-flip
    tests (:func:`sign_flip_pvalue`, :func:`sign_flip_sum_pvalue`), Bonferroni-combined
    (twice the smaller p). The first has power when many maneuvers improve a little, the
    second when a minority improves a lot. Returns the ``(z, p)`` of the test that decided."""
    return improvement_tests([d], n_perm, [seed])[0]


def improvement_tests(
    ds: Sequence[FloatArray], n_perm: int, seeds: Sequence[int]
) -> list[tuple[float, float]]:
    """:func:`improvement_test` of each ``ds[i]`` with ``seeds[i]``, the randomization draws
    of all of them counted at once (in parallel in the engine): the same numbers as one call
    each."""
    jobs: list[tuple[FloatArray, float, int]] = []
    zs: list[tuple[float, float]] = []
    for d_all, seed in zip(ds, seeds, strict=True):
        d = _nonzero(d_all)
        if d.size < 2:
            zs.append((0.0, 0.0))
            jobs += [(np.zeros(0), 1.0, seed), (np.zeros(0), 1.0, seed + 1)]
            continue
        wt_r, w_r, z_r = _rank_statistic(d)
        wt_s, w_s, z_s = _sum_statistic(d)
        zs.append((z_r, z_s))
        jobs += [(wt_r, w_r, seed), (wt_s, w_s, seed + 1)]
    ps = _flip_ps(jobs, n_perm)
    out = []
    for i, (z_r, z_s) in enumerate(zs):
        p_r, p_s = ps[2 * i], ps[2 * i + 1]
        if p_s < p_r:
            out.append((z_s, min(1.0, 2.0 * p_s)))
        else:
            out.append((z_r, min(1.0, 2.0 * p_r)))
    return out


#: Draws added when a sign-flip p-value lands in the far tail (see :func:`_flip_p`).
TAIL_DRAWS = 10

#: Rows of random signs of one ``Generator.integers`` call of the sign-flip draws.
_DRAW_CALL = 50_000

#: Fewer hits than this in the first draws add the tail draws (see :func:`_flip_p`).
_MIN_TAIL_HITS = 20


def _engine_hits(weights: FloatArray, w: float, n_perm: int, seed: int) -> tuple[int, int]:
    """``(hits, draws)`` of :func:`_flip_p` counted by the engine
    (``aero_core::signflip``) on the PCG64 stream of ``np.random.default_rng(seed)``."""
    st = np.random.default_rng(seed).bit_generator.state["state"]
    return _core.sign_flip_hits(
        np.ascontiguousarray(weights, dtype=np.float64), float(w), int(st["state"]),
        int(st["inc"]), n_perm, _DRAW_CALL, TAIL_DRAWS, _MIN_TAIL_HITS,
    )  # fmt: skip


@functools.cache
def _sign_bytes_match() -> bool:
    """True when the engine's draws are this numpy's ``integers`` signs (checked once:
    ranks, so the sums are exact; maneuver counts with and without a remainder of 8, calls
    ending inside a 32-bit word, the tail extension)."""
    for seed, n, n_perm in ((3, 7, 1001), (11, 203, 1000), (5, 13, 999)):
        weights = np.arange(1.0, n + 1.0)
        for w in (0.0, 0.6 * weights.sum()):
            if _engine_hits(weights, w, n_perm, seed) != _numpy_hits(weights, w, n_perm, seed):
                return False
    return True


def _numpy_hits(weights: FloatArray, w: float, n_perm: int, seed: int) -> tuple[int, int]:
    """``(hits, draws)`` of :func:`_flip_p` with numpy's own ``integers`` signs."""
    rng = np.random.default_rng(seed)
    n = weights.size
    hits, draws, total = 0, 0, n_perm
    while draws < total:
        k = min(total - draws, _DRAW_CALL)
        signs8 = rng.integers(0, 2, size=(k, n), dtype=np.int8) * 2 - 1
        hits += int(np.sum(signs8 @ weights >= w))
        draws += k
        if draws == n_perm and hits < _MIN_TAIL_HITS:
            total = n_perm * TAIL_DRAWS
    return hits, draws


def _flip_p(weights: FloatArray, w: float, n_perm: int, seed: int) -> float:
    """``P(sum(s * weights) >= w)`` under random signs ``s``, by ``n_perm`` seeded draws,
    ``(1 + hits) / (1 + draws)``. When fewer than 20 draws reach ``w`` the estimate is
    mostly its floor ``1/(n_perm + 1)``, which a Bonferroni factor then multiplies: with 20
    candidates and the two combined tests, no effect could reach p < 0.01 at 4,000 draws. So
    ``TAIL_DRAWS - 1`` times as many draws are added (same seed, same answer).

    The signs are those of ``Generator(seed).integers(0, 2, size=(k, n), dtype=np.int8)``
    called for at most :data:`_DRAW_CALL` draws at a time, counted by the engine
    (``aero_core::signflip``, which reads numpy's PCG64 stream; :func:`_numpy_hits`, numpy's
    own draws, if this numpy draws otherwise). The engine adds each draw's signed weights in
    groups of 8, another order than ``signs @ weights``: the same for integer weights (ranks),
    within rounding otherwise."""
    return _flip_ps([(np.asarray(weights, dtype=np.float64), w, seed)], n_perm)[0]


def _flip_ps(jobs: Sequence[tuple[FloatArray, float, int]], n_perm: int) -> list[float]:
    """:func:`_flip_p` of each ``(weights, w, seed)``; in the engine, all at once. An empty
    ``weights`` (fewer than two non-zero improvements) gives 1."""
    live = [i for i, (wt, _, _) in enumerate(jobs) if wt.size]
    out = [1.0] * len(jobs)
    if _sign_bytes_match():
        states = [np.random.default_rng(jobs[i][2]).bit_generator.state["state"] for i in live]
        counts = _core.sign_flip_hits_many(
            [np.ascontiguousarray(jobs[i][0], dtype=np.float64) for i in live],
            [float(jobs[i][1]) for i in live],
            [int(st["state"]) for st in states],
            [int(st["inc"]) for st in states],
            n_perm, _DRAW_CALL, TAIL_DRAWS, _MIN_TAIL_HITS,
        )  # fmt: skip
    else:
        counts = [_numpy_hits(jobs[i][0], jobs[i][1], n_perm, jobs[i][2]) for i in live]
    for i, (hits, draws) in zip(live, counts, strict=True):
        out[i] = (1.0 + hits) / (draws + 1.0)
    return out
