//! Diagnosis: datasets from the twin with an effect the diagnosis is not told about (cause,
//! joint and size drawn from a recorded seed at 1.5–4× what a rigid fit absorbs); the diagnosis
//! sees only q, L, t and temp, like measured data.

#[cfg(feature = "rerun")]
use crate::common;

use twincal::calib::effects::EffectKind;
use twincal::calib::pipeline::ModelSpec;
use twincal::dataset::{Dataset, Row};
use twincal::diagnose::hidden::{clean, hidden};
use twincal::diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use twincal::robot::Robot;
use twincal::sim::generate::{generate, Silent};
use twincal::sim::scenario::Scenario;

fn run(s: &Scenario, robot: &Robot) -> Diagnosis {
    let g = generate(s, robot, &Silent).unwrap();
    // Only what measured data hold: the generator's split column is dropped too.
    let data = Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: s.name.clone() };
    let opts = DiagnoseOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap());
    diagnose(&data, &opts, &|_| {}).unwrap().0
}

#[test]
fn a_hidden_effect_is_named_with_its_size() {
    for seed in [1, 4, 21] {
        let (s, robot, truth) = hidden(seed, 1).unwrap();
        let h = &truth[0];
        let d = run(&s, &robot);
        eprintln!("seed {seed}: hidden {h:?}; found {:?}", d.causes.iter().map(|c| (&c.cause, c.joint, c.magnitude, c.uncertainty)).collect::<Vec<_>>());
        let first = d.causes.first().unwrap_or_else(|| panic!("seed {seed}: {h:?} not found ({})", d.verdict));
        assert!(h.named_by(first), "seed {seed}: hidden {h:?}, named {} joint {:?} first", first.cause, first.joint);
        assert!(h.sized_by(first), "seed {seed}: size {} ± {} vs true {}", first.magnitude, first.uncertainty, h.magnitude);
        assert!(first.heldout_rmse_after_mm < first.heldout_rmse_before_mm && first.p_value < 0.01);
        // The extended model predicts unseen rows about as well as the rows it was fitted to
        // (no repeated configurations here, so the data's floor is only their resolution), and
        // near the reading noise the scenario draws.
        let sigma = s.draw_wire.noise_std_mm / (s.draw_wire.samples as f64).sqrt();
        assert!(d.final_heldout_rmse_mm < 1.25 * d.final_train_rmse_mm, "seed {seed}: {} vs in-sample {}", d.final_heldout_rmse_mm, d.final_train_rmse_mm);
        assert!(d.final_heldout_rmse_mm < 1.5 * sigma, "seed {seed}: {} vs reading noise {sigma}", d.final_heldout_rmse_mm);
        assert!(d.noise_floor_source.contains("lower bound"), "{}", d.noise_floor_source);
    }
}

#[test]
fn clean_data_come_back_geometric_only() {
    for seed in [101, 102] {
        let (s, robot) = clean(seed).unwrap();
        let d = run(&s, &robot);
        assert!(d.causes.is_empty() && d.verdict == "geometric_only", "seed {seed}: {:?}", d.causes);
        assert!(d.outliers.is_empty(), "seed {seed}: {:?}", d.outliers);
    }
}

#[test]
fn two_hidden_effects_are_both_named() {
    let (s, robot, truth) = hidden(7, 2).unwrap();
    assert_eq!(truth.len(), 2);
    let d = run(&s, &robot);
    eprintln!("hidden {truth:?}; found {:?}", d.causes.iter().map(|c| (&c.cause, c.joint, c.magnitude, c.uncertainty)).collect::<Vec<_>>());
    for h in &truth {
        let c = d.causes.iter().find(|c| h.named_by(c)).unwrap_or_else(|| panic!("{h:?} not named: {}", d.verdict));
        assert!(h.sized_by(c), "{h:?}: size {} ± {}", c.magnitude, c.uncertainty);
    }
}

