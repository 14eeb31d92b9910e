//! The validated envelope of an extended model: where the flight data behind it lie.
//!
//! 14 CFR Part 60 Appendix A (Table A1A, stall characteristics; FSTD Directive 2) asks that the
//! stall model's alpha/beta validity range be declared, supported by flight-test data, and that
//! the simulator show the instructor when the aircraft leaves it (an "outside the validated
//! envelope" indication; ICAO 9625 ed. 4 and EASA CS-FSTD(A) Issue 2 carry the same rule).
//! The envelope stored with a fitted Δ model is the data's α/β coverage per flap setting:
//! the alpha axis is cut into bands of `band_deg`; a band is covered when enough maneuvers
//! (the fit's `min_maneuvers_identified`) have samples in it, and its sideslip range is the
//! smallest and largest β measured there. A state is inside when its band at the nearest
//! flap setting is covered and its β lies within that band's range.
//!
//! This is a data envelope (what was flown), not a statement that the Δ is right there; the
//! identification statistics say that.

use serde::{Deserialize, Serialize};

use crate::error::{AeroError, Result};

/// One covered alpha band of one flap setting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnvelopeBand {
    /// Band index: the band holds `band * band_deg <= alpha < (band + 1) * band_deg`.
    pub band: i64,
    /// Smallest sideslip measured in the band, deg.
    pub beta_min_deg: f64,
    /// Largest sideslip measured in the band, deg.
    pub beta_max_deg: f64,
    /// Maneuvers with samples in the band.
    pub maneuvers: u32,
}

/// The stored envelope (one list of covered bands per flap setting).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnvelopeSpec {
    /// Width of the alpha bands, deg.
    pub band_deg: f64,
    /// Flap settings, deg, increasing.
    pub flaps_deg: Vec<f64>,
    /// Per flap setting, its covered bands in increasing order.
    pub bands: Vec<Vec<EnvelopeBand>>,
    /// Maneuvers a band needs to count as covered (as recorded by the fit).
    pub min_maneuvers: u32,
}

/// A validated envelope, ready to answer [`Envelope::contains`].
#[derive(Debug, Clone, PartialEq)]
pub struct Envelope {
    spec: EnvelopeSpec,
}

impl Envelope {
    /// Check and wrap a stored envelope.
    ///
    /// # Errors
    /// [`AeroError::InvalidInput`] naming the flap and band when the band width is not a
    /// positive finite number, the flaps are not increasing, a flap has no band list, the
    /// bands are not increasing, or a band's β range is not finite with `min <= max`.
    pub fn new(spec: EnvelopeSpec) -> Result<Self> {
        if !(spec.band_deg.is_finite() && spec.band_deg > 0.0) {
            return Err(AeroError::invalid(
                "envelope band_deg",
                format!(
                    "is {}; it must be a positive number of degrees",
                    spec.band_deg
                ),
            ));
        }
        if spec.flaps_deg.is_empty()
            || spec.flaps_deg.iter().any(|f| !f.is_finite())
            || spec.flaps_deg.windows(2).any(|w| w[0] >= w[1])
        {
            return Err(AeroError::invalid(
                "envelope flaps_deg",
                format!(
                    "{:?} must be finite and strictly increasing, at least one",
                    spec.flaps_deg
                ),
            ));
        }
        if spec.bands.len() != spec.flaps_deg.len() {
            return Err(AeroError::invalid(
                "envelope bands",
                format!(
                    "has {} band lists for {} flap settings",
                    spec.bands.len(),
                    spec.flaps_deg.len()
                ),
            ));
        }
        for (flap, bands) in spec.flaps_deg.iter().zip(&spec.bands) {
            if let Some(w) = bands.windows(2).find(|w| w[0].band >= w[1].band) {
                return Err(AeroError::invalid(
                    format!("envelope, flap {flap}"),
                    format!(
                        "bands {} and {} are not in increasing order",
                        w[0].band, w[1].band
                    ),
                ));
            }
            for b in bands {
                let ok = b.beta_min_deg.is_finite()
                    && b.beta_max_deg.is_finite()
                    && b.beta_min_deg <= b.beta_max_deg;
                if !ok {
                    return Err(AeroError::invalid(
                        format!("envelope, flap {flap}, band {}", b.band),
                        format!(
                            "beta range [{}, {}] must be finite with min <= max",
                            b.beta_min_deg, b.beta_max_deg
                        ),
                    ));
                }
            }
        }
        Ok(Envelope { spec })
    }

