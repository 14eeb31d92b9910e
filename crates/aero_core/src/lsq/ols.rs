//! The OLS fit itself. See [`ols`] for the method and the conventions.

// Index loops over the p columns read closer to the formulas.
#![allow(clippy::needless_range_loop)]

use std::borrow::Cow;

use faer::Mat;

use super::cluster::{cr2, ClusterCov};
use super::colored::{padded_len, toeplitz_gram_cols};
use super::pool::{give_real, take_real};
use super::stats::{f_sf, student_t_sf_two_sided};
use crate::error::{AeroError, Result};

/// Default threshold on the condition index (`σ_max / σ_k`) of the
/// column-normalized regressor matrix above which a singular direction is a
/// *near dependency*: the parameters loading on it are marked not
/// identifiable (their variance is inflated by more than ~1e12 relative to
/// an orthogonal design of the same column norms).
pub const COLLINEAR_COND_DEFAULT: f64 = 1e6;
/// A column belongs to a near dependency when at least this share of the
/// variance of its parameter comes from that singular direction (Belsley,
/// Kuh & Welsch 1980, variance-decomposition proportions of the
/// column-normalized X). The same share summed over all near dependencies
/// marks a parameter not identifiable.
pub const VDP_MIN: f64 = 0.5;
/// A column belongs to an exact dependency (zero singular value) when the
/// absolute loading of the unit null vector on it is at least this.
pub const LOADING_EXACT_MIN: f64 = 1e-6;
/// Variance inflation factors above this get a note (the usual rule of thumb).
pub const VIF_NOTE: f64 = 10.0;

/// Rows per chunk of the tall-skinny QR (fixed, so results do not depend
/// on the number of threads).
const CHUNK: usize = 2048;

/// Block size of faer's Householder QR of a chunk. With only `p + 1`
/// columns the blocked (compact-WY) variant spends more in its small
/// matrix products than it saves; the unblocked one (1) is ~25% faster on
/// 2048 x 13 chunks and equally accurate.
const QR_BLOCK: usize = 1;

/// Options of [`ols`].
#[derive(Debug, Clone)]
pub struct OlsOptions {
    /// Drop rows where X or z is not finite (NaN, ±inf) instead of refusing
    /// them. Default `false`: an error lists the first bad rows.
    pub drop_nan: bool,
    /// Compute the coloured-residual covariance (Morelli & Klein Eq. 5.80).
    /// Default `true`.
    pub colored: bool,
    /// Truncate the residual autocorrelation beyond this lag (samples) in the
    /// coloured-residual covariance. Default `None`: all lags, as `r_colores`.
    pub max_lag: Option<usize>,
    /// Accept an exactly rank-deficient X and return the minimum-norm
    /// solution in column-normalized units (`numpy.linalg.lstsq` of X with
    /// unit-norm columns, scaled back), truncating the same singular values
    /// the rank was counted on; the parameters of the dependent columns are
    /// then marked not identifiable. Default `false`: error.
    pub min_norm: bool,
    /// Condition-index threshold of a near dependency
    /// ([`COLLINEAR_COND_DEFAULT`]).
    pub collinear_cond: f64,
    /// Column names for messages and notes (empty: `x0, x1, ...`).
    pub names: Vec<String>,
}

impl Default for OlsOptions {
    fn default() -> Self {
        OlsOptions {
            drop_nan: false,
            colored: true,
            max_lag: None,
            min_norm: false,
            collinear_cond: COLLINEAR_COND_DEFAULT,
            names: Vec::new(),
        }
    }
}

/// One (near) null direction of the column-normalized regressor matrix.
#[derive(Debug, Clone, PartialEq)]
pub struct NearDependency {
    /// `σ_max / σ_k` of the column-normalized X (infinite for an exact zero).
    pub condition_index: f64,
    /// Columns involved: variance-decomposition proportion >= [`VDP_MIN`]
    /// (near), or |loading| >= [`LOADING_EXACT_MIN`] (exact); largest loading first.
    pub columns: Vec<usize>,
    /// Their variance-decomposition proportions (NaN for an exact dependency).
    pub proportions: Vec<f64>,
    /// Their loadings (components of the unit right singular vector).
    pub loadings: Vec<f64>,
}

/// Collinearity diagnostics of a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Collinearity {
    /// Condition number of the column-normalized X (each column scaled to unit norm).
    pub condition_number: f64,
    /// Condition number of X as given.
    pub condition_number_unscaled: f64,
    /// Variance inflation factors `1/(1 - R_j²)`, `R_j²` of column j
    /// regressed on the others (centered when another column is constant,
    /// as statsmodels' `variance_inflation_factor`).
    pub vif: Vec<f64>,
    /// Near and exact dependencies, worst first.
    pub dependencies: Vec<NearDependency>,
    /// True when X is numerically rank deficient.
    pub rank_deficient: bool,
}

/// The result of [`ols`]. Matrices are row-major `p × p`.
#[derive(Debug, Clone)]
pub struct OlsFit {
    /// Column names.
    pub names: Vec<String>,
    /// Estimates θ̂ (thesis Eq. 2.13), units of z per unit of each column.
    pub params: Vec<f64>,
    /// Conventional covariance `s² (XᵀX)⁻¹` (pseudo-inverse if minimum-norm).
    pub cov: Vec<f64>,
    /// Conventional standard errors.
    pub std_err: Vec<f64>,
    /// Coloured-residual covariance (Morelli & Klein Eq. 5.80), if asked.
    pub cov_colored: Option<Vec<f64>>,
    /// Standard errors corrected for coloured residuals, if asked.
    pub std_err_colored: Option<Vec<f64>>,
    /// Cluster-robust (CR2) covariance with Bell-McCaffrey degrees of
    /// freedom ([`super::cluster`]), when clusters were given
    /// ([`ols_rows_clustered`]).
    pub cluster: Option<ClusterCov>,
    /// t statistics θ̂ / s(θ̂).
    pub t_values: Vec<f64>,
    /// Two-sided p-values of the t statistics (Student t, `dof` degrees of freedom).
    pub p_values: Vec<f64>,
    /// Partial F per parameter, thesis Eq. 2.5: θ̂² / s²(θ̂).
    pub partial_f: Vec<f64>,
    /// Coefficient of determination (centered if X has a constant column, else uncentered).
    pub r2: f64,
    /// Adjusted R²: `1 - (N - k_const)/(N - rank) (1 - R²)`.
    pub r2_adj: f64,
    /// Overall F statistic of the regression (model vs constant-only or vs zero).
    pub f_value: f64,
    /// Its p-value.
    pub f_pvalue: f64,
    /// Residual variance `s² = RSS / (N - rank)`.
    pub s2: f64,
    /// Residual sum of squares.
    pub rss: f64,
    /// Total sum of squares used for R² (centered or not, see `r2`).
    pub tss: f64,
    /// Fit error `100 rms(v) / rms(z)`, percent.
    pub fit_error_pct: f64,
    /// Predicted residual sum of squares `Σ (v_i / (1 - h_ii))²`.
    pub press: f64,
    /// Predicted squared error (Morelli): `RSS/N + σ²_max rank/N`, with
    /// `σ²_max = Σ (z - z̄)² / N`.
    pub pse: f64,
    /// Singular values of X, descending.
    pub singular_values: Vec<f64>,
    /// Singular values of the column-normalized X, descending.
    pub singular_values_scaled: Vec<f64>,
    /// Condition number of the column-normalized X.
    pub condition_number: f64,
    /// Numerical rank.
    pub rank: usize,
    /// Collinearity diagnostics.
    pub collinearity: Collinearity,
    /// Whether each parameter is identifiable from these data.
    pub identifiable: Vec<bool>,
    /// One note per parameter ("" when none): why not identifiable, high VIF.
    pub notes: Vec<String>,
    /// Number of rows used.
    pub nobs: usize,
    /// Residual degrees of freedom `N - rank`.
    pub dof: usize,
    /// Model degrees of freedom `rank - k_const`.
    pub df_model: usize,
    /// Index of the constant column, if any.
    pub const_column: Option<usize>,
    /// Mean of the residuals.
    pub residual_mean: f64,
    /// Rows dropped for non-finite values (with `drop_nan`), input indices.
    pub dropped_rows: Vec<usize>,
}

