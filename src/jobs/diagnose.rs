//! A diagnosis job: the data, the request and the files it writes.

use super::files::{check_model_outputs, data_inputs, load_dataset, stage_identified_twin, Figures, Recordings};
use crate::calib::pipeline::CalibResult;
use crate::dataset::Dataset;
use crate::diagnose::{DiagnoseOptions, Diagnosis};
use crate::error::Result;
use crate::output::OutputSet;
use crate::report::verdict::{judge, with_verdict, Limit, Verdict};
use crate::requests::DiagnoseRequest;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A diagnosis as `twincal diagnose` runs it (the field docs are its `--help`): the data, the
/// request (which Python fills from keyword arguments) and the files it writes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct DiagnoseJob {
    /// Dataset folder, CSV or xlsx (q1..qN and L, or a tracker's x, y, z; optional t, temp). No
    /// truth file is read.
    #[cfg_attr(feature = "clap", arg(long))]
    pub data: PathBuf,
    /// The diagnosis's options.
    #[cfg_attr(feature = "clap", command(flatten))]
    pub request: DiagnoseRequest,
    /// The diagnosis report.
    #[cfg_attr(feature = "clap", arg(long, default_value = "report.json"))]
    pub out: PathBuf,
    /// The extended model, saved like any calibration result.
    #[cfg_attr(feature = "clap", arg(long, default_value = "diagnosed.json"))]
    pub result: PathBuf,
    /// The recording and the HTML report.
    #[cfg_attr(feature = "clap", command(flatten))]
    pub figures: Figures,
    /// Also write the identified twin (scenario and URDF, see `calibrate --scenario-out`),
    /// with the named causes at their sizes.
    #[cfg_attr(feature = "clap", arg(long))]
    pub scenario_out: Option<PathBuf>,
}

/// What `diagnose` found, before anything is written: the report, the extended model (a
/// calibration result), the verdict, and the data and options they came from.
pub struct Diagnosed {
    /// What report.json holds.
    pub report: Diagnosis,
    /// The extended model (diagnosed.json).
    pub result: CalibResult,
    /// The verdict against `--max-heldout-rmse-mm`, when given.
    pub verdict: Option<Verdict>,
    /// The resolved options.
    pub opts: DiagnoseOptions,
    /// The rows diagnosed (the training rows of `--test-fraction`, when given).
    pub data: Dataset,
}

impl DiagnoseJob {
    /// A job on `data` with `request` and the command's default outputs (`report.json`,
    /// `diagnosed.json`).
    pub fn new(data: PathBuf, request: DiagnoseRequest) -> Self {
        DiagnoseJob { data, request, out: "report.json".into(), result: "diagnosed.json".into(), figures: Figures::default(), scenario_out: None }
    }

    /// Every option checked and resolved (reads no data; reads --robot's URDF).
    pub fn options(&self) -> Result<(DiagnoseOptions, Limit)> {
        self.request.options()
    }

    /// The files this diagnosis reads and writes, checked against each other. `data`: whether
    /// `--data` is read.
    pub fn check_files(&self, data: bool) -> Result<()> {
        let data_files = if data { data_inputs(&self.data) } else { Vec::new() };
        let mut inputs: Vec<(&str, &Path)> = data_files.iter().map(|p| ("--data", p.as_path())).collect();
        let model_file = self.request.model.input();
        if let Some(m) = &model_file {
            inputs.push(("--model", m));
        }
        if let Some(r) = &self.request.loads.robot {
            inputs.push(("--robot", r));
        }
        let outs: Vec<(&str, &Path)> = vec![("--out", &self.out), ("--result", &self.result)];
        check_model_outputs(&inputs, outs, self.figures.rrd.as_deref(), self.figures.report.as_deref(), self.scenario_out.as_deref())
    }

    /// The whole job: checks the files and the options, reads the data, diagnoses (`say` hears
    /// each step's line) and writes every output, together or none.
    pub fn run(&self, say: &(dyn Fn(&str) + Sync), recordings: &dyn Recordings) -> Result<Diagnosed> {
        self.check_files(true)?;
        let planned = self.options()?;
        let data = load_dataset(&self.data, &self.request.reading, true)?;
        let d = diagnose_loaded(&self.request, planned, data, say)?;
        write_diagnosis(self, &d, recordings)?;
        Ok(d)
    }
}

/// The diagnosis a job runs, with its options ([`DiagnoseJob::options`]) on data already
/// loaded; `say` hears each step's line.
pub fn diagnose_loaded(
    request: &DiagnoseRequest,
    (opts, limit): (DiagnoseOptions, Limit),
    original: Dataset,
    say: &(dyn Fn(&str) + Sync),
) -> Result<Diagnosed> {
    let resolve = |setup: &crate::calib::pipeline::CalibOptions| crate::calib::pipeline::resolve_stations(&original, setup);
    let (found, (mut report, mut result), data) = match diagnose_on_stations(request, &opts, &original, resolve(&opts.baseline_options())?, say)? {
        // Change points found before any cause was in the model may be a drift the causes named
        // explain (a warm-up reads as a slow train of moves): searched again with them.
        (found, (report, result), data) if !found.is_empty() && !result.model.effects.is_empty() => {
            let mut with = opts.baseline_options();
            with.effects = result.model.effects.iter().map(|b| (b.kind, b.joint)).collect();
            let again = resolve(&with)?;
            if again.1.len() < found.len() {
                say(&format!(
                    "set-up changes searched again with {} in the model: {} of the {} change points were its drift; the diagnosis again",
                    effects_list(&result.model),
                    found.len() - again.1.len(),
                    found.len()
                ));
                diagnose_on_stations(request, &opts, &original, again, say)?
            } else {
                (found, (report, result), data)
            }
        }
        other => other,
    };
    let (data, test) = data;
    result.setup = crate::calib::pipeline::setup::setup_report(&result.model, &result.x, &data, opts.stations, &found);
    report.setup = result.setup.clone();
    if let Some(test) = &test {
        report.unseen = on_unseen_rows(&opts, &result, &data, test, request.split_by)?;
    }
    let verdict = judge(&[(limit, "heldout_rmse_mm", Some(report.final_heldout_rmse_mm), "cross-validated held-out RMSE of the final model")]);
    Ok(Diagnosed { report, result, verdict, opts, data })
}

