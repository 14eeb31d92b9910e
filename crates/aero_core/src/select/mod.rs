//! Model-structure selection of the Δ model per coefficient and flap setting
//! (thesis Section 2.2 and 3.3.2), validated by cross-validation over maneuvers.
//!
//! The identification regresses the qualified-model error $z$ (Eq. 3.5) bin by
//! bin in alpha. Which regressors of a candidate pool enter the model is
//! decided here, once for all bins of a flap setting (as the thesis keeps one
//! structure per coefficient and flap), in three steps:
//!
//! 1. **Per bin**, a candidate generator orders and cuts the pool:
//!    - *forward stepwise regression* (Klein, Batterson & Murphy 1981; Klein &
//!      Morelli 2006, Section 5.4.2; SIDPAC `swr`): start from the forced
//!      terms (the bias), add the candidate of largest partial F (Eq. 2.5)
//!      while it exceeds $F_{in}$, drop a term whose partial F fell below
//!      $F_{out}$; default $F_{in} = F_{out} = 4$ (SIDPAC's cut-off);
//!    - *multivariate orthogonal functions* (Morelli 1995): orthogonalise the
//!      candidates greedily in order of the largest reduction of the residual
//!      sum of squares and keep the prefix minimising the predicted squared
//!      error $PSE = \frac{1}{N}(z-\hat y)^T(z-\hat y) + \sigma^2_{max}\frac{k}{N}$,
//!      $\sigma^2_{max} = \frac{1}{N}\sum (z - \bar z)^2$ (Morelli 1995, Eq. 28-29).
//!
//!    Neighbouring samples are correlated (the residuals are coloured), so the
//!    white-residual F and PSE penalty overstate the information in $N$
//!    samples. Both are scaled by the bin's variance inflation $\kappa \ge 1$
//!    of the full pool fit: $F/\kappa$ is compared with $F_{in}$, and the PSE
//!    penalty is $\kappa\,\sigma^2_{max} k/N$ (the effective sample size is
//!    $N/\kappa$). With coloured-residual standard errors in the pool fit
//!    (Morelli & Klein, Eq. 5.80), $\kappa = \mathrm{median}_j\,(s_{colored,j}/s_j)^2$;
//!    without (the fast path of [`identify_flap`]), the integrated
//!    autocorrelation of the pool fit's residuals within maneuver segments,
//!    $\kappa = 1 + 2\sum_{k=1}^{L}(1-\tfrac{k}{L+1})\rho_k$, $L = 50$ samples
//!    (Bartlett window): the inflation of the variance of a mean, the case of
//!    slowly varying regressors.
//! 2. **Per flap**, each candidate's *selection frequency* (share of fitted
//!    bins that selected it) is counted; candidates selected in fewer than
//!    `min_bins` bins are dropped.
//! 3. **Cross-validation over maneuvers** (K folds of whole maneuvers, never
//!    of samples: neighbouring samples are correlated) scores nested
//!    structures bin by bin along a greedy path: from the forced columns, the
//!    remaining candidate whose addition lowers the CV error most is added
//!    next (a training fit leaves out the regressors its data do not excite,
//!    as the final per-bin fit does); the smallest k
//!    whose CV mean squared error is within one standard error of the best is
//!    kept (the one-standard-error rule, Hastie, Tibshirani & Friedman 2009,
//!    Section 7.10, with the standard error of the fold-by-fold differences
//!    from the best, [`CvScore::paired_se`]); then kept candidates are dropped one at a time while
//!    that lowers the cross-validated error (backward elimination on the
//!    held-out error).
//!
//! Everything after the per-bin row pass works on per-(bin, maneuver)
//! augmented Gram matrices $[X\ z]^T[X\ z]$ ([`BinGrams`]), so the subset
//! regressions, the folds and the bootstrap of [`crate::bootstrap`] cost
//! $O(p^3)$ per bin, independent of the number of samples.

// Index loops over the p columns read closer to the formulas.
#![allow(clippy::needless_range_loop)]

use crate::bootstrap::{bootstrap_smoothed, Bootstrap, BootstrapOptions, Reselect};
use crate::error::{AeroError, Result, ResultExt};
use crate::identify::{
    adjacent_consistency, fit_bins, fit_planned, low_excitation, noise_floor, plan_bins,
    smooth_parameters, snr, BinFit, BinnedFit, Design, IdentifyOptions, SmoothOptions,
    SmoothedParameter,
};
use crate::partition::partition_alpha;
use crate::sim::rng::Stream;
use std::borrow::Cow;

mod collinear;
mod folds;
mod path;
use folds::{CvGrams, FoldGrams};
mod stepwise;
pub use collinear::{
    collinear_to_prune, fitted_totals, gram_collinearity, planned_totals, BinCollinearity, Pruned,
};
pub use stepwise::stepwise;

/// Per-maneuver sufficient statistics of one bin.
#[derive(Debug, Clone, Default)]
pub struct BinStats {
    /// Maneuver ids present in the bin, increasing.
    pub maneuvers: Vec<u64>,
    /// Samples per maneuver.
    pub n: Vec<usize>,
    /// Per maneuver, the lower triangle by rows of the augmented Gram matrix of the scaled
    /// columns (the last column is z), then the column sums ([`packed_width`] entries each,
    /// concatenated): what [`BinStats::fold_totals`] adds up, contiguously.
    pub packed: Vec<f64>,
}

/// Entries of a maneuver's [`BinStats::packed`] statistics for an augmented Gram matrix of
/// `dim` columns.
pub fn packed_width(dim: usize) -> usize {
    dim * (dim + 1) / 2 + dim
}

/// The sufficient statistics of all bins of a binned fit.
#[derive(Debug, Clone)]
pub struct BinGrams {
    /// Number of regressor columns plus one (z).
    pub dim: usize,
    /// Column scales (RMS over the flap's rows; 1 for an all-zero column), the last for z.
    pub scale: Vec<f64>,
    /// Per bin.
    pub bins: Vec<BinStats>,
}

impl BinStats {
    /// Weighted sum over maneuvers (`weights[k]` for the k-th maneuver of the
    /// bin, or all ones): Gram matrix, sums and number of samples ([`BinStats::fold_totals`]
    /// with one fold).
    pub fn total(&self, dim: usize, weights: Option<&[f64]>) -> (Vec<f64>, Vec<f64>, f64) {
        let mut one = self.fold_totals(dim, 1, |_| Some(0), |k| weights.map_or(1.0, |w| w[k]));
        one.pop()
            .unwrap_or_else(|| (vec![0.0; dim * dim], vec![0.0; dim], 0.0))
    }

    /// Weighted sums per fold in one pass over the maneuvers: the k-th maneuver of the bin
    /// adds `weight(k)` times its Gram matrix, sums and sample count to fold `fold(k)` (none:
    /// to no fold), maneuvers in order; a zero weight adds nothing.
    pub fn fold_totals(
        &self,
        dim: usize,
        folds: usize,
        fold: impl Fn(usize) -> Option<usize>,
        weight: impl Fn(usize) -> f64,
    ) -> Vec<(Vec<f64>, Vec<f64>, f64)> {
        let wdt = packed_width(dim);
        let mut acc = vec![0.0; folds * wdt];
        let mut count = vec![0.0; folds];
        self.add_packed(dim, folds, fold, weight, &mut acc, &mut count);
        acc.chunks_exact(wdt.max(1))
            .zip(count)
            .map(|(pk, n)| {
                let (tri, sums) = pk.split_at(wdt - dim);
                (unpack_lower(tri, dim), sums.to_vec(), n)
            })
            .collect()
    }

    /// Adds `weight(k)` times the k-th maneuver's packed statistics ([`BinStats::packed`]) to
    /// fold `fold(k)`'s run of `acc` (`folds` runs of [`packed_width`]) and its samples to
    /// `count[fold(k)]`, maneuvers in order (one contiguous axpy each); a zero weight or no
    /// fold adds nothing.
    pub fn add_packed(
        &self,
        dim: usize,
        folds: usize,
        fold: impl Fn(usize) -> Option<usize>,
        weight: impl Fn(usize) -> f64,
        acc: &mut [f64],
        count: &mut [f64],
    ) {
        let (wdt, packed) = (packed_width(dim), &self.packed);
        for k in 0..self.maneuvers.len() {
            let Some(f) = fold(k).filter(|&f| f < folds) else {
                continue;
            };
            let w = weight(k);
            if w == 0.0 {
                continue;
            }
            count[f] += w * self.n[k] as f64;
            for (a, b) in acc[f * wdt..(f + 1) * wdt]
                .iter_mut()
                .zip(&packed[k * wdt..(k + 1) * wdt])
            {
                *a += w * b;
            }
        }
    }
}

/// The symmetric `dim × dim` matrix (row-major) of a lower triangle packed by rows.
fn unpack_lower(tri: &[f64], dim: usize) -> Vec<f64> {
    let mut g = vec![0.0; dim * dim];
    unpack_lower_into(tri, dim, &mut g);
    g
}

/// [`unpack_lower`] into `g` (`dim × dim`, every entry written).
fn unpack_lower_into(tri: &[f64], dim: usize, g: &mut [f64]) {
    let mut at = 0;
    for i in 0..dim {
        for j in 0..=i {
            g[i * dim + j] = tri[at];
            g[j * dim + i] = tri[at];
            at += 1;
        }
    }
}

/// Add `Σ_r x_r x_rᵀ` over the rows of `rows` (row-major, `dim` wide) to the lower triangle
/// `tri` (packed by rows). Each entry is summed over the rows in their order, a few entries
/// of a row of the triangle at a time held in registers: the same sums, in the same order,
/// as adding one row's outer product after another.
fn gram_lower_add(rows: &[f64], dim: usize, tri: &mut [f64]) {
    let mut at = 0;
    for a in 0..dim {
        let len = a + 1;
        let mut b0 = 0;
        while b0 < len {
            // the widest kernel that stays inside the row; entries past the triangle's row
            // (b > a) are computed and not stored
            let w = len - b0;
            let done = if b0 + 8 <= dim {
                gram_entries::<8>(rows, dim, a, b0, &mut tri[at + b0..at + len])
            } else if b0 + 4 <= dim {
                gram_entries::<4>(rows, dim, a, b0, &mut tri[at + b0..at + len])
            } else if b0 + 2 <= dim {
                gram_entries::<2>(rows, dim, a, b0, &mut tri[at + b0..at + len])
            } else {
                gram_entries::<1>(rows, dim, a, b0, &mut tri[at + b0..at + len])
            };
            debug_assert!(done >= 1 && done <= w);
            b0 += done;
        }
        at += len;
    }
}

/// `out[k] += Σ_r x_r[a] x_r[b0 + k]` for `k < min(W, out.len())`, summed over the rows in
/// order in `W` registers (`b0 + W <= dim`); returns how many entries were written.
#[inline(always)]
fn gram_entries<const W: usize>(
    rows: &[f64],
    dim: usize,
    a: usize,
    b0: usize,
    out: &mut [f64],
) -> usize {
    let w = W.min(out.len());
    let mut acc = [0.0f64; W];
    // copied in and out entry by entry over the W registers (masked past `w`): a slice copy of
    // the variable length `w` is a call to memcpy, which cost more than a maneuver's few rows
    for k in 0..W {
        if k < w {
            acc[k] = out[k];
        }
    }
    for row in rows.chunks_exact(dim) {
        let xa = row[a];
        if let Ok(xb) = <&[f64; W]>::try_from(&row[b0..b0 + W]) {
            for k in 0..W {
                acc[k] += xa * xb[k];
            }
        }
    }
    for k in 0..W {
        if k < w {
            out[k] = acc[k];
        }
    }
    w
}

