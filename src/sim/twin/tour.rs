//! The acquisition itself simulated in rapier: one multibody runs the tour in order. The
//! controller moves the motor side of each joint along a joint-space trajectory
//! ([`super::motion::Move`]); the link follows through the transmission (spring with structural
//! damping, in series with the backlash band and its dry friction) under gravity, payload and
//! cable tension. After each move the arm is held for `sensor.hold_s` while the draw-wire sensor
//! samples at `sensor.rate_hz`; a stability gate watches the readings, and the `samples` readings
//! after the hold are averaged. The flank each joint rests on comes out of the motion.
//!
//! The joint coordinate is the link angle (rotation away from the configuration the multibody was
//! built at). The transmission acts on δ = link − motor, the motor side being the commanded
//! trajectory plus the encoder eccentricity. Time stepping:
//!
//! * **fine** (`simulation.dt_s`, aligned with the sensor's samples): the final deceleration, the
//!   hold and the reading window. Joints whose transmission mode is slow enough (ω·dt < 0.5) get
//!   their spring as an explicit torque (symplectic Euler: no numerical damping, so the damping
//!   ratio is the scenario's); stiffer ones rapier's implicit spring (stable, but it damps their
//!   fast modes numerically by k·dt).
//! * **coarse** (`acquisition.coarse_dt_s`, every spring implicit): the move up to its final
//!   deceleration.
//! * **none**: once the gate is open and the transient, decaying at the slowest modelled rate,
//!   would have fallen below 1 nm at the tool before the readings start, the arm is put at rest
//!   at its static equilibrium on the flanks it is on (the dynamics' fixed point) and the rest
//!   of the hold and the readings need no steps.
//!
//! The tour is cut into chunks of `acquisition.chunk_poses` poses. A chunk starts at rest at the
//! pose before its first one (the quasi-static equilibrium on the rule's flanks, see
//! [`super::approach_sides`]), at the time the schedule gives, so chunks are independent and
//! run in parallel with results that do not depend on the number of threads.

pub use super::acquisition::{Acquired, Acquisition, AcquisitionModel, OnTimeout, PhaseStats, Schedule, Timing, TourSettings, MAX_COARSE_DT_S, PHASES};
use super::motion::Move;
use super::rapier_sim::{build, contacts, dvec, joint_inertias, nvec, State};
use super::{PoseCommand, RestingPose, Twin};
use crate::error::{Error, Result};
use crate::robot::kinematics::{FkWork, Frame, PointJacobian};
use crate::sim::effects::statics::{Contact, Transmission};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rapier3d_f64::prelude::*;

/// Below this tool displacement (m) a transient no longer matters.
const NEGLIGIBLE_M: f64 = 1e-9;

/// Lever used to turn joint amplitudes into tool displacements, m (bounds the IRB 120's reach).
const REACH_M: f64 = 1.0;

/// Explicit springs where ω·dt stays below this (ω from the joint's inertia with the rest of the
/// arm held; the coupled modes run higher, and at 1.0 slow tours with short holds diverged).
const EXPLICIT_LIMIT: f64 = 0.5;

/// Largest link-to-motor twist before the simulation counts as diverged, rad.
const MAX_TWIST_RAD: f64 = 0.1;

struct Sim<'a> {
    twin: &'a Twin,
    acq: &'a Acquisition,
    trans: Option<&'a Transmission>,
    world: Option<(PhysicsWorld, Vec<MultibodyJointHandle>, Vec<RigidBodyHandle>)>,
    /// Motor-side angles (chain inputs) the multibody was built at.
    q_build: Vec<f64>,
    axes: Vec<Vector3<f64>>,
    tool_in_last: Vector3<f64>,
    states: Vec<State>,
    /// Per pose: structural damping (N·m·s/rad), transmission mode ω (rad/s).
    damping: Vec<f64>,
    omega: Vec<f64>,
    zeta_min: f64,
    steps: usize,
    ws: FkWork,
}

impl<'a> Sim<'a> {
    fn motor(&self, mv: &Move, j: usize, t: f64) -> (f64, f64) {
        let (q, v) = mv.joint(j, t);
        motor_of(self.twin, j, q, v)
    }

