//! One error type for the whole crate: every message names the offending input.

use std::path::PathBuf;

/// Errors that reach the user. Each variant carries enough context to act on.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("cannot read {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("URDF {path}: {msg}")]
    Urdf { path: String, msg: String },
    #[error("scenario {path}: {msg}")]
    Scenario { path: String, msg: String },
    #[error("data {path}: {msg}")]
    Data { path: String, msg: String },
    #[error("sensor: {0}")]
    Sensor(String),
    #[error("simulation: {0}")]
    Simulation(String),
    #[error("calibration: {0}")]
    Calibration(String),
    #[error("{0}")]
    Invalid(String),
}

pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
    pub fn data(path: impl std::fmt::Display, msg: impl Into<String>) -> Self {
        Error::Data { path: path.to_string(), msg: msg.into() }
    }
}
