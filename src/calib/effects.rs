//! Non-geometric effect blocks of a calibration model. Each block is one physical effect the twin
//! simulates (`src/effects`), with a few named, interpretable parameters, in the form a
//! calibration fits from q, L and the optional t / temp columns:
//!
//! | block | parameters | what it adds |
//! |---|---|---|
//! | `joint_compliance` (joint j) | c_j, rad/(N·m) | joint angle + c_j·τ_j (static torque from the URDF inertials, payload, cable) |
//! | `backlash` (joint j) | h_j, rad (half band) | joint angle + h_j·side_j (load side, else approach side) |
//! | `thermal_drift` | α, 1/K (with `temp`) or s, τ (time only) | every link length × (1 + α·(T − T_ref)) or (1 + s·(1 − e^(−t/τ))) |
//! | `thermal_drift` (joint j) | z_j, rad/K (with `temp`) or z_j, τ_j (time only) | joint angle + z_j·(T − T_ref) or z_j·(1 − e^(−t/τ_j)): joint-zero drift |
//! | `encoder_eccentricity` (joint j) | a_j, b_j, rad | joint angle + a_j·sin q_j + b_j·cos q_j |
//! | `sensor_nonlinearity` | p2..p4, m | reading + Σ p_k·P_k(v), Legendre polynomials P2..P4 over the data's reading range |
//!
//! The per-row inputs they need (torques, sides, time, temperature) travel in one
//! [`RowInputs`] per sample. Derivatives are analytic and checked against finite differences.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// The effects a calibration model can represent.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    JointCompliance,
    Backlash,
    ThermalDrift,
    EncoderEccentricity,
    SensorNonlinearity,
}

impl EffectKind {
    pub const ALL: [EffectKind; 5] =
        [EffectKind::JointCompliance, EffectKind::Backlash, EffectKind::ThermalDrift, EffectKind::EncoderEccentricity, EffectKind::SensorNonlinearity];

    pub fn name(self) -> &'static str {
        match self {
            EffectKind::JointCompliance => "joint_compliance",
            EffectKind::Backlash => "backlash",
            EffectKind::ThermalDrift => "thermal_drift",
            EffectKind::EncoderEccentricity => "encoder_eccentricity",
            EffectKind::SensorNonlinearity => "sensor_nonlinearity",
        }
    }
    /// Whether the effect has one block per joint.
    pub fn per_joint(self) -> bool {
        matches!(self, EffectKind::JointCompliance | EffectKind::Backlash | EffectKind::EncoderEccentricity)
    }
    /// The joints a block of this kind may sit on: every joint for per-joint effects, none for
    /// whole-arm effects; thermal drift is both (the length scale, and each joint's zero drift).
    pub fn joint_options(self, n_joints: usize) -> Vec<Option<usize>> {
        match self {
            EffectKind::ThermalDrift => std::iter::once(None).chain((0..n_joints).map(Some)).collect(),
            k if k.per_joint() => (0..n_joints).map(Some).collect(),
            _ => vec![None],
        }
    }
    /// Accepts the names above and the short forms `compliance`, `thermal`, `eccentricity`,
    /// `nonlinearity`.
    pub fn parse(s: &str) -> Result<EffectKind> {
        let s = s.trim().to_ascii_lowercase();
        let short = match s.as_str() {
            "compliance" => Some(EffectKind::JointCompliance),
            "thermal" => Some(EffectKind::ThermalDrift),
            "eccentricity" => Some(EffectKind::EncoderEccentricity),
            "nonlinearity" => Some(EffectKind::SensorNonlinearity),
            _ => None,
        };
        short.or_else(|| EffectKind::ALL.into_iter().find(|k| k.name() == s)).ok_or_else(|| {
            Error::Invalid(format!(
                "unknown effect '{s}' (expected compliance, backlash, thermal, eccentricity or nonlinearity, optionally with :JOINT, e.g. compliance:2)"
            ))
        })
    }
}

/// Physical unit of an effect parameter, for display and priors.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectUnit {
    /// rad/(N·m), shown in µrad/(N·m).
    Compliance,
    /// rad, shown in millidegrees.
    SmallAngle,
    /// rad/K, shown in millidegrees per kelvin.
    AnglePerKelvin,
    /// 1/K, shown in ppm/K.
    PerKelvin,
    /// dimensionless, shown in ppm.
    Ratio,
    /// s.
    Seconds,
    /// m, shown in mm.
    Length,
}

