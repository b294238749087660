//! `twincal ik` on pose targets: every solution of the calibrated arm for each pose
//! ([`twincal::compensate::Compensator::pose_solutions`]: from each of the nominal arm's
//! solutions, all of them in closed form where its geometry has one), one row each, and with a
//! twin the true tool-point error of every solution.

use nalgebra::{Matrix3, Vector3};
use std::path::Path;
use twincal::calib::pipeline::CalibResult;
use twincal::compensate::{nominal_x, read_targets, Compensator, Target};
use twincal::error::{Error, Result};
use twincal::ik::solver::{PoseSolution, NEAR_SINGULAR_MM_PER_RAD};
use twincal::ik::{IkStatus, JacobianKind, TwinCheck};

/// Whether the targets file's header holds an orientation column (rx, ry or rz): pose targets
/// (a header the file cannot give is left to the point reader to name).
pub fn holds_poses(path: &Path) -> bool {
    twincal::dataset::CsvColumns::read(path).map(|t| ["rx", "ry", "rz"].iter().any(|c| t.has(c))).unwrap_or(false)
}

/// One Jacobian's answers: per target every solution found with how well it is conditioned
/// (mm/rad), and its true error on the twin.
struct PoseRun {
    label: String,
    solutions: Vec<Vec<PoseSolution>>,
    conditioning: Vec<Vec<f64>>,
    true_error_mm: Option<Vec<Vec<f64>>>,
    median_seconds: f64,
}

impl PoseRun {
    fn solve(c: &Compensator, kind: JacobianKind, poses: &[(Vector3<f64>, Matrix3<f64>)], check: Option<&TwinCheck>) -> PoseRun {
        let twincal::compensate::branches::PoseAnswers { solutions, conditioning, seconds } = c.solve_poses(poses, kind);
        let true_error_mm = check.map(|tc| {
            solutions
                .iter()
                .zip(poses)
                .map(|(ss, (p, _))| ss.iter().map(|s| if s.status == IkStatus::Converged { (tc.true_point(&s.q) - p).norm() } else { f64::NAN }).collect())
                .collect()
        });
        PoseRun { label: format!("calibrated/{}", kind.name()), solutions, conditioning, true_error_mm, median_seconds: twincal::stats::median(&seconds) }
    }

    fn converged(&self) -> impl Iterator<Item = &PoseSolution> {
        self.solutions.iter().flatten().filter(|s| s.status == IkStatus::Converged)
    }
}

/// ik.csv for poses: per target and solver, one row per solution (solution 1, 2, ...; a target
/// with none has one row with the search's status and no solution number), with its
/// conditioning (mm/rad; below [`NEAR_SINGULAR_MM_PER_RAD`] next to a singularity).
fn poses_csv(n_joints: usize, runs: &[PoseRun], poses: &[(Vector3<f64>, Matrix3<f64>)], euler: twincal::measurement::Euler) -> String {
    let joints: String = (1..=n_joints).map(|j| format!("q{j},")).collect();
    let mut csv = format!(
        "target,x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg,solver,solution,status,iterations,residual_mm,residual_deg,{joints}conditioning_mm_per_rad,true_error_mm\n"
    );
    for run in runs {
        for (i, (ss, (p, r))) in run.solutions.iter().zip(poses).enumerate() {
            let a = euler.angles(r).map(f64::to_degrees);
            for (k, s) in ss.iter().enumerate() {
                let converged = s.status == IkStatus::Converged;
                let q: Vec<String> = s.q.iter().map(|v| format!("{:.6}", v.to_degrees())).collect();
                let number = if converged { (k + 1).to_string() } else { String::new() };
                let te = run.true_error_mm.as_ref().filter(|_| converged).map(|v| format!("{:.6}", v[i][k])).unwrap_or_default();
                csv.push_str(&format!(
                    "{},{},{},{},{:.6},{:.6},{:.6},{},{number},{},{},{:.6},{:.6},{},{:.3},{te}\n",
                    i + 1,
                    p.x,
                    p.y,
                    p.z,
                    a[0],
                    a[1],
                    a[2],
                    run.label,
                    s.status.name(),
                    s.iterations,
                    s.residual_mm,
                    s.residual_deg,
                    q.join(","),
                    run.conditioning[i][k]
                ));
            }
        }
    }
    csv
}

