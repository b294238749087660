//! `twincal diagnose`: its arguments, the run and the summary it prints.

use super::*;

/// Arguments of `twincal diagnose` (the field docs are its `--help`).
#[derive(Clone, Debug, clap::Args)]
pub struct DiagnoseArgs {
    /// Dataset folder, CSV or xlsx (q1..qN and L, or a tracker's x, y, z; optional t, temp). No
    /// truth file is read.
    #[arg(long)]
    pub data: PathBuf,
    /// Unit of the joint angles in the data.
    #[arg(long, value_enum, default_value_t = AngleArg::Auto)]
    pub angles: AngleArg,
    #[command(flatten)]
    pub reading: ReadingArgs,
    #[command(flatten)]
    pub model: ModelArgs,
    #[command(flatten)]
    pub loads: LoadArgs,
    /// Candidate effects (default: every kind the data support).
    #[arg(long, value_delimiter = ',')]
    pub candidates: Vec<String>,
    /// Cross-validation folds (contiguous blocks of acquisition order).
    #[arg(long, allow_negative_numbers = true, default_value_t = twincal::diagnose::DEFAULT_FOLDS)]
    pub folds: usize,
    /// Family-wise significance level of each selection step.
    #[arg(long, default_value_t = twincal::diagnose::DEFAULT_ALPHA, allow_negative_numbers = true)]
    pub alpha: f64,
    #[arg(long, allow_negative_numbers = true, default_value_t = 0)]
    pub seed: u64,
    /// The diagnosis report.
    #[arg(long, default_value = "report.json")]
    pub out: PathBuf,
    /// The extended model, saved like any calibration result.
    #[arg(long, default_value = "diagnosed.json")]
    pub result: PathBuf,
    /// Rerun recording of the evidence.
    #[arg(long)]
    pub rrd: Option<PathBuf>,
    /// Self-contained HTML report (tables and plots, opens offline in any browser).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Accuracy limit for the verdict in --out: the final cross-validated held-out RMSE, mm.
    #[arg(long, allow_negative_numbers = true)]
    pub max_test_rmse_mm: Option<f64>,
    /// Logging step of the joint angles in degrees, for the noise floor (default: read from the
    /// data's decimals).
    #[arg(long, allow_negative_numbers = true)]
    pub angle_resolution_deg: Option<f64>,
    /// The instrument's stated accuracy, mm (standard uncertainty of one coordinate or of the
    /// cable length), for the noise floor.
    #[arg(long, allow_negative_numbers = true)]
    pub instrument_accuracy_mm: Option<f64>,
    /// Fit with equal weights even where the data give per-row standard deviations (a
    /// tracker's sx, sy, sz; by default they weight the fits as 1/(floor² + s²)).
    #[arg(long)]
    pub ignore_row_std: bool,
    /// The joint angles' logging error: auto (where rows share sweeps and the angles are
    /// logged at a step, every fit is generalised least squares with the covariance it implies)
    /// or off (rows taken as independent).
    #[arg(long, default_value = "auto")]
    pub noise_model: String,
    /// Diagnose on the other rows only: hold out this fraction of the rows (the split
    /// `calibrate --test-fraction` draws with the same --seed), never seen, so that `replay`
    /// can measure the identified twin on them.
    #[arg(long, allow_negative_numbers = true)]
    pub test_fraction: Option<f64>,
    /// How --test-fraction draws its rows: blocks (whole sweeps, pauses, declared blocks) or
    /// rows (stratified by the reading).
    #[arg(long, default_value = "blocks")]
    pub split_by: String,
    /// Also write the identified twin (scenario and URDF, see `calibrate --scenario-out`),
    /// with the named causes at their sizes.
    #[arg(long)]
    pub scenario_out: Option<PathBuf>,
}

/// What `diagnose` found, before anything is written: the report, the extended model (a
/// calibration result), the verdict, and the data and options they came from.
pub struct Diagnosed {
    pub report: twincal::diagnose::Diagnosis,
    pub result: twincal::calib::run::CalibResult,
    pub verdict: Option<twincal::report::verdict::Verdict>,
    pub opts: twincal::diagnose::DiagnoseOptions,
    pub data: Dataset,
}

