//! `twincal export`: a calibrated model for a controller or driver (the library's
//! [`twincal::jobs::ExportJob`]), and what the file does not carry.

use super::*;

/// Runs the export and prints what it wrote, its read-back check and its warnings.
pub fn export(job: &twincal::jobs::ExportJob, quiet: bool) -> Result<()> {
    let s = job.run()?;
    for w in &s.warnings {
        eprintln!("warning: {w}");
    }
    if !quiet {
        eprintln!("wrote {} ({}); read back, its tool point is the model's to {:.1e} m over 64 configurations", s.out.display(), s.format, s.round_trip_m);
        if let (Some(gaps), Some(other)) = (&s.against, &job.against) {
            eprintln!("joint by joint against {} (each frame in its parent's, zero joint angles):", other.display());
            for g in gaps {
                let what = if g.joint > gaps.len() - 1 { "flange".to_string() } else { format!("joint {}", g.joint) };
                eprintln!("  {what:<8} {:>9.4} mm {:>9.4}°", g.position_mm, g.rotation_deg);
            }
        }
    }
    Ok(())
}
