//! `twincal study hold`: what the acquisition protocol costs. The scenario's tour (its first
//! poses) is simulated for every hold time and approach speed; each reading's transient error
//! (its noise-free length minus that of the arm at rest on the flanks it ends on) gives a bias and
//! a spread per setting, next to the robot time the protocol takes.

use crate::error::Result;
use crate::robot::Robot;
use crate::sim::generate::{build_twin, sample_poses, Progress};
use crate::sim::scenario::Scenario;
use crate::sim::twin::tour::{acquire, Acquisition, AcquisitionModel, OnTimeout, Schedule, TourSettings};
use serde::Serialize;

/// One setting of the study.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct HoldStudyRow {
    /// Joint speed while moving, fraction of the URDF speed limits.
    pub speed_fraction: f64,
    /// Hold time before the readings, s.
    pub hold_s: f64,
    /// Poses of the tour simulated.
    pub poses: usize,
    /// Mean transient error of the readings, mm.
    pub bias_mm: f64,
    /// Standard deviation of the transient error, mm.
    pub spread_mm: f64,
    /// Largest |transient error|, mm.
    pub max_mm: f64,
    /// Poses whose gate was still closed when the hold ended (read anyway here).
    pub gate_closed: usize,
    /// Median gate opening time over the poses where it opened, s after arrival.
    pub median_gate_s: Option<f64>,
    /// Robot time per pose (move, hold, readings), s.
    pub time_per_pose_s: f64,
}

impl HoldStudyRow {
    /// What is wrong with a row read back (a part of a sharded study): every number finite,
    /// spreads, sizes and times not negative, the bias within the largest error, at least one
    /// pose and no more closed gates than poses.
    pub fn check(&self) -> std::result::Result<(), String> {
        let finite = [self.speed_fraction, self.hold_s, self.bias_mm, self.spread_mm, self.max_mm, self.time_per_pose_s];
        if !finite.iter().all(|v| v.is_finite()) || self.median_gate_s.is_some_and(|g| !g.is_finite()) {
            return Err("a number that is not finite".into());
        }
        if self.spread_mm < 0.0 || self.max_mm < 0.0 || self.time_per_pose_s < 0.0 || self.hold_s < 0.0 || self.median_gate_s.is_some_and(|g| g < 0.0) {
            return Err(format!(
                "a spread, size or time below zero (spread_mm {}, max_mm {}, time_per_pose_s {})",
                self.spread_mm, self.max_mm, self.time_per_pose_s
            ));
        }
        if self.bias_mm.abs() > self.max_mm * (1.0 + 1e-9) {
            return Err(format!("a bias of {} mm beyond the largest error {} mm", self.bias_mm, self.max_mm));
        }
        if self.poses == 0 || self.gate_closed > self.poses || !(self.speed_fraction > 0.0 && self.speed_fraction <= 1.0) {
            return Err(format!("{} poses, {} closed gates, speed fraction {}", self.poses, self.gate_closed, self.speed_fraction));
        }
        Ok(())
    }
}

/// The study's settings.
#[derive(Clone, Debug)]
pub struct HoldStudy {
    /// Hold times to try, s.
    pub holds_s: Vec<f64>,
    /// Approach speeds to try, fractions of the URDF speed limits.
    pub speed_fractions: Vec<f64>,
    /// The first this many poses of the scenario's tour.
    pub poses: usize,
}

/// Poses a hold study takes from the scenario's tour unless told otherwise.
pub const DEFAULT_POSES: usize = 60;

impl HoldStudy {
    /// Checks every value, naming the option.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if self.holds_s.is_empty() || self.holds_s.iter().any(|h| !(h.is_finite() && (0.0..=crate::sim::instrument::drawwire::MAX_HOLD_S).contains(h))) {
            return Err(format!("--holds needs values in [0, {}] s, got {:?}", crate::sim::instrument::drawwire::MAX_HOLD_S, self.holds_s));
        }
        if self.speed_fractions.is_empty() || self.speed_fractions.iter().any(|v| !(v.is_finite() && *v > 0.0 && *v <= 1.0)) {
            return Err(format!("--speeds needs fractions in (0, 1], got {:?}", self.speed_fractions));
        }
        for (name, v) in [("--holds", &self.holds_s), ("--speeds", &self.speed_fractions)] {
            if let Some(d) = v.iter().enumerate().find_map(|(i, a)| v[..i].contains(a).then_some(a)) {
                return Err(format!("{name} lists {d} twice"));
            }
        }
        if !(1..=crate::sim::scenario::MAX_POSES).contains(&self.poses) {
            return Err(format!("--poses must be in 1..={}, got {}", crate::sim::scenario::MAX_POSES, self.poses));
        }
        Ok(())
    }
}

