//! Monte Carlo of straight stalls with the stochastic roll-off on (thesis
//! Section 3.4.3, Figures 3.13-3.14): many independent stalls of the 6-DOF
//! simulator, each reduced to a few numbers — maximum bank, onset alpha, the
//! roll-off actually met, the dynamic roll-control (DRC) peak and the FAR
//! 25.203(c) verdict — with no time history kept.
//!
//! Stall `k` is the straight stall of repetition `k / 2` of the campaign with
//! the same seed (pusher on for even `k`), flown by [`crate::sim::campaign::Flight`]:
//! its seed is the campaign's SplitMix64 seed of that maneuver, and every
//! random component (setup, pilot, gusts, roll-off) has its own ChaCha8
//! stream of that seed. A stall's summary therefore depends only on the seed
//! and `k`: identical whatever the thread count, and identical to the
//! truth of the campaign maneuver (checked in the tests).

use crate::error::{AeroError, Result};
use crate::rolloff::RollOffDraw;
use crate::sim::campaign::{adx37_models, resolve_effects, CampaignSpec, Flight, ManeuverPlan};
use crate::sim::eom::ix;
use crate::sim::pilot::Kind;
use crate::sim::rng::derive_seed;

/// FAR 25.203(c): the bank angle in a straight stall must not exceed 20 deg.
pub const FAR25_203_MAX_BANK_DEG: f64 = 20.0;

/// Maneuvers per campaign repetition (5 flaps × 4 kinds × pusher on/off).
const PER_REPETITION: usize = 40;

/// What to fly.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct MonteCarloSpec {
    /// The campaign the stalls belong to: seed, effects (the roll-off must be
    /// among them, `stochastic_rolloff` with its scale), roll-off statistics,
    /// gusts, pilot excitation, simulation rate. Its `repetitions`, `only`,
    /// `record_hz` and `noise_scale` are not used (nothing is recorded).
    pub campaign: CampaignSpec,
    /// Flap setting, deg (one of the five of the ADX-37).
    pub flap_deg: f64,
    /// First stall index.
    pub first: usize,
    /// Number of stalls.
    pub n: usize,
    /// Fraction of the largest |ΔC_l| met that marks the onset (the detector's 20 %).
    pub onset_fraction: f64,
    /// Bank limit of the FAR 25.203 verdict, deg.
    pub bank_limit_deg: f64,
}

impl Default for MonteCarloSpec {
    fn default() -> Self {
        MonteCarloSpec {
            campaign: CampaignSpec::default(),
            flap_deg: 0.0,
            first: 0,
            n: 100,
            onset_fraction: 0.2,
            bank_limit_deg: FAR25_203_MAX_BANK_DEG,
        }
    }
}

impl MonteCarloSpec {
    /// Parse from JSON (missing fields take their defaults).
    ///
    /// # Errors
    /// [`AeroError::Parse`] naming the JSON line.
    pub fn from_json(text: &str) -> Result<Self> {
        serde_json::from_str(text)
            .map_err(|e| AeroError::parse("Monte Carlo spec (JSON)", e.line(), e.to_string()))
    }

    /// The campaign plan of stall `k` (straight, repetition `k / 2`, pusher on for even `k`).
    ///
    /// # Errors
    /// When the flap setting is not one of the five of the ADX-37.
    pub fn plan(&self, k: usize) -> Result<ManeuverPlan> {
        let fi = crate::aircraft::qualified::FLAP_STALL
            .iter()
            .position(|f| f.flap_deg == self.flap_deg)
            .ok_or_else(|| {
                AeroError::invalid(
                    "Monte Carlo flap_deg",
                    format!(
                        "{} deg is not a flap setting of the ADX-37; use 0, 5, 10, 15 or 35",
                        self.flap_deg
                    ),
                )
            })?;
        let index = (k / 2) * PER_REPETITION + fi * 2 * Kind::ALL.len() + k % 2;
        Ok(ManeuverPlan {
            index,
            flap_deg: self.flap_deg,
            kind: Kind::Straight,
            pusher: k % 2 == 0,
            seed: derive_seed(self.campaign.seed, index as u64),
        })
    }
}

