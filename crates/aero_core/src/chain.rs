//! Measurement-chain calibration of the qualified model (Python
//! `aerodelta.fit.calibrate_chain`, `FitConfig.chain_calibration`).
//!
//! On the samples where the extended model is the qualified one (alpha below the
//! flap's `alpha_l`), the error `z = C_meas − C_qual` is regressed on
//! `[1, dC_qual/dt, d²C_qual/dt², Δ-structure regressors]` by the engine's least
//! squares ([`crate::lsq::ols_clustered`], CR2 errors clustered by maneuver). The
//! slopes of the two derivatives are the chain's time skew τ (s) and second-order
//! smoothing κ (s²): a measured coefficient that reads like the model at `t + τ`
//! is `C + τ Ċ + (τ²/2) C̈ + …`, and a central difference of rates sampled every
//! Δt has the trapezoid response ¼, ½, ¼, i.e. `C + (Δt²/4) C̈` (Morelli & Klein,
//! *Aircraft System Identification*, 2nd ed., §5.4 and §9.6 on time skews and
//! numerical differentiation). The calibrated model `C_qual + τ Ċ_qual + κ C̈_qual`
//! is returned for every sample.

use std::collections::HashMap;

use crate::error::{AeroError, ErrorKind, Result, ResultExt};
use crate::lsq::{ols_clustered, OlsOptions};
use crate::regressor::Expr;
use crate::rolloff_detect::median;

/// Three-point difference weights on sample times ([`time_derivatives`]).
#[derive(Debug, Clone)]
pub struct Stencil {
    /// Per interior sample `i` (index `i − 1`): both neighbours are in the same
    /// maneuver, with positive spacings no larger than 1.5 × the median step.
    ok: Vec<bool>,
    /// Spacing to the previous sample, s.
    hm: Vec<f64>,
    /// Spacing to the next sample, s.
    hp: Vec<f64>,
}

impl Stencil {
    /// The stencil of sample times `t` (s; rows in time order within each maneuver's
    /// contiguous samples) and per-row maneuver codes; `None` when no spacing is usable
    /// (fewer than 3 samples, no finite positive step inside a maneuver).
    pub fn new(t: &[f64], maneuver: &[u64]) -> Option<Stencil> {
        let n = t.len();
        if n < 3 || maneuver.len() != n {
            return None;
        }
        let mut steps: Vec<f64> = (1..n)
            .filter(|&i| maneuver[i] == maneuver[i - 1])
            .map(|i| t[i] - t[i - 1])
            .filter(|s| s.is_finite() && *s > 0.0)
            .collect();
        if steps.is_empty() {
            return None;
        }
        let gap = 1.5 * median(&mut steps);
        let mut ok = Vec::with_capacity(n - 2);
        let mut hm = Vec::with_capacity(n - 2);
        let mut hp = Vec::with_capacity(n - 2);
        for i in 1..n - 1 {
            let (m, p) = (t[i] - t[i - 1], t[i + 1] - t[i]);
            ok.push(
                maneuver[i - 1] == maneuver[i]
                    && maneuver[i + 1] == maneuver[i]
                    && m > 0.0
                    && p > 0.0
                    && m <= gap
                    && p <= gap,
            );
            hm.push(m);
            hp.push(p);
        }
        Some(Stencil { ok, hm, hp })
    }
}

/// First and second time derivatives of `y` by three-point differences on unequally
/// spaced samples: with `s± ` the one-sided slopes, `ẏ = (s₊ h₋ + s₋ h₊)/(h₋ + h₊)` and
/// `ÿ = 2 (s₊ − s₋)/(h₋ + h₊)` (exact for a quadratic). NaN at a maneuver's ends, across
/// a gap and where a neighbour is not finite.
pub fn time_derivatives(y: &[f64], st: Option<&Stencil>) -> (Vec<f64>, Vec<f64>) {
    let n = y.len();
    let mut d1 = vec![f64::NAN; n];
    let mut d2 = vec![f64::NAN; n];
    let Some(st) = st else {
        return (d1, d2);
    };
    if st.ok.len() + 2 != n {
        return (d1, d2);
    }
    for k in 0..n - 2 {
        if !st.ok[k] {
            continue;
        }
        let (hm, hp) = (st.hm[k], st.hp[k]);
        let sp = (y[k + 2] - y[k + 1]) / hp;
        let sm = (y[k + 1] - y[k]) / hm;
        d1[k + 1] = (sp * hm + sm * hp) / (hm + hp);
        d2[k + 1] = 2.0 * (sp - sm) / (hm + hp);
    }
    (d1, d2)
}