/// Accumulate the per-(bin, maneuver) augmented Gram matrices of `design`
/// and `z` over the bins' rows (`members[b]`: row indices of bin b). Rows with
/// a non-finite regressor or z are skipped (as the per-bin fit drops them).
pub fn bin_grams(design: &Design, z: &[f64], members: &[Vec<usize>], maneuver: &[u64]) -> BinGrams {
    let p = design.ncols();
    let dim = p + 1;
    // rows with every regressor and z finite, decided once
    let ok: Vec<bool> = (0..design.nrows.min(z.len()))
        .map(|r| {
            z[r].is_finite()
                && design.values[r * p..(r + 1) * p]
                    .iter()
                    .all(|v| v.is_finite())
        })
        .collect();
    let row_ok = |r: usize| ok[r];
    // column scales over every binned row
    let mut ss = vec![0.0; dim];
    let mut cnt = 0.0f64;
    for rows in members {
        for &r in rows {
            if !row_ok(r) {
                continue;
            }
            cnt += 1.0;
            for j in 0..p {
                ss[j] += design.values[r * p + j].powi(2);
            }
            ss[p] += z[r] * z[r];
        }
    }
    let scale: Vec<f64> = ss
        .iter()
        .map(|s| {
            let r = (s / cnt.max(1.0)).sqrt();
            if r > 0.0 && r.is_finite() {
                r
            } else {
                1.0
            }
        })
        .collect();
    let wdt = packed_width(dim);
    let work = |rows: &Vec<usize>| -> BinStats {
        let mut order: Vec<usize> = rows.iter().copied().filter(|&r| row_ok(r)).collect();
        order.sort_by_key(|&r| maneuver[r]);
        // sized once: one run of packed statistics per maneuver
        let groups = order.chunk_by(|&a, &b| maneuver[a] == maneuver[b]).count();
        let mut st = BinStats {
            maneuvers: Vec::with_capacity(groups),
            n: Vec::with_capacity(groups),
            packed: Vec::with_capacity(groups * wdt),
        };
        // one maneuver's scaled rows (row-major, `dim` wide) at a time
        let mut buf: Vec<f64> = Vec::new();
        for group in order.chunk_by(|&a, &b| maneuver[a] == maneuver[b]) {
            buf.clear();
            for &r in group {
                let x = &design.values[r * p..(r + 1) * p];
                buf.extend(x.iter().zip(&scale).map(|(v, s)| v / s));
                buf.push(z[r] / scale[p]);
            }
            st.maneuvers.push(maneuver[group[0]]);
            st.n.push(group.len());
            let at = st.packed.len();
            st.packed.extend(std::iter::repeat_n(0.0, wdt));
            let (tri, sums) = st.packed[at..].split_at_mut(wdt - dim);
            gram_lower_add(&buf, dim, tri);
            for row in buf.chunks_exact(dim) {
                for (s, x) in sums.iter_mut().zip(row) {
                    *s += x;
                }
            }
        }
        st
    };
    #[cfg(feature = "parallel")]
    let bins = {
        use rayon::prelude::*;
        members.par_iter().map(work).collect()
    };
    #[cfg(not(feature = "parallel"))]
    let bins = members.iter().map(work).collect();
    BinGrams { dim, scale, bins }
}

/// Least squares on the columns `cols` from an augmented Gram matrix `g`
/// (`dim × dim`, z last), by Cholesky of the normal equations (the columns
/// are scaled to unit RMS, so their condition is that of the data's
/// correlation). Returns the estimates (scaled units) and the residual sum
/// of squares, or `None` when the columns are (numerically) dependent: a
/// Cholesky pivot below `1e-10` of its diagonal.
pub fn solve_subset(g: &[f64], dim: usize, cols: &[usize]) -> Option<(Vec<f64>, f64)> {
    let (mut work, mut th) = (Vec::new(), Vec::new());
    solve_subset_into(g, dim, cols, &mut work, &mut th).map(|sse| (th, sse))
}

/// [`solve_subset`] into the caller's buffers (no allocation once they have grown): the
/// estimates in `th`, `work` as scratch; returns the residual sum of squares.
pub fn solve_subset_into(
    g: &[f64],
    dim: usize,
    cols: &[usize],
    work: &mut Vec<f64>,
    th: &mut Vec<f64>,
) -> Option<f64> {
    let k = cols.len();
    let zc = dim - 1;
    th.clear();
    if k == 0 {
        return Some(g[zc * dim + zc].max(0.0));
    }
    // work: the Cholesky factor (k × k), then the forward solution (k)
    work.clear();
    work.resize(k * k + k, 0.0);
    let (l, y) = work.split_at_mut(k * k);
    if !(0..k).all(|i| cholesky_row(g, dim, cols, i, l, k)) {
        return None;
    }
    th.resize(k, 0.0);
    cholesky_solve(g, dim, cols, l, k, y, th);
    let fit: f64 = th.iter().zip(cols).map(|(t, &c)| t * g[c * dim + zc]).sum();
    let sse = (g[zc * dim + zc] - fit).max(0.0);
    th.iter().all(|v| v.is_finite()).then_some(sse)
}

/// The columns `0..p` of the augmented Gram matrix `g` kept in order when each is tried
/// after the kept ones and left out where [`solve_subset`] of the kept ones and it fails (a
/// Cholesky pivot below `1e-10` of its diagonal, or estimates not finite). The factor is
/// grown a row per column: the rows of a Cholesky factor of the first `k` columns are those of
/// the first `k` rows of any longer one, so each trial costs `O(k²)`, not a factorization, and
/// decides as the trial factorization does, to the bit.
fn independent_columns(g: &[f64], dim: usize, p: usize) -> Vec<usize> {
    independent_subset(g, dim, &(0..p).collect::<Vec<_>>())
}

/// [`independent_columns`] over the columns `candidates` of `g`, tried in their order.
pub(crate) fn independent_subset(g: &[f64], dim: usize, candidates: &[usize]) -> Vec<usize> {
    let p = candidates.len();
    let mut cols: Vec<usize> = Vec::with_capacity(p);
    // rows of L with stride p, the forward solution y and the estimates th
    let mut l = vec![0.0; p * p];
    let (mut y, mut th) = (vec![0.0; p], vec![0.0; p]);
    for &c in candidates {
        // the trial: row k - 1 of L for the columns cols + [c], then the solution with it
        cols.push(c);
        let k = cols.len();
        let kept = cholesky_row(g, dim, &cols, k - 1, &mut l, p) && {
            cholesky_solve(g, dim, &cols, &l, p, &mut y[..k], &mut th[..k]);
            th[..k].iter().all(|v| v.is_finite())
        };
        if !kept {
            cols.pop();
        }
    }
    cols
}

/// Row `i` of the Cholesky factor `l` (rows `stride` apart, rows `0..i` already there) of
/// the augmented Gram matrix `g` over the columns `cols[..=i]`; false when the pivot is NaN,
/// not positive, or below `1e-10` of its diagonal: column `cols[i]` depends on the earlier
/// ones (the rule of [`solve_subset`]).
#[inline]
fn cholesky_row(
    g: &[f64],
    dim: usize,
    cols: &[usize],
    i: usize,
    l: &mut [f64],
    stride: usize,
) -> bool {
    let c = cols[i];
    for j in 0..=i {
        let mut s = g[c * dim + cols[j]];
        for m in 0..j {
            s -= l[i * stride + m] * l[j * stride + m];
        }
        if i == j {
            let d = g[c * dim + c];
            if s.is_nan() || s <= 1e-10 * d || d <= 0.0 {
                return false;
            }
            l[i * stride + i] = s.sqrt();
        } else {
            l[i * stride + j] = s / l[j * stride + j];
        }
    }
    true
}

/// The least-squares estimates `th` of `z` (the last column of `g`) on `cols` from their
/// Cholesky factor `l` (rows `stride` apart): forward substitution into `y`, then back
/// substitution (`y` and `th` of `cols.len()` entries).
#[inline]
fn cholesky_solve(
    g: &[f64],
    dim: usize,
    cols: &[usize],
    l: &[f64],
    stride: usize,
    y: &mut [f64],
    th: &mut [f64],
) {
    let (k, zc) = (cols.len(), dim - 1);
    for i in 0..k {
        let mut s = g[cols[i] * dim + zc];
        for m in 0..i {
            s -= l[i * stride + m] * y[m];
        }
        y[i] = s / l[i * stride + i];
    }
    for i in (0..k).rev() {
        let mut s = y[i];
        for m in i + 1..k {
            s -= l[m * stride + i] * th[m];
        }
        th[i] = s / l[i * stride + i];
    }
}

/// Held-out sums of a fit `theta` on `cols` against another augmented Gram
/// matrix: `(Σ(z-ẑ)², Σz², Σẑ²)` in scaled units.
pub fn held_out(g: &[f64], dim: usize, cols: &[usize], theta: &[f64]) -> (f64, f64, f64) {
    let zc = dim - 1;
    let zz = g[zc * dim + zc];
    let mut cross = 0.0;
    let mut yy = 0.0;
    // θᵀGθ over the lower triangle (G symmetric)
    for (i, &a) in cols.iter().enumerate() {
        cross += theta[i] * g[a * dim + zc];
        let row = &g[a * dim..(a + 1) * dim];
        let mut off = 0.0;
        for (j, &b) in cols[..i].iter().enumerate() {
            off += theta[j] * row[b];
        }
        yy += theta[i] * (2.0 * off + theta[i] * row[a]);
    }
    ((zz - 2.0 * cross + yy).max(0.0), zz, yy.max(0.0))
}

/// Multivariate orthogonal functions with the predicted squared error
/// (Morelli 1995): greedy orthogonalisation in order of the largest residual
/// reduction, cut at the minimum of the (κ-scaled) PSE. Returns the selected
/// columns (forced first).
pub fn mof_pse(
    g: &[f64],
    dim: usize,
    n: f64,
    forced: &[usize],
    candidates: &[usize],
    kappa: f64,
) -> Vec<usize> {
    let mut sel: Vec<usize> = Vec::new();
    for &c in forced {
        sel.push(c);
        if solve_subset(g, dim, &sel).is_none() {
            sel.pop();
        }
    }
    let Some((_, sse0)) = solve_subset(g, dim, &sel) else {
        return sel;
    };
    if n <= 0.0 {
        return sel;
    }
    // σ²_max about the mean when the bias is forced, else about zero
    let s2max = sse0 / n;
    let pen = kappa.max(1.0) * s2max / n;
    let pse = |sse: f64, k: usize| sse / n + pen * k as f64;
    let mut best_len = sel.len();
    let mut best = pse(sse0, sel.len());
    let mut order = sel.clone();
    loop {
        let mut next: Option<(usize, f64)> = None;
        for &c in candidates {
            if order.contains(&c) {
                continue;
            }
            let mut t = order.clone();
            t.push(c);
            if let Some((_, e)) = solve_subset(g, dim, &t) {
                if next.is_none_or(|(_, be)| e < be) {
                    next = Some((c, e));
                }
            }
        }
        let Some((c, e)) = next else { break };
        order.push(c);
        let v = pse(e, order.len());
        if v < best {
            best = v;
            best_len = order.len();
        }
    }
    order.truncate(best_len);
    order
}

/// Candidate generator of the per-bin step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Forward stepwise regression with partial F.
    Stepwise,
    /// Multivariate orthogonal functions with PSE.
    Mof,
}

/// Settings of [`select_structure`].
#[derive(Debug, Clone)]
pub struct SelectOptions {
    /// Per-bin candidate generator.
    pub method: Method,
    /// Partial F to enter (after the κ scaling; SIDPAC: 4).
    pub f_in: f64,
    /// Partial F to stay.
    pub f_out: f64,
    /// A candidate may not enter a bin's stepwise regression if afterwards a selected
    /// non-forced column's variance inflation factor exceeds this (see [`stepwise`];
    /// Klein & Morelli 2006, Section 5.4.1: 10). `f64::INFINITY`: no guard.
    pub max_vif: f64,
    /// Columns always in the model (e.g. the bias).
    pub forced: Vec<usize>,
    /// A candidate must be selected in at least this many bins of the flap.
    pub min_bins: usize,
    /// Number of cross-validation folds (whole maneuvers).
    pub folds: usize,
    /// Seed of the maneuvers' assignment to folds.
    pub seed: u64,
    /// A candidate with in-bin excitation below this (see
    /// [`crate::identify::IdentifyOptions::min_excitation`]) may not enter in that bin.
    pub min_excitation: f64,
    /// Nor below this multiple of its noise floor (see
    /// [`crate::identify::IdentifyOptions::min_excitation_snr`]).
    pub min_excitation_snr: f64,
    /// Training points per parameter a fold's bin regression needs; with
    /// fewer, the fold predicts the training fit of the forced columns there (zero Δ when
    /// even those cannot be fitted; see `fallback_sums`).
    pub min_points_per_param: usize,
    /// Extra structures to score by cross-validation (column lists), e.g.
    /// the thesis's default structure.
    pub extra: Vec<Vec<usize>>,
    /// Score the selection itself by nested cross-validation ([`Selection::outer`]): the
    /// whole selection reruns once per fold on the other folds' maneuvers. Costs `folds`
    /// more selections.
    pub nested: bool,
    /// Companion columns `(a, b)`: when the selection keeps `a` (after the
    /// one-standard-error rule and the backward pruning), it adds `b` if the structure with
    /// `b` predicts the held-out maneuvers within one standard error of the structure without
    /// it (the standard error of its cross-validated error over the folds, the classic
    /// one-standard-error rule of Hastie, Tibshirani & Friedman 2009, Section 7.10, turned the
    /// other way), for a term whose absence biases a reported parameter more than the
    /// held-out error can see. `|β|` with `β`: the kink of a table piecewise linear in β
    /// at β = 0 goes into the intercept and the slope without it, while most samples have
    /// small |β|. Where the aircraft has no kink and `|β|` only adds variance, the held-out
    /// error rises by more than that and it stays out. A companion a bin cannot identify
    /// (collinear, not excited) is then marked as such by the per-bin fit.
    pub companions: Vec<(usize, usize)>,
}

