//! A comparison of methods over seeds (`twincal compare`): accuracy and time tables with
//! Wilcoxon tests, in one process or sharded across several (joined by [`reduce_compare`]).

use super::files::{data_inputs, load_dataset, Recordings};
use super::shard::{self, Parts};
use crate::calib::pipeline::Method;
use crate::dataset::Dataset;
use crate::error::{Error, Result};
use crate::output::{check_outputs, OutputSet};
use crate::progress::Progress;
use crate::requests::{ModelChoice, Reading};
use crate::stats::metrics::ErrorStats;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Most seeds `compare` (and `bench calib`) accept.
pub const MAX_SEEDS: u64 = 1000;
/// The methods `compare` runs when none are named: the classical ones.
pub const DEFAULT_METHODS: [Method; 5] = [Method::LM, Method::EKF, Method::PF, Method::PSO, Method::RBF];

/// Most calibrations (methods × seeds) one `compare` runs.
pub const MAX_COMPARE_JOBS: u64 = 5000;

/// `--seeds`, checked: between 1 and [`MAX_SEEDS`].
pub fn check_seeds(seeds: u64) -> Result<()> {
    if !(1..=MAX_SEEDS).contains(&seeds) {
        return Err(Error::Invalid(format!("--seeds must be between 1 and {MAX_SEEDS}, got {seeds}")));
    }
    Ok(())
}

/// One calibration run inside `compare`.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct CompareRun {
    /// The method's name.
    pub method: String,
    /// The seed of the split and of a stochastic method.
    pub seed: u64,
    /// Training residuals after calibration (mm).
    pub train: ErrorStats,
    /// Test residuals after calibration (mm).
    pub test: ErrorStats,
    /// The optimiser's iterations.
    pub iterations: usize,
    /// Wall time of the calibration (s).
    pub seconds: f64,
    /// For a reading of several values (a tracker's point): the test rows' position error |Δp|
    /// (its `mae` is the mean absolute position error).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_position: Option<ErrorStats>,
    /// What the calibration warned of (a method ending worse than its start, few rows, ...).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// |test residual| of every test value (mm), for the per-sample test; not written.
    #[serde(skip)]
    pub test_abs_residuals: Vec<f64>,
}

/// What a compare is over: every shard of one study holds the same (its hash ties them).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CompareConfig {
    /// The data's label (its path).
    pub data: String,
    /// SHA-256 of the data file's bytes.
    pub data_sha256: String,
    /// Rows of the data.
    pub rows: usize,
    /// The methods compared, in order.
    pub methods: Vec<String>,
    /// Seeds per method.
    pub seeds: u64,
    /// Fraction held out by each seed's split.
    pub test_fraction: f64,
    /// Effort of the stochastic methods.
    pub effort: f64,
    /// The model fitted (`--model` and `--params`).
    pub model: String,
    /// SHA-256 of the model's URDF, when it is a file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_sha256: Option<String>,
    /// How the data were read: the angle unit, the instrument and a pose's Euler convention.
    pub reading: String,
    /// The version of twincal that ran it.
    pub twincal_version: String,
}

impl CompareConfig {
    /// SHA-256 of the configuration's JSON, hex; the data's path is left out (its SHA-256 is
    /// in), so shards that reach the same file by other paths agree.
    pub fn hash(&self) -> String {
        let keyed = CompareConfig { data: String::new(), ..self.clone() };
        crate::dataset::truth::sha256_hex(serde_json::to_string(&keyed).unwrap_or_default().as_bytes())
    }
    /// Work items in their fixed order: item `id` is seed `id / methods` with method `id % methods`.
    pub fn items(&self) -> u64 {
        self.seeds * self.methods.len() as u64
    }
}

/// What one finished work item of a sharded compare records (beside the study's
/// configuration, see [`shard::Line`]).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct CompareItem {
    /// The run.
    pub run: CompareRun,
    /// |test residual| of the run, kept for seed 0 (the per-sample Wilcoxon test).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub test_abs_residuals: Vec<f64>,
}

impl shard::Config for CompareConfig {
    const KIND: &'static str = "compare";
    fn hash(&self) -> String {
        CompareConfig::hash(self)
    }
    fn items(&self) -> u64 {
        CompareConfig::items(self)
    }
}

