//! The greedy forward path of the structure selection, scored by cross-validation with one
//! Cholesky factor per bin and fold extended along the path, and every candidate scored in
//! `O(1)` from sums it carries along the path.
//!
//! At every step of the path each remaining candidate `c` is scored as `path + [c]`: per bin
//! and fold, the training fit on the excited columns of `path + [c]` predicts the fold. Let
//! `L` be the Cholesky factor of the training normal equations of the path's excited columns
//! `S`, `y = L⁻¹ X_Sᵀ z` and `θ = L⁻ᵀ y` the path's estimates. The bordered Cholesky update
//! (Golub & Van Loan 2013, Section 4.2.5) gives the candidate's `w = L⁻¹ X_Sᵀ x_c`, pivot
//! `d = x_cᵀx_c − wᵀw`, `u = (x_cᵀz − wᵀy)/√d`, and the estimates of `S + [c]`:
//! `θ_c = u/√d` and `θ − θ_c v` with `v = L⁻ᵀ w`. With the fold's Gram matrix `F` over `S`,
//! `a = X_{f,S}ᵀ z_f`, `g = X_{f,S}ᵀ x_{f,c}` and `γ = x_{f,c}ᵀ x_{f,c}`, and
//! `q_a = L⁻¹a`, `r = L⁻¹g`, `M = L⁻¹ F L⁻ᵀ` (so that `vᵀb = wᵀL⁻¹b` and `θᵀb = yᵀL⁻¹b`),
//! the held-out sums `Σẑ_f z_f` and `Σẑ_f²` of the candidate's fit are
//!
//! ```text
//! cross = yᵀq_a − θ_c wᵀq_a + θ_c a_c
//! yy    = yᵀMy − 2θ_c wᵀMy + θ_c² wᵀMw + 2θ_c yᵀr − 2θ_c² wᵀr + θ_c² γ
//! ```
//!
//! Growing `S` by one column adds one entry to `y`, `w`, `r`, `q_a` and one row to `M` and
//! leaves the earlier ones unchanged (the leading block of the inverse of a lower-triangular
//! matrix is the inverse of its leading block). So every product above is carried along the
//! path: the path's `yᵀq_a`, `yᵀMy` per bin and fold, and `wᵀw`, `wᵀy`, `wᵀq_a`, `wᵀr`,
//! `wᵀMw`, `wᵀMy`, `yᵀr` per candidate, each extended in `O(k)` per new row
//! ([`Cand::extend`]); a new row of `M` is `(r_c − M w_c)/√d` with diagonal
//! `(w_cᵀMw_c − 2w_cᵀr_c + γ_c)/d` for the column `c` the path takes (`O(k²)` once per bin,
//! fold and step). Computing `θ` of `path + [c]` and its held-out sums afresh cost `O(k²)`
//! per candidate and step, refactoring `O(k³)`. The scores are those of `super::cv_score`
//! to rounding (checked in the test builds).

use super::stepwise::PIVOT_TOL;
use super::{fold_cells, BinGrams, CvAccum, CvScore, Excitation, FoldGrams};

/// What one candidate carries along the path in one bin and fold: the length of its `w` and
/// `r` and their products.
#[derive(Clone, Copy, Default)]
struct Cand {
    len: usize,
    /// `wᵀw`, `wᵀy`, `wᵀq_a`, `wᵀr`, `wᵀMw`, `wᵀMy`, `yᵀr`.
    ww: f64,
    wy: f64,
    wqa: f64,
    wr: f64,
    wmw: f64,
    wmy: f64,
    yr: f64,
}

/// One bin and fold of the path; its vectors live in the scorer's arenas.
struct Cell<'g> {
    /// Held-out and training Gram matrices (augmented, `dim × dim`) and samples.
    fold: &'g [f64],
    train: &'g [f64],
    n_fold: f64,
    n_train: f64,
    /// Fold index.
    f: usize,
    /// Columns in the factor (the path's excited columns).
    k: usize,
    /// A path column was dependent on the earlier ones: every extension is singular too,
    /// and the bin predicts `fallback`.
    dead: bool,
    /// Held-out sums where the training set cannot fit a structure (`super::fallback_sums`).
    fallback: (f64, f64, f64),
    /// The held-out sums of the path itself.
    base: (f64, f64, f64),
    /// The path's `θᵀa = yᵀq_a` and `θᵀFθ = yᵀMy`, unclamped.
    cross: f64,
    yy: f64,
}