impl Default for SelectOptions {
    fn default() -> Self {
        SelectOptions {
            method: Method::Stepwise,
            f_in: 4.0,
            f_out: 4.0,
            max_vif: 10.0,
            forced: vec![0],
            min_bins: 4,
            folds: 5,
            seed: 0,
            min_excitation: 0.05,
            min_excitation_snr: 3.0,
            min_points_per_param: 10,
            extra: Vec::new(),
            nested: true,
            companions: Vec::new(),
        }
    }
}

/// Cross-validated score of one structure.
#[derive(Debug, Clone, PartialEq)]
pub struct CvScore {
    /// Columns of the structure.
    pub columns: Vec<usize>,
    /// Held-out RMS of z - ẑ (units of z).
    pub rms: f64,
    /// Held-out Theil inequality coefficient of ẑ against z.
    pub tic: f64,
    /// Held-out mean squared error (units of z squared).
    pub mse: f64,
    /// Standard error of `mse` over the folds.
    pub mse_se: f64,
    /// Held-out mean squared error of each fold (NaN for a fold with no held-out sample).
    pub fold_mse: Vec<f64>,
}

impl CvScore {
    /// The score of `columns` when it was not computed (NaN everywhere).
    pub fn not_computed(columns: &[usize]) -> Self {
        CvScore {
            columns: columns.to_vec(),
            rms: f64::NAN,
            tic: f64::NAN,
            mse: f64::NAN,
            mse_se: f64::NAN,
            fold_mse: Vec::new(),
        }
    }

    /// Standard error of the mean fold-by-fold difference `self − other` of the held-out
    /// MSE (paired over the folds; NaN with fewer than two common folds).
    ///
    /// The maneuvers of a fold are the same for every structure, so the differences
    /// cancel the between-fold spread that both share (a fold holding a hard maneuver is
    /// hard for every structure): with a few maneuvers per flap the unpaired
    /// [`CvScore::mse_se`] can be as large as the error itself, and the
    /// one-standard-error rule then accepts any structure, down to the intercept alone.
    pub fn paired_se(&self, other: &CvScore) -> f64 {
        let d: Vec<f64> = self
            .fold_mse
            .iter()
            .zip(&other.fold_mse)
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .map(|(a, b)| a - b)
            .collect();
        let k = d.len() as f64;
        if k < 2.0 {
            return f64::NAN;
        }
        let m = d.iter().sum::<f64>() / k;
        (d.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (k - 1.0) / k).sqrt()
    }
}

/// The outcome of [`select_structure`].
#[derive(Debug, Clone)]
pub struct Selection {
    /// Per bin of the pool fit, per pool column: selected in that bin.
    pub selected: Vec<Vec<bool>>,
    /// Per bin, per pool column: final partial F (κ-scaled; NaN when not computed).
    pub partial_f: Vec<Vec<f64>>,
    /// Per bin, per pool column: correlation of z with the regressor.
    pub correlation: Vec<Vec<f64>>,
    /// Per bin: variance inflation κ used.
    pub kappa: Vec<f64>,
    /// Per bin: the bin was fitted (enough data) and took part.
    pub fitted: Vec<bool>,
    /// Per pool column: number of fitted bins that selected it.
    pub count: Vec<usize>,
    /// The nested structures scored (forced + the k most frequent), k = 0, 1, ...
    pub nested: Vec<CvScore>,
    /// The full pool's score.
    pub full: CvScore,
    /// Scores of [`SelectOptions::extra`].
    pub extra: Vec<CvScore>,
    /// Chosen columns (increasing).
    pub chosen: Vec<usize>,
    /// Index into `nested` of the structure chosen by the one-standard-error rule.
    pub chosen_k: usize,
    /// Score of the final structure (`chosen`, after the backward pruning). Optimistic:
    /// the same folds chose it.
    pub pruned: CvScore,
    /// The selection's own held-out score (with [`SelectOptions::nested`]): for each fold, the
    /// whole selection (per-bin stepwise, frequencies, cross-validated path on the remaining
    /// folds, one-standard-error rule, backward pruning) runs on the other folds' maneuvers,
    /// and the structure it chooses, fitted on them, predicts the fold (Hastie, Tibshirani &
    /// Friedman 2009, Section 7.10.2, "the right way"). This is the number to quote for
    /// the selected structure; `pruned` is not. The bins, the excitation marks and the
    /// coloured-residual inflation κ come from all maneuvers (they read the regressors and
    /// the pool fit's residual colour, not which terms predict the held-out responses).
    /// `columns` are the final structure's; per fold the chosen columns differ.
    pub outer: Option<CvScore>,
    /// Per fold, the columns the fold's own selection chose (empty without `nested`).
    pub outer_chosen: Vec<Vec<usize>>,
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// Variance inflation of coloured residuals in one bin of a fit:
/// `median_j (s_colored,j / s_j)²`, at least 1 (1 when not available).
pub fn bin_kappa(fit: &BinnedFit, b: usize) -> f64 {
    let bin = &fit.bins[b];
    let r: Vec<f64> = (0..bin.params.len())
        .filter(|&j| bin.identifiable[j])
        .map(|j| (bin.std_err_colored[j] / bin.std_err[j]).powi(2))
        .filter(|v| v.is_finite())
        .collect();
    let k = median(r);
    if k.is_finite() {
        k.max(1.0)
    } else {
        1.0
    }
}

/// Largest lag of the residual autocorrelation in [`residual_kappa`], samples.
pub const KAPPA_MAX_LAG: usize = 50;

/// Variance inflation from the residuals of one bin's fit (see the module
/// doc): `rows` increasing (time order within each maneuver), `theta` the bin's
/// estimates. Lags pair rows within one run of consecutive rows of the same maneuver;
/// each lag's autocovariance is summed run by run, in row order.
pub fn residual_kappa(
    design: &Design,
    z: &[f64],
    maneuver: &[u64],
    rows: &[usize],
    theta: &[f64],
) -> f64 {
    let p = design.ncols();
    if theta.len() != p || theta.iter().any(|t| !t.is_finite()) {
        return 1.0;
    }
    let r: Vec<f64> = rows
        .iter()
        .map(|&i| {
            let x = &design.values[i * p..(i + 1) * p];
            z[i] - x.iter().zip(theta).map(|(a, b)| a * b).sum::<f64>()
        })
        .collect();
    let mean = {
        let (s, c) = r
            .iter()
            .filter(|v| v.is_finite())
            .fold((0.0, 0.0), |(s, c), v| (s + v, c + 1.0));
        if c > 0.0 {
            s / c
        } else {
            return 1.0;
        }
    };
    // centred residuals, zero where not finite (such a row adds nothing to any lag)
    let d: Vec<f64> = r
        .iter()
        .map(|v| if v.is_finite() { v - mean } else { 0.0 })
        .collect();
    let g0: f64 = r
        .iter()
        .filter(|v| v.is_finite())
        .map(|v| (v - mean).powi(2))
        .sum();
    if g0 <= 0.0 {
        return 1.0;
    }
    // runs of consecutive rows of one maneuver: [start, end) in positions of `rows`
    let mut runs = Vec::new();
    let mut start = 0;
    for m in 1..=rows.len() {
        if m == rows.len()
            || rows[m] != rows[m - 1] + 1
            || maneuver[rows[m]] != maneuver[rows[m - 1]]
        {
            runs.push((start, m));
            start = m;
        }
    }
    let mut k_sum = 0.0;
    for k in 1..=KAPPA_MAX_LAG.min(rows.len().saturating_sub(1)) {
        let mut g = 0.0;
        for &(a, b) in &runs {
            if b - a > k {
                for (x, y) in d[a..b - k].iter().zip(&d[a + k..b]) {
                    g += x * y;
                }
            }
        }
        k_sum += (1.0 - k as f64 / (KAPPA_MAX_LAG as f64 + 1.0)) * g / g0;
    }
    (1.0 + 2.0 * k_sum).max(1.0)
}

/// Rows of each bin of a binned fit.
pub fn bin_members(fit: &BinnedFit) -> Vec<Vec<usize>> {
    let mut members = vec![Vec::new(); fit.bins.len()];
    for (r, &b) in fit.partition.index.iter().enumerate() {
        if b >= 0 {
            members[b as usize].push(r);
        }
    }
    members
}

/// Cross-validation folds: fold index of each maneuver id (sorted ids,
/// seeded shuffle, round robin).
fn fold_of(maneuver: &[u64], folds: usize, seed: u64) -> std::collections::HashMap<u64, usize> {
    // rows come in runs per maneuver: collapse the runs before sorting
    let mut ids: Vec<u64> = Vec::new();
    for &m in maneuver {
        if ids.last() != Some(&m) {
            ids.push(m);
        }
    }
    ids.sort_unstable();
    ids.dedup();
    let mut rng = Stream::new(seed, 0x5e1ec7);
    for i in (1..ids.len()).rev() {
        let j = (rng.next_u64() % (i as u64 + 1)) as usize;
        ids.swap(i, j);
    }
    ids.iter()
        .enumerate()
        .map(|(i, &m)| (m, i % folds.max(1)))
        .collect()
}

/// What a training fit may use: the flap-wide standard deviation of each
/// (scaled) column, which columns are constant, and the low-excitation
/// threshold of [`crate::identify::IdentifyOptions::min_excitation`].
struct Excitation<'a> {
    flap_sd: &'a [f64],
    constant: &'a [bool],
    min: f64,
}

impl Excitation<'_> {
    /// The columns of `cols` the training data `(g, s, n)` of one bin excite:
    /// as in the final per-bin fit, a regressor whose in-bin standard deviation
    /// is below `min` times the flap's is not identifiable there and is left out
    /// of the fit (its held-out contribution is zero) instead of being estimated
    /// from the little variation the training maneuvers happen to hold.
    /// The excited columns go into `out` (cleared first).
    fn excited(
        &self,
        g: &[f64],
        s: &[f64],
        n: f64,
        dim: usize,
        cols: &[usize],
        out: &mut Vec<usize>,
    ) {
        out.clear();
        out.extend(cols.iter().copied().filter(|&j| {
            if self.constant[j] {
                return true;
            }
            if n <= 1.0 || self.flap_sd[j] <= 0.0 {
                return false;
            }
            let v = ((g[j * dim + j] - s[j] * s[j] / n) / (n - 1.0)).max(0.0);
            v.sqrt() >= self.min * self.flap_sd[j]
        }));
    }
}

#[allow(clippy::too_many_arguments)]
fn cv_score(
    grams: &BinGrams,
    trains: &FoldGrams,
    folds: &FoldGrams,
    fitted: &[bool],
    cols: &[usize],
    min_points: usize,
    excitation: &Excitation<'_>,
    fallback: &[(f64, f64, f64)],
) -> CvScore {
    cv_score_per_fold(
        grams,
        trains,
        folds,
        fitted,
        &|_| cols,
        min_points,
        excitation,
        cols,
        fallback,
    )
}

/// [`cv_score`] with the columns of each fold's training fit given by `cols_of(fold)` (the
/// structure a selection chose on that fold's training maneuvers); `label` is the score's
/// [`CvScore::columns`]. Where the training maneuvers cannot fit the structure in a bin, the
/// fold predicts what [`fallback_sums`] gives.
#[allow(clippy::too_many_arguments)]
fn cv_score_per_fold<'c>(
    grams: &BinGrams,
    trains: &FoldGrams,
    folds: &FoldGrams,
    fitted: &[bool],
    cols_of: &dyn Fn(usize) -> &'c [usize],
    min_points: usize,
    excitation: &Excitation<'_>,
    label: &[usize],
    fallback: &[(f64, f64, f64)],
) -> CvScore {
    let dim = grams.dim;
    let nf = folds.folds();
    let mut acc = CvAccum::new(nf);
    // buffers reused over the bins and folds (the path search calls this thousands of times)
    let mut buf = CellBuffers::default();
    for c in fold_cells(fitted, folds, trains) {
        let (e, z2, y2) = cell_fit(&c, dim, cols_of(c.f), min_points, excitation, &mut buf)
            .unwrap_or(fallback[c.b * nf + c.f]);
        acc.add(c.f, e, z2, y2, c.n_fold);
    }
    acc.finish(grams.scale[dim - 1].powi(2), label)
}

