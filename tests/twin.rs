//! The twin's physics and sensor against their quasi-static and analytic counterparts.

use nalgebra::Vector3;
use rand::SeedableRng;
use twincal::effects::statics::Contact;
use twincal::effects::{Backlash, Compliance, Effects, Payload, Thermal};
use twincal::generate::{generate, Silent};
use twincal::robot::Robot;
use twincal::scenario::Scenario;
use twincal::sensor::DrawWire;
use twincal::twin::{PoseCommand, SettleOptions, Twin};

fn scenario(name: &str) -> (Scenario, Robot) {
    Scenario::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios").join(format!("{name}.toml"))).unwrap()
}

fn sensor() -> DrawWire {
    let (s, _) = scenario("irb120_evo_nph");
    s.sensor
}

fn deg(v: [f64; 6]) -> Vec<f64> {
    v.iter().map(|d| d.to_radians()).collect()
}

#[test]
fn ideal_length_equals_analytic_distance() {
    let (s, robot) = scenario("irb120_ideal");
    let g = generate(&s, &robot, &Silent).unwrap();
    assert_eq!(g.dataset.rows.len(), s.sampling.poses);
    let chain = robot.error_chain();
    let zero = vec![0.0; chain.n_params()];
    let e = Vector3::from(s.sensor.exit_point_mm);
    let tool = Vector3::from(s.sensor.tool_point_mm) * 1e-3;
    let mut worst: f64 = 0.0;
    for r in &g.dataset.rows {
        let q: Vec<f64> = r.q_deg.iter().map(|d| d.to_radians()).collect();
        let p = chain.point(&q, &zero, 1.0, chain.flange(), &tool) * 1e3;
        let l = (p - e).norm() + s.sensor.length_offset_mm;
        worst = worst.max((r.l_mm.unwrap() - l).abs());
    }
    assert!(worst < 1e-6, "worst |L - analytic| = {worst:e} mm");
}

fn compliant_twin(effects: Effects) -> Twin {
    let robot = Robot::irb120();
    let n = robot.error_chain().n_params();
    Twin::new(robot, vec![0.0; n], effects, sensor(), SettleOptions::default())
}

fn stiffness() -> Vec<f64> {
    vec![1.5e5, 1.0e5, 8.0e4, 3.0e4, 3.0e4, 2.0e4]
}

#[test]
fn compliance_deflection_is_torque_over_stiffness() {
    let k = stiffness();
    let effects = Effects {
        compliance: Some(Compliance { stiffness_nm_per_rad: k.clone(), damping_nms_per_rad: None }),
        payload: Some(Payload { mass_kg: 1.0, com_mm: [50.0, 0.0, 0.0] }),
        ..Default::default()
    };
    let twin = compliant_twin(effects);
    for q in [[0.0, 30.0, -20.0, 10.0, 45.0, 0.0], [60.0, -30.0, 40.0, -90.0, -60.0, 120.0], [-45.0, 70.0, -80.0, 30.0, 90.0, -30.0]] {
        let cmd = PoseCommand { q_cmd: deg(q), sides: vec![-1.0; 6], t: 0.0 };
        let sim = twin.simulate(&cmd).unwrap();
        assert!(sim.steps > 0);
        // Joint 2 carries the arm: a real, visible deflection.
        assert!(sim.deflection[1].abs() > 1e-5, "joint 2 deflection {}", sim.deflection[1]);
        for j in 0..6 {
            let expect = sim.torque[j] / k[j];
            assert!((sim.deflection[j] - expect).abs() < 1e-9 + 1e-6 * expect.abs(), "joint {j}: δ = {:e}, τ/k = {expect:e}", sim.deflection[j]);
        }
        let qs = twin.quasi_static(&cmd);
        let d = (sim.tool - qs.tool).norm() * 1e3;
        assert!(d < 1e-3, "rapier vs quasi-static tool point: {d:e} mm");
    }
}

fn full_effects() -> Effects {
    let (s, _) = scenario("irb120_evo_nph");
    s.effects
}