/// What a comparison runs (the field docs are `twincal compare --help`): its options but
/// `--data` and the files it writes; Python's `twincal.compare` keyword arguments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
#[serde(default)]
pub struct CompareRequest {
    /// How the data are read.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub reading: Reading,
    /// The methods compared (comma-separated, any case).
    #[cfg_attr(
        feature = "clap",
        arg(long, value_enum, value_delimiter = ',', default_values_t = DEFAULT_METHODS, ignore_case = true)
    )]
    pub methods: Vec<Method>,
    /// Number of seeds (1 to 1000).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 30, allow_negative_numbers = true))]
    pub seeds: u64,
    /// The model fitted.
    #[cfg_attr(feature = "clap", command(flatten))]
    #[serde(flatten)]
    pub model: ModelChoice,
    /// Test fraction of each seed's re-split, in (0, 1) (default: the dataset's split size, else 0.2).
    #[cfg_attr(feature = "clap", arg(long, allow_negative_numbers = true))]
    pub test_fraction: Option<f64>,
    /// Effort of the stochastic methods (1 = full budget).
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 1.0, allow_negative_numbers = true))]
    pub effort: f64,
}

impl Default for CompareRequest {
    fn default() -> Self {
        CompareRequest {
            reading: Reading::default(),
            methods: DEFAULT_METHODS.to_vec(),
            seeds: 30,
            model: ModelChoice::default(),
            test_fraction: None,
            effort: 1.0,
        }
    }
}

/// A comparison as `twincal compare` runs it: the data, the request and the files it writes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct CompareJob {
    /// Dataset folder, CSV or xlsx.
    #[cfg_attr(feature = "clap", arg(long))]
    pub data: PathBuf,
    /// The comparison's options.
    #[cfg_attr(feature = "clap", command(flatten))]
    pub request: CompareRequest,
    /// Also write the tables as JSON.
    #[cfg_attr(feature = "clap", arg(long))]
    pub out: Option<PathBuf>,
    /// Rerun recording of the accuracy table and the per-seed spread of each method.
    #[cfg_attr(feature = "clap", arg(long))]
    pub rrd: Option<PathBuf>,
    /// Run only work items with id % N == i (items: seed × method, id = seed · methods +
    /// method, in a fixed order), appending each to --shard-out as it finishes; `twincal reduce`
    /// joins the parts. Re-running a shard skips the items its file holds.
    #[cfg_attr(feature = "clap", arg(long, value_name = "i/N", allow_hyphen_values = true))]
    pub shard: Option<String>,
    /// The shard's partial file (JSONL; needed with --shard).
    #[cfg_attr(feature = "clap", arg(long))]
    pub shard_out: Option<PathBuf>,
}

/// What a comparison found: the tables (Markdown, what `compare` prints), each calibration's
/// warnings, once per method and wording, and its outputs (`out`, `rrd`) staged: they appear
/// when the caller commits them (after showing the table, so that a failure to show it leaves
/// no file behind), and not at all when it drops them.
pub struct Comparison {
    /// The accuracy and time table and the Wilcoxon tests, Markdown.
    pub table: String,
    /// `METHOD (seed S, ...): WARNING` lines.
    pub warnings: Vec<String>,
    /// The staged outputs: `outputs.commit()` writes them.
    pub outputs: OutputSet,
}

/// What [`compare`] did: the whole comparison, or one shard's part.
pub enum Compared {
    /// Every item ran here: the tables (and `--out`, `--rrd` staged).
    Done(Comparison),
    /// A shard ran its items and appended them to its partial file: the line it reports.
    Shard(String),
}

/// Fewest seeds for the across-seeds Wilcoxon test: with 5 or fewer, the smallest two-sided
/// exact p-value is 2/2⁵ = 0.0625.
pub const MIN_SEEDS_FOR_TEST: usize = 6;