/// One bin and fold of the cross-validation: the fold's Gram matrix and samples, its
/// training set's Gram matrix, column sums and samples.
struct FoldCell<'g> {
    b: usize,
    f: usize,
    fold: &'g [f64],
    n_fold: f64,
    train: &'g [f64],
    train_sums: &'g [f64],
    n_train: f64,
}

/// The cells of the fitted bins' non-empty folds, bin by bin, folds in order.
fn fold_cells<'a, 'g: 'a>(
    fitted: &'a [bool],
    folds: &'g FoldGrams,
    trains: &'g FoldGrams,
) -> impl Iterator<Item = FoldCell<'g>> + 'a {
    let nf = folds.folds();
    fitted
        .iter()
        .enumerate()
        .filter(|(_, &ok)| ok)
        .flat_map(move |(b, _)| (0..nf).map(move |f| (b, f)))
        .filter_map(move |(b, f)| {
            let (fold, _, n_fold) = folds.get(b, f);
            let (train, train_sums, n_train) = trains.get(b, f);
            (n_fold != 0.0).then_some(FoldCell {
                b,
                f,
                fold,
                n_fold,
                train,
                train_sums,
                n_train,
            })
        })
}

/// Scratch of [`cell_fit`], reused over the cells.
#[derive(Default)]
struct CellBuffers {
    used: Vec<usize>,
    work: Vec<f64>,
    th: Vec<f64>,
}

/// Held-out sums `(Σ(z−ẑ)², Σz², Σẑ²)` of the training fit of the columns of `cols` the
/// cell's training set excites, or `None` when it cannot be fitted: fewer than `min_points`
/// per parameter, or the columns dependent there.
fn cell_fit(
    c: &FoldCell<'_>,
    dim: usize,
    cols: &[usize],
    min_points: usize,
    excitation: &Excitation<'_>,
    buf: &mut CellBuffers,
) -> Option<(f64, f64, f64)> {
    excitation.excited(c.train, c.train_sums, c.n_train, dim, cols, &mut buf.used);
    if c.n_train < (min_points * buf.used.len().max(1)) as f64 {
        return None;
    }
    solve_subset_into(c.train, dim, &buf.used, &mut buf.work, &mut buf.th)?;
    Some(held_out(c.fold, dim, &buf.used, &buf.th))
}

/// Held-out sums of a fold whose bin predicts zero Δ (no training fit).
fn zero_prediction(gf: &[f64], dim: usize) -> (f64, f64, f64) {
    let z2 = gf[dim * dim - 1];
    (z2, z2, 0.0)
}

/// Per bin and fold (index `b · folds + f`), the held-out sums `(Σ(z−ẑ)², Σz², Σẑ²)` of what
/// the fold predicts where a structure cannot be fitted on its training maneuvers (fewer
/// than `min_points` per parameter, dependent columns, estimates not finite): the training
/// fit of the `forced` columns (the bias), or zero Δ where even that cannot be fitted. Bins
/// not fitted and empty folds hold zeros (never read).
///
/// The shipped model never predicts zero Δ in a bin for want of points: the partition merges
/// sparse bins, and the smoothing spans a bin the final fit cannot identify from its
/// neighbours. Scoring zero there charged every structure larger than the one the sparse
/// cell could still fit with the whole Δ of that cell: at the edge of the data (a bin of 3
/// maneuvers at the highest alpha, a fold holding out 2 of them) that is the bias itself, 0.02
/// in C_l on the JSBSim DHC-6 at flap 40, and adding ΔC_l_β there raised one fold's held-out
/// error 16-fold, so the selection kept the intercept alone (`docs/identification.md`,
/// session 32). The forced columns are in every structure compared, so this charges none of
/// them for the data's sparseness; a structure still loses the rest of its terms there.
fn fallback_sums(
    dim: usize,
    trains: &FoldGrams,
    folds: &FoldGrams,
    fitted: &[bool],
    forced: &[usize],
    min_points: usize,
    excitation: &Excitation<'_>,
) -> Vec<(f64, f64, f64)> {
    let nf = folds.folds();
    let mut out = vec![(0.0, 0.0, 0.0); fitted.len() * nf];
    let mut buf = CellBuffers::default();
    for c in fold_cells(fitted, folds, trains) {
        out[c.b * nf + c.f] = cell_fit(&c, dim, forced, min_points, excitation, &mut buf)
            .unwrap_or_else(|| zero_prediction(c.fold, dim));
    }
    out
}

/// Sums of a cross-validated score over bins and folds.
#[derive(Clone)]
struct CvAccum {
    sse: f64,
    zz: f64,
    yy: f64,
    n: f64,
    /// Per fold: (sse, n).
    per_fold: Vec<(f64, f64)>,
}

impl CvAccum {
    fn new(folds: usize) -> Self {
        CvAccum {
            sse: 0.0,
            zz: 0.0,
            yy: 0.0,
            n: 0.0,
            per_fold: vec![(0.0, 0.0); folds],
        }
    }

    fn add(&mut self, f: usize, e: f64, z2: f64, y2: f64, nfold: f64) {
        self.sse += e;
        self.zz += z2;
        self.yy += y2;
        self.n += nfold;
        self.per_fold[f].0 += e;
        self.per_fold[f].1 += nfold;
    }

    /// The score, `s2` the squared scale of z.
    fn finish(&self, s2: f64, label: &[usize]) -> CvScore {
        let (sse, zz, yy, n) = (self.sse, self.zz, self.yy, self.n);
        let mse = if n > 0.0 { s2 * sse / n } else { f64::NAN };
        let all_folds: Vec<f64> = self
            .per_fold
            .iter()
            .map(|(e, c)| if *c > 0.0 { s2 * e / c } else { f64::NAN })
            .collect();
        let fold_mse: Vec<f64> = all_folds
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .collect();
        let k = fold_mse.len() as f64;
        let mse_se = if k > 1.0 {
            let m = fold_mse.iter().sum::<f64>() / k;
            (fold_mse.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (k - 1.0) / k).sqrt()
        } else {
            f64::NAN
        };
        let den = (zz / n.max(1.0)).sqrt() + (yy / n.max(1.0)).sqrt();
        let tic = if den > 0.0 {
            (sse / n.max(1.0)).sqrt() / den
        } else {
            f64::NAN
        };
        CvScore {
            columns: label.to_vec(),
            rms: mse.sqrt(),
            tic,
            mse,
            mse_se,
            fold_mse: all_folds,
        }
    }
}

fn check_inputs(
    design: &Design,
    z: &[f64],
    maneuver: &[u64],
    pool_fit: &BinnedFit,
    opts: &SelectOptions,
) -> Result<()> {
    let p = design.ncols();
    if z.len() != design.nrows || maneuver.len() != design.nrows {
        return Err(AeroError::invalid(
            "structure selection",
            format!(
                "z has {} rows and maneuver {}, the regressors {}",
                z.len(),
                maneuver.len(),
                design.nrows
            ),
        ));
    }
    if let Some(&c) = opts.forced.iter().find(|&&c| c >= p) {
        return Err(AeroError::invalid(
            "structure selection, forced",
            format!("column {c} is out of the pool's {p} columns"),
        ));
    }
    if let Some(&(a, b)) = opts.companions.iter().find(|(a, b)| *a >= p || *b >= p) {
        return Err(AeroError::invalid(
            "structure selection, companions",
            format!("pair ({a}, {b}) is out of the pool's {p} columns"),
        ));
    }
    if opts.folds < 2 {
        return Err(AeroError::invalid(
            "structure selection, folds",
            format!("is {}; cross-validation needs at least 2 folds", opts.folds),
        ));
    }
    if pool_fit.partition.index.len() != design.nrows {
        return Err(AeroError::invalid(
            "structure selection, pool fit",
            format!(
                "covers {} rows, the regressors have {}",
                pool_fit.partition.index.len(),
                design.nrows
            ),
        ));
    }
    Ok(())
}

/// Select the structure of one coefficient at one flap setting from a pool
/// (see the module doc). `pool_fit` is [`crate::identify::fit_bins`] of the
/// whole pool `design` over the same `z` and `maneuver` (it gives the bins,
/// their coloured-residual inflation and the excitation of each candidate).
///
/// # Errors
/// [`AeroError::InvalidInput`] for lengths that differ, an empty pool, a
/// forced column out of range or fewer than 2 folds.
pub fn select_structure(
    design: &Design,
    z: &[f64],
    maneuver: &[u64],
    pool_fit: &BinnedFit,
    opts: &SelectOptions,
) -> Result<Selection> {
    check_inputs(design, z, maneuver, pool_fit, opts)?;
    let members = bin_members(pool_fit);
    let grams = bin_grams(design, z, &members, maneuver);
    select_with_grams(design, z, maneuver, pool_fit, &grams, opts)
}

/// [`select_structure`] with the Gram matrices of `pool_fit`'s bins already
/// computed ([`bin_grams`] over [`bin_members`]).
///
/// # Errors
/// As [`select_structure`].
pub fn select_with_grams(
    design: &Design,
    z: &[f64],
    maneuver: &[u64],
    pool_fit: &BinnedFit,
    grams: &BinGrams,
    opts: &SelectOptions,
) -> Result<Selection> {
    select_weighted(design, z, maneuver, pool_fit, grams, opts, None, None)
}

/// [`select_with_grams`] with each maneuver's samples counted `weights[id]`
/// times (absent: 0): the selection run again on a bootstrap replicate of the
/// maneuvers, from the same Gram matrices (the bins and the excitation marks
/// are the estimate's, and so is the coloured-residual inflation κ per bin
/// when `kappa` gives it: the estimate's [`Selection::kappa`]).
///
/// # Errors
/// As [`select_structure`]; a `kappa` of another length than the bins.
#[allow(clippy::too_many_arguments)]
pub fn select_weighted(
    design: &Design,
    z: &[f64],
    maneuver: &[u64],
    pool_fit: &BinnedFit,
    grams: &BinGrams,
    opts: &SelectOptions,
    weights: Option<&std::collections::HashMap<u64, f64>>,
    kappa: Option<&[f64]>,
) -> Result<Selection> {
    select_impl(
        design, z, maneuver, pool_fit, grams, opts, weights, kappa, true, None,
    )
}

/// The columns [`select_weighted`] chooses, without the scores that only report on them
/// (the full pool's, the extra structures', the chosen structure's own and the nested
/// cross-validation): what a bootstrap replicate and a nested fold's inner selection use.
/// The decisions are those of [`select_weighted`] to the bit (the same computation up to
/// `chosen`).
///
/// # Errors
/// As [`select_weighted`].
#[allow(clippy::too_many_arguments)]
pub fn select_chosen(
    design: &Design,
    z: &[f64],
    maneuver: &[u64],
    pool_fit: &BinnedFit,
    grams: &BinGrams,
    opts: &SelectOptions,
    weights: Option<&std::collections::HashMap<u64, f64>>,
    kappa: Option<&[f64]>,
) -> Result<Vec<usize>> {
    let so = SelectOptions {
        nested: false,
        ..opts.clone()
    };
    select_impl(
        design, z, maneuver, pool_fit, grams, &so, weights, kappa, false, None,
    )
    .map(|s| s.chosen)
}

