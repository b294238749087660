//! A ball seated in an artifact's sockets: the twin's acquisition, the calibration from the
//! seated rows alone judged on a tracker's points of the same arm that no fit saw, the files as
//! tools write them, and what such rows cannot determine said by name.

use crate::common::artifact::{lm, scenario, scenario_path, twincal};
use std::path::Path;
use twincal::dataset::{Dataset, ReadOptions};
use twincal::sim::scenario::Scenario;

/// An artifact made as designed, at the temperature it was made at, and a ball that seats
/// exactly: the sockets' arm predicts unseen tracker points as well as a tracker calibration of
/// the same arm from as many rows (within 1.5x, three seeds). With the scenario's artifact (a
/// spacing made 0.01 mm long, a printed plate 1 K warm, the ball off-centre by 0.01 mm): still
/// several times better than the nominal arm on every seed, and no better than the scale the
/// stated spacing leaves (the report names it).
#[test]
fn a_ball_in_sockets_calibrates_the_arm_judged_on_unseen_tracker_points() {
    let exact = |t: String| {
        t.replace("made_error_mm = [[0.0, 0.0], [0.01, 0.0]]", "made_error_mm = [[0.0, 0.0], [0.0, 0.0]]")
            .replace("expansion_ppm_per_k = 68.0", "expansion_ppm_per_k = 0.0")
            .replace("seat_std_mm = 0.01", "seat_std_mm = 0.0")
    };
    let (s_exact, robot) = scenario("irb120_sockets", &exact);
    let (s_real, _) = scenario("irb120_sockets", &|t| t);
    for seed in 1..=3u64 {
        let c = twincal::artifact_check::check(&Scenario { seed, ..s_exact.clone() }, &robot, &lm(&robot)).unwrap();
        assert!(c.artifact_mm <= 1.5 * c.tracker_mm, "seed {seed}: exact artifact: sockets {:.4} mm vs tracker {:.4} mm", c.artifact_mm, c.tracker_mm);
        assert!(c.nominal_mm > 20.0 * c.artifact_mm, "seed {seed}: nominal {:.4} mm vs sockets {:.4} mm", c.nominal_mm, c.artifact_mm);
        let r = twincal::artifact_check::check(&Scenario { seed, ..s_real.clone() }, &robot, &lm(&robot)).unwrap();
        assert!(r.nominal_mm > 4.0 * r.artifact_mm, "seed {seed}: nominal {:.4} mm vs sockets {:.4} mm", r.nominal_mm, r.artifact_mm);
        assert!(r.artifact_mm > 2.0 * c.artifact_mm, "seed {seed}: a spacing made wrong must show: {:.4} vs {:.4} mm", r.artifact_mm, c.artifact_mm);
    }
}

/// The same seed writes the same bytes; the folder of one file per socket per placement (radians,
/// as recording tools write them) reads as the same rows as dataset.csv.
#[test]
fn socket_files_are_byte_identical_and_read_as_tools_write_them() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scenario_path("irb120_sockets");
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for out in [&a, &b] {
        let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let bytes = |p: &Path| std::fs::read(p.join("dataset.csv")).unwrap();
    assert_eq!(bytes(&a), bytes(&b));
    let data = Dataset::load(&a).unwrap();
    assert_eq!(data.measurement(), Some(twincal::measurement::Measurement::Socket));
    assert_eq!(data.stations().labels.len(), 6);
    // One folder per placement, one file per socket, joint angles in radians.
    let tool = dir.path().join("tool");
    for r in &data.rows {
        let folder = tool.join(r.station.as_ref().unwrap());
        std::fs::create_dir_all(&folder).unwrap();
        let f = folder.join(format!("{}.csv", r.socket().unwrap()));
        let header = if f.exists() { String::new() } else { "q1,q2,q3,q4,q5,q6\n".into() };
        let line: Vec<String> = r.q_deg.iter().map(|d| format!("{:.12}", d.to_radians())).collect();
        let mut text = std::fs::read_to_string(&f).unwrap_or_default();
        text.push_str(&header);
        text.push_str(&(line.join(",") + "\n"));
        std::fs::write(&f, text).unwrap();
    }
    let read = Dataset::load_with(&tool, &ReadOptions { angles: twincal::dataset::AngleUnit::Rad, ..Default::default() }).unwrap();
    assert_eq!(read.rows.len(), data.rows.len());
    assert_eq!(read.stations().labels, data.stations().labels);
    for (x, y) in read.rows.iter().zip(&data.rows) {
        assert_eq!((&x.station, &x.feature), (&y.station, &y.feature));
        assert!(x.q_deg.iter().zip(&y.q_deg).all(|(p, q)| (p - q).abs() < 1e-9), "{:?} vs {:?}", x.q_deg, y.q_deg);
    }
}

