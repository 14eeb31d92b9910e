//! Per-event nuisance columns of the roll-off moment and the refinement of each event's
//! centre, for the gap diagnosis (`aerodelta.diagnosis.stochastic`: its docstrings give the
//! reasoning, this module the numerics).
//!
//! A roll-off (thesis Section 3.4.3) is a transient C_l spike whose moment is a Gaussian in
//! alpha of width σ (thesis Figure 3.14), `g = exp(−u²/2)`, `u = (α_e − α_c)/σ`, with a random
//! amplitude per event. The diagnosis profiles each detected event's moment out of its
//! maneuver with two columns, `g` and `u·g` (the derivative in the centre, which absorbs a
//! small error in it), evaluated at the alpha `α_e` at which the runtime model
//! ([`crate::rolloff`]) evaluates its Gaussian along the record:
//! - zero before the draw: the last armed upward crossing of the re-arm alpha before the
//!   spike's peak ([`draw_index`]; the model is armed at first and re-armed only once alpha
//!   falls the hysteresis below the re-arm alpha);
//! - the flown alpha until the stall has reached the centre, then the alpha travelled since,
//!   `2·α_top − α` with `α_top` the highest alpha since the draw ([`travelled_alpha`]), so the
//!   spike is not met a second time on the way down;
//! - zero once that alpha is [`SPENT_WIDTHS`] widths past the centre, and after.
//!
//! The columns are therefore non-zero on one run of each maneuver's rows, from the draw until
//! the spike is spent ([`Spike`]). [`event_columns`] lays them out as the diagnosis's sparse
//! columns; [`refine_centres`] chooses each event's centre among its peak alpha and a few
//! shifts above it ([`CENTRE_SHIFTS_DEG`]) by the share of the residual its two columns
//! explain (a stall that turns back before the centre meets only the rising flank, whose peak
//! lies below the centre).
//!
//! This mirrors the numpy implementation it replaced, row for row. Two numerical differences:
//! the two-column least squares ([`explained_by_two`]) is a Householder QR instead of numpy's
//! SVD-based `lstsq`, with the same rank rule (the same centre unless two trials explain the
//! residual equally to within rounding); and `exp` is the C library's, which numpy's
//! vectorised one differs from by one ulp on a few per cent of arguments.

use crate::error::{AeroError, Result};
use crate::rolloff::{RollOffConfig, SPENT_WIDTHS};

/// Centres tried above a spike's peak alpha, deg ([`refine_centres`]).
pub const CENTRE_SHIFTS_DEG: [f64; 7] = [0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5];

/// Fewest rows on which a trial centre's columns must be non-zero to be judged.
pub const MIN_ROWS: usize = 3;

/// The runtime model's parameters the columns follow (a subset of [`RollOffConfig`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpikeShape {
    /// Width σ of the Gaussian in alpha, deg (thesis Figure 3.14: 0.5).
    pub width_deg: f64,
    /// Alpha whose armed upward crossing makes a draw, deg (thesis: 15).
    pub rearm_alpha_deg: f64,
    /// Alpha must fall this far below the re-arm alpha before a crossing draws again, deg.
    pub rearm_hysteresis_deg: f64,
}

impl Default for SpikeShape {
    /// The runtime model's defaults ([`RollOffConfig::default`]).
    fn default() -> Self {
        SpikeShape::from_config(&RollOffConfig::default())
    }
}

impl SpikeShape {
    /// The shape of a runtime model's configuration.
    pub fn from_config(c: &RollOffConfig) -> Self {
        SpikeShape {
            width_deg: c.width_deg,
            rearm_alpha_deg: c.rearm_alpha_deg,
            rearm_hysteresis_deg: c.rearm_hysteresis_deg,
        }
    }

    /// The default shape with width `width_deg`.
    pub fn with_width(width_deg: f64) -> Self {
        SpikeShape {
            width_deg,
            ..SpikeShape::default()
        }
    }

    /// Check the values: width finite and positive, re-arm alpha finite, hysteresis finite and
    /// not negative.
    pub fn check(&self) -> Result<()> {
        if !(self.width_deg.is_finite() && self.width_deg > 0.0) {
            return Err(AeroError::invalid(
                "roll-off width sigma_deg",
                format!("is {}; it must be finite and positive", self.width_deg),
            ));
        }
        let hysteresis_ok =
            self.rearm_hysteresis_deg.is_finite() && self.rearm_hysteresis_deg >= 0.0;
        if !self.rearm_alpha_deg.is_finite() || !hysteresis_ok {
            return Err(AeroError::invalid(
                "roll-off re-arm",
                "the re-arm alpha must be finite and the hysteresis finite and >= 0",
            ));
        }
        Ok(())
    }
}

/// The records as the diagnosis lays them out: per row the alpha and time, and per maneuver
/// its rows in time order, `rows[bounds[m]..bounds[m + 1]]`.
#[derive(Debug, Clone, Copy)]
pub struct Records<'a> {
    /// Angle of attack per row, deg.
    pub alpha_deg: &'a [f64],
    /// Time per row, s.
    pub t: &'a [f64],
    /// Row indices, maneuver after maneuver, each maneuver's in time order.
    pub rows: &'a [usize],
    /// Where each maneuver's rows start in `rows`, then the end (`M + 1` entries).
    pub bounds: &'a [usize],
}

impl Records<'_> {
    /// Maneuvers `M`.
    pub fn n_maneuvers(&self) -> usize {
        self.bounds.len().saturating_sub(1)
    }

    /// The rows of maneuver `m`, in time order (after [`Records::check`]).
    pub fn rows_of(&self, m: usize) -> &[usize] {
        &self.rows[self.bounds[m]..self.bounds[m + 1]]
    }

    /// Check the layout: equal lengths of alpha and t, `bounds` non-decreasing within `rows`,
    /// every row index in range.
    pub fn check(&self) -> Result<()> {
        let n = self.alpha_deg.len();
        if self.t.len() != n {
            return Err(AeroError::invalid(
                "t",
                format!("has {} rows, alpha_deg {n}", self.t.len()),
            ));
        }
        if self.bounds.is_empty() {
            return Err(AeroError::invalid(
                "maneuver bounds",
                "is empty; give M + 1 entries",
            ));
        }
        if self.bounds.windows(2).any(|w| w[0] > w[1])
            || self.bounds.last().is_some_and(|&b| b > self.rows.len())
        {
            return Err(AeroError::invalid(
                "maneuver bounds",
                format!(
                    "must be non-decreasing offsets into the {} rows",
                    self.rows.len()
                ),
            ));
        }
        if let Some(&r) = self.rows.iter().find(|&&r| r >= n) {
            return Err(AeroError::invalid(
                "maneuver rows",
                format!("row {r} of {n}"),
            ));
        }
        Ok(())
    }
}