#[test]
fn rapier_agrees_with_quasi_static_with_every_effect() {
    let (s, robot) = scenario("irb120_evo_nph");
    let twin = twincal::generate::build_twin(&s, &robot);
    let poses = twincal::generate::sample_poses(&s, &robot).unwrap();
    let sides = twincal::twin::approach_sides(&[0.0; 6], &poses);
    let mut worst: f64 = 0.0;
    let mut moved: f64 = 0.0;
    for i in (0..poses.len()).step_by(20) {
        let cmd = PoseCommand { q_cmd: poses[i].clone(), sides: sides[i].clone(), t: 600.0 + i as f64 };
        let sim = twin.simulate(&cmd).unwrap();
        let qs = twin.quasi_static(&cmd);
        assert_eq!(sim.contact, qs.contact, "pose {i}");
        worst = worst.max((sim.tool - qs.tool).norm() * 1e3);
        moved = moved.max(qs.deflection.iter().fold(0.0f64, |m, d| m.max(d.abs())));
    }
    assert!(moved > 1e-5, "effects should deflect the joints");
    assert!(worst < 1e-3, "worst rapier vs quasi-static tool distance {worst:e} mm");
}

#[test]
fn backlash_side_flips_with_load_sign_and_approach() {
    let effects = Effects {
        compliance: Some(Compliance { stiffness_nm_per_rad: stiffness(), damping_nms_per_rad: None }),
        backlash: Some(Backlash { width_deg: vec![0.05; 6], breakaway_nm: 0.3 }),
        ..full_effects()
    };
    let effects = Effects { thermal: None, ..effects };
    let twin = compliant_twin(effects);
    // Joint 2 leaning forward vs backward: gravity torque changes sign, so does the flank.
    let fwd = PoseCommand { q_cmd: deg([0.0, 40.0, 0.0, 0.0, 0.0, 0.0]), sides: vec![-1.0; 6], t: 0.0 };
    let back = PoseCommand { q_cmd: deg([0.0, -40.0, 0.0, 0.0, 0.0, 0.0]), sides: vec![-1.0; 6], t: 0.0 };
    let a = twin.simulate(&fwd).unwrap();
    let b = twin.simulate(&back).unwrap();
    assert!(a.torque[1] * b.torque[1] < 0.0, "gravity torques {} {}", a.torque[1], b.torque[1]);
    assert!(a.torque[1].abs() > 1.0);
    let side = |c: Contact| match c {
        Contact::Positive => 1,
        Contact::Negative => -1,
        other => panic!("joint 2 should rest on a flank, got {other:?}"),
    };
    assert_eq!(side(a.contact[1]), a.torque[1].signum() as i32);
    assert_eq!(side(b.contact[1]), b.torque[1].signum() as i32);
    assert_eq!(-side(a.contact[1]), side(b.contact[1]));
    let h = 0.025f64.to_radians();
    assert!((a.deflection[1] - (a.torque[1].signum() * h + a.torque[1] / 1.0e5)).abs() < 1e-9);

    // Joint 1 (vertical axis) carries almost no load: its flank is the approach direction's.
    let q = deg([20.0, 10.0, 0.0, 0.0, 0.0, 0.0]);
    let from_below = twin.simulate(&PoseCommand { q_cmd: q.clone(), sides: vec![-1.0; 6], t: 0.0 }).unwrap();
    let from_above = twin.simulate(&PoseCommand { q_cmd: q.clone(), sides: vec![1.0; 6], t: 0.0 }).unwrap();
    assert!(from_below.torque[0].abs() < 0.3, "joint 1 load {}", from_below.torque[0]);
    assert!(from_below.deflection[0] < 0.0 && from_above.deflection[0] > 0.0);
    assert!((from_above.deflection[0] - from_below.deflection[0] - 2.0 * h).abs() < 1e-4 * h + 2.0 * 0.3 / 1.5e5);
    let moved = (from_above.tool - from_below.tool).norm() * 1e3;
    assert!(moved > 0.01, "approach direction should move the tool, moved {moved} mm");

    // And the dataset order sets the approach: increasing then decreasing joint 1.
    let sides = twincal::twin::approach_sides(&[0.0; 6], &[deg([10.0, 0.0, 0.0, 0.0, 0.0, 0.0]), deg([5.0, 0.0, 0.0, 0.0, 0.0, 0.0])]);
    assert_eq!(sides[0][0], -1.0);
    assert_eq!(sides[1][0], 1.0);
}

