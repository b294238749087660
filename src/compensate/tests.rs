use super::verify::verify_seed;
use crate::calib::pipeline::{CalibOptions, Method, ModelSpec, Parametrisation};
use crate::sim::scenario::Scenario;

/// The arm of scenario `name` calibrated on its twin's data (LM, Hayati), and its nominal vector.
fn calibrated_on_its_twin(name: &str) -> (crate::calib::pipeline::CalibResult, Vec<f64>) {
    let (s, robot) = scenario(name, "");
    let g = crate::sim::generate::generate(&s, &robot, &crate::sim::generate::Silent).unwrap();
    let r = crate::calib::pipeline::calibrate(&g.dataset, None, &CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM))
        .unwrap();
    let x_nom = super::nominal_x(&r);
    (r, x_nom)
}

fn scenario(name: &str, extra: &str) -> (Scenario, crate::robot::Robot) {
    let path = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios")).join(format!("{name}.toml"));
    let text = std::fs::read_to_string(&path).unwrap().replacen("[sensor]", &format!("{extra}\n[sensor]"), 1);
    let s = Scenario::from_toml(&text, name).unwrap();
    let robot = s.load_robot(path.parent()).unwrap();
    (s, robot)
}

#[test]
fn compensated_commands_beat_the_nominal_ones_on_the_twin() {
    let (s, robot) = scenario("irb120_geometric", "");
    let opts = CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM);
    let c = verify_seed(&s, &robot, &opts, 60, 1, false).unwrap();
    eprintln!("{c:#?}");
    // The compensation gains what the calibration predicts: the nominal commands' AP as the
    // calibrated model sees it is the measured one to within the calibration's own error, and
    // the compensated commands land within a few times that error.
    let err = c.calibration_test_rmse_mm;
    assert!((c.predicted_nominal_ap_mm.mean - c.nominal_ap_mm.mean).abs() < 3.0 * err, "{c:?}");
    assert!(c.compensated_ap_mm.mean < 2.0 * err && c.compensated_ap_mm.max < 6.0 * err, "{c:?}");
    assert!(c.nominal_ap_mm.mean > 20.0 * c.compensated_ap_mm.mean, "{c:?}");
}

/// Compliance under a 3 kg payload, hidden in a tracker scenario: the calibration models it
/// (`--effects compliance` with the stated payload) and the compensation takes each target's own
/// torques into account.
#[test]
fn compensation_carries_compliance_under_the_payload() {
    let extra = "[effects.compliance]\nstiffness_nm_per_rad = [1.5e5, 2.0e4, 3.0e4, 3.0e4, 3.0e4, 2.0e4]\n\n[effects.payload]\nmass_kg = 3.0\ncom_mm = [40.0, 0.0, 60.0]\n";
    let (s, robot) = scenario("irb120_tracker", extra);
    let mut opts = CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM);
    opts.effects = (0..6).map(|j| (crate::calib::effects::EffectKind::Compliance, Some(j))).collect();
    opts.loads.joints.payload = s.effects.payload.clone();
    let c = verify_seed(&s, &robot, &opts, 60, 2, false).unwrap();
    eprintln!("{c:#?}");
    let geometric = verify_seed(&s, &robot, &CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM), 60, 2, false).unwrap();
    eprintln!("geometric only: {geometric:#?}");
    let err = c.calibration_test_rmse_mm;
    assert!((c.predicted_nominal_ap_mm.mean - c.nominal_ap_mm.mean).abs() < 3.0 * err, "{c:?}");
    assert!(c.compensated_ap_mm.mean < 2.0 * err, "{c:?}");
    assert!(geometric.compensated_ap_mm.mean > 2.0 * c.compensated_ap_mm.mean, "{geometric:?}");
}

/// Pose targets on a UR10 measured by a 6-D probe: the compensated commands reach the targets'
/// positions and orientations on the twin far better than the nominal ones, as the calibrated
/// model predicts.
#[test]
fn compensated_pose_commands_reach_position_and_orientation_on_the_twin() {
    let (s, robot) = scenario("ur10_pose", "");
    let opts = CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM);
    let c = verify_seed(&s, &robot, &opts, 40, 1, true).unwrap();
    eprintln!("{c:#?}");
    let err = c.calibration_test_rmse_mm;
    let (before, after) = c.orientation_deg.unwrap();
    assert!(c.judged >= 30, "{c:?}");
    assert!(c.compensated_ap_mm.mean < 2.0 * err && c.nominal_ap_mm.mean > 10.0 * c.compensated_ap_mm.mean, "{c:?}");
    assert!(after.mean < 0.01 && before.mean > 5.0 * after.mean, "{before:?} {after:?}");
    // Points only on a twin that reads no orientation: refused by name.
    let (s, robot) = scenario("irb120_tracker", "");
    let e = verify_seed(&s, &robot, &CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM), 5, 1, true).unwrap_err();
    assert!(e.to_string().contains("6-D probe"), "{e}");
}