impl EffectUnit {
    pub fn display(self) -> f64 {
        match self {
            EffectUnit::Compliance | EffectUnit::PerKelvin | EffectUnit::Ratio => 1e6,
            EffectUnit::SmallAngle | EffectUnit::AnglePerKelvin => 180.0 / std::f64::consts::PI * 1e3,
            EffectUnit::Seconds => 1.0,
            EffectUnit::Length => 1e3,
        }
    }
    pub fn unit(self) -> &'static str {
        match self {
            EffectUnit::Compliance => "urad/Nm",
            EffectUnit::SmallAngle => "mdeg",
            EffectUnit::AnglePerKelvin => "mdeg/K",
            EffectUnit::PerKelvin => "ppm/K",
            EffectUnit::Ratio => "ppm",
            EffectUnit::Seconds => "s",
            EffectUnit::Length => "mm",
        }
    }
}

/// How the thermal block is driven.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ThermalDrive {
    /// Measured temperature: scale = 1 + α·(T − `ref_c`).
    Temperature { ref_c: f64 },
    /// Time only: first-order warm-up, scale = 1 + s·(1 − e^(−t/τ)).
    WarmUp,
}

/// One effect in a calibration model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EffectBlock {
    pub kind: EffectKind,
    /// Joint (0-based) of a per-joint effect.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermal: Option<ThermalDrive>,
    /// Sensor nonlinearity: reading range [lo, hi] (m) its polynomials are normalised over.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_m: Option<[f64; 2]>,
}

impl EffectBlock {
    pub fn joint(kind: EffectKind, j: usize) -> Self {
        EffectBlock { kind, joint: Some(j), thermal: None, range_m: None }
    }
    /// A short label: `joint_compliance[j2]`, `thermal_drift`.
    pub fn label(&self) -> String {
        match self.joint {
            Some(j) => format!("{}[j{}]", self.kind.name(), j + 1),
            None => self.kind.name().to_string(),
        }
    }
    /// Names and units of the block's parameters.
    pub fn params(&self) -> Vec<(String, EffectUnit)> {
        let j = self.joint.map(|j| j + 1).unwrap_or(0);
        match self.kind {
            EffectKind::JointCompliance => vec![(format!("compliance.j{j}"), EffectUnit::Compliance)],
            EffectKind::Backlash => vec![(format!("backlash.j{j}"), EffectUnit::SmallAngle)],
            EffectKind::EncoderEccentricity => {
                vec![(format!("eccentricity.j{j}.sin"), EffectUnit::SmallAngle), (format!("eccentricity.j{j}.cos"), EffectUnit::SmallAngle)]
            }
            EffectKind::ThermalDrift => match (self.thermal, self.joint) {
                (Some(ThermalDrive::Temperature { .. }), None) => vec![("thermal.alpha".into(), EffectUnit::PerKelvin)],
                (_, None) => vec![("thermal.scale".into(), EffectUnit::Ratio), ("thermal.tau".into(), EffectUnit::Seconds)],
                (Some(ThermalDrive::Temperature { .. }), Some(_)) => vec![(format!("thermal.zero_drift.j{j}"), EffectUnit::AnglePerKelvin)],
                (_, Some(_)) => {
                    vec![(format!("thermal.zero_drift.j{j}"), EffectUnit::SmallAngle), (format!("thermal.zero_drift.j{j}.tau"), EffectUnit::Seconds)]
                }
            },
            EffectKind::SensorNonlinearity => (2..=4).map(|k| (format!("sensor_nl.p{k}"), EffectUnit::Length)).collect(),
        }
    }
    /// Starting values of the parameters (no effect): zero, except a warm-up time constant,
    /// which starts at a third of the data's time span `t_span_s`.
    pub fn start(&self, t_span_s: f64) -> Vec<f64> {
        let mut v = vec![0.0; self.params().len()];
        if self.kind == EffectKind::ThermalDrift && !matches!(self.thermal, Some(ThermalDrive::Temperature { .. })) {
            v[1] = (t_span_s / 3.0).max(1.0);
        }
        v
    }
}

/// What one sample carries besides q and L.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RowInputs {
    /// Time from the start of acquisition, s.
    pub t_s: Option<f64>,
    /// Measured temperature, °C.
    pub temp_c: Option<f64>,
    /// Static joint torques, N·m, one per joint; empty without an inertial model (read as zero).
    pub torque: Vec<f64>,
    /// Backlash flank per joint (±1; 0 when unknown); empty when no flank is known.
    pub side: Vec<f64>,
}