/// The command end to end: report.json with the documented fields, the extended model usable
/// by `predict`, a recording, and named errors for bad options.
#[test]
fn diagnose_through_the_cli() {
    let (s, robot, truth) = hidden(1, 1).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let g = generate(&s, &robot, &Silent).unwrap();
    twincal::sim::generate::write_outputs(&g, &data).unwrap();
    let (report, model, rrd) = (dir.path().join("report.json"), dir.path().join("model.json"), dir.path().join("d.rrd"));
    let html = dir.path().join("d.html");
    let bin = env!("CARGO_BIN_EXE_twincal");
    let p = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let o = std::process::Command::new(bin)
        .args([
            "diagnose",
            "--data",
            &p(&data),
            "--out",
            &p(&report),
            "--result",
            &p(&model),
            "--rrd",
            &p(&rrd),
            "--report",
            &p(&html),
            "--max-test-rmse-mm",
            "1",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let h = &truth[0];
    assert!(err.contains(&format!("cause 1: {} joint {}", h.cause.name(), h.joint.unwrap() + 1)), "hidden {h:?}: {err}");
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert!(r["noise_floor_mm"].as_f64().unwrap() > 0.0 && r["baseline"]["heldout_rmse_mm"].as_f64().unwrap() > r["final_heldout_rmse_mm"].as_f64().unwrap());
    let c = &r["causes"][0];
    for key in ["cause", "joint", "magnitude", "unit", "uncertainty", "heldout_rmse_before_mm", "heldout_rmse_after_mm", "p_value"] {
        assert!(!c[key].is_null(), "cause lacks {key}: {c}");
    }
    assert_eq!(c["cause"], h.cause.name());
    assert_eq!(c["joint"], h.joint.unwrap() + 1);
    assert!((c["magnitude"].as_f64().unwrap() - truth[0].magnitude).abs() < 0.3 * truth[0].magnitude);
    // The verdict against the held-out limit, the page, and a recording whose views all have data.
    assert_eq!(r["verdict"]["pass"], true, "{}", r["verdict"]);
    assert_eq!(r["verdict"]["checks"][0]["name"], "heldout_rmse_mm");
    assert_eq!(r["verdict"]["checks"][0]["value"].as_f64(), r["final_heldout_rmse_mm"].as_f64());
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.contains(h.cause.name()) && page.contains("PASS") && !page.contains("<script"));
    #[cfg(feature = "rerun")]
    {
        let rec = common::read(&rrd);
        assert_eq!(rec.timeline.as_deref(), Some("step"));
        rec.assert_no_empty_view();
        for (e, c) in [
            ("/evidence/cause_1/with", "Points2D:positions"),
            ("/evidence/cause_1/without", "Points2D:labels"),
            ("/world/before/train", "Points3D:colors"),
            ("/world/after/colorbar/bar", "LineStrips3D:strips"),
            ("/docs/summary", "TextDocument:text"),
        ] {
            assert!(rec.holds(e, c, "static"), "{e} lacks {c}");
        }
        let steps = common::scalars(&rrd, "/steps/heldout_rmse_mm");
        assert_eq!(steps.len(), r["causes"].as_array().unwrap().len() + 1);
        assert!(
            (steps[0] - r["baseline"]["heldout_rmse_mm"].as_f64().unwrap()).abs() < 1e-9
                && (steps[steps.len() - 1] - r["final_heldout_rmse_mm"].as_f64().unwrap()).abs() < 1e-9,
            "{steps:?}"
        );
    }
    // The extended model predicts the data through `predict`, effects included.
    let pred = dir.path().join("pred.csv");
    let o = std::process::Command::new(bin).args(["predict", "--model", &p(&model), "--data", &p(&data), "--out", &p(&pred), "--quiet"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&pred).unwrap();
    let res: Vec<f64> = text.lines().skip(1).map(|l| l.rsplit(',').next().unwrap().parse().unwrap()).collect();
    // `--result` is the model the report evaluated: through `predict` it reproduces the report's
    // in-sample RMSE over the rows the diagnosis kept.
    let outliers: Vec<usize> = r["outliers"].as_array().unwrap().iter().map(|o| o["row"].as_u64().unwrap() as usize - 1).collect();
    let kept: Vec<f64> = res.iter().enumerate().filter(|(i, _)| !outliers.contains(i)).map(|(_, v)| *v).collect();
    let kept_rmse = (kept.iter().map(|v| v * v).sum::<f64>() / kept.len() as f64).sqrt();
    let reported = r["final_train_rmse_mm"].as_f64().unwrap();
    assert!((kept_rmse - reported).abs() < 1e-6 * reported, "predict RMSE {kept_rmse} vs the report's {reported}");
    // Bad options are named; nothing is written.
    let out2 = dir.path().join("r2.json");
    for (args, needle) in [(vec!["--candidates", "gravity"], "unknown effect"), (vec!["--folds", "1"], "--folds"), (vec!["--alpha", "2"], "--alpha")] {
        let mut a = vec!["diagnose", "--data", data.to_str().unwrap(), "--out", out2.to_str().unwrap()];
        a.extend(args);
        let o = std::process::Command::new(bin).args(&a).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(needle), "{a:?}: {err}");
        assert!(!out2.exists());
    }
}

/// The embedded scenario acquires by the simulated tour (flanks from the motion, every effect on):
/// given the loads it knows (payload and cable tension, from the data sheets), the diagnosis names
/// the joint-2 backlash among its causes at the twin's band width, and reaches the noise floor.
#[test]
fn the_simulated_tour_shows_its_backlash() {
    use twincal::sim::effects::Payload;
    let (s, robot) = Scenario::default_embedded().unwrap();
    assert_eq!(s.acquisition.model, twincal::sim::twin::tour::AcquisitionModel::Simulated);
    let truth_width = s.effects.backlash.as_ref().unwrap().width_deg[1];
    let g = generate(&s, &robot, &Silent).unwrap();
    let data = Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: s.name.clone() };
    let mut opts = DiagnoseOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap());
    opts.loads.joints.payload = Some(Payload { mass_kg: 0.5, com_mm: [40.0, 0.0, 0.0] });
    opts.loads.joints.cable_tension_n = 6.0;
    let d = diagnose(&data, &opts, &|_| {}).unwrap().0;
    let found: Vec<_> = d.causes.iter().map(|c| (&c.cause, c.joint, c.magnitude, c.uncertainty)).collect();
    let c = d.causes.iter().find(|c| c.cause == EffectKind::Backlash && c.joint == Some(2)).unwrap_or_else(|| panic!("no joint-2 backlash: {found:?}"));
    let e = (c.magnitude - truth_width).abs();
    assert!(e <= 3.0 * c.uncertainty || e <= 0.3 * truth_width, "width {} ± {} vs {truth_width}: {found:?}", c.magnitude, c.uncertainty);
    assert!(d.final_heldout_rmse_mm < 1.25 * d.final_train_rmse_mm && d.final_heldout_rmse_mm < 0.7 * d.baseline.heldout_rmse_mm, "{found:?}");
}

