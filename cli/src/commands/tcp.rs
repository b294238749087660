//! `twincal tcp` and `twincal user-frame`: the tool's own routines (the library's
//! [`twincal::jobs::TcpJob`] and [`twincal::jobs::UserFrameJob`]) and what they print.

use super::*;

/// Fits the tool point and prints it with its accuracy.
pub fn tcp(job: &twincal::jobs::TcpJob, quiet: bool) -> Result<()> {
    let fit = job.run()?;
    if !quiet {
        fit.lines().iter().for_each(|l| eprintln!("{l}"));
        if let Some(p) = &job.out {
            eprintln!("wrote {}", p.display());
        }
    }
    Ok(())
}

/// Finds the user frame and prints it with its accuracy.
pub fn user_frame(job: &twincal::jobs::UserFrameJob, quiet: bool) -> Result<()> {
    let frame = job.run()?;
    if !quiet {
        frame.lines().iter().for_each(|l| eprintln!("{l}"));
        if let Some(p) = &job.out {
            eprintln!("wrote {}", p.display());
        }
    }
    Ok(())
}
