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
}

impl Thermal {
    fn default_ambient() -> f64 {
        20.0
    }
    /// Temperature rise at time `t` s from start.
    pub fn delta_t(&self, t: f64) -> f64 {
        if self.time_constant_s <= 0.0 {
            return self.delta_t_max_k;
        }
        self.delta_t_max_k * (1.0 - (-t / self.time_constant_s).exp())
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

/// A payload rigidly attached to the flange.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Payload {
    pub mass_kg: f64,
    /// Centre of mass in the flange frame, mm.
    pub com_mm: [f64; 3],
}

/// All effects of a twin; `None` means off.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Effects {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compliance: Option<Compliance>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub backlash: Option<Backlash>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermal: Option<Thermal>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload: Option<Payload>,
}

impl Effects {
    /// Whether the joints can move at all under load (otherwise the arm is rigid).
    pub fn joints_yield(&self) -> bool {
        self.compliance.is_some() || self.backlash.as_ref().is_some_and(|b| b.width_deg.iter().any(|w| *w > 0.0))
    }
    pub fn validate(&self, n_joints: usize) -> Result<(), String> {
        if let Some(c) = &self.compliance {
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
        }
        if let Some(b) = &self.backlash {
            if b.width_deg.len() != n_joints {
                return Err(format!("effects.backlash.width_deg has {} values, the robot has {n_joints} joints", b.width_deg.len()));
            }
            if b.width_deg.iter().any(|w| !(w.is_finite() && *w >= 0.0 && *w < 5.0)) {
                return Err("effects.backlash.width_deg must be in [0, 5) degrees".into());
            }
            if !(b.breakaway_nm.is_finite() && b.breakaway_nm >= 0.0) {
                return Err("effects.backlash.breakaway_nm must be >= 0".into());
            }
        }
        if let Some(t) = &self.thermal {
            let ok = [t.alpha_per_k, t.delta_t_max_k, t.time_constant_s, t.ambient_c].iter().all(|v| v.is_finite());
            if !ok || t.time_constant_s < 0.0 || t.alpha_per_k.abs() > 1e-3 {
                return Err("effects.thermal: values must be finite, time_constant_s >= 0, |alpha_per_k| <= 1e-3".into());
            }
            if !t.zero_drift_deg_per_k.is_empty() && t.zero_drift_deg_per_k.len() != n_joints {
                return Err(format!("effects.thermal.zero_drift_deg_per_k needs {n_joints} values"));
            }
        }
        if let Some(p) = &self.payload {
            if !(p.mass_kg.is_finite() && p.mass_kg >= 0.0) || p.com_mm.iter().any(|v| !v.is_finite()) {
                return Err("effects.payload: mass_kg must be >= 0 and com_mm finite".into());
            }
        }
        Ok(())
    }
}