impl RowInputs {
    /// Static torque of joint `j`, N·m (0 when unknown).
    pub fn torque(&self, j: usize) -> f64 {
        self.torque.get(j).copied().unwrap_or(0.0)
    }
    /// Backlash flank of joint `j` (±1; 0 when unknown).
    pub fn side(&self, j: usize) -> f64 {
        self.side.get(j).copied().unwrap_or(0.0)
    }
}

/// Legendre polynomials P2..P4 and their derivatives at v. (P0, a constant, is the sensor's
/// length offset; P1, a gain error, is a uniform scale of every measured length, which the
/// geometry and the offset absorb almost entirely: the data cannot tell it apart.)
pub fn legendre(v: f64) -> ([f64; 3], [f64; 3]) {
    let v2 = v * v;
    (
        [0.5 * (3.0 * v2 - 1.0), 0.5 * (5.0 * v2 * v - 3.0 * v), 0.125 * (35.0 * v2 * v2 - 30.0 * v2 + 3.0)],
        [3.0 * v, 0.5 * (15.0 * v2 - 3.0), 0.125 * (140.0 * v2 * v - 60.0 * v)],
    )
}

/// The effect state of one row: joint offsets and length scale, with the partial derivatives of
/// each with respect to the effect parameters.
#[derive(Clone, Debug, Default)]
pub struct EffectState {
    /// Offset of each joint, rad.
    pub dq: Vec<f64>,
    /// ∂Δq_j/∂q_j: how each joint's offset changes with its own commanded angle.
    pub ddq_dq: Vec<f64>,
    pub scale: f64,
    /// (parameter index, joint, ∂Δq_joint/∂param).
    pub joint_terms: Vec<(usize, usize, f64)>,
    /// (parameter index, ∂scale/∂param).
    pub scale_terms: Vec<(usize, f64)>,
}

/// Evaluates the joint-offset and scale effects of `blocks` whose parameters start at `first`
/// in `x`, for a row with commanded angles `q` (rad) and inputs `inp`.
pub fn joint_and_scale_effects(blocks: &[EffectBlock], first: usize, x: &[f64], q: &[f64], inp: &RowInputs, st: &mut EffectState) {
    // Resized to the row's joints; after the first row this allocates nothing.
    st.dq.clear();
    st.dq.resize(q.len(), 0.0);
    st.ddq_dq.clear();
    st.ddq_dq.resize(q.len(), 0.0);
    st.scale = 1.0;
    st.joint_terms.clear();
    st.scale_terms.clear();
    let mut k = first;
    for b in blocks {
        let n = b.params().len();
        match b.kind {
            EffectKind::JointCompliance => {
                let j = b.joint.unwrap_or(0);
                st.dq[j] += x[k] * inp.torque(j);
                st.joint_terms.push((k, j, inp.torque(j)));
            }
            EffectKind::Backlash => {
                let j = b.joint.unwrap_or(0);
                st.dq[j] += x[k] * inp.side(j);
                st.joint_terms.push((k, j, inp.side(j)));
            }
            EffectKind::EncoderEccentricity => {
                let j = b.joint.unwrap_or(0);
                let (s, c) = q[j].sin_cos();
                st.dq[j] += x[k] * s + x[k + 1] * c;
                st.ddq_dq[j] += x[k] * c - x[k + 1] * s;
                st.joint_terms.push((k, j, s));
                st.joint_terms.push((k + 1, j, c));
            }
            EffectKind::ThermalDrift => {
                // The thermal state: temperature rise (with `temp`) or warm-up fraction.
                let (f, dfdtau) = match b.thermal {
                    Some(ThermalDrive::Temperature { ref_c }) => (inp.temp_c.map(|t| t - ref_c).unwrap_or(0.0), None),
                    _ => {
                        let t = inp.t_s.unwrap_or(0.0);
                        let tau = x[k + 1].max(1e-3);
                        let e = (-t / tau).exp();
                        (1.0 - e, Some(-e * t / (tau * tau)))
                    }
                };
                match b.joint {
                    None => {
                        st.scale += x[k] * f;
                        st.scale_terms.push((k, f));
                        if let Some(d) = dfdtau {
                            st.scale_terms.push((k + 1, x[k] * d));
                        }
                    }
                    Some(j) => {
                        st.dq[j] += x[k] * f;
                        st.joint_terms.push((k, j, f));
                        if let Some(d) = dfdtau {
                            st.joint_terms.push((k + 1, j, x[k] * d));
                        }
                    }
                }
            }
            EffectKind::SensorNonlinearity => {}
        }
        k += n;
    }
}
