//! What holds a resting arm where it is, as the twin and the calibration both need it: the
//! static loads on its joints (gravity on the links, a payload, a cable's pull) and the backlash
//! flank each joint rests on after the moves that led there.

use super::kinematics::{Chain, FkWork, PointJacobian};
use super::Robot;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// A payload rigidly attached to the flange.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Payload {
    /// Mass, kg ([`LoadModel::new`] ignores a payload whose mass is not positive).
    pub mass_kg: f64,
    /// Centre of mass in the flange frame, mm.
    pub com_mm: [f64; 3],
}

/// Standard gravity, m/s², along −z of the base frame.
pub const GRAVITY: f64 = 9.81;

/// Cable tension acting on the tool point, pulling it towards the cable exit point.
#[derive(Clone, Debug, PartialEq)]
pub struct CableLoad {
    /// Exit point in the base frame, m.
    pub exit_point: Vector3<f64>,
    /// Attachment point in the flange frame, m.
    pub tool_point: Vector3<f64>,
    /// Tension, N.
    pub tension: f64,
}

impl CableLoad {
    /// Force on the tool point at world position `p`.
    pub fn force_at(&self, p: &Vector3<f64>) -> Vector3<f64> {
        let d = self.exit_point - p;
        let n = d.norm();
        if n < 1e-12 {
            Vector3::zeros()
        } else {
            d * (self.tension / n)
        }
    }
}

/// A force pressing the instrument's target against an artifact: the operator (or a spring, a
/// magnet) holding the ball in its socket, a probe's trigger force on a face. It acts along the
/// flange's z axis (the ball's stem, the probe's shank), the artifact pushing back towards the
/// flange.
#[derive(Clone, Debug, PartialEq)]
pub struct Push {
    /// Where it acts, in the flange frame, m (the ball's or the stylus's centre).
    pub point: Vector3<f64>,
    /// Its size, N.
    pub force_n: f64,
}

/// Everything that loads the joints of a resting arm.
#[derive(Clone, Debug)]
pub struct LoadModel {
    /// Gravitational acceleration in the base frame, m/s² ((0, 0, −[`GRAVITY`]) from [`Self::new`]).
    pub gravity: Vector3<f64>,
    /// Per moving link: mass (kg) and COM in the link frame (m).
    pub links: Vec<(f64, Vector3<f64>)>,
    /// Payload mass (kg) and COM in the flange frame (m).
    pub payload: Option<(f64, Vector3<f64>)>,
    /// The cable pulling at the tool point, if any.
    pub cable: Option<CableLoad>,
    /// The artifact pushing back on the instrument's target, if any.
    pub push: Option<Push>,
}

impl LoadModel {
    /// The robot's links with `payload` on the flange and `cable` pulling at the tool point.
    pub fn new(robot: &Robot, payload: Option<&Payload>, cable: Option<CableLoad>) -> Self {
        LoadModel {
            gravity: Vector3::new(0.0, 0.0, -GRAVITY),
            links: robot.links.iter().map(|l| (l.mass, l.com)).collect(),
            payload: payload.filter(|p| p.mass_kg > 0.0).map(|p| (p.mass_kg, crate::units::to_m(Vector3::from(p.com_mm)))),
            cable,
            push: None,
        }
    }

    /// Generalised joint torques (N·m) of all loads, from frames already evaluated in `ws`.
    /// A positive torque pushes the joint towards larger angles.
    pub fn torques(&self, chain: &Chain, ws: &FkWork, jac: &mut PointJacobian, out: &mut [f64]) {
        out.iter_mut().for_each(|t| *t = 0.0);
        let mut add = |f: usize, local: &Vector3<f64>, force: Option<Vector3<f64>>, mass: f64, jac: &mut PointJacobian| {
            chain.point_jacobian(ws, f, local, jac);
            let force = force.unwrap_or(self.gravity * mass);
            for (t, d) in out.iter_mut().zip(&jac.dq) {
                *t += d.dot(&force);
            }
        };
        for (j, (m, com)) in self.links.iter().enumerate() {
            if *m > 0.0 {
                add(j + 1, com, None, *m, jac);
            }
        }
        let flange = chain.flange();
        if let Some((m, com)) = &self.payload {
            add(flange, com, None, *m, jac);
        }
        if let Some(c) = &self.cable {
            let p = chain.frame(ws, flange).point(&c.tool_point);
            let force = c.force_at(&p);
            add(flange, &c.tool_point, Some(force), 0.0, jac);
        }
        if let Some(p) = &self.push {
            let force = -chain.frame(ws, flange).rot.column(2) * p.force_n;
            add(flange, &p.point, Some(force), 0.0, jac);
        }
    }
}

/// Backlash approach flanks for a sequence of commanded poses (any angle unit: only the signs of
/// the moves count), starting from `home`:
/// the link trails the motor, so a joint that last moved towards larger angles rests on its
/// negative flank. A joint that does not move keeps its previous flank.
pub fn approach_sides(home: &[f64], poses: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut prev = home.to_vec();
    let mut sides = vec![-1.0; home.len()];
    poses
        .iter()
        .map(|q| {
            for j in 0..q.len() {
                let d = q[j] - prev[j];
                if d > 0.0 {
                    sides[j] = -1.0;
                } else if d < 0.0 {
                    sides[j] = 1.0;
                }
            }
            prev = q.clone();
            sides.clone()
        })
        .collect()
}

/// Which flank a joint rests on, or free inside the band.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Contact {
    /// No backlash: plain spring.
    Spring,
    /// On the positive flank, spring loaded.
    Positive,
    /// On the negative flank, spring loaded.
    Negative,
    /// Held at the approach flank by static friction against a load pulling it into the band
    /// (the shaft still twists by load/stiffness).
    Held,
    /// Inside the band, on neither flank: a simulation stopped early, or in the simulated tour a
    /// link the move's deceleration carried off its flank and friction holds (load at most the
    /// breakaway).
    Free,
}