/// Settings of [`calibrate`].
#[derive(Debug, Clone, Copy)]
pub struct ChainOptions {
    /// Fewest calibration samples.
    pub min_samples: usize,
    /// Fewest maneuvers among them.
    pub min_maneuvers: usize,
}

/// The chain's estimates for one coefficient.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainEstimate {
    /// Time skew τ, s.
    pub skew_s: f64,
    /// Second-order smoothing κ, s².
    pub curvature_s2: f64,
    /// t statistic of τ (CR2, clustered by maneuver).
    pub t_skew: f64,
    /// t statistic of κ.
    pub t_curvature: f64,
    /// Calibration samples.
    pub samples: usize,
    /// Their maneuvers.
    pub maneuvers: usize,
}

/// What [`calibrate`] found for one coefficient.
#[derive(Debug, Clone, PartialEq)]
pub enum ChainOutcome {
    /// The estimates and the calibrated coefficient, one value per sample (the input value
    /// where a derivative is not defined).
    Calibrated {
        /// τ, κ and their statistics.
        estimate: ChainEstimate,
        /// `C_qual + τ Ċ_qual + κ C̈_qual`.
        corrected: Vec<f64>,
    },
    /// Not calibrated, and why.
    Skipped(String),
}

/// The structures' regressors, each distinct expression evaluated once for all
/// coefficients at the samples that can calibrate ([`calibrate_all`]).
struct Regressors {
    /// Trusted samples with a three-point stencil, ascending.
    rows: Vec<usize>,
    /// Values at `rows` per expression source; expressions reading a channel the data
    /// lack are absent.
    values: HashMap<String, Vec<f64>>,
}

impl Regressors {
    fn new<'a>(
        stencil: Option<&Stencil>,
        trusted: &[bool],
        inputs: &[ChainInput<'_>],
        lookup: &dyn Fn(&str) -> Option<&'a [f64]>,
    ) -> Result<Regressors> {
        let n = trusted.len();
        let rows: Vec<usize> = match stencil {
            Some(st) => (1..n.saturating_sub(1))
                .filter(|&i| trusted[i] && st.ok[i - 1])
                .collect(),
            None => Vec::new(),
        };
        let mut exprs: Vec<(&str, Expr)> = Vec::new();
        for inp in inputs {
            for (name, src) in inp.terms {
                let e =
                    Expr::parse(src).with_context(|| format!("chain calibration term '{name}'"))?;
                if !exprs.iter().any(|(s, _)| *s == src.as_str()) {
                    exprs.push((src, e));
                }
            }
        }
        // the channels, gathered once at the rows
        let mut gathered: HashMap<String, Vec<f64>> = HashMap::new();
        for (_, e) in &exprs {
            for c in e.columns() {
                if let (Some(col), false) = (lookup(&c), gathered.contains_key(&c)) {
                    if col.len() != n {
                        return Err(AeroError::invalid(
                            format!("chain calibration column '{c}'"),
                            format!("has {} rows, expected {n}", col.len()),
                        ));
                    }
                    let v = rows.iter().map(|&i| col[i]).collect();
                    gathered.insert(c, v);
                }
            }
        }
        let at_rows = |c: &str| gathered.get(c).map(Vec::as_slice);
        let mut values = HashMap::new();
        for (src, e) in &exprs {
            if e.columns().iter().all(|c| gathered.contains_key(c)) {
                let v = e
                    .eval_columns(&at_rows, rows.len())
                    .with_context(|| format!("chain calibration regressor '{src}'"))?;
                values.insert((*src).to_string(), v);
            }
        }
        Ok(Regressors { rows, values })
    }
}

