//! Six joints are not special: a seven-joint arm (the Barrett WAM, `urdf/wam.urdf`, scenario
//! `scenarios/wam_geometric.toml`) goes through the twin, calibration, diagnosis and IK like the
//! IRB 120 does, with nothing but its URDF and its scenario.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use twincal::calib::pipeline::{calibrate, CalibOptions, Method, ModelSpec, TruthFile};
use twincal::dataset::{Dataset, Row};
use twincal::diagnose::{diagnose, DiagnoseOptions};
use twincal::sim::generate::{generate, write_outputs, Silent};
use twincal::sim::scenario::Scenario;

fn root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn twincal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).arg("--quiet").output().expect("runs")
}

fn scenario(seed: u64) -> (Scenario, twincal::robot::Robot) {
    let (mut s, robot) = Scenario::load(&root().join("scenarios/wam_geometric.toml")).unwrap();
    s.seed = seed;
    (s, robot)
}

fn wam() -> ModelSpec {
    ModelSpec::parse(root().join("urdf/wam.urdf").to_str().unwrap(), twincal::calib::pipeline::Parametrisation::Hayati).unwrap()
}

#[test]
fn a_seven_joint_arm_calibrates_to_the_noise_floor_with_its_parameters_within_3_sigma() {
    for seed in [1, 2, 3] {
        let (s, robot) = scenario(seed);
        assert_eq!(robot.dof(), 7);
        let g = generate(&s, &robot, &Silent).unwrap();
        let dir = tempfile::tempdir().unwrap();
        write_outputs(&g, dir.path()).unwrap();
        let ds = Dataset::load(dir.path()).unwrap();
        assert_eq!(ds.n_joints(), 7);
        assert!(ds.to_csv_string().starts_with("q1,q2,q3,q4,q5,q6,q7,L,"));
        let truth = TruthFile::find(dir.path()).unwrap().unwrap();
        let r = calibrate(&ds, Some(&truth), &CalibOptions::new(wam(), Method::LM)).unwrap();
        let test = r.evaluation.metrics.test_after.as_ref().unwrap().rmse;
        let floor = s.draw_wire.noise_std_mm / (s.draw_wire.samples as f64).sqrt();
        assert!(r.solve.converged, "seed {seed}: {}", r.solve.stop_reason);
        assert!(test < 1.3 * floor, "seed {seed}: held-out RMSE {test} mm vs reading noise {floor} mm");
        let cmp = r.evaluation.truth_comparison.clone().unwrap();
        assert!(cmp.identifiable >= 29, "seed {seed}: {cmp:?}");
        assert_eq!(cmp.within_3_sigma, cmp.identifiable, "seed {seed}: {cmp:?}");
        // The model keeps the URDF's seven joint limits (IK and sampling use them).
        assert_eq!(r.model.joint_limits(), robot.limits());
    }
}

#[test]
fn a_hidden_compliance_on_a_seven_joint_arm_is_named_with_its_size() {
    let (mut s, robot) = scenario(5);
    // Joint 2 (the shoulder pitch, which carries the arm) gives way 50 µrad per N·m.
    let mut stiff = vec![1e12; 7];
    stiff[1] = 2.0e4;
    s.effects.compliance = Some(twincal::sim::effects::Compliance { stiffness_nm_per_rad: stiff, damping_nms_per_rad: None });
    let g = generate(&s, &robot, &Silent).unwrap();
    let data = Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: s.name.clone() };
    let (d, _) = diagnose(&data, &DiagnoseOptions::new(wam()), &|_| {}).unwrap();
    let first = d.causes.first().unwrap_or_else(|| panic!("nothing named: {}", d.verdict));
    assert_eq!((first.cause.name(), first.joint), ("compliance", Some(2)), "{:?}", d.causes);
    assert!((first.magnitude - 50.0).abs() < 3.0 * first.uncertainty, "{} ± {} vs 50 urad/Nm", first.magnitude, first.uncertainty);
    assert!(d.final_heldout_rmse_mm < 0.2 * first.heldout_rmse_before_mm);
}

