//! The command line: its commands and options (what `twincal --help` shows), and the run of
//! one parsed command. `main` adds the process's concerns (signals, exit codes); the Python
//! package runs the same commands in its process.

use crate::commands;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser)]
#[command(name = "twincal", version, about = "Digital twin, calibration and diagnosis of serial arms measured with a draw-wire sensor or a laser tracker")]
pub struct Cli {
    /// No progress bars or summaries on stderr (warnings and errors are still printed).
    #[arg(long, global = true)]
    pub quiet: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
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
        #[arg(long, allow_negative_numbers = true)]
        seed: Option<u64>,
        /// Measure these poses instead of sampling them: a pose list (columns q1..qN in
        /// degrees, as `twincal plan` writes it), in its order, none held out.
        #[arg(long)]
        poses: Option<PathBuf>,
    },
    /// Plan the measurement poses worth measuring for a scenario's arm, instrument and cell:
    /// feasible candidates (limits, collisions, keep-out, line of sight, range), the
    /// calibration's identifiable parameters, an optimal design and a short tour.
    Plan(twincal::jobs::PlanJob),
    /// Calibrate a model on measured data (dataset folder, CSV or xlsx).
    Calibrate(commands::CalibrateJob),
    /// From measured data: what the geometric model gets wrong, which effect causes it, how big
    /// it is and how much better the extended model predicts unseen rows.
    Diagnose(commands::DiagnoseJob),
    /// The twin driven through a measured acquisition: per row its reading beside the measured
    /// one, and how far apart they are (what the simulation gets wrong).
    Replay(commands::ReplayJob),
    /// Write a calibrated model for a controller or driver: URDF, a per-joint frame table, a
    /// standard or modified D-H table, or the ROS UR driver's kinematics YAML; read back and
    /// checked before it is written, with what it cannot carry named.
    Export(twincal::jobs::ExportJob),
    /// Write a pose list (plan's poses.csv, or any list generate --poses reads) as a measurement
    /// program the controller runs as it is: ABB RAPID, KUKA KRL or URScript, joint moves in the
    /// list's order, a hold and a wait until each pose is measured.
    Program(twincal::jobs::ProgramJob),
    /// The N-point TCP: the tool's tip on the flange from four or more configurations holding
    /// it at one fixed point (or several), with its accuracy from the residuals; on the nominal
    /// arm or a calibration's (--model).
    Tcp(twincal::jobs::TcpJob),
    /// The 3-point user frame: a work object's frame from the tool's tip touched at its origin,
    /// a point on its +x axis and a point on its xy plane, with the accuracy the tool gives it.
    UserFrame(twincal::jobs::UserFrameJob),
    /// What a controller that takes no new kinematic model can be given of a calibration
    /// (`calibrate --controller-subset`): the joints' zero offsets, the tool and the instrument's
    /// frame, as RAPID tooldata / wobjdata, KRL FRAMEs for TOOL_DATA / BASE_DATA, or URScript.
    ControllerData(twincal::jobs::ControllerDataJob),
    /// The joint commands that make the calibrated arm reach a program's targets (points in the
    /// base frame, or joint targets taught on the nominal model), with the payload it runs with:
    /// per target the command, its status, the predicted residual and the filtered Cartesian
    /// target for a controller that applies its own nominal kinematics.
    Compensate(twincal::jobs::CompensateJob),
    /// ISO 9283 pose accuracy (AP), repeatability (RP), distance accuracy (AD) and the
    /// orientation error of measured poses against one or more models' commanded positions
    /// (before and after a calibration).
    Iso9283(twincal::jobs::Iso9283Job),
    /// Predict readings (cable lengths or tracker points) with a calibrated model.
    Predict {
        /// A result.json written by `calibrate`.
        #[arg(long)]
        model: PathBuf,
        /// Joint angles, with or without measured lengths (dataset folder, CSV or xlsx).
        #[arg(long)]
        data: PathBuf,
        #[command(flatten)]
        reading: commands::Reading,
        /// Rows a station the model was not calibrated at is registered on (its first ones, then
        /// not unseen); 0 refuses such a station.
        #[arg(long, default_value_t = twincal::calib::pipeline::DEFAULT_REGISTER_ROWS)]
        register_rows: usize,
        #[arg(long, default_value = "predictions.csv")]
        out: PathBuf,
    },
    /// Inverse kinematics on a calibrated model (geometry + corrector), per-target status; on a
    /// twin dataset also the true tool-point error of each solution against nominal and floor.
    Ik(crate::commands::ik::IkArgs),
    /// Compare methods over seeds: accuracy and time tables with Wilcoxon signed-rank tests.
    Compare(commands::CompareJob),
    /// Join the partial files of `--shard i/N` runs (compare, study hold, bench diagnose): every
    /// item exactly once, then the same table (and compare's --out and --rrd, a hold study's
    /// --rrd) as one run.
    Reduce {
        /// The shards' partial files (JSONL).
        #[arg(required = true)]
        parts: Vec<PathBuf>,
        /// Also write the tables as JSON.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Rerun recording of the accuracy table and the per-seed spread of each method.
        #[arg(long)]
        rrd: Option<PathBuf>,
    },
    /// Benchmarks: `twin` (settled poses per second, rapier against the quasi-static model),
    /// `calib` (LM speed, accuracy over seeds, the full comparison, HSR-RobotCali when present),
    /// `diagnose`, `dsade` (Evo-NPH speed, ablations, DE engines; --seeds, default 30), `ik`,
    /// `awnn` (PSO-EKF-AWNN: speed, accuracy, data efficiency, sensitivity), `real` (the real
    /// datasets in ../shared/data), `diagnose-ur10` (diagnose on the UR10's 11 911-row series,
    /// --repeat runs, against 60 s) or `replay` (1 000 rows replayed through the scenario's
    /// acquisition against 5 s, the identified twin's cost against 1 s).
    Bench(commands::BenchArgs),
    /// Studies of the acquisition protocol on the simulated tour: `hold` (bias and spread of the
    /// readings against the hold time and the approach speed).
    Study(commands::StudyArgs),
}

