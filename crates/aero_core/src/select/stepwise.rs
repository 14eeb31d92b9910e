//! Forward stepwise regression with partial-F entry and removal (Klein, Batterson &
//! Murphy 1981; Klein & Morelli 2006, Section 5.4.2; SIDPAC `swr`) on one bin's augmented
//! Gram matrix, with a collinearity guard on entry.
//!
//! The Cholesky factor `L` of the selected columns' normal equations is grown one column
//! at a time: a candidate `c` costs one forward substitution `L w = X_Sᵀ x_c`
//! (`O(k²)`), its pivot `d = x_cᵀx_c − wᵀw` is the residual sum of squares of `x_c`
//! on the selected columns, and the residual sum of squares of z drops by
//! `u² = (x_cᵀz − wᵀy)² / d`, `y = L⁻¹ X_Sᵀ z` (the bordered Cholesky update, Golub & Van
//! Loan 2013, Section 4.2.5). Refactoring the `k × k` matrix for every candidate subset,
//! `O(k³)`, was half the time of a reselecting bootstrap. A removal uses
//! `SSE_{S∖j} = SSE_S + θ_j² / [(X_SᵀX_S)⁻¹]_{jj}` and refactors once.
//!
//! **Collinearity guard.** A candidate enters only if afterwards no selected non-forced
//! column has a variance inflation factor above `max_vif` (Klein & Morelli 2006,
//! Section 5.4.1: VIF > 10 marks harmful collinearity). The VIF is taken with the forced
//! columns partialled out, `VIF_j = [(X_SᵀX_S)⁻¹]_{jj} · ‖(I − P_F) x_j‖²`; with the bias as
//! the forced column this is the usual centred VIF `1 / (1 − R_j²)`. `‖(I − P_F) x_j‖²` is
//! read off the factor: the first `|F|` entries of `L`'s row `j` are `x_j`'s coordinates on
//! the forced columns. When the candidate of largest partial F would break the guard, the
//! next largest above `F_in` is tried: of two regressors that carry the same information in
//! a bin (β̇ and p̂ sin α − r̂ cos α at high alpha), one enters, not both with inflated and
//! mutually cancelling estimates.

/// Pivot tolerance of [`Factor::probe`], relative to the column's own sum of squares (the
/// same rule as [`super::solve_subset`]).
pub(super) const PIVOT_TOL: f64 = 1e-10;

/// Cholesky factor of the normal equations of a growing set of columns of an augmented
/// Gram matrix (`dim × dim`, z last).
#[derive(Clone)]
pub(super) struct Factor<'a> {
    g: &'a [f64],
    dim: usize,
    cols: Vec<usize>,
    /// Row `i` of the lower factor holds `i + 1` entries.
    l: Vec<Vec<f64>>,
    /// `L⁻¹ X_Sᵀ z`.
    y: Vec<f64>,
    /// Residual sum of squares of z on `cols`.
    sse: f64,
}

/// What a candidate column would add to a [`Factor`].
pub(super) struct Probe {
    /// `L⁻¹ X_Sᵀ x_c`.
    pub(super) w: Vec<f64>,
    /// Pivot `x_cᵀx_c − wᵀw` (> 0).
    pub(super) d: f64,
    /// New entry of `y`.
    pub(super) u: f64,
}

impl<'a> Factor<'a> {
    pub(super) fn new(g: &'a [f64], dim: usize) -> Self {
        let zc = dim - 1;
        Factor {
            g,
            dim,
            cols: Vec::new(),
            l: Vec::new(),
            y: Vec::new(),
            sse: g[zc * dim + zc].max(0.0),
        }
    }

    /// Factor of `cols` in order, skipping any dependent on the earlier ones.
    pub(super) fn of(g: &'a [f64], dim: usize, cols: &[usize]) -> Self {
        let mut f = Factor::new(g, dim);
        for &c in cols {
            if let Some(p) = f.probe(c) {
                f.push(c, p);
            }
        }
        f
    }

