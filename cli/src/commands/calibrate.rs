//! `twincal calibrate`: its arguments, the run and the summary it prints.

use super::*;
use twincal::requests::CalibrateRequest;

/// Arguments of `twincal calibrate` (the field docs are its `--help`): the data, the request
/// (the library's [`CalibrateRequest`], which Python fills from keyword arguments) and the files
/// it writes.
#[derive(Clone, Debug, clap::Args)]
pub struct CalibrateArgs {
    /// Dataset folder (DIR/dataset.csv, with truth.json when the twin made it), CSV, or xlsx (file.xlsx#Sheet).
    #[arg(long)]
    pub data: PathBuf,
    #[command(flatten)]
    pub request: CalibrateRequest,
    /// The calibrated model and its report.
    #[arg(long, default_value = "result.json")]
    pub out: PathBuf,
    /// Also write the calibrated model as a URDF.
    #[arg(long)]
    pub urdf: Option<PathBuf>,
    #[command(flatten)]
    pub figures: Figures,
    /// Also write the identified twin: a scenario (and, beside it, the calibrated URDF it names)
    /// whose geometry, instrument placement, effect sizes, noise and logging resolutions are the
    /// identified ones, so that `generate` and `replay` simulate this robot.
    #[arg(long)]
    pub scenario_out: Option<PathBuf>,
}

/// What `calibrate` computed, before anything is written: the result, its verdict, and what
/// the outputs are drawn from (the options and the data calibrated on).
pub struct Calibration {
    pub result: twincal::calib::run::CalibResult,
    pub verdict: Option<twincal::report::verdict::Verdict>,
    pub opts: twincal::calib::run::CalibOptions,
    pub data: Dataset,
}

impl CalibrateArgs {
    /// Every option checked and resolved (reads no data; reads --robot's URDF).
    pub fn options(&self) -> Result<(twincal::calib::run::CalibOptions, [Limit; 2])> {
        self.request.options()
    }

    /// The files this calibration reads and writes, by option, checked against each other
    /// (no output over an input, no two outputs on one file). `data`: whether `--data` is read.
    pub fn check_files(&self, data: bool) -> Result<()> {
        let a = self;
        let data_files = if data { data_inputs(&a.data) } else { Vec::new() };
        let model_file = a.request.model.input();
        let mut inputs: Vec<(&str, &Path)> = data_files.iter().map(|p| ("--data", p.as_path())).collect();
        if let Some(m) = &model_file {
            inputs.push(("--model", m));
        }
        let mut outs: Vec<(&str, &Path)> = vec![("--out", &a.out)];
        outs.extend(a.urdf.as_deref().map(|p| ("--urdf", p)));
        check_model_outputs(&inputs, outs, a.figures.rrd.as_deref(), a.figures.report.as_deref(), a.scenario_out.as_deref())
    }
}

/// `twincal calibrate`. Its outputs (`--out`, `--urdf`, `--rrd`) appear together or not at all.
/// Warnings (an optimiser that stopped without converging) go to stderr also with `--quiet`.
pub fn calibrate(a: &CalibrateArgs, quiet: bool) -> Result<()> {
    let planned = a.options()?;
    a.check_files(true)?;
    let data = load_dataset(&a.data, &a.request.reading, true)?;
    let truth = twincal::calib::run::TruthFile::find(&a.data)?;
    // The exact bytes calibrated on, so that `ik` can tell their twin from another one.
    let file = &data_inputs(&a.data)[0];
    let sha = twincal::dataset::truth::sha256_hex(&std::fs::read(file).map_err(|e| Error::io(file, e))?);
    let c = calibrate_loaded(planned, data, truth.as_ref(), Some(sha))?;
    write_calibration(a, &c, quiet)
}

/// The calibration `calibrate` runs, with its options (`CalibrateArgs::options`) on data
/// already loaded: `truth` the twin's truth file when it belongs to these data, `data_sha256`
/// the fingerprint of the bytes they came from.
pub fn calibrate_loaded(
    (opts, limits): (twincal::calib::run::CalibOptions, [Limit; 2]),
    data: Dataset,
    truth: Option<&twincal::calib::run::TruthFile>,
    data_sha256: Option<String>,
) -> Result<Calibration> {
    let mut result = twincal::calib::run::calibrate(&data, truth, &opts)?;
    result.data_sha256 = data_sha256;
    let test = result.metrics.test_after.as_ref();
    let source = if test.is_some() { "test rows after calibration" } else { "no test rows: hold some out with --test-fraction or a split column" };
    let verdict = judge(&[(limits[0], "test_rmse_mm", test.map(|t| t.rmse), source), (limits[1], "test_max_mm", test.map(|t| t.max), source)]);
    Ok(Calibration { result, verdict, opts, data })
}

