//! Non-geometric effects, one component each, with named parameters.
//!
//! Every component has a quasi-static form used by the twin's equilibrium check and, later, by
//! calibration and diagnosis; the twin's rapier simulation is driven by the same parameters.

pub mod statics;

use serde::{Deserialize, Serialize};

/// Torsional joint compliance: each joint holds its commanded angle through a spring.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Compliance {
    /// Stiffness per joint, N·m/rad.
    pub stiffness_nm_per_rad: Vec<f64>,
    /// Viscous damping per joint, N·m·s/rad (simulation only; chosen near-critical when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping_nms_per_rad: Option<Vec<f64>>,
}

/// Gear backlash: a dead band per joint between the motor-side and link-side angle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Backlash {
    /// Total width of the dead band per joint, degrees.
    pub width_deg: Vec<f64>,
    /// Dry friction inside the band per joint, N·m: a load below it leaves the link on the flank of
    /// the last approach, a load above it pushes the link to the flank the load points to.
    #[serde(default = "Backlash::default_breakaway")]
    pub breakaway_nm: f64,
}

impl Backlash {
    fn default_breakaway() -> f64 {
        0.5
    }
    /// Half the dead band of joint `j`, rad (0 for a joint the list does not cover).
    pub fn half_width_rad(&self, j: usize) -> f64 {
        0.5 * self.width_deg.get(j).copied().unwrap_or(0.0).to_radians()
    }
}

/// Thermal drift: first-order warm-up of the structure over acquisition time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Thermal {
    /// Linear expansion coefficient of the links, 1/K (aluminium ≈ 23e-6).
    pub alpha_per_k: f64,
    /// Final temperature rise over ambient, K.
    pub delta_t_max_k: f64,
    /// Warm-up time constant, s.
    pub time_constant_s: f64,
    /// Ambient (start) temperature, °C.
    #[serde(default = "Thermal::default_ambient")]
    pub ambient_c: f64,
    /// Joint zero drift per joint, degrees per kelvin of rise.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub zero_drift_deg_per_k: Vec<f64>,
    /// The temperature sensor (the dataset's `temp` column): time constant of its first-order lag
    /// behind the structure's temperature, s (0: no lag).
    #[serde(default)]
    pub temp_lag_s: f64,
    /// Constant offset of the temperature sensor, K.
    #[serde(default)]
    pub temp_offset_k: f64,
    /// Standard deviation of the Gaussian noise of one temperature reading, K.
    #[serde(default)]
    pub temp_noise_k: f64,
    /// Whether the dataset has a `temp` column at all (false: time only).
    #[serde(default = "Thermal::default_temp_column")]
    pub temp_column: bool,
}

