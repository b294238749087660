//! `twincal replay`: the twin driven through a measured acquisition, row by row, and what it
//! reads beside what was measured: the residual field real − twin is what the simulation gets
//! wrong, before any calibration.

use super::files::{data_inputs, load_dataset, scenario_inputs, Recordings};
use crate::dataset::{Dataset, Split};
use crate::error::{Error, Result};
use crate::measurement::Measurement;
use crate::output::{check_outputs, OutputSet};
use crate::progress::Progress;
use crate::requests::Reading;
use crate::sim::scenario::Scenario;
use crate::stats::metrics::ErrorStats;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How a replay judges the twin (the field docs are `twincal replay --help`): its options but
/// `--data`, `--scenario` and the files it writes; Python's `twincal.replay` keyword arguments.
#[derive(Clone, Default, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct ReplayRequest {
    /// How the data are read.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub reading: Reading,
    /// Judge the twin on the rows `calibrate --test-fraction F --seed S` holds out (the rows an
    /// identification with the same flags never saw); default: the data's split column, else
    /// every row.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub test_fraction: Option<f64>,
    /// How --test-fraction draws its rows: blocks, rows or time (as `calibrate --split-by`).
    #[cfg_attr(feature = "clap", arg(long, value_enum, default_value_t = crate::calib::pipeline::SplitBy::default()))]
    pub split_by: crate::calib::pipeline::SplitBy,
    /// Seed of that split.
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true, default_value_t = 0))]
    pub seed: u64,
}

/// A replay as `twincal replay` runs it: the data, the twin, the request and the files it writes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct ReplayJob {
    /// Measured data (dataset folder, CSV or xlsx): q1..qN and the instrument's reading, in
    /// acquisition order; a `t` column stamps the twin's rows with the measured times.
    #[cfg_attr(feature = "clap", arg(long))]
    pub data: PathBuf,
    /// The twin: a scenario (the nominal robot's, or one `calibrate`/`diagnose --scenario-out`
    /// identified). Its instrument must be the data's.
    #[cfg_attr(feature = "clap", arg(long))]
    pub scenario: PathBuf,
    /// The replay's options.
    #[cfg_attr(feature = "clap", command(flatten))]
    pub request: ReplayRequest,
    /// Output folder: replay.csv (per row: measured, twin, twin without noise, residual),
    /// replay.json (the summary) and twin/ (the twin's own dataset.csv and truth.json at the
    /// measured poses, the judged rows marked test: data to run the methods on beside the real
    /// ones).
    #[cfg_attr(feature = "clap", arg(long, default_value = "replay"))]
    pub out: PathBuf,
    /// Rerun recording: the tool points coloured by the twin's noise and by measured − twin,
    /// histograms, the numbers.
    #[cfg_attr(feature = "clap", arg(long))]
    pub rrd: Option<PathBuf>,
    /// Self-contained HTML report: the numbers, measured − twin against the joint angles,
    /// reading, time and temperature beside the twin's own noise.
    #[cfg_attr(feature = "clap", arg(long))]
    pub report: Option<PathBuf>,
}

/// One set of rows' fidelity.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Fidelity {
    /// Measured − the twin's noise-free reading, per value (mm).
    pub residual: ErrorStats,
    /// Position error |Δp| per row of a tracker's point (mm).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub position: Option<ErrorStats>,
    /// Rows with a value beyond the outlier rule (6 robust standard deviations of these
    /// residuals around their median, as calibrate's screen): glitches no twin reproduces
    /// row for row.
    pub outlier_rows: usize,
    /// The residuals of the other rows.
    pub inliers: ErrorStats,
}

