//! A user's request run end to end on files, as the command line and Python both run it: read
//! the inputs (a dataset folder, CSV or xlsx sheet, a scenario, a model), run the calibration or
//! the diagnosis, and stage every output in one [`OutputSet`](crate::output::OutputSet) so that they
//! appear together or not at all, none over a file the run reads.
//!
//! Recordings for the Rerun viewer come through [`Recordings`], which the `twincal-viz` package
//! implements: this library writes none itself. What a run prints is its caller's.

mod calibrate;
mod compare;
mod compensate;
mod controller_data;
mod diagnose;
mod export;
mod files;
mod iso9283;
mod plan;
mod predict;
mod program;
mod replay;
pub mod shard;
pub mod tcp;

pub use calibrate::{calibrate_loaded, write_calibration, CalibrateJob, Calibration};
pub use compare::{
    check_seeds, compare, finish as finish_comparison, reduce_compare, CompareConfig, CompareItem, CompareJob, CompareRequest, CompareRun, Compared,
    Comparison, MAX_COMPARE_JOBS, MAX_SEEDS, MIN_SEEDS_FOR_TEST,
};
pub use compensate::{CompensateJob, CompensateSummary};
pub use controller_data::{ControllerDataJob, ControllerDataSummary};
pub use diagnose::{diagnose_loaded, write_diagnosis, DiagnoseJob, Diagnosed};
pub use export::{ExportJob, ExportSummary};
pub use files::{
    check_model_outputs, data_inputs, load_dataset, load_scenario, scenario_inputs, scenario_urdf_path, stage_identified_twin, Figures, NoRecordings,
    Recordings,
};
pub use iso9283::{figures as iso9283_figures, iso9283_table, Iso9283, Iso9283Job, ModelFigures, PoseFigures};
pub use plan::{PlanJob, PLAN_FILE, POSES_FILE, PROGRAM_NAME};
pub use predict::{predicted_readings, prediction_csv, residuals, rotation_residual_deg, Predicted};
pub use program::{ProgramJob, ProgramSummary};
pub use replay::{replay, AfterCalibration, Fidelity, ReplayJob, ReplayRequest, ReplaySummary};
pub use tcp::{TcpJob, UserFrameJob};

#[cfg(test)]
mod tests;
