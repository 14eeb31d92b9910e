//! Detection of uncommanded roll-off events in flight records (thesis
//! Section 3.4.3, the four-step procedure behind Table 3.2).
//!
//! The thesis procedure, made automatic:
//! 1. look for a sudden, uncommanded spike in rolling moment $C_l$ while the
//!    aileron was quasi-constant up to that time;
//! 2. verify the spike was not caused by another sudden change of state
//!    (rudder, spoilers, or any channel the caller lists);
//! 3. record the angle of attack at its onset;
//! 4. record its peak magnitude and direction.
//!
//! The signal searched is a rolling-moment *residual* $e(t)$: best the
//! residual of a fitted deterministic model ($C_{l,meas} - C_{l,ext}$), else
//! $C_{l,meas} - C_{l,qual}$. Its slowly varying part (a running median over
//! `trend_window_s`) is removed, so a model error that drifts with alpha is
//! not taken for a spike. The noise scale is the robust standard deviation
//! $1.4826\,\mathrm{MAD}$ of the detrended residual below `min_alpha_deg`
//! (pre-stall, where no roll-off is expected), or of the whole record when the
//! pre-stall part is too short. A candidate is a run where
//! $|e| > \max(k\sigma, C_{min})$ while alpha is above `min_alpha_deg`; its
//! onset walks back from the peak to where $|e|$ falls below
//! `onset_fraction` of the peak. The event is *uncommanded* when the aileron
//! and every other listed channel stayed within their allowed change over
//! `quiet_window_s` before the onset, and the aileron did not step (change by more than its
//! allowance within one sample) from `quiet_window_s` before the onset to as long after the
//! spike's end: a step input makes a spike of the measured moment, which is a central
//! difference of the (zero-phase smoothed) rates and cannot follow a moment that jumps
//! between two samples. Sign convention: a positive $C_l$
//! rolls right wing down (Etkin), reported as direction `+1` ("right").

use crate::error::{AeroError, Result};

/// Thresholds of the detector. Defaults follow the thesis's description of
/// the events (sudden, short, at alpha well above the linear range).
#[derive(Debug, Clone, PartialEq)]
pub struct DetectConfig {
    /// Window of the running median removed as the slow trend, s. It must be
    /// at least twice `max_duration_s`, or the median follows the spike.
    pub trend_window_s: f64,
    /// Spike threshold in robust noise standard deviations.
    pub threshold_sigma: f64,
    /// Absolute floor of the spike magnitude (|ΔCl|).
    pub min_magnitude: f64,
    /// Only alpha above this is searched, deg; below it estimates the noise.
    pub min_alpha_deg: f64,
    /// Onset: walking back from the peak, the first sample below this fraction of the peak.
    pub onset_fraction: f64,
    /// The aileron (and other channels) must be quasi-constant over this window before onset, s.
    pub quiet_window_s: f64,
    /// Largest aileron change (max - min, deg) allowed in the quiet window.
    pub max_aileron_change_deg: f64,
    /// A spike lasting longer than this is not a transient roll-off, s.
    pub max_duration_s: f64,
    /// Keep only the first (initial) roll-off of each record, as Table 3.2 does.
    pub first_only: bool,
}

impl Default for DetectConfig {
    fn default() -> Self {
        DetectConfig {
            trend_window_s: 12.0,
            threshold_sigma: 5.0,
            min_magnitude: 0.003,
            min_alpha_deg: 10.0,
            onset_fraction: 0.2,
            // tuned on virtual campaigns (tests/test_rolloff.py): the pilot's
            // aileron works within ~0.5 s of a roll-off's onset at 20 % of its
            // peak, and its stick noise moves the aileron 2-3 deg over 1 s
            quiet_window_s: 0.5,
            max_aileron_change_deg: 4.0,
            max_duration_s: 6.0,
            first_only: true,
        }
    }
}

/// Another channel that must stay quasi-constant before an event (step 2).
#[derive(Debug, Clone, Copy)]
pub struct QuietChannel<'a> {
    /// Channel name, for the rejection reason.
    pub name: &'a str,
    /// Samples, aligned with `t`.
    pub values: &'a [f64],
    /// Largest change (max - min) allowed in the quiet window, in the channel's unit.
    pub max_change: f64,
}