#[test]
fn thermal_growth_shows_in_length_over_time() {
    let th = Thermal::new(23e-6, 8.0, 900.0, 20.0);
    let effects = Effects { thermal: Some(th.clone()), ..Default::default() };
    let twin = compliant_twin(effects);
    let q = deg([30.0, 30.0, 10.0, 0.0, 30.0, 0.0]);
    let l = |t: f64| twin.sensor.ideal_length(&twin.simulate(&PoseCommand { q_cmd: q.clone(), sides: vec![-1.0; 6], t }).unwrap().tool);
    let ls: Vec<f64> = [0.0, 300.0, 900.0, 3600.0, 20000.0].iter().map(|t| l(*t)).collect();
    for w in ls.windows(2) {
        assert!(w[1] != w[0]);
    }
    let total = ls[4] - ls[0];
    assert!(total.abs() > 0.02, "thermal change of L {total} mm");
    // First-order warm-up: after one time constant 63 % of the final change.
    let frac = (ls[2] - ls[0]) / total;
    assert!((frac - (1.0 - (-1.0f64).exp())).abs() < 0.02, "fraction after τ: {frac}");
}

#[test]
fn averaged_noise_matches_sigma_over_sqrt_n() {
    let mut s = sensor();
    s.noise_std_mm = 0.05;
    s.resolution_mm = 0.001;
    s.linearity_pct_fs = 0.0;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let n = 4000;
    let v: Vec<f64> = (0..n).map(|_| s.read(800.0, &mut rng).unwrap()).collect();
    let mean = v.iter().sum::<f64>() / n as f64;
    let std = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
    let expect = 0.05 / (s.samples as f64).sqrt();
    assert!((std / expect - 1.0).abs() < 0.10, "std {std} vs σ/√N {expect}");
    assert!((mean - 800.0).abs() < 4.0 * expect / (n as f64).sqrt() + 1e-3);
}

#[test]
fn out_of_range_reading_is_an_error_not_clipped() {
    let s = sensor();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let e = s.read(2500.0, &mut rng).unwrap_err();
    assert!(e.to_string().contains("outside the sensor range"), "{e}");
    assert!(s.read(-5.0, &mut rng).is_err());
}

/// Nothing in the path is IRB-120 specific: another 6R URDF (tilted origins, skew axes, a fixed
/// joint inside the chain, a continuous joint) loads, simulates and agrees with its statics.
#[test]
fn another_six_r_urdf_loads_and_simulates_the_same_way() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let (s, robot) = Scenario::load(&dir.join("fixture_6r.toml")).unwrap();
    assert_eq!(robot.dof(), 6);
    // No link is named like a flange: the flange is the last moving link.
    assert_eq!(robot.flange_name, "l6");
    // The fixed joint's child mass is merged into the previous moving link.
    assert!((robot.links.iter().map(|l| l.mass).sum::<f64>() - 11.3).abs() < 1e-9);
    let g = generate(&s, &robot, &Silent).unwrap();
    assert_eq!(g.dataset.rows.len() + g.truth.rejected.len(), 40);
    assert!(g.dataset.rows.len() >= 30);
    let twin = &g.twin;
    let poses = twincal::generate::sample_poses(&s, &robot).unwrap();
    let sides = twincal::twin::approach_sides(&[0.0; 6], &poses);
    for i in 0..10 {
        let cmd = PoseCommand { q_cmd: poses[i].clone(), sides: sides[i].clone(), t: 0.0 };
        let sim = twin.simulate(&cmd).unwrap();
        let qs = twin.quasi_static(&cmd);
        assert!((sim.tool - qs.tool).norm() * 1e3 < 1e-3, "pose {i}");
        assert!(sim.deflection.iter().any(|d| d.abs() > 1e-6));
    }
    // Its D-H description reproduces its URDF kinematics.
    let guess = twincal::calib::model::SensorGuess { exit_m: [0.9, -0.2, 0.0], offset_m: 0.08, tool_m: [0.04, 0.0, 0.005] };
    let dh = twincal::calib::model::CalibModel::dh(&robot, &guess, true);
    let fr = twincal::calib::model::CalibModel::frame(&robot, &guess);
    let (mut a, mut b) = (dh.work(), fr.work());
    for q in poses.iter().take(10) {
        let p = dh.tool_point(&dh.nominal, q, &mut a);
        let r = fr.tool_point(&fr.nominal, q, &mut b);
        assert!((p - r).norm() < 1e-12);
    }
}
