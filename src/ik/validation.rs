//! Validation of IK on the twin: the true tool-point error of every solution.
//!
//! The twin is rebuilt from the truth file beside the calibration data (true frame errors,
//! effects, sensor and tool placement) and each solution is commanded to it through its
//! quasi-static model: approach from the zero pose (backlash flanks), thermal state at the median
//! acquisition time of the dataset. Its tool point is the truth.
//!
//! Lengths cannot fix the rotation about joint 1's axis nor the base height (the exit point
//! absorbs them), so a calibrated model lives in its own frame. Positions are compared in the
//! frame of the truth-equivalent model (the result's `truth` values, computed from the truth
//! alone, see `calib::equivalent`): a rigid fit maps the twin's tool points onto that model's
//! over 300 random configurations. Targets for `--random N` are the twin's true tool points of
//! random configurations inside the calibrated joint ranges, mapped the same way.
//!
//! Beside the calibrated model's IK, two references are solved on the same targets: the
//! uncalibrated nominal model (the starting point) and the truth-equivalent model (the floor:
//! the best a rigid model of this parametrisation can do).

use super::solver::{rigid_fit, IkModel, IkOptions, IkSolution, IkStatus, JacobianKind};
use crate::calib::correctors::Correct;
use crate::calib::pipeline::CalibResult;
use crate::dataset::truth::TruthFile;
use crate::error::{Error, Result};
use crate::robot::Robot;
use crate::sim::twin::{PoseCommand, Twin};
use nalgebra::{Matrix3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use std::time::Instant;

/// The twin behind a dataset and the frame map into a calibration's frame.
pub struct TwinCheck {
    /// The twin rebuilt from the truth file; solutions are commanded through its quasi-static
    /// model.
    pub twin: Twin,
    /// Time the twin is commanded at, s: the dataset's median acquisition time (0 without a time
    /// column), for its thermal state.
    pub t_ref: f64,
    /// Truth-equivalent model vector (the result's `truth` values, internal units).
    pub x_eq: Vec<f64>,
    rot: Matrix3<f64>,
    trans: Vector3<f64>,
    /// RMS of the rigid fit, mm (what the truth-equivalent rigid model cannot represent).
    pub fit_rms_mm: f64,
}

impl TwinCheck {
    /// From the truth file beside `data` (a dataset folder or file) and a result calibrated on it.
    pub fn load(data: &Path, r: &CalibResult) -> Result<TwinCheck> {
        let truth = TruthFile::find(data)?
            .ok_or_else(|| Error::Invalid(format!("{}: no truth.json beside the data; twin validation needs the twin's dataset folder", data.display())))?;
        if let (Some(ours), Some(link)) = (&r.provenance.data_sha256, &truth.dataset) {
            if *ours != link.sha256 {
                return Err(Error::Invalid(format!(
                    "{}: this twin was generated with other data than the model was calibrated on (dataset SHA-256 {} vs the model's {}); \
                     pass --twin DIR with the model's twin, or --no-twin",
                    data.display(),
                    &link.sha256[..12.min(link.sha256.len())],
                    &ours[..12.min(ours.len())]
                )));
            }
        }
        let folder = if data.is_dir() { data.to_path_buf() } else { data.parent().map(Path::to_path_buf).unwrap_or_default() };
        let tpath = folder.join(crate::dataset::truth::TRUTH_FILE);
        let text = std::fs::read_to_string(&tpath).map_err(|e| Error::io(&tpath, e))?;
        let raw: serde_json::Value = serde_json::from_str(&text).map_err(|e| Error::data(tpath.display(), e.to_string()))?;
        // The twin's robot: the URDF the truth file carries, else the embedded IRB 120.
        let robot = match raw.get("robot_urdf").and_then(|v| v.as_str()) {
            Some(text) => Robot::from_urdf_str(text, &format!("{} (robot_urdf)", tpath.display()))?,
            None => Robot::irb120(),
        };
        if raw.get("robot").and_then(|v| v.as_str()) != Some(robot.name.as_str()) {
            return Err(Error::Invalid(format!(
                "{}: the truth file names the robot {} but carries no robot_urdf, and is not the embedded IRB 120's ({}); \
                 regenerate the twin's dataset to validate against it",
                tpath.display(),
                raw.get("robot").map(|v| v.to_string()).unwrap_or_else(|| "(none)".into()),
                robot.name
            )));
        }
        if robot.dof() != r.model.chain.n_joints {
            return Err(Error::Invalid(format!(
                "{}: the twin's robot has {} joints, the calibrated model {}",
                tpath.display(),
                robot.dof(),
                r.model.chain.n_joints
            )));
        }
        let params = robot
            .param_names()
            .iter()
            .zip(robot.param_kinds())
            .map(|(n, kind)| {
                let v = *truth.parameters.get(n).ok_or_else(|| Error::data(tpath.display(), format!("parameter {n} missing")))?;
                Ok(kind.from_file(v))
            })
            .collect::<Result<Vec<f64>>>()?;
        let effects =
            serde_json::from_value(raw.get("effects").cloned().unwrap_or_default()).map_err(|e| Error::data(tpath.display(), format!("effects: {e}")))?;
        let tension = raw.pointer("/sensor/tension_n").and_then(|v| v.as_f64()).unwrap_or(0.0);
        let sensor = serde_json::from_value(serde_json::json!({
            "exit_point_mm": truth.draw_wire.exit_point_mm,
            "tool_point_mm": truth.tool.point_mm,
            "length_offset_mm": truth.draw_wire.length_offset_mm,
            "tension_n": tension,
        }))
        .map_err(|e| Error::data(tpath.display(), format!("sensor: {e}")))?;
        let twin = Twin::new(robot, params, effects, sensor, Default::default());
        let ds = crate::dataset::Dataset::load(data)?;
        let mut ts: Vec<f64> = ds.rows.iter().filter_map(|r| r.t_s).collect();
        ts.sort_by(f64::total_cmp);
        let t_ref = ts.get(ts.len() / 2).copied().unwrap_or(0.0);
        let x_eq =
            r.parameters.iter().enumerate().map(|(k, p)| p.truth.map(|t| t / r.model.kinds[k].display())).collect::<Option<Vec<f64>>>().ok_or_else(|| {
                Error::Invalid(
                    "the result has no truth-equivalent values: calibrate on the twin's dataset folder (with its truth.json) first, or pass --no-twin".into(),
                )
            })?;
        let mut c = TwinCheck { twin, t_ref, x_eq, rot: Matrix3::identity(), trans: Vector3::zeros(), fit_rms_mm: 0.0 };
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let ranges = data_ranges(r);
        let mut w = r.model.work();
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for _ in 0..300 {
            let q = random_in(&ranges, &mut rng);
            a.push(c.twin_point_raw(&q));
            b.push(crate::units::to_mm(r.model.tool_point(&c.x_eq, &q, &mut w)));
        }
        (c.rot, c.trans) = rigid_fit(&a, &b);
        c.fit_rms_mm = (a.iter().zip(&b).map(|(p, q)| (c.rot * p + c.trans - q).norm_squared()).sum::<f64>() / a.len() as f64).sqrt();
        Ok(c)
    }
    fn twin_point_raw(&self, q: &[f64]) -> Vector3<f64> {
        let sides = crate::sim::twin::approach_sides(&vec![0.0; q.len()], &[q.to_vec()]).remove(0);
        crate::units::to_mm(self.twin.quasi_static(&PoseCommand { q_cmd: q.to_vec(), sides, t: self.t_ref }).tool)
    }
    /// The twin's true tool point for commanded angles `q` (rad), mm, in the calibration's frame.
    pub fn true_point(&self, q: &[f64]) -> Vector3<f64> {
        self.rot * self.twin_point_raw(q) + self.trans
    }
}

/// Joint ranges of the calibration data (the GKAN's grid when there is one, else the limits).
fn data_ranges(r: &CalibResult) -> Vec<(f64, f64)> {
    match &r.corrector {
        Some(crate::calib::correctors::Corrector::Gkan(g)) => g.lo.iter().zip(&g.hi).map(|(a, b)| (*a, *b)).collect(),
        Some(crate::calib::correctors::Corrector::Mlp(m)) => m.lo.iter().zip(&m.hi).map(|(a, b)| (*a, *b)).collect(),
        _ => r.model.joint_limits(),
    }
    .into_iter()
    .zip(r.model.joint_limits())
    .map(|((a, b), (lo, hi))| (a.max(lo), b.min(hi)))
    .collect()
}

fn random_in(ranges: &[(f64, f64)], rng: &mut ChaCha8Rng) -> Vec<f64> {
    ranges.iter().map(|(lo, hi)| lo + (hi - lo) * rng.random::<f64>()).collect()
}

/// `n` reachable targets: the true tool points (the twin's, else the calibrated model's own) of
/// random configurations inside the calibrated joint ranges.
pub fn random_targets(r: &CalibResult, check: Option<&TwinCheck>, n: usize, seed: u64) -> Vec<Vector3<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let ranges = data_ranges(r);
    let corr: Option<&dyn Correct> = r.corrector.as_ref().map(|c| c.as_correct());
    let m = IkModel::new(&r.model, &r.x, corr, r.model.joint_limits());
    let mut w = m.work();
    (0..n)
        .map(|_| {
            let q = random_in(&ranges, &mut rng);
            match check {
                Some(c) => c.true_point(&q),
                None => m.position(&q, &mut w, None),
            }
        })
        .collect()
}