/// What socket rows cannot determine is said, never fitted silently: no spacing (no scale), one
/// socket, too few or unturned seatings, a method that never sees a spacing; a seated row with
/// a tracker's reading is refused.
#[test]
fn what_artifact_rows_cannot_determine_is_said() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s");
    let sc = scenario_path("irb120_sockets");
    assert!(twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]).status.success());
    let data = Dataset::load(&out).unwrap();
    let refused = |d: &Dataset, extra: &[&str], expect: &str| {
        let f = dir.path().join("d.csv");
        d.write_csv(&f).unwrap();
        let mut args = vec!["calibrate", "--data", f.to_str().unwrap(), "--quiet"];
        args.extend_from_slice(extra);
        let o = twincal(&args);
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(expect), "{extra:?}: expected '{expect}' in: {err}");
    };
    refused(&data, &[], "no known spacing between sockets");
    let one = Dataset { rows: data.rows.iter().filter(|r| r.socket() == Some("A") && r.station.as_deref() == Some("p1")).cloned().collect(), ..data.clone() };
    refused(&one, &["--spacing-mm", "A:B=50"], "seated in one socket only");
    let few: Vec<_> = data.rows.iter().enumerate().filter(|(i, _)| i % 30 < 2).map(|(_, r)| twincal::dataset::Row { split: None, ..r.clone() }).collect();
    refused(&Dataset { rows: few, ..data.clone() }, &["--spacing-mm", "A:B=50"], "cannot place the socket");
    refused(&data, &["--spacing-mm", "A:B=50", "--method", "ekf"], "never sees a spacing");
    refused(&data, &["--spacing-mm", "A:Z=50"], "no stated spacing ties two sockets");
    // An artifact of two sockets: its spacing needs no names.
    let o = twincal(&["calibrate", "--data", out.to_str().unwrap(), "--spacing-mm", "50", "--out", dir.path().join("r.json").to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("r.json")).unwrap()).unwrap();
    let cannot = r["artifact"]["cannot_see"].as_array().unwrap();
    assert!(cannot.iter().any(|c| c.as_str().unwrap().starts_with("the base frame")), "{cannot:?}");
    assert!(cannot.iter().any(|c| c.as_str().unwrap().contains("scale")), "{cannot:?}");
    let csv = std::fs::read_to_string(out.join("dataset.csv")).unwrap();
    let mut lines = csv.lines();
    let header = lines.next().unwrap().to_string() + ",x,y,z";
    let body: Vec<String> = lines.map(|l| l.to_string() + ",400,0,300").collect();
    let f = dir.path().join("both.csv");
    std::fs::write(&f, header + "\n" + &body.join("\n")).unwrap();
    let o = twincal(&["calibrate", "--data", f.to_str().unwrap(), "--spacing-mm", "A:B=50", "--quiet"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("reads nothing"), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Seated rows and 20 tracker points of the same arm in one fit (one file: a row naming its
/// socket reads nothing, the others the tracker's x, y, z): the held-out tracker points several
/// times better than the sockets alone, and the plate's spacing found as it was made rather than
/// as stated. The file round-trips; a seated row with a tracker reading is refused.
#[test]
fn sockets_and_a_few_tracker_points_fit_together() {
    let (s, robot) = scenario("irb120_sockets", &|t| t);
    for seed in [1u64, 2] {
        let c = twincal::artifact_check::mixed(&Scenario { seed, ..s.clone() }, &robot, &lm(&robot), 20).unwrap();
        assert!(c.mixed_mm < c.artifact_mm / 4.0 && c.mixed_mm < 0.02, "seed {seed}: {c:?}");
        assert!((c.spacing_fitted_mm - c.spacing_made_mm).abs() < 0.008, "seed {seed}: {c:?}");
    }
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("mixed.csv");
    let text = "q1,q2,q3,q4,q5,q6,x,y,z,placement,socket\n\
                10,20,30,40,50,60,,,,p1,A\n\
                11,21,31,41,51,61,400.1,20.2,300.3,,\n";
    std::fs::write(&f, text).unwrap();
    let d = Dataset::load(&f).unwrap();
    assert_eq!(d.measurement(), Some(twincal::measurement::Measurement::Socket));
    assert_eq!(d.also_measurement(), Some(twincal::measurement::Measurement::Point));
    let back = dir.path().join("back.csv");
    d.write_csv(&back).unwrap();
    assert_eq!(Dataset::load(&back).unwrap().rows, d.rows);
    std::fs::write(&f, text.replace("60,,,,p1,A", "60,1,2,3,p1,A")).unwrap();
    let e = Dataset::load(&f).unwrap_err().to_string();
    assert!(e.contains("reads nothing"), "{e}");
}

/// The operator's preload along the ball's stem loads the joints: with the force stated
/// (`--preload-n`), `diagnose` names the joints' compliance from the seated rows alone, at the
/// twin's sizes, and the held-out fit falls to that of an arm with no compliance; an arm as stiff
/// as the twin's links under the same preload is left geometric (two seeds each). Tracker rows
/// refuse the option by name.
#[test]
fn diagnose_names_compliance_under_the_socket_preload() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_string_lossy().into_owned();
    let base = std::fs::read_to_string(scenario_path("irb120_sockets"))
        .unwrap()
        .replace("seat_std_mm = 0.01", "seat_std_mm = 0.003")
        .replace("preload_n = 0.0", "preload_n = 30.0");
    let compliant = base.replace("[sensor]", "[effects.compliance]\nstiffness_nm_per_rad = [1.5e5, 1.0e5, 8.0e4, 3.0e4, 3.0e4, 2.0e4]\n\n[sensor]");
    let run = |text: &str, seed: u64, name: &str| -> serde_json::Value {
        std::fs::write(p(&format!("{name}.toml")), text.replace("seed = 7", &format!("seed = {seed}"))).unwrap();
        let g = twincal(&["generate", "--scenario", &p(&format!("{name}.toml")), "--out", &p(name), "--quiet"]);
        assert!(g.status.success(), "{}", String::from_utf8_lossy(&g.stderr));
        let (out, result) = (p(&format!("{name}.json")), p(&format!("{name}_model.json")));
        let d = twincal(&["diagnose", "--data", &p(name), "--spacing-mm", "50", "--preload-n", "30", "--out", &out, "--result", &result, "--quiet"]);
        assert!(d.status.success(), "{}", String::from_utf8_lossy(&d.stderr));
        serde_json::from_str(&std::fs::read_to_string(p(&format!("{name}.json"))).unwrap()).unwrap()
    };
    for seed in [1u64, 2] {
        let stiff = run(&base, seed, &format!("stiff{seed}"));
        assert_eq!(stiff["verdict"], "geometric_only", "seed {seed}: {}", stiff["causes"]);
        let floor = stiff["final_heldout_rmse_mm"].as_f64().unwrap();
        let d = run(&compliant, seed, &format!("compliant{seed}"));
        let causes = d["causes"].as_array().unwrap();
        assert!(causes.iter().all(|c| c["cause"] == "compliance"), "seed {seed}: {causes:?}");
        // Compliance = 1/stiffness, urad/Nm.
        for (joint, truth) in [(1, 1e6 / 1.5e5), (2, 1e6 / 1.0e5), (3, 1e6 / 8.0e4)] {
            let c = causes.iter().find(|c| c["joint"] == joint).unwrap_or_else(|| panic!("seed {seed}: joint {joint} not named: {causes:?}"));
            let m = c["magnitude"].as_f64().unwrap();
            assert!((m - truth).abs() < 0.15 * truth, "seed {seed}: joint {joint}: {m:.2} urad/Nm against {truth:.2}");
        }
        let before = d["baseline"]["heldout_rmse_mm"].as_f64().unwrap();
        let after = d["final_heldout_rmse_mm"].as_f64().unwrap();
        assert!(before > 2.0 * after && after < 1.2 * floor, "seed {seed}: {before:.4} -> {after:.4} mm, stiff arm {floor:.4} mm");
    }
    let g = twincal(&["generate", "--scenario", scenario_path("irb120_tracker").to_str().unwrap(), "--out", &p("tracker"), "--quiet"]);
    assert!(g.status.success());
    let e = twincal(&["calibrate", "--data", &p("tracker"), "--preload-n", "20", "--out", &p("t.json")]);
    assert_eq!(e.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&e.stderr).contains("--preload-n"), "{}", String::from_utf8_lossy(&e.stderr));
}

/// One ball seated in the sockets and touching a block's faces: both kinds of rows in one file
/// and one fit (the faces are stations beside the sockets, each instrument weighted by its own
/// scatter). The twin writes the same bytes for a seed; the fit states each socket and face and
/// both kinds of distance, and says where the plate's spacing (stated as designed, made 0.03 mm long)
/// and the block's step disagree, not once they are stated with their uncertainties; with an
/// exact plate it predicts unseen tracker points better than either artifact alone. Rows naming both or neither, and a spacing naming a socket and a
/// face, are refused by name.
#[test]
fn sockets_and_faces_fit_together() {
    let (s, robot) = scenario("irb120_sockets_planes", &exact_plate);
    let s = Scenario { seed: 1, ..s };
    let both = twincal::artifact_check::check(&s, &robot, &lm(&robot)).unwrap();
    let sockets = twincal::artifact_check::check(&Scenario { planes: None, ..s.clone() }, &robot, &lm(&robot)).unwrap();
    let faces = twincal::artifact_check::check(&Scenario { sockets: None, ..s.clone() }, &robot, &lm(&robot)).unwrap();
    assert!(both.artifact_mm < sockets.artifact_mm && both.artifact_mm < faces.artifact_mm, "both {both:?}\nsockets {sockets:?}\nfaces {faces:?}");
    assert!(both.nominal_mm > 20.0 * both.artifact_mm, "{both:?}");

    let dir = tempfile::tempdir().unwrap();
    // The plate's second socket made 0.03 mm out (600 ppm long), the block's step 0.002 mm.
    let sc = dir.path().join("long_plate.toml");
    let text = std::fs::read_to_string(scenario_path("irb120_sockets_planes")).unwrap();
    std::fs::write(&sc, text.replace("made_error_mm = [[0.0, 0.0], [0.01, 0.0]]", "made_error_mm = [[0.0, 0.0], [0.03, 0.0]]")).unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for out in [&a, &b] {
        let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    for f in ["dataset.csv", "sockets.json", "planes.json"] {
        assert_eq!(std::fs::read(a.join(f)).unwrap(), std::fs::read(b.join(f)).unwrap(), "{f}");
    }
    let d = Dataset::load(&a).unwrap();
    assert_eq!(d.measurement(), Some(twincal::measurement::Measurement::Socket));
    assert_eq!(d.also_measurement(), Some(twincal::measurement::Measurement::Plane));
    let back = dir.path().join("back.csv");
    d.write_csv(&back).unwrap();
    assert_eq!(Dataset::load(&back).unwrap().rows, d.rows);
    let result = dir.path().join("result.json");
    let o = twincal(&["calibrate", "--data", a.to_str().unwrap(), "--spacing-mm", "A:B=50", "--spacing-mm", "low:high=25", "--out", result.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&o.stderr).to_string() + &String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{text}");
    for want in ["socket p1/A", "face p1/low", "spacing p1/A-p1/B", "spacing p1/low-p1/high", "weighted by its own scatter"] {
        assert!(text.contains(want), "'{want}' missing:\n{text}");
    }
    // The plate made 0.03 mm long stated as designed beside the block's step: the two scales
    // disagree and the report says so; stated with their uncertainties, they do not.
    assert!(text.contains("stated distances disagree"), "{text}");
    let o = twincal(&[
        "calibrate",
        "--data",
        a.to_str().unwrap(),
        "--spacing-mm",
        "A:B=50±0.02,low:high=25±0.001",
        "--out",
        dir.path().join("sd.json").to_str().unwrap(),
    ]);
    let sd = String::from_utf8_lossy(&o.stderr).to_string() + &String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && !sd.contains("stated distances disagree") && sd.contains("stated 50.0000 ± 0.0200 mm"), "{sd}");
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&result).unwrap()).unwrap();
    assert_eq!(r["artifact"]["sockets"].as_array().map(Vec::len), Some(6), "{}", r["artifact"]);
    assert_eq!(r["artifact"]["faces"].as_array().map(Vec::len), Some(12), "{}", r["artifact"]);
    let o = twincal(&["calibrate", "--data", a.to_str().unwrap(), "--spacing-mm", "A:low=3", "--out", dir.path().join("r2.json").to_str().unwrap()]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.code() == Some(2) && e.contains("not two sockets nor two faces"), "{e}");

    let f = dir.path().join("bad.csv");
    let text = "q1,q2,q3,q4,q5,q6,placement,socket,plane\n10,20,30,40,50,60,p1,A,\n11,21,31,41,51,61,p1,,low\n";
    std::fs::write(&f, text).unwrap();
    assert_eq!(Dataset::load(&f).unwrap().also_measurement(), Some(twincal::measurement::Measurement::Plane));
    std::fs::write(&f, text.replace("61,p1,,low", "61,p1,A,low")).unwrap();
    let e = Dataset::load(&f).unwrap_err().to_string();
    assert!(e.contains("names a socket and a face"), "{e}");
    std::fs::write(&f, text.replace("61,p1,,low", "61,p1,,")).unwrap();
    let e = Dataset::load(&f).unwrap_err().to_string();
    assert!(e.contains("neither a socket nor a face"), "{e}");
    std::fs::write(&f, text.replace("61,p1,,low", "61,p1,,A")).unwrap();
    let e = Dataset::load(&f).unwrap_err().to_string();
    assert!(e.contains("names a socket and a face"), "{e}");
}

