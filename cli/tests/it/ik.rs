//! `twincal ik` on pose targets: every solution of the calibrated arm, one row each, with the
//! true tool-point error of each on the twin.

use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};

fn twincal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).output().expect("runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The IRB 120 calibrated on its tracker twin; pose targets are the calibrated arm's own poses at
/// 40 random configurations (5–95 % of each joint's range): `ik` answers each with every branch,
/// the configuration it came from among them (to 0.02°; solved to 0.0001 mm and 0.0001°) wherever the pose is not next to a
/// singularity, each row's true tool point on the twin within a few hundredths of a mm of the
/// target, and the same orientation columns read back; joint targets are refused by name.
#[test]
fn ik_answers_a_pose_target_with_every_solution_of_the_calibrated_arm() {
    use rand::{Rng, SeedableRng};
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("d");
    let scenario = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/irb120_tracker.toml");
    assert!(twincal(&["--quiet", "generate", "--scenario", scenario, "--out", s(&data)]).status.success());
    let result = dir.path().join("r.json");
    let o = twincal(&["--quiet", "calibrate", "--data", s(&data), "--out", s(&result)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = twincal::calib::pipeline::CalibResult::load(&result).unwrap();
    let x_nom = twincal::compensate::nominal_x(&r);
    let c = twincal::compensate::Compensator::new(&r, &x_nom, None, 0.01, 0.001).unwrap();
    let limits = r.model.joint_limits();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let euler = twincal::measurement::Euler::default();
    let (mut rows, mut origins) = (String::from("x,y,z,rx,ry,rz\n"), Vec::new());
    for _ in 0..40 {
        let q: Vec<f64> = limits.iter().map(|(lo, hi)| lo + (hi - lo) * (0.05 + 0.9 * rng.random::<f64>())).collect();
        let (p, rot) = c.predicted_pose(&q);
        let a = euler.angles(&rot).map(f64::to_degrees);
        rows.push_str(&format!("{:.9},{:.9},{:.9},{:.9},{:.9},{:.9}\n", p.x, p.y, p.z, a[0], a[1], a[2]));
        origins.push((q.iter().map(|v| v.to_degrees()).collect::<Vec<f64>>(), p));
    }
    let targets = dir.path().join("poses.csv");
    std::fs::write(&targets, rows).unwrap();
    let out = dir.path().join("ik.csv");
    let o = twincal(&["ik", "--model", s(&result), "--targets", s(&targets), "--tol-mm", "0.0001", "--tol-deg", "0.0001", "--out", s(&out)]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(stderr.contains("in closed form, every one within the joint limits"), "{stderr}");
    eprintln!("{stderr}{}", String::from_utf8_lossy(&o.stdout));
    let text = std::fs::read_to_string(&out).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap_or_else(|| panic!("no column {n} in {header:?}"));
    let mut by_target: BTreeMap<usize, Vec<Vec<&str>>> = BTreeMap::new();
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        by_target.entry(f[col("target")].parse().unwrap()).or_default().push(f);
    }
    assert_eq!(by_target.len(), 40);
    let (mut checked, mut counts) = (0, Vec::new());
    for (t, solutions) in &by_target {
        let (q, p) = &origins[t - 1];
        counts.push(solutions.len());
        for f in solutions {
            assert_eq!(f[col("status")], "converged", "target {t}: {f:?}");
            let at = Vector3::new(f[col("x_mm")].parse().unwrap(), f[col("y_mm")].parse().unwrap(), f[col("z_mm")].parse::<f64>().unwrap());
            assert!((at - p).norm() < 1e-6, "target {t}: its point written as {at:?}, asked {p:?}");
            let te: f64 = f[col("true_error_mm")].parse().unwrap();
            assert!(te < 0.05, "target {t}: a solution's true tool point {te:.4} mm off the target");
        }
        // Next to a singularity (the conditioning column says it) a configuration is
        // ill-conditioned: the solutions there are a degree apart or more for a hundredth of a mm.
        let conditioned = |f: &Vec<&str>| f[col("conditioning_mm_per_rad")].parse::<f64>().unwrap() >= twincal::ik::solver::NEAR_SINGULAR_MM_PER_RAD;
        if solutions.iter().all(conditioned) {
            checked += 1;
            let angles = |f: &Vec<&str>| (1..=6).map(|j| f[col(&format!("q{j}"))].parse::<f64>().unwrap()).collect::<Vec<f64>>();
            let near = |a: &[f64]| a.iter().zip(q).all(|(x, y)| ((x - y + 540.0).rem_euclid(360.0) - 180.0).abs() < 0.02);
            assert!(solutions.iter().any(|f| near(&angles(f))), "target {t}: {q:?} not among {:?}", solutions.iter().map(angles).collect::<Vec<_>>());
        }
    }
    eprintln!("{checked} regular targets; solutions per target {counts:?}");
    assert!(checked >= 30 && counts.iter().all(|n| (1..=8).contains(n)) && counts.iter().any(|n| *n >= 4), "{counts:?}");
    // Joint targets are compensate's, not ik's.
    let joints = dir.path().join("joints.csv");
    std::fs::write(&joints, "q1,q2,q3,q4,q5,q6,rx\n0,0,0,0,30,0,1\n").unwrap();
    let o = twincal(&["ik", "--model", s(&result), "--targets", s(&joints), "--out", s(&dir.path().join("j.csv"))]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
}
