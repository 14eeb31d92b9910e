//! Per-bin equation-error identification of the Δ model (thesis Section
//! 3.3.2, Eq. 3.5-3.10), adjacent-bin consistency (Section 3.3.4) and the
//! smoothing of the per-bin parameters into simulator tables (Section 3.4,
//! Eq. 3.13, 3.19).
//!
//! For one coefficient and one flap setting: the qualified-model error
//! $z = C_{meas} - C_{qual}$ (Eq. 3.5) is regressed on the regressors of the
//! postulated Δ model (Eq. 3.6-3.9) separately in each angle-of-attack bin
//! (Section 3.3.1), by least squares (Eq. 3.10, computed by QR in
//! [`crate::lsq`]). Every parameter of every bin is reported with its
//! conventional and coloured-residual standard errors and is marked *not
//! identifiable* — instead of silently kept — when
//! - the bin has fewer than the required points or maneuvers;
//! - the bin holds fewer than `min_maneuvers_identified` maneuvers: the
//!   estimate would carry those few maneuvers' own errors (sensor biases,
//!   gusts), and a bootstrap over maneuvers cannot measure its spread;
//! - its regressor hardly varies in the bin (low excitation, Section 3.3.3):
//!   the regressor's standard deviation in the bin is below
//!   `min_excitation` times its standard deviation over the flap's data, or
//!   below `min_excitation_snr` times the regressor's noise floor
//!   ([`noise_floor`]). The first rule compares a bin with the rest of its
//!   flap and cannot see a regressor that is quiet at every alpha (a control
//!   held still throughout a campaign); the second compares it with the
//!   measurement noise, whatever the rest of the data do. The floor reads the
//!   time structure of sampled data (motion slow against the sample rate):
//!   regressors drawn afresh at every row look like noise to it, so turn it
//!   off (`min_excitation_snr = 0`) for such data;
//! - it is collinear with others (the near-dependency diagnostics of
//!   [`crate::lsq`], Section 3.3.3 "Data Collinearity"), or its variance
//!   inflation factor exceeds `max_vif` (Klein & Morelli 2006, Section 5.4.1:
//!   10): the note names the regressors its estimate trades against (the
//!   estimate correlations `|ρ_jk| ≥ 0.5` of the conventional covariance, or
//!   the largest one). Its variance is then more than `max_vif` times what its
//!   own excitation would give, and the estimate splits one effect between
//!   the collinear terms (β̇ against p̂ sin α − r̂ cos α at high alpha).
//!
//! Rows of a bin are passed to the regression in input order, so the
//! coloured-residual correction sees each maneuver's samples in time order,
//! with the segments of different maneuvers spliced one after another.

use crate::error::{AeroError, Result, ResultExt};
use crate::lsq::stats::{student_t_ppf, student_t_sf_two_sided};
use crate::lsq::{ols_rows_clustered, OlsFit, OlsOptions};
use crate::partition::{partition_alpha, AlphaBins, PartitionOptions};
use crate::regressor::Expr;
use crate::spline::{smoothing_spline, Smoothing, SplineExtrapolation};

/// Settings of the per-bin identification.
#[derive(Debug, Clone)]
pub struct IdentifyOptions {
    /// Alpha partitioning (nominal width, points per parameter, maneuvers per bin).
    pub partition: PartitionOptions,
    /// Compute coloured-residual standard errors.
    pub colored: bool,
    /// Lag truncation of the coloured-residual correction, samples.
    pub max_lag: Option<usize>,
    /// A regressor whose in-bin standard deviation is below this fraction of
    /// its standard deviation over the flap's data is "low excitation".
    pub min_excitation: f64,
    /// Condition-index threshold of a near dependency (collinearity).
    pub collinear_cond: f64,
    /// A regressor whose in-bin standard deviation is below this multiple of
    /// its noise floor ([`noise_floor`]) is "low excitation".
    pub min_excitation_snr: f64,
    /// Fewest maneuvers in a bin for its parameters to be identified.
    pub min_maneuvers_identified: usize,
    /// A non-constant regressor whose variance inflation factor in a bin exceeds this is
    /// not identified there ("collinear with ..."); `f64::INFINITY`: only the
    /// condition-index rule.
    pub max_vif: f64,
    /// In [`crate::select::identify_flap`], leave out of the structure a term collinear in
    /// most bins of the flap ([`crate::select::collinear_to_prune`]); `false` keeps a given
    /// structure whole (its collinear terms are then not identified bin by bin).
    pub prune_collinear: bool,
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        IdentifyOptions {
            partition: PartitionOptions::default(),
            colored: true,
            max_lag: None,
            min_excitation: 0.05,
            collinear_cond: OlsOptions::default().collinear_cond,
            min_excitation_snr: 3.0,
            min_maneuvers_identified: 5,
            max_vif: 10.0,
            prune_collinear: true,
        }
    }
}

/// A regressor matrix built from expressions over data columns.
#[derive(Debug, Clone)]
pub struct Design {
    /// Parameter names, one per column.
    pub names: Vec<String>,
    /// The expressions.
    pub exprs: Vec<Expr>,
    /// Row-major values, `nrows × names.len()`.
    pub values: Vec<f64>,
    /// Number of rows.
    pub nrows: usize,
}

/// Storage a thread reuses from one [`Design::build_into`] to the next: the row-major values
/// (handed to the design built and taken back by [`DesignBuffers::recycle`]) and the columns
/// of the expressions that are not plain data columns.
#[derive(Debug, Default)]
pub struct DesignBuffers {
    values: Vec<f64>,
    columns: Vec<Vec<f64>>,
}

impl DesignBuffers {
    /// Take back the values' storage of a design (built by [`Design::build_into`] or not) for
    /// the next build.
    pub fn recycle(&mut self, design: Design) {
        self.values = design.values;
    }
}