/// One record's signals.
#[derive(Debug, Clone, Copy)]
pub struct RecordSignals<'a> {
    /// Time, s, strictly increasing.
    pub t: &'a [f64],
    /// Angle of attack, deg.
    pub alpha_deg: &'a [f64],
    /// Rolling-moment residual searched for spikes.
    pub cl_residual: &'a [f64],
    /// Aileron, deg.
    pub da_deg: &'a [f64],
}

/// A detected (or rejected) spike.
#[derive(Debug, Clone, PartialEq)]
pub struct RolloffEvent {
    /// Sample index of the onset.
    pub onset_index: usize,
    /// Sample index of the peak.
    pub peak_index: usize,
    /// Onset time, s.
    pub t_onset: f64,
    /// Peak time, s.
    pub t_peak: f64,
    /// Angle of attack at onset, deg.
    pub alpha_onset_deg: f64,
    /// Signed peak of the detrended residual.
    pub peak: f64,
    /// +1 right wing down (positive Cl), -1 left.
    pub direction: i8,
    /// Time the spike stays above the onset fraction, s.
    pub duration_s: f64,
    /// Robust noise standard deviation of the record.
    pub noise_sigma: f64,
    /// Empty for an accepted event; otherwise why it was rejected.
    pub rejected: String,
}

/// The median of each window `[i - half, i + half]` of `x` (clipped at the ends, NaNs left
/// out), by a sorted copy of the window updated one sample at a time: `O(n·w)` memory moves
/// instead of a selection per sample. The values are those of [`median`] on each window.
fn running_median(x: &[f64], half: usize) -> Vec<f64> {
    fn place(win: &[f64], v: f64) -> usize {
        win.partition_point(|w| w.total_cmp(&v).is_lt())
    }
    let n = x.len();
    let mut out = Vec::with_capacity(n);
    let mut win: Vec<f64> = Vec::with_capacity(2 * half + 1);
    for &v in &x[..half.saturating_add(1).min(n)] {
        if !v.is_nan() {
            win.insert(place(&win, v), v);
        }
    }
    for i in 0..n {
        if i > 0 {
            if let Some(&v) = x.get(i.saturating_add(half)) {
                if !v.is_nan() {
                    win.insert(place(&win, v), v);
                }
            }
            if i > half {
                let v = x[i - half - 1];
                if !v.is_nan() {
                    // the first element not below v is v itself (total order: same bits)
                    win.remove(place(&win, v));
                }
            }
        }
        out.push(median_sorted(&win));
    }
    out
}

/// The median of sorted values (NaN when empty), as [`median`] computes it.
fn median_sorted(win: &[f64]) -> f64 {
    let n = win.len();
    if n == 0 {
        return f64::NAN;
    }
    let m = n / 2;
    if n % 2 == 1 {
        win[m]
    } else {
        0.5 * (win[m - 1] + win[m])
    }
}

/// The median of `buf` (reordered; NaN when empty; the mean of the two middle values for an
/// even count, as numpy's), by selection.
pub(crate) fn median(buf: &mut [f64]) -> f64 {
    if buf.is_empty() {
        return f64::NAN;
    }
    let m = buf.len() / 2;
    buf.select_nth_unstable_by(m, f64::total_cmp);
    let hi = buf[m];
    if buf.len() % 2 == 1 {
        hi
    } else {
        let lo = buf[..m].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lo + hi)
    }
}

fn robust_sigma(values: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.filter(|x| x.is_finite()).collect();
    let m = median(&mut v);
    let mut dev: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    1.4826 * median(&mut dev)
}

fn range_over(x: &[f64], lo: usize, hi: usize) -> f64 {
    let (mut mn, mut mx) = (f64::INFINITY, f64::NEG_INFINITY);
    for &v in &x[lo..=hi] {
        if v.is_finite() {
            mn = mn.min(v);
            mx = mx.max(v);
        }
    }
    if mx >= mn {
        mx - mn
    } else {
        0.0
    }
}

/// Largest change of `x` between consecutive samples in `lo..=hi` (finite pairs only).
fn largest_step(x: &[f64], lo: usize, hi: usize) -> f64 {
    x[lo..=hi]
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| d.is_finite())
        .fold(0.0, f64::max)
}