/// The summary of one stall.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StallSummary {
    /// Stall index `k`.
    pub stall: usize,
    /// Index of the same maneuver in the campaign.
    pub maneuver_index: usize,
    /// Stick pusher installed.
    pub pusher: bool,
    /// Whether it fired.
    pub pusher_fired: bool,
    /// Duration flown, s.
    pub duration_s: f64,
    /// Maximum true alpha, deg.
    pub max_alpha_deg: f64,
    /// Maximum |φ| over the stall and recovery, deg (thesis Figure 3.13).
    pub max_bank_deg: f64,
    /// Maximum |φ'| with φ' = φ + φ̇ · 1 s (thesis Eq. 3.20, φ̇ the Euler roll
    /// rate), deg: the peak of the dynamic roll-control (DRC) plot.
    pub max_dynamic_roll_deg: f64,
    /// Whether `max_bank_deg` ≤ the bank limit (FAR 25.203(c)).
    pub far25_203_pass: bool,
    /// True alpha when the injected |ΔC_l| first reaches `onset_fraction` of
    /// its largest value, deg (NaN when the stall never met the roll-off).
    pub onset_alpha_deg: f64,
    /// Time of that onset, s (NaN when none).
    pub onset_t: f64,
    /// Signed largest injected ΔC_l met (0 when none): the roll-off magnitude.
    pub peak: f64,
    /// Direction of the roll-off met: +1 right wing down, −1 left, 0 none.
    pub direction: i8,
    /// Signed peak of the draw that made the roll-off met (s k A_f, reached only if
    /// alpha gets to the centre); with no roll-off met, of the draw at the first
    /// crossing of the re-arm alpha (0 when alpha never crossed it).
    pub drawn_peak: f64,
    /// Centre of that draw's Gaussian, deg.
    pub drawn_center_deg: f64,
    /// Time of that draw (its crossing), s; NaN when no draw was made.
    pub drawn_t: f64,
    /// Counted upward crossings of the re-arm alpha (each made new draws; after a
    /// draw, alpha must fall below the re-arm alpha less the hysteresis first).
    pub crossings: usize,
}

/// Fly stall `k` of `spec` and summarise it.
///
/// # Errors
/// When the trim fails or the simulation diverges (naming the maneuver).
pub fn run_stall(spec: &MonteCarloSpec, k: usize) -> Result<StallSummary> {
    let (qual, _) = adx37_models()?;
    let (aero, _, rolloff_on, scale) = resolve_effects(&spec.campaign)?;
    let mut campaign = spec.campaign.clone();
    campaign.rolloff.scale *= if rolloff_on { scale } else { 1.0 };
    fly(&campaign, qual, &aero, rolloff_on, spec, k)
}

fn fly(
    campaign: &CampaignSpec,
    qual: &crate::aircraft::qualified::QualifiedModel,
    aero: &[crate::aircraft::effects::ActiveEffect],
    rolloff_on: bool,
    spec: &MonteCarloSpec,
    k: usize,
) -> Result<StallSummary> {
    let m = spec.plan(k)?;
    let mut f = Flight::new(campaign, qual, aero, rolloff_on, &m)?;
    let mut trace: Vec<(f64, f64, f64)> = Vec::with_capacity(f.max_steps.min(8192));
    let (mut max_alpha, mut max_bank, mut max_drc) = (f64::NEG_INFINITY, 0.0f64, 0.0f64);
    let (mut big, mut big_abs) = (0.0f64, 0.0f64);
    let mut met: Option<RollOffDraw> = None;
    loop {
        let st = f.command();
        let x = &f.sim.x;
        let a_deg = st.air.alpha.to_degrees();
        let (phi, theta) = (x[ix::PHI], x[ix::THETA]);
        // Euler roll rate φ̇ = p + (q sin φ + r cos φ) tan θ, rad/s
        let phidot = x[ix::P] + (x[ix::Q] * phi.sin() + x[ix::R] * phi.cos()) * theta.tan();
        max_alpha = max_alpha.max(a_deg);
        max_bank = max_bank.max(phi.abs().to_degrees());
        max_drc = max_drc.max((phi + phidot).abs().to_degrees());
        if let Some(r) = f.model.rolloff.as_ref() {
            let d = r.delta_cl(a_deg);
            if d != 0.0 {
                trace.push((f.sim.t, a_deg, d));
                if d.abs() > big_abs {
                    (big, big_abs) = (d, d.abs());
                    met = Some(r.current());
                }
            }
        }
        if f.done() {
            break;
        }
        f.integrate(&st, m.index)?;
    }
    let onset = trace
        .iter()
        .find(|(_, _, d)| big_abs > 0.0 && d.abs() >= spec.onset_fraction * big_abs);
    let history = f.model.rolloff.as_ref().map_or(&[][..], |r| &r.history[..]);
    // one draw per counted upward crossing of the re-arm alpha (none before the first)
    let draw = met.or_else(|| history.first().copied());
    Ok(StallSummary {
        stall: k,
        maneuver_index: m.index,
        pusher: m.pusher,
        pusher_fired: f.pusher_fired(),
        duration_s: f.sim.t,
        max_alpha_deg: max_alpha,
        max_bank_deg: max_bank,
        max_dynamic_roll_deg: max_drc,
        far25_203_pass: max_bank <= spec.bank_limit_deg,
        onset_alpha_deg: onset.map_or(f64::NAN, |o| o.1),
        onset_t: onset.map_or(f64::NAN, |o| o.0),
        peak: big,
        direction: if big > 0.0 {
            1
        } else if big < 0.0 {
            -1
        } else {
            0
        },
        drawn_peak: draw.map_or(0.0, |d| d.peak),
        drawn_center_deg: draw.map_or(f64::NAN, |d| d.center_deg),
        drawn_t: draw.map_or(f64::NAN, |d| d.t),
        crossings: history.len(),
    })
}