    /// `x ← L⁻ᵀ x` (the first `k` entries), sweeping the rows of `L` from the last: row `i`
    /// fixes `x_i` and is subtracted from the entries before it: the column-oriented back
    /// substitution of `Lᵀ x = b` (Golub & Van Loan 2013, Section 3.1).
    fn back_substitute(&self, x: &mut [f64]) {
        for i in (0..self.cols.len()).rev() {
            let row = &self.l[i];
            let xi = x[i] / row[i];
            x[i] = xi;
            for (a, l) in x[..i].iter_mut().zip(&row[..i]) {
                *a -= l * xi;
            }
        }
    }

    /// The forward substitution of column `c`; `None` when it is (numerically) dependent on
    /// the columns already in, or not finite.
    pub(super) fn probe(&self, c: usize) -> Option<Probe> {
        let mut w = Vec::with_capacity(self.cols.len() + 1);
        let (d, u) = self.probe_into(c, &mut w)?;
        Some(Probe { w, d, u })
    }

    /// [`Factor::probe`] into the caller's buffer `w` (`L⁻¹ X_Sᵀ x_c`); returns the pivot
    /// `d` and the new entry `u` of `y`.
    pub(super) fn probe_into(&self, c: usize, w: &mut Vec<f64>) -> Option<(f64, f64)> {
        w.clear();
        self.probe_cached(c, w)
    }

    /// [`Factor::probe_into`] continuing from a `w` computed against an earlier state of this
    /// factor (its first `w.len()` columns): only the rows added since are substituted, `O(k)`
    /// per new row. Extending the factor along a path of columns this way costs `O(k²)` per
    /// candidate over the whole path instead of per step.
    pub(super) fn probe_cached(&self, c: usize, w: &mut Vec<f64>) -> Option<(f64, f64)> {
        let (g, dim) = (self.g, self.dim);
        let zc = dim - 1;
        let k = self.cols.len();
        for i in w.len().min(k)..k {
            let row = &self.l[i];
            let mut s = g[self.cols[i] * dim + c];
            for m in 0..i {
                s -= row[m] * w[m];
            }
            w.push(s / row[i]);
        }
        let gcc = g[c * dim + c];
        let d = gcc - w.iter().map(|v| v * v).sum::<f64>();
        if d.is_nan() || gcc <= 0.0 || d <= PIVOT_TOL * gcc {
            return None;
        }
        let u =
            (g[c * dim + zc] - w.iter().zip(&self.y).map(|(a, b)| a * b).sum::<f64>()) / d.sqrt();
        u.is_finite().then_some((d, u))
    }

    /// Residual sum of squares with the probed column added.
    fn sse_with(&self, p: &Probe) -> f64 {
        (self.sse - p.u * p.u).max(0.0)
    }

    /// The columns in, in order.
    pub(super) fn cols(&self) -> &[usize] {
        &self.cols
    }

    pub(super) fn push(&mut self, c: usize, p: Probe) {
        self.sse = self.sse_with(&p);
        let mut row = p.w;
        row.push(p.d.sqrt());
        self.l.push(row);
        self.y.push(p.u);
        self.cols.push(c);
    }

    /// Estimates `θ = L⁻ᵀ y` (scaled units).
    pub(super) fn theta(&self) -> Vec<f64> {
        let mut th = self.y.clone();
        self.back_substitute(&mut th);
        th
    }

    /// Diagonal of `(X_SᵀX_S)⁻¹ = L⁻ᵀ L⁻¹`: column sums of squares of `L⁻¹`.
    fn inv_diag(&self) -> Vec<f64> {
        let k = self.cols.len();
        let mut diag = vec![0.0; k];
        // column j of L⁻¹ by forward substitution of e_j
        let mut v = vec![0.0; k];
        for j in 0..k {
            v.iter_mut().for_each(|x| *x = 0.0);
            for i in j..k {
                let mut s = if i == j { 1.0 } else { 0.0 };
                for m in j..i {
                    s -= self.l[i][m] * v[m];
                }
                v[i] = s / self.l[i][i];
            }
            diag[j] = v[j..].iter().map(|x| x * x).sum();
        }
        diag
    }

    /// Largest variance inflation factor of the columns from position `nf` on, with the
    /// first `nf` (the forced columns) partialled out (see the module doc).
    fn max_vif(&self, nf: usize) -> f64 {
        self.vifs(nf).into_iter().fold(1.0, f64::max)
    }

