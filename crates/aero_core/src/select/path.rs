//! The greedy forward path of the structure selection, scored by cross-validation with one
//! Cholesky factor per bin and fold extended along the path.
//!
//! At every step of the path each remaining candidate `c` is scored as `path + [c]`: per bin
//! and fold, the training fit on the excited columns of `path + [c]` predicts the fold. The
//! factor of the path's excited columns is kept per bin and fold and grows by one row when the
//! path takes a column; each candidate keeps its forward substitution `w_c = L⁻¹ X_Sᵀ x_c`
//! and extends it by the new row only ([`Factor::probe_cached`]). A candidate then costs
//! `O(k)` for its pivot and `O(k²)` for its estimates and held-out error, where refactoring
//! `path + [c]` cost `O(k³)` per candidate and step. The scores are those of
//! `super::cv_score` to rounding (checked in the test builds).

use super::stepwise::{Factor, Probe};
use super::{held_out, zero_prediction, BinGrams, CvAccum, CvScore, Excitation, FoldGrams};

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
    /// Estimates of the path's excited columns.
    theta: Vec<f64>,
    /// Per pool column, its cached forward substitution against `factor`.
    w: Vec<Vec<f64>>,
    /// The held-out sums of the path itself.
    base: (f64, f64, f64),
}

/// The path's cells and the rules of a training fit.
pub(super) struct PathScorer<'g> {
    cells: Vec<(usize, Cell<'g>)>,
    dim: usize,
    nf: usize,
    min_points: usize,
    s2: f64,
    path: Vec<usize>,
}

impl<'g> PathScorer<'g> {
    /// The scorer of the path starting at `start` (the forced columns).
    pub(super) fn new(
        grams: &BinGrams,
        trains: &'g FoldGrams,
        folds: &'g FoldGrams,
        fitted: &[bool],
        start: &[usize],
        min_points: usize,
        excitation: &Excitation<'_>,
    ) -> Self {
        let dim = grams.dim;
        let p = dim - 1;
        let nf = folds.first().map_or(0, Vec::len);
        let all: Vec<usize> = (0..p).collect();
        let mut cells = Vec::new();
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
                    theta: Vec::new(),
                    w: vec![Vec::new(); p],
                    base: (0.0, 0.0, 0.0),
                };
                for &c in start {
                    cell.push(c);
                }
                cell.refresh(dim, min_points);
                cells.push((f, cell));
            }
        }
        PathScorer {
            cells,
            dim,
            nf,
            min_points,
            s2: grams.scale[dim - 1].powi(2),
            path: start.to_vec(),
        }
    }

    /// Scores of `path + [c]` for each `c` of `cands`.
    pub(super) fn scores(&mut self, cands: &[usize]) -> Vec<CvScore> {
        let mut accs = vec![CvAccum::new(self.nf); cands.len()];
        let (mut th, mut cols) = (Vec::new(), Vec::new());
        let (dim, min_points) = (self.dim, self.min_points);
        for (f, cell) in &mut self.cells {
            let k = cell.factor.as_ref().map_or(0, |fa| fa.cols().len());
            let enough = cell.n_train >= (min_points * (k + 1).max(1)) as f64;
            for (i, &c) in cands.iter().enumerate() {
                let sums = if !cell.excited[c] {
                    cell.base
                } else {
                    match &cell.factor {
                        Some(fa) if enough => match fa.probe_cached(c, &mut cell.w[c]) {
                            Some((d, u)) => {
                                fa.theta_with(&cell.theta, &cell.w[c], d, u, &mut th);
                                cols.clear();
                                cols.extend_from_slice(fa.cols());
                                cols.push(c);
                                let s = held_out(cell.fold, dim, &cols, &th);
                                if th.iter().all(|v| v.is_finite()) {
                                    s
                                } else {
                                    zero_prediction(cell.fold, dim)
                                }
                            }
                            None => zero_prediction(cell.fold, dim),
                        },
                        _ => zero_prediction(cell.fold, dim),
                    }
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

    /// The path takes column `c`.
    pub(super) fn add(&mut self, c: usize) {
        self.path.push(c);
        let (dim, min_points) = (self.dim, self.min_points);
        for (_, cell) in &mut self.cells {
            cell.push(c);
            cell.refresh(dim, min_points);
        }
    }
}

impl Cell<'_> {
    /// Column `c` joins the path: into the factor when this training set excites it.
    fn push(&mut self, c: usize) {
        if !self.excited[c] {
            return;
        }
        if let Some(fa) = &mut self.factor {
            let mut w = std::mem::take(&mut self.w[c]);
            match fa.probe_cached(c, &mut w) {
                Some((d, u)) => fa.push(c, Probe { w, d, u }),
                None => self.factor = None,
            }
        }
    }

    /// Estimates and held-out sums of the path itself.
    fn refresh(&mut self, dim: usize, min_points: usize) {
        self.base = match &self.factor {
            Some(fa) if self.n_train >= (min_points * fa.cols().len().max(1)) as f64 => {
                self.theta = fa.theta();
                if self.theta.iter().all(|v| v.is_finite()) {
                    held_out(self.fold, dim, fa.cols(), &self.theta)
                } else {
                    zero_prediction(self.fold, dim)
                }
            }
            Some(fa) => {
                self.theta = fa.theta();
                zero_prediction(self.fold, dim)
            }
            None => zero_prediction(self.fold, dim),
        };
    }
}