/// `twincal compare`: every method on every seed (a fresh stratified split per seed), then the
/// accuracy / time table and Wilcoxon signed-rank tests of each method against the first one,
/// across seeds (test RMSE) and per sample (|test residual| of seed 0).
pub fn compare(a: &CompareJob, bar: &dyn Progress, recordings: &dyn Recordings) -> Result<Compared> {
    use crate::calib::pipeline::{calibrate as run, CalibOptions};
    use rayon::prelude::*;
    let r = &a.request;
    let (seeds, test_fraction, effort) = (r.seeds, r.test_fraction, r.effort);
    let methods = check_compare_request(r)?;
    let data_files = data_inputs(&a.data);
    let outs: Vec<(&str, &Path)> = a.out.as_deref().map(|p| ("--out", p)).into_iter().chain(a.rrd.as_deref().map(|p| ("--rrd", p))).collect();
    if !outs.is_empty() {
        let mut inputs: Vec<(&str, &Path)> = data_files.iter().map(|p| ("--data", p.as_path())).collect();
        let model_file = r.model.input();
        inputs.extend(model_file.as_deref().map(|m| ("--model", m)));
        check_outputs(&inputs, &outs)?;
    }
    let spec = r.model.spec()?;
    let ds = load_dataset(&a.data, &r.reading, true)?;
    let n = ds.rows.len();
    let frac = test_fraction.unwrap_or_else(|| {
        let t = ds.test_indices().len();
        if t > 0 && t < n {
            t as f64 / n as f64
        } else {
            0.2
        }
    });
    if (frac * n as f64).round() < 1.0 || (frac * n as f64).round() as usize >= n {
        return Err(Error::Invalid(format!("test fraction {frac} of {n} rows leaves no test rows or no training rows")));
    }
    let config = compare_config(r, &ds, &data_files[0], &methods, frac)?;
    // Work items in their fixed order; a shard runs its own and skips those its file holds.
    let inputs: Vec<(&str, &Path)> = data_files.iter().map(|p| ("--data", p.as_path())).collect();
    let shard = shard::from_options(a.shard.as_deref(), a.shard_out.as_deref(), a.out.is_some() || a.rrd.is_some(), "--out and --rrd", &config, &inputs)?;
    let jobs: Vec<(u64, u64, Method)> = (0..seeds)
        .flat_map(|s| {
            let k_methods = methods.len() as u64;
            methods.iter().enumerate().map(move |(k, m)| (s * k_methods + k as u64, s, *m)).collect::<Vec<_>>()
        })
        .filter(|(id, _, _)| shard.as_ref().is_none_or(|sh| sh.wants(*id)))
        .collect();
    bar.start(jobs.len() as u64, "calibrations");
    let runs: Vec<Result<CompareRun>> = jobs
        .par_iter()
        .map(|(id, seed, m)| {
            let mut o = CalibOptions::new(spec.clone(), *m);
            o.split.test_fraction = Some(frac);
            o.seed = *seed;
            o.effort = effort;
            let r = run(&ds, None, &o)?;
            // The residuals the calibration scored (with each row's inputs: temperature, flanks,
            // torques; and reading steps), not a re-prediction from the angles alone.
            let test_abs_residuals: Vec<f64> = r.test_residuals_mm.iter().map(|v| v.abs()).collect();
            bar.inc(1);
            let run = CompareRun {
                method: m.name().into(),
                seed: *seed,
                train: r.evaluation.metrics.train_after,
                test: r.evaluation.metrics.test_after.unwrap_or_default(),
                iterations: r.solve.iterations,
                seconds: r.provenance.wall_time_s,
                test_position: r.evaluation.metrics.test_position_after,
                warnings: r.warnings,
                test_abs_residuals,
            };
            // A shard appends each finished item at once, a whole line (a killed run loses only
            // the items it was running).
            if let Some(sh) = &shard {
                let item = CompareItem { test_abs_residuals: if *seed == 0 { run.test_abs_residuals.clone() } else { Vec::new() }, run: run.clone() };
                sh.append(*id, &config, &item)?;
            }
            Ok(run)
        })
        .collect();
    bar.finish();
    let runs: Vec<CompareRun> = runs.into_iter().collect::<Result<_>>()?;
    if let Some(sh) = &shard {
        return Ok(Compared::Shard(sh.summary(runs.len())));
    }
    finish(&config, &runs, a.out.as_deref(), a.rrd.as_deref(), recordings).map(Compared::Done)
}