    /// Variance inflation factor of each column from position `nf` on (see the module doc),
    /// in order.
    pub(super) fn vifs(&self, nf: usize) -> Vec<f64> {
        let inv = self.inv_diag();
        (nf..self.cols.len())
            .map(|i| {
                let c = self.cols[i];
                let css =
                    self.g[c * self.dim + c] - self.l[i][..nf].iter().map(|v| v * v).sum::<f64>();
                inv[i] * css.max(0.0)
            })
            .collect()
    }

    /// `(X_SᵀX_S)⁻¹` (row-major `k × k`) from `L⁻¹`.
    pub(super) fn inverse(&self) -> Vec<f64> {
        let k = self.cols.len();
        // columns of L⁻¹ (lower triangular), row-major in li
        let mut li = vec![0.0; k * k];
        for j in 0..k {
            for i in j..k {
                let mut s = if i == j { 1.0 } else { 0.0 };
                for m in j..i {
                    s -= self.l[i][m] * li[m * k + j];
                }
                li[i * k + j] = s / self.l[i][i];
            }
        }
        let mut inv = vec![0.0; k * k];
        for a in 0..k {
            for b in 0..=a {
                let v: f64 = (a..k).map(|m| li[m * k + a] * li[m * k + b]).sum();
                inv[a * k + b] = v;
                inv[b * k + a] = v;
            }
        }
        inv
    }

    /// Residual sum of squares of z on the columns in.
    pub(super) fn sse(&self) -> f64 {
        self.sse
    }

    /// Residual sum of squares without the column at position `i`.
    fn sse_without(&self, i: usize, theta: &[f64], inv: &[f64]) -> f64 {
        self.sse + theta[i] * theta[i] / inv[i]
    }
}

/// Partial F of the last entered column against the residual of `sse` on `dof` degrees of
/// freedom (infinite for an exact fit), divided by the variance inflation `kappa`.
fn partial_f(drop: f64, sse: f64, dof: f64, kappa: f64) -> f64 {
    if sse > 0.0 {
        drop / (sse / dof) / kappa
    } else {
        f64::INFINITY
    }
}

