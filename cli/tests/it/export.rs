//! `twincal export`, end to end: a calibrated UR5 written in every format, each file read back
//! by the library and checked against the result's own tool point; what a file cannot carry
//! named; bad requests refused with exit code 2 and no file.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use twincal::calib::pipeline::CalibResult;

fn twincal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).output().expect("runs")
}

fn root() -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).to_path_buf()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn a_calibrated_ur5_is_written_in_every_format_and_each_reads_back_to_its_tool_point() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(root().join("scenarios/ur5_tracker.toml")).unwrap();
    let scenario = dir.path().join("ur5.toml");
    let urdf = root().join("urdf/ur5.urdf");
    std::fs::write(&scenario, text.replace("poses = 300", "poses = 120").replace("test = 100", "test = 20").replace("../urdf/ur5.urdf", s(&urdf))).unwrap();
    let data = dir.path().join("d");
    assert!(twincal(&["--quiet", "generate", "--scenario", s(&scenario), "--out", s(&data)]).status.success());
    let result = dir.path().join("r.json");
    let o = twincal(&["--quiet", "calibrate", "--data", s(&data), "--model", s(&urdf), "--out", s(&result)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = CalibResult::load(&result).unwrap();
    for (name, format) in
        [("ur5.urdf", None), ("ur5.yaml", None), ("f.csv", Some("frames")), ("f.json", Some("frames")), ("dh.csv", Some("dh")), ("mdh.json", Some("mdh"))]
    {
        let out = dir.path().join(name);
        let mut args = vec!["export", "--model", s(&result), "--out", s(&out), "--robot", s(&urdf)];
        if let Some(f) = format {
            args.extend(["--format", f]);
        }
        let o = twincal(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success() && err.contains("read back"), "{name}: {err}");
        let f = twincal::export::format(format.unwrap_or(if name.ends_with("urdf") { "urdf" } else { "ur-yaml" })).unwrap();
        let back = f.read(&std::fs::read_to_string(&out).unwrap(), &twincal::export::extension(&out)).unwrap();
        let worst = twincal::export::round_trip_error(&back, &r.model, &r.x, 1000);
        assert!(worst < 1e-9, "{name}: {worst:e} m");
    }
}

#[test]
fn effects_and_correctors_are_named_as_not_carried_and_bad_requests_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("d");
    assert!(twincal(&["--quiet", "generate", "--out", s(&data)]).status.success());
    let result = dir.path().join("r.json");
    let o = twincal(&["--quiet", "calibrate", "--data", s(&data), "--effects", "eccentricity:1", "--method", "rbf", "--out", s(&result)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.path().join("f.json");
    let o = twincal(&["export", "--model", s(&result), "--out", s(&out), "--format", "frames"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("warning: eccentricity[j1] is not carried") && err.contains("corrector is not carried"), "{err}");
    let file: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(file["not_carried"].as_array().unwrap().len(), 2, "{file}");
    for (args, needle) in [
        (vec!["--out", "t.csv"], "give --format"),
        (vec!["--out", "t.step"], "cannot tell the export format"),
        (vec!["--out", "t.txt", "--format", "dh"], "a dh file ends in .csv or .json"),
        (vec!["--out", "t.yaml", "--robot", "nowhere.urdf"], "nowhere.urdf"),
        (vec!["--out", "t.yaml", "--robot", "ur5"], "expected irb120 or a .urdf path"),
        (vec!["--out", "t.urdf", "--robot", concat!(env!("CARGO_MANIFEST_DIR"), "/../urdf/ur10.urdf")], "is not the arm the model was calibrated on"),
    ] {
        let mut full = vec!["--quiet", "export", "--model", s(&result)];
        let owned: Vec<String> = args.iter().map(|a| if a.starts_with("t.") { s(&dir.path().join(a)).to_string() } else { a.to_string() }).collect();
        full.extend(owned.iter().map(String::as_str));
        let o = twincal(&full);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    let leftovers: Vec<_> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).filter(|n| n.starts_with("t.")).collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    // A hand-edited result file is refused by the loader, with exit code 2.
    let edited = dir.path().join("edited.json");
    std::fs::write(&edited, std::fs::read_to_string(&result).unwrap().replacen("\"x\"", "\"y_\"", 1)).unwrap();
    let o = twincal(&["--quiet", "export", "--model", s(&edited), "--out", s(&dir.path().join("e.urdf"))]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A UR's kinematics file as the nominal (the factory calibration the UR driver extracts): the
/// UR10's own kinematics written as one and given as `--model` (with the URDF lending its
/// inertials) calibrates the twin's tracker data as the URDF does (held-out RMSE equal to 1e-6
/// mm); a file that is no kinematics file is refused by name.
#[test]
fn a_ur_kinematics_file_is_the_nominal_of_a_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let d = |n: &str| dir.path().join(n);
    let ur10 = root().join("urdf/ur10.urdf");
    let ok = |o: Output| {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    ok(twincal(&["--quiet", "generate", "--scenario", s(&root().join("scenarios/ur10_tracker.toml")), "--out", s(&d("data"))]));
    // The nominal arm (placement only) written as a UR kinematics file.
    ok(twincal(&["--quiet", "calibrate", "--data", s(&d("data")), "--model", s(&ur10), "--placement-only", "--out", s(&d("nominal.json"))]));
    ok(twincal(&["--quiet", "export", "--model", s(&d("nominal.json")), "--out", s(&d("factory.yaml"))]));
    let rmse = |p: &Path| CalibResult::load(p).unwrap().evaluation.metrics.test_after.unwrap().rmse;
    ok(twincal(&["--quiet", "calibrate", "--data", s(&d("data")), "--model", s(&ur10), "--out", s(&d("urdf.json"))]));
    ok(twincal(&["--quiet", "calibrate", "--data", s(&d("data")), "--model", s(&d("factory.yaml")), "--robot", s(&ur10), "--out", s(&d("yaml.json"))]));
    assert!((rmse(&d("urdf.json")) - rmse(&d("yaml.json"))).abs() < 1e-6, "{} vs {}", rmse(&d("urdf.json")), rmse(&d("yaml.json")));
    // Joint by joint against the factory file: the file itself is its own to 1e-6 mm; the
    // recalibration departs from it by the twin's geometric errors (a few tenths of a mm).
    let gaps = |model: &Path, out: &str| -> Vec<(f64, f64)> {
        let o = twincal(&["export", "--model", s(model), "--out", s(&d(out)), "--against", s(&d("factory.yaml"))]);
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert!(o.status.success(), "{err}");
        let rows: Vec<(f64, f64)> = err
            .lines()
            .filter(|l| {
                let w: Vec<&str> = l.split_whitespace().collect();
                (w.first() == Some(&"joint") && w.get(1).is_some_and(|n| n.parse::<usize>().is_ok())) || w.first() == Some(&"flange")
            })
            .map(|l| {
                let v: Vec<f64> = l.split_whitespace().filter_map(|w| w.trim_end_matches('°').parse().ok()).collect();
                (v[v.len() - 2], v[v.len() - 1])
            })
            .collect();
        assert_eq!(rows.len(), 7, "six joints and the flange: {err}");
        rows
    };
    assert!(gaps(&d("nominal.json"), "same.yaml").iter().all(|(p, r)| *p < 1e-6 && *r < 1e-6));
    let moved = gaps(&d("yaml.json"), "recal.yaml");
    let largest = moved.iter().map(|g| g.0).fold(0.0, f64::max);
    assert!(largest > 0.05 && largest < 5.0, "{moved:?}");
    // A file that is no UR kinematics file is refused by name.
    std::fs::write(d("bad.yaml"), "kinematics:\n  shoulder:\n    x: 0\n").unwrap();
    let o = twincal(&["calibrate", "--data", s(&d("data")), "--model", s(&d("bad.yaml")), "--out", s(&d("bad.json"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("bad.yaml") && !d("bad.json").exists(), "{}", String::from_utf8_lossy(&o.stderr));
}
