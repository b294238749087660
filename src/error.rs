//! One error type for the whole crate: every message names the offending input or output.

use std::path::PathBuf;

/// Errors that reach the user. Each variant carries enough context to act on.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Reading an input failed.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The input read.
        path: PathBuf,
        /// What the operating system reported.
        source: std::io::Error,
    },
    /// Writing (or renaming into place) an output failed.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The output written.
        path: PathBuf,
        /// What the operating system reported.
        source: std::io::Error,
    },
    /// Creating an output's folder failed.
    #[error("cannot create folder {path}: {source}")]
    CreateDir {
        /// The folder created.
        path: PathBuf,
        /// What the operating system reported.
        source: std::io::Error,
    },
    /// A robot description (URDF) that cannot be read or used.
    #[error("URDF {path}: {msg}")]
    Urdf {
        /// The URDF file (or what it was read from).
        path: String,
        /// What is wrong with it.
        msg: String,
    },
    /// A scenario that cannot be read, is invalid, or cannot be run.
    #[error("scenario {path}: {msg}")]
    Scenario {
        /// The scenario file (or the scenario's name).
        path: String,
        /// What is wrong with it.
        msg: String,
    },
    /// Data (a dataset, a truth file) that cannot be read or used.
    #[error("data {path}: {msg}")]
    Data {
        /// The data file or folder.
        path: String,
        /// What is wrong with it.
        msg: String,
    },
    /// A calibrated-model (result.json) file that cannot be used.
    #[error("model {path}: {msg}")]
    Model {
        /// The result file.
        path: String,
        /// What is wrong with it.
        msg: String,
    },
    /// The sensor gave no usable reading (every pose rejected).
    #[error("sensor: {0}")]
    Sensor(String),
    /// The simulation failed (a pose that did not settle, a joint that diverged).
    #[error("simulation: {0}")]
    Simulation(String),
    /// A calibration method failed (diverged, nothing to learn, a model that does not load back).
    #[error("calibration: {0}")]
    Calibration(String),
    /// Anything else: an invalid option or combination of inputs; the message says which.
    #[error("{0}")]
    Invalid(String),
}

/// The crate's result type, with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// A failed read of `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }
    /// A failed write of the output `path`.
    pub fn write(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Write { path: path.into(), source }
    }
    /// A failed creation of the output folder `path`.
    pub fn create_dir(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::CreateDir { path: path.into(), source }
    }
    /// Unusable data at `path`, with what is wrong with them.
    pub fn data(path: impl std::fmt::Display, msg: impl Into<String>) -> Self {
        Error::Data { path: path.to_string(), msg: msg.into() }
    }
    /// An unusable result file at `path`, with what is wrong with it.
    pub fn model(path: impl std::fmt::Display, msg: impl Into<String>) -> Self {
        Error::Model { path: path.to_string(), msg: msg.into() }
    }
}

/// A number as a message shows it: plain where that is short, else in scientific notation (a
/// hand-typed 1e308 is not printed as 309 digits).
pub fn shown(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e9).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod shown_tests {
    #[test]
    fn large_and_tiny_numbers_are_scientific() {
        assert_eq!(super::shown(1e308), "1e308");
        assert_eq!(super::shown(-2.5e-7), "-2.5e-7");
        assert_eq!(super::shown(123.25), "123.25");
        assert_eq!(super::shown(f64::NAN), "NaN");
    }
}
