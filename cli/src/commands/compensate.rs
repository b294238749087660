//! `twincal compensate`: the library's [`twincal::jobs::CompensateJob`], and what it prints.

use super::*;

/// Runs the compensation and prints its summary and warnings.
pub fn compensate(job: &twincal::jobs::CompensateJob, quiet: bool) -> Result<()> {
    let s = job.run()?;
    for w in &s.warnings {
        eprintln!("warning: {w}");
    }
    let rms = |v: &mut dyn Iterator<Item = f64>| {
        let (n, ss) = v.fold((0usize, 0.0), |(n, s), x| (n + 1, s + x * x));
        (ss / n.max(1) as f64).sqrt()
    };
    if let (Some(f), false) = (&s.program, quiet) {
        use twincal::controller::filter::Outcome;
        let done: Vec<&twincal::compensate::Compensated> =
            f.targets.iter().filter(|t| t.outcome == Outcome::Filtered).filter_map(|t| t.compensated.as_ref()).collect();
        let nothing = f.targets.iter().filter(|t| t.outcome == Outcome::NothingToMove).count();
        // An RMS over no target is no error of zero.
        let predicted = match done.is_empty() {
            true => "no target filtered, so no predicted error to state".to_string(),
            false => format!(
                "predicted error of the written targets RMS {:.4} mm, of the filtered {:.6} mm",
                rms(&mut done.iter().map(|t| t.nominal_error_mm)),
                rms(&mut done.iter().map(|t| t.residual_mm))
            ),
        };
        eprintln!(
            "filtered {} of {} targets ({nothing} with nothing to move, {} left as written, {} run-time motions left){}: {predicted}; wrote {} and {}",
            done.len(),
            f.targets.len(),
            f.targets.len() - done.len() - nothing,
            f.run_time.len(),
            s.payload.map_or(String::new(), |(m, c)| format!(" under a {m} kg payload at ({}, {}, {}) mm", c[0], c[1], c[2])),
            job.filtered_dir.display(),
            job.report.display()
        );
        return Ok(());
    }
    if !quiet && s.reachable == 0 {
        eprintln!("compensated {} targets, none reachable; wrote {}", s.targets.len(), job.out.display());
    } else if !quiet {
        let reached: Vec<&twincal::compensate::Compensated> = s.targets.iter().filter(|t| t.status == twincal::compensate::Status::Reachable).collect();
        eprintln!(
            "compensated {} targets ({} reachable){}: predicted error of the nominal commands RMS {:.4} mm, of the compensated {:.6} mm; wrote {}",
            s.targets.len(),
            s.reachable,
            s.payload.map_or(String::new(), |(m, c)| format!(" under a {m} kg payload at ({}, {}, {}) mm", c[0], c[1], c[2])),
            rms(&mut reached.iter().map(|t| t.nominal_error_mm)),
            rms(&mut reached.iter().map(|t| t.residual_mm)),
            job.out.display()
        );
    }
    Ok(())
}