    fn coords(&self) -> (Vec<f64>, Vec<f64>) {
        let n = self.q_build.len();
        match &self.world {
            Some((world, handles, _)) if self.trans.is_some() => {
                let (mb, _) = world.multibody_joints.get(handles[0]).expect("built");
                let x = (0..n).map(|j| mb.link(j + 1).map(|l| l.joint().coords()[3]).unwrap_or(0.0)).collect();
                let v = mb.generalized_velocity().iter().copied().collect();
                (x, v)
            }
            _ => (vec![0.0; n], vec![0.0; n]),
        }
    }

    /// Link-side chain angles and deflections at time `t` of move `mv`.
    fn link(&self, mv: &Move, t: f64) -> (Vec<f64>, Vec<f64>) {
        let n = self.q_build.len();
        let (x, _) = self.coords();
        let mut q = vec![0.0; n];
        let mut d = vec![0.0; n];
        for j in 0..n {
            let (qm, _) = self.motor(mv, j, t);
            if self.trans.is_some() {
                q[j] = self.q_build[j] + x[j];
                d[j] = q[j] - qm;
            } else {
                q[j] = qm;
            }
        }
        (q, d)
    }

    /// Per-pose dynamics parameters at the move's target.
    fn prepare(&mut self, mv: &Move, t_abs: f64) {
        let Some(trans) = self.trans else { return };
        let n = self.q_build.len();
        let q_motor: Vec<f64> = (0..n).map(|j| self.motor(mv, j, mv.duration).0).collect();
        let (p, scale) = self.twin.params_at(t_abs);
        self.twin.chain.forward(&q_motor, &p, scale, &mut self.ws);
        let frames: Vec<Frame> = (0..self.twin.chain.n_frames()).map(|f| self.twin.chain.frame(&self.ws, f)).collect();
        let inertia = joint_inertias(self.twin, &frames);
        let given = self.twin.effects.compliance.as_ref().and_then(|c| c.damping_nms_per_rad.clone());
        self.zeta_min = f64::INFINITY;
        for j in 0..n {
            let (k, i) = (trans.stiffness[j], inertia[j].max(1e-9));
            self.omega[j] = (k / i).sqrt();
            self.damping[j] = match &given {
                Some(d) => d[j],
                None => 2.0 * self.acq.damping_ratio * (k * i).sqrt(),
            };
            self.zeta_min = self.zeta_min.min(self.damping[j] / (2.0 * (k * i).sqrt()));
        }
    }

