//! One pose of the twin in rapier3d-f64: a fixed base, one dynamic body per link with the URDF
//! inertia (payload merged into the last link), joined by reduced-coordinate multibody joints.
//!
//! Each joint's motor-side angle (commanded + encoder eccentricity, see [`Twin::motor_command`]) is
//! built into its parent-side frame, so the joint coordinate is the link-side deflection δ. The
//! transmission acts through rapier's implicit joint spring, switched per step between "on a
//! flank" (spring with its rest angle at the flank) and "inside the band" (no spring, dry
//! friction), which is backlash in series with compliance. Cable tension is an external
//! force on the last link at the tool point, recomputed every step.

use super::{PoseCommand, RestingPose, Twin};
use crate::error::{Error, Result};
use crate::robot::kinematics::{FkWork, Frame};
use crate::robot::Inertial;
use crate::sim::effects::statics::{Contact, Transmission};
use nalgebra::{Matrix3, Vector3};
use rapier3d_f64::glamx::{DMat3, DQuat, DVec3};
use rapier3d_f64::prelude::*;

pub(super) fn dvec(v: &Vector3<f64>) -> DVec3 {
    DVec3::new(v.x, v.y, v.z)
}
pub(super) fn nvec(v: DVec3) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}
fn dmat(m: &Matrix3<f64>) -> DMat3 {
    DMat3::from_cols(dvec(&m.column(0).into()), dvec(&m.column(1).into()), dvec(&m.column(2).into()))
}
pub(super) fn pose(f: &Frame) -> Pose {
    Pose::from_parts(dvec(&f.pos), DQuat::from_mat3(&dmat(&f.rot)).normalize())
}
pub(super) fn frame(p: &Pose) -> Frame {
    let m = DMat3::from_quat(p.rotation);
    let c = |v: DVec3| nvec(v);
    Frame { rot: Matrix3::from_columns(&[c(m.x_axis), c(m.y_axis), c(m.z_axis)]), pos: nvec(p.translation) }
}

/// A rotation taking the x axis onto the unit vector `u`.
fn align_x_to(u: &Vector3<f64>) -> Matrix3<f64> {
    let x = Vector3::x();
    let c = x.dot(u);
    if c > 1.0 - 1e-15 {
        return Matrix3::identity();
    }
    if c < -1.0 + 1e-15 {
        return Matrix3::new(-1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0);
    }
    *nalgebra::Rotation3::rotation_between(&x, u).expect("non-antiparallel").matrix()
}

fn mass_props(i: &Inertial) -> MassProperties {
    // A massless link would make the multibody mass matrix singular.
    let (m, inertia) = if i.mass > 1e-9 { (i.mass, i.inertia) } else { (1e-6, Matrix3::identity() * 1e-9) };
    MassProperties::with_inertia_matrix(dvec(&i.com), m, dmat(&inertia))
}

/// Per-joint transmission state (the settling loop and the simulated tour).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum State {
    Spring,
    Flank(f64),
    Free,
}

/// The contact each joint is in, from its transmission state and its deflection δ = link − motor
/// (rad): on a flank but pulled off it (held by friction), on the positive or negative flank,
/// inside the band, or a plain spring.
pub(super) fn contacts(states: &[State], delta: &[f64], half_band: &[f64]) -> Vec<Contact> {
    states
        .iter()
        .enumerate()
        .map(|(j, s)| match s {
            State::Spring => Contact::Spring,
            State::Flank(s) if (delta[j] - s * half_band[j]) * s < 0.0 => Contact::Held,
            State::Flank(s) if *s > 0.0 => Contact::Positive,
            State::Flank(_) => Contact::Negative,
            State::Free => Contact::Free,
        })
        .collect()
}

/// Simulates the pose `cmd`, whose angles are the true motor-side ones (see [`Twin::motor_command`]).
pub(super) fn simulate(twin: &Twin, cmd: &PoseCommand) -> Result<RestingPose> {
    let chain = &twin.chain;
    let n = chain.n_joints;
    let (params, scale) = twin.params_at(cmd.t);
    let mut ws = FkWork::new(chain);
    chain.forward(&cmd.q_cmd, &params, scale, &mut ws);
    let frames: Vec<Frame> = (0..chain.n_frames()).map(|f| chain.frame(&ws, f)).collect();

    let (mut world, handles, bodies) = build(twin, &frames)?;
    let pose = Posed { cmd, frames: &frames, params: &params, scale };
    let Some(trans) = twin.transmission.as_ref() else {
        // Rigid arm: nothing moves, the multibody's own forward kinematics gives the pose.
        return read_back(twin, &world, &handles, &pose, Settled { deflection: vec![0.0; n], contact: vec![Contact::Spring; n], steps: 0 });
    };
    settle(twin, trans, &mut world, (&handles, &bodies), &pose)
}

