//! `twincal program`: a pose list written as a measurement program for the controller (the
//! library's [`twincal::jobs::ProgramJob`]).

use super::*;

/// Writes the program and says which files.
pub fn program(job: &twincal::jobs::ProgramJob, quiet: bool) -> Result<()> {
    let s = job.run()?;
    if !quiet {
        let files: Vec<String> = s.files.iter().map(|f| f.display().to_string()).collect();
        eprintln!("wrote {} ({} program, {} poses)", files.join(" and "), s.format.name(), s.poses);
    }
    Ok(())
}