/// `replay.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReplaySummary {
    /// The version of twincal that replayed.
    pub twincal_version: String,
    /// The measured data's label (its path).
    pub data: String,
    /// The twin's scenario file.
    pub scenario: String,
    /// The instrument (`length`, `point`, `pose`).
    pub measurement: String,
    /// Rows of the data.
    pub rows: usize,
    /// Rows the twin read.
    pub replayed: usize,
    /// Rows (1-based) the twin could not read, with the reason.
    pub rejected: Vec<(usize, String)>,
    /// What the user should know of the replay (readings beyond the reading polynomial's range).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Which rows `judged` covers.
    pub judged_on: String,
    /// Every replayed row.
    pub all: Fidelity,
    /// The rows judged (held out from an identification), when there is a split.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub judged: Option<Fidelity>,
    /// The twin's own reading noise: its reading − its noise-free reading, RMS per value (mm).
    pub twin_noise_rms_mm: f64,
    /// Two-sample Kolmogorov–Smirnov test of the judged rows' residuals (measured − twin
    /// without noise) against the twin's own noise (its reading − its noise-free reading):
    /// alike when the twin is right and its noise is the data's.
    pub ks_distance: f64,
    /// Its p-value.
    pub ks_p_value: f64,
    /// The real rows and the twin's dataset (`twin/`) calibrated alike (LM, the twin's robot as
    /// the nominal model), judged on the same held-out rows: does the twin's data look like the
    /// real data to a calibration?
    #[serde(skip_serializing_if = "Option::is_none")]
    pub after_calibration: Option<AfterCalibration>,
    /// Wall time of the replay (s).
    pub seconds: f64,
}

/// See [`ReplaySummary::after_calibration`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AfterCalibration {
    /// The method and model both were calibrated with.
    pub model: String,
    /// Held-out residuals after calibration, per value, of the real rows and of the twin's.
    pub real: ErrorStats,
    /// See `real`.
    pub twin: ErrorStats,
    /// Two-sample Kolmogorov–Smirnov test of the two sets of held-out residuals.
    pub ks_distance: f64,
    /// Its p-value.
    pub ks_p_value: f64,
}

/// Calibrates the real rows and the twin's rows alike and compares their held-out residuals;
/// `None` without held-out rows, or when either calibration fails.
fn after_calibration(
    data: &Dataset,
    twin: &Dataset,
    robot: &crate::robot::Robot,
    test_fraction: Option<f64>,
    seed: u64,
    by: crate::calib::pipeline::SplitBy,
) -> Option<AfterCalibration> {
    use crate::calib::pipeline::{calibrate, CalibOptions, Method, ModelSpec, Parametrisation};
    let run = |d: &Dataset, f: Option<f64>, p: Parametrisation| {
        let mut o = CalibOptions::new(ModelSpec::nominal(robot.clone(), p), Method::LM);
        (o.split.test_fraction, o.seed, o.split.by) = (f, seed, by);
        calibrate(d, None, &o).ok()
    };
    let pair = |p: Parametrisation| Some((run(data, test_fraction, p)?, run(twin, None, p)?));
    let (model, (real, tw)) = match pair(Parametrisation::Hayati) {
        Some(r) => (Parametrisation::Hayati.name(), r),
        None => (Parametrisation::Frame.name(), pair(Parametrisation::Frame)?),
    };
    if real.test_residuals_mm.is_empty() || tw.test_residuals_mm.is_empty() {
        return None;
    }
    let (ks_distance, ks_p_value) = crate::stats::ks_two_sample(&real.test_residuals_mm, &tw.test_residuals_mm);
    Some(AfterCalibration {
        model: format!("lm, {} ({model})", robot.name),
        real: ErrorStats::of(&real.test_residuals_mm),
        twin: ErrorStats::of(&tw.test_residuals_mm),
        ks_distance,
        ks_p_value,
    })
}

