//! Per-bin, per-fold sufficient statistics of the cross-validation: each fold's Gram matrix,
//! the bin's total and each fold's training complement (total minus fold), in flat arrays.
//!
//! A fold's statistics are the weighted sum of its maneuvers' packed statistics
//! ([`super::BinStats::packed`]: lower triangle and column sums, one contiguous run per
//! maneuver), the total the sum of the folds and a training set the total minus its fold;
//! each is summed packed and unpacked once into its full symmetric matrix.

use super::{packed_width, BinGrams};

/// Gram matrices (`dim × dim`, row-major), column sums and sample counts per bin and fold.
#[derive(Clone)]
pub(super) struct FoldGrams {
    dim: usize,
    folds: usize,
    g: Vec<f64>,
    s: Vec<f64>,
    n: Vec<f64>,
}

/// The folds', the totals' (one "fold" per bin) and the training sets' statistics.
pub(super) struct CvGrams {
    pub(super) folds: FoldGrams,
    pub(super) totals: FoldGrams,
    pub(super) trains: FoldGrams,
}

impl FoldGrams {
    fn zeros(dim: usize, bins: usize, folds: usize) -> Self {
        FoldGrams {
            dim,
            folds,
            g: vec![0.0; bins * folds * dim * dim],
            s: vec![0.0; bins * folds * dim],
            n: vec![0.0; bins * folds],
        }
    }

    /// Room for `bins × folds` entries, none yet: [`FoldGrams::push`] appends them in order
    /// (bin by bin, folds in order), each written once.
    fn with_capacity(dim: usize, bins: usize, folds: usize) -> Self {
        FoldGrams {
            dim,
            folds,
            g: Vec::with_capacity(bins * folds * dim * dim),
            s: Vec::with_capacity(bins * folds * dim),
            n: Vec::with_capacity(bins * folds),
        }
    }

    /// Appends the next entry: packed statistics `pk` (lower triangle, then sums) with `n`
    /// samples, the triangle unpacked into its full symmetric matrix.
    fn push(&mut self, pk: &[f64], n: f64) {
        let dim = self.dim;
        let (tri, sums) = pk.split_at(pk.len() - dim);
        for i in 0..dim {
            // row i: the triangle's row i, then column i below the diagonal
            let at = i * (i + 1) / 2;
            self.g.extend_from_slice(&tri[at..=at + i]);
            self.g
                .extend((i + 1..dim).map(|j| tri[j * (j + 1) / 2 + i]));
        }
        self.s.extend_from_slice(sums);
        self.n.push(n);
    }

    /// Folds per bin.
    pub(super) fn folds(&self) -> usize {
        self.folds
    }

    /// Gram matrix, column sums and samples of bin `b`, fold `f`.
    pub(super) fn get(&self, b: usize, f: usize) -> (&[f64], &[f64], f64) {
        let (dim, i) = (self.dim, b * self.folds + f);
        (
            &self.g[i * dim * dim..(i + 1) * dim * dim],
            &self.s[i * dim..(i + 1) * dim],
            self.n[i],
        )
    }
}

/// The sum of `blocks` (folds of `w` entries each, one after the other), added in fold order
/// into `total` (zeroed first), and each fold's training complement `total − fold` into
/// `trains` (laid out as `blocks`).
fn total_and_complements(blocks: &[f64], w: usize, total: &mut [f64], trains: &mut [f64]) {
    total.fill(0.0);
    for blk in blocks.chunks_exact(w) {
        total.iter_mut().zip(blk).for_each(|(a, v)| *a += v);
    }
    for (tr, blk) in trains.chunks_exact_mut(w).zip(blocks.chunks_exact(w)) {
        for ((t, a), v) in tr.iter_mut().zip(&*total).zip(blk) {
            *t = a - v;
        }
    }
}

impl CvGrams {
    /// The statistics of `grams`' bins for `folds` folds: the `k`-th maneuver of bin `b` goes
    /// to fold `fold(b, k)` (none: to no fold) with weight `weight(b, k)` (0: left out).
    /// Sums run over the maneuvers in order, then over the folds in order.
    pub(super) fn new(
        grams: &BinGrams,
        folds: usize,
        fold: impl Fn(usize, usize) -> Option<usize>,
        weight: impl Fn(usize, usize) -> f64,
    ) -> Self {
        let dim = grams.dim;
        let nb = grams.bins.len();
        let wdt = packed_width(dim);
        let mut out = CvGrams {
            folds: FoldGrams::with_capacity(dim, nb, folds),
            totals: FoldGrams::with_capacity(dim, nb, 1),
            trains: FoldGrams::with_capacity(dim, nb, folds),
        };
        let mut acc = vec![0.0; folds * wdt];
        let mut count = vec![0.0; folds];
        let mut total = vec![0.0; wdt];
        let mut train = vec![0.0; folds * wdt];
        let (mut n_total, mut n_train) = ([0.0], vec![0.0; folds]);
        for (b, bs) in grams.bins.iter().enumerate() {
            acc.iter_mut().for_each(|v| *v = 0.0);
            count.iter_mut().for_each(|v| *v = 0.0);
            bs.add_packed(
                dim,
                folds,
                |k| fold(b, k),
                |k| weight(b, k),
                &mut acc,
                &mut count,
            );
            total_and_complements(&acc, wdt, &mut total, &mut train);
            total_and_complements(&count, 1, &mut n_total, &mut n_train);
            out.totals.push(&total, n_total[0]);
            for f in 0..folds {
                let at = f * wdt..(f + 1) * wdt;
                out.folds.push(&acc[at.clone()], count[f]);
                out.trains.push(&train[at], n_train[f]);
            }
        }
        out
    }

    /// These statistics with fold `out`'s maneuvers given weight 0, as [`CvGrams::new`] would
    /// sum them (the nested cross-validation's selection on the other folds): the other
    /// folds' sums are unchanged, fold `out`'s are zero, and the totals and training sets are
    /// summed again in fold order, elementwise as `new` sums the packed entries, so the
    /// result is the same to the bit without a second pass over the maneuvers.
    pub(super) fn without_fold(&self, out: usize) -> Self {
        let (dim, nf) = (self.folds.dim, self.folds.folds);
        let nb = self.totals.n.len();
        let (d2, mut folds) = (dim * dim, self.folds.clone());
        for b in 0..nb {
            let i = b * nf + out;
            folds.g[i * d2..(i + 1) * d2].fill(0.0);
            folds.s[i * dim..(i + 1) * dim].fill(0.0);
            folds.n[i] = 0.0;
        }
        let mut totals = FoldGrams::zeros(dim, nb, 1);
        let mut trains = FoldGrams::zeros(dim, nb, nf);
        for b in 0..nb {
            let (g, sums, n) = (
                b * nf * d2..(b + 1) * nf * d2,
                b * nf * dim..(b + 1) * nf * dim,
                b * nf..(b + 1) * nf,
            );
            total_and_complements(
                &folds.g[g.clone()],
                d2,
                &mut totals.g[b * d2..(b + 1) * d2],
                &mut trains.g[g],
            );
            total_and_complements(
                &folds.s[sums.clone()],
                dim,
                &mut totals.s[b * dim..(b + 1) * dim],
                &mut trains.s[sums],
            );
            total_and_complements(
                &folds.n[n.clone()],
                1,
                &mut totals.n[b..=b],
                &mut trains.n[n],
            );
        }
        CvGrams {
            folds,
            totals,
            trains,
        }
    }
}
