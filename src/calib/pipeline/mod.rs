//! `twincal calibrate` as a pipeline of named stages:
//!
//! ```text
//! rows ─ split ─► sensor placement ─► identifiability ─► noise estimate ─► solve ─► uncertainty
//!                 (placement.rs)       (identify.rs)                        (method.rs)
//!      ─► metrics ─► truth comparison (equivalent.rs) ─► CalibResult
//! ```
//!
//! Each stage is a function of its own below or in the module named; the method is a
//! [`Solver`] value that carries its own settings.

pub mod artifact;
mod calibrate;
mod effect_blocks;
pub mod equivalent;
pub mod generic;
mod options;
pub mod placement;
pub mod register;
mod result;
pub mod setup;
mod split;
mod stages;

pub use crate::calib::fit::identify::{identify, still_joints, STILL_SPAN_DEG};
pub use crate::calib::methods::{Method, Solver};
pub use crate::dataset::truth::TruthFile;
pub use calibrate::*;
pub use effect_blocks::*;
pub use options::{
    check_inertial, flange_gap_mm, CalibOptions, FloorOptions, FreeParams, LoadOptions, ModelSpec, Parametrisation, ScreenOptions, SplitBy, SplitOptions,
    StationSource, DEFAULT_EFFORT, DEFAULT_OUTLIER_K, DEFAULT_RANK_TOL, OTHER_ARM_MM,
};
pub use register::{Registration, DEFAULT_REGISTER_ROWS};
pub use result::*;
pub use split::*;
pub use stages::*;