/// Replays the measured acquisition `a.data` through the twin of `a.scenario`, row by row, and
/// writes replay.csv, replay.json, the twin's dataset and the recording and report asked for,
/// together or none. Returns the summary (replay.json).
pub fn replay(a: &ReplayJob, progress: &dyn Progress, recordings: &dyn Recordings) -> Result<ReplaySummary> {
    let t0 = Instant::now();
    crate::requests::check_test_fraction(a.request.test_fraction)?;
    let split_by = a.request.split_by;
    let (mut s, robot) = Scenario::load(&a.scenario)?;
    let (csv_path, json_path, twin_dir) = replay_outputs(a, &s)?;
    let data = load_dataset(&a.data, &a.request.reading, true)?;
    let m = data.measurement().ok_or_else(|| Error::data(&data.source, "no readings to replay against"))?;
    let twin_m = s.instruments.measurement();
    same_instrument(m, twin_m)?;
    data.require_joints(robot.dof(), &format!("the scenario's robot '{}'", robot.name))?;
    let n = data.rows.len();
    // The twin reads every row (no split of its own), at the measured poses and, where the data
    // have them, the measured times.
    s.sampling.test = 0;
    s.sampling.poses = n;
    let poses: Vec<Vec<f64>> = data.rows.iter().map(|r| r.q_deg.iter().map(|v| v.to_radians()).collect()).collect();
    let times: Option<Vec<f64>> = data.rows.iter().map(|r| r.t_s).collect();
    let mut g = crate::sim::generate::generate_at(&s, &robot, poses.clone(), times.clone(), progress)?;
    // The fidelity is judged at the logged angles, the twin's own dataset at jittered ones.
    let mut jittered_g = jittered_twin(&s, &robot, &poses, times)?;

    let d = m.dim();
    let twin = twin_readings(&g, m, n);
    let rejected: Vec<(usize, String)> = g.truth.rejected.iter().map(|r| (r.index + 1, r.reason.clone())).collect();
    let (judged_idx, judged_on) = judged_rows(&a.request, &data, split_by)?;
    let measured: Vec<Vec<f64>> = data.rows.iter().map(|r| r.values_mm().unwrap_or_default()).collect();
    let residual = |i: usize| residual_of(&twin, &measured, i);
    let fidelity = |rows: &[usize]| fidelity_on(rows, &twin, &measured, d);
    let all_idx: Vec<usize> = (0..n).collect();
    let judged_rows = judged_idx.as_deref().unwrap_or(&all_idx);
    let twin_noise: Vec<f64> = twin.iter().flatten().flat_map(|(read, ideal)| read.iter().zip(ideal).map(|(a, b)| a - b)).collect();
    let judged_res: Vec<f64> = judged_rows.iter().filter_map(|&i| residual(i)).flatten().collect();
    let (ks_distance, ks_p_value) = crate::stats::ks_two_sample(&judged_res, &twin_noise);
    let mut summary = ReplaySummary {
        twincal_version: env!("CARGO_PKG_VERSION").into(),
        data: data.source.clone(),
        scenario: a.scenario.display().to_string(),
        measurement: m.name().into(),
        rows: n,
        warnings: g.warnings(),
        replayed: twin.iter().filter(|t| t.is_some()).count(),
        rejected,
        judged_on,
        all: fidelity(&all_idx),
        judged: judged_idx.as_ref().map(|idx| fidelity(idx)),
        twin_noise_rms_mm: ErrorStats::of(&twin_noise).rmse,
        ks_distance,
        ks_p_value,
        after_calibration: None,
        seconds: 0.0,
    };

    // The judged rows as a set: replay.csv marks them, and they are the twin's test rows.
    let judged_set: Option<std::collections::BTreeSet<usize>> = judged_idx.as_ref().map(|v| v.iter().copied().collect());
    let text = replay_csv(&data, robot.dof(), m, &measured, &twin, judged_set.as_ref());
    let figs = (a.rrd.is_some() || a.report.is_some())
        .then(|| figures(&summary, &Replayed { data: &data, g: &g, twin: &twin, measured: &measured, judged: judged_idx.as_deref() }, &s, m));
    // The twin's dataset: the judged rows are its test rows.
    let twin_data = match jittered_g.as_mut() {
        Some(j) => j,
        None => &mut g,
    };
    if let Some(judged_set) = &judged_set {
        for (row, p) in twin_data.dataset.rows.iter_mut().zip(twin_data.truth.poses.iter_mut()) {
            let split = if judged_set.contains(&p.index) { Split::Test } else { Split::Train };
            (row.split, p.split) = (Some(split), split);
        }
    }
    summary.after_calibration =
        judged_idx.as_ref().and_then(|_| after_calibration(&data, &twin_data.dataset, &robot, a.request.test_fraction, a.request.seed, split_by));
    summary.seconds = t0.elapsed().as_secs_f64();
    let mut outputs = OutputSet::new();
    if let Some(f) = &figs {
        if let Some(p) = &a.rrd {
            recordings.replay(f, &mut outputs, p)?;
        }
        if let Some(p) = &a.report {
            outputs.write(p, crate::report::html::replay_page(f).as_bytes())?;
        }
    }
    crate::sim::generate::stage_outputs(twin_data, &twin_dir, &mut outputs)?;
    outputs.write(&csv_path, text.as_bytes())?;
    outputs.write_json(&json_path, &summary)?;
    outputs.commit()?;
    Ok(summary)
}

