//! Bootstrap over maneuvers of the smoothed Δ parameters (Efron & Tibshirani
//! 1993, Ch. 6 and 13: percentile intervals; resampling whole maneuvers, the
//! "block" that keeps the correlation of neighbouring samples, Künsch 1989).
//!
//! Each replicate draws the flap's maneuvers with replacement (seeded
//! ChaCha8), refits every bin of the final structure from the per-(bin,
//! maneuver) Gram matrices of [`crate::select::bin_grams`] weighted by the
//! draw counts, and smooths the refitted bins exactly as the estimate was
//! smoothed (thesis Eq. 3.13, the same bins, spline and grid). The
//! `(1-level)/2` and `(1+level)/2` percentiles of the replicates at each grid
//! alpha are the confidence band of the smoothed parameter, widened on its side
//! by the spline's own bias ([`spline_bias`]: every replicate's spline cuts a
//! peak as the estimate's does, so the percentiles alone cannot hold the truth
//! there).
//!
//! A bin enters a replicate's smoothing for a parameter when it entered the
//! estimate's smoothing (identified there, or not identified only for
//! collinearity) and the resampled bin still holds enough points and maneuvers
//! and is not singular.
//!
//! Two floors on the bands, because the percentiles alone held the truth less often than
//! their level on independent aircraft (JSBSim F-15 and DHC-6, `docs/identification.md`,
//! session 25; development seeds 1-5, reported on fresh seeds):
//! - a bin's band contains the bin's cluster-robust interval, `θ̂ ± t((1+level)/2, ν) se`
//!   with the CR2 standard error and its Bell-McCaffrey degrees of freedom
//!   ([`crate::lsq::cluster`]): a percentile bootstrap over G maneuvers carries the
//!   small-cluster bias that CR2 with t(ν) corrects (Cameron & Miller 2015, Section VI);
//! - the smoothed band contains, at each grid alpha, the bands of the bins the parameter was
//!   smoothed from, interpolated linearly between their centres (held beyond the first and
//!   the last): smoothing (Eq. 3.13) narrows the replicates' spread, but where the spline
//!   cuts the truth's variation over alpha its bias is not narrowed with it, and the
//!   pilot's bias estimate ([`spline_bias`]) did not cover it. The table's band therefore
//!   never claims more precision than the bins it smooths.
//!
//! With a [`Reselect`], each replicate also runs the structure selection
//! again on its resampled maneuvers ([`crate::select::select_weighted`], from
//! the same Gram matrices): a parameter of the final structure that the
//! replicate's selection does not keep is zero in that replicate (its term
//! is absent), and the kept ones are refitted without it. The bands then carry
//! the selection's own uncertainty, which a band computed for a structure
//! chosen on the same data lacks (post-selection inference; Efron 2014,
//! "Estimation and accuracy after model selection", bootstraps the whole
//! procedure the same way). Terms the replicate would add are not refitted.

// Index loops over the p columns read closer to the formulas.
#![allow(clippy::needless_range_loop)]

use crate::error::{AeroError, Result};
use crate::identify::{
    smooth_bins, smooth_parameters, BinnedFit, Design, SmoothOptions, SmoothedParameter,
};
use crate::lsq::stats::student_t_ppf;
use crate::select::{
    bin_grams, bin_members, independent_subset, select_chosen, solve_subset, BinGrams,
    SelectOptions,
};
use crate::sim::rng::{derive_seed, Stream};

/// One replicate: smoothed values per parameter on the grid, the bin
/// estimates per bin and parameter (NaN where not refitted), and which
/// parameters its selection kept.
type Replicate = (Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<bool>);

/// Settings of [`bootstrap_smoothed`].
#[derive(Debug, Clone)]
pub struct BootstrapOptions {
    /// Number of replicates.
    pub replicates: usize,
    /// Seed (the same seed gives the same bands, whatever the thread count).
    pub seed: u64,
    /// Confidence level of the band, e.g. 0.95.
    pub level: f64,
    /// Points per parameter a resampled bin needs.
    pub min_points_per_param: usize,
    /// Distinct maneuvers a resampled bin needs.
    pub min_maneuvers: usize,
    /// Run the structure selection again in each replicate (see the module
    /// doc); used by [`crate::select::identify_flap`] when it selected.
    pub reselect: bool,
}