/// The rows a fit uses: all, or a list of input row indices.
struct Rows<'a> {
    list: Option<Cow<'a, [usize]>>,
    m: usize,
}

impl Rows<'_> {
    #[inline]
    fn get(&self, k: usize) -> usize {
        match &self.list {
            Some(l) => l[k],
            None => k,
        }
    }
}

/// Run `f(state, start, end)` on fixed chunks of `0..m`, in parallel when
/// the `parallel` feature is on, with one `init()` state (work buffers) per
/// worker; the results come back in chunk order.
fn chunked<T, S, I, F>(m: usize, chunk: usize, init: I, f: F) -> Vec<T>
where
    T: Send,
    I: Fn() -> S + Sync + Send,
    F: Fn(&mut S, usize, usize) -> T + Sync + Send,
{
    let nchunks = m.div_ceil(chunk);
    let run = |st: &mut S, c: usize| f(st, c * chunk, ((c + 1) * chunk).min(m));
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        (0..nchunks).into_par_iter().map_init(init, run).collect()
    }
    #[cfg(not(feature = "parallel"))]
    {
        let mut st = init();
        (0..nchunks).map(|c| run(&mut st, c)).collect()
    }
}

/// Column stride of a chunk of `rn` rows in the work buffers: padded by one
/// cache line, since columns of 2048 values lie 16 KiB apart and would all
/// map to the same L1 set (the row-to-column transpose then thrashes).
fn padded(rn: usize) -> usize {
    rn + 8
}

/// Copy rows `s..e` (of the fit's row list) of `X`, and of `z` if given,
/// into `out`, column-major with column stride `ld` (`z` last).
#[allow(clippy::too_many_arguments)]
fn gather(
    x: &[f64],
    p: usize,
    z: Option<&[f64]>,
    rows: &Rows<'_>,
    s: usize,
    e: usize,
    out: &mut [f64],
    ld: usize,
) {
    let rn = e - s;
    match &rows.list {
        None => {
            for (i, row) in x[s * p..e * p].chunks_exact(p).enumerate() {
                for (j, &v) in row.iter().enumerate() {
                    out[j * ld + i] = v;
                }
            }
            if let Some(z) = z {
                out[p * ld..p * ld + rn].copy_from_slice(&z[s..e]);
            }
        }
        Some(list) => {
            for (i, &r) in list[s..e].iter().enumerate() {
                for (j, &v) in x[r * p..(r + 1) * p].iter().enumerate() {
                    out[j * ld + i] = v;
                }
                if let Some(z) = z {
                    out[p * ld + i] = z[r];
                }
            }
        }
    }
}

