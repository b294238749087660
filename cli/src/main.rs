//! The `twincal` command line.

use clap::Parser;
use std::process::ExitCode;
use twincal_cli::cli::Cli;

fn main() -> ExitCode {
    let args = Cli::parse();
    if let Err(e) = twincal_cli::signals::install_signal_cleanup() {
        use std::io::Write;
        let _ = writeln!(std::io::stderr(), "error: {e}");
        return ExitCode::from(2);
    }
    // A reader that closes our stdout early (`| head -1`) ends the command quietly: printing
    // then panics inside the standard library; the hook keeps that panic silent, the unwinding
    // removes any half-written output, and the command exits with 141 (128 + SIGPIPE), what a
    // shell reports for a writer whose pipe closed.
    let default_hook = std::panic::take_hook();
    // Panics the library catches and turns into a clean error (a malformed spreadsheet inside
    // its reader) print nothing either.
    // A stdout or stderr that cannot be written (a full disk, `>/dev/full`) ends the command
    // with a one-line error (when stderr still takes it) and exit code 2, never a panic message.
    std::panic::set_hook(Box::new(move |info| {
        if stream_failure(info.payload()).is_none() && !twincal::output::panics_are_quiet() {
            default_hook(info);
        }
    }));
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || twincal_cli::cli::run(args)));
    let result = match run {
        Ok(r) => r,
        Err(payload) => match stream_failure(payload.as_ref()) {
            Some(StreamFailure::ClosedPipe) => return ExitCode::from(141),
            Some(StreamFailure::Other(what)) => {
                use std::io::Write;
                let _ = writeln!(std::io::stderr(), "error: {what}");
                return ExitCode::from(2);
            }
            None => std::panic::resume_unwind(payload),
        },
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // A stderr that cannot be written (2>/dev/full) must not turn the error into a panic.
            use std::io::Write;
            let _ = writeln!(std::io::stderr(), "error: {e}");
            ExitCode::from(2)
        }
    }
}

/// A standard stream the command could not write.
enum StreamFailure {
    /// The reader closed the pipe (`| head -1`).
    ClosedPipe,
    /// Any other failure, described (e.g. "failed printing to stdout: No space left on device").
    Other(String),
}

/// Whether a panic is the standard library's "failed printing to stdout/stderr", and why.
fn stream_failure(payload: &(dyn std::any::Any + Send)) -> Option<StreamFailure> {
    let text = payload.downcast_ref::<String>().map(String::as_str).or_else(|| payload.downcast_ref::<&str>().copied()).unwrap_or("");
    if text.contains("Broken pipe") || text.contains("os error 32") {
        Some(StreamFailure::ClosedPipe)
    } else if text.starts_with("failed printing to std") {
        Some(StreamFailure::Other(text.to_string()))
    } else {
        None
    }
}