    /// One rapier step of length `dt` from `t` (time from the move's start). Returns the largest
    /// joint speed relative to its motor after the step, rad/s.
    fn step(&mut self, mv: &Move, t: f64, dt: f64, fine: bool) -> Result<f64> {
        let Some(trans) = self.trans else { return Ok(0.0) };
        let n = self.q_build.len();
        let (x, v0) = self.coords();
        let mut torque = vec![0.0; n];
        let mut qd_end = vec![0.0; n];
        let motor0: Vec<(f64, f64)> = (0..n).map(|j| self.motor(mv, j, t)).collect();
        let motor1: Vec<(f64, f64)> = (0..n).map(|j| self.motor(mv, j, t + dt)).collect();
        {
            let (world, handles, _) = self.world.as_mut().expect("built");
            let (mb, _) = world.multibody_joints.get_mut(handles[0]).expect("built");
            for j in 0..n {
                let (qm0, _) = motor0[j];
                let (qm1, qd1) = motor1[j];
                qd_end[j] = qd1;
                let (k, h) = (trans.stiffness[j], trans.half_band[j]);
                let delta = self.q_build[j] + x[j] - qm0;
                // Contact decided against where the motor will be at the step's end (a coarse step may
                // carry it across the whole band), and in a coarse step where the link is heading too
                // (a link carried along on a flank would otherwise look left behind).
                let ahead = self.q_build[j] + x[j] + if fine { 0.0 } else { v0[j] * dt } - qm1;
                self.states[j] = next_state(self.states[j], ahead, (k, h, trans.breakaway), fine);
                let c = self.damping[j];
                let Some(link) = mb.link_mut(j + 1) else { continue };
                let (spring, rest, damp, extra, friction) = match self.states[j] {
                    State::Free => (0.0, 0.0, 0.0, 0.0, trans.breakaway > 0.0),
                    State::Spring | State::Flank(_) => {
                        let s = if let State::Flank(s) = self.states[j] { s } else { 0.0 };
                        if fine && self.omega[j] * dt < EXPLICIT_LIMIT {
                            // Explicit spring at the step's start, damping relative to the motor.
                            (0.0, 0.0, c, -k * (delta - s * h) + c * qd1, false)
                        } else {
                            // Implicit spring towards the motor's position at the step's end; it damps by k·dt itself.
                            let d = (c - k * dt).max(0.0);
                            (k, qm1 - self.q_build[j] + s * h, d, d * qd1, false)
                        }
                    }
                };
                link.joint.set_spring(3, spring, rest);
                mb.damping_mut()[j] = damp;
                mb.frictions_mut()[j] = if friction { trans.breakaway } else { 0.0 };
                torque[j] = extra;
            }
        }
        let (world, _, bodies) = self.world.as_mut().expect("built");
        for b in bodies.iter().skip(1) {
            let rb = &mut world.bodies[*b];
            rb.reset_forces(false);
            rb.reset_torques(false);
        }
        for j in 0..n {
            if torque[j] == 0.0 {
                continue;
            }
            let child = &world.bodies[bodies[j + 1]];
            let axis = nvec(child.position().rotation * dvec(&self.axes[j]));
            world.bodies[bodies[j + 1]].add_torque(dvec(&(axis * torque[j])), false);
            if j > 0 {
                world.bodies[bodies[j]].add_torque(dvec(&(-axis * torque[j])), false);
            }
        }
        if let Some(cable) = &self.twin.load.cable {
            let rb = &mut world.bodies[bodies[n]];
            let p = nvec(rb.position().transform_point(dvec(&self.tool_in_last)));
            rb.add_force_at_point(dvec(&cable.force_at(&p)), dvec(&p), false);
        }
        world.integration_parameters.dt = dt;
        world.step();
        self.steps += 1;
        let (x, v) = self.coords();
        let mut fastest: f64 = 0.0;
        for j in 0..n {
            // No real transmission twists by a tenth of a radian: that is a diverged integration.
            let twist = self.q_build[j] + x[j] - motor1[j].0;
            if !(v[j].is_finite() && twist.abs() < MAX_TWIST_RAD) {
                return Err(Error::Simulation(format!("joint {} diverged (link {twist:e} rad off its motor)", j + 1)));
            }
            fastest = fastest.max((v[j] - qd_end[j]).abs());
        }
        Ok(fastest)
    }

    /// Steps from `t0` to `t1` (times from the move's start) with steps of at most `dt_max`.
    fn run(&mut self, mv: &Move, t0: f64, t1: f64, dt_max: f64, fine: bool) -> Result<usize> {
        if t1 <= t0 || self.trans.is_none() {
            return Ok(0);
        }
        let count = ((t1 - t0) / dt_max - 1e-9).ceil().max(1.0) as usize;
        let dt = (t1 - t0) / count as f64;
        for k in 0..count {
            self.step(mv, t0 + k as f64 * dt, dt, fine)?;
        }
        Ok(count)
    }

    /// Tool point (m) and noise-free length (mm) at time `t` of move `mv`, `t_abs` absolute.
    fn reading(&mut self, mv: &Move, t: f64, t_abs: f64) -> (Vector3<f64>, f64) {
        let (q, _) = self.link(mv, t);
        let (p, scale) = self.twin.params_at(t_abs);
        let chain = &self.twin.chain;
        chain.forward(&q, &p, scale, &mut self.ws);
        let tool = chain.frame(&self.ws, chain.flange()).point(&self.twin.draw_wire.tool_point_m());
        (tool, self.twin.draw_wire.ideal_length(&tool))
    }

