//! `twincal iso9283`, end to end: a twin's tracker data before (the nominal arm registered to
//! the tracker) and after calibration, on the rows the calibration held out; the UR10's ISO-cube
//! series d (../shared) with the series-b calibration; bad requests.

use crate::datasets::shared;
use std::path::Path;
use std::process::{Command, Output};

fn twincal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).output().expect("runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn ok(o: Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).to_string()
}

fn ap_means(json: &Path) -> Vec<f64> {
    let e: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    e["models"].as_array().unwrap().iter().map(|m| m["ap_mm"]["mean"].as_f64().unwrap()).collect()
}

#[test]
fn a_calibration_brings_the_held_out_pose_accuracy_of_twin_tracker_data_to_its_noise() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/irb120_tracker.toml"));
    let data = dir.path().join("d");
    ok(twincal(&["--quiet", "generate", "--scenario", s(scenario), "--out", s(&data)]));
    let (before, after) = (dir.path().join("before.json"), dir.path().join("after.json"));
    ok(twincal(&["--quiet", "calibrate", "--data", s(&data), "--placement-only", "--out", s(&before)]));
    ok(twincal(&["--quiet", "calibrate", "--data", s(&data), "--out", s(&after)]));
    let out = dir.path().join("iso.json");
    let page = dir.path().join("iso.html");
    let table = ok(twincal(&["iso9283", "--data", s(&data), "--model", s(&before), "--model", s(&after), "--out", s(&out), "--report", s(&page)]));
    assert!(table.contains("| held out |"), "{table}");
    // The HTML page holds the same table and the per-pose AP histograms.
    let html = std::fs::read_to_string(&page).unwrap();
    let ap_text = format!("{:.4}", ap_means(&out)[1]);
    assert!(html.contains("<h1>ISO 9283") && html.contains(&ap_text) && html.contains("<svg") && html.contains("AP per pose"), "{html}");
    let ap = ap_means(&out);
    // Nominal (registered): the geometric errors' millimetre; calibrated: the tracker's noise.
    assert!(ap[0] > 0.2 && ap[1] < 0.01 && ap[1] < ap[0] / 30.0, "{ap:?}\n{table}");
    // What a controller without a kinematic model keeps (joint zero offsets, base, tool): fitted
    // on those alone, between the nominal and the full model, and nothing else moved.
    let subset = dir.path().join("subset.json");
    let printed = ok(twincal(&["calibrate", "--data", s(&data), "--controller-subset", "--out", s(&subset)]));
    let sub: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&subset).unwrap()).unwrap();
    for p in sub["parameters"].as_array().unwrap().iter().filter(|p| !p["fixed"].as_bool().unwrap()) {
        let name = p["name"].as_str().unwrap();
        assert!(!name.starts_with("joint_") || name.ends_with(".theta"), "{name} fitted by --controller-subset");
    }
    let out3 = dir.path().join("iso3.json");
    ok(twincal(&["iso9283", "--data", s(&data), "--model", s(&before), "--model", s(&subset), "--model", s(&after), "--out", s(&out3)]));
    let ap3 = ap_means(&out3);
    assert!(ap3[0] > ap3[1] && ap3[1] > 3.0 * ap3[2], "nominal / controller subset / full: {ap3:?}\n{printed}");
    // Written as the controllers' own data: the same tool in RAPID, KRL and URScript, the
    // offsets of the result; a full calibration's values are refused.
    let (m, k, u) = (dir.path().join("twc_cal.mod"), dir.path().join("twc_cal.dat"), dir.path().join("twc_cal.script"));
    ok(twincal(&["controller-data", "--model", s(&subset), "--format", "rapid", "--tool-mass-kg", "0.5", "--out", s(&m)]));
    ok(twincal(&["controller-data", "--model", s(&subset), "--format", "krl", "--out", s(&k)]));
    ok(twincal(&["controller-data", "--model", s(&subset), "--format", "urscript", "--out", s(&u)]));
    let (mt, kt, ut) = (std::fs::read_to_string(&m).unwrap(), std::fs::read_to_string(&k).unwrap(), std::fs::read_to_string(&u).unwrap());
    let after_marker = |t: &str, marker: &str| -> Vec<f64> {
        let rest = &t[t.find(marker).unwrap_or_else(|| panic!("{marker} in {t}")) + marker.len()..];
        rest.split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == 'e')).filter(|w| !w.is_empty()).take(3).map(|w| w.parse().unwrap()).collect()
    };
    let rapid = after_marker(&mt, "twc_tool := [TRUE,[[");
    let krl = after_marker(&kt.replace("X ", "").replace("Y ", "").replace("Z ", ""), "TWC_TOOL={");
    let ur: Vec<f64> = after_marker(&ut, "set_tcp(p[").iter().map(|v| v * 1000.0).collect();
    for (a, b) in rapid.iter().zip(&krl).chain(rapid.iter().zip(&ur)) {
        assert!((a - b).abs() < 1e-3, "tool: RAPID {rapid:?}, KRL {krl:?}, URScript {ur:?}");
    }
    let thetas: Vec<f64> = sub["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["name"].as_str().unwrap().ends_with(".theta"))
        .map(|p| p["value"].as_f64().unwrap() - p["nominal"].as_f64().unwrap())
        .collect();
    for (j, d) in thetas.iter().enumerate() {
        let line = mt
            .lines()
            .find(|l| l.trim_start_matches(['!', ' ']).starts_with(&format!("joint_{} ", j + 1)))
            .unwrap_or_else(|| panic!("joint_{} in {mt}", j + 1));
        let written: f64 = line.split_whitespace().last().unwrap().parse().unwrap();
        assert!((written - d).abs() < 2e-6, "joint_{}: {written} written, {d} in the result", j + 1);
    }
    assert!(mt.contains("PERS wobjdata twc_instrument") && kt.contains("TWC_BASE={") && ut.contains("twc_instrument = p["));
    // Beside the full calibration of the same rows, in the controller's own frames: the subset's
    // held-out RMSE between the nominal's and the full model's, the tool in tool0 (the IRB 120's
    // flange frame turned 90° about y).
    let m2 = dir.path().join("twc_cal2.mod");
    let o = twincal(&[
        "controller-data",
        "--model",
        s(&subset),
        "--full",
        s(&after),
        "--robot",
        "irb120",
        "--format",
        "rapid",
        "--tool-mass-kg",
        "0.5",
        "--out",
        s(&m2),
    ]);
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{err}");
    let m2t = std::fs::read_to_string(&m2).unwrap();
    let line = m2t.lines().find(|l| l.contains("held-out rows (RMSE)")).unwrap_or_else(|| panic!("{m2t}"));
    let rmse: Vec<f64> = line.split(" mm").filter_map(|w| w.split_whitespace().last().and_then(|v| v.parse().ok())).collect();
    assert!(rmse.len() == 3 && rmse[0] > rmse[1] && rmse[1] > 3.0 * rmse[2], "nominal / subset / full: {line}");
    assert!(err.contains(&format!("this subset {:.4} mm", rmse[1])), "{err}");
    let tool0 = after_marker(&m2t, "twc_tool := [TRUE,[[");
    assert!((tool0[0] + rapid[2]).abs() < 1e-3 && (tool0[1] - rapid[1]).abs() < 1e-3 && (tool0[2] - rapid[0]).abs() < 1e-3, "tool0 {tool0:?} flange {rapid:?}");
    // A full calibration of other data is no comparison: refused, nothing written.
    let (data5, seed5) = (dir.path().join("d5"), dir.path().join("seed5.json"));
    ok(twincal(&["--quiet", "generate", "--scenario", s(scenario), "--seed", "5", "--out", s(&data5)]));
    ok(twincal(&["--quiet", "calibrate", "--data", s(&data5), "--out", s(&seed5)]));
    let other = twincal(&["controller-data", "--model", s(&subset), "--full", s(&seed5), "--format", "krl", "--out", s(&dir.path().join("o.dat"))]);
    assert_eq!(other.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&other.stderr).contains("not calibrated on the same rows") && !dir.path().join("o.dat").exists());
    // The subset given as its own full calibration is no comparison either.
    let itself = twincal(&["controller-data", "--model", s(&subset), "--full", s(&subset), "--format", "krl", "--out", s(&dir.path().join("i.dat"))]);
    assert_eq!(itself.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&itself.stderr).contains("not a full one") && !dir.path().join("i.dat").exists());
    let full = twincal(&["controller-data", "--model", s(&after), "--format", "krl", "--out", s(&dir.path().join("full.dat"))]);
    assert_eq!(full.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&full.stderr).contains("--controller-subset") && !dir.path().join("full.dat").exists());
    let e = twincal(&["calibrate", "--data", s(&data), "--controller-subset", "--effects", "compliance", "--out", s(&dir.path().join("x.json"))]);
    assert_eq!(e.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&e.stderr).contains("--controller-subset fits"), "{}", String::from_utf8_lossy(&e.stderr));
    // Another arm's tracker data (a UR10's) judged by this IRB 120 model: judged, and named.
    let other = dir.path().join("ur10");
    let ur10 = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/ur10_tracker.toml"));
    ok(twincal(&["--quiet", "generate", "--scenario", s(ur10), "--out", s(&other)]));
    let o = twincal(&["iso9283", "--data", s(&other), "--model", s(&after)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && err.contains("a model of another arm"), "{err}");
    // A draw-wire's lengths are not positions; a missing model is clap's error.
    let cable = dir.path().join("c");
    ok(twincal(&["--quiet", "generate", "--out", s(&cable)]));
    let o = twincal(&["iso9283", "--data", s(&cable), "--model", s(&after)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("model predicts a laser-tracker") || err.contains("judges positions"), "{err}");
    assert_eq!(twincal(&["iso9283", "--data", s(&data)]).status.code(), Some(2));
    let o = twincal(&["iso9283", "--data", s(&data), "--model", s(&after), "--out", s(&after)]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    let o = twincal(&["iso9283", "--data", s(&data), "--model", s(&after), "--report", s(&after)]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    // A result whose held-out rows were edited: a row past the data, a row named twice.
    let text = std::fs::read_to_string(&after).unwrap();
    let mut r: serde_json::Value = serde_json::from_str(&text).unwrap();
    let rows = r["provenance"]["test_rows"].as_array().unwrap().clone();
    assert!(!rows.is_empty());
    for (edit, says) in [(99999, "past the"), (rows[0].as_u64().unwrap(), "twice")] {
        let mut edited = rows.clone();
        edited.push(serde_json::json!(edit));
        r["provenance"]["test_rows"] = serde_json::Value::Array(edited);
        let path = dir.path().join("edited.json");
        std::fs::write(&path, serde_json::to_string(&r).unwrap()).unwrap();
        let o = twincal(&["iso9283", "--data", s(&data), "--model", s(&path)]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("test_rows") && err.contains(says) && !err.contains("panicked"), "{err}");
    }
}

/// The UR10's ISO-cube series d, judged on the rows its registration held out: the nominal arm
/// and the arm calibrated on series b (a tracker placed elsewhere), each registered to series d
/// by `calibrate --placement-only` on the rest.
#[test]
fn the_ur10_iso_cube_series_is_more_accurate_with_the_series_b_calibration() {
    let (Some(b), Some(d)) = (shared("data/ipa-ur10/ur10_series_b.csv"), shared("data/ipa-ur10/ur10_series_d.csv")) else { return };
    let dir = tempfile::tempdir().unwrap();
    let urdf = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../urdf/ur10.urdf"));
    let (rb, calibrated) = (dir.path().join("b.json"), dir.path().join("b.urdf"));
    ok(twincal(&["--quiet", "calibrate", "--data", s(&b), "--model", s(urdf), "--out", s(&rb)]));
    ok(twincal(&["--quiet", "export", "--model", s(&rb), "--out", s(&calibrated), "--robot", s(urdf)]));
    let (before, after) = (dir.path().join("d_nominal.json"), dir.path().join("d_calibrated.json"));
    for (model, out) in [(urdf, &before), (calibrated.as_path(), &after)] {
        ok(twincal(&[
            "--quiet",
            "calibrate",
            "--data",
            s(&d),
            "--model",
            s(model),
            "--params",
            "frame",
            "--placement-only",
            "--test-fraction",
            "0.3",
            "--out",
            s(out),
        ]));
    }
    let out = dir.path().join("iso.json");
    let table = ok(twincal(&["iso9283", "--data", s(&d), "--model", s(&before), "--model", s(&after), "--out", s(&out)]));
    eprintln!("{table}");
    let ap = ap_means(&out);
    assert!(ap[1] < 0.8 * ap[0], "{ap:?}\n{table}");
    let e: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert!(e["models"][0]["rp_mm"]["n"].as_u64().unwrap() >= 10, "{e}");
}
