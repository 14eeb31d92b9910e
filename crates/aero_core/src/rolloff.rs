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
//! time alpha crosses the re-arm alpha (15 deg) from below:
//! - the direction s = +1 (right) with probability 0.58, else −1 (thesis: "58%
//!   Right, 42% Left");
//! - the magnitude factor k ~ N(1, 0.225²), clipped at 0 ("Magnitude variance:
//!   22.5% of mean magnitudes", read as the coefficient of variation);
//! - the centre shift δα ~ N(0, 1.31²) deg ("α standard deviation: 1.31°").
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
    /// Alpha whose crossing from below re-arms the draws, deg (thesis: 15).
    pub rearm_alpha_deg: f64,
    /// Overall scale of the amplitude (1 = thesis magnitudes).
    pub scale: f64,
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
        {
            return Err(AeroError::invalid(
                "rolloff",
                "width_deg must be > 0, alpha_std_deg and magnitude_cv >= 0",
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
    /// Time of the crossing, s (0 for the initial draw).
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
    /// Every draw made (the initial one first).
    pub history: Vec<RollOffDraw>,
}

impl RollOff {
    /// A generator for flap setting `flap_deg` with its own stream (seed, stream id);
    /// the first draw is made at once.
    ///
    /// # Errors
    /// When the configuration is invalid (see [`RollOffConfig::validate`]).
    pub fn new(config: RollOffConfig, flap_deg: f64, seed: u64, stream: u64) -> Result<Self> {
        config.validate()?;
        let flap = config.for_flap(flap_deg);
        let mut r = RollOff {
            config,
            flap,
            rng: Stream::new(seed, stream),
            draw: RollOffDraw {
                t: 0.0,
                sign: 1.0,
                factor: 1.0,
                alpha_shift_deg: 0.0,
                center_deg: flap.mean_alpha_deg,
                peak: 0.0,
            },
            last_alpha_deg: f64::NEG_INFINITY,
            history: Vec::with_capacity(MAX_HISTORY),
        };
        r.redraw(0.0);
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

    /// The current draws.
    pub fn current(&self) -> RollOffDraw {
        self.draw
    }

    /// Feed the alpha at time `t` (once per step): redraw on an upward crossing
    /// of the re-arm alpha. Returns true when a new draw was made.
    pub fn update(&mut self, t: f64, alpha_deg: f64) -> bool {
        let rearm = self.config.rearm_alpha_deg;
        let crossed =
            self.last_alpha_deg < rearm && alpha_deg >= rearm && self.last_alpha_deg.is_finite();
        self.last_alpha_deg = alpha_deg;
        if crossed {
            self.redraw(t);
        }
        crossed
    }

    /// ΔC_l at `alpha_deg` with the current draws (pure).
    pub fn delta_cl(&self, alpha_deg: f64) -> f64 {
        let z = (alpha_deg - self.draw.center_deg) / self.config.width_deg;
        if z.abs() > 12.0 {
            return 0.0; // exp(-72) < 1e-31: below any double-precision C_l sum
        }
        self.draw.peak * (-0.5 * z * z).exp()
    }
}

/// `n` successive draws of a fresh generator (for statistics and the Python API).
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
    let mut out = Vec::with_capacity(n);
    out.push(r.current());
    for i in 1..n {
        out.push(r.redraw(i as f64));
    }
    Ok(out)
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
            // one upward crossing of the re-arm alpha per cycle
            r.update(i as f64, 14.0);
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
    fn redraws_only_on_upward_crossing_and_shape_is_gaussian() {
        let cfg = RollOffConfig::default();
        let mut r = RollOff::new(cfg, 0.0, 1, 0).unwrap();
        assert!(!r.update(0.0, 10.0));
        assert!(r.update(0.1, 15.5));
        assert!(!r.update(0.2, 16.0));
        assert!(!r.update(0.3, 14.0));
        assert!(r.update(0.4, 15.0));
        let d = r.current();
        assert!((r.delta_cl(d.center_deg) - d.peak).abs() < 1e-15);
        let one_sigma = r.delta_cl(d.center_deg + 0.5) / d.peak;
        assert!((one_sigma - (-0.5f64).exp()).abs() < 1e-12);
        assert_eq!(r.history.len(), 3);
        // same seed, same draws; other stream, other draws
        let a = RollOff::new(RollOffConfig::default(), 0.0, 1, 0)
            .unwrap()
            .current();
        let b = RollOff::new(RollOffConfig::default(), 0.0, 1, 1)
            .unwrap()
            .current();
        assert_eq!(
            a,
            RollOff::new(RollOffConfig::default(), 0.0, 1, 0)
                .unwrap()
                .current()
        );
        assert_ne!(a, b);
    }
}
