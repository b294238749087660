//! Calibration: identification of model parameters from datasets.

pub mod awnn;
pub mod awnn_select;
pub mod corrector;
pub mod effects;
pub mod equivalent;
pub mod evonph;
pub mod export;
pub mod generic;
pub mod gkan;
pub mod gkan_select;
pub mod identify;
pub mod ik;
pub mod inputs;
pub mod method;
pub mod metrics;
pub mod model;
pub mod optim;
pub mod placement;
pub mod problem;
pub mod psoekf;
pub mod rbf;
pub mod ridge_cv;
pub mod run;
pub mod stats;
pub mod tolerance;
pub mod truth;