/// The table, the warnings and the outputs (staged) of a finished comparison (every item's run,
/// in item order): what `compare` prints and writes, and `reduce` the same from the shards' parts.
pub fn finish(config: &CompareConfig, runs: &[CompareRun], out: Option<&Path>, rrd: Option<&Path>, recordings: &dyn Recordings) -> Result<Comparison> {
    use crate::stats::wilcoxon_signed_rank;
    let methods: Vec<Method> = config.methods.iter().map(|m| Method::parse(m)).collect::<Result<_>>()?;
    let (seeds, frac, n) = (config.seeds, config.test_fraction, config.rows);
    let by = |m: &str| runs.iter().filter(|r| r.method == m).cloned().collect::<Vec<_>>();
    let mut table = String::new();
    table.push_str(&format!("# Method comparison on {} ({} rows, {seeds} seeds, test fraction {frac:.2})\n\n", config.data, n));

    table.push_str(&accuracy_table(&methods, runs));
    let mut tests = Vec::new();
    let reference = methods[0].name();
    let ref_runs = by(reference);
    table.push_str(&format!("\n## Wilcoxon signed-rank tests against `{reference}` (two-sided)\n\n| method | across seeds: W | p | per sample (seed 0): W | p |\n|---|---|---|---|---|\n"));
    for m in methods.iter().skip(1) {
        let r = by(m.name());
        let a: Vec<f64> = ref_runs.iter().map(|x| x.test.rmse).collect();
        let b: Vec<f64> = r.iter().map(|x| x.test.rmse).collect();
        // With fewer seeds no difference can reach p < 0.05 (two-sided): no test is printed.
        let across = if a.len() >= MIN_SEEDS_FOR_TEST { wilcoxon_signed_rank(&a, &b).ok() } else { None };
        let per = wilcoxon_signed_rank(&ref_runs[0].test_abs_residuals, &r[0].test_abs_residuals).ok();
        let cell = |w: &Option<crate::stats::Wilcoxon>| match w {
            Some(w) => (format!("{:.1}", w.statistic.abs()), format!("{:.3e}", w.p_value)),
            None => ("–".into(), "–".into()),
        };
        let (wa, pa) = cell(&across);
        let (wp, pp) = cell(&per);
        table.push_str(&format!("| {} | {wa} | {pa} | {wp} | {pp} |\n", m.name()));
        tests.push(serde_json::json!({"method": m.name(), "against": reference, "across_seeds": across.map(|w| serde_json::json!({"statistic": w.statistic, "p_value": w.p_value, "n": w.n})), "per_sample": per.map(|w| serde_json::json!({"statistic": w.statistic, "p_value": w.p_value, "n": w.n}))}));
    }
    if (seeds as usize) < MIN_SEEDS_FOR_TEST && methods.len() > 1 {
        table.push_str(&format!(
            "\nAcross seeds: not tested; with {seeds} seed(s) no difference can reach p < 0.05 (two-sided Wilcoxon needs at least {MIN_SEEDS_FOR_TEST}).\n"
        ));
    }
    let mut outputs = OutputSet::new();
    if let Some(p) = rrd {
        let names: Vec<String> = methods.iter().map(|m| m.name().to_string()).collect();
        recordings.comparison(&table, &names, runs, &mut outputs, p)?;
    }
    if let Some(p) = out {
        outputs.write_json(p, &serde_json::json!({"data": config.data, "seeds": seeds, "test_fraction": frac, "runs": runs, "wilcoxon": tests}))?;
    }
    Ok(Comparison { table, warnings: run_warnings(runs), outputs })
}

/// The methods `compare` runs, after checking its options: methods given once each, the
/// seeds, the number of calibrations, the test fraction and the effort.
fn check_compare_request(a: &CompareRequest) -> Result<Vec<Method>> {
    let (seeds, test_fraction, effort) = (a.seeds, a.test_fraction, a.effort);
    let methods = a.methods.clone();
    if methods.is_empty() {
        return Err(Error::Invalid("--methods is empty: compare needs at least one method".into()));
    }
    if let Some(m) = methods.iter().enumerate().find_map(|(i, m)| methods[..i].contains(m).then_some(m)) {
        return Err(Error::Invalid(format!("--methods lists {} twice", m.name())));
    }
    check_seeds(seeds)?;
    let jobs_count = seeds * methods.len() as u64;
    if jobs_count > MAX_COMPARE_JOBS {
        return Err(Error::Invalid(format!(
            "{} methods x {seeds} seeds = {jobs_count} calibrations, more than compare runs at once ({MAX_COMPARE_JOBS})",
            methods.len()
        )));
    }
    crate::requests::check_test_fraction(test_fraction)?;
    if test_fraction == Some(0.0) {
        return Err(Error::Invalid("--test-fraction 0 holds no row out, and compare scores every seed on held-out rows".into()));
    }
    crate::requests::check_effort(effort)?;
    Ok(methods)
}

