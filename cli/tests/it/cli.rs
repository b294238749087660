//! The command line, end to end: outputs, determinism and bad input.

use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn twincal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).arg("--quiet").output().expect("runs")
}

fn scenario(name: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios").join(format!("{name}.toml"))
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

#[test]
fn a_scenario_written_for_another_arm_and_foreign_result_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = r#"<robot name="two"><link name="a"/><link name="b"/><link name="c"/>
      <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="0" velocity="1"/></joint>
      <joint name="j2" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="0" velocity="1"/></joint></robot>"#;
    std::fs::write(dir.path().join("two.urdf"), urdf).unwrap();
    let text = std::fs::read_to_string(scenario("irb120_ideal")).unwrap().replace("robot = \"irb120\"", "robot = \"two.urdf\"");
    let sc = dir.path().join("two.toml");
    std::fs::write(&sc, text).unwrap();
    let out = dir.path().join("out");
    // Any number of joints is fine, but this scenario's six sampling ranges do not fit two.
    let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_rejected(&o, "the robot has 2 joints", &out);

    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{\"method\": \"lm\"}").unwrap();
    let csv = dir.path().join("d.csv");
    std::fs::write(&csv, "q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,300\n").unwrap();
    let pred = dir.path().join("pred");
    let o = twincal(&["predict", "--model", bad.to_str().unwrap(), "--data", csv.to_str().unwrap(), "--out", pred.join("p.csv").to_str().unwrap()]);
    assert_rejected(&o, "not a twincal calibration result", &pred);
}

