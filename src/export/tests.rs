use super::*;
use crate::calib::model::DrawWireGuess;
use rand::{Rng, SeedableRng};

fn arms() -> Vec<Robot> {
    vec![
        Robot::from_urdf_str(include_str!("../../urdf/ur5.urdf"), "ur5").unwrap(),
        Robot::from_urdf_str(include_str!("../../urdf/ur10.urdf"), "ur10").unwrap(),
        Robot::irb120(),
    ]
}

/// The arm's models (D-H, Hayati, frame) with every chain parameter moved off its nominal, as a
/// calibration leaves them.
fn calibrated(robot: &Robot) -> Vec<(CalibModel, Vec<f64>)> {
    let g = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.062, 0.004, -0.003] };
    [CalibModel::dh(robot, &g, false), CalibModel::dh(robot, &g, true), CalibModel::frame(robot, &g)]
        .into_iter()
        .map(|m| {
            let mut x = m.nominal.clone();
            for k in 0..m.n_chain() {
                x[k] += 2e-3 * ((k as f64) * 2.1 + robot.dof() as f64).sin();
            }
            (m, x)
        })
        .collect()
}

fn worst_of_1000(back: &ReadBack, m: &CalibModel, x: &[f64], seed: u64) -> f64 {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut w = m.work();
    (0..1000)
        .map(|_| {
            let q: Vec<f64> = (0..m.chain.n_joints).map(|_| rng.random_range(-std::f64::consts::PI..std::f64::consts::PI)).collect();
            (back.tool_point(&q) - m.tool_point(x, &q, &mut w)).norm()
        })
        .fold(0.0, f64::max)
}

#[test]
fn every_export_read_back_gives_the_calibrated_tool_point_to_a_nanometre() {
    for robot in arms() {
        for (m, x) in calibrated(&robot) {
            let table = JointTable::of(&m, &x);
            for f in FORMATS {
                for ext in f.extensions() {
                    let mut warnings = Vec::new();
                    let text = f.write(&table, &m, &x, Some(&robot), ext, &mut warnings).unwrap();
                    let back = f.read(&text, ext).unwrap_or_else(|e| panic!("{} {} .{ext}: {e}", robot.name, f.name()));
                    let worst = worst_of_1000(&back, &m, &x, 11);
                    assert!(worst < 1e-9, "{} {} {} .{ext}: {worst:e} m", robot.name, m.name, f.name());
                    // Every format carries the chain. Allowed: a UR file's flange off joint 6's axis
                    // (a D-H model's a6 and alpha6 move it off; the rest goes to the tool offset),
                    // and a D-H table's far common normal of nearly parallel axes (a Hayati model's).
                    let said = |w: &String| {
                        (f.name() == "ur-yaml" && (w.contains("off joint 6's axis") || w.contains("turned from joint 6's frame")))
                            || (f.name().ends_with("dh") && w.contains("nearly parallel"))
                    };
                    assert!(warnings.iter().all(said), "{} {} {}: {warnings:?}", robot.name, m.name, f.name());
                }
            }
        }
    }
}

#[test]
fn a_flange_off_joint_6s_axis_goes_to_the_ur_tool_offset_with_a_warning() {
    let robot = &arms()[0];
    let (m, x) = calibrated(robot).remove(2);
    let mut table = JointTable::of(&m, &x);
    // Tilt the flange and move it off the axis: a joint origin cannot hold that.
    let tilt = Frame { rot: nalgebra::Rotation3::from_euler_angles(0.01, -0.02, 0.3).into_inner(), pos: Vector3::new(0.002, -0.001, 0.0) };
    table.flange = table.flange.compose(&tilt);
    let mut warnings = Vec::new();
    let text = ur_yaml::UrYaml.write(&table, &m, &x, None, "yaml", &mut warnings).unwrap();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("off joint 6's axis") && warnings[0].contains("turned") && warnings[0].contains("TCP"), "{}", warnings[0]);
    // A flange turned but on the axis names the turn only (no "off by (0, 0, 0) mm").
    let mut turned = JointTable::of(&m, &x);
    turned.flange = turned.flange.compose(&Frame { pos: Vector3::zeros(), ..tilt });
    let mut only = Vec::new();
    ur_yaml::UrYaml.write(&turned, &m, &x, None, "yaml", &mut only).unwrap();
    assert!(only.len() == 1 && only[0].contains("turned from joint 6's frame") && !only[0].contains("off joint 6's axis"), "{only:?}");
    let back = ur_yaml::UrYaml.read(&text, "yaml").unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut w = m.work();
    for _ in 0..200 {
        let q: Vec<f64> = (0..6).map(|_| rng.random_range(-3.0..3.0)).collect();
        let f = m.flange_frame(&x, &q, &mut w).compose(&tilt);
        assert!((back.tool_point(&q) - f.point(&table.tcp)).norm() < 1e-9);
    }
}

#[test]
fn formats_are_found_by_name_and_by_extension_or_refused_by_name() {
    assert_eq!(format("UR-YAML").unwrap().name(), "ur-yaml");
    assert!(format("dh2").err().unwrap().to_string().contains("expected one of urdf, frames, dh, mdh, ur-yaml"));
    assert_eq!(format_of_path(std::path::Path::new("arm.urdf")).unwrap().name(), "urdf");
    assert_eq!(format_of_path(std::path::Path::new("k.yaml")).unwrap().name(), "ur-yaml");
    let e = format_of_path(std::path::Path::new("t.csv")).err().unwrap().to_string();
    assert!(e.contains("frames, dh, mdh") && e.contains("--format"), "{e}");
    let wam = Robot::from_urdf_str(include_str!("../../urdf/wam.urdf"), "wam").unwrap();
    let (m, x) = calibrated(&wam).remove(2);
    let e = ur_yaml::UrYaml.write(&JointTable::of(&m, &x), &m, &x, None, "yaml", &mut Vec::new()).unwrap_err().to_string();
    assert!(e.contains("six joints; this arm has 7"), "{e}");
}

