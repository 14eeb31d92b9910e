//! A model's coefficients seen through the smoother the measured ones came through.
//!
//! The measured coefficients (thesis Eq. 3.2-3.4) are built from channels the ingestion
//! smoothed maneuver by maneuver ([`super::smooth`], SIDPAC `smoo`), each with the Wiener
//! weights its own spectrum chose: $C_Y$ from the lateral acceleration, $C_l$ from the roll
//! rate's derivative, $C_n$ from the yaw rate's. A simulator's coefficients evaluated along the
//! records keep their full band, so the equation-error target $C_{meas} - C_{qual}$ (Eq. 3.5)
//! holds the part of every fast transient that the smoothing took from the measurement only.
//! On the JSBSim DHC-6 this read as a $\Delta C_{Y_0}$ of about a third of a bin's standard
//! error in recoveries, where the noise drives the lateral accelerometer's cut-off to about
//! 2 Hz (`docs/identification.md`, Session 26).
//!
//! Once chosen, the weights make the smoother linear, so passing the model's force or moment,
//! $C\,\bar q$ (the measurement is the smoothed force over the dynamic pressure), through the
//! same weights gives it exactly the band of the measurement: the two sides of the equation
//! carry the same information (Klein & Morelli, *Aircraft System Identification*, 2006,
//! Section 5.5). The weights are redesigned here from the raw reference channel by the same
//! deterministic smoother, so a maneuver must still be the record the ingestion smoothed: each
//! maneuver's raw check channel is smoothed again and must reproduce the smoothed one stored
//! beside it, otherwise the maneuver is left at full band and counted ([`MatchReport`]).

use crate::band::segments;
use crate::error::{AeroError, Result};

use super::smooth::Smoother;

/// One coefficient to pass through the smoother of its measurement's channel.
#[derive(Debug, Clone, Copy)]
pub struct Channel<'a> {
    /// The raw channel whose smoothing sets the measured coefficient's band, one value per row.
    pub reference: &'a [f64],
    /// The model's coefficient, one value per row.
    pub target: &'a [f64],
}

/// What [`through_smoother`] did, in maneuvers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MatchReport {
    /// Maneuvers whose smoothing was reproduced, their coefficients passed through it.
    pub matched: usize,
    /// Maneuvers ingested without smoothing (the smoothed check channel is the raw one).
    pub unsmoothed: usize,
    /// Maneuvers whose rows are not the record the smoother saw (cut, resampled, edited or
    /// with gaps): left at full band.
    pub changed: usize,
    /// Coefficient-maneuvers left at full band for a non-finite value in the reference, the
    /// target or the scale.
    pub nonfinite: usize,
}

/// Relative tolerance of the reproduced smoothing (the same deterministic smoother on the same
/// samples; only the pairing of channels in one FFT changes the last bits).
const REPRODUCED: f64 = 1e-9;

enum Outcome {
    Matched(Vec<Option<Vec<f64>>>),
    Unsmoothed,
    Changed,
}