/// A plan of few seatings (24 over two sockets at three placements) seats every socket it uses
/// at least as often as a calibration needs to place it (3 turned configurations): the design
/// had put 2 at one socket, which `calibrate` refuses; those went to the others, and the plan says
/// so.
#[test]
fn a_plan_seats_every_socket_it_uses_often_enough_to_place_it() {
    let (s, robot) = scenario("irb120_sockets", &|t| t);
    let popts = twincal::plan::PlanOptions { n: 24, candidates: 600, seed: 1, ..Default::default() };
    let plan = twincal::plan::artifact::plan(&s, &robot, &popts).unwrap();
    let features = plan.features.as_ref().unwrap();
    let mut counts: std::collections::BTreeMap<&str, usize> = std::collections::BTreeMap::new();
    features.iter().for_each(|f| *counts.entry(f.as_str()).or_default() += 1);
    eprintln!("{counts:?}; {:?}", plan.warnings);
    assert_eq!(features.len(), 24);
    assert!(counts.values().all(|&k| k >= twincal::measurement::socket::MIN_ROWS_PER_SOCKET), "{counts:?}");
    assert!(plan.warnings.iter().any(|w| w.contains("fewer rows than a calibration needs")), "{:?}", plan.warnings);
}

/// `plan` for a socket plate verified by seating on the twin (`artifact_check::plan_check`): 24
/// planned seatings, made on the true arm as an operator makes them (jogged to the planned
/// joints, the ball pushed into its socket), calibrate it better on unseen tracker points than
/// random sets of 24 of the plan's candidates seated the same way, as many in each socket: over
/// six seeds (the plate exact, seated within 0.01 mm) the planned error is under 0.9x the random
/// sets' median in the median (0.75x; seed by seed it is not always below: 24 seatings for 38
/// parameters and six sockets leave much to chance).
#[test]
fn planned_seatings_beat_random_ones_on_the_twin() {
    let (s, robot) = scenario("irb120_sockets", &exact_plate);
    let ratios: Vec<f64> = (1..=6u64)
        .map(|seed| {
            let popts = twincal::plan::PlanOptions { n: 24, candidates: 600, seed, ..Default::default() };
            let c = twincal::artifact_check::plan_check(&s, &robot, &popts, &lm(&robot), 5).unwrap();
            let median = twincal::stats::median(&c.random_mm);
            eprintln!("seed {seed}: planned {:.4} mm, random {:?}", c.planned_mm, c.random_mm);
            c.planned_mm / median
        })
        .collect();
    eprintln!("planned / random median: {ratios:?}");
    assert!(twincal::stats::median(&ratios) < 0.9, "{ratios:?}");
}

/// A scenario's plate made exact: its second socket where designed, no expansion.
fn exact_plate(t: String) -> String {
    t.replace("made_error_mm = [[0.0, 0.0], [0.01, 0.0]]", "made_error_mm = [[0.0, 0.0], [0.0, 0.0]]")
        .replace("expansion_ppm_per_k = 68.0", "expansion_ppm_per_k = 0.0")
}
