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
use twincal::dataset::Dataset;
use twincal::error::{Error, Result};
use twincal::io::{check_outputs, OutputSet};
use twincal::report::verdict::{judge, with_verdict, Limit};
use twincal::sim::generate::{generate as run_generate, stage_outputs, Generated, Progress, Silent};
use twincal::sim::scenario::Scenario;

/// Most seeds `compare` and `bench calib` accept.
pub const MAX_SEEDS: u64 = 1000;
/// Most calibrations (methods × seeds) one `compare` runs.
pub const MAX_COMPARE_JOBS: u64 = 5000;
/// Range of `--effort` (a multiple of the methods' default budgets): below a hundredth of it a
/// stochastic method has next to no iterations, and its "result" is its start.
pub const MIN_EFFORT: f64 = 0.01;
pub const MAX_EFFORT: f64 = 10.0;
/// Most repetitions `bench` accepts.
pub const MAX_REPEAT: usize = 1000;

/// `--angles`: unit of the joint angles in a dataset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum AngleArg {
    /// Degrees, unless the values look like radians (then an error says so).
    Auto,
    /// Degrees.
    Deg,
    /// Radians.
    Rad,
}

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
fn load_dataset(path: &Path, angles: AngleArg, reading: &ReadingArgs, require_length: bool) -> Result<Dataset> {
    Dataset::load_with(path, &load_options(angles, reading, require_length)?)
}