/// What would keep the simulation busy for days is refused up front: a tiny speed fraction, a
/// joint without a velocity limit; and a revolute joint without a range is named as such.
#[test]
fn tours_that_would_run_for_days_and_joints_without_limits_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let base = std::fs::read_to_string(scenario("irb120_geometric")).unwrap();
    let slow = dir.path().join("slow.toml");
    std::fs::write(&slow, base.replace("[sampling]\n", "[sampling]\nspeed_fraction = 1e-9\n")).unwrap();
    let t0 = std::time::Instant::now();
    let o = twincal(&["generate", "--scenario", s(&slow), "--out", s(&out)]);
    assert_rejected(&o, "h of robot time", &out);
    assert_eq!(o.status.code(), Some(2));
    let o = twincal(&["study", "hold", "--poses", "3", "--holds", "1", "--speeds", "1e-9", "--rrd", s(&dir.path().join("h.rrd"))]);
    assert!(!o.status.success() && stderr(&o).contains("h of robot time"), "{}", stderr(&o));
    assert!(t0.elapsed().as_secs() < 60, "refused up front, not after simulating");

    let urdf = |joint2: &str| {
        format!(
            r#"<robot name="two"><link name="a"/><link name="b"/><link name="c"/>
      <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="0" velocity="1"/></joint>
      <joint name="j2" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>{joint2}</joint></robot>"#
        )
    };
    let two = base
        .replace("robot = \"irb120\"", "robot = \"two.urdf\"")
        .replace("ranges_deg = [[-90, 90], [-45, 80], [-90, 50], [-150, 150], [-100, 100], [-180, 180]]", "ranges_deg = [[-50, 50], [-50, 50]]");
    let sc = dir.path().join("two.toml");
    std::fs::write(&sc, two).unwrap();
    std::fs::write(dir.path().join("two.urdf"), urdf("")).unwrap();
    let o = twincal(&["generate", "--scenario", s(&sc), "--out", s(&out)]);
    assert_rejected(&o, "revolute joint 'j2' has no range", &out);
    // A joint without a velocity limit moves at a default speed, and the user is told.
    std::fs::write(dir.path().join("two.urdf"), urdf(r#"<limit lower="-1" upper="1" effort="0" velocity="0"/>"#)).unwrap();
    let o = twincal(&["generate", "--scenario", s(&sc), "--out", s(&out)]);
    assert!(stderr(&o).contains("warning: joint 'j2' of robot 'two' has no velocity limit in its URDF"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("panicked"));
}

/// A spreadsheet the reader library panics on (a cell pointing at a shared string that does not
/// exist) gets the clean error and no panic text on stderr.
#[test]
fn a_spreadsheet_the_reader_panics_on_prints_no_panic_text() {
    use std::io::Write as _;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.xlsx");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
    let ns = "http://schemas.openxmlformats.org/spreadsheetml/2006/main";
    let rel = "http://schemas.openxmlformats.org/officeDocument/2006/relationships";
    let parts = [
        (
            "[Content_Types].xml",
            r#"<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types"><Default Extension="xml" ContentType="application/xml"/></Types>"#
                .to_string(),
        ),
        ("xl/workbook.xml", format!(r#"<workbook xmlns="{ns}" xmlns:r="{rel}"><sheets><sheet name="S" sheetId="1" r:id="rId1"/></sheets></workbook>"#)),
        (
            "xl/_rels/workbook.xml.rels",
            format!(
                r#"<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships"><Relationship Id="rId1" Type="{rel}/worksheet" Target="worksheets/sheet1.xml"/></Relationships>"#
            ),
        ),
        ("xl/sharedStrings.xml", format!(r#"<sst xmlns="{ns}" count="1" uniqueCount="1"><si><t>q1</t></si></sst>"#)),
        ("xl/worksheets/sheet1.xml", format!(r#"<worksheet xmlns="{ns}"><sheetData><row r="1"><c r="A1" t="s"><v>99</v></c></row></sheetData></worksheet>"#)),
    ];
    for (name, text) in parts {
        zip.start_file(name, zip::write::SimpleFileOptions::default()).unwrap();
        zip.write_all(text.as_bytes()).unwrap();
    }
    zip.finish().unwrap();
    let o = twincal(&["calibrate", "--data", s(&path), "--out", s(&dir.path().join("r.json"))]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(e.contains("bad.xlsx") && e.contains("malformed"), "{e}");
    assert!(!e.contains("panicked") && !e.contains("backtrace"), "{e}");
}

/// Names in `dir` (sorted), recursively one level for folders.
fn names_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().to_string()).collect();
    v.sort();
    v
}

fn assert_no_temp_files(dir: &Path) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name().to_string_lossy().to_string();
        assert!(!name.contains(".tmp"), "temporary file {name} left in {}", dir.display());
        if entry.file_type().unwrap().is_dir() {
            assert_no_temp_files(&entry.path());
        }
    }
}

/// A small noisy dataset with geometric errors (fast to generate and to calibrate).
fn small_geometric(dir: &Path, name: &str) -> PathBuf {
    let text = std::fs::read_to_string(scenario("irb120_geometric")).unwrap().replace("poses = 400", "poses = 100").replace("test = 100", "test = 10");
    let sc = dir.join(format!("{name}.toml"));
    std::fs::write(&sc, text).unwrap();
    let out = dir.join(name);
    let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    out
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn outputs_onto_inputs_or_onto_each_other_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let csv = data.join("dataset.csv");
    let truth = data.join("truth.json");
    let before_csv = std::fs::read(&csv).unwrap();
    let before_truth = std::fs::read(&truth).unwrap();
    let res = dir.path().join("r.json");
    let o = twincal(&["calibrate", "--data", s(&data), "--out", s(&res)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let before_res = std::fs::read(&res).unwrap();
    let sc = dir.path().join("d.toml");
    let via_dots = data.join("../d/dataset.csv");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["calibrate", "--data", s(&data), "--out", s(&csv)], "is also an input"),
        (vec!["calibrate", "--data", s(&csv), "--out", s(&via_dots)], "is also an input"),
        (vec!["calibrate", "--data", s(&data), "--urdf", s(&truth)], "is also an input"),
        (vec!["calibrate", "--data", s(&data), "--out", s(&res), "--rrd", s(&res)], "are the same file"),
        (vec!["calibrate", "--data", s(&data), "--out", s(dir.path())], "existing folder"),
        (vec!["predict", "--model", s(&res), "--data", s(&data), "--out", s(&csv)], "is also an input"),
        (vec!["predict", "--model", s(&res), "--data", s(&csv), "--out", s(&res)], "is also an input"),
        (vec!["compare", "--data", s(&data), "--seeds", "1", "--methods", "lm", "--out", s(&csv)], "is also an input"),
        // A folder input means every file read there: the twin's truth too.
        (vec!["predict", "--model", s(&res), "--data", s(&data), "--out", s(&truth)], "is also an input"),
        (vec!["compare", "--data", s(&data), "--seeds", "1", "--methods", "lm", "--out", s(&truth)], "is also an input"),
        (vec!["compare", "--data", s(&data), "--seeds", "1", "--methods", "lm", "--rrd", s(&truth)], "is also an input"),
        // ik reads the result's data and its twin (found beside the data or named by --twin).
        (vec!["ik", "--model", s(&res), "--random", "2", "--out", s(&truth)], "is also an input"),
        (vec!["ik", "--model", s(&res), "--random", "2", "--out", s(&csv)], "is also an input"),
        (vec!["ik", "--model", s(&res), "--twin", s(&data), "--random", "2", "--out", s(&truth)], "is also an input"),
        (vec!["ik", "--model", s(&res), "--random", "2", "--out", s(&res)], "is also an input"),
        (vec!["generate", "--scenario", s(&sc), "--out", s(dir.path()), "--rrd", s(&sc)], "is also an input"),
        (vec!["generate", "--scenario", s(&sc), "--out", s(&data), "--rrd", s(&csv)], "are the same file"),
    ];
    for (args, needle) in cases {
        let o = twincal(&args);
        assert!(!o.status.success(), "{args:?} should fail");
        let e = stderr(&o);
        assert!(e.contains(needle) && !e.contains("panicked"), "{args:?}: {e}");
    }
    assert_eq!(std::fs::read(&csv).unwrap(), before_csv);
    assert_eq!(std::fs::read(&truth).unwrap(), before_truth);
    assert_eq!(std::fs::read(&res).unwrap(), before_res);
    assert_no_temp_files(dir.path());
}

#[test]
fn stale_truth_is_detected() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let truth: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(data.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["dataset"]["file"], "dataset.csv");
    assert_eq!(truth["dataset"]["rows"], 100);
    assert_eq!(truth["dataset"]["sha256"].as_str().unwrap().len(), 64);
    // Edit one value of the dataset: the truth no longer describes it.
    let csv = std::fs::read_to_string(data.join("dataset.csv")).unwrap();
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[5].split(',').map(String::from).collect();
    let l: f64 = cells[6].parse().unwrap();
    cells[6] = format!("{}", l + 0.5);
    lines[5] = cells.join(",");
    std::fs::write(data.join("dataset.csv"), lines.join("\n") + "\n").unwrap();
    let res = dir.path().join("r.json");
    for d in [data.clone(), data.join("dataset.csv")] {
        let o = twincal(&["calibrate", "--data", s(&d), "--out", s(&res)]);
        assert_rejected(&o, "does not belong to", &dir.path().join("none"));
        assert!(stderr(&o).contains("regenerate"), "{}", stderr(&o));
        assert!(!res.exists());
    }
    // A truth file from an older twincal (no fingerprint): ignored with a warning.
    let mut old = truth.clone();
    old.as_object_mut().unwrap().remove("dataset");
    std::fs::write(data.join("truth.json"), old.to_string()).unwrap();
    let o = twincal(&["calibrate", "--data", s(&data), "--out", s(&res)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("warning:") && stderr(&o).contains("no dataset fingerprint"), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&res).unwrap()).unwrap();
    assert!(r["evaluation"]["truth_comparison"].is_null(), "an unmatched truth must not be used");
}

#[test]
fn negative_sensor_guess_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    // Exit point behind and to the right of the base: negative x and y.
    let text = std::fs::read_to_string(scenario("irb120_geometric"))
        .unwrap()
        .replace("exit_point_mm = [800.0, 300.0, 50.0]", "exit_point_mm = [-700.0, -300.0, 50.0]")
        .replace("poses = 400", "poses = 100")
        .replace("test = 100", "test = 10");
    let sc = dir.path().join("neg.toml");
    std::fs::write(&sc, text).unwrap();
    let data = dir.path().join("neg");
    let o = twincal(&["generate", "--scenario", s(&sc), "--out", s(&data)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("r.json");
    // Space-separated value starting with '-', as a user types it.
    let o = twincal(&["calibrate", "--data", s(&data), "--draw-wire-guess", "-690,-310,45,118,60,0,0", "--out", s(&res)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&res).unwrap()).unwrap();
    let exit_x = r["parameters"].as_array().unwrap().iter().find(|p| p["name"] == "exit.x").unwrap()["value"].as_f64().unwrap();
    assert!((exit_x + 700.0).abs() < 5.0, "exit.x = {exit_x}");
    // Other numeric options take negative values too, and are then refused by range, not by the parser.
    let o = twincal(&["calibrate", "--data", s(&data), "--test-fraction", "-0.2", "--out", s(&res)]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--test-fraction must be in"), "{}", stderr(&o));
}

#[test]
fn options_that_do_not_apply_or_make_no_sense_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let d = s(&data);
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["calibrate", "--data", d, "--model", "generic6r", "--params", "dh"], "--params dh applies to nominal models"),
        (vec!["compare", "--data", d, "--model", "generic6r", "--params", "frame"], "--params frame applies to nominal models"),
        (vec!["bench", "twin", "--seeds", "3"], "--seeds applies to bench calib"),
        (vec!["bench", "--compare"], "--compare applies to bench calib"),
        (vec!["bench", "calib", "--seeds", "0"], "--seeds must be between 1 and 1000, got 0"),
        (vec!["bench", "calib", "--scenario", "x.toml"], "--scenario applies to bench twin"),
        (vec!["bench", "twin", "--repeat", "0"], "--repeat must be between 1 and 1000, got 0"),
        (vec!["bench", "fast"], "invalid value 'fast'"),
        (vec!["bench", "diagnose-ur10", "--seeds", "3"], "not bench diagnose-ur10 (it runs on ../shared/data"),
        (vec!["bench", "diagnose-ur10", "--repeat", "0"], "--repeat must be between 1 and 1000, got 0"),
        (vec!["bench", "calib", "--categories", "hidden"], "--categories applies to bench diagnose"),
        (vec!["bench", "diagnose", "--categories", "hidden,foo"], "unknown --categories entry 'foo'"),
        (vec!["bench", "noise-model", "--scenario", "x.toml"], "--scenario applies to bench twin, replay, not bench noise-model"),
        (vec!["calibrate", "--data", d, "--noise-model", "gls"], "invalid value 'gls' for '--noise-model"),
        (vec!["compare", "--data", d, "--test-fraction", "0"], "--test-fraction 0 holds no row out, and compare scores"),
        (vec!["compare", "--data", d, "--test-fraction", "1"], "--test-fraction must be in [0, 1) (0: no row held out), got 1"),
        (vec!["calibrate", "--data", d, "--test-fraction", "1"], "--test-fraction must be in [0, 1) (0: no row held out), got 1"),
        (vec!["diagnose", "--data", d, "--test-fraction", "-0.1"], "--test-fraction must be in [0, 1) (0: no row held out), got -0.1"),
        (vec!["replay", "--data", d, "--scenario", "x.toml", "--test-fraction", "1.5"], "--test-fraction must be in [0, 1) (0: no row held out), got 1.5"),
        (vec!["predict", "--model", "m.json", "--data", d, "--stations", "one"], "unexpected argument '--stations'"),
        (vec!["iso9283", "--data", d, "--stations", "one"], "unexpected argument '--stations'"),
        (vec!["compare", "--data", d, "--stations", "one"], "unexpected argument '--stations'"),
        (vec!["replay", "--data", d, "--scenario", "x.toml", "--stations", "one"], "unexpected argument '--stations'"),
        (vec!["compare", "--data", d, "--seeds", "18000000000000000000"], "--seeds must be between 1 and 1000"),
        (vec!["compare", "--data", d, "--seeds", "0"], "--seeds must be between 1 and 1000, got 0"),
        (vec!["compare", "--data", d, "--methods", "lm,ekf,lm"], "--methods lists lm twice"),
        (vec!["compare", "--data", d, "--effort", "1e-9"], "--effort must be in [0.01, 10], got 0.000000001"),
        (vec!["generate", "--seed", "-3"], "invalid value '-3' for '--seed <SEED>'"),
        (vec!["diagnose", "--data", d, "--folds", "-3"], "invalid value '-3' for '--folds <FOLDS>'"),
        (vec!["calibrate", "--data", d, "--effort", "11"], "--effort must be in [0.01, 10], got 11"),
        (vec!["calibrate", "--data", d, "--angles", "grad"], "invalid value 'grad'"),
        (vec!["calibrate", "--data", d, "--model", "generic6r", "--draw-wire-guess", "0,0,0,0,0,0,0"], "--draw-wire-guess applies to a nominal model"),
    ];
    for (args, needle) in cases {
        let t0 = std::time::Instant::now();
        let o = twincal(&args);
        assert!(!o.status.success(), "{args:?} should fail");
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let e = stderr(&o);
        assert!(e.contains(needle) && !e.contains("panicked"), "{args:?}: {e}");
        assert!(t0.elapsed().as_secs_f64() < 10.0, "{args:?} must be refused before any work");
    }
    assert_no_temp_files(dir.path());
}

#[test]
fn a_failing_command_leaves_no_output_and_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let blocker = dir.path().join("blocker");
    std::fs::write(&blocker, "not a folder").unwrap();
    let outs = dir.path().join("outs");
    std::fs::create_dir(&outs).unwrap();
    // --urdf (and --rrd) are staged before --out, whose folder cannot be created.
    let mut args = vec!["calibrate", "--data", s(&data), "--urdf", "PLACEHOLDER", "--out", "PLACEHOLDER"];
    let urdf = outs.join("cal.urdf");
    let out = blocker.join("r.json");
    args[4] = s(&urdf);
    args[6] = s(&out);
    let rrd = outs.join("cal.rrd");
    if cfg!(feature = "rerun") {
        args.extend(["--rrd", s(&rrd)]);
    }
    let o = twincal(&args);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains(&format!("cannot create folder {}", blocker.display())), "{e}");
    assert!(!e.contains("cannot read"), "a write failure is not a read failure: {e}");
    assert!(names_in(&outs).is_empty(), "{:?}", names_in(&outs));
    assert_no_temp_files(dir.path());
    // generate into a folder whose parent is a file: a write error naming the folder.
    let o = twincal(&["generate", "--scenario", s(&dir.path().join("d.toml")), "--out", s(&blocker.join("g"))]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("cannot create folder"), "{}", stderr(&o));
    assert_no_temp_files(dir.path());
}

#[test]
fn an_optimiser_stopped_by_its_budget_is_a_warning_even_when_quiet() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let res = dir.path().join("r.json");
    // 1 % of PSO's iteration budget: it stops on the limit, not on its convergence test.
    let o = twincal(&["calibrate", "--data", s(&data), "--method", "pso", "--effort", "0.01", "--out", s(&res)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("warning: pso stopped without converging (maximum number of iterations reached"), "{e}");
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&res).unwrap()).unwrap();
    assert_eq!(r["solve"]["converged"], false);
    // A converged LM run prints no warning.
    let o = twincal(&["calibrate", "--data", s(&data), "--out", s(&res)]);
    assert!(o.status.success());
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
}