/// Each `channels[k].target` passed, maneuver by maneuver, through the Wiener weights the
/// smoother chooses for `channels[k].reference`, as a force: `S(target * scale) / scale`
/// (`scale` the dynamic pressure). `check_raw` and `check_smoothed` are a channel the
/// ingestion smoothed and its stored smoothed values (the roll rate): a maneuver is matched
/// when smoothing its rows of `check_raw` again gives `check_smoothed`, left as it is and
/// counted as unsmoothed when the two are equal, and as changed otherwise or when its rows
/// (in time order) are not one uniformly sampled run. Rows are in any order; `maneuver`
/// codes them, `t` is the time, s.
///
/// # Errors
/// [`AeroError::InvalidInput`] for lengths that differ or a non-finite time (naming its row).
pub fn through_smoother(
    t: &[f64],
    maneuver: &[u64],
    check_raw: &[f64],
    check_smoothed: &[f64],
    scale: &[f64],
    channels: &[Channel],
) -> Result<(Vec<Vec<f64>>, MatchReport)> {
    let n = t.len();
    let mut lens = vec![
        ("maneuver", maneuver.len()),
        ("check channel (raw)", check_raw.len()),
        ("check channel (smoothed)", check_smoothed.len()),
        ("scale", scale.len()),
    ];
    for c in channels {
        lens.push(("reference", c.reference.len()));
        lens.push(("target", c.target.len()));
    }
    for (what, len) in lens {
        if len != n {
            return Err(AeroError::invalid(
                format!("smoother match, {what}"),
                format!("has {len} rows where 't' has {n}"),
            ));
        }
    }
    if let Some(i) = t.iter().position(|v| !v.is_finite()) {
        return Err(AeroError::invalid(
            format!("channel 't', row {i}"),
            "is not a finite time; matching the smoother needs each sample's time in seconds",
        ));
    }
    // every maneuver's rows in time order, cut where the sampling breaks
    let mut pieces: Vec<(u64, Vec<usize>)> = segments(maneuver, t)
        .into_iter()
        .map(|rows| (maneuver[rows[0]], rows))
        .collect();
    // a maneuver in more than one piece is not the record the smoother saw
    let mut split = std::collections::HashMap::<u64, usize>::new();
    for (m, _) in &pieces {
        *split.entry(*m).or_default() += 1;
    }
    pieces.retain(|(m, _)| split[m] == 1);
    let changed_split = split.values().filter(|&&k| k > 1).count();
    let gather = |rows: &[usize], x: &[f64]| -> Vec<f64> { rows.iter().map(|&r| x[r]).collect() };
    let finite = |x: &[f64]| x.iter().all(|v| v.is_finite());
    let work = |rows: &[usize]| -> Outcome {
        let raw = gather(rows, check_raw);
        let stored = gather(rows, check_smoothed);
        if !finite(&raw) || !finite(&stored) {
            return Outcome::Changed;
        }
        let sm = Smoother::new(rows.len());
        let q = gather(rows, scale);
        let scaled_ok = q.iter().all(|v| v.is_finite() && *v != 0.0);
        // series 0 is the check channel, then one per coefficient: the references designed
        // two per FFT, the targets (the check channel itself, then the forces) filtered two
        // per FFT, each through its own reference's weights; a coefficient with a non-finite
        // value rides along as the check channel and is left as it is
        let mut refs: Vec<Vec<f64>> = vec![raw.clone()];
        let mut targets: Vec<Vec<f64>> = vec![raw.clone()];
        let mut ok = vec![true];
        for c in channels {
            let reference = gather(rows, c.reference);
            let force: Vec<f64> = rows.iter().zip(&q).map(|(&r, s)| c.target[r] * s).collect();
            let good = scaled_ok && finite(&reference) && finite(&force);
            refs.push(if good { reference } else { raw.clone() });
            targets.push(if good { force } else { raw.clone() });
            ok.push(good);
        }
        let mut weights: Vec<Option<Vec<f64>>> = Vec::with_capacity(refs.len());
        for pair in refs.chunks(2) {
            let (wa, wb) = sm.weights_pair(&pair[0], pair.get(1).unwrap_or(&pair[0]));
            weights.push(wa);
            if pair.len() == 2 {
                weights.push(wb);
            }
        }
        let mut filtered: Vec<Vec<f64>> = Vec::with_capacity(targets.len());
        for (k, pair) in targets.chunks(2).enumerate() {
            let (i, j) = (2 * k, 2 * k + 1);
            let second = pair.get(1).unwrap_or(&pair[0]);
            let wj = weights.get(j).and_then(Option::as_deref);
            let (fa, fb) = sm.apply_pair(&pair[0], second, weights[i].as_deref(), wj);
            filtered.push(fa);
            if pair.len() == 2 {
                filtered.push(fb);
            }
        }
        let size = stored.iter().fold(1.0_f64, |a, v| a.max(v.abs()));
        let reproduced = filtered[0]
            .iter()
            .zip(&stored)
            .all(|(a, b)| (a - b).abs() <= REPRODUCED * size);
        if !reproduced {
            return if raw == stored {
                Outcome::Unsmoothed
            } else {
                Outcome::Changed
            };
        }
        Outcome::Matched(
            filtered
                .into_iter()
                .zip(ok)
                .skip(1)
                .map(|(f, good)| good.then(|| f.into_iter().zip(&q).map(|(v, s)| v / s).collect()))
                .collect(),
        )
    };
    #[cfg(feature = "parallel")]
    let done: Vec<Outcome> = {
        use rayon::prelude::*;
        pieces.par_iter().map(|(_, rows)| work(rows)).collect()
    };
    #[cfg(not(feature = "parallel"))]
    let done: Vec<Outcome> = pieces.iter().map(|(_, rows)| work(rows)).collect();
    let mut out: Vec<Vec<f64>> = channels.iter().map(|c| c.target.to_vec()).collect();
    let mut report = MatchReport {
        changed: changed_split,
        ..MatchReport::default()
    };
    for ((_, rows), outcome) in pieces.iter().zip(done) {
        match outcome {
            Outcome::Unsmoothed => report.unsmoothed += 1,
            Outcome::Changed => report.changed += 1,
            Outcome::Matched(values) => {
                report.matched += 1;
                for (dst, v) in out.iter_mut().zip(values) {
                    let Some(v) = v else {
                        report.nonfinite += 1;
                        continue;
                    };
                    for (&r, x) in rows.iter().zip(v) {
                        dst[r] = x;
                    }
                }
            }
        }
    }
    Ok((out, report))
}

