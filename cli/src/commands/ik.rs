//! `twincal ik`: inverse kinematics on a calibrated model (any corrector), per-target statuses,
//! and, where the data came from the twin, the true tool-point error of every solution (see
//! [`twincal::ik`]).

use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use twincal::calib::pipeline::CalibResult;
use twincal::dataset::truth::TruthFile;
use twincal::error::{Error, Result};
pub use twincal::ik::solver::{check_tol_mm, MAX_TOL_MM};
use twincal::ik::{ik_runs, random_targets, table, IkOptions, IkRun, IkStatus, JacobianChoice, JacobianKind, TwinCheck};

/// Reads target points (mm) from a CSV with columns x, y, z (header required; other columns
/// ignored), by the dataset reader's rules ([`twincal::dataset::read_csv_columns`]: `;` or tab,
/// decimal commas, quotes, comments, a byte-order mark). Non-numeric fields are refused with the
/// line number; NaN is accepted and answered with the status `invalid`.
pub fn read_targets(path: &Path) -> Result<Vec<Vector3<f64>>> {
    let out: Vec<Vector3<f64>> = twincal::dataset::read_csv_columns(path, &["x", "y", "z"])?.into_iter().map(|v| Vector3::new(v[0], v[1], v[2])).collect();
    if out.is_empty() {
        return Err(Error::data(path.display(), "no targets after the header"));
    }
    let far = twincal::measurement::point::MAX_COORD_MM;
    if let Some((i, t)) = out.iter().enumerate().find(|(_, t)| t.iter().any(|v| v.abs() > far)) {
        return Err(Error::data(
            path.display(),
            format!(
                "target {} ({}, {}, {}) mm is implausible (a coordinate beyond {far} mm)",
                i + 1,
                twincal::error::shown(t.x),
                twincal::error::shown(t.y),
                twincal::error::shown(t.z)
            ),
        ));
    }
    Ok(out)
}

/// Arguments of `twincal ik` (the field docs are its `--help`).
#[derive(Clone, Debug, clap::Args)]
pub struct IkArgs {
    /// A result.json written by `calibrate`.
    #[arg(long)]
    pub model: PathBuf,
    /// CSV of targets in the robot's base frame: points (columns x,y,z in mm; for a model
    /// calibrated on a laser tracker's points too, ik solves for the tool point in the base), or
    /// poses (x,y,z with rx,ry,rz in degrees, --euler): every solution of the calibrated arm for
    /// each pose, one row each.
    #[arg(long)]
    pub targets: Option<PathBuf>,
    /// N reachable targets: the true tool points of random configurations inside the
    /// calibrated joint ranges (the twin's, else the model's own).
    #[arg(long, allow_negative_numbers = true)]
    pub random: Option<usize>,
    /// Twin dataset folder with truth.json (default: the result's data, when it has one).
    #[arg(long)]
    pub twin: Option<PathBuf>,
    /// Do not validate on a twin even when a truth file is found.
    #[arg(long)]
    pub no_twin: bool,
    /// Which Jacobian the solver steps with: the method's own (hybrid), the chain's alone
    /// (analytic), the correction's alone (neural), or all three side by side.
    #[arg(long, value_enum, ignore_case = true, default_value_t = JacobianChoice::default())]
    pub jacobian: JacobianChoice,
    /// Model residual (mm) at which a target counts as solved.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    pub tol_mm: f64,
    /// Orientation residual (degrees) at which a pose target counts as solved.
    #[arg(long, default_value_t = 0.001, allow_negative_numbers = true)]
    pub tol_deg: f64,
    /// The Euler convention of pose targets' rx, ry, rz: capitals for rotations about the
    /// moving axes (intrinsic; XYZ is R = Rx(rx)·Ry(ry)·Rz(rz)), lower case for the fixed axes
    /// (extrinsic; xyz is R = Rz(rz)·Ry(ry)·Rx(rx)).
    #[arg(long, default_value_t = twincal::measurement::Euler::default())]
    pub euler: twincal::measurement::Euler,
    #[arg(long, allow_negative_numbers = true, default_value_t = 0)]
    pub seed: u64,
    /// Per-target solutions.
    #[arg(long, default_value = "ik.csv")]
    pub out: PathBuf,
}

/// A target has no temperature, time or approach history: the model is solved in its reference
/// state. Says so when the model reads more than the angles.
fn warn_reference_state(r: &CalibResult) {
    // A target has no temperature, time or approach history: the model is solved in its
    // reference state. Say so when the model reads more than the angles.
    let read: Vec<String> = r.columns_read().into_iter().map(|(c, why)| format!("{c} ({why})")).collect();
    if !read.is_empty() {
        eprintln!("warning: the model also reads {}; ik solves every target at the reference value (no rise)", read.join(", "));
    }
    if r.reads_flanks() {
        eprintln!(
            "warning: the model reads backlash flanks or joint torques (a backlash block, or its network's flank or torque inputs); ik solves every target \
             with no flank and no torque input (a target has no approach history)"
        );
    }
}

/// ik.csv: per target and solver, the status, iterations, residual, the joint angles (degrees)
/// and the true error on the twin when there is one.
fn solutions_csv(r: &CalibResult, runs: &[IkRun], targets: &[Vector3<f64>]) -> String {
    let joints: Vec<String> = (1..=r.model.chain.n_joints).map(|j| format!("q{j},")).collect();
    let mut csv = format!("target,x_mm,y_mm,z_mm,solver,status,iterations,residual_mm,{}true_error_mm\n", joints.concat());
    for run in runs {
        for (i, (s, t)) in run.solutions.iter().zip(targets).enumerate() {
            let q: Vec<String> = s.q.iter().map(|v| format!("{:.6}", v.to_degrees())).collect();
            // An invalid target (NaN) has no solution to measure.
            let te = run.true_error_mm.as_ref().filter(|_| s.status != IkStatus::Invalid).map(|v| format!("{:.6}", v[i])).unwrap_or_default();
            csv.push_str(&format!(
                "{},{},{},{},{},{},{},{:.6},{},{te}\n",
                i + 1,
                t.x,
                t.y,
                t.z,
                run.label,
                s.status.name(),
                s.iterations,
                s.residual_mm,
                q.join(",")
            ));
        }
    }
    csv
}

