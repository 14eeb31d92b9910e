//! Band-limited equation error: one zero-phase low-pass applied, maneuver by
//! maneuver, to the qualified-model error $z = C_{meas} - C_{qual}$ (thesis
//! Eq. 3.5) and to every regressor of the Δ model (Eq. 3.6-3.9) before the
//! per-bin least squares (Eq. 3.10).
//!
//! Why: the measured coefficients are built from smoothed rates and their
//! derivatives (Eq. 3.2-3.4, the SIDPAC smoothing of Section 3.2.3), so they
//! have lost what lies above the smoother's cut-off (about 2-4 Hz on the
//! virtual campaigns), while the control positions and the qualified model
//! evaluated along them keep it. The part of the control's response the
//! output lost then reads as a Δ: on 20 virtual campaigns it biased
//! $\Delta C_{n_{\delta_r}}$ by 0.8 and $\Delta C_{n_\beta}$ by 0.5 of their
//! standard deviations where the true Δ is zero. A linear filter applied to
//! both sides keeps the equation-error relation $z = X\theta$ (Klein & Morelli
//! 2006, Ch. 5: equation error needs the output and the regressors to carry the
//! same information; the frequency-domain form fits only the band where the
//! rigid-body motion lies), so filtering both with one band removes the
//! mismatch. The alpha used to bin the rows is not filtered.
//!
//! Each maneuver's rows are put in time order and cut at gaps (a step over
//! 1.5 times the maneuver's median sample interval, or time not increasing);
//! each piece of at least [`MIN_SEGMENT`] samples is filtered by
//! [`Smoother::lowpass_pair`], the smoother's end treatment with a fixed
//! cut-off. Shorter pieces, and a channel holding a non-finite value in a
//! piece, are left as they are and counted in the [`BandReport`]. Constant
//! regressors (the bias "1") are not touched.

use std::collections::HashMap;

use crate::error::{AeroError, Result};
use crate::identify::Design;
use crate::preprocess::smooth::Smoother;

/// Shortest run of samples that is filtered.
pub const MIN_SEGMENT: usize = 16;

/// What [`lowpass_by_maneuver`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BandReport {
    /// Pieces of maneuvers filtered.
    pub segments: usize,
    /// Samples in the filtered pieces.
    pub samples_filtered: usize,
    /// Samples left as they are (pieces shorter than [`MIN_SEGMENT`]).
    pub samples_unfiltered: usize,
    /// Channel pieces left as they are because they held a non-finite value.
    pub channels_skipped: usize,
}

/// Time-ordered pieces of each maneuver, in the order the maneuvers first appear.
pub(crate) fn segments(maneuver: &[u64], t: &[f64]) -> Vec<Vec<usize>> {
    let mut order: Vec<u64> = Vec::new();
    let mut rows: HashMap<u64, Vec<usize>> = HashMap::new();
    for (i, &m) in maneuver.iter().enumerate() {
        rows.entry(m)
            .or_insert_with(|| {
                order.push(m);
                Vec::new()
            })
            .push(i);
    }
    let mut out = Vec::new();
    for m in order {
        let mut r = rows.remove(&m).unwrap_or_default();
        r.sort_by(|&a, &b| t[a].total_cmp(&t[b]));
        let mut steps: Vec<f64> = r
            .windows(2)
            .map(|w| t[w[1]] - t[w[0]])
            .filter(|d| *d > 0.0)
            .collect();
        if steps.is_empty() {
            out.push(r);
            continue;
        }
        steps.sort_by(f64::total_cmp);
        let dt = steps[steps.len() / 2];
        let mut cur = vec![r[0]];
        for w in r.windows(2) {
            let d = t[w[1]] - t[w[0]];
            if d <= 0.0 || d > 1.5 * dt {
                out.push(std::mem::take(&mut cur));
            }
            cur.push(w[1]);
        }
        out.push(cur);
    }
    out
}

/// Filtered values of one piece: per channel, `None` when left as it is.
type Piece = Vec<Option<Vec<f64>>>;

