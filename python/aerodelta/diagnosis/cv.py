"""Cross-validated least squares over candidate effects, from per-maneuver sufficient statistics.

The gap ``y = C_meas - C_sim`` of one coefficient is modelled as a sum of candidate effects.
An alpha-dependent (aerodynamic) regressor ``x_r`` enters as ``theta_{f,k,r} h_k(alpha) x_r``
with ``h_k`` the piecewise-linear hat functions on a knot grid in alpha (per flap ``f``): the
continuous counterpart of the thesis's per-bin Δ parameters (Section 3.3, Eq. 3.10); a global
(measurement) regressor enters with one parameter. Every fit is equation-error least squares.

Each maneuver's rows are reduced once to ``G_m = D_m' D_m``, ``b_m = D_m' y_m`` and
``y_m' y_m`` over its flap's columns (the hat basis makes ``D_m`` sparse: only two knots per row
are non-zero, so the reduction costs ``O(n (2R + G)^2)``). A fold's training normal equations
are then the total minus the fold's, and the held-out squared error of maneuver ``m`` under
parameters ``theta`` is ``y_m'y_m - 2 theta' b_m + theta' G_m theta``: cross-validation by
maneuver (never by sample: neighbouring samples are correlated) costs one small solve per fold.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

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
    """

    grid: HatGrid
    n_flaps: int
    aero_names: list[str]
    global_names: list[str]
    man_flap: IntArray  # flap index per maneuver
    gram: list[FloatArray]  # per maneuver, local layout
    xty: list[FloatArray]
    yty: FloatArray
    n_rows: IntArray

    @property
    def n_local(self) -> int:
        """Columns of one flap's local layout."""
        return self.grid.n * len(self.aero_names) + len(self.global_names)


def build_design(  # noqa: PLR0917 - the reduction's inputs, all positional by design
    y: FloatArray,
    maneuver: IntArray,
    flap: IntArray,
    alpha_deg: FloatArray,
    aero: FloatArray,
    glob: FloatArray,
    aero_names: list[str],
    global_names: list[str],
    grid: HatGrid,
    n_maneuvers: int,
    n_flaps: int,
) -> Design:
    """Reduce the rows to per-maneuver ``G_m``, ``b_m``, ``y_m'y_m``.

    Parameters
    ----------
    y
        Gap per row.
    maneuver, flap
        Maneuver code (``0..n_maneuvers-1``) and flap index per row; a maneuver has one flap.
    alpha_deg
        Angle of attack per row, deg.
    aero, glob
        Aerodynamic (``n x R``) and global (``n x Gn``) regressor columns.
    """
    r_n, g_n = aero.shape[1], glob.shape[1]
    k_n = grid.n
    n_local = k_n * r_n + g_n
    j, w1 = grid.locate(alpha_deg)
    w0 = 1.0 - w1
    order = np.lexsort((j, maneuver))
    m_sorted = maneuver[order]
    bounds = np.searchsorted(m_sorted, np.arange(n_maneuvers + 1))
    man_flap = np.zeros(n_maneuvers, dtype=np.int64)
    gram: list[FloatArray] = []
    xty: list[FloatArray] = []
    yty = np.zeros(n_maneuvers)
    n_rows = np.zeros(n_maneuvers, dtype=np.int64)
    for m in range(n_maneuvers):
        rows = order[bounds[m] : bounds[m + 1]]
        g_m = np.zeros((n_local, n_local))
        b_m = np.zeros(n_local)
        if rows.size:
            man_flap[m] = int(flap[rows[0]])
            jm = j[rows]
            cuts = np.flatnonzero(np.diff(jm)) + 1
            for seg in np.split(np.arange(rows.size), cuts):
                rr = rows[seg]
                jj = int(jm[seg[0]])
                xa = aero[rr]
                d = np.hstack([xa * w0[rr, None], xa * w1[rr, None], glob[rr]])
                idx = np.concatenate(
                    [
                        jj * r_n + np.arange(r_n),
                        (jj + 1) * r_n + np.arange(r_n),
                        k_n * r_n + np.arange(g_n),
                    ]
                )
                g_m[np.ix_(idx, idx)] += d.T @ d
                b_m[idx] += d.T @ y[rr]
            yty[m] = float(y[rows] @ y[rows])
            n_rows[m] = rows.size
        gram.append(g_m)
        xty.append(b_m)
    return Design(
        grid, n_flaps, list(aero_names), list(global_names), man_flap, gram, xty, yty, n_rows
    )


