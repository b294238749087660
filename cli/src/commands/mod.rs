//! The command line's commands, one file each (kept in the library so tests can call them),
//! and what they share: argument groups, dataset and model loading, progress bars, limits.

mod bench;
mod calibrate;
mod compare;
mod diagnose;
mod generate;
pub mod ik;
mod predict;
mod replay;
mod study;
#[cfg(test)]
mod tests;

pub use bench::bench_command;
use calibrate::print_verdict;
pub use calibrate::{calibrate, calibrate_loaded, calibration_warnings, write_calibration, CalibrateArgs, Calibration};
pub use compare::{compare, reduce, CompareArgs, CompareRun};
pub use diagnose::{diagnose, diagnose_loaded, write_diagnosis, DiagnoseArgs, Diagnosed};
pub use generate::generate;
pub use predict::{predict, predicted_readings, prediction_csv};
pub use replay::{replay, ReplayArgs};
pub use study::{study, StudyTarget};

use std::path::{Path, PathBuf};
use std::time::Instant;
pub use twincal::dataset::AngleUnit;
use twincal::dataset::Dataset;
use twincal::error::{Error, Result};
use twincal::io::{check_outputs, OutputSet};
use twincal::report::verdict::{judge, with_verdict, Limit};
pub use twincal::requests::{ModelChoice, Reading};
use twincal::sim::generate::{generate as run_generate, stage_outputs, Generated, Progress, Silent};
use twincal::sim::scenario::Scenario;

/// Most seeds `compare` and `bench calib` accept.
pub const MAX_SEEDS: u64 = 1000;
/// Most calibrations (methods × seeds) one `compare` runs.
pub const MAX_COMPARE_JOBS: u64 = 5000;
/// Most repetitions `bench` accepts.
pub const MAX_REPEAT: usize = 1000;

/// `twincal bench` targets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchTarget {
    /// The twin: settled poses per second, rapier against the quasi-static model.
    Twin,
    /// The calibration core's targets.
    Calib,
    /// The diagnosis: detection and false-alarm rates over hidden-effect scenarios, time.
    Diagnose,
    /// Evo-NPH: DS-ADE speed, ablations with the truth, DE engines on one objective (Table 10).
    Dsade,
    /// Inverse kinematics: Jacobian variants, time per query, true error on the twin.
    Ik,
    /// PSO-EKF-AWNN: stage times against LM, accuracy and truth over seeds, data efficiency,
    /// sensitivity to Q, R and the learning rate, HSR-RobotCali.
    Awnn,
    /// Real measured data: HSR generic model per search seed and its diagnosis, RobotCali
    /// methods over random splits with and without the outlier screen.
    Real,
    /// Diagnose on the UR10's 11 911-row series a (../shared/data, sorted by t): median wall
    /// time of --repeat runs against the 60 s target, and what it named.
    DiagnoseUr10,
    /// The joint angles' logging error as a noise model: lm, dsade-gkan and pso-ekf-awnn with
    /// and without it on realistic acquisitions (sweeps, 0.1° logging), true error and time.
    NoiseModel,
    /// Replay of 1 000 rows through the scenario's acquisition (default: the embedded
    /// scenario's simulated tour) against 5 s, and the identified twin's cost against 1 s.
    Replay,
}

/// Loads a dataset for a command. `require_length`: the `L` column must be present (calibrate,
/// compare) or may be absent (predict).
fn load_dataset(path: &Path, reading: &Reading, require_length: bool) -> Result<Dataset> {
    Dataset::load_with(path, &reading.load_options(require_length)?)
}

/// The figures of a calibration or a diagnosis (`--rrd`, `--report`), written with its other
/// outputs or not at all.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct Figures {
    /// Rerun recording of the run: the data, the fit before and after, and what it found
    /// (open it with the Rerun viewer).
    #[arg(long)]
    pub rrd: Option<PathBuf>,
    /// Self-contained HTML report (tables and plots, opens offline in any browser).
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// `--shard i/N --shard-out PART.jsonl` of `study hold` and `bench diagnose` (see
/// [`crate::shard`]).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct ShardArgs {
    /// Run only the work items with id % N == i (in a fixed order, each with its own seed),
    /// appending each to --shard-out as it finishes; `twincal reduce` joins the parts.
    /// Re-running a shard skips the items its file holds.
    #[arg(long, value_name = "i/N", allow_hyphen_values = true)]
    pub shard: Option<String>,
    /// The shard's partial file (JSONL; needed with --shard).
    #[arg(long)]
    pub shard_out: Option<PathBuf>,
}