/// The structure selection a replicate runs again ([`bootstrap_smoothed`]).
#[derive(Debug, Clone, Copy)]
pub struct Reselect<'a> {
    /// The candidate pool (same rows and `z` as the final design).
    pub pool: &'a Design,
    /// The pool's per-bin fit the selection worked on.
    pub pool_fit: &'a BinnedFit,
    /// Its per-(bin, maneuver) Gram matrices.
    pub grams: &'a BinGrams,
    /// The selection's settings.
    pub select: &'a SelectOptions,
    /// The estimate's coloured-residual inflation per pool bin ([`crate::select::Selection::kappa`]).
    pub kappa: &'a [f64],
    /// Pool column of each parameter of the final structure.
    pub chosen: &'a [usize],
}

impl Default for BootstrapOptions {
    fn default() -> Self {
        BootstrapOptions {
            replicates: 200,
            seed: 0,
            level: 0.95,
            min_points_per_param: 10,
            min_maneuvers: 2,
            reselect: false,
        }
    }
}

/// Bootstrap result for the parameters of one coefficient and flap.
#[derive(Debug, Clone)]
pub struct Bootstrap {
    /// Parameter names.
    pub names: Vec<String>,
    /// Table grid, deg.
    pub alpha_deg: Vec<f64>,
    /// Per parameter, per replicate, the smoothed values on the grid.
    pub replicates: Vec<Vec<Vec<f64>>>,
    /// Per parameter, lower band on the grid: the replicates' percentile, reaching the
    /// estimate, widened by the spline's bias on its side ([`spline_bias`]), and containing
    /// the interpolated bands of the smoothed bins (module doc).
    pub lower: Vec<Vec<f64>>,
    /// Per parameter, upper band on the grid.
    pub upper: Vec<Vec<f64>>,
    /// Per bin, per parameter: bootstrap standard deviation of the bin estimate (NaN if unavailable).
    pub bin_std: Vec<Vec<f64>>,
    /// Per bin, per parameter: lower band of the bin estimate, the replicates' percentile
    /// reaching the estimate and containing its CR2 t interval (module doc; NaN if
    /// unavailable).
    pub bin_lower: Vec<Vec<f64>>,
    /// Per bin, per parameter: upper band of the bin estimate.
    pub bin_upper: Vec<Vec<f64>>,
    /// Per bin, per parameter: replicates in which the bin estimate could be
    /// refitted (the others failed: too few points or maneuvers drawn, a
    /// singular resampled bin). Under half of the replicates gives no band.
    pub bin_replicates_ok: Vec<Vec<usize>>,
    /// Per parameter: replicates whose smoothing of it succeeded (the others refitted too few
    /// bins: too few distinct maneuvers drawn; their values are NaN in `replicates`). Under
    /// half of the replicates gives no smoothed band (`lower`, `upper` NaN).
    pub replicates_ok: Vec<usize>,
    /// Per parameter: share of replicates whose own selection kept the term
    /// (1 without reselection).
    pub inclusion: Vec<f64>,
    /// Confidence level.
    pub level: f64,
}

/// Smoothing parameter of the pilot spline of [`spline_bias`] (alpha in deg): close to
/// interpolation, it follows a peak of the bin estimates that the table's spline cuts.
pub const SPLINE_BIAS_PILOT_P: f64 = 0.99;

/// The smoothing spline's bias on its grid, estimated by an undersmoothed pilot (Ruppert,
/// Wand & Carroll 2003, Section 6.4: the bias of a linear smoother is `(S − I)θ`, estimated
/// with a less biased pilot in place of θ): `s_pilot − s`, with the pilot spline through the
/// same bins at `SPLINE_BIAS_PILOT_P`, 0 where the parameter was set to zero. Eq. 3.13 trades
/// fidelity for smoothness: at a peak or a corner of the true parameter the table's spline
/// sits inside the bin estimates, and every bootstrap replicate's spline sits there too, so a
/// percentile band of the replicates misses the truth by that bias however many replicates
/// are drawn. The bands are widened on the bias's side by it (the union of the band and the
/// band shifted by the bias). The pilot carries more of the bins' noise, so this can only
/// make a band wider.
///
/// # Errors
/// Those of the pilot's smoothing.
pub fn spline_bias(
    fit: &BinnedFit,
    base: &[SmoothedParameter],
    smooth: &SmoothOptions,
) -> Result<Vec<Vec<f64>>> {
    let pilot = smooth_parameters(
        fit,
        &SmoothOptions {
            p: SPLINE_BIAS_PILOT_P.max(smooth.p),
            ..smooth.clone()
        },
    )?;
    Ok(base
        .iter()
        .zip(&pilot)
        .map(|(b, q)| {
            if !b.note.is_empty() || !q.note.is_empty() || b.values.len() != q.values.len() {
                vec![0.0; b.values.len()]
            } else {
                q.values.iter().zip(&b.values).map(|(x, y)| x - y).collect()
            }
        })
        .collect())
}

