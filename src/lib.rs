//! twincal: a digital twin and calibration toolkit for serial industrial arms, the library. The
//! command line (`twincal-cli`: clap, progress bars, signals, Rerun recordings) and the Python
//! package are built over it; this crate has none of their dependencies.
//!
//! Data flow, one folder per stage: [`robot`] (URDF → kinematic chain) → [`sim`] (the twin:
//! rapier simulation with its effects and instrument, dataset generation) → [`dataset`] →
//! [`calib`] (models × [`optim`] × correctors, the [`measurement`] an instrument gives) → [`ik`],
//! [`diagnose`] → [`report`].
//!
//! Start from the [`prelude`]: its example runs the whole job (the twin's data, a calibration, a
//! diagnosis, compensated commands) as `cargo test` checks it.

// Numeric code indexes several arrays in step (`for k in 0..n { a[k] … b[k] … }`), and its
// comparisons are written `!(x > 0.0)` on purpose so that NaN fails them: these two lints fight
// both idioms.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]
// Every public item carries its rustdoc (CI builds with -Dwarnings).
#![warn(missing_docs)]

pub mod artifact_check;
pub mod calib;
pub mod compensate;
pub mod controller;
pub mod dataset;
pub mod diagnose;
pub mod error;
pub mod export;
pub mod identified;
pub mod ik;
pub mod jobs;
pub mod math;
pub mod measurement;
pub mod optim;
pub mod output;
pub mod plan;
pub mod prelude;
pub mod progress;
pub mod report;
pub mod requests;
pub mod robot;
pub mod seed;
pub mod sim;
pub mod stats;
pub mod tcp;
pub mod units;

pub use error::{Error, Result};
