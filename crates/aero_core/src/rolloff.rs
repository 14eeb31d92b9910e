//! The runtime stochastic roll-off of thesis Section 3.4.3 ("Implementation",
//! Figure 3.14).
//!
//! A roll-off is a transient rolling-moment spike near stall, uncorrelated with
//! the states. It is modelled as a Gaussian in alpha,
//!
//! ΔC_l(α) = s · k · A_f · exp(−½ ((α − α_f − δα)/σ)²),
//!
//! with, per flap setting f, the mean onset alpha α_f and the mean magnitude
//! A_f of Table 3.2, σ = 0.5 deg ("roll-off that happens within a 1 degree
//! window while having a smooth ramp up"), and three random draws made each
//! time alpha crosses the re-arm alpha (15 deg) from below (thesis: "generated
//! every time the simulation passes through 15° α from below"):
//! - the direction s = +1 (right) with probability 0.58, else −1 (thesis: "58%
//!   Right, 42% Left");
//! - the magnitude factor k ~ N(1, 0.225²), clipped at 0 ("Magnitude variance:
//!   22.5% of mean magnitudes", read as the coefficient of variation);
//! - the centre shift δα ~ N(0, 1.31²) deg ("α standard deviation: 1.31°").
//!
//! One draw per stall, made before the roll-off can act and held for the whole
//! stall: no roll-off acts before the first crossing (ΔC_l = 0 until a draw is
//! made), and after a draw the model re-arms only once alpha has fallen below
//! `rearm_alpha_deg − rearm_hysteresis_deg` (2 deg by default; the stall
//! recovery takes alpha far below it). Without the hysteresis, gusts and stick
//! noise near 15 deg made up to 15 crossings per stall, each replacing the draw
//! abruptly, possibly in the middle of the spike, and the draw met was biased
//! toward low centres (met sooner). A centre drawn below the crossing still
//! starts at the crossing: the onset of a roll-off is never below the re-arm
//! alpha (the statistics account for this truncation, see `aerodelta.rolloff`).
//! The roll-off acts once per draw (thesis: "once started the roll-off seems
//! to end within 1° angle of attack"): once alpha has passed the centre, the
//! Gaussian is evaluated at the alpha *travelled* since, α_top + (α_top − α)
//! with α_top the highest alpha since the draw, so the spike keeps decaying
//! when the stall turns back (stick pusher, recovery) instead of being met a
//! second time on the way down as a short, sharp spike (10-20 deg/s of alpha);
//! it is spent (exactly 0) once that alpha is [`SPENT_WIDTHS`] widths past the
//! centre. A stall that turns back below the centre meets the rising flank
//! only, and the same flank back down.
//!
//! Draws come from a seeded ChaCha8 stream (portable: the same sequence on
//! every machine), one independent stream per instance (seed, stream id), and
//! nothing allocates per step.

use crate::error::{AeroError, Result};
use crate::sim::rng::Stream;

/// Roll-off statistics of one flap setting (thesis Table 3.2).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FlapRollOff {
    /// Flap setting, deg.
    pub flap_deg: f64,
    /// Mean onset alpha, deg.
    pub mean_alpha_deg: f64,
    /// Mean peak |ΔC_l|.
    pub magnitude: f64,
    /// Probability of a right (positive C_l) roll-off.
    pub p_right: f64,
}

/// Configuration of the roll-off model.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RollOffConfig {
    /// One row per flap setting; the nearest row in flap is used.
    pub flaps: Vec<FlapRollOff>,
    /// Width σ of the Gaussian in alpha, deg (thesis: 0.5).
    pub width_deg: f64,
    /// Standard deviation of the centre shift, deg (thesis: 1.31).
    pub alpha_std_deg: f64,
    /// Coefficient of variation of the magnitude factor (thesis: 0.225).
    pub magnitude_cv: f64,
    /// Alpha whose crossing from below makes a new draw, deg (thesis: 15).
    pub rearm_alpha_deg: f64,
    /// After a draw, alpha must fall below `rearm_alpha_deg − rearm_hysteresis_deg`
    /// before a new crossing draws again, deg (default 2: one draw per stall,
    /// however alpha chatters about the re-arm alpha).
    #[serde(default = "default_hysteresis")]
    pub rearm_hysteresis_deg: f64,
    /// Overall scale of the amplitude (1 = thesis magnitudes).
    pub scale: f64,
}

/// Default [`RollOffConfig::rearm_hysteresis_deg`], deg.
pub const DEFAULT_REARM_HYSTERESIS_DEG: f64 = 2.0;

fn default_hysteresis() -> f64 {
    DEFAULT_REARM_HYSTERESIS_DEG
}