/// One solver configuration on every target.
pub struct IkRun {
    /// What was solved (`hybrid`, `nominal/analytic (uncalibrated)`, ...).
    pub label: String,
    /// The solution of every target, in target order.
    pub solutions: Vec<IkSolution>,
    /// Mean wall time of one query, s.
    pub seconds_per_query: f64,
    /// Median time of one query, s.
    pub median_seconds: f64,
    /// True tool-point error per target, mm (with a twin).
    pub true_error_mm: Option<Vec<f64>>,
}

impl IkRun {
    /// Share of targets that converged (0..1).
    pub fn success(&self) -> f64 {
        self.solutions.iter().filter(|s| s.status == IkStatus::Converged).count() as f64 / self.solutions.len().max(1) as f64
    }
    /// Mean iterations per target, over every start.
    pub fn mean_iterations(&self) -> f64 {
        self.solutions.iter().map(|s| s.iterations as f64).sum::<f64>() / self.solutions.len().max(1) as f64
    }
    /// Mean model residual per target, mm.
    pub fn mean_residual(&self) -> f64 {
        self.solutions.iter().map(|s| s.residual_mm).sum::<f64>() / self.solutions.len().max(1) as f64
    }
}

/// Solves every target with one model and Jacobian, timed per query (single thread).
pub fn run_ik(label: &str, m: &IkModel, kind: JacobianKind, targets: &[Vector3<f64>], o: &IkOptions, check: Option<&TwinCheck>) -> IkRun {
    let mut w = m.work();
    let t0 = Instant::now();
    let mut times = Vec::with_capacity(targets.len());
    let solutions: Vec<IkSolution> = targets
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let o = IkOptions { seed: o.seed.wrapping_add(i as u64), ..o.clone() };
            let t1 = Instant::now();
            let s = m.solve(t, kind, &o, &mut w);
            times.push(t1.elapsed().as_secs_f64());
            s
        })
        .collect();
    let seconds_per_query = t0.elapsed().as_secs_f64() / targets.len().max(1) as f64;
    let median_seconds = if times.is_empty() { 0.0 } else { crate::stats::median(&times) };
    let true_error_mm =
        check.map(|c| solutions.iter().zip(targets).map(|(s, t)| if s.status == IkStatus::Invalid { 0.0 } else { (c.true_point(&s.q) - t).norm() }).collect());
    IkRun { label: label.into(), solutions, seconds_per_query, median_seconds, true_error_mm }
}