/// Per solver, the targets it did not solve, by status.
fn print_failures(runs: &[IkRun]) {
    for run in runs {
        let bad: Vec<String> = [IkStatus::Unreachable, IkStatus::JointLimit, IkStatus::Singular, IkStatus::NotConverged, IkStatus::Invalid]
            .iter()
            .filter_map(|st| {
                let n = run.solutions.iter().filter(|s| s.status == *st).count();
                (n > 0).then(|| format!("{n} {}", st.name()))
            })
            .collect();
        if !bad.is_empty() {
            eprintln!("  {}: {}", run.label, bad.join(", "));
        }
    }
}

/// `twincal ik`.
pub fn ik(a: &IkArgs, quiet: bool) -> Result<()> {
    if a.targets.is_some() == a.random.is_some() {
        return Err(Error::Invalid("give exactly one of --targets FILE and --random N".into()));
    }
    if let Some(n) = a.random {
        if !(1..=100_000).contains(&n) {
            return Err(Error::Invalid(format!("--random must be in 1..=100000, got {n}")));
        }
    }
    check_tol_mm(a.tol_mm, "--tol-mm")?;
    let kinds: Vec<JacobianKind> = a.jacobian.kinds();
    let r = CalibResult::load(&a.model)?;
    warn_reference_state(&r);
    if a.twin.is_some() && a.no_twin {
        return Err(Error::Invalid("--twin DIR validates on a twin and --no-twin skips it: give one of them".into()));
    }
    let data = result_data(&a.model, &r);
    let twin_dir = match (&a.twin, a.no_twin) {
        (_, true) => None,
        (Some(d), false) => Some(d.clone()),
        (None, false) => match TruthFile::find(&data) {
            Ok(found) => found.map(|_| data.clone()),
            Err(e) => {
                return Err(Error::Invalid(format!(
                    "the twin beside the model's data is unreadable ({e}); pass --twin DIR with the model's twin, or --no-twin"
                )))
            }
        },
    };
    // Every file read: the model, the targets, the model's data and the twin's files.
    let mut read: Vec<(&str, PathBuf)> = vec![("--model", a.model.clone())];
    read.extend(a.targets.iter().map(|t| ("--targets", t.clone())));
    read.extend(super::data_inputs(&data).into_iter().map(|p| ("the model's data", p)));
    if let Some(d) = &twin_dir {
        read.extend(super::data_inputs(d).into_iter().map(|p| ("the twin", p)));
    }
    twincal::output::check_outputs(&read, &[("--out", &a.out)])?;
    let check = twin_dir.as_deref().map(|d| TwinCheck::load(d, &r)).transpose()?;
    if let Some(f) = a.targets.as_deref().filter(|f| super::ik_poses::holds_poses(f)) {
        let request = super::ik_poses::PoseRequest { model: &a.model, tol_mm: a.tol_mm, tol_deg: a.tol_deg, euler: a.euler, out: &a.out };
        return super::ik_poses::ik_poses(&request, f, &r, &kinds, check.as_ref(), quiet);
    }
    let targets: Vec<Vector3<f64>> = match (&a.targets, a.random) {
        (Some(f), _) => read_targets(f)?,
        (None, Some(n)) => random_targets(&r, check.as_ref(), n, a.seed),
        _ => unreachable!("checked above"),
    };
    let o = IkOptions { tol_mm: a.tol_mm, seed: a.seed, ..Default::default() };
    let runs = ik_runs(&r, &targets, &kinds, &o, check.as_ref());
    let csv = solutions_csv(&r, &runs, &targets);
    let mut outputs = twincal::output::OutputSet::new();
    outputs.write(&a.out, csv.as_bytes())?;
    outputs.commit()?;
    if !quiet {
        eprintln!(
            "ik on {} ({} targets, tolerance {} mm{})",
            a.model.display(),
            targets.len(),
            a.tol_mm,
            check.as_ref().map(|c| format!("; twin frame fit RMS {:.4} mm", c.fit_rms_mm)).unwrap_or_default()
        );
    }
    println!("{}", table(&runs));
    print_failures(&runs);
    Ok(())
}

/// The model's data path: as recorded when it is absolute or exists from here; else relative to
/// the model file's folder, where `calibrate` may have been run (a path recorded relative to
/// another folder). Where both exist and the model records its data's SHA-256, the one whose
/// dataset matches wins.
fn result_data(model: &Path, r: &CalibResult) -> PathBuf {
    let recorded = PathBuf::from(&r.provenance.data);
    if recorded.is_absolute() {
        return recorded;
    }
    let beside = model.parent().map(|d| d.join(&recorded));
    let matches = |p: &Path| {
        let file = super::data_inputs(p).swap_remove(0);
        match (&r.provenance.data_sha256, std::fs::read(&file)) {
            (Some(sha), Ok(bytes)) => twincal::dataset::truth::sha256_hex(&bytes) == *sha,
            _ => false,
        }
    };
    match beside {
        Some(b) if b.exists() && (!recorded.exists() || (!matches(&recorded) && matches(&b))) => b,
        _ => recorded,
    }
}
