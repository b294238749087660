//! Program filtering verified on executed programs: the twin calibrated on its own dataset; a
//! program written offline (a tool on the flange, a work object, each target with its
//! configuration data) for targets the calibration never saw; the program and its filtered copy
//! each interpreted by a nominal controller (the nominal model's inverse kinematics on the
//! branch the configuration data state, through the program's frames) and executed by the
//! twin's true arm (its geometry, its effects under its payload).
//!
//! The targets are the twin's true tool points at seeded configurations of their own inside
//! the ranges the data cover (a walk from one to the next, as a program's neighbouring
//! targets), carried into the calibrated model's frame by its registration to
//! the twin ([`crate::compensate::Compensator::registration`]); the tool's orientation there is
//! the calibrated model's. The program's tool is the calibrated tool point turned about itself,
//! so the twin's instrument reads the TCP. Each program's AP (ISO 9283 position accuracy, one
//! cycle) is the distance from each target to the attained point after the rigid registration
//! that best maps the attained points onto the targets (the frame a cell's accuracy test
//! registers), fitted on the targets the filter moved, so that no program is charged for where
//! the cell puts the arm.

use super::sample::{pose_layout, SampleProgram};
use super::{filter_program, FilterOptions, Outcome, Setup};
use crate::calib::pipeline::{calibrate, CalibOptions};
use crate::compensate::verify::{calibration_rows, data_ranges, execute};
use crate::compensate::{nominal_x, Compensator};
use crate::controller::Language;
use crate::error::{Error, Result};
use crate::robot::Robot;
use crate::sim::generate::{generate, Silent};
use crate::sim::scenario::Scenario;
use crate::stats::metrics::ErrorStats;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

/// One seed's executed-program check.
#[derive(Clone, Debug, Serialize)]
pub struct ProgramCheck {
    /// The scenario's seed.
    pub seed: u64,
    /// The calibration's held-out RMSE on its own test rows, mm.
    pub calibration_test_rmse_mm: f64,
    /// Targets written in the program.
    pub targets: usize,
    /// Targets whose numbers the filter rewrote.
    pub filtered: usize,
    /// Targets it left as written (a branch change, not reached, no nominal solution).
    pub left: usize,
    /// Targets judged: both programs interpreted by the nominal controller and executed.
    pub judged: usize,
    /// AP of the program as written, mm.
    pub original_ap_mm: ErrorStats,
    /// AP of the filtered program, mm.
    pub filtered_ap_mm: ErrorStats,
    /// AP of the filtered program on the targets it filtered (the others are executed as
    /// written), mm.
    pub filtered_only_ap_mm: ErrorStats,
}

/// The nominal controller's command for each target of a program (its sites after the first,
/// the home joint target): `None` where it finds no solution with the target's configuration.
fn interpret(
    c: &Compensator,
    setup: &Setup,
    lang: Language,
    files: &[crate::controller::ProgramFile],
    frames: &[crate::controller::ProgramFile],
) -> Result<Vec<Option<Vec<f64>>>> {
    Ok(super::read_program(c, setup, lang, files, frames, &FilterOptions::default())?.into_iter().skip(1).collect())
}

/// A program's configurations: a seeded walk through the joint ranges the data cover, each
/// joint stepping by up to [`STEP_DEG`] from one target to the next (reflected at the range's
/// ends), as a program moves between neighbouring targets rather than across the workspace.
fn walk(ranges: &[(f64, f64)], n: usize, seed: u64) -> Vec<Vec<f64>> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x9A0C_2A3E_11F7_5EED);
    let mut q: Vec<f64> = ranges.iter().map(|(lo, hi)| lo + (hi - lo) * rng.random::<f64>()).collect();
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        out.push(q.clone());
        for (v, (lo, hi)) in q.iter_mut().zip(ranges) {
            *v += STEP_DEG.to_radians() * (2.0 * rng.random::<f64>() - 1.0);
            if *v < *lo {
                *v = 2.0 * lo - *v;
            }
            if *v > *hi {
                *v = 2.0 * hi - *v;
            }
        }
    }
    out
}

/// Largest step of a joint between two neighbouring targets of a program, degrees.
const STEP_DEG: f64 = 15.0;