/// A cell's vectors: per slot (a column that may join the path, [`PathScorer::slot`]) its
/// `w` and `r`; the factor `L` and `M = L⁻¹ F L⁻ᵀ` (lower triangles packed by rows, row `i`
/// at `i(i+1)/2`); `y`, `q_a` and, per row `i` of `M`, `M[i, ..i]·y[..i]`; the factor's
/// columns and the slots' products.
struct Parts<'a> {
    w: &'a mut [f64],
    r: &'a mut [f64],
    l: &'a mut [f64],
    m: &'a mut [f64],
    y: &'a mut [f64],
    qa: &'a mut [f64],
    mdy: &'a mut [f64],
    cols: &'a mut [usize],
    cand: &'a mut [Cand],
}

/// Entries of one cell's block of [`PathScorer::store`].
fn block(kmax: usize) -> usize {
    2 * kmax * kmax + kmax * (kmax + 1) + 3 * kmax
}

impl<'a> Parts<'a> {
    fn of(blk: &'a mut [f64], cols: &'a mut [usize], cand: &'a mut [Cand], kmax: usize) -> Self {
        let tri = kmax * (kmax + 1) / 2;
        let (w, rest) = blk.split_at_mut(kmax * kmax);
        let (r, rest) = rest.split_at_mut(kmax * kmax);
        let (l, rest) = rest.split_at_mut(tri);
        let (m, rest) = rest.split_at_mut(tri);
        let (y, rest) = rest.split_at_mut(kmax);
        let (qa, mdy) = rest.split_at_mut(kmax);
        Parts {
            w,
            r,
            l,
            m,
            y,
            qa,
            mdy,
            cols,
            cand,
        }
    }
}

/// Row `i` of a lower triangle packed by rows.
fn row(t: &[f64], i: usize) -> &[f64] {
    &t[i * (i + 1) / 2..(i + 1) * (i + 2) / 2]
}