/// The hidden-effect scenarios acquired as real data are: in sweeps (one or two joints moving at
/// a time), joint angles logged at 0.001°, three runs of glitching readings. The diagnosis keeps
/// scattered glitch rows out, corrects runs that are one offset (reading steps) and keeps them,
/// judges on the folds that suit the acquisition, and still names the hidden cause with its size.
#[test]
fn a_hidden_effect_is_named_in_sweep_ordered_data_with_glitch_runs() {
    use twincal::sim::scenario::{GlitchKind, Glitches, Order};
    for seed in [1, 4, 21] {
        let kind = if seed == 4 { GlitchKind::Offset } else { GlitchKind::Scatter };
        let (mut s, robot, truth) = hidden(seed, 1).unwrap();
        s.sampling.order = Order::Sweeps;
        s.sampling.logged_decimals = Some(3);
        s.glitches = Some(Glitches { runs: 3, rows: 6, size_mm: 1.0, kind, joint: None, size_deg: None });
        let h = &truth[0];
        let g = generate(&s, &robot, &Silent).unwrap();
        let data = Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: s.name.clone() };
        let d =
            diagnose(&data, &DiagnoseOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap()), &|_| {}).unwrap().0;
        eprintln!(
            "seed {seed}: hidden {h:?}; judged on {}; found {:?}",
            d.judged_on,
            d.causes.iter().map(|c| (&c.cause, c.joint, c.magnitude, c.uncertainty)).collect::<Vec<_>>()
        );
        // The screen judges rows against the geometric model, before any cause is known: a row
        // the hidden effect pushes far may be flagged too (at most two here).
        let (glitch, other): (Vec<usize>, Vec<usize>) = d.outliers.iter().map(|o| o.row - 1).partition(|r| g.truth.glitch_rows.contains(r));
        if kind == GlitchKind::Scatter {
            assert!(d.reading_steps.is_empty(), "seed {seed}: scattered glitches taken for steps: {:?}", d.reading_steps);
            assert!(glitch.len() >= 15 && other.len() <= 2, "seed {seed}: {} of 18 glitch rows found, other rows {other:?}", glitch.len());
        } else {
            // Each run is one offset: a reading step over its rows, corrected and kept.
            assert_eq!(d.reading_steps.len(), 3, "seed {seed}: {:?}", d.reading_steps);
            for st in &d.reading_steps {
                let rows: Vec<usize> = (st.first_row - 1..st.last_row).collect();
                assert!(rows.len() >= 4 && rows.iter().all(|r| g.truth.glitch_rows.contains(r)), "seed {seed}: step {st:?} is no glitch run");
            }
            assert!(other.len() <= 2, "seed {seed}: other rows kept out {other:?}");
        }
        let first = d.causes.first().unwrap_or_else(|| panic!("seed {seed}: {h:?} not found ({})", d.verdict));
        assert!(h.named_by(first) && h.sized_by(first), "seed {seed}: hidden {h:?}, named {}", first.summary());
    }
}

