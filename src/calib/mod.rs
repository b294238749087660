//! Calibration: identification of model parameters from datasets.

pub mod optim;
