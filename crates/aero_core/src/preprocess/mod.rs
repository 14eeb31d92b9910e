//! Flight test preprocessing (thesis Section 3.3 and 2.4): the numerics the Python ingestion
//! layer calls once a record has been read, mapped to canonical units and validated.
//!
//! - [`fft`]: a small any-length FFT (radix-2 and Bluestein) used by the smoother;
//! - [`smooth`]: zero-phase optimal Fourier (Wiener) smoother with a data-chosen cut-off (SIDPAC `smoo`);
//! - [`deriv`]: smoothed numerical derivatives (SIDPAC `deriv`, local polynomial);
//! - [`kinematics`]: accelerometer and vane transfers to the CG;
//! - [`coefficients`]: measured Cl, Cn, CY (Eq. 3.2-3.4), CX, CZ, Cm;
//! - [`compat`]: data compatibility / flight path reconstruction (Section 2.4);
//! - [`plausibility`]: unit and sign plausibility of the channels from kinematic consistency;
//! - [`maneuver`]: the per-maneuver pipeline and its parallel batch form;
//! - [`matched`]: a model's coefficients seen through the smoother the measured ones came through.

// Sample-indexed loops mirror the equations; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

pub mod coefficients;
pub mod compat;
pub mod deriv;
pub mod fft;
pub mod kinematics;
pub mod maneuver;
pub mod matched;
pub mod plausibility;
pub mod smooth;
