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
//! - [`sim`]: the 6-DOF simulator (Eq. 3.1), pilot, sensors and campaign generator;
//! - [`aircraft`]: the representative turboprop, its qualified and truth models;
//! - [`rolloff`]: the stochastic roll-off of Section 3.4.3 (runtime model);
//! - [`buffet`]: the stall buffet at the accelerometers (runtime model: seeded structural
//!   modes driven by an alpha-scheduled forcing);
//! - [`preprocess`]: flight-test preprocessing: smoothing, derivatives, CG and
//!   vane transfers, measured coefficients (Eq. 3.2-3.4), data compatibility;
//! - [`daveml`]: DAVE-ML (AIAA S-119) models: read, evaluate, run their check
//!   cases, write models with self-generated check cases, and merge a model
//!   into an existing file (the extended model: qualified + blended Δ);
//! - [`lsq`]: equation-error least squares by QR (Eq. 2.12-2.13, 3.10) with
//!   standard errors (conventional and coloured-residual), collinearity diagnostics;
//! - [`spline`]: cubic smoothing splines with MATLAB `csaps` semantics (Eq. 3.13);
//! - [`partition`]: alpha partitioning into bins of enough points (Section 3.3.1);
//! - [`regressor`]: the expression language of Δ-model regressors
//!   (dead-band splines of Eq. 3.15-3.16, products, user columns);
//! - [`identify`]: per-bin equation-error Δ identification with identifiability
//!   marks, adjacent-bin consistency and smoothing into tables (Sections 3.3-3.4);
//! - [`band`]: one zero-phase low-pass on the qualified-model error and the regressors
//!   (band-limited equation error, so the smoothed measured coefficients and the raw
//!   controls carry the same band);
//! - [`select`]: structure selection of the Δ model per coefficient and flap
//!   (stepwise partial F, orthogonal functions with PSE, cross-validation over maneuvers);
//! - [`bootstrap`]: confidence bands on the smoothed parameters by resampling maneuvers;
//! - [`chain`]: the measurement chain's time skew and smoothing, calibrated on the qualified
//!   model below alpha_l (three-point time derivatives, clustered least squares);
//! - [`delta_model`]: the Δ part of the extended model (Eq. 3.11-3.12, 3.19),
//!   its versioned file and an allocation-free bound evaluation;
//! - [`kirchhoff`]: the Kirchhoff flow-separation stall of the longitudinal axis
//!   (Fischenberg): static separation curve, the exact ODE step, C_L and C_m, a runtime state;
//! - [`output_error`]: output-error estimation (Levenberg-Marquardt with sensitivities,
//!   multi-maneuver, Cramér-Rao bounds with the coloured-residual correction) of the Kirchhoff model;
//! - [`rolloff_detect`]: detection of uncommanded roll-off events (Section 3.4.3);
//! - [`rolloff_events`]: the detected events' nuisance columns along the records (the runtime
//!   model's spike shape, Figure 3.14) and the refinement of their centres, for the diagnosis;
//! - [`rolloff_mc`]: parallel Monte Carlo of straight stalls with the roll-off,
//!   per-stall summaries (max bank, onset alpha, DRC peak, FAR 25.203);
//! - [`fsutil`]: atomic writes;
//! - [`error`]: the error kinds every module returns.
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod aircraft;
pub mod band;
pub mod bootstrap;
pub mod buffet;
pub mod chain;
pub mod daveml;
pub mod delta_model;
pub mod envelope;
pub mod error;
pub mod fsutil;
pub mod goman_khrabrov;
pub mod hatcv;
pub mod identify;
pub mod kirchhoff;
pub mod lsq;
pub mod output_error;
pub mod partition;
pub mod preprocess;
pub mod regressor;
pub mod rolloff;
pub mod rolloff_detect;
pub mod rolloff_events;
pub mod rolloff_mc;
pub mod select;
pub mod signflip;
pub mod sim;
pub mod spline;
pub mod stall_form;
pub mod stall_spec;
pub mod table;
mod text;

pub use error::{AeroError, ErrorKind, Result, ResultExt};
