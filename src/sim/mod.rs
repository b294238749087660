//! The digital twin: everything that makes a dataset with known true parameters.
//!
//! [`scenario`] (the TOML file: robot, true errors, effects, instrument, acquisition) →
//! [`twin`] (rapier multibody settled at each pose under the [`effects`]: compliance, backlash,
//! thermal drift, eccentricity; the simulated tour) → [`instrument`] (the draw-wire's reading of
//! the settled tool point) → [`generate`] (the dataset and its truth file, byte-identical for a
//! scenario and seed). Nothing here reads a calibration: the calibration side sees only the
//! dataset, never these settings.

pub mod artifact;
pub mod effects;
pub mod generate;
pub mod instrument;
pub mod planes;
pub mod pose_list;
pub mod scenario;
pub mod study;
pub mod twin;
pub mod workspace;