/// replay's outputs (replay.csv, replay.json, the twin's folder), checked against its inputs.
fn replay_outputs(a: &ReplayJob, s: &Scenario) -> Result<(PathBuf, PathBuf, PathBuf)> {
    if a.out.exists() && !a.out.is_dir() {
        return Err(Error::Invalid(format!("--out {} is a file; replay writes a folder (replay.csv, replay.json)", a.out.display())));
    }
    let (csv_path, json_path) = (a.out.join("replay.csv"), a.out.join("replay.json"));
    let twin_dir = a.out.join("twin");
    let (twin_csv, twin_truth) = (twin_dir.join(crate::dataset::DATASET_FILE), twin_dir.join(crate::dataset::truth::TRUTH_FILE));
    let mut inputs: Vec<(&str, PathBuf)> = data_inputs(&a.data).iter().map(|p| ("--data", p.clone())).collect();
    inputs.extend(scenario_inputs(Some(&a.scenario), s));
    let mut outs: Vec<(&str, &Path)> =
        vec![("--out", csv_path.as_path()), ("--out", json_path.as_path()), ("--out", twin_csv.as_path()), ("--out", twin_truth.as_path())];
    outs.extend(a.rrd.as_deref().map(|p| ("--rrd", p)));
    outs.extend(a.report.as_deref().map(|p| ("--report", p)));
    check_outputs(&inputs, &outs)?;
    Ok((csv_path, json_path, twin_dir))
}

/// Row `i`'s measured reading less the twin's noise-free one; None where the twin rejected it.
fn residual_of(twin: &[Option<(Vec<f64>, Vec<f64>)>], measured: &[Vec<f64>], i: usize) -> Option<Vec<f64>> {
    twin[i].as_ref().map(|(_, ideal)| measured[i].iter().zip(ideal).map(|(a, b)| a - b).collect())
}

/// How well the twin reproduces `rows`: the residuals' statistics, a point's position error,
/// the rows beyond the outlier rule and the statistics without them.
fn fidelity_on(rows: &[usize], twin: &[Option<(Vec<f64>, Vec<f64>)>], measured: &[Vec<f64>], d: usize) -> Fidelity {
    let r: Vec<Vec<f64>> = rows.iter().filter_map(|&i| residual_of(twin, measured, i)).collect();
    let flat: Vec<f64> = r.iter().flatten().copied().collect();
    let (med, scale) = crate::stats::robust_scale(&flat);
    let k = crate::calib::pipeline::DEFAULT_OUTLIER_K;
    let inlier = |v: &Vec<f64>| v.iter().all(|x| (x - med).abs() <= k * scale);
    Fidelity {
        residual: ErrorStats::of(&flat),
        position: (d > 1).then(|| ErrorStats::of(&r.iter().map(|v| v.iter().take(3).map(|x| x * x).sum::<f64>().sqrt()).collect::<Vec<_>>())),
        outlier_rows: r.iter().filter(|v| !inlier(v)).count(),
        inliers: ErrorStats::of(&r.iter().filter(|v| inlier(v)).flatten().copied().collect::<Vec<_>>()),
    }
}

