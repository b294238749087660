//! The digital twin: the true robot (geometry with errors) as a rapier3d multibody under gravity,
//! with joint compliance, backlash, thermal drift, payload and cable tension, and the draw-wire sensor.
//!
//! Each pose is simulated in a world of its own: the arm arrives on the backlash flanks its approach
//! motion leaves it on, then settles under load until motion has died out. Poses depend on each
//! other only through the approach flanks and the acquisition time, both known in advance, so they
//! can be simulated in parallel and still give the same result as a sequential run.

pub mod acquisition;
pub mod motion;
pub mod rapier_sim;
pub mod tour;

/// Most poses one scenario or twin run takes.
pub const MAX_POSES: usize = 100_000;

use crate::robot::kinematics::{Chain, FkWork, Frame};
use crate::robot::Robot;
use crate::sim::effects::statics::{equilibrium, Contact, LoadModel, Transmission};
use crate::sim::effects::Effects;
use crate::sim::instrument::DrawWire;
use nalgebra::Vector3;

/// Options of the rapier settling loop.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SettleOptions {
    /// Time step, s.
    #[serde(default = "SettleOptions::default_dt")]
    pub dt_s: f64,
    /// Settled when no joint moves by more than this per step (rad) ...
    #[serde(default = "SettleOptions::default_tol")]
    pub step_tolerance_rad: f64,
    /// ... for this many consecutive steps.
    #[serde(default = "SettleOptions::default_quiet")]
    pub quiet_steps: usize,
    /// Give up after this many steps (an error for that pose).
    #[serde(default = "SettleOptions::default_max")]
    pub max_steps: usize,
    /// Damping ratio used for joints whose damping is not given.
    #[serde(default = "SettleOptions::default_zeta")]
    pub damping_ratio: f64,
}

/// Largest `simulation.max_steps` (1000 s of simulated time at the default 1 ms step).
pub const MAX_SETTLE_STEPS: usize = 1_000_000;

impl SettleOptions {
    /// Checks every value, naming the key (`simulation.<key>`) of the first bad one.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.dt_s > 0.0 && self.dt_s <= 0.01) {
            return Err(format!("simulation.dt_s = {} must be in (0, 0.01] s", self.dt_s));
        }
        if !(self.step_tolerance_rad.is_finite() && self.step_tolerance_rad > 0.0) {
            return Err(format!("simulation.step_tolerance_rad = {:?} must be finite and > 0", self.step_tolerance_rad));
        }
        if !(1..=MAX_SETTLE_STEPS).contains(&self.max_steps) {
            return Err(format!("simulation.max_steps = {} must be in 1..={MAX_SETTLE_STEPS}", self.max_steps));
        }
        if !(1..=self.max_steps).contains(&self.quiet_steps) {
            return Err(format!("simulation.quiet_steps = {} must be in 1..=max_steps ({})", self.quiet_steps, self.max_steps));
        }
        if !(self.damping_ratio.is_finite() && self.damping_ratio > 0.0) {
            return Err(format!("simulation.damping_ratio = {} must be finite and > 0", self.damping_ratio));
        }
        Ok(())
    }

    fn default_dt() -> f64 {
        1e-3
    }
    fn default_tol() -> f64 {
        1e-13
    }
    fn default_quiet() -> usize {
        5
    }
    fn default_max() -> usize {
        20_000
    }
    fn default_zeta() -> f64 {
        1.0
    }
}

impl Default for SettleOptions {
    fn default() -> Self {
        SettleOptions {
            dt_s: Self::default_dt(),
            step_tolerance_rad: Self::default_tol(),
            quiet_steps: Self::default_quiet(),
            max_steps: Self::default_max(),
            damping_ratio: Self::default_zeta(),
        }
    }
}

/// What the twin is asked to do for one pose.
#[derive(Clone, Debug)]
pub struct PoseCommand {
    /// Commanded (controller) joint angles, rad.
    pub q_cmd: Vec<f64>,
    /// Backlash flank each joint arrives on (±1).
    pub sides: Vec<f64>,
    /// Acquisition time, s from start (thermal state).
    pub t: f64,
}

/// The resting state of the true arm at one pose.
#[derive(Clone, Debug)]
pub struct RestingPose {
    /// Link-side angles as the chain sees them (motor side + deflection), rad.
    pub q_link: Vec<f64>,
    /// Encoder eccentricity: true motor-side minus commanded (reported) angle per joint, rad.
    pub eccentricity: Vec<f64>,
    /// Link-side deflection per joint (link side minus motor side), rad.
    pub deflection: Vec<f64>,
    /// Load torque per joint at rest (gravity, payload, cable tension), N·m.
    pub torque: Vec<f64>,
    /// Where each joint's transmission came to rest.
    pub contact: Vec<Contact>,
    /// Tool point, base frame, m.
    pub tool: Vector3<f64>,
    /// Link frames (base, links, flange).
    pub frames: Vec<Frame>,
    /// Simulation steps to settle (0 for the quasi-static model or a rigid arm).
    pub steps: usize,
}