/// Fly stalls `first .. first + n` of `spec` in parallel (rayon, with the
/// `parallel` feature) and return their summaries in stall order. `threads`:
/// the size of a dedicated pool (`None`: rayon's global pool, sized by
/// `RAYON_NUM_THREADS` or the core count). The result does not depend on it.
///
/// # Errors
/// An invalid spec, or the first stall that failed (naming it).
pub fn run_monte_carlo(spec: &MonteCarloSpec, threads: Option<usize>) -> Result<Vec<StallSummary>> {
    let (qual, _) = adx37_models()?;
    let (aero, _, rolloff_on, scale) = resolve_effects(&spec.campaign)?;
    if !(0.0..=1.0).contains(&spec.onset_fraction) || spec.onset_fraction == 0.0 {
        return Err(AeroError::invalid(
            "Monte Carlo onset_fraction",
            format!("{} must lie in (0, 1]", spec.onset_fraction),
        ));
    }
    if !(spec.campaign.sim_hz.is_finite() && spec.campaign.sim_hz > 0.0) {
        return Err(AeroError::invalid(
            "Monte Carlo campaign.sim_hz",
            "must be a positive rate, Hz",
        ));
    }
    spec.plan(spec.first)?;
    let mut campaign = spec.campaign.clone();
    campaign.rolloff.scale *= if rolloff_on { scale } else { 1.0 };
    let run = |k: usize| fly(&campaign, qual, &aero, rolloff_on, spec, k);
    let range = spec.first..spec.first + spec.n;
    #[cfg(feature = "parallel")]
    let results: Vec<Result<StallSummary>> = {
        use rayon::prelude::*;
        let go = || range.clone().into_par_iter().map(run).collect();
        match threads {
            Some(t) => rayon::ThreadPoolBuilder::new()
                .num_threads(t.max(1))
                .build()
                .map_err(|e| AeroError::invalid("Monte Carlo thread pool", e.to_string()))?
                .install(go),
            None => go(),
        }
    };
    #[cfg(not(feature = "parallel"))]
    let results: Vec<Result<StallSummary>> = {
        let _ = threads;
        range.map(run).collect()
    };
    results.into_iter().collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aircraft::truth::EffectSpec;
    use crate::sim::campaign::run_campaign;

    fn spec(seed: u64, flap_deg: f64, n: usize) -> MonteCarloSpec {
        MonteCarloSpec {
            campaign: CampaignSpec {
                seed,
                effects: vec![EffectSpec {
                    name: "stochastic_rolloff".into(),
                    magnitude: 1.0,
                    shape: None,
                }],
                record_hz: 100.0,
                ..CampaignSpec::default()
            },
            flap_deg,
            n,
            ..MonteCarloSpec::default()
        }
    }

    #[test]
    fn stall_summary_equals_the_campaign_maneuvers_truth() {
        // stalls 2, 3 are the straight stalls (pusher on, off) of repetition 1 at flap 10
        let mut s = spec(11, 10.0, 2);
        s.first = 2;
        let mc = run_monte_carlo(&s, Some(1)).unwrap();
        let mut c = s.campaign.clone();
        c.repetitions = 2;
        c.only = vec![mc[0].maneuver_index, mc[1].maneuver_index];
        let camp = run_campaign(&c).unwrap();
        for (a, m) in mc.iter().zip(&camp) {
            assert_eq!(m.plan.kind, Kind::Straight);
            assert_eq!(a.pusher, m.plan.pusher);
            assert_eq!(a.pusher_fired, m.pusher_fired);
            // the campaign records every step at 100 Hz: same maxima
            assert_eq!(a.max_bank_deg, m.max_bank_deg, "{}", m.id);
            assert_eq!(a.max_alpha_deg, m.max_alpha_deg, "{}", m.id);
            let col = |name: &str| {
                let i = m.truth_names.iter().position(|n| n == name).unwrap();
                &m.truth[i]
            };
            let (t, alpha, d) = (
                col("t"),
                col("alpha_true_deg"),
                col("dCl_stochastic_rolloff"),
            );
            let big = d
                .iter()
                .fold(0.0f64, |b, v| if v.abs() > b.abs() { *v } else { b });
            assert_eq!(a.peak, big);
            let i = d.iter().position(|v| v.abs() >= 0.2 * big.abs()).unwrap();
            assert_eq!(a.onset_alpha_deg, alpha[i]);
            assert_eq!(a.onset_t, t[i]);
            assert!((a.duration_s - t[t.len() - 1]).abs() < 1e-9);
        }
    }

    #[cfg(feature = "parallel")]
    #[test]
    fn thread_count_does_not_change_results() {
        let s = spec(4, 0.0, 6);
        let one = run_monte_carlo(&s, Some(1)).unwrap();
        let two = run_monte_carlo(&s, Some(2)).unwrap();
        let global = run_monte_carlo(&s, None).unwrap();
        assert_eq!(one.len(), 6);
        for ((a, b), c) in one.iter().zip(&two).zip(&global) {
            // bitwise equality (NaN onsets compare equal through their bits)
            assert_eq!(format!("{a:?}"), format!("{b:?}"));
            assert_eq!(format!("{a:?}"), format!("{c:?}"));
        }
        // a sub-range gives the same stalls
        let mut sub = s.clone();
        sub.first = 3;
        sub.n = 2;
        let part = run_monte_carlo(&sub, Some(2)).unwrap();
        assert_eq!(format!("{:?}", part[0]), format!("{:?}", one[3]));
    }

    #[test]
    fn drawn_peak_is_met_when_alpha_passes_the_centre() {
        // when the stall's alpha exceeds the Gaussian's centre, the largest ΔC_l met is
        // the drawn peak (to the sampling of the 100 Hz steps), its onset alpha lies
        // sqrt(2 ln 5) widths below the centre (20 % of the peak on the rising side)
        let s = spec(21, 15.0, 8);
        let mc = run_monte_carlo(&s, None).unwrap();
        let width = s.campaign.rolloff.width_deg;
        let mut checked = 0;
        for a in &mc {
            // the draw made at the stall's (counted) crossing of the re-arm alpha, when
            // its centre lies far enough above it for the whole rising flank to be met
            if a.crossings == 1
                && a.drawn_center_deg > s.campaign.rolloff.rearm_alpha_deg + 1.0
                && a.max_alpha_deg > a.drawn_center_deg + 0.5
                && a.drawn_peak != 0.0
            {
                assert!((a.peak / a.drawn_peak - 1.0).abs() < 0.01, "{a:?}");
                let z = (2.0 * 5f64.ln()).sqrt() * width;
                assert!(
                    (a.onset_alpha_deg - (a.drawn_center_deg - z)).abs() < 0.1,
                    "{a:?}"
                );
                assert_eq!(a.direction as f64, a.drawn_peak.signum());
                checked += 1;
            }
            assert_eq!(a.far25_203_pass, a.max_bank_deg <= 20.0);
        }
        assert!(checked >= 2, "only {checked} stalls passed the centre");
    }

    #[test]
    fn unknown_flap_is_rejected() {
        let s = spec(1, 12.0, 1);
        let e = run_monte_carlo(&s, Some(1)).unwrap_err();
        assert!(e.to_string().contains("flap"), "{e}");
    }
}
