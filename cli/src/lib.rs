//! The `twincal` command line over the `twincal` library: the commands and their options (clap),
//! progress bars, the process's signals, benchmarks, sharded runs and Rerun recordings (behind the
//! `rerun` feature). A library too, so the integration tests and the Python package run the same
//! commands in their process.

// As in the library: numeric code indexes several arrays in step, and `!(x > 0.0)` is written
// on purpose so that NaN fails it.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod bench;
pub mod cli;
pub mod commands;
/// Sharded studies (the library's, which `compare` uses too).
pub use twincal::jobs::shard;
pub mod signals;
