//! Progress of long runs, reported through a trait the command line implements with a bar.

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