/// [`select_weighted`]; with `report` false, the reporting scores (`full`, `extra`,
/// `pruned`) are not computed and left as [`CvScore::not_computed`]. `given`: the
/// cross-validation's statistics for these `weights` when the caller has them
/// ([`CvGrams::without_fold`]), else they are summed here.
#[allow(clippy::too_many_arguments)]
fn select_impl(
    design: &Design,
    z: &[f64],
    maneuver: &[u64],
    pool_fit: &BinnedFit,
    grams: &BinGrams,
    opts: &SelectOptions,
    weights: Option<&std::collections::HashMap<u64, f64>>,
    kappa: Option<&[f64]>,
    report: bool,
    given: Option<CvGrams>,
) -> Result<Selection> {
    check_inputs(design, z, maneuver, pool_fit, opts)?;
    let weight = |m: &u64| weights.map_or(1.0, |w| w.get(m).copied().unwrap_or(0.0));
    if grams.bins.len() != pool_fit.bins.len() || grams.dim != design.ncols() + 1 {
        return Err(AeroError::invalid(
            "structure selection, Gram matrices",
            "do not match the pool fit; compute them with bin_grams over bin_members(pool_fit)",
        ));
    }
    let p = design.ncols();
    let dim = grams.dim;
    let nb = pool_fit.bins.len();
    // rows per bin, only for the residual autocorrelation when no kappa is given
    let members = if kappa.is_none() {
        bin_members(pool_fit)
    } else {
        Vec::new()
    };
    let fitted: Vec<bool> = pool_fit.bins.iter().map(|b| b.note.is_empty()).collect();
    // per bin and fold, the fold's Gram matrix (every maneuver is in one fold), in one pass
    // over the maneuvers; a bin's total is the sum of its folds
    let fold_map = fold_of(maneuver, opts.folds, opts.seed);
    let cv = given.unwrap_or_else(|| {
        CvGrams::new(
            grams,
            opts.folds,
            |b, k| fold_map.get(&grams.bins[b].maneuvers[k]).copied(),
            |b, k| weight(&grams.bins[b].maneuvers[k]),
        )
    });
    let (folds, trains) = (&cv.folds, &cv.trains);
    if kappa.is_some_and(|k| k.len() != nb) {
        return Err(AeroError::invalid(
            "structure selection, kappa",
            format!("has {} values for {nb} bins", kappa.map_or(0, <[f64]>::len)),
        ));
    }
    let kappa_of = |b: usize| {
        if let Some(k) = kappa {
            return k[b];
        }
        let bin = &pool_fit.bins[b];
        if bin.std_err_colored.iter().any(|v| v.is_finite()) {
            bin_kappa(pool_fit, b)
        } else if fitted[b] {
            residual_kappa(design, z, maneuver, &members[b], &bin.params)
        } else {
            1.0
        }
    };
    #[cfg(feature = "parallel")]
    let kappa: Vec<f64> = {
        use rayon::prelude::*;
        (0..nb).into_par_iter().map(kappa_of).collect()
    };
    #[cfg(not(feature = "parallel"))]
    let kappa: Vec<f64> = (0..nb).map(kappa_of).collect();

    let mut selected = vec![vec![false; p]; nb];
    let mut partial_f = vec![vec![f64::NAN; p]; nb];
    let mut correlation = vec![vec![f64::NAN; p]; nb];
    for b in 0..nb {
        let (g, s, n) = cv.totals.get(b, 0);
        if n > 1.0 {
            let zc = dim - 1;
            let vz = g[zc * dim + zc] - s[zc] * s[zc] / n;
            for j in 0..p {
                let vx = g[j * dim + j] - s[j] * s[j] / n;
                let cxz = g[j * dim + zc] - s[j] * s[zc] / n;
                if vx > 1e-12 * g[j * dim + j].max(f64::MIN_POSITIVE) && vz > 0.0 {
                    correlation[b][j] = cxz / (vx * vz).sqrt();
                }
            }
        }
        if !fitted[b] {
            continue;
        }
        let bin = &pool_fit.bins[b];
        let candidates: Vec<usize> = (0..p)
            .filter(|&j| !opts.forced.contains(&j))
            .filter(|&j| {
                design.exprs[j].is_constant()
                    || (bin.excitation[j] >= opts.min_excitation
                        && bin.excitation_snr[j] >= opts.min_excitation_snr)
            })
            .collect();
        let sel = match opts.method {
            Method::Stepwise => {
                let (sel, f) = stepwise(
                    g,
                    dim,
                    n,
                    &opts.forced,
                    &candidates,
                    kappa[b],
                    opts.f_in,
                    opts.f_out,
                    opts.max_vif,
                );
                partial_f[b] = f;
                sel
            }
            Method::Mof => mof_pse(g, dim, n, &opts.forced, &candidates, kappa[b]),
        };
        for c in sel {
            selected[b][c] = true;
        }
    }
    let count: Vec<usize> = (0..p)
        .map(|j| (0..nb).filter(|&b| fitted[b] && selected[b][j]).count())
        .collect();

    let mut order: Vec<usize> = (0..p)
        .filter(|j| !opts.forced.contains(j) && count[*j] >= opts.min_bins.max(1))
        .collect();
    order.sort_by(|a, b| count[*b].cmp(&count[*a]).then(a.cmp(b)));
    // flap-wide standard deviations of the scaled columns (sum over the bins)
    let (mut gf, mut sf, mut nf) = (vec![0.0; dim * dim], vec![0.0; dim], 0.0);
    for b in 0..nb {
        let (g, s, c) = cv.totals.get(b, 0);
        gf.iter_mut().zip(g).for_each(|(a, b)| *a += b);
        sf.iter_mut().zip(s).for_each(|(a, b)| *a += b);
        nf += c;
    }
    let flap_sd: Vec<f64> = (0..p)
        .map(|j| {
            if nf > 1.0 {
                ((gf[j * dim + j] - sf[j] * sf[j] / nf) / (nf - 1.0))
                    .max(0.0)
                    .sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let constant: Vec<bool> = design
        .exprs
        .iter()
        .map(crate::regressor::Expr::is_constant)
        .collect();
    let excitation = Excitation {
        flap_sd: &flap_sd,
        constant: &constant,
        min: opts.min_excitation,
    };
    let fallback = fallback_sums(
        grams.dim,
        trains,
        folds,
        &fitted,
        &opts.forced,
        opts.min_points_per_param,
        &excitation,
    );
    let score = |cols: &[usize]| {
        cv_score(
            grams,
            trains,
            folds,
            &fitted,
            cols,
            opts.min_points_per_param,
            &excitation,
            &fallback,
        )
    };
    // the greedy path: from the forced columns, add at each step the frequent
    // candidate whose addition gives the lowest cross-validated error (a
    // candidate the per-bin selection picks often but that predicts other
    // maneuvers badly, such as a thrust difference acting as an indicator of the
    // one asymmetric-thrust maneuver of a fold, then comes late, not first)
    let mut nested = Vec::with_capacity(order.len() + 1);
    let mut cols: Vec<usize> = opts.forced.clone();
    nested.push(score(&cols));
    let mut left = order.clone();
    let mut scorer = path::PathScorer::new(
        grams,
        trains,
        folds,
        &fitted,
        &cols,
        &order,
        opts.min_points_per_param,
        &excitation,
        &fallback,
    );
    let key = |s: &CvScore| {
        if s.mse.is_finite() {
            s.mse
        } else {
            f64::INFINITY
        }
    };
    while !left.is_empty() {
        let scores = scorer.scores(&left);
        // in the test builds, every extended-factor score is checked against the refit
        #[cfg(test)]
        for (s, &c) in scores.iter().zip(&left) {
            let mut trial = cols.clone();
            trial.push(c);
            let r = score(&trial);
            let close = |a: f64, b: f64| {
                (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-9 * a.abs().max(b.abs())
            };
            assert!(close(s.mse, r.mse) && close(s.tic, r.tic), "{s:?} vs {r:?}");
            assert_eq!(s.columns, r.columns);
        }
        let Some((i, s)) = scores
            .into_iter()
            .enumerate()
            .min_by(|a, b| key(&a.1).total_cmp(&key(&b.1)))
        else {
            break;
        };
        let c = left.remove(i);
        scorer.add(c);
        cols.push(c);
        nested.push(s);
    }
    let best = nested
        .iter()
        .enumerate()
        .filter(|(_, s)| s.mse.is_finite())
        .min_by(|a, b| a.1.mse.total_cmp(&b.1.mse))
        .map_or(0, |(i, _)| i);
    // one-standard-error rule on the paired fold differences from the best structure
    let chosen_k = nested
        .iter()
        .position(|s| {
            let se = s.paired_se(&nested[best]);
            s.mse <= nested[best].mse + if se.is_finite() { se } else { 0.0 }
        })
        .unwrap_or(best);
    // backward pruning by cross-validation: drop a kept candidate while its removal lowers
    // the held-out error (confounded pairs, e.g. rudder and thrust asymmetry held against
    // each other by the pilot, enter together by frequency but predict worse than one)
    let mut chosen = nested[chosen_k].columns.clone();
    let mut current = nested[chosen_k].mse;
    loop {
        let trial = chosen
            .iter()
            .filter(|c| !opts.forced.contains(c))
            .map(|&c| {
                let cols: Vec<usize> = chosen.iter().copied().filter(|&x| x != c).collect();
                score(&cols)
            })
            .filter(|s| s.mse.is_finite())
            .min_by(|a, b| a.mse.total_cmp(&b.mse));
        match trial {
            Some(s) if s.mse < current => {
                current = s.mse;
                chosen = s.columns;
            }
            _ => break,
        }
    }
    // companions of the kept columns, in the order given (a companion's own companion too),
    // each where its held-out error stays within one standard error (over the folds) of the
    // structure's without it: the two predict alike, and the one with the companion reports
    // unbiased parameters where the companion's effect is real
    let mut base: Option<CvScore> = None; // scored when a companion is first tried
    for _ in 0..opts.companions.len() {
        let mut grew = false;
        for &(a, b) in &opts.companions {
            if !chosen.contains(&a) || chosen.contains(&b) {
                continue;
            }
            let mut trial = chosen.clone();
            trial.push(b);
            let s = score(&trial);
            let base = base.get_or_insert_with(|| score(&chosen));
            let se = base.mse_se;
            if s.mse.is_finite() && s.mse <= base.mse + if se.is_finite() { se } else { 0.0 } {
                chosen = trial;
                *base = s;
                grew = true;
            }
        }
        if !grew {
            break;
        }
    }
    let all: Vec<usize> = (0..p).collect();
    let (pruned, full, extra) = if report {
        let pruned = score(&chosen);
        (
            pruned,
            score(&all),
            opts.extra.iter().map(|c| score(c)).collect(),
        )
    } else {
        (
            CvScore::not_computed(&chosen),
            CvScore::not_computed(&all),
            Vec::new(),
        )
    };
    chosen.sort_unstable();
    // nested cross-validation: the selection reruns on each fold's training maneuvers (the
    // same fold assignment, so its inner folds are the other folds)
    let (outer, outer_chosen) = if opts.nested {
        let inner = SelectOptions {
            nested: false,
            ..opts.clone()
        };
        let select_fold = |f: usize| -> Result<Vec<usize>> {
            let w: std::collections::HashMap<u64, f64> = fold_map
                .iter()
                .map(|(m, &fm)| (*m, if fm == f { 0.0 } else { weight(m) }))
                .collect();
            // select_chosen with these weights; their fold sums are this selection's
            // without fold f
            select_impl(
                design,
                z,
                maneuver,
                pool_fit,
                grams,
                &inner,
                Some(&w),
                Some(&kappa),
                false,
                Some(cv.without_fold(f)),
            )
            .map(|s| s.chosen)
        };
        #[cfg(feature = "parallel")]
        let per_fold: Vec<Vec<usize>> = {
            use rayon::prelude::*;
            (0..opts.folds)
                .into_par_iter()
                .map(select_fold)
                .collect::<Result<_>>()?
        };
        #[cfg(not(feature = "parallel"))]
        let per_fold: Vec<Vec<usize>> = (0..opts.folds).map(select_fold).collect::<Result<_>>()?;
        let outer = cv_score_per_fold(
            grams,
            trains,
            folds,
            &fitted,
            &|f| &per_fold[f],
            opts.min_points_per_param,
            &excitation,
            &chosen,
            &fallback,
        );
        (Some(outer), per_fold)
    } else {
        (None, Vec::new())
    };
    Ok(Selection {
        outer,
        outer_chosen,
        pruned,
        selected,
        partial_f,
        correlation,
        kappa,
        fitted,
        count,
        nested,
        full,
        extra,
        chosen,
        chosen_k,
    })
}

/// The candidate pool's per-bin least squares from the Gram matrices alone
/// (the fast path of [`identify_flap`]): the partition of
/// [`crate::identify::fit_bins`] for the pool's column count, the same
/// too-little-data and low-excitation rules, and estimates from the columns
/// that keep the normal equations positive definite, taken in pool order
/// (a column dependent on earlier ones is marked not identifiable,
/// "linearly dependent"). Standard errors are not computed (NaN).
///
/// # Errors
/// Partition errors; lengths that differ.
pub fn pool_bins(
    design: &Design,
    z: &[f64],
    alpha_deg: &[f64],
    maneuver: &[u64],
    identify: &IdentifyOptions,
) -> Result<BinnedFit> {
    pool_bins_grams(design, z, alpha_deg, maneuver, identify).map(|(f, _)| f)
}

/// [`pool_bins`] and the per-(bin, maneuver) Gram matrices it was computed from.
///
/// # Errors
/// As [`pool_bins`].
pub fn pool_bins_grams(
    design: &Design,
    z: &[f64],
    alpha_deg: &[f64],
    maneuver: &[u64],
    identify: &IdentifyOptions,
) -> Result<(BinnedFit, BinGrams)> {
    let n = design.nrows;
    if z.len() != n || alpha_deg.len() != n || maneuver.len() != n {
        return Err(AeroError::invalid(
            "structure selection, candidate pool",
            format!(
                "z, alpha_deg and maneuver have {}, {} and {} rows, the regressors {n}",
                z.len(),
                alpha_deg.len(),
                maneuver.len()
            ),
        ));
    }
    let p = design.ncols();
    let partition = partition_alpha(alpha_deg, p, Some(maneuver), &identify.partition)?;
    let mut members = vec![Vec::new(); partition.counts.len()];
    for (r, &b) in partition.index.iter().enumerate() {
        if b >= 0 {
            members[b as usize].push(r);
        }
    }
    let grams = bin_grams(design, z, &members, maneuver);
    let dim = grams.dim;
    let totals: Vec<(Vec<f64>, Vec<f64>, f64)> =
        grams.bins.iter().map(|b| b.total(dim, None)).collect();
    // flap-wide column variances (scaled units) from the sum over bins
    let (mut gf, mut sf, mut nf) = (vec![0.0; dim * dim], vec![0.0; dim], 0.0);
    for (g, s, c) in &totals {
        gf.iter_mut().zip(g).for_each(|(a, b)| *a += b);
        sf.iter_mut().zip(s).for_each(|(a, b)| *a += b);
        nf += c;
    }
    let var = |g: &[f64], s: &[f64], c: f64, j: usize| {
        if c > 1.0 {
            ((g[j * dim + j] - s[j] * s[j] / c) / (c - 1.0)).max(0.0)
        } else {
            0.0
        }
    };
    let flap_sd: Vec<f64> = (0..p).map(|j| var(&gf, &sf, nf, j).sqrt()).collect();
    let const_col: Vec<bool> = design
        .exprs
        .iter()
        .map(crate::regressor::Expr::is_constant)
        .collect();
    let floor = noise_floor(design, maneuver);
    let required = identify.partition.min_points_per_param * p;
    let min_man = identify.partition.min_maneuvers.max(1);
    let bins: Vec<BinFit> = (0..members.len())
        .map(|b| {
            let (g, s, c) = &totals[b];
            let n_man = grams.bins[b].maneuvers.len();
            let excitation: Vec<f64> = (0..p)
                .map(|j| {
                    if const_col[j] {
                        1.0
                    } else if flap_sd[j] > 0.0 {
                        var(g, s, *c, j).sqrt() / flap_sd[j]
                    } else {
                        0.0
                    }
                })
                .collect();
            // a constant regressor's floor is zero: infinite
            let excitation_snr: Vec<f64> = (0..p)
                .map(|j| snr(var(g, s, *c, j).sqrt() * grams.scale[j], floor[j]))
                .collect();
            let mut bin = BinFit::unfitted(
                (partition.edges[b], partition.edges[b + 1]),
                members[b].len(),
                n_man,
                excitation,
                excitation_snr,
            );
            if members[b].len() < required || n_man < min_man {
                bin.note = format!(
                    "too little data: {} points from {n_man} maneuvers, {required} points and \
                     {min_man} maneuvers required",
                    members[b].len()
                );
                bin.notes = vec!["bin not fitted: too little data".into(); p];
                return bin;
            }
            let cols = independent_columns(g, dim, p);
            if let Some((th, sse)) = solve_subset(g, dim, &cols) {
                bin.params = vec![0.0; p];
                for (i, &j) in cols.iter().enumerate() {
                    bin.params[j] = th[i] * grams.scale[p] / grams.scale[j];
                }
                let dof = (*c - cols.len() as f64).max(1.0);
                bin.residual_std = (sse / dof).sqrt() * grams.scale[p];
            }
            for j in 0..p {
                let mut why = Vec::new();
                if !cols.contains(&j) {
                    why.push(
                        "not identifiable: linearly dependent on other regressors".to_string(),
                    );
                }
                if !const_col[j] {
                    if let Some(w) =
                        low_excitation(bin.excitation[j], bin.excitation_snr[j], identify)
                    {
                        why.push(w);
                    }
                }
                bin.identifiable[j] = why.is_empty();
                bin.smoothable[j] = why.is_empty();
                bin.notes[j] = why.join("; ");
            }
            bin
        })
        .collect();
    let consistency = (0..p).map(|j| adjacent_consistency(&bins, j)).collect();
    Ok((
        BinnedFit {
            names: design.names.clone(),
            bins,
            consistency,
            partition,
        },
        grams,
    ))
}

/// The design restricted to columns `cols` (in that order).
pub fn subset_design(design: &Design, cols: &[usize]) -> Design {
    let p = design.ncols();
    let k = cols.len();
    let mut values = vec![0.0; design.nrows * k];
    for r in 0..design.nrows {
        for (i, &c) in cols.iter().enumerate() {
            values[r * k + i] = design.values[r * p + c];
        }
    }
    Design {
        names: cols.iter().map(|&c| design.names[c].clone()).collect(),
        exprs: cols.iter().map(|&c| design.exprs[c].clone()).collect(),
        values,
        nrows: design.nrows,
    }
}

/// The identification of one coefficient at one flap setting with an optional
/// structure selection and bootstrap: what [`identify_flap`] returns.
#[derive(Debug, Clone)]
pub struct FlapFit {
    /// The selection over the pool (`None`: the pool is the structure).
    pub selection: Option<Selection>,
    /// The pool's per-bin fit the selection worked on (`None` without selection).
    pub pool_fit: Option<BinnedFit>,
    /// Pool columns of the final structure, increasing.
    pub chosen: Vec<usize>,
    /// Columns left out of the structure as collinear ([`collinear_to_prune`]), in order.
    pub pruned: Vec<Pruned>,
    /// Per-bin fit of the final structure.
    pub fit: BinnedFit,
    /// Its smoothed parameters.
    pub smoothed: Vec<SmoothedParameter>,
    /// Bootstrap bands (`None` when not asked).
    pub bootstrap: Option<Bootstrap>,
}

/// Identify one coefficient at one flap setting: optionally select the
/// structure from the `pool` ([`select_structure`]), fit the chosen
/// regressors bin by bin ([`fit_bins`]), leaving out a term collinear in most
/// bins when [`IdentifyOptions::prune_collinear`] ([`collinear_to_prune`],
/// refitting after each), smooth them
/// ([`smooth_parameters`]) and optionally bootstrap the smoothed parameters
/// over maneuvers ([`bootstrap_smoothed`]).
///
/// # Errors
/// Those of the steps, with the step named.
#[allow(clippy::too_many_arguments)]
pub fn identify_flap(
    pool: &Design,
    z: &[f64],
    alpha_deg: &[f64],
    maneuver: &[u64],
    identify: &IdentifyOptions,
    select: Option<&SelectOptions>,
    smooth: &SmoothOptions,
    boot: Option<&BootstrapOptions>,
) -> Result<FlapFit> {
    let (selection, pool_fit, pool_grams, chosen) = match select {
        Some(so) => {
            // the pool's bins, excitation and residuals (for κ) from Gram matrices: the
            // pool's standard errors and collinearity diagnostics are not needed here
            let (pf, grams) = pool_bins_grams(pool, z, alpha_deg, maneuver, identify)
                .context("structure selection, candidate pool")?;
            let sel = select_with_grams(pool, z, maneuver, &pf, &grams, so)?;
            let chosen = sel.chosen.clone();
            (Some(sel), Some(pf), Some(grams), chosen)
        }
        None => (None, None, None, (0..pool.ncols()).collect()),
    };
    let mut chosen = chosen;
    let mut pruned = Vec::new();
    // the pool itself when the structure is the whole pool (no copy)
    let subset = |cols: &[usize]| -> Cow<'_, Design> {
        if cols.len() == pool.ncols() {
            Cow::Borrowed(pool)
        } else {
            Cow::Owned(subset_design(pool, cols))
        }
    };
    let design0 = subset(&chosen);
    let (fit, design) = if identify.prune_collinear && identify.max_vif.is_finite() {
        // decide from the Gram matrices of the bins the structure would be fitted in (one
        // factor per bin and step), then fit the final structure once
        let plan = plan_bins(&design0, z, alpha_deg, maneuver, identify)?;
        let grams = bin_grams(&design0, z, &plan.members, maneuver);
        let totals = planned_totals(&grams, &plan);
        let constant0: Vec<bool> = design0.exprs.iter().map(|e| e.is_constant()).collect();
        let mut keep: Vec<usize> = (0..design0.ncols()).collect();
        loop {
            // indexed by position in `keep`
            let table = gram_collinearity(&totals, grams.dim, &keep, &constant0);
            let names: Vec<String> = keep.iter().map(|&j| design0.names[j].clone()).collect();
            let constant: Vec<bool> = keep.iter().map(|&j| constant0[j]).collect();
            match collinear_to_prune(&table, &names, &constant, identify.max_vif) {
                Some((i, note)) => {
                    pruned.push(Pruned {
                        column: chosen[keep[i]],
                        note,
                    });
                    keep.remove(i);
                }
                None => break,
            }
        }
        if pruned.is_empty() {
            // the planned bins are the structure's: no second partition
            (fit_planned(&design0, z, maneuver, plan, identify), design0)
        } else {
            // fewer columns: the points-per-parameter rule may bin differently
            chosen = keep.iter().map(|&j| chosen[j]).collect();
            let design = subset(&chosen);
            (fit_bins(&design, z, alpha_deg, maneuver, identify)?, design)
        }
    } else {
        (
            fit_bins(&design0, z, alpha_deg, maneuver, identify)?,
            design0,
        )
    };
    let smoothed = smooth_parameters(&fit, smooth)?;
    let bootstrap = match boot {
        Some(bo) => {
            // with a selection, each replicate selects again (bands that carry the selection)
            let rs = match (&selection, &pool_fit, &pool_grams, select) {
                (Some(sel), Some(pf), Some(g), Some(so)) if bo.reselect => Some(Reselect {
                    pool,
                    pool_fit: pf,
                    grams: g,
                    select: so,
                    kappa: &sel.kappa,
                    chosen: &chosen,
                }),
                _ => None,
            };
            Some(
                bootstrap_smoothed(&design, z, maneuver, &fit, smooth, bo, rs.as_ref())
                    .context("bootstrap")?,
            )
        }
        None => None,
    };
    Ok(FlapFit {
        selection,
        pool_fit,
        chosen,
        pruned,
        fit,
        smoothed,
        bootstrap,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The identification settings for these i.i.d. regressors: drawn afresh at every row, they
    /// look like white noise to the noise-floor rule, which reads the time structure of sampled
    /// flight data ([`crate::identify::noise_floor`]), so that rule is off.
    pub(crate) fn iid_identify() -> IdentifyOptions {
        IdentifyOptions {
            min_excitation_snr: 0.0,
            ..IdentifyOptions::default()
        }
    }

    /// z = 0.002 + b(α) x1 - 0.03 x2 + noise, with x3, x4 pure noise regressors.
    fn data(n: usize, seed: u64) -> (Design, Vec<f64>, Vec<f64>, Vec<u64>) {
        let mut rng = Stream::new(seed, 1);
        let mut cols: Vec<Vec<f64>> = (0..4).map(|_| Vec::with_capacity(n)).collect();
        let (mut alpha, mut z, mut man) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..n {
            let a = 5.0 + 15.0 * rng.uniform();
            let x: Vec<f64> = (0..4).map(|_| rng.range(-1.0, 1.0)).collect();
            let b = 0.01 * (a - 12.0).max(0.0);
            z.push(0.002 + b * x[0] - 0.03 * x[1] + 0.002 * rng.normal());
            for j in 0..4 {
                cols[j].push(x[j]);
            }
            alpha.push(a);
            man.push((i / 400) as u64);
        }
        let lookup = |c: &str| -> Option<&[f64]> {
            match c {
                "x1" => Some(&cols[0]),
                "x2" => Some(&cols[1]),
                "x3" => Some(&cols[2]),
                "x4" => Some(&cols[3]),
                _ => None,
            }
        };
        let regs: Vec<(String, String)> = [
            ("bias", "1"),
            ("b", "x1"),
            ("c", "x2"),
            ("d", "x3"),
            ("e", "x4"),
        ]
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
        let design = Design::build(&regs, &lookup, n).expect("design");
        (design, z, alpha, man)
    }

    #[test]
    fn residual_kappa_is_one_for_white_and_large_for_correlated_residuals() {
        let n = 4000;
        let mut rng = Stream::new(5, 2);
        let white: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        // AR(1) with phi = 0.9: integrated autocorrelation (1 + phi) / (1 - phi) = 19
        let mut ar = vec![0.0; n];
        for i in 1..n {
            ar[i] = 0.9 * ar[i - 1] + rng.normal();
        }
        let ones = vec![1.0; n];
        let lookup = |c: &str| -> Option<&[f64]> { (c == "one").then_some(&ones[..]) };
        let design = Design::build(&[("b".into(), "one".into())], &lookup, n).expect("design");
        let rows: Vec<usize> = (0..n).collect();
        let man = vec![0u64; n];
        let kw = residual_kappa(&design, &white, &man, &rows, &[0.0]);
        let ka = residual_kappa(&design, &ar, &man, &rows, &[0.0]);
        assert!((kw - 1.0).abs() < 0.3, "{kw}");
        // the Bartlett window and the 50-lag truncation shrink 19 somewhat
        assert!(ka > 8.0 && ka < 19.0, "{ka}");
    }

    #[test]
    fn independent_columns_keep_what_refactoring_each_trial_keeps() {
        // columns: x0, x1, x0 + x1 (dependent), a zero column, x2, 1e-7 x0 + x3 (kept), and
        // x1 - x2 (dependent); the trial-by-trial factorizations decide the reference
        let n = 400;
        let mut rng = Stream::new(21, 1);
        let x: Vec<Vec<f64>> = (0..4)
            .map(|_| (0..n).map(|_| rng.normal()).collect())
            .collect();
        let cols: Vec<Vec<f64>> = vec![
            x[0].clone(),
            x[1].clone(),
            (0..n).map(|i| x[0][i] + x[1][i]).collect(),
            vec![0.0; n],
            x[2].clone(),
            (0..n).map(|i| 1e-7 * x[0][i] + x[3][i]).collect(),
            (0..n).map(|i| x[1][i] - x[2][i]).collect(),
        ];
        let z: Vec<f64> = (0..n)
            .map(|i| x[0][i] - 2.0 * x[2][i] + rng.normal())
            .collect();
        let p = cols.len();
        let dim = p + 1;
        let v = |c: usize, i: usize| if c < p { cols[c][i] } else { z[i] };
        let g: Vec<f64> = (0..dim * dim)
            .map(|ab| (0..n).map(|i| v(ab / dim, i) * v(ab % dim, i)).sum())
            .collect();
        let mut want: Vec<usize> = Vec::new();
        for j in 0..p {
            want.push(j);
            if solve_subset(&g, dim, &want).is_none() {
                want.pop();
            }
        }
        assert_eq!(independent_columns(&g, dim, p), want);
        assert_eq!(want, vec![0, 1, 4, 5]);
    }

    #[test]
    fn fold_sums_without_a_fold_are_those_summed_with_its_weights_zero() {
        // the nested cross-validation's statistics derived from the outer ones equal, bit for
        // bit, those summed afresh over the maneuvers with the left-out fold's weights 0
        // (weights other than 1 too, and a maneuver with weight 0 already)
        let (design, z, alpha, man) = data(20_000, 7);
        let opts = iid_identify();
        let (_, grams) = pool_bins_grams(&design, &z, &alpha, &man, &opts).expect("pool");
        let nf = 5;
        let fold_map = fold_of(&man, nf, 3);
        let weight = |m: u64| [1.0, 2.0, 0.0, 1.0, 3.0][(m % 5) as usize];
        let build = |out: Option<usize>| {
            CvGrams::new(
                &grams,
                nf,
                |b, k| fold_map.get(&grams.bins[b].maneuvers[k]).copied(),
                |b, k| {
                    let m = grams.bins[b].maneuvers[k];
                    if Some(fold_map[&m]) == out {
                        0.0
                    } else {
                        weight(m)
                    }
                },
            )
        };
        let outer = build(None);
        let bits = |g: &FoldGrams, b: usize, f: usize| {
            let (m, s, n) = g.get(b, f);
            let mut v: Vec<u64> = m.iter().chain(s).map(|x| x.to_bits()).collect();
            v.push(n.to_bits());
            v
        };
        for out in 0..nf {
            let (want, got) = (build(Some(out)), outer.without_fold(out));
            for b in 0..grams.bins.len() {
                assert_eq!(
                    bits(&got.totals, b, 0),
                    bits(&want.totals, b, 0),
                    "total {b}"
                );
                for f in 0..nf {
                    assert_eq!(
                        bits(&got.folds, b, f),
                        bits(&want.folds, b, f),
                        "fold {b} {f}"
                    );
                    assert_eq!(
                        bits(&got.trains, b, f),
                        bits(&want.trains, b, f),
                        "train {b}"
                    );
                }
            }
        }
    }

    #[test]
    fn gram_triangle_is_the_sum_of_the_rows_outer_products_bit_for_bit() {
        // every width the kernels take (dim 1 to 21), from a non-zero start: each entry is
        // the running sum of x_a x_b over the rows, in row order
        let mut rng = Stream::new(11, 4);
        for dim in 1..=21 {
            let m = 7;
            let rows: Vec<f64> = (0..m * dim).map(|_| rng.normal()).collect();
            let start: Vec<f64> = (0..dim * (dim + 1) / 2).map(|_| rng.normal()).collect();
            let mut want = start.clone();
            for row in rows.chunks_exact(dim) {
                let mut at = 0;
                for a in 0..dim {
                    for b in 0..=a {
                        want[at] += row[a] * row[b];
                        at += 1;
                    }
                }
            }
            let mut got = start.clone();
            gram_lower_add(&rows, dim, &mut got);
            assert_eq!(
                got.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                want.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                "dim {dim}"
            );
        }
    }

    #[test]
    fn residual_kappa_pairs_rows_within_runs_of_one_maneuver_only() {
        // a bin's rows: three maneuvers, a gap inside the second, a NaN residual; the
        // Bartlett-weighted autocorrelation written out pair by pair
        let n = 900;
        let mut rng = Stream::new(8, 3);
        let mut z = vec![0.0; n];
        for i in 1..n {
            z[i] = 0.7 * z[i - 1] + rng.normal();
        }
        z[450] = f64::NAN;
        let man: Vec<u64> = (0..n).map(|i| (i / 300) as u64).collect();
        let rows: Vec<usize> = (0..n).filter(|i| !(380..395).contains(i)).collect();
        let ones = vec![1.0; n];
        let lookup = |c: &str| -> Option<&[f64]> { (c == "one").then_some(&ones[..]) };
        let design = Design::build(&[("b".into(), "one".into())], &lookup, n).expect("design");
        let theta = [0.2];
        let r: Vec<f64> = rows.iter().map(|&i| z[i] - 0.2).collect();
        let fin: Vec<f64> = r.iter().copied().filter(|v| v.is_finite()).collect();
        let mean = fin.iter().sum::<f64>() / fin.len() as f64;
        let g0: f64 = fin.iter().map(|v| (v - mean).powi(2)).sum();
        let mut k_sum = 0.0;
        for k in 1..=KAPPA_MAX_LAG {
            let mut g = 0.0;
            for m in 0..rows.len() - k {
                let (a, b) = (rows[m], rows[m + k]);
                let same = (a..=b).all(|i| man[i] == man[a]);
                if b == a + k && same && r[m].is_finite() && r[m + k].is_finite() {
                    g += (r[m] - mean) * (r[m + k] - mean);
                }
            }
            k_sum += (1.0 - k as f64 / (KAPPA_MAX_LAG as f64 + 1.0)) * g / g0;
        }
        let want = (1.0 + 2.0 * k_sum).max(1.0);
        let got = residual_kappa(&design, &z, &man, &rows, &theta);
        assert!((got - want).abs() < 1e-12 * want, "{got} {want}");
        assert!(want > 3.0, "{want}");
    }

    #[test]
    fn pool_bins_agree_with_the_qr_fit_of_every_bin() {
        let (design, z, alpha, man) = data(20_000, 4);
        let opts = iid_identify();
        let qr = fit_bins(&design, &z, &alpha, &man, &opts).expect("fit");
        let gram = pool_bins(&design, &z, &alpha, &man, &opts).expect("pool");
        assert_eq!(qr.bins.len(), gram.bins.len());
        for (a, b) in qr.bins.iter().zip(&gram.bins) {
            assert_eq!(
                (a.alpha_lo, a.n, a.note.is_empty()),
                (b.alpha_lo, b.n, b.note.is_empty())
            );
            assert_eq!(a.identifiable, b.identifiable);
            for (x, y) in a.params.iter().zip(&b.params) {
                assert!((x - y).abs() <= 1e-8 * (1.0 + x.abs()), "{x} vs {y}");
            }
            for (x, y) in a.excitation.iter().zip(&b.excitation) {
                assert!((x - y).abs() <= 1e-9, "{x} vs {y}");
            }
        }
    }

    #[test]
    fn paired_se_is_the_standard_error_of_the_fold_differences() {
        let sc = |f: Vec<f64>| CvScore {
            columns: vec![],
            rms: f64::NAN,
            tic: f64::NAN,
            mse: f64::NAN,
            mse_se: f64::NAN,
            fold_mse: f,
        };
        // fold errors that share a large between-fold spread, with a steady difference
        let a = sc(vec![1.0, 5.0, 2.0, 9.0, 3.0]);
        let b = sc(vec![1.5, 5.4, 2.6, 9.5, 3.5]);
        // d = b - a = 0.5, 0.4, 0.6, 0.5, 0.5: mean 0.5, sample variance 0.005
        let want = (0.005f64 / 5.0).sqrt();
        assert!((b.paired_se(&a) - want).abs() < 1e-12);
        // a fold missing in either is left out; fewer than two common folds: NaN
        let c = sc(vec![f64::NAN, 5.4, f64::NAN, f64::NAN, f64::NAN]);
        assert!(c.paired_se(&a).is_nan());
    }

    #[test]
    fn solve_subset_matches_the_normal_equations_of_a_small_case() {
        // z = 1 + 2 x exactly on x = 0, 1, 2: Gram of [1, x, z]
        let rows = [[1.0, 0.0, 1.0], [1.0, 1.0, 3.0], [1.0, 2.0, 5.0]];
        let mut g = vec![0.0; 9];
        for r in rows {
            for a in 0..3 {
                for b in 0..3 {
                    g[a * 3 + b] += r[a] * r[b];
                }
            }
        }
        let (th, sse) = solve_subset(&g, 3, &[0, 1]).expect("solves");
        assert!((th[0] - 1.0).abs() < 1e-12 && (th[1] - 2.0).abs() < 1e-12);
        assert!(sse < 1e-12);
        // a column duplicated is dependent
        assert!(solve_subset(&g, 3, &[0, 0]).is_none());
    }

    /// z = 0.5 x1 + 0.3 s + 0.2 x3 + noise, where the "spoiler" s = 0.8 x1 + 0.05 noise is
    /// geared to x1 (VIF about 80 in every bin).
    fn geared(n: usize, seed: u64) -> (Design, Vec<f64>, Vec<f64>, Vec<u64>) {
        let mut rng = Stream::new(seed, 9);
        let (mut x1, mut s, mut x3, mut z, mut alpha, mut man) =
            (vec![], vec![], vec![], vec![], vec![], vec![]);
        for i in 0..n {
            let a = rng.range(-1.0, 1.0);
            let sp = 0.8 * a + 0.05 * rng.normal();
            let c = rng.range(-1.0, 1.0);
            z.push(0.5 * a + 0.3 * sp + 0.2 * c + 0.01 * rng.normal());
            x1.push(a);
            s.push(sp);
            x3.push(c);
            alpha.push(5.0 + 15.0 * rng.uniform());
            man.push((i / 400) as u64);
        }
        let lookup = |c: &str| -> Option<&[f64]> {
            match c {
                "x1" => Some(&x1),
                "s" => Some(&s),
                "x3" => Some(&x3),
                _ => None,
            }
        };
        let regs: Vec<(String, String)> = [("bias", "1"), ("a", "x1"), ("c", "x3"), ("sp", "s")]
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
        let design = Design::build(&regs, &lookup, n).expect("design");
        (design, z, alpha, man)
    }

    #[test]
    fn a_term_collinear_in_most_bins_leaves_the_structure_and_its_partner_carries_it() {
        let (design, z, alpha, man) = geared(20_000, 2);
        let identify = iid_identify();
        let sm = SmoothOptions::default();
        let ff = identify_flap(&design, &z, &alpha, &man, &identify, None, &sm, None).expect("fit");
        // the last listed collinear term leaves; the note names its partner
        assert_eq!(ff.chosen, vec![0, 1, 2]);
        assert_eq!(ff.pruned.len(), 1);
        assert_eq!(ff.pruned[0].column, 3);
        assert!(
            ff.pruned[0].note.contains("collinear with 'a'"),
            "{}",
            ff.pruned[0].note
        );
        // x1's estimate carries the geared term: 0.5 + 0.3 * 0.8
        for bin in ff.fit.bins.iter().filter(|b| b.note.is_empty()) {
            assert!(bin.identifiable[1], "{:?}", bin.notes);
            assert!((bin.params[1] - 0.74).abs() < 0.02, "{}", bin.params[1]);
        }
        // kept whole: both not identified, named against each other, yet in the table
        let keep = IdentifyOptions {
            prune_collinear: false,
            ..identify.clone()
        };
        let whole = identify_flap(&design, &z, &alpha, &man, &keep, None, &sm, None).expect("fit");
        assert!(whole.pruned.is_empty());
        for bin in whole.fit.bins.iter().filter(|b| b.note.is_empty()) {
            assert!(bin.vif[1] > 10.0 && bin.vif[3] > 10.0);
            assert!(!bin.identifiable[1] && !bin.identifiable[3]);
            assert!(
                bin.notes[1].starts_with("collinear with 'sp'"),
                "{}",
                bin.notes[1]
            );
            assert!(
                bin.notes[3].starts_with("collinear with 'a'"),
                "{}",
                bin.notes[3]
            );
            assert!(bin.smoothable[1] && bin.smoothable[3]);
            assert!(bin.identifiable[2], "{}", bin.notes[2]);
        }
        // the smoothed tables keep the combination the data excite: a + 0.8 sp = 0.74
        let (ta, ts) = (&whole.smoothed[1].values, &whole.smoothed[3].values);
        for (va, vs) in ta.iter().zip(ts) {
            if *va != 0.0 {
                assert!((va + 0.8 * vs - 0.74).abs() < 0.02, "{va} {vs}");
            }
        }
        // no limit: the condition-index rule alone identifies both
        let loose = IdentifyOptions {
            max_vif: f64::INFINITY,
            ..identify
        };
        let free = identify_flap(&design, &z, &alpha, &man, &loose, None, &sm, None).expect("fit");
        assert!(free.pruned.is_empty());
        assert!(free
            .fit
            .bins
            .iter()
            .any(|b| b.identifiable[1] && b.identifiable[3]));
    }

    #[test]
    fn gram_collinearity_gives_the_qr_fits_vif_t_and_partner() {
        let (design, z, alpha, man) = geared(20_000, 4);
        let fit = fit_bins(&design, &z, &alpha, &man, &iid_identify()).expect("fit");
        let grams = bin_grams(&design, &z, &bin_members(&fit), &man);
        let constant: Vec<bool> = design.exprs.iter().map(|e| e.is_constant()).collect();
        let table = gram_collinearity(
            &fitted_totals(&grams, &fit),
            grams.dim,
            &[0, 1, 2, 3],
            &constant,
        );
        let bins: Vec<&BinFit> = fit.bins.iter().filter(|b| b.note.is_empty()).collect();
        assert_eq!(table.len(), bins.len());
        for (t, b) in table.iter().zip(&bins) {
            for j in 1..4 {
                assert!(
                    (t.vif[j] - b.vif[j]).abs() < 1e-6 * b.vif[j],
                    "{} {}",
                    t.vif[j],
                    b.vif[j]
                );
                let tq = (b.params[j] / b.std_err[j]).abs();
                assert!((t.t[j] - tq).abs() < 1e-6 * tq.max(1.0), "{} {tq}", t.t[j]);
                assert_eq!(t.partner[j], b.most_correlated[j]);
            }
        }
    }

    #[test]
    fn planned_totals_are_the_totals_of_the_bins_the_fit_fits() {
        // the collinearity rule decides before the fit: it must see the bins the fit fits,
        // not one with enough rows but too few finite ones (the fit fails there; the data
        // rule itself is `BinPlan::enough_data` in both)
        let (design, mut z, alpha, man) = geared(20_000, 4);
        let opts = iid_identify();
        let plan = plan_bins(&design, &z, &alpha, &man, &opts).expect("plan");
        let b = (0..plan.members.len())
            .find(|&b| plan.enough_data(b))
            .expect("a bin with data");
        for &r in &plan.members[b][3..] {
            z[r] = f64::NAN;
        }
        let fit = fit_bins(&design, &z, &alpha, &man, &opts).expect("fit");
        assert!(
            fit.bins[b].note.starts_with("not fitted"),
            "{}",
            fit.bins[b].note
        );
        let grams = bin_grams(&design, &z, &plan.members, &man);
        assert_eq!(bin_members(&fit), plan.members);
        let want = fitted_totals(&grams, &fit);
        assert!(want.len() >= 2);
        assert_eq!(planned_totals(&grams, &plan), want);
    }

    #[test]
    fn a_column_that_never_moves_leaves_the_others_vifs_alone() {
        // the pool's x3 ("c") replaced by zeros: dependent on the bias in every bin
        let (design, z, alpha, man) = geared(8_000, 6);
        let mut zero = design.clone();
        for r in 0..zero.nrows {
            zero.values[r * 4 + 2] = 0.0;
        }
        let fit = fit_bins(&design, &z, &alpha, &man, &iid_identify()).expect("fit");
        let grams = bin_grams(&zero, &z, &bin_members(&fit), &man);
        let totals = fitted_totals(&grams, &fit);
        let constant = [true, false, false, false];
        let with = gram_collinearity(&totals, grams.dim, &[0, 1, 2, 3], &constant);
        let without = gram_collinearity(&totals, grams.dim, &[0, 1, 3], &constant);
        for (a, b) in with.iter().zip(&without) {
            assert!(a.vif[2].is_nan() && a.partner[2].is_none());
            assert!((a.vif[1] - b.vif[1]).abs() < 1e-9 * b.vif[1]);
            assert!((a.vif[3] - b.vif[2]).abs() < 1e-9 * b.vif[2]);
            assert_eq!(a.partner[1], Some(3));
        }
        // and the zero column is not what the rule leaves out
        let names: Vec<String> = ["bias", "a", "c", "sp"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let (j, _) = collinear_to_prune(&with, &names, &constant, 10.0).expect("sp is collinear");
        assert_eq!(j, 3);
    }

    #[test]
    fn reselecting_bootstrap_zeroes_a_noise_term_the_replicates_drop() {
        use crate::bootstrap::{bootstrap_smoothed, BootstrapOptions, Reselect};
        let (design, z, alpha, man) = data(30_000, 3);
        let identify = iid_identify();
        let (pf, grams) = pool_bins_grams(&design, &z, &alpha, &man, &identify).expect("pool");
        let so = SelectOptions {
            min_excitation_snr: 0.0,
            ..SelectOptions::default()
        };
        // every maneuver counted once: the selection without weights, to the last bit
        let ones: std::collections::HashMap<u64, f64> = man.iter().map(|m| (*m, 1.0)).collect();
        let a = select_with_grams(&design, &z, &man, &pf, &grams, &so).expect("select");
        let b = select_weighted(
            &design,
            &z,
            &man,
            &pf,
            &grams,
            &so,
            Some(&ones),
            Some(&a.kappa),
        )
        .expect("w");
        assert_eq!(a.chosen, vec![0, 1, 2]);
        assert_eq!(a.chosen, b.chosen);
        for (x, y) in a.nested.iter().zip(&b.nested) {
            assert_eq!(x.mse.to_bits(), y.mse.to_bits());
        }
        // a final structure that kept the noise term x3 (pool column 3): the replicates'
        // own selections drop it, so it is exactly zero in them and its band holds zero
        let chosen = vec![0, 1, 2, 3];
        let fin = subset_design(&design, &chosen);
        let fit = fit_bins(&fin, &z, &alpha, &man, &identify).expect("fit");
        let bo = BootstrapOptions {
            replicates: 40,
            seed: 1,
            ..BootstrapOptions::default()
        };
        let sm = SmoothOptions::default();
        let rs = Reselect {
            pool: &design,
            pool_fit: &pf,
            grams: &grams,
            select: &so,
            kappa: &a.kappa,
            chosen: &chosen,
        };
        let with = bootstrap_smoothed(&fin, &z, &man, &fit, &sm, &bo, Some(&rs)).expect("boot");
        let without = bootstrap_smoothed(&fin, &z, &man, &fit, &sm, &bo, None).expect("boot");
        let zero = |reps: &[Vec<f64>]| reps.iter().filter(|r| r.iter().all(|v| *v == 0.0)).count();
        assert!(zero(&with.replicates[3]) * 10 >= 9 * bo.replicates);
        assert_eq!(zero(&without.replicates[3]), 0);
        for (b, bin) in fit.bins.iter().enumerate() {
            if bin.identifiable[3] {
                assert!(with.bin_lower[b][3] <= 0.0 && 0.0 <= with.bin_upper[b][3]);
            }
            // no band excludes its own estimate, even where the replicates collapse to zero
            for j in 0..4 {
                let (lo, hi, est) = (with.bin_lower[b][j], with.bin_upper[b][j], bin.params[j]);
                if lo.is_finite() {
                    assert!(
                        lo <= est && est <= hi,
                        "bin {b} param {j}: {est} not in [{lo}, {hi}]"
                    );
                }
                assert!(with.bin_replicates_ok[b][j] <= bo.replicates);
            }
        }
        // inclusion frequencies: the noise term is kept by at most a tenth of the replicates,
        // the true terms by all; without reselection every term counts as kept
        assert!(with.inclusion[3] <= 0.1, "{:?}", with.inclusion);
        assert!(with.inclusion[1] == 1.0 && with.inclusion[2] == 1.0);
        assert!(without.inclusion.iter().all(|&v| v == 1.0));
        // the true terms, kept by every replicate, keep bands of the same width
        let width = |bt: &crate::bootstrap::Bootstrap, j: usize| -> f64 {
            let w: Vec<f64> = (0..fit.bins.len())
                .map(|b| bt.bin_upper[b][j] - bt.bin_lower[b][j])
                .filter(|v| v.is_finite())
                .collect();
            w.iter().sum::<f64>() / w.len() as f64
        };
        for j in [1, 2] {
            let r = width(&with, j) / width(&without, j);
            assert!((0.8..1.25).contains(&r), "parameter {j}: width ratio {r}");
        }
    }

    #[test]
    fn stepwise_and_mof_keep_the_true_terms_and_drop_noise_terms() {
        let (design, z, alpha, man) = data(30_000, 3);
        let pool = fit_bins(&design, &z, &alpha, &man, &iid_identify()).expect("fit");
        for method in [Method::Stepwise, Method::Mof] {
            let opts = SelectOptions {
                method,
                min_excitation_snr: 0.0,
                ..SelectOptions::default()
            };
            let sel = select_structure(&design, &z, &man, &pool, &opts).expect("selects");
            assert_eq!(sel.chosen, vec![0, 1, 2], "{method:?}: {:?}", sel.count);
            // the noise regressors are rarely selected (about 5 % of bins at F_in = 4)
            let nfit = sel.fitted.iter().filter(|f| **f).count();
            assert!(
                sel.count[3] * 5 < nfit && sel.count[4] * 5 < nfit,
                "{:?}",
                sel.count
            );
            // the selected structure predicts held-out maneuvers better than the bias alone
            assert!(sel.nested[sel.chosen_k].mse < sel.nested[0].mse);
            assert!(sel.nested[sel.chosen_k].mse <= sel.full.mse + sel.full.mse_se);
        }
    }

    #[test]
    fn a_companion_joins_its_kept_term_and_the_score_is_the_shipped_structures() {
        let (design, z, alpha, man) = data(30_000, 3);
        let pool = fit_bins(&design, &z, &alpha, &man, &iid_identify()).expect("fit");
        let base = SelectOptions {
            min_excitation_snr: 0.0,
            ..SelectOptions::default()
        };
        // x3 (noise, a held-out cost far below the error's standard error) rides with x1
        // (kept), x4 with x3 (a chain); nothing joins a dropped term
        let opts = SelectOptions {
            companions: vec![(4, 2), (1, 3), (3, 4)],
            ..base.clone()
        };
        let sel = select_structure(&design, &z, &man, &pool, &opts).expect("selects");
        assert_eq!(sel.chosen, vec![0, 1, 2, 3, 4]);
        // the reported score is the shipped structure's, not the path's
        assert_eq!(sel.pruned.columns, sel.chosen);
        let plain = select_structure(&design, &z, &man, &pool, &base).expect("selects");
        assert_eq!(plain.chosen, vec![0, 1, 2]);
        let only_dropped = SelectOptions {
            companions: vec![(3, 1), (4, 3)],
            ..base.clone()
        };
        let sel = select_structure(&design, &z, &man, &pool, &only_dropped).expect("selects");
        assert_eq!(sel.chosen, vec![0, 1, 2]);
        let bad = SelectOptions {
            companions: vec![(1, 9)],
            ..base
        };
        let e = select_structure(&design, &z, &man, &pool, &bad).unwrap_err();
        assert!(e.to_string().contains("companions"), "{e}");
    }
}
