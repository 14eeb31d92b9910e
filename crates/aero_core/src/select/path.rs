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

use super::stepwise::{Factor, Probe, PIVOT_TOL};
use super::{zero_prediction, BinGrams, CvAccum, CvScore, Excitation, FoldGrams};

/// What one candidate carries along the path in one bin and fold: the length of its `w` and
/// `r` (kept in [`Cell::vecs`]) and their sums.
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

/// The path's quantities of one bin and fold a candidate is extended against.
struct Along<'a> {
    factor: &'a Factor<'a>,
    fold: &'a [f64],
    dim: usize,
    qa: &'a [f64],
    /// `M`, lower triangle packed by rows (row `i` at `i(i+1)/2`, `i + 1` entries).
    m: &'a [f64],
    /// Per row `i` of `M`, `M[i, ..i]·y[..i]`.
    mdy: &'a [f64],
}

impl Cand {
    /// Extends the carried sums of column `c` by the factor's rows added since the last call;
    /// `w` and `r` are the candidate's vectors (room for every row of the path).
    fn extend(&mut self, c: usize, at: &Along<'_>, w: &mut [f64], r: &mut [f64]) {
        let (fa, dim) = (at.factor, at.dim);
        let g = fa.gram();
        let y = fa.y();
        let cols = fa.cols();
        for i in self.len.min(cols.len())..cols.len() {
            let row = fa.row(i);
            let s = cols[i];
            let (mut sw, mut sr) = (g[s * dim + c], at.fold[s * dim + c]);
            for ((l, a), b) in row[..i].iter().zip(&w[..i]).zip(&r[..i]) {
                sw -= l * a;
                sr -= l * b;
            }
            let (om, rr) = (sw / row[i], sr / row[i]);
            let mrow = &at.m[i * (i + 1) / 2..(i + 1) * (i + 2) / 2];
            let mw: f64 = mrow[..i].iter().zip(&w[..i]).map(|(a, b)| a * b).sum();
            self.wmw += 2.0 * om * mw + om * om * mrow[i];
            self.wmy += om * at.mdy[i] + mw * y[i] + om * mrow[i] * y[i];
            self.ww += om * om;
            self.wy += om * y[i];
            self.wqa += om * at.qa[i];
            self.wr += om * rr;
            self.yr += y[i] * rr;
            w[i] = om;
            r[i] = rr;
        }
        self.len = self.len.max(cols.len());
    }

    /// Pivot `d` and new entry `u` of `y` for the column `c` (the rule of
    /// `Factor::probe_cached`); `None` when `c` is (numerically) dependent on the path.
    fn pivot(&self, g: &[f64], dim: usize, c: usize) -> Option<(f64, f64)> {
        let gcc = g[c * dim + c];
        let d = gcc - self.ww;
        if d.is_nan() || gcc <= 0.0 || d <= PIVOT_TOL * gcc {
            return None;
        }
        let u = (g[c * dim + dim - 1] - self.wy) / d.sqrt();
        u.is_finite().then_some((d, u))
    }
}

/// One bin and fold of the path.
struct Cell<'g> {
    /// Held-out Gram matrix and samples.
    fold: &'g [f64],
    n_fold: f64,
    n_train: f64,
    /// Per pool column: excited in this training set.
    excited: Vec<bool>,
    /// Factor of the path's excited columns; `None` once one of them was dependent on the
    /// earlier ones (every extension is then singular too, and the bin predicts zero).
    factor: Option<Factor<'g>>,
    /// Per slot (a column that may join the path, [`PathScorer::slot`]), its carried sums.
    cand: Vec<Cand>,
    /// Per slot, its `w` then its `r`, `kmax` entries each.
    vecs: Vec<f64>,
    /// The held-out sums of the path itself.
    base: (f64, f64, f64),
    /// The path's `θᵀa = yᵀq_a` and `θᵀFθ = yᵀMy`, unclamped.
    cross: f64,
    yy: f64,
    /// `q_a = L⁻¹ a` and, per row `i` of `M`, `M[i, ..i]·y[..i]`.
    qa: Vec<f64>,
    mdy: Vec<f64>,
    /// `M = L⁻¹ F L⁻ᵀ`, lower triangle packed by rows.
    m: Vec<f64>,
}

