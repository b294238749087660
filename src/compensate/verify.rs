//! Compensation verified on executed poses: the twin calibrated on its own dataset, then made
//! to execute the nominal and the compensated commands for targets the calibration never saw,
//! each attained position compared with its target (ISO 9283's position accuracy AP for one
//! cycle: the distance from the target to the attained position).
//!
//! The targets are the twin's true tool points at random configurations (seeded apart from the
//! dataset's) inside the ranges the data cover: points the arm reaches, none of them a row of
//! the calibration. The commands are executed by the same twin (its geometry, its effects under
//! its payload), and its truth gives the attained tool points.
//!
//! A model's base frame is known only up to what no measurement of the arm fixes (where the
//! arm stands in the cell), so each model is first registered to the twin as an accuracy test
//! registers a robot to its tracker: the rigid transform that best maps the twin's true tool
//! points at the calibration's configurations onto the model's own predictions there. The
//! nominal model gets its own best registration, the calibrated model its own; a target is
//! given to each model in its frame. Distances do not depend on the frame: the AP is the
//! distance between the attained point and the target in the twin's frame.

use super::{nominal_x, Compensator, Status, Target};
use crate::calib::pipeline::{calibrate, CalibOptions, CalibResult};
use crate::error::{Error, Result};
use crate::measurement::Euler;
use crate::robot::Robot;
use crate::sim::generate::{generate, generate_at, Generated, Silent};
use crate::sim::scenario::Scenario;
use crate::stats::metrics::ErrorStats;
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// One seed's verification.
#[derive(Clone, Debug, Serialize)]
pub struct SeedCheck {
    /// The scenario's seed.
    pub seed: u64,
    /// The calibration's held-out RMSE on its own test rows, mm.
    pub calibration_test_rmse_mm: f64,
    /// Targets drawn, and how many of them both commands reached on the twin (the rest were
    /// rejected by the twin, or not reachable on the nominal or the calibrated model).
    pub targets: usize,
    /// Targets judged.
    pub judged: usize,
    /// AP of the nominal commands, mm.
    pub nominal_ap_mm: ErrorStats,
    /// AP of the compensated commands, mm.
    pub compensated_ap_mm: ErrorStats,
    /// The nominal commands' AP as the calibrated model predicts it (where it puts the tool
    /// for them, in the twin's frame through its registration), mm: the gain the calibration
    /// promises, beside the one measured.
    pub predicted_nominal_ap_mm: ErrorStats,
    /// The compensated commands' AP as the calibrated model predicts it (its IK residual), mm.
    pub predicted_compensated_ap_mm: ErrorStats,
    /// For pose targets: the angle between each target's orientation and the attained one
    /// (degrees) with the nominal commands, and with the compensated ones.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation_deg: Option<(ErrorStats, ErrorStats)>,
}

/// The attained tool pose of every executed command, in command order (the point in mm, the
/// tool's orientation when the twin's instrument reads it: a 6-D probe's, in the base frame);
/// `None` where the twin rejected the pose.
pub(crate) type Attained = Option<(Vector3<f64>, Option<Matrix3<f64>>)>;

pub(crate) fn execute(s: &Scenario, robot: &Robot, commands: &[Vec<f64>]) -> Result<Vec<Attained>> {
    let g: Generated = generate_at(s, robot, commands.to_vec(), None, &Silent)?;
    // y = R·p + t: a probe's orientation in the tracker's frame turned back to the base's.
    let to_base = g.truth.tracker.as_ref().map(|t| Euler::XYZ.matrix(t.rotation_deg.map(f64::to_radians)).transpose());
    let mut out = vec![None; commands.len()];
    for p in &g.truth.poses {
        let rot = p.pose_true.zip(to_base).map(|(v, r)| r * Euler::XYZ.matrix([v[3], v[4], v[5]].map(f64::to_radians)));
        out[p.index] = Some((Vector3::from(p.tool_mm), rot));
    }
    Ok(out)
}

/// `n` random configurations (rad) inside the joint ranges the data of `g` cover, shrunk by a
/// tenth at each end.
pub(crate) fn random_configurations(g: &Generated, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let ranges = data_ranges(g);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x5EED_7A26_E75C_0DE5);
    (0..n).map(|_| ranges.iter().map(|(lo, hi)| lo + (hi - lo) * rng.random::<f64>()).collect()).collect()
}

/// The calibration's rows of `g`: their joint angles (rad) and the twin's true tool points there
/// (mm), on which a model is registered to the twin.
pub(crate) fn calibration_rows(g: &Generated) -> (Vec<Vec<f64>>, Vec<Vector3<f64>>) {
    let q = g.dataset.rows.iter().map(|row| row.q_deg.iter().map(|d| d.to_radians()).collect()).collect();
    let truth = g.truth.poses.iter().map(|p| Vector3::from(p.tool_mm)).collect();
    (q, truth)
}

