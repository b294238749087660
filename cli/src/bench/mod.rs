//! Every benchmark (`twincal bench TARGET`): each prints its targets beside what it measured.
//! `commands/bench.rs` only checks the options and calls these.
//!
//! * [`twin`]: `bench twin` (the simulated tour, rapier against the quasi-static model);
//! * [`calib`]: `bench calib` (LM's speed and accuracy, the untuned methods, HSR-RobotCali);
//! * [`diagnose`]: `bench diagnose` (speed, detection and false alarms on hidden effects);
//! * [`evo`]: `bench dsade` and `bench ik` (Evo-NPH: DS-ADE + GKAN, the hybrid-Jacobian IK);
//! * [`awnn`]: `bench awnn` (PSO-EKF-AWNN and its ablations);
//! * [`real`]: `bench real` (the real measured datasets in ../shared/data) and `bench
//!   diagnose-ur10` (diagnose on the UR10's 11 911-row series against 60 s), with [`generic`]
//!   (the tracker files without their URDF: the generic arm against the URDF-seeded one);
//! * [`noise`]: `bench noise-model` (the logging error modelled or not, in lm, dsade-gkan and
//!   pso-ekf-awnn, on realistic acquisitions of the twin);
//! * [`replay`]: `bench replay` (1 000 rows replayed against 5 s, the identified twin's cost);
//! * [`sockets`]: `bench sockets` (a ball seated in an artifact's sockets: calibrated from the
//!   seated rows, judged on unseen tracker points);
//! * [`stations`]: `bench stations` (a tracker moved during the acquisition: found, sized, no
//!   false alarm; a 3-station campaign of 3 000 poses timed).

pub mod awnn;
pub mod calib;
pub mod compensate;
pub mod diagnose;
pub mod evo;
pub mod generic;
pub mod noise;
pub mod plan;
pub mod planes;
pub mod programs;
pub mod real;
pub mod replay;
pub mod sockets;
pub mod stations;
pub mod twin;