#[test]
fn model_file_errors_are_labelled_model() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{}").unwrap();
    let o = twincal(&["predict", "--model", s(&bad), "--data", s(&data), "--out", s(&dir.path().join("p.csv"))]);
    assert!(!o.status.success());
    assert!(stderr(&o).starts_with(&format!("error: model {}", bad.display())), "{}", stderr(&o));
    let o = twincal(&["predict", "--model", s(&dir.path().join("missing.json")), "--data", s(&data), "--out", s(&dir.path().join("p.csv"))]);
    assert!(stderr(&o).contains("cannot read"), "{}", stderr(&o));
    assert!(!dir.path().join("p.csv").exists());
}

#[test]
fn bench_twin_reports_rapier_against_the_quasi_static_model() {
    let dir = tempfile::tempdir().unwrap();
    let sc = small_full_scenario(dir.path(), 16);
    let o = twincal(&["bench", "twin", "--scenario", s(&sc), "--repeat", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let line = out.lines().find(|l| l.contains("rapier vs quasi-static")).unwrap_or_else(|| panic!("{out}"));
    let worst: f64 = line.split("difference ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert!(worst < 1e-3, "{line}");
    assert!(line.contains("over 16 poses") && line.contains("backlash contacts differ in 0 poses"), "{line}");
}

#[cfg(unix)]
#[test]
fn sigint_and_sigterm_leave_no_partial_output() {
    let dir = tempfile::tempdir().unwrap();
    // Large enough to still be settling poses when the signal arrives.
    let text = std::fs::read_to_string(scenario("irb120_evo_nph")).unwrap().replace("poses = 600", "poses = 4000");
    let sc = dir.path().join("big.toml");
    std::fs::write(&sc, text).unwrap();
    for (sig, code) in [("TERM", 143), ("INT", 130)] {
        let out = dir.path().join(format!("out-{sig}"));
        let rrd = dir.path().join(format!("{sig}.rrd"));
        let child = Command::new(env!("CARGO_BIN_EXE_twincal"))
            .args(["generate", "--quiet", "--scenario", s(&sc), "--out", s(&out), "--rrd", s(&rrd)])
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(500));
        let k = Command::new("kill").args([&format!("-{sig}"), &child.id().to_string()]).status().unwrap();
        assert!(k.success());
        let o = child.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(code), "SIG{sig}: {}", stderr(&o));
        assert!(stderr(&o).contains(&format!("interrupted by SIG{sig}")), "{}", stderr(&o));
        assert!(!out.exists() || names_in(&out).is_empty(), "{:?}", names_in(&out));
        assert!(!rrd.exists());
        assert_no_temp_files(dir.path());
    }
}

#[test]
fn predict_writes_lengths_and_residuals() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let res = dir.path().join("r.json");
    assert!(twincal(&["calibrate", "--data", s(&data), "--out", s(&res)]).status.success());
    let p = dir.path().join("p/pred.csv");
    let o = twincal(&["predict", "--model", s(&res), "--data", s(&data), "--angles", "deg", "--out", s(&p)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&p).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "q1,q2,q3,q4,q5,q6,L,L_pred,residual");
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|c| c.parse().unwrap()).collect()).collect();
    assert_eq!(rows.len(), 100);
    for r in &rows {
        assert!((r[6] - r[7] - r[8]).abs() < 1e-9 && r[8].abs() < 1.0, "{r:?}");
    }
}

