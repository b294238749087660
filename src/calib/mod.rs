//! Calibration: identification of model parameters from datasets. One folder per job, each
//! using only the ones listed before it:
//!
//! * [`effects`]: the non-geometric effect blocks and the row inputs they read;
//! * [`model`]: the calibration model (chain, instrument placement, effect blocks) and the
//!   documented tolerances;
//! * [`fit`]: a model on samples as a least-squares fit of readings, with its noise model
//!   (logging rounding, per-row weights), robust screening, identifiability and the data's floor;
//! * [`correctors`]: learned corrections of what the geometry leaves;
//! * [`methods`]: the calibration methods, each a [`methods::Solver`], registered by name;
//! * [`pipeline`]: the `calibrate` pipeline, its options, stages and result.

pub mod correctors;
pub mod effects;
pub mod fit;
pub mod methods;
pub mod model;
pub mod pipeline;
