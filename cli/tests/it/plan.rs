//! `twincal plan`, end to end: a plan in a cell with a floor and a keep-out box, every planned
//! pose feasible and inside the ranges; its pose list measured by `generate --poses` and
//! calibrated; the recording; bad requests and bad pose lists refused with exit code 2.

use std::path::Path;
use std::process::{Command, Output};

fn twincal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).output().expect("runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `calibrate` of `data` with compliance under 3 kg at (40, 0, 60) mm, written to `result`.
fn calibrate_with_compliance(data: &Path, result: &Path) {
    let o = twincal(&[
        "--quiet",
        "calibrate",
        "--data",
        s(data),
        "--effects",
        "compliance",
        "--payload-kg",
        "3",
        "--payload-com-mm",
        "40,0,60",
        "--out",
        s(result),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

const CELL: &str = "\n[workspace]\nlink_radius_mm = 45.0\nfloor_z_mm = 0.0\nkeep_out = [{ name = \"fixture\", min_mm = [250.0, -400.0, 0.0], max_mm = [450.0, -200.0, 300.0] }]\n";

#[test]
fn a_plan_is_feasible_measured_by_generate_and_calibrated() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(root.join("scenarios/irb120_tracker.toml")).unwrap() + CELL;
    let scenario = dir.path().join("cell.toml");
    std::fs::write(&scenario, text).unwrap();
    let out = dir.path().join("plan");
    let rrd = dir.path().join("plan.rrd");
    let o = twincal(&["plan", "--scenario", s(&scenario), "--poses", "20", "--candidates", "3000", "--out", s(&out), "--rrd", s(&rrd)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("planned 20 poses") && err.contains("link in a keep-out box"), "{err}");
    let plan: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    assert!(plan["tour"]["total_s"].as_f64().unwrap() <= plan["unordered"]["total_s"].as_f64().unwrap());
    // The ceiling: a certified bound below the plan, what the plan and the best 20 are worth.
    let (ce, i) = (&plan["ceiling"], plan["indices"]["i_prediction_variance"].as_f64().unwrap());
    let lower = ce["bound"]["lower"].as_f64().unwrap();
    assert!(lower > 0.0 && lower <= i && ce["bound"]["gap"].as_f64().unwrap() < 0.05, "{ce}");
    let (pw, bw) = (ce["plan_worth"].as_u64().unwrap(), ce["best_worth"].as_u64().unwrap());
    assert!(20 < pw && pw <= bw && bw <= 160, "{ce}");
    assert!(
        err.contains(&format!("best any 20 poses of this pool can do: I >= {lower:.4} (a certified bound")) && err.contains(&format!("the plan about {pw}")),
        "{err}"
    );
    assert!(std::fs::metadata(&rrd).unwrap().len() > 1000);
    // The pose list: 20 rows, inside the scenario's ranges, measured in its order.
    let data = dir.path().join("d");
    let o = twincal(&["--quiet", "generate", "--scenario", s(&scenario), "--poses", s(&out.join("poses.csv")), "--out", s(&data)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let truth: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(data.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["poses"].as_array().unwrap().len(), 20);
    // Every planned tool point clear of the box and the floor (the capsules' axes are checked
    // by the library's tests; the tool point is the last capsule's end).
    for p in truth["poses"].as_array().unwrap() {
        let t: Vec<f64> = p["tool_mm"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        let inside = t[0] > 250.0 - 45.0 && t[0] < 450.0 + 45.0 && t[1] > -445.0 && t[1] < -155.0 && t[2] < 345.0;
        assert!(!inside && t[2] > 45.0, "tool point {t:?} in the box or on the floor");
    }
    let o = twincal(&["--quiet", "calibrate", "--data", s(&data), "--out", s(&dir.path().join("r.json"))]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // A pose the cell refuses (the tool in the fixture's box) added to the list: refused by
    // its row and reason, nothing written.
    let mut list = std::fs::read_to_string(out.join("poses.csv")).unwrap();
    let header = list.lines().next().unwrap().to_string();
    let q = |c: &str| match c {
        "q1" => "-40",
        "q2" | "q5" => "60",
        "q3" => "30",
        _ => "0",
    };
    list.push_str(&format!("{}\n", header.split(',').map(q).collect::<Vec<_>>().join(",")));
    let bad = dir.path().join("bad_poses.csv");
    std::fs::write(&bad, list).unwrap();
    let o = twincal(&["--quiet", "generate", "--scenario", s(&scenario), "--poses", s(&bad), "--out", s(&dir.path().join("d2"))]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("pose 21 of the list") && err.contains("link in a keep-out box"), "{err}");
    assert!(!dir.path().join("d2").join("dataset.csv").exists());
}

#[test]
fn bad_plan_requests_and_pose_lists_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p");
    let file = dir.path().join("file.txt");
    std::fs::write(&file, "x").unwrap();
    for (args, needle) in [
        (vec!["--poses", "0"], "--poses must be in"),
        (vec!["--poses", "40", "--candidates", "20"], "--candidates must be in"),
        (vec!["--criterion", "e"], "unknown criterion 'e'"),
        (vec!["--params", "xyz"], "xyz"),
        (vec!["--effects", "bogus"], "bogus"),
        (vec!["--effects", "thermal"], "thermal"),
        (vec!["--effects", "compliance", "--payload-kg", "-3"], "--payload-kg must be in"),
        (vec!["--scenario", "nowhere.toml"], "nowhere.toml"),
    ] {
        let mut a = vec!["plan", "--out", s(&out)];
        a.extend(args);
        let o = twincal(&a);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{a:?}: {err}");
        assert!(err.contains(needle), "{a:?}: {err}");
        assert!(!out.exists(), "{a:?} wrote {}", out.display());
    }
    let o = twincal(&["plan", "--out", s(&file)]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
    // Fewer cable readings than parameters: planned, with a warning and no ceiling.
    let o = twincal(&["plan", "--poses", "12", "--candidates", "500", "--out", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("warning: no ceiling: 12 poses read 12 values for") && !err.contains("best any"), "{err}");
    let plan: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    assert!(plan["ceiling"].is_null() && plan["ceiling_note"].as_str().unwrap().contains("plan more poses"), "{}", plan["ceiling"]);
    std::fs::remove_dir_all(&out).unwrap();
    // The warning is a `warning:` line of its own, also with --quiet (the summary is not).
    let o = twincal(&["plan", "--quiet", "--poses", "12", "--candidates", "500", "--out", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.lines().any(|l| l.starts_with("warning: no ceiling: 12 poses")) && !err.contains("planned"), "{err}");
    std::fs::remove_dir_all(&out).unwrap();
    // Pose lists generate refuses, and the dataset it does not write.
    let data = dir.path().join("d");
    // Twelve poses written in radians (every |q| within 2π, q2 spanning 1.1).
    let radians: String = std::iter::once("q1,q2,q3,q4,q5,q6".to_string())
        .chain((0..12).map(|k| format!("0.1,{},0.3,-0.2,0.5,1.0", 0.1 * k as f64)))
        .collect::<Vec<_>>()
        .join("\n");
    for (text, needle) in [
        (radians.as_str(), "columns q1..q6 look like radians (all 12 poses have |q| <= 1.100, q2 spans 1.100)"),
        ("q1,q2,q3,q4,q5,q6\n10,20,30,40,50,500\n", "outside joint 6's limits"),
        ("q1,q2,q3,q4,q5,q6,q7\n0,0,0,0,0,0,0\n", "has a column q7"),
        ("q1,q2,q3\n0,0,0\n", "q1..q6"),
        ("q1,q2,q3,q4,q5,q6\nNaN,0,0,0,0,0\n", "pose 1: q1 = NaN is not a number of degrees"),
        ("q1,q2,q3,q4,q5,q6\n", "no poses"),
    ] {
        let poses = dir.path().join("poses.csv");
        std::fs::write(&poses, text).unwrap();
        let o = twincal(&["generate", "--poses", s(&poses), "--out", s(&data)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{text}: {err}");
        assert!(err.contains(needle), "{text}: {err}");
        assert!(!data.exists());
    }
    // A pose list where generate would write its dataset: refused, the list untouched.
    let d2 = dir.path().join("d2");
    std::fs::create_dir(&d2).unwrap();
    let poses = d2.join("dataset.csv");
    std::fs::write(&poses, "q1,q2,q3,q4,q5,q6\n0,0,0,0,30,0\n").unwrap();
    let o = twincal(&["generate", "--poses", s(&poses), "--out", s(&d2)]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read_to_string(&poses).unwrap(), "q1,q2,q3,q4,q5,q6\n0,0,0,0,30,0\n");
}

/// A plan for the next calibration of a calibrated arm (`--model`): the result's own compliance
/// blocks are designed for under its payload, its parametrisation named; a model of another
/// instrument than the scenario's, or `--model` with `--effects`, is refused by name.
#[test]
fn a_plan_for_a_calibrated_model_designs_for_its_own_blocks() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("d");
    assert!(twincal(&["--quiet", "generate", "--out", s(&data)]).status.success());
    let result = dir.path().join("r.json");
    calibrate_with_compliance(&data, &result);
    let out = dir.path().join("plan");
    let o = twincal(&["--quiet", "plan", "--model", s(&result), "--poses", "40", "--candidates", "2000", "--out", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let plan: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    let identifiable: Vec<&str> = plan["identifiable"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    assert!(identifiable.iter().filter(|n| n.contains("compliance")).count() >= 4, "{identifiable:?}");
    assert!(plan["parametrisation"].as_str().unwrap().contains("calibrated"), "{}", plan["parametrisation"]);
    assert!(plan["indices"]["i_prediction_variance"].as_f64().unwrap() < plan["random_median"]["i_prediction_variance"].as_f64().unwrap());
    let tracker = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/irb120_tracker.toml");
    for (extra, needle) in [(vec!["--scenario", tracker], "calibrated on length readings"), (vec!["--effects", "compliance"], "not with --params or --effects")]
    {
        let never = dir.path().join("never");
        let mut args = vec!["--quiet", "plan", "--model", s(&result), "--out", s(&never)];
        args.extend(extra.iter().copied());
        let o = twincal(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(needle) && !err.contains("panicked"), "{err}");
        assert!(!never.exists());
    }
}

/// Plans over payloads (`--payloads 0,6`) for a compliance hidden in a tracker twin: each pose
/// gets its payload, `generate --poses` measures one payload after the other (the rows carry
/// `payload_kg`, times go on), and a calibration with compliance reads each row's torques under
/// its own payload and sizes joint 2's compliance; bad payload requests are refused by name.
#[test]
fn a_plan_over_payloads_is_measured_one_payload_after_the_other_and_sizes_the_compliance() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let hidden = "[effects.compliance]\nstiffness_nm_per_rad = [1.5e5, 2.0e4, 3.0e4, 3.0e4, 3.0e4, 2.0e4]\n\n[effects.payload]\nmass_kg = 3.0\ncom_mm = [40.0, 0.0, 60.0]\n\n[sensor]";
    let text = std::fs::read_to_string(root.join("scenarios/irb120_tracker.toml")).unwrap().replacen("[sensor]", hidden, 1);
    let scenario = dir.path().join("c.toml");
    std::fs::write(&scenario, text).unwrap();
    let out = dir.path().join("plan");
    let o = twincal(&[
        "plan",
        "--scenario",
        s(&scenario),
        "--effects",
        "compliance",
        "--payloads",
        "0,6",
        "--poses",
        "50",
        "--candidates",
        "2000",
        "--out",
        s(&out),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("payloads: ") && err.contains("s changing the payload"), "{err}");
    let list = std::fs::read_to_string(out.join("poses.csv")).unwrap();
    assert!(list.lines().next().unwrap().ends_with(",payload_kg"), "{list}");
    let payloads: Vec<f64> = list.lines().skip(1).map(|l| l.rsplit(',').next().unwrap().parse().unwrap()).collect();
    assert_eq!(payloads.len(), 50);
    // One payload after the other, each used.
    assert!(payloads.windows(2).filter(|w| w[0] != w[1]).count() == 1 && payloads.contains(&0.0) && payloads.contains(&6.0), "{payloads:?}");
    let data = dir.path().join("d");
    let o = twincal(&["--quiet", "generate", "--scenario", s(&scenario), "--poses", s(&out.join("poses.csv")), "--out", s(&data)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let ds = twincal::dataset::Dataset::load(&data.join("dataset.csv")).unwrap();
    assert_eq!(ds.rows.iter().map(|r| r.payload_kg.unwrap()).collect::<Vec<_>>(), payloads);
    assert!(ds.rows.windows(2).all(|w| w[1].t_s.unwrap() > w[0].t_s.unwrap()));
    let result = dir.path().join("r.json");
    calibrate_with_compliance(&data, &result);
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&result).unwrap()).unwrap();
    let j2 = r["parameters"].as_array().unwrap().iter().find(|p| p["name"] == "compliance.j2").unwrap();
    let (v, truth) = (j2["value"].as_f64().unwrap(), j2["truth"].as_f64().unwrap());
    assert!((v - truth).abs() < 0.01 * truth, "compliance j2 {v} vs truth {truth}");
    for (extra, needle) in [(vec!["--payloads", "0,-1"], "--payloads: -1 kg is not a payload"), (vec!["--payloads", "2,2"], "a payload twice")] {
        let never = dir.path().join("never");
        let mut args = vec!["--quiet", "plan", "--scenario", s(&scenario), "--effects", "compliance", "--out", s(&never)];
        args.extend(extra.iter().copied());
        let o = twincal(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(needle) && !err.contains("panicked"), "{err}");
    }
    let o = twincal(&["--quiet", "plan", "--scenario", s(&scenario), "--payloads", "0,6", "--out", s(&dir.path().join("never"))]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("load-driven effects"), "{}", String::from_utf8_lossy(&o.stderr));
    // A pose list's payload out of range, and a dataset's payload column with a gap, are named.
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, list.replacen(",0\n", ",-3\n", 1)).unwrap();
    let o = twincal(&["--quiet", "generate", "--scenario", s(&scenario), "--poses", s(&bad), "--out", s(&dir.path().join("never"))]);
    assert!(o.status.code() == Some(2) && String::from_utf8_lossy(&o.stderr).contains("payload_kg = -3"), "{}", String::from_utf8_lossy(&o.stderr));
    let gap = dir.path().join("gap.csv");
    let csv = std::fs::read_to_string(data.join("dataset.csv")).unwrap();
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    let col = lines[0].split(',').position(|h| h == "payload_kg").unwrap();
    let mut cells: Vec<String> = lines[3].split(',').map(String::from).collect();
    cells[col].clear();
    lines[3] = cells.join(",");
    std::fs::write(&gap, lines.join("\n") + "\n").unwrap();
    let o = twincal(&["--quiet", "calibrate", "--data", s(&gap), "--out", s(&dir.path().join("never.json"))]);
    assert!(o.status.code() == Some(2) && String::from_utf8_lossy(&o.stderr).contains("empty payload_kg value"), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `plan --model` with another arm's result refuses it (it planned silently for the wrong arm);
/// `--payload-kg` with no load-driven effect is warned (it was ignored without a word).
#[test]
fn plan_refuses_another_arms_model_and_warns_a_payload_nothing_sees() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let data = dir.path().join("ur10");
    let o = twincal(&["generate", "--scenario", s(&root.join("scenarios/ur10_tracker.toml")), "--out", s(&data)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let result = dir.path().join("ur10.json");
    let o = twincal(&["calibrate", "--data", s(&data.join("dataset.csv")), "--model", s(&root.join("urdf/ur10.urdf")), "--out", s(&result)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.path().join("p");
    let o = twincal(&["plan", "--model", s(&result), "--poses", "30", "--candidates", "500", "--out", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--model is another arm than the scenario's") && !out.exists(), "{err}");
    let o = twincal(&["plan", "--quiet", "--payload-kg", "3", "--poses", "30", "--candidates", "500", "--out", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.lines().any(|l| l.starts_with("warning: --payload-kg changes only what load-driven effects see")), "{err}");
    let plan: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    assert_eq!(plan["warnings"].as_array().map(Vec::len), Some(1), "{}", plan["warnings"]);
}

/// The joint angles (degrees) of a pose list's rows.
fn pose_rows(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let qs: Vec<usize> = (0..header.len()).filter(|&k| header[k].starts_with('q')).collect();
    lines.map(|l| l.split(',').collect::<Vec<_>>()).map(|c| qs.iter().map(|&k| c[k].parse().unwrap()).collect()).collect()
}

/// A plan written as a measurement program, and a pose list written as one by `twincal
/// program`: the program moves to the pose list's poses in its order (read back to the pose
/// list's decimals), in RAPID, KRL and URScript; an existing output is never a pose list read,
/// and a bad request writes nothing.
#[test]
fn a_plan_and_a_pose_list_become_measurement_programs() {
    use twincal::controller::{Language, ProgramFile};
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let read = |lang: Language, folder: &Path, name: &str| -> Vec<Vec<f64>> {
        let files: Vec<ProgramFile> = lang
            .file_names(name)
            .into_iter()
            .map(|n| ProgramFile { text: std::fs::read_to_string(folder.join(&n)).unwrap_or_else(|e| panic!("{n}: {e}")), name: n })
            .collect();
        lang.joint_targets(&files).unwrap().iter().map(|q| q.iter().map(|v| v.to_degrees()).collect()).collect()
    };
    let same = |a: &[Vec<f64>], b: &[Vec<f64>]| a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.iter().zip(y).all(|(u, v)| (u - v).abs() < 1e-5));
    // The IRB 120's plan as RAPID, then its pose list as KRL.
    let p = dir.path().join("p");
    let o = twincal(&["plan", "--poses", "8", "--candidates", "400", "--program-format", "rapid", "--hold-s", "1.5", "--out", s(&p)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let poses = pose_rows(&p.join("poses.csv"));
    assert_eq!(poses.len(), 8);
    assert!(same(&read(Language::Rapid, &p, "twincal_plan"), &poses));
    assert!(std::fs::read_to_string(p.join("twincal_plan.mod")).unwrap().contains("CONST num twc_hold := 1.5;"));
    let k = dir.path().join("k");
    let o = twincal(&["program", "--poses", s(&p.join("poses.csv")), "--format", "krl", "--out", s(&k)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(same(&read(Language::Krl, &k, "twincal_tour"), &poses));
    // A UR10's plan as URScript.
    let u = dir.path().join("u");
    let ur10 = root.join("scenarios/ur10_tracker.toml");
    let o = twincal(&["plan", "--scenario", s(&ur10), "--poses", "8", "--candidates", "400", "--program-format", "urscript", "--out", s(&u)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(same(&read(Language::Urscript, &u, "twincal_plan"), &pose_rows(&u.join("poses.csv"))));
    // Refused, nothing written: a pose list outside the robot's limits, a bad name, an output
    // that is the pose list itself.
    let bad = dir.path().join("bad");
    let o = twincal(&["program", "--poses", s(&p.join("poses.csv")), "--format", "rapid", "--name", "9x", "--out", s(&bad)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("program name '9x'") && !bad.exists());
    let o = twincal(&["program", "--poses", s(&u.join("poses.csv")), "--format", "rapid", "--out", s(&bad)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("limits") && !bad.exists(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::copy(p.join("poses.csv"), k.join("same.mod")).unwrap();
    let o = twincal(&["program", "--poses", s(&k.join("same.mod")), "--format", "rapid", "--name", "same", "--out", s(&k)]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(same(&pose_rows(&k.join("same.mod")), &poses), "the pose list is left as it was");
}

/// An artifact's plan: the configurations to seat (touch) chosen among the artifact's own
/// acquisition on the nominal arm, each with its placement and feature, placement after
/// placement; better by its criterion than the median random set of as many; a measurement
/// program for it refused by name.
#[test]
fn a_plan_for_an_artifact_names_each_configurations_placement_and_feature() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    for (file, column) in [("irb120_sockets.toml", "socket"), ("irb120_planes.toml", "plane")] {
        let out = dir.path().join(file);
        let sc = root.join("scenarios").join(file);
        let o = twincal(&["plan", "--scenario", s(&sc), "--poses", "60", "--candidates", "600", "--out", s(&out), "--quiet"]);
        assert!(o.status.success(), "{file}: {}", String::from_utf8_lossy(&o.stderr));
        let csv = std::fs::read_to_string(out.join("poses.csv")).unwrap();
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        assert!(header.contains(&"placement") && header.contains(&column), "{file}: {header:?}");
        let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
        assert_eq!(rows.len(), 60);
        let p = header.iter().position(|h| *h == "placement").unwrap();
        // Placement after placement: once left, a placement is not visited again.
        let mut seen: Vec<&str> = Vec::new();
        for r in &rows {
            if seen.last() != Some(&r[p]) {
                assert!(!seen.contains(&r[p]), "{file}: placement {} visited twice", r[p]);
                seen.push(r[p]);
            }
        }
        let plan: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("plan.json")).unwrap()).unwrap();
        let (planned, random) = (plan["indices"]["i_prediction_variance"].as_f64().unwrap(), plan["random_median"]["i_prediction_variance"].as_f64().unwrap());
        assert!(planned < random, "{file}: planned {planned} vs random {random}");
        assert_eq!(plan["features"].as_array().unwrap().len(), 60);
        let o =
            twincal(&["plan", "--scenario", s(&sc), "--poses", "60", "--candidates", "600", "--out", s(&dir.path().join("p")), "--program-format", "rapid"]);
        assert_eq!(o.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&o.stderr).contains("by hand"), "{}", String::from_utf8_lossy(&o.stderr));
    }
}
