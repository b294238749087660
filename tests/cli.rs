//! The command line, end to end: outputs, determinism and bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn twincal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).arg("--quiet").output().expect("runs")
}

fn scenario(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios").join(format!("{name}.toml"))
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// A small all-effects scenario written next to the test's files.
fn small_full_scenario(dir: &Path, poses: usize) -> PathBuf {
    let text = std::fs::read_to_string(scenario("irb120_evo_nph")).unwrap();
    let text = text.replace("poses = 600", &format!("poses = {poses}")).replace("test = 100", "test = 8");
    let p = dir.join("small.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn generate_writes_dataset_and_truth_deterministically() {
    let dir = tempfile::tempdir().unwrap();
    let sc = small_full_scenario(dir.path(), 40);
    let a = dir.path().join("a");
    let b = dir.path().join("b");
    for out in [&a, &b] {
        let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    for f in ["dataset.csv", "truth.json"] {
        let x = std::fs::read(a.join(f)).unwrap();
        let y = std::fs::read(b.join(f)).unwrap();
        assert!(!x.is_empty());
        assert!(x == y, "{f} differs between two runs with the same seed");
    }
    let csv = std::fs::read_to_string(a.join("dataset.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap(), "q1,q2,q3,q4,q5,q6,L,t,temp,split");
    assert_eq!(lines.count(), 40);
    let truth: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(a.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["sensor"]["exit_point_mm"].as_array().unwrap().len(), 3);
    assert!(truth["sensor"]["length_offset_mm"].is_number());
    assert_eq!(truth["tool"]["point_mm"].as_array().unwrap().len(), 3);
    assert_eq!(truth["poses"].as_array().unwrap().len(), 40);
    assert!(truth["poses"][0]["tool_mm"].is_array() && truth["poses"][0]["length_noise_free_mm"].is_number());
    assert_eq!(truth["parameters"].as_object().unwrap().len(), 42);
    // A different seed gives a different dataset.
    let c = dir.path().join("c");
    let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", c.to_str().unwrap(), "--seed", "5"]);
    assert!(o.status.success());
    assert_ne!(std::fs::read(a.join("dataset.csv")).unwrap(), std::fs::read(c.join("dataset.csv")).unwrap());
}

fn assert_rejected(o: &Output, needle: &str, out: &Path) {
    assert!(!o.status.success(), "should fail");
    let e = stderr(o);
    assert!(e.contains(needle), "error should mention {needle:?}: {e}");
    assert!(!e.contains("panicked"), "{e}");
    assert!(!out.exists() || std::fs::read_dir(out).unwrap().next().is_none(), "no output may be left in {}", out.display());
}

#[test]
fn unknown_scenario_key_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scenario("irb120_ideal")).unwrap().replace("[sampling]", "[sampling]\nposes_count = 3");
    let sc = dir.path().join("bad.toml");
    std::fs::write(&sc, text).unwrap();
    let out = dir.path().join("out");
    let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_rejected(&o, "poses_count", &out);
}

#[test]
fn bad_scenario_values_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let cases = [
        ("stiffness", "[effects.compliance]\nstiffness_nm_per_rad = [1.0, 2.0]\n", "stiffness_nm_per_rad"),
        ("range", "", "range_mm"),
        ("missing", "", "missing field"),
    ];
    for (name, extra, needle) in cases {
        let mut text = std::fs::read_to_string(scenario("irb120_ideal")).unwrap();
        match name {
            "range" => text = text.replace("range_mm = [0.0, 2000.0]", "range_mm = [2000.0, 0.0]"),
            "missing" => text = text.replace("seed = 1\n", ""),
            _ => text.push_str(extra),
        }
        let sc = dir.path().join(format!("{name}.toml"));
        std::fs::write(&sc, text).unwrap();
        let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert_rejected(&o, needle, &out);
    }
}

#[test]
fn readings_outside_the_sensor_range_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    // A short sensor range: most poses fall outside it; the sampler keeps only nominal readings
    // inside, and the true arm pushes a few over the edge.
    let text = std::fs::read_to_string(scenario("irb120_ideal")).unwrap().replace("range_mm = [0.0, 2000.0]", "range_mm = [0.0, 40.0]");
    let sc = dir.path().join("short.toml");
    std::fs::write(&sc, text).unwrap();
    let out = dir.path().join("out");
    let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_rejected(&o, "sensor range", &out);
}

#[test]
fn missing_scenario_file_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = twincal(&["generate", "--scenario", "/nonexistent/x.toml", "--out", out.to_str().unwrap()]);
    assert_rejected(&o, "/nonexistent/x.toml", &out);
}

#[cfg(feature = "rerun")]
#[test]
fn recordings_are_written_for_generate_and_calibrate() {
    let dir = tempfile::tempdir().unwrap();
    let sc = small_full_scenario(dir.path(), 30);
    let out = dir.path().join("data");
    let rrd = dir.path().join("gen.rrd");
    let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap(), "--rrd", rrd.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::metadata(&rrd).unwrap().len() > 10_000);
    let cal = dir.path().join("cal.rrd");
    let res = dir.path().join("r.json");
    let o = twincal(&["calibrate", "--data", out.to_str().unwrap(), "--out", res.to_str().unwrap(), "--rrd", cal.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::metadata(&cal).unwrap().len() > 1_000);
    // Nothing temporary is left next to the recordings.
    let names: Vec<String> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().to_string()).collect();
    assert!(names.iter().all(|n| !n.contains(".tmp")), "{names:?}");
}

#[test]
fn robots_without_six_joints_and_foreign_result_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = r#"<robot name="two"><link name="a"/><link name="b"/><link name="c"/>
      <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="0" velocity="1"/></joint>
      <joint name="j2" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="0" velocity="1"/></joint></robot>"#;
    std::fs::write(dir.path().join("two.urdf"), urdf).unwrap();
    let text = std::fs::read_to_string(scenario("irb120_ideal")).unwrap().replace("robot = \"irb120\"", "robot = \"two.urdf\"");
    let sc = dir.path().join("two.toml");
    std::fs::write(&sc, text).unwrap();
    let out = dir.path().join("out");
    let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_rejected(&o, "six joint angles", &out);

    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{\"method\": \"lm\"}").unwrap();
    let csv = dir.path().join("d.csv");
    std::fs::write(&csv, "q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,300\n").unwrap();
    let pred = dir.path().join("pred");
    let o = twincal(&["predict", "--model", bad.to_str().unwrap(), "--data", csv.to_str().unwrap(), "--out", pred.join("p.csv").to_str().unwrap()]);
    assert_rejected(&o, "not a twincal calibration result", &pred);
}