/// Refuses data read by another instrument than the scenario's twin's.
fn same_instrument(m: Measurement, twin_m: Measurement) -> Result<()> {
    if m != twin_m {
        return Err(Error::Invalid(format!(
            "the data hold a {} ({}), the scenario's twin reads a {} ({}): replay needs the same instrument{}",
            m.def().describe(),
            m.def().file_columns().join(", "),
            twin_m.def().describe(),
            twin_m.def().file_columns().join(", "),
            // A file whose columns include the twin's (a pose's x, y, z) can be read as the twin's.
            if twin_m.def().file_columns().iter().all(|c| m.def().file_columns().contains(c)) {
                format!(" (read the file with --measurement {})", twin_m.name())
            } else {
                String::new()
            }
        )));
    }
    Ok(())
}

/// The twin's own dataset where the scenario logs the angles at a resolution: the twin's arm
/// stands somewhere within the logging step of each measured angle (as the real one did), and
/// its log reads the measured angle. None without a logging resolution.
fn jittered_twin(s: &Scenario, robot: &crate::robot::Robot, poses: &[Vec<f64>], times: Option<Vec<f64>>) -> Result<Option<crate::sim::generate::Generated>> {
    Ok(match s.sampling.logged_decimals {
        Some(dec) => {
            use rand::{Rng, SeedableRng};
            let step = 10f64.powi(-(dec as i32));
            let jittered = poses
                .iter()
                .enumerate()
                .map(|(i, q)| {
                    let mut rng =
                        rand_chacha::ChaCha8Rng::seed_from_u64(crate::sim::scenario::stream_seed(s.seed, crate::sim::scenario::Stream::LoggedAngle, i as u64));
                    q.iter().map(|v| v + (rng.random::<f64>() - 0.5) * step.to_radians()).collect()
                })
                .collect();
            Some(crate::sim::generate::generate_at(s, robot, jittered, times, &crate::sim::generate::Silent)?)
        }
        None => None,
    })
}

/// Per data row: the twin's reading and its noise-free reading (model values, mm); None where
/// the twin rejected the pose.
fn twin_readings(g: &crate::sim::generate::Generated, m: Measurement, n: usize) -> Vec<Option<(Vec<f64>, Vec<f64>)>> {
    let d = m.dim();
    let mut twin: Vec<Option<(Vec<f64>, Vec<f64>)>> = vec![None; n];
    for (row, p) in g.dataset.rows.iter().zip(&g.truth.poses) {
        let ideal = p.noise_free_reading_mm(m).unwrap_or_default();
        if let (Some(read), true) = (row.values_mm(), ideal.len() == d) {
            twin[p.index] = Some((read, ideal));
        }
    }
    twin
}

/// The rows the twin is judged on (None: every row), and how they were chosen.
fn judged_rows(a: &ReplayRequest, data: &Dataset, split_by: crate::calib::pipeline::SplitBy) -> Result<(Option<Vec<usize>>, String)> {
    Ok(match a.test_fraction {
        Some(f) if f <= 0.0 => (None, "every row (--test-fraction 0)".into()),
        Some(f) => {
            let blocks = crate::dataset::blocks::detect(data, None).0;
            let (_, test) = crate::calib::pipeline::split_rows(data, &blocks, Some(f), a.seed, split_by)?;
            (Some(test), format!("the rows --test-fraction {f} --seed {} holds out (as calibrate and diagnose draw them)", a.seed))
        }
        None if data.rows.iter().any(|r| r.split == Some(Split::Test)) => (Some(data.test_indices()), "the data's test rows (split column)".into()),
        None => (None, "every row (no split: pass --test-fraction to judge on rows an identification never saw)".into()),
    })
}