impl DiagnoseArgs {
    /// Every option checked and resolved (reads no data; reads --robot's URDF).
    pub fn options(&self) -> Result<(twincal::diagnose::DiagnoseOptions, Limit)> {
        let a = self;
        if let Some(f) = a.test_fraction {
            if !(f > 0.0 && f < 1.0) {
                return Err(Error::Invalid(format!("--test-fraction must be in (0, 1), got {f}")));
            }
        }
        let limit = Limit { flag: "--max-test-rmse-mm", value: a.max_test_rmse_mm };
        limit.validate()?;
        if !(a.alpha > 0.0 && a.alpha < 0.5) {
            return Err(Error::Invalid(format!("--alpha must be in (0, 0.5), got {}", a.alpha)));
        }
        let mut opts = twincal::diagnose::DiagnoseOptions::new(a.model.spec()?);
        let (loads, inertial) = a.loads.resolve()?;
        opts.loads = loads;
        opts.inertial = inertial;
        opts.folds = a.folds;
        opts.alpha = a.alpha;
        opts.seed = a.seed;
        opts.row_std = !a.ignore_row_std;
        opts.noise_model = a.noise_model.parse()?;
        opts.instrument_accuracy_mm = super::instrument_accuracy(a.instrument_accuracy_mm)?;
        // Checked here, with the other options, before any data are read.
        a.split_by.parse::<twincal::calib::run::SplitBy>()?;
        opts.candidates = parse_effects("--candidates", &a.candidates)?;
        if let Some(r) = a.angle_resolution_deg {
            if !(r.is_finite() && r > 0.0 && r <= 10.0) {
                return Err(Error::Invalid(format!("--angle-resolution-deg must be in (0, 10] degrees, got {r}")));
            }
            opts.angle_step_deg = Some(r);
        }
        Ok((opts, limit))
    }

    /// The files this diagnosis reads and writes, checked against each other. `data`: whether
    /// `--data` is read.
    pub fn check_files(&self, data: bool) -> Result<()> {
        let a = self;
        let data_files = if data { data_inputs(&a.data) } else { Vec::new() };
        let mut inputs: Vec<(&str, &Path)> = data_files.iter().map(|p| ("--data", p.as_path())).collect();
        let model_file = a.model.input();
        if let Some(m) = &model_file {
            inputs.push(("--model", m));
        }
        if let Some(r) = &a.loads.robot {
            inputs.push(("--robot", r));
        }
        let outs: Vec<(&str, &Path)> = vec![("--out", &a.out), ("--result", &a.result)];
        check_model_outputs(&inputs, outs, a.rrd.as_deref(), a.report.as_deref(), a.scenario_out.as_deref())
    }
}

/// `twincal diagnose`: report.json, the extended model (a calibration result) and optionally a
/// recording, all together or none.
pub fn diagnose(a: &DiagnoseArgs, quiet: bool) -> Result<()> {
    a.check_files(true)?;
    let planned = a.options()?;
    let data = load_dataset(&a.data, a.angles, &a.reading, true)?;
    let say = |line: &str| {
        if !quiet {
            eprintln!("  {line}");
        }
    };
    let d = diagnose_loaded(a, planned, data, &say)?;
    write_diagnosis(a, &d, quiet)
}

/// The diagnosis `diagnose` runs, with its options (`DiagnoseArgs::options`) on data already
/// loaded; `say` hears each step's line.
pub fn diagnose_loaded(
    a: &DiagnoseArgs,
    (opts, limit): (twincal::diagnose::DiagnoseOptions, Limit),
    mut data: Dataset,
    say: &(dyn Fn(&str) + Sync),
) -> Result<Diagnosed> {
    if let Some(f) = a.test_fraction {
        // The rows calibrate --test-fraction f --seed s trains on; the rest are never seen.
        let (train, _) = twincal::calib::run::split_rows(&data, Some(f), a.seed, a.split_by.parse()?)?;
        let rows = train.iter().map(|&i| twincal::dataset::Row { split: None, ..data.rows[i].clone() }).collect();
        data = Dataset { rows, source: format!("{} (the {} training rows of --test-fraction {f})", data.source, train.len()) };
    }
    let (report, result) = twincal::diagnose::diagnose(&data, &opts, say)?;
    let verdict = judge(&[(limit, "heldout_rmse_mm", Some(report.final_heldout_rmse_mm), "cross-validated held-out RMSE of the final model")]);
    Ok(Diagnosed { report, result, verdict, opts, data })
}