/// The immutable true robot: geometry with its errors, effects and sensor.
#[derive(Clone, Debug)]
pub struct Twin {
    /// The robot as its URDF describes it (nominal geometry, joints, inertials).
    pub robot: Robot,
    /// The robot's error chain, which `params` act on.
    pub chain: Chain,
    /// True geometric error parameters (chain units: m, rad).
    pub params: Vec<f64>,
    /// The twin's non-geometric effects.
    pub effects: Effects,
    /// The draw-wire sensor (with a tracker: the tool point it reads, the hold and samples).
    pub draw_wire: DrawWire,
    /// An instrument that reads the tool point instead of the cable (none: the cable reads).
    pub instruments: crate::sim::instrument::Instruments,
    /// The static loads on the joints: the links' weight, the payload and the cable's pull.
    pub load: LoadModel,
    /// The joint transmission (compliance in series with backlash); `None` when the joints are
    /// rigid.
    pub transmission: Option<Transmission>,
    /// Options of the rapier settling loop.
    pub settle: SettleOptions,
}

impl Twin {
    /// The twin of `robot` with true error parameters `params` (chain units: m, rad), its effects,
    /// sensor and settling options; read by the cable until [`Self::with_instruments`].
    pub fn new(robot: Robot, params: Vec<f64>, effects: Effects, draw_wire: DrawWire, settle: SettleOptions) -> Self {
        let chain = robot.error_chain();
        let load = LoadModel::new(&robot, effects.payload.as_ref(), draw_wire.cable_load());
        let transmission = Transmission::from_effects(&effects, robot.dof());
        Twin { robot, chain, params, effects, draw_wire, instruments: Default::default(), load, transmission, settle }
    }

    /// The twin read by the active one of `instruments` instead of its cable.
    pub fn with_instruments(mut self, instruments: crate::sim::instrument::Instruments) -> Self {
        self.instruments = instruments;
        self
    }

    /// Parameters and length scale in force at time `t` (every effect's joint-zero shift and
    /// length scale applied: thermal drift).
    pub fn params_at(&self, t: f64) -> (Vec<f64>, f64) {
        let mut p = self.params.clone();
        let scale = self.effects.length_scale(t);
        for j in 0..self.chain.n_joints {
            if let Some(op) = self.chain.joint_op(j) {
                if let Some(i) = self.chain.ops[op].param {
                    if let Some(d) = self.effects.zero_shift_rad(j, t) {
                        p[i] += d;
                    }
                }
            }
        }
        (p, scale)
    }

    fn resting(&self, q_link: Vec<f64>, p: &[f64], scale: f64) -> (Vector3<f64>, Vec<Frame>) {
        let mut ws = FkWork::new(&self.chain);
        self.chain.forward(&q_link, p, scale, &mut ws);
        let frames: Vec<Frame> = (0..self.chain.n_frames()).map(|f| self.chain.frame(&ws, f)).collect();
        let tool = frames[self.chain.flange()].point(&self.draw_wire.tool_point_m());
        (tool, frames)
    }

    /// Encoder errors at the commanded (reported) angles `q_cmd` (rad): true motor-side minus
    /// commanded angle per joint, rad, every effect's [`crate::sim::effects::TwinEffect::motor_offset_rad`]
    /// (the encoder eccentricity; zeros when no effect is on).
    pub fn eccentricity(&self, q_cmd: &[f64]) -> Vec<f64> {
        q_cmd.iter().enumerate().map(|(j, q)| self.effects.motor_offset_rad(j, *q).unwrap_or(0.0)).collect()
    }

    /// The command as the drive executes it: the true motor-side angles (commanded + encoder
    /// eccentricity) with the same approach flanks (they follow the commanded motion) and time.
    /// Both the rapier simulation and the quasi-static model start from it.
    pub fn motor_command(&self, cmd: &PoseCommand) -> PoseCommand {
        let q_motor = cmd.q_cmd.iter().zip(self.eccentricity(&cmd.q_cmd)).map(|(q, e)| q + e).collect();
        PoseCommand { q_cmd: q_motor, sides: cmd.sides.clone(), t: cmd.t }
    }

    /// The quasi-static resting pose from torque equilibrium (no dynamics).
    pub fn quasi_static(&self, cmd: &PoseCommand) -> RestingPose {
        let motor = self.motor_command(cmd);
        let (p, scale) = self.params_at(motor.t);
        let eq = equilibrium(&self.chain, &p, scale, &motor.q_cmd, &self.load, self.transmission.as_ref(), &motor.sides);
        let (tool, frames) = self.resting(eq.q.clone(), &p, scale);
        let eccentricity = self.eccentricity(&cmd.q_cmd);
        RestingPose { q_link: eq.q, eccentricity, deflection: eq.deflection, torque: eq.torque, contact: eq.contact, tool, frames, steps: 0 }
    }

    /// The resting pose simulated in rapier.
    pub fn simulate(&self, cmd: &PoseCommand) -> crate::Result<RestingPose> {
        let mut rest = rapier_sim::simulate(self, &self.motor_command(cmd))?;
        rest.eccentricity = self.eccentricity(&cmd.q_cmd);
        Ok(rest)
    }
}

/// The backlash approach-flank rule lives with the effects ([`crate::sim::effects::approach_sides`]):
/// the twin and the calibration's row inputs apply the same one.
pub use crate::sim::effects::approach_sides;
