//! Equation-error ordinary least squares (thesis §2.3.1 Eq. 2.12-2.13 and
//! §3.3.2 Eq. 3.10) with the statistics used to judge a fitted model:
//! covariance, standard errors (conventional and corrected for coloured
//! residuals), t, p, partial F (thesis Eq. 2.5), R², adjusted R², fit error,
//! PRESS, PSE, singular values, condition numbers and collinearity
//! diagnostics.
//!
//! - [`ols`] / [`ols_rows`]: the fit, on all rows or on a subset of rows
//!   (per-alpha-bin fits reuse one regressor matrix);
//! - [`colored`]: the coloured-residual covariance (Morelli & Klein Eq. 5.80)
//!   in O(p N log N) by FFT;
//! - [`cluster`]: the cluster-robust CR2 covariance with Bell-McCaffrey
//!   degrees of freedom (rows of one maneuver are one cluster);
//! - [`stats`]: log-gamma, regularized incomplete beta, Student t and F.

pub mod cluster;
pub mod colored;
mod ols;
mod pool;
pub mod stats;

pub use ols::{
    ols, ols_clustered, ols_rows, ols_rows_clustered, Collinearity, NearDependency, OlsFit,
    OlsOptions, COLLINEAR_COND_DEFAULT, LOADING_EXACT_MIN, VDP_MIN, VIF_NOTE,
};