/// A temperature column that never changes (a sensor that did not move) drives nothing: the
/// drift the rows show over time is fitted against t instead, and named.
#[test]
fn a_drift_behind_a_constant_temperature_column_is_named_over_time() {
    let mut s = Scenario::from_toml(include_str!("../../../scenarios/irb120_geometric.toml"), "geometric").unwrap();
    s.effects.thermal = Some(twincal::sim::effects::Thermal::new(25e-6, 5.0, 600.0, 21.0));
    let robot = s.load_robot(None).unwrap();
    let g = generate(&s, &robot, &Silent).unwrap();
    let rows: Vec<Row> = g.dataset.rows.iter().map(|r| Row { split: None, temp_c: Some(21.0), ..r.clone() }).collect();
    let data = Dataset { rows, source: "broken temperature sensor".into() };
    let opts = DiagnoseOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap());
    let d = diagnose(&data, &opts, &|_| {}).unwrap().0;
    assert!(d.causes.iter().any(|c| c.cause == EffectKind::Thermal && c.joint.is_none()), "{}", d.verdict);
    // The model it writes runs on t: predict needs t, not temp.
    let (_, result) = diagnose(&data, &opts, &|_| {}).unwrap();
    assert!(result.columns_read().iter().all(|(c, _)| *c == "t"), "{:?}", result.columns_read());
}

/// Real-like acquisitions (sweeps of 20 poses, joint angles logged at 0.1° or 0.01°, runs of
/// disturbed readings): the diagnosis finds the sweeps, holds them out whole, fits the logging
/// error as shared within each sweep, names nothing where nothing is hidden, and names an
/// effect that rises above the data's floor with its joint and size.
#[test]
fn real_like_acquisitions_in_sweeps_with_logged_angles() {
    use twincal::diagnose::hidden::{hidden_realistic, realistic};
    for (seed, decimals) in [(20_001, 1), (20_003, 2)] {
        let (s, robot) = realistic(seed, decimals).unwrap();
        let d = run(&s, &robot);
        eprintln!("clean seed {seed} at {decimals} decimals: {} ({}); deff {:.2}; {:?}", d.verdict, d.acquisition.summary, d.design_effect, d.warnings);
        assert!(d.acquisition.multi_row_blocks >= 15 && d.acquisition.sweep_boundaries >= 15, "{}", d.acquisition.summary);
        assert!(d.causes.is_empty(), "seed {seed}: false alarm {}", d.verdict);
        // Held-out rows are whole sweeps: the held-out RMSE is at the logging floor, within what
        // the rounding of some twenty sweeps' still joints lets a realised mean square stray from
        // its expectation, and no leak is warned.
        assert!(d.final_heldout_rmse_mm >= 0.8 * d.noise_floor_mm, "seed {seed}: {} below the floor {}", d.final_heldout_rmse_mm, d.noise_floor_mm);
        assert!(!d.warnings.iter().any(|w| w.contains("split leaks")), "{:?}", d.warnings);
    }
    for seed in [30_001, 30_002] {
        let (s, robot, truth, floor) = hidden_realistic(seed, 2, 1.5..4.0).unwrap();
        let h = &truth[0];
        let d = run(&s, &robot);
        eprintln!("seed {seed}: hidden {h:?} (floor {floor:.4} mm); found {}", d.causes.iter().map(|c| c.summary()).collect::<Vec<_>>().join("; "));
        let first = d.causes.first().unwrap_or_else(|| panic!("seed {seed}: {h:?} not found ({})", d.verdict));
        assert!(h.named_by(first) && h.sized_by(first), "seed {seed}: hidden {h:?}, named {}", first.summary());
    }
}

