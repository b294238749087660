//! What a Rust user of the library imports first: `use twincal::prelude::*;`.
//!
//! The twin's scenario and robot, the dataset, the requests as the command line and Python take
//! them, the calibration and the diagnosis with their options and results, the compensation of
//! targets, and the crate's error.
//!
//! The whole job in a few lines: a short acquisition of the embedded scenario's twin, a
//! calibration as `twincal calibrate` runs it, the diagnosis of the same rows, and the commands
//! that put the calibrated arm's tool on a point.
//!
//! ```
//! use twincal::prelude::*;
//!
//! // The twin: the embedded IRB 120 scenario, 60 poses of which 15 held out.
//! let (mut scenario, robot) = Scenario::default_embedded()?;
//! scenario.sampling.poses = 60;
//! scenario.sampling.test = 15;
//! let generated = generate(&scenario, &robot, &Silent)?;
//!
//! // `twincal calibrate`'s default request: LM on the Hayati model.
//! let (options, _limits) = CalibrateRequest::default().options()?;
//! let result = calibrate(&generated.dataset, None, &options)?;
//! let after = result.evaluation.metrics.test_after.as_ref().expect("held-out rows");
//! let before = result.evaluation.metrics.test_before.as_ref().expect("held-out rows");
//! assert!(after.rmse < 0.5 * before.rmse);
//!
//! // The calibrated model's prediction of a row's reading (the cable length, mm).
//! let row = &generated.dataset.rows[0];
//! let predicted = result.predict_mm(&row.q_deg);
//! assert!((predicted - row.reading_mm[0]).abs() < 0.5);
//!
//! // `twincal diagnose`: what the geometric model misses, named by cause.
//! let (options, _limit) = DiagnoseRequest::default().options()?;
//! let (diagnosis, _model) = diagnose(&generated.dataset, &options, &|_| {})?;
//! println!("{}", diagnosis.verdict);
//!
//! // `twincal compensate`: the joint commands that put the calibrated tool on a point.
//! let nominal = nominal_x(&result);
//! let compensator = Compensator::new(&result, &nominal, result.torque_model.clone(), 0.001, 0.001)?;
//! let target = compensator.predicted(&[0.1, 0.2, 0.3, 0.0, 0.5, 0.0]);
//! let done = compensator.compensate(&[Target::Point(target)]);
//! assert_eq!(done[0].status, Status::Reachable);
//! # Ok::<(), twincal::Error>(())
//! ```

pub use crate::calib::effects::{EffectChoice, EffectKind};
pub use crate::calib::pipeline::{calibrate, CalibOptions, CalibResult, Method, ModelSpec, Parametrisation};
pub use crate::compensate::{nominal_x, Compensated, Compensator, Status, Target};
pub use crate::dataset::{Dataset, ReadOptions};
pub use crate::diagnose::{diagnose, DiagnoseOptions, Diagnosis};
pub use crate::error::{Error, Result};
pub use crate::measurement::{Euler, Measurement};
pub use crate::progress::Silent;
pub use crate::requests::{CalibrateRequest, DiagnoseRequest};
pub use crate::robot::Robot;
pub use crate::sim::generate::generate;
pub use crate::sim::scenario::Scenario;
