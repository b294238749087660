//! A touch probe (or a dial indicator) on a block's faces: the twin's acquisition, the
//! calibration from the contacts alone judged on a tracker's points of the same arm that no fit
//! saw, and what such rows cannot determine said by name.

use crate::common::artifact::{lm, scenario, scenario_path, twincal};
use twincal::dataset::Dataset;
use twincal::sim::scenario::Scenario;

/// An exact probe on an exact block: the faces' arm predicts unseen tracker points as well as a
/// tracker calibration of the same arm from as many rows (within 1.5x, three seeds). With the
/// scenario's probe (pre-travel, lobing, trigger scatter) and block (a step made 2 µm long,
/// 1 K warm): still many times better than the nominal arm, and worse than the exact case (the
/// step's error scales the arm: the report names it).
#[test]
fn a_probe_on_a_blocks_faces_calibrates_the_arm_judged_on_unseen_tracker_points() {
    let exact = |t: String| {
        t.replace("pretravel_um = 4.0", "pretravel_um = 0.0")
            .replace("lobing_um = 2.0", "lobing_um = 0.0")
            .replace("trigger_std_um = 0.5", "trigger_std_um = 0.0")
            .replace("made_error_mm = [0.0, 0.002, 0.0, 0.0]", "made_error_mm = [0.0, 0.0, 0.0, 0.0]")
            .replace("expansion_ppm_per_k = 12.0", "expansion_ppm_per_k = 0.0")
    };
    let (s_exact, robot) = scenario("irb120_planes", &exact);
    let (s_real, _) = scenario("irb120_planes", &|t| t);
    for seed in 1..=3u64 {
        let c = twincal::artifact_check::check(&Scenario { seed, ..s_exact.clone() }, &robot, &lm(&robot)).unwrap();
        assert!(c.artifact_mm <= 1.5 * c.tracker_mm, "seed {seed}: exact probe: faces {:.4} mm vs tracker {:.4} mm", c.artifact_mm, c.tracker_mm);
        assert!(c.nominal_mm > 20.0 * c.artifact_mm, "seed {seed}: nominal {:.4} mm vs faces {:.4} mm", c.nominal_mm, c.artifact_mm);
        let r = twincal::artifact_check::check(&Scenario { seed, ..s_real.clone() }, &robot, &lm(&robot)).unwrap();
        assert!(r.nominal_mm > 10.0 * r.artifact_mm, "seed {seed}: nominal {:.4} mm vs faces {:.4} mm", r.nominal_mm, r.artifact_mm);
        assert!(r.artifact_mm > 1.5 * c.artifact_mm, "seed {seed}: a step made wrong must show: {:.4} vs {:.4} mm", r.artifact_mm, c.artifact_mm);
    }
}