/// Everything `ik` and `bench ik` compute: the calibrated model's runs per Jacobian, then (with a
/// twin) the nominal and floor references with the hybrid Jacobian.
pub fn ik_runs(r: &CalibResult, targets: &[Vector3<f64>], kinds: &[JacobianKind], o: &IkOptions, check: Option<&TwinCheck>) -> Vec<IkRun> {
    let limits = r.model.joint_limits();
    let corr: Option<&dyn Correct> = r.corrector.as_ref().map(|c| c.as_correct());
    let m = IkModel::new(&r.model, &r.x, corr, limits.clone());
    let mut runs: Vec<IkRun> = kinds.iter().map(|k| run_ik(&format!("calibrated/{}", k.name()), &m, *k, targets, o, check)).collect();
    if let Some(c) = check {
        let x_nom = r.model.nominal.clone();
        let nominal = IkModel::new(&r.model, &x_nom, None, limits.clone());
        runs.push(run_ik("nominal/analytic (uncalibrated)", &nominal, JacobianKind::Analytic, targets, o, check));
        let floor = IkModel::new(&r.model, &c.x_eq, None, limits);
        runs.push(run_ik("truth-equivalent/analytic (floor)", &floor, JacobianKind::Analytic, targets, o, check));
    }
    runs
}

/// The summary table of a set of runs.
pub fn table(runs: &[IkRun]) -> String {
    let mut s = String::from("| solver | success | mean iterations | mean model residual (mm) | µs per query (median) | true error median (mm) | true error mean | true error max |\n|---|---|---|---|---|---|---|---|\n");
    for r in runs {
        let te = |f: &dyn Fn(&[f64]) -> f64| r.true_error_mm.as_ref().map(|v| format!("{:.4}", f(v))).unwrap_or_else(|| "–".into());
        s.push_str(&format!(
            "| {} | {:.1} % | {:.1} | {:.5} | {:.1} | {} | {} | {} |\n",
            r.label,
            100.0 * r.success(),
            r.mean_iterations(),
            r.mean_residual(),
            r.median_seconds * 1e6,
            te(&|v: &[f64]| if v.is_empty() { 0.0 } else { crate::stats::median(v) }),
            te(&|v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64),
            te(&|v: &[f64]| v.iter().cloned().fold(0.0, f64::max)),
        ));
    }
    s
}