/// Runs one parsed command line (what `twincal ARGS` does, but for the process's exit code and
/// signal handling, which are `main`'s).
pub fn run(args: Cli) -> twincal::Result<()> {
    let quiet = args.quiet;
    match args.command {
        Command::Generate { scenario, out, rrd, seed, poses } => {
            commands::generate(scenario.as_deref(), &out, rrd.as_deref(), seed, poses.as_deref(), args.quiet)
        }
        Command::Plan(a) => commands::plan(&a, args.quiet),
        Command::Calibrate(a) => commands::calibrate(&a, args.quiet),
        Command::Diagnose(a) => commands::diagnose(&a, args.quiet),
        Command::Predict { model, data, reading, register_rows, out } => commands::predict(&model, &data, &reading, register_rows, &out, args.quiet),
        Command::Compare(a) => commands::compare(&a, args.quiet),
        Command::Reduce { parts, out, rrd } => commands::reduce(&parts, out.as_deref(), rrd.as_deref(), args.quiet),
        Command::Replay(a) => commands::replay(&a, args.quiet),
        Command::Export(a) => commands::export(&a, args.quiet),
        Command::Program(a) => commands::program(&a, args.quiet),
        Command::Tcp(a) => commands::tcp(&a, args.quiet),
        Command::UserFrame(a) => commands::user_frame(&a, args.quiet),
        Command::ControllerData(a) => commands::controller_data(&a, args.quiet),
        Command::Compensate(a) => commands::compensate(&a, args.quiet),
        Command::Iso9283(a) => {
            let e = a.run()?;
            for w in &e.warnings {
                eprintln!("warning: {w}");
            }
            print!("{}", twincal::jobs::iso9283_table(&e));
            Ok(())
        }
        Command::Ik(a) => crate::commands::ik::ik(&a, args.quiet),
        Command::Study(a) => commands::study(&a, args.quiet),
        Command::Bench(a) => commands::bench_command(&a, quiet),
    }
}
