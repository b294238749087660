//! `twincal diagnose`: the run (the library's job) and the summary it prints.

use super::*;

/// `twincal diagnose` (the library's [`DiagnoseJob`]): report.json, the extended model (a
/// calibration result) and optionally a recording, all together or none; and what it prints.
pub fn diagnose(a: &DiagnoseJob, quiet: bool) -> Result<()> {
    let say = |line: &str| {
        if !quiet {
            eprintln!("  {line}");
        }
    };
    let d = a.run(&say, &twincal_viz::Rerun)?;
    let report = &d.report;
    if !quiet {
        print_diagnosis(report);
        if let Some(art) = &d.result.artifact {
            art.lines().iter().for_each(|l| eprintln!("  {l}"));
        }
        eprintln!(
            "  wrote {} and {}; the same model by calibrate: {}",
            a.out.display(),
            a.result.display(),
            calibrate_line(a, &report.effects_option, report.no_sensor_lag)
        );
    }
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    print_verdict(d.verdict.as_ref(), &a.out);
    Ok(())
}

/// The `calibrate` command that fits the diagnosed model: the same data, model and loads, and
/// the effects kept (none: the geometric model).
fn calibrate_line(a: &DiagnoseJob, effects: &str, no_sensor_lag: bool) -> String {
    let quote = |p: &Path| {
        let t = p.display().to_string();
        if t.chars().all(|c| c.is_ascii_alphanumeric() || "/._-#".contains(c)) {
            t
        } else {
            format!("'{}'", t.replace('\'', "'\\''"))
        }
    };
    let mut line = format!("twincal calibrate --data {}", quote(&a.data));
    if a.request.model.model != "irb120" {
        line += &format!(" --model {}", quote(Path::new(&a.request.model.model)));
    }
    if let Some(p) = &a.request.model.params {
        line += &format!(" --params {}", p.name());
    }
    if a.request.reading.angles != AngleUnit::Auto {
        line += &format!(" --angles {}", clap::ValueEnum::to_possible_value(&a.request.reading.angles).map(|v| v.get_name().to_string()).unwrap_or_default());
    }
    if let Some(r) = &a.request.loads.robot {
        line += &format!(" --robot {}", quote(r));
    }
    if let Some(m) = a.request.loads.payload_kg {
        line += &format!(" --payload-kg {m}");
    }
    if let Some(c) = &a.request.loads.payload_com_mm {
        line += &format!(" --payload-com-mm {}", c.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(","));
    }
    if a.request.loads.cable_tension_n != 0.0 {
        line += &format!(" --cable-tension-n {}", a.request.loads.cable_tension_n);
    }
    if a.request.loads.preload_n != 0.0 {
        line += &format!(" --preload-n {}", a.request.loads.preload_n);
    }
    if !effects.is_empty() {
        line += &format!(" --effects {effects}");
    }
    if no_sensor_lag {
        line += " --no-sensor-lag";
    }
    if let Some(r) = a.request.floor.angle_resolution_deg {
        line += &format!(" --angle-resolution-deg {r}");
    }
    if !a.request.artifact.spacing_mm.is_empty() {
        line += &format!(" --spacing-mm {}", a.request.artifact.spacing_mm.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(","));
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
    if let Some(setup) = &d.setup {
        setup.lines().iter().for_each(|l| eprintln!("  {l}"));
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
    match (&d.unexplained, d.causes.is_empty()) {
        (None, true) => eprintln!("  verdict: geometric_only (no effect improves the held-out fit significantly)"),
        (Some(u), true) => eprintln!("  verdict: unexplained: {u}"),
        (Some(u), false) => eprintln!("  unexplained remainder: {u}"),
        (None, false) => {}
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
    if let Some(r) = &d.remainder {
        let within = if !r.white && d.unexplained.is_none() { " (within the data's floor: not unexplained)" } else { "" };
        eprintln!("  what remains: {}{within}", r.summary());
    }
    let sources: Vec<String> = d.noise_floor.sources.iter().map(|s| format!("{} {:.4} mm", s.source, s.rms_mm)).collect();
    if sources.is_empty() {
        eprintln!("  what remains: no floor of the data is known (no repeated configurations, no logging step in the angles or the readings)");
    } else {
        eprintln!("  the data's floor ({}) accounts for {:.0} % of the final held-out mean square", sources.join(", "), 100.0 * d.floor_share_of_remaining);
    }
    if let Some(u) = &d.unseen {
        eprintln!("  {}", u.line());
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
