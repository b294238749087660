//! SIGINT / SIGTERM: the process's concern, so the command line's and not the library's.

use twincal::{Error, Result};

/// Installs a SIGINT / SIGTERM handler (once per process) that removes every staged temporary
/// output file ([`twincal::output::abandon_staged_and_exit`]) and exits with 128 + the signal number
/// (130 / 143). A commit in progress finishes first.
pub fn install_signal_cleanup() -> Result<()> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    static INSTALLED: std::sync::Once = std::sync::Once::new();
    let mut result = Ok(());
    INSTALLED.call_once(|| {
        let mut signals = match signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) {
            Ok(s) => s,
            Err(e) => {
                result = Err(Error::Invalid(format!("cannot install the SIGINT/SIGTERM handler: {e}")));
                return;
            }
        };
        std::thread::spawn(move || {
            if let Some(sig) = signals.forever().next() {
                let name = if sig == SIGINT { "SIGINT" } else { "SIGTERM" };
                twincal::output::abandon_staged_and_exit(&format!("error: interrupted by {name}; unfinished outputs removed"), 128 + sig);
            }
        });
    });
    result
}