    /// Tool point (m) of the arm at rest at commanded pose `q_cmd` at time `t`, on the flanks the
    /// joints are on now (a flank loaded off by more than the breakaway gives way to the other);
    /// a joint inside its band keeps its deflection `delta` when friction holds it (load at most the
    /// breakaway), else the load carries it to its flank. Also returns the
    /// link angles and the flank states.
    /// The quasi-static fixed point of [`crate::sim::effects::statics::equilibrium`] with that rule.
    fn rest_reference(&mut self, q_cmd: &[f64], delta: &[f64], t: f64) -> (Vector3<f64>, Vec<f64>, Vec<State>) {
        let twin = self.twin;
        let chain = &twin.chain;
        let n = q_cmd.len();
        let q_motor: Vec<f64> = (0..n).map(|j| motor_of(twin, j, q_cmd[j], 0.0).0).collect();
        let (p, scale) = twin.params_at(t);
        let mut q = q_motor.clone();
        let mut d = delta.to_vec();
        let mut states = self.states.clone();
        if let Some(trans) = self.trans {
            let mut jac = PointJacobian::new(chain);
            let mut tau = vec![0.0; n];
            for _ in 0..100 {
                chain.forward(&q, &p, scale, &mut self.ws);
                twin.load.torques(chain, &self.ws, &mut jac, &mut tau);
                let mut change: f64 = 0.0;
                for j in 0..n {
                    // A flank whose load pulls the link off it by more than the breakaway lets go:
                    // the load carries the link across the band to its own flank.
                    // A joint inside its band (between flanks when the transient was judged
                    // over) is carried by a load above the breakaway to the load's flank; below
                    // it, friction holds it where it is.
                    match states[j] {
                        State::Flank(s) if tau[j] * s < 0.0 && tau[j].abs() > trans.breakaway => states[j] = State::Flank(-s),
                        State::Free if tau[j].abs() > trans.breakaway => states[j] = State::Flank(tau[j].signum()),
                        _ => {}
                    }
                    let new = match states[j] {
                        State::Spring => tau[j] / trans.stiffness[j],
                        State::Flank(s) => s * trans.half_band[j] + tau[j] / trans.stiffness[j],
                        State::Free => delta[j],
                    };
                    change = change.max((new - d[j]).abs());
                    d[j] = new;
                    q[j] = q_motor[j] + new;
                }
                if change < 1e-15 {
                    break;
                }
            }
        }
        chain.forward(&q, &p, scale, &mut self.ws);
        (chain.frame(&self.ws, chain.flange()).point(&twin.draw_wire.tool_point_m()), q, states)
    }

    /// Puts the arm at rest (no velocity) at its static equilibrium on its current flanks, at time
    /// `t` of move `mv` (`t_abs` absolute).
    fn snap_to_rest(&mut self, mv: &Move, t: f64, t_abs: f64) -> Result<()> {
        if self.trans.is_none() {
            return Ok(());
        }
        let (_, delta) = self.link(mv, t);
        let q_cmd: Vec<f64> = (0..delta.len()).map(|j| mv.joint(j, t).0).collect();
        let (_, q, states) = self.rest_reference(&q_cmd, &delta, t_abs);
        self.states = states;
        let (x, _) = self.coords();
        let disp: Vec<f64> = (0..q.len()).map(|j| q[j] - self.q_build[j] - x[j]).collect();
        let (world, handles, _) = self.world.as_mut().expect("built");
        let (mb, _) = world.multibody_joints.get_mut(handles[0]).ok_or_else(|| Error::Simulation("multibody missing".into()))?;
        mb.apply_displacements(&disp);
        mb.generalized_velocity_mut().fill(0.0);
        mb.forward_kinematics(&world.bodies, false);
        mb.update_rigid_bodies(&mut world.bodies, true);
        Ok(())
    }

    fn contacts(&self, delta: &[f64]) -> Vec<Contact> {
        let Some(trans) = self.trans else { return vec![Contact::Spring; delta.len()] };
        contacts(&self.states, delta, &trans.half_band)
    }
}

/// The motor-side angle and velocity of joint `j` commanded to `q` at velocity `v`: every
/// effect's encoder error added, the velocity through its slope.
fn motor_of(twin: &Twin, j: usize, q: f64, v: f64) -> (f64, f64) {
    let e = &twin.effects;
    let Some(offset) = e.motor_offset_rad(j, q) else { return (q, v) };
    let h = 1e-6;
    let at = |q: f64| e.motor_offset_rad(j, q).unwrap_or(0.0);
    let slope = (at(q + h) - at(q - h)) / (2.0 * h);
    (q + offset, v * (1.0 + slope))
}