/// Runs the study on scenario `s`: its twin, effects, sensor and gate, the acquisition simulated
/// with readings taken even when the gate is still closed.
pub fn hold_study(s: &Scenario, robot: &Robot, study: &HoldStudy, progress: &dyn Progress) -> Result<Vec<HoldStudyRow>> {
    hold_study_at(s, robot, study, &study_poses(s, robot, study)?, progress)
}

/// [`hold_study`] through the study's poses, already taken ([`study_poses`]).
pub fn hold_study_at(s: &Scenario, robot: &Robot, study: &HoldStudy, poses: &[Vec<f64>], progress: &dyn Progress) -> Result<Vec<HoldStudyRow>> {
    progress.start((study.holds_s.len() * study.speed_fractions.len() * poses.len()) as u64, "hold study");
    let mut rows = Vec::new();
    for (v, h) in study.settings() {
        rows.push(hold_setting(s, robot, poses, v, h, progress)?);
    }
    progress.finish();
    Ok(rows)
}

impl HoldStudy {
    /// The settings in the study's fixed order (speeds outer, holds inner): work item `id` is
    /// setting `id`.
    pub fn settings(&self) -> Vec<(f64, f64)> {
        self.speed_fractions.iter().flat_map(|&v| self.holds_s.iter().map(move |&h| (v, h))).collect()
    }
}

/// The poses a study takes: the first `study.poses` of the scenario's tour (checked settings).
pub fn study_poses(s: &Scenario, robot: &Robot, study: &HoldStudy) -> Result<Vec<Vec<f64>>> {
    study.validate().map_err(crate::error::Error::Invalid)?;
    let mut poses = sample_poses(s, robot)?;
    poses.truncate(study.poses);
    Ok(poses)
}

/// One setting of the study: the tour through `poses` at speed fraction `v` with hold `h` s.
pub fn hold_setting(s: &Scenario, robot: &Robot, poses: &[Vec<f64>], v: f64, h: f64, progress: &dyn Progress) -> Result<HoldStudyRow> {
    let home = vec![0.0; robot.dof()];
    let acq = Acquisition { model: AcquisitionModel::Simulated, on_timeout: OnTimeout::Read, ..s.acquisition.clone() };
    let mut sc = s.clone();
    sc.draw_wire.hold_s = h;
    sc.sampling.speed_fraction = v;
    let times = crate::sim::generate::acquisition_times(&sc, robot, poses);
    if crate::sim::generate::check_robot_time(&sc, &times).is_err() {
        let end = times.iter().copied().fold(0.0, f64::max);
        return Err(crate::error::Error::Invalid(format!(
            "--speeds {}: {} poses would take {:.1} h of robot time, more than the {} h a run simulates; use larger fractions \
             (or check the URDF's joint velocity limits)",
            crate::error::shown(v),
            poses.len(),
            end / 3600.0,
            crate::sim::generate::MAX_ROBOT_TIME_S / 3600.0
        )));
    }
    let twin = build_twin(&sc, robot);
    let settings = TourSettings { seed: sc.seed, speed_fraction: v };
    let acquired: Vec<_> = acquire(&twin, &acq, settings, &home, poses, None, progress).into_iter().collect::<Result<_>>()?;
    let e: Vec<f64> = acquired.iter().map(|a| a.transient_mm).collect();
    let m = e.len() as f64;
    let bias = e.iter().sum::<f64>() / m;
    let spread = if e.len() > 1 { (e.iter().map(|x| (x - bias).powi(2)).sum::<f64>() / (m - 1.0)).sqrt() } else { 0.0 };
    let gates: Vec<f64> = acquired.iter().filter_map(|a| a.gate_s).collect();
    let timing = crate::sim::twin::tour::Timing { speed_fraction: v, ramp_s: acq.ramp_s, hold_s: h, window_s: sc.draw_wire.window_s() };
    let schedule = Schedule::new(robot, &timing, &home, poses, None);
    let end = schedule.read_t.last().copied().unwrap_or(0.0) + 0.5 * sc.draw_wire.window_s();
    Ok(HoldStudyRow {
        speed_fraction: v,
        hold_s: h,
        poses: e.len(),
        bias_mm: bias,
        spread_mm: spread,
        max_mm: e.iter().fold(0.0f64, |a, x| a.max(x.abs())),
        gate_closed: acquired.len() - gates.len(),
        median_gate_s: (!gates.is_empty()).then(|| crate::math::median(&gates)),
        time_per_pose_s: end / m,
    })
}
