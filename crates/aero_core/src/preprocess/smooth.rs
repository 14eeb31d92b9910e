//! Zero-phase optimal Fourier (Wiener) smoother for flight data, after SIDPAC
//! `smoo` (Klein & Morelli, *Aircraft System Identification*, 2006;
//! thesis Section 3.2.3 uses SIDPAC).
//!
//! Steps, for samples $x_0..x_{n-1}$ at interval $\Delta t$:
//! 1. remove the straight line through the end points, $d_j = x_j - x_0 - (x_{n-1}-x_0)\,j/(n-1)$,
//!    so $d_0 = d_{n-1} = 0$;
//! 2. extend $d$ as an odd sequence of period $M = 2(n-1)$ (a sine series: no jump and no
//!    kink at either end, so no Gibbs ringing) and take its DFT $D_k$, $f_k = k/(M\Delta t)$;
//! 3. estimate the white-noise floor $N_0$ as the mean of $|D_k|^2$ over the top 40 % of
//!    the band, fit $\ln |D_k|^2 = a + b k$ over the band where the (running-mean)
//!    spectrum stands above $2N_0$ (bins $k \le k_b$): the signal model is
//!    $S_k = \max(e^{a+bk}, \bar P_k - N_0)$ for $k \le k_b$ and $e^{a+bk}$ above;
//! 4. apply the real, even (hence zero-phase) Wiener weights $W_k = S_k/(S_k+N_0)$, invert,
//!    add the line back.
//!
//! The cut-off reported is where the signal model meets the noise floor,
//! $f_c = k_c/(M\Delta t)$ with $a + b k_c = \ln N_0$; the noise standard deviation is
//! $\hat\sigma = \sqrt{N_0/M}$ (for white noise $E|D_k|^2 = M\sigma^2$).

use nalgebra::Complex;

use super::fft::FftPlan;

/// A smoothed signal with the cut-off the data chose.
#[derive(Debug, Clone, PartialEq)]
pub struct Smoothed {
    /// Smoothed samples, same length as the input.
    pub values: Vec<f64>,
    /// Frequency where the signal model meets the noise floor, Hz (Nyquist when no noise was found).
    pub cutoff_hz: f64,
    /// Estimated standard deviation of the white measurement noise, input units.
    pub noise_std: f64,
}

/// Smoother for one record length; reuse it across the channels of a maneuver.
#[derive(Debug, Clone)]
pub struct Smoother {
    n: usize,
    plan: Option<FftPlan>,
}

impl Smoother {
    /// Plan a smoother for records of `n` samples.
    pub fn new(n: usize) -> Self {
        let plan = if n >= 8 {
            Some(FftPlan::new(2 * (n - 1)))
        } else {
            None
        };
        Smoother { n, plan }
    }