/// One detected event: its maneuver (an index of [`Records`]), its centre and the time of its
/// peak.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Event {
    /// Maneuver index.
    pub maneuver: usize,
    /// Centre alpha of the Gaussian, deg.
    pub centre_deg: f64,
    /// Time of the spike's peak, s (the draw is the last one before it).
    pub t_peak: f64,
}

/// Index of the sample at which the runtime model made the draw met at time `t_peak`, along
/// one maneuver's alpha and time (time order): the last armed upward crossing of the re-arm
/// alpha (`alpha[i − 1] < rearm <= alpha[i]`) at or before `t_peak`. The model is armed at
/// first; a crossing that draws disarms it, and it is re-armed by a sample below
/// `rearm − hysteresis` between that crossing and a later one. 0 when there is no such
/// crossing (the record starts above the re-arm alpha).
pub fn draw_index(alpha: &[f64], t: &[f64], t_peak: f64, shape: &SpikeShape) -> usize {
    let rearm = shape.rearm_alpha_deg;
    let low = rearm - shape.rearm_hysteresis_deg;
    let (mut start, mut armed, mut low_since) = (0, true, false);
    for (i, (&a, &ti)) in alpha.iter().zip(t).enumerate() {
        if i > 0 && a >= rearm && alpha[i - 1] < rearm {
            if ti > t_peak {
                break;
            }
            if !armed && low_since {
                armed = true;
            }
            if armed {
                (start, armed, low_since) = (i, false, false);
            }
        }
        low_since |= a < low;
    }
    start
}

/// The alpha at which the runtime model evaluates its Gaussian along one stall from its draw,
/// deg: `alpha` until the stall has reached `centre` (the highest alpha so far, `top`, is at
/// least `centre`), then the alpha travelled since, `2·top − alpha`.
pub fn travelled_alpha(alpha: &[f64], centre: f64) -> Vec<f64> {
    let mut top = f64::NEG_INFINITY;
    alpha
        .iter()
        .map(|&a| {
            top = top.max(a);
            if top >= centre {
                2.0 * top - a
            } else {
                a
            }
        })
        .collect()
}

/// The two columns of one event along one maneuver, on the run of its rows where they live:
/// rows `start..start + g.len()` of the maneuver (local, time order).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Spike {
    /// First row (local): the draw.
    pub start: usize,
    /// `g = exp(−u²/2)` per row of the run.
    pub g: Vec<f64>,
    /// `u·g` per row of the run.
    pub ug: Vec<f64>,
}

/// The columns of a spike drawn at local row `start` and centred at `centre` deg along one
/// maneuver's alpha (time order): from the draw until the travelled alpha
/// ([`travelled_alpha`]) first reaches `centre + SPENT_WIDTHS·σ` (that row excluded).
pub fn spike(alpha: &[f64], start: usize, centre: f64, shape: &SpikeShape) -> Spike {
    let sigma = shape.width_deg;
    let spent = centre + SPENT_WIDTHS * sigma;
    let eff = travelled_alpha(alpha.get(start..).unwrap_or(&[]), centre);
    let (g, ug) = eff
        .iter()
        .take_while(|&&e| e < spent)
        .map(|&e| {
            let u = (e - centre) / sigma;
            let g = (-0.5 * u * u).exp();
            (g, u * g)
        })
        .unzip();
    Spike { start, g, ug }
}

/// Sum of squared fitted values of the least-squares fit of `y` on the columns `x1`, `x2`
/// (equal lengths `m`), what numpy's `lstsq(rcond=None)` gives: `‖P y‖²`, `P` the projection
/// on the columns' numerical span, whose rank counts the singular values above
/// `ε·max(m, 2)` times the largest.
///
/// Householder QR of `[x1 x2]`, `c = Q'y` (first two entries) and `R` (2 × 2, upper): at full
/// rank `‖c‖²`; at rank 1 `(w·c)²`, `w` the leading left singular vector of `R`; 0 when both
/// columns are zero.
pub fn explained_by_two(x1: &[f64], x2: &[f64], y: &[f64]) -> f64 {
    let m = y.len();
    if m == 0 || x1.len() != m || x2.len() != m {
        return 0.0;
    }
    let (mut a, mut b, mut c) = (x1.to_vec(), x2.to_vec(), y.to_vec());
    let r11 = reflect(&mut a, &mut b, &mut c);
    let (r12, c1) = (b[0], c[0]);
    let (r22, c2) = if m > 1 {
        let r22 = reflect(&mut b[1..], &mut [], &mut c[1..]);
        (r22, c[1])
    } else {
        (0.0, 0.0)
    };
    let (s_min, s_max) = singular_values_upper(r11, r12, r22);
    if s_max == 0.0 {
        return 0.0;
    }
    if s_min > f64::EPSILON * m.max(2) as f64 * s_max {
        return c1 * c1 + c2 * c2;
    }
    let w = leading_left_vector(r11, r12, r22);
    let p = w.0 * c1 + w.1 * c2;
    p * p
}

/// Apply to `x`, `o1` and `o2` the Householder reflection that maps `x` onto its first axis;
/// return the first entry of `x` reflected (`∓‖x‖`, 0 when `x` is zero and left alone).
/// `o1` may be empty (nothing to reflect); `x` is scaled by its largest magnitude first, so
/// neither tiny nor huge entries under- or overflow.
fn reflect(x: &mut [f64], o1: &mut [f64], o2: &mut [f64]) -> f64 {
    let scale = x.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    if scale == 0.0 || !scale.is_finite() {
        return 0.0;
    }
    for v in x.iter_mut() {
        *v /= scale;
    }
    let norm = x.iter().map(|v| v * v).sum::<f64>().sqrt();
    let diag = if x[0] >= 0.0 { -norm } else { norm };
    x[0] -= diag; // v = x − diag·e1; |v_0| = norm + |x_0| keeps v'v away from cancellation
    let vtv: f64 = x.iter().map(|v| v * v).sum();
    for o in [o1, o2] {
        if o.len() != x.len() {
            continue;
        }
        let s = 2.0 * x.iter().zip(o.iter()).map(|(v, w)| v * w).sum::<f64>() / vtv;
        for (w, v) in o.iter_mut().zip(x.iter()) {
            *w -= s * v;
        }
    }
    diag * scale
}

