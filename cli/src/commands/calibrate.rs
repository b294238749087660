//! `twincal calibrate`: the run (the library's job) and the summary it prints.

use super::*;

/// `twincal calibrate` (the library's [`CalibrateJob`]), and what it prints. Its outputs
/// (`--out`, `--urdf`, `--rrd`, `--report`, `--scenario-out`) appear together or not at all.
/// Warnings (an optimiser that stopped without converging) go to stderr also with `--quiet`.
pub fn calibrate(a: &CalibrateJob, quiet: bool) -> Result<()> {
    let c = a.run(&twincal_viz::Rerun)?;
    let result = &c.result;
    if !quiet {
        print_summary(result);
        let subset = [(a.request.placement_only, "--placement-only"), (a.request.controller_subset, "--controller-subset")];
        if let Some((_, flag)) = subset.iter().find(|(on, _)| *on) {
            eprintln!("  {flag}: every other parameter is held at the nominal model by request (the fixed list above includes them)");
        }
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
pub fn calibration_warnings(r: &twincal::calib::pipeline::CalibResult) -> Vec<String> {
    r.warnings.clone()
}

/// How the rows were weighted and the noise model that took the angles' logging error out.
fn print_noise_handling(r: &twincal::calib::pipeline::CalibResult) {
    if let Some(w) = &r.solve.weighting {
        eprintln!(
            "  weights from the rows' own standard deviations ({} of {} training rows, RMS {:.4} mm): 1/(floor² + s²) with the floor {:.4} mm the data add \
             (robust residual sd {:.4} mm); largest / smallest weight {:.2}",
            w.rows_with_std, w.rows, w.instrument_rms_mm, w.floor_mm, w.residual_sd_mm, w.weight_span
        );
    }
    if let Some(n) = &r.solve.noise_model {
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
fn print_screen(r: &twincal::calib::pipeline::CalibResult) {
    let m = &r.evaluation.metrics;
    let row = |label: &str, s: &twincal::stats::metrics::ErrorStats| format!("  {label:<14} {:>10.4} {:>10.4} {:>10.4}", s.rmse, s.std, s.max);
    // The screen ran when it has a robust scale (it does not for too few rows per parameter,
    // nor for readings of several values).
    if r.screen.outlier_k > 0.0 && r.screen.robust_scale_mm > 0.0 {
        let runs: Vec<String> =
            r.screen.outlier_runs.iter().map(|u| format!("rows {}-{} ({:+.2} mm)", u.first_row, u.last_row, u.median_residual_mm)).collect();
        eprintln!(
            "  outliers (> {} robust sd of {:.4} mm): {} training rows kept out{}; {} test rows beyond the same rule",
            r.screen.outlier_k,
            r.screen.robust_scale_mm,
            r.screen.outliers.len(),
            if runs.is_empty() { String::new() } else { format!(", runs: {}", runs.join(", ")) },
            r.screen.test_outliers.len()
        );
        for s in &r.screen.reading_steps {
            eprintln!(
                "  reading step: rows {}-{} read {:+.2} ± {:.2} mm off ({} training rows), corrected and kept",
                s.first_row, s.last_row, s.offset_mm, s.std_mm, s.rows
            );
        }
        if r.screen.test_rows_in_steps > 0 {
            eprintln!("  {} test rows inside reading steps corrected by their step's offset (from training rows)", r.screen.test_rows_in_steps);
        }
        if let (Some(t), false) = (&m.test_after_inliers, r.screen.test_outliers.is_empty()) {
            eprintln!("{}", row("test inliers", t));
        }
    }
}

/// The data's noise floor and the held-out RMSE against it.
fn print_floor(r: &twincal::calib::pipeline::CalibResult) {
    let m = &r.evaluation.metrics;
    if r.evaluation.noise_floor.as_ref().is_some_and(|f| f.sources.is_empty()) {
        eprintln!("  noise floor of the data: not measurable (no repeated configurations, and neither the angles nor the readings show a logging step)");
    }
    if let Some(f) = r.evaluation.noise_floor.as_ref().filter(|f| !f.sources.is_empty()) {
        let parts: Vec<String> = f.sources.iter().map(|s| format!("{} {:.4}", s.source, s.rms_mm)).collect();
        // Without repeated configurations the reading's own noise is not in the data: the
        // floor is only what the logging resolutions show, a lower bound.
        let measured = f.has(twincal::calib::fit::floor::FloorKind::Repeatability);
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

fn print_summary(r: &twincal::calib::pipeline::CalibResult) {
    let m = &r.evaluation.metrics;
    let row = |label: &str, s: &twincal::stats::metrics::ErrorStats| format!("  {label:<14} {:>10.4} {:>10.4} {:>10.4}", s.rmse, s.std, s.max);
    eprintln!(
        "{} / {} on {} ({} train, {} test rows), {} iterations, {:.3} s",
        r.provenance.method,
        r.provenance.model_name,
        r.provenance.data,
        r.provenance.n_train,
        r.provenance.n_test,
        r.solve.iterations,
        r.provenance.wall_time_s
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
    if let Some(setup) = &r.setup {
        setup.lines().iter().for_each(|l| eprintln!("  {l}"));
    }
    if let Some(a) = &r.artifact {
        a.lines().iter().for_each(|l| eprintln!("  {l}"));
    }
    if let Some(s) = &r.solve.search {
        eprintln!("  generic arm: {} shapes drawn, {} converged on every training row, {} of them at the best cost", s.starts, s.finalists, s.in_best_basin);
    }
    let fixed: Vec<&str> = r.parameters.iter().filter(|p| p.fixed).map(|p| p.name.as_str()).collect();
    eprintln!(
        "  identifiable: {} of {} parameters; fixed (not identifiable from these poses): {}",
        r.parameters.len() - fixed.len(),
        r.parameters.len(),
        fixed.join(", ")
    );
    let id = |k: &str| r.solve.identifiability.get(k).and_then(|v| v.as_f64());
    if let (Some(all), Some(c)) = (id("condition_all"), id("condition_identifiable")) {
        eprintln!("  condition number: {all:.3e} with every parameter free, {c:.3e} for the identifiable set");
    }
    if let Some(still) = r.solve.identifiability.get("still_joints").and_then(|v| v.as_array()).filter(|v| !v.is_empty()) {
        let joints: Vec<String> = still.iter().map(|j| j.to_string()).collect();
        eprintln!("  joints that do not move in the data (held for the identifiability analysis): {}", joints.join(", "));
    }
    print_screen(r);
    if let Some(t) = &m.test_after_trimmed {
        eprintln!("{}", row("test, best 99%", t));
    }
    print_floor(r);
    if let Some(t) = &r.evaluation.truth_comparison {
        eprintln!(
            "  truth: {}/{} identifiable parameters within 3σ (max |z| = {:.2}); sensor noise floor {:.4} mm",
            t.within_3_sigma, t.identifiable, t.max_abs_z, t.noise_floor_mm
        );
    }
}
