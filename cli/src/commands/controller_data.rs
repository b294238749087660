//! `twincal controller-data`: a controller-subset calibration as the controller's own data (the
//! library's [`twincal::jobs::ControllerDataJob`]).

use super::*;

/// Writes the data file and prints the offsets and the tool.
pub fn controller_data(job: &twincal::jobs::ControllerDataJob, quiet: bool) -> Result<()> {
    let s = job.run()?;
    if !quiet {
        let offsets: Vec<String> = s.joint_offsets_deg.iter().map(|(n, v)| format!("{n} {v:+.4}°")).collect();
        eprintln!(
            "wrote {}: joint zero offsets {}; tool ({:.3}, {:.3}, {:.3}) mm",
            s.out.display(),
            offsets.join(", "),
            s.tool_mm[0],
            s.tool_mm[1],
            s.tool_mm[2]
        );
        if let Some(h) = &s.held_out {
            let full = h.full_rmse_mm.map_or(String::new(), |f| format!(", the full calibration {f:.4} mm"));
            eprintln!(
                "on the calibration's {} held-out rows (RMSE): nominal {:.4} mm, this subset {:.4} mm{full}",
                h.rows, h.nominal_rmse_mm, h.subset_rmse_mm
            );
        }
    }
    Ok(())
}