impl Default for RollOffConfig {
    /// Thesis Table 3.2 (straight stalls) and the Section 3.4.3 statistics.
    fn default() -> Self {
        let row = |flap_deg, mean_alpha_deg, magnitude| FlapRollOff {
            flap_deg,
            mean_alpha_deg,
            magnitude,
            p_right: 0.58,
        };
        RollOffConfig {
            flaps: vec![
                row(0.0, 17.09, 0.01030),
                row(5.0, 17.81, 0.01587),
                row(10.0, 17.75, 0.01760),
                row(15.0, 18.04, 0.02315),
                row(35.0, 17.60, 0.02566),
            ],
            width_deg: 0.5,
            alpha_std_deg: 1.31,
            magnitude_cv: 0.225,
            rearm_alpha_deg: 15.0,
            rearm_hysteresis_deg: DEFAULT_REARM_HYSTERESIS_DEG,
            scale: 1.0,
        }
    }
}

impl RollOffConfig {
    /// Check the configuration.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the field when a row is missing or a
    /// value is out of its domain.
    pub fn validate(&self) -> Result<()> {
        if self.flaps.is_empty() {
            return Err(AeroError::invalid(
                "rolloff.flaps",
                "is empty; give at least one flap row",
            ));
        }
        for (i, f) in self.flaps.iter().enumerate() {
            if !(0.0..=1.0).contains(&f.p_right) || !f.magnitude.is_finite() {
                return Err(AeroError::invalid(
                    format!("rolloff.flaps[{i}]"),
                    "p_right must lie in [0, 1] and magnitude be finite",
                ));
            }
        }
        if self.width_deg.is_nan()
            || self.width_deg <= 0.0
            || self.alpha_std_deg < 0.0
            || self.magnitude_cv < 0.0
            || self.rearm_hysteresis_deg.is_nan()
            || self.rearm_hysteresis_deg < 0.0
        {
            return Err(AeroError::invalid(
                "rolloff",
                "width_deg must be > 0, alpha_std_deg, magnitude_cv and rearm_hysteresis_deg >= 0",
            ));
        }
        Ok(())
    }

    /// The row whose flap setting is nearest `flap_deg`.
    pub fn for_flap(&self, flap_deg: f64) -> FlapRollOff {
        let mut best = self.flaps[0];
        for f in &self.flaps {
            if (f.flap_deg - flap_deg).abs() < (best.flap_deg - flap_deg).abs() {
                best = *f;
            }
        }
        best
    }
}

/// One set of draws, made at an upward crossing of the re-arm alpha.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RollOffDraw {
    /// Time of the crossing, s.
    pub t: f64,
    /// Direction: +1 right, −1 left.
    pub sign: f64,
    /// Magnitude factor k.
    pub factor: f64,
    /// Centre shift δα, deg.
    pub alpha_shift_deg: f64,
    /// Resulting centre α_f + δα, deg.
    pub center_deg: f64,
    /// Resulting peak ΔC_l = s k A_f.
    pub peak: f64,
}

/// The roll-off is spent once the alpha travelled past its centre exceeds this
/// many widths (exp(−8) = 3.4e-4 of the peak remains there).
pub const SPENT_WIDTHS: f64 = 4.0;

/// Draws kept in [`RollOff::history`] (allocated once; later draws are not kept).
pub const MAX_HISTORY: usize = 64;

/// The stateful roll-off generator of one aircraft.
#[derive(Debug, Clone)]
pub struct RollOff {
    config: RollOffConfig,
    flap: FlapRollOff,
    rng: Stream,
    draw: RollOffDraw,
    last_alpha_deg: f64,
    armed: bool,
    active: bool,
    spent: bool,
    alpha_top_deg: f64,
    /// Every draw made, one per counted crossing of the re-arm alpha.
    pub history: Vec<RollOffDraw>,
}

impl RollOff {
    /// A generator for flap setting `flap_deg` with its own stream (seed, stream id),
    /// armed and inactive: no roll-off acts until alpha first crosses the re-arm alpha.
    ///
    /// # Errors
    /// When the configuration is invalid (see [`RollOffConfig::validate`]).
    pub fn new(config: RollOffConfig, flap_deg: f64, seed: u64, stream: u64) -> Result<Self> {
        config.validate()?;
        let flap = config.for_flap(flap_deg);
        let r = RollOff {
            config,
            flap,
            rng: Stream::new(seed, stream),
            draw: RollOffDraw {
                t: 0.0,
                sign: 0.0,
                factor: 0.0,
                alpha_shift_deg: 0.0,
                center_deg: flap.mean_alpha_deg,
                peak: 0.0,
            },
            last_alpha_deg: f64::NEG_INFINITY,
            armed: true,
            active: false,
            spent: false,
            alpha_top_deg: f64::NEG_INFINITY,
            history: Vec::with_capacity(MAX_HISTORY),
        };
        Ok(r)
    }

