//! Position inverse kinematics on a calibrated model ([`solver`]: the paper's hybrid-Jacobian
//! solver and its variants) and its validation against the twin the data came from
//! ([`validation`]).

pub mod closed_form;
pub mod solver;
pub mod validation;

pub use closed_form::{ClosedForm, ClosedFormKind};
pub use solver::{rigid_fit, IkModel, IkOptions, IkSolution, IkStatus, IkWork, JacobianChoice, JacobianKind};
pub use validation::{ik_runs, random_targets, run_ik, table, IkRun, TwinCheck};