/// Singular values `(min, max)` of the upper-triangular `[[f, g], [0, h]]` (LAPACK `dlas2`:
/// accurate, no overflow).
fn singular_values_upper(f: f64, g: f64, h: f64) -> (f64, f64) {
    let (fa, ga, ha) = (f.abs(), g.abs(), h.abs());
    let (fhmn, fhmx) = (fa.min(ha), fa.max(ha));
    if fhmn == 0.0 {
        let smax = if fhmx == 0.0 {
            ga
        } else {
            let (lo, hi) = (fhmx.min(ga), fhmx.max(ga));
            hi * (1.0 + (lo / hi) * (lo / hi)).sqrt()
        };
        (0.0, smax)
    } else if ga < fhmx {
        let as_ = 1.0 + fhmn / fhmx;
        let at = (fhmx - fhmn) / fhmx;
        let au = (ga / fhmx) * (ga / fhmx);
        let c = 2.0 / ((as_ * as_ + au).sqrt() + (at * at + au).sqrt());
        (fhmn * c, fhmx / c)
    } else {
        let au = fhmx / ga;
        if au == 0.0 {
            ((fhmn * fhmx) / ga, ga)
        } else {
            let as_ = 1.0 + fhmn / fhmx;
            let at = (fhmx - fhmn) / fhmx;
            let c = 1.0
                / ((1.0 + (as_ * au) * (as_ * au)).sqrt() + (1.0 + (at * au) * (at * au)).sqrt());
            (2.0 * (fhmn * c) * au, ga / (c + c))
        }
    }
}

/// The left singular vector of the largest singular value of `[[f, g], [0, h]]`: the leading
/// eigenvector `(cos θ, sin θ)`, `θ = ½ atan2(2q, p − s)`, of `R R' = [[p, q], [q, s]]`
/// (entries scaled by the largest first).
fn leading_left_vector(f: f64, g: f64, h: f64) -> (f64, f64) {
    let scale = f.abs().max(g.abs()).max(h.abs());
    let (f, g, h) = (f / scale, g / scale, h / scale);
    let (p, q, s) = (f * f + g * g, g * h, h * h);
    let theta = 0.5 * (2.0 * q).atan2(p - s);
    (theta.cos(), theta.sin())
}

/// One column of the sparse nuisance block: its non-zero rows (global indices) and values.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SparseColumn {
    /// Row indices.
    pub rows: Vec<usize>,
    /// Values at those rows.
    pub values: Vec<f64>,
}

/// Check the events against the records and the values every event's maneuver reads (`alpha`,
/// `t` and, when given, `residual`) for finiteness, naming the first bad one.
fn check_inputs(
    rec: &Records<'_>,
    events: &[Event],
    residual: Option<&[f64]>,
    shape: &SpikeShape,
) -> Result<()> {
    shape.check()?;
    rec.check()?;
    if let Some(r) = residual {
        if r.len() != rec.alpha_deg.len() {
            return Err(AeroError::invalid(
                "residual",
                format!("has {} rows, alpha_deg {}", r.len(), rec.alpha_deg.len()),
            ));
        }
    }
    let n_m = rec.n_maneuvers();
    let mut seen = vec![false; n_m];
    for (i, e) in events.iter().enumerate() {
        if e.maneuver >= n_m {
            return Err(AeroError::invalid(
                format!("roll-off event {i}"),
                format!("maneuver {} of {n_m}", e.maneuver),
            ));
        }
        if !e.centre_deg.is_finite() || !e.t_peak.is_finite() {
            return Err(AeroError::invalid(
                format!("roll-off event {i}"),
                format!(
                    "centre {} deg, peak time {} s: both must be finite",
                    e.centre_deg, e.t_peak
                ),
            ));
        }
        if std::mem::replace(&mut seen[e.maneuver], true) {
            continue;
        }
        for &r in rec.rows_of(e.maneuver) {
            let bad = |what: &str, v: f64| {
                AeroError::invalid(
                    format!("{what}, row {r} (maneuver {})", e.maneuver),
                    format!("is {v}; the rows of a maneuver with a roll-off event must be finite"),
                )
            };
            if !rec.alpha_deg[r].is_finite() {
                return Err(bad("alpha_deg", rec.alpha_deg[r]));
            }
            if !rec.t[r].is_finite() {
                return Err(bad("t", rec.t[r]));
            }
            if let Some(res) = residual.filter(|res| !res[r].is_finite()) {
                return Err(bad("residual", res[r]));
            }
        }
    }
    Ok(())
}

/// Gather `values` at `rows`.
fn gather(values: &[f64], rows: &[usize]) -> Vec<f64> {
    rows.iter().map(|&r| values[r]).collect()
}

/// Map `f` over `items` in order, in parallel with the `parallel` feature (each item's work is
/// independent, so the result is the same with any number of threads).
fn map_ordered<T: Sync, U: Send>(items: &[T], f: impl Fn(&T) -> U + Sync + Send) -> Vec<U> {
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        items.par_iter().map(f).collect()
    }
    #[cfg(not(feature = "parallel"))]
    {
        items.iter().map(f).collect()
    }
}

