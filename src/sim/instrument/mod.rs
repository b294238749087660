//! Measurement instruments. The draw-wire (cable) length sensor is the one the papers use.

pub mod drawwire;
pub use drawwire::DrawWire;