/// How `--angles`, `--measurement` and `--euler` read a dataset (for any source: a file, or
/// columns in memory).
pub fn load_options(angles: AngleArg, reading: &ReadingArgs, require_length: bool) -> Result<twincal::dataset::LoadOptions> {
    use twincal::dataset::AngleUnit;
    let angles = match angles {
        AngleArg::Auto => AngleUnit::Auto,
        AngleArg::Deg => AngleUnit::Deg,
        AngleArg::Rad => AngleUnit::Rad,
    };
    let (measurement, euler) = reading.resolve()?;
    Ok(twincal::dataset::LoadOptions { angles, require_length, measurement, euler })
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

/// How a dataset's reading columns are read (`--measurement`, `--euler`).
#[derive(Clone, Debug, clap::Args)]
pub struct ReadingArgs {
    /// The instrument whose columns to read when the header holds more than one's (point: only
    /// x, y, z of a file that also has a pose's rx, ry, rz); default: what the header holds
    /// (L: length; x, y, z: point; x, y, z, rx, ry, rz: pose).
    #[arg(long, value_name = "length|point|pose")]
    pub measurement: Option<String>,
    /// The Euler convention of a pose's rx, ry, rz (degrees): capitals for rotations about the
    /// moving axes (intrinsic; XYZ is R = Rx(rx)·Ry(ry)·Rz(rz)), lower case for the fixed axes
    /// (extrinsic; xyz is R = Rz(rz)·Ry(ry)·Rx(rx)); ZYX, ZYZ, ... likewise.
    #[arg(long, default_value = "XYZ")]
    pub euler: String,
}

impl Default for ReadingArgs {
    fn default() -> Self {
        ReadingArgs { measurement: None, euler: "XYZ".into() }
    }
}

impl ReadingArgs {
    /// The instrument asked for and the Euler convention, or an error naming the flag.
    pub fn resolve(&self) -> Result<(Option<twincal::measurement::Measurement>, twincal::measurement::Euler)> {
        use twincal::measurement::{Euler, Measurement};
        let measurement = match &self.measurement {
            None => None,
            Some(name) => Some(Measurement::ALL.into_iter().find(|m| m.name().eq_ignore_ascii_case(name.trim())).ok_or_else(|| {
                Error::Invalid(format!("--measurement '{name}' is not one of {}", Measurement::ALL.iter().map(|m| m.name()).collect::<Vec<_>>().join(", ")))
            })?),
        };
        let euler = Euler::parse(&self.euler).map_err(|e| Error::Invalid(format!("--euler: {e}")))?;
        Ok((measurement, euler))
    }
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

/// The calibration model a `--model` / `--params` pair names; `--params` is refused for
/// `generic6r`, which has no nominal model to parametrise.
fn model_spec(model: &str, params: Option<&str>) -> Result<twincal::calib::run::ModelSpec> {
    if model == "generic6r" {
        if let Some(p) = params {
            return Err(Error::Invalid(format!("--params {p} applies to nominal models (irb120 or a .urdf); generic6r has no nominal model to parametrise")));
        }
    }
    twincal::calib::run::ModelSpec::parse(model, params.unwrap_or("hayati"))
}

/// Which model a calibration fits (`--model`, `--params`).
#[derive(Clone, Debug, clap::Args)]
pub struct ModelArgs {
    /// irb120 (embedded URDF), a .urdf path, or generic6r (no nominal).
    #[arg(long, default_value = "irb120")]
    pub model: String,
    /// Parametrisation of a nominal model: hayati (D-H, β on parallel axes; the default), dh (papers' 24)
    /// or frame. Not for generic6r.
    #[arg(long)]
    pub params: Option<String>,
}

impl ModelArgs {
    /// The model these options name; `--params` is refused for `generic6r`.
    pub fn spec(&self) -> Result<twincal::calib::run::ModelSpec> {
        model_spec(&self.model, self.params.as_deref())
    }

    /// `--model` as an input file, when it names one (a .urdf).
    fn input(&self) -> Option<PathBuf> {
        self.model.ends_with(".urdf").then(|| PathBuf::from(&self.model))
    }
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

/// Robust estimation and the data's floor (`--outliers`, `--loss`, `--angle-resolution-deg`).
#[derive(Clone, Debug, clap::Args)]
pub struct RobustArgs {
    /// Training rows more than this many robust standard deviations (1.4826 MAD) off the fit
    /// are outliers: kept out and listed in the result (0: keep every row).
    #[arg(long, default_value_t = twincal::calib::run::DEFAULT_OUTLIER_K, allow_negative_numbers = true)]
    pub outliers: f64,
    /// Keep out the rows of a run of outliers even when they all sit one constant offset off
    /// (by default such a reading step is corrected and its rows kept).
    #[arg(long)]
    pub no_reading_steps: bool,
    /// Least-squares loss of `--method lm`: l2, huber or cauchy (by IRLS, robust scale from the data).
    #[arg(long, default_value = "l2")]
    pub loss: String,
    /// Logging step of the joint angles in degrees, for the noise floor (default: read from the
    /// data's decimals).
    #[arg(long, allow_negative_numbers = true)]
    pub angle_resolution_deg: Option<f64>,
    /// The instrument's stated accuracy, mm (standard uncertainty of one coordinate or of the
    /// cable length), for the noise floor.
    #[arg(long, allow_negative_numbers = true)]
    pub instrument_accuracy_mm: Option<f64>,
    /// Fit with equal weights even where the data give per-row standard deviations (a
    /// tracker's sx, sy, sz; by default they weight the fit as 1/(floor² + s²)).
    #[arg(long)]
    pub ignore_row_std: bool,
}

/// `--instrument-accuracy-mm`, checked: a standard uncertainty in (0, 100] mm.
pub fn instrument_accuracy(v: Option<f64>) -> Result<Option<f64>> {
    match v {
        Some(a) if !(a.is_finite() && a > 0.0 && a <= 100.0) => {
            Err(Error::Invalid(format!("--instrument-accuracy-mm must be in (0, 100] mm (a standard uncertainty of one coordinate), got {a}")))
        }
        _ => Ok(v),
    }
}

impl RobustArgs {
    /// (outlier threshold, loss, angle step), validated.
    pub fn resolve(&self) -> Result<(f64, twincal::calib::problem::robust::Loss, Option<f64>)> {
        if !(self.outliers.is_finite() && (self.outliers == 0.0 || (2.0..=100.0).contains(&self.outliers))) {
            return Err(Error::Invalid(format!("--outliers must be 0 (off) or in [2, 100] robust standard deviations, got {}", self.outliers)));
        }
        if let Some(r) = self.angle_resolution_deg {
            if !(r.is_finite() && r > 0.0 && r <= 10.0) {
                return Err(Error::Invalid(format!("--angle-resolution-deg must be in (0, 10] degrees, got {r}")));
            }
        }
        Ok((self.outliers, twincal::calib::problem::robust::Loss::parse(&self.loss)?, self.angle_resolution_deg))
    }
}

/// What loads the joints, for the torque-driven effects (`--robot`, `--payload-kg`,
/// `--payload-com-mm`, `--cable-tension-n`).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct LoadArgs {
    /// URDF whose inertial data give the static joint torques (default: the model's own robot;
    /// needed for joint_compliance with generic6r).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Payload on the flange, kg.
    #[arg(long, allow_negative_numbers = true)]
    pub payload_kg: Option<f64>,
    /// Payload centre of mass in the flange frame, mm (x,y,z).
    #[arg(long, allow_negative_numbers = true, value_delimiter = ',', allow_hyphen_values = true, value_name = "X,Y,Z")]
    pub payload_com_mm: Option<Vec<f64>>,
    /// Draw-wire cable tension from the sensor's data sheet, N (0: ignored).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub cable_tension_n: f64,
}

impl LoadArgs {
    /// The load options and the inertial robot (`--robot`), validated.
    pub fn resolve(&self) -> Result<(twincal::calib::effects::inputs::LoadOptions, Option<twincal::robot::Robot>)> {
        let mut o = twincal::calib::effects::inputs::LoadOptions::default();
        if !(self.cable_tension_n.is_finite() && (0.0..=1000.0).contains(&self.cable_tension_n)) {
            return Err(Error::Invalid(format!("--cable-tension-n must be in [0, 1000] N, got {}", self.cable_tension_n)));
        }
        o.cable_tension_n = self.cable_tension_n;
        match (self.payload_kg, &self.payload_com_mm) {
            (None, None) => {}
            (Some(m), com) => {
                if !(m.is_finite() && (0.0..=1000.0).contains(&m)) {
                    return Err(Error::Invalid(format!("--payload-kg must be in [0, 1000] kg, got {m}")));
                }
                let com = com.clone().unwrap_or_else(|| vec![0.0; 3]);
                if com.len() != 3 || com.iter().any(|v| !v.is_finite() || v.abs() > 5000.0) {
                    return Err(Error::Invalid("--payload-com-mm needs 3 finite values in mm (x,y,z in the flange frame, each within ±5000)".into()));
                }
                o.payload = Some(twincal::sim::effects::Payload { mass_kg: m, com_mm: [com[0], com[1], com[2]] });
            }
            (None, Some(_)) => return Err(Error::Invalid("--payload-com-mm needs --payload-kg".into())),
        }
        let robot = match &self.robot {
            Some(p) => Some(twincal::robot::Robot::from_urdf_file(p)?),
            None => None,
        };
        Ok((o, robot))
    }
}

/// Parses `--effects compliance,backlash:2,thermal`: a kind, optionally `:JOINT` (1..N, checked against the data).
/// The `KIND[:JOINT]` items of an option (`--effects`, `--candidates`; `option` names it in
/// errors).
pub fn parse_effects(option: &str, list: &[String]) -> Result<Vec<(twincal::calib::effects::EffectKind, Option<usize>)>> {
    use twincal::calib::effects::EffectKind;
    // `--effects ,` (or an empty string) names nothing: an option given must name an effect.
    if !list.is_empty() && list.iter().all(|s| s.trim().is_empty()) {
        return Err(Error::Invalid(format!("{option} '{}' names no effect: give KIND[:JOINT] items separated by commas", list.join(","))));
    }
    list.iter()
        .filter(|s| !s.trim().is_empty())
        .map(|item| {
            let (kind, joint) = match item.split_once(':') {
                Some((k, j)) => {
                    let max = twincal::dataset::MAX_JOINTS;
                    let bad = || Error::Invalid(format!("{option} {item}: the joint after ':' must be a joint number, 1..N"));
                    let j: usize = j.trim().parse().map_err(|_| bad())?;
                    if !(1..=max).contains(&j) {
                        return Err(bad());
                    }
                    (EffectKind::parse(k).map_err(|e| Error::Invalid(format!("{option} {item}: {e}")))?, Some(j - 1))
                }
                None => (EffectKind::parse(item).map_err(|e| Error::Invalid(format!("{option} {item}: {e}")))?, None),
            };
            let allowed = kind.joint_options(twincal::dataset::MAX_JOINTS).contains(&joint) || (joint.is_none() && kind.per_joint());
            if !allowed {
                return Err(Error::Invalid(format!("{option} {item}: {} is not a per-joint effect", kind.name())));
            }
            Ok((kind, joint))
        })
        .collect()
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