/// The files a `--data` path reads: `DIR/dataset.csv` for a folder, the file otherwise (without
/// an xlsx `#Sheet`), plus the truth file `calibrate` reads beside either.
pub fn data_inputs(data: &Path) -> Vec<PathBuf> {
    let file = if data.is_dir() {
        data.join(twincal::dataset::DATASET_FILE)
    } else {
        match data.to_string_lossy().rsplit_once('#') {
            Some((f, _)) if !data.exists() => PathBuf::from(f),
            _ => data.to_path_buf(),
        }
    };
    let dir = if data.is_dir() { data.to_path_buf() } else { file.parent().map(Path::to_path_buf).unwrap_or_default() };
    vec![file, dir.join(twincal::dataset::truth::TRUTH_FILE)]
}

/// A terminal progress bar (hidden when stderr is not a terminal).
pub struct Bar(indicatif::ProgressBar);

impl Bar {
    pub fn new() -> Self {
        let pb = indicatif::ProgressBar::new(0);
        pb.set_style(
            indicatif::ProgressStyle::with_template("{msg:>16} [{bar:40}] {pos}/{len} ({per_sec}, eta {eta})")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        Bar(pb)
    }
}

impl Default for Bar {
    fn default() -> Self {
        Self::new()
    }
}

impl Progress for Bar {
    fn start(&self, total: u64, what: &str) {
        self.0.set_length(total);
        self.0.set_position(0);
        self.0.set_message(what.to_string());
    }
    fn inc(&self, n: u64) {
        self.0.inc(n);
    }
    fn finish(&self) {
        self.0.finish_and_clear();
    }
}

pub fn progress(quiet: bool) -> Box<dyn Progress> {
    if quiet {
        Box::new(Silent)
    } else {
        Box::new(Bar::new())
    }
}

pub fn load_scenario(path: Option<&Path>) -> Result<(Scenario, twincal::robot::Robot)> {
    match path {
        Some(p) => Scenario::load(p),
        None => Scenario::default_embedded(),
    }
}

/// The files a scenario run reads: the scenario and the URDF it names.
fn scenario_inputs(path: Option<&Path>, s: &twincal::sim::scenario::Scenario) -> Vec<(&'static str, PathBuf)> {
    let mut v: Vec<(&str, PathBuf)> = path.map(|p| ("--scenario", p.to_path_buf())).into_iter().collect();
    v.extend(s.robot_file(path.and_then(Path::parent)).map(|p| ("the scenario's robot", p)));
    v
}

fn check_repeat(repeat: usize) -> Result<()> {
    if !(1..=MAX_REPEAT).contains(&repeat) {
        return Err(Error::Invalid(format!("--repeat must be between 1 and {MAX_REPEAT}, got {repeat}")));
    }
    Ok(())
}

fn check_seeds(seeds: u64) -> Result<()> {
    if !(1..=MAX_SEEDS).contains(&seeds) {
        return Err(Error::Invalid(format!("--seeds must be between 1 and {MAX_SEEDS}, got {seeds}")));
    }
    Ok(())
}

/// Above this many times a floor that is only a lower bound (no repeated configurations), the
/// ratio says nothing about the fit and is not printed.
const MAX_BOUND_RATIO: f64 = 10.0;

/// Loads a calibrated model (result.json); its errors are labelled `model PATH`.
fn load_model(path: &Path) -> Result<twincal::calib::run::CalibResult> {
    twincal::calib::run::CalibResult::load(path)
}

/// The URDF `--scenario-out FILE` writes beside the scenario (FILE with extension `.urdf`).
pub fn scenario_urdf_path(p: &Path) -> PathBuf {
    p.with_extension("urdf")
}

/// Checks the outputs of a command that writes a model (`calibrate`, `diagnose`): `outs`, its
/// own, plus `--rrd`, `--report` and `--scenario-out` with the URDF written beside it, against
/// each other and the `inputs` (see [`check_outputs`]).
fn check_model_outputs<'a>(
    inputs: &[(&str, &Path)],
    mut outs: Vec<(&'a str, &'a Path)>,
    rrd: Option<&'a Path>,
    report: Option<&'a Path>,
    scenario_out: Option<&'a Path>,
) -> Result<()> {
    outs.extend(rrd.map(|p| ("--rrd", p)));
    outs.extend(report.map(|p| ("--report", p)));
    let twin_urdf = scenario_out.map(scenario_urdf_path);
    outs.extend(scenario_out.map(|p| ("--scenario-out", p)));
    let mut all: Vec<(&str, &Path)> = outs;
    all.extend(twin_urdf.as_deref().map(|p| ("--scenario-out's URDF", p)));
    check_outputs(inputs, &all)
}

/// Stages the identified twin of `result` (see [`twincal::identified`]): the scenario at
/// `path` and its URDF beside it.
pub fn stage_identified_twin(
    outputs: &mut OutputSet,
    path: &Path,
    result: &twincal::calib::run::CalibResult,
    data: &Dataset,
    nominal: Option<&twincal::robot::Robot>,
    how: &str,
) -> Result<()> {
    let twin = twincal::identified::identified_scenario(result, data, nominal, path, how)?;
    outputs.write(&scenario_urdf_path(path), twin.urdf.as_bytes())?;
    outputs.write(path, twin.toml.as_bytes())
}
