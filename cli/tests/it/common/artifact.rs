//! What the artifact tests share: the command line, a scenario of `scenarios/` with its text
//! edited, and the least-squares calibration's options for its arm.

use std::path::{Path, PathBuf};
use std::process::Output;
use twincal::calib::pipeline::{CalibOptions, Method, ModelSpec, Parametrisation};
use twincal::sim::scenario::Scenario;

/// The `twincal` executable run with `args`.
pub fn twincal(args: &[&str]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).output().expect("runs")
}

/// The path of `scenarios/NAME.toml`.
pub fn scenario_path(name: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios")).join(format!("{name}.toml"))
}

/// `scenarios/NAME.toml` with its text edited by `edit`, and its robot.
pub fn scenario(name: &str, edit: &dyn Fn(String) -> String) -> (Scenario, twincal::robot::Robot) {
    let path = scenario_path(name);
    let text = edit(std::fs::read_to_string(&path).unwrap());
    let s = Scenario::from_toml(&text, name).unwrap();
    let robot = s.load_robot(path.parent()).unwrap();
    (s, robot)
}

/// Least squares on the Hayati model of `robot`.
pub fn lm(robot: &twincal::robot::Robot) -> CalibOptions {
    CalibOptions::new(ModelSpec::Nominal { robot: Box::new(robot.clone()), parametrisation: Parametrisation::Hayati }, Method::LM)
}