impl Design {
    /// Evaluate `regressors` (`(name, expression)` pairs) over columns of `n` rows.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the regressor that does not parse
    /// or reads a missing column.
    pub fn build<'a>(
        regressors: &[(String, String)],
        lookup: &dyn Fn(&str) -> Option<&'a [f64]>,
        n: usize,
    ) -> Result<Design> {
        Design::build_into(regressors, lookup, n, &mut DesignBuffers::default())
    }

    /// [`Design::build`] in the storage of `buffers`: the same design, without a fresh
    /// allocation (and its page faults) when the buffers have held one as large. A
    /// regressor that is a plain data column is read in place; the values' storage moves
    /// into the design (give it back with [`DesignBuffers::recycle`]).
    ///
    /// # Errors
    /// Those of [`Design::build`].
    pub fn build_into<'a>(
        regressors: &[(String, String)],
        lookup: &dyn Fn(&str) -> Option<&'a [f64]>,
        n: usize,
        buffers: &mut DesignBuffers,
    ) -> Result<Design> {
        if regressors.is_empty() {
            return Err(AeroError::invalid(
                "model structure",
                "has no regressors; give at least one (e.g. the bias '1')",
            ));
        }
        let p = regressors.len();
        let mut names = Vec::with_capacity(p);
        let mut exprs = Vec::with_capacity(p);
        // per regressor, its data column (read in place) or its values in `buffers.columns[j]`
        let mut data: Vec<Option<&'a [f64]>> = Vec::with_capacity(p);
        if buffers.columns.len() < p {
            buffers.columns.resize_with(p, Vec::new);
        }
        for ((name, src), scratch) in regressors.iter().zip(&mut buffers.columns) {
            let e = Expr::parse(src).with_context(|| format!("parameter '{name}'"))?;
            let col = e
                .as_data_column(lookup, n)
                .with_context(|| format!("parameter '{name}'"))?;
            if col.is_none() {
                e.eval_columns_into(lookup, n, scratch)
                    .with_context(|| format!("parameter '{name}'"))?;
            }
            data.push(col);
            names.push(name.clone());
            exprs.push(e);
        }
        let cols: Vec<&[f64]> = data
            .iter()
            .zip(&buffers.columns)
            .map(|(d, scratch)| d.unwrap_or(scratch.as_slice()))
            .collect();
        // row-major, written row by row (the columns are read as p sequential streams)
        let mut values = std::mem::take(&mut buffers.values);
        values.clear();
        values.reserve(n * p);
        for i in 0..n {
            values.extend(cols.iter().map(|c| c[i]));
        }
        Ok(Design {
            names,
            exprs,
            values,
            nrows: n,
        })
    }

    /// Number of parameters.
    pub fn ncols(&self) -> usize {
        self.names.len()
    }

    /// The sample standard deviation of every column over `rows` (non-finite values
    /// skipped), in one pass over the rows: Welford's update per column, in row order.
    fn column_stds(&self, rows: impl Iterator<Item = usize>) -> Vec<f64> {
        let p = self.ncols();
        let mut acc = vec![(0.0f64, 0.0f64, 0.0f64); p];
        for r in rows {
            for ((n, mean, m2), &v) in acc.iter_mut().zip(&self.values[r * p..(r + 1) * p]) {
                if v.is_finite() {
                    *n += 1.0;
                    let d = v - *mean;
                    *mean += d / *n;
                    *m2 += d * (v - *mean);
                }
            }
        }
        acc.iter()
            .map(|&(n, _, m2)| {
                if n > 1.0 {
                    (m2 / (n - 1.0)).sqrt()
                } else {
                    0.0
                }
            })
            .collect()
    }
}

/// The estimate of one bin.
#[derive(Debug, Clone)]
pub struct BinFit {
    /// Lower alpha edge, deg.
    pub alpha_lo: f64,
    /// Upper alpha edge, deg.
    pub alpha_hi: f64,
    /// Number of samples.
    pub n: usize,
    /// Number of distinct maneuvers.
    pub n_maneuvers: usize,
    /// Estimates (NaN when the bin could not be fitted).
    pub params: Vec<f64>,
    /// Conventional standard errors.
    pub std_err: Vec<f64>,
    /// Standard errors corrected for coloured residuals (NaN when not computed).
    pub std_err_colored: Vec<f64>,
    /// Cluster-robust standard errors, maneuvers as clusters, CR2
    /// ([`crate::lsq::cluster`]): the default for intervals, p-values and
    /// the adjacent-bin check (the smoothing weights stay conventional). NaN where undefined (one maneuver
    /// alone determines the parameter; the note says so).
    pub std_err_cluster: Vec<f64>,
    /// Bell-McCaffrey degrees of freedom of the cluster-robust errors (Student t).
    pub dof_cluster: Vec<f64>,
    /// Half-width of the 95 % interval, `t(0.975, dof_cluster) std_err_cluster`.
    pub ci95_half_width: Vec<f64>,
    /// Two-sided p-value of `θ̂ / std_err_cluster` under Student t with `dof_cluster`.
    pub p_value: Vec<f64>,
    /// Partial F per parameter (Eq. 2.5).
    pub partial_f: Vec<f64>,
    /// Excitation of each regressor: in-bin std over the flap's std.
    pub excitation: Vec<f64>,
    /// In-bin std of each regressor over its noise floor ([`noise_floor`];
    /// infinite for a constant regressor or a noiseless one).
    pub excitation_snr: Vec<f64>,
    /// Variance inflation factor of each regressor.
    pub vif: Vec<f64>,
    /// Per parameter, the other non-constant parameter whose estimate correlates most with
    /// it (conventional covariance; `None` when the bin was not fitted or has no other).
    pub most_correlated: Vec<Option<usize>>,
    /// Whether each parameter is identified in this bin.
    pub identifiable: Vec<bool>,
    /// Whether the bin's estimate enters the parameter's smoothed table: identified, or not
    /// identified only for its variance inflation (`max_vif`). Collinear estimates are not
    /// separate derivatives, but their errors cancel along the direction the data excite,
    /// and the smoothing (linear in the bin values, the same bins for every collinear
    /// term) keeps that combination; leaving the bins out would lose the group's effect.
    pub smoothable: Vec<bool>,
    /// Why not, per parameter ("" when identified).
    pub notes: Vec<String>,
    /// R² of the bin's regression.
    pub r2: f64,
    /// Condition number of the column-normalized regressors.
    pub condition_number: f64,
    /// Residual standard deviation.
    pub residual_std: f64,
    /// A note for the whole bin ("" when fitted).
    pub note: String,
}