/// What `diagnose` writes of a diagnosis (`--out`, `--result`, and `--rrd`, `--report`,
/// `--scenario-out` when given), all together or none, and what it prints. The caller has
/// checked the files (`DiagnoseArgs::check_files`).
pub fn write_diagnosis(a: &DiagnoseArgs, d: &Diagnosed, quiet: bool) -> Result<()> {
    let (report, result, data) = (&d.report, &d.result, &d.data);
    let mut outputs = OutputSet::new();
    let figures = (a.rrd.is_some() || a.report.is_some()).then(|| twincal::report::DiagnosisFigures::new(report, result, data));
    if let (Some(p), Some(f)) = (&a.rrd, &figures) {
        crate::viz::results::record_diagnosis(report, f, &mut outputs, p)?;
    }
    if let (Some(p), Some(f)) = (&a.report, &figures) {
        outputs.write(p, twincal::report::html::diagnosis_page(report, f, d.verdict.as_ref()).as_bytes())?;
    }
    if let Some(p) = &a.scenario_out {
        stage_identified_twin(&mut outputs, p, result, data, d.opts.model.robot(), "diagnose")?;
    }
    outputs.write_json(&a.out, &with_verdict(report, d.verdict.as_ref())?)?;
    outputs.write_json(&a.result, result)?;
    outputs.commit()?;
    if !quiet {
        print_diagnosis(report);
        eprintln!("  wrote {} and {}; the same model by calibrate: {}", a.out.display(), a.result.display(), calibrate_line(a, &report.effects_option));
    }
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    print_verdict(d.verdict.as_ref(), &a.out);
    Ok(())
}

/// The `calibrate` command that fits the diagnosed model: the same data, model and loads, and
/// the effects kept (none: the geometric model).
fn calibrate_line(a: &DiagnoseArgs, effects: &str) -> String {
    let quote = |p: &Path| {
        let t = p.display().to_string();
        if t.chars().all(|c| c.is_ascii_alphanumeric() || "/._-#".contains(c)) {
            t
        } else {
            format!("'{}'", t.replace('\'', "'\\''"))
        }
    };
    let mut line = format!("twincal calibrate --data {}", quote(&a.data));
    if a.model.model != "irb120" {
        line += &format!(" --model {}", quote(Path::new(&a.model.model)));
    }
    if let Some(p) = &a.model.params {
        line += &format!(" --params {p}");
    }
    if a.angles != AngleArg::Auto {
        line += &format!(" --angles {}", clap::ValueEnum::to_possible_value(&a.angles).map(|v| v.get_name().to_string()).unwrap_or_default());
    }
    if let Some(r) = &a.loads.robot {
        line += &format!(" --robot {}", quote(r));
    }
    if let Some(m) = a.loads.payload_kg {
        line += &format!(" --payload-kg {m}");
    }
    if let Some(c) = &a.loads.payload_com_mm {
        line += &format!(" --payload-com-mm {}", c.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(","));
    }
    if a.loads.cable_tension_n != 0.0 {
        line += &format!(" --cable-tension-n {}", a.loads.cable_tension_n);
    }
    if !effects.is_empty() {
        line += &format!(" --effects {effects}");
    }
    if let Some(r) = a.angle_resolution_deg {
        line += &format!(" --angle-resolution-deg {r}");
    }
    line
}

