//! Smoothed numerical derivatives of sampled flight data.
//!
//! Two methods, both zero-phase:
//! - [`smooth_deriv`], after SIDPAC `deriv` (Klein & Morelli 2006): smooth with
//!   the optimal Fourier smoother ([`super::smooth`]) and take central differences at interior
//!   points, $\dot x_j = (x_{j+1} - x_{j-1})/(2\Delta t)$, and second-order one-sided
//!   differences at the ends, $\dot x_0 = (-3x_0 + 4x_1 - x_2)/(2\Delta t)$;
//! - [`local_poly_deriv`], a local polynomial (Savitzky-Golay) least-squares fit of order
//!   `order` over `2h+1` samples, differentiated at the centre; near the ends the window is
//!   shifted inside the record and the fit evaluated off-centre.

use nalgebra::{DMatrix, DVector};

use super::smooth::Smoother;
use crate::error::{AeroError, Result};

/// Central differences of `x` sampled every `dt` s (second-order at every point).
///
/// ```
/// use aero_core::preprocess::deriv::central_diff;
/// let x: Vec<f64> = (0..5).map(|i| (i as f64).powi(2)).collect();
/// assert_eq!(central_diff(&x, 1.0), vec![0.0, 2.0, 4.0, 6.0, 8.0]);
/// ```
pub fn central_diff(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    match n {
        0 => vec![],
        1 => vec![0.0],
        2 => {
            let d = (x[1] - x[0]) / dt;
            vec![d, d]
        }
        _ => {
            let mut d = vec![0.0; n];
            d[0] = (-3.0 * x[0] + 4.0 * x[1] - x[2]) / (2.0 * dt);
            d[n - 1] = (3.0 * x[n - 1] - 4.0 * x[n - 2] + x[n - 3]) / (2.0 * dt);
            for j in 1..n - 1 {
                d[j] = (x[j + 1] - x[j - 1]) / (2.0 * dt);
            }
            d
        }
    }
}

/// SIDPAC-`deriv`-like derivative: optimal Fourier smoothing, then central differences.
/// Returns the derivative and the smoother cut-off (Hz).
pub fn smooth_deriv(smoother: &Smoother, x: &[f64], dt: f64) -> (Vec<f64>, f64) {
    let s = smoother.smooth(x, dt);
    (central_diff(&s.values, dt), s.cutoff_hz)
}

/// Weights $w_i$ such that $\dot x(t_c) = \sum_i w_i x_i$ for a polynomial of `order` fitted by
/// least squares to samples at offsets `offsets` (in samples) from the evaluation point.
fn poly_deriv_weights(offsets: &[f64], order: usize, dt: f64) -> Result<Vec<f64>> {
    let m = offsets.len();
    let a = DMatrix::from_fn(m, order + 1, |i, k| offsets[i].powi(k as i32));
    let ata = a.transpose() * &a;
    let inv = ata.try_inverse().ok_or_else(|| {
        AeroError::invalid("local polynomial derivative", "singular window design")
    })?;
    // derivative at offset 0 is coefficient 1 / dt
    let e1 = DVector::from_fn(order + 1, |k, _| if k == 1 { 1.0 } else { 0.0 });
    let row = (inv * e1).transpose() * a.transpose();
    Ok(row.iter().map(|v| v / dt).collect())
}

/// Savitzky-Golay derivative: a polynomial of degree `order` fitted over `2*half+1` samples.
///
/// # Errors
/// `InvalidInput` when `order < 1` or the window (`2*half+1`) does not exceed `order` or the record.
///
/// ```
/// use aero_core::preprocess::deriv::local_poly_deriv;
/// let x: Vec<f64> = (0..50).map(|i| (0.1 * i as f64).powi(3)).collect();
/// let d = local_poly_deriv(&x, 0.1, 4, 3).unwrap();
/// assert!((d[0] - 0.0).abs() < 1e-9 && (d[49] - 3.0 * 4.9f64.powi(2)).abs() < 1e-9);
/// ```
pub fn local_poly_deriv(x: &[f64], dt: f64, half: usize, order: usize) -> Result<Vec<f64>> {
    let n = x.len();
    let w = 2 * half + 1;
    if order < 1 || w <= order || n < w {
        return Err(AeroError::invalid(
            "local polynomial derivative",
            format!(
                "window of {w} samples, order {order}, record of {n}: need order >= 1 and order < window <= record"
            ),
        ));
    }
    let centre: Vec<f64> = (0..w).map(|i| i as f64 - half as f64).collect();
    let wc = poly_deriv_weights(&centre, order, dt)?;
    let mut d = vec![0.0; n];
    for j in half..n - half {
        d[j] = wc
            .iter()
            .zip(&x[j - half..=j + half])
            .map(|(a, b)| a * b)
            .sum();
    }
    for j in (0..half).chain(n - half..n) {
        let start = if j < half { 0 } else { n - w };
        let offs: Vec<f64> = (0..w).map(|i| (start + i) as f64 - j as f64).collect();
        let wj = poly_deriv_weights(&offs, order, dt)?;
        d[j] = wj
            .iter()
            .zip(&x[start..start + w])
            .map(|(a, b)| a * b)
            .sum();
    }
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::preprocess::smooth::tests_support::gauss;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;

    #[test]
    fn smoothed_derivative_of_noisy_sine_is_within_bound() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let dt = 0.02;
        let n = 3000;
        let w = 2.0 * std::f64::consts::PI * 0.3;
        let sigma = 0.01;
        let x: Vec<f64> = (0..n)
            .map(|i| (w * i as f64 * dt).sin() + sigma * gauss(&mut rng))
            .collect();
        let (d, fc) = smooth_deriv(&Smoother::new(n), &x, dt);
        let err: Vec<f64> = (0..n)
            .map(|i| d[i] - w * (w * i as f64 * dt).cos())
            .collect();
        let rms = (err[10..n - 10].iter().map(|e| e * e).sum::<f64>() / (n - 20) as f64).sqrt();
        // bound: 2 % of the derivative amplitude w (noise alone would give sigma/dt/sqrt(2) = 0.35)
        assert!(rms < 0.02 * w, "rms {rms}, cutoff {fc}");
    }

    #[test]
    fn local_poly_is_exact_on_polynomials_and_bounded_on_noise() {
        let dt = 0.05;
        let x: Vec<f64> = (0..40)
            .map(|i| 1.0 + 2.0 * (i as f64 * dt) - (i as f64 * dt).powi(2))
            .collect();
        let d = local_poly_deriv(&x, dt, 3, 2).unwrap();
        for (i, di) in d.iter().enumerate() {
            assert!((di - (2.0 - 2.0 * i as f64 * dt)).abs() < 1e-9);
        }
        assert!(local_poly_deriv(&x, dt, 1, 3).is_err());
    }
}