    /// Smooth `x` (length `n`, finite) sampled every `dt` seconds. Records shorter than
    /// 8 samples, or a length other than the planned one, are returned unchanged.
    ///
    /// ```
    /// use aero_core::preprocess::smooth::Smoother;
    /// let dt = 0.02;
    /// let x: Vec<f64> = (0..500).map(|i| (i as f64 * dt).sin()).collect();
    /// let s = Smoother::new(x.len()).smooth(&x, dt);
    /// assert!(s.values.iter().zip(&x).all(|(a, b)| (a - b).abs() < 1e-3));
    /// ```
    pub fn smooth(&self, x: &[f64], dt: f64) -> Smoothed {
        let n = x.len();
        let nyq = 0.5 / dt;
        let plan = match &self.plan {
            Some(p) if n == self.n => p,
            _ => {
                return Smoothed {
                    values: x.to_vec(),
                    cutoff_hz: nyq,
                    noise_std: 0.0,
                }
            }
        };
        let m = 2 * (n - 1);
        let x0 = x[0];
        let slope = (x[n - 1] - x0) / (n - 1) as f64;
        let mut buf = vec![Complex::new(0.0, 0.0); m];
        for j in 0..n {
            buf[j].re = x[j] - x0 - slope * j as f64;
        }
        for j in 1..n - 1 {
            buf[m - j].re = -buf[j].re;
        }
        buf[0].re = 0.0;
        buf[n - 1].re = 0.0;
        plan.run(&mut buf, false);
        let kmax = n - 1; // Nyquist bin
        let power: Vec<f64> = (0..=kmax).map(|k| buf[k].norm_sqr()).collect();
        let lo = ((0.6 * kmax as f64) as usize).max(1);
        let noise: f64 = power[lo..=kmax].iter().sum::<f64>() / (kmax - lo + 1) as f64;
        let unchanged = |buf: &[Complex<f64>]| {
            let _ = buf;
            Smoothed {
                values: x.to_vec(),
                cutoff_hz: nyq,
                noise_std: (noise / m as f64).sqrt(),
            }
        };
        if noise.is_nan() || noise <= 0.0 || !noise.is_finite() {
            return unchanged(&buf);
        }
        // running mean of the power spectrum
        let w = (kmax / 200).max(2);
        let mut pbar = vec![0.0; kmax + 1];
        {
            let mut acc = 0.0;
            let mut cnt = 0usize;
            let (mut a, mut b) = (1usize, 1usize); // window [a, b)
            for k in 1..=kmax {
                let want_a = k.saturating_sub(w).max(1);
                let want_b = (k + w + 1).min(kmax + 1);
                while b < want_b {
                    acc += power[b];
                    cnt += 1;
                    b += 1;
                }
                while a < want_a {
                    acc -= power[a];
                    cnt -= 1;
                    a += 1;
                }
                pbar[k] = acc / cnt.max(1) as f64;
            }
        }
        let kc = (1..=kmax).find(|&k| pbar[k] <= 2.0 * noise).unwrap_or(kmax);
        // log-linear fit of the signal spectrum over 1..kc where it stands above the floor
        let (mut s0, mut s1, mut s2, mut sy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for k in 1..=kc {
            if power[k] > noise {
                let kf = k as f64;
                let y = power[k].ln();
                s0 += 1.0;
                s1 += kf;
                s2 += kf * kf;
                sy += y;
                sxy += kf * y;
            }
        }
        let det = s0 * s2 - s1 * s1;
        let (a, b) = if s0 >= 2.0 && det > 0.0 {
            let b = (s0 * sxy - s1 * sy) / det;
            ((sy - b * s1) / s0, b)
        } else {
            // no resolvable signal band: pass only what clearly stands above the floor
            (f64::NEG_INFINITY, -1.0)
        };
        if b >= 0.0 {
            return unchanged(&buf);
        }
        let kcut = if a.is_finite() {
            ((noise.ln() - a) / b).clamp(0.0, kmax as f64)
        } else {
            kc as f64
        };
        for k in 0..=kmax {
            let model = if a.is_finite() {
                (a + b * k as f64).exp()
            } else {
                0.0
            };
            // trust the measured spectrum only inside the signal band
            let emp = if k <= kc { pbar[k] - noise } else { 0.0 };
            let s = model.max(emp).max(0.0);
            let wk = if k == 0 { 1.0 } else { s / (s + noise) };
            buf[k] *= wk;
            if k > 0 && k < m - k {
                buf[m - k] *= wk;
            }
        }
        plan.run(&mut buf, true);
        let scale = 1.0 / m as f64;
        let values = (0..n)
            .map(|j| buf[j].re * scale + x0 + slope * j as f64)
            .collect();
        Smoothed {
            values,
            cutoff_hz: kcut / (m as f64 * dt),
            noise_std: (noise / m as f64).sqrt(),
        }
    }
}

/// Smooth one signal (plans a [`Smoother`] for its length).
pub fn smooth(x: &[f64], dt: f64) -> Smoothed {
    Smoother::new(x.len()).smooth(x, dt)
}

#[cfg(test)]
pub(crate) mod tests_support {
    use rand_chacha::ChaCha8Rng;
    use rand_core::Rng;

    /// Standard normal draw (Box-Muller) for seeded test noise.
    pub(crate) fn gauss(rng: &mut ChaCha8Rng) -> f64 {
        let u1 = ((rng.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
        let u2 = ((rng.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::tests_support::gauss;
    use super::*;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;

    #[test]
    fn removes_white_noise_and_keeps_the_signal() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let dt = 0.02;
        let n = 3000;
        let sigma = 0.05;
        let truth: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 * dt;
                2.0 * (2.0 * std::f64::consts::PI * 0.2 * t).sin()
                    + 0.5 * t / 60.0
                    + 0.3 * (1.3 * t).cos()
            })
            .collect();
        let x: Vec<f64> = truth.iter().map(|v| v + sigma * gauss(&mut rng)).collect();
        let s = smooth(&x, dt);
        let rms = (s
            .values
            .iter()
            .zip(&truth)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / n as f64)
            .sqrt();
        // error well below the noise (bound: sigma / 4)
        assert!(rms < sigma / 4.0, "rms {rms}");
        assert!(
            (s.noise_std - sigma).abs() < 0.2 * sigma,
            "noise {}",
            s.noise_std
        );
        assert!(
            s.cutoff_hz > 0.2 && s.cutoff_hz < 5.0,
            "cutoff {}",
            s.cutoff_hz
        );
    }

    #[test]
    fn constant_and_short_signals_pass_unchanged() {
        let x = vec![3.0; 100];
        assert_eq!(smooth(&x, 0.1).values, x);
        let y = vec![1.0, 2.0, 3.0];
        assert_eq!(smooth(&y, 0.1).values, y);
    }
}