/// The labels of a model's effect blocks, joined.
fn effects_list(m: &crate::calib::model::CalibModel) -> String {
    m.effects.iter().map(|b| b.label()).collect::<Vec<_>>().join(", ")
}

/// What [`diagnose_on_stations`] gives: the set-up changes, the diagnosis and its result, the
/// rows it ran on and the rows `--test-fraction` kept back.
type OnStations = (crate::calib::pipeline::setup::Found, (Diagnosis, CalibResult), (Dataset, Option<Dataset>));

/// The diagnosis of `original` on its resolved stations (`resolved`: the relabelled rows, if
/// any, and the set-up changes found), on the training rows of `--test-fraction` where given:
/// the set-up changes, the diagnosis and the rows it ran on.
fn diagnose_on_stations(
    request: &DiagnoseRequest,
    opts: &DiagnoseOptions,
    original: &Dataset,
    (labelled, found): (Option<Dataset>, crate::calib::pipeline::setup::Found),
    say: &(dyn Fn(&str) + Sync),
) -> Result<OnStations> {
    let mut data = labelled.unwrap_or_else(|| original.clone());
    if !found.is_empty() {
        say(&format!(
            "set-up changes: {} change point(s) in the residuals of a first fit; the instrument stood at {} stations",
            found.len(),
            data.stations().len()
        ));
    }
    let mut unseen = None;
    if let Some(f) = request.test_fraction.filter(|f| *f > 0.0) {
        // The rows calibrate --test-fraction f --seed s trains on; the rest are never seen.
        let blocks = crate::dataset::blocks::detect(&data, request.floor.angle_resolution_deg).0;
        let (train, test) = crate::calib::pipeline::split_rows(&data, &blocks, Some(f), request.seed, request.split_by)?;
        let part = |idx: &[usize], what: String| Dataset {
            rows: idx.iter().map(|&i| crate::dataset::Row { split: None, ..data.rows[i].clone() }).collect(),
            source: what,
        };
        unseen = Some(part(&test, format!("{} (the {} test rows of --test-fraction {f})", data.source, test.len())));
        data = part(&train, format!("{} (the {} training rows of --test-fraction {f})", data.source, train.len()));
    }
    let d = crate::diagnose::diagnose(&data, opts, say)?;
    Ok((found, d, (data, unseen)))
}

/// The geometric model (calibrated on the diagnosed rows `data` as the diagnosis' baseline is)
/// and the diagnosed model `result` on the rows `--test-fraction` kept back (`test`, drawn `by`):
/// their RMSE per value there, mm. `None` where the test rows read nothing to predict.
fn on_unseen_rows(
    opts: &DiagnoseOptions,
    result: &CalibResult,
    data: &Dataset,
    test: &Dataset,
    by: crate::calib::pipeline::SplitBy,
) -> Result<Option<crate::diagnose::Unseen>> {
    let m = result.model.measurement;
    if m.is_constant() || test.rows.is_empty() {
        return Ok(None);
    }
    let geometric = crate::calib::pipeline::calibrate(data, None, &opts.baseline_options())?;
    let (geometric_rmse_mm, final_rmse_mm) = (geometric.rmse_on(test), result.rmse_on(test));
    if !(geometric_rmse_mm.is_finite() && final_rmse_mm.is_finite()) {
        return Ok(None);
    }
    Ok(Some(crate::diagnose::Unseen { rows: test.rows.len(), split_by: by, geometric_rmse_mm, final_rmse_mm }))
}

/// Writes what `diagnose` writes of a diagnosis (`--out`, `--result`, and `--rrd`, `--report`,
/// `--scenario-out` when given), all together or none. The caller has checked the files
/// ([`DiagnoseJob::check_files`]).
pub fn write_diagnosis(a: &DiagnoseJob, d: &Diagnosed, recordings: &dyn Recordings) -> Result<()> {
    let (report, result, data) = (&d.report, &d.result, &d.data);
    result.check_writable()?;
    let mut outputs = OutputSet::new();
    let figures = (a.figures.rrd.is_some() || a.figures.report.is_some()).then(|| crate::report::DiagnosisFigures::new(report, result, data));
    if let (Some(p), Some(f)) = (&a.figures.rrd, &figures) {
        recordings.diagnosis(report, f, &mut outputs, p)?;
    }
    if let (Some(p), Some(f)) = (&a.figures.report, &figures) {
        outputs.write(p, crate::report::html::diagnosis_page(report, f, d.verdict.as_ref()).as_bytes())?;
    }
    if let Some(p) = &a.scenario_out {
        stage_identified_twin(&mut outputs, p, result, data, d.opts.model.robot(), "diagnose")?;
    }
    outputs.write_json(&a.out, &with_verdict(report, d.verdict.as_ref())?)?;
    outputs.write_json(&a.result, result)?;
    outputs.commit()
}
