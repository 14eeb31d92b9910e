"""Equation-error ordinary least squares with its statistics (engine: ``aero_core::lsq``).

The fit solves thesis Eq. 2.12-2.13 / 3.10 by a Householder QR (never the normal
equations), and reports what is needed to judge a model: conventional standard errors,
standard errors corrected for coloured residuals (Morelli & Klein Eq. 5.80, SIDPAC
``r_colores``), t, p, partial F (thesis Eq. 2.5), R², adjusted R², fit error, PRESS, PSE,
singular values, condition numbers, variance inflation factors and which parameters the
data cannot identify. Given a cluster id per row (``groups``, e.g. the maneuver), it also
reports cluster-robust CR2 standard errors with Bell-McCaffrey degrees of freedom (Bell &
McCaffrey 2002; Imbens & Kolesár 2016), valid under any correlation of the residuals inside
a cluster (``aero_core::lsq::cluster``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import polars as pl

from aerodelta import _core

FloatArray = npt.NDArray[np.float64]


class OLSResults:
    """Immutable result of :func:`ols` (statsmodels-like; keeps no raw data).

    Attributes are read-only properties. Arrays are indexed like the columns of X.
    """

    __slots__ = ("_f",)

    _f: _core.OlsFit

    def __init__(self) -> None:
        raise TypeError("OLSResults is built by aerodelta.ols(...)")

    @classmethod
    def _from_core(cls, f: _core.OlsFit) -> OLSResults:
        obj = cls.__new__(cls)
        object.__setattr__(obj, "_f", f)
        return obj

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError("OLSResults is immutable")

    # --- estimates -------------------------------------------------------------------
    @property
    def names(self) -> list[str]:
        """Parameter (column) names."""
        return self._f.names

    @property
    def params(self) -> FloatArray:
        """Estimates θ̂, in units of z per unit of each regressor."""
        return self._f.params

    @property
    def cov(self) -> FloatArray:
        """Conventional covariance ``s² (XᵀX)⁻¹``, shape (p, p)."""
        return self._f.cov

    @property
    def cov_corrected(self) -> FloatArray | None:
        """Covariance corrected for coloured residuals (None if not computed)."""
        return self._f.cov_colored

    @property
    def std_err(self) -> FloatArray:
        """Conventional standard errors ``sqrt(diag(s² (XᵀX)⁻¹))``."""
        return self._f.std_err

    @property
    def std_err_corrected(self) -> FloatArray | None:
        """Standard errors corrected for coloured residuals (Morelli & Klein Eq. 5.80)."""
        return self._f.std_err_colored

    @property
    def cov_cluster(self) -> FloatArray | None:
        """Cluster-robust CR2 covariance, shape (p, p); None without ``groups``.

        ``M [Σ_g X_gᵀ A_g e_g e_gᵀ A_g X_g] M`` with ``M = (XᵀX)⁻¹`` and
        ``A_g = (I − H_gg)^(−1/2)`` (Bell & McCaffrey 2002). Entry (i, j) is in units of
        ``params[i] · params[j]``. Rows and columns of parameters without a cluster-robust
        error (see :attr:`notes_cluster`) are NaN.
        """
        return self._f.cov_cluster

    @property
    def std_err_cluster(self) -> FloatArray | None:
        """Cluster-robust CR2 standard errors, units of :attr:`params`; None without ``groups``.

        NaN where undefined: a single cluster alone determines the parameter (its reason in
        :attr:`notes_cluster`). Unlike statsmodels' ``cov_type='cluster'`` (CR1) no
        ``G/(G-1)`` factor is applied: the CR2 adjustment is unbiased under iid errors.
        """
        return self._f.std_err_cluster

    @property
    def dof_cluster(self) -> FloatArray | None:
        """Bell-McCaffrey degrees of freedom of each cluster-robust error (dimensionless).

        Use Student t with these (per parameter) for intervals and tests; at most
        ``n_groups - 1`` in balanced designs, fewer when a few clusters carry most of a
        regressor's excitation. None without ``groups``, NaN where the error is undefined.
        """
        return self._f.dof_cluster

    @property
    def n_groups(self) -> int | None:
        """Number of distinct ``groups`` ids among the fitted rows; None without ``groups``."""
        return self._f.n_clusters

    @property
    def notes_cluster(self) -> list[str] | None:
        """Why each parameter has no cluster-robust error ("" when it has one); None without
        ``groups``."""
        return self._f.notes_cluster

    @property
    def tvalues(self) -> FloatArray:
        """t statistics ``θ̂ / s(θ̂)`` (conventional standard errors)."""
        return self._f.t_values

    @property
    def pvalues(self) -> FloatArray:
        """Two-sided p-values of the t statistics (Student t, ``df_resid`` dof)."""
        return self._f.p_values

    @property
    def partial_f(self) -> FloatArray:
        """Partial F per parameter, thesis Eq. 2.5: ``θ̂² / s²(θ̂)``."""
        return self._f.partial_f

    # --- fit statistics --------------------------------------------------------------
    @property
    def r2(self) -> float:
        """R²: centered when X has a constant column, uncentered otherwise (as statsmodels)."""
        return self._f.r2

    @property
    def r2_adj(self) -> float:
        """Adjusted R² ``1 - (N - k_const) / df_resid · (1 - R²)``."""
        return self._f.r2_adj

    @property
    def fvalue(self) -> float:
        """Overall F statistic of the regression."""
        return self._f.f_value

    @property
    def f_pvalue(self) -> float:
        """p-value of the overall F statistic."""
        return self._f.f_pvalue

    @property
    def s2(self) -> float:
        """Residual variance ``RSS / df_resid`` (units of z squared)."""
        return self._f.s2

    @property
    def ssr(self) -> float:
        """Residual sum of squares."""
        return self._f.rss

    @property
    def fit_error_pct(self) -> float:
        """Fit error ``100 · rms(residual) / rms(z)``, percent."""
        return self._f.fit_error_pct

    @property
    def press(self) -> float:
        """Predicted residual sum of squares ``Σ (v_i / (1 - h_ii))²``."""
        return self._f.press

    @property
    def pse(self) -> float:
        """Predicted squared error (Morelli): ``RSS/N + σ²_max · p/N``, ``σ²_max = var(z)``."""
        return self._f.pse

    @property
    def residual_mean(self) -> float:
        """Mean of the residuals."""
        return self._f.residual_mean

    # --- conditioning ----------------------------------------------------------------
    @property
    def singular_values(self) -> FloatArray:
        """Singular values of X, descending."""
        return self._f.singular_values

    @property
    def singular_values_scaled(self) -> FloatArray:
        """Singular values of X with each column scaled to unit norm, descending."""
        return self._f.singular_values_scaled

    @property
    def condition_number(self) -> float:
        """Condition number of the column-normalized X."""
        return self._f.condition_number

    @property
    def condition_number_unscaled(self) -> float:
        """Condition number of X as given."""
        return self._f.condition_number_unscaled

    @property
    def rank(self) -> int:
        """Numerical rank of X."""
        return self._f.rank

    @property
    def vif(self) -> FloatArray:
        """Variance inflation factors (as statsmodels ``variance_inflation_factor``)."""
        return self._f.vif

    @property
    def dependencies(self) -> list[tuple[float, list[str], list[float], list[float]]]:
        """(Near) dependencies of the column-normalized X, worst first.

        Each is (condition index, column names, loadings of the unit singular vector,
        variance-decomposition proportions); exact dependencies have an infinite
        condition index and NaN proportions.
        """
        names = self.names
        return [
            (ci, [names[j] for j in cols], ld, vdp) for ci, cols, ld, vdp in self._f.dependencies
        ]

    @property
    def identifiable(self) -> npt.NDArray[np.bool_]:
        """Whether each parameter is identifiable from these data."""
        return np.asarray(self._f.identifiable, dtype=bool)

    @property
    def notes(self) -> list[str]:
        """One note per parameter (empty when none): why not identifiable, high VIF."""
        return self._f.notes

    @property
    def nobs(self) -> int:
        """Number of rows used."""
        return self._f.nobs

    @property
    def df_resid(self) -> int:
        """Residual degrees of freedom ``N - rank``."""
        return self._f.dof

    @property
    def df_model(self) -> int:
        """Model degrees of freedom ``rank - k_const``."""
        return self._f.df_model

    @property
    def const_column(self) -> int | None:
        """Index of the constant column, if X has one."""
        return self._f.const_column

    @property
    def dropped_rows(self) -> list[int]:
        """Input rows dropped for NaN/inf (only with ``drop_nan=True``)."""
        return self._f.dropped_rows

    # --- tables ----------------------------------------------------------------------
    def conf_int(
        self, alpha: float = 0.05, corrected: bool = False, *, cluster: bool = False
    ) -> pl.DataFrame:
        """Two-sided ``1 - alpha`` confidence intervals, in units of :attr:`params`.

        Parameters
        ----------
        alpha
            Significance level, in (0, 1).
        corrected
            Use the standard errors corrected for coloured residuals (Student t,
            ``df_resid`` dof).
        cluster
            Use the cluster-robust CR2 standard errors with Student t on each parameter's
            Bell-McCaffrey dof (:attr:`dof_cluster`; needs ``groups``). NaN bounds where
            the cluster-robust error is undefined.

        Returns
        -------
        polars.DataFrame
            Columns ``name``, ``lower``, ``upper``. Default: conventional standard errors,
            Student t with ``df_resid`` dof.
        """
        if not 0.0 < alpha < 1.0:
            raise _core.OutOfRangeError(f"argument 'alpha': {alpha} is not in (0, 1)")
        if cluster:
            if corrected:
                raise _core.InvalidInputError(
                    "conf_int: give corrected=True or cluster=True, not both"
                )
            se_cl, dof_cl = self.std_err_cluster, self.dof_cluster
            if se_cl is None or dof_cl is None:
                raise _core.InvalidInputError(
                    "conf_int(cluster=True): the fit was made without groups"
                )
            qs = np.array(
                [
                    _core.student_t_ppf(1.0 - alpha / 2.0, float(d)) if np.isfinite(d) else np.nan
                    for d in dof_cl
                ]
            )
            return pl.DataFrame(
                {
                    "name": self.names,
                    "lower": self.params - qs * se_cl,
                    "upper": self.params + qs * se_cl,
                }
            )
        se = self.std_err_corrected if corrected else self.std_err
        if se is None:
            raise _core.InvalidInputError(
                "conf_int(corrected=True): the fit was made with colored=False"
            )
        q = _core.student_t_ppf(1.0 - alpha / 2.0, float(self.df_resid))
        return pl.DataFrame(
            {"name": self.names, "lower": self.params - q * se, "upper": self.params + q * se}
        )

    def summary(self, alpha: float = 0.05) -> pl.DataFrame:
        """One row per parameter.

        Columns: ``name, estimate, std_err, std_err_corrected, std_err_cluster,
        dof_cluster, t, p, ci_lo, ci_hi, partial_f, vif, identifiable, note`` (t, p and the
        interval at ``1 - alpha`` on the conventional standard errors; the cluster-robust
        ones and their Bell-McCaffrey dof are NaN without ``groups``, and the note also
        says why a parameter has no cluster-robust error).
        """
        ci = self.conf_int(alpha)
        se_c = self.std_err_corrected
        p = len(self.names)
        nan = np.full(p, np.nan)
        se_cl, dof_cl, nc = self.std_err_cluster, self.dof_cluster, self.notes_cluster
        notes = self.notes
        if nc is not None:
            notes = ["; ".join(t for t in (a, b) if t) for a, b in zip(notes, nc, strict=True)]
        return pl.DataFrame(
            {
                "name": self.names,
                "estimate": self.params,
                "std_err": self.std_err,
                "std_err_corrected": se_c if se_c is not None else nan,
                "std_err_cluster": se_cl if se_cl is not None else nan,
                "dof_cluster": dof_cl if dof_cl is not None else nan,
                "t": self.tvalues,
                "p": self.pvalues,
                "ci_lo": ci["lower"],
                "ci_hi": ci["upper"],
                "partial_f": self.partial_f,
                "vif": self.vif,
                "identifiable": self.identifiable,
                "note": notes,
            }
        )

    def __str__(self) -> str:
        lines = [
            "OLS (equation error, QR)",
            f"  nobs {self.nobs}   df_resid {self.df_resid}   rank {self.rank}",
            f"  R² {self.r2:.6f}   adj R² {self.r2_adj:.6f}   "
            f"F {self.fvalue:.4g} (p {self.f_pvalue:.3g})",
            f"  s {np.sqrt(self.s2):.6g}   fit error {self.fit_error_pct:.3f} %   "
            f"PRESS {self.press:.6g}   PSE {self.pse:.6g}",
            f"  condition number {self.condition_number:.4g} (column-normalized), "
            f"{self.condition_number_unscaled:.4g} (as given)",
        ]
        se_cl, dof_cl, nc = self.std_err_cluster, self.dof_cluster, self.notes_cluster
        if se_cl is not None:
            lines.append(
                f"  {self.n_groups} groups: cluster-robust CR2 errors (se_clust), "
                "Bell-McCaffrey dof (dof_cl)"
            )
        lines.append("")
        w = max(8, *(len(n) for n in self.names))
        cl_head = f" {'se_clust':>11} {'dof_cl':>7}" if se_cl is not None else ""
        head = (
            f"  {'name':<{w}} {'estimate':>13} {'std_err':>11} {'se_corr':>11}{cl_head} "
            f"{'t':>9} {'p':>9} {'partial F':>11} {'VIF':>9}  note"
        )
        lines.append(head)
        se_c = self.std_err_corrected
        for j, name in enumerate(self.names):
            sc = f"{se_c[j]:11.4e}" if se_c is not None else f"{'-':>11}"
            cl = ""
            note = self.notes[j]
            if se_cl is not None and dof_cl is not None and nc is not None:
                cl = f" {se_cl[j]:11.4e} {dof_cl[j]:7.1f}"
                note = "; ".join(t for t in (note, nc[j]) if t)
            lines.append(
                f"  {name:<{w}} {self.params[j]:13.6g} {self.std_err[j]:11.4e} {sc}{cl} "
                f"{self.tvalues[j]:9.3f} {self.pvalues[j]:9.3g} {self.partial_f[j]:11.4g} "
                f"{self.vif[j]:9.3g}  {note}"
            )
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (
            f"<OLSResults nobs={self.nobs} p={len(self.names)} r2={self.r2:.6f} "
            f"cond={self.condition_number:.3g}>"
        )


def ols(
    X: npt.ArrayLike | pl.DataFrame,
    z: npt.ArrayLike | pl.Series,
    names: Sequence[str] | None = None,
    *,
    drop_nan: bool = False,
    colored: bool = True,
    max_lag: int | None = None,
    min_norm: bool = False,
    collinear_cond: float = 1e6,
    rows: npt.ArrayLike | None = None,
    groups: npt.ArrayLike | pl.Series | None = None,
) -> OLSResults:
    """Ordinary least squares ``z ≈ X θ`` (thesis Eq. 2.12-2.13, 3.10) with statistics.

    Parameters
    ----------
    X
        Regressors, shape (N, p): a 2-D array or a polars DataFrame (names from its
        columns). Include a column of ones for an intercept; R² is centered when X has
        a constant column, uncentered otherwise (as statsmodels).
    z
        Measured output, N values (e.g. a force or moment coefficient, dimensionless).
    names
        Parameter names (default: DataFrame columns, else ``x0, x1, ...``).
    drop_nan
        Drop rows where X or z is NaN/inf (listed in ``dropped_rows``) instead of
        raising :class:`~aerodelta.InvalidInputError` naming them.
    colored
        Also compute standard errors corrected for coloured residuals (Morelli & Klein
        Eq. 5.80, SIDPAC ``r_colores``; O(p N log N) by FFT). Rows are taken as
        consecutive samples.
    max_lag
        Truncate the residual autocorrelation beyond this many samples (default: all).
    min_norm
        Accept an exactly rank-deficient X and return the minimum-norm solution in
        column-normalized units (``numpy.linalg.lstsq`` of X with unit-norm columns, scaled
        back; equal to ``lstsq`` of X when the dependent columns have equal norms), the
        dependent parameters marked not identifiable.
    collinear_cond
        Condition index of the column-normalized X above which a direction is a near
        dependency and its parameters are marked not identifiable.
    rows
        Optional row indices: fit on this subset only (no copy of X).
    groups
        Optional cluster id of each row of X (N integers, units: none; e.g. the maneuver
        id): rows of one cluster may have correlated residuals, rows of different clusters
        not. Then the result also carries the cluster-robust CR2 covariance
        (:attr:`~OLSResults.cov_cluster`), standard errors
        (:attr:`~OLSResults.std_err_cluster`) and Bell-McCaffrey degrees of freedom
        (:attr:`~OLSResults.dof_cluster`). Ids are labels (any integers, any order; rows of
        a cluster need not be contiguous); with ``rows`` or ``drop_nan`` only the fitted
        rows count. Integral floats are accepted; NaN is not.

    Returns
    -------
    OLSResults

    Raises
    ------
    InvalidInputError
        Shapes do not match, or NaN/inf rows (the message lists them) without ``drop_nan``;
        ``groups`` not one integer id per row of X (length, NaN/inf, non-integral values,
        non-numeric dtype).
    TooLittleDataError
        Not more rows than parameters, or X rank deficient (the message names the
        dependent columns) without ``min_norm``; the fitted rows in fewer than 2 ``groups``.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.column_stack([np.ones(5), np.arange(5.0)])
    >>> r = ols(x, 1.0 + 2.0 * np.arange(5.0), names=["bias", "slope"])
    >>> [round(float(v), 12) for v in r.params]
    [1.0, 2.0]
    """
    if isinstance(X, pl.DataFrame):
        if names is None:
            names = X.columns
        xa = X.to_numpy().astype(np.float64, copy=False)
    else:
        xa = np.asarray(X, dtype=np.float64)
    if xa.ndim != 2:
        raise _core.InvalidInputError(f"argument 'X': must be 2-D (N, p), got shape {xa.shape}")
    xa = np.ascontiguousarray(xa)
    za = np.ascontiguousarray(
        (z.to_numpy() if isinstance(z, pl.Series) else np.asarray(z))
        .astype(np.float64, copy=False)
        .ravel()
    )
    ra = None
    if rows is not None:
        ri = np.asarray(rows)
        if ri.size and (ri.min() < 0 or not np.issubdtype(ri.dtype, np.integer)):
            raise _core.InvalidInputError("argument 'rows': must be non-negative integers")
        ra = np.ascontiguousarray(ri, dtype=np.uint64)
    nm = [str(n) for n in names] if names is not None else None
    ga = _groups(groups, xa.shape[0]) if groups is not None else None
    f = _core.ols(
        xa,
        za,
        rows=ra,
        names=nm,
        drop_nan=drop_nan,
        colored=colored,
        max_lag=max_lag,
        min_norm=min_norm,
        collinear_cond=collinear_cond,
        groups=ga,
    )
    if ga is not None and (f.n_clusters or 0) < 2:
        raise _core.TooLittleDataError(
            f"argument 'groups': the {f.nobs} fitted rows are in {f.n_clusters} group; "
            "cluster-robust standard errors need at least 2"
        )
    return OLSResults._from_core(f)


def _groups(groups: npt.ArrayLike | pl.Series, n: int) -> npt.NDArray[np.uint64]:
    """``groups`` as the engine's ``uint64`` cluster ids, refusing what is not one integer id
    per row (signed ids are reinterpreted bit for bit: distinct ids stay distinct)."""
    g = groups.to_numpy() if isinstance(groups, pl.Series) else np.asarray(groups)
    if g.ndim != 1:
        raise _core.InvalidInputError(
            f"argument 'groups': must be 1-D (one cluster id per row of X), got shape {g.shape}"
        )
    if g.shape[0] != n:
        raise _core.InvalidInputError(
            f"argument 'groups': has {g.shape[0]} values but X has {n} rows"
        )
    if g.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(g))
        if bad.size:
            raise _core.InvalidInputError(
                f"argument 'groups': {bad.size} NaN/inf values (first at rows "
                f"{bad[:5].tolist()}); give an integer cluster id for every row"
            )
        off = np.flatnonzero((g != np.round(g)) | (np.abs(g) > 2.0**53))
        if off.size:
            raise _core.InvalidInputError(
                f"argument 'groups': not integer cluster ids (e.g. {g[off[0]]!r} at row "
                f"{int(off[0])})"
            )
        g = g.astype(np.int64)
    if g.dtype.kind == "u":
        return np.ascontiguousarray(g, dtype=np.uint64)
    if g.dtype.kind == "i":
        return np.ascontiguousarray(g.astype(np.int64, copy=False)).view(np.uint64)
    raise _core.InvalidInputError(
        f"argument 'groups': must be integer cluster ids, got dtype {g.dtype}"
    )


__all__ = ["OLSResults", "ols"]