/// Calibrate the chain for one coefficient: `q` (qualified) and `meas` (measured) per
/// sample, `terms` the Δ structure's `(name, regressor)` pairs postulated for it. A term
/// reading a channel the data lack, or constant over the calibration samples (the
/// intercept), is left out; samples where a kept term is not finite are dropped.
fn calibrate(
    stencil: Option<&Stencil>,
    maneuver: &[u64],
    regs: &Regressors,
    q: &[f64],
    meas: &[f64],
    terms: &[(String, String)],
    opts: &ChainOptions,
) -> Result<ChainOutcome> {
    let n = q.len();
    for (name, len) in [("maneuver", maneuver.len()), ("meas", meas.len())] {
        if len != n {
            return Err(AeroError::invalid(
                "chain calibration",
                format!("'{name}' has {len} values but the qualified coefficient has {n}"),
            ));
        }
    }
    let (d1, d2) = time_derivatives(q, stencil);
    // positions in `regs.rows` of the samples with a finite error and derivatives
    let mut sel: Vec<usize> = (0..regs.rows.len())
        .filter(|&k| {
            let i = regs.rows[k];
            (meas[i] - q[i]).is_finite() && d1[i].is_finite() && d2[i].is_finite()
        })
        .collect();
    let mut names = vec![
        "intercept".to_string(),
        "dC_qual/dt".to_string(),
        "d2C_qual/dt2".to_string(),
    ];
    // the kept terms' values at `regs.rows`
    let mut cols: Vec<&[f64]> = Vec::new();
    for (name, src) in terms {
        let Some(all) = regs.values.get(src) else {
            continue;
        };
        let (lo, hi) = sel
            .iter()
            .map(|&k| all[k])
            .filter(|x| x.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            });
        if hi - lo > 0.0 {
            names.push(name.clone());
            cols.push(all);
        }
    }
    sel.retain(|&k| cols.iter().all(|c| c[k].is_finite()));
    let rows: Vec<usize> = sel.iter().map(|&k| regs.rows[k]).collect();
    let ids: Vec<u64> = rows.iter().map(|&i| maneuver[i]).collect();
    let groups = {
        let mut g = ids.clone();
        g.sort_unstable();
        g.dedup();
        g.len()
    };
    let m = rows.len();
    // clustered errors need two maneuvers whatever the setting
    let min_maneuvers = opts.min_maneuvers.max(2);
    if m < opts.min_samples || groups < min_maneuvers {
        return Ok(ChainOutcome::Skipped(format!(
            "{m} samples of {groups} maneuvers below alpha_l ({} samples and {min_maneuvers} \
             maneuvers needed)",
            opts.min_samples
        )));
    }
    let k = 3 + cols.len();
    let mut x = vec![0.0; m * k];
    let mut z = Vec::with_capacity(m);
    for (j, (row, &i)) in x.chunks_exact_mut(k).zip(&rows).enumerate() {
        row[0] = 1.0;
        row[1] = d1[i];
        row[2] = d2[i];
        for (v, c) in row[3..].iter_mut().zip(&cols) {
            *v = c[sel[j]];
        }
        z.push(meas[i] - q[i]);
    }
    let ols_opts = OlsOptions {
        colored: false,
        names,
        ..OlsOptions::default()
    };
    let fit = ols_clustered(&x, m, k, &z, &ids, &ols_opts);
    let not_independent = |why: &str| {
        ChainOutcome::Skipped(format!(
            "the qualified model's time derivatives below alpha_l are not independent of the \
             intercept and the structure's regressors{}",
            if why.is_empty() {
                String::new()
            } else {
                format!(": {why}")
            }
        ))
    };
    let fit = match fit {
        Ok(f) => f,
        Err(e) if e.kind() == ErrorKind::TooLittleData => {
            return Ok(dependent(&x, m, k, &z, &ids, &ols_opts)
                .unwrap_or_else(|| not_independent(&e.to_string())))
        }
        Err(e) => return Ok(not_independent(&e.to_string())),
    };
    // the derivatives must not be (near) combinations of the other columns
    if fit.rank < k || fit.collinearity.vif[1..3].iter().any(|&v| v > 1e8) {
        return Ok(not_independent(""));
    }
    let Some(cl) = fit.cluster.as_ref() else {
        return Ok(not_independent("no cluster-robust covariance"));
    };
    let (b1, b2) = (fit.params[1], fit.params[2]);
    let estimate = ChainEstimate {
        skew_s: b1,
        curvature_s2: b2,
        t_skew: b1 / cl.std_err[1],
        t_curvature: b2 / cl.std_err[2],
        samples: m,
        maneuvers: if cl.n_clusters > 0 {
            cl.n_clusters
        } else {
            groups
        },
    };
    let corrected = (0..n)
        .map(|i| {
            let corr = if d1[i].is_finite() && d2[i].is_finite() {
                b1 * d1[i] + b2 * d2[i]
            } else {
                0.0
            };
            q[i] + corr
        })
        .collect();
    Ok(ChainOutcome::Calibrated {
        estimate,
        corrected,
    })
}