/// Forward stepwise regression with partial-F entry and removal (Klein &
/// Morelli 2006, Section 5.4.2), on one bin's Gram matrix, with the collinearity guard of
/// the module doc. `n`: samples; `forced`: always kept; `candidates`: may enter; `kappa`:
/// variance inflation dividing every partial F (see [`super`]); `max_vif`: largest VIF a
/// non-forced selected column may reach (`f64::INFINITY`: no guard). Returns the selected
/// columns (forced first, then in order of entry) and, per column of the Gram matrix, its
/// final partial F (to remove for a selected column, to enter for the others; NaN when not
/// computable).
#[allow(clippy::too_many_arguments)]
pub fn stepwise(
    g: &[f64],
    dim: usize,
    n: f64,
    forced: &[usize],
    candidates: &[usize],
    kappa: f64,
    f_in: f64,
    f_out: f64,
    max_vif: f64,
) -> (Vec<usize>, Vec<f64>) {
    let mut fac = Factor::of(g, dim, forced);
    let nf = fac.cols.len();
    let kappa = kappa.max(1.0);
    // per column, its forward substitution against the factor's first rows (extended by
    // the rows an entry adds, emptied when a removal refactors): the same numbers as a
    // fresh probe, at O(k) per entry instead of O(k²)
    let mut cache: Vec<Vec<f64>> = vec![Vec::new(); dim];
    for _ in 0..4 * dim {
        // entry: candidates by decreasing partial F; the first above F_in that keeps every
        // VIF within max_vif enters
        let dof = n - fac.cols.len() as f64 - 1.0;
        if dof <= 0.0 {
            break;
        }
        // (column, partial F, pivot, new entry of y); the substitution stays in the cache
        let mut trials: Vec<(usize, f64, f64, f64)> = candidates
            .iter()
            .filter(|c| !fac.cols.contains(c))
            .filter_map(|&c| {
                let (d, u) = fac.probe_cached(c, &mut cache[c])?;
                let e = (fac.sse - u * u).max(0.0);
                Some((c, partial_f(fac.sse - e, e, dof, kappa), d, u))
            })
            .collect();
        // stable: equal F keep the candidates' order
        trials.sort_by(|a, b| b.1.total_cmp(&a.1));
        let mut entered = false;
        for (c, f, d, u) in trials {
            if f.is_nan() || f <= f_in {
                break;
            }
            let p = Probe {
                w: cache[c].clone(),
                d,
                u,
            };
            let mut next = fac.clone();
            next.push(c, p);
            if max_vif.is_finite() && next.max_vif(nf) > max_vif {
                continue;
            }
            fac = next;
            entered = true;
            break;
        }
        if !entered {
            break;
        }
        // removal of the weakest non-forced column, unless that is the one just entered
        loop {
            let k = fac.cols.len();
            let dof = n - k as f64;
            let (theta, inv) = (fac.theta(), fac.inv_diag());
            let worst = (nf..k)
                .map(|i| {
                    let e = fac.sse_without(i, &theta, &inv);
                    (i, partial_f(e - fac.sse, fac.sse, dof, kappa))
                })
                .filter(|(_, f)| !f.is_nan())
                .min_by(|a, b| a.1.total_cmp(&b.1));
            match worst {
                Some((i, f)) if f < f_out && i + 1 < k => {
                    let mut cols = fac.cols.clone();
                    cols.remove(i);
                    fac = Factor::of(g, dim, &cols);
                    cache.iter_mut().for_each(Vec::clear);
                }
                _ => break,
            }
        }
    }
    // final partial F of every column
    let k = fac.cols.len();
    let dof_in = n - k as f64;
    let dof_out = dof_in - 1.0;
    let (theta, inv) = (fac.theta(), fac.inv_diag());
    let partial: Vec<f64> = (0..dim - 1)
        .map(|c| {
            if let Some(i) = fac.cols.iter().position(|&s| s == c) {
                let e = fac.sse_without(i, &theta, &inv);
                if fac.sse > 0.0 && dof_in > 0.0 && e.is_finite() {
                    (e - fac.sse) / (fac.sse / dof_in) / kappa
                } else {
                    f64::NAN
                }
            } else {
                match fac.probe(c) {
                    Some(p) => {
                        let e = fac.sse_with(&p);
                        if e > 0.0 && dof_out > 0.0 {
                            (fac.sse - e) / (e / dof_out) / kappa
                        } else {
                            f64::NAN
                        }
                    }
                    None => f64::NAN,
                }
            }
        })
        .collect();
    (fac.cols, partial)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::select::solve_subset;
    use crate::sim::rng::Stream;

    /// The stepwise regression as it was before the updated factor: every candidate subset
    /// refactored from scratch by [`solve_subset`] (the reference of the equivalence test).
    #[allow(clippy::too_many_arguments)]
    fn stepwise_reference(
        g: &[f64],
        dim: usize,
        n: f64,
        forced: &[usize],
        candidates: &[usize],
        kappa: f64,
        f_in: f64,
        f_out: f64,
    ) -> (Vec<usize>, Vec<f64>) {
        let mut sel: Vec<usize> = Vec::new();
        for &c in forced {
            sel.push(c);
            if solve_subset(g, dim, &sel).is_none() {
                sel.pop();
            }
        }
        let forced_kept = sel.clone();
        let kappa = kappa.max(1.0);
        let sse_of = |s: &[usize]| solve_subset(g, dim, s).map(|(_, e)| e);
        let Some(mut sse) = sse_of(&sel) else {
            return (sel, vec![f64::NAN; dim - 1]);
        };
        for _ in 0..4 * dim {
            // entry
            let dof = n - sel.len() as f64 - 1.0;
            if dof <= 0.0 {
                break;
            }
            let mut best: Option<(usize, f64, f64)> = None;
            for &c in candidates {
                if sel.contains(&c) {
                    continue;
                }
                let mut trial = sel.clone();
                trial.push(c);
                if let Some(e) = sse_of(&trial) {
                    let f = if e > 0.0 {
                        (sse - e) / (e / dof) / kappa
                    } else {
                        f64::INFINITY
                    };
                    if best.is_none_or(|(_, bf, _)| f > bf) {
                        best = Some((c, f, e));
                    }
                }
            }
            match best {
                Some((c, f, e)) if f > f_in => {
                    sel.push(c);
                    sse = e;
                }
                _ => break,
            }
            // removal
            loop {
                let dof = n - sel.len() as f64;
                let mut worst: Option<(usize, f64, f64)> = None;
                for (i, &c) in sel.iter().enumerate() {
                    if forced_kept.contains(&c) {
                        continue;
                    }
                    let mut trial = sel.clone();
                    trial.remove(i);
                    if let Some(e) = sse_of(&trial) {
                        let f = if sse > 0.0 {
                            (e - sse) / (sse / dof) / kappa
                        } else {
                            f64::INFINITY
                        };
                        if worst.is_none_or(|(_, wf, _)| f < wf) {
                            worst = Some((i, f, e));
                        }
                    }
                }
                match worst {
                    Some((i, f, e)) if f < f_out && i < sel.len() - 1 => {
                        sel.remove(i);
                        sse = e;
                    }
                    _ => break,
                }
            }
        }
        // final partial F of every column
        let dof_in = n - sel.len() as f64;
        let dof_out = dof_in - 1.0;
        let partial: Vec<f64> = (0..dim - 1)
            .map(|c| {
                if let Some(i) = sel.iter().position(|&s| s == c) {
                    let mut t = sel.clone();
                    t.remove(i);
                    match sse_of(&t) {
                        Some(e) if sse > 0.0 && dof_in > 0.0 => (e - sse) / (sse / dof_in) / kappa,
                        _ => f64::NAN,
                    }
                } else {
                    let mut t = sel.clone();
                    t.push(c);
                    match sse_of(&t) {
                        Some(e) if e > 0.0 && dof_out > 0.0 => (sse - e) / (e / dof_out) / kappa,
                        _ => f64::NAN,
                    }
                }
            })
            .collect();
        (sel, partial)
    }

    /// Augmented Gram matrix of `x` (row-major `n × p`) and `z`, columns scaled to unit RMS.
    fn gram(x: &[f64], n: usize, p: usize, z: &[f64]) -> Vec<f64> {
        let dim = p + 1;
        let col = |j: usize, i: usize| if j < p { x[i * p + j] } else { z[i] };
        let scale: Vec<f64> = (0..dim)
            .map(|j| ((0..n).map(|i| col(j, i).powi(2)).sum::<f64>() / n as f64).sqrt())
            .collect();
        let mut g = vec![0.0; dim * dim];
        for a in 0..dim {
            for b in 0..dim {
                g[a * dim + b] =
                    (0..n).map(|i| col(a, i) * col(b, i)).sum::<f64>() / (scale[a] * scale[b]);
            }
        }
        g
    }

    /// Bias, five regressors of which x3 is x1 plus a little noise and x5 pure noise.
    fn problem(seed: u64, n: usize, collinear_noise: f64) -> (Vec<f64>, usize, usize, Vec<f64>) {
        let mut rng = Stream::new(seed, 3);
        let p = 6;
        let mut x = vec![0.0; n * p];
        let mut z = vec![0.0; n];
        for i in 0..n {
            let v: Vec<f64> = (0..5).map(|_| rng.normal()).collect();
            let x3 = v[0] + collinear_noise * v[2];
            let row = [1.0, v[0], v[1], x3, v[3], v[4]];
            x[i * p..(i + 1) * p].copy_from_slice(&row);
            z[i] = 0.3 + 0.8 * v[0] - 0.4 * v[1] + 0.5 * x3 + 0.1 * v[3] + 0.5 * rng.normal();
        }
        (x, n, p, z)
    }

    #[test]
    fn the_updated_factor_selects_as_the_refactoring_reference() {
        for seed in 0..40u64 {
            let noise = [0.05, 0.3, 1.0, 3.0][(seed % 4) as usize];
            let n = 60 + 40 * (seed as usize % 5);
            let (x, n, p, z) = problem(seed, n, noise);
            let g = gram(&x, n, p, &z);
            let dim = p + 1;
            let cands: Vec<usize> = (1..p).collect();
            for (kappa, f_in) in [(1.0, 4.0), (3.0, 4.0), (1.0, 1.0)] {
                let (a, fa) = stepwise(
                    &g,
                    dim,
                    n as f64,
                    &[0],
                    &cands,
                    kappa,
                    f_in,
                    f_in,
                    f64::INFINITY,
                );
                let (b, fb) =
                    stepwise_reference(&g, dim, n as f64, &[0], &cands, kappa, f_in, f_in);
                assert_eq!(a, b, "seed {seed}, kappa {kappa}, f_in {f_in}");
                for (u, v) in fa.iter().zip(&fb) {
                    assert!(
                        (u.is_nan() && v.is_nan()) || (u - v).abs() <= 1e-7 * v.abs().max(1.0),
                        "seed {seed}: partial F {u} vs {v}"
                    );
                }
            }
        }
    }

    #[test]
    fn vif_is_the_closed_form_of_two_correlated_regressors() {
        // with the bias partialled out, VIF = 1 / (1 - r²) for r the sample correlation
        let (x, n, p, z) = problem(7, 500, 0.3);
        let g = gram(&x, n, p, &z);
        let f = Factor::of(&g, p + 1, &[0, 1, 3]);
        let mean = |j: usize| (0..n).map(|i| x[i * p + j]).sum::<f64>() / n as f64;
        let (m1, m3) = (mean(1), mean(3));
        let (mut s11, mut s33, mut s13) = (0.0, 0.0, 0.0);
        for i in 0..n {
            let (a, b) = (x[i * p + 1] - m1, x[i * p + 3] - m3);
            s11 += a * a;
            s33 += b * b;
            s13 += a * b;
        }
        let r2 = s13 * s13 / (s11 * s33);
        let want = 1.0 / (1.0 - r2);
        let got = f.max_vif(1);
        assert!((got - want).abs() < 1e-9 * want, "{got} vs {want}");
        assert!(
            want > 10.0,
            "the test needs a harmful collinearity: VIF {want}"
        );
    }

    #[test]
    fn the_guard_keeps_one_of_a_collinear_pair() {
        let (x, n, p, z) = problem(11, 400, 0.3);
        let g = gram(&x, n, p, &z);
        let cands: Vec<usize> = (1..p).collect();
        let (free, _) = stepwise(
            &g,
            p + 1,
            n as f64,
            &[0],
            &cands,
            1.0,
            4.0,
            4.0,
            f64::INFINITY,
        );
        assert!(free.contains(&1) && free.contains(&3), "{free:?}");
        let (guarded, _) = stepwise(&g, p + 1, n as f64, &[0], &cands, 1.0, 4.0, 4.0, 10.0);
        assert!(guarded.contains(&1) ^ guarded.contains(&3), "{guarded:?}");
        assert!(
            guarded.contains(&2),
            "an uncorrelated true term still enters: {guarded:?}"
        );
        let f = Factor::of(&g, p + 1, &guarded);
        assert!(f.max_vif(1) <= 10.0);
    }

    #[test]
    fn inverse_diagonal_and_drop_in_sse_match_refits() {
        let (x, n, p, z) = problem(3, 300, 1.0);
        let g = gram(&x, n, p, &z);
        let cols = [0, 1, 2, 3, 4];
        let f = Factor::of(&g, p + 1, &cols);
        let (th, sse) = solve_subset(&g, p + 1, &cols).expect("full rank");
        assert!((f.sse - sse).abs() < 1e-9 * sse);
        for (a, b) in f.theta().iter().zip(&th) {
            assert!((a - b).abs() < 1e-9 * b.abs().max(1e-3));
        }
        let inv = f.inv_diag();
        for i in 0..cols.len() {
            let rest: Vec<usize> = cols.iter().copied().filter(|&c| c != cols[i]).collect();
            let (_, e) = solve_subset(&g, p + 1, &rest).expect("full rank");
            let got = f.sse_without(i, &th, &inv);
            assert!((got - e).abs() < 1e-9 * e, "column {i}: {got} vs {e}");
        }
    }
}