/// The pose a simulation settles: its command, the link frames it starts from (base, links,
/// flange) and the geometry at its time (parameters and thermal scale).
struct Posed<'a> {
    cmd: &'a PoseCommand,
    frames: &'a [Frame],
    params: &'a [f64],
    scale: f64,
}

/// Where the transmission came to rest: each joint's deflection (link − motor, rad) and
/// contact, after how many steps.
struct Settled {
    deflection: Vec<f64>,
    contact: Vec<Contact>,
    steps: usize,
}

/// The multibody at the configuration whose link frames are `frames` (base, links, flange): a
/// fixed base and one dynamic body per link (payload merged into the last), joined by revolute
/// multibody joints (fixed joints for a rigid arm) whose coordinate is the rotation away from
/// `frames`. Returns the world, the joint handles and the body handles (base first).
pub(super) fn build(twin: &Twin, frames: &[Frame]) -> Result<(PhysicsWorld, Vec<MultibodyJointHandle>, Vec<RigidBodyHandle>)> {
    let chain = &twin.chain;
    let n = chain.n_joints;
    let flange_in_last = frames[chain.flange()].relative_to(&frames[n]);
    let mut world = PhysicsWorld::new();
    world.gravity = dvec(&twin.load.gravity);
    world.integration_parameters.dt = twin.settle.dt_s;
    let base = world.bodies.insert(RigidBodyBuilder::fixed().pose(pose(&frames[0])).build());
    let mut bodies = vec![base];
    for j in 0..n {
        let mut inertial = twin.robot.links[j].clone();
        if j == n - 1 {
            if let Some((m, com)) = &twin.load.payload {
                let payload = Inertial { mass: *m, com: flange_in_last.point(com), inertia: Matrix3::zeros() };
                inertial = inertial.combine(&payload);
            }
        }
        let rb = RigidBodyBuilder::dynamic().pose(pose(&frames[j + 1])).additional_mass_properties(mass_props(&inertial)).can_sleep(false).build();
        bodies.push(world.bodies.insert(rb));
    }

    // Joints: parent frame → commanded child frame, then the free rotation about the joint axis.
    let mut handles = Vec::with_capacity(n);
    for j in 0..n {
        let op = chain.joint_op(j).ok_or_else(|| Error::Simulation(format!("joint {j} has no rotation")))?;
        let axis = chain.ops[op].axis;
        let parent_to_child = frames[j + 1].relative_to(&frames[j]);
        let align = Frame { rot: align_x_to(&axis), pos: Vector3::zeros() };
        let mask = if twin.transmission.is_some() { JointAxesMask::LOCKED_REVOLUTE_AXES } else { JointAxesMask::LOCKED_FIXED_AXES };
        let joint = GenericJointBuilder::new(mask).local_frame1(pose(&parent_to_child.compose(&align))).local_frame2(pose(&align)).build();
        let h = world.multibody_joints.insert(bodies[j], bodies[j + 1], joint, true).ok_or_else(|| Error::Simulation(format!("rapier refused joint {j}")))?;
        handles.push(h);
    }

    // The root is the fixed base: let rapier take its pose and drop the root's free degrees of freedom.
    {
        let (mb, _) = world.multibody_joints.get_mut(handles[0]).ok_or_else(|| Error::Simulation("multibody missing".into()))?;
        mb.set_self_contacts_enabled(false);
        mb.forward_kinematics(&world.bodies, true);
        mb.update_rigid_bodies(&mut world.bodies, true);
    }
    Ok((world, handles, bodies))
}