impl Thermal {
    fn default_ambient() -> f64 {
        20.0
    }
    fn default_temp_column() -> bool {
        true
    }
    /// A warm-up and no drift yet: 5 K over a 600 s time constant from a 21 °C ambient (what
    /// [`Effects::set_size`] adds a drift to, and the temperature the hidden-effect generator's
    /// poses read).
    pub fn warm_up() -> Self {
        Thermal::new(0.0, 5.0, 600.0, 21.0)
    }
    /// A thermal effect without joint-zero drift and with an ideal temperature sensor (no lag,
    /// offset or noise, a `temp` column written).
    pub fn new(alpha_per_k: f64, delta_t_max_k: f64, time_constant_s: f64, ambient_c: f64) -> Self {
        Thermal {
            alpha_per_k,
            delta_t_max_k,
            time_constant_s,
            ambient_c,
            zero_drift_deg_per_k: Vec::new(),
            temp_lag_s: 0.0,
            temp_offset_k: 0.0,
            temp_noise_k: 0.0,
            temp_column: true,
        }
    }
    /// Temperature rise at time `t` s from start.
    pub fn delta_t(&self, t: f64) -> f64 {
        if self.time_constant_s <= 0.0 {
            return self.delta_t_max_k;
        }
        self.delta_t_max_k * (1.0 - (-t / self.time_constant_s).exp())
    }
    /// The rise the temperature sensor sees at time `t`: the structure's rise ΔTmax·(1 − e^(−t/τ))
    /// through the sensor's first-order lag τs (starting at ambient), in closed form
    /// ΔTmax·[1 − (τ·e^(−t/τ) − τs·e^(−t/τs))/(τ − τs)], → ΔTmax·[1 − (1 + t/τ)·e^(−t/τ)] as τs → τ.
    pub fn sensed_delta_t(&self, t: f64) -> f64 {
        let (tau, ts) = (self.time_constant_s, self.temp_lag_s);
        if ts <= 0.0 {
            return self.delta_t(t);
        }
        if tau <= 0.0 {
            // The structure jumps to ΔTmax at the start; the sensor follows with its own lag.
            return -self.delta_t_max_k * (-t / ts).exp_m1();
        }
        // (τ·e^(−t/τ) − τs·e^(−t/τs))/(τ − τs) = e^(−t/τ) + τs·e^(−t/τs)·(e^x − 1)/(τ − τs) with
        // x = t·(τ − τs)/(τ·τs); written with expm1 it stays exact as τs approaches τ.
        let d = tau - ts;
        let x = t * d / (tau * ts);
        let ratio = if d == 0.0 {
            (1.0 + t / tau) * (-t / tau).exp()
        } else if x.abs() < 1.0 {
            (-t / tau).exp() + ts * (-t / ts).exp() * x.exp_m1() / d
        } else {
            (tau * (-t / tau).exp() - ts * (-t / ts).exp()) / d
        };
        self.delta_t_max_k * (1.0 - ratio)
    }
    /// What the temperature sensor reads at time `t` (°C) before noise: ambient + offset + the
    /// lagged rise.
    pub fn sensed_temp_c(&self, t: f64) -> f64 {
        self.ambient_c + self.temp_offset_k + self.sensed_delta_t(t)
    }
    /// Link length scale factor at time `t`.
    pub fn scale(&self, t: f64) -> f64 {
        1.0 + self.alpha_per_k * self.delta_t(t)
    }
    /// Joint zero shift of joint `j` at time `t`, radians.
    pub fn zero_shift_rad(&self, j: usize, t: f64) -> f64 {
        self.zero_drift_deg_per_k.get(j).copied().unwrap_or(0.0).to_radians() * self.delta_t(t)
    }
}

/// Encoder eccentricity: the controller reports the commanded angle q, but the true (motor-side)
/// joint angle is q + A·sin(q + φ) per joint (= q + A·cos φ·sin q + A·sin φ·cos q).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Eccentricity {
    /// Amplitude A per joint, degrees (|A| < 1°).
    pub amplitude_deg: Vec<f64>,
    /// Phase φ per joint, degrees.
    pub phase_deg: Vec<f64>,
}

/// Largest |amplitude| of the encoder eccentricity, degrees (exclusive).
pub const MAX_ECCENTRICITY_DEG: f64 = 1.0;

impl Eccentricity {
    /// True minus reported angle of joint `j` at the reported angle `q` (rad), radians.
    pub fn offset_rad(&self, j: usize, q: f64) -> f64 {
        let a = self.amplitude_deg.get(j).copied().unwrap_or(0.0).to_radians();
        let phi = self.phase_deg.get(j).copied().unwrap_or(0.0).to_radians();
        a * (q + phi).sin()
    }
    /// The `sin q` and `cos q` coefficients (a_j, b_j) of joint `j`, degrees: A·cos φ, A·sin φ.
    pub fn sin_cos_deg(&self, j: usize) -> (f64, f64) {
        let a = self.amplitude_deg.get(j).copied().unwrap_or(0.0);
        let phi = self.phase_deg.get(j).copied().unwrap_or(0.0).to_radians();
        (a * phi.cos(), a * phi.sin())
    }
}

pub use crate::robot::statics::{approach_sides, Payload};

/// All effects of a twin; `None` means off.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Effects {
    /// Torsional joint compliance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compliance: Option<Compliance>,
    /// Gear backlash.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backlash: Option<Backlash>,
    /// Thermal drift.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermal: Option<Thermal>,
    /// A payload on the flange.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload: Option<Payload>,
    /// Encoder eccentricity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eccentricity: Option<Eccentricity>,
}

