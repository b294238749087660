//! `twincal replay`: the library's replay job and the summary it prints.

use super::*;
use twincal::jobs::{Fidelity, ReplayJob, ReplaySummary};

/// `twincal replay`: the twin driven through a measured acquisition, row by row, and what it
/// reads beside what was measured.
pub fn replay(a: &ReplayJob, quiet: bool) -> Result<()> {
    let summary = twincal::jobs::replay(a, progress(quiet).as_ref(), &twincal_viz::Rerun)?;
    if !quiet {
        print_summary(&summary, &a.out);
    }
    for (row, why) in summary.rejected.iter().take(3) {
        eprintln!("warning: row {row} was not replayed: {why}");
    }
    for w in &summary.warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}

fn print_summary(s: &ReplaySummary, out: &Path) {
    eprintln!("replay of {} ({} rows, {} replayed) through {} in {:.2} s", s.data, s.rows, s.replayed, s.scenario, s.seconds);
    let line = |label: &str, f: &Fidelity| {
        let pos = f.position.as_ref().map_or(String::new(), |p| format!("; |Δp| mean {:.4} / RMS {:.4} / MAX {:.4} mm", p.mae, p.rmse, p.max));
        eprintln!(
            "  {label:<10} measured − twin: RMSE {:.4} mm, mean {:+.4} mm, MAX {:.4} mm over {} values{pos}",
            f.residual.rmse, f.residual.mean, f.residual.max, f.residual.n
        );
        if f.outlier_rows > 0 {
            eprintln!("  {:<10} without {} outlier rows (beyond 6 robust sd): RMSE {:.4} mm, MAX {:.4} mm", "", f.outlier_rows, f.inliers.rmse, f.inliers.max);
        }
    };
    line("all rows", &s.all);
    if let Some(j) = &s.judged {
        line("judged", j);
    }
    eprintln!("  judged on {}", s.judged_on);
    eprintln!(
        "  the twin's own noise {:.4} mm RMS; residuals against it: Kolmogorov–Smirnov D {:.3} (p {:.2e})",
        s.twin_noise_rms_mm, s.ks_distance, s.ks_p_value
    );
    if let Some(c) = &s.after_calibration {
        eprintln!(
            "  calibrated alike ({}), held-out residuals: real {:.4} mm RMS, the twin's data {:.4} mm; Kolmogorov–Smirnov D {:.3} (p {:.2e})",
            c.model, c.real.rmse, c.twin.rmse, c.ks_distance, c.ks_p_value
        );
    }
    eprintln!("  wrote {}", out.display());
}
