//! Benchmarks beyond `bench calib` / `bench diagnose` (which still live with their commands in
//! `cli`): each prints its targets beside what it measured.
//!
//! * [`evo`]: `bench dsade` and `bench ik` (Evo-NPH: DS-ADE + GKAN, the hybrid-Jacobian IK);
//! * [`awnn`]: `bench awnn` (PSO-EKF-AWNN and its ablations);
//! * [`real`]: `bench real` (the real measured datasets in ../shared/data).

pub mod awnn;
pub mod evo;
pub mod real;