def profile_out(design: Design, n_nuisance: int) -> Design:
    """Remove per-maneuver nuisance columns from the statistics (Frisch-Waugh-Lovell).

    The last ``n_nuisance`` global columns of ``design`` are nuisance regressors whose
    amplitudes are free *per maneuver* (a roll-off event's moment: a random draw, Section
    3.4.3). Each maneuver's ``G``, ``b``, ``y'y`` are replaced by those of its data projected
    off its own nuisance columns, ``G_DD - G_DN G_NN^+ G_ND`` and so on: every later fit,
    held-out or not, is then the fit with each maneuver's nuisance amplitudes estimated from
    that maneuver alone. Columns a maneuver does not use (all zero) drop out of ``G_NN^+``.
    """
    if n_nuisance <= 0:
        return design
    p = design.n_local
    keep = p - n_nuisance
    gram, xty, yty = [], [], design.yty.copy()
    for m, (g, b) in enumerate(zip(design.gram, design.xty, strict=True)):
        g_dd, g_dn, g_nn = g[:keep, :keep], g[:keep, keep:], g[keep:, keep:]
        b_d, b_n = b[:keep], b[keep:]
        live = np.diag(g_nn) > 0.0
        if live.any():
            g_nn_l = g_nn[np.ix_(live, live)]
            inv = np.linalg.pinv(g_nn_l, rcond=1e-10, hermitian=True)
            g_dn_l = g_dn[:, live]
            gram.append(g_dd - g_dn_l @ inv @ g_dn_l.T)
            xty.append(b_d - g_dn_l @ (inv @ b_n[live]))
            yty[m] = max(float(design.yty[m] - b_n[live] @ inv @ b_n[live]), 0.0)
        else:
            gram.append(g_dd.copy())
            xty.append(b_d.copy())
    return Design(
        design.grid,
        design.n_flaps,
        list(design.aero_names),
        list(design.global_names[: len(design.global_names) - n_nuisance]),
        design.man_flap.copy(),
        gram,
        xty,
        yty,
        design.n_rows.copy(),
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
    out = []
    for f in range(design.n_flaps):
        diag = np.zeros(design.n_local)
        for m in np.flatnonzero(design.man_flap == f):
            diag += np.diag(design.gram[m])
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
    minus the fold's), with the penalty added to the training ones."""

    folds: IntArray  # fold per maneuver
    train_gram: list[list[FloatArray]]  # [fold][flap]
    train_xty: list[list[FloatArray]]
    total_gram: list[FloatArray]  # [flap], penalised
    total_xty: list[FloatArray]


def fold_stats(design: Design, folds: IntArray) -> FoldStats:
    """Sum the maneuvers' statistics per fold and flap."""
    n_q = int(folds.max()) + 1 if folds.size else 1
    n_f, p = design.n_flaps, design.n_local
    g = np.zeros((n_q, n_f, p, p))
    x = np.zeros((n_q, n_f, p))
    for m, q in enumerate(folds):
        f = design.man_flap[m]
        g[q, f] += design.gram[m]
        x[q, f] += design.xty[m]
    pen = penalty(design)
    tg = g.sum(axis=0)
    tx = x.sum(axis=0)
    train_g = [[tg[f] - g[q, f] + pen[f] for f in range(n_f)] for q in range(n_q)]
    train_x = [[tx[f] - x[q, f] for f in range(n_f)] for q in range(n_q)]
    return FoldStats(
        folds, train_g, train_x, [tg[f] + pen[f] for f in range(n_f)], [tx[f] for f in range(n_f)]
    )


def local_columns(
    design: Design, aero: Sequence[str], glob: Sequence[str]
) -> tuple[IntArray, IntArray]:
    """Local-layout columns (alpha-dependent, global) of the given regressors."""
    k, r = design.grid.n, len(design.aero_names)
    ridx = sorted(design.aero_names.index(a) for a in aero)
    a_cols = np.array([kk * r + ri for kk in range(k) for ri in ridx], dtype=np.int64)
    g_cols = np.array(sorted(k * r + design.global_names.index(x) for x in glob), dtype=np.int64)
    return a_cols, g_cols


def solve(
    design: Design,
    grams: Sequence[FloatArray],
    xtys: Sequence[FloatArray],
    cols: tuple[IntArray, IntArray],
) -> list[FloatArray]:
    """Penalised least squares on the columns ``cols``; per flap, the local parameter vector.

    The flaps' alpha-dependent blocks are independent given the global parameters, so the
    system is solved by the Schur complement of the global block (block-diagonal solves per
    flap, then one small dense solve).
    """
    a_cols, g_cols = cols
    n_f = design.n_flaps
    thetas = [np.zeros(design.n_local) for _ in range(n_f)]
    ng = g_cols.size
    s_mat = np.zeros((ng, ng))
    s_rhs = np.zeros(ng)
    parts = []
    for f in range(n_f):
        gm, xv = grams[f], xtys[f]
        a = gm[np.ix_(a_cols, a_cols)]
        d = np.diag(a)
        live = d > 1e-12 * max(float(d.max()) if d.size else 0.0, 1e-300)
        ac = a_cols[live]
        a = a[np.ix_(live, live)]
        c = gm[np.ix_(ac, g_cols)]
        s_mat += gm[np.ix_(g_cols, g_cols)]
        s_rhs += xv[g_cols]
        if ac.size:
            rhs = np.column_stack([xv[ac], c])
            try:
                sol = np.linalg.solve(a, rhs)
            except np.linalg.LinAlgError:
                sol = np.linalg.lstsq(a, rhs, rcond=None)[0]
            s_mat -= c.T @ sol[:, 1:]
            s_rhs -= c.T @ sol[:, 0]
        else:
            sol = np.zeros((0, ng + 1))
        parts.append((ac, sol))
    th_g = np.zeros(ng)
    if ng:
        dg = np.diag(s_mat)
        livg = dg > 1e-12 * max(float(np.abs(dg).max()), 1e-300)
        if livg.any():
            sm = s_mat[np.ix_(livg, livg)]
            th_g[livg] = np.linalg.lstsq(sm, s_rhs[livg], rcond=None)[0]
    for f, (ac, sol) in enumerate(parts):
        if ac.size:
            thetas[f][ac] = sol[:, 0] - sol[:, 1:] @ th_g
        thetas[f][g_cols] = th_g
    return thetas


def heldout_sse(
    design: Design, stats: FoldStats, cols: tuple[IntArray, IntArray]
) -> tuple[FloatArray, list[list[FloatArray]]]:
    """Held-out squared error per maneuver of the model on ``cols`` (each maneuver predicted by
    the fit on the other folds), and each fold's per-flap parameters."""
    n_q = len(stats.train_gram)
    thetas = []
    sse = design.yty.copy()
    # the parameters are zero off the model's columns: the quadratic forms need only those
    idx = np.concatenate(cols)
    for q in range(n_q):
        th = solve(design, stats.train_gram[q], stats.train_xty[q], cols)
        thetas.append(th)
        for m in np.flatnonzero(stats.folds == q):
            t = th[design.man_flap[m]][idx]
            g = design.gram[m][np.ix_(idx, idx)]
            sse[m] = design.yty[m] - 2.0 * t @ design.xty[m][idx] + t @ g @ t
    return sse, thetas


def row_prediction(  # noqa: PLR0917 - rows' columns, positional by design
    design: Design,
    thetas: Sequence[FloatArray],
    flap: IntArray,
    alpha_deg: FloatArray,
    aero: FloatArray,
    glob: FloatArray,
) -> FloatArray:
    """The model ``sum theta * column`` at each row (``thetas``: per-flap local vectors)."""
    k_n, r_n = design.grid.n, len(design.aero_names)
    j, w1 = design.grid.locate(alpha_deg)
    th = np.stack([t[: k_n * r_n].reshape(k_n, r_n) for t in thetas])
    coef = th[flap, j] * (1.0 - w1)[:, None] + th[flap, j + 1] * w1[:, None]
    out = np.einsum("nr,nr->n", coef, aero)
    if glob.shape[1]:
        out = out + glob @ thetas[0][k_n * r_n :]
    return out


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
    d = np.asarray(d, dtype=np.float64)
    d = d[d != 0.0]
    n = d.size
    if n < 2:
        return 0.0, 1.0
    ranks = _abs_ranks(d)
    w = float(np.sum(ranks[d > 0]) - np.sum(ranks[d < 0]))
    sd = float(np.sqrt(np.sum(ranks**2)))
    p = _flip_p(ranks, w, n_perm, seed)
    return w / sd, p


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
        shifted = np.zeros_like(dist)
        shifted[k:] = dist[:-k]
        dist = 0.5 * (dist + shifted)
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
    d = np.asarray(d, dtype=np.float64)
    d = d[d != 0.0]
    n = d.size
    if n < 2:
        return 0.0, 1.0
    w = float(d.sum())
    sd = float(np.sqrt(np.sum(d * d)))
    p = _flip_p(d, w, n_perm, seed)
    return (w / sd if sd > 0 else 0.0), p


def improvement_test(d: FloatArray, n_perm: int, seed: int) -> tuple[float, float]:
    """The selection's test of a held-out improvement: the signed-rank and the sum sign-flip
    tests (:func:`sign_flip_pvalue`, :func:`sign_flip_sum_pvalue`), Bonferroni-combined
    (twice the smaller p). The first has power when many maneuvers improve a little, the
    second when a minority improves a lot. Returns the ``(z, p)`` of the test that decided."""
    z_r, p_r = sign_flip_pvalue(d, n_perm, seed)
    z_s, p_s = sign_flip_sum_pvalue(d, n_perm, seed + 1)
    if p_s < p_r:
        return z_s, min(1.0, 2.0 * p_s)
    return z_r, min(1.0, 2.0 * p_r)


#: Draws added when a sign-flip p-value lands in the far tail (see :func:`_flip_p`).
TAIL_DRAWS = 10


def _flip_p(weights: FloatArray, w: float, n_perm: int, seed: int) -> float:
    """``P(sum(s * weights) >= w)`` under random signs ``s``, by ``n_perm`` seeded draws,
    ``(1 + hits) / (1 + draws)``. When fewer than 20 draws reach ``w`` the estimate is
    mostly its floor ``1/(n_perm + 1)``, which a Bonferroni factor then multiplies: with 20
    candidates and the two combined tests, no effect could reach p < 0.01 at 4,000 draws. So
    ``TAIL_DRAWS - 1`` times as many draws are added (same seed, same answer)."""
    rng = np.random.default_rng(seed)
    n = weights.size
    hits, draws = 0, 0
    total = n_perm
    while draws < total:
        k = min(total - draws, 50_000)
        signs = rng.integers(0, 2, size=(k, n), dtype=np.int8) * 2 - 1
        hits += int(np.sum(signs @ weights >= w))
        draws += k
        if draws == n_perm and hits < 20:
            total = n_perm * TAIL_DRAWS
    return (1.0 + hits) / (draws + 1.0)
