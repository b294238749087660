//! No nominal under a tracker: the generic arm (`--model generic6r`; seven joints alike) found
//! from tracker points and 6-D poses alone, against the calibration seeded with the arm's URDF.
//! The twin's tracker scenarios (a spherical-wrist IRB 120, a UR5 and a UR10 with three
//! parallel axes, a 7-joint WAM) and the real UR5, WAM and UR10 files (../shared, skipped when
//! absent): the generic arm predicts unseen rows within 5 % of the URDF-seeded calibration, more
//! than one of its finalists reaches the best basin, and the URDF it exports, taken as the
//! nominal of a later run, calibrates to the same held-out error.

use twincal::calib::pipeline::{calibrate, CalibOptions, CalibResult, Method, ModelSpec, Parametrisation};
use twincal::dataset::Dataset;
use twincal::robot::Robot;

/// The held-out rows' mean position error |Δp|, mm.
fn held_out(r: &CalibResult) -> f64 {
    r.evaluation.metrics.test_position_after.as_ref().expect("held-out rows").mae
}

fn options(spec: ModelSpec, seed: u64, test_fraction: Option<f64>) -> CalibOptions {
    let mut o = CalibOptions::new(spec, Method::LM);
    o.seed = seed;
    o.split.test_fraction = test_fraction;
    o
}

/// The generic arm against the URDF-seeded calibration on `data`; returns both held-out errors.
fn generic_against_urdf(what: &str, data: &Dataset, robot: &Robot, seed: u64, test_fraction: Option<f64>) -> (f64, f64) {
    let urdf = calibrate(data, None, &options(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), seed, test_fraction)).unwrap();
    let generic = calibrate(data, None, &options(ModelSpec::Generic, seed, test_fraction)).unwrap();
    let (g, u) = (held_out(&generic), held_out(&urdf));
    let search = generic.solve.search.as_ref().expect("the generic search reports itself");
    eprintln!("{what}: held-out mean |dp| generic {g:.4} mm, URDF-seeded {u:.4} mm; search {search:?}");
    assert!(g <= 1.05 * u, "{what}: the generic arm predicts unseen rows at {g:.4} mm against {u:.4} mm with the URDF");
    assert!(search.in_best_basin >= 2 && search.in_best_basin <= search.finalists, "{what}: {search:?}");
    assert_eq!(generic.model.chain.n_joints, robot.joints.len(), "{what}");
    // The generic arm written as a URDF is a nominal a later run starts from.
    let text = twincal::export::urdf::urdf(&generic.model, &generic.x, None, "found");
    let found = Robot::from_urdf_str(&text, "found").unwrap();
    let again = calibrate(data, None, &options(ModelSpec::nominal(found, Parametrisation::Hayati), seed, test_fraction)).unwrap();
    let before = again.evaluation.metrics.test_position_before.as_ref().unwrap().mae;
    assert!((before - g).abs() < 0.01 * g + 1e-4, "{what}: the exported arm, placed, predicts at {before:.4} mm against the generic {g:.4} mm");
    assert!(held_out(&again) <= 1.02 * g + 1e-4, "{what}: calibrated from the exported arm {:.4} mm against {g:.4} mm", held_out(&again));
    (g, u)
}

/// The twin's four tracker arms, points and poses, with their declared test rows.
#[test]
fn the_generic_arm_matches_the_urdf_seeded_calibration_on_the_twins_trackers() {
    for name in ["irb120_tracker", "ur5_tracker", "ur10_pose", "wam_tracker"] {
        let (data, robot) = crate::datasets::generated(name, 1, "");
        generic_against_urdf(name, &data, &robot, 0, None);
    }
}

/// The real UR5, WAM and UR10 (series b) files, a fifth of the rows held out.
#[test]
fn the_generic_arm_matches_the_urdf_seeded_calibration_on_real_tracker_files() {
    let root = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    for (rel, urdf) in [
        ("data/ur5-lasertracker/ur5_grid_pool.csv", root.join("../shared/reference/ur_description/ur5_robot.urdf")),
        ("data/wam-lasertracker/wam_grid.csv", root.join("urdf/wam.urdf")),
        ("data/ipa-ur10/ur10_series_b.csv", root.join("urdf/ur10.urdf")),
    ] {
        let Some(path) = crate::datasets::shared(rel) else { continue };
        if !urdf.exists() {
            crate::datasets::skip(&urdf);
            continue;
        }
        let data = Dataset::load(&path).unwrap();
        let robot = Robot::from_urdf_file(&urdf).unwrap();
        generic_against_urdf(rel, &data, &robot, 0, Some(0.2));
    }
}
