//! The integration tests, one test binary (one link of the library and the command line
//! instead of one per file): each module is a file of tests, `common` and `datasets` their
//! shared helpers. Run one file's tests with `cargo test --release --test it NAME::`.

mod common;
mod datasets;

mod architecture;
mod arms;
mod calibrate;
mod cli;
mod compensate;
mod diagnose;
mod docs;
mod evonph;
mod export;
mod fuzz;
mod generic;
mod ik;
mod inputs;
mod iso9283;
mod measurement;
mod plan;
mod planes;
mod pose;
mod programs;
mod realdata;
mod recordings;
mod replay;
mod seven_joints;
mod shards;
mod sockets;
mod stations;
mod tcp;
mod tour;
mod twin;