fn filter_piece(rows: &[usize], channels: &[Vec<f64>], t: &[f64], fc_hz: f64) -> Piece {
    let n = rows.len();
    let dt = (t[rows[n - 1]] - t[rows[0]]) / (n - 1) as f64;
    let sm = Smoother::new(n);
    let data: Vec<Option<Vec<f64>>> = channels
        .iter()
        .map(|c| {
            let v: Vec<f64> = rows.iter().map(|&r| c[r]).collect();
            v.iter().all(|x| x.is_finite()).then_some(v)
        })
        .collect();
    let live: Vec<usize> = (0..data.len()).filter(|&k| data[k].is_some()).collect();
    let mut out: Piece = vec![None; channels.len()];
    for pair in live.chunks(2) {
        let a = data[pair[0]].as_deref().unwrap_or(&[]);
        let b = pair.get(1).and_then(|&k| data[k].as_deref()).unwrap_or(a);
        let (fa, fb) = sm.lowpass_pair(a, b, dt, fc_hz);
        out[pair[0]] = Some(fa);
        if let Some(&k) = pair.get(1) {
            out[k] = Some(fb);
        }
    }
    out
}

/// Low-pass `z` and the non-constant columns of `design` at `fc_hz`, maneuver
/// by maneuver (see the module doc). `t` is the time of each row, s.
///
/// # Errors
/// [`AeroError::InvalidInput`] for lengths that differ, a cut-off that is not
/// a positive number, or a non-finite time (naming its row).
pub fn lowpass_by_maneuver(
    design: &mut Design,
    z: &mut [f64],
    maneuver: &[u64],
    t: &[f64],
    fc_hz: f64,
) -> Result<BandReport> {
    let n = design.nrows;
    for (what, len) in [("z", z.len()), ("maneuver", maneuver.len()), ("t", t.len())] {
        if len != n {
            return Err(AeroError::invalid(
                format!("band-limited fit, {what}"),
                format!("has {len} rows, the regressors have {n}"),
            ));
        }
    }
    if !(fc_hz.is_finite() && fc_hz > 0.0) {
        return Err(AeroError::invalid(
            "band_hz",
            format!("is {fc_hz}; give a positive cut-off in Hz (e.g. 2.5) or none"),
        ));
    }
    if let Some(i) = t.iter().position(|v| !v.is_finite()) {
        return Err(AeroError::invalid(
            format!("channel 't', row {i}"),
            "is not a finite time; the band-limited fit needs each sample's time in seconds",
        ));
    }
    let p = design.ncols();
    let cols: Vec<usize> = (0..p).filter(|&j| !design.exprs[j].is_constant()).collect();
    // channel 0 is z, then the non-constant regressors
    let mut channels: Vec<Vec<f64>> = Vec::with_capacity(cols.len() + 1);
    channels.push(z.to_vec());
    for &j in &cols {
        channels.push((0..n).map(|i| design.values[i * p + j]).collect());
    }
    let pieces = segments(maneuver, t);
    let mut report = BandReport::default();
    let work = |rows: &Vec<usize>| -> Option<Piece> {
        (rows.len() >= MIN_SEGMENT).then(|| filter_piece(rows, &channels, t, fc_hz))
    };
    #[cfg(feature = "parallel")]
    let done: Vec<Option<Piece>> = {
        use rayon::prelude::*;
        pieces.par_iter().map(work).collect()
    };
    #[cfg(not(feature = "parallel"))]
    let done: Vec<Option<Piece>> = pieces.iter().map(work).collect();
    for (rows, piece) in pieces.iter().zip(done) {
        let Some(piece) = piece else {
            report.samples_unfiltered += rows.len();
            continue;
        };
        report.segments += 1;
        report.samples_filtered += rows.len();
        for (k, vals) in piece.into_iter().enumerate() {
            let Some(vals) = vals else {
                report.channels_skipped += 1;
                continue;
            };
            for (&r, v) in rows.iter().zip(vals) {
                if k == 0 {
                    z[r] = v;
                } else {
                    design.values[r * p + cols[k - 1]] = v;
                }
            }
        }
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::Stream;

    fn design_of(cols: &[(&str, &str)], data: &HashMap<String, Vec<f64>>, n: usize) -> Design {
        let regs: Vec<(String, String)> = cols
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
        let lookup = |name: &str| data.get(name).map(|v| v.as_slice());
        Design::build(&regs, &lookup, n).expect("design")
    }

    #[test]
    fn a_sine_below_the_band_passes_and_one_above_is_removed() {
        // 0.5 Hz passes (weight 1 below 0.75 fc), 6 Hz is stopped (weight 0 above 1.25 fc)
        let (dt, n, fc) = (0.02, 1500, 2.0);
        let tt: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
        let w = |f: f64| -> Vec<f64> {
            tt.iter()
                .map(|t| (2.0 * std::f64::consts::PI * f * t).sin())
                .collect()
        };
        let (slow, fast) = (w(0.5), w(6.0));
        let x: Vec<f64> = slow.iter().zip(&fast).map(|(a, b)| a + b).collect();
        let sm = Smoother::new(n);
        let (y, y2) = sm.lowpass_pair(&x, &slow, dt, fc);
        // away from the ends, where the taper bridges the record
        for i in 100..n - 100 {
            assert!(
                (y[i] - slow[i]).abs() < 2e-3,
                "i {i}: {} vs {}",
                y[i],
                slow[i]
            );
            assert!((y2[i] - slow[i]).abs() < 2e-3);
        }
    }

    #[test]
    fn a_linear_relation_survives_the_filter_and_constants_are_untouched() {
        // z = 0.01 + 0.3 x1 - 0.2 x2 exactly, over two maneuvers given interleaved and out of
        // time order: the filtered z is the same combination of the filtered regressors
        let n = 800;
        let mut rng = Stream::new(3, 1);
        let mut data: HashMap<String, Vec<f64>> = HashMap::new();
        let (mut man, mut t) = (Vec::new(), Vec::new());
        let (mut x1, mut x2) = (Vec::new(), Vec::new());
        for i in 0..n {
            let m = (i % 2) as u64;
            man.push(m);
            t.push((i / 2) as f64 * 0.02);
            x1.push(rng.normal());
            x2.push((i as f64 * 0.01).sin() + rng.normal());
        }
        // reverse the rows: time order must come from t, not from row order
        man.reverse();
        t.reverse();
        x1.reverse();
        x2.reverse();
        let mut z: Vec<f64> = (0..n).map(|i| 0.01 + 0.3 * x1[i] - 0.2 * x2[i]).collect();
        data.insert("x1".into(), x1);
        data.insert("x2".into(), x2);
        let mut d = design_of(&[("b", "1"), ("a1", "x1"), ("a2", "x2")], &data, n);
        let before = d.values.clone();
        let rep = lowpass_by_maneuver(&mut d, &mut z, &man, &t, 2.0).expect("filter");
        assert_eq!(rep.segments, 2);
        assert_eq!(rep.samples_filtered, n);
        let mut moved = 0.0f64;
        for i in 0..n {
            let (c, a, b) = (d.values[3 * i], d.values[3 * i + 1], d.values[3 * i + 2]);
            assert_eq!(c, 1.0);
            assert!((z[i] - (0.01 + 0.3 * a - 0.2 * b)).abs() < 1e-12, "row {i}");
            moved = moved.max((a - before[3 * i + 1]).abs());
        }
        assert!(
            moved > 0.5,
            "white noise regressor must lose its high band: {moved}"
        );
    }

    #[test]
    fn gaps_split_maneuvers_and_short_pieces_stay() {
        let t: Vec<f64> = (0..40)
            .map(|i| {
                if i < 30 {
                    i as f64 * 0.02
                } else {
                    5.0 + i as f64 * 0.02
                }
            })
            .collect();
        let man = vec![7u64; 40];
        let mut data: HashMap<String, Vec<f64>> = HashMap::new();
        data.insert("x".into(), (0..40).map(|i| ((i * 7) % 5) as f64).collect());
        let mut d = design_of(&[("a", "x")], &data, 40);
        let mut z: Vec<f64> = (0..40).map(|i| i as f64).collect();
        let rep = lowpass_by_maneuver(&mut d, &mut z, &man, &t, 2.0).expect("filter");
        assert_eq!(
            (rep.segments, rep.samples_filtered, rep.samples_unfiltered),
            (1, 30, 10)
        );
        assert_eq!(&d.values[30..], &data["x"][30..]);
        let err = lowpass_by_maneuver(&mut d, &mut z, &man, &t, 0.0).unwrap_err();
        assert!(err.to_string().contains("band_hz"), "{err}");
        let mut tb = t.clone();
        tb[4] = f64::NAN;
        let err = lowpass_by_maneuver(&mut d, &mut z, &man, &tb, 2.0).unwrap_err();
        assert!(err.to_string().contains("row 4"), "{err}");
    }
}