/// One raw sample of the twin's instrument for the stability gate, appended to `raw`: the cable's
/// reading of noise-free length `l` (mm), or with a tracker its reading of tool point `tool` (one
/// sample's noise).
fn gate_sample(twin: &Twin, tool: &Vector3<f64>, l: f64, rng: &mut ChaCha8Rng, raw: &mut Vec<f64>) {
    match twin.instruments.active() {
        Some(i) => raw.extend(i.raw_sample(tool, rng)),
        None => raw.push(twin.draw_wire.raw_sample(l, rng)),
    }
}

/// How far the mean of the last `ng` raw samples (of `dim` values each, row after row) is from
/// the mean of the `ng` before them, mm: the change of a length, or the distance between points.
fn gate_change_mm(raw: &[f64], ng: usize, dim: usize) -> f64 {
    let m = raw.len();
    let mean = |from: usize, to: usize, c: usize| raw[from..to].iter().skip(c).step_by(dim).sum::<f64>() / ng as f64;
    if dim == 1 {
        return (mean(m - ng, m, 0) - mean(m - 2 * ng, m - ng, 0)).abs();
    }
    (0..dim).map(|c| (mean(m - ng * dim, m, c) - mean(m - 2 * ng * dim, m - ng * dim, c)).powi(2)).sum::<f64>().sqrt()
}

/// Simulates the whole tour `poses` (commanded angles, rad) starting from `home`, chunked and in
/// parallel; one result per pose, in order. `progress` is told of every pose done.
pub fn acquire(
    twin: &Twin,
    acq: &Acquisition,
    settings: TourSettings,
    home: &[f64],
    poses: &[Vec<f64>],
    read_at: Option<&[f64]>,
    progress: &dyn crate::progress::Progress,
) -> Vec<Result<Acquired>> {
    use rayon::prelude::*;
    let sn = &twin.draw_wire;
    let timing = Timing { speed_fraction: settings.speed_fraction, ramp_s: acq.ramp_s, hold_s: sn.hold_s, window_s: sn.window_s() };
    let schedule = Schedule::new(&twin.robot, &timing, home, poses, read_at);
    let rule = super::approach_sides(home, poses);
    let run = TourRun { twin, acq, settings, schedule: &schedule, home, poses, rule: &rule, progress };
    let starts: Vec<usize> = (0..poses.len()).step_by(acq.chunk_poses.max(1)).collect();
    let chunks: Vec<Vec<Result<Acquired>>> = starts
        .par_iter()
        .map(|&a| {
            let b = (a + acq.chunk_poses).min(poses.len());
            let r = run_chunk(&run, a, b);
            r.unwrap_or_else(|e| (a..b).map(|_| Err(Error::Simulation(e.to_string()))).collect())
        })
        .collect();
    chunks.into_iter().flatten().collect()
}

/// One tour, as every chunk of it reads it: the twin, the acquisition and its settings, the
/// schedule, the start, the poses and the flanks the approach rule puts each joint on.
struct TourRun<'a> {
    twin: &'a Twin,
    acq: &'a Acquisition,
    settings: TourSettings,
    schedule: &'a Schedule,
    home: &'a [f64],
    poses: &'a [Vec<f64>],
    rule: &'a [Vec<f64>],
    progress: &'a dyn crate::progress::Progress,
}