/// Each joint's range (rad) in the data of `g`, shrunk by a tenth at each end.
pub(crate) fn data_ranges(g: &Generated) -> Vec<(f64, f64)> {
    let dof = g.dataset.n_joints();
    (0..dof)
        .map(|j| {
            let (lo, hi) = g.dataset.rows.iter().map(|r| r.q_deg[j].to_radians()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
            let m = 0.1 * (hi - lo);
            (lo + m, hi - m)
        })
        .collect()
}

/// Calibrates the twin of `s` (at seed `seed`) with `opts`, then executes the nominal and the
/// compensated commands for `n_targets` unseen targets on it: points, or with `poses` (a twin
/// whose instrument reads a 6-D probe) the probe's true poses, position and orientation.
pub fn verify_seed(s: &Scenario, robot: &Robot, opts: &CalibOptions, n_targets: usize, seed: u64, poses: bool) -> Result<SeedCheck> {
    let mut s = s.clone();
    s.seed = seed;
    let g = generate(&s, robot, &Silent)?;
    let r: CalibResult = calibrate(&g.dataset, None, opts)?;
    // Targets: the twin's true tool points (and orientations) at configurations of their own.
    let configurations = random_configurations(&g, n_targets, seed);
    let truth: Vec<(Vector3<f64>, Option<Matrix3<f64>>)> = execute(&s, robot, &configurations)?.into_iter().flatten().collect();
    if poses && truth.iter().any(|t| t.1.is_none()) {
        return Err(Error::Invalid(format!("{}: pose targets need a twin whose instrument reads the tool's orientation (a 6-D probe)", s.name)));
    }
    let x_nom = nominal_x(&r);
    let c = Compensator::new(&r, &x_nom, r.torque_model.clone(), 0.001, 0.001)?;
    // Each model registered to the twin on the calibration's configurations.
    let (reg_q, reg_true) = calibration_rows(&g);
    let (to_cal, to_nom) = (c.registration(&reg_q, &reg_true, false), c.registration(&reg_q, &reg_true, true));
    // A target in a model's frame: its point and orientation carried by the registration.
    let carry = |(rot, tr): &(Matrix3<f64>, Vector3<f64>), (p, o): &(Vector3<f64>, Option<Matrix3<f64>>)| match o.filter(|_| poses) {
        Some(o) => Target::Pose(rot * p + tr, rot * o),
        None => Target::Point(rot * p + tr),
    };
    let solved = c.compensate(&truth.iter().map(|t| carry(&to_cal, t)).collect::<Vec<_>>());
    // The nominal controller's commands (none where its own model does not reach the target: a
    // controller refuses those, and they are not judged).
    let nominal_q: Vec<Option<Vec<f64>>> = match poses {
        true => c.nominal_pose_commands(&truth.iter().map(|(p, o)| (to_nom.0 * p + to_nom.1, to_nom.0 * o.unwrap_or_default())).collect::<Vec<_>>()),
        false => c.nominal_commands(&truth.iter().map(|(p, _)| to_nom.0 * p + to_nom.1).collect::<Vec<_>>()),
    };
    let mid: Vec<f64> = r.model.joint_limits().iter().map(|(lo, hi)| 0.5 * (lo + hi)).collect();
    let nominal = execute(&s, robot, &nominal_q.iter().map(|q| q.clone().unwrap_or_else(|| mid.clone())).collect::<Vec<_>>())?;
    let compensated = execute(&s, robot, &solved.iter().map(|k| k.command_q.clone()).collect::<Vec<_>>())?;
    let (mut before, mut after, mut predicted, mut residual) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut turn_before, mut turn_after) = (Vec::new(), Vec::new());
    for (k, (t, o)) in truth.iter().enumerate() {
        if let (Some(nq), Some((a, ra)), Some((b, rb)), Status::Reachable) = (&nominal_q[k], nominal[k], compensated[k], solved[k].status) {
            before.push((a - t).norm());
            after.push((b - t).norm());
            let (rot, tr) = &to_cal;
            predicted.push((rot.transpose() * (c.predicted(nq) - tr) - t).norm());
            residual.push(solved[k].residual_mm);
            if let (true, Some(o), Some(ra), Some(rb)) = (poses, o, ra, rb) {
                turn_before.push(crate::ik::solver::turn(o, &ra).norm().to_degrees());
                turn_after.push(crate::ik::solver::turn(o, &rb).norm().to_degrees());
            }
        }
    }
    if after.is_empty() {
        return Err(Error::Invalid(format!("seed {seed}: no target was reached by both commands on the twin")));
    }
    Ok(SeedCheck {
        seed,
        calibration_test_rmse_mm: r.evaluation.metrics.test_after.as_ref().map_or(f64::NAN, |m| m.rmse),
        targets: n_targets,
        judged: after.len(),
        nominal_ap_mm: ErrorStats::of(&before),
        compensated_ap_mm: ErrorStats::of(&after),
        predicted_nominal_ap_mm: ErrorStats::of(&predicted),
        predicted_compensated_ap_mm: ErrorStats::of(&residual),
        orientation_deg: poses.then(|| (ErrorStats::of(&turn_before), ErrorStats::of(&turn_after))),
    })
}