/// Why a rank-deficient calibration regression is skipped, naming the columns of its exact
/// dependencies (from the minimum-norm fit); `None` when that fit fails too.
fn dependent(
    x: &[f64],
    m: usize,
    k: usize,
    z: &[f64],
    ids: &[u64],
    opts: &OlsOptions,
) -> Option<ChainOutcome> {
    let mn = OlsOptions {
        min_norm: true,
        ..opts.clone()
    };
    let fit = ols_clustered(x, m, k, z, ids, &mn).ok()?;
    let mut cols: Vec<usize> = fit
        .collinearity
        .dependencies
        .iter()
        .filter(|d| d.condition_index.is_infinite())
        .flat_map(|d| d.columns.iter().copied())
        .collect();
    cols.sort_unstable();
    cols.dedup();
    let list = cols
        .iter()
        .map(|&j| format!("'{}'", fit.names[j]))
        .collect::<Vec<_>>()
        .join(", ");
    Some(ChainOutcome::Skipped(
        if cols.iter().any(|&j| j == 1 || j == 2) {
            format!(
                "the qualified model's time derivatives below alpha_l are linear combinations of \
             the intercept and the structure's regressors (dependent: {list})"
            )
        } else {
            format!(
                "the structure's regressors are linearly dependent below alpha_l (dependent: \
             {list}); combine or remove them, or fit with chain_calibration=False"
            )
        },
    ))
}

/// One coefficient's data for [`calibrate_all`].
#[derive(Debug, Clone, Copy)]
pub struct ChainInput<'a> {
    /// Qualified coefficient per sample.
    pub q: &'a [f64],
    /// Measured coefficient per sample.
    pub meas: &'a [f64],
    /// The Δ structure's `(name, regressor)` pairs (empty under selection).
    pub terms: &'a [(String, String)],
}

