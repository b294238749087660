//! A calibration job: the data, the request and the files it writes.

use super::files::{check_model_outputs, data_inputs, load_dataset, stage_identified_twin, Figures, Recordings};
use crate::calib::pipeline::{CalibOptions, CalibResult, ModelSpec, TruthFile};
use crate::dataset::Dataset;
use crate::error::Result;
use crate::output::OutputSet;
use crate::report::verdict::{judge, with_verdict, Limit, Verdict};
use crate::requests::CalibrateRequest;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A calibration as `twincal calibrate` runs it (the field docs are its `--help`): the data, the
/// request (which Python fills from keyword arguments) and the files it writes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct CalibrateJob {
    /// Dataset folder (DIR/dataset.csv, with truth.json when the twin made it), CSV, or xlsx (file.xlsx#Sheet).
    #[cfg_attr(feature = "clap", arg(long))]
    pub data: PathBuf,
    /// The calibration's options.
    #[cfg_attr(feature = "clap", command(flatten))]
    pub request: CalibrateRequest,
    /// The calibrated model and its report.
    #[cfg_attr(feature = "clap", arg(long, default_value = "result.json"))]
    pub out: PathBuf,
    /// Also write the calibrated model as a URDF.
    #[cfg_attr(feature = "clap", arg(long))]
    pub urdf: Option<PathBuf>,
    /// The recording and the HTML report.
    #[cfg_attr(feature = "clap", command(flatten))]
    pub figures: Figures,
    /// Also write the identified twin: a scenario (and, beside it, the calibrated URDF it names)
    /// whose geometry, instrument placement, effect sizes, noise and logging resolutions are the
    /// identified ones, so that `generate` and `replay` simulate this robot.
    #[cfg_attr(feature = "clap", arg(long))]
    pub scenario_out: Option<PathBuf>,
}

/// What `calibrate` computed, before anything is written: the result, its verdict, and what
/// the outputs are drawn from (the options and the data calibrated on).
pub struct Calibration {
    /// The calibrated model and its figures.
    pub result: CalibResult,
    /// The verdict against `--max-test-rmse-mm` / `--max-test-max-mm`, when either was given.
    pub verdict: Option<Verdict>,
    /// The resolved options.
    pub opts: CalibOptions,
    /// The data calibrated on.
    pub data: Dataset,
}

impl CalibrateJob {
    /// A job on `data` with `request` and the command's default output (`result.json`).
    pub fn new(data: PathBuf, request: CalibrateRequest) -> Self {
        CalibrateJob { data, request, out: "result.json".into(), urdf: None, figures: Figures::default(), scenario_out: None }
    }

    /// Every option checked and resolved (reads no data; reads --robot's URDF).
    pub fn options(&self) -> Result<(CalibOptions, [Limit; 2])> {
        self.request.options()
    }

    /// The files this calibration reads and writes, by option, checked against each other
    /// (no output over an input, no two outputs on one file). `data`: whether `--data` is read.
    pub fn check_files(&self, data: bool) -> Result<()> {
        let data_files = if data { data_inputs(&self.data) } else { Vec::new() };
        let model_file = self.request.model.input();
        let mut inputs: Vec<(&str, &Path)> = data_files.iter().map(|p| ("--data", p.as_path())).collect();
        if let Some(m) = &model_file {
            inputs.push(("--model", m));
        }
        let mut outs: Vec<(&str, &Path)> = vec![("--out", &self.out)];
        outs.extend(self.urdf.as_deref().map(|p| ("--urdf", p)));
        check_model_outputs(&inputs, outs, self.figures.rrd.as_deref(), self.figures.report.as_deref(), self.scenario_out.as_deref())
    }

    /// The whole job: checks the options and the files, reads the data (and the truth file
    /// beside them), calibrates and writes every output, together or none.
    pub fn run(&self, recordings: &dyn Recordings) -> Result<Calibration> {
        let planned = self.options()?;
        self.check_files(true)?;
        let data = load_dataset(&self.data, &self.request.reading, true)?;
        let truth = TruthFile::find(&self.data)?;
        // The exact bytes calibrated on, so that `ik` can tell their twin from another one.
        let file = &data_inputs(&self.data)[0];
        let sha = crate::dataset::truth::file_sha256(file)?;
        let c = calibrate_loaded(planned, data, truth.as_ref(), Some(sha))?;
        write_calibration(self, &c, recordings)?;
        Ok(c)
    }
}

/// The calibration a job runs, with its options ([`CalibrateJob::options`]) on data already
/// loaded: `truth` the twin's truth file when it belongs to these data, `data_sha256` the
/// fingerprint of the bytes they came from.
pub fn calibrate_loaded(
    (opts, limits): (CalibOptions, [Limit; 2]),
    data: Dataset,
    truth: Option<&TruthFile>,
    data_sha256: Option<String>,
) -> Result<Calibration> {
    let mut result = crate::calib::pipeline::calibrate(&data, truth, &opts)?;
    result.provenance.data_sha256 = data_sha256;
    let test = result.evaluation.metrics.test_after.as_ref();
    let source = if test.is_some() { "test rows after calibration" } else { "no test rows: hold some out with --test-fraction or a split column" };
    let verdict = judge(&[(limits[0], "test_rmse_mm", test.map(|t| t.rmse), source), (limits[1], "test_max_mm", test.map(|t| t.max), source)]);
    Ok(Calibration { result, verdict, opts, data })
}

/// Writes what `calibrate` writes of a calibration (`--out`, and `--urdf`, `--rrd`, `--report`,
/// `--scenario-out` when given), all together or none. The caller has checked the files
/// ([`CalibrateJob::check_files`]).
pub fn write_calibration(a: &CalibrateJob, c: &Calibration, recordings: &dyn Recordings) -> Result<()> {
    let (result, data, opts) = (&c.result, &c.data, &c.opts);
    result.check_writable()?;
    let mut outputs = OutputSet::new();
    let figures = if a.figures.rrd.is_some() || a.figures.report.is_some() { Some(crate::report::CalibFigures::new(result, data)?) } else { None };
    if let (Some(p), Some(f)) = (&a.figures.rrd, &figures) {
        recordings.calibration(result, f, &mut outputs, p)?;
    }
    if let (Some(p), Some(f)) = (&a.figures.report, &figures) {
        outputs.write(p, crate::report::html::calibration_page(result, f, c.verdict.as_ref()).as_bytes())?;
    }
    if let Some(p) = &a.urdf {
        let nominal = match &opts.model {
            ModelSpec::Nominal { robot, .. } => Some(robot.as_ref()),
            ModelSpec::Generic => None,
        };
        outputs.write(p, crate::export::urdf::urdf(&result.model, &result.x, nominal, "calibrated").as_bytes())?;
    }
    if let Some(p) = &a.scenario_out {
        let how = match opts.free {
            crate::calib::pipeline::FreeParams::All => "calibrate",
            crate::calib::pipeline::FreeParams::Placement => "calibrate --placement-only",
            crate::calib::pipeline::FreeParams::Controller => "calibrate --controller-subset",
        };
        stage_identified_twin(&mut outputs, p, result, data, opts.model.robot(), how)?;
    }
    outputs.write_json(&a.out, &with_verdict(result, c.verdict.as_ref())?)?;
    outputs.commit()
}