#[cfg(test)]
mod tests {
    use super::super::smooth::tests_support::gauss;
    use super::*;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;

    /// The report with these counts: matched, unsmoothed, changed, nonfinite.
    fn counts(matched: usize, unsmoothed: usize, changed: usize, nonfinite: usize) -> MatchReport {
        MatchReport {
            matched,
            unsmoothed,
            changed,
            nonfinite,
        }
    }

    /// (t, maneuver, p raw, ay raw, model, qbar).
    type Records = (Vec<f64>, Vec<u64>, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

    /// Two maneuvers of noisy records, in time order.
    fn records() -> Records {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (mut t, mut m, mut p, mut ay, mut c, mut q) =
            (vec![], vec![], vec![], vec![], vec![], vec![]);
        for (man, len) in [(7u64, 600usize), (3, 450)] {
            for i in 0..len {
                let s = i as f64 * 0.02;
                t.push(100.0 * man as f64 + s);
                m.push(man);
                p.push(10.0 * (0.9 * s).sin() + 0.5 * gauss(&mut rng));
                ay.push((1.7 * s).sin() + 0.3 * gauss(&mut rng));
                c.push(
                    0.01 * (1.7 * s).sin() + 0.004 * (2.0 * std::f64::consts::PI * 6.0 * s).sin(),
                );
                q.push(2000.0 + 100.0 * (0.2 * s).cos());
            }
        }
        (t, m, p, ay, c, q)
    }

    #[test]
    fn a_reproduced_smoothing_passes_the_model_through_the_references_weights() {
        let (t, m, p, ay, c, q) = records();
        // what the ingestion stored: p smoothed per maneuver
        let mut ps = p.clone();
        for (a, b) in [(0usize, 600usize), (600, 1050)] {
            let s = Smoother::new(b - a).smooth(&p[a..b], 0.02).values;
            ps[a..b].copy_from_slice(&s);
        }
        // rows stored in reverse: the matching sorts them by time within each maneuver
        let rev = |x: &[f64]| -> Vec<f64> { x.iter().rev().copied().collect() };
        let mr: Vec<u64> = m.iter().rev().copied().collect();
        let (tr, pr, psr, ayr, cr, qr) = (rev(&t), rev(&p), rev(&ps), rev(&ay), rev(&c), rev(&q));
        let (out, rep) = through_smoother(
            &tr,
            &mr,
            &pr,
            &psr,
            &qr,
            &[Channel {
                reference: &ayr,
                target: &cr,
            }],
        )
        .unwrap();
        assert_eq!(rep, counts(2, 0, 0, 0));
        // the reference: per maneuver in time order, S_ay(c q) / q
        for (a, b) in [(0usize, 600usize), (600, 1050)] {
            let force: Vec<f64> = (a..b).map(|i| c[i] * q[i]).collect();
            let want = Smoother::new(b - a).smooth_like(&ay[a..b], &force);
            for (k, i) in (a..b).enumerate() {
                let got = out[0][1049 - i];
                assert!((got - want[k] / q[i]).abs() < 1e-15, "row {i}");
            }
        }
        // inside each maneuver (its end samples keep their values) the 6 Hz part, 4e-3, is
        // gone and the 1.7 Hz one kept
        let resid: f64 = [(50usize, 550usize), (650, 1000)]
            .iter()
            .flat_map(|&(a, b)| a..b)
            .map(|i| (out[0][1049 - i] - 0.01 * (1.7 * (t[i] % 100.0)).sin()).abs())
            .fold(0.0, f64::max);
        assert!(resid < 4e-4, "max residual {resid}");
    }

    #[test]
    fn unsmoothed_and_changed_maneuvers_are_left_at_full_band_and_counted() {
        let (t, m, p, ay, c, q) = records();
        let ch = [Channel {
            reference: &ay,
            target: &c,
        }];
        // ingested without smoothing: the stored channel is the raw one
        let (out, rep) = through_smoother(&t, &m, &p, &p, &q, &ch).unwrap();
        assert_eq!(rep, counts(0, 2, 0, 0));
        assert_eq!(out[0], c);
        // the first maneuver cut after ingestion (its first 100 rows gone): not reproduced
        let mut ps = p.clone();
        for (a, b) in [(0usize, 600usize), (600, 1050)] {
            let s = Smoother::new(b - a).smooth(&p[a..b], 0.02).values;
            ps[a..b].copy_from_slice(&s);
        }
        let k = 100;
        let (out, rep) = through_smoother(
            &t[k..],
            &m[k..],
            &p[k..],
            &ps[k..],
            &q[k..],
            &[Channel {
                reference: &ay[k..],
                target: &c[k..],
            }],
        )
        .unwrap();
        assert_eq!(rep, counts(1, 0, 1, 0));
        assert_eq!(out[0][..500], c[k..600]);
        // a gap inside a maneuver: changed; a NaN in the model: counted, left as it is
        let mut tg = t.clone();
        for v in &mut tg[300..600] {
            *v += 1.0;
        }
        let mut cn = c.clone();
        cn[700] = f64::NAN;
        let (out, rep) = through_smoother(
            &tg,
            &m,
            &p,
            &ps,
            &q,
            &[Channel {
                reference: &ay,
                target: &cn,
            }],
        )
        .unwrap();
        assert_eq!(rep, counts(1, 0, 1, 1));
        assert_eq!(out[0][..600], c[..600]);
        assert!(out[0][700].is_nan());
    }

    #[test]
    fn refuses_unequal_lengths_and_bad_times() {
        let t = [0.0, 0.1, f64::NAN];
        let x = [0.0; 3];
        let e = through_smoother(&t, &[1, 1, 1], &x, &x, &x, &[]).unwrap_err();
        assert!(e.to_string().contains("row 2"), "{e}");
        let e = through_smoother(&t[..2], &[1, 1, 1], &x, &x, &x, &[]).unwrap_err();
        assert!(e.to_string().contains("maneuver"), "{e}");
    }
}
