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
}