/// A reader that closes stdout early (`twincal compare ... | head -1`) ends the command quietly:
/// no panic message, exit code 141 (128 + SIGPIPE, as a shell reports it), and no output file
/// half-written.
#[test]
fn a_closed_stdout_ends_the_command_quietly() {
    use std::process::Stdio;
    let dir = tempfile::tempdir().unwrap();
    let sc = small_full_scenario(dir.path(), 40);
    let data = dir.path().join("d");
    assert!(twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", data.to_str().unwrap()]).status.success());
    let json = dir.path().join("cmp.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_twincal"))
        .args(["compare", "--data", data.to_str().unwrap(), "--methods", "lm", "--seeds", "2", "--quiet", "--out", json.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert!(!err.contains("panicked") && !err.contains("Broken pipe"), "{err}");
    assert_eq!(o.status.code(), Some(141), "{err}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(!json.exists() && left.len() == 2, "no output, no temporary file: {left:?}");
}

/// A scenario's robot URDF is an input of `generate` and `study`: a recording onto it is refused.
#[test]
fn the_scenario_s_robot_file_is_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("arm.urdf");
    std::fs::copy(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/fixture_6r.urdf"), &urdf).unwrap();
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/fixture_6r.toml")).unwrap();
    assert!(text.contains("fixture_6r.urdf"), "the fixture scenario names its URDF");
    let sc = dir.path().join("s.toml");
    std::fs::write(&sc, text.replace("fixture_6r.urdf", "arm.urdf")).unwrap();
    let before = std::fs::read(&urdf).unwrap();
    for args in [
        vec!["generate", "--scenario", s(&sc), "--out", s(&dir.path().join("g")), "--rrd", s(&urdf)],
        vec!["study", "hold", "--scenario", s(&sc), "--poses", "2", "--rrd", s(&urdf)],
    ] {
        let o = twincal(&args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains("is also an input (the scenario's robot"), "{args:?}: {e}");
    }
    assert_eq!(std::fs::read(&urdf).unwrap(), before);
}

/// A stdout that cannot be written (a full disk) is a one-line error with exit code 2, never a
/// panic message; the outputs are not written.
#[test]
fn an_unwritable_stdout_is_an_error_not_a_panic() {
    if !Path::new("/dev/full").exists() {
        eprintln!("skipped: no /dev/full on this system");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let json = dir.path().join("cmp.json");
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_twincal"))
        .args(["compare", "--data", s(&data), "--methods", "lm", "--seeds", "2", "--quiet", "--out", s(&json)])
        .stdout(full)
        .output()
        .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("error: failed printing to stdout") && !e.contains("panicked") && !e.contains("backtrace"), "{e}");
    assert!(!json.exists());
}

/// `diagnose` refuses folds that could fit the geometric model exactly and warns (stderr and
/// report.json) when they are short of three rows per parameter; the calibrate command it
/// suggests runs as printed, with the loads it was given.
#[test]
fn diagnose_checks_its_folds_and_suggests_a_command_that_runs() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let rows: Vec<String> = std::fs::read_to_string(data.join("dataset.csv")).unwrap().lines().map(String::from).collect();
    let few = dir.path().join("few.csv");
    std::fs::write(&few, rows[..37].join("\n") + "\n").unwrap();
    let (rep, res) = (dir.path().join("rep.json"), dir.path().join("res.json"));
    let o = twincal(&["diagnose", "--data", s(&few), "--out", s(&rep), "--result", s(&res)]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("training rows per fold") && e.contains("an exact fit says nothing"), "{e}");
    assert!(!rep.exists() && !res.exists());
    // Not quiet: the suggestion is part of the summary.
    let o = Command::new(env!("CARGO_BIN_EXE_twincal"))
        .args(["diagnose", "--data", s(&data), "--out", s(&rep), "--result", s(&res), "--payload-kg", "0.5", "--payload-com-mm", "40,0,0"])
        .output()
        .unwrap();
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    let warned = e.contains("warning: only") && e.contains("training rows per fold");
    let d: serde_json::Value = serde_json::from_slice(&std::fs::read(&rep).unwrap()).unwrap();
    let in_json = d["warnings"].as_array().is_some_and(|w| w.iter().any(|w| w.as_str().unwrap().contains("training rows per fold")));
    // 110 rows, 5 folds, a fifth kept back: about 70 training rows per fold for 25 parameters.
    assert!(warned && in_json, "{e}");
    let line = e.lines().find_map(|l| l.split_once("the same model by calibrate: ").map(|(_, c)| c.to_string())).expect("a suggestion");
    assert!(line.contains("--payload-kg 0.5") && line.contains("--payload-com-mm 40,0,0"), "{line}");
    let mut args: Vec<String> = line.split_whitespace().skip(1).map(String::from).collect();
    args.extend(["--out".into(), s(&dir.path().join("cal.json")).into(), "--quiet".into()]);
    let o = Command::new(env!("CARGO_BIN_EXE_twincal")).args(&args).output().unwrap();
    assert!(o.status.success(), "{line}: {}", stderr(&o));
}

/// A hand-edited result file is checked as a whole on load: link masses and their count, the
/// cable's tension, the chain's axes and offsets, keys twincal does not write, a parameter report
/// that does not match the model; each refusal names what is wrong (exit 2).
#[test]
fn hand_edited_result_values_out_of_range_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let res = dir.path().join("r.json");
    let o = twincal(&[
        "calibrate",
        "--data",
        s(&data),
        "--out",
        s(&res),
        "--payload-kg",
        "0.5",
        "--payload-com-mm",
        "40,0,0",
        "--cable-tension-n",
        "5",
        "--effects",
        "compliance:2",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&res).unwrap()).unwrap();
    type Edit = fn(&mut serde_json::Value);
    assert_eq!(r["schema_version"], 2, "result.json carries its schema version");
    let cases: [(Edit, &str); 18] = [
        (|r| r["schema_version"] = 3.into(), "schema_version 3, written by a newer twincal"),
        // A wrong type is named by its JSON path.
        (|r| r["schema_version"] = "2".into(), "schema_version: invalid type: string \"2\""),
        (|r| r["solve"]["iterations"] = "many".into(), "solve.iterations: invalid type"),
        (
            |r| {
                r.as_object_mut().unwrap().remove("torque_model");
            },
            "compliance block reads joint torques, but the file has no torque_model",
        ),
        (|r| r["torque_model"]["links"].as_array_mut().unwrap().truncate(3), "3 link masses for a model of 6 joints"),
        (|r| r["torque_model"]["links"][1][0] = 1e6.into(), "link 2 has mass 1000000 kg"),
        (|r| r["torque_model"]["cable"][2] = 1e9.into(), "cable tension 1e9 N"),
        (|r| r["torque_model"]["payload"][0] = (-0.5).into(), "payload -0.5 kg"),
        (|r| r["model"]["chain"]["ops"][0]["axis"] = serde_json::json!([0.0, 0.0, 5.0]), "is not a unit vector"),
        (|r| r["model"]["chain"]["ops"][1]["base"] = 1e6.into(), "offset 1000000"),
        (|r| r["calibrated_by"] = "me".into(), "unknown key 'calibrated_by'"),
        (|r| r["model"]["stiffness"] = 1.into(), "unknown key 'model.stiffness'"),
        (|r| r["parameters"].as_array_mut().unwrap().truncate(5), "the parameter report lists 5 parameters"),
        // The report is derived from the model: an edit there is refused, not half-applied.
        (|r| r["parameters"][3]["nominal"] = 1e300.into(), "parameters[3] (joint_1.alpha): nominal 1e300"),
        (|r| r["parameters"][3]["std_uncertainty"] = (-1.0).into(), "std_uncertainty -1 must be a finite number >= 0"),
        (|r| r["x"][5] = 1e6.into(), "the chain's joint_2.a = 1000000 (x)"),
        (|r| r["parameters"][5]["value"] = 7.into(), "parameters[5] (joint_2.a): value 7 is not the model's"),
        (|r| r["model"]["nominal"][5] = 1e5.into(), "the chain's joint_2.a"),
    ];
    // What twincal leaves out when empty may be given empty.
    let mut empty = r.clone();
    empty["provenance"]["test_rows"] = serde_json::json!([]);
    empty["corrector"] = serde_json::Value::Null;
    let p = dir.path().join("empty.json");
    std::fs::write(&p, serde_json::to_string(&empty).unwrap()).unwrap();
    let o = twincal(&["predict", "--model", s(&p), "--data", s(&data), "--out", s(&dir.path().join("pe.csv"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Saved by an editor with a byte-order mark, as data files may be: read.
    let bom = dir.path().join("bom.json");
    std::fs::write(&bom, format!("\u{feff}{}", std::fs::read_to_string(&res).unwrap())).unwrap();
    let o = twincal(&["predict", "--model", s(&bom), "--data", s(&data), "--out", s(&dir.path().join("pb.csv"))]);
    assert!(o.status.success(), "{}", stderr(&o));
    for (k, (edit, needle)) in cases.iter().enumerate() {
        let mut bad = r.clone();
        edit(&mut bad);
        let p = dir.path().join(format!("bad{k}.json"));
        std::fs::write(&p, serde_json::to_string(&bad).unwrap()).unwrap();
        for cmd in [
            vec!["predict", "--model", s(&p), "--data", s(&data), "--out", s(&dir.path().join("p.csv"))],
            vec!["ik", "--model", s(&p), "--random", "2", "--out", s(&dir.path().join("ik.csv"))],
        ] {
            let o = twincal(&cmd);
            let e = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{needle}: {e}");
            assert!(e.contains(needle) && e.contains(s(&p)) && !e.contains("panicked"), "{needle}: {e}");
        }
    }
}

/// Messages name the option the user gave and show huge numbers briefly: `--candidates` (not
/// `--effects`, no doubled prefix), a 1e308 angle, an ik target file naming a column twice.
#[test]
fn messages_name_the_option_given_and_numbers_briefly() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let out = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    for (cand, needle) in [
        ("backlash:0", "invalid value 'backlash:0' for '--candidates <CANDIDATES>': the joint"),
        ("backlash:9", "--candidates backlash: joint 9"),
        ("nonsense", "invalid value 'nonsense' for '--candidates <CANDIDATES>': unknown effect"),
    ] {
        let o = twincal(&["diagnose", "--data", s(&data), "--candidates", cand, "--out", &out("d.json"), "--result", &out("r.json")]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains(needle) && !e.contains("backlash: backlash"), "{cand}: {e}");
    }
    let text = std::fs::read_to_string(data.join("dataset.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let first: Vec<&str> = lines[1].split(',').collect();
    lines[1] = std::iter::once("1e308").chain(first[1..].iter().copied()).collect::<Vec<_>>().join(",");
    let huge = dir.path().join("huge.csv");
    std::fs::write(&huge, lines.join("\n")).unwrap();
    let o = twincal(&["calibrate", "--data", s(&huge), "--out", &out("c.json")]);
    let e = stderr(&o);
    assert!(e.contains("1e308 deg is implausible") && e.len() < 400, "{e}");
    let targets = dir.path().join("t.csv");
    std::fs::write(&targets, "x,x,y,z\n1,300,0,400\n").unwrap();
    let res = out("res.json");
    assert!(twincal(&["calibrate", "--data", s(&data), "--out", &res]).status.success());
    let o = twincal(&["ik", "--model", &res, "--targets", s(&targets), "--no-twin", "--out", &out("ik.csv")]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("names the column x twice"), "{e}");
    std::fs::write(&targets, "x,y,z\n1e308,0,400\n").unwrap();
    let o = twincal(&["ik", "--model", &res, "--targets", s(&targets), "--no-twin", "--out", &out("ik.csv")]);
    let e = stderr(&o);
    assert!(o.status.code() == Some(2) && e.contains("target 1 (1e308, 0, 400) mm is implausible"), "{e}");
}

/// Outputs are never renamed over a special file: a FIFO, a symbolic link or a device is
/// refused by name before any work. A stderr that cannot be written ends an error with exit 2.
#[test]
fn special_files_are_not_outputs_and_a_full_stderr_is_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let fifo = dir.path().join("ff");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let target = dir.path().join("target.json");
    std::fs::write(&target, "keep").unwrap();
    let link = dir.path().join("link.json");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    for (out, says) in [(s(&fifo), "is not a regular file"), (s(&link), "is a symbolic link"), ("/dev/null", "is not a regular file")] {
        let o = twincal(&["calibrate", "--data", s(&data), "--out", out]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{out}: {e}");
        assert!(e.contains(says), "{out}: {e}");
    }
    assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo() && std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep");
    if Path::new("/dev/full").exists() {
        let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
        let o = Command::new(env!("CARGO_BIN_EXE_twincal")).args(["calibrate", "--data", "no/such/folder"]).stderr(full).output().unwrap();
        assert_eq!(o.status.code(), Some(2));
    }
}

/// The second sweep's accepted nonsense and misleading output: each is refused or said.
#[test]
fn nonsense_from_the_second_sweep_is_refused_or_said() {
    let dir = tempfile::tempdir().unwrap();
    let data = small_geometric(dir.path(), "d");
    let out = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let res = out("r.json");
    assert!(twincal(&["calibrate", "--data", s(&data), "--out", &res]).status.success());
    // ik: --twin with --no-twin; a NaN target gets no true error.
    let o = twincal(&["ik", "--model", &res, "--twin", s(&data), "--no-twin", "--random", "2", "--out", &out("ik.csv")]);
    assert!(o.status.code() == Some(2) && stderr(&o).contains("give one of them"), "{}", stderr(&o));
    std::fs::write(out("t.csv"), "x,y,z\nnan,0,400\n").unwrap();
    let o = twincal(&["ik", "--model", &res, "--targets", &out("t.csv"), "--jacobian", "analytic", "--out", &out("ik.csv")]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out("ik.csv")).unwrap();
    assert!(csv.lines().nth(1).unwrap().contains(",invalid,") && csv.lines().nth(1).unwrap().ends_with(','), "{csv}");
    // compare with one seed shows no spread.
    let o = twincal(&["compare", "--data", s(&data), "--methods", "lm", "--seeds", "1"]);
    assert!(o.status.success() && !String::from_utf8_lossy(&o.stdout).contains('±'), "{}", String::from_utf8_lossy(&o.stdout));
    // study: a hold or speed named twice.
    let o = twincal(&["study", "hold", "--holds", "0.5,0.5", "--poses", "2"]);
    assert!(o.status.code() == Some(2) && stderr(&o).contains("--holds lists 0.5 twice"), "{}", stderr(&o));
    // predict beyond the model's joint limits says so.
    let text = std::fs::read_to_string(data.join("dataset.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[1].split(',').map(String::from).collect();
    cells[2] = "170".into();
    lines[1] = cells.join(",");
    std::fs::write(out("far.csv"), lines.join("\n")).unwrap();
    let o = twincal(&["predict", "--model", &res, "--data", &out("far.csv"), "--out", &out("p.csv")]);
    assert!(o.status.success() && stderr(&o).contains("outside the model's joint limits (first: row 1, q3 = 170 deg)"), "{}", stderr(&o));
    // A placement and a learned corrector edited beyond anything a calibration writes.
    let mut r: serde_json::Value = serde_json::from_slice(&std::fs::read(&res).unwrap()).unwrap();
    let k = r["parameters"].as_array().unwrap().iter().position(|p| p["name"] == "exit.x").unwrap();
    r["x"][k] = 1e6.into();
    std::fs::write(out("bad.json"), r.to_string()).unwrap();
    let o = twincal(&["predict", "--model", &out("bad.json"), "--data", s(&data), "--out", &out("p.csv")]);
    assert!(o.status.code() == Some(2) && stderr(&o).contains("placement exit.x = 1000000 is beyond 100"), "{}", stderr(&o));
    let rbf = out("rbf.json");
    assert!(twincal(&["calibrate", "--data", s(&data), "--method", "rbf", "--out", &rbf]).status.success());
    let mut r: serde_json::Value = serde_json::from_slice(&std::fs::read(&rbf).unwrap()).unwrap();
    // An input statistic may be large (a time input's mean over days is 1e5 s and more): loaded.
    let mut big_input = r.clone();
    big_input["corrector"]["input_scale"][0] = 2e5.into();
    std::fs::write(out("big_input.json"), big_input.to_string()).unwrap();
    let o = twincal(&["predict", "--model", &out("big_input.json"), "--data", s(&data), "--out", &out("p.csv")]);
    assert!(o.status.success(), "{}", stderr(&o));
    r["corrector"]["weights"][0] = 1e6.into();
    std::fs::write(out("bad.json"), r.to_string()).unwrap();
    let o = twincal(&["predict", "--model", &out("bad.json"), "--data", s(&data), "--out", &out("p.csv")]);
    assert!(o.status.code() == Some(2) && stderr(&o).contains("corrector.weights[0] = 1000000.0 is beyond"), "{}", stderr(&o));
    // pso-ekf-awnn-v5 (geometry and unpenalised output layers together) on 60 training rows of
    // the all-effects twin interpolates them: said, on stderr and in the result.
    let text = std::fs::read_to_string(scenario("irb120_evo_nph")).unwrap();
    let text = text.replace("poses = 600", "poses = 80").replace("test = 100", "test = 20").replace("model = \"simulated\"", "model = \"settled\"");
    let sc = dir.path().join("settled.toml");
    std::fs::write(&sc, text).unwrap();
    let full = dir.path().join("full");
    assert!(twincal(&["generate", "--scenario", s(&sc), "--seed", "2024", "--out", s(&full)]).status.success());
    let v5 = out("v5.json");
    let o = twincal(&["calibrate", "--data", s(&full), "--method", "pso-ekf-awnn-v5", "--out", &v5]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&v5).unwrap()).unwrap();
    let (train, test) =
        (r["evaluation"]["metrics"]["train_after"]["rmse"].as_f64().unwrap(), r["evaluation"]["metrics"]["test_after"]["rmse"].as_f64().unwrap());
    let said = e.contains("fits the training rows far inside the reading noise");
    let kept = r["warnings"].as_array().unwrap().iter().any(|w| w.as_str().unwrap().contains("far inside the reading noise"));
    assert!(said && kept, "train {train}, test {test}: {e}");
    // ik on a network that reads the backlash flanks (pso-ekf-awnn-x) says it solves without them.
    let x = out("x.json");
    assert!(twincal(&["calibrate", "--data", s(&full), "--method", "pso-ekf-awnn-x", "--out", &x]).status.success());
    let o = twincal(&["ik", "--model", &x, "--random", "2", "--no-twin", "--jacobian", "analytic", "--out", &out("ikx.csv")]);
    assert!(o.status.success() && stderr(&o).contains("warning: the model reads backlash flanks"), "{}", stderr(&o));
}

/// result.json of layout 1 (flat: before `provenance`, `solve`, `screen` and `evaluation`)
/// still loads and predicts as the nested file it came from; a file of a newer layout is
/// refused by name.
#[test]
fn a_flat_result_file_of_layout_1_still_loads_and_predicts_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let (data, nested) = (dir.path().join("d"), dir.path().join("r2.json"));
    assert!(twincal(&["generate", "--out", &s(&data)]).status.success());
    let o = twincal(&["calibrate", "--data", &s(&data), "--out", &s(&nested)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&nested).unwrap()).unwrap();
    assert_eq!(v["schema_version"], 2);
    assert!(v["provenance"]["test_rows"].as_array().is_some_and(|t| !t.is_empty()) && v["evaluation"]["metrics"]["test_after"]["rmse"].is_number());
    let mut flat = v.as_object().unwrap().clone();
    for group in ["provenance", "solve", "screen", "evaluation"] {
        for (k, x) in flat.remove(group).unwrap().as_object().unwrap() {
            flat.insert(k.clone(), x.clone());
        }
    }
    flat.insert("schema_version".into(), 1.into());
    let old = dir.path().join("r1.json");
    std::fs::write(&old, serde_json::to_string_pretty(&flat).unwrap()).unwrap();
    let predict = |model: &Path, out: &str| {
        let out = dir.path().join(out);
        let o = twincal(&["predict", "--model", &s(model), "--data", &s(&data), "--out", &s(&out)]);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read_to_string(out).unwrap()
    };
    assert_eq!(predict(&old, "p1.csv"), predict(&nested, "p2.csv"));
    flat.insert("schema_version".into(), 3.into());
    std::fs::write(&old, serde_json::to_string_pretty(&flat).unwrap()).unwrap();
    let o = twincal(&["predict", "--model", &s(&old), "--data", &s(&data), "--out", &s(&dir.path().join("p3.csv"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("schema_version 3, written by a newer twincal"), "{}", stderr(&o));
}

/// A URDF without link masses loads no joint: compliance asked of it is refused (by calibrate's
/// --effects and diagnose's --candidates), naming what would load the joints; a payload does.
#[test]
fn compliance_on_a_urdf_without_masses_is_refused_until_something_loads_the_joints() {
    let dir = tempfile::tempdir().unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let data = dir.path().join("d");
    assert!(twincal(&["generate", "--out", &s(&data)]).status.success());
    let text = std::fs::read_to_string(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../urdf/irb120.urdf"))).unwrap();
    let mut bare = String::new();
    let mut rest = text.as_str();
    while let Some(i) = rest.find("<inertial>") {
        bare.push_str(&rest[..i]);
        rest = &rest[rest[i..].find("</inertial>").unwrap() + i + "</inertial>".len()..];
    }
    bare.push_str(rest);
    assert!(!bare.contains("<mass"));
    let urdf = dir.path().join("bare.urdf");
    std::fs::write(&urdf, bare).unwrap();
    let out = dir.path().join("r.json");
    for args in [
        vec!["calibrate", "--data", &s(&data), "--model", &s(&urdf), "--effects", "compliance:2", "--out", &s(&out)],
        vec![
            "diagnose",
            "--data",
            &s(&data),
            "--model",
            &s(&urdf),
            "--candidates",
            "compliance",
            "--out",
            &s(&out),
            "--result",
            &s(&dir.path().join("m.json")),
        ],
    ] {
        let o = twincal(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("nothing loads the joints"), "{args:?}: {}", stderr(&o));
        assert!(!out.exists());
    }
    let o = twincal(&["calibrate", "--data", &s(&data), "--model", &s(&urdf), "--effects", "compliance:2", "--payload-kg", "3", "--out", &s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
}