/// A thermal drift of the whole arm (99 ppm/K over a 5 K warm-up) hidden in sweeps logged at 0.01°
/// with three glitch runs, on six seeds: the diagnosis names it and `calibrate --effects
/// thermal` sizes it, each within 3 of its stated standard uncertainties of the truth. The
/// twin's sweeps step in round increments, so the swept joint's rounding, like the holding
/// joints', is shared by the sweep; and the rows are screened with the drift in the model (the
/// geometry alone takes the start of the warm-up for reading steps and corrects it away).
#[test]
fn a_thermal_drift_in_logged_sweeps_is_sized_within_its_uncertainty() {
    use twincal::calib::effects::EffectKind;
    use twincal::calib::pipeline::{calibrate, CalibOptions, Method};
    let (s0, robot, truth, _) = twincal::diagnose::hidden::hidden_realistic(30_005, 2, 1.5..4.0).unwrap();
    let h = &truth[0];
    assert!(h.cause == EffectKind::Thermal && h.joint.is_none(), "{h:?}");
    for seed in [101, 103, 104, 106, 109, 111] {
        let s = Scenario { seed, name: format!("thermal-{seed}"), ..s0.clone() };
        let d = run(&s, &robot);
        let c = d.causes.first().unwrap_or_else(|| panic!("seed {seed}: nothing named ({})", d.verdict));
        eprintln!("seed {seed}: diagnose {}", c.summary());
        assert!(h.named_by(c) && (c.magnitude - h.magnitude).abs() <= 3.0 * c.uncertainty, "seed {seed}: hidden {h:?}, named {}", c.summary());
        let g = generate(&s, &robot, &Silent).unwrap();
        let mut opts = CalibOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap(), Method::LM);
        opts.effects = vec![(EffectKind::Thermal, None)];
        let r = calibrate(&g.dataset, None, &opts).unwrap();
        let p = r.parameters.iter().find(|p| p.name == "thermal.alpha").expect("the drift's parameter");
        let sd = p.std_uncertainty.expect("an uncertainty");
        eprintln!("seed {seed}: calibrate {:.2} ± {sd:.2} ppm/K (truth {:.2})", p.value, h.magnitude);
        assert!((p.value - h.magnitude).abs() <= 3.0 * sd, "seed {seed}: calibrate {} ± {sd}, truth {}", p.value, h.magnitude);
    }
}

/// Faults in the logged joint angles (an offset, a sign, a stale value over a run of 8 rows),
/// hidden in sweep-ordered data logged at 0.01° beside the readings' own glitches: each run is
/// tested against every hypothesis (the reading, one joint's logged angle, the instrument) and
/// what is named is the fault that was hidden, with its rows; a run whose hypotheses cannot be
/// told apart is left ambiguous or unexplained, never given the wrong cause. The runs stay out of the fit,
/// and the diagnosis names no effect.
#[test]
fn joint_reading_faults_are_named_with_their_rows() {
    use twincal::diagnose::hidden::realistic;
    use twincal::sim::scenario::{GlitchKind, Glitches};
    // Joints 1 and 2 swapped: the pair whose logged values stay within each other's limits on
    // the IRB 120 (a swap of joints with narrower limits is refused as data past its limits).
    for (kind, name, joint) in [
        (GlitchKind::Offset, "reading_offset", None),
        (GlitchKind::JointOffset, "joint_offset", None),
        (GlitchKind::JointSign, "joint_sign", None),
        (GlitchKind::JointStale, "joint_stale", None),
        (GlitchKind::JointSwap, "joint_swap", Some(1)),
    ] {
        let (mut s, robot) = realistic(20_001, 2).unwrap();
        s.glitches = Some(Glitches { runs: 3, rows: 8, size_mm: 2.0, kind, joint, size_deg: None });
        let g = generate(&s, &robot, &Silent).unwrap();
        let data = Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: s.name.clone() };
        let d =
            diagnose(&data, &DiagnoseOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap()), &|_| {}).unwrap().0;
        for f in &d.run_faults {
            eprintln!("{name}: rows {}-{}: {}", f.first_row, f.last_row, f.evidence);
        }
        assert_eq!(d.run_faults.len(), 3, "{name}: {:?}", d.run_faults);
        let mut named = 0;
        for f in &d.run_faults {
            let rows: Vec<usize> = (f.first_row - 1..f.last_row).collect();
            assert!(rows.iter().all(|r| g.truth.glitch_rows.contains(r)), "{name}: rows {}-{} are no hidden run", f.first_row, f.last_row);
            assert!(["unexplained", "ambiguous", name].contains(&f.cause.name()), "{name}: rows {}-{} named {}", f.first_row, f.last_row, f.cause);
            if f.cause.name() == name {
                named += 1;
                assert!(f.rms_corrected_mm < 0.1 * f.rms_as_logged_mm, "{f:?}");
            }
            if f.cause.name() == "joint_offset" {
                let v = f.value.unwrap().abs();
                assert!((0.95..1.55).contains(&v), "{f:?}");
            }
        }
        assert!(named >= 2, "{name}: {named} of 3 runs named");
        assert!(d.causes.is_empty(), "{name}: {}", d.verdict);
    }
}