impl BinFit {
    /// A bin of `n` samples from `n_maneuvers` maneuvers between the alpha `edges` before its
    /// fit: every statistic NaN, nothing identified, no note.
    pub fn unfitted(
        edges: (f64, f64),
        n: usize,
        n_maneuvers: usize,
        excitation: Vec<f64>,
        excitation_snr: Vec<f64>,
    ) -> Self {
        let p = excitation.len();
        let nan = vec![f64::NAN; p];
        BinFit {
            alpha_lo: edges.0,
            alpha_hi: edges.1,
            n,
            n_maneuvers,
            params: nan.clone(),
            std_err: nan.clone(),
            std_err_colored: nan.clone(),
            std_err_cluster: nan.clone(),
            dof_cluster: nan.clone(),
            ci95_half_width: nan.clone(),
            p_value: nan.clone(),
            partial_f: nan.clone(),
            excitation,
            excitation_snr,
            vif: nan,
            most_correlated: vec![None; p],
            identifiable: vec![false; p],
            smoothable: vec![false; p],
            notes: vec![String::new(); p],
            r2: f64::NAN,
            condition_number: f64::NAN,
            residual_std: f64::NAN,
            note: String::new(),
        }
    }

    /// The standard error of parameter `j` used for the adjacent-bin check:
    /// the cluster-robust one where defined, else the conventional one.
    pub fn se(&self, j: usize) -> f64 {
        let c = self.std_err_cluster.get(j).copied().unwrap_or(f64::NAN);
        if c.is_finite() {
            c
        } else {
            self.std_err[j]
        }
    }
}

/// Adjacent-bin consistency of one parameter (Section 3.3.4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Consistency {
    /// `rms(θ_{k+1} - θ_k) / (√2 rms(θ_k))` over identified neighbours: about
    /// 1 or more for estimates scattered around zero (not identified), small
    /// for a parameter that varies smoothly with alpha.
    pub scatter: f64,
    /// Median of `|θ_{k+1} - θ_k| / √(s_k² + s_{k+1}²)`: about 0.67 when the
    /// steps are what the standard errors predict, much larger when the
    /// standard errors understate the scatter.
    pub step_z: f64,
    /// Number of adjacent identified pairs used.
    pub pairs: usize,
}

/// All bins of one coefficient and flap setting.
#[derive(Debug, Clone)]
pub struct BinnedFit {
    /// Parameter names.
    pub names: Vec<String>,
    /// The bins, in increasing alpha.
    pub bins: Vec<BinFit>,
    /// Per parameter.
    pub consistency: Vec<Consistency>,
    /// The partition used.
    pub partition: AlphaBins,
}