/// What a comparison is of: its data (and the file's hash), methods, seeds, split, effort, model
/// and reading options; the shards of one comparison share it.
fn compare_config(a: &CompareRequest, ds: &Dataset, file: &Path, methods: &[Method], frac: f64) -> Result<CompareConfig> {
    let n = ds.rows.len();
    let (seeds, effort) = (a.seeds, a.effort);
    Ok(CompareConfig {
        data: ds.source.clone(),
        data_sha256: crate::dataset::truth::file_sha256(file)?,
        rows: n,
        methods: methods.iter().map(|m| m.name().to_string()).collect(),
        seeds,
        test_fraction: frac,
        effort,
        model: format!("{} {}", a.model.model, a.model.params.map_or("", |p| p.name())).trim().to_string(),
        model_sha256: match a.model.input() {
            Some(m) => Some(crate::dataset::truth::file_sha256(&m)?),
            None => None,
        },
        reading: format!("angles {}, measurement {}, euler {}", a.reading.angles.name(), ds.measurement().map_or("none", |m| m.name()), a.reading.euler),
        twincal_version: env!("CARGO_PKG_VERSION").into(),
    })
}

/// The accuracy and time table (mean ± std over seeds), and a tracker's position errors.
fn accuracy_table(methods: &[Method], runs: &[CompareRun]) -> String {
    use crate::stats::mean_std;
    let by = |m: &str| runs.iter().filter(|r| r.method == m).cloned().collect::<Vec<_>>();
    let mut table = String::new();
    table.push_str(
        "| method | train RMSE | train STD | train MAX | test RMSE | test STD | test MAX | iterations | seconds |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    // One seed has no spread to show.
    let ms = |v: Vec<f64>| {
        let (m, s) = mean_std(&v);
        if v.len() > 1 {
            format!("{m:.4} ± {s:.4}")
        } else {
            format!("{m:.4}")
        }
    };
    for m in methods {
        let r = by(m.name());
        table.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            m.name(),
            ms(r.iter().map(|x| x.train.rmse).collect()),
            ms(r.iter().map(|x| x.train.std).collect()),
            ms(r.iter().map(|x| x.train.max).collect()),
            ms(r.iter().map(|x| x.test.rmse).collect()),
            ms(r.iter().map(|x| x.test.std).collect()),
            ms(r.iter().map(|x| x.test.max).collect()),
            ms(r.iter().map(|x| x.iterations as f64).collect()),
            ms(r.iter().map(|x| x.seconds).collect()),
        ));
    }
    // A tracker's points: the test rows' position error |Δp| too (mean, as papers quote it).
    let points = runs.iter().any(|r| r.test_position.is_some());
    if points {
        table.push_str("\nResiduals are per coordinate; the test rows' position error |Δp| (mm):\n\n| method | mean | RMS | MAX |\n|---|---|---|---|\n");
        for m in methods {
            let r = by(m.name());
            let p = |f: fn(&ErrorStats) -> f64| ms(r.iter().filter_map(|x| x.test_position.as_ref().map(f)).collect());
            table.push_str(&format!("| {} | {} | {} | {} |\n", m.name(), p(|e| e.mae), p(|e| e.rmse), p(|e| e.max)));
        }
    }
    table
}

/// Each calibration's warnings, once per method and wording (seeds listed).
fn run_warnings(runs: &[CompareRun]) -> Vec<String> {
    let mut warned: Vec<(String, String, Vec<u64>)> = Vec::new();
    for r in runs {
        for w in &r.warnings {
            match warned.iter_mut().find(|(m, t, _)| *m == r.method && t == w) {
                Some((_, _, seeds)) => seeds.push(r.seed),
                None => warned.push((r.method.clone(), w.clone(), vec![r.seed])),
            }
        }
    }
    warned
        .iter()
        .map(|(m, w, seeds)| {
            let seeds: Vec<String> = seeds.iter().map(u64::to_string).collect();
            format!("{m} (seed {}): {w}", seeds.join(", "))
        })
        .collect()
}

