//! `twincal compare`: methods over seeds, accuracy and time tables with Wilcoxon tests.

use super::*;

/// One calibration run inside `compare`.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct CompareRun {
    pub method: String,
    pub seed: u64,
    pub train: twincal::stats::metrics::ErrorStats,
    pub test: twincal::stats::metrics::ErrorStats,
    pub iterations: usize,
    pub seconds: f64,
    /// For a reading of several values (a tracker's point): the test rows' position error |Δp|
    /// (its `mae` is the mean absolute position error).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_position: Option<twincal::stats::metrics::ErrorStats>,
    /// What the calibration warned of (a method ending worse than its start, few rows, ...).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    #[serde(skip)]
    pub test_abs_residuals: Vec<f64>,
}

/// What a compare is over: every shard of one study holds the same (its hash ties them).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CompareConfig {
    pub data: String,
    /// SHA-256 of the data file's bytes.
    pub data_sha256: String,
    pub rows: usize,
    pub methods: Vec<String>,
    pub seeds: u64,
    pub test_fraction: f64,
    pub effort: f64,
    pub model: String,
    /// SHA-256 of the model's URDF, when it is a file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_sha256: Option<String>,
    /// How the data were read: the angle unit, the instrument and a pose's Euler convention.
    pub reading: String,
    pub twincal_version: String,
}

impl CompareConfig {
    /// SHA-256 of the configuration's JSON, hex; the data's path is left out (its SHA-256 is
    /// in), so shards that reach the same file by other paths agree.
    pub fn hash(&self) -> String {
        let keyed = CompareConfig { data: String::new(), ..self.clone() };
        twincal::dataset::truth::sha256_hex(serde_json::to_string(&keyed).unwrap_or_default().as_bytes())
    }
    /// Work items in their fixed order: item `id` is seed `id / methods` with method `id % methods`.
    pub fn items(&self) -> u64 {
        self.seeds * self.methods.len() as u64
    }
}

/// What one finished work item of a sharded compare records (beside the study's
/// configuration, see [`crate::shard::Line`]).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct CompareItem {
    pub run: CompareRun,
    /// |test residual| of the run, kept for seed 0 (the per-sample Wilcoxon test).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub test_abs_residuals: Vec<f64>,
}

impl crate::shard::Config for CompareConfig {
    const KIND: &'static str = "compare";
    fn hash(&self) -> String {
        CompareConfig::hash(self)
    }
    fn items(&self) -> u64 {
        CompareConfig::items(self)
    }
}

/// Arguments of `twincal compare` (the field docs are its `--help`).
#[derive(Clone, Debug, clap::Args)]
pub struct CompareArgs {
    #[arg(long)]
    pub data: PathBuf,
    #[command(flatten)]
    pub reading: Reading,
    /// The methods compared (comma-separated, any case).
    #[arg(long, value_delimiter = ',', default_value = "lm,ekf,pf,pso,rbf", ignore_case = true, value_parser = twincal::requests::method_values())]
    pub methods: Vec<String>,
    /// Number of seeds (1 to 1000).
    #[arg(long, default_value_t = 30, allow_negative_numbers = true)]
    pub seeds: u64,
    #[command(flatten)]
    pub model: ModelChoice,
    /// Test fraction of each seed's re-split, in (0, 1) (default: the dataset's split size, else 0.2).
    #[arg(long, allow_negative_numbers = true)]
    pub test_fraction: Option<f64>,
    /// Effort of the stochastic methods (1 = full budget).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub effort: f64,
    /// Also write the tables as JSON.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Rerun recording of the accuracy table and the per-seed spread of each method.
    #[arg(long)]
    pub rrd: Option<PathBuf>,
    /// Run only work items with id % N == i (items: seed × method, id = seed · methods +
    /// method, in a fixed order), appending each to --shard-out as it finishes; `twincal reduce`
    /// joins the parts. Re-running a shard skips the items its file holds.
    #[arg(long, value_name = "i/N", allow_hyphen_values = true)]
    pub shard: Option<String>,
    /// The shard's partial file (JSONL; needed with --shard).
    #[arg(long)]
    pub shard_out: Option<PathBuf>,
}

/// Fewest seeds for the across-seeds Wilcoxon test: with 5 or fewer, the smallest two-sided
/// exact p-value is 2/2⁵ = 0.0625.
pub const MIN_SEEDS_FOR_TEST: usize = 6;