fn print_diagnosis(d: &twincal::diagnose::Diagnosis) {
    eprintln!("diagnosis of {} ({} rows, {} outliers kept out) in {:.1} s", d.data, d.rows, d.outliers.len(), d.seconds);
    if !d.reading.is_empty() {
        eprintln!("  {}", d.reading);
    }
    for o in &d.outliers {
        eprintln!("  outlier: row {} residual {:+.3} mm ({:+.1} robust sd)", o.row, o.residual_mm, o.robust_z);
    }
    for u in &d.outlier_runs {
        eprintln!("  outlier run: rows {}-{}, median residual {:+.3} mm", u.first_row, u.last_row, u.median_residual_mm);
    }
    for s in &d.reading_steps {
        eprintln!(
            "  reading step: rows {}-{} read {:+.3} ± {:.3} mm off ({} rows; the reading jumped and stayed), corrected and kept",
            s.first_row, s.last_row, s.offset_mm, s.std_mm, s.rows
        );
    }
    for f in &d.run_faults {
        eprintln!("  rows {}-{}: {}", f.first_row, f.last_row, f.evidence);
    }
    eprintln!("  acquisition: {} (design effect {:.2})", d.acquisition.summary, d.design_effect);
    if let Some(n) = &d.noise_model {
        eprintln!(
            "  noise model: joint angles logged at {} deg, shared by the rows of a block that hold them or step them evenly ({:.4} mm per value on average), reading noise {:.4} mm at the final model: the fits are generalised least squares",
            n.angle_step_deg, n.rounding_mm, n.reading_noise_mm
        );
    }
    eprintln!("  noise floor {:.4} mm ({})", d.noise_floor_mm, d.noise_floor_source);
    eprintln!(
        "  geometric model ({}): held-out RMSE {:.4} mm on blocked folds, {:.4} mm on interleaved folds; judged on {} folds ({} selection rows, {} confirmation rows kept back)",
        d.baseline.model, d.baseline.heldout_rmse_blocked_mm, d.baseline.heldout_rmse_interleaved_mm, d.judged_on, d.selection_rows, d.confirmation_rows
    );
    let top: Vec<String> = d.evidence.iter().take(4).map(|e| format!("{} r={:+.2}", e.feature, e.correlation)).collect();
    eprintln!("  residual follows most: {}", top.join(", "));
    if d.causes.is_empty() {
        eprintln!("  verdict: geometric_only (no effect improves the held-out fit significantly)");
    }
    for (i, c) in d.causes.iter().enumerate() {
        eprintln!("  cause {}: {}", i + 1, c.summary());
        eprintln!(
            "           confirmation rows: {:.4} -> {:.4} mm; other folds: {:.4} -> {:.4} mm",
            c.confirmation_rmse_before_mm, c.confirmation_rmse_after_mm, c.heldout_rmse_other_folds_before_mm, c.heldout_rmse_other_folds_after_mm
        );
    }
    if !d.unconfirmed.is_empty() {
        eprintln!("  not confirmed on the confirmation rows (left out of the model): {}", d.unconfirmed.join(", "));
    }
    eprintln!(
        "  final held-out RMSE {:.4} mm ({}); the final model's RMSE on the {} kept rows: {:.4} mm",
        d.final_heldout_rmse_mm,
        d.against_floor(),
        d.rows - d.outliers.len(),
        d.final_train_rmse_mm
    );
    let sources: Vec<String> = d.noise_floor.sources.iter().map(|s| format!("{} {:.4} mm", s.source, s.rms_mm)).collect();
    if sources.is_empty() {
        eprintln!("  what remains: no floor of the data is known (no repeated configurations, no logging step in the angles or the readings)");
    } else {
        eprintln!(
            "  what remains: the data's floor ({}) accounts for {:.0} % of the final held-out mean square",
            sources.join(", "),
            100.0 * d.floor_share_of_remaining
        );
    }
    if let Some(c) = &d.comparison {
        eprintln!(
            "  held-out RMSE geometric / physical extension / RBF compensator: {:.4} / {:.4} / {:.4} mm",
            c.heldout_rmse_mm[0], c.heldout_rmse_mm[1], c.heldout_rmse_mm[2]
        );
        eprintln!(
            "  extrapolation to q2 > {:.1} deg ({} rows, trained on {}): {:.4} / {:.4} / {:.4} mm",
            c.q2_split_deg,
            c.extrapolation_rows[1],
            c.extrapolation_rows[0],
            c.extrapolation_rmse_mm[0],
            c.extrapolation_rmse_mm[1],
            c.extrapolation_rmse_mm[2]
        );
    }
}
