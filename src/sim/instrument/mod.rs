//! The twin's instruments: the draw-wire (cable) length sensor the papers use, and a laser
//! tracker reading the same tool point in 3-D (through the calibration's own
//! [`crate::measurement::Measurement::Point`]: one reading function for the twin and the fit).

pub mod drawwire;
pub mod tracker;
pub use drawwire::DrawWire;
pub use tracker::Tracker;
