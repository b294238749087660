//! twincal: a digital twin of a serial industrial arm for generating and calibrating draw-wire
//! calibration datasets.
//!
//! Data flow, one folder per stage: [`robot`] (URDF → kinematic chain) → [`twin`] (rapier
//! simulation with [`effects`] and a [`sensor`]) → [`dataset`] → calibration → recordings ([`viz`]).

// Numeric code indexes several arrays in step (`for k in 0..n { a[k] … b[k] … }`), and its
// comparisons are written `!(x > 0.0)` on purpose so that NaN fails them: these two lints fight
// both idioms.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod bench;
pub mod calib;
pub mod commands;
pub mod dataset;
pub mod diagnose;
pub mod effects;
pub mod error;
pub mod generate;
pub mod ik;
pub mod io;
pub mod measurement;
pub mod optim;
pub mod report;
pub mod robot;
pub mod scenario;
pub mod sensor;
pub mod twin;
pub mod viz;

pub use error::{Error, Result};