/// A joint-3 compliance the unloaded IRB 120 hides (120 tracker rows: `geometric_only`) and
/// payload runs of 0, 1.5 and 3 kg at the same poses reveal: named first and sized within 3σ
/// once the payload's centre of mass is stated; without it a warning says the size depends on it.
#[test]
fn payload_runs_reveal_a_compliance_the_unloaded_arm_hides() {
    use twincal::calib::effects::inputs::JointLoads;
    use twincal::sim::pose_list::{generate_pose_list, PoseList};
    let scenario = include_str!("../../../scenarios/irb120_tracker.toml")
        .replace("[sensor]", "[effects.compliance]\nstiffness_nm_per_rad = [1e12, 1e12, 6e5, 1e12, 1e12, 1e12]\n\n[effects.payload]\nmass_kg = 0.0\ncom_mm = [150.0, 0.0, 100.0]\n\n[sensor]")
        .replace("decimals = 4", "decimals = 4\nwrite_std = true");
    let mut s = Scenario::from_toml(&scenario, "payload runs (test)").unwrap();
    (s.seed, s.sampling.poses, s.sampling.test) = (11, 120, 0);
    let robot = s.load_robot(None).unwrap();
    let poses = twincal::sim::generate::sample_poses(&s, &robot).unwrap();
    let runs = [0.0, 1.5, 3.0];
    let list =
        PoseList { q: runs.iter().flat_map(|_| poses.iter().cloned()).collect(), payload_kg: Some(runs.iter().flat_map(|m| vec![*m; poses.len()]).collect()) };
    let g = generate_pose_list(&s, &robot, list, &Silent).unwrap();
    let rows: Vec<Row> = g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect();
    let truth = 1.0 / 6e5 * 1e6; // µrad/N·m
    let opts = DiagnoseOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap());
    let unloaded = Dataset { rows: rows.iter().filter(|r| r.payload_kg == Some(0.0)).cloned().collect(), source: "unloaded".into() };
    assert_eq!(unloaded.rows.len(), 120);
    let d = diagnose(&unloaded, &opts, &|_| {}).unwrap().0;
    assert!(d.causes.is_empty(), "the unloaded run alone: {}", d.verdict);
    let all = Dataset { rows, source: "payload runs".into() };
    let com = JointLoads { payload: Some(twincal::robot::statics::Payload { mass_kg: 0.0, com_mm: [150.0, 0.0, 100.0] }), ..Default::default() };
    let d =
        diagnose(&all, &DiagnoseOptions { loads: twincal::calib::pipeline::LoadOptions { joints: com, inertial: None }, ..opts.clone() }, &|_| {}).unwrap().0;
    let first = d.causes.first().unwrap_or_else(|| panic!("the payload runs: {}", d.verdict));
    eprintln!("payload runs: {} (truth {truth:.4} urad/Nm)", first.summary());
    assert!(first.cause == EffectKind::Compliance && first.joint == Some(3), "{}", d.verdict);
    assert!((first.magnitude - truth).abs() < 3.0 * first.uncertainty, "{} vs {truth}", first.summary());
    let d = diagnose(&all, &opts, &|_| {}).unwrap().0;
    assert!(d.warnings.iter().any(|w| w.contains("no centre of mass is stated")), "{:?}", d.warnings);
}