#[test]
fn malformed_files_are_refused_by_what_is_wrong() {
    let robot = &arms()[1];
    let (m, x) = calibrated(robot).remove(0);
    let t = JointTable::of(&m, &x);
    let yaml = ur_yaml::UrYaml.write(&t, &m, &x, None, "yaml", &mut Vec::new()).unwrap();
    for (edit, expect) in [
        (yaml.replacen("    roll:", "    rol:", 1), "unknown key 'rol'"),
        (yaml.replacen("    yaw: ", "    yaw: abc", 1), "is not a number"),
        (yaml.lines().filter(|l| !l.starts_with("    z:")).collect::<Vec<_>>().join("\n"), "shoulder.z is missing"),
    ] {
        let e = ur_yaml::UrYaml.read(&edit, "yaml").err().unwrap_or_else(|| panic!("accepted: {edit}")).to_string();
        assert!(e.contains(expect), "{e}");
    }
    let csv = dh::Dh::STANDARD.write(&t, &m, &x, None, "csv", &mut Vec::new()).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    let bad = csv.replace(lines[lines.len() - 1], "6,NaN,0,0,0");
    assert!(dh::Dh::STANDARD.read(&bad, "csv").unwrap_err().to_string().contains("D-H row 6 holds NaN"));
    let json = dh::Dh::MODIFIED.write(&t, &m, &x, None, "json", &mut Vec::new()).unwrap();
    assert!(dh::Dh::STANDARD.read(&json, "json").unwrap_err().to_string().contains("a modified D-H table read as standard"));
    let frames = frames::Frames.write(&t, &m, &x, None, "json", &mut Vec::new()).unwrap();
    let e = frames::Frames.read(&frames.replacen("\"axis\"", "\"axes\"", 1), "json").unwrap_err().to_string();
    assert!(e.contains("axis"), "{e}");
    let e = frames::Frames.read("frame,parent\njoint_1,base\n", "csv").unwrap_err().to_string();
    assert!(e.contains("line 2") || e.contains("frame table"), "{e}");
}

/// A Hayati model rebuilt from an exported calibrated URDF (nearly parallel axes: a UR's joints 2
/// to 4) is the exported arm exactly, with no far common normal (which a result file refuses).
#[test]
fn a_hayati_model_of_an_exported_calibrated_urdf_is_exact_and_loadable() {
    for robot in arms() {
        for (m, x) in calibrated(&robot) {
            let text = urdf::urdf(&m, &x, Some(&robot), "calibrated");
            let back = Robot::from_urdf_str(&text, "exported").unwrap();
            let g = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: x[m.n_chain() + 4..m.n_chain() + 7].try_into().unwrap() };
            let h = CalibModel::dh(&back, &g, true);
            assert!(
                h.chain.ops.iter().all(|o| o.base.abs() < 10.0),
                "{} {}: an operation of {} m/rad",
                robot.name,
                m.name,
                h.chain.ops.iter().map(|o| o.base.abs()).fold(0.0, f64::max)
            );
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
            let (mut w1, mut w2) = (m.work(), h.work());
            for _ in 0..200 {
                let q: Vec<f64> = (0..robot.dof()).map(|_| rng.random_range(-3.0..3.0)).collect();
                let d = (m.tool_point(&x, &q, &mut w1) - h.tool_point(&h.nominal, &q, &mut w2)).norm();
                assert!(d < 1e-9, "{} {}: {d:e} m", robot.name, m.name);
            }
        }
    }
}

/// A UR kinematics file read as a robot: the UR10's nominal written by the exporter, read back as
/// a model's nominal arm, puts the flange where the URDF's does (1e-9 m over 200 configurations).
#[test]
fn a_ur_kinematics_file_is_a_nominal_robot() {
    let ur10 = Robot::from_urdf_str(include_str!("../../urdf/ur10.urdf"), "ur10").unwrap();
    let g = DrawWireGuess { exit_m: [0.8, 0.3, 0.05], offset_m: 0.12, tool_m: [0.0, 0.0, 0.0] };
    let m = CalibModel::dh(&ur10, &g, true);
    let mut warnings = Vec::new();
    let text = ur_yaml::UrYaml.write(&JointTable::of(&m, &m.nominal), &m, &m.nominal, None, "yaml", &mut warnings).unwrap();
    let robot = ur_yaml::robot(&text, "ur10.yaml").unwrap();
    assert_eq!(robot.dof(), 6);
    let (a, b) = (ur10.error_chain(), robot.error_chain());
    let (za, zb) = (vec![0.0; a.n_params()], vec![0.0; b.n_params()]);
    let (mut wa, mut wb) = (crate::robot::kinematics::FkWork::new(&a), crate::robot::kinematics::FkWork::new(&b));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for _ in 0..200 {
        let q: Vec<f64> = (0..6).map(|_| rng.random_range(-3.0..3.0)).collect();
        a.forward(&q, &za, 1.0, &mut wa);
        b.forward(&q, &zb, 1.0, &mut wb);
        let (fa, fb) = (a.frame(&wa, a.flange()), b.frame(&wb, b.flange()));
        assert!((fa.pos - fb.pos).norm() < 1e-9 && (fa.rot - fb.rot).norm() < 1e-9, "{q:?}");
    }
    let e = ur_yaml::robot(&text.replace("    pitch:", "    pich:"), "bad.yaml").unwrap_err().to_string();
    assert!(e.contains("bad.yaml") && e.contains("pich"), "{e}");
}
