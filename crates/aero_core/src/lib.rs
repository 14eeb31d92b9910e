//! # aero_core
//!
//! The engine of aerodelta: it extends a flight simulator's aerodynamic
//! database into the stall regime from flight test data (the method of
//! "Lateral Post-stall Aerodynamic Modeling using Flight Test Data", MASc
//! thesis, University of Toronto, 2016; equation numbers below refer to it).
//!
//! Pure Rust, no Python: a real-time simulator embeds this crate directly.
//! One concept per module:
//! - [`table`]: gridded N-D lookup tables, hold or linear extrapolation, a
//!   batch path and an allocation-free single-point path;
//! - [`lsq`]: equation-error OLS by QR with covariance, standard errors
//!   (also corrected for coloured residuals), t/p, partial F, R², PRESS, PSE
//!   and collinearity diagnostics (Eq. 2.5, 2.12-2.13, 3.10);
//! - [`error`]: the error kinds every module returns.
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod error;
pub mod lsq;
pub mod table;

pub use error::{AeroError, ErrorKind, Result, ResultExt};
