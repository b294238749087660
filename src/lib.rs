//! twincal: a digital twin of a serial industrial arm for generating and calibrating draw-wire
//! calibration datasets.
//!
//! Data flow, one folder per stage: [`robot`] (URDF → kinematic chain) → [`twin`] (rapier
//! simulation with [`effects`] and a [`sensor`]) → [`dataset`] → calibration → recordings ([`viz`]).

pub mod calib;
pub mod cli;
pub mod dataset;
pub mod diagnose;
pub mod effects;
pub mod error;
pub mod generate;
pub mod io;
pub mod robot;
pub mod scenario;
pub mod sensor;
pub mod twin;
pub mod viz;

pub use error::{Error, Result};