/// The summary table of pose runs.
fn poses_table(runs: &[PoseRun]) -> String {
    let mut s = String::from(
        "| solver | targets solved | solutions per target (mean, most) | next to a singularity | mean model residual (mm, deg) | ms per target (median) | true error median (mm) | true error max |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in runs {
        let n = r.solutions.len().max(1);
        let solved = r.solutions.iter().filter(|ss| ss.iter().any(|s| s.status == IkStatus::Converged)).count();
        let counts: Vec<usize> = r.solutions.iter().map(|ss| ss.iter().filter(|s| s.status == IkStatus::Converged).count()).collect();
        let found: Vec<&PoseSolution> = r.converged().collect();
        let singular = r
            .solutions
            .iter()
            .flatten()
            .zip(r.conditioning.iter().flatten())
            .filter(|(s, k)| s.status == IkStatus::Converged && **k < NEAR_SINGULAR_MM_PER_RAD)
            .count();
        let mean = |f: &dyn Fn(&PoseSolution) -> f64| found.iter().map(|s| f(s)).sum::<f64>() / found.len().max(1) as f64;
        let te: Vec<f64> = r.true_error_mm.iter().flatten().flatten().copied().filter(|v| v.is_finite()).collect();
        let shown = |f: &dyn Fn(&[f64]) -> f64| if te.is_empty() { "–".to_string() } else { format!("{:.4}", f(&te)) };
        s.push_str(&format!(
            "| {} | {solved} of {} | {:.2}, {} | {singular} | {:.6}, {:.6} | {:.2} | {} | {} |\n",
            r.label,
            r.solutions.len(),
            counts.iter().sum::<usize>() as f64 / n as f64,
            counts.iter().max().copied().unwrap_or(0),
            mean(&|s| s.residual_mm),
            mean(&|s| s.residual_deg),
            r.median_seconds * 1e3,
            shown(&|v| twincal::stats::median(v)),
            shown(&|v| v.iter().copied().fold(0.0, f64::max)),
        ));
    }
    s
}

/// What `ik` asks of pose targets: the model file (for the messages), the tolerances, the Euler
/// convention and the output file.
pub struct PoseRequest<'a> {
    pub model: &'a Path,
    pub tol_mm: f64,
    pub tol_deg: f64,
    pub euler: twincal::measurement::Euler,
    pub out: &'a Path,
}

/// `twincal ik --targets POSES`: every solution of every pose target, per Jacobian asked for.
pub fn ik_poses(a: &PoseRequest, file: &Path, r: &CalibResult, kinds: &[JacobianKind], check: Option<&TwinCheck>, quiet: bool) -> Result<()> {
    let n = r.model.chain.n_joints;
    let poses: Vec<(Vector3<f64>, Matrix3<f64>)> = read_targets(file, n, a.euler)?
        .into_iter()
        .map(|t| match t {
            Target::Pose(p, m) => Ok((p, m)),
            _ => Err(Error::data(file.display(), "ik solves points (x, y, z) or poses (x, y, z, rx, ry, rz); joint targets are for compensate")),
        })
        .collect::<Result<_>>()?;
    let x_nom = nominal_x(r);
    let c = Compensator::new(r, &x_nom, None, a.tol_mm, a.tol_deg)?;
    let runs: Vec<PoseRun> = kinds.iter().map(|k| PoseRun::solve(&c, *k, &poses, check)).collect();
    let mut outputs = twincal::output::OutputSet::new();
    outputs.write(a.out, poses_csv(n, &runs, &poses, a.euler).as_bytes())?;
    outputs.commit()?;
    if !quiet {
        eprintln!(
            "ik on {} ({} pose targets, tolerances {} mm and {} deg; the nominal arm's solutions {}{})",
            a.model.display(),
            poses.len(),
            a.tol_mm,
            a.tol_deg,
            if c.closed_form() { "in closed form, every one within the joint limits" } else { "by numerical search (no closed form: one solution per target)" },
            check.map(|c| format!("; twin frame fit RMS {:.4} mm", c.fit_rms_mm)).unwrap_or_default()
        );
    }
    println!("{}", poses_table(&runs));
    for run in &runs {
        let unsolved = run.solutions.iter().filter(|ss| ss.iter().all(|s| s.status != IkStatus::Converged)).count();
        if unsolved > 0 {
            eprintln!("  {}: {unsolved} targets without a solution (their rows say why)", run.label);
        }
    }
    Ok(())
}