/// Simulates poses `a..b` of the tour, from rest at the pose before them.
fn run_chunk(run: &TourRun, a: usize, b: usize) -> Result<Vec<Result<Acquired>>> {
    let TourRun { twin, acq, settings, schedule, home, poses, rule, progress } = *run;
    let chain = &twin.chain;
    let n = chain.n_joints;
    // At rest at the pose before the chunk, on the rule's flanks.
    let (q0, sides0) = if a == 0 { (home.to_vec(), vec![-1.0; n]) } else { (poses[a - 1].clone(), rule[a - 1].clone()) };
    let t0 = schedule.chunk_start(a);
    let start = twin.quasi_static(&PoseCommand { q_cmd: q0.clone(), sides: sides0.clone(), t: t0 });
    let q_build = twin.motor_command(&PoseCommand { q_cmd: q0.clone(), sides: sides0.clone(), t: t0 }).q_cmd;
    let (p, scale) = twin.params_at(t0);
    let mut ws = FkWork::new(chain);
    chain.forward(&q_build, &p, scale, &mut ws);
    let frames: Vec<Frame> = (0..chain.n_frames()).map(|f| chain.frame(&ws, f)).collect();
    let trans = twin.transmission.as_ref();
    let world = if trans.is_some() {
        let (mut world, handles, bodies) = build(twin, &frames)?;
        world.integration_parameters.num_solver_iterations = 1;
        {
            let (mb, _) = world.multibody_joints.get_mut(handles[0]).ok_or_else(|| Error::Simulation("multibody missing".into()))?;
            if mb.ndofs() != n {
                return Err(Error::Simulation(format!("multibody has {} degrees of freedom, expected {n}", mb.ndofs())));
            }
            mb.apply_displacements(&start.deflection);
            mb.forward_kinematics(&world.bodies, false);
            mb.update_rigid_bodies(&mut world.bodies, true);
        }
        Some((world, handles, bodies))
    } else {
        None
    };
    let states = match trans {
        Some(t) => (0..n).map(|j| if t.half_band[j] == 0.0 { State::Spring } else { State::Flank(sides0[j]) }).collect(),
        None => vec![State::Spring; n],
    };
    let axes = (0..n).map(|j| chain.joint_op(j).map(|op| chain.ops[op].axis).unwrap_or_else(Vector3::z)).collect();
    let tool_in_last = frames[chain.flange()].relative_to(&frames[n]).point(&twin.draw_wire.tool_point_m());
    let mut sim = Sim {
        twin,
        acq,
        trans,
        world,
        q_build,
        axes,
        tool_in_last,
        states,
        damping: vec![0.0; n],
        omega: vec![0.0; n],
        zeta_min: 0.0,
        steps: 0,
        ws: FkWork::new(chain),
    };
    let mut out = Vec::with_capacity(b - a);
    for i in a..b {
        let r = acquire_pose(&mut sim, settings, schedule, i, &rule[i]);
        progress.inc(1);
        let failed = r.is_err();
        out.push(r);
        if failed {
            // The state is lost: the rest of the chunk cannot be simulated.
            for _ in i + 1..b {
                out.push(Err(Error::Simulation(format!("an earlier pose of the chunk (pose {i}) failed"))));
                progress.inc(1);
            }
            break;
        }
    }
    Ok(out)
}

/// A pose's clock: the move's start (s from the start of acquisition), the fine steps per
/// reading period, their length and the period (s).
#[derive(Clone, Copy)]
struct Clock {
    t_start: f64,
    sub: usize,
    fine_dt: f64,
    period: f64,
}

/// The hold's outcome: when the gate opened and when the transient became negligible (s after
/// the arrival), where stepping stopped (time, reading sample), and the fine steps it took.
struct Hold {
    gate_s: Option<f64>,
    negligible_s: Option<f64>,
    t: f64,
    k: usize,
    fine_steps: usize,
}