/// The path's cells and the rules of a training fit.
pub(super) struct PathScorer<'g> {
    cells: Vec<(usize, Cell<'g>)>,
    dim: usize,
    nf: usize,
    min_points: usize,
    s2: f64,
    path: Vec<usize>,
    /// Per pool column, its slot in the cells' carried sums (`usize::MAX`: never on the path).
    slot: Vec<usize>,
    /// Slots: the columns that may join the path.
    kmax: usize,
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
    ) -> Self {
        let dim = grams.dim;
        let p = dim - 1;
        let nf = folds.first().map_or(0, Vec::len);
        let all: Vec<usize> = (0..p).collect();
        let mut slot = vec![usize::MAX; p];
        let mut kmax = 0;
        for &c in start.iter().chain(later) {
            if c < p && slot[c] == usize::MAX {
                slot[c] = kmax;
                kmax += 1;
            }
        }
        let mut scorer = PathScorer {
            cells: Vec::new(),
            dim,
            nf,
            min_points,
            s2: grams.scale[dim - 1].powi(2),
            path: start.to_vec(),
            slot,
            kmax,
        };
        let mut used = Vec::new();
        for (b, fg) in folds.iter().enumerate() {
            if !fitted[b] {
                continue;
            }
            for (f, (gf, _, nfold)) in fg.iter().enumerate() {
                if *nfold == 0.0 {
                    continue;
                }
                let (train, strain, ntrain) = &trains[b][f];
                excitation.excited(train, strain, *ntrain, dim, &all, &mut used);
                let mut excited = vec![false; p];
                for &j in &used {
                    excited[j] = true;
                }
                let mut cell = Cell {
                    fold: gf,
                    n_fold: *nfold,
                    n_train: *ntrain,
                    excited,
                    factor: Some(Factor::new(train, dim)),
                    cand: vec![Cand::default(); kmax],
                    vecs: vec![0.0; 2 * kmax * kmax],
                    base: (0.0, 0.0, 0.0),
                    cross: 0.0,
                    yy: 0.0,
                    qa: Vec::with_capacity(kmax),
                    mdy: Vec::with_capacity(kmax),
                    m: Vec::with_capacity(kmax * (kmax + 1) / 2),
                };
                for &c in start {
                    cell.push(c, scorer.slot[c], kmax, dim);
                }
                cell.refresh(dim, min_points);
                scorer.cells.push((f, cell));
            }
        }
        scorer
    }

    /// Scores of `path + [c]` for each `c` of `cands` (columns of `later`).
    pub(super) fn scores(&mut self, cands: &[usize]) -> Vec<CvScore> {
        let mut accs = vec![CvAccum::new(self.nf); cands.len()];
        let (dim, min_points, kmax) = (self.dim, self.min_points, self.kmax);
        for (f, cell) in &mut self.cells {
            let k = cell.factor.as_ref().map_or(0, |fa| fa.cols().len());
            let enough = cell.n_train >= (min_points * (k + 1).max(1)) as f64;
            for (i, &c) in cands.iter().enumerate() {
                let sums = if !cell.excited[c] {
                    cell.base
                } else if enough {
                    cell.score(c, self.slot[c], kmax, dim)
                } else {
                    zero_prediction(cell.fold, dim)
                };
                accs[i].add(*f, sums.0, sums.1, sums.2, cell.n_fold);
            }
        }
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

    /// The path takes column `c` (a column of `later`).
    pub(super) fn add(&mut self, c: usize) {
        self.path.push(c);
        let (dim, min_points, kmax) = (self.dim, self.min_points, self.kmax);
        let slot = self.slot[c];
        for (_, cell) in &mut self.cells {
            cell.push(c, slot, kmax, dim);
            cell.refresh(dim, min_points);
        }
    }
}