/// The effects the twin takes at a given physical size ([`Effects::set_size`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SizedEffect {
    /// Joint compliance.
    Compliance,
    /// Gear backlash.
    Backlash,
    /// Encoder eccentricity.
    Eccentricity,
    /// Thermal drift (the whole arm's growth, or a joint's zero drift).
    Thermal,
}

impl SizedEffect {
    /// Its key in a scenario's `[effects]`.
    pub fn name(self) -> &'static str {
        match self {
            SizedEffect::Compliance => "compliance",
            SizedEffect::Backlash => "backlash",
            SizedEffect::Eccentricity => "eccentricity",
            SizedEffect::Thermal => "thermal",
        }
    }
}

impl Effects {
    /// Whether the joints can move at all under load (otherwise the arm is rigid).
    pub fn joints_yield(&self) -> bool {
        self.compliance.is_some() || self.backlash.as_ref().is_some_and(|b| b.width_deg.iter().any(|w| *w > 0.0))
    }
    /// The effects that are on: the twin's registry, one line per effect. Nothing is allocated:
    /// the tour asks it at every simulation step.
    pub fn all(&self) -> impl Iterator<Item = &dyn TwinEffect> {
        let on: [Option<&dyn TwinEffect>; 5] = [
            self.compliance.as_ref().map(|e| e as &dyn TwinEffect),
            self.backlash.as_ref().map(|e| e as &dyn TwinEffect),
            self.thermal.as_ref().map(|e| e as &dyn TwinEffect),
            self.payload.as_ref().map(|e| e as &dyn TwinEffect),
            self.eccentricity.as_ref().map(|e| e as &dyn TwinEffect),
        ];
        on.into_iter().flatten()
    }
    /// Puts an effect of a known physical size into the twin of an arm with `n` joints (the
    /// hidden-effect generator and the identified twin use this): a compliance `size` rad/N·m,
    /// a backlash of half-band `size` rad, an eccentricity of amplitude `size` rad at `phase`
    /// rad, a thermal drift of `size` per kelvin for the whole arm or a joint's zero drift of
    /// `size` rad/K (on the warm-up [`Thermal::warm_up`] when the twin has no thermal effect
    /// yet).
    pub fn set_size(&mut self, kind: SizedEffect, n: usize, joint: Option<usize>, size: f64, phase: f64) -> Result<(), String> {
        let j = joint.unwrap_or(0);
        if j >= n {
            return Err(format!("{}: joint {} of an arm with {n} joints", kind.name(), j + 1));
        }
        match kind {
            SizedEffect::Compliance => {
                let c = self.compliance.get_or_insert(Compliance { stiffness_nm_per_rad: vec![1e12; n], damping_nms_per_rad: None });
                c.stiffness_nm_per_rad[j] = 1.0 / size;
            }
            SizedEffect::Backlash => {
                let b = self.backlash.get_or_insert(Backlash { width_deg: vec![0.0; n], breakaway_nm: 0.3 });
                b.width_deg[j] = 2.0 * size.to_degrees();
            }
            SizedEffect::Eccentricity if size.to_degrees().abs() >= MAX_ECCENTRICITY_DEG => {
                return Err(format!("identified at {:.3}°, beyond the twin's {MAX_ECCENTRICITY_DEG}°", size.to_degrees()));
            }
            SizedEffect::Eccentricity => {
                let e = self.eccentricity.get_or_insert(Eccentricity { amplitude_deg: vec![0.0; n], phase_deg: vec![0.0; n] });
                e.amplitude_deg[j] = size.to_degrees();
                e.phase_deg[j] = phase.to_degrees();
            }
            SizedEffect::Thermal => {
                let t = self.thermal.get_or_insert_with(Thermal::warm_up);
                match joint {
                    None => t.alpha_per_k = size,
                    Some(j) => {
                        t.zero_drift_deg_per_k.resize(n, 0.0);
                        t.zero_drift_deg_per_k[j] = size.to_degrees();
                    }
                }
            }
        }
        Ok(())
    }
    /// Checks every effect that is on for an arm of `n_joints`, naming the key of the first bad
    /// value.
    pub fn validate(&self, n_joints: usize) -> Result<(), String> {
        self.all().try_for_each(|e| e.validate(n_joints))
    }
    /// True motor-side minus commanded angle of joint `j` at the commanded angle `q` (rad), rad:
    /// the sum of [`TwinEffect::motor_offset_rad`] over the effects that have one; `None` when
    /// none has.
    pub fn motor_offset_rad(&self, j: usize, q: f64) -> Option<f64> {
        self.all().filter_map(|e| e.motor_offset_rad(j, q)).reduce(|a, b| a + b)
    }
    /// Shift of joint `j`'s zero at time `t` (rad): the sum of [`TwinEffect::zero_shift_rad`]
    /// over the effects that have one; `None` when none has.
    pub fn zero_shift_rad(&self, j: usize, t: f64) -> Option<f64> {
        self.all().filter_map(|e| e.zero_shift_rad(j, t)).reduce(|a, b| a + b)
    }
    /// Link length scale at time `t`: the product of [`TwinEffect::length_scale`] over the
    /// effects that have one (1 for none).
    pub fn length_scale(&self, t: f64) -> f64 {
        self.all().filter_map(|e| e.length_scale(t)).reduce(|a, b| a * b).unwrap_or(1.0)
    }
}

