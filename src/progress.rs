//! Progress of long runs, reported through a trait the command line implements with a bar.

/// Reports progress of long runs (a progress bar in the CLI, nothing in tests).
pub trait Progress: Sync {
    fn start(&self, _total: u64, _what: &str) {}
    fn inc(&self, _n: u64) {}
    fn finish(&self) {}
}

/// No progress reporting.
pub struct Silent;
impl Progress for Silent {}