/// A run where one joint is logged off and the reading jumps at the same row (a cable re-hooked
/// after the fault): neither a joint's fault nor a reading offset alone explains it; the two
/// together are named, with both sizes.
#[test]
fn a_joint_fault_with_a_reading_jump_is_named_as_both() {
    use twincal::diagnose::hidden::realistic;
    use twincal::sim::scenario::{GlitchKind, Glitches};
    let (mut s, robot) = realistic(20_001, 2).unwrap();
    s.glitches = Some(Glitches { runs: 3, rows: 8, size_mm: 2.0, kind: GlitchKind::JointOffsetAndReading, joint: None, size_deg: Some(1.0) });
    let g = generate(&s, &robot, &Silent).unwrap();
    let data = Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: s.name.clone() };
    let d = diagnose(&data, &DiagnoseOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap()), &|_| {}).unwrap().0;
    for f in &d.run_faults {
        eprintln!("rows {}-{}: {} ({})", f.first_row, f.last_row, f.cause, f.evidence);
    }
    let named: Vec<_> = d.run_faults.iter().filter(|f| f.cause.name() == "joint_offset+reading_offset").collect();
    assert!(named.len() >= 2, "{:?}", d.run_faults);
    for f in named {
        let rows: Vec<usize> = (f.first_row - 1..f.last_row).collect();
        assert!(rows.iter().all(|r| g.truth.glitch_rows.contains(r)), "rows {}-{} are no hidden run", f.first_row, f.last_row);
        assert!((0.95..1.55).contains(&f.value.unwrap().abs()) && (1.9..3.1).contains(&f.reading_offset_mm.unwrap().abs()), "{f:?}");
        assert!(f.rms_corrected_mm < 0.1 * f.rms_as_logged_mm, "{f:?}");
    }
    assert!(d.causes.is_empty(), "{}", d.verdict);
}

/// A warm-up whose temperature sensor lags the structure by a third of the warm-up's time
/// constant, under a tracker that never moved: calibrate fits the sensor's lag and sizes the
/// expansion within 3σ of the truth (without the lag it is sized 9 % low, beyond 5σ); the
/// warm-up's drift is not taken for moves of the tracker; diagnose, as the command runs it
/// (set-up changes first), names the drift, sizes it within 3σ and finds no set-up change.
#[test]
fn a_warm_up_behind_a_lagging_sensor_is_sized_and_not_taken_for_moves() {
    use twincal::sim::effects::Thermal;
    let mut s = Scenario::from_toml(include_str!("../../../scenarios/irb120_tracker.toml"), "warm-up (test)").unwrap();
    (s.seed, s.sampling.poses, s.sampling.test) = (11, 400, 100);
    s.effects.thermal = Some(Thermal { temp_lag_s: 300.0, ..Thermal::new(23e-6, 10.0, 900.0, 20.0) });
    let robot = s.load_robot(None).unwrap();
    let data = generate(&s, &robot, &Silent).unwrap().dataset;
    let spec = || ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap();
    let param = |r: &twincal::calib::pipeline::CalibResult, name: &str| {
        let p = r.parameters.iter().find(|p| p.name == name).unwrap_or_else(|| panic!("no {name}"));
        (p.value, p.std_uncertainty.unwrap_or(f64::NAN))
    };
    let fit = |lag: bool| {
        let mut o = twincal::calib::pipeline::CalibOptions::new(spec(), twincal::calib::pipeline::Method::LM);
        o.effects = vec![(twincal::calib::effects::EffectKind::Thermal, None)];
        o.sensor_lag = lag;
        twincal::calib::pipeline::calibrate(&data, None, &o).unwrap()
    };
    let r = fit(true);
    let ((alpha, sd), (lag, lag_sd)) = (param(&r, "thermal.alpha"), param(&r, "thermal.alpha.sensor_lag"));
    eprintln!("with the lag: alpha {alpha:.3} ± {sd:.3} ppm/K, lag {lag:.0} ± {lag_sd:.0} s");
    assert!((alpha - 23.0).abs() < 3.0 * sd, "alpha {alpha} ± {sd} ppm/K against 23");
    assert!((lag - 300.0).abs() < 3.0 * lag_sd.max(10.0), "lag {lag} ± {lag_sd} s against 300");
    assert!(r.setup.as_ref().is_none_or(|s| s.stations.len() <= 1 && s.mounts.len() <= 1), "a warm-up taken for moves: {:?}", r.setup);
    let (alpha0, sd0) = param(&fit(false), "thermal.alpha");
    eprintln!("without it: alpha {alpha0:.3} ± {sd0:.3} ppm/K");
    assert!(alpha0 < 23.0 - 5.0 * sd0, "the lag left out should size the expansion low: {alpha0} ± {sd0}");
    let rows = Dataset { rows: data.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: data.source.clone() };
    let opts = DiagnoseOptions::new(spec());
    let d = twincal::jobs::diagnose_loaded(&twincal::requests::DiagnoseRequest::default(), (opts, Default::default()), rows.clone(), &|_| {}).unwrap();
    let first = d.report.causes.first().unwrap_or_else(|| panic!("nothing named: {}", d.report.verdict));
    eprintln!("diagnose: {}", first.summary());
    assert!(first.cause == EffectKind::Thermal && first.joint.is_none(), "{}", d.report.verdict);
    assert!((first.magnitude - 23.0).abs() < 3.0 * first.uncertainty, "{}", first.summary());
    assert!(d.report.setup.as_ref().is_none_or(|s| s.stations.len() <= 1 && s.mounts.len() <= 1), "set-up changes found: {:?}", d.report.setup);
    // A drift is kept on what comes later: chosen among the thermal forms forward in time, and
    // it predicts the later stretches of the run better than the model without it.
    let step = d.report.steps.iter().find(|s| s.kept.as_deref() == Some("thermal")).expect("the step that kept it");
    assert_eq!(step.kept_on, Some(twincal::diagnose::KeptOn::ForwardInTime));
    let (before, after) = (first.forward_rmse_before_mm.unwrap(), first.forward_rmse_after_mm.unwrap());
    assert!(after < 0.8 * before, "forward in time {before:.4} -> {after:.4} mm");
    // Diagnosed on the first 70 % of the rows in time, the model with the drift predicts the
    // last 30 %, never seen, better than the geometric model calibrated on the same rows.
    let request = twincal::requests::DiagnoseRequest { test_fraction: Some(0.3), split_by: twincal::calib::pipeline::SplitBy::Time, ..Default::default() };
    let d = twincal::jobs::diagnose_loaded(&request, (DiagnoseOptions::new(spec()), Default::default()), rows.clone(), &|_| {}).unwrap();
    assert_eq!(d.data.rows.last().and_then(|r| r.t_s), rows.rows[d.data.rows.len() - 1].t_s, "the training rows are the first in time");
    let unseen = d.report.unseen.as_ref().expect("held-out rows judged");
    eprintln!("{}: {}", d.report.verdict, unseen.line());
    assert_eq!(unseen.rows, rows.rows.len() - d.data.rows.len());
    assert!(unseen.final_rmse_mm < 0.8 * unseen.geometric_rmse_mm, "{}", unseen.line());
}

