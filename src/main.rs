//! The `twincal` command line.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use twincal::cli::{self, AngleArg, BenchTarget, StudyTarget};

#[derive(Parser)]
#[command(name = "twincal", version, about = "Digital twin and calibration of serial arms measured with a draw-wire sensor")]
struct Cli {
    /// No progress bars or summaries on stderr (warnings and errors are still printed).
    #[arg(long, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

/// Which model a calibration fits.
#[derive(clap::Args)]
struct ModelArgs {
    /// irb120 (embedded URDF), a .urdf path, or generic6r (no nominal).
    #[arg(long, default_value = "irb120")]
    model: String,
    /// Parametrisation of a nominal model: hayati (D-H, β on parallel axes; the default), dh (papers' 24)
    /// or frame. Not for generic6r.
    #[arg(long)]
    params: Option<String>,
}

/// What loads the joints, for the torque-driven effects.
#[derive(clap::Args)]
struct LoadArgs {
    /// URDF whose inertial data give the static joint torques (default: the model's own robot;
    /// needed for joint_compliance with generic6r).
    #[arg(long)]
    robot: Option<PathBuf>,
    /// Payload on the flange, kg.
    #[arg(long, allow_negative_numbers = true)]
    payload_kg: Option<f64>,
    /// Payload centre of mass in the flange frame, mm (x,y,z).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_name = "X,Y,Z")]
    payload_com_mm: Option<Vec<f64>>,
    /// Draw-wire cable tension from the sensor's data sheet, N (0: ignored).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    cable_tension_n: f64,
}

impl LoadArgs {
    fn into_cli(self) -> cli::LoadArgs {
        cli::LoadArgs { robot: self.robot, payload_kg: self.payload_kg, payload_com_mm: self.payload_com_mm, cable_tension_n: self.cable_tension_n }
    }
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
    /// Calibrate a model on measured data (dataset folder, CSV or xlsx).
    Calibrate {
        /// Dataset folder (DIR/dataset.csv, with truth.json when the twin made it), CSV, or xlsx (file.xlsx#Sheet).
        #[arg(long)]
        data: PathBuf,
        /// Unit of the joint angles in the data (auto: degrees unless they look like radians).
        #[arg(long, value_enum, default_value_t = AngleArg::Auto)]
        angles: AngleArg,
        /// lm, ekf, pf, pso, rbf, dsade-gkan (Evo-NPH; ablations dsade-gkan-v1, -v2, -v3), pso-ekf-awnn (ablations: pso-ekf-awnn-v1 .. -v5; pso-ekf-awnn-x: network also on temperature and backlash flanks, network/LM alternations).
        #[arg(long, default_value = "lm")]
        method: String,
        #[command(flatten)]
        model: ModelArgs,
        /// Hold out this fraction instead of the dataset's split column (0 trains on every row).
        #[arg(long, allow_negative_numbers = true)]
        test_fraction: Option<f64>,
        /// Seed of the hold-out split and of the stochastic methods.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Sensor geometry guess, mm: exit x,y,z, length offset, tool x,y,z (default: estimated).
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_name = "EX,EY,EZ,OFFSET,TX,TY,TZ")]
        sensor_guess: Option<Vec<f64>>,
        /// Relative singular-value threshold for identifiability.
        #[arg(long, default_value_t = 1e-7, allow_negative_numbers = true)]
        rank_tol: f64,
        /// Budget of the stochastic methods and of the generic model's global search (1 = default).
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
        effort: f64,
        /// The calibrated model and its report.
        #[arg(long, default_value = "result.json")]
        out: PathBuf,
        /// Also write the calibrated model as a URDF.
        #[arg(long)]
        urdf: Option<PathBuf>,
        /// Rerun recording of the residual field before and after, convergence and parameters.
        #[arg(long)]
        rrd: Option<PathBuf>,
        /// Self-contained HTML report (tables and plots, opens offline in any browser).
        #[arg(long)]
        report: Option<PathBuf>,
        /// Accuracy limit for the verdict in --out: RMSE of the test rows after calibration, mm.
        #[arg(long, allow_negative_numbers = true)]
        max_test_rmse_mm: Option<f64>,
        /// Accuracy limit for the verdict in --out: largest |residual| of the test rows, mm.
        #[arg(long, allow_negative_numbers = true)]
        max_test_max_mm: Option<f64>,
        /// Non-geometric effects to fit with the geometry: compliance, backlash, thermal,
        /// eccentricity, nonlinearity, each optionally on one joint (backlash:2).
        #[arg(long, value_delimiter = ',')]
        effects: Vec<String>,
        #[command(flatten)]
        loads: LoadArgs,
    },
    /// From measured data: what the geometric model gets wrong, which effect causes it, how big
    /// it is and how much better the extended model predicts unseen rows.
    Diagnose {
        /// Dataset folder, CSV or xlsx (q1..q6, L; optional t, temp). No truth file is read.
        #[arg(long)]
        data: PathBuf,
        /// Unit of the joint angles in the data.
        #[arg(long, value_enum, default_value_t = AngleArg::Auto)]
        angles: AngleArg,
        #[command(flatten)]
        model: ModelArgs,
        #[command(flatten)]
        loads: LoadArgs,
        /// Candidate effects (default: every kind the data support).
        #[arg(long, value_delimiter = ',')]
        candidates: Vec<String>,
        /// Cross-validation folds (contiguous blocks of acquisition order).
        #[arg(long, default_value_t = 5)]
        folds: usize,
        /// Family-wise significance level of each selection step.
        #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
        alpha: f64,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// The diagnosis report.
        #[arg(long, default_value = "report.json")]
        out: PathBuf,
        /// The extended model, saved like any calibration result.
        #[arg(long, default_value = "diagnosed.json")]
        result: PathBuf,
        /// Rerun recording of the evidence.
        #[arg(long)]
        rrd: Option<PathBuf>,
        /// Self-contained HTML report (tables and plots, opens offline in any browser).
        #[arg(long)]
        report: Option<PathBuf>,
        /// Accuracy limit for the verdict in --out: the final cross-validated held-out RMSE, mm.
        #[arg(long, allow_negative_numbers = true)]
        max_test_rmse_mm: Option<f64>,
    },
    /// Predict cable lengths with a calibrated model.
    Predict {
        /// A result.json written by `calibrate`.
        #[arg(long)]
        model: PathBuf,
        /// Joint angles, with or without measured lengths (dataset folder, CSV or xlsx).
        #[arg(long)]
        data: PathBuf,
        /// Unit of the joint angles in the data.
        #[arg(long, value_enum, default_value_t = AngleArg::Auto)]
        angles: AngleArg,
        #[arg(long, default_value = "predictions.csv")]
        out: PathBuf,
    },
    /// Inverse kinematics on a calibrated model (geometry + corrector), per-target status; on a
    /// twin dataset also the true tool-point error of each solution against nominal and floor.
    Ik {
        /// A result.json written by `calibrate`.
        #[arg(long)]
        model: PathBuf,
        /// CSV of target points with columns x,y,z in mm (the calibration's frame).
        #[arg(long)]
        targets: Option<PathBuf>,
        /// N reachable targets: the true tool points of random configurations inside the
        /// calibrated joint ranges (the twin's, else the model's own).
        #[arg(long)]
        random: Option<usize>,
        /// Twin dataset folder with truth.json (default: the result's data, when it has one).
        #[arg(long)]
        twin: Option<PathBuf>,
        /// Do not validate on a twin even when a truth file is found.
        #[arg(long)]
        no_twin: bool,
        /// analytic, neural, hybrid or all.
        #[arg(long, default_value = "all")]
        jacobian: String,
        /// Model residual (mm) at which a target counts as solved.
        #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
        tol_mm: f64,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Per-target solutions.
        #[arg(long, default_value = "ik.csv")]
        out: PathBuf,
    },
    /// Compare methods over seeds: accuracy and time tables with Wilcoxon signed-rank tests.
    Compare {
        #[arg(long)]
        data: PathBuf,
        /// Unit of the joint angles in the data.
        #[arg(long, value_enum, default_value_t = AngleArg::Auto)]
        angles: AngleArg,
        #[arg(long, value_delimiter = ',', default_value = "lm,ekf,pf,pso,rbf")]
        methods: Vec<String>,
        /// Number of seeds (1 to 1000).
        #[arg(long, default_value_t = 30, allow_negative_numbers = true)]
        seeds: u64,
        #[command(flatten)]
        model: ModelArgs,
        /// Test fraction of each seed's re-split, in (0, 1) (default: the dataset's split size, else 0.2).
        #[arg(long, allow_negative_numbers = true)]
        test_fraction: Option<f64>,
        /// Effort of the stochastic methods (1 = full budget).
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
        effort: f64,
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
    /// or `awnn` (PSO-EKF-AWNN: speed, accuracy, data efficiency, sensitivity).
    Bench {
        #[arg(value_enum, default_value_t = BenchTarget::Twin)]
        what: BenchTarget,
        /// twin: scenario TOML (default: the embedded one).
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Repetitions, 1 to 1000 (the median is reported).
        #[arg(long, default_value_t = 3, allow_negative_numbers = true)]
        repeat: usize,
        /// calib: number of seeds for the accuracy targets, 1 to 1000 (default 20).
        #[arg(long, allow_negative_numbers = true)]
        seeds: Option<u64>,
        /// calib: also time `compare` over 30 seeds with every method.
        #[arg(long)]
        compare: bool,
    },
    /// Studies of the acquisition protocol on the simulated tour: `hold` (bias and spread of the
    /// readings against the hold time and the approach speed).
    Study {
        #[arg(value_enum)]
        what: StudyTarget,
        /// Scenario TOML; default: the embedded irb120_evo_nph scenario.
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Hold times, s.
        #[arg(long, value_delimiter = ',', default_value = "0.02,0.05,0.1,0.2,0.5,1,2", allow_negative_numbers = true)]
        holds: Vec<f64>,
        /// Approach speeds, fractions of the URDF speed limits.
        #[arg(long, value_delimiter = ',', default_value = "0.05,0.2,0.5", allow_negative_numbers = true)]
        speeds: Vec<f64>,
        /// The first this many poses of the scenario's tour.
        #[arg(long, default_value_t = 60)]
        poses: usize,
        /// Rerun recording of bias and spread against the hold time.
        #[arg(long)]
        rrd: Option<PathBuf>,
    },
}

