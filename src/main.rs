//! The `twincal` command line.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use twincal::cli;

#[derive(Parser)]
#[command(name = "twincal", version, about = "Digital twin and calibration of serial arms measured with a draw-wire sensor")]
struct Cli {
    /// No progress bars or summaries on stderr.
    #[arg(long, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scenario and write DIR/dataset.csv and DIR/truth.json.
    Generate {
        /// Scenario TOML; default: the embedded irb120_evo_nph scenario.
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Output folder.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Also write a Rerun recording of the arm, cable and tool points.
        #[arg(long)]
        rrd: Option<PathBuf>,
        /// Override the scenario's seed.
        #[arg(long)]
        seed: Option<u64>,
    },
    /// Benchmark the twin: settled poses per second for a scenario with all effects.
    Bench {
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Repetitions (the median is reported).
        #[arg(long, default_value_t = 3)]
        repeat: usize,
    },
}

fn main() -> ExitCode {
    let args = Cli::parse();
    let result = match args.command {
        Command::Generate { scenario, out, rrd, seed } => cli::generate(scenario.as_deref(), &out, rrd.as_deref(), seed, args.quiet),
        Command::Bench { scenario, repeat } => cli::bench(scenario.as_deref(), repeat, args.quiet),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
