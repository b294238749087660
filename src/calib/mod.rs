//! Calibration: identification of model parameters from datasets.

pub mod export;
pub mod identify;
pub mod model;
pub mod optim;
pub mod problem;
pub mod run;
pub mod rbf;
pub mod stats;
pub mod truth;
pub mod metrics;