fn main() -> ExitCode {
    let args = Cli::parse();
    if let Err(e) = twincal::io::install_signal_cleanup() {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    let result = match args.command {
        Command::Generate { scenario, out, rrd, seed } => cli::generate(scenario.as_deref(), &out, rrd.as_deref(), seed, args.quiet),
        Command::Calibrate {
            data,
            angles,
            method,
            model: ModelArgs { model, params },
            test_fraction,
            seed,
            sensor_guess,
            rank_tol,
            effort,
            out,
            urdf,
            rrd,
            report,
            max_test_rmse_mm,
            max_test_max_mm,
            effects,
            loads,
        } => cli::calibrate(
            &cli::CalibrateArgs {
                data,
                angles,
                method,
                model,
                params,
                test_fraction,
                seed,
                sensor_guess,
                rank_tol,
                effort,
                out,
                urdf,
                rrd,
                effects,
                loads: loads.into_cli(),
                report,
                max_test_rmse_mm,
                max_test_max_mm,
            },
            args.quiet,
        ),
        Command::Diagnose {
            data,
            angles,
            model: ModelArgs { model, params },
            loads,
            candidates,
            folds,
            alpha,
            seed,
            out,
            result,
            rrd,
            report,
            max_test_rmse_mm,
        } => cli::diagnose(
            &cli::DiagnoseArgs {
                data,
                angles,
                model,
                params,
                loads: loads.into_cli(),
                candidates,
                folds,
                alpha,
                seed,
                out,
                result,
                rrd,
                report,
                max_test_rmse_mm,
            },
            args.quiet,
        ),
        Command::Predict { model, data, angles, out } => cli::predict(&model, &data, angles, &out, args.quiet),
        Command::Compare { data, angles, methods, seeds, model: ModelArgs { model, params }, test_fraction, effort, out, rrd } => cli::compare(
            &cli::CompareArgs {
                data: &data,
                angles,
                methods: &methods,
                seeds,
                model: &model,
                params: params.as_deref(),
                test_fraction,
                effort,
                out: out.as_deref(),
                rrd: rrd.as_deref(),
            },
            args.quiet,
        ),
        Command::Ik { model, targets, random, twin, no_twin, jacobian, tol_mm, seed, out } => {
            twincal::ikcmd::ik(&twincal::ikcmd::IkArgs { model, targets, random, twin, no_twin, jacobian, tol_mm, seed, out }, args.quiet)
        }
        Command::Study { what, scenario, holds, speeds, poses, rrd } => cli::study(
            what,
            scenario.as_deref(),
            &twincal::twin::study::HoldStudy { holds_s: holds, speed_fractions: speeds, poses },
            rrd.as_deref(),
            args.quiet,
        ),
        Command::Bench { what, scenario, repeat, seeds, compare } => cli::bench_command(what, scenario.as_deref(), repeat, seeds, compare, args.quiet),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