/// What `calibrate` writes of a calibration (`--out`, and `--urdf`, `--rrd`, `--report`,
/// `--scenario-out` when given), all together or none, and what it prints. The caller has
/// checked the files (`CalibrateArgs::check_files`).
pub fn write_calibration(a: &CalibrateArgs, c: &Calibration, quiet: bool) -> Result<()> {
    use twincal::calib::run::ModelSpec;
    let (result, data, opts) = (&c.result, &c.data, &c.opts);
    let mut outputs = OutputSet::new();
    let figures = if a.figures.rrd.is_some() || a.figures.report.is_some() { Some(twincal::report::CalibFigures::new(result, data)?) } else { None };
    if let (Some(p), Some(f)) = (&a.figures.rrd, &figures) {
        crate::viz::results::record_calibration(result, f, &mut outputs, p)?;
    }
    if let (Some(p), Some(f)) = (&a.figures.report, &figures) {
        outputs.write(p, twincal::report::html::calibration_page(result, f, c.verdict.as_ref()).as_bytes())?;
    }
    if let Some(p) = &a.urdf {
        let nominal = match &opts.model {
            ModelSpec::Nominal { robot, .. } => Some(robot.as_ref()),
            ModelSpec::Generic6r => None,
        };
        outputs.write(p, twincal::calib::run::export::urdf(&result.model, &result.x, nominal, "calibrated").as_bytes())?;
    }
    if let Some(p) = &a.scenario_out {
        let how = if a.request.placement_only { "calibrate --placement-only" } else { "calibrate" };
        stage_identified_twin(&mut outputs, p, result, data, opts.model.robot(), how)?;
    }
    outputs.write_json(&a.out, &with_verdict(result, c.verdict.as_ref())?)?;
    outputs.commit()?;
    if !quiet {
        print_summary(result);
        if let Some(p) = &a.scenario_out {
            eprintln!("  identified twin: {} (robot {})", p.display(), scenario_urdf_path(p).display());
        }
    }
    print_verdict(c.verdict.as_ref(), &a.out);
    for w in calibration_warnings(result) {
        eprintln!("warning: {w}");
    }
    Ok(())
}

/// The verdict on stderr (also with `--quiet`: it is the answer a user asked for).
pub(super) fn print_verdict(v: Option<&twincal::report::verdict::Verdict>, file: &Path) {
    let Some(v) = v else { return };
    let checks: Vec<String> = v
        .checks
        .iter()
        .map(|c| match c.value {
            Some(x) => format!("{} {x:.4} {} {:.4} mm", c.name, if c.pass { "<=" } else { ">" }, c.limit),
            None => format!("{} not measured ({})", c.name, c.source),
        })
        .collect();
    eprintln!("verdict: {} ({}); in {}", if v.pass { "PASS" } else { "FAIL" }, checks.join(", "), file.display());
}

/// What a user must know about a calibration that succeeded: an optimiser that stopped on its
/// iteration / evaluation budget instead of a convergence test.
pub fn calibration_warnings(r: &twincal::calib::run::CalibResult) -> Vec<String> {
    r.warnings.clone()
}

/// How the rows were weighted and the noise model that took the angles' logging error out.
fn print_noise_handling(r: &twincal::calib::run::CalibResult) {
    if let Some(w) = &r.weighting {
        eprintln!(
            "  weights from the rows' own standard deviations ({} of {} training rows, RMS {:.4} mm): 1/(floor² + s²) with the floor {:.4} mm the data add \
             (robust residual sd {:.4} mm); largest / smallest weight {:.2}",
            w.rows_with_std, w.rows, w.instrument_rms_mm, w.floor_mm, w.residual_sd_mm, w.weight_span
        );
    }
    if let Some(n) = &r.noise_model {
        eprintln!(
            "  noise model: joint angles logged at {} deg, shared by the rows of a sweep (rounding {:.4} mm, reading noise {:.4} mm per value); \
             the logging error estimated per sweep and joint was taken out of the training readings before the fit (RMS {:.4} mm; --noise-model off keeps them)",
            n.angle_step_deg,
            n.rounding_mm,
            n.reading_noise_mm,
            n.removed_rms_mm.unwrap_or(0.0)
        );
    }
}

/// The outlier screen: rows kept out, their runs, reading steps, and the test inliers' errors.
fn print_screen(r: &twincal::calib::run::CalibResult) {
    let m = &r.metrics;
    let row = |label: &str, s: &twincal::stats::metrics::ErrorStats| format!("  {label:<14} {:>10.4} {:>10.4} {:>10.4}", s.rmse, s.std, s.max);
    // The screen ran when it has a robust scale (it does not for too few rows per parameter,
    // nor for readings of several values).
    if r.outlier_k > 0.0 && r.robust_scale_mm > 0.0 {
        let runs: Vec<String> = r.outlier_runs.iter().map(|u| format!("rows {}-{} ({:+.2} mm)", u.first_row, u.last_row, u.median_residual_mm)).collect();
        eprintln!(
            "  outliers (> {} robust sd of {:.4} mm): {} training rows kept out{}; {} test rows beyond the same rule",
            r.outlier_k,
            r.robust_scale_mm,
            r.outliers.len(),
            if runs.is_empty() { String::new() } else { format!(", runs: {}", runs.join(", ")) },
            r.test_outliers.len()
        );
        for s in &r.reading_steps {
            eprintln!(
                "  reading step: rows {}-{} read {:+.2} ± {:.2} mm off ({} training rows), corrected and kept",
                s.first_row, s.last_row, s.offset_mm, s.std_mm, s.rows
            );
        }
        if r.test_rows_in_steps > 0 {
            eprintln!("  {} test rows inside reading steps corrected by their step's offset (from training rows)", r.test_rows_in_steps);
        }
        if let (Some(t), false) = (&m.test_after_inliers, r.test_outliers.is_empty()) {
            eprintln!("{}", row("test inliers", t));
        }
    }
}