/// Noise floor of each regressor: the standard deviation of white noise that
/// would give its second differences, $\hat\sigma = 1.4826\,
/// \mathrm{median}|x_{i-1} - 2x_i + x_{i+1}| / \sqrt 6$, over consecutive rows of
/// the same maneuver (rows in time order, as ingested; every other triple).
/// A smooth signal has second differences near zero, so the median reads the
/// noise; a control held still reads its sensor noise, a smoothed channel
/// almost nothing. Zero for a constant regressor or one without triples.
pub fn noise_floor(design: &Design, maneuver: &[u64]) -> Vec<f64> {
    let p = design.ncols();
    let n = design.nrows.min(maneuver.len());
    let constant: Vec<bool> = design.exprs.iter().map(Expr::is_constant).collect();
    // one pass over the triples, row-major (every column's differences in row order)
    let mut d2: Vec<Vec<f64>> = (0..p)
        .map(|j| Vec::with_capacity(if constant[j] { 0 } else { n / 2 }))
        .collect();
    let row = |i: usize| &design.values[i * p..(i + 1) * p];
    let mut i = 1;
    while i + 1 < n {
        if maneuver[i - 1] == maneuver[i] && maneuver[i] == maneuver[i + 1] {
            let (a, b, c) = (row(i - 1), row(i), row(i + 1));
            for j in 0..p {
                let v = (a[j] - 2.0 * b[j] + c[j]).abs();
                if !constant[j] && v.is_finite() {
                    d2[j].push(v);
                }
            }
        }
        i += 2;
    }
    d2.iter_mut()
        .map(|d| {
            if d.is_empty() {
                return 0.0;
            }
            let mid = d.len() / 2;
            let (_, m, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
            1.4826 * *m / 6f64.sqrt()
        })
        .collect()
}

/// Why parameter `j` of a bin is low excitation (`None` when it is not): the
/// two rules of the module doc.
pub(crate) fn low_excitation(ratio: f64, snr: f64, opts: &IdentifyOptions) -> Option<String> {
    if ratio < opts.min_excitation {
        Some(format!(
            "low excitation: std in bin is {:.1}% of the flap's (minimum {:.1}%)",
            100.0 * ratio,
            100.0 * opts.min_excitation
        ))
    } else if snr < opts.min_excitation_snr {
        Some(format!(
            "low excitation: std in bin is {snr:.1} times the regressor's noise floor \
             (minimum {:.1})",
            opts.min_excitation_snr
        ))
    } else {
        None
    }
}

/// In-bin std over the noise floor (infinite when the floor is zero).
pub(crate) fn snr(sd: f64, floor: f64) -> f64 {
    if floor > 0.0 {
        sd / floor
    } else {
        f64::INFINITY
    }
}

fn fit_one_bin(
    design: &Design,
    z: &[f64],
    rows: &[usize],
    maneuver: &[u64],
    opts: &IdentifyOptions,
) -> Result<OlsFit> {
    let ols_opts = OlsOptions {
        drop_nan: true,
        colored: opts.colored,
        max_lag: opts.max_lag,
        min_norm: true,
        collinear_cond: opts.collinear_cond,
        names: design.names.clone(),
    };
    ols_rows_clustered(
        &design.values,
        design.nrows,
        design.ncols(),
        z,
        rows,
        maneuver,
        &ols_opts,
    )
}

/// The alpha bins of a design and the rows in each (the partition of
/// [`partition_alpha`], which depends on the number of columns through the
/// points-per-parameter rule), with the data requirement every bin must meet
/// before it is fitted.
#[derive(Debug, Clone)]
pub struct BinPlan {
    /// The partition.
    pub partition: AlphaBins,
    /// Rows of each bin, in input order.
    pub members: Vec<Vec<usize>>,
    /// Distinct maneuvers of each bin, sorted.
    pub maneuvers: Vec<Vec<u64>>,
    /// Points a bin needs (`min_points_per_param` × columns).
    pub required: usize,
    /// Maneuvers a bin needs.
    pub min_maneuvers: usize,
}

impl BinPlan {
    /// Whether bin `b` has the points and maneuvers to be fitted.
    pub fn enough_data(&self, b: usize) -> bool {
        self.members[b].len() >= self.required && self.maneuvers[b].len() >= self.min_maneuvers
    }
}

/// The bins [`fit_bins`] fits for `design` (same checks, same partition).
///
/// # Errors
/// As [`fit_bins`].
pub fn plan_bins(
    design: &Design,
    z: &[f64],
    alpha_deg: &[f64],
    maneuver: &[u64],
    opts: &IdentifyOptions,
) -> Result<BinPlan> {
    let n = design.nrows;
    for (what, len) in [
        ("z", z.len()),
        ("alpha_deg", alpha_deg.len()),
        ("maneuver", maneuver.len()),
    ] {
        if len != n {
            return Err(AeroError::invalid(
                format!("identification, {what}"),
                format!("has {len} rows, the regressors have {n}"),
            ));
        }
    }
    let p = design.ncols();
    let partition = partition_alpha(alpha_deg, p, Some(maneuver), &opts.partition)?;
    let nb = partition.counts.len();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); nb];
    for (r, &b) in partition.index.iter().enumerate() {
        if b >= 0 {
            members[b as usize].push(r);
        }
    }
    let maneuvers = members
        .iter()
        .map(|rows| {
            let mut m: Vec<u64> = rows.iter().map(|&r| maneuver[r]).collect();
            m.sort_unstable();
            m.dedup();
            m
        })
        .collect();
    Ok(BinPlan {
        partition,
        members,
        maneuvers,
        required: opts.partition.min_points_per_param * p,
        min_maneuvers: opts.partition.min_maneuvers.max(1),
    })
}

/// Identify the Δ parameters bin by bin.
///
/// `z` is the qualified-model error (Eq. 3.5), `alpha_deg` the angle of
/// attack and `maneuver` an integer id per row (for the maneuvers-per-bin
/// rule and the consistency of the coloured-residual correction).
///
/// # Errors
/// [`AeroError::InvalidInput`] when lengths differ or the data are empty;
/// partition errors. A bin that cannot be fitted is reported in its
/// [`BinFit::note`], not as an error.
pub fn fit_bins(
    design: &Design,
    z: &[f64],
    alpha_deg: &[f64],
    maneuver: &[u64],
    opts: &IdentifyOptions,
) -> Result<BinnedFit> {
    let plan = plan_bins(design, z, alpha_deg, maneuver, opts)?;
    Ok(fit_planned(design, z, maneuver, plan, opts))
}