    /// Make a new set of draws (time `t`, s).
    pub fn redraw(&mut self, t: f64) -> RollOffDraw {
        let c = &self.config;
        let sign = if self.rng.bernoulli(self.flap.p_right) {
            1.0
        } else {
            -1.0
        };
        let factor = (1.0 + c.magnitude_cv * self.rng.normal()).max(0.0);
        let shift = c.alpha_std_deg * self.rng.normal();
        self.active = true;
        self.spent = false;
        self.alpha_top_deg = f64::NEG_INFINITY;
        self.draw = RollOffDraw {
            t,
            sign,
            factor,
            alpha_shift_deg: shift,
            center_deg: self.flap.mean_alpha_deg + shift,
            peak: sign * factor * self.flap.magnitude * c.scale,
        };
        if self.history.len() < MAX_HISTORY {
            self.history.push(self.draw);
        }
        self.draw
    }

    /// The current draws (peak 0, sign 0 before the first draw: no roll-off).
    pub fn current(&self) -> RollOffDraw {
        self.draw
    }

    /// True once a draw has been made (the roll-off can act).
    pub fn is_active(&self) -> bool {
        self.active
    }

    /// True once alpha has passed the current draw's spike (no ΔC_l until the next draw).
    pub fn is_spent(&self) -> bool {
        self.spent
    }

    /// Feed the alpha at time `t` (once per step): redraw on an upward crossing
    /// of the re-arm alpha when armed; re-arm once alpha is below the re-arm
    /// alpha less the hysteresis; mark the roll-off spent once alpha is past the
    /// spike. Returns true when a new draw was made.
    pub fn update(&mut self, t: f64, alpha_deg: f64) -> bool {
        let rearm = self.config.rearm_alpha_deg;
        if self.active {
            if self.effective_alpha(alpha_deg)
                >= self.draw.center_deg + SPENT_WIDTHS * self.config.width_deg
            {
                self.spent = true;
            }
            self.alpha_top_deg = self.alpha_top_deg.max(alpha_deg);
        }
        if alpha_deg < rearm - self.config.rearm_hysteresis_deg {
            self.armed = true;
        }
        let crossed = self.armed
            && self.last_alpha_deg < rearm
            && alpha_deg >= rearm
            && self.last_alpha_deg.is_finite();
        self.last_alpha_deg = alpha_deg;
        if crossed {
            self.armed = false;
            self.redraw(t);
        }
        crossed
    }

    /// The alpha at which the Gaussian is evaluated, deg: `alpha_deg` until alpha has
    /// passed the centre, then the alpha travelled since, α_top + (α_top − α).
    fn effective_alpha(&self, alpha_deg: f64) -> f64 {
        let top = self.alpha_top_deg.max(alpha_deg);
        if top >= self.draw.center_deg {
            top + (top - alpha_deg)
        } else {
            alpha_deg
        }
    }

    /// ΔC_l at `alpha_deg` with the current draws and alpha history (pure).
    pub fn delta_cl(&self, alpha_deg: f64) -> f64 {
        if self.draw.peak == 0.0 || self.spent {
            return 0.0; // no draw yet (or a zero draw), or the spike already traversed
        }
        let z = (self.effective_alpha(alpha_deg) - self.draw.center_deg) / self.config.width_deg;
        if z.abs() > 12.0 {
            return 0.0; // exp(-72) < 1e-31: below any double-precision C_l sum
        }
        self.draw.peak * (-0.5 * z * z).exp()
    }
}

