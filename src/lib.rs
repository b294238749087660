//! twincal: a digital twin of a serial industrial arm for generating and calibrating draw-wire
//! calibration datasets.
//!
//! Data flow, one folder per stage: [`robot`] (URDF → kinematic chain) → [`sim`] (the twin:
//! rapier simulation with its effects and instrument, dataset generation) → [`dataset`] →
//! [`calib`] (models × [`optim`] × correctors, the [`measurement`] an instrument gives) → [`ik`],
//! [`diagnose`] → [`report`] and recordings ([`viz`]).

// Numeric code indexes several arrays in step (`for k in 0..n { a[k] … b[k] … }`), and its
// comparisons are written `!(x > 0.0)` on purpose so that NaN fails them: these two lints fight
// both idioms.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod bench;
pub mod calib;
pub mod cli;
pub mod commands;
pub mod dataset;
pub mod diagnose;
pub mod error;
pub mod identified;
pub mod ik;
pub mod io;
pub mod math;
pub mod measurement;
pub mod optim;
pub mod progress;
pub mod report;
pub mod robot;
pub mod seed;
pub mod shard;
pub mod sim;
pub mod stats;
pub mod viz;

pub use error::{Error, Result};
