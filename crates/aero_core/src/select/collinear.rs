//! Terms a flap's data cannot tell apart: leave the weakest of a collinear group out of
//! the structure, for every bin of the flap at once.
//!
//! A regressor whose variance inflation factor exceeds `max_vif` (Klein & Morelli 2006,
//! Section 5.4.1: 10) in a bin is not identified there ([`crate::identify`]). When that
//! happens in most bins of a flap, as for a roll spoiler geared to the aileron or β̇ beside
//! p̂ and r̂ at high alpha, marking the group not identified would drop its effect from the
//! model; estimating both would split one effect between two terms with inflated, mutually
//! cancelling estimates. The remedy of Klein & Morelli (Section 5.4.1: fix one of the
//! collinear parameters) is applied with the fixed value zero: of the terms collinear in most
//! bins, the one listed last in the structure leaves it, with a note naming the term it cannot
//! be told from, and the structure is fitted again. The structure's order is its priority:
//! the thesis structures and the candidate pool list the primary derivatives (β, p̂, r̂, δa,
//! δr) before the secondary ones (thrust, spoiler, β̇, products), so a roll spoiler geared to
//! the aileron leaves and the aileron term carries both. The weaker `|t|` is no guide here:
//! collinearity inflates both standard errors alike. The kept terms
//! then carry the group's effect along the direction the data excite, which is what a
//! simulator flying the same kind of maneuvers needs; their values are not the separate
//! derivatives, and the note says so.

use super::stepwise::Factor;
use super::{median, BinGrams};
use crate::identify::estimate_correlations;
use crate::identify::{BinPlan, BinnedFit};

/// A term left out of a flap's structure.
#[derive(Debug, Clone, PartialEq)]
pub struct Pruned {
    /// Column of the candidate pool (or given structure).
    pub column: usize,
    /// Why, naming the term it is collinear with.
    pub note: String,
}

/// What the collinearity rule reads of one fitted bin, per column of the structure.
#[derive(Debug, Clone)]
pub struct BinCollinearity {
    /// Variance inflation factor (NaN for a column dependent on the earlier ones: the
    /// near-dependency and excitation rules speak for it).
    pub vif: Vec<f64>,
    /// The other non-constant column whose estimate correlates most with this one's.
    pub partner: Vec<Option<usize>>,
    /// `|t|` of the estimate (conventional standard error).
    pub t: Vec<f64>,
}

/// Each fitted bin's (note empty) augmented Gram matrix summed over its maneuvers, and its
/// sample count: the input of [`gram_collinearity`], computed once per structure.
pub fn fitted_totals(grams: &BinGrams, fit: &BinnedFit) -> Vec<(Vec<f64>, f64)> {
    grams
        .bins
        .iter()
        .zip(&fit.bins)
        .filter(|(_, b)| b.note.is_empty())
        .map(|(bs, _)| {
            let (g, _, n) = bs.total(grams.dim, None);
            (g, n)
        })
        .collect()
}

/// [`fitted_totals`] before any fit: the bins of `plan` with enough data
/// ([`BinPlan::enough_data`]) and more finite rows than columns, the bins the fit of the
/// same design fits (its least squares fails only on fewer usable rows, or an SVD that
/// does not converge).
pub fn planned_totals(grams: &BinGrams, plan: &BinPlan) -> Vec<(Vec<f64>, f64)> {
    let p = grams.dim - 1;
    grams
        .bins
        .iter()
        .enumerate()
        .filter(|(b, _)| plan.enough_data(*b))
        .map(|(_, bs)| bs.total(grams.dim, None))
        .filter(|(_, _, n)| *n > p as f64)
        .map(|(g, _, n)| (g, n))
        .collect()
}

