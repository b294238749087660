//! What a user asks of a calibration or a diagnosis, as they write it: the options of
//! `twincal calibrate` and `twincal diagnose`, and the keyword arguments of Python's
//! `twincal.calibrate` and `twincal.diagnose`. Each request is a typed value with its defaults
//! (serde, and with the `clap` feature a clap argument group the command line flattens), checked
//! and resolved into the library's options by one function ([`CalibrateRequest::options`],
//! [`DiagnoseRequest::options`]). Where the data come from and where outputs go are not part of
//! a request.
//!
//! The argument groups several requests share (how readings are read, the model, what loads the
//! joints, the data's floor) are defined once in `groups.rs`; [`from_json`] reads a request from
//! a JSON object of options (Python's keyword arguments), naming any unknown option and the
//! option whose value has the wrong type.

mod calibrate;
mod diagnose;
mod groups;
mod json;

pub use calibrate::{check_effort, check_test_fraction, CalibrateRequest, MAX_EFFORT, MIN_EFFORT};
pub use diagnose::DiagnoseRequest;
pub use groups::{Floor, Loads, ModelChoice, Reading, Robust, SetUp};
pub use json::from_json;
