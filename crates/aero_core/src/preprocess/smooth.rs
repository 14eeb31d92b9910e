//! Zero-phase optimal Fourier (Wiener) smoother for flight data, after SIDPAC
//! `smoo` (Klein & Morelli, *Aircraft System Identification*, 2006;
//! thesis Section 3.2.3 uses SIDPAC).
//!
//! Steps, for samples $x_0..x_{n-1}$ at interval $\Delta t$:
//! 1. remove the straight line through the end values $\hat x_0, \hat x_{n-1}$ (each from a
//!    least-squares quadratic over the first/last 5 % of the record, 5 to 50 samples, so one
//!    noisy end sample does not tilt the record): $d_j = x_j - \hat x_0 - (\hat x_{n-1}-\hat x_0)\,j/(n-1)$;
//! 2. extend $d$ as an odd sequence (a sine series: no jump and no kink at either end, so no
//!    Gibbs ringing). To use a power-of-two FFT, the half period $H$ is the next power of two
//!    $\ge n-1$; the $L = H-(n-1)$ samples past the end are the odd reflection about the end,
//!    $d_{n-1+j} = -d_{n-1-j}\,w_j$, under a taper $w_j = \cos^2(\pi j/(2(L+1)))$ (value and slope
//!    stay continuous at the end, and the bridge reaches 0 at $H$). The sequence, odd about 0
//!    and $H$, has period $M = 2H$; its DFT is $D_k$, $f_k = k/(M\Delta t)$;
//! 3. estimate the white-noise floor $N_0$ as the mean of $|D_k|^2$ over the top 40 % of
//!    the band, fit $\ln |D_k|^2 = a + b k$ over the band where the (running-mean)
//!    spectrum stands above $2N_0$ (bins $k \le k_b$): the signal model is
//!    $S_k = \max(e^{a+bk}, \bar P_k - N_0)$ for $k \le k_b$ and $e^{a+bk}$ above;
//! 4. apply the real, even (hence zero-phase) Wiener weights $W_k = S_k/(S_k+N_0)$, invert,
//!    add the line back. Two channels share one complex FFT (real and imaginary parts).
//!
//! The cut-off reported is where the signal model meets the noise floor,
//! $f_c = k_c/(M\Delta t)$ with $a + b k_c = \ln N_0$; the noise standard deviation is
//! $\hat\sigma = \sqrt{N_0/N_e}$ with $N_e = 2(n-2) + 2\sum_j w_j^2$ the noise-carrying
//! samples of the extended sequence (for white noise $E|D_k|^2 = N_e\sigma^2$).

use nalgebra::Complex;

use super::fft::FftPlan;

type C = Complex<f64>;

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
    /// Half period H (power of two >= n-1).
    half: usize,
    taper: Vec<f64>,
    n_eff: f64,
    plan: Option<FftPlan>,
}

/// Wiener weights for bins 0..=H, the cut-off bin and the noise floor.
struct Design {
    weights: Vec<f64>,
    kcut: f64,
    noise: f64,
    filter: bool,
}

impl Smoother {
    /// Plan a smoother for records of `n` samples.
    pub fn new(n: usize) -> Self {
        if n < 8 {
            return Smoother {
                n,
                half: 0,
                taper: vec![],
                n_eff: 1.0,
                plan: None,
            };
        }
        let half = (n - 1).next_power_of_two();
        let l = half - (n - 1);
        let taper: Vec<f64> = (0..=l)
            .map(|j| {
                let c = (std::f64::consts::PI * j as f64 / (2.0 * (l + 1) as f64)).cos();
                c * c
            })
            .collect();
        let n_eff = 2.0 * ((n - 2) as f64 + taper.iter().skip(1).map(|w| w * w).sum::<f64>());
        Smoother {
            n,
            half,
            taper,
            n_eff,
            plan: Some(FftPlan::new(2 * half)),
        }
    }

    /// Detrend and extend `x` into the real (`imag = false`) or imaginary part of `buf`.
    fn fill(&self, buf: &mut [C], x: &[f64], imag: bool) -> (f64, f64) {
        let n = self.n;
        let h = self.half;
        let m = 2 * h;
        let k = (n / 20).clamp(5, 50).min(n);
        let x0 = end_value(x[..k].iter().copied());
        let x1 = end_value(x[n - k..].iter().rev().copied());
        let slope = (x1 - x0) / (n - 1) as f64;
        let mut d = vec![0.0; h + 1];
        for j in 1..n {
            d[j] = x[j] - x0 - slope * j as f64;
        }
        for j in 1..self.taper.len() {
            if n - 1 + j < h {
                d[n - 1 + j] = -d[n - 1 - j] * self.taper[j];
            }
        }
        let set = |c: &mut C, v: f64| {
            if imag {
                c.im = v;
            } else {
                c.re = v;
            }
        };
        for j in 1..h {
            set(&mut buf[j], d[j]);
            set(&mut buf[m - j], -d[j]);
        }
        (x0, slope)
    }