/// The hold after move `mv` (pose `i`): raw readings at the sensor's rate feed the stability
/// gate; once it is open, stepping stops when the transient, decaying at the slowest modelled
/// rate, is negligible by the time the readings start.
fn hold(sim: &mut Sim, mv: &Move, seed: u64, i: usize, clock: Clock, hold_samples: usize) -> Result<Hold> {
    let (twin, acq) = (sim.twin, sim.acq);
    let sn = &twin.draw_wire;
    let Clock { t_start, sub, fine_dt, period } = clock;
    let arrive = mv.duration;
    let window_start = arrive + sn.hold_s;
    let ng = acq.gate_samples(sn.rate_hz);
    let mut rng = ChaCha8Rng::seed_from_u64(crate::seed::stream_seed(seed, crate::seed::Stream::Gate, i as u64));
    // The instrument's raw samples, `dim` values each: the cable's length or the tracker's point.
    let dim = twin.instruments.active().map_or(1, |i| i.measurement().file_lengths());
    let mut raw: Vec<f64> = Vec::with_capacity((dim * hold_samples).min(1 << 16));
    let (mut gate_s, mut negligible_s) = (None, None);
    let slow = sim.omega.iter().copied().fold(f64::INFINITY, f64::min);
    let recent = if slow.is_finite() && slow > 0.0 { ((std::f64::consts::TAU / slow) * sn.rate_hz).ceil() as usize } else { 1 };
    let mut speeds: std::collections::VecDeque<f64> = std::collections::VecDeque::new();
    let mut fine_steps = 0;
    let mut t = arrive;
    let mut k = 0;
    while k < hold_samples {
        k += 1;
        let mut fastest: f64 = 0.0;
        for _ in 0..sub {
            fastest = fastest.max(sim.step(mv, t, fine_dt, true)?);
            fine_steps += usize::from(sim.trans.is_some());
            t += fine_dt;
        }
        t = arrive + k as f64 * period;
        if gate_s.is_none() {
            let (tool, l) = sim.reading(mv, t, t_start + t);
            gate_sample(twin, &tool, l, &mut rng, &mut raw);
            if raw.len() >= 2 * ng * dim && gate_change_mm(&raw, ng, dim) < acq.gate_mm {
                gate_s = Some(k as f64 * period);
            }
        }
        speeds.push_back(fastest);
        if speeds.len() > recent {
            speeds.pop_front();
        }
        if gate_s.is_some() && (sim.trans.is_none() || speeds.len() >= recent) {
            let amplitude = if sim.trans.is_none() { 0.0 } else { speeds.iter().copied().fold(0.0, f64::max) / slow * REACH_M };
            if amplitude * (-sim.zeta_min * slow * (window_start - t)).exp() < NEGLIGIBLE_M {
                negligible_s = Some(t - arrive);
                break;
            }
        }
    }
    Ok(Hold { gate_s, negligible_s, t, k, fine_steps })
}

/// The reading window after the hold, from `window_start`: the samples' lengths and the sum of
/// their tool points (m), the time reached and the steps taken (none once `resting`).
fn reading_window(sim: &mut Sim, mv: &Move, clock: Clock, window_start: f64, resting: bool) -> Result<(Vec<f64>, Vector3<f64>, f64, usize)> {
    let Clock { t_start, sub, fine_dt, period } = clock;
    let samples = sim.twin.draw_wire.samples;
    let mut s = 0;
    let mut lengths = Vec::with_capacity(samples);
    let mut tool_sum = Vector3::zeros();
    let mut t = window_start;
    for k in 1..=samples {
        let tk = window_start + k as f64 * period;
        if !resting {
            for _ in 0..sub {
                sim.step(mv, t, fine_dt, true)?;
                s += 1;
                t += fine_dt;
            }
        }
        t = tk;
        let (tool, l) = sim.reading(mv, tk, t_start + tk);
        lengths.push(l);
        tool_sum += tool;
    }
    Ok((lengths, tool_sum, t, s))
}

/// The arm's frames and its joint torques at link angles `q_link` at time `t_read`.
fn frames_and_torques(sim: &mut Sim, q_link: &[f64], t_read: f64) -> (Vec<Frame>, Vec<f64>) {
    let twin = sim.twin;
    let (p, scale) = twin.params_at(t_read);
    let chain = &twin.chain;
    chain.forward(q_link, &p, scale, &mut sim.ws);
    let frames: Vec<Frame> = (0..chain.n_frames()).map(|f| chain.frame(&sim.ws, f)).collect();
    let mut torque = vec![0.0; q_link.len()];
    let mut jac = PointJacobian::new(chain);
    twin.load.torques(chain, &sim.ws, &mut jac, &mut torque);
    (frames, torque)
}

