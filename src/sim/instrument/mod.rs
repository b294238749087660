//! The twin's instruments: the draw-wire (cable) length sensor the papers use, and a laser
//! tracker reading the same tool point in 3-D (through the calibration's own
//! [`crate::measurement::Measurement::Point`]: one reading function for the twin and the fit).

pub mod drawwire;
pub mod tracker;
pub use drawwire::DrawWire;
pub use tracker::Tracker;

/// The true placement (m, rad) of the instrument a twin reads with: the tracker's (with a 6-D
/// probe's orientation) when there is one, else the draw-wire's; the target is the sensor's
/// tool point.
pub fn placement(sensor: &DrawWire, tracker: Option<&Tracker>) -> crate::measurement::Placement {
    use crate::measurement::Placement;
    let tool = sensor.tool_point_m();
    match tracker {
        Some(t) => Placement::tracker(t.translation_mm, t.rotation_deg, t.probe_rotation_deg, tool),
        None => Placement::cable(sensor.exit_point_m(), crate::units::to_m(sensor.length_offset_mm), tool),
    }
}