    /// The stored form.
    pub fn spec(&self) -> &EnvelopeSpec {
        &self.spec
    }

    /// Index of the flap setting nearest `flap_deg` (the lower one on a tie).
    fn nearest_flap(&self, flap_deg: f64) -> usize {
        let f = &self.spec.flaps_deg;
        let mut best = 0;
        for (k, v) in f.iter().enumerate() {
            if (v - flap_deg).abs() < (f[best] - flap_deg).abs() {
                best = k;
            }
        }
        best
    }

    /// True when the state (flap, α, β in deg) lies in a covered band of the nearest flap
    /// setting, within its measured β range. Non-finite inputs are outside.
    pub fn contains(&self, flap_deg: f64, alpha_deg: f64, beta_deg: f64) -> bool {
        if !(flap_deg.is_finite() && alpha_deg.is_finite() && beta_deg.is_finite()) {
            return false;
        }
        let band = (alpha_deg / self.spec.band_deg).floor();
        if band.abs() > 1e15 {
            return false;
        }
        let band = band as i64;
        let bands = &self.spec.bands[self.nearest_flap(flap_deg)];
        match bands.binary_search_by_key(&band, |b| b.band) {
            Ok(i) => {
                let b = &bands[i];
                b.beta_min_deg <= beta_deg && beta_deg <= b.beta_max_deg
            }
            Err(_) => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> EnvelopeSpec {
        let band = |band, lo, hi| EnvelopeBand {
            band,
            beta_min_deg: lo,
            beta_max_deg: hi,
            maneuvers: 3,
        };
        EnvelopeSpec {
            band_deg: 2.0,
            flaps_deg: vec![0.0, 20.0],
            bands: vec![
                vec![band(2, -5.0, 5.0), band(3, -8.0, 6.0), band(5, -2.0, 2.0)],
                vec![band(1, -1.0, 1.0)],
            ],
            min_maneuvers: 2,
        }
    }

    #[test]
    fn inside_and_outside_by_band_beta_and_flap() {
        let e = Envelope::new(spec()).unwrap();
        assert!(e.contains(0.0, 4.0, 0.0)); // band 2, its lower edge
        assert!(e.contains(0.0, 7.99, -8.0)); // band 3, the β minimum itself
        assert!(!e.contains(0.0, 7.99, -8.01));
        assert!(!e.contains(0.0, 8.5, 0.0)); // band 4: not covered (a hole)
        assert!(e.contains(0.0, 10.0, 2.0));
        assert!(!e.contains(0.0, 12.0, 0.0)); // past the last covered band
        assert!(!e.contains(0.0, 3.99, 0.0)); // below the first
        assert!(e.contains(9.0, 5.0, 0.0)); // flap 9 -> nearest 0
        assert!(!e.contains(11.0, 5.0, 0.0)); // flap 11 -> nearest 20: band 2 not covered
        assert!(e.contains(11.0, 2.5, 0.5));
        assert!(e.contains(10.0, 5.0, 0.0)); // a tie goes to the lower flap
        assert!(!e.contains(0.0, f64::NAN, 0.0));
        assert!(!e.contains(0.0, 1e300, 0.0));
    }

    #[test]
    fn malformed_envelopes_are_refused_with_their_place() {
        let mut s = spec();
        s.band_deg = 0.0;
        assert!(Envelope::new(s)
            .unwrap_err()
            .to_string()
            .contains("band_deg"));
        let mut s = spec();
        s.bands[0].swap(0, 1);
        let msg = Envelope::new(s).unwrap_err().to_string();
        assert!(
            msg.contains("flap 0") && msg.contains("increasing"),
            "{msg}"
        );
        let mut s = spec();
        s.bands[1][0].beta_min_deg = 2.0;
        let msg = Envelope::new(s).unwrap_err().to_string();
        assert!(msg.contains("flap 20, band 1"), "{msg}");
        let mut s = spec();
        s.bands.pop();
        assert!(Envelope::new(s)
            .unwrap_err()
            .to_string()
            .contains("1 band lists"));
        let mut s = spec();
        s.flaps_deg = vec![20.0, 0.0];
        assert!(Envelope::new(s).is_err());
    }
}