/// [`fit_bins`] in the bins of `plan`, which [`plan_bins`] made for this `design`, `z`,
/// `maneuver` and `opts` (its checks passed): a caller that planned the bins already does
/// not partition again.
pub(crate) fn fit_planned(
    design: &Design,
    z: &[f64],
    maneuver: &[u64],
    plan: BinPlan,
    opts: &IdentifyOptions,
) -> BinnedFit {
    debug_assert_eq!(
        plan.required,
        opts.partition.min_points_per_param * design.ncols()
    );
    let n = design.nrows;
    let p = design.ncols();
    let nb = plan.members.len();
    let flap_std = design.column_stds(0..n);
    let floor = noise_floor(design, maneuver);
    let const_col: Vec<bool> = design.exprs.iter().map(Expr::is_constant).collect();
    let (required, min_maneuvers) = (plan.required, plan.min_maneuvers);

    let work = |b: usize| -> BinFit {
        let rows = &plan.members[b];
        let maneuvers = &plan.maneuvers[b];
        let in_bin_std = design.column_stds(rows.iter().copied());
        let excitation: Vec<f64> = (0..p)
            .map(|j| {
                if const_col[j] {
                    1.0
                } else if flap_std[j] > 0.0 {
                    in_bin_std[j] / flap_std[j]
                } else {
                    0.0
                }
            })
            .collect();
        // a constant regressor's floor is zero: infinite
        let excitation_snr: Vec<f64> = (0..p).map(|j| snr(in_bin_std[j], floor[j])).collect();
        let mut bin = BinFit::unfitted(
            (plan.partition.edges[b], plan.partition.edges[b + 1]),
            rows.len(),
            maneuvers.len(),
            excitation,
            excitation_snr,
        );
        if !plan.enough_data(b) {
            bin.note = format!(
                "too little data: {} points from {} maneuvers, {} points and {} maneuvers required",
                rows.len(),
                maneuvers.len(),
                required,
                min_maneuvers
            );
            bin.notes = vec!["bin not fitted: too little data".into(); p];
            return bin;
        }
        match fit_one_bin(design, z, rows, maneuver, opts) {
            Err(e) => {
                bin.note = format!("not fitted: {e}");
                bin.notes = vec!["bin not fitted".into(); p];
            }
            Ok(fit) => {
                bin.params = fit.params.clone();
                bin.std_err = fit.std_err.clone();
                bin.std_err_colored = fit
                    .std_err_colored
                    .clone()
                    .unwrap_or_else(|| vec![f64::NAN; p]);
                if let Some(c) = &fit.cluster {
                    bin.std_err_cluster = c.std_err.clone();
                    bin.dof_cluster = c.dof.clone();
                    for j in 0..p {
                        let (se, dof) = (c.std_err[j], c.dof[j]);
                        if se.is_finite() && dof.is_finite() {
                            bin.ci95_half_width[j] = student_t_ppf(0.975, dof) * se;
                            bin.p_value[j] = student_t_sf_two_sided(bin.params[j] / se, dof);
                        }
                    }
                }
                bin.partial_f = fit.partial_f.clone();
                bin.vif = fit.collinearity.vif.clone();
                bin.most_correlated = (0..p)
                    .map(|j| {
                        estimate_correlations(&fit.cov, &const_col, j)
                            .first()
                            .map(|c| c.0)
                    })
                    .collect();
                bin.r2 = fit.r2;
                bin.condition_number = fit.condition_number;
                bin.residual_std = fit.s2.sqrt();
                #[allow(clippy::needless_range_loop)]
                for j in 0..p {
                    let mut why = Vec::new();
                    let mut collinear_only = false;
                    if !fit.identifiable[j] {
                        why.push(if fit.notes[j].is_empty() {
                            "collinear".to_string()
                        } else {
                            fit.notes[j].clone()
                        });
                    }
                    if !const_col[j] {
                        if let Some(w) =
                            low_excitation(bin.excitation[j], bin.excitation_snr[j], opts)
                        {
                            why.push(w);
                        }
                        if fit.identifiable[j] && bin.vif[j] > opts.max_vif {
                            collinear_only = why.is_empty();
                            why.push(collinear_note(&fit, &design.names, &const_col, j, opts));
                        }
                    }
                    if bin.n_maneuvers < opts.min_maneuvers_identified {
                        why.push(format!(
                            "{} maneuvers in the bin (minimum {}): the estimate would carry \
                             their own errors",
                            bin.n_maneuvers, opts.min_maneuvers_identified
                        ));
                    }
                    if !bin.params[j].is_finite() || !bin.std_err[j].is_finite() {
                        why.push("estimate not finite".into());
                    } else if !bin.std_err_cluster[j].is_finite() && why.is_empty() {
                        why.push(fit.cluster.as_ref().map_or_else(
                            || "no cluster-robust standard error".to_string(),
                            |c| c.notes[j].clone(),
                        ));
                    }
                    bin.identifiable[j] = why.is_empty();
                    bin.smoothable[j] = why.is_empty() || (collinear_only && why.len() == 1);
                    bin.notes[j] = why.join("; ");
                }
            }
        }
        bin
    };

    #[cfg(feature = "parallel")]
    let bins: Vec<BinFit> = {
        use rayon::prelude::*;
        (0..nb).into_par_iter().map(work).collect()
    };
    #[cfg(not(feature = "parallel"))]
    let bins: Vec<BinFit> = (0..nb).map(work).collect();

    let consistency = (0..p).map(|j| adjacent_consistency(&bins, j)).collect();
    BinnedFit {
        names: design.names.clone(),
        bins,
        consistency,
        partition: plan.partition,
    }
}

/// `|ρ_jk|` of parameter `j`'s estimate with every other non-constant parameter `k`
/// (conventional covariance `cov`, `p × p` row-major), largest first (NaN counted as 0).
pub(crate) fn estimate_correlations(
    cov: &[f64],
    const_col: &[bool],
    j: usize,
) -> Vec<(usize, f64)> {
    let p = const_col.len();
    let mut r: Vec<(usize, f64)> = (0..p)
        .filter(|&k| k != j && !const_col[k])
        .map(|k| {
            let r = cov[j * p + k] / (cov[j * p + j] * cov[k * p + k]).sqrt();
            (k, if r.is_finite() { r.abs() } else { 0.0 })
        })
        .collect();
    r.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    r
}

/// "collinear with 'a', 'b' (VIF v > max)": the regressors whose estimates correlate with
/// parameter `j`'s by `|ρ| ≥ 0.5` in the conventional covariance of `fit` (constant columns
/// left out), largest first, at most three; the most correlated one when none reaches 0.5.
fn collinear_note(
    fit: &OlsFit,
    names: &[String],
    const_col: &[bool],
    j: usize,
    opts: &IdentifyOptions,
) -> String {
    let partners = estimate_correlations(&fit.cov, const_col, j);
    let strong = partners
        .iter()
        .filter(|(_, r)| *r >= 0.5)
        .count()
        .clamp(1, 3);
    let listed: Vec<String> = partners
        .iter()
        .take(strong)
        .map(|(k, r)| format!("'{}' (estimate correlation {r:.2})", names[*k]))
        .collect();
    let with = if listed.is_empty() {
        "the other regressors".to_string()
    } else {
        listed.join(", ")
    };
    format!(
        "collinear with {with}: VIF {:.0} > {}",
        fit.collinearity.vif[j], opts.max_vif
    )
}