/// Samples around `peak` where `sign * x` stays above `fraction` of the peak.
fn spike_extent(x: &[f64], peak: usize, sign: f64, fraction: f64) -> (usize, usize) {
    let floor = fraction * (x[peak] * sign).abs();
    let mut on = peak;
    while on > 0 && x[on - 1] * sign > floor {
        on -= 1;
    }
    let mut off = peak;
    while off + 1 < x.len() && x[off + 1] * sign > floor {
        off += 1;
    }
    (on, off)
}

/// A straight line through the medians of `x` over `w` samples before `on`
/// and `w` samples after `off`, each kept half the spike's extent away from
/// it; `None` when either side has no data.
fn local_baseline(x: &[f64], on: usize, off: usize, w: usize) -> Option<impl Fn(usize) -> f64> {
    let n = x.len();
    // Keep a margin of half the spike's extent between the windows and the
    // spike, so the flanks below the onset fraction do not lift the baseline.
    let margin = (off - on) / 2;
    let b_end = on.checked_sub(margin)?;
    let a_start = off + 1 + margin;
    if b_end == 0 || a_start >= n {
        return None;
    }
    let lo = b_end.saturating_sub(w);
    let hi = (a_start + w).min(n);
    let finite = |s: &[f64]| -> Vec<f64> { s.iter().copied().filter(|v| v.is_finite()).collect() };
    let mut before = finite(&x[lo..b_end]);
    let mut after = finite(&x[a_start..hi]);
    if before.is_empty() || after.is_empty() {
        return None;
    }
    let (x0, y0) = (0.5 * (lo + b_end) as f64, median(&mut before));
    let (x1, y1) = (0.5 * (a_start + hi) as f64, median(&mut after));
    let slope = (y1 - y0) / (x1 - x0);
    Some(move |k: usize| y0 + slope * (k as f64 - x0))
}

/// Smallest half-width of the parabola fitted at the spike's top to measure its
/// peak, s.
const PEAK_FIT_MIN_S: f64 = 0.04;

/// Vertex value of the least-squares parabola through `x[c - h ..= c + h]`, when
/// that window lies inside `x`, holds no NaN, the parabola bends toward the
/// peak and its vertex lies inside the window.
fn parabola_vertex(x: &[f64], c: usize, h: usize) -> Option<f64> {
    if c < h || c + h >= x.len() {
        return None;
    }
    let (mut s0, mut s2, mut s4, mut sy, mut sxy, mut sx2y) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (k, &y) in x[c - h..=c + h].iter().enumerate() {
        if !y.is_finite() {
            return None;
        }
        let u = k as f64 - h as f64;
        s0 += 1.0;
        s2 += u * u;
        s4 += u * u * u * u;
        sy += y;
        sxy += u * y;
        sx2y += u * u * y;
    }
    // symmetric abscissae: the odd moments vanish
    let c2 = (s0 * sx2y - s2 * sy) / (s0 * s4 - s2 * s2);
    let c1 = sxy / s2;
    let c0 = (sy - c2 * s2) / s0;
    let at = -c1 / (2.0 * c2);
    if c2 * x[c] >= 0.0 || !at.is_finite() || at.abs() > h as f64 {
        return None;
    }
    Some(c0 - c1 * c1 / (4.0 * c2))
}