/// An effect as the twin knows it: its scenario table (`[effects.<key>]`, the struct itself),
/// the check of its values, and how it moves the arm's kinematics. Effects that act through the
/// physics (a spring in the joint, a dead band, a mass) are simulated by the rapier multibody
/// and the statics, which read their structs; the kinematic forms below are applied by the twin
/// wherever it computes an arm (quasi-static, simulated, and along the tour), so an effect that
/// acts as an encoder error, a joint-zero shift or a length scale is this implementation alone.
pub trait TwinEffect {
    /// Checks the values for an arm of `n_joints`, naming `effects.<key>.<field>`.
    fn validate(&self, n_joints: usize) -> Result<(), String>;
    /// True motor-side minus commanded angle of joint `j` at the commanded angle `q` (rad), rad:
    /// an error of the angle the controller reports. `None`: the effect has none.
    fn motor_offset_rad(&self, _j: usize, _q: f64) -> Option<f64> {
        None
    }
    /// Shift of joint `j`'s zero at time `t` (s), rad; `None`: the effect has none.
    fn zero_shift_rad(&self, _j: usize, _t: f64) -> Option<f64> {
        None
    }
    /// Factor on every link length at time `t` (s); `None`: the effect has none.
    fn length_scale(&self, _t: f64) -> Option<f64> {
        None
    }
}

impl TwinEffect for Compliance {
    fn validate(&self, n_joints: usize) -> Result<(), String> {
        let c = self;
        if c.stiffness_nm_per_rad.len() != n_joints {
            return Err(format!("effects.compliance.stiffness_nm_per_rad has {} values, the robot has {n_joints} joints", c.stiffness_nm_per_rad.len()));
        }
        if c.stiffness_nm_per_rad.iter().any(|k| !(k.is_finite() && *k > 0.0)) {
            return Err("effects.compliance.stiffness_nm_per_rad must be finite and > 0".into());
        }
        if let Some(d) = &c.damping_nms_per_rad {
            if d.len() != n_joints || d.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(format!("effects.compliance.damping_nms_per_rad needs {n_joints} finite values >= 0"));
            }
        }
        Ok(())
    }
}

impl TwinEffect for Backlash {
    fn validate(&self, n_joints: usize) -> Result<(), String> {
        let b = self;
        if b.width_deg.len() != n_joints {
            return Err(format!("effects.backlash.width_deg has {} values, the robot has {n_joints} joints", b.width_deg.len()));
        }
        if b.width_deg.iter().any(|w| !(w.is_finite() && *w >= 0.0 && *w < 5.0)) {
            return Err("effects.backlash.width_deg must be in [0, 5) degrees".into());
        }
        if !(b.breakaway_nm.is_finite() && b.breakaway_nm >= 0.0) {
            return Err("effects.backlash.breakaway_nm must be >= 0".into());
        }
        Ok(())
    }
}

