//! Zero-phase optimal Fourier (Wiener) smoother for flight data, after SIDPAC
//! `smoo` (Klein & Morelli, *Aircraft System Identification*, 2006;
//! thesis Section 3.2.3 uses SIDPAC).
//!
//! Steps, for samples $x_0..x_{n-1}$ at interval $\Delta t$:
//! 1. remove the straight line through the end points, $d_j = x_j - x_0 - (x_{n-1}-x_0)\,j/(n-1)$,
//!    so $d_0 = d_{n-1} = 0$ (the line is added back at the end);
//! 2. make $d$ periodic without a jump or a kink: past the last sample, its odd reflection about
//!    that sample, $d_{n-1+j} = -d_{n-1-j}\,w_j$, and before the first, $d_{-j} = -d_j\,w'_j$, each
//!    under a taper $w_j = \cos^2(\pi j/(2(L+1)))$ over the $L$ padding samples, so value and
//!    slope stay continuous at both ends and the bridges meet at zero. The period $P$ is the
//!    power of two $\ge n + \max(n/4, 16)$; the DFT is $D_k$, $f_k = k/(P\Delta t)$. Unlike a
//!    pure sine series, neither end sample is a symmetry point, so both ends are smoothed too;
//! 3. estimate the white-noise floor $N_0$ as the mean of $|D_k|^2$ over the top 40 % of
//!    the band, fit $\ln |D_k|^2 = a + b k$ over the band where the (running-mean)
//!    spectrum stands above $2N_0$ (bins $k \le k_b$): the signal model is
//!    $S_k = \max(e^{a+bk}, \bar P_k - N_0)$ for $k \le k_b$ and $e^{a+bk}$ above;
//! 4. apply the real, even (hence zero-phase) Wiener weights $W_k = S_k/(S_k+N_0)$, invert,
//!    add the line back. Two channels share one complex FFT (real and imaginary parts).
//!
//! The cut-off reported is where the signal model meets the noise floor,
//! $f_c = k_c/(P\Delta t)$ with $a + b k_c = \ln N_0$; the noise standard deviation is
//! $\hat\sigma = \sqrt{N_0/N_e}$ with $N_e = (n-2) + \sum_j w_j^2 + \sum_j w_j'^2$ the
//! noise-carrying samples of one period (Parseval: the mean of $|D_k|^2$ is $N_e\sigma^2$).

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
    /// Half the FFT period (the Nyquist bin).
    half: usize,
    taper_end: Vec<f64>,
    taper_start: Vec<f64>,
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
                taper_end: vec![],
                taper_start: vec![],
                n_eff: 1.0,
                plan: None,
            };
        }
        let period = (n + (n / 4).max(16)).next_power_of_two();
        let pad = period - n;
        let l_end = pad / 2;
        let l_start = pad - l_end;
        let taper = |l: usize| -> Vec<f64> {
            (0..=l)
                .map(|j| {
                    let c = (std::f64::consts::PI * j as f64 / (2.0 * (l + 1) as f64)).cos();
                    c * c
                })
                .collect()
        };
        let (taper_end, taper_start) = (taper(l_end), taper(l_start));
        let energy = |t: &[f64]| -> f64 {
            t.iter()
                .enumerate()
                .skip(1)
                .filter(|(j, _)| *j < n - 1)
                .map(|(_, w)| w * w)
                .sum()
        };
        let n_eff = (n - 2) as f64 + energy(&taper_end) + energy(&taper_start);
        Smoother {
            n,
            half: period / 2,
            taper_end,
            taper_start,
            n_eff,
            plan: Some(FftPlan::new(period)),
        }
    }

    /// Detrend `x` and write one period of its bridged extension into the real
    /// (`imag = false`) or imaginary part of `buf`; returns the line `(x0, slope)`.
    fn fill(&self, buf: &mut [C], x: &[f64], imag: bool) -> (f64, f64) {
        let n = self.n;
        let p = 2 * self.half;
        let x0 = x[0];
        let slope = (x[n - 1] - x0) / (n - 1) as f64;
        let d = |j: usize| -> f64 { x[j] - x0 - slope * j as f64 };
        let set = |c: &mut C, v: f64| {
            if imag {
                c.im = v;
            } else {
                c.re = v;
            }
        };
        for j in 0..n {
            set(&mut buf[j], d(j));
        }
        // end bridge: odd reflection about the last sample, tapered to zero
        for (j, w) in self.taper_end.iter().enumerate().skip(1) {
            let v = if j < n - 1 { -d(n - 1 - j) * w } else { 0.0 };
            set(&mut buf[n - 1 + j], v);
        }
        // start bridge (backwards from the end of the period): odd reflection about sample 0
        for (j, w) in self.taper_start.iter().enumerate().skip(1) {
            let v = if j < n - 1 { -d(j) * w } else { 0.0 };
            if p - j > n - 1 + self.taper_end.len() - 1 {
                set(&mut buf[p - j], v);
            }
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

    /// The split power spectra `(|X_k|², |Y_k|²)`, k = 0..=H, of two channels packed in one
    /// complex FFT: `X_k = (Z_k + conj Z_{M-k})/2`, `Y_k = (Z_k - conj Z_{M-k})/(2i)`.
    fn split_powers(&self, buf: &[C]) -> (Vec<f64>, Vec<f64>) {
        let h = self.half;
        let m = 2 * h;
        let mut px = vec![0.0; h + 1];
        let mut py = vec![0.0; h + 1];
        for k in 0..=h {
            let zk = buf[k];
            let zm = buf[(m - k) % m].conj();
            px[k] = ((zk + zm) * 0.5).norm_sqr();
            py[k] = ((zk - zm) * 0.5).norm_sqr();
        }
        (px, py)
    }

    /// The packed spectrum of two channels with each part scaled by its own real, even
    /// weight (`wx(k)`, `wy(k)` for bins 0..=H).
    fn weigh_split(
        &self,
        buf: &[C],
        wx: impl Fn(usize) -> f64,
        wy: impl Fn(usize) -> f64,
    ) -> Vec<C> {
        let h = self.half;
        let m = 2 * h;
        let mut out = vec![C::new(0.0, 0.0); m];
        for k in 0..m {
            let kk = if k <= h { k } else { m - k };
            let zk = buf[k];
            let zm = buf[(m - k) % m].conj();
            let xk = (zk + zm) * 0.5;
            let yk = (zk - zm) * C::new(0.0, -0.5);
            out[k] = xk * wx(kk) + C::new(0.0, 1.0) * yk * wy(kk);
        }
        out
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
        let (buf, lines) = self.forward_pair(plan, x, y);
        let (px, py) = self.split_powers(&buf);
        let dx = self.design(&px);
        let dy = self.design(&py);
        let out = self.weigh_split(&buf, |k| dx.weights[k], |k| dy.weights[k]);
        let (vx, vy) = self.back_pair(plan, out, lines);
        (self.result(x, dt, &dx, vx), self.result(y, dt, &dy, vy))
    }

    /// The spectrum of one period of both channels' bridged extensions (`x` in the real
    /// part, `y` in the imaginary part) and the two lines removed.
    fn forward_pair(&self, plan: &FftPlan, x: &[f64], y: &[f64]) -> (Vec<C>, [(f64, f64); 2]) {
        let mut buf = vec![C::new(0.0, 0.0); 2 * self.half];
        let lx = self.fill(&mut buf, x, false);
        let ly = self.fill(&mut buf, y, true);
        plan.run(&mut buf, false);
        (buf, [lx, ly])
    }

    /// The two channels back from a filtered packed spectrum, with their lines added back.
    fn back_pair(
        &self,
        plan: &FftPlan,
        mut buf: Vec<C>,
        lines: [(f64, f64); 2],
    ) -> (Vec<f64>, Vec<f64>) {
        plan.run(&mut buf, true);
        let scale = 1.0 / buf.len() as f64;
        let [(x0, sx), (y0, sy)] = lines;
        (0..self.n)
            .map(|j| {
                let jf = j as f64;
                (
                    buf[j].re * scale + x0 + sx * jf,
                    buf[j].im * scale + y0 + sy * jf,
                )
            })
            .unzip()
    }
}

impl Smoother {
    /// `target` through the Wiener weights the smoother chooses for `reference` (both of the
    /// planned length, finite): the same end treatment (each channel's own line removed and
    /// added back, tapered odd reflections) and the weights $W_k$ designed on the reference's
    /// spectrum (step 3-4 of the module doc), applied to the target's. With fixed weights the
    /// smoother is linear, so a model output seen through it carries the band the smoothed
    /// measurement carries (filter consistency of equation error: Klein & Morelli 2006,
    /// Section 5.5). The target is returned unchanged where [`Smoother::smooth`] would
    /// return the reference unchanged (too short, another length, no noise floor found).
    pub fn smooth_like(&self, reference: &[f64], target: &[f64]) -> Vec<f64> {
        if reference.len() != self.n || target.len() != self.n {
            return target.to_vec();
        }
        // the reference's spectrum as [`Smoother::smooth`] takes it (the channel in both
        // parts of one FFT), so the weights are the ones it applies, and a degenerate
        // reference (a constant) sees no rounding from the target in its spectrum
        let (w, _) = self.weights_pair(reference, reference);
        self.apply_pair(target, target, w.as_deref(), w.as_deref())
            .0
    }

    /// The Wiener weights the smoother designs for each of two channels of the planned
    /// length (one FFT for both, split as [`Smoother::smooth_pair`] splits it): `None` for a
    /// channel it would leave unchanged (no noise floor found, or no plan: too short).
    pub fn weights_pair(&self, x: &[f64], y: &[f64]) -> (Option<Vec<f64>>, Option<Vec<f64>>) {
        let n = self.n;
        let plan = match &self.plan {
            Some(p) if x.len() == n && y.len() == n => p,
            _ => return (None, None),
        };
        let (buf, _) = self.forward_pair(plan, x, y);
        let (px, py) = self.split_powers(&buf);
        let keep = |d: Design| d.filter.then_some(d.weights);
        (keep(self.design(&px)), keep(self.design(&py)))
    }

    /// Two channels of the planned length through given weights (bins 0..=H, as
    /// [`Smoother::weights_pair`] gives them; `None`: the channel unchanged), with the
    /// smoother's end treatment, one FFT each way for both.
    pub fn apply_pair(
        &self,
        x: &[f64],
        y: &[f64],
        wx: Option<&[f64]>,
        wy: Option<&[f64]>,
    ) -> (Vec<f64>, Vec<f64>) {
        let n = self.n;
        let plan = match &self.plan {
            Some(p) if x.len() == n && y.len() == n && (wx.is_some() || wy.is_some()) => p,
            _ => return (x.to_vec(), y.to_vec()),
        };
        let (buf, lines) = self.forward_pair(plan, x, y);
        let out = self.weigh_split(
            &buf,
            |k| wx.map_or(1.0, |w| w[k]),
            |k| wy.map_or(1.0, |w| w[k]),
        );
        self.back_pair(plan, out, lines)
    }
}

impl Smoother {
    /// Zero-phase low-pass of two channels of the same record at a fixed cut-off `fc_hz`,
    /// with the smoother's end treatment (line removed, tapered odd reflections, one FFT
    /// period): the weight is 1 up to `0.75 fc`, 0 from `1.25 fc`, and `cos²` between
    /// (0.5 at `fc`). A record shorter than 8 samples, or of another length than planned,
    /// is returned unchanged. Used to give the qualified-model error and the regressors of
    /// the Δ fit one common band ([`crate::band`]).
    pub fn lowpass_pair(&self, x: &[f64], y: &[f64], dt: f64, fc_hz: f64) -> (Vec<f64>, Vec<f64>) {
        let n = self.n;
        let plan = match &self.plan {
            Some(p) if x.len() == n && y.len() == n && fc_hz > 0.0 && dt > 0.0 => p,
            _ => return (x.to_vec(), y.to_vec()),
        };
        let h = self.half;
        let m = 2 * h;
        let (mut buf, lines) = self.forward_pair(plan, x, y);
        let (f1, f2) = (0.75 * fc_hz, 1.25 * fc_hz);
        let weight = |k: usize| -> f64 {
            let f = k as f64 / (m as f64 * dt);
            if f <= f1 {
                1.0
            } else if f >= f2 {
                0.0
            } else {
                let c = (0.5 * std::f64::consts::PI * (f - f1) / (f2 - f1)).cos();
                c * c
            }
        };
        // both channels carry the same real, even weight: the packed spectrum is scaled as is
        for k in 0..m {
            let kk = if k <= h { k } else { m - k };
            buf[k] *= weight(kk);
        }
        self.back_pair(plan, buf, lines)
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
    fn every_length_keeps_a_clean_signal() {
        // lengths at, just above and below powers of two (bridge lengths 0 .. n-2)
        for n in [8usize, 9, 10, 17, 33, 1025, 1026, 2048, 3000] {
            let dt = 0.05;
            let x: Vec<f64> = (0..n)
                .map(|i| 1.0 + 0.3 * (0.4 * i as f64 * dt).sin())
                .collect();
            let s = smooth(&x, dt);
            assert_eq!(s.values.len(), n);
            let err = s
                .values
                .iter()
                .zip(&x)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-3, "n={n}: max error {err}");
        }
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
    fn smooth_like_applies_the_references_weights() {
        let dt = 0.02;
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let n = 1500;
        let x: Vec<f64> = (0..n)
            .map(|i| {
                (0.03 * i as f64).sin() + 0.2 * (0.4 * i as f64).sin() + 0.02 * gauss(&mut rng)
            })
            .collect();
        let sm = Smoother::new(n);
        let own = sm.smooth(&x, dt);
        assert!(own.cutoff_hz < 0.5 / dt, "the reference must be filtered");
        // the reference seen through its own weights is its smoothed self
        let same = sm.smooth_like(&x, &x);
        let err = same
            .iter()
            .zip(&own.values)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-12, "the reference through its own weights: {err}");
        // linear in the target (each target's own line removed and added back): a y + b x + c
        let y: Vec<f64> = (0..n)
            .map(|i| (0.11 * i as f64).cos() + 0.5 * gauss(&mut rng))
            .collect();
        let combo: Vec<f64> = y
            .iter()
            .zip(&x)
            .enumerate()
            .map(|(i, (u, v))| 2.0 * u - 3.0 * v + 1.5 + 0.001 * i as f64)
            .collect();
        let sy = sm.smooth_like(&x, &y);
        let sc = sm.smooth_like(&x, &combo);
        for i in 0..n {
            let want = 2.0 * sy[i] - 3.0 * own.values[i] + 1.5 + 0.001 * i as f64;
            assert!((sc[i] - want).abs() < 1e-9, "row {i}: {} vs {want}", sc[i]);
        }
        // the reference's weights: a 12 Hz target, far above its 1 Hz cut-off, is removed
        // (in the middle third: the end samples keep their values, as the reference's do,
        // and the step the filter leaves there rings for a while)
        let fast: Vec<f64> = (0..n)
            .map(|i| (2.0 * std::f64::consts::PI * 12.0 * i as f64 * dt).sin())
            .collect();
        let sf = sm.smooth_like(&x, &fast);
        let kept = sf[n / 3..2 * n / 3]
            .iter()
            .fold(0.0_f64, |a, v| a.max(v.abs()));
        assert!(
            kept < 0.005,
            "12 Hz above a {} Hz cut-off kept at {kept}",
            own.cutoff_hz
        );
        // no noise floor in the reference (a constant): the target passes unchanged
        assert_eq!(sm.smooth_like(&vec![2.0; n], &y), y);
        // another length: unchanged
        assert_eq!(sm.smooth_like(&x[..10], &y[..10]), y[..10].to_vec());
    }

    #[test]
    fn designed_weights_applied_equal_the_smoother() {
        let dt = 0.02;
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        let n = 2100;
        let x: Vec<f64> = (0..n)
            .map(|i| (0.02 * i as f64).sin() + 0.03 * gauss(&mut rng))
            .collect();
        let y: Vec<f64> = (0..n)
            .map(|i| 2.0 * (0.05 * i as f64).cos() + 0.2 * gauss(&mut rng))
            .collect();
        let sm = Smoother::new(n);
        let (a, b) = sm.smooth_pair(&x, &y, dt);
        let (wx, wy) = sm.weights_pair(&x, &y);
        let (fx, fy) = sm.apply_pair(&x, &y, wx.as_deref(), wy.as_deref());
        for (u, v) in fx.iter().zip(&a.values).chain(fy.iter().zip(&b.values)) {
            assert!((u - v).abs() < 1e-12, "{u} vs {v}");
        }
        // the weights swapped: each channel through the other's
        let (gx, _) = sm.apply_pair(&x, &y, wy.as_deref(), None);
        let like = sm.smooth_like(&y, &x);
        for (u, v) in gx.iter().zip(&like) {
            assert!((u - v).abs() < 1e-12, "{u} vs {v}");
        }
        // a constant has no noise floor: no weights, and None leaves a channel as it is
        let (wc, _) = sm.weights_pair(&vec![1.0; n], &vec![1.0; n]);
        assert!(wc.is_none());
        assert_eq!(sm.apply_pair(&x, &y, None, None), (x.clone(), y.clone()));
        let (_, same) = sm.apply_pair(&x, &y, wx.as_deref(), None);
        assert!(same.iter().zip(&y).all(|(u, v)| (u - v).abs() < 1e-12));
    }

    #[test]
    fn constant_and_short_signals_pass_unchanged() {
        let x = vec![3.0; 100];
        assert_eq!(smooth(&x, 0.1).values, x);
        let y = vec![1.0, 2.0, 3.0];
        assert_eq!(smooth(&y, 0.1).values, y);
    }
}
