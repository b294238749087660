//! Calibration: identification of model parameters from datasets.

pub mod correctors;
pub mod effects;
pub mod equivalent;
pub mod export;
pub mod floor;
pub mod folds;
pub mod generic;
pub mod gls;
pub mod identify;
pub mod inputs;
pub mod methods;
pub mod metrics;
pub mod model;
pub mod noise_model;
pub mod placement;
pub mod problem;
pub mod ridge_cv;
pub mod robust;
pub mod run;
pub mod stats;
pub mod tolerance;
pub mod twin_out;
pub mod weighting;