/// The shards' partial files of one comparison (read as [`Parts`] of kind `compare`) joined,
/// checked (one configuration; every item exactly once once retries' duplicates are dropped)
/// and rendered as the single-process [`compare`] renders them: the same table, `out` and
/// `rrd`. Also the number of items and of duplicates dropped, and the configuration's hash.
pub fn reduce_compare(read: Parts, out: Option<&Path>, rrd: Option<&Path>, recordings: &dyn Recordings) -> Result<(Comparison, usize, usize, String)> {
    if read.kind() != "compare" {
        return Err(Error::Invalid(format!("the parts are of a '{}' study, not a comparison", read.kind())));
    }
    let (mut config, items, duplicates) = read.gather::<CompareConfig, CompareItem>()?;
    let mut runs: Vec<CompareRun> = items.into_iter().map(|l| CompareRun { test_abs_residuals: l.test_abs_residuals, ..l.run }).collect();
    check_runs(&config, &runs)?;
    // What is printed of the parts' text shows its control characters, never acts on them.
    config.data = printable(&config.data);
    runs.iter_mut().for_each(|r| r.warnings.iter_mut().for_each(|w| *w = printable(w)));
    let hash = config.hash();
    let c = finish(&config, &runs, out, rrd, recordings)?;
    Ok((c, runs.len(), duplicates, hash))
}

/// Every run of a comparison read from parts is one a calibration can have given: the methods
/// the configuration lists, finite non-negative errors and times, and per-sample residuals of
/// seed 0 as many for every method (the test rows of one split). A part edited by hand is
/// refused with the item named.
/// What is wrong with one run's numbers (a negative or non-finite statistic, time or residual),
/// whatever its study.
fn run_numbers(r: &CompareRun) -> std::result::Result<(), String> {
    let stats_ok = |s: &ErrorStats| [s.rmse, s.std, s.max, s.mae].iter().all(|v| v.is_finite() && *v >= 0.0) && s.max >= s.mae;
    if !stats_ok(&r.train) || !stats_ok(&r.test) || r.test_position.as_ref().is_some_and(|p| !stats_ok(p)) {
        return Err("an error statistic that is negative, not finite, or a MAX below the mean".into());
    }
    if !(r.seconds.is_finite() && r.seconds >= 0.0) {
        return Err(format!("a time of {} s", r.seconds));
    }
    if r.test_abs_residuals.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
        return Err("a |test residual| that is negative or not finite".into());
    }
    Ok(())
}

impl shard::Item for CompareItem {
    fn check(&self) -> std::result::Result<(), String> {
        run_numbers(&self.run)?;
        match self.test_abs_residuals.iter().all(|v| v.is_finite() && *v >= 0.0) {
            true => Ok(()),
            false => Err("a |test residual| that is negative or not finite".into()),
        }
    }
}

fn check_runs(config: &CompareConfig, runs: &[CompareRun]) -> Result<()> {
    let bad = |r: &CompareRun, what: &str| Error::Invalid(format!("{} seed {}: {what} (a hand-edited part?)", printable(&r.method), r.seed));
    let mut seed0_len: Option<usize> = None;
    for r in runs {
        if !config.methods.contains(&r.method) {
            return Err(bad(r, "a method the comparison does not list"));
        }
        run_numbers(r).map_err(|why| bad(r, &why))?;
        if r.seed == 0 {
            match seed0_len {
                Some(n) if n != r.test_abs_residuals.len() => {
                    return Err(bad(r, &format!("{} per-sample test residuals where the other methods have {n}", r.test_abs_residuals.len())))
                }
                _ => seed0_len = Some(r.test_abs_residuals.len()),
            }
        }
    }
    Ok(())
}

/// `s` with its control characters (terminal escapes, line breaks) written as `\u{..}`.
fn printable(s: &str) -> String {
    s.chars().map(|c| if c.is_control() { format!("\\u{{{:x}}}", c as u32) } else { c.to_string() }).collect()
}