/// Inertia about each joint axis of everything distal to it (payload included), kg·m², from the
/// frames at the commanded pose. Frame `j + 1` closes right after joint `j`'s rotation, so its
/// origin lies on that joint's axis and the axis keeps its direction.
pub(super) fn joint_inertias(twin: &Twin, frames: &[Frame]) -> Vec<f64> {
    let chain = &twin.chain;
    let n = chain.n_joints;
    let mut bodies: Vec<Inertial> = (0..n).map(|i| twin.robot.links[i].transformed(&frames[i + 1])).collect();
    if let Some((m, com)) = &twin.load.payload {
        bodies.push(Inertial { mass: *m, com: frames[chain.flange()].point(com), inertia: Matrix3::zeros() });
    }
    (0..n)
        .map(|j| {
            let axis = chain.joint_op(j).map(|op| chain.ops[op].axis).unwrap_or_else(Vector3::z);
            let (o, w) = (frames[j + 1].pos, frames[j + 1].rot * axis);
            bodies[j..]
                .iter()
                .map(|b| {
                    let r = b.com - o;
                    let r_perp = r - w * w.dot(&r);
                    w.dot(&(b.inertia * w)) + b.mass * r_perp.norm_squared()
                })
                .sum()
        })
        .collect()
}

fn settle(
    twin: &Twin,
    trans: &Transmission,
    world: &mut PhysicsWorld,
    (handles, bodies): (&[MultibodyJointHandle], &[RigidBodyHandle]),
    pose: &Posed,
) -> Result<RestingPose> {
    let (cmd, frames) = (pose.cmd, pose.frames);
    let chain = &twin.chain;
    let n = chain.n_joints;
    // Every joint arrives resting on the flank its approach motion leaves it on.
    let mut states: Vec<State> = (0..n).map(|j| if trans.half_band[j] == 0.0 { State::Spring } else { State::Flank(cmd.sides[j]) }).collect();
    let initial: Vec<f64> = (0..n).map(|j| cmd.sides[j] * trans.half_band[j]).collect();
    start_at(twin, trans, world, handles[0], &initial, frames)?;

    let tool_local = twin.draw_wire.tool_point_m();
    let flange_in_last = frames[chain.flange()].relative_to(&frames[n]);
    let tool_in_last = flange_in_last.point(&tool_local);
    let last_body = bodies[n];

    let mut prev = initial.clone();
    let mut quiet = 0;
    let mut steps = 0;
    let mut delta = initial;
    while steps < twin.settle.max_steps {
        set_transmission(trans, world, handles[0], &mut states, &delta);
        // Cable tension on the tool point.
        if let Some(cable) = &twin.load.cable {
            let rb = &mut world.bodies[last_body];
            let p = nvec(rb.position().transform_point(dvec(&tool_in_last)));
            rb.reset_forces(false);
            rb.reset_torques(false);
            rb.add_force_at_point(dvec(&cable.force_at(&p)), dvec(&p), false);
        }
        world.step();
        steps += 1;
        let (mb, _) = world.multibody_joints.get(handles[0]).expect("checked above");
        let mut change: f64 = 0.0;
        for j in 0..n {
            let d = mb.link(j + 1).map(|l| l.joint().coords()[3]).unwrap_or(0.0);
            if !d.is_finite() {
                return Err(Error::Simulation(format!("joint {} diverged at step {steps}", j + 1)));
            }
            change = change.max((d - prev[j]).abs());
            delta[j] = d;
        }
        prev.copy_from_slice(&delta);
        let sliding = states.contains(&State::Free);
        if change < twin.settle.step_tolerance_rad && !sliding {
            quiet += 1;
            if quiet >= twin.settle.quiet_steps {
                if !slip(trans, &mut states, &delta) {
                    break;
                }
                quiet = 0;
            }
        } else {
            quiet = 0;
        }
    }
    if steps >= twin.settle.max_steps {
        return Err(Error::Simulation(format!("pose did not settle within {} steps", twin.settle.max_steps)));
    }
    let contact = contacts(&states, &delta, &trans.half_band);
    read_back(twin, world, handles, pose, Settled { deflection: delta, contact, steps })
}

