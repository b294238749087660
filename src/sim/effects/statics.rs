//! Quasi-static form of the load-dependent effects: joint torques from gravity, payload and cable
//! tension, and the transmission law (compliance in series with backlash) that turns them into
//! link-side deflections. The twin's rapier simulation must settle where this model says.

use super::Effects;
use crate::robot::kinematics::{Chain, FkWork, PointJacobian};
pub use crate::robot::statics::{CableLoad, LoadModel, GRAVITY};

/// Stiffness used for a joint with backlash when compliance is off: the gear is then practically rigid
/// on its flanks (30 N·m deflect it by 0.3 µrad).
pub const RIGID_STIFFNESS: f64 = 1e8;

/// The joint transmission: a torsional spring in series with a dead band.
#[derive(Clone, Debug, PartialEq)]
pub struct Transmission {
    /// N·m/rad per joint.
    pub stiffness: Vec<f64>,
    /// Half the backlash band per joint, rad.
    pub half_band: Vec<f64>,
    /// Dry friction inside the band, N·m.
    pub breakaway: f64,
}

pub use crate::robot::statics::Contact;

impl Transmission {
    /// `None` when the joints are rigid (no compliance, no backlash).
    pub fn from_effects(effects: &Effects, n: usize) -> Option<Self> {
        if !effects.joints_yield() {
            return None;
        }
        let stiffness = match &effects.compliance {
            Some(c) => c.stiffness_nm_per_rad.clone(),
            None => vec![RIGID_STIFFNESS; n],
        };
        let (half_band, breakaway) = match &effects.backlash {
            Some(b) => ((0..n).map(|j| b.half_width_rad(j)).collect(), b.breakaway_nm),
            None => (vec![0.0; n], 0.0),
        };
        Some(Transmission { stiffness, half_band, breakaway })
    }

    /// Link-side deflection δ = q_link − q_motor of joint `j` at rest under load torque `tau`,
    /// having arrived on the flank `side` (±1: the link trails the motor, so a positive approach
    /// motion leaves it on the negative flank).
    pub fn deflection(&self, j: usize, tau: f64, side: f64) -> (f64, Contact) {
        let k = self.stiffness[j];
        let h = self.half_band[j];
        if h == 0.0 {
            return (tau / k, Contact::Spring);
        }
        let flank = |s: f64| if s > 0.0 { Contact::Positive } else { Contact::Negative };
        if tau * side >= 0.0 {
            (side * h + tau / k, flank(side))
        } else if tau.abs() <= self.breakaway {
            (side * h + tau / k, Contact::Held)
        } else {
            (-side * h + tau / k, flank(-side))
        }
    }
}

/// A resting state of the arm.
#[derive(Clone, Debug)]
pub struct Equilibrium {
    /// Link-side joint angles, as seen by the chain (rad, commanded + deflection).
    pub q: Vec<f64>,
    /// Link-side deflection per joint (link minus motor side), rad.
    pub deflection: Vec<f64>,
    /// Load torque per joint, N·m.
    pub torque: Vec<f64>,
    /// Where each joint's transmission rests.
    pub contact: Vec<Contact>,
    /// Fixed-point iterations the solve took.
    pub iterations: usize,
}

/// Solves the quasi-static equilibrium by fixed-point iteration on the deflections.
/// `q_cmd` are the commanded angles (rad), `sides` the approach flanks (±1).
pub fn equilibrium(chain: &Chain, params: &[f64], scale: f64, q_cmd: &[f64], load: &LoadModel, trans: Option<&Transmission>, sides: &[f64]) -> Equilibrium {
    let n = chain.n_joints;
    let mut ws = FkWork::new(chain);
    let mut jac = PointJacobian::new(chain);
    let mut delta = vec![0.0; n];
    let mut tau = vec![0.0; n];
    let mut contact = vec![Contact::Spring; n];
    let mut q: Vec<f64> = q_cmd.to_vec();
    let mut iterations = 0;
    for it in 0..100 {
        iterations = it + 1;
        chain.forward(&q, params, scale, &mut ws);
        load.torques(chain, &ws, &mut jac, &mut tau);
        let Some(t) = trans else { break };
        let mut change: f64 = 0.0;
        for j in 0..n {
            let (d, c) = t.deflection(j, tau[j], sides[j]);
            change = change.max((d - delta[j]).abs());
            delta[j] = d;
            contact[j] = c;
            q[j] = q_cmd[j] + d;
        }
        if change < 1e-15 {
            break;
        }
    }
    Equilibrium { q, deflection: delta, torque: tau, contact, iterations }
}
