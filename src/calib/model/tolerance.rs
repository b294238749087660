//! What a calibration may assume before it has seen the data: documented manufacturing and set-up
//! tolerances. Priors, search boxes and initial spreads of every method come from here and from
//! the noise estimated from the data, never from the settings of whatever generated the data.

use crate::calib::effects::EffectUnit;
use crate::calib::model::{CalibModel, Kind};

/// One-sigma tolerances of an arm as built and of a draw-wire set-up as installed.
///
/// * `length_mm`: link lengths and joint-origin offsets of a machined and assembled arm.
///   Machined parts of a 300 mm link hold about ±0.2–0.3 mm (ISO 2768-m); assembly adds as
///   much again, so 0.5 mm is one standard deviation of an as-built offset.
/// * `angle_deg`: joint axis directions and joint zeros after the manufacturer's own zeroing
///   (a zeroing fixture or vernier marks read to about ±0.1°).
/// * `sensor_mm`: the draw-wire's exit point, length offset and tool point after the initial
///   placement (multilateration, then a sensor-only fit against the nominal arm). That fit
///   absorbs the arm's own errors into the sensor, so allow a few millimetres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerances {
    /// Link lengths and joint-origin offsets, mm.
    pub length_mm: f64,
    /// Joint axis directions and joint zeros, degrees.
    pub angle_deg: f64,
    /// The instrument placement (exit point, length offset, tool point), mm.
    pub sensor_mm: f64,
}

impl Default for Tolerances {
    fn default() -> Self {
        Tolerances { length_mm: 0.5, angle_deg: 0.1, sensor_mm: 2.0 }
    }
}

impl Tolerances {
    /// One standard deviation per parameter of `model`, in its internal units (m, rad).
    pub fn prior_std(&self, model: &CalibModel) -> Vec<f64> {
        let sensor = model.setup_range();
        (0..model.n_params())
            .map(|k| match model.kinds[k] {
                _ if sensor.contains(&k) => crate::units::to_m(self.sensor_mm),
                Kind::Length => crate::units::to_m(self.length_mm),
                Kind::Angle => self.angle_deg.to_radians(),
                Kind::Effect(u) => effect_scale(u),
            })
            .collect()
    }
}

/// A plausible size of an effect parameter on an industrial arm, one standard deviation:
/// 50 µrad/(N·m) of joint compliance (a 20 kN·m/rad gear), 10 millidegrees of backlash or
/// eccentricity, 2 millidegrees per kelvin of joint-zero drift, 25 ppm/K of expansion (aluminium 23, steel 12), 100 ppm of warm-up growth, a
/// warm-up time constant of half an hour, a temperature sensor's lag of ten minutes (a probe in
/// air follows within minutes, a casting's core its surface within tens), 0.1 mm of reading
/// nonlinearity.
pub fn effect_scale(u: EffectUnit) -> f64 {
    match u {
        EffectUnit::Compliance => 50e-6,
        EffectUnit::SmallAngle => 0.01f64.to_radians(),
        EffectUnit::AnglePerKelvin => 0.002f64.to_radians(),
        EffectUnit::PerKelvin => 25e-6,
        EffectUnit::Ratio => 1e-4,
        EffectUnit::Seconds => 1800.0,
        EffectUnit::Lag => 600.0,
        EffectUnit::Length => 1e-4,
    }
}