/// Calibrates the twin of `s` at `seed` with `opts`, writes a program of `n_targets` unseen
/// targets in `lang`, filters it, and executes both on the twin.
pub fn verify_program(s: &Scenario, robot: &Robot, opts: &CalibOptions, lang: Language, n_targets: usize, seed: u64) -> Result<ProgramCheck> {
    let mut s = s.clone();
    s.seed = seed;
    let g = generate(&s, robot, &Silent)?;
    let r = calibrate(&g.dataset, None, opts)?;
    let x_nom = nominal_x(&r);
    let c = Compensator::new(&r, &x_nom, r.torque_model.clone(), 0.001, 0.001)?;
    let setup = Setup::new(&r, &x_nom, Some(robot));
    let (reg_q, reg_true) = calibration_rows(&g);
    let (rot, tr) = c.registration(&reg_q, &reg_true, false);
    // The targets: the twin's true tool points, in the calibrated model's frame.
    let configurations = walk(&data_ranges(&g), n_targets, seed);
    let truth = execute(&s, robot, &configurations)?;
    let tool = setup.probe_tool() * Isometry3::rotation(Vector3::new(0.2, -0.3, 0.1));
    let frame = Isometry3::from_parts(Translation3::new(350.0, -120.0, 80.0), UnitQuaternion::from_euler_angles(0.05, -0.03, 0.6));
    let layout = pose_layout(lang);
    let mut targets = Vec::new();
    let mut points = Vec::new();
    for (q, t) in configurations.iter().zip(&truth) {
        let Some((p_true, _)) = t else { continue };
        let (_, r_model) = c.predicted_pose(q);
        let tcp = setup.program_pose(&(rot * p_true + tr), &r_model) * tool;
        targets.push((frame.inverse() * tcp, setup.config(layout, q)));
        points.push(*p_true);
    }
    let prog = SampleProgram { name: "twc_check".into(), tool, frame, targets, home: configurations[0].clone() };
    let (files, frames) = prog.write(lang);
    let filtered = filter_program(&c, &setup, lang, &files, &frames, &FilterOptions::default())?;
    let count = |o: &dyn Fn(&Outcome) -> bool| filtered.targets.iter().skip(1).filter(|t| o(&t.outcome)).count();
    let before = interpret(&c, &setup, lang, &files, &frames)?;
    let after = interpret(&c, &setup, lang, &filtered.files, &frames)?;
    let judged: Vec<usize> = (0..points.len()).filter(|&k| before[k].is_some() && after[k].is_some()).collect();
    let run = |cmds: &[Option<Vec<f64>>]| execute(&s, robot, &judged.iter().map(|&k| cmds[k].clone().unwrap_or_default()).collect::<Vec<_>>());
    let (a, b) = (run(&before)?, run(&after)?);
    let both: Vec<usize> = (0..judged.len()).filter(|&i| a[i].is_some() && b[i].is_some()).collect();
    if both.len() < 3 || both.iter().filter(|&&i| filtered.targets[judged[i] + 1].outcome == Outcome::Filtered).count() < 3 {
        return Err(Error::Invalid(format!("seed {seed}: only {} targets executed by both programs", both.len())));
    }
    let target: Vec<Vector3<f64>> = both.iter().map(|&i| points[judged[i]]).collect();
    // Each target's AP after the registration of the program's attained points, fitted on the
    // targets the filter moved (the same for both programs: a target left as written, executed
    // with its full error, does not tilt the frame the others are judged in).
    let moved: Vec<bool> = both.iter().map(|&i| filtered.targets[judged[i] + 1].outcome == Outcome::Filtered).collect();
    let ap = |attained: &[crate::compensate::verify::Attained]| -> Vec<f64> {
        let got: Vec<Vector3<f64>> = both.iter().map(|&i| attained[i].as_ref().map(|x| x.0).unwrap_or_default()).collect();
        let pick = |v: &[Vector3<f64>]| v.iter().zip(&moved).filter(|(_, m)| **m).map(|(p, _)| *p).collect::<Vec<_>>();
        let (rr, tt) = crate::ik::rigid_fit(&pick(&got), &pick(&target));
        got.iter().zip(&target).map(|(g, t)| (rr * g + tt - t).norm()).collect()
    };
    let (ap_a, ap_b) = (ap(&a), ap(&b));
    let filtered_only: Vec<f64> = ap_b.iter().zip(&moved).filter(|(_, m)| **m).map(|(e, _)| *e).collect();
    Ok(ProgramCheck {
        seed,
        calibration_test_rmse_mm: r.evaluation.metrics.test_after.as_ref().map_or(f64::NAN, |m| m.rmse),
        targets: points.len(),
        filtered: count(&|o| *o == Outcome::Filtered),
        left: count(&|o| !matches!(o, Outcome::Filtered | Outcome::NothingToMove)),
        judged: both.len(),
        original_ap_mm: ErrorStats::of(&ap_a),
        filtered_ap_mm: ErrorStats::of(&ap_b),
        filtered_only_ap_mm: ErrorStats::of(&filtered_only),
    })
}