impl Cell<'_> {
    /// Extends the products of column `c` (in `slot`) by the factor's rows added since its
    /// last extension: `O(k)` per row.
    fn extend(&self, pt: &mut Parts<'_>, c: usize, slot: usize, kmax: usize, dim: usize) {
        let cd = &mut pt.cand[slot];
        let w = &mut pt.w[slot * kmax..(slot + 1) * kmax];
        let r = &mut pt.r[slot * kmax..(slot + 1) * kmax];
        for i in cd.len.min(self.k)..self.k {
            let li = row(pt.l, i);
            let s = pt.cols[i];
            let (mut sw, mut sr) = (self.train[s * dim + c], self.fold[s * dim + c]);
            for ((l, a), b) in li[..i].iter().zip(&w[..i]).zip(&r[..i]) {
                sw -= l * a;
                sr -= l * b;
            }
            let (om, rr) = (sw / li[i], sr / li[i]);
            let mi = row(pt.m, i);
            let mw: f64 = mi[..i].iter().zip(&w[..i]).map(|(a, b)| a * b).sum();
            let yi = pt.y[i];
            cd.wmw += 2.0 * om * mw + om * om * mi[i];
            cd.wmy += om * pt.mdy[i] + mw * yi + om * mi[i] * yi;
            cd.ww += om * om;
            cd.wy += om * yi;
            cd.wqa += om * pt.qa[i];
            cd.wr += om * rr;
            cd.yr += yi * rr;
            w[i] = om;
            r[i] = rr;
        }
        cd.len = cd.len.max(self.k);
    }

    /// Pivot `d` and new entry `u` of `y` for column `c` given its products (the rule of
    /// `Factor::probe_cached`); `None` when `c` is (numerically) dependent on the path.
    fn pivot(&self, cd: &Cand, c: usize, dim: usize) -> Option<(f64, f64)> {
        let gcc = self.train[c * dim + c];
        let d = gcc - cd.ww;
        if d.is_nan() || gcc <= 0.0 || d <= PIVOT_TOL * gcc {
            return None;
        }
        let u = (self.train[c * dim + dim - 1] - cd.wy) / d.sqrt();
        u.is_finite().then_some((d, u))
    }

    /// Held-out sums `(Σ(z−ẑ)², Σz², Σẑ²)` of the training fit of the path's columns and `c`
    /// (see the module doc); the fold predicts `fallback` when `c` depends on the path or a
    /// sum is not finite.
    fn score(
        &self,
        pt: &mut Parts<'_>,
        c: usize,
        slot: usize,
        kmax: usize,
        dim: usize,
    ) -> (f64, f64, f64) {
        let fold = self.fold;
        if self.dead {
            return self.fallback;
        }
        self.extend(pt, c, slot, kmax, dim);
        let cd = pt.cand[slot];
        let Some((d, u)) = self.pivot(&cd, c, dim) else {
            return self.fallback;
        };
        let tc = u / d.sqrt();
        let zz = fold[dim * dim - 1];
        let cross = self.cross - tc * cd.wqa + tc * fold[c * dim + dim - 1];
        let yy = self.yy - 2.0 * tc * cd.wmy + tc * tc * cd.wmw + 2.0 * tc * cd.yr
            - 2.0 * tc * tc * cd.wr
            + tc * tc * fold[c * dim + c];
        let sse = zz - 2.0 * cross + yy;
        if tc.is_finite() && sse.is_finite() && yy.is_finite() {
            (sse.max(0.0), zz, yy.max(0.0))
        } else {
            self.fallback
        }
    }

    /// Column `c` (in `slot`) joins the factor (the caller checked that this training set
    /// excites it): new rows of `L` and `M`, new entries of `y`, `q_a` and the path's sums.
    fn push(&mut self, pt: &mut Parts<'_>, c: usize, slot: usize, kmax: usize, dim: usize) {
        if self.dead {
            return;
        }
        self.extend(pt, c, slot, kmax, dim);
        let cd = pt.cand[slot];
        let Some((d, u)) = self.pivot(&cd, c, dim) else {
            self.dead = true;
            return;
        };
        let (k, lam) = (self.k, d.sqrt());
        let w = &pt.w[slot * kmax..slot * kmax + k];
        let r = &pt.r[slot * kmax..slot * kmax + k];
        // L's new row: [w, √d]
        let at = k * (k + 1) / 2;
        pt.l[at..at + k].copy_from_slice(w);
        pt.l[at + k] = lam;
        // M's new row: (r_c − M w_c) / λ, and its diagonal (wᵀMw − 2wᵀr + γ) / d
        let (done, new) = pt.m.split_at_mut(at);
        let new = &mut new[..=k];
        new[..k].copy_from_slice(r);
        for i in 0..k {
            let mi = row(done, i);
            let mut acc = mi[i] * w[i];
            for j in 0..i {
                acc += mi[j] * w[j];
                new[j] -= mi[j] * w[i];
            }
            new[i] -= acc;
        }
        for v in &mut new[..k] {
            *v /= lam;
        }
        new[k] = (cd.wmw - 2.0 * cd.wr + self.fold[c * dim + c]) / d;
        let dy: f64 = new[..k].iter().zip(&pt.y[..k]).map(|(a, b)| a * b).sum();
        let mu = new[k];
        pt.mdy[k] = dy;
        let qa = (self.fold[c * dim + dim - 1] - cd.wqa) / lam;
        pt.qa[k] = qa;
        pt.y[k] = u;
        pt.cols[k] = c;
        self.k = k + 1;
        // the path's own sums with y's new entry u: yᵀq_a and yᵀMy
        self.cross += u * qa;
        self.yy += 2.0 * u * dy + mu * u * u;
    }

    /// Held-out sums of the path itself.
    fn refresh(&mut self, dim: usize, min_points: usize) {
        let fold = self.fold;
        let zz = fold[dim * dim - 1];
        let sse = zz - 2.0 * self.cross + self.yy;
        self.base = if !self.dead
            && self.n_train >= (min_points * self.k.max(1)) as f64
            && sse.is_finite()
            && self.yy.is_finite()
        {
            (sse.max(0.0), zz, self.yy.max(0.0))
        } else {
            self.fallback
        };
    }
}