/// A joint's contact state after a step, from `before` and `ahead` (the deflection against where
/// the motor will be at the step's end), with stiffness `k`, half band `h` and breakaway torque.
fn next_state(before: State, ahead: f64, (k, h, breakaway): (f64, f64, f64), fine: bool) -> State {
    let next = match before {
        State::Spring => State::Spring,
        State::Flank(s) => {
            let pull = ahead - s * h;
            if pull * s < 0.0 && k * pull.abs() > breakaway {
                State::Free
            } else {
                State::Flank(s)
            }
        }
        State::Free if ahead.abs() >= h => State::Flank(ahead.signum()),
        State::Free => State::Free,
    };
    if fine || next != State::Free {
        return next;
    }
    // A coarse step is far longer than a crossing of the band: the link lands on the flank it is
    // heading for (the other one when it just let go of one).
    match before {
        State::Flank(s) => State::Flank(-s),
        _ => State::Flank(if ahead >= 0.0 { 1.0 } else { -1.0 }),
    }
}

fn acquire_pose(sim: &mut Sim, settings: TourSettings, schedule: &Schedule, i: usize, rule: &[f64]) -> Result<Acquired> {
    use std::time::Instant;
    let twin = sim.twin;
    let sn = &twin.draw_wire;
    let acq = sim.acq;
    let mv = &schedule.moves[i];
    let t_start = schedule.move_start[i];
    let mut stats = PhaseStats::default();
    let phase = |stats: &mut PhaseStats, k: usize, t0: Instant, steps: usize| {
        stats.steps[k] += steps;
        stats.seconds[k] += t0.elapsed().as_secs_f64();
    };
    sim.prepare(mv, t_start + mv.duration);
    let period = 1.0 / sn.rate_hz;
    let sub = (period / twin.settle.dt_s - 1e-9).ceil().max(1.0) as usize;
    let fine_dt = period / sub as f64;

    // The move: coarse until its final deceleration, fine through it.
    let t_dec = (mv.duration - mv.ramp).max(0.0);
    let c = Instant::now();
    let s = sim.run(mv, 0.0, t_dec, acq.coarse_dt_s, false)?;
    phase(&mut stats, 0, c, s);
    let c = Instant::now();
    let s = sim.run(mv, t_dec, mv.duration, fine_dt, true)?;
    phase(&mut stats, 1, c, s);

    // The hold: raw readings at rate_hz feed the gate.
    let arrive = mv.duration;
    let hold_samples = (sn.hold_s * sn.rate_hz + 1e-9).floor() as usize;
    let window_start = arrive + sn.hold_s;
    let c = Instant::now();
    let clock = Clock { t_start, sub, fine_dt, period };
    let mut resting = sim.trans.is_none();
    let Hold { gate_s, negligible_s, t, k, fine_steps } = hold(sim, mv, settings.seed, i, clock, hold_samples)?;
    phase(&mut stats, 2, c, fine_steps);
    if k < hold_samples {
        // What is left of the transient decays below 1 nm before the readings: the rest of the
        // hold passes with the arm at rest where it is heading (the static equilibrium on its
        // flanks, which is also the fixed point of the dynamics), without stepping.
        let c = Instant::now();
        sim.snap_to_rest(mv, t, t_start + t)?;
        resting = true;
        phase(&mut stats, 3, c, 0);
    }

    // The reading window after the hold.
    let c = Instant::now();
    let (lengths, tool_sum, t, s) = reading_window(sim, mv, clock, window_start, resting)?;
    phase(&mut stats, 4, c, if sim.trans.is_some() { s } else { 0 });
    let t_read = schedule.read_t[i];
    let (q_link, deflection) = sim.link(mv, t);
    let contact = sim.contacts(&deflection);
    let reference = sim.rest_reference(&mv.to, &deflection, t_read).0;
    let transient_mm = if twin.instruments.active().is_some() {
        // How far the window's mean point is from the arm at rest (a rigid transform away from
        // what the tracker reads).
        crate::units::to_mm((tool_sum / sn.samples as f64 - reference).norm())
    } else {
        let mean_l = lengths.iter().sum::<f64>() / lengths.len() as f64;
        mean_l - sn.ideal_length(&reference)
    };
    let (frames, torque) = frames_and_torques(sim, &q_link, t_read);
    let rest = RestingPose {
        q_link,
        eccentricity: twin.eccentricity(&mv.to),
        deflection,
        torque,
        contact,
        tool: tool_sum / sn.samples as f64,
        frames,
        steps: stats.steps.iter().sum(),
    };
    Ok(Acquired { rest, lengths, gate_s, transient_mm, negligible_s, rule_sides: rule.to_vec(), stats })
}
