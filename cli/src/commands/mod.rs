//! The command line's commands, one file each (kept in the library so tests can call them),
//! and what they share: argument groups, dataset and model loading, progress bars, limits.

mod bench;
mod calibrate;
mod compare;
mod compensate;
mod controller_data;
mod diagnose;
mod export;
mod generate;
pub mod ik;
mod ik_poses;
mod plan;
mod predict;
mod program;
mod replay;
mod study;
mod tcp;

pub use bench::{bench_command, BenchArgs};
use calibrate::print_verdict;
pub use calibrate::{calibrate, calibration_warnings};
pub use compare::{compare, reduce};
pub use compensate::compensate;
pub use controller_data::controller_data;
pub use diagnose::diagnose;
pub use export::export;
pub use generate::generate;
pub use plan::plan;
pub use predict::predict;
pub use program::program;
pub use replay::replay;
pub use study::{study, StudyArgs, StudyTarget};
pub use tcp::{tcp, user_frame};
pub use twincal::jobs::ReplayJob;

use std::path::{Path, PathBuf};
use std::time::Instant;
pub use twincal::dataset::AngleUnit;
use twincal::error::{Error, Result};
pub use twincal::jobs::{
    check_seeds, data_inputs, load_scenario, scenario_urdf_path, CalibrateJob, CompareJob, CompareRequest, CompareRun, DiagnoseJob, Figures, MAX_COMPARE_JOBS,
    MAX_SEEDS,
};
use twincal::jobs::{load_dataset, scenario_inputs};
use twincal::output::{check_outputs, OutputSet};
pub use twincal::requests::{ModelChoice, Reading};
use twincal::sim::generate::{generate as run_generate, stage_outputs, Generated, Progress, Silent};

/// Most repetitions `bench` accepts.
pub const MAX_REPEAT: usize = 1000;

/// `twincal bench` targets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchTarget {
    /// The twin: settled poses per second, rapier against the quasi-static model.
    Twin,
    /// The calibration core's targets.
    Calib,
    /// The diagnosis: detection and false-alarm rates over hidden-effect scenarios, time.
    Diagnose,
    /// Evo-NPH: DS-ADE speed, ablations with the truth, DE engines on one objective (Table 10).
    Dsade,
    /// Inverse kinematics: Jacobian variants, time per query, true error on the twin.
    Ik,
    /// PSO-EKF-AWNN: stage times against LM, accuracy and truth over seeds, data efficiency,
    /// sensitivity to Q, R and the learning rate, HSR-RobotCali.
    Awnn,
    /// Real measured data: HSR generic model per search seed and its diagnosis, RobotCali
    /// methods over random splits with and without the outlier screen.
    Real,
    /// Diagnose on the UR10's 11 911-row series a (../shared/data, sorted by t): median wall
    /// time of --repeat runs against the 60 s target, and what it named; then rows against
    /// seconds of the generic arm on its first 1 000 to 10 000 rows (targets 20 s and 90 s)
    DiagnoseUr10,
    /// The joint angles' logging error as a noise model: lm, dsade-gkan and pso-ekf-awnn with
    /// and without it on realistic acquisitions (sweeps, 0.1° logging), true error and time.
    NoiseModel,
    /// Replay of 1 000 rows through the scenario's acquisition (default: the embedded
    /// scenario's simulated tour) against 5 s, and the identified twin's cost against 1 s.
    Replay,
    /// Compensation verified on executed poses: nominal against compensated commands for unseen
    /// targets on the twin, AP over seeds for geometric and non-geometric scenarios, cable and
    /// tracker; and compensate's time for 10 000 targets.
    Compensate,
    /// Robot programs filtered and executed on the twin: RAPID on an IRB 120, URScript on a
    /// UR10, KRL on a KUKA-like arm, each written offline in a work object with a tool, as
    /// written and filtered, interpreted by a nominal controller, AP over seeds; and the filter's
    /// time for a 10 000-target module.
    Programs,
    /// Measurement plans verified on the twin: planned against random feasible poses, each
    /// calibrated, true error on independent test poses over seeds; and plan's time for 30 poses
    /// of 10 000 candidates.
    Plan,
    /// Measurement plans against hidden compliance alone (part of `plan`): does a plan that
    /// includes the effect (and, with payloads to choose from, the payload per pose) name and size
    /// it where random feasible poses do not?
    PlanHidden,
    /// Set-up changes of a tracker campaign on the twin: a tracker re-stationed, re-registered or
    /// bumped found at its rows and sized, no false alarm on one that never moved or on a
    /// misfit; a 3-station campaign of 3 000 poses timed.
    Stations,
    /// A ball seated in an artifact's sockets on the twin: calibrated from the seated rows
    /// alone, judged on unseen tracker points of the same arm beside the nominal arm and a
    /// tracker calibration from as many rows.
    Sockets,
    /// A touch probe on a block's faces on the twin: calibrated from the contacts alone, judged
    /// on unseen tracker points of the same arm beside the nominal arm and a tracker calibration
    /// from as many rows.
    Planes,
}

/// `--shard i/N --shard-out PART.jsonl` of `study hold` and `bench diagnose` (see
/// [`twincal::jobs::shard`]).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct ShardArgs {
    /// Run only the work items with id % N == i (in a fixed order, each with its own seed),
    /// appending each to --shard-out as it finishes; `twincal reduce` joins the parts.
    /// Re-running a shard skips the items its file holds.
    #[arg(long, value_name = "i/N", allow_hyphen_values = true)]
    pub shard: Option<String>,
    /// The shard's partial file (JSONL; needed with --shard).
    #[arg(long)]
    pub shard_out: Option<PathBuf>,
}

/// A terminal progress bar (hidden when stderr is not a terminal).
pub struct Bar(indicatif::ProgressBar);

impl Bar {
    pub fn new() -> Self {
        let pb = indicatif::ProgressBar::new(0);
        pb.set_style(
            indicatif::ProgressStyle::with_template("{msg:>16} [{bar:40}] {pos}/{len} ({per_sec}, eta {eta})")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        Bar(pb)
    }
}

impl Default for Bar {
    fn default() -> Self {
        Self::new()
    }
}

impl Progress for Bar {
    fn start(&self, total: u64, what: &str) {
        self.0.set_length(total);
        self.0.set_position(0);
        self.0.set_message(what.to_string());
    }
    fn inc(&self, n: u64) {
        self.0.inc(n);
    }
    fn finish(&self) {
        self.0.finish_and_clear();
    }
}

pub fn progress(quiet: bool) -> Box<dyn Progress> {
    if quiet {
        Box::new(Silent)
    } else {
        Box::new(Bar::new())
    }
}

fn check_repeat(repeat: usize) -> Result<()> {
    if !(1..=MAX_REPEAT).contains(&repeat) {
        return Err(Error::Invalid(format!("--repeat must be between 1 and {MAX_REPEAT}, got {repeat}")));
    }
    Ok(())
}

/// Above this many times a floor that is only a lower bound (no repeated configurations), the
/// ratio says nothing about the fit and is not printed.
const MAX_BOUND_RATIO: f64 = 10.0;

/// Loads a calibrated model (result.json); its errors are labelled `model PATH`.
fn load_model(path: &Path) -> Result<twincal::calib::pipeline::CalibResult> {
    twincal::calib::pipeline::CalibResult::load(path)
}