/// `twincal compare`: every method on every seed (a fresh stratified split per seed), then the
/// accuracy / time table and Wilcoxon signed-rank tests of each method against the first one,
/// across seeds (test RMSE) and per sample (|test residual| of seed 0).
pub fn compare(a: &CompareArgs, quiet: bool) -> Result<()> {
    use rayon::prelude::*;
    use twincal::calib::run::{calibrate as run, CalibOptions, Method};
    let (seeds, test_fraction, effort) = (a.seeds, a.test_fraction, a.effort);
    let methods = check_compare_args(a)?;
    let data_files = data_inputs(&a.data);
    let outs: Vec<(&str, &Path)> = a.out.as_deref().map(|p| ("--out", p)).into_iter().chain(a.rrd.as_deref().map(|p| ("--rrd", p))).collect();
    if !outs.is_empty() {
        let mut inputs: Vec<(&str, &Path)> = data_files.iter().map(|p| ("--data", p.as_path())).collect();
        let model_file = a.model.input();
        inputs.extend(model_file.as_deref().map(|m| ("--model", m)));
        check_outputs(&inputs, &outs)?;
    }
    let spec = a.model.spec()?;
    let ds = load_dataset(&a.data, &a.reading, true)?;
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
    let config = compare_config(a, &ds, &data_files[0], &methods, frac)?;
    // Work items in their fixed order; a shard runs its own and skips those its file holds.
    let inputs: Vec<(&str, &Path)> = data_files.iter().map(|p| ("--data", p.as_path())).collect();
    let shard =
        crate::shard::from_options(a.shard.as_deref(), a.shard_out.as_deref(), a.out.is_some() || a.rrd.is_some(), "--out and --rrd", &config, &inputs)?;
    let jobs: Vec<(u64, u64, Method)> = (0..seeds)
        .flat_map(|s| {
            let k_methods = methods.len() as u64;
            methods.iter().enumerate().map(move |(k, m)| (s * k_methods + k as u64, s, *m)).collect::<Vec<_>>()
        })
        .filter(|(id, _, _)| shard.as_ref().is_none_or(|sh| sh.wants(*id)))
        .collect();
    let bar = progress(quiet);
    bar.start(jobs.len() as u64, "calibrations");
    let runs: Vec<Result<CompareRun>> = jobs
        .par_iter()
        .map(|(id, seed, m)| {
            let mut o = CalibOptions::new(spec.clone(), *m);
            o.test_fraction = Some(frac);
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
                train: r.metrics.train_after,
                test: r.metrics.test_after.unwrap_or_default(),
                iterations: r.iterations,
                seconds: r.wall_time_s,
                test_position: r.metrics.test_position_after,
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
        if !quiet {
            eprintln!("{}", sh.summary(runs.len()));
        }
        return Ok(());
    }
    finish(&config, &runs, a.out.as_deref(), a.rrd.as_deref())
}

/// The table, the warnings and the outputs of a finished comparison (every item's run, in item
/// order): what `compare` prints and writes, and `reduce` the same from the shards' parts.
pub fn finish(config: &CompareConfig, runs: &[CompareRun], out: Option<&Path>, rrd: Option<&Path>) -> Result<()> {
    use twincal::calib::run::Method;
    use twincal::stats::wilcoxon_signed_rank;
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
        let cell = |w: &Option<twincal::stats::Wilcoxon>| match w {
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
    println!("{table}");
    print_run_warnings(runs);
    let mut outputs = OutputSet::new();
    if let Some(p) = rrd {
        let names: Vec<String> = methods.iter().map(|m| m.name().to_string()).collect();
        let rows: Vec<crate::viz::results::CompareRow> = runs
            .iter()
            .map(|r| crate::viz::results::CompareRow { method: &r.method, seed: r.seed, test_rmse_mm: r.test.rmse, test_max_mm: r.test.max })
            .collect();
        crate::viz::results::record_comparison(&table, &names, &rows, &mut outputs, p)?;
    }
    if let Some(p) = out {
        outputs.write_json(p, &serde_json::json!({"data": config.data, "seeds": seeds, "test_fraction": frac, "runs": runs, "wilcoxon": tests}))?;
    }
    outputs.commit()?;
    Ok(())
}

/// The methods `compare` runs, after checking its options: methods given once each, the
/// seeds, the number of calibrations, the test fraction and the effort.
fn check_compare_args(a: &CompareArgs) -> Result<Vec<twincal::calib::run::Method>> {
    use twincal::calib::run::Method;
    let (seeds, test_fraction, effort) = (a.seeds, a.test_fraction, a.effort);
    let methods: Vec<Method> = a.methods.iter().map(|m| Method::parse(m)).collect::<Result<_>>()?;
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
    if let Some(f) = test_fraction {
        if !(f > 0.0 && f < 1.0) {
            return Err(Error::Invalid(format!("--test-fraction must be in (0, 1) for compare (every seed is scored on held-out rows), got {f}")));
        }
    }
    twincal::requests::check_effort(effort)?;
    Ok(methods)
}

/// What a comparison is of: its data (and the file's hash), methods, seeds, split, effort, model
/// and reading options; the shards of one comparison share it.
fn compare_config(a: &CompareArgs, ds: &Dataset, file: &Path, methods: &[twincal::calib::run::Method], frac: f64) -> Result<CompareConfig> {
    let n = ds.rows.len();
    let (seeds, effort) = (a.seeds, a.effort);
    Ok(CompareConfig {
        data: ds.source.clone(),
        data_sha256: twincal::dataset::truth::sha256_hex(&std::fs::read(file).map_err(|e| Error::io(file, e))?),
        rows: n,
        methods: methods.iter().map(|m| m.name().to_string()).collect(),
        seeds,
        test_fraction: frac,
        effort,
        model: format!("{} {}", a.model.model, a.model.params.as_deref().unwrap_or("")).trim().to_string(),
        model_sha256: match a.model.input() {
            Some(m) => Some(twincal::dataset::truth::sha256_hex(&std::fs::read(&m).map_err(|e| Error::io(&m, e))?)),
            None => None,
        },
        reading: format!(
            "angles {}, measurement {}, euler {}",
            clap::ValueEnum::to_possible_value(&a.reading.angles).map(|v| v.get_name().to_string()).unwrap_or_default(),
            ds.measurement().map_or("none", |m| m.name()),
            a.reading.euler
        ),
        twincal_version: env!("CARGO_PKG_VERSION").into(),
    })
}

/// The accuracy and time table (mean ± std over seeds), and a tracker's position errors.
fn accuracy_table(methods: &[twincal::calib::run::Method], runs: &[CompareRun]) -> String {
    use twincal::stats::mean_std;
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
            let p = |f: fn(&twincal::stats::metrics::ErrorStats) -> f64| ms(r.iter().filter_map(|x| x.test_position.as_ref().map(f)).collect());
            table.push_str(&format!("| {} | {} | {} | {} |\n", m.name(), p(|e| e.mae), p(|e| e.rmse), p(|e| e.max)));
        }
    }
    table
}