#[test]
fn generate_calibrate_diagnose_and_ik_run_on_a_seven_joint_arm_from_the_command_line() {
    let dir = std::env::temp_dir().join(format!("twincal-wam-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let p = |name: &str| dir.join(name).to_str().unwrap().to_owned();
    let scen = root().join("scenarios/wam_geometric.toml");
    let urdf = root().join("urdf/wam.urdf");
    let ok = |o: Output| assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    ok(twincal(&["generate", "--scenario", scen.to_str().unwrap(), "--out", &p("data")]));
    ok(twincal(&["calibrate", "--data", &p("data"), "--model", urdf.to_str().unwrap(), "--out", &p("result.json")]));
    ok(twincal(&["diagnose", "--data", &p("data"), "--model", urdf.to_str().unwrap(), "--out", &p("diag"), "--result", &p("diagnosed.json")]));
    assert!(dir.join("diagnosed.json").exists());
    ok(twincal(&["predict", "--model", &p("result.json"), "--data", &p("data"), "--out", &p("pred.csv")]));
    let pred = std::fs::read_to_string(dir.join("pred.csv")).unwrap();
    assert!(pred.starts_with("q1,q2,q3,q4,q5,q6,q7,L,L_pred,residual\n"), "{}", &pred[..80]);
    // IK, validated against the twin the truth file describes (its URDF travels in truth.json).
    ok(twincal(&["ik", "--model", &p("result.json"), "--random", "30", "--out", &p("ik.csv")]));
    let ik = std::fs::read_to_string(dir.join("ik.csv")).unwrap();
    let header: Vec<&str> = ik.lines().next().unwrap().split(',').collect();
    assert!(header.contains(&"q7"), "{header:?}");
    let (status, err) = (header.iter().position(|h| *h == "status").unwrap(), header.iter().position(|h| *h == "true_error_mm").unwrap());
    let solver = header.iter().position(|h| *h == "solver").unwrap();
    let rows: Vec<Vec<&str>> = ik.lines().skip(1).map(|l| l.split(',').collect()).filter(|f: &Vec<&str>| f[solver] == "calibrated/hybrid").collect();
    assert_eq!(rows.len(), 30);
    for f in &rows {
        assert_eq!(f[status], "converged", "{f:?}");
        let e: f64 = f[err].parse().unwrap();
        assert!(e < 0.05, "true error {e} mm after calibration: {f:?}");
    }
    // A twin generated with other data (another seed) is not the model's: ik refuses to validate on it.
    ok(twincal(&["generate", "--scenario", scen.to_str().unwrap(), "--seed", "99", "--out", &p("other")]));
    let o = twincal(&["ik", "--model", &p("result.json"), "--twin", &p("other"), "--random", "3", "--out", &p("ik_other.csv")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("generated with other data than the model was calibrated on"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // Targets in a spreadsheet export (byte-order mark, quoted header, `;`, decimal commas) read
    // as the dataset reader reads them; a short row is named.
    let targets = dir.join("targets.csv");
    std::fs::write(&targets, "\u{feff}\"X\";\"Y\";\"Z\";\"note\"\n300,5;-200;500;a\nNaN;0;0;b\n").unwrap();
    ok(twincal(&["ik", "--model", &p("result.json"), "--targets", targets.to_str().unwrap(), "--no-twin", "--out", &p("ik_t.csv")]));
    let t = std::fs::read_to_string(dir.join("ik_t.csv")).unwrap();
    assert!(t.lines().nth(1).unwrap().starts_with("1,300.5,-200,500,"), "{t}");
    assert!(t.lines().any(|l| l.starts_with("2,NaN,0,0,") && l.contains(",invalid,")), "{t}");
    std::fs::write(&targets, "x,y,z\n1,2\n").unwrap();
    let o = twincal(&["ik", "--model", &p("result.json"), "--targets", targets.to_str().unwrap(), "--no-twin", "--out", &p("ik_short.csv")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("line 2: malformed CSV: expected 3 fields (as in the header), found 2"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // A tolerance that accepts any configuration is refused.
    let o = twincal(&["ik", "--model", &p("result.json"), "--random", "5", "--tol-mm", "1e9", "--out", &p("ik_loose.csv")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--tol-mm must be in (0, 10] mm"));
    // A dataset of six joint angles is refused by a seven-joint model, naming both counts.
    let six = dir.join("six.csv");
    std::fs::write(&six, "q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,700\n").unwrap();
    let o = twincal(&["predict", "--model", &p("result.json"), "--data", six.to_str().unwrap(), "--out", &p("six_pred.csv")]);
    assert_eq!(o.status.code(), Some(2));
    let msg = String::from_utf8_lossy(&o.stderr);
    assert!(msg.contains("6 joint angles") && msg.contains("7 joints") && !msg.contains("panicked"), "{msg}");
    assert!(!Path::new(&p("six_pred.csv")).exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The seven-joint arm measured by a laser tracker (`scenarios/wam_tracker.toml`, with each
/// row's standard deviation): calibrated to the noise with every identifiable parameter within
/// 3σ over three seeds, the tracker placed from the data; a compliance hidden in joint 2 named
/// with its size; IK reaching the twin's true points.
#[test]
fn a_seven_joint_arm_measured_by_a_laser_tracker() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    let urdf = root().join("urdf/wam.urdf");
    let urdf = urdf.to_str().unwrap();
    let text = std::fs::read_to_string(root().join("scenarios/wam_tracker.toml")).unwrap().replacen("\"../urdf/wam.urdf\"", &format!("{urdf:?}"), 1);
    std::fs::write(dir.path().join("plain.toml"), &text).unwrap();
    let ok = |o: Output| assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json = |name: &str| -> serde_json::Value { serde_json::from_slice(&std::fs::read(dir.path().join(name)).unwrap()).unwrap() };
    for seed in ["1", "2", "3"] {
        ok(twincal(&["generate", "--scenario", &p("plain.toml"), "--seed", seed, "--out", &p(&format!("d{seed}"))]));
        ok(twincal(&["calibrate", "--data", &p(&format!("d{seed}")), "--model", urdf, "--out", &p(&format!("r{seed}.json"))]));
        let (r, truth) = (json(&format!("r{seed}.json")), json(&format!("d{seed}/truth.json")));
        let (test, noise) = (r["evaluation"]["metrics"]["test_after"]["rmse"].as_f64().unwrap(), truth["noise_std_mm"].as_f64().unwrap());
        assert!(test / noise > 0.8 && test / noise < 1.25, "seed {seed}: held-out RMSE {test} mm against the noise {noise} mm");
        let c = &r["evaluation"]["truth_comparison"];
        assert!(c["identifiable"].as_u64().unwrap() >= 30 && c["within_3_sigma"] == c["identifiable"], "seed {seed}: {c}");
        assert!(r["solve"]["weighting"]["rows_with_std"].as_u64().unwrap() > 0, "the rows' std weight the fit");
        for name in ["tracker.x", "tracker.y", "tracker.z"] {
            let q = r["parameters"].as_array().unwrap().iter().find(|q| q["name"] == name).unwrap();
            let e = (q["value"].as_f64().unwrap() - q["truth"].as_f64().unwrap()).abs();
            assert!(e < 3.0 * q["std_uncertainty"].as_f64().unwrap() + 1e-3, "seed {seed}: {name} off by {e} mm: {q}");
        }
    }
    ok(twincal(&["predict", "--model", &p("r1.json"), "--data", &p("d1"), "--out", &p("pred.csv")]));
    assert!(std::fs::read_to_string(dir.path().join("pred.csv")).unwrap().starts_with("q1,q2,q3,q4,q5,q6,q7,x,y,z,x_pred,"));
    // IK against the twin: the true points are reached to the noise.
    ok(twincal(&["ik", "--model", &p("r1.json"), "--random", "20", "--out", &p("ik.csv")]));
    let ik = std::fs::read_to_string(dir.path().join("ik.csv")).unwrap();
    let header: Vec<&str> = ik.lines().next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let mut errors: Vec<f64> = ik
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f[col("solver")] == "calibrated/hybrid")
        .map(|f| {
            assert_eq!(f[col("status")], "converged", "{f:?}");
            f[col("true_error_mm")].parse::<f64>().unwrap()
        })
        .collect();
    errors.sort_by(f64::total_cmp);
    assert_eq!(errors.len(), 20);
    assert!(errors[10] < 0.01, "true error median {} mm", errors[10]);
    // A joint-2 compliance of 50 µrad/N·m hidden in the tracker's points.
    let hidden =
        text.replacen("[sensor]", "[effects.compliance]\nstiffness_nm_per_rad = [1.0e12, 2.0e4, 1.0e12, 1.0e12, 1.0e12, 1.0e12, 1.0e12]\n\n[sensor]", 1);
    std::fs::write(dir.path().join("hidden.toml"), hidden).unwrap();
    ok(twincal(&["generate", "--scenario", &p("hidden.toml"), "--seed", "5", "--out", &p("c5")]));
    ok(twincal(&["diagnose", "--data", &p("c5"), "--model", urdf, "--out", &p("c5.json"), "--result", &p("c5r.json")]));
    let d = json("c5.json");
    assert_eq!(d["verdict"], "compliance[j2]", "{}", d["causes"]);
    let (size, sd) = (d["causes"][0]["magnitude"].as_f64().unwrap(), d["causes"][0]["uncertainty"].as_f64().unwrap());
    assert!((size - 50.0).abs() < 3.0 * sd + 0.5, "{size} ± {sd} against the truth 50");
}

/// Six-joint rows with the seven-joint arm's URDF (or the reverse) are refused by name before
/// anything evaluates the arm at them, for every instrument and station source: a tracker's rows
/// once reached the station search first and panicked in the forward kinematics.
#[test]
fn rows_of_another_joint_count_are_refused_by_name_for_every_instrument() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    let urdf = root().join("urdf/wam.urdf");
    for (name, scenario) in [("tracker", "irb120_tracker"), ("cable", "irb120_geometric"), ("sockets", "irb120_sockets")] {
        let sc = root().join(format!("scenarios/{scenario}.toml"));
        assert!(twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", &p(name)]).status.success());
        for command in ["calibrate", "diagnose"] {
            for stations in ["auto", "declared", "blocks", "one"] {
                let o = twincal(&[
                    command,
                    "--data",
                    &p(name),
                    "--model",
                    urdf.to_str().unwrap(),
                    "--stations",
                    stations,
                    "--spacing-mm",
                    "50",
                    "--out",
                    &p("out.json"),
                ]);
                let err = String::from_utf8_lossy(&o.stderr);
                assert_eq!(o.status.code(), Some(2), "{command} {name} --stations {stations}: {err}");
                assert!(err.contains("6 joint angles") && err.contains("7 joints") && !err.contains("panicked"), "{command} {name}: {err}");
            }
        }
    }
}
