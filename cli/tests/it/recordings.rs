//! The recordings read back: every view of each command's layout has data on the timeline the
//! viewer opens on, and the entities, archetypes and timelines the views rely on are there; the
//! HTML report and the verdict of `calibrate`.
#![cfg(feature = "rerun")]

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn twincal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_twincal")).args(args).arg("--quiet").output().expect("runs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The all-effects scenario with fewer poses (8 held out).
fn small_scenario(dir: &Path, poses: usize) -> PathBuf {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios/irb120_evo_nph.toml");
    let text = std::fs::read_to_string(path).unwrap().replace("poses = 600", &format!("poses = {poses}")).replace("test = 100", "test = 8");
    let p = dir.join("small.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// `generate --scenario sc --out dir/data --rrd dir/gen.rrd`, its recording read back: it opens
/// on `pose` and every view has data.
fn generated(dir: &Path, sc: &Path) -> (PathBuf, common::Recording) {
    let (data, gen) = (dir.join("data"), dir.join("gen.rrd"));
    let o = twincal(&["generate", "--scenario", s(sc), "--out", s(&data), "--rrd", s(&gen)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = common::read(&gen);
    assert_eq!(r.timeline.as_deref(), Some("pose"));
    r.assert_no_empty_view();
    (data, r)
}

#[test]
fn generate_calibrate_and_compare_recordings_hold_what_their_views_show() {
    let dir = tempfile::tempdir().unwrap();
    let sc = small_scenario(dir.path(), 60);
    // generate: opens on `pose`; static residual field, plots and histogram; the arm per pose.
    let (data, r) = generated(dir.path(), &sc);
    for (e, c, t) in [
        ("/world/tool_points", "Points3D:positions", "static"),
        ("/world/tool_points", "Points3D:labels", "static"),
        ("/world/colorbar/bar", "LineStrips3D:strips", "static"),
        ("/world/colorbar/values", "Points3D:labels", "static"),
        ("/world/instrument/cable_exit", "Points3D:positions", "static"),
        ("/world/arm/frame_1", "Transform3D:translation", "pose"),
        ("/world/arm/frame_1", "TransformAxes3D:axis_length", "static"),
        ("/world/arm/links", "LineStrips3D:strips", "pose"),
        ("/world/arm/joints", "Points3D:positions", "pose"),
        ("/world/cable", "LineStrips3D:strips", "acquisition_time"),
        ("/world/current", "Points3D:positions", "pose"),
        ("/residuals/histogram", "BarChart:values", "static"),
        ("/effects/deflection/j2", "Scalars:scalars", "pose"),
        ("/effects/deflection/j2", "SeriesPoints:marker_sizes", "static"),
        ("/effects/backlash/j6", "Scalars:scalars", "pose"),
        ("/effects/thermal/scale_ppm", "Scalars:scalars", "pose"),
        ("/docs/legend", "TextDocument:text", "static"),
    ] {
        assert!(r.holds(e, c, t), "generate: {e} lacks {c} on {t}: {:?}", r.entities.get(e));
    }
    for f in ["q1", "q2", "q3", "q4", "q5", "q6", "L", "t", "temp"] {
        assert!(r.holds(&format!("/plots/{f}/points"), "Points2D:positions", "static"), "plot {f}");
        assert!(r.holds(&format!("/plots/{f}/frame/ticks"), "Points2D:labels", "static"), "plot {f}");
        assert_eq!(r.entities[&format!("/plots/{f}/current")].rows.get("pose"), Some(&60), "one highlight per pose in plot {f}");
    }
    let kinds = |cls: &str| r.views.iter().filter(|v| v.class == cls).count();
    assert_eq!((kinds("3D"), kinds("2D"), kinds("TimeSeries"), kinds("BarChart"), kinds("TextDocument")), (1, 9, 3, 1, 1), "{:#?}", r.views);
    assert!(r.views.iter().filter(|v| v.class == "2D").all(|v| v.has_bounds), "every plot is framed");
    assert_eq!(r.view("Legend").origin, "/docs");
    assert_eq!(
        r.entities_of(r.view("vs q3")),
        [
            "/plots/q3/current",
            "/plots/q3/frame/box",
            "/plots/q3/frame/grid",
            "/plots/q3/frame/ticks",
            "/plots/q3/frame/x_title",
            "/plots/q3/frame/zero",
            "/plots/q3/points"
        ]
    );

    // calibrate: before / after side by side, convergence from the start, verdict and report.
    let (res, cal, html) = (dir.path().join("r.json"), dir.path().join("cal.rrd"), dir.path().join("r.html"));
    let o = twincal(&[
        "calibrate",
        "--data",
        s(&data),
        "--out",
        s(&res),
        "--rrd",
        s(&cal),
        "--report",
        s(&html),
        "--max-test-rmse-mm",
        "10",
        "--max-test-max-mm",
        "0.0001",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("verdict: FAIL") && err.contains("test_max_mm"), "the verdict is printed also with --quiet: {err}");
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&res).unwrap()).unwrap();
    let v = &j["verdict"];
    assert_eq!(v["pass"], false, "{v}");
    assert_eq!((v["checks"][0]["name"].as_str(), v["checks"][0]["pass"].as_bool()), (Some("test_rmse_mm"), Some(true)));
    assert_eq!((v["checks"][1]["name"].as_str(), v["checks"][1]["pass"].as_bool()), (Some("test_max_mm"), Some(false)));
    assert_eq!(v["checks"][1]["value"].as_f64(), j["evaluation"]["metrics"]["test_after"]["max"].as_f64());

    let r = common::read(&cal);
    assert_eq!(r.timeline.as_deref(), Some("iteration"));
    r.assert_no_empty_view();
    for (e, c, t) in [
        ("/world/before/train", "Points3D:labels", "static"),
        ("/world/before/test", "Points3D:positions", "static"),
        ("/world/after/train", "Points3D:colors", "static"),
        ("/world/after/colorbar/bar", "LineStrips3D:strips", "static"),
        ("/world/arm/links", "LineStrips3D:strips", "static"),
        ("/residuals/before", "BarChart:values", "static"),
        ("/residuals/after", "BarChart:abscissa", "static"),
        ("/convergence/rms/train", "Scalars:scalars", "iteration"),
        ("/convergence/rms/test", "Scalars:scalars", "iteration"),
        ("/convergence/cost", "Scalars:scalars", "iteration"),
        ("/final/lengths/change", "Points2D:positions", "static"),
        ("/final/angles/sigma", "LineStrips2D:strips", "static"),
        ("/final/placement/truth", "Points2D:positions", "static"),
        ("/docs/summary", "TextDocument:text", "static"),
    ] {
        assert!(r.holds(e, c, t), "calibrate: {e} lacks {c} on {t}: {:?}", r.entities.get(e));
    }
    assert!(r.entities.keys().any(|e| e.starts_with("/params/lengths/")) && r.entities.keys().any(|e| e.starts_with("/params/placement/")));
    // The two 3D views each leave out the other side.
    let before = r.view("Before calibration");
    assert!(r.entities_of(before).iter().all(|e| !e.starts_with("/world/after")) && r.entities_of(before).contains(&"/world/before/train"));
    // Iteration 0 is the starting point, the last one the result.
    let rms = common::scalars(&cal, "/convergence/rms/train");
    let m = &j["evaluation"]["metrics"];
    assert!(rms.len() >= 2, "{rms:?}");
    assert!((rms[0] - m["train_before"]["rmse"].as_f64().unwrap()).abs() < 1e-9, "{rms:?} vs {}", m["train_before"]);
    assert!((rms[rms.len() - 1] - m["train_after"]["rmse"].as_f64().unwrap()).abs() < 1e-9, "{rms:?} vs {}", m["train_after"]);

    // The report: one self-contained page with the numbers and the verdict.
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.starts_with("<!DOCTYPE html>") && page.trim_end().ends_with("</html>"));
    assert!(page.matches("<svg").count() >= 14, "histograms, 9 feature plots, convergence, parameters");
    for bad in ["<script", "src=", "href=", "@import", "url("] {
        assert!(!page.contains(bad), "the page must not load anything: {bad}");
    }
    assert!(page.contains(&format!("{:.4}", m["test_after"]["rmse"].as_f64().unwrap())) && page.contains("FAIL") && page.contains("test_max_mm"));

    // compare: the table and the per-seed spread.
    let cmp = dir.path().join("cmp.rrd");
    let o = twincal(&["compare", "--data", s(&data), "--methods", "lm,ekf", "--seeds", "2", "--rrd", s(&cmp)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = common::read(&cmp);
    r.assert_no_empty_view();
    for (e, c) in [("/docs/table", "TextDocument:text"), ("/spread/test_rmse/seeds", "Points2D:labels"), ("/spread/test_max/mean_sd", "LineStrips2D:strips")] {
        assert!(r.holds(e, c, "static"), "compare: {e} lacks {c}");
    }
    assert_eq!(r.views.len(), 3, "{:#?}", r.views);
    // study hold: three plots (one series per speed, with a legend) and the table; static.
    let hold = dir.path().join("hold.rrd");
    let o = twincal(&["study", "hold", "--scenario", s(&sc), "--poses", "4", "--holds", "0.02,0.5", "--speeds", "0.2,0.5", "--rrd", s(&hold)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = common::read(&hold);
    r.assert_no_empty_view();
    assert_eq!(r.views.len(), 4, "{:#?}", r.views);
    for q in ["bias_um", "spread_um", "max_um"] {
        for (e, c) in [
            (format!("/study/{q}/speed_0.20/points"), "Points2D:labels"),
            (format!("/study/{q}/speed_0.50/line"), "LineStrips2D:strips"),
            (format!("/study/{q}/legend"), "Points2D:labels"),
            (format!("/study/{q}/frame/ticks"), "Points2D:labels"),
        ] {
            assert!(r.holds(&e, c, "static"), "study: {e} lacks {c}");
        }
    }
    assert!(r.holds("/docs/table", "TextDocument:text", "static"));
    // Nothing temporary is left next to the outputs.
    let names: Vec<String> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().to_string()).collect();
    assert!(names.iter().all(|n| !n.contains(".tmp")), "{names:?}");
}

#[test]
fn limits_are_checked_and_missing_test_rows_fail_the_verdict() {
    let dir = tempfile::tempdir().unwrap();
    let sc = small_scenario(dir.path(), 40);
    let data = dir.path().join("data");
    assert!(twincal(&["generate", "--scenario", s(&sc), "--out", s(&data)]).status.success());
    let (res, html) = (dir.path().join("r.json"), dir.path().join("r.html"));
    for (flag, v) in [("--max-test-rmse-mm", "-1"), ("--max-test-max-mm", "0"), ("--max-test-rmse-mm", "nan")] {
        let o = twincal(&["calibrate", "--data", s(&data), "--out", s(&res), "--report", s(&html), flag, v]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flag} {v}: {err}");
        assert!(err.contains(flag) && !err.contains("panicked"), "{err}");
        assert!(!res.exists() && !html.exists(), "nothing is written on bad input");
    }
    // Training on every row leaves nothing to measure the test limits on: the check fails, and
    // says why; without limits there is no verdict at all.
    let o = twincal(&["calibrate", "--data", s(&data), "--out", s(&res), "--test-fraction", "0", "--max-test-rmse-mm", "1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&res).unwrap()).unwrap();
    assert_eq!(j["verdict"]["pass"], false);
    assert!(j["verdict"]["checks"][0]["value"].is_null() && j["verdict"]["checks"][0]["source"].as_str().unwrap().contains("no test rows"));
    assert!(twincal(&["calibrate", "--data", s(&data), "--out", s(&res)]).status.success());
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&res).unwrap()).unwrap();
    assert!(j.get("verdict").is_none());
}

/// `generate --rrd` with a laser tracker: the tracker where the scenario puts it (its axes and
/// head at −Rᵀt), its line of sight to the reflector at every pose, every tool point coloured by
/// its distance from the nominal arm's reflector, and one plot per coordinate.
#[test]
fn generate_draws_a_tracker_and_its_line_of_sight() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios/irb120_tracker.toml"))
        .unwrap()
        .replace("poses = 300", "poses = 40")
        .replace("test = 100", "test = 8");
    let sc = dir.path().join("tracker.toml");
    std::fs::write(&sc, text).unwrap();
    let (_, r) = generated(dir.path(), &sc);
    for (e, c, t) in [
        ("/world/instrument/tracker", "Transform3D:translation", "static"),
        ("/world/instrument/tracker/head", "Points3D:positions", "static"),
        ("/world/line_of_sight", "LineStrips3D:strips", "pose"),
        ("/world/tool_points", "Points3D:labels", "static"),
        ("/world/colorbar/values", "Points3D:labels", "static"),
        ("/residuals/histogram", "BarChart:values", "static"),
        ("/docs/legend", "TextDocument:text", "static"),
    ] {
        assert!(r.holds(e, c, t), "generate: {e} lacks {c} on {t}: {:?}", r.entities.get(e));
    }
    assert!(!r.entities.contains_key("/world/cable") && !r.entities.contains_key("/world/instrument/cable_exit"), "no cable is drawn");
    assert_eq!(r.entities["/world/line_of_sight"].rows.get("pose"), Some(&40), "one line of sight per pose");
    for f in ["q1", "q6", "x", "y", "z"] {
        assert!(r.holds(&format!("/plots/{f}/points"), "Points2D:positions", "static"), "plot {f}");
    }
    assert!(r.views.iter().any(|v| v.name.starts_with("Arm, tracker, tool points")), "{:#?}", r.views);
}

/// Artifact rows in the recordings and the HTML report: `calibrate` on socket rows draws each
/// socket where the fit puts it (labelled with its scatter), the stated spacings and the ball at
/// the arm's flange, and plots every row at its socket, with no cable nor tracker; its page lists
/// the sockets, the spacings stated against fitted and what the rows cannot see. A probe's faces
/// are drawn as faces, and `diagnose` on socket rows draws the same artifact.
#[test]
fn artifact_rows_draw_their_sockets_and_faces() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    let (data, res, rrd, html) = (dir.path().join("sock"), dir.path().join("r.json"), dir.path().join("c.rrd"), dir.path().join("c.html"));
    assert!(twincal(&["generate", "--scenario", s(&root.join("scenarios/irb120_sockets.toml")), "--out", s(&data)]).status.success());
    let o = twincal(&["calibrate", "--data", s(&data), "--spacing-mm", "50", "--out", s(&res), "--rrd", s(&rrd), "--report", s(&html)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = common::read(&rrd);
    r.assert_no_empty_view();
    for (e, c) in [
        ("/world/artifact/sockets", "Points3D:labels"),
        ("/world/artifact/spacings", "LineStrips3D:strips"),
        ("/world/artifact/spacing_labels", "Points3D:labels"),
        ("/world/artifact/ball", "Points3D:positions"),
        ("/artifact_rows/0", "Points2D:positions"),
        ("/artifact_rows/5", "Points2D:labels"),
    ] {
        assert!(r.holds(e, c, "static"), "calibrate: {e} lacks {c}: {:?}", r.entities.get(e));
    }
    assert!(!r.entities.keys().any(|e| e.starts_with("/world/instrument") || e == "/world/cable"), "no instrument beside the artifact is drawn");
    assert!(r.views.iter().any(|v| v.name.starts_with("Every row at its socket")), "{:#?}", r.views);
    let page = std::fs::read_to_string(&html).unwrap();
    for want in ["The artifact: 6 sockets", "p3/B", "fitted − stated (µm)", "What these rows cannot see", "the base frame"] {
        assert!(page.contains(want), "the page lacks {want:?}");
    }
    let (d_rrd, d_out) = (dir.path().join("d.rrd"), dir.path().join("d.json"));
    let o =
        twincal(&["diagnose", "--data", s(&data), "--spacing-mm", "50", "--out", s(&d_out), "--result", s(&dir.path().join("dr.json")), "--rrd", s(&d_rrd)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = common::read(&d_rrd);
    r.assert_no_empty_view();
    assert!(r.holds("/world/artifact/sockets", "Points3D:labels", "static") && r.holds("/artifact_rows/0", "Points2D:positions", "static"));
    let (planes, p_rrd) = (dir.path().join("planes"), dir.path().join("p.rrd"));
    assert!(twincal(&["generate", "--scenario", s(&root.join("scenarios/irb120_planes.toml")), "--out", s(&planes)]).status.success());
    let o = twincal(&["calibrate", "--data", s(&planes), "--spacing-mm", "low:high=25", "--out", s(&dir.path().join("p.json")), "--rrd", s(&p_rrd)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = common::read(&p_rrd);
    r.assert_no_empty_view();
    for (e, c) in
        [("/world/artifact/faces", "LineStrips3D:strips"), ("/world/artifact/normals", "LineStrips3D:strips"), ("/world/artifact/stylus", "Points3D:positions")]
    {
        assert!(r.holds(e, c, "static"), "planes: {e} lacks {c}: {:?}", r.entities.get(e));
    }
}