/// Detect roll-off events in one record.
///
/// Returns accepted *and* rejected candidates (see [`RolloffEvent::rejected`])
/// so every decision is traceable; filter on `rejected.is_empty()`.
///
/// # Errors
/// [`AeroError::InvalidInput`] when the signals differ in length, time is not
/// strictly increasing, or a threshold is not positive.
pub fn detect(
    s: &RecordSignals<'_>,
    others: &[QuietChannel<'_>],
    cfg: &DetectConfig,
) -> Result<Vec<RolloffEvent>> {
    let n = s.t.len();
    for (name, len) in [
        ("alpha_deg", s.alpha_deg.len()),
        ("Cl residual", s.cl_residual.len()),
        ("da_deg", s.da_deg.len()),
    ] {
        if len != n {
            return Err(AeroError::invalid(
                format!("roll-off detection, channel {name}"),
                format!("has {len} samples, time has {n}"),
            ));
        }
    }
    for o in others {
        if o.values.len() != n {
            return Err(AeroError::invalid(
                format!("roll-off detection, channel {}", o.name),
                format!("has {} samples, time has {n}", o.values.len()),
            ));
        }
    }
    for (name, v) in [
        ("trend_window_s", cfg.trend_window_s),
        ("threshold_sigma", cfg.threshold_sigma),
        ("quiet_window_s", cfg.quiet_window_s),
        ("max_duration_s", cfg.max_duration_s),
    ] {
        if v.is_nan() || v <= 0.0 {
            return Err(AeroError::invalid(
                format!("roll-off detection, {name}"),
                format!("is {v}; it must be positive"),
            ));
        }
    }
    if cfg.trend_window_s < 2.0 * cfg.max_duration_s {
        return Err(AeroError::invalid(
            "roll-off detection, trend_window_s",
            format!(
                "is {} s but must be at least twice max_duration_s ({} s), or the running median follows the spike",
                cfg.trend_window_s, cfg.max_duration_s
            ),
        ));
    }
    if n < 8 {
        return Ok(Vec::new());
    }
    if let Some(i) = (1..n).find(|&i| s.t[i].is_nan() || s.t[i] <= s.t[i - 1]) {
        return Err(AeroError::invalid(
            format!("roll-off detection, time row {i}"),
            format!("t = {} does not exceed the previous {}", s.t[i], s.t[i - 1]),
        ));
    }
    let dt = (s.t[n - 1] - s.t[0]) / (n - 1) as f64;
    let half = ((0.5 * cfg.trend_window_s / dt).round() as usize).max(1);
    let trend = running_median(s.cl_residual, half);
    let e: Vec<f64> = s
        .cl_residual
        .iter()
        .zip(&trend)
        .map(|(a, b)| a - b)
        .collect();

    let pre: Vec<f64> = (0..n)
        .filter(|&i| s.alpha_deg[i] < cfg.min_alpha_deg)
        .map(|i| e[i])
        .collect();
    let sigma = if pre.len() >= 50 {
        robust_sigma(pre.into_iter())
    } else {
        robust_sigma(e.iter().copied())
    };
    let thresh = (cfg.threshold_sigma * sigma).max(cfg.min_magnitude);
    let quiet = ((cfg.quiet_window_s / dt).round() as usize).max(1);

    let mut events = Vec::new();
    let mut i = 0usize;
    while i < n {
        if !(s.alpha_deg[i] > cfg.min_alpha_deg && e[i].abs() > thresh) {
            i += 1;
            continue;
        }
        // The run above threshold with one sign: find its end and its peak.
        let sign = e[i].signum();
        let mut j = i;
        let mut peak_i = i;
        while j < n && e[j] * sign > thresh {
            if e[j] * sign > e[peak_i] * sign {
                peak_i = j;
            }
            j += 1;
        }
        // First pass on the median-detrended residual, then one refinement
        // against a local straight baseline through the raw residual just
        // outside the spike (the running median is biased by the spike itself).
        let (mut on, mut off) = spike_extent(&e, peak_i, sign, cfg.onset_fraction);
        let (mut peak, mut peak_i2) = (e[peak_i], peak_i);
        let mut signal: Option<Vec<f64>> = None;
        // Iterate: each better baseline widens the extent, which moves the
        // baseline windows further off the spike's flanks (3 passes suffice).
        for _ in 0..3 {
            let Some(base) = local_baseline(s.cl_residual, on, off, quiet) else {
                break;
            };
            let lo = on.saturating_sub(quiet);
            let hi = (off + quiet).min(n - 1);
            let local: Vec<f64> = (0..n).map(|k| s.cl_residual[k] - base(k)).collect();
            peak_i2 = (lo..=hi)
                .max_by(|&a, &b| (local[a] * sign).total_cmp(&(local[b] * sign)))
                .unwrap_or(peak_i);
            peak = local[peak_i2];
            (on, off) = spike_extent(&local, peak_i2, sign, cfg.onset_fraction);
            signal = Some(local);
        }
        let peak_i = peak_i2;
        // The largest noisy sample overstates the peak by about a noise standard
        // deviation; the vertex of a parabola fitted over the spike's top does not.
        // Window: ±1/10 of the extent above the onset fraction (±0.36 standard
        // deviations of a Gaussian spike at the 20 % fraction: the quartic term
        // lowers the vertex by < 0.5 %), at least ±PEAK_FIT_MIN_S.
        let h = ((off - on) / 10).max(((PEAK_FIT_MIN_S / dt).round() as usize).max(2));
        if let Some(v) = parabola_vertex(signal.as_deref().unwrap_or(&e), peak_i, h) {
            if v * sign > 0.0 {
                peak = v;
            }
        }
        let duration = s.t[off] - s.t[on];
        let mut rejected = String::new();
        if duration > cfg.max_duration_s {
            rejected = format!(
                "lasts {duration:.2} s, longer than max_duration_s = {} s: not a transient",
                cfg.max_duration_s
            );
        } else if on < quiet {
            rejected = "starts before a full quiet window of data".to_string();
        } else {
            let lo = on - quiet;
            // from the quiet window before the onset to as long after the spike's end: an
            // aileron step makes a spike of the measured moment (a central difference of rates
            // cannot follow a moment that jumps between two samples, and the zero-phase
            // smoothing of the rates spreads it to both sides of the step), so an aileron
            // change within one sample larger than its quiet-window allowance marks it
            // commanded (step 2: "not caused by another sudden change of state"). The other
            // channels keep their window rule only: fast spoilers slaved to the wheel move
            // 2-4 deg per sample in a pilot's reaction to a true roll-off.
            let end = (off + quiet).min(n - 1).max(on);
            let da_change = range_over(s.da_deg, lo, on);
            let da_step = largest_step(s.da_deg, lo, end);
            if da_change > cfg.max_aileron_change_deg {
                rejected = format!(
                    "aileron moved {da_change:.2} deg in the {} s before onset (allowed {}): commanded",
                    cfg.quiet_window_s, cfg.max_aileron_change_deg
                );
            } else if da_step > cfg.max_aileron_change_deg {
                rejected = format!(
                    "aileron stepped {da_step:.2} deg within one sample during the spike (allowed {}): commanded",
                    cfg.max_aileron_change_deg
                );
            } else {
                for o in others {
                    let c = range_over(o.values, lo, on);
                    if c > o.max_change {
                        rejected = format!(
                            "{} changed by {c:.3} in the {} s before onset (allowed {}): explained by another input",
                            o.name, cfg.quiet_window_s, o.max_change
                        );
                        break;
                    }
                }
            }
        }
        let accepted = rejected.is_empty();
        events.push(RolloffEvent {
            onset_index: on,
            peak_index: peak_i,
            t_onset: s.t[on],
            t_peak: s.t[peak_i],
            alpha_onset_deg: s.alpha_deg[on],
            peak,
            direction: if peak > 0.0 { 1 } else { -1 },
            duration_s: duration,
            noise_sigma: sigma,
            rejected,
        });
        if accepted && cfg.first_only {
            break;
        }
        i = off.max(j) + 1;
    }
    Ok(events)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic stall: alpha ramps from 5 deg at 0.5 deg/s; a Gaussian-in-alpha spike
    /// (thesis Fig. 3.14 shape, sigma 0.5 deg) of known size sits at alpha0.
    #[allow(clippy::type_complexity)]
    fn record(
        alpha0: f64,
        amp: f64,
        noise: f64,
        seed: u64,
    ) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = 2000;
        let dt = 0.02;
        let mut state = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut rnd = || {
            // deterministic uniform(-1, 1) noise (LCG; tests only)
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let t: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        // alpha rises at 0.5 deg/s near stall, so a roll-off lasts a few seconds
        let alpha: Vec<f64> = t.iter().map(|&t| 5.0 + 15.0 * t / 30.0).collect();
        let cl: Vec<f64> = alpha
            .iter()
            .map(|&a| {
                0.002 * (a / 20.0)
                    + amp * (-0.5 * ((a - alpha0) / 0.5).powi(2)).exp()
                    + noise * rnd()
            })
            .collect();
        let da = vec![0.5; n];
        (t, alpha, cl, da)
    }

    #[test]
    fn finds_the_injected_spike_with_its_alpha_size_and_sign() {
        for (amp, seed) in [(0.015, 1u64), (-0.02, 2), (0.01, 3)] {
            let (t, alpha, cl, da) = record(17.0, amp, 0.0005, seed);
            let sig = RecordSignals {
                t: &t,
                alpha_deg: &alpha,
                cl_residual: &cl,
                da_deg: &da,
            };
            let ev: Vec<_> = detect(&sig, &[], &DetectConfig::default())
                .expect("detects")
                .into_iter()
                .filter(|e| e.rejected.is_empty())
                .collect();
            assert_eq!(ev.len(), 1, "amp {amp}: {ev:?}");
            let e = &ev[0];
            assert_eq!(e.direction, amp.signum() as i8);
            assert!((e.peak - amp).abs() < 0.15 * amp.abs(), "{e:?}");
            // onset at 20 % of the Gaussian: alpha0 - 0.5*sqrt(2 ln 5) = alpha0 - 0.897
            assert!((e.alpha_onset_deg - (17.0 - 0.897)).abs() < 0.25, "{e:?}");
        }
    }

    #[test]
    fn a_step_input_during_the_spike_is_commanded_and_a_rate_limited_reaction_is_not() {
        // the spike at 17 deg: alpha 17 at t = 24 s, sample 1200
        let (t, alpha, cl, da0) = record(17.0, 0.015, 0.0005, 4);
        let events = |da: &[f64]| {
            let sig = RecordSignals {
                t: &t,
                alpha_deg: &alpha,
                cl_residual: &cl,
                da_deg: da,
            };
            detect(&sig, &[], &DetectConfig::default()).expect("runs")
        };
        let stepped_at = |k: usize| {
            let mut da = da0.clone();
            da[k..].iter_mut().for_each(|v| *v += 10.0);
            da
        };
        // (a) a 10-deg aileron step between the samples just before the peak (the DHC-6's
        // doublets in JSBSim: a surface jump within one 20-ms frame)
        let ev = events(&stepped_at(1200));
        assert!(ev.iter().all(|e| !e.rejected.is_empty()), "{ev:?}");
        assert!(
            ev.iter().any(|e| e.rejected.contains("stepped 10.00 deg")),
            "{ev:?}"
        );
        // (a') the same step 0.2 s after the spike's end (20 % of the peak, 0.9 deg past it
        // at 0.5 deg/s: sample 1290): the zero-phase smoothing of the rates spreads a
        // step's moment spike to both sides, so it is still commanded
        let ev = events(&stepped_at(1300));
        assert!(ev.iter().all(|e| !e.rejected.is_empty()), "{ev:?}");
        // (b) the pilot's reaction between the onset (20 % of the peak, 0.9 deg before it at
        // 0.5 deg/s: sample 1110-1115) and the peak, at the actuator's 60 deg/s (1.2 deg per
        // sample, 12 deg in all): still an uncommanded roll-off
        let mut da = da0.clone();
        for (k, v) in da[1130..].iter_mut().enumerate() {
            *v += (1.2 * k as f64).min(12.0);
        }
        let ev = events(&da);
        assert_eq!(
            ev.iter().filter(|e| e.rejected.is_empty()).count(),
            1,
            "{ev:?}"
        );
    }

    #[test]
    fn peak_is_unbiased_by_the_noise() {
        // the largest of noisy samples overstates the peak; the fitted vertex does not:
        // the mean over 40 records lies within 4 standard errors of the injected 0.01
        let amp = 0.01;
        let noise = 0.001; // uniform(-1, 1) scaled: standard deviation 0.00058
        let peaks: Vec<f64> = (0..40u64)
            .map(|seed| {
                let (t, alpha, cl, da) = record(17.0, amp, noise, 100 + seed);
                let sig = RecordSignals {
                    t: &t,
                    alpha_deg: &alpha,
                    cl_residual: &cl,
                    da_deg: &da,
                };
                detect(&sig, &[], &DetectConfig::default()).expect("detects")[0].peak
            })
            .collect();
        let n = peaks.len() as f64;
        let mean = peaks.iter().sum::<f64>() / n;
        let sd = (peaks.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        assert!(
            (mean - amp).abs() < 4.0 * sd / n.sqrt(),
            "mean {mean} sd {sd}"
        );
        assert!(parabola_vertex(&[0.0, 1.0, 2.0, 1.0, 0.0], 2, 2).is_some());
        let v = parabola_vertex(&[-1.0, 0.0, 1.0, 0.0, -1.0], 2, 1).expect("vertex");
        assert!((v - 1.0).abs() < 1e-12);
        assert!(parabola_vertex(&[1.0, 0.0, 1.0], 1, 1).is_none()); // bends away
    }

    #[test]
    fn commanded_spike_is_rejected_with_reason() {
        let (t, alpha, cl, mut da) = record(17.0, 0.015, 0.0005, 4);
        // the pilot moved the aileron by 5 deg just before the spike
        for (i, a) in alpha.iter().enumerate() {
            if *a > 16.0 {
                da[i] = 5.5;
            }
        }
        let sig = RecordSignals {
            t: &t,
            alpha_deg: &alpha,
            cl_residual: &cl,
            da_deg: &da,
        };
        let ev = detect(&sig, &[], &DetectConfig::default()).expect("runs");
        assert!(!ev.is_empty());
        assert!(
            ev.iter().all(|e| e.rejected.contains("aileron moved")),
            "{ev:?}"
        );
        let dr: Vec<f64> = alpha
            .iter()
            .map(|&a| if a > 16.0 { 4.0 } else { 0.0 })
            .collect();
        let (_, _, cl2, da2) = record(17.0, 0.015, 0.0005, 5);
        let sig = RecordSignals {
            t: &t,
            alpha_deg: &alpha,
            cl_residual: &cl2,
            da_deg: &da2,
        };
        let others = [QuietChannel {
            name: "dr_deg",
            values: &dr,
            max_change: 2.0,
        }];
        let ev = detect(&sig, &others, &DetectConfig::default()).expect("runs");
        assert!(
            ev.iter().all(|e| e.rejected.contains("dr_deg changed")),
            "{ev:?}"
        );
    }

    #[test]
    fn no_spike_no_event_over_many_seeds() {
        let mut false_events = 0;
        for seed in 0..200u64 {
            let (t, alpha, cl, da) = record(17.0, 0.0, 0.0005, seed + 100);
            let sig = RecordSignals {
                t: &t,
                alpha_deg: &alpha,
                cl_residual: &cl,
                da_deg: &da,
            };
            false_events += detect(&sig, &[], &DetectConfig::default())
                .expect("runs")
                .iter()
                .filter(|e| e.rejected.is_empty())
                .count();
        }
        assert_eq!(false_events, 0);
    }

    #[test]
    fn bad_input_is_refused_with_place() {
        let t = [0.0, 1.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
        let z = [0.0; 9];
        let sig = RecordSignals {
            t: &t,
            alpha_deg: &z,
            cl_residual: &z,
            da_deg: &z,
        };
        let e = detect(&sig, &[], &DetectConfig::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("time row 2"), "{e}");
        let sig = RecordSignals {
            t: &t,
            alpha_deg: &z[..3],
            cl_residual: &z,
            da_deg: &z,
        };
        let e = detect(&sig, &[], &DetectConfig::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("alpha_deg"), "{e}");
    }

    #[test]
    fn median_matches_definition() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        let rm = running_median(&[1.0, 9.0, 2.0, 8.0, 3.0], 1);
        assert_eq!(rm, vec![5.0, 2.0, 8.0, 3.0, 5.5]);
    }

    #[test]
    fn sliding_median_is_the_median_of_each_window_bit_for_bit() {
        // the reference: a selection on each clipped window, NaNs left out
        let naive = |x: &[f64], half: usize| -> Vec<f64> {
            (0..x.len())
                .map(|i| {
                    let lo = i.saturating_sub(half);
                    let hi = (i + half + 1).min(x.len());
                    let mut b: Vec<f64> =
                        x[lo..hi].iter().copied().filter(|v| !v.is_nan()).collect();
                    median(&mut b)
                })
                .collect()
        };
        let mut rng = crate::sim::rng::Stream::new(17, 3);
        for (n, half) in [(0, 3), (1, 0), (5, 10), (200, 7), (700, 300), (64, 1)] {
            let x: Vec<f64> = (0..n)
                .map(|k| match k % 13 {
                    0 => f64::NAN,
                    1 => -0.0,
                    2 => 0.0,
                    3 => 1.5, // repeated values
                    _ => rng.normal(),
                })
                .collect();
            let got = running_median(&x, half);
            let want = naive(&x, half);
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                assert!(g.to_bits() == w.to_bits(), "n {n} half {half}: {g} vs {w}");
            }
        }
        assert!(running_median(&[f64::NAN, f64::NAN], 1)
            .iter()
            .all(|v| v.is_nan()));
    }
}