/// replay.csv: the row, its angles and time, whether it is judged, then per value the measured,
/// the twin's, the twin's noise-free reading and measured − noise-free.
fn replay_csv(
    data: &Dataset,
    dof: usize,
    m: Measurement,
    measured: &[Vec<f64>],
    twin: &[Option<(Vec<f64>, Vec<f64>)>],
    judged: Option<&std::collections::BTreeSet<usize>>,
) -> String {
    let d = m.dim();
    let cols = m.def().columns();
    let mut text = String::from("row");
    (1..=dof).for_each(|j| text += &format!(",q{j}"));
    text += ",t,judged";
    for suffix in ["", "_twin", "_twin_ideal", "_residual"] {
        cols.iter().for_each(|c| text += &format!(",{c}{suffix}"));
    }
    text.push('\n');
    for (i, row) in data.rows.iter().enumerate() {
        text += &(i + 1).to_string();
        row.q_deg.iter().for_each(|q| text += &format!(",{q}"));
        text += &format!(",{},{}", row.t_s.map_or(String::new(), |t| t.to_string()), u8::from(judged.is_none_or(|s| s.contains(&i))));
        let blank = |text: &mut String| (0..d).for_each(|_| text.push(','));
        measured[i].iter().for_each(|v| text += &format!(",{v}"));
        match &twin[i] {
            Some((read, ideal)) => {
                let r: Vec<f64> = measured[i].iter().zip(ideal).map(|(a, b)| a - b).collect();
                for v in read.iter().chain(ideal).chain(&r) {
                    text += &format!(",{v}");
                }
            }
            _ => (0..3).for_each(|_| blank(&mut text)),
        }
        text.push('\n');
    }
    text
}

/// The rows of a replay: the measured data, the twin's run over them, each row's twin reading
/// (with its noise-free reading), the measured values and the rows judged.
struct Replayed<'a> {
    data: &'a Dataset,
    g: &'a crate::sim::generate::Generated,
    twin: &'a [Option<(Vec<f64>, Vec<f64>)>],
    measured: &'a [Vec<f64>],
    judged: Option<&'a [usize]>,
}

/// The report's and the recording's figures, over the replayed rows.
fn figures(summary: &ReplaySummary, r: &Replayed, s: &Scenario, m: Measurement) -> crate::report::ReplayFigures {
    let Replayed { data, g, twin, measured, judged } = *r;
    let rows: Vec<usize> = (0..data.rows.len()).filter(|&i| twin[i].is_some()).collect();
    let tool_of: std::collections::BTreeMap<usize, [f64; 3]> = g.truth.poses.iter().map(|p| (p.index, p.tool_mm)).collect();
    let (mut noise, mut residual) = (Vec::new(), Vec::new());
    for &i in &rows {
        let (read, ideal) = twin[i].as_ref().expect("replayed rows");
        noise.extend(read.iter().zip(ideal).map(|(a, b)| a - b));
        residual.extend(measured[i].iter().zip(ideal).map(|(a, b)| a - b));
    }
    let kept = data.subset(&rows);
    let placement = crate::sim::instrument::placement(&s.draw_wire, &s.instruments);
    let line = |f: &Fidelity| Some(f.residual);
    let mut stats = vec![("every row: measured − twin".to_string(), line(&summary.all)), ("every row, no outliers".to_string(), Some(summary.all.inliers))];
    if let Some(j) = &summary.judged {
        stats.push(("judged rows: measured − twin".into(), line(j)));
        stats.push(("judged rows, no outliers".into(), Some(j.inliers)));
    }
    crate::report::ReplayFigures {
        title: format!("Replay of {} through {}", summary.data, summary.scenario),
        measurement: m,
        judged_on: format!("Judged on {}; {} of {} rows replayed.", summary.judged_on, summary.replayed, summary.rows),
        stats,
        ks_line: format!(
            "The twin's own noise: {:.4} mm RMS. Judged residuals against it: Kolmogorov–Smirnov D {:.3}, p {:.2e}.",
            summary.twin_noise_rms_mm, summary.ks_distance, summary.ks_p_value
        ),
        judged: rows.iter().map(|i| judged.is_none_or(|j| j.contains(i))).collect(),
        noise_mm: noise,
        residual_mm: residual,
        tools_mm: rows.iter().map(|i| tool_of.get(i).copied().unwrap_or([0.0; 3])).collect(),
        instrument: crate::report::InstrumentPose::of(&placement),
        features: crate::report::features(&kept),
    }
}