/// What remains after the named cause, characterised (issue 65): on tracker rows with their own
/// sx, sy, sz and an effect at half a row's noise, the remainder after the named cause is white
/// and its apparent noise is the instrument's (not `unexplained`); where an effect at twice the
/// noise is of a kind the diagnosis may not name, what remains follows the joints and is
/// reported `unexplained`.
#[test]
fn what_remains_is_white_at_the_instruments_noise_or_reported_unexplained() {
    use twincal::diagnose::hidden::hidden_tracker;
    let rows = |s: &Scenario, robot: &Robot| {
        let g = generate(s, robot, &Silent).unwrap();
        Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: s.name.clone() }
    };
    let opts = DiagnoseOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap());
    let (s, robot, truth, sigma) = hidden_tracker(50_001, 0.5..0.6).unwrap();
    let d = diagnose(&rows(&s, &robot), &opts, &|_| {}).unwrap().0;
    let r = d.remainder.as_ref().expect("characterised");
    eprintln!("hidden {:?}: {}; what remains: {}", truth[0], d.verdict, r.summary());
    assert!(truth[0].named_by(&d.causes[0]) && d.unexplained.is_none() && r.white, "{}: {:?}", d.verdict, d.unexplained);
    let k = r.noise_ratio().expect("the rows state their noise");
    assert!((0.8..1.3).contains(&k), "apparent noise {:.4} mm is {k:.2}x the stated (one row {sigma:.4} mm)", r.apparent_position_mm);
    let (s, robot, truth, _) = hidden_tracker(55_001, 2.0..3.0).unwrap();
    let kinds =
        twincal::calib::effects::EffectKind::ALL.into_iter().filter(|k| *k != truth[0].cause && *k != twincal::calib::effects::EffectKind::Nonlinearity);
    let without = DiagnoseOptions { candidates: kinds.map(|k| (k, None)).collect(), ..opts };
    let d = diagnose(&rows(&s, &robot), &without, &|_| {}).unwrap().0;
    let r = d.remainder.as_ref().expect("characterised");
    eprintln!("hidden {:?}, not a candidate: {}; {}", truth[0], d.verdict, r.summary());
    assert!(d.verdict.ends_with("unexplained") && !r.white, "{}", d.verdict);
    assert!(r.structure().any(|t| t.against.starts_with('q')), "{:?}", r.tests);
}