impl TwinEffect for Thermal {
    fn validate(&self, n_joints: usize) -> Result<(), String> {
        let t = self;
        let scalars = [
            ("alpha_per_k", t.alpha_per_k),
            ("delta_t_max_k", t.delta_t_max_k),
            ("time_constant_s", t.time_constant_s),
            ("ambient_c", t.ambient_c),
            ("temp_lag_s", t.temp_lag_s),
            ("temp_offset_k", t.temp_offset_k),
            ("temp_noise_k", t.temp_noise_k),
        ];
        for (key, v) in scalars {
            if !v.is_finite() {
                return Err(format!("effects.thermal.{key} = {v} must be finite"));
            }
        }
        if t.alpha_per_k.abs() > 1e-3 {
            return Err(format!("effects.thermal.alpha_per_k = {} must be within ±1e-3 per K", t.alpha_per_k));
        }
        for (key, v) in [("time_constant_s", t.time_constant_s), ("temp_lag_s", t.temp_lag_s), ("temp_noise_k", t.temp_noise_k)] {
            if v < 0.0 {
                return Err(format!("effects.thermal.{key} = {v} must be >= 0"));
            }
        }
        if t.zero_drift_deg_per_k.iter().any(|v| !v.is_finite()) || (!t.zero_drift_deg_per_k.is_empty() && t.zero_drift_deg_per_k.len() != n_joints) {
            return Err(format!("effects.thermal.zero_drift_deg_per_k needs {n_joints} finite values"));
        }
        Ok(())
    }
    fn zero_shift_rad(&self, j: usize, t: f64) -> Option<f64> {
        Some(Thermal::zero_shift_rad(self, j, t))
    }
    fn length_scale(&self, t: f64) -> Option<f64> {
        Some(self.scale(t))
    }
}

impl TwinEffect for Eccentricity {
    fn validate(&self, n_joints: usize) -> Result<(), String> {
        let e = self;
        for (key, v) in [("amplitude_deg", &e.amplitude_deg), ("phase_deg", &e.phase_deg)] {
            if v.len() != n_joints {
                return Err(format!("effects.eccentricity.{key} has {} values, the robot has {n_joints} joints", v.len()));
            }
            if let Some(x) = v.iter().find(|x| !x.is_finite()) {
                return Err(format!("effects.eccentricity.{key} = {x} must be finite"));
            }
        }
        if let Some(a) = e.amplitude_deg.iter().find(|a| a.abs() >= MAX_ECCENTRICITY_DEG) {
            return Err(format!("effects.eccentricity.amplitude_deg = {a} must be within ±{MAX_ECCENTRICITY_DEG}° (exclusive)"));
        }
        Ok(())
    }
    fn motor_offset_rad(&self, j: usize, q: f64) -> Option<f64> {
        Some(self.offset_rad(j, q))
    }
}

