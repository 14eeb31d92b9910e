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
    /// The fold's Gram matrix over the factor's columns, in their order: row `i` holds
    /// `G[S_i, S_0..=S_i]`, then `G[S_i, z]` (contiguous, for [`held_out_packed`]).
    packed: Vec<Vec<f64>>,
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
                    packed: Vec::new(),
                };
                for &c in start {
                    cell.push(c, dim);
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
        let mut th = Vec::new();
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
                                let s = held_out_packed(
                                    &cell.packed,
                                    &cell.fold[c * dim..(c + 1) * dim],
                                    fa.cols(),
                                    c,
                                    cell.fold[dim * dim - 1],
                                    &th,
                                );
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
            cell.push(c, dim);
            cell.refresh(dim, min_points);
        }
    }
}

impl Cell<'_> {
    /// Column `c` joins the path: into the factor when this training set excites it.
    fn push(&mut self, c: usize, dim: usize) {
        if !self.excited[c] {
            return;
        }
        if let Some(fa) = &mut self.factor {
            let mut w = std::mem::take(&mut self.w[c]);
            match fa.probe_cached(c, &mut w) {
                Some((d, u)) => {
                    fa.push(c, Probe { w, d, u });
                    let row = &self.fold[c * dim..(c + 1) * dim];
                    let mut packed: Vec<f64> = fa.cols().iter().map(|&s| row[s]).collect();
                    packed.push(row[dim - 1]);
                    self.packed.push(packed);
                }
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

/// [`held_out`] of the columns `cols` followed by `c`, with the fold's Gram matrix over `cols`
/// given `packed` (rows as [`Cell::packed`]), `row_c` the fold's row of `c` and `zz` its
/// `Σz²`: the same sums in the same order (bit-identical), the `cols` block read contiguously.
fn held_out_packed(
    packed: &[Vec<f64>],
    row_c: &[f64],
    cols: &[usize],
    c: usize,
    zz: f64,
    theta: &[f64],
) -> (f64, f64, f64) {
    let k = cols.len();
    let zc = row_c.len() - 1;
    let mut cross = 0.0;
    let mut yy = 0.0;
    for (i, row) in packed.iter().enumerate() {
        cross += theta[i] * row[i + 1];
        let mut off = 0.0;
        for (t, g) in theta[..i].iter().zip(&row[..i]) {
            off += t * g;
        }
        yy += theta[i] * (2.0 * off + theta[i] * row[i]);
    }
    cross += theta[k] * row_c[zc];
    let mut off = 0.0;
    for (t, &s) in theta[..k].iter().zip(cols) {
        off += t * row_c[s];
    }
    yy += theta[k] * (2.0 * off + theta[k] * row_c[c]);
    ((zz - 2.0 * cross + yy).max(0.0), zz, yy.max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Stream;

    /// The packed held-out sums are `held_out`'s, bit for bit, for columns in any order.
    #[test]
    fn packed_held_out_is_held_out_bit_for_bit() {
        let mut rng = Stream::new(7, 1);
        let (n, dim) = (50, 7);
        let rows: Vec<Vec<f64>> = (0..n)
            .map(|_| (0..dim).map(|_| rng.normal()).collect())
            .collect();
        let mut g = vec![0.0; dim * dim];
        for r in &rows {
            for a in 0..dim {
                for b in 0..dim {
                    g[a * dim + b] += r[a] * r[b];
                }
            }
        }
        for cols in [vec![0usize], vec![3, 0, 5], vec![5, 1, 2, 0, 4]] {
            let (path, c) = cols.split_at(cols.len() - 1);
            let packed: Vec<Vec<f64>> = path
                .iter()
                .enumerate()
                .map(|(i, &s)| {
                    let mut row: Vec<f64> = path[..=i].iter().map(|&t| g[s * dim + t]).collect();
                    row.push(g[s * dim + dim - 1]);
                    row
                })
                .collect();
            let theta: Vec<f64> = (0..cols.len()).map(|_| rng.normal()).collect();
            let a = held_out(&g, dim, &cols, &theta);
            let b = held_out_packed(
                &packed,
                &g[c[0] * dim..(c[0] + 1) * dim],
                path,
                c[0],
                g[dim * dim - 1],
                &theta,
            );
            assert_eq!(a.0.to_bits(), b.0.to_bits(), "{cols:?}");
            assert_eq!(a.1.to_bits(), b.1.to_bits());
            assert_eq!(a.2.to_bits(), b.2.to_bits());
        }
    }
}
