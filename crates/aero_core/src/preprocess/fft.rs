//! A small complex FFT for any length: iterative radix-2 for powers of two,
//! Bluestein's chirp-z algorithm otherwise. Plans cache the twiddles and the
//! chirp so that the many channels of one maneuver (same length) share them.
//!
//! Forward transform $X_k = \sum_j x_j e^{-2\pi i jk/n}$; the inverse is
//! unnormalised ($n\,x_j = \sum_k X_k e^{+2\pi i jk/n}$) and callers divide by $n$.

use nalgebra::Complex;

type C = Complex<f64>;

/// Radix-2 plan for a power-of-two length.
#[derive(Debug, Clone)]
struct Radix2 {
    n: usize,
    /// Per stage (butterfly span 2, 4, ..., n), contiguous forward twiddles
    /// `exp(-2 pi i k / len)`, k < len/2, and their conjugates.
    fwd: Vec<Vec<C>>,
    inv: Vec<Vec<C>>,
}

impl Radix2 {
    fn new(n: usize) -> Self {
        debug_assert!(n.is_power_of_two());
        let mut fwd = Vec::new();
        let mut inv = Vec::new();
        let mut len = 2;
        while len <= n {
            let tw: Vec<C> = (0..len / 2)
                .map(|k| {
                    let a = -2.0 * std::f64::consts::PI * k as f64 / len as f64;
                    C::new(a.cos(), a.sin())
                })
                .collect();
            inv.push(tw.iter().map(|w| w.conj()).collect());
            fwd.push(tw);
            len *= 2;
        }
        Radix2 { n, fwd, inv }
    }

    /// In-place transform; `inverse` conjugates the twiddles (no 1/n).
    fn run(&self, x: &mut [C], inverse: bool) {
        let n = self.n;
        if n <= 1 {
            return;
        }
        // bit reversal
        let bits = n.trailing_zeros();
        for i in 0..n {
            let j = i.reverse_bits() >> (usize::BITS - bits);
            if j > i {
                x.swap(i, j);
            }
        }
        let stages = if inverse { &self.inv } else { &self.fwd };
        for tw in stages {
            let half = tw.len();
            for chunk in x.chunks_exact_mut(2 * half) {
                let (a, b) = chunk.split_at_mut(half);
                for ((ak, bk), wk) in a.iter_mut().zip(b.iter_mut()).zip(tw) {
                    let t = *bk * *wk;
                    *bk = *ak - t;
                    *ak += t;
                }
            }
        }
    }
}

/// An FFT plan for one length.
#[derive(Debug, Clone)]
pub struct FftPlan {
    n: usize,
    kind: Kind,
}

#[derive(Debug, Clone)]
enum Kind {
    Pow2(Radix2),
    Bluestein {
        inner: Radix2,
        /// `chirp[j] = exp(-i pi j^2 / n)`, j < n.
        chirp: Vec<C>,
        /// FFT of the conjugate chirp laid out circularly (forward).
        chirp_hat: Vec<C>,
    },
}

impl FftPlan {
    /// Plan a transform of length `n` (any `n >= 1`).
    pub fn new(n: usize) -> Self {
        if n.is_power_of_two() {
            return FftPlan {
                n,
                kind: Kind::Pow2(Radix2::new(n)),
            };
        }
        let m = (2 * n - 1).next_power_of_two();
        let inner = Radix2::new(m);
        let chirp: Vec<C> = (0..n)
            .map(|j| {
                // j^2 mod 2n keeps the angle small and exact
                let jj = ((j as u128 * j as u128) % (2 * n as u128)) as f64;
                let a = -std::f64::consts::PI * jj / n as f64;
                C::new(a.cos(), a.sin())
            })
            .collect();
        let mut b = vec![C::new(0.0, 0.0); m];
        b[0] = chirp[0].conj();
        for j in 1..n {
            b[j] = chirp[j].conj();
            b[m - j] = chirp[j].conj();
        }
        inner.run(&mut b, false);
        FftPlan {
            n,
            kind: Kind::Bluestein {
                inner,
                chirp,
                chirp_hat: b,
            },
        }
    }

    /// The transform length.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether the length is zero (never, for a valid plan).
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Transform `x` (length `n`) in place; `inverse` gives the unnormalised inverse.
    pub fn run(&self, x: &mut [C], inverse: bool) {
        debug_assert_eq!(x.len(), self.n);
        match &self.kind {
            Kind::Pow2(r) => r.run(x, inverse),
            Kind::Bluestein {
                inner,
                chirp,
                chirp_hat,
            } => {
                // inverse DFT = conj(DFT(conj(x)))
                let m = inner.n;
                let mut a = vec![C::new(0.0, 0.0); m];
                for j in 0..self.n {
                    let xj = if inverse { x[j].conj() } else { x[j] };
                    a[j] = xj * chirp[j];
                }
                inner.run(&mut a, false);
                for (ak, bk) in a.iter_mut().zip(chirp_hat) {
                    *ak *= bk;
                }
                inner.run(&mut a, true);
                let scale = 1.0 / m as f64;
                for k in 0..self.n {
                    let v = a[k] * chirp[k] * scale;
                    x[k] = if inverse { v.conj() } else { v };
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn naive(x: &[C]) -> Vec<C> {
        let n = x.len();
        (0..n)
            .map(|k| {
                x.iter().enumerate().fold(C::new(0.0, 0.0), |acc, (j, v)| {
                    let a = -2.0 * std::f64::consts::PI * (j * k) as f64 / n as f64;
                    acc + v * C::new(a.cos(), a.sin())
                })
            })
            .collect()
    }

    #[test]
    fn matches_naive_dft_for_pow2_and_other_lengths() {
        for n in [1usize, 2, 8, 12, 30, 97, 128] {
            let x: Vec<C> = (0..n)
                .map(|j| C::new((j as f64 * 0.7).sin(), (j as f64 * 0.3).cos()))
                .collect();
            let want = naive(&x);
            let plan = FftPlan::new(n);
            let mut got = x.clone();
            plan.run(&mut got, false);
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).norm() < 1e-9 * n as f64, "n={n}");
            }
            plan.run(&mut got, true);
            for (g, w) in got.iter().zip(&x) {
                assert!(
                    (g / n as f64 - w).norm() < 1e-12 * n as f64,
                    "inverse n={n}"
                );
            }
        }
    }
}