/// Puts the multibody (`handle`) at the joints' starting deflections `initial` and sets each
/// joint's damping: given, or near-critical from the inertia it moves with the rest held.
fn start_at(twin: &Twin, trans: &Transmission, world: &mut PhysicsWorld, handle: MultibodyJointHandle, initial: &[f64], frames: &[Frame]) -> Result<()> {
    let n = initial.len();
    let (mb, _) = world.multibody_joints.get_mut(handle).ok_or_else(|| Error::Simulation("multibody missing".into()))?;
    if mb.ndofs() != n {
        return Err(Error::Simulation(format!("multibody has {} degrees of freedom, expected {n}", mb.ndofs())));
    }
    mb.apply_displacements(initial);
    mb.forward_kinematics(&world.bodies, false);
    mb.update_rigid_bodies(&mut world.bodies, true);
    let inertia = joint_inertias(twin, frames);
    let damping: Vec<f64> = (0..n)
        .map(|j| {
            twin.effects
                .compliance
                .as_ref()
                .and_then(|c| c.damping_nms_per_rad.as_ref())
                .map(|d| d[j])
                .unwrap_or_else(|| 2.0 * twin.settle.damping_ratio * (trans.stiffness[j] * inertia[j].max(1e-9)).sqrt())
        })
        .collect();
    for (j, d) in damping.iter().enumerate() {
        mb.damping_mut()[j] = *d;
    }
    Ok(())
}

/// The transmission's state machine at deflections `delta` (a free joint that reaches a flank
/// rests on it), and each joint's spring and friction for it.
fn set_transmission(trans: &Transmission, world: &mut PhysicsWorld, handle: MultibodyJointHandle, states: &mut [State], delta: &[f64]) {
    let (mb, _) = world.multibody_joints.get_mut(handle).expect("checked in start_at");
    for j in 0..states.len() {
        let h = trans.half_band[j];
        let d = delta[j];
        states[j] = match states[j] {
            State::Spring => State::Spring,
            State::Free if d.abs() > h => State::Flank(d.signum()),
            other => other,
        };
        let (k, rest, friction) = match states[j] {
            State::Spring => (trans.stiffness[j], 0.0, 0.0),
            State::Flank(s) => (trans.stiffness[j], s * h, 0.0),
            State::Free => (0.0, 0.0, trans.breakaway),
        };
        // Link 0 is the fixed base; joint j moves link j + 1.
        if let Some(link) = mb.link_mut(j + 1) {
            link.joint.set_spring(3, k, rest);
        }
        mb.frictions_mut()[j] = friction;
    }
}

/// At rest: a joint pulled off its flank by more than static friction holds slips into the band
/// (and the arm settles again); whether any did. Judged at rest, not during transients, so that
/// the outcome depends on the static load only.
fn slip(trans: &Transmission, states: &mut [State], delta: &[f64]) -> bool {
    let mut slipped = false;
    for j in 0..states.len() {
        if let State::Flank(s) = states[j] {
            let pull = delta[j] - s * trans.half_band[j];
            if pull * s < 0.0 && trans.stiffness[j] * pull.abs() > trans.breakaway {
                states[j] = State::Free;
                slipped = true;
            }
        }
    }
    slipped
}

fn read_back(twin: &Twin, world: &PhysicsWorld, handles: &[MultibodyJointHandle], pose: &Posed, settled: Settled) -> Result<RestingPose> {
    let (cmd, params, scale) = (pose.cmd, pose.params, pose.scale);
    let Settled { deflection, contact, steps } = settled;
    let chain = &twin.chain;
    let n = chain.n_joints;
    let (mb, _) = world.multibody_joints.get(handles[0]).ok_or_else(|| Error::Simulation("multibody missing".into()))?;
    // Link frames as rapier holds them; the flange follows from the last link.
    let mut frames: Vec<Frame> = (0..=n).map(|i| mb.link(i).map(|l| frame(l.local_to_world())).unwrap_or(Frame::identity())).collect();
    let q_link: Vec<f64> = cmd.q_cmd.iter().zip(&deflection).map(|(q, d)| q + d).collect();
    let mut ws = FkWork::new(chain);
    chain.forward(&q_link, params, scale, &mut ws);
    let flange_in_last = chain.frame(&ws, chain.flange()).relative_to(&chain.frame(&ws, n));
    frames.push(frames[n].compose(&flange_in_last));
    let tool = frames[n + 1].point(&twin.draw_wire.tool_point_m());
    let mut torque = vec![0.0; n];
    let mut jac = crate::robot::kinematics::PointJacobian::new(chain);
    twin.load.torques(chain, &ws, &mut jac, &mut torque);
    Ok(RestingPose { q_link, eccentricity: vec![0.0; n] /* set by Twin::simulate */, deflection, torque, contact, tool, frames, steps })
}