impl Cell<'_> {
    /// The carried sums of column `c` in `slot`, extended to the factor's current rows, and
    /// its `w` and `r`; `None` without a factor.
    fn extend(&mut self, c: usize, slot: usize, kmax: usize, dim: usize) -> Option<()> {
        let fa = self.factor.as_ref()?;
        let at = Along {
            factor: fa,
            fold: self.fold,
            dim,
            qa: &self.qa,
            m: &self.m,
            mdy: &self.mdy,
        };
        let (w, r) = self.vecs[2 * slot * kmax..2 * (slot + 1) * kmax].split_at_mut(kmax);
        self.cand[slot].extend(c, &at, w, r);
        Some(())
    }

    /// Held-out sums `(Σ(z−ẑ)², Σz², Σẑ²)` of the training fit of the path's columns and `c`
    /// (see the module doc); the fold predicts zero when `c` depends on the path or an
    /// estimate is not finite.
    fn score(&mut self, c: usize, slot: usize, kmax: usize, dim: usize) -> (f64, f64, f64) {
        let fold = self.fold;
        if self.extend(c, slot, kmax, dim).is_none() {
            return zero_prediction(fold, dim);
        }
        let Some(fa) = self.factor.as_ref() else {
            return zero_prediction(fold, dim);
        };
        let cd = self.cand[slot];
        let Some((d, u)) = cd.pivot(fa.gram(), dim, c) else {
            return zero_prediction(fold, dim);
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
            zero_prediction(fold, dim)
        }
    }

    /// Column `c` (in `slot`) joins the path: into the factor when this training set excites
    /// it, with the new row of `M` and entry of `q_a`.
    fn push(&mut self, c: usize, slot: usize, kmax: usize, dim: usize) {
        if !self.excited[c] || self.extend(c, slot, kmax, dim).is_none() {
            return;
        }
        let Some(fa) = self.factor.as_ref() else {
            return;
        };
        let cd = self.cand[slot];
        let Some((d, u)) = cd.pivot(fa.gram(), dim, c) else {
            self.factor = None;
            return;
        };
        let fold = self.fold;
        let lam = d.sqrt();
        let k = fa.cols().len();
        let base = 2 * slot * kmax;
        let (w, r) = (
            &self.vecs[base..base + k],
            &self.vecs[base + kmax..base + kmax + k],
        );
        // new row of M: (r_c − M w_c) / λ, and its diagonal (wᵀMw − 2wᵀr + γ) / d
        let mut mw = vec![0.0; k];
        for i in 0..k {
            let row = &self.m[i * (i + 1) / 2..(i + 1) * (i + 2) / 2];
            for j in 0..i {
                mw[i] += row[j] * w[j];
                mw[j] += row[j] * w[i];
            }
            mw[i] += row[i] * w[i];
        }
        let mu = (cd.wmw - 2.0 * cd.wr + fold[c * dim + c]) / d;
        let y = fa.y();
        let mut dy = 0.0;
        for ((a, b), yj) in r.iter().zip(&mw).zip(y) {
            let mk = (a - b) / lam;
            self.m.push(mk);
            dy += mk * yj;
        }
        self.m.push(mu);
        self.mdy.push(dy);
        let qa = (fold[c * dim + dim - 1] - cd.wqa) / lam;
        self.qa.push(qa);
        // the path's own sums with y's new entry u: yᵀq_a and yᵀMy
        self.cross += u * qa;
        self.yy += 2.0 * u * dy + mu * u * u;
        let probe = Probe {
            w: w.to_vec(),
            d,
            u,
        };
        if let Some(fa) = &mut self.factor {
            fa.push(c, probe);
        }
    }

    /// Held-out sums of the path itself.
    fn refresh(&mut self, dim: usize, min_points: usize) {
        let fold = self.fold;
        let k = match &self.factor {
            Some(fa) => fa.cols().len(),
            None => {
                self.base = zero_prediction(fold, dim);
                return;
            }
        };
        let zz = fold[dim * dim - 1];
        let sse = zz - 2.0 * self.cross + self.yy;
        self.base = if self.n_train >= (min_points * k.max(1)) as f64
            && sse.is_finite()
            && self.yy.is_finite()
        {
            (sse.max(0.0), zz, self.yy.max(0.0))
        } else {
            zero_prediction(fold, dim)
        };
    }
}