/// Each calibration's warnings, once per method and wording (seeds listed).
fn print_run_warnings(runs: &[CompareRun]) {
    let mut warned: Vec<(String, String, Vec<u64>)> = Vec::new();
    for r in runs {
        for w in &r.warnings {
            match warned.iter_mut().find(|(m, t, _)| *m == r.method && t == w) {
                Some((_, _, seeds)) => seeds.push(r.seed),
                None => warned.push((r.method.clone(), w.clone(), vec![r.seed])),
            }
        }
    }
    for (m, w, seeds) in &warned {
        let seeds: Vec<String> = seeds.iter().map(u64::to_string).collect();
        eprintln!("warning: {m} (seed {}): {w}", seeds.join(", "));
    }
}

/// `twincal reduce PARTS...`: the shards' partial files of one comparison joined, checked (one
/// configuration; every item exactly once once retries' duplicates are dropped) and rendered as
/// the single-process `compare` renders them: the same table, `--out` and `--rrd`.
pub fn reduce(parts: &[PathBuf], out: Option<&Path>, rrd: Option<&Path>, quiet: bool) -> Result<()> {
    if parts.is_empty() {
        return Err(Error::Invalid("reduce needs the shards' partial files (twincal reduce PART...)".into()));
    }
    let outs: Vec<(&str, &Path)> = out.map(|p| ("--out", p)).into_iter().chain(rrd.map(|p| ("--rrd", p))).collect();
    check_outputs(&parts.iter().map(|p| ("PART", p.as_path())).collect::<Vec<_>>(), &outs)?;
    let read = crate::shard::Parts::read(parts)?;
    match read.kind() {
        "compare" => {}
        "study-hold" if out.is_some() => {
            return Err(Error::Invalid("--out applies to compare's parts; a hold study's reduce prints its table (and writes --rrd)".into()))
        }
        "study-hold" => return super::study::reduce_hold(read, rrd, quiet),
        "bench-diagnose" if out.is_some() || rrd.is_some() => {
            return Err(Error::Invalid("bench diagnose's reduce prints its lines and rates; --out and --rrd apply to compare's parts".into()))
        }
        "bench-diagnose" => return crate::bench::diagnose::reduce_detection(read, quiet),
        k => return Err(Error::Invalid(format!("the parts are of a study twincal does not know ('{k}'): written by another twincal version?"))),
    }
    let (config, items, duplicates) = read.gather::<CompareConfig, CompareItem>()?;
    let runs: Vec<CompareRun> = items.into_iter().map(|l| CompareRun { test_abs_residuals: l.test_abs_residuals, ..l.run }).collect();
    if !quiet {
        eprintln!("reduced {} parts: {} items of config {}, {duplicates} duplicates dropped", parts.len(), runs.len(), &config.hash()[..12]);
    }
    finish(&config, &runs, out, rrd)
}
