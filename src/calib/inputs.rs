//! Per-row inputs of the effect blocks, computed once over the whole file in acquisition order
//! (before any train/test split): static joint torques from an inertial model (the URDF's
//! links, an optional payload and the cable's pull) and the backlash flank of every joint.
//!
//! The flank rule: where the static torque on a joint exceeds [`LoadOptions::torque_threshold_nm`]
//! the load holds the link on the flank it points to; below it the link stays on the flank its
//! last motion left it on (the link trails the motor: a move towards larger angles leaves it on
//! the negative flank). The arm is assumed to start at its home pose (all angles zero).

use super::effects::{EffectBlock, EffectKind, RowInputs, ThermalDrive};
use crate::dataset::Dataset;
use crate::effects::statics::{CableLoad, LoadModel};
use crate::effects::{Effects, Payload};
use crate::error::{Error, Result};
use crate::robot::kinematics::{FkWork, PointJacobian};
use crate::robot::Robot;
use nalgebra::Vector3;

/// What loads the joints, as far as the user knows it.
#[derive(Clone, Debug)]
pub struct LoadOptions {
    /// Payload on the flank (mass and centre of mass in the flange frame, mm).
    pub payload: Option<Payload>,
    /// Draw-wire spring tension, N (from the sensor's data sheet; 0 = ignore).
    pub cable_tension_n: f64,
    /// Static torque above which the load, not the approach motion, decides the backlash flank.
    pub torque_threshold_nm: f64,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions { payload: None, cable_tension_n: 0.0, torque_threshold_nm: 0.5 }
    }
}

/// Inputs of every row of `data` (file order). `robot` is the inertial model (None: torques are
/// zero and flanks follow the approach motion only); `exit_m` / `tool_m` place the cable.
pub fn row_inputs(data: &Dataset, robot: Option<&Robot>, loads: &LoadOptions, exit_m: Vector3<f64>, tool_m: Vector3<f64>) -> Vec<RowInputs> {
    let n = data.rows.len();
    let mut out: Vec<RowInputs> = data.rows.iter().map(|r| RowInputs { t_s: r.t_s, temp_c: r.temp_c, ..Default::default() }).collect();
    if let Some(robot) = robot {
        let effects = Effects { payload: loads.payload.clone(), ..Default::default() };
        let cable = (loads.cable_tension_n > 0.0).then(|| CableLoad { exit_point: exit_m, tool_point: tool_m, tension: loads.cable_tension_n });
        let load = LoadModel::new(robot, &effects, cable);
        let chain = robot.error_chain();
        let zero = vec![0.0; chain.n_params()];
        let mut ws = FkWork::new(&chain);
        let mut jac = PointJacobian::new(&chain);
        let mut tau = vec![0.0; chain.n_joints];
        for (i, r) in data.rows.iter().enumerate() {
            let q: Vec<f64> = r.q_deg.iter().map(|d| d.to_radians()).collect();
            chain.forward(&q, &zero, 1.0, &mut ws);
            load.torques(&chain, &ws, &mut jac, &mut tau);
            for j in 0..6.min(tau.len()) {
                out[i].torque[j] = tau[j];
            }
        }
    }
    // Approach flanks in file order from the home pose, then the load rule.
    let mut prev = [0.0f64; 6];
    let mut approach = [-1.0f64; 6];
    for i in 0..n {
        let q = data.rows[i].q_deg;
        for j in 0..6 {
            if q[j] > prev[j] {
                approach[j] = -1.0;
            } else if q[j] < prev[j] {
                approach[j] = 1.0;
            }
            let tau = out[i].torque[j];
            out[i].side[j] = if tau.abs() > loads.torque_threshold_nm { tau.signum() } else { approach[j] };
        }
        prev = q;
    }
    out
}

/// A block of `kind` (on joint `joint` for per-joint effects) set up for these data: the thermal
/// block is driven by the `temp` column when every row has one, else by `t`; the nonlinearity
/// is normalised over the data's reading range. Errors name what the data lack.
pub fn block_for(data: &Dataset, kind: EffectKind, joint: Option<usize>, has_torques: bool) -> Result<EffectBlock> {
    let mut b = EffectBlock { kind, joint, thermal: None, range_m: None };
    if kind.per_joint() && joint.is_none_or(|j| j >= 6) {
        return Err(Error::Invalid(format!("{} needs a joint 1..6", kind.name())));
    }
    match kind {
        EffectKind::JointCompliance if !has_torques => {
            return Err(Error::Invalid("joint_compliance needs joint torques: give the robot's URDF (--robot FILE) for its inertial data".into()))
        }
        EffectKind::ThermalDrift => {
            if let Some(t0) = data.rows.first().and_then(|r| r.temp_c).filter(|_| data.rows.iter().all(|r| r.temp_c.is_some())) {
                b.thermal = Some(ThermalDrive::Temperature { ref_c: t0 });
            } else if data.rows.iter().all(|r| r.t_s.is_some()) {
                b.thermal = Some(ThermalDrive::WarmUp);
            } else {
                return Err(Error::Invalid("thermal_drift needs a temp or t column on every row".into()));
            }
        }
        EffectKind::SensorNonlinearity => {
            let (lo, hi) = data.rows.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), r| (a.min(r.l_mm), b.max(r.l_mm)));
            b.range_m = Some([lo * 1e-3, hi * 1e-3]);
        }
        _ => {}
    }
    Ok(b)
}

/// Time span of the data, s (0 without a t column).
pub fn time_span(data: &Dataset) -> f64 {
    let ts: Vec<f64> = data.rows.iter().filter_map(|r| r.t_s).collect();
    if ts.is_empty() {
        return 0.0;
    }
    ts.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - ts.iter().cloned().fold(f64::INFINITY, f64::min)
}