const E: crate::measurement::Euler = crate::measurement::Euler::XYZ;

#[test]
fn a_targets_file_is_points_poses_or_this_arms_joints() {
    let dir = std::env::temp_dir().join(format!("twincal-targets-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let points = super::read_targets(&file("p.csv", "x,y,z\n400,0,500\n"), 6, E).unwrap();
    assert_eq!(points, [super::Target::Point(nalgebra::Vector3::new(400.0, 0.0, 500.0))]);
    let joints = super::read_targets(&file("q.csv", "q1,q2,q3,q4,q5,q6\n10,0,0,0,30,0\n"), 6, E).unwrap();
    assert!(matches!(&joints[0], super::Target::Joints(q) if (q[0] - 10f64.to_radians()).abs() < 1e-15));
    let e = super::read_targets(&file("q7.csv", "q1,q2,q3,q4,q5,q6,q7\n0,0,0,0,30,0,0\n"), 6, E).unwrap_err().to_string();
    assert!(e.contains("column q7") && e.contains("6 joints"), "{e}");
    let e = super::read_targets(&file("both.csv", "x,y,z,q1,q2,q3,q4,q5,q6\n400,0,500,0,0,0,0,30,0\n"), 6, E).unwrap_err().to_string();
    assert!(e.contains("not both"), "{e}");
    let e = super::read_targets(&file("nan.csv", "x,y,z\nNaN,0,500\n"), 6, E).unwrap_err().to_string();
    assert!(e.contains("not a point"), "{e}");
    // Poses: the orientation in the convention given (here extrinsic xyz: Rz·Ry·Rx).
    let xyz = crate::measurement::Euler::parse("xyz").unwrap();
    let poses = super::read_targets(&file("pose.csv", "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg\n400,0,500,10,20,30\n"), 6, xyz).unwrap();
    let r = |axis: nalgebra::Unit<nalgebra::Vector3<f64>>, deg: f64| *nalgebra::Rotation3::from_axis_angle(&axis, deg.to_radians()).matrix();
    let expected = r(nalgebra::Vector3::z_axis(), 30.0) * r(nalgebra::Vector3::y_axis(), 20.0) * r(nalgebra::Vector3::x_axis(), 10.0);
    assert!(matches!(&poses[0], super::Target::Pose(p, m) if p.x == 400.0 && (m - expected).norm() < 1e-12), "{poses:?}");
    for (text, says) in [
        ("x,y,z,rx,ry\n400,0,500,0,0\n", "2 of the orientation columns"),
        ("rx,ry,rz\n0,0,0\n", "no x, y, z"),
        ("x,y,z,rx,ry,rz\n400,0,500,0,NaN,0\n", "orientation"),
        ("x,y,z\n0.4,0,0.5\n0.3,0.1,0.6\n", "metres"),
        ("x,y,z\n", "no targets"),
        ("x,y,z,rx,ry,rz\n", "no targets"),
    ] {
        let e = super::read_targets(&file("bad.csv", text), 6, E).unwrap_err().to_string();
        assert!(e.contains(says), "{text}: {e}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The nominal controller of an arm with a closed form finds every solution of a pose: the
/// configuration a pose was computed at is among them, for configurations across the joint
/// ranges of the IRB 120 and the UR10 (their calibrations' nominal models).
#[test]
fn the_nominal_closed_form_finds_the_configuration_a_pose_came_from() {
    use rand::{Rng, SeedableRng};
    for name in ["irb120_tracker", "ur10_tracker"] {
        let (r, x_nom) = calibrated_on_its_twin(name);
        let c = super::Compensator::new(&r, &x_nom, None, 0.001, 0.001).unwrap();
        assert!(c.closed_form(), "{name}");
        let limits = r.model.joint_limits();
        let nominal = crate::ik::IkModel::new(&r.model, &x_nom, None, limits.clone());
        let mut w = nominal.work();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut missed = Vec::new();
        let mut probes: Vec<Vec<f64>> = vec![[5.47f64, 10.99, -75.59, 20.08, 77.65, 46.0].iter().map(|d| d.to_radians()).collect()];
        probes.extend((0..300).map(|_| limits.iter().map(|(lo, hi)| lo + (hi - lo) * (0.05 + 0.9 * rng.random::<f64>())).collect::<Vec<f64>>()));
        for q in &probes {
            let (p, rot) = nominal.pose(q, &mut w, None);
            let found = c.nominal_pose_solutions(&p, &rot, &mut w);
            if !found.iter().any(|s| s.iter().zip(q).all(|(a, b)| (a - b).abs() < 1e-6)) {
                missed.push((q.iter().map(|v| v.to_degrees()).collect::<Vec<_>>(), found.len()));
            }
        }
        assert!(missed.is_empty(), "{name}: {} of {} missed: {:?}", missed.len(), probes.len(), &missed[..missed.len().min(3)]);
    }
}

/// Every solution of the calibrated arm for a pose (`Compensator::pose_solutions`, what `ik`
/// answers pose targets with), on the IRB 120 and the UR10 calibrated on their trackers (no
/// closed form of their own): away from singularities (`IkModel::pose_conditioning` above
/// `NEAR_SINGULAR_MM_PER_RAD`), the configuration a pose came from is always among them to
/// 1e-4 rad, and so is every solution that local descents from 60 random starts converge to; near
/// one (solutions there are ill-conditioned, a joint's angle free to a degree or more), each pose
/// still has a solution within `ik`'s default tolerances.
#[test]
fn every_solution_of_a_calibrated_pose_is_found() {
    use crate::ik::{IkOptions, IkStatus, JacobianKind};
    use rand::{Rng, SeedableRng};
    for name in ["irb120_tracker", "ur10_tracker"] {
        let (r, x_nom) = calibrated_on_its_twin(name);
        let c = super::Compensator::new(&r, &x_nom, None, 1e-4, 1e-4).unwrap();
        // Near a singularity, `ik`'s default tolerances.
        let at_defaults = super::Compensator::new(&r, &x_nom, None, 0.01, 0.001).unwrap();
        let limits = r.model.joint_limits();
        let calibrated = crate::ik::IkModel::new(&r.model, &r.x, None, limits.clone());
        let (mut wc, mut wn) = c.works();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        // One solution per branch: the same modulo a turn.
        let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| crate::ik::closed_form::wrap(x - y).abs() < 1e-4);
        let (mut counts, mut missed, mut extra, mut singular) = (Vec::new(), Vec::new(), Vec::new(), 0);
        for k in 0..120 {
            let q: Vec<f64> = limits.iter().map(|(lo, hi)| lo + (hi - lo) * (0.05 + 0.9 * rng.random::<f64>())).collect();
            let (p, rot) = c.predicted_pose(&q);
            let all = c.pose_solutions(&p, &rot, JacobianKind::Analytic, &mut wc, &mut wn);
            let found: Vec<Vec<f64>> = all.into_iter().filter(|s| s.status == IkStatus::Converged).map(|s| s.q).collect();
            if calibrated.pose_conditioning(&q, &mut wc) < crate::ik::solver::NEAR_SINGULAR_MM_PER_RAD {
                singular += 1;
                let s = at_defaults.pose_solutions(&p, &rot, JacobianKind::Analytic, &mut wc, &mut wn);
                assert!(s.iter().any(|s| s.status == IkStatus::Converged), "{name}: no solution near a singularity at {q:?}: {s:?}");
                continue;
            }
            counts.push(found.len());
            if !found.iter().any(|f| same(f, &q)) {
                missed.push(q.iter().map(|v| v.to_degrees()).collect::<Vec<_>>());
            }
            if k % 4 == 0 {
                for start in 0..60u64 {
                    let o = IkOptions { local: true, tol_mm: 1e-4, tol_deg: 1e-4, max_iter: 200, seed: start, ..IkOptions::default() };
                    let s = calibrated.solve_pose_from(&p, &rot, Some(&calibrated.random_q(&mut rng)), JacobianKind::Analytic, &o, &mut wc);
                    if s.status == IkStatus::Converged && !found.iter().any(|f| same(f, &s.q)) {
                        extra.push(s.q.iter().map(|v| v.to_degrees()).collect::<Vec<_>>());
                    }
                }
            }
        }
        let mean = counts.iter().sum::<usize>() as f64 / counts.len() as f64;
        eprintln!(
            "{name}: {mean:.2} solutions per pose (most {}) on {} poses, {singular} near a singularity; the original missed {}, {} solutions found only by random starts",
            counts.iter().max().unwrap(),
            counts.len(),
            missed.len(),
            extra.len()
        );
        assert!(missed.is_empty(), "{name}: {missed:?}");
        assert!(extra.is_empty(), "{name}: {:?}", &extra[..extra.len().min(3)]);
        // At most the eight branches of a six-axis arm with a closed form, several within the limits.
        assert!(mean >= 3.0 && counts.iter().all(|n| (1..=8).contains(n)) && counts.len() >= 100, "{name}: {counts:?}");
    }
}