/// The band `(lower, upper)` at `alpha` of bands given at sorted centres `(alpha, lower,
/// upper)`: linear between the two centres around it, the first or the last held beyond
/// them; `None` without a centre.
fn interpolate_band(nodes: &[(f64, f64, f64)], alpha: f64) -> Option<(f64, f64)> {
    let (first, last) = (nodes.first()?, nodes.last()?);
    if alpha <= first.0 {
        return Some((first.1, first.2));
    }
    if alpha >= last.0 {
        return Some((last.1, last.2));
    }
    let k = nodes.partition_point(|n| n.0 <= alpha);
    let (a, b) = (nodes[k - 1], nodes[k]);
    let w = if b.0 > a.0 {
        (alpha - a.0) / (b.0 - a.0)
    } else {
        0.0
    };
    Some((a.1 + w * (b.1 - a.1), a.2 + w * (b.2 - a.2)))
}

/// Linear-interpolated quantile of sorted values (numpy's default).
fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let h = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(sorted.len() - 1);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// Bootstrap the smoothed parameters of `fit` (the per-bin fit of `design`
/// on `z`), with the selection run again in each replicate when `reselect`
/// is given; see the module doc.
///
/// # Errors
/// [`AeroError::InvalidInput`] for fewer than 2 replicates, a level outside
/// (0, 1), lengths that differ or a `reselect` that does not match `design`;
/// smoothing and selection errors.
pub fn bootstrap_smoothed(
    design: &Design,
    z: &[f64],
    maneuver: &[u64],
    fit: &BinnedFit,
    smooth: &SmoothOptions,
    opts: &BootstrapOptions,
    reselect: Option<&Reselect<'_>>,
) -> Result<Bootstrap> {
    if opts.replicates < 2 {
        return Err(AeroError::invalid(
            "bootstrap, replicates",
            format!("is {}; give at least 2 (e.g. 200)", opts.replicates),
        ));
    }
    if !(opts.level > 0.0 && opts.level < 1.0) {
        return Err(AeroError::invalid(
            "bootstrap, level",
            format!(
                "is {}; give a confidence level in (0, 1), e.g. 0.95",
                opts.level
            ),
        ));
    }
    if z.len() != design.nrows || maneuver.len() != design.nrows {
        return Err(AeroError::invalid(
            "bootstrap",
            format!(
                "z has {} rows and maneuver {}, the regressors {}",
                z.len(),
                maneuver.len(),
                design.nrows
            ),
        ));
    }
    let p = design.ncols();
    if let Some(rs) = reselect {
        if rs.chosen.len() != p || rs.chosen.iter().any(|&c| c >= rs.pool.ncols()) {
            return Err(AeroError::invalid(
                "bootstrap, reselection",
                format!(
                    "maps {} parameters into a pool of {}; the final structure has {p}",
                    rs.chosen.len(),
                    rs.pool.ncols()
                ),
            ));
        }
    }
    let members = bin_members(fit);
    let grams = bin_grams(design, z, &members, maneuver);
    let dim = grams.dim;
    let mut ids: Vec<u64> = maneuver.to_vec();
    ids.sort_unstable();
    ids.dedup();
    let m = ids.len();
    let required = (opts.min_points_per_param * p) as f64;
    let base = smooth_parameters(fit, smooth)?;

    let one = |rep: usize| -> Result<Replicate> {
        let mut rng = Stream::new(derive_seed(opts.seed, rep as u64), 0xb007);
        let mut count = vec![0.0f64; m];
        for _ in 0..m {
            count[(rng.next_u64() % m as u64) as usize] += 1.0;
        }
        // the parameters the replicate keeps: all, or those its own selection keeps
        let keep: Vec<bool> = match reselect {
            None => vec![true; p],
            Some(rs) => {
                let w: std::collections::HashMap<u64, f64> = ids
                    .iter()
                    .zip(&count)
                    .filter(|(_, c)| **c > 0.0)
                    .map(|(id, c)| (*id, *c))
                    .collect();
                // the replicate's selection only (no reporting scores, no nested score)
                let chosen = select_chosen(
                    rs.pool,
                    z,
                    maneuver,
                    rs.pool_fit,
                    rs.grams,
                    rs.select,
                    Some(&w),
                    Some(rs.kappa),
                )?;
                rs.chosen.iter().map(|c| chosen.contains(c)).collect()
            }
        };
        let cols: Vec<usize> = (0..p).filter(|&j| keep[j]).collect();
        // the bins only: the fit's partition (a bin index per sample) is not read
        let mut bins = fit.bins.clone();
        for (b, bs) in grams.bins.iter().enumerate() {
            let w: Vec<f64> = bs
                .maneuvers
                .iter()
                .map(|id| ids.binary_search(id).map_or(0.0, |k| count[k]))
                .collect();
            let distinct = w.iter().filter(|v| **v > 0.0).count();
            let (g, _, n) = bs.total(dim, Some(&w));
            let sol = if n >= required && distinct >= opts.min_maneuvers.max(1) {
                match solve_subset(&g, dim, &cols) {
                    Some((th, _)) => Some((th, None)),
                    None => {
                        // a column the resample leaves dependent (a channel constant or
                        // zero in it): refitted without it, as the estimate's bins are
                        // (minimum norm); the others are not lost with it
                        let kept = independent_subset(&g, dim, &cols);
                        solve_subset(&g, dim, &kept).map(|(th, _)| (th, Some(kept)))
                    }
                }
            } else {
                None
            };
            let bin = &mut bins[b];
            match sol {
                Some((th, kept)) => {
                    bin.params.iter_mut().for_each(|v| *v = 0.0);
                    let used = kept.as_deref().unwrap_or(&cols);
                    for (i, &j) in used.iter().enumerate() {
                        bin.params[j] = th[i] * grams.scale[p] / grams.scale[j];
                    }
                    for &j in cols.iter().filter(|j| !used.contains(j)) {
                        bin.identifiable[j] = false;
                        bin.smoothable[j] = false;
                    }
                }
                None => {
                    bin.identifiable.iter_mut().for_each(|v| *v = false);
                    bin.smoothable.iter_mut().for_each(|v| *v = false);
                }
            }
        }
        let sm = smooth_bins(&fit.names, &bins, smooth)?;
        let per_bin: Vec<Vec<f64>> = bins
            .iter()
            .map(|b| {
                (0..p)
                    .map(|j| {
                        if b.identifiable[j] {
                            b.params[j]
                        } else {
                            f64::NAN
                        }
                    })
                    .collect()
            })
            .collect();
        // a parameter the estimate set to zero stays zero in every replicate; one the
        // replicate cannot smooth (too few of its bins refitted: too few distinct maneuvers
        // drawn) is a failed replicate for it, NaN, not a zero
        let values = sm
            .into_iter()
            .zip(&base)
            .map(|(s, b)| {
                if !b.note.is_empty() {
                    b.values.clone()
                } else if !s.note.is_empty() {
                    vec![f64::NAN; s.values.len()]
                } else {
                    s.values
                }
            })
            .collect();
        Ok((values, per_bin, keep))
    };
    #[cfg(feature = "parallel")]
    let reps: Vec<Replicate> = {
        use rayon::prelude::*;
        (0..opts.replicates)
            .into_par_iter()
            .map(one)
            .collect::<Result<_>>()?
    };
    #[cfg(not(feature = "parallel"))]
    let reps: Vec<Replicate> = (0..opts.replicates).map(one).collect::<Result<_>>()?;

    let grid = base
        .first()
        .map(|s| s.alpha_deg.clone())
        .unwrap_or_default();
    let ng = grid.len();
    let mut replicates = vec![Vec::with_capacity(opts.replicates); p];
    for (vals, _, _) in &reps {
        for (j, v) in vals.iter().enumerate() {
            replicates[j].push(v.clone());
        }
    }
    let (qlo, qhi) = (0.5 * (1.0 - opts.level), 0.5 * (1.0 + opts.level));
    let mut lower = vec![vec![f64::NAN; ng]; p];
    let mut upper = vec![vec![f64::NAN; ng]; p];
    let bias = spline_bias(fit, &base, smooth)?;
    let replicates_ok: Vec<usize> = replicates
        .iter()
        .map(|r| r.iter().filter(|v| v.iter().all(|x| !x.is_nan())).count())
        .collect();
    for j in 0..p {
        // as per bin: under half of the replicates smoothed, no band
        if replicates_ok[j] < 2 || 2 * replicates_ok[j] < reps.len() {
            continue;
        }
        for i in 0..ng {
            let mut col: Vec<f64> = replicates[j]
                .iter()
                .map(|r| r[i])
                .filter(|v| v.is_finite())
                .collect();
            col.sort_by(f64::total_cmp);
            // as per bin: the band reaches the smoothed estimate itself
            let est = base[j].values.get(i).copied().unwrap_or(f64::NAN);
            let (lo, hi) = (quantile(&col, qlo), quantile(&col, qhi));
            let (lo, hi) = if est.is_finite() {
                (lo.min(est), hi.max(est))
            } else {
                (lo, hi)
            };
            // the spline's own bias, on its side (see spline_bias)
            let b = bias[j].get(i).copied().unwrap_or(0.0);
            lower[j][i] = lo + b.min(0.0);
            upper[j][i] = hi + b.max(0.0);
        }
    }
    let nb = fit.bins.len();
    let (mut bin_std, mut bin_lower, mut bin_upper) = (
        vec![vec![f64::NAN; p]; nb],
        vec![vec![f64::NAN; p]; nb],
        vec![vec![f64::NAN; p]; nb],
    );
    let mut bin_replicates_ok = vec![vec![0usize; p]; nb];
    let inclusion: Vec<f64> = (0..p)
        .map(|j| reps.iter().filter(|r| r.2[j]).count() as f64 / reps.len() as f64)
        .collect();
    for b in 0..nb {
        for j in 0..p {
            let mut v: Vec<f64> = reps
                .iter()
                .map(|(_, pb, _)| pb[b][j])
                .filter(|v| v.is_finite())
                .collect();
            bin_replicates_ok[b][j] = v.len();
            if v.len() < 2 || 2 * v.len() < reps.len() {
                continue;
            }
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            bin_std[b][j] =
                (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt();
            v.sort_by(f64::total_cmp);
            // A percentile band never excludes its own estimate: when the
            // replicates sit on one side of it (a term most replicates drop
            // collapses to zero), the band reaches the estimate.
            let bin = &fit.bins[b];
            let est = bin.params[j];
            let (mut lo, mut hi) = (quantile(&v, qlo), quantile(&v, qhi));
            if est.is_finite() {
                (lo, hi) = (lo.min(est), hi.max(est));
                // never inside the bin's CR2 t interval at the band's level
                let (se, dof) = (bin.std_err_cluster[j], bin.dof_cluster[j]);
                if se.is_finite() && se > 0.0 && dof.is_finite() && dof > 0.0 {
                    let h = student_t_ppf(qhi, dof) * se;
                    if h.is_finite() {
                        (lo, hi) = (lo.min(est - h), hi.max(est + h));
                    }
                }
            }
            (bin_lower[b][j], bin_upper[b][j]) = (lo, hi);
        }
    }
    // the smoothed band contains the bands of the bins it was smoothed from
    for j in 0..p {
        let mut nodes: Vec<(f64, f64, f64)> = fit
            .bins
            .iter()
            .enumerate()
            .filter(|(b, bin)| {
                bin.smoothable.get(j).copied().unwrap_or(false)
                    && bin_lower[*b][j].is_finite()
                    && bin_upper[*b][j].is_finite()
            })
            .map(|(b, bin)| {
                (
                    0.5 * (bin.alpha_lo + bin.alpha_hi),
                    bin_lower[b][j],
                    bin_upper[b][j],
                )
            })
            .collect();
        nodes.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (i, &al) in grid.iter().enumerate() {
            if !(lower[j][i].is_finite() && upper[j][i].is_finite()) {
                continue;
            }
            if let Some((lo, hi)) = interpolate_band(&nodes, al) {
                lower[j][i] = lower[j][i].min(lo);
                upper[j][i] = upper[j][i].max(hi);
            }
        }
    }
    Ok(Bootstrap {
        names: fit.names.clone(),
        alpha_deg: grid,
        replicates,
        lower,
        upper,
        bin_std,
        bin_lower,
        bin_upper,
        bin_replicates_ok,
        replicates_ok,
        inclusion,
        level: opts.level,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::fit_bins;
    use crate::sim::rng::Stream;

    #[test]
    fn quantile_is_numpys_linear_rule() {
        let v = [1.0, 2.0, 3.0, 4.0];
        assert!((quantile(&v, 0.5) - 2.5).abs() < 1e-12);
        assert!((quantile(&v, 0.025) - 1.075).abs() < 1e-12);
    }

    /// One synthetic data set: z = truth(α) x + per-maneuver offset + noise,
    /// and its noise-free version.
    type Synthetic = (Design, Vec<f64>, Vec<f64>, Vec<f64>, Vec<u64>);

    fn truth(al: f64) -> f64 {
        // a smooth onset, as the effects of the virtual aircraft
        let u = ((al - 10.0) / 8.0).clamp(0.0, 1.0);
        0.05 * u * u * (3.0 - 2.0 * u)
    }

    fn synthetic(seed: u64, x: &mut Vec<f64>) -> Synthetic {
        let n = 24_000;
        let mut rng = Stream::new(seed, 1);
        let (mut a, mut z, mut z0, mut man) = (vec![], vec![], vec![], vec![]);
        x.clear();
        for i in 0..n {
            let al = 5.0 + 15.0 * rng.uniform();
            let xi = rng.range(-1.0, 1.0);
            let m = (i / 300) as u64;
            // a per-maneuver offset makes the residuals correlated within maneuvers
            let off = 0.002 * ((m * 7919 % 13) as f64 / 6.0 - 1.0);
            z.push(truth(al) * xi + off + 0.003 * rng.normal());
            z0.push(truth(al) * xi);
            a.push(al);
            x.push(xi);
            man.push(m);
        }
        let lookup = |c: &str| -> Option<&[f64]> { (c == "x").then_some(&x[..]) };
        let regs = vec![("bias".into(), "1".into()), ("b".into(), "x".into())];
        let design = Design::build(&regs, &lookup, n).expect("design");
        (design, z, z0, a, man)
    }

    /// At a sharp peak of the true parameter the smoothing spline (Eq. 3.13, p = 0.4) sits
    /// under the bin estimates, and so does every replicate's spline: the percentile band
    /// alone misses the truth there; widened by the spline's bias it holds it.
    #[test]
    fn smoothed_bands_carry_the_spline_bias_at_a_peak() {
        let peak = |al: f64| 0.05 * (-0.5 * ((al - 12.0) / 1.5).powi(2)).exp();
        let n = 24_000;
        let mut rng = Stream::new(11, 1);
        let (mut a, mut z, mut man, mut x) = (vec![], vec![], vec![], vec![]);
        for i in 0..n {
            let al = 5.0 + 15.0 * rng.uniform();
            let xi = rng.range(-1.0, 1.0);
            z.push(peak(al) * xi + 0.001 * rng.normal());
            a.push(al);
            x.push(xi);
            man.push((i / 300) as u64);
        }
        let lookup = |c: &str| -> Option<&[f64]> { (c == "x").then_some(&x[..]) };
        let regs = vec![("bias".into(), "1".into()), ("b".into(), "x".into())];
        let design = Design::build(&regs, &lookup, n).expect("design");
        let opts = crate::select::tests::iid_identify();
        let sm = SmoothOptions::default();
        let bo = BootstrapOptions {
            replicates: 60,
            seed: 5,
            ..BootstrapOptions::default()
        };
        let fit = fit_bins(&design, &z, &a, &man, &opts).expect("fit");
        let b = bootstrap_smoothed(&design, &z, &man, &fit, &sm, &bo, None).expect("boot");
        let base = smooth_parameters(&fit, &sm).expect("smooth");
        let bias = spline_bias(&fit, &base, &sm).expect("pilot").swap_remove(1);
        let i = b
            .alpha_deg
            .iter()
            .position(|&al| (al - 12.0).abs() < 1e-9)
            .expect("grid point at the peak");
        let t = peak(12.0);
        // the spline cuts the peak by more than the replicates spread
        assert!(bias[i] > 0.002, "bias {}", bias[i]);
        assert!(
            base[1].values[i] < t - 0.002,
            "{} vs {t}",
            base[1].values[i]
        );
        let percentile_hi = b.upper[1][i] - bias[i];
        assert!(
            percentile_hi < t,
            "the percentile band alone holds the peak: {percentile_hi}"
        );
        assert!(
            b.lower[1][i] <= t && t <= b.upper[1][i],
            "{} {} {t}",
            b.lower[1][i],
            b.upper[1][i]
        );
        // far from the peak (truth flat at zero) the estimated bias is small
        for (k, &al) in b.alpha_deg.iter().enumerate() {
            if (al - 12.0).abs() > 4.5 && al > 6.0 && al < 19.0 {
                assert!(bias[k].abs() < 0.002, "{al}: {}", bias[k]);
            }
        }
    }

    /// Six maneuvers and five needed per resampled bin: most replicates draw too few distinct
    /// maneuvers to refit enough bins, and such a replicate is counted as failed (NaN), never
    /// read as a zero parameter; under half of them left, no smoothed band. With 80
    /// maneuvers none fails.
    #[test]
    fn replicates_that_cannot_smooth_are_failures_not_zeros() {
        let opts = crate::select::tests::iid_identify();
        let sm = SmoothOptions::default();
        let bo = BootstrapOptions {
            replicates: 40,
            seed: 9,
            min_maneuvers: 5,
            ..BootstrapOptions::default()
        };
        let mut x = Vec::new();
        let (design, z, _, a, man) = synthetic(2, &mut x);
        let few: Vec<u64> = man.iter().map(|m| m / 14).collect(); // 80 -> 6 maneuvers
        for (ids, all_ok) in [(&few, false), (&man, true)] {
            let fit = fit_bins(&design, &z, &a, ids, &opts).expect("fit");
            let b = bootstrap_smoothed(&design, &z, ids, &fit, &sm, &bo, None).expect("boot");
            let reps = &b.replicates[1];
            let finite = reps
                .iter()
                .filter(|r| r.iter().all(|v| v.is_finite()))
                .count();
            assert!(reps
                .iter()
                .all(|r| r.iter().all(|v| v.is_finite()) || r.iter().all(|v| v.is_nan())));
            assert!(
                reps.iter().all(|r| r.iter().any(|v| *v != 0.0)),
                "a zero replicate"
            );
            assert_eq!(b.replicates_ok[1], finite);
            if all_ok {
                assert_eq!(finite, bo.replicates);
                assert!(b.lower[1].iter().all(|v| v.is_finite()));
            } else {
                assert!(2 * finite < bo.replicates, "{finite} replicates smoothed");
                assert!(b.lower[1].iter().chain(&b.upper[1]).all(|v| v.is_nan()));
            }
        }
    }

    /// A structure term whose channel is zero throughout (a thrust difference of symmetric
    /// engines): the estimate's bins leave it out (minimum norm) and fit the others; so does
    /// every replicate, instead of failing every bin on the singular Gram matrix (which left
    /// no replicate to smooth the other terms).
    #[test]
    fn a_dependent_column_does_not_fail_the_replicates() {
        let opts = crate::select::tests::iid_identify();
        let sm = SmoothOptions::default();
        let bo = BootstrapOptions {
            replicates: 30,
            seed: 4,
            ..BootstrapOptions::default()
        };
        let mut x = Vec::new();
        let (design, z, _, a, man) = synthetic(1, &mut x);
        let zero = vec![0.0; design.nrows];
        let lookup = |c: &str| -> Option<&[f64]> {
            match c {
                "x" => Some(&x[..]),
                "zero" => Some(&zero[..]),
                _ => None,
            }
        };
        let regs = vec![
            ("bias".into(), "1".into()),
            ("b".into(), "x".into()),
            ("d".into(), "zero".into()),
        ];
        let with_zero = Design::build(&regs, &lookup, design.nrows).expect("design");
        let fit = fit_bins(&with_zero, &z, &a, &man, &opts).expect("fit");
        let b = bootstrap_smoothed(&with_zero, &z, &man, &fit, &sm, &bo, None).expect("boot");
        assert_eq!(b.replicates_ok[1], bo.replicates);
        // the same band as without the zero column
        let fit0 = fit_bins(&design, &z, &a, &man, &opts).expect("fit");
        let b0 = bootstrap_smoothed(&design, &z, &man, &fit0, &sm, &bo, None).expect("boot");
        for (u, v) in b.lower[1].iter().zip(&b0.lower[1]) {
            assert!((u - v).abs() <= 1e-9 * v.abs().max(1e-6), "{u} vs {v}");
        }
    }

    /// Bands from resampled maneuvers cover their estimand in at least 90 %
    /// of the grid points over several data sets, and are deterministic for a
    /// seed. The estimand checked here is the smoothing of the noise-free bins
    /// (the truth seen through the same spline), computed from the noise-free
    /// data; the bands also carry the spline's estimated bias
    /// ([`spline_bias`]), which only widens them.
    #[test]
    fn bands_cover_the_smoothed_truth_and_repeat_for_a_seed() {
        let opts = crate::select::tests::iid_identify();
        let sm = SmoothOptions::default();
        let bo = BootstrapOptions {
            replicates: 100,
            seed: 3,
            ..BootstrapOptions::default()
        };
        let (mut inside, mut total) = (0, 0);
        let mut x = Vec::new();
        for seed in 0..4 {
            let (design, z, z0, a, man) = synthetic(seed, &mut x);
            let fit = fit_bins(&design, &z, &a, &man, &opts).expect("fit");
            let b1 = bootstrap_smoothed(&design, &z, &man, &fit, &sm, &bo, None).expect("boot");
            if seed == 0 {
                let b2 = bootstrap_smoothed(&design, &z, &man, &fit, &sm, &bo, None).expect("boot");
                assert_eq!(b1.lower, b2.lower);
                assert_eq!(b1.upper, b2.upper);
            }
            let fit0 = fit_bins(&design, &z0, &a, &man, &opts).expect("fit");
            let reference = smooth_parameters(&fit0, &sm).expect("smooths");
            for (i, al) in b1.alpha_deg.iter().enumerate() {
                let t = reference[1].values[i];
                // the smoothing bias is small against the onset's size
                assert!(
                    (t - truth(*al)).abs() < 0.002,
                    "{al}: {t} vs {}",
                    truth(*al)
                );
                total += 1;
                if b1.lower[1][i] <= t && t <= b1.upper[1][i] {
                    inside += 1;
                }
            }
        }
        assert!(inside as f64 >= 0.9 * total as f64, "{inside}/{total}");
    }

    /// The two floors of the bands (module doc), against their definitions: every bin band
    /// holds the bin's CR2 interval `θ̂ ± t(0.975, ν) se` (the t quantile checked against a
    /// closed form: ν = 2 gives `4.302653`), and the smoothed band at every grid alpha holds
    /// the bin bands interpolated between the smoothed bins' centres. On maneuvers with
    /// offsets (correlated residuals), where the percentile band alone sits inside the CR2
    /// interval in some bins: the floor is not vacuous.
    #[test]
    fn bands_hold_the_cr2_interval_and_the_smoothed_bins_bands() {
        assert!((student_t_ppf(0.975, 2.0) - 4.302_652_729_911).abs() < 1e-9);
        let opts = crate::select::tests::iid_identify();
        let sm = SmoothOptions::default();
        let bo = BootstrapOptions {
            replicates: 40,
            seed: 9,
            ..BootstrapOptions::default()
        };
        let mut x = Vec::new();
        let (design, z, _, a, man) = synthetic(2, &mut x);
        let fit = fit_bins(&design, &z, &a, &man, &opts).expect("fit");
        let b = bootstrap_smoothed(&design, &z, &man, &fit, &sm, &bo, None).expect("boot");
        let (mut checked, mut raised) = (0, 0);
        for (bi, bin) in fit.bins.iter().enumerate() {
            for j in 0..2 {
                let (lo, hi) = (b.bin_lower[bi][j], b.bin_upper[bi][j]);
                let (se, dof) = (bin.std_err_cluster[j], bin.dof_cluster[j]);
                if !(lo.is_finite() && se.is_finite() && dof.is_finite()) {
                    continue;
                }
                let h = student_t_ppf(0.975, dof) * se;
                let est = bin.params[j];
                assert!(
                    lo <= est - h && est + h <= hi,
                    "bin {bi}, {j}: {lo}..{hi} vs {est} ± {h}"
                );
                checked += 1;
                // the band's edge is the interval's: the percentile alone was inside it
                if lo == est - h || hi == est + h {
                    raised += 1;
                }
            }
        }
        assert!(checked >= 20, "{checked}");
        assert!(raised > 0, "no bin band was raised to its CR2 interval");
        let j = 1;
        let centres: Vec<(f64, f64, f64)> = fit
            .bins
            .iter()
            .enumerate()
            .filter(|(bi, bin)| bin.smoothable[j] && b.bin_lower[*bi][j].is_finite())
            .map(|(bi, bin)| {
                (
                    0.5 * (bin.alpha_lo + bin.alpha_hi),
                    b.bin_lower[bi][j],
                    b.bin_upper[bi][j],
                )
            })
            .collect();
        assert!(centres.len() >= 5);
        for (i, &al) in b.alpha_deg.iter().enumerate() {
            // the bin bands at this alpha, interpolated by hand between the neighbours
            let k = centres.iter().position(|c| c.0 > al);
            let (lo, hi) = match k {
                Some(0) => (centres[0].1, centres[0].2),
                None => (centres[centres.len() - 1].1, centres[centres.len() - 1].2),
                Some(k) => {
                    let (c0, c1) = (centres[k - 1], centres[k]);
                    let w = (al - c0.0) / (c1.0 - c0.0);
                    (c0.1 + w * (c1.1 - c0.1), c0.2 + w * (c1.2 - c0.2))
                }
            };
            let tol = 1e-12 * (1.0 + lo.abs().max(hi.abs()));
            assert!(
                b.lower[j][i] <= lo + tol && hi - tol <= b.upper[j][i],
                "{al}: {lo}..{hi}"
            );
        }
    }
}
