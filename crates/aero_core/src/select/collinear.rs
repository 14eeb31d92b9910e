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

use super::median;
use crate::identify::BinnedFit;

/// A term left out of a flap's structure.
#[derive(Debug, Clone, PartialEq)]
pub struct Pruned {
    /// Column of the candidate pool (or given structure).
    pub column: usize,
    /// Why, naming the term it is collinear with.
    pub note: String,
}

/// The column of `fit` to leave out and its note: the last non-constant column with a VIF
/// above `max_vif` in more than half of the fitted bins (`None` when there is none). `constant`: per column of
/// `fit`, whether it is the bias (never left out).
pub fn collinear_to_prune(
    fit: &BinnedFit,
    constant: &[bool],
    max_vif: f64,
) -> Option<(usize, String)> {
    if !max_vif.is_finite() {
        return None;
    }
    let fitted: Vec<_> = fit.bins.iter().filter(|b| b.note.is_empty()).collect();
    let m = fitted.len();
    let p = fit.names.len();
    let mut worst: Option<(usize, f64, usize)> = None; // (column, median |t|, bins over)
                                                       // the last listed term collinear in most bins
    for j in (0..p).rev().filter(|&j| !constant[j]) {
        let over = fitted.iter().filter(|b| b.vif[j] > max_vif).count();
        if m == 0 || 2 * over <= m {
            continue;
        }
        let t = median(
            fitted
                .iter()
                .map(|b| (b.params[j] / b.std_err[j]).abs())
                .filter(|t| t.is_finite())
                .collect(),
        );
        worst = Some((j, if t.is_finite() { t } else { 0.0 }, over));
        break;
    }
    let (j, t, over) = worst?;
    // the term it is most often most correlated with, over the bins where it is collinear
    let mut counts = vec![0usize; p];
    for b in fitted.iter().filter(|b| b.vif[j] > max_vif) {
        if let Some(k) = b.most_correlated[j] {
            counts[k] += 1;
        }
    }
    let partner = (0..p)
        .filter(|&k| counts[k] > 0)
        .max_by(|&a, &b| counts[a].cmp(&counts[b]).then(b.cmp(&a)))
        .map_or_else(
            || "the other terms".to_string(),
            |k| format!("'{}'", fit.names[k]),
        );
    let vif = median(
        fitted
            .iter()
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