/// Sum of `f(v)` over `col` with four interleaved accumulators (so the loop
/// pipelines), combined in a fixed order.
#[inline]
fn sum4(col: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    let mut acc = [0.0; 4];
    let mut it = col.chunks_exact(4);
    for q in it.by_ref() {
        for l in 0..4 {
            acc[l] += f(q[l]);
        }
    }
    let mut t = 0.0;
    for &v in it.remainder() {
        t += f(v);
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + t
}

fn no_convergence(what: &str) -> AeroError {
    AeroError::NoConvergence {
        place: "least squares".into(),
        iterations: 0,
        residual: f64::NAN,
        message: format!("the SVD of the triangular factor did not converge ({what})"),
    }
}

/// Ordinary least squares `z ≈ X θ` on all rows.
///
/// `x` is row-major `nrows × ncols` (a C-contiguous numpy array), `z` has
/// `nrows` values. Intercepts are the caller's: include a column of ones.
///
/// # Method
/// The estimate minimises thesis Eq. 2.12 and equals Eq. 2.13 / 3.10, but
/// the normal equations are never formed: a Householder QR of `[X | z]`
/// (faer), computed as a tall-skinny QR over fixed chunks of 2048 rows
/// (parallel with the `parallel` feature, bit-identical whatever the number
/// of threads), gives `R` and `Qᵀz`; `θ̂ = R⁻¹ Qᵀz` and `(XᵀX)⁻¹ = R⁻¹R⁻ᵀ`.
/// Leverages for PRESS are `h_i = ‖x_iᵀ R⁻¹‖²` (the rows of the thin Q).
/// The coloured-residual covariance ([`super::colored`]) is evaluated as
/// `R⁻¹ (Qᵀ T Q) R⁻ᵀ` with `Q = X R⁻¹`, which equals the textbook
/// `(XᵀX)⁻¹ Xᵀ T X (XᵀX)⁻¹` but does not cancel for near-collinear X. Long
/// work buffers are recycled between calls (a process-wide pool of at most
/// 1 GiB), since first-touch page faults cost as much as the FFTs.
///
/// # Conventions
/// - R² is centered (`TSS = Σ(z − z̄)²`) when X has a constant column (a
///   non-zero column with all values equal), uncentered (`TSS = Σz²`)
///   otherwise, as statsmodels (implicit constants, e.g. dummies summing to
///   one, are not detected). Adjusted R², overall F and VIFs follow
///   statsmodels likewise.
/// - PSE (Morelli & Klein Ch. 5; SIDPAC `lesq`/`pse`): `RSS/N + σ²_max·p/N`
///   with `σ²_max = Σ(z − z̄)²/N` and `p` the rank.
/// - Fit error: `100·rms(v)/rms(z)` percent (rms about zero, not the mean).
///
/// # Rank and collinearity
/// Singular values of `R D⁻¹` (D: column norms) are those of the
/// column-normalized X. The rank counts those above `σ_max·max(N,p)·ε`
/// (the LAPACK/numpy `matrix_rank` tolerance). An exactly rank-deficient X
/// is refused with an error naming the dependent columns unless
/// `min_norm` is set. Directions with condition index above
/// `collinear_cond` are reported in [`Collinearity`]; a parameter that takes
/// at least [`VDP_MIN`] of its variance from such directions (Belsley's
/// variance-decomposition proportions) is marked not identifiable with a
/// note naming the columns it is collinear with.
///
/// # Errors
/// Shapes that do not match, non-finite values (unless `drop_nan`), fewer
/// rows than parameters plus one, rank deficiency (unless `min_norm`).
pub fn ols(x: &[f64], nrows: usize, ncols: usize, z: &[f64], opts: &OlsOptions) -> Result<OlsFit> {
    fit(x, nrows, ncols, z, None, None, opts)
}

/// [`ols`] on a subset of rows of `x`/`z` (input row indices, any order;
/// the order matters only for the coloured-residual correction, which
/// treats consecutive listed rows as consecutive samples). Nothing is
/// copied but the chunks the QR works on.
pub fn ols_rows(
    x: &[f64],
    nrows: usize,
    ncols: usize,
    z: &[f64],
    rows: &[usize],
    opts: &OlsOptions,
) -> Result<OlsFit> {
    if let Some(&bad) = rows.iter().find(|&&r| r >= nrows) {
        return Err(AeroError::out_of_range(
            "ols rows",
            format!("row index {bad} but X has {nrows} rows"),
        ));
    }
    fit(x, nrows, ncols, z, Some(rows), None, opts)
}

/// One cluster id per row of X.
fn check_clusters(clusters: &[u64], nrows: usize) -> Result<()> {
    if clusters.len() != nrows {
        return Err(AeroError::invalid(
            "clusters",
            format!("has {} values but X has {nrows} rows", clusters.len()),
        ));
    }
    Ok(())
}

/// [`ols`] with a cluster id per row (`clusters.len() == nrows`; e.g. the
/// maneuver): the fit also carries the cluster-robust CR2 covariance with
/// Bell-McCaffrey degrees of freedom ([`OlsFit::cluster`],
/// [`super::cluster`]). Ids are arbitrary; rows dropped for non-finite
/// values (`drop_nan`) do not count.
///
/// # Errors
/// As [`ols`], and when `clusters` has another length than `z`.
pub fn ols_clustered(
    x: &[f64],
    nrows: usize,
    ncols: usize,
    z: &[f64],
    clusters: &[u64],
    opts: &OlsOptions,
) -> Result<OlsFit> {
    check_clusters(clusters, nrows)?;
    fit(x, nrows, ncols, z, None, Some(clusters), opts)
}

/// [`ols_rows`] with a cluster id per input row (`clusters.len() == nrows`;
/// in an alpha bin, the maneuver): the fit also carries the cluster-robust
/// CR2 covariance with Bell-McCaffrey degrees of freedom
/// ([`OlsFit::cluster`], [`super::cluster`]).
///
/// # Errors
/// As [`ols_rows`], and when `clusters` has another length than `z`.
pub fn ols_rows_clustered(
    x: &[f64],
    nrows: usize,
    ncols: usize,
    z: &[f64],
    rows: &[usize],
    clusters: &[u64],
    opts: &OlsOptions,
) -> Result<OlsFit> {
    check_clusters(clusters, nrows)?;
    if let Some(&bad) = rows.iter().find(|&&r| r >= nrows) {
        return Err(AeroError::out_of_range(
            "ols rows",
            format!("row index {bad} but X has {nrows} rows"),
        ));
    }
    fit(x, nrows, ncols, z, Some(rows), Some(clusters), opts)
}

fn col_name(names: &[String], j: usize) -> String {
    names.get(j).cloned().unwrap_or_else(|| format!("x{j}"))
}

fn quoted_list(names: &[String], cols: &[usize]) -> String {
    cols.iter()
        .map(|&j| format!("'{}'", col_name(names, j)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Whether every value is finite, checked in parallel blocks (a full
/// read of X, memory bound).
fn all_finite_par(v: &[f64]) -> bool {
    const BLOCK: usize = 1 << 16;
    let ok = |c: &[f64]| c.iter().all(|x| x.is_finite());
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        v.par_chunks(BLOCK).all(ok)
    }
    #[cfg(not(feature = "parallel"))]
    {
        v.chunks(BLOCK).all(ok)
    }
}

/// Refuse or drop non-finite rows; returns the rows to use and the dropped ones.
fn select_rows<'a>(
    x: &[f64],
    p: usize,
    z: &[f64],
    rows: Option<&'a [usize]>,
    opts: &OlsOptions,
) -> Result<(Rows<'a>, Vec<usize>)> {
    let m0 = rows.map_or(z.len(), |r| r.len());
    let row_ok = |r: usize| z[r].is_finite() && x[r * p..(r + 1) * p].iter().all(|v| v.is_finite());
    let all_finite = match rows {
        None => all_finite_par(x) && all_finite_par(z),
        Some(l) => l.iter().all(|&r| row_ok(r)),
    };
    if all_finite {
        return Ok((
            Rows {
                list: rows.map(Cow::Borrowed),
                m: m0,
            },
            Vec::new(),
        ));
    }
    let idx = |k: usize| rows.map_or(k, |l| l[k]);
    let bad: Vec<usize> = (0..m0).map(idx).filter(|&r| !row_ok(r)).collect();
    if !opts.drop_nan {
        let shown: Vec<String> = bad
            .iter()
            .take(10)
            .map(|&r| {
                let what = if !z[r].is_finite() {
                    "z".to_string()
                } else {
                    let j = x[r * p..(r + 1) * p]
                        .iter()
                        .position(|v| !v.is_finite())
                        .unwrap_or(0);
                    format!("column '{}'", col_name(&opts.names, j))
                };
                format!("row {r} ({what})")
            })
            .collect();
        let more = if bad.len() > 10 {
            format!(" and {} more", bad.len() - 10)
        } else {
            String::new()
        };
        return Err(AeroError::invalid(
            "least squares data",
            format!(
                "{} rows contain NaN or infinite values: {}{more}; clean them or ask to drop them (drop_nan)",
                bad.len(),
                shown.join(", ")
            ),
        ));
    }
    let kept: Vec<usize> = (0..m0).map(idx).filter(|&r| row_ok(r)).collect();
    let m = kept.len();
    Ok((
        Rows {
            list: Some(Cow::Owned(kept)),
            m,
        },
        bad,
    ))
}

/// Count, mean, min, max and centered sum of squares of each column of
/// `[X | z]`, plus Σz²; merged over chunks by Chan et al.'s pairwise formula
/// (in chunk order, so deterministic).
#[derive(Clone)]
struct ColStats {
    n: f64,
    mean: Vec<f64>,
    min: Vec<f64>,
    max: Vec<f64>,
    m2: Vec<f64>,
    zz: f64,
}

impl ColStats {
    /// Statistics of a column-major block of `rows` rows and `n` columns,
    /// column stride `ld`, all values finite.
    fn of_block(a: &[f64], rows: usize, ld: usize, n: usize) -> Self {
        let mut st = ColStats {
            n: rows as f64,
            mean: vec![0.0; n],
            min: vec![f64::INFINITY; n],
            max: vec![f64::NEG_INFINITY; n],
            m2: vec![0.0; n],
            zz: 0.0,
        };
        for j in 0..n {
            let col = &a[j * ld..j * ld + rows];
            let mut lo = [f64::INFINITY; 4];
            let mut hi = [f64::NEG_INFINITY; 4];
            let mut it = col.chunks_exact(4);
            for q in it.by_ref() {
                for l in 0..4 {
                    lo[l] = if q[l] < lo[l] { q[l] } else { lo[l] };
                    hi[l] = if q[l] > hi[l] { q[l] } else { hi[l] };
                }
            }
            for &v in it.remainder() {
                lo[0] = if v < lo[0] { v } else { lo[0] };
                hi[0] = if v > hi[0] { v } else { hi[0] };
            }
            let lo = lo
                .iter()
                .fold(f64::INFINITY, |a, &b| if b < a { b } else { a });
            let hi = hi
                .iter()
                .fold(f64::NEG_INFINITY, |a, &b| if b > a { b } else { a });
            let mean = sum4(col, |v| v) / rows as f64;
            st.mean[j] = mean;
            st.min[j] = lo;
            st.max[j] = hi;
            st.m2[j] = sum4(col, |v| (v - mean) * (v - mean));
            if j == n - 1 {
                st.zz = sum4(col, |v| v * v);
            }
        }
        st
    }

    fn merge(&mut self, o: &ColStats) {
        let n = self.n + o.n;
        for j in 0..self.mean.len() {
            let delta = o.mean[j] - self.mean[j];
            self.m2[j] += o.m2[j] + delta * delta * self.n * o.n / n;
            self.mean[j] += delta * o.n / n;
            self.min[j] = self.min[j].min(o.min[j]);
            self.max[j] = self.max[j].max(o.max[j]);
        }
        self.zz += o.zz;
        self.n = n;
    }
}

/// Upper-triangular R (`(p+1) × (p+1)`) of `[X | z]` by a tall-skinny
/// Householder QR over fixed chunks, and the column statistics.
fn tsqr(x: &[f64], p: usize, z: &[f64], rows: &Rows<'_>) -> (Mat<f64>, ColStats) {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::qr::no_pivoting::factor::{qr_in_place, qr_in_place_scratch};
    let n = p + 1;
    // Householder QR in place in a per-worker column-major buffer (faer,
    // unblocked: see `QR_BLOCK`).
    let chunk_r = |a: &mut Vec<f64>, start: usize, end: usize| -> (Mat<f64>, ColStats) {
        let rn = end - start;
        let ld = padded(rn);
        a.resize(ld * n, 0.0);
        gather(x, p, Some(z), rows, start, end, a, ld);
        let st = ColStats::of_block(a, rn, ld, n);
        let bs = QR_BLOCK;
        let size = rn.min(n);
        let mut coeff = Mat::<f64>::zeros(bs, size);
        let mut mem = MemBuffer::new(qr_in_place_scratch::<f64>(
            rn,
            n,
            bs,
            faer::Par::Seq,
            Default::default(),
        ));
        let mut am = faer::MatMut::from_column_major_slice_with_stride_mut(a, rn, n, ld);
        qr_in_place(
            am.as_mut(),
            coeff.as_mut(),
            faer::Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        );
        (upper(am.as_ref().subrows(0, size)), st)
    };
    let parts = chunked(rows.m, CHUNK, Vec::new, chunk_r);
    let mut stats = parts[0].1.clone();
    for (_, st) in &parts[1..] {
        stats.merge(st);
    }
    if parts.len() == 1 {
        return (pad_square(&parts[0].0, n), stats);
    }
    let total: usize = parts.iter().map(|(r, _)| r.nrows()).sum();
    let mut stacked = Mat::zeros(total, n);
    let mut at = 0;
    for (r, _) in &parts {
        for i in 0..r.nrows() {
            for j in i..n {
                stacked[(at + i, j)] = r[(i, j)];
            }
        }
        at += r.nrows();
    }
    (pad_square(&upper(stacked.qr().thin_R()), n), stats)
}

fn upper(r: faer::MatRef<'_, f64>) -> Mat<f64> {
    Mat::from_fn(
        r.nrows(),
        r.ncols(),
        |i, j| if j >= i { r[(i, j)] } else { 0.0 },
    )
}

fn pad_square(r: &Mat<f64>, n: usize) -> Mat<f64> {
    Mat::from_fn(n, n, |i, j| if i < r.nrows() { r[(i, j)] } else { 0.0 })
}

/// Inverse of a non-singular upper-triangular matrix by back substitution.
fn inv_upper(r: &Mat<f64>) -> Mat<f64> {
    let p = r.nrows();
    let mut inv = Mat::<f64>::zeros(p, p);
    for j in 0..p {
        // Solve R x = e_j; x is zero below j.
        for i in (0..=j).rev() {
            let mut s = if i == j { 1.0 } else { 0.0 };
            for k in i + 1..=j {
                s -= r[(i, k)] * inv[(k, j)];
            }
            inv[(i, j)] = s / r[(i, i)];
        }
    }
    inv
}

/// Cluster index of each fitted row and the number of clusters: the distinct
/// ids sorted (so the numbering does not depend on the row order), looked up
/// once per run of equal ids.
fn cluster_index(ids: &[u64], rows: &Rows<'_>) -> (Vec<usize>, usize) {
    let m = rows.m;
    let mut uniq: Vec<u64> = Vec::new();
    let mut prev = None;
    for k in 0..m {
        let v = ids[rows.get(k)];
        if prev != Some(v) {
            uniq.push(v);
            prev = Some(v);
        }
    }
    uniq.sort_unstable();
    uniq.dedup();
    let mut idx = Vec::with_capacity(m);
    let (mut prev, mut cur) = (None, 0);
    for k in 0..m {
        let v = ids[rows.get(k)];
        if prev != Some(v) {
            cur = uniq.binary_search(&v).unwrap_or(0);
            prev = Some(v);
        }
        idx.push(cur);
    }
    (idx, uniq.len())
}

/// Cluster Gram matrices `W_g = Q_gᵀQ_g` (`k × k` row-major, one after the
/// other) and scores `Q_gᵀe_g` (`k` each), `Q = X B`, for the cluster
/// ([`super::cluster`]). Clusters are processed in parallel, each on its own
/// rows in order in blocks of [`CHUNK`] rows (`Q` block by one product with
/// `B`, then `Qᵀ[Q | e]`): the sums do not depend on the number of threads,
/// and nothing of size `N × k` is stored.
fn cluster_grams(
    x: &[f64],
    p: usize,
    rows: &Rows<'_>,
    idx: &[usize],
    ng: usize,
    resid: &[f64],
    b: &Mat<f64>,
) -> (Vec<f64>, Vec<f64>) {
    use faer::{Accum, MatMut, MatRef, Par};
    let k = b.ncols();
    // Fitted rows grouped by cluster, in row order inside each (counting sort).
    let mut off = vec![0usize; ng + 1];
    for &g in idx {
        off[g + 1] += 1;
    }
    for g in 0..ng {
        off[g + 1] += off[g];
    }
    let mut next = off[..ng].to_vec();
    let mut order = vec![0usize; idx.len()];
    for (i, &g) in idx.iter().enumerate() {
        order[next[g]] = i;
        next[g] += 1;
    }
    // Per-worker buffers: the block of X, then [Q | e], column-major.
    let new_work = || (Vec::<f64>::new(), Vec::<f64>::new());
    let one = |wk: &mut (Vec<f64>, Vec<f64>), g: usize, wg: &mut [f64], sg: &mut [f64]| {
        let mut acc = Mat::<f64>::zeros(k, k + 1);
        for blk in order[off[g]..off[g + 1]].chunks(CHUNK) {
            let rn = blk.len();
            let ld = padded(rn);
            let (a, qe) = wk;
            a.resize(ld * p, 0.0);
            qe.resize(ld * (k + 1), 0.0);
            for (i, &f) in blk.iter().enumerate() {
                let r = rows.get(f);
                for (j, &v) in x[r * p..(r + 1) * p].iter().enumerate() {
                    a[j * ld + i] = v;
                }
                qe[k * ld + i] = resid[f];
            }
            let am = MatRef::from_column_major_slice_with_stride(a, rn, p, ld);
            let mut qm = MatMut::from_column_major_slice_with_stride_mut(qe, rn, k + 1, ld);
            faer::linalg::matmul::matmul(
                qm.as_mut().subcols_mut(0, k),
                Accum::Replace,
                am,
                b.as_ref(),
                1.0,
                Par::Seq,
            );
            let qr = qm.as_ref();
            faer::linalg::matmul::matmul(
                acc.as_mut(),
                Accum::Add,
                qr.subcols(0, k).transpose(),
                qr,
                1.0,
                Par::Seq,
            );
        }
        for a in 0..k {
            for c in 0..k {
                wg[a * k + c] = acc[(a, c)];
            }
            sg[a] = acc[(a, k)];
        }
    };
    let mut w = vec![0.0; ng * k * k];
    let mut s = vec![0.0; ng * k];
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        w.par_chunks_mut(k * k)
            .zip(s.par_chunks_mut(k))
            .enumerate()
            .for_each_init(new_work, |wk, (g, (wg, sg))| one(wk, g, wg, sg));
    }
    #[cfg(not(feature = "parallel"))]
    {
        let mut wk = new_work();
        for (g, (wg, sg)) in w.chunks_mut(k * k).zip(s.chunks_mut(k)).enumerate() {
            one(&mut wk, g, wg, sg);
        }
    }
    (w, s)
}

fn fit(
    x: &[f64],
    nrows: usize,
    p: usize,
    z: &[f64],
    rows: Option<&[usize]>,
    clusters: Option<&[u64]>,
    opts: &OlsOptions,
) -> Result<OlsFit> {
    if p == 0 {
        return Err(AeroError::invalid(
            "X",
            "has no columns: give at least one regressor",
        ));
    }
    if x.len() != nrows * p {
        return Err(AeroError::invalid(
            "X",
            format!("has {} values for {nrows} rows x {p} columns", x.len()),
        ));
    }
    if z.len() != nrows {
        return Err(AeroError::invalid(
            "z",
            format!("has {} values but X has {nrows} rows", z.len()),
        ));
    }
    if !opts.names.is_empty() && opts.names.len() != p {
        return Err(AeroError::invalid(
            "names",
            format!("{} names for {p} columns", opts.names.len()),
        ));
    }
    let names: Vec<String> = (0..p).map(|j| col_name(&opts.names, j)).collect();
    let (rows, dropped) = select_rows(x, p, z, rows, opts)?;
    let m = rows.m;
    if m <= p {
        return Err(AeroError::too_little(
            "least squares",
            format!(
                "{m} usable rows for {p} parameters: need at least {} rows",
                p + 1
            ),
        ));
    }

    // QR of [X | z] and column statistics (constant detection, centered
    // sums for R² and VIF) in one pass.
    let (raug, cs) = tsqr(x, p, z, &rows);
    let col_css = cs.m2[..p].to_vec();
    let (z_css, z_ss) = (cs.m2[p], cs.zz);
    let const_column = (0..p).find(|&j| cs.min[j] == cs.max[j] && cs.max[j] != 0.0);
    let r = Mat::from_fn(p, p, |i, j| raug[(i, j)]);
    let qtz: Vec<f64> = (0..p).map(|i| raug[(i, p)]).collect();

    // Column norms and singular values (scaled and not).
    let d: Vec<f64> = (0..p)
        .map(|j| (0..=j).map(|i| r[(i, j)] * r[(i, j)]).sum::<f64>().sqrt())
        .collect();
    let rs = Mat::from_fn(p, p, |i, j| if d[j] > 0.0 { r[(i, j)] / d[j] } else { 0.0 });
    let svd_s = rs.svd().map_err(|_| no_convergence("column-normalized"))?;
    let sv_scaled: Vec<f64> = (0..p).map(|k| svd_s.S()[k]).collect();
    let vs = svd_s.V();
    let svd_u = r.svd().map_err(|_| no_convergence("unscaled"))?;
    let sv: Vec<f64> = (0..p).map(|k| svd_u.S()[k]).collect();
    let smax = sv_scaled[0];
    let tol = smax * (m.max(p) as f64) * f64::EPSILON;
    let rank = sv_scaled.iter().filter(|&&s| s > tol).count();
    let cond = |s: &[f64]| {
        if s[p - 1] > 0.0 {
            s[0] / s[p - 1]
        } else {
            f64::INFINITY
        }
    };
    let condition_number = cond(&sv_scaled);
    let condition_number_unscaled = cond(&sv);

    // Variance-decomposition proportions over the non-null directions.
    let phi = |j: usize, k: usize| (vs[(j, k)] / sv_scaled[k]).powi(2);
    let phi_tot: Vec<f64> = (0..p)
        .map(|j| {
            (0..p)
                .filter(|&k| sv_scaled[k] > tol)
                .map(|k| phi(j, k))
                .sum()
        })
        .collect();
    let mut near_share = vec![0.0; p];
    let mut dependencies = Vec::new();
    for k in (0..p).rev() {
        let ci = if sv_scaled[k] > 0.0 {
            smax / sv_scaled[k]
        } else {
            f64::INFINITY
        };
        let exact = sv_scaled[k] <= tol;
        if !(exact || ci > opts.collinear_cond) {
            continue;
        }
        let mut cols: Vec<(usize, f64, f64)> = if exact {
            (0..p)
                .map(|j| (j, vs[(j, k)], f64::NAN))
                .filter(|c| c.1.abs() >= LOADING_EXACT_MIN)
                .collect()
        } else {
            (0..p)
                .map(|j| (j, vs[(j, k)], phi(j, k) / phi_tot[j]))
                .inspect(|c| near_share[c.0] += c.2)
                .filter(|c| c.2 >= VDP_MIN)
                .collect()
        };
        cols.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        dependencies.push(NearDependency {
            condition_index: if exact { f64::INFINITY } else { ci },
            columns: cols.iter().map(|c| c.0).collect(),
            loadings: cols.iter().map(|c| c.1).collect(),
            proportions: cols.iter().map(|c| c.2).collect(),
        });
    }
    let rank_deficient = rank < p;
    if rank_deficient && !opts.min_norm {
        let groups: Vec<String> = dependencies
            .iter()
            .filter(|dep| dep.condition_index.is_infinite())
            .map(|dep| format!("[{}]", quoted_list(&names, &dep.columns)))
            .collect();
        return Err(AeroError::too_little(
            "least squares",
            format!(
                "X has rank {rank} < {p} columns: linearly dependent columns {}; \
                 remove or combine them, or ask for the minimum-norm solution (min_norm)",
                groups.join(", ")
            ),
        ));
    }

    // Solve; B with (XᵀX)⁻¹ = B Bᵀ.
    let (params, b) = if !rank_deficient {
        let rinv = inv_upper(&r);
        let th: Vec<f64> = (0..p)
            .map(|i| (i..p).map(|k| rinv[(i, k)] * qtz[k]).sum())
            .collect();
        (th, rinv)
    } else {
        // Truncated SVD of the column-normalized R D⁻¹, keeping the `rank`
        // directions the rank was counted on (truncating the unscaled SVD
        // instead would keep other directions when the columns' scales
        // differ): θ = D⁻¹ V_r Σ_r⁻¹ U_rᵀ Qᵀz, the minimum-norm solution in
        // normalized units, and B = D⁻¹ V_r Σ_r⁻¹.
        let u = svd_s.U();
        let b = Mat::from_fn(p, rank, |i, k| {
            if d[i] > 0.0 {
                vs[(i, k)] / sv_scaled[k] / d[i]
            } else {
                0.0
            }
        });
        let utc: Vec<f64> = (0..rank)
            .map(|k| (0..p).map(|i| u[(i, k)] * qtz[i]).sum())
            .collect();
        let th: Vec<f64> = (0..p)
            .map(|i| (0..rank).map(|k| b[(i, k)] * utc[k]).sum())
            .collect();
        (th, b)
    };
    let nb = b.ncols();
    let xtx_inv = Mat::from_fn(p, p, |i, j| {
        (0..nb).map(|k| b[(i, k)] * b[(j, k)]).sum::<f64>()
    });

    // Residuals and leverages, chunk by chunk: [ŷ | Q] = X_chunk [θ | B]
    // (h_i = ‖q_i‖²). With the coloured correction the Q blocks are kept
    // for the FFT stage: the correction is computed as B (Qᵀ T Q) Bᵀ, whose
    // middle factor is well conditioned, rather than (XᵀX)⁻¹ (Xᵀ T X) (XᵀX)⁻¹,
    // which cancels catastrophically for near-collinear X.
    let tb = Mat::from_fn(
        p,
        1 + nb,
        |i, k| if k == 0 { params[i] } else { b[(i, k - 1)] },
    );
    let keep_blocks = opts.colored;
    // With the coloured correction each column of Q goes straight into its
    // own recycled FFT input buffer (zero-padded later by the FFT stage).
    // Per-worker work buffers: the padded chunk of X, then [ŷ | Q] and the
    // leverages.
    struct Pass2Work {
        a: Vec<f64>,
        w: Vec<f64>,
        h: Vec<f64>,
    }
    let new_work = || Pass2Work {
        a: Vec::new(),
        w: Vec::new(),
        h: Vec::new(),
    };
    let pass2 = |wk: &mut Pass2Work, c: usize, outs: Vec<&mut [f64]>| {
        let (s, e) = (c * CHUNK, ((c + 1) * CHUNK).min(m));
        let rn = e - s;
        let ld = padded(rn);
        wk.a.resize(ld * p, 0.0);
        wk.w.resize(ld * (1 + nb), 0.0);
        gather(x, p, None, &rows, s, e, &mut wk.a, ld);
        let a = faer::MatRef::from_column_major_slice_with_stride(&wk.a, rn, p, ld);
        let mut wm =
            faer::MatMut::from_column_major_slice_with_stride_mut(&mut wk.w, rn, 1 + nb, ld);
        faer::linalg::matmul::matmul(
            wm.as_mut(),
            faer::Accum::Replace,
            a,
            tb.as_ref(),
            1.0,
            faer::Par::Seq,
        );
        let w = &wk.w;
        for (k, col) in outs.into_iter().enumerate() {
            col.copy_from_slice(&w[(k + 1) * ld..(k + 1) * ld + rn]);
        }
        // h_i = Σ_k q_ik², accumulated column by column (k ascending).
        wk.h.clear();
        wk.h.resize(rn, 0.0);
        for k in 1..=nb {
            for (hi, q) in wk.h.iter_mut().zip(&w[k * ld..k * ld + rn]) {
                *hi += q * q;
            }
        }
        let mut res = Vec::with_capacity(rn);
        let (mut rss, mut press, mut sum) = (0.0, 0.0, 0.0);
        for (i, (&h, &fit)) in wk.h.iter().zip(&w[..rn]).enumerate() {
            let v = z[rows.get(s + i)] - fit;
            let loo = v / (1.0 - h);
            rss += v * v;
            press += if h < 1.0 - 1e-12 {
                loo * loo
            } else {
                f64::INFINITY
            };
            sum += v;
            res.push(v);
        }
        (res, rss, press, sum)
    };
    let mut qcols: Vec<Vec<f64>> = if keep_blocks {
        let l = padded_len(m);
        (0..nb).map(|_| take_real(l)).collect()
    } else {
        Vec::new()
    };
    let parts: Vec<(Vec<f64>, f64, f64, f64)> = if keep_blocks {
        // Chunk c of every Q column, as disjoint mutable slices.
        let mut outs: Vec<Vec<&mut [f64]>> = (0..m.div_ceil(CHUNK))
            .map(|_| Vec::with_capacity(nb))
            .collect();
        for col in qcols.iter_mut() {
            for (c, sl) in col[..m].chunks_mut(CHUNK).enumerate() {
                outs[c].push(sl);
            }
        }
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            outs.into_par_iter()
                .enumerate()
                .map_init(new_work, |wk, (c, o)| pass2(wk, c, o))
                .collect()
        }
        #[cfg(not(feature = "parallel"))]
        {
            let mut wk = new_work();
            outs.into_iter()
                .enumerate()
                .map(|(c, o)| pass2(&mut wk, c, o))
                .collect()
        }
    } else {
        chunked(m, CHUNK, new_work, |wk: &mut Pass2Work, s, _e| {
            pass2(wk, s / CHUNK, Vec::new())
        })
    };
    let mut resid = take_real(m);
    let (mut rss, mut press, mut rsum) = (0.0, 0.0, 0.0);
    let mut at = 0;
    for (r_, a, b_, c) in parts {
        resid[at..at + r_.len()].copy_from_slice(&r_);
        at += r_.len();
        rss += a;
        press += b_;
        rsum += c;
    }

    // Statistics.
    let dof = m - rank;
    let s2 = rss / dof as f64;
    let cov: Vec<f64> = (0..p * p)
        .map(|ij| s2 * xtx_inv[(ij / p, ij % p)])
        .collect();
    let std_err: Vec<f64> = (0..p).map(|j| cov[j * p + j].max(0.0).sqrt()).collect();
    let t_values: Vec<f64> = params.iter().zip(&std_err).map(|(t, s)| t / s).collect();
    let p_values: Vec<f64> = t_values
        .iter()
        .map(|&t| student_t_sf_two_sided(t, dof as f64))
        .collect();
    let partial_f: Vec<f64> = t_values.iter().map(|t| t * t).collect();
    let k_const = usize::from(const_column.is_some());
    let tss = if k_const == 1 { z_css } else { z_ss };
    let r2 = 1.0 - rss / tss;
    let r2_adj = 1.0 - (m - k_const) as f64 / dof as f64 * (1.0 - r2);
    let df_model = rank.saturating_sub(k_const);
    let (f_value, f_pvalue) = if df_model > 0 {
        let f = ((tss - rss) / df_model as f64) / s2;
        (f, f_sf(f, df_model as f64, dof as f64))
    } else {
        (f64::NAN, f64::NAN)
    };
    let fit_error_pct = 100.0 * (rss / z_ss).sqrt();
    let pse = rss / m as f64 + (z_css / m as f64) * rank as f64 / m as f64;
    let vif: Vec<f64> = (0..p)
        .map(|j| {
            let centered = const_column.is_some_and(|c| c != j);
            let ss = if centered { col_css[j] } else { d[j] * d[j] };
            ss * xtx_inv[(j, j)]
        })
        .collect();

    // Identifiability and notes.
    let mut identifiable = vec![true; p];
    let mut notes = vec![String::new(); p];
    for dep in &dependencies {
        for &j in &dep.columns {
            identifiable[j] = false;
            let others: Vec<usize> = dep.columns.iter().copied().filter(|&c| c != j).collect();
            let what = if dep.condition_index.is_infinite() {
                "linearly dependent on".to_string()
            } else {
                format!(
                    "near-collinear (condition index {:.2e}) with",
                    dep.condition_index
                )
            };
            let note = format!("not identifiable: {what} {}", quoted_list(&names, &others));
            if notes[j].is_empty() {
                notes[j] = note;
            }
        }
    }
    for j in 0..p {
        if identifiable[j] && near_share[j] >= VDP_MIN {
            identifiable[j] = false;
            notes[j] = format!(
                "not identifiable: {:.0}% of its variance comes from near-collinear directions",
                100.0 * near_share[j]
            );
        }
        if notes[j].is_empty() && vif[j] > VIF_NOTE {
            notes[j] = format!(
                "VIF {:.1} > {VIF_NOTE}: correlated with other regressors",
                vif[j]
            );
        }
    }

    // Coloured residuals.
    let (cov_colored, std_err_colored) = if opts.colored {
        let mid = toeplitz_gram_cols(std::mem::take(&mut qcols), &resid, opts.max_lag)?;
        let c = &b * &mid * b.transpose();
        let cv: Vec<f64> = (0..p * p)
            .map(|ij| 0.5 * (c[(ij / p, ij % p)] + c[(ij % p, ij / p)]))
            .collect();
        // A negative variance (truncated lags can make the estimate
        // indefinite) has no standard error: NaN, never 0.
        let se: Vec<f64> = (0..p)
            .map(|j| {
                let v = cv[j * p + j];
                if v >= 0.0 {
                    v.sqrt()
                } else {
                    f64::NAN
                }
            })
            .collect();
        (Some(cv), Some(se))
    } else {
        (None, None)
    };
    for q in qcols {
        give_real(q);
    }
    let cluster = clusters.map(|ids| {
        let (idx, ng) = cluster_index(ids, &rows);
        let (w, sc) = if ng >= 2 {
            cluster_grams(x, p, &rows, &idx, ng, &resid[..m], &b)
        } else {
            (Vec::new(), Vec::new())
        };
        let bflat: Vec<f64> = (0..p * nb).map(|ja| b[(ja / nb, ja % nb)]).collect();
        cr2(&w, &sc, ng, nb, &bflat, p)
    });
    give_real(resid);

    Ok(OlsFit {
        names,
        params,
        cov,
        std_err,
        cov_colored,
        std_err_colored,
        cluster,
        t_values,
        p_values,
        partial_f,
        r2,
        r2_adj,
        f_value,
        f_pvalue,
        s2,
        rss,
        tss,
        fit_error_pct,
        press,
        pse,
        singular_values: sv,
        singular_values_scaled: sv_scaled,
        condition_number,
        rank,
        collinearity: Collinearity {
            condition_number,
            condition_number_unscaled,
            vif,
            dependencies,
            rank_deficient,
        },
        identifiable,
        notes,
        nobs: m,
        dof,
        df_model,
        const_column,
        residual_mean: rsum / m as f64,
        dropped_rows: dropped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ErrorKind;
    use proptest::prelude::*;

    fn design(n: usize, p: usize, seed: u64) -> Vec<f64> {
        // Deterministic pseudo-random design (xorshift), column 0 constant.
        let mut s = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        let mut x = vec![0.0; n * p];
        for i in 0..n {
            for j in 0..p {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                x[i * p + j] = if j == 0 {
                    1.0
                } else {
                    (s % 10_000) as f64 / 5000.0 - 1.0
                };
            }
        }
        x
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        #[test]
        fn recovers_params_on_noise_free_data(
            seed in 0u64..10_000,
            n in 20usize..5000,
            theta in proptest::collection::vec(-100.0f64..100.0, 4),
        ) {
            let p = theta.len();
            let x = design(n, p, seed);
            let z: Vec<f64> = (0..n).map(|i| (0..p).map(|j| x[i * p + j] * theta[j]).sum()).collect();
            let f = ols(&x, n, p, &z, &OlsOptions::default()).unwrap();
            for j in 0..p {
                prop_assert!((f.params[j] - theta[j]).abs() <= 1e-9 * (1.0 + theta[j].abs()));
            }
            prop_assert!(f.rss <= 1e-14 * z.iter().map(|v| v * v).sum::<f64>() + 1e-20);
            prop_assert!(f.identifiable.iter().all(|&b| b));
        }
    }

    #[test]
    fn chunked_and_single_chunk_agree_and_subset_equals_copy() {
        let (n, p) = (5000, 3);
        let x = design(n, p, 7);
        let z: Vec<f64> = (0..n)
            .map(|i| x[i * p + 1] * 2.0 - x[i * p + 2] + ((i * 7919) % 13) as f64 * 0.01)
            .collect();
        let rows: Vec<usize> = (0..n).filter(|i| i % 3 != 0).collect();
        let a = ols_rows(&x, n, p, &z, &rows, &OlsOptions::default()).unwrap();
        let xs: Vec<f64> = rows
            .iter()
            .flat_map(|&r| x[r * p..(r + 1) * p].to_vec())
            .collect();
        let zs: Vec<f64> = rows.iter().map(|&r| z[r]).collect();
        let b = ols(&xs, rows.len(), p, &zs, &OlsOptions::default()).unwrap();
        assert_eq!(a.params, b.params);
        assert_eq!(a.std_err_colored, b.std_err_colored);
        // The R² etc. from a 2-chunk and a 1-chunk QR agree closely.
        let c = ols_rows(&x, n, p, &z, &rows[..1000], &OlsOptions::default()).unwrap();
        assert!(c.r2 > 0.9);
    }

    #[test]
    fn clustered_on_all_rows_equals_the_row_list_path() {
        let (n, p) = (5000, 3);
        let x = design(n, p, 17);
        let z: Vec<f64> = (0..n)
            .map(|i| 0.5 * x[i * p + 1] - x[i * p + 2] + ((i * 7919) % 13) as f64 * 0.01)
            .collect();
        // Arbitrary, unsorted ids: 37 clusters of consecutive rows.
        let ids: Vec<u64> = (0..n).map(|i| ((i / 137) as u64 * 7919) % 1009).collect();
        let all: Vec<usize> = (0..n).collect();
        let opts = OlsOptions::default();
        let a = ols_clustered(&x, n, p, &z, &ids, &opts).unwrap();
        let b = ols_rows_clustered(&x, n, p, &z, &all, &ids, &opts).unwrap();
        assert_eq!(a.params, b.params);
        let (ca, cb) = (a.cluster.unwrap(), b.cluster.unwrap());
        assert_eq!(ca, cb);
        assert_eq!(ca.n_clusters, n.div_ceil(137));
        assert!(ca.std_err.iter().all(|s| s.is_finite() && *s > 0.0));
        let e = ols_clustered(&x, n, p, &z, &ids[1..], &opts).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::InvalidInput);
        assert!(e.to_string().contains("clusters"), "{e}");
    }

    #[test]
    fn nan_rows_refused_or_dropped() {
        let (n, p) = (50, 2);
        let mut x = design(n, p, 3);
        let mut z: Vec<f64> = (0..n).map(|i| 1.0 + x[i * p + 1]).collect();
        x[7 * p + 1] = f64::NAN;
        z[11] = f64::INFINITY;
        let opts = OlsOptions {
            names: vec!["one".into(), "beta".into()],
            ..Default::default()
        };
        let e = ols(&x, n, p, &z, &opts).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::InvalidInput);
        let msg = e.to_string();
        assert!(
            msg.contains("row 7 (column 'beta')") && msg.contains("row 11 (z)"),
            "{msg}"
        );
        let f = ols(
            &x,
            n,
            p,
            &z,
            &OlsOptions {
                drop_nan: true,
                ..opts
            },
        )
        .unwrap();
        assert_eq!(f.dropped_rows, vec![7, 11]);
        assert_eq!(f.nobs, 48);
        assert!((f.params[1] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn rank_deficiency_names_columns() {
        let (n, p) = (40, 4);
        let mut x = design(n, p, 5);
        for i in 0..n {
            x[i * p + 3] = x[i * p + 1] + x[i * p + 2];
        }
        let z: Vec<f64> = (0..n).map(|i| x[i * p + 1]).collect();
        let opts = OlsOptions {
            names: vec!["c".into(), "a".into(), "b".into(), "s".into()],
            ..Default::default()
        };
        let e = ols(&x, n, p, &z, &opts).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::TooLittleData);
        let msg = e.to_string();
        assert!(
            msg.contains("'a'")
                && msg.contains("'b'")
                && msg.contains("'s'")
                && !msg.contains("'c'"),
            "{msg}"
        );
        let f = ols(
            &x,
            n,
            p,
            &z,
            &OlsOptions {
                min_norm: true,
                ..opts
            },
        )
        .unwrap();
        assert_eq!(f.rank, 3);
        assert_eq!(f.identifiable, vec![true, false, false, false]);
    }

    #[test]
    fn recycled_buffers_do_not_change_results() {
        let fit_of = |n: usize, seed: u64| {
            let p = 3;
            let x = design(n, p, seed);
            let z: Vec<f64> = (0..n)
                .map(|i| x[i * p + 1] - 0.5 * x[i * p + 2] + ((i * 31) % 7) as f64 * 0.1)
                .collect();
            ols(&x, n, p, &z, &OlsOptions::default()).unwrap()
        };
        let a = fit_of(3000, 1);
        let _ = fit_of(9000, 2);
        let _ = fit_of(500, 3);
        let b = fit_of(3000, 1);
        assert_eq!(a.params, b.params);
        assert_eq!(a.std_err_colored, b.std_err_colored);
        assert_eq!(a.press, b.press);
    }

    #[test]
    fn too_few_rows() {
        let x = design(3, 3, 1);
        let e = ols(&x, 3, 3, &[1.0, 2.0, 3.0], &OlsOptions::default()).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::TooLittleData);
    }

    #[test]
    fn upper_inverse() {
        let r = Mat::from_fn(
            3,
            3,
            |i, j| if j >= i { (1 + i + 2 * j) as f64 } else { 0.0 },
        );
        let inv = inv_upper(&r);
        let prod = &r * &inv;
        for i in 0..3 {
            for j in 0..3 {
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((prod[(i, j)] - e).abs() < 1e-14);
            }
        }
    }
}