    fn design(&self, power: &[f64]) -> Design {
        let kmax = self.half;
        let lo = ((0.6 * kmax as f64) as usize).max(1);
        let noise: f64 = power[lo..=kmax].iter().sum::<f64>() / (kmax - lo + 1) as f64;
        let pass = Design {
            weights: vec![1.0; kmax + 1],
            kcut: kmax as f64,
            noise,
            filter: false,
        };
        if noise.is_nan() || noise <= 0.0 || !noise.is_finite() {
            return pass;
        }
        // running mean of the power spectrum
        let w = (kmax / 200).max(2);
        let mut pbar = vec![0.0; kmax + 1];
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
            return pass;
        }
        let kcut = if a.is_finite() {
            ((noise.ln() - a) / b).clamp(0.0, kmax as f64)
        } else {
            kc as f64
        };
        let weights = (0..=kmax)
            .map(|k| {
                if k == 0 {
                    return 1.0;
                }
                let model = if a.is_finite() {
                    (a + b * k as f64).exp()
                } else {
                    0.0
                };
                // trust the measured spectrum only inside the signal band
                let emp = if k <= kc { pbar[k] - noise } else { 0.0 };
                let s = model.max(emp).max(0.0);
                s / (s + noise)
            })
            .collect();
        Design {
            weights,
            kcut,
            noise,
            filter: true,
        }
    }

    fn unchanged(&self, x: &[f64], dt: f64) -> Smoothed {
        Smoothed {
            values: x.to_vec(),
            cutoff_hz: 0.5 / dt,
            noise_std: 0.0,
        }
    }

    fn result(&self, x: &[f64], dt: f64, d: &Design, vals: Vec<f64>) -> Smoothed {
        let m = 2 * self.half;
        let noise_std = (d.noise / self.n_eff).sqrt();
        if !d.filter {
            return Smoothed {
                values: x.to_vec(),
                cutoff_hz: 0.5 / dt,
                noise_std,
            };
        }
        Smoothed {
            values: vals,
            cutoff_hz: d.kcut / (m as f64 * dt),
            noise_std,
        }
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
        let (a, _) = self.smooth_pair(x, x, dt);
        a
    }

    /// Smooth two channels of the same record at once (one complex FFT for both).
    pub fn smooth_pair(&self, x: &[f64], y: &[f64], dt: f64) -> (Smoothed, Smoothed) {
        let n = self.n;
        let plan = match &self.plan {
            Some(p) if x.len() == n && y.len() == n => p,
            _ => return (self.unchanged(x, dt), self.unchanged(y, dt)),
        };
        let h = self.half;
        let m = 2 * h;
        let mut buf = vec![C::new(0.0, 0.0); m];
        let (x0, sx) = self.fill(&mut buf, x, false);
        let (y0, sy) = self.fill(&mut buf, y, true);
        plan.run(&mut buf, false);
        // split: X_k = (Z_k + conj Z_{M-k})/2, Y_k = (Z_k - conj Z_{M-k})/(2i)
        let mut px = vec![0.0; h + 1];
        let mut py = vec![0.0; h + 1];
        for k in 0..=h {
            let zk = buf[k];
            let zm = buf[(m - k) % m].conj();
            px[k] = ((zk + zm) * 0.5).norm_sqr();
            py[k] = ((zk - zm) * 0.5).norm_sqr();
        }
        let dx = self.design(&px);
        let dy = self.design(&py);
        let mut out = vec![C::new(0.0, 0.0); m];
        for k in 0..m {
            let kk = if k <= h { k } else { m - k };
            let zk = buf[k];
            let zm = buf[(m - k) % m].conj();
            let xk = (zk + zm) * 0.5;
            let yk = (zk - zm) * C::new(0.0, -0.5);
            out[k] = xk * dx.weights[kk] + C::new(0.0, 1.0) * yk * dy.weights[kk];
        }
        plan.run(&mut out, true);
        let scale = 1.0 / m as f64;
        let mut vx = Vec::with_capacity(n);
        let mut vy = Vec::with_capacity(n);
        for j in 0..n {
            let jf = j as f64;
            let (re, im) = (out[j].re * scale, out[j].im * scale);
            vx.push(re + x0 + sx * jf);
            vy.push(im + y0 + sy * jf);
        }
        (self.result(x, dt, &dx, vx), self.result(y, dt, &dy, vy))
    }
}

/// Value at the first sample of a least-squares quadratic through `xs` (the end points of the
/// detrending line, so that one noisy end sample does not tilt the whole record).
fn end_value(xs: impl Iterator<Item = f64>) -> f64 {
    let (mut m, mut v) = (
        nalgebra::Matrix3::<f64>::zeros(),
        nalgebra::Vector3::<f64>::zeros(),
    );
    let mut first = 0.0;
    for (i, y) in xs.enumerate() {
        if i == 0 {
            first = y;
        }
        let b = nalgebra::Vector3::new(1.0, i as f64, (i * i) as f64);
        m += b * b.transpose();
        v += b * y;
    }
    m.lu().solve(&v).map_or(first, |c| c[0])
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
    fn pair_equals_two_singles() {
        let dt = 0.02;
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let x: Vec<f64> = (0..1234)
            .map(|i| (0.01 * i as f64).sin() + 0.01 * gauss(&mut rng))
            .collect();
        let y: Vec<f64> = (0..1234)
            .map(|i| 3.0 * (0.02 * i as f64).cos() + 0.05 * gauss(&mut rng))
            .collect();
        let sm = Smoother::new(x.len());
        let (a, b) = sm.smooth_pair(&x, &y, dt);
        let (a1, b1) = (sm.smooth(&x, dt), sm.smooth(&y, dt));
        for (u, v) in a
            .values
            .iter()
            .zip(&a1.values)
            .chain(b.values.iter().zip(&b1.values))
        {
            assert!((u - v).abs() < 1e-9);
        }
        assert!(
            (a.cutoff_hz - a1.cutoff_hz).abs() < 1e-9 && (b.noise_std - b1.noise_std).abs() < 1e-12
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
