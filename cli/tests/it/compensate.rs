//! `twincal compensate`, end to end: points and taught joint targets, the columns it writes, a
//! payload stated for a model with compliance, and bad requests refused with exit code 2.

use std::path::Path;
use std::process::{Command, Output};

fn twincal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).output().expect("runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn compensate_writes_commands_for_points_and_taught_joints_and_refuses_bad_requests() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("d");
    assert!(twincal(&["--quiet", "generate", "--out", s(&data)]).status.success());
    let result = dir.path().join("r.json");
    let o = twincal(&[
        "--quiet",
        "calibrate",
        "--data",
        s(&data),
        "--effects",
        "compliance",
        "--payload-kg",
        "0.5",
        "--payload-com-mm",
        "40,0,0",
        "--out",
        s(&result),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let points = dir.path().join("p.csv");
    std::fs::write(&points, "x,y,z\n400,100,500\n350,-150,450\n9000,0,0\n").unwrap();
    let out = dir.path().join("c.csv");
    let o = twincal(&["compensate", "--model", s(&result), "--targets", s(&points), "--out", s(&out), "--payload-kg", "2", "--payload-com-mm", "0,0,80"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("1 of 3 targets not reached") && err.contains("under a 2 kg payload"), "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let mut rd = csv::Reader::from_reader(text.as_bytes());
    let header: Vec<String> = rd.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(&header[..4], ["x_mm", "y_mm", "z_mm", "q1_deg"]);
    let status = header.iter().position(|h| h == "status").unwrap();
    let residual = header.iter().position(|h| h == "residual_mm").unwrap();
    let rows: Vec<csv::StringRecord> = rd.records().map(Result::unwrap).collect();
    assert_eq!(rows.iter().map(|r| r[status].to_string()).collect::<Vec<_>>(), ["reachable", "reachable", "unreachable"]);
    assert!(rows[..2].iter().all(|r| r[residual].parse::<f64>().unwrap() <= 0.001), "{text}");
    // Joint targets taught on the nominal model.
    let joints = dir.path().join("q.csv");
    std::fs::write(&joints, "q1,q2,q3,q4,q5,q6\n10,20,-10,30,40,50\n").unwrap();
    let o = twincal(&["--quiet", "compensate", "--model", s(&result), "--targets", s(&joints), "--out", s(&dir.path().join("cq.csv"))]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let never = dir.path().join("never.csv");
    for (args, needle) in [
        (vec!["--targets", "nowhere.csv"], "nowhere.csv"),
        (vec!["--targets", "P", "--payload-kg", "-2"], "--payload-kg must be in"),
        (vec!["--targets", "P", "--tol-mm", "0"], "--tol-mm must be in"),
        (vec!["--targets", "P", "--out", "P"], "refusing to overwrite"),
    ] {
        let mut full = vec!["--quiet", "compensate", "--model", s(&result)];
        let owned: Vec<String> = args.iter().map(|a| if *a == "P" { s(&points).to_string() } else { a.to_string() }).collect();
        full.extend(owned.iter().map(String::as_str));
        if !args.contains(&"--out") {
            full.extend(["--out", s(&never)]);
        }
        let o = twincal(&full);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle) && !err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(!never.exists());
    // Joint targets and pose angles written in radians are refused, not read as tiny degrees.
    let q_rad = dir.path().join("q_rad.csv");
    let rows: Vec<String> = (0..12).map(|k| format!("0.2,{},-0.4,0.6,0.8,1.0", -0.5 + 0.1 * k as f64)).collect();
    std::fs::write(&q_rad, format!("q1,q2,q3,q4,q5,q6\n{}\n", rows.join("\n"))).unwrap();
    let p_rad = dir.path().join("p_rad.csv");
    let rows: Vec<String> = (0..12).map(|k| format!("{},200,400,3.1,{},0.5", 300 + 10 * k, -0.3 + 0.05 * k as f64)).collect();
    std::fs::write(&p_rad, format!("x,y,z,rx,ry,rz\n{}\n", rows.join("\n"))).unwrap();
    for (file, needle) in [(&q_rad, "columns q1..q6 look like radians (all 12 targets"), (&p_rad, "columns rx, ry, rz look like radians (all 12 targets")] {
        let o = twincal(&["--quiet", "compensate", "--model", s(&result), "--targets", s(file), "--out", s(&never)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(needle), "{err}");
    }
    assert!(!never.exists());
}

/// Pose targets on a UR10 calibrated from a 6-D probe: each reached in position and orientation
/// (the model's residuals within the tolerances), the orientation columns written in the
/// convention asked for, and bad pose requests refused by name.
#[test]
fn compensate_reaches_pose_targets_in_position_and_orientation() {
    use twincal::compensate::nominal_x;
    use twincal::ik::IkModel;
    use twincal::measurement::Euler;
    let dir = tempfile::tempdir().unwrap();
    let scenario = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/ur10_pose.toml");
    let data = dir.path().join("d");
    assert!(twincal(&["--quiet", "generate", "--scenario", scenario, "--out", s(&data)]).status.success());
    let result = dir.path().join("r.json");
    let urdf = concat!(env!("CARGO_MANIFEST_DIR"), "/../urdf/ur10.urdf");
    let o = twincal(&["--quiet", "calibrate", "--data", s(&data), "--model", urdf, "--out", s(&result)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Targets: the nominal model's tool poses at three configurations, in extrinsic z-y-x angles.
    let r = twincal::calib::pipeline::CalibResult::load(&result).unwrap();
    let x_nom = nominal_x(&r);
    let ik = IkModel::new(&r.model, &x_nom, None, r.model.joint_limits());
    let mut w = ik.work();
    let zyx = Euler::parse("zyx").unwrap();
    let mut text = String::from("x,y,z,rx,ry,rz\n");
    let configurations = [[10.0, -60.0, 70.0, -100.0, -80.0, 20.0], [-30.0, -110.0, -40.0, -60.0, 50.0, -90.0], [60.0, -45.0, 100.0, -150.0, -30.0, 120.0f64]];
    for q in &configurations {
        let (p, m) = ik.pose(&q.map(f64::to_radians), &mut w, None);
        let a = zyx.angles(&m).map(f64::to_degrees);
        text += &format!("{},{},{},{},{},{}\n", p.x, p.y, p.z, a[0], a[1], a[2]);
    }
    let targets = dir.path().join("poses.csv");
    std::fs::write(&targets, &text).unwrap();
    let out = dir.path().join("c.csv");
    let o = twincal(&["--quiet", "compensate", "--model", s(&result), "--targets", s(&targets), "--euler", "zyx", "--out", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let written = std::fs::read_to_string(&out).unwrap();
    let mut rd = csv::Reader::from_reader(written.as_bytes());
    let header: Vec<String> = rd.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(&header[..7], ["x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg", "q1_deg"]);
    let col = |n: &str| header.iter().position(|h| h == n).unwrap();
    let rows: Vec<csv::StringRecord> = rd.records().map(Result::unwrap).collect();
    let given: Vec<Vec<f64>> = text.lines().skip(1).map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    for (row, g) in rows.iter().zip(&given) {
        let v = |n: &str| row[col(n)].parse::<f64>().unwrap();
        assert_eq!(&row[col("status")], "reachable", "{written}");
        assert!(v("residual_mm") <= 0.001 && v("residual_deg") <= 0.001, "{written}");
        // The calibration moves the arm: the nominal command misses the target by more.
        assert!(v("nominal_error_mm") > 0.05 && v("nominal_error_deg") > 0.001, "{written}");
        assert!((v("rx_deg") - g[3]).abs() < 1e-6 && (v("rz_deg") - g[5]).abs() < 1e-6, "{written}");
        // The filtered pose is the nominal model's at the command.
        let q: Vec<f64> = (1..=6).map(|j| v(&format!("q{j}_deg")).to_radians()).collect();
        let (fp, fm) = ik.pose(&q, &mut w, None);
        let fa = zyx.angles(&fm).map(f64::to_degrees);
        assert!((fp.x - v("x_filtered_mm")).abs() < 1e-5 && (fa[1] - v("ry_filtered_deg")).abs() < 1e-5, "{written}");
    }
    let two = dir.path().join("two.csv");
    std::fs::write(&two, "x,y,z,rx,ry\n400,0,500,0,0\n").unwrap();
    for (args, needle) in [
        (vec!["--targets", s(&targets), "--euler", "XXY"], "--euler"),
        (vec!["--targets", s(&targets), "--tol-deg", "0"], "--tol-deg must be in"),
        (vec!["--targets", s(&two)], "2 of the orientation columns"),
    ] {
        let never = dir.path().join("never.csv");
        let mut full = vec!["--quiet", "compensate", "--model", s(&result), "--out", s(&never)];
        full.extend(args.iter().copied());
        let o = twincal(&full);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle) && !err.contains("panicked"), "{args:?}: {err}");
        assert!(!never.exists());
    }
    // Fifteen poses over the whole workspace, written in two conventions: each command is the
    // same whatever the convention, beside its nominal command (its branch), its angles the
    // turns nearest the nominal's.
    let mut rng = 7u64;
    let mut next = || {
        rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((rng >> 11) as f64 / (1u64 << 53) as f64) * 340.0 - 170.0
    };
    let xyz = Euler::parse("XYZ").unwrap();
    let (mut a, mut b) = (String::from("x,y,z,rx,ry,rz\n"), String::from("x,y,z,rx,ry,rz\n"));
    for _ in 0..15 {
        let q: Vec<f64> = (0..6).map(|_| next().to_radians()).collect();
        let (p, m) = ik.pose(&q, &mut w, None);
        for (text, e) in [(&mut a, &zyx), (&mut b, &xyz)] {
            let g = e.angles(&m).map(f64::to_degrees);
            *text += &format!("{},{},{},{},{},{}\n", p.x, p.y, p.z, g[0], g[1], g[2]);
        }
    }
    let commands = |text: &str, euler: &str| -> Vec<(String, Vec<f64>, Vec<f64>)> {
        let (t, out) = (dir.path().join(format!("t_{euler}.csv")), dir.path().join(format!("c_{euler}.csv")));
        std::fs::write(&t, text).unwrap();
        let o = twincal(&["--quiet", "compensate", "--model", s(&result), "--targets", s(&t), "--euler", euler, "--out", s(&out)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let written = std::fs::read_to_string(&out).unwrap();
        let mut rd = csv::Reader::from_reader(written.as_bytes());
        let header: Vec<String> = rd.headers().unwrap().iter().map(String::from).collect();
        let col = |n: &str| header.iter().position(|h| h == n).unwrap();
        rd.records()
            .map(|r| {
                let r = r.unwrap();
                let qs = |p: &str| (1..=6).map(|j| r[col(&format!("{p}q{j}_deg"))].parse::<f64>().unwrap()).collect::<Vec<f64>>();
                (r[col("status")].to_string(), qs(""), qs("nominal_"))
            })
            .collect()
    };
    let (ca, cb) = (commands(&a, "zyx"), commands(&b, "XYZ"));
    let reached = ca.iter().filter(|c| c.0 == "reachable").count();
    assert!(reached >= 12, "{reached} of 15 reached: {ca:?}");
    for ((sa, qa, na), (sb, qb, nb)) in ca.iter().zip(&cb) {
        assert_eq!(sa, sb);
        if sa != "reachable" {
            continue;
        }
        let far = |q: &[f64], n: &[f64]| q.iter().zip(n).map(|(x, y)| (x - y).abs()).fold(0.0f64, f64::max);
        assert!(far(qa, na) <= twincal::compensate::BRANCH_DEG, "a command off its nominal's branch: {qa:?} from {na:?}");
        assert!(far(qa, qb) < 1e-3 && far(na, nb) < 1e-3, "the convention changed the command: {qa:?} / {qb:?} (nominal {na:?} / {nb:?})");
    }
}