impl TwinEffect for Payload {
    fn validate(&self, _n_joints: usize) -> Result<(), String> {
        if !(self.mass_kg.is_finite() && self.mass_kg >= 0.0) || self.com_mm.iter().any(|v| !v.is_finite()) {
            return Err("effects.payload: mass_kg must be >= 0 and com_mm finite".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn thermal(tau: f64, lag: f64) -> Thermal {
        Thermal { temp_lag_s: lag, ..Thermal::new(23e-6, 10.0, tau, 21.0) }
    }

    /// The sensor's lag integrated numerically: τs·y' = ΔT(t) − y, y(0) = 0 (RK4).
    fn integrated(th: &Thermal, t_end: f64) -> f64 {
        let n = 200_000;
        let h = t_end / n as f64;
        let f = |t: f64, y: f64| (th.delta_t(t) - y) / th.temp_lag_s;
        let mut y = 0.0;
        for i in 0..n {
            let t = i as f64 * h;
            let k1 = f(t, y);
            let k2 = f(t + 0.5 * h, y + 0.5 * h * k1);
            let k3 = f(t + 0.5 * h, y + 0.5 * h * k2);
            let k4 = f(t + h, y + h * k3);
            y += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        y
    }

    #[test]
    fn sensed_rise_is_the_lagged_structure_rise() {
        for (tau, lag) in [(1800.0, 120.0), (900.0, 900.0), (900.0, 900.0 * (1.0 + 1e-12)), (100.0, 1000.0), (600.0, 1.0)] {
            let th = thermal(tau, lag);
            for t in [1.0, 60.0, 450.0, 2000.0, 9000.0] {
                let (closed, numeric) = (th.sensed_delta_t(t), integrated(&th, t));
                assert!((closed - numeric).abs() < 1e-9, "τ {tau}, τs {lag}, t {t}: closed {closed} vs RK4 {numeric}");
                assert!(closed < th.delta_t(t) && closed > 0.0, "the sensor lags behind the structure");
            }
            assert_eq!(th.sensed_delta_t(0.0), 0.0);
            assert!((th.sensed_delta_t(1e7) - 10.0).abs() < 1e-12);
        }
        // A structure that jumps at once (τ = 0) is followed by the sensor's own first-order rise.
        let th = thermal(0.0, 50.0);
        assert!((th.sensed_delta_t(50.0) - 10.0 * (1.0 - (-1.0f64).exp())).abs() < 1e-12);
        // No lag: the structure's rise itself, bit for bit.
        let th = thermal(1800.0, 0.0);
        for t in [0.0, 10.0, 1e4] {
            assert_eq!(th.sensed_delta_t(t), th.delta_t(t));
            assert_eq!(th.sensed_temp_c(t), th.ambient_c + th.delta_t(t));
        }
        // Offset adds on top.
        let th = Thermal { temp_offset_k: 0.3, ..thermal(1800.0, 120.0) };
        assert!((th.sensed_temp_c(500.0) - (21.3 + th.sensed_delta_t(500.0))).abs() < 1e-12);
    }

    #[test]
    fn sensed_rise_is_continuous_through_equal_time_constants() {
        let at = |lag: f64| thermal(900.0, lag).sensed_delta_t(700.0);
        let equal = at(900.0);
        let limit = 10.0 * (1.0 - (1.0 + 700.0 / 900.0) * (-700.0f64 / 900.0).exp());
        assert!((equal - limit).abs() < 1e-13);
        for rel in [1e-15, 1e-12, 1e-9, 1e-6] {
            for lag in [900.0 * (1.0 + rel), 900.0 * (1.0 - rel)] {
                assert!((at(lag) - equal).abs() < 10.0 * rel + 1e-13, "τs = {lag}: {} vs {equal}", at(lag));
            }
        }
    }

    #[test]
    fn eccentricity_maps_to_sin_and_cos_coefficients() {
        let e = Eccentricity { amplitude_deg: vec![0.005, -0.01, 0.2, 0.0, 0.0, 0.0], phase_deg: vec![30.0, -120.0, 90.0, 0.0, 0.0, 0.0] };
        for j in 0..3 {
            let (a, b) = e.sin_cos_deg(j);
            for q in [-2.0, -0.3, 0.0, 0.7, 1.9f64] {
                let expect = (a * q.sin() + b * q.cos()).to_radians();
                assert!((e.offset_rad(j, q) - expect).abs() < 1e-15, "joint {j} q {q}");
            }
        }
        assert!(e.offset_rad(2, 0.0) > 0.0 && (e.offset_rad(2, 0.0) - 0.2f64.to_radians()).abs() < 1e-15);
        assert_eq!(e.offset_rad(3, 1.0), 0.0);
    }

    #[test]
    fn eccentricity_and_temperature_sensor_values_are_checked_naming_the_key() {
        let ok = Eccentricity { amplitude_deg: vec![0.005; 6], phase_deg: vec![0.0; 6] };
        let check = |e: Eccentricity| Effects { eccentricity: Some(e), ..Default::default() }.validate(6);
        assert!(check(ok.clone()).is_ok());
        assert!(check(Eccentricity { amplitude_deg: vec![-0.999; 6], ..ok.clone() }).is_ok());
        let cases = [
            ("effects.eccentricity.amplitude_deg", Eccentricity { amplitude_deg: vec![0.005; 5], ..ok.clone() }),
            ("effects.eccentricity.amplitude_deg", Eccentricity { amplitude_deg: vec![0.005, 1.0, 0.0, 0.0, 0.0, 0.0], ..ok.clone() }),
            ("effects.eccentricity.amplitude_deg", Eccentricity { amplitude_deg: vec![0.005, -1.5, 0.0, 0.0, 0.0, 0.0], ..ok.clone() }),
            ("effects.eccentricity.amplitude_deg", Eccentricity { amplitude_deg: vec![f64::NAN; 6], ..ok.clone() }),
            ("effects.eccentricity.phase_deg", Eccentricity { phase_deg: vec![0.0; 7], ..ok.clone() }),
            ("effects.eccentricity.phase_deg", Eccentricity { phase_deg: vec![0.0, 0.0, f64::INFINITY, 0.0, 0.0, 0.0], ..ok.clone() }),
        ];
        for (key, e) in cases {
            let msg = check(e.clone()).expect_err(key);
            assert!(msg.contains(key), "{e:?}: {msg}");
        }
        let th = |t: Thermal| Effects { thermal: Some(t), ..Default::default() }.validate(6);
        let base = Thermal::new(23e-6, 10.0, 1800.0, 21.0);
        assert!(th(Thermal { temp_lag_s: 120.0, temp_offset_k: -0.3, temp_noise_k: 0.05, temp_column: false, ..base.clone() }).is_ok());
        let cases = [
            ("effects.thermal.temp_lag_s", Thermal { temp_lag_s: -1.0, ..base.clone() }),
            ("effects.thermal.temp_lag_s", Thermal { temp_lag_s: f64::NAN, ..base.clone() }),
            ("effects.thermal.temp_offset_k", Thermal { temp_offset_k: f64::INFINITY, ..base.clone() }),
            ("effects.thermal.temp_noise_k", Thermal { temp_noise_k: -0.01, ..base.clone() }),
            ("effects.thermal.temp_noise_k", Thermal { temp_noise_k: f64::NAN, ..base.clone() }),
            ("effects.thermal.time_constant_s", Thermal { time_constant_s: -5.0, ..base.clone() }),
            ("effects.thermal.alpha_per_k", Thermal { alpha_per_k: 0.01, ..base.clone() }),
            ("effects.thermal.delta_t_max_k", Thermal { delta_t_max_k: f64::NAN, ..base.clone() }),
            ("effects.thermal.zero_drift_deg_per_k", Thermal { zero_drift_deg_per_k: vec![0.001; 3], ..base.clone() }),
        ];
        for (key, t) in cases {
            let msg = th(t.clone()).expect_err(key);
            assert!(msg.contains(key), "{t:?}: {msg}");
        }
    }

    #[test]
    fn an_effect_is_set_at_its_physical_size() {
        let mut e = Effects::default();
        e.set_size(SizedEffect::Compliance, 6, Some(1), 2e-6, 0.0).unwrap();
        e.set_size(SizedEffect::Backlash, 6, Some(2), 0.05f64.to_radians(), 0.0).unwrap();
        e.set_size(SizedEffect::Eccentricity, 6, Some(0), 0.02f64.to_radians(), 0.5).unwrap();
        e.set_size(SizedEffect::Thermal, 6, None, 20e-6, 0.0).unwrap();
        e.set_size(SizedEffect::Thermal, 6, Some(4), 1e-3f64.to_radians(), 0.0).unwrap();
        assert!((e.compliance.as_ref().unwrap().stiffness_nm_per_rad[1] - 5e5).abs() < 1e-6);
        assert!((e.backlash.as_ref().unwrap().width_deg[2] - 0.1).abs() < 1e-12);
        let ecc = e.eccentricity.as_ref().unwrap();
        assert!((ecc.amplitude_deg[0] - 0.02).abs() < 1e-12 && (ecc.phase_deg[0] - 0.5f64.to_degrees()).abs() < 1e-12);
        let t = e.thermal.as_ref().unwrap();
        assert_eq!((t.alpha_per_k, t.delta_t_max_k, t.time_constant_s), (20e-6, 5.0, 600.0));
        assert!((t.zero_drift_deg_per_k[4] - 1e-3).abs() < 1e-15 && t.zero_drift_deg_per_k.len() == 6);
        e.validate(6).unwrap();
        assert!(e.set_size(SizedEffect::Backlash, 6, Some(6), 1e-3, 0.0).unwrap_err().contains("joint 7"));
    }
}
