//! Progress of long runs, reported through a trait the command line implements with a bar, and
//! a way to stop them: [`request_stop`] makes every running computation of the process unwind at
//! its next check ([`check_stop`], in the fits' residuals and Jacobians), dropping what it staged.
//! Python's Ctrl-C uses it; the command line ends its process instead.

use std::sync::atomic::{AtomicBool, Ordering};

/// Reports progress of long runs (a progress bar in the CLI, nothing in tests).
pub trait Progress: Sync {
    /// A stage of `total` steps, described by `what`, begins.
    fn start(&self, _total: u64, _what: &str) {}
    /// `n` more steps are done.
    fn inc(&self, _n: u64) {}
    /// The stage is over.
    fn finish(&self) {}
}

/// No progress reporting.
pub struct Silent;
impl Progress for Silent {}

static STOP: AtomicBool = AtomicBool::new(false);

/// The unwinding payload of a computation stopped by [`request_stop`].
#[derive(Debug)]
pub struct Stopped;

/// Asks every running computation to stop at its next [`check_stop`].
pub fn request_stop() {
    STOP.store(true, Ordering::SeqCst);
}

/// Lets computations run again (once the stopped ones have unwound).
pub fn clear_stop() {
    STOP.store(false, Ordering::SeqCst);
}

/// Unwinds the calling computation with a [`Stopped`] payload when a stop was requested (no
/// panic message: `resume_unwind` skips the panic hook). Cheap: one atomic load.
#[inline]
pub fn check_stop() {
    if STOP.load(Ordering::Relaxed) {
        std::panic::resume_unwind(Box::new(Stopped));
    }
}