/// `n` successive draws of a fresh generator, as `n` counted crossings would make
/// them (for statistics and the Python API).
///
/// # Errors
/// When the configuration is invalid.
pub fn sample_draws(
    config: &RollOffConfig,
    flap_deg: f64,
    seed: u64,
    stream: u64,
    n: usize,
) -> Result<Vec<RollOffDraw>> {
    let mut r = RollOff::new(config.clone(), flap_deg, seed, stream)?;
    Ok((0..n).map(|i| r.redraw(i as f64)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draw_statistics_match_configuration() {
        // 1e5 crossings: direction probability, magnitude CV and alpha spread
        // within 5 standard errors of the configured values.
        let cfg = RollOffConfig::default();
        let mut r = RollOff::new(cfg.clone(), 10.0, 42, 3).unwrap();
        let n = 100_000usize;
        let (mut right, mut sk, mut sk2, mut sa, mut sa2) = (0usize, 0.0, 0.0, 0.0, 0.0);
        for i in 0..n {
            // one stall per cycle: recovery below the hysteresis band, then a crossing
            r.update(i as f64, 12.0);
            assert!(r.update(i as f64 + 0.5, 16.0));
            let d = r.current();
            right += usize::from(d.sign > 0.0);
            sk += d.factor;
            sk2 += d.factor * d.factor;
            sa += d.alpha_shift_deg;
            sa2 += d.alpha_shift_deg * d.alpha_shift_deg;
        }
        let nf = n as f64;
        let p = right as f64 / nf;
        assert!(
            (p - 0.58).abs() < 5.0 * (0.58 * 0.42 / nf).sqrt(),
            "p_right {p}"
        );
        let mk = sk / nf;
        let sdk = (sk2 / nf - mk * mk).sqrt();
        assert!(
            (mk - 1.0).abs() < 5.0 * 0.225 / nf.sqrt(),
            "mean factor {mk}"
        );
        assert!((sdk - 0.225).abs() < 0.01, "factor sd {sdk}");
        let ma = sa / nf;
        let sda = (sa2 / nf - ma * ma).sqrt();
        assert!(ma.abs() < 5.0 * 1.31 / nf.sqrt());
        assert!(
            (sda - 1.31).abs() < 5.0 * 1.31 / (2.0 * nf).sqrt(),
            "alpha sd {sda}"
        );
    }

    #[test]
    fn redraws_only_on_armed_upward_crossing_and_shape_is_gaussian() {
        let cfg = RollOffConfig::default();
        let mut r = RollOff::new(cfg, 0.0, 1, 0).unwrap();
        // no roll-off before the first draw, whatever the alpha
        assert!(!r.is_active());
        assert_eq!(r.delta_cl(17.09), 0.0);
        assert!(!r.update(0.0, 10.0));
        assert!(r.update(0.1, 15.5));
        assert!(r.is_active());
        let first = r.current();
        assert!(!r.update(0.2, 16.0));
        // chatter about 15 deg within the 2 deg hysteresis: the draw is held
        assert!(!r.update(0.3, 14.0));
        assert!(!r.update(0.4, 15.0));
        assert_eq!(r.current(), first);
        // recovery below 13 deg re-arms; the next crossing draws again
        assert!(!r.update(0.5, 12.9));
        assert!(r.update(0.6, 15.0));
        assert_ne!(r.current(), first);
        let d = r.current();
        assert!((r.delta_cl(d.center_deg) - d.peak).abs() < 1e-15);
        let one_sigma = r.delta_cl(d.center_deg + 0.5) / d.peak;
        assert!((one_sigma - (-0.5f64).exp()).abs() < 1e-12);
        assert_eq!(r.history.len(), 2);
        assert_eq!(r.history[0], first);
        // once past the centre the spike decays with the alpha travelled, up or down
        assert!(!r.update(0.65, d.center_deg + 0.25));
        let back = r.delta_cl(d.center_deg) / d.peak; // 0.25 up + 0.25 down = 1 width
        assert!((back - (-0.5f64).exp()).abs() < 1e-12, "{back}");
        assert!(r.delta_cl(d.center_deg - 3.0).abs() < 1e-9 * d.peak.abs());
        // past the spike by 4 widths it is spent: alpha falling back meets nothing
        assert!(!r.update(0.7, d.center_deg + 2.0));
        assert!(r.is_spent());
        assert_eq!(r.delta_cl(d.center_deg), 0.0);
        assert!(!r.update(0.8, 12.0));
        assert!(r.update(0.9, 15.5));
        assert!(!r.is_spent());
        assert_eq!(r.history[1].t, 0.6);
        // same seed, same draws; other stream, other draws
        let cfg = RollOffConfig::default();
        let a = sample_draws(&cfg, 0.0, 1, 0, 3).unwrap();
        assert_eq!(a, sample_draws(&cfg, 0.0, 1, 0, 3).unwrap());
        assert_ne!(a, sample_draws(&cfg, 0.0, 1, 1, 3).unwrap());
        assert_eq!(a[0].sign.abs(), 1.0);
    }

    #[test]
    fn zero_hysteresis_redraws_on_every_crossing_and_old_configs_parse() {
        let mut r = RollOff::new(
            RollOffConfig {
                rearm_hysteresis_deg: 0.0,
                ..RollOffConfig::default()
            },
            0.0,
            1,
            0,
        )
        .unwrap();
        r.update(0.0, 14.9);
        assert!(r.update(0.1, 15.1));
        r.update(0.2, 14.9);
        assert!(r.update(0.3, 15.1));
        // a configuration written before the hysteresis existed gets the default
        let mut v = serde_json::to_value(RollOffConfig::default()).unwrap();
        v.as_object_mut().unwrap().remove("rearm_hysteresis_deg");
        let back: RollOffConfig = serde_json::from_value(v).unwrap();
        assert_eq!(back.rearm_hysteresis_deg, DEFAULT_REARM_HYSTERESIS_DEG);
        let bad = RollOffConfig {
            rearm_hysteresis_deg: -1.0,
            ..RollOffConfig::default()
        };
        assert!(bad.validate().is_err());
    }
}