/// Adjacent-bin consistency of parameter `j` (see [`Consistency`]).
pub fn adjacent_consistency(bins: &[BinFit], j: usize) -> Consistency {
    let mut diffs = Vec::new();
    let mut zs = Vec::new();
    for w in bins.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        if a.identifiable[j] && b.identifiable[j] {
            let d = b.params[j] - a.params[j];
            diffs.push(d);
            let s = (a.se(j).powi(2) + b.se(j).powi(2)).sqrt();
            if s > 0.0 {
                zs.push((d / s).abs());
            }
        }
    }
    let ident: Vec<f64> = bins
        .iter()
        .filter(|b| b.identifiable[j])
        .map(|b| b.params[j])
        .collect();
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    let scatter = if diffs.is_empty() || rms(&ident) == 0.0 {
        f64::NAN
    } else {
        rms(&diffs) / (std::f64::consts::SQRT_2 * rms(&ident))
    };
    zs.sort_by(f64::total_cmp);
    let step_z = if zs.is_empty() {
        f64::NAN
    } else if zs.len() % 2 == 1 {
        zs[zs.len() / 2]
    } else {
        0.5 * (zs[zs.len() / 2 - 1] + zs[zs.len() / 2])
    };
    Consistency {
        scatter,
        step_z,
        pairs: diffs.len(),
    }
}

/// How the per-bin parameters become a table in alpha (Section 3.4).
#[derive(Debug, Clone)]
pub struct SmoothOptions {
    /// Smoothing parameter p of Eq. 3.13 (thesis: 0.4), alpha in deg.
    pub p: f64,
    /// Weight each bin by `1/s²` (normalised to mean one) instead of equally.
    pub weighted: bool,
    /// Table breakpoint spacing, deg.
    pub grid_step_deg: f64,
    /// Highest alpha of the table, deg (thesis: 10 deg past stall); the table
    /// holds its last value beyond.
    pub alpha_max_deg: f64,
    /// Fewer identified bins than this: the parameter is set to zero (the
    /// qualified model is kept) and a note says so.
    pub min_identified_bins: usize,
}

impl Default for SmoothOptions {
    fn default() -> Self {
        SmoothOptions {
            p: 0.4,
            weighted: false,
            grid_step_deg: 0.5,
            alpha_max_deg: f64::INFINITY,
            min_identified_bins: 4,
        }
    }
}

/// A parameter smoothed against alpha and resampled on a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct SmoothedParameter {
    /// Parameter name.
    pub name: String,
    /// Grid, deg.
    pub alpha_deg: Vec<f64>,
    /// Smoothed values on the grid.
    pub values: Vec<f64>,
    /// Number of identified bins used.
    pub bins_used: usize,
    /// "" or why the parameter was set to zero.
    pub note: String,
}

/// The common table grid of a binned fit: from the first bin centre to the
/// last (or `alpha_max_deg`), every `grid_step_deg`, ends included.
pub fn table_grid(fit: &BinnedFit, opts: &SmoothOptions) -> Vec<f64> {
    bins_grid(&fit.bins, opts)
}

/// [`table_grid`] of `bins` (in increasing alpha).
fn bins_grid(bins: &[BinFit], opts: &SmoothOptions) -> Vec<f64> {
    let centres: Vec<f64> = bins
        .iter()
        .map(|b| 0.5 * (b.alpha_lo + b.alpha_hi))
        .collect();
    let (Some(&lo), Some(&hi)) = (centres.first(), centres.last()) else {
        return Vec::new();
    };
    let hi = hi.min(opts.alpha_max_deg);
    if hi.is_nan() || hi <= lo || opts.grid_step_deg <= 0.0 {
        return vec![lo];
    }
    let step = opts.grid_step_deg;
    let start = (lo / step).ceil() * step;
    let mut grid = vec![lo];
    let mut a = start;
    while a < hi - 1e-9 {
        if a > lo + 1e-9 {
            grid.push(a);
        }
        a += step;
    }
    grid.push(hi);
    grid
}

/// Smooth each parameter of a binned fit with a `csaps` spline through its
/// identified bins (Eq. 3.13) and resample it on [`table_grid`], holding the
/// end values beyond the identified range (tables clipped past stall,
/// Section 3.4).
///
/// # Errors
/// Spline errors with the parameter named.
pub fn smooth_parameters(fit: &BinnedFit, opts: &SmoothOptions) -> Result<Vec<SmoothedParameter>> {
    smooth_bins(&fit.names, &fit.bins, opts)
}