/// The same seed writes the same bytes; the file's `plane` column names each contact's face;
/// the stylus and the step are found, the faces' scatter is the probe's, and what the contacts
/// cannot determine is said. A dial indicator's readings (`indicator` column) calibrate the
/// same way.
#[test]
fn face_files_are_byte_identical_and_a_calibration_states_what_it_found() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scenario_path("irb120_planes");
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for out in [&a, &b] {
        let o = twincal(&["generate", "--scenario", sc.to_str().unwrap(), "--out", out.to_str().unwrap(), "--quiet"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let bytes = std::fs::read(a.join("dataset.csv")).unwrap();
    assert_eq!(bytes, std::fs::read(b.join("dataset.csv")).unwrap());
    assert!(String::from_utf8_lossy(&bytes).lines().next().unwrap().contains(",placement,plane,"));
    let r = dir.path().join("r.json");
    let o = twincal(&["calibrate", "--data", a.to_str().unwrap(), "--spacing-mm", "low:high=25", "--out", r.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&r).unwrap()).unwrap();
    let art = &v["artifact"];
    let stylus: Vec<f64> = art["target_mm"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    let truth: serde_json::Value = serde_json::from_slice(&std::fs::read(a.join("planes.json")).unwrap()).unwrap();
    let true_stylus: Vec<f64> = truth["stylus_mm"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    let off = (0..3).map(|k| (stylus[k] - true_stylus[k]).powi(2)).sum::<f64>().sqrt();
    // The stylus against the arm's nominal frames: within the arm's own errors (tenths of a mm).
    assert!(off < 1.0, "stylus {stylus:?} vs {true_stylus:?}");
    assert_eq!(art["faces"].as_array().unwrap().len(), 12);
    assert!(art["faces"].as_array().unwrap().iter().all(|f| f["scatter_mm"].as_f64().unwrap() < 0.005), "{}", art["faces"]);
    for s in art["spacings"].as_array().unwrap() {
        assert!((s["fitted_mm"].as_f64().unwrap() - 25.0).abs() < 0.005, "{s}");
    }
    let cannot: Vec<&str> = art["cannot_see"].as_array().unwrap().iter().map(|c| c.as_str().unwrap()).collect();
    assert!(cannot.iter().any(|c| c.starts_with("the base frame: every face")), "{cannot:?}");
    assert!(cannot.iter().any(|c| c.contains("scale beyond the stated step")), "{cannot:?}");
    let test = v["evaluation"]["metrics"]["test_after"]["rmse"].as_f64().unwrap();
    assert!(test < 0.005, "held-out contacts: {test} mm");
    // A dial indicator pressed onto the faces nearly square, read to 1 µm.
    let ind = dir.path().join("ind.toml");
    let text = std::fs::read_to_string(&sc).unwrap().replace("force_n = 0.5", "force_n = 1.0\nindicator = true").replace("tilt_deg = 30.0", "tilt_deg = 20.0");
    std::fs::write(&ind, text).unwrap();
    let c = dir.path().join("c");
    let o = twincal(&["generate", "--scenario", ind.to_str().unwrap(), "--out", c.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let d = Dataset::load(&c).unwrap();
    assert_eq!(d.measurement(), Some(twincal::measurement::Measurement::Indicator));
    let o =
        twincal(&["calibrate", "--data", c.to_str().unwrap(), "--spacing-mm", "low:high=25", "--out", dir.path().join("ri.json").to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("ri.json")).unwrap()).unwrap();
    let (before, after) =
        (v["evaluation"]["metrics"]["test_before"]["rmse"].as_f64().unwrap(), v["evaluation"]["metrics"]["test_after"]["rmse"].as_f64().unwrap());
    assert!(after < before / 10.0, "indicator: held-out {before} -> {after} mm");
}

/// One face, no step, too few contacts, rows naming a socket and a face at once: each refused by name
/// with exit code 2, never a silent fit.
#[test]
fn what_face_rows_cannot_determine_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p");
    let sc = scenario_path("irb120_planes");
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
    refused(&data, &[], "no known step between faces");
    let one = Dataset {
        rows: data.rows.iter().filter(|r| r.feature.as_ref().is_some_and(|f| f.label == "low") && r.station.as_deref() == Some("p1")).cloned().collect(),
        ..data.clone()
    };
    refused(&one, &["--spacing-mm", "low:high=25"], "touched one face only");
    let few: Vec<_> = data.rows.iter().enumerate().filter(|(i, _)| i % 30 < 3).map(|(_, r)| twincal::dataset::Row { split: None, ..r.clone() }).collect();
    refused(&Dataset { rows: few, ..data.clone() }, &["--spacing-mm", "low:high=25"], "cannot place the face");
    refused(&data, &["--spacing-mm", "low:side=25", "--method", "ekf"], "never sees a spacing");
    let csv = std::fs::read_to_string(out.join("dataset.csv")).unwrap();
    let both = csv
        .replacen(",plane,", ",plane,socket,", 1)
        .lines()
        .enumerate()
        .map(|(i, l)| if i == 0 { l.to_string() } else { l.replacen(",train", ",A,train", 1).replacen(",test", ",A,test", 1) })
        .collect::<Vec<_>>()
        .join("\n");
    let f = dir.path().join("both.csv");
    std::fs::write(&f, both).unwrap();
    let o = twincal(&["calibrate", "--data", f.to_str().unwrap(), "--spacing-mm", "low:high=25", "--quiet"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("names a socket and a face"), "{}", String::from_utf8_lossy(&o.stderr));
}