/// The data's noise floor and the held-out RMSE against it.
fn print_floor(r: &twincal::calib::run::CalibResult) {
    let m = &r.metrics;
    if r.noise_floor.as_ref().is_some_and(|f| f.sources.is_empty()) {
        eprintln!("  noise floor of the data: not measurable (no repeated configurations, and neither the angles nor the readings show a logging step)");
    }
    if let Some(f) = r.noise_floor.as_ref().filter(|f| !f.sources.is_empty()) {
        let parts: Vec<String> = f.sources.iter().map(|s| format!("{} {:.4}", s.source, s.rms_mm)).collect();
        // Without repeated configurations the reading's own noise is not in the data: the
        // floor is only what the logging resolutions show, a lower bound.
        let measured = f.sources.iter().any(|s| s.source == "repeatability");
        let (bound, why) = if measured { ("", "") } else { ("at least ", "; no repeated configurations, so the reading's own noise is not measured") };
        eprintln!("  noise floor of the data: {bound}{:.4} mm ({}{why})", f.total_mm, parts.join(", "));
        if let (Some(t), Some(tt), true) = (&m.test_after, &m.test_after_trimmed, f.total_mm > 0.0) {
            let ratio = t.rmse / f.total_mm;
            if measured || ratio <= MAX_BOUND_RATIO {
                eprintln!("  held-out RMSE / floor = {ratio:.3} (without the worst 1 % of test rows: {:.3})", tt.rmse / f.total_mm);
            } else {
                eprintln!("  held-out RMSE is more than {MAX_BOUND_RATIO}× that lower bound: the data do not show their floor");
            }
        }
    }
}

fn print_summary(r: &twincal::calib::run::CalibResult) {
    let m = &r.metrics;
    let row = |label: &str, s: &twincal::stats::metrics::ErrorStats| format!("  {label:<14} {:>10.4} {:>10.4} {:>10.4}", s.rmse, s.std, s.max);
    eprintln!(
        "{} / {} on {} ({} train, {} test rows), {} iterations, {:.3} s",
        r.method.name(),
        r.model_name,
        r.data,
        r.n_train,
        r.n_test,
        r.iterations,
        r.wall_time_s
    );
    eprintln!("  {:<14} {:>10} {:>10} {:>10}   (mm)", "residuals", "RMSE", "STD", "MAX");
    eprintln!("{}", row("train before", &m.train_before));
    eprintln!("{}", row("train after", &m.train_after));
    if let (Some(b), Some(a)) = (&m.test_before, &m.test_after) {
        eprintln!("{}", row("test before", b));
        eprintln!("{}", row("test after", a));
    }
    let meas = r.model.measurement;
    if meas.dim() > 1 {
        let cols = meas.def().columns().join(", ");
        match (&m.test_position_before, &m.test_position_after) {
            (Some(b), Some(a)) => eprintln!(
                "  residuals are per coordinate ({cols}); the test rows' position error |Δp| (mean / RMS / MAX): {:.4} / {:.4} / {:.4} mm, before {:.4} / {:.4} / {:.4} mm",
                a.mae, a.rmse, a.max, b.mae, b.rmse, b.max
            ),
            _ => eprintln!("  residuals are per coordinate ({cols})"),
        }
    }
    print_noise_handling(r);
    let fixed: Vec<&str> = r.parameters.iter().filter(|p| p.fixed).map(|p| p.name.as_str()).collect();
    eprintln!(
        "  identifiable: {} of {} parameters; fixed (not identifiable from these poses): {}",
        r.parameters.len() - fixed.len(),
        r.parameters.len(),
        fixed.join(", ")
    );
    let id = |k: &str| r.identifiability.get(k).and_then(|v| v.as_f64());
    if let (Some(all), Some(c)) = (id("condition_all"), id("condition_identifiable")) {
        eprintln!("  condition number: {all:.3e} with every parameter free, {c:.3e} for the identifiable set");
    }
    if let Some(still) = r.identifiability.get("still_joints").and_then(|v| v.as_array()).filter(|v| !v.is_empty()) {
        let joints: Vec<String> = still.iter().map(|j| j.to_string()).collect();
        eprintln!("  joints that do not move in the data (held for the identifiability analysis): {}", joints.join(", "));
    }
    print_screen(r);
    if let Some(t) = &m.test_after_trimmed {
        eprintln!("{}", row("test, best 99%", t));
    }
    print_floor(r);
    if let Some(t) = &r.truth_comparison {
        eprintln!(
            "  truth: {}/{} identifiable parameters within 3σ (max |z| = {:.2}); sensor noise floor {:.4} mm",
            t.within_3_sigma, t.identifiable, t.max_abs_z, t.noise_floor_mm
        );
    }
}