/// The path's cells and the rules of a training fit.
pub(super) struct PathScorer<'g> {
    cells: Vec<Cell<'g>>,
    dim: usize,
    p: usize,
    nf: usize,
    min_points: usize,
    s2: f64,
    path: Vec<usize>,
    /// Per pool column, its slot in the cells' vectors (`usize::MAX`: never on the path).
    slot: Vec<usize>,
    /// Slots: the columns that may join the path.
    kmax: usize,
    /// Per cell and pool column: excited in the cell's training set.
    excited: Vec<bool>,
    /// Per cell, [`block`] entries (see [`Parts`]).
    store: Vec<f64>,
    /// Per cell, the factor's columns (`kmax`) and the slots' products (`kmax`).
    cols: Vec<usize>,
    cand: Vec<Cand>,
}

impl<'g> PathScorer<'g> {
    /// The scorer of the path starting at `start` (the forced columns), which may take the
    /// columns of `later`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        grams: &BinGrams,
        trains: &'g FoldGrams,
        folds: &'g FoldGrams,
        fitted: &[bool],
        start: &[usize],
        later: &[usize],
        min_points: usize,
        excitation: &Excitation<'_>,
        fallback: &[(f64, f64, f64)],
    ) -> Self {
        let dim = grams.dim;
        let p = dim - 1;
        let nf = folds.folds();
        let all: Vec<usize> = (0..p).collect();
        let mut slot = vec![usize::MAX; p];
        let mut kmax = 0;
        for &c in start.iter().chain(later) {
            if c < p && slot[c] == usize::MAX {
                slot[c] = kmax;
                kmax += 1;
            }
        }
        let mut cells = Vec::new();
        let mut excited = Vec::new();
        let mut used = Vec::new();
        for c in fold_cells(fitted, folds, trains) {
            excitation.excited(c.train, c.train_sums, c.n_train, dim, &all, &mut used);
            let at = excited.len();
            excited.resize(at + p, false);
            for &j in &used {
                excited[at + j] = true;
            }
            cells.push(Cell {
                fold: c.fold,
                train: c.train,
                n_fold: c.n_fold,
                n_train: c.n_train,
                f: c.f,
                k: 0,
                dead: false,
                fallback: fallback[c.b * nf + c.f],
                base: (0.0, 0.0, 0.0),
                cross: 0.0,
                yy: 0.0,
            });
        }
        let n = cells.len();
        let mut scorer = PathScorer {
            cells,
            dim,
            p,
            nf,
            min_points,
            s2: grams.scale[dim - 1].powi(2),
            path: Vec::new(),
            slot,
            kmax,
            excited,
            store: vec![0.0; n * block(kmax)],
            cols: vec![0; n * kmax],
            cand: vec![Cand::default(); n * kmax],
        };
        for &c in start {
            scorer.add(c);
        }
        if start.is_empty() {
            scorer.refresh_all();
        }
        scorer
    }

    /// Every cell's held-out sums of the path.
    fn refresh_all(&mut self) {
        let (dim, min_points) = (self.dim, self.min_points);
        for cell in &mut self.cells {
            cell.refresh(dim, min_points);
        }
    }

    /// Calls `f` with every cell, its vectors and its excited columns.
    fn each_cell(&mut self, mut f: impl FnMut(&mut Cell<'g>, &mut Parts<'_>, &[bool])) {
        let (p, kmax) = (self.p, self.kmax);
        let blocks = self.store.chunks_mut(block(kmax).max(1));
        let cols = self.cols.chunks_mut(kmax.max(1));
        let cand = self.cand.chunks_mut(kmax.max(1));
        let excited = self.excited.chunks(p.max(1));
        for ((((cell, blk), cl), cd), ex) in self
            .cells
            .iter_mut()
            .zip(blocks)
            .zip(cols)
            .zip(cand)
            .zip(excited)
        {
            f(cell, &mut Parts::of(blk, cl, cd, kmax), ex);
        }
    }

    /// Scores of `path + [c]` for each `c` of `cands` (columns of `later`).
    pub(super) fn scores(&mut self, cands: &[usize]) -> Vec<CvScore> {
        let mut accs = vec![CvAccum::new(self.nf); cands.len()];
        let (dim, min_points, kmax) = (self.dim, self.min_points, self.kmax);
        let slots: Vec<usize> = cands.iter().map(|&c| self.slot[c]).collect();
        self.each_cell(|cell, pt, ex| {
            let enough = cell.n_train >= (min_points * (cell.k + 1).max(1)) as f64;
            for (i, (&c, &sl)) in cands.iter().zip(&slots).enumerate() {
                let sums = if !ex[c] {
                    cell.base
                } else if enough {
                    cell.score(pt, c, sl, kmax, dim)
                } else {
                    cell.fallback
                };
                accs[i].add(cell.f, sums.0, sums.1, sums.2, cell.n_fold);
            }
        });
        cands
            .iter()
            .zip(&accs)
            .map(|(&c, a)| {
                let mut label = self.path.clone();
                label.push(c);
                a.finish(self.s2, &label)
            })
            .collect()
    }

    /// The path takes column `c` (a column of `start` or `later`).
    pub(super) fn add(&mut self, c: usize) {
        self.path.push(c);
        let (dim, min_points, kmax) = (self.dim, self.min_points, self.kmax);
        let slot = self.slot[c];
        self.each_cell(|cell, pt, ex| {
            if ex[c] {
                cell.push(pt, c, slot, kmax, dim);
            }
            cell.refresh(dim, min_points);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::super::{cv_score, fallback_sums, BinStats, CvGrams};
    use super::*;
    use crate::sim::rng::Stream;

    /// Per-maneuver statistics of rows `[x_0..x_{p-1}, z]` (already scaled).
    fn stats(rows_of: &[Vec<Vec<f64>>], dim: usize) -> BinStats {
        let mut st = BinStats::default();
        for (m, rows) in rows_of.iter().enumerate() {
            st.maneuvers.push(m as u64);
            st.n.push(rows.len());
            for a in 0..dim {
                for b in 0..=a {
                    st.packed.push(rows.iter().map(|r| r[a] * r[b]).sum());
                }
            }
            for a in 0..dim {
                st.packed.push(rows.iter().map(|r| r[a]).sum());
            }
        }
        st
    }

    /// A bin whose training maneuvers hold too few rows for `[bias, x]` (6 rows, 4 per
    /// parameter needed) but enough for the bias predicts the training mean, as the bias
    /// alone does, and not zero: the held-out error is `Σ(z_f − mean(z_train))²` per fold
    /// (closed form), for the refit and along the path alike.
    #[test]
    fn a_cell_too_sparse_for_the_structure_predicts_the_bias_fit() {
        let mut rng = Stream::new(7, 1);
        let (p, dim, folds, min_points) = (2usize, 3usize, 2usize, 4usize);
        let rows_of: Vec<Vec<Vec<f64>>> = (0..4)
            .map(|_| {
                (0..3)
                    .map(|_| {
                        let x = rng.normal();
                        vec![1.0, x, 5.0 + 0.3 * x + 0.1 * rng.normal()]
                    })
                    .collect()
            })
            .collect();
        let grams = BinGrams {
            dim,
            scale: vec![1.0; dim],
            bins: vec![stats(&rows_of, dim)],
        };
        let cv = CvGrams::new(&grams, folds, |_, k| Some(k % folds), |_, _| 1.0);
        let fitted = [true];
        let (flap_sd, constant) = (vec![1.0; p], vec![true, false]);
        let excitation = Excitation {
            flap_sd: &flap_sd,
            constant: &constant,
            min: 0.05,
        };
        let fallback = fallback_sums(
            dim,
            &cv.trains,
            &cv.folds,
            &fitted,
            &[0],
            min_points,
            &excitation,
        );
        let score = |cols: &[usize]| {
            cv_score(
                &grams,
                &cv.trains,
                &cv.folds,
                &fitted,
                cols,
                min_points,
                &excitation,
                &fallback,
            )
        };
        // closed form: per fold, the held-out rows against the training rows' mean z
        let mut want = Vec::new();
        for f in 0..folds {
            let z = |keep: bool| -> Vec<f64> {
                (0..4)
                    .filter(|k| (k % folds == f) == keep)
                    .flat_map(|k| rows_of[k].iter().map(|r| r[2]))
                    .collect()
            };
            let (held, train) = (z(true), z(false));
            let mean = train.iter().sum::<f64>() / train.len() as f64;
            want.push(held.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / held.len() as f64);
        }
        let (bias, both) = (score(&[0]), score(&[0, 1]));
        for (got, w) in [&bias, &both]
            .iter()
            .flat_map(|s| s.fold_mse.iter().zip(&want))
        {
            assert!((got - w).abs() <= 1e-12 * w, "{got} vs {w}");
        }
        assert!(both.mse < 1.0, "zero Δ would score about 25: {}", both.mse);
        let mut scorer = PathScorer::new(
            &grams,
            &cv.trains,
            &cv.folds,
            &fitted,
            &[0],
            &[1],
            min_points,
            &excitation,
            &fallback,
        );
        let path = scorer.scores(&[1]).remove(0);
        assert!((path.mse - both.mse).abs() <= 1e-12 * both.mse);
    }

    /// Along a path through every candidate, the carried-product scores equal a refit's
    /// (`cv_score`) in bins with a dependent column (the cell dies), a column that never
    /// moves (not excited), too few rows for the longer fits, and bootstrap-like weights
    /// (0, 1 and 2).
    #[test]
    fn carried_scores_equal_the_refit_along_the_path() {
        let mut rng = Stream::new(11, 3);
        let (p, nm, folds) = (6usize, 12usize, 3usize);
        let dim = p + 1;
        let mut bins = Vec::new();
        for kind in 0..4 {
            let per = if kind == 3 { 3 } else { 25 };
            let rows_of: Vec<Vec<Vec<f64>>> = (0..nm)
                .map(|_| {
                    (0..per)
                        .map(|_| {
                            let mut x: Vec<f64> = (0..p).map(|_| rng.normal()).collect();
                            x[0] = 1.0;
                            if kind == 1 {
                                x[3] = 2.0 * x[1] - x[2];
                            }
                            if kind == 2 {
                                x[2] = 0.0;
                            }
                            let z = 0.3 + 0.5 * x[1] - 0.2 * x[4] + 0.3 * rng.normal();
                            x.push(z);
                            x
                        })
                        .collect()
                })
                .collect();
            bins.push(stats(&rows_of, dim));
        }
        let grams = BinGrams {
            dim,
            scale: vec![1.0; dim],
            bins,
        };
        let weight = |k: usize| [0.0, 1.0, 2.0, 1.0][k % 4];
        let cv = CvGrams::new(&grams, folds, |_, k| Some(k % folds), |_, k| weight(k));
        let fitted = vec![true; grams.bins.len()];
        let flap_sd = vec![1.0; p];
        let constant: Vec<bool> = (0..p).map(|j| j == 0).collect();
        let excitation = Excitation {
            flap_sd: &flap_sd,
            constant: &constant,
            min: 0.05,
        };
        let (start, later) = (vec![0usize], vec![1usize, 2, 3, 4, 5]);
        let min_points = 4;
        let fallback = fallback_sums(
            grams.dim,
            &cv.trains,
            &cv.folds,
            &fitted,
            &start,
            min_points,
            &excitation,
        );
        let mut scorer = PathScorer::new(
            &grams,
            &cv.trains,
            &cv.folds,
            &fitted,
            &start,
            &later,
            min_points,
            &excitation,
            &fallback,
        );
        let mut path = start.clone();
        let mut left = later.clone();
        let close = |a: f64, b: f64| {
            (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-9 * a.abs().max(b.abs())
        };
        let mut dead_seen = false;
        while !left.is_empty() {
            let scores = scorer.scores(&left);
            for (s, &c) in scores.iter().zip(&left) {
                let mut cols = path.clone();
                cols.push(c);
                let r = cv_score(
                    &grams,
                    &cv.trains,
                    &cv.folds,
                    &fitted,
                    &cols,
                    min_points,
                    &excitation,
                    &fallback,
                );
                assert!(
                    close(s.mse, r.mse) && close(s.tic, r.tic),
                    "{cols:?}: {s:?} vs {r:?}"
                );
                assert_eq!(s.columns, r.columns);
                for (a, b) in s.fold_mse.iter().zip(&r.fold_mse) {
                    assert!(close(*a, *b), "{cols:?}: fold {a} vs {b}");
                }
            }
            // take the candidates in pool order, so that 1, 2 and 3 (dependent in bin 1) join
            let c = left.remove(0);
            scorer.add(c);
            path.push(c);
            dead_seen |= scorer.cells.iter().any(|cell| cell.dead);
        }
        assert!(dead_seen, "the dependent column should end a cell's factor");
        // the column that never moves was left out of bin 2's cells
        assert!(scorer
            .cells
            .iter()
            .zip(scorer.excited.chunks(p))
            .any(|(_, ex)| !ex[2]));
    }
}
