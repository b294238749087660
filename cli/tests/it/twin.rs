//! The twin's physics and sensor against their quasi-static and analytic counterparts.

use nalgebra::Vector3;
use rand::SeedableRng;
use twincal::robot::Robot;
use twincal::sim::effects::statics::Contact;
use twincal::sim::effects::{Backlash, Compliance, Eccentricity, Effects, Payload, Thermal};
use twincal::sim::generate::{build_twin, generate, sample_poses, Silent};
use twincal::sim::instrument::DrawWire;
use twincal::sim::scenario::Scenario;
use twincal::sim::twin::{PoseCommand, SettleOptions, Twin};

fn scenario(name: &str) -> (Scenario, Robot) {
    Scenario::load(&std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios").join(format!("{name}.toml"))).unwrap()
}

fn sensor() -> DrawWire {
    let (s, _) = scenario("irb120_evo_nph");
    s.draw_wire
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
    let e = Vector3::from(s.draw_wire.exit_point_mm);
    let tool = Vector3::from(s.draw_wire.tool_point_mm) * 1e-3;
    let mut worst: f64 = 0.0;
    for r in &g.dataset.rows {
        let q: Vec<f64> = r.q_deg.iter().map(|d| d.to_radians()).collect();
        let p = chain.point(&q, &zero, 1.0, chain.flange(), &tool) * 1e3;
        let l = (p - e).norm() + s.draw_wire.length_offset_mm;
        worst = worst.max((r.l_mm().unwrap() - l).abs());
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
        for (j, kj) in k.iter().enumerate() {
            let expect = sim.torque[j] / kj;
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
    let twin = twincal::sim::generate::build_twin(&s, &robot);
    let poses = twincal::sim::generate::sample_poses(&s, &robot).unwrap();
    let sides = twincal::sim::twin::approach_sides(&[0.0; 6], &poses);
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
    let sides = twincal::sim::twin::approach_sides(&[0.0; 6], &[deg([10.0, 0.0, 0.0, 0.0, 0.0, 0.0]), deg([5.0, 0.0, 0.0, 0.0, 0.0, 0.0])]);
    assert_eq!(sides[0][0], -1.0);
    assert_eq!(sides[1][0], 1.0);
}

#[test]
fn thermal_growth_shows_in_length_over_time() {
    let th = Thermal::new(23e-6, 8.0, 900.0, 20.0);
    let effects = Effects { thermal: Some(th.clone()), ..Default::default() };
    let twin = compliant_twin(effects);
    let q = deg([30.0, 30.0, 10.0, 0.0, 30.0, 0.0]);
    let l = |t: f64| twin.draw_wire.ideal_length(&twin.simulate(&PoseCommand { q_cmd: q.clone(), sides: vec![-1.0; 6], t }).unwrap().tool);
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
    let poses = twincal::sim::generate::sample_poses(&s, &robot).unwrap();
    let sides = twincal::sim::twin::approach_sides(&[0.0; 6], &poses);
    for i in 0..10 {
        let cmd = PoseCommand { q_cmd: poses[i].clone(), sides: sides[i].clone(), t: 0.0 };
        let sim = twin.simulate(&cmd).unwrap();
        let qs = twin.quasi_static(&cmd);
        assert!((sim.tool - qs.tool).norm() * 1e3 < 1e-3, "pose {i}");
        assert!(sim.deflection.iter().any(|d| d.abs() > 1e-6));
    }
    // Its D-H description reproduces its URDF kinematics.
    let guess = twincal::calib::model::DrawWireGuess { exit_m: [0.9, -0.2, 0.0], offset_m: 0.08, tool_m: [0.04, 0.0, 0.005] };
    let dh = twincal::calib::model::CalibModel::dh(&robot, &guess, true);
    let fr = twincal::calib::model::CalibModel::frame(&robot, &guess);
    let (mut a, mut b) = (dh.work(), fr.work());
    for q in poses.iter().take(10) {
        let p = dh.tool_point(&dh.nominal, q, &mut a);
        let r = fr.tool_point(&fr.nominal, q, &mut b);
        assert!((p - r).norm() < 1e-12);
    }
}

fn eccentricity() -> Eccentricity {
    Eccentricity { amplitude_deg: vec![0.02, -0.015, 0.01, 0.03, 0.02, 0.05], phase_deg: vec![30.0, -60.0, 120.0, 0.0, 90.0, -150.0] }
}

/// A·sin(q + φ) written as the calibration side models it, a·sin q + b·cos q (rad).
fn expected_eccentricity(e: &Eccentricity, q: &[f64]) -> Vec<f64> {
    q.iter()
        .enumerate()
        .map(|(j, q)| {
            let (a, b) = e.sin_cos_deg(j);
            (a * q.sin() + b * q.cos()).to_radians()
        })
        .collect()
}

#[test]
fn eccentricity_moves_the_settled_tool_as_the_quasi_static_model_says() {
    let (s, robot) = scenario("irb120_evo_nph");
    let plain = build_twin(&s, &robot);
    let mut se = s.clone();
    se.effects.eccentricity = Some(eccentricity());
    se.validate(&robot, "eccentric").unwrap();
    let ecc = build_twin(&se, &robot);
    let poses = sample_poses(&s, &robot).unwrap();
    let sides = twincal::sim::twin::approach_sides(&[0.0; 6], &poses);
    let (mut worst, mut moved, mut moved_l): (f64, f64, f64) = (0.0, 0.0, 0.0);
    for i in (0..poses.len()).step_by(40) {
        let cmd = PoseCommand { q_cmd: poses[i].clone(), sides: sides[i].clone(), t: 600.0 + i as f64 };
        let sim = ecc.simulate(&cmd).unwrap();
        let qs = ecc.quasi_static(&cmd);
        let before = plain.simulate(&cmd).unwrap();
        assert_eq!(sim.contact, qs.contact, "pose {i}");
        // Rapier and the quasi-static model see the same eccentricity, and agree where the arm rests.
        worst = worst.max((sim.tool - qs.tool).norm() * 1e3);
        let expect = expected_eccentricity(&eccentricity(), &poses[i]);
        for j in 0..6 {
            assert!((sim.eccentricity[j] - expect[j]).abs() < 1e-15 && qs.eccentricity[j] == sim.eccentricity[j], "pose {i} joint {j}");
            // Link side = commanded + eccentricity + deflection.
            assert!((sim.q_link[j] - (poses[i][j] + expect[j] + sim.deflection[j])).abs() < 1e-14);
        }
        // The eccentricity moves the tool by what the quasi-static model says it does.
        let qs_before = plain.quasi_static(&cmd);
        let predicted = (qs.tool - qs_before.tool) * 1e3;
        let simulated = (sim.tool - before.tool) * 1e3;
        assert!((predicted - simulated).norm() < 1e-3, "pose {i}: rapier shift {simulated:?} vs quasi-static {predicted:?} mm");
        moved = moved.max(simulated.norm());
        moved_l = moved_l.max((ecc.draw_wire.ideal_length(&sim.tool) - plain.draw_wire.ideal_length(&before.tool)).abs());
    }
    assert!(worst < 1e-3, "worst rapier vs quasi-static tool distance {worst:e} mm");
    assert!(moved > 0.05, "eccentricity should move the tool, at most {moved} mm");
    assert!(moved_l > 0.01, "eccentricity should change L, at most {moved_l} mm");
}

#[test]
fn eccentricity_changes_l_by_its_first_order_sensitivity() {
    // A rigid arm: the tool sits exactly where the chain puts it at the true motor angles.
    let robot = Robot::irb120();
    let chain = robot.error_chain();
    let zero = vec![0.0; chain.n_params()];
    let e = eccentricity();
    let twin = Twin::new(robot, zero.clone(), Effects { eccentricity: Some(e.clone()), ..Default::default() }, sensor(), SettleOptions::default());
    let rigid = compliant_twin(Effects::default());
    let tool = twin.draw_wire.tool_point_m();
    let length = |q: &[f64]| twin.draw_wire.ideal_length(&chain.point(q, &zero, 1.0, chain.flange(), &tool));
    for q in [[20.0, 30.0, -20.0, 10.0, 45.0, 30.0], [-40.0, 10.0, 20.0, -60.0, -30.0, 90.0]] {
        let q = deg(q);
        let cmd = PoseCommand { q_cmd: q.clone(), sides: vec![-1.0; 6], t: 0.0 };
        let rest = twin.simulate(&cmd).unwrap();
        let shift = expected_eccentricity(&e, &q);
        let q_true: Vec<f64> = q.iter().zip(&shift).map(|(a, b)| a + b).collect();
        assert!((rest.tool - chain.point(&q_true, &zero, 1.0, chain.flange(), &tool)).norm() < 1e-12);
        // ΔL against Σ ∂L/∂q_j · e_j (central differences; second order ≈ 1e-4 mm).
        let dl = twin.draw_wire.ideal_length(&rest.tool) - twin.draw_wire.ideal_length(&rigid.simulate(&cmd).unwrap().tool);
        let h = 1e-6;
        let linear: f64 = (0..6)
            .map(|j| {
                let (mut a, mut b) = (q.clone(), q.clone());
                a[j] += h;
                b[j] -= h;
                (length(&a) - length(&b)) / (2.0 * h) * shift[j]
            })
            .sum();
        assert!(dl.abs() > 0.01, "pose {q:?}: ΔL = {dl} mm");
        assert!((dl - linear).abs() < 2e-4, "ΔL {dl} mm vs first order {linear} mm");
    }
}

/// The ideal scenario with `effects` on.
fn ideal_with(effects: Effects) -> (Scenario, Robot) {
    let (mut s, robot) = scenario("irb120_ideal");
    s.effects = effects;
    s.validate(&robot, "patched").unwrap();
    (s, robot)
}

#[test]
fn dataset_records_the_encoder_angles_and_truth_the_eccentricity() {
    let (s, robot) = ideal_with(Effects { eccentricity: Some(eccentricity()), ..Default::default() });
    let g = generate(&s, &robot, &Silent).unwrap();
    let chain = robot.error_chain();
    let zero = vec![0.0; chain.n_params()];
    let tool = s.draw_wire.tool_point_m();
    let (mut worst, mut off): (f64, f64) = (0.0, 0.0);
    for (r, t) in g.dataset.rows.iter().zip(&g.truth.poses) {
        let q: Vec<f64> = r.q_deg.iter().map(|d| d.to_radians()).collect();
        let ecc = expected_eccentricity(&eccentricity(), &q);
        let recorded = t.eccentricity_mdeg.as_ref().expect("eccentricity recorded per pose");
        for j in 0..6 {
            assert!((recorded[j] - ecc[j].to_degrees() * 1e3).abs() < 1e-9);
            assert!((t.q_cmd_deg[j] - r.q_deg[j]).abs() < 1e-9, "the dataset holds the commanded angles");
        }
        let q_true: Vec<f64> = q.iter().zip(&ecc).map(|(a, b)| a + b).collect();
        let l = |q: &[f64]| s.draw_wire.ideal_length(&chain.point(q, &zero, 1.0, chain.flange(), &tool));
        worst = worst.max((r.l_mm().unwrap() - l(&q_true)).abs());
        off = off.max((r.l_mm().unwrap() - l(&q)).abs());
    }
    assert!(worst < 1e-6, "L vs the analytic distance at the true angles: {worst:e} mm");
    assert!(off > 0.05, "L should not match the commanded angles, at most {off} mm off");
    // Without the effect nothing is recorded.
    let (s, robot) = ideal_with(Effects::default());
    let g = generate(&s, &robot, &Silent).unwrap();
    assert!(g.truth.poses.iter().all(|p| p.eccentricity_mdeg.is_none()));
}

fn warm_up(lag: f64, offset: f64, noise: f64, column: bool) -> Thermal {
    Thermal { temp_lag_s: lag, temp_offset_k: offset, temp_noise_k: noise, temp_column: column, ..Thermal::new(23e-6, 8.0, 900.0, 20.0) }
}

#[test]
fn temp_column_is_a_lagging_sensor_reading() {
    let th = warm_up(300.0, 0.0, 0.0, true);
    let (s, robot) = ideal_with(Effects { thermal: Some(th.clone()), ..Default::default() });
    let g = generate(&s, &robot, &Silent).unwrap();
    let csv = g.dataset.to_csv_string();
    assert!(csv.starts_with("q1,q2,q3,q4,q5,q6,L,t,temp,split\n"), "{}", &csv[..60]);
    for (r, p) in g.dataset.rows.iter().zip(&g.truth.poses) {
        let temp = r.temp_c.unwrap();
        assert_eq!(p.temp_measured_c, Some(temp));
        assert!((p.delta_t_k - th.delta_t(p.t_s)).abs() < 1e-15);
        // The reading is the closed-form lagged rise at the dataset's precision ...
        assert!((temp - (20.0 + th.sensed_delta_t(p.t_s))).abs() <= 5e-4 + 1e-12, "t {}: {temp}", p.t_s);
        // ... and never more than the structure's rise.
        assert!(temp - 20.0 <= p.delta_t_k + 5e-4);
    }
    // Early on the sensor has seen a fraction of the rise: the first rows measure clearly less.
    let first = &g.truth.poses[..5];
    for p in first {
        let measured = p.temp_measured_c.unwrap() - 20.0;
        assert!(p.delta_t_k > 0.0 && measured < 0.7 * p.delta_t_k, "t {}: sensor {measured} K, structure {} K", p.t_s, p.delta_t_k);
    }
    // The structure itself, which drives the length scale, warms as before.
    let last = g.truth.poses.last().unwrap();
    assert!(last.delta_t_k > last.temp_measured_c.unwrap() - 20.0);
}

#[test]
fn temp_sensor_noise_and_offset_are_seeded_and_deterministic() {
    let th = warm_up(120.0, 0.3, 0.05, true);
    let (s, robot) = ideal_with(Effects { thermal: Some(th.clone()), ..Default::default() });
    let a = generate(&s, &robot, &Silent).unwrap();
    let b = generate(&s, &robot, &Silent).unwrap();
    assert_eq!(a.dataset.to_csv_string(), b.dataset.to_csv_string(), "same scenario and seed, same bytes");
    let residual: Vec<f64> = a.truth.poses.iter().map(|p| p.temp_measured_c.unwrap() - th.sensed_temp_c(p.t_s)).collect();
    let n = residual.len() as f64;
    let mean = residual.iter().sum::<f64>() / n;
    let std = (residual.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    assert!((0.03..0.075).contains(&std), "noise std {std} K, set 0.05 K");
    assert!(mean.abs() < 4.0 * 0.05 / n.sqrt(), "noise mean {mean} K (the offset is not noise)");
    // Every reading sits on the 1 mK grid.
    assert!(a.dataset.rows.iter().all(|r| (r.temp_c.unwrap() * 1e3 - (r.temp_c.unwrap() * 1e3).round()).abs() < 1e-6));
    // Another seed draws other noise; the noise-free parts (L of the ideal arm) follow their own streams.
    let mut s2 = s.clone();
    s2.seed += 1;
    let c = generate(&s2, &robot, &Silent).unwrap();
    let r2: Vec<f64> = c.truth.poses.iter().map(|p| p.temp_measured_c.unwrap() - th.sensed_temp_c(p.t_s)).collect();
    assert_ne!(residual, r2);
    // Noise off, offset kept: the same rows less the noise.
    let (s3, _) = ideal_with(Effects { thermal: Some(warm_up(120.0, 0.3, 0.0, true)), ..Default::default() });
    let d = generate(&s3, &robot, &Silent).unwrap();
    for (x, y) in a.dataset.rows.iter().zip(&d.dataset.rows) {
        assert_eq!((&x.q_deg, x.l_mm(), x.t_s), (&y.q_deg, y.l_mm(), y.t_s));
        assert!((x.temp_c.unwrap() - y.temp_c.unwrap()).abs() < 0.25);
    }
}

#[test]
fn temp_column_false_writes_time_only() {
    let th = warm_up(120.0, 0.3, 0.05, false);
    let (s, robot) = ideal_with(Effects { thermal: Some(th), ..Default::default() });
    let g = generate(&s, &robot, &Silent).unwrap();
    let csv = g.dataset.to_csv_string();
    assert!(csv.starts_with("q1,q2,q3,q4,q5,q6,L,t,split\n"), "{}", &csv[..60]);
    assert!(!csv.contains("temp"));
    assert!(g.dataset.rows.iter().all(|r| r.temp_c.is_none() && r.t_s.is_some()));
    let json = serde_json::to_value(&g.truth).unwrap();
    for p in json["poses"].as_array().unwrap() {
        assert!(p.get("temp_measured_c").is_none() && p["delta_t_k"].as_f64().unwrap() > 0.0, "{p}");
    }
    // Without the thermal effect the column stays: a constant ambient.
    let (s, robot) = ideal_with(Effects::default());
    let g = generate(&s, &robot, &Silent).unwrap();
    assert!(g.dataset.rows.iter().all(|r| r.temp_c == Some(20.0)));
}
