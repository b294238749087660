//! Where an instrument sits: its own placement parameters and the target point on the flange.

use super::Measurement;
use nalgebra::{Matrix3, Vector3};

/// Where the instrument sits in a parameter vector: its own parameters (for the draw-wire the
/// exit point in the base frame and the length offset; for a tracker the base-to-tracker
/// transform), then the target point on the flange (m). See `CalibModel::placement`.
#[derive(Clone, Debug, PartialEq)]
pub struct Placement {
    /// The kind of instrument placed.
    pub measurement: Measurement,
    /// The instrument's own parameters, in [`Measurement::placement_names`] order (m, rad).
    pub own: Vec<f64>,
    /// The target point (tool point, reflector) in the flange frame, m.
    pub tool: Vector3<f64>,
}

impl Placement {
    /// A draw-wire's placement: exit point (base frame), length offset and tool point, m.
    pub fn cable(exit: Vector3<f64>, length_offset: f64, tool: Vector3<f64>) -> Placement {
        Placement { measurement: Measurement::Length, own: vec![exit.x, exit.y, exit.z, length_offset], tool }
    }
    /// A laser tracker's placement as files state it: base-to-tracker translation (mm) and
    /// rotation (degrees, X-Y-Z), and with a 6-D probe its orientation on the flange (degrees),
    /// which makes it read poses instead of points.
    pub fn tracker(translation_mm: [f64; 3], rotation_deg: [f64; 3], probe_rotation_deg: Option<[f64; 3]>, tool: Vector3<f64>) -> Placement {
        let mut own: Vec<f64> = translation_mm.iter().map(crate::units::to_m).chain(rotation_deg.iter().map(|v| v.to_radians())).collect();
        let measurement = match probe_rotation_deg {
            Some(r) => {
                own.extend(r.map(f64::to_radians));
                Measurement::Pose
            }
            None => Measurement::Point,
        };
        Placement { measurement, own, tool }
    }
    /// Every placement value in the parameter vector's order: the instrument's own, then the
    /// target's three.
    pub fn values(&self) -> Vec<f64> {
        self.own.iter().chain(self.tool.iter()).copied().collect()
    }
    /// The same instrument on a flange frame re-expressed: `rot` and `pos` are the old flange
    /// frame in the new one (the target point moves with them, a probe's orientation on the
    /// flange turns with them; the instrument's own station does not change).
    pub fn on_flange(&self, rot: &Matrix3<f64>, pos: &Vector3<f64>) -> Placement {
        let mut own = self.own.clone();
        if self.measurement == Measurement::Pose {
            let r = rot * super::pose::probe_rotation(&own);
            own[6..9].copy_from_slice(&super::pose::xyz_angles(&r));
        }
        Placement { measurement: self.measurement, own, tool: rot * self.tool + pos }
    }
    /// The draw-wire's exit point (base frame, m); `None` for another instrument.
    pub fn exit(&self) -> Option<Vector3<f64>> {
        (self.measurement == Measurement::Length).then(|| Vector3::new(self.own[0], self.own[1], self.own[2]))
    }
}