/// [`calibrate`] for several coefficients sampled at the same times `t` (s) and
/// maneuvers: one [`Stencil`], the coefficients side by side (in parallel with the
/// `parallel` feature); outcomes in the order of `inputs`.
///
/// # Errors
/// As [`calibrate`], and when `t` and `maneuver` differ in length.
pub fn calibrate_all<'a>(
    t: &[f64],
    maneuver: &[u64],
    trusted: &[bool],
    inputs: &[ChainInput<'_>],
    lookup: &dyn Fn(&str) -> Option<&'a [f64]>,
    opts: &ChainOptions,
) -> Result<Vec<ChainOutcome>> {
    if t.len() != maneuver.len() {
        return Err(AeroError::invalid(
            "chain calibration",
            format!(
                "'t' has {} values but 'maneuver' has {}",
                t.len(),
                maneuver.len()
            ),
        ));
    }
    if trusted.len() != t.len() {
        return Err(AeroError::invalid(
            "chain calibration",
            format!(
                "'trusted' has {} values but 't' has {}",
                trusted.len(),
                t.len()
            ),
        ));
    }
    let stencil = Stencil::new(t, maneuver);
    let regs = Regressors::new(stencil.as_ref(), trusted, inputs, lookup)?;
    let one = |inp: &ChainInput<'_>| {
        calibrate(
            stencil.as_ref(),
            maneuver,
            &regs,
            inp.q,
            inp.meas,
            inp.terms,
            opts,
        )
    };
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        inputs.par_iter().map(one).collect()
    }
    #[cfg(not(feature = "parallel"))]
    {
        inputs.iter().map(one).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three-point differences are exact on a quadratic, whatever the spacing; none at a
    /// maneuver's ends or beside a gap over 1.5 × the median step.
    #[test]
    fn derivatives_exact_on_a_quadratic_and_none_across_ends_or_gaps() {
        let t = [0.0, 0.1, 0.25, 0.3, 0.4, 0.5, 0.6, 2.0, 2.1, 2.2];
        let man = [1, 1, 1, 1, 1, 2, 2, 2, 2, 2];
        let y: Vec<f64> = t.iter().map(|&s| 1.0 - 3.0 * s + 2.5 * s * s).collect();
        let st = Stencil::new(&t, &man);
        let (d1, d2) = time_derivatives(&y, st.as_ref());
        for i in [1, 2, 3, 8] {
            assert!((d1[i] - (-3.0 + 5.0 * t[i])).abs() < 1e-12, "d1 at {i}");
            assert!((d2[i] - 5.0).abs() < 1e-9, "d2 at {i}");
        }
        // ends of maneuvers 1 (rows 0, 4) and 2 (rows 5, 9), and the 1.4 s gap (rows 6, 7)
        for i in [0, 4, 5, 6, 7, 9] {
            assert!(d1[i].is_nan() && d2[i].is_nan(), "row {i}");
        }
    }

    fn frame(n_man: usize, tau: f64) -> (Vec<f64>, Vec<u64>, Vec<f64>, Vec<f64>) {
        let (mut t, mut man, mut q, mut meas) = (vec![], vec![], vec![], vec![]);
        let sig =
            |s: f64, ph: f64| 0.02 * (2.1 * s + ph).sin() + 0.008 * (7.3 * s + 2.0 * ph).sin();
        for m in 0..n_man {
            let ph = 0.7 * m as f64;
            for i in 0..500 {
                let s = 0.02 * i as f64;
                t.push(s);
                man.push(m as u64);
                q.push(sig(s, ph));
                meas.push(sig(s + tau, ph));
            }
        }
        (t, man, q, meas)
    }

    /// A measured coefficient that reads the model at `t + τ` gives τ back (the analytic
    /// reference: `C(t + τ) = C + τ Ċ + τ²/2 C̈ + …`).
    #[test]
    fn recovers_a_time_skew() {
        let (t, man, q, meas) = frame(8, 0.006);
        let trusted = vec![true; t.len()];
        let none = |_: &str| -> Option<&[f64]> { None };
        let input = ChainInput {
            q: &q,
            meas: &meas,
            terms: &[],
        };
        let opts = ChainOptions {
            min_samples: 200,
            min_maneuvers: 5,
        };
        let out = calibrate_all(&t, &man, &trusted, &[input], &none, &opts).unwrap();
        let ChainOutcome::Calibrated {
            estimate,
            corrected,
        } = &out[0]
        else {
            panic!("skipped: {:?}", out[0]);
        };
        assert!((estimate.skew_s / 0.006 - 1.0).abs() < 0.03, "{estimate:?}");
        assert_eq!(estimate.maneuvers, 8);
        assert_eq!(estimate.samples, 8 * 498);
        // a maneuver's first sample keeps the model's value
        assert_eq!(corrected[0], q[0]);
    }

    /// Too few maneuvers, and two structure terms that are one: skipped, naming why.
    #[test]
    fn skipped_with_the_reason() {
        let (t, man, q, meas) = frame(3, 0.004);
        let trusted = vec![true; t.len()];
        let opts = ChainOptions {
            min_samples: 200,
            min_maneuvers: 5,
        };
        let none = |_: &str| -> Option<&[f64]> { None };
        let input = ChainInput {
            q: &q,
            meas: &meas,
            terms: &[],
        };
        let out = calibrate_all(&t, &man, &trusted, &[input], &none, &opts).unwrap();
        assert_eq!(
            out[0],
            ChainOutcome::Skipped(
                "1494 samples of 3 maneuvers below alpha_l (200 samples and 5 maneuvers needed)"
                    .into()
            )
        );
        let da: Vec<f64> = t.iter().map(|s| (3.0 * s).cos()).collect();
        let lookup = |n: &str| (n == "da_deg").then_some(&da[..]);
        let terms = [
            ("a".to_string(), "da_deg".to_string()),
            ("b".to_string(), "2 * da_deg".to_string()),
        ];
        let input = ChainInput {
            q: &q,
            meas: &meas,
            terms: &terms,
        };
        let opts = ChainOptions {
            min_samples: 200,
            min_maneuvers: 2,
        };
        let out = calibrate_all(&t, &man, &trusted, &[input], &lookup, &opts).unwrap();
        let ChainOutcome::Skipped(why) = &out[0] else {
            panic!("calibrated with dependent terms");
        };
        assert!(
            why.contains("structure's regressors are linearly dependent")
                && why.contains("'a', 'b'"),
            "{why}"
        );
    }
}