/// [`BinCollinearity`] of every bin of `totals` (each fitted bin's augmented Gram matrix,
/// `dim × dim`, and its sample count: [`BinStats::total`](super::BinStats::total)) for the
/// columns `cols` (constant columns, `constant[c]`, partialled out of the VIFs), from one
/// Cholesky factor per bin: the rule is applied column after column without refitting the
/// bins' QR. The vectors are indexed by position in `cols`, and so are the partners.
pub fn gram_collinearity(
    totals: &[(Vec<f64>, f64)],
    dim: usize,
    cols: &[usize],
    constant: &[bool],
) -> Vec<BinCollinearity> {
    // constant columns first (they are partialled out), then the others in order
    let order: Vec<usize> = (0..cols.len())
        .filter(|&i| constant[cols[i]])
        .chain((0..cols.len()).filter(|&i| !constant[cols[i]]))
        .collect();
    let nf = order.iter().filter(|&&i| constant[cols[i]]).count();
    totals
        .iter()
        .map(|(g, n)| {
            let n = *n;
            let want: Vec<usize> = order.iter().map(|&i| cols[i]).collect();
            // a column dependent on earlier ones (all zero: a control never moved) is skipped
            // by the factor: its VIF is left NaN, as the QR fit leaves it to the near-dependency
            // and excitation rules, and the others are judged among themselves
            let fac = Factor::of(g, dim, &want);
            let k = cols.len();
            let mut out = BinCollinearity {
                vif: vec![f64::NAN; k],
                partner: vec![None; k],
                t: vec![f64::NAN; k],
            };
            let inside: Vec<usize> = order
                .iter()
                .copied()
                .filter(|&i| fac.cols().contains(&cols[i]))
                .collect();
            let kin = inside.len();
            let nf_in = inside
                .iter()
                .filter(|&&i| constant[cols[i]])
                .count()
                .min(nf);
            let vifs = fac.vifs(nf_in);
            let inv = fac.inverse();
            let theta = fac.theta();
            let s2 = fac.sse() / (n - kin as f64).max(1.0);
            let const_in: Vec<bool> = inside.iter().map(|&i| constant[cols[i]]).collect();
            for (pos, &i) in inside.iter().enumerate() {
                out.vif[i] = if pos < nf_in { 1.0 } else { vifs[pos - nf_in] };
                out.t[i] = (theta[pos] / (s2 * inv[pos * kin + pos]).sqrt()).abs();
                out.partner[i] = estimate_correlations(&inv, &const_in, pos)
                    .first()
                    .map(|&(q, _)| inside[q]);
            }
            out
        })
        .collect()
}

/// The column to leave out and its note: the last non-constant column with a VIF above
/// `max_vif` in more than half of the fitted `bins` (`None` when there is none). Columns are
/// those of `names`; `constant[j]`: the bias (never left out).
pub fn collinear_to_prune(
    bins: &[BinCollinearity],
    names: &[String],
    constant: &[bool],
    max_vif: f64,
) -> Option<(usize, String)> {
    if !max_vif.is_finite() {
        return None;
    }
    let m = bins.len();
    let p = names.len();
    // the last listed term collinear in most bins
    let (j, over) = (0..p).rev().filter(|&j| !constant[j]).find_map(|j| {
        let over = bins.iter().filter(|b| b.vif[j] > max_vif).count();
        (m > 0 && 2 * over > m).then_some((j, over))
    })?;
    let t = median(
        bins.iter()
            .map(|b| b.t[j])
            .filter(|t| t.is_finite())
            .collect(),
    );
    let t = if t.is_finite() { t } else { 0.0 };
    // the term it is most often most correlated with, over the bins where it is collinear
    let mut counts = vec![0usize; p];
    for b in bins.iter().filter(|b| b.vif[j] > max_vif) {
        if let Some(k) = b.partner[j] {
            counts[k] += 1;
        }
    }
    let partner = (0..p)
        .filter(|&k| counts[k] > 0)
        .max_by(|&a, &b| counts[a].cmp(&counts[b]).then(b.cmp(&a)))
        .map_or_else(
            || "the other terms".to_string(),
            |k| format!("'{}'", names[k]),
        );
    let vif = median(
        bins.iter()
            .map(|b| b.vif[j])
            .filter(|v| v.is_finite())
            .collect(),
    );
    Some((
        j,
        format!(
            "left out: collinear with {partner} in {over} of {m} fitted bins (median VIF \
             {vif:.0} > {max_vif}, median |t| {t:.1}); these data cannot tell their effects \
             apart, the kept terms carry them"
        ),
    ))
}
