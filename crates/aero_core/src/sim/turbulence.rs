//! Dryden turbulence, MIL-F-8785C forms (medium/high altitude: L_u = L_v =
//! L_w = 1750 ft = 533.4 m), driven by a seeded normal stream.
//!
//! With T = L/V and white noise of unit two-sided spectral density,
//! H_u(s) = σ_u √(2T) / (1 + T s) and H_{v,w}(s) = σ √T (1 + √3 T s)/(1 + T s)²
//! give output variances σ_u², σ² (the MIL-F-8785C spectra up to the
//! normalisation of the input). Integrated by forward Euler at the loop's step
//! (T ≈ 9 s ≫ dt), the sampled noise having variance 1/dt.

use nalgebra::Vector3;

use crate::sim::rng::Stream;

/// MIL-F-8785C scale length above 2000 ft, m.
pub const L_HIGH_M: f64 = 533.4;

/// A Dryden gust generator (body-axis gust velocities u_g, v_g, w_g).
#[derive(Debug, Clone)]
pub struct Dryden {
    /// RMS intensity per axis, m/s.
    pub sigma: [f64; 3],
    /// Scale length, m.
    pub length_m: f64,
    rng: Stream,
    xu: f64,
    xv: [f64; 2],
    xw: [f64; 2],
}

impl Dryden {
    /// A generator with intensities `sigma` (m/s) on its own stream.
    pub fn new(sigma: [f64; 3], seed: u64, stream: u64) -> Self {
        Dryden {
            sigma,
            length_m: L_HIGH_M,
            rng: Stream::new(seed, stream),
            xu: 0.0,
            xv: [0.0; 2],
            xw: [0.0; 2],
        }
    }

    /// Advance by `dt` at airspeed `tas`; returns the gust velocity (body axes), m/s.
    pub fn advance(&mut self, tas: f64, dt: f64) -> Vector3<f64> {
        let t = self.length_m / tas.max(10.0);
        let k = 1.0 / dt.sqrt();
        let nu = self.rng.normal() * k;
        let nv = self.rng.normal() * k;
        let nw = self.rng.normal() * k;
        self.xu += dt * (nu - self.xu) / t;
        let second = |x: &mut [f64; 2], n: f64| {
            let x0 = x[0];
            x[0] += dt * (n - x[0]) / t;
            x[1] += dt * (x0 - x[1]) / t;
            x[1] + 3f64.sqrt() * (x[0] - x[1])
        };
        let yv = second(&mut self.xv, nv);
        let yw = second(&mut self.xw, nw);
        Vector3::new(
            self.sigma[0] * (2.0 * t).sqrt() * self.xu,
            self.sigma[1] * t.sqrt() * yv,
            self.sigma[2] * t.sqrt() * yw,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gust_rms_matches_intensity() {
        // Long run at constant speed: sample RMS within 15 % of sigma (the
        // correlation time is ~9 s, so 20 000 s gives ~2000 independent samples).
        let mut d = Dryden::new([1.0, 1.5, 0.8], 3, 0);
        let dt = 0.02;
        let n = 1_000_000;
        let mut s2 = [0.0; 3];
        for _ in 0..n {
            let g = d.advance(60.0, dt);
            for k in 0..3 {
                s2[k] += g[k] * g[k];
            }
        }
        for (k, sig) in [1.0, 1.5, 0.8].iter().enumerate() {
            let rms = (s2[k] / n as f64).sqrt();
            assert!(
                (rms / sig - 1.0).abs() < 0.15,
                "axis {k}: rms {rms} vs {sig}"
            );
        }
    }
}