/// [`smooth_parameters`] of the parameters `names` over `bins` (in increasing alpha): what
/// it reads of a binned fit, for a caller that has changed the bins' estimates (a bootstrap
/// replicate) without the rest of the fit (its partition holds a bin index per sample).
///
/// # Errors
/// As [`smooth_parameters`].
pub fn smooth_bins(
    names: &[String],
    bins: &[BinFit],
    opts: &SmoothOptions,
) -> Result<Vec<SmoothedParameter>> {
    let grid = bins_grid(bins, opts);
    let mut out = Vec::with_capacity(names.len());
    for (j, name) in names.iter().enumerate() {
        let used: Vec<&BinFit> = bins
            .iter()
            .filter(|b| b.smoothable[j] && 0.5 * (b.alpha_lo + b.alpha_hi) <= opts.alpha_max_deg)
            .collect();
        if used.len() < opts.min_identified_bins.max(2) {
            out.push(SmoothedParameter {
                name: name.clone(),
                alpha_deg: grid.clone(),
                values: vec![0.0; grid.len()],
                bins_used: used.len(),
                note: format!(
                    "identified in {} bins (fewer than {}): Δ set to zero, the qualified model is kept",
                    used.len(),
                    opts.min_identified_bins.max(2)
                ),
            });
            continue;
        }
        let x: Vec<f64> = used
            .iter()
            .map(|b| 0.5 * (b.alpha_lo + b.alpha_hi))
            .collect();
        let y: Vec<f64> = used.iter().map(|b| b.params[j]).collect();
        let w: Option<Vec<f64>> = opts.weighted.then(|| {
            let raw: Vec<f64> = used
                .iter()
                // conventional errors, as before the cluster-robust ones
                // became the default (weighting by those is not measured yet)
                .map(|b| 1.0 / b.std_err[j].powi(2).max(f64::MIN_POSITIVE))
                .collect();
            let mean = raw.iter().sum::<f64>() / raw.len() as f64;
            raw.iter().map(|v| v / mean).collect()
        });
        let spline = smoothing_spline(&x, &y, w.as_deref(), Smoothing::Fixed(opts.p))
            .with_context(|| format!("smoothing parameter '{name}'"))?;
        let (x0, x1) = (x[0], x[x.len() - 1]);
        let values = grid
            .iter()
            .map(|&a| spline.eval(a.clamp(x0, x1), 0, SplineExtrapolation::Hold))
            .collect();
        out.push(SmoothedParameter {
            name: name.clone(),
            alpha_deg: grid.clone(),
            values,
            bins_used: used.len(),
            note: String::new(),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A truth with alpha-dependent parameters: z = a(α) + b(α) x1 + c x2 + noise.
    type Columns = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>, Vec<u64>);

    fn truth_data(n: usize, seed: u64) -> Columns {
        let mut s = seed.wrapping_add(0x9E3779B97F4A7C15);
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut alpha = Vec::with_capacity(n);
        let mut x1 = Vec::with_capacity(n);
        let mut x2 = Vec::with_capacity(n);
        let mut z = Vec::with_capacity(n);
        let mut man = Vec::with_capacity(n);
        for i in 0..n {
            let a = 5.0 + 15.0 * rnd();
            let u1 = 2.0 * rnd() - 1.0;
            let u2 = 2.0 * rnd() - 1.0;
            let noise = 0.001 * (rnd() + rnd() + rnd() - 1.5);
            let b = 0.01 * (a - 12.0).max(0.0);
            z.push(0.002 + b * u1 - 0.03 * u2 + noise);
            alpha.push(a);
            x1.push(u1);
            x2.push(u2);
            man.push((i / 500) as u64);
        }
        (alpha, x1, x2, z, man)
    }

    /// Fit `z ~ bias + b x1 + c x2` bin by bin with the default options.
    fn fit_truth(alpha: &[f64], x1: &[f64], x2: &[f64], z: &[f64], man: &[u64]) -> BinnedFit {
        let lookup = |c: &str| -> Option<&[f64]> {
            match c {
                "x1" => Some(x1),
                "x2" => Some(x2),
                _ => None,
            }
        };
        let regs = vec![
            ("bias".to_string(), "1".to_string()),
            ("b".to_string(), "x1".to_string()),
            ("c".to_string(), "x2".to_string()),
        ];
        let design = Design::build(&regs, &lookup, z.len()).expect("design");
        // i.i.d. regressors look like white noise to the noise-floor rule, which reads the time
        // structure of sampled flight data: off here
        let opts = IdentifyOptions {
            min_excitation_snr: 0.0,
            ..IdentifyOptions::default()
        };
        fit_bins(&design, z, alpha, man, &opts).expect("fits")
    }

    #[test]
    fn recovers_alpha_dependent_parameters_bin_by_bin() {
        let (alpha, x1, x2, z, man) = truth_data(40_000, 1);
        let fit = fit_truth(&alpha, &x1, &x2, &z, &man);
        assert!(fit.bins.len() > 40, "{} bins", fit.bins.len());
        let mut inside = 0;
        let mut total = 0;
        for bin in &fit.bins {
            let a = 0.5 * (bin.alpha_lo + bin.alpha_hi);
            let truth = [0.002, 0.01 * (a - 12.0).max(0.0), -0.03];
            #[allow(clippy::needless_range_loop)]
            for j in 0..3 {
                assert!(bin.identifiable[j], "{:?}", bin.notes);
                total += 1;
                // within-bin variation of b(α) is tiny against the 0.2 deg bin width
                if (bin.params[j] - truth[j]).abs() < 3.0 * bin.std_err[j] + 0.01 * 0.1 {
                    inside += 1;
                }
            }
        }
        assert!(inside as f64 >= 0.97 * total as f64, "{inside}/{total}");
        // c is constant: tiny scatter; b varies smoothly
        assert!(fit.consistency[2].scatter < 0.1, "{:?}", fit.consistency[2]);
        let sm = smooth_parameters(&fit, &SmoothOptions::default()).expect("smooths");
        let b = &sm[1];
        for (a, v) in b.alpha_deg.iter().zip(&b.values) {
            let want = 0.01 * (a - 12.0).max(0.0);
            assert!((v - want).abs() < 0.006, "alpha {a}: {v} vs {want}");
        }
    }

    #[test]
    fn noise_floor_reads_white_noise_under_a_slow_signal() {
        // x = 4 sin(0.3 t) + N(0, 0.3²) at 50 Hz, 20 maneuvers: the floor is the noise's 0.3
        // (the sine's second differences are 4·0.3²·0.02² ≈ 1.4e-4); a constant column reads 0
        let (n, dt) = (20_000, 0.02);
        let mut rng = crate::sim::rng::Stream::new(11, 1);
        let x: Vec<f64> = (0..n)
            .map(|i| 4.0 * (0.3 * i as f64 * dt).sin() + 0.3 * rng.normal())
            .collect();
        let man: Vec<u64> = (0..n).map(|i| (i / 1000) as u64).collect();
        let lookup = |c: &str| -> Option<&[f64]> { (c == "x").then_some(x.as_slice()) };
        let regs = vec![
            ("b".to_string(), "1".to_string()),
            ("a".to_string(), "x".to_string()),
        ];
        let d = Design::build(&regs, &lookup, n).expect("design");
        let f = noise_floor(&d, &man);
        assert_eq!(f[0], 0.0);
        assert!((f[1] - 0.3).abs() < 0.015, "{}", f[1]);
        // a jump between maneuvers is not a second difference: one maneuver at +100
        let y: Vec<f64> = (0..n)
            .map(|i| x[i] + if man[i] % 2 == 1 { 100.0 } else { 0.0 })
            .collect();
        let lookup = |c: &str| -> Option<&[f64]> { (c == "x").then_some(y.as_slice()) };
        let d = Design::build(&regs, &lookup, n).expect("design");
        assert!((noise_floor(&d, &man)[1] - 0.3).abs() < 0.015);
    }

    #[test]
    fn a_regressor_quiet_everywhere_is_low_excitation_by_its_noise_floor() {
        // sampled data: x1 a slow manoeuvre, x2 a control held at 0.5 read through a sensor
        // with 0.01 of white noise at every alpha. x2's spread in a bin is its spread over the
        // flap (the relative rule passes it) and its noise floor (rule 2 does not)
        let n = 20_000;
        let mut rng = crate::sim::rng::Stream::new(5, 1);
        let (mut alpha, mut x1, mut x2, mut z, mut man) = (vec![], vec![], vec![], vec![], vec![]);
        for i in 0..n {
            let t = i as f64 * 0.02;
            // each 8 s maneuver sweeps alpha from 5 to 20 deg and back
            let ph = 2.0 * std::f64::consts::PI * (i % 400) as f64 / 400.0;
            let a = 5.0 + 15.0 * (0.5 - 0.5 * ph.cos());
            let u1 = (1.3 * t).sin() + 0.01 * rng.normal();
            let u2 = 0.5 + 0.01 * rng.normal();
            z.push(0.002 + 0.01 * (a - 12.0).max(0.0) * u1 - 0.03 * u2 + 0.001 * rng.normal());
            alpha.push(a);
            x1.push(u1);
            x2.push(u2);
            man.push((i / 400) as u64);
        }
        let lookup = |c: &str| -> Option<&[f64]> {
            match c {
                "x1" => Some(&x1),
                "x2" => Some(&x2),
                _ => None,
            }
        };
        let regs = vec![
            ("bias".to_string(), "1".to_string()),
            ("b".to_string(), "x1".to_string()),
            ("c".to_string(), "x2".to_string()),
        ];
        let design = Design::build(&regs, &lookup, n).expect("design");
        let fit = fit_bins(&design, &z, &alpha, &man, &IdentifyOptions::default()).expect("fit");
        let mut fitted = 0;
        for bin in fit.bins.iter().filter(|b| b.note.is_empty()) {
            fitted += 1;
            assert!(
                bin.excitation[2] > 0.5,
                "relative rule: {}",
                bin.excitation[2]
            );
            assert!(bin.excitation_snr[2] < 1.5, "{}", bin.excitation_snr[2]);
            assert!(!bin.identifiable[2]);
            assert!(bin.notes[2].contains("noise floor"), "{}", bin.notes[2]);
            // x1 moves: far above its floor, identified
            assert!(bin.excitation_snr[1] > 10.0, "{}", bin.excitation_snr[1]);
            assert!(bin.identifiable[1], "{}", bin.notes[1]);
        }
        assert!(fitted > 10, "{fitted}");
    }

    #[test]
    fn low_excitation_and_sparse_bins_are_marked() {
        let (alpha, x1, mut x2, z, man) = truth_data(20_000, 2);
        // x2 barely moves above 15 deg: the pilot held the control still
        for (i, a) in alpha.iter().enumerate() {
            if *a > 15.0 {
                x2[i] *= 1e-4;
            }
        }
        let fit = fit_truth(&alpha, &x1, &x2, &z, &man);
        for bin in &fit.bins {
            if bin.alpha_lo > 15.05 {
                assert!(!bin.identifiable[2], "{:?}", bin);
                assert!(bin.notes[2].contains("low excitation"), "{}", bin.notes[2]);
            }
        }
    }

    #[test]
    fn a_design_built_in_used_buffers_is_the_fresh_one() {
        let n = 500;
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.11).cos() - 0.2).collect();
        let lookup = |c: &str| -> Option<&[f64]> {
            match c {
                "x" => Some(&x),
                "y" => Some(&y),
                _ => None,
            }
        };
        let regs: Vec<(String, String)> = [
            ("bias", "1"),
            ("x", "x"),
            ("xy", "x * y"),
            ("ny", "-(y - 0.5) / x"),
            ("db", "deadband(x, 0.3)"),
            ("pw", "y^3 + 2 * x"),
        ]
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
        let fresh = Design::build(&regs, &lookup, n).expect("design");
        // buffers that held a wider design of other values, then a narrower one
        let mut buffers = DesignBuffers::default();
        let wide: Vec<(String, String)> = (0..9)
            .map(|j| (format!("c{j}"), format!("y * {j}")))
            .collect();
        let d = Design::build_into(&wide, &lookup, n, &mut buffers).expect("design");
        buffers.recycle(d);
        let d = Design::build_into(&regs[..2], &lookup, n, &mut buffers).expect("design");
        buffers.recycle(d);
        let again = Design::build_into(&regs, &lookup, n, &mut buffers).expect("design");
        assert_eq!(again.names, fresh.names);
        assert_eq!(again.nrows, fresh.nrows);
        assert_eq!(again.values.len(), fresh.values.len());
        for (a, b) in again.values.iter().zip(&fresh.values) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
        // and each column is the expression evaluated point by point
        for (j, e) in fresh.exprs.iter().enumerate() {
            for i in 0..n {
                let v = e.eval_point(&|c: &str| lookup(c).map(|col| col[i]));
                assert_eq!(v.to_bits(), fresh.values[i * regs.len() + j].to_bits());
            }
        }
    }

    #[test]
    fn errors_name_the_regressor() {
        let lookup = |_: &str| -> Option<&[f64]> { None };
        let e = Design::build(&[("dCl_p".into(), "phat".into())], &lookup, 3)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("parameter 'dCl_p'") && e.contains("'phat'"),
            "{e}"
        );
    }
}
