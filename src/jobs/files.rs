//! What every job shares: the files a `--data` path reads, scenarios, the outputs' checks, the
//! identified twin's files and the recordings' interface.

use crate::calib::pipeline::CalibResult;
use crate::dataset::Dataset;
use crate::diagnose::Diagnosis;
use crate::error::Result;
use crate::output::{check_outputs, OutputSet};
use crate::report::{CalibFigures, DiagnosisFigures, ReplayFigures};
use crate::requests::Reading;
use crate::sim::scenario::Scenario;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// `--robot` as an input file, where it names one (not the embedded arm).
pub fn named_robot_input(robot: &crate::robot::RobotChoice) -> Option<(&'static str, PathBuf)> {
    robot.file().map(|f| ("--robot", f.to_path_buf()))
}

/// The files a `--data` path reads: `DIR/dataset.csv` for a folder, the file otherwise (without
/// an xlsx `#Sheet`), plus the truth file `calibrate` reads beside either.
pub fn data_inputs(data: &Path) -> Vec<PathBuf> {
    if let Some(files) = crate::dataset::artifact_files(data) {
        return files.into_iter().map(|(_, f)| f).collect();
    }
    match crate::dataset::campaign_files(data) {
        Some(files) => files,
        None => vec![crate::dataset::truth::dataset_file(data), crate::dataset::truth::truth_file(data)],
    }
}

/// Loads a dataset for a job. `require_length`: the reading columns must be present (calibrate,
/// compare) or may be absent (predict).
pub fn load_dataset(path: &Path, reading: &Reading, require_length: bool) -> Result<Dataset> {
    Dataset::load_with(path, &reading.load_options(require_length))
}

/// A scenario and its robot: the file at `path`, or the embedded default scenario.
pub fn load_scenario(path: Option<&Path>) -> Result<(Scenario, crate::robot::Robot)> {
    match path {
        Some(p) => Scenario::load(p),
        None => Scenario::default_embedded(),
    }
}

/// The files a scenario run reads, by option: the scenario and the URDF it names.
pub fn scenario_inputs(path: Option<&Path>, s: &Scenario) -> Vec<(&'static str, PathBuf)> {
    let mut v: Vec<(&str, PathBuf)> = path.map(|p| ("--scenario", p.to_path_buf())).into_iter().collect();
    v.extend(s.robot_file(path.and_then(Path::parent)).map(|p| ("the scenario's robot", p)));
    v
}

/// The URDF `--scenario-out FILE` writes beside the scenario (FILE with extension `.urdf`).
pub fn scenario_urdf_path(p: &Path) -> PathBuf {
    p.with_extension("urdf")
}

/// Checks the outputs of a job that writes a model (`calibrate`, `diagnose`): `outs`, its
/// own, plus `--rrd`, `--report` and `--scenario-out` with the URDF written beside it, against
/// each other and the `inputs` (see [`check_outputs`]).
pub fn check_model_outputs<'a>(
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

/// Stages the identified twin of `result` (see [`crate::identified`]): the scenario at `path`
/// and its URDF beside it.
pub fn stage_identified_twin(
    outputs: &mut OutputSet,
    path: &Path,
    result: &CalibResult,
    data: &Dataset,
    nominal: Option<&crate::robot::Robot>,
    how: &str,
) -> Result<()> {
    let twin = crate::identified::identified_scenario(result, data, nominal, path, how)?;
    outputs.write(&scenario_urdf_path(path), twin.urdf.as_bytes())?;
    outputs.write(path, twin.toml.as_bytes())
}

/// The figures of a calibration or a diagnosis (`--rrd`, `--report`), written with its other
/// outputs or not at all.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct Figures {
    /// Rerun recording of the run: the data, the fit before and after, and what it found
    /// (open it with the Rerun viewer).
    #[cfg_attr(feature = "clap", arg(long))]
    pub rrd: Option<PathBuf>,
    /// Self-contained HTML report (tables and plots, opens offline in any browser).
    #[cfg_attr(feature = "clap", arg(long))]
    pub report: Option<PathBuf>,
}

/// The recordings a job can stage beside its other outputs (`--rrd`). The `twincal-viz` package
/// implements them for the Rerun viewer; [`NoRecordings`] refuses every one.
pub trait Recordings: Sync {
    /// Stages the recording of a calibration at `path`.
    fn calibration(&self, result: &CalibResult, figures: &CalibFigures, outputs: &mut OutputSet, path: &Path) -> Result<()>;
    /// Stages the recording of a diagnosis at `path`.
    fn diagnosis(&self, report: &Diagnosis, figures: &DiagnosisFigures, outputs: &mut OutputSet, path: &Path) -> Result<()>;
    /// Stages the recording of a replay at `path`.
    fn replay(&self, figures: &ReplayFigures, outputs: &mut OutputSet, path: &Path) -> Result<()>;
    /// Stages the recording of a comparison at `path`: its tables (Markdown), the methods in
    /// order and every run.
    fn comparison(&self, table: &str, methods: &[String], runs: &[super::CompareRun], outputs: &mut OutputSet, path: &Path) -> Result<()>;
    /// Stages the recording of a measurement plan for scenario `s` at `path`.
    fn plan(&self, plan: &crate::plan::Plan, s: &Scenario, robot: &crate::robot::Robot, outputs: &mut OutputSet, path: &Path) -> Result<()>;
}

/// No recordings: a job asked for one fails before writing anything.
pub struct NoRecordings;

impl NoRecordings {
    fn refuse(path: &Path) -> Result<()> {
        Err(crate::error::Error::Invalid(format!("cannot write {}: this build of twincal writes no Rerun recordings", path.display())))
    }
}

impl Recordings for NoRecordings {
    fn calibration(&self, _: &CalibResult, _: &CalibFigures, _: &mut OutputSet, path: &Path) -> Result<()> {
        Self::refuse(path)
    }
    fn diagnosis(&self, _: &Diagnosis, _: &DiagnosisFigures, _: &mut OutputSet, path: &Path) -> Result<()> {
        Self::refuse(path)
    }
    fn replay(&self, _: &ReplayFigures, _: &mut OutputSet, path: &Path) -> Result<()> {
        Self::refuse(path)
    }
    fn comparison(&self, _: &str, _: &[String], _: &[super::CompareRun], _: &mut OutputSet, path: &Path) -> Result<()> {
        Self::refuse(path)
    }
    fn plan(&self, _: &crate::plan::Plan, _: &Scenario, _: &crate::robot::Robot, _: &mut OutputSet, path: &Path) -> Result<()> {
        Self::refuse(path)
    }
}