/// The per-event nuisance columns of the roll-off moment (module doc), `2K` of them for `K`
/// the most events of one maneuver: a maneuver's events sorted by centre (ties in the given
/// order), its `j`-th event has `g` in column `2j` and `u·g` in column `2j + 1`. A column
/// holds its maneuvers' non-zero entries, maneuver after maneuver in the order of their first
/// event in `events`, each in time order (`aerodelta.diagnosis.stochastic.event_columns`).
///
/// # Errors
/// [`AeroError::InvalidInput`] for a malformed layout (see [`Records::check`]), an event whose
/// maneuver is out of range or whose centre or peak time is not finite, a non-finite alpha or
/// time on an event's maneuver, or an invalid shape.
pub fn event_columns(
    rec: &Records<'_>,
    events: &[Event],
    shape: &SpikeShape,
) -> Result<Vec<SparseColumn>> {
    check_inputs(rec, events, None, shape)?;
    // maneuvers in the order of their first event, each with its events sorted by centre
    let mut order: Vec<usize> = Vec::new();
    let mut per: Vec<Vec<Event>> = vec![Vec::new(); rec.n_maneuvers()];
    for e in events {
        if per[e.maneuver].is_empty() {
            order.push(e.maneuver);
        }
        per[e.maneuver].push(*e);
    }
    let mut tasks: Vec<(usize, usize, Event)> = Vec::with_capacity(events.len());
    for &m in &order {
        // stable, equal centres in the given order (the centres are finite: checked)
        per[m].sort_by(|a, b| {
            a.centre_deg
                .partial_cmp(&b.centre_deg)
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        tasks.extend(per[m].iter().enumerate().map(|(j, e)| (m, j, *e)));
    }
    let k = order.iter().map(|&m| per[m].len()).max().unwrap_or(0);
    let spikes = map_ordered(&tasks, |&(m, _, e)| {
        let rows = rec.rows_of(m);
        let (a, t) = (gather(rec.alpha_deg, rows), gather(rec.t, rows));
        let start = draw_index(&a, &t, e.t_peak, shape);
        spike(&a, start, e.centre_deg, shape)
    });
    let mut cols = vec![SparseColumn::default(); 2 * k];
    for (&(m, j, _), s) in tasks.iter().zip(&spikes) {
        let rows = &rec.rows_of(m)[s.start..];
        for (c, vals) in [(2 * j, &s.g), (2 * j + 1, &s.ug)] {
            for (&r, &v) in rows.iter().zip(vals.iter()) {
                if v != 0.0 {
                    cols[c].rows.push(r);
                    cols[c].values.push(v);
                }
            }
        }
    }
    Ok(cols)
}

/// Each event's centre chosen among `centre + shift` for the `shifts` (deg, tried in order;
/// [`CENTRE_SHIFTS_DEG`] in the diagnosis) as the one whose two columns explain the most of
/// `residual` on its maneuver ([`explained_by_two`] on the rows where either column is
/// non-zero; a trial with fewer than [`MIN_ROWS`] such rows is not judged, a later trial must
/// explain strictly more to be chosen, and the event keeps its centre when no trial is judged).
/// The draw is the same for every trial ([`draw_index`] at the event's peak time).
/// (`aerodelta.diagnosis.stochastic.refine_centres`.)
///
/// # Errors
/// As [`event_columns`], and for a residual of the wrong length or not finite on an event's
/// maneuver, or a non-finite shift.
pub fn refine_centres(
    rec: &Records<'_>,
    residual: &[f64],
    events: &[Event],
    shifts: &[f64],
    shape: &SpikeShape,
) -> Result<Vec<f64>> {
    check_inputs(rec, events, Some(residual), shape)?;
    if let Some(s) = shifts.iter().find(|s| !s.is_finite()) {
        return Err(AeroError::invalid(
            "centre shifts",
            format!("{s} is not finite"),
        ));
    }
    Ok(map_ordered(events, |e| {
        let rows = rec.rows_of(e.maneuver);
        let (a, t) = (gather(rec.alpha_deg, rows), gather(rec.t, rows));
        let start = draw_index(&a, &t, e.t_peak, shape);
        let r = &gather(residual, rows)[start.min(rows.len())..];
        let (mut best, mut best_c) = (-1.0, e.centre_deg);
        let (mut x1, mut x2, mut y) = (Vec::new(), Vec::new(), Vec::new());
        for &dc in shifts {
            let centre = e.centre_deg + dc;
            let s = spike(&a, start, centre, shape);
            x1.clear();
            x2.clear();
            y.clear();
            for ((&g, &ug), &ri) in s.g.iter().zip(&s.ug).zip(r) {
                if g != 0.0 || ug != 0.0 {
                    x1.push(g);
                    x2.push(ug);
                    y.push(ri);
                }
            }
            if y.len() < MIN_ROWS {
                continue;
            }
            let explained = explained_by_two(&x1, &x2, &y);
            if explained > best {
                (best, best_c) = (explained, centre);
            }
        }
        best_c
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rolloff::RollOff;
    use crate::sim::rng::Stream;

    const DT: f64 = 0.02;

    /// Alpha through the knots `(alpha, duration to reach it from the previous knot, s)`,
    /// starting at `a0`, one sample per `DT`, with a small wiggle (stick noise).
    fn profile(a0: f64, knots: &[(f64, f64)], wiggle: f64) -> Vec<f64> {
        let mut out = vec![a0];
        let mut prev = a0;
        for &(a, dur) in knots {
            let n = (dur / DT).round() as usize;
            for i in 1..=n {
                out.push(prev + (a - prev) * i as f64 / n as f64);
            }
            prev = a;
        }
        out.iter()
            .enumerate()
            .map(|(i, a)| a + wiggle * (1.7 * i as f64 * DT).sin())
            .collect()
    }

    fn times(n: usize, t0: f64) -> Vec<f64> {
        (0..n).map(|i| t0 + i as f64 * DT).collect()
    }

    // ---- the dense numpy-style reference: full-length columns, cumulative maxima, SVD lstsq

    fn ref_draw_index(a: &[f64], t: &[f64], tp: f64) -> usize {
        let up: Vec<usize> = (1..a.len())
            .filter(|&i| a[i] >= 15.0 && a[i - 1] < 15.0)
            .collect();
        let low: Vec<bool> = a.iter().map(|&x| x < 13.0).collect();
        let (mut start, mut armed, mut prev) = (0, true, 0);
        for i in up {
            if t[i] > tp {
                break;
            }
            if !armed && low[prev..i].iter().any(|&b| b) {
                armed = true;
            }
            if armed {
                (start, armed, prev) = (i, false, i);
            }
        }
        start
    }

    fn cummax(x: &[f64]) -> Vec<f64> {
        let mut m = f64::NEG_INFINITY;
        x.iter()
            .map(|&v| {
                m = m.max(v);
                m
            })
            .collect()
    }

    fn ref_columns(a: &[f64], start: usize, ac: f64, sigma: f64) -> (Vec<f64>, Vec<f64>) {
        let n = a.len();
        let (mut g, mut ug) = (vec![0.0; n], vec![0.0; n]);
        let seg = &a[start..];
        let top = cummax(seg);
        let eff: Vec<f64> = seg
            .iter()
            .zip(&top)
            .map(|(&x, &tp)| if tp >= ac { 2.0 * tp - x } else { x })
            .collect();
        let spent: Vec<f64> = eff
            .iter()
            .map(|&e| f64::from(u8::from(e >= ac + 4.0 * sigma)))
            .collect();
        let gone = cummax(&spent);
        for i in 0..seg.len() {
            if gone[i] == 0.0 {
                let u = (eff[i] - ac) / sigma;
                g[start + i] = (-0.5 * u * u).exp();
                ug[start + i] = u * g[start + i];
            }
        }
        (g, ug)
    }

    /// numpy's `lstsq(x, y, rcond=None)`, then the sum of squared fitted values: the thin SVD
    /// of the dense `m × 2` matrix (faer), the fitted values `Σ u_k (u_k'y)` over the singular
    /// values above `ε·max(m, 2)` times the largest.
    fn ref_explained(x: &[Vec<f64>; 2], y: &[f64]) -> f64 {
        let m = y.len();
        let a = faer::Mat::from_fn(m, 2, |i, j| x[j][i]);
        let svd = a.thin_svd().unwrap();
        let (u, s) = (svd.U(), svd.S());
        let k_n = m.min(2);
        let smax = (0..k_n).map(|k| s[k]).fold(0.0, f64::max);
        let mut fitted = vec![0.0; m];
        for k in 0..k_n {
            if smax > 0.0 && s[k] > f64::EPSILON * m.max(2) as f64 * smax {
                let c: f64 = (0..m).map(|i| u[(i, k)] * y[i]).sum();
                for (i, f) in fitted.iter_mut().enumerate() {
                    *f += c * u[(i, k)];
                }
            }
        }
        fitted.iter().map(|f| f * f).sum()
    }

    fn ref_refine(a: &[f64], t: &[f64], r: &[f64], ac: f64, tp: f64, sigma: f64) -> f64 {
        let start = ref_draw_index(a, t, tp);
        let (mut best, mut best_c) = (-1.0, ac);
        for dc in CENTRE_SHIFTS_DEG {
            let (g, ug) = ref_columns(a, start, ac + dc, sigma);
            let nz: Vec<usize> = (0..a.len())
                .filter(|&i| g[i] != 0.0 || ug[i] != 0.0)
                .collect();
            if nz.len() < 3 {
                continue;
            }
            let x = [
                nz.iter().map(|&i| g[i]).collect(),
                nz.iter().map(|&i| ug[i]).collect(),
            ];
            let y: Vec<f64> = nz.iter().map(|&i| r[i]).collect();
            let e = ref_explained(&x, &y);
            if e > best {
                (best, best_c) = (e, ac + dc);
            }
        }
        best_c
    }

    /// A frame of several maneuvers, rows interleaved (maneuver m's rows are not contiguous,
    /// and not in time order in the frame), with its layout: per maneuver the alpha profile
    /// and events `(centre, t_peak)`.
    struct Frame {
        alpha: Vec<f64>,
        t: Vec<f64>,
        rows: Vec<usize>,
        bounds: Vec<usize>,
        events: Vec<Event>,
        residual: Vec<f64>,
    }

    fn frame() -> Frame {
        let man: Vec<Vec<f64>> = vec![
            // 0: a stall that passes its centre, then recovers
            profile(10.0, &[(18.6, 4.0), (9.0, 2.0)], 0.05),
            // 1: chatter about 15 deg within the hysteresis, then a stall that turns back at
            //    16.8 deg, before its centre
            profile(
                12.0,
                &[
                    (15.4, 1.0),
                    (14.3, 0.3),
                    (15.3, 0.3),
                    (14.6, 0.2),
                    (16.8, 1.0),
                    (11.0, 1.5),
                ],
                0.02,
            ),
            // 2: two stalls, re-armed between them
            profile(
                10.0,
                &[(17.5, 3.0), (11.0, 1.5), (19.2, 3.0), (10.0, 2.0)],
                0.05,
            ),
            // 3: the record starts above the re-arm alpha
            profile(16.0, &[(18.0, 1.0), (12.0, 1.5)], 0.0),
            // 4: no event
            profile(5.0, &[(12.0, 2.0)], 0.1),
        ];
        let t_of: Vec<Vec<f64>> = man
            .iter()
            .enumerate()
            .map(|(m, a)| times(a.len(), 100.0 * m as f64))
            .collect();
        let at = |m: usize, alpha: f64, from: f64| -> (f64, f64) {
            // the first time maneuver m reaches `alpha` after `from`, and that alpha
            let i = (0..man[m].len())
                .find(|&i| t_of[m][i] >= from && man[m][i] >= alpha)
                .unwrap();
            (man[m][i], t_of[m][i])
        };
        let top = |m: usize, from: f64, to: f64| -> (f64, f64) {
            let mut best = (f64::NEG_INFINITY, 0.0);
            for i in 0..man[m].len() {
                if t_of[m][i] >= from && t_of[m][i] <= to && man[m][i] > best.0 {
                    best = (man[m][i], t_of[m][i]);
                }
            }
            best
        };
        let (a0, t0) = at(0, 17.3, 0.0);
        let (a1, t1) = top(1, 100.0, 200.0);
        let (a2a, t2a) = top(2, 200.0, 206.0);
        let (a2b, t2b) = top(2, 206.0, 300.0);
        let (a3, t3) = top(3, 300.0, 400.0);
        let events = vec![
            // maneuver 2's events given in reverse order of centre; maneuver 1 first
            Event {
                maneuver: 1,
                centre_deg: a1,
                t_peak: t1,
            },
            Event {
                maneuver: 2,
                centre_deg: a2b - 0.6,
                t_peak: t2b,
            },
            Event {
                maneuver: 0,
                centre_deg: a0,
                t_peak: t0,
            },
            Event {
                maneuver: 2,
                centre_deg: a2a - 0.2,
                t_peak: t2a,
            },
            Event {
                maneuver: 3,
                centre_deg: a3,
                t_peak: t3,
            },
        ];
        // interleave the rows: row i of the frame is maneuver (i mod 5)'s next sample while
        // it has one; each maneuver's samples then appear in reverse time order within blocks
        let mut queue: Vec<Vec<usize>> = man.iter().map(|a| (0..a.len()).collect()).collect();
        for q in &mut queue {
            q.reverse();
        }
        let (mut alpha, mut t, mut owner) = (Vec::new(), Vec::new(), Vec::new());
        let mut local = Vec::new();
        let mut m = 0;
        while queue.iter().any(|q| !q.is_empty()) {
            if let Some(i) = queue[m].pop() {
                alpha.push(man[m][i]);
                t.push(t_of[m][i]);
                owner.push(m);
                local.push(i);
            }
            m = (m + 3) % man.len();
        }
        let mut rows = Vec::new();
        let mut bounds = vec![0];
        for m in 0..man.len() {
            let mut r: Vec<usize> = (0..alpha.len()).filter(|&i| owner[i] == m).collect();
            r.sort_by(|&x, &y| t[x].total_cmp(&t[y]));
            rows.extend(r);
            bounds.push(rows.len());
        }
        // a residual: true spikes at centres above some peaks, plus noise
        let mut noise = Stream::new(7, 1);
        let mut residual: Vec<f64> = (0..alpha.len()).map(|_| 2e-4 * noise.normal()).collect();
        for (e, (dc, amp)) in events.iter().zip([
            (0.75, 0.02),
            (0.25, -0.015),
            (0.0, 0.01),
            (0.5, 0.012),
            (0.0, 0.02),
        ]) {
            let r = &rows[bounds[e.maneuver]..bounds[e.maneuver + 1]];
            let a: Vec<f64> = r.iter().map(|&i| alpha[i]).collect();
            let tt: Vec<f64> = r.iter().map(|&i| t[i]).collect();
            let (g, _) = ref_columns(
                &a,
                ref_draw_index(&a, &tt, e.t_peak),
                e.centre_deg + dc,
                0.5,
            );
            for (k, &i) in r.iter().enumerate() {
                residual[i] += amp * g[k];
            }
        }
        let _ = local;
        Frame {
            alpha,
            t,
            rows,
            bounds,
            events,
            residual,
        }
    }

    fn records(f: &Frame) -> Records<'_> {
        Records {
            alpha_deg: &f.alpha,
            t: &f.t,
            rows: &f.rows,
            bounds: &f.bounds,
        }
    }

    #[test]
    fn columns_and_centres_match_the_dense_reference() {
        let f = frame();
        let rec = records(&f);
        let shape = SpikeShape::default();
        assert_eq!(shape.width_deg, 0.5);
        let cols = event_columns(&rec, &f.events, &shape).unwrap();
        // maneuver 2 has the most events (2): four columns
        assert_eq!(cols.len(), 4);
        // the reference layout: maneuvers in the order of their first event, events by centre
        let mut want = vec![SparseColumn::default(); 4];
        for m in [1usize, 2, 0, 3] {
            let r = rec.rows_of(m);
            let a: Vec<f64> = r.iter().map(|&i| f.alpha[i]).collect();
            let tt: Vec<f64> = r.iter().map(|&i| f.t[i]).collect();
            let mut evs: Vec<&Event> = f.events.iter().filter(|e| e.maneuver == m).collect();
            evs.sort_by(|x, y| x.centre_deg.partial_cmp(&y.centre_deg).unwrap());
            for (j, e) in evs.iter().enumerate() {
                let start = ref_draw_index(&a, &tt, e.t_peak);
                let (g, ug) = ref_columns(&a, start, e.centre_deg, 0.5);
                for (c, v) in [(2 * j, &g), (2 * j + 1, &ug)] {
                    for k in 0..v.len() {
                        if v[k] != 0.0 {
                            want[c].rows.push(r[k]);
                            want[c].values.push(v[k]);
                        }
                    }
                }
            }
        }
        assert_eq!(cols, want);
        // maneuver 2's second stall, re-armed, draws again; maneuver 1's chatter does not
        let local = |m: usize| -> (Vec<f64>, Vec<f64>) {
            let r = rec.rows_of(m);
            (
                r.iter().map(|&i| f.alpha[i]).collect(),
                r.iter().map(|&i| f.t[i]).collect(),
            )
        };
        let (a2, t2) = local(2);
        let (d1, d2) = (
            draw_index(&a2, &t2, f.events[3].t_peak, &shape),
            draw_index(&a2, &t2, f.events[1].t_peak, &shape),
        );
        assert!(d1 > 0 && d2 > d1 && a2[d1..d2].iter().any(|&a| a < 13.0));
        let (a1, t1) = local(1);
        let d = draw_index(&a1, &t1, f.events[0].t_peak, &shape);
        let crossings = (1..a1.len())
            .filter(|&i| a1[i] >= 15.0 && a1[i - 1] < 15.0)
            .count();
        assert!(crossings >= 2 && d == (1..a1.len()).find(|&i| a1[i] >= 15.0).unwrap());
        // every event's columns are non-trivial, and maneuver 3's draw is its first row
        assert!(cols.iter().all(|c| c.rows.len() > 10));
        assert!(cols[0].rows.contains(&rec.rows_of(3)[0]));
        let refined =
            refine_centres(&rec, &f.residual, &f.events, &CENTRE_SHIFTS_DEG, &shape).unwrap();
        let mut shifted = 0;
        for (e, &c) in f.events.iter().zip(&refined) {
            let r = rec.rows_of(e.maneuver);
            let a: Vec<f64> = r.iter().map(|&i| f.alpha[i]).collect();
            let tt: Vec<f64> = r.iter().map(|&i| f.t[i]).collect();
            let res: Vec<f64> = r.iter().map(|&i| f.residual[i]).collect();
            assert_eq!(
                c,
                ref_refine(&a, &tt, &res, e.centre_deg, e.t_peak, 0.5),
                "{e:?}"
            );
            shifted += usize::from(c != e.centre_deg);
        }
        // the flank-only stall (maneuver 1) moved its centre above its peak
        assert!(refined[0] > f.events[0].centre_deg, "{refined:?}");
        assert!(shifted >= 2, "{refined:?}");
    }

    #[test]
    fn draw_index_follows_the_armed_crossings() {
        let s = SpikeShape::default();
        let t: Vec<f64> = (0..12).map(f64::from).collect();
        // starts above the re-arm alpha: no crossing, the draw is the first sample
        assert_eq!(draw_index(&[16.0, 17.0, 14.0, 13.5], &t[..4], 10.0, &s), 0);
        // chatter within the hysteresis: the first crossing holds
        let chatter = [14.0, 15.1, 14.2, 15.3, 14.9, 15.8, 17.0, 16.0];
        assert_eq!(draw_index(&chatter, &t[..8], 10.0, &s), 1);
        // recovery below 13 deg re-arms: the second stall's crossing draws again ...
        let two = [14.0, 15.5, 17.0, 12.9, 14.0, 15.0, 16.5, 14.0];
        assert_eq!(draw_index(&two, &t[..8], 10.0, &s), 5);
        // ... but not for a peak before it, and a crossing at the peak time counts
        assert_eq!(draw_index(&two, &t[..8], 4.9, &s), 1);
        assert_eq!(draw_index(&two, &t[..8], 5.0, &s), 5);
        // a dip to exactly 13 deg does not re-arm (below, strictly)
        let not_low = [14.0, 15.5, 13.0, 15.5, 16.0];
        assert_eq!(draw_index(&not_low, &t[..5], 10.0, &s), 1);
        // every case as the reference reads them
        for a in [&chatter[..], &two[..], &not_low[..]] {
            for tp in [0.0, 1.0, 3.0, 4.9, 5.0, 11.0] {
                assert_eq!(
                    draw_index(a, &t[..a.len()], tp, &s),
                    ref_draw_index(a, &t, tp)
                );
            }
        }
        assert_eq!(
            travelled_alpha(&[14.0, 16.0, 17.0, 16.5, 15.0], 16.5),
            [14.0, 16.0, 17.0, 17.5, 19.0]
        );
    }

    /// The columns are the runtime model's spike, `ΔC_l / peak`, along the alpha it flew
    /// (`crate::rolloff::RollOff`, seeded draws): chatter about 15 deg, a stall to 17.5 deg,
    /// recovery below the hysteresis, a stall to 19.5 deg. Compared from each draw to the next
    /// (the runtime then holds another draw), for centres above the crossing alpha (the
    /// runtime's `α_top` starts after the crossing sample, ours at it: the two differ only
    /// when the centre is below the crossing alpha and alpha dips right after it).
    #[test]
    fn columns_are_the_runtime_models_spike() {
        let a = profile(
            11.0,
            &[
                (15.2, 1.0),
                (14.4, 0.3),
                (15.1, 0.3),
                (17.5, 2.0),
                (11.0, 2.0),
                (19.5, 3.0),
                (10.0, 2.0),
            ],
            0.0,
        );
        let t = times(a.len(), 0.0);
        let shape = SpikeShape::default();
        let (mut flank, mut passed) = (0, 0);
        for seed in 0..60 {
            let mut r = RollOff::new(RollOffConfig::default(), 0.0, seed, 0).unwrap();
            let mut ratio = vec![0.0; a.len()];
            let mut draws = Vec::new();
            for i in 0..a.len() {
                if r.update(t[i], a[i]) {
                    draws.push(i);
                }
                let d = r.current();
                if d.peak != 0.0 {
                    ratio[i] = r.delta_cl(a[i]) / d.peak;
                }
            }
            assert_eq!(draws.len(), 2, "one draw per stall");
            for (k, &i0) in draws.iter().enumerate() {
                let d = r.history[k];
                if d.peak == 0.0 || d.center_deg <= a[i0] {
                    continue;
                }
                let end = draws.get(k + 1).copied().unwrap_or(a.len());
                let start = draw_index(&a, &t, t[end - 1], &shape);
                assert_eq!(start, i0);
                assert_eq!(t[start], d.t);
                let s = spike(&a, start, d.center_deg, &shape);
                for (i, &want) in ratio.iter().enumerate().take(end).skip(i0) {
                    let ours = s.g.get(i - start).copied().unwrap_or(0.0);
                    assert!(
                        (ours - want).abs() <= 1e-12,
                        "seed {seed}, row {i}: {ours} vs {want}"
                    );
                }
                let top = a[i0..end].iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
                if top < d.center_deg {
                    flank += 1;
                } else {
                    passed += 1;
                }
            }
        }
        assert!(
            flank >= 5 && passed >= 5,
            "flank-only {flank}, passed {passed}"
        );
    }

    /// A stall that turns back at 17.2 deg, before the centre 17.95 deg of its roll-off: the
    /// spike is `A exp(−½((α − α_c)/σ)²)` from the draw on (the travelled alpha never leaves
    /// the flown one), peaks at the top, and the search finds its centre 0.75 deg above the
    /// peak, where the two columns explain all of it. A second maneuver's stall passes its
    /// centre: the search stays at the peak.
    #[test]
    fn refinement_finds_the_centre_of_a_known_spike() {
        let a0 = profile(10.0, &[(17.2, 3.6), (10.0, 3.0)], 0.0);
        let a1 = profile(10.0, &[(18.5, 4.0), (10.0, 3.0)], 0.0);
        let (t0, t1) = (times(a0.len(), 0.0), times(a1.len(), 50.0));
        let n0 = a0.len();
        let alpha: Vec<f64> = a0.iter().chain(&a1).copied().collect();
        let t: Vec<f64> = t0.iter().chain(&t1).copied().collect();
        let rows: Vec<usize> = (0..alpha.len()).collect();
        let bounds = [0, n0, alpha.len()];
        let rec = Records {
            alpha_deg: &alpha,
            t: &t,
            rows: &rows,
            bounds: &bounds,
        };
        let (amp, sigma) = (0.02, 0.5);
        let true_c = 17.2 + 0.75;
        let mut residual = vec![0.0; alpha.len()];
        let cross0 = (1..n0)
            .find(|&i| a0[i] >= 15.0 && a0[i - 1] < 15.0)
            .unwrap();
        for i in cross0..n0 {
            residual[i] = amp * (-0.5 * ((a0[i] - true_c) / sigma).powi(2)).exp();
        }
        // the passing stall: centre 17.5, the alpha travelled once past it, spent 2 deg on
        let c1 = 17.5;
        let cross1 = (1..a1.len())
            .find(|&i| a1[i] >= 15.0 && a1[i - 1] < 15.0)
            .unwrap();
        let mut top = f64::NEG_INFINITY;
        for i in cross1..a1.len() {
            top = top.max(a1[i]);
            let eff = if top >= c1 {
                top + (top - a1[i])
            } else {
                a1[i]
            };
            if eff >= c1 + 2.0 {
                break;
            }
            residual[n0 + i] = -amp * (-0.5 * ((eff - c1) / sigma).powi(2)).exp();
        }
        let i_top = (0..n0).max_by(|&i, &j| a0[i].total_cmp(&a0[j])).unwrap();
        let i_c1 = (0..a1.len()).find(|&i| a1[i] >= c1).unwrap();
        let events = [
            Event {
                maneuver: 0,
                centre_deg: a0[i_top],
                t_peak: t0[i_top],
            },
            Event {
                maneuver: 1,
                centre_deg: c1,
                t_peak: t1[i_c1],
            },
        ];
        assert_eq!(a0[i_top], 17.2);
        let shape = SpikeShape::with_width(sigma);
        let got = refine_centres(&rec, &residual, &events, &CENTRE_SHIFTS_DEG, &shape).unwrap();
        assert_eq!(got, [17.2 + 0.75, c1]);
        // at the true centre the columns explain the whole spike: sum of squares
        let s = spike(&a0, cross0, true_c, &shape);
        let y = &residual[cross0..cross0 + s.g.len()];
        let ss: f64 = residual[..n0].iter().map(|r| r * r).sum();
        assert_eq!(s.g.len(), n0 - cross0);
        assert!((explained_by_two(&s.g, &s.ug, y) / ss - 1.0).abs() < 1e-12);
    }

    #[test]
    fn two_column_least_squares_matches_a_dense_svd() {
        let mut rng = Stream::new(3, 0);
        let check = |x1: &[f64], x2: &[f64], y: &[f64], tol: f64| {
            let want = ref_explained(&[x1.to_vec(), x2.to_vec()], y);
            let got = explained_by_two(x1, x2, y);
            assert!(
                (got - want).abs() <= tol * want.max(1e-300),
                "m {}: {got} vs {want}",
                y.len()
            );
            got
        };
        for m in [1usize, 2, 3, 7, 50, 400] {
            let x1: Vec<f64> = (0..m).map(|_| rng.normal()).collect();
            let x2: Vec<f64> = (0..m).map(|_| rng.normal()).collect();
            let y: Vec<f64> = (0..m).map(|_| rng.normal()).collect();
            check(&x1, &x2, &y, 1e-12);
            // one column scaled far down or up: numerically rank 1 as for numpy
            for s in [1e-150, 1e150] {
                let x1s: Vec<f64> = x1.iter().map(|v| v * s).collect();
                check(&x1s, &x2, &y, 1e-12);
            }
            // both scaled far down or up: the same span, no under- or overflow
            let full = explained_by_two(&x1, &x2, &y);
            for s in [1e-160, 1e160] {
                let (x1s, x2s): (Vec<f64>, Vec<f64>) =
                    x1.iter().zip(&x2).map(|(a, b)| (a * s, b * s)).unzip();
                assert!((explained_by_two(&x1s, &x2s, &y) - full).abs() <= 1e-12 * full);
            }
            // nearly collinear, still full rank
            let near: Vec<f64> = x1
                .iter()
                .zip(&x2)
                .map(|(a, b)| 3.0 * a + 1e-7 * b)
                .collect();
            check(&x1, &near, &y, 1e-6);
            // exactly collinear and a zero column: rank 1, the projection on x1
            let twice: Vec<f64> = x1.iter().map(|v| 2.0 * v).collect();
            let on_x1 = {
                let xy: f64 = x1.iter().zip(&y).map(|(a, b)| a * b).sum();
                xy * xy / x1.iter().map(|a| a * a).sum::<f64>()
            };
            for x2c in [&twice, &vec![0.0; m]] {
                let got = check(&x1, x2c, &y, 1e-10);
                assert!((got - on_x1).abs() <= 1e-10 * on_x1);
                let got = explained_by_two(x2c, &x1, &y);
                assert!((got - on_x1).abs() <= 1e-10 * on_x1);
            }
            assert_eq!(explained_by_two(&vec![0.0; m], &vec![0.0; m], &y), 0.0);
            // y in the span: all of it explained
            let inside: Vec<f64> = x1.iter().zip(&x2).map(|(a, b)| 0.3 * a - 2.0 * b).collect();
            if m >= 2 {
                let ss: f64 = inside.iter().map(|v| v * v).sum();
                assert!((explained_by_two(&x1, &x2, &inside) / ss - 1.0).abs() < 1e-12);
            }
        }
    }

    #[cfg(feature = "parallel")]
    #[test]
    fn same_bytes_with_any_thread_count() {
        let f = frame();
        let rec = records(&f);
        let shape = SpikeShape::default();
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    let cols = event_columns(&rec, &f.events, &shape).unwrap();
                    let c =
                        refine_centres(&rec, &f.residual, &f.events, &CENTRE_SHIFTS_DEG, &shape)
                            .unwrap();
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    (
                        cols.iter()
                            .map(|c| (c.rows.clone(), bits(&c.values)))
                            .collect::<Vec<_>>(),
                        bits(&c),
                    )
                })
        };
        let one = run(1);
        assert_eq!(one, run(2));
        assert_eq!(one, run(3));
    }

    #[test]
    fn bad_inputs_are_refused_by_name() {
        let f = frame();
        let rec = records(&f);
        let shape = SpikeShape::default();
        let err = |r: Result<Vec<SparseColumn>>| r.unwrap_err().to_string();
        let mut ev = f.events.clone();
        ev[1].maneuver = 9;
        assert!(err(event_columns(&rec, &ev, &shape)).contains("roll-off event 1: maneuver 9 of 5"));
        let mut ev = f.events.clone();
        ev[0].centre_deg = f64::NAN;
        assert!(err(event_columns(&rec, &ev, &shape)).contains("roll-off event 0"));
        assert!(
            err(event_columns(&rec, &f.events, &SpikeShape::with_width(0.0))).contains("sigma_deg")
        );
        // a non-finite alpha on an event's maneuver is refused, elsewhere it is not read
        let mut alpha = f.alpha.clone();
        alpha[rec.rows_of(2)[5]] = f64::NAN;
        alpha[rec.rows_of(4)[5]] = f64::NAN;
        let bad = Records {
            alpha_deg: &alpha,
            ..rec
        };
        assert!(err(event_columns(&bad, &f.events, &shape)).contains("alpha_deg, row"));
        assert!(event_columns(&bad, &f.events[..1], &shape).is_ok());
        let bounds = [0, 10, f.rows.len() + 1];
        let bad = Records {
            bounds: &bounds,
            ..rec
        };
        assert!(err(event_columns(&bad, &[], &shape)).contains("maneuver bounds"));
        let rows = vec![f.alpha.len(); 3];
        let bad = Records {
            rows: &rows,
            bounds: &[0, 3],
            ..rec
        };
        assert!(err(event_columns(&bad, &[], &shape)).contains("maneuver rows"));
        let short = &f.residual[1..];
        let e = refine_centres(&rec, short, &f.events, &CENTRE_SHIFTS_DEG, &shape).unwrap_err();
        assert!(e.to_string().starts_with("residual"), "{e}");
        let mut res = f.residual.clone();
        res[rec.rows_of(0)[0]] = f64::INFINITY;
        let e = refine_centres(&rec, &res, &f.events, &CENTRE_SHIFTS_DEG, &shape).unwrap_err();
        assert!(e.to_string().starts_with("residual, row"), "{e}");
        let e = refine_centres(&rec, &f.residual, &f.events, &[0.0, f64::NAN], &shape).unwrap_err();
        assert_eq!(e.kind(), crate::ErrorKind::InvalidInput);
        // no events: no columns, no centres
        assert!(event_columns(&rec, &[], &shape).unwrap().is_empty());
        assert!(
            refine_centres(&rec, &f.residual, &[], &CENTRE_SHIFTS_DEG, &shape)
                .unwrap()
                .is_empty()
        );
    }
}
